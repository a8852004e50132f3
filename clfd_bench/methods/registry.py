"""Method names -> method classes: the built-in methods, installed plugins, import specs.

A method is named in one of three ways (``--method`` of every command, ``RunConfig.method``):

* a built-in name (``sg``, ``ft``, ..., ``ewc``, ``agem``, ``packnet``: :data:`BUILTIN`);
* the name of an installed plugin, i.e. an entry point of the group
  :data:`ENTRY_POINT_GROUP` (``clfd_bench.methods``) in the plugin package's metadata::

      [project.entry-points."clfd_bench.methods"]
      mymethod = "mypackage.methods:MyMethod"

* an import spec ``package.module:ClassName``, or ``path/to/file.py:ClassName`` for a file
  outside any package (stored with its absolute path, so resumed runs and worker processes
  find it again).

Every class that is not built in is checked by :func:`check_method_class` before use, and an
error names what is missing. The method's hyperparameters come from a TOML file with the
same tables as ``baselines/<name>.toml`` (``--config``, else :func:`own_config_file`, else
``baselines/<name>.toml``: :func:`clfd_bench.harness.config.resolve_config`).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
import sys
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path

from clfd_bench.learning.part_config import PART_FIELDS, Rule
from clfd_bench.methods.agem import AveragedGEM
from clfd_bench.methods.base import Method
from clfd_bench.methods.ewc import OnlineEWC
from clfd_bench.methods.ft import FineTuning
from clfd_bench.methods.hn import ChunkedHypernetworkMethod, HypernetworkMethod
from clfd_bench.methods.mas import MemoryAwareSynapses
from clfd_bench.methods.packnet import PackNet
from clfd_bench.methods.rep import Replay
from clfd_bench.methods.sg import SingleNodePerTask
from clfd_bench.methods.si import SynapticIntelligence

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "PAPER_METHODS",
    "MethodClassError",
    "UnknownMethodError",
    "check_method_class",
    "get_method_class",
    "installed_plugins",
    "list_methods",
    "normalise_method",
    "own_config_file",
]

ENTRY_POINT_GROUP = "clfd_bench.methods"
"""The entry-point group plugin packages register their methods under."""

BUILTIN: dict[str, type[Method]] = {
    cls.name: cls
    for cls in (
        SingleNodePerTask,
        FineTuning,
        Replay,
        SynapticIntelligence,
        MemoryAwareSynapses,
        HypernetworkMethod,
        ChunkedHypernetworkMethod,
        OnlineEWC,
        AveragedGEM,
        PackNet,
    )
}
"""The built-in methods by name: the paper's seven in the paper's order (``PAPER_METHODS``),
then the ones added here through the plugin interface (online EWC, A-GEM, PackNet)."""

PAPER_METHODS: tuple[str, ...] = ("sg", "ft", "rep", "si", "mas", "hn", "chn")
"""The paper's seven methods (the default method list of leaderboards and the paper grid)."""

_NAME = re.compile(r"^[a-z][a-z0-9_-]*$")
_REQUIRED_HOOKS = ("field", "trainable")


class UnknownMethodError(KeyError):
    """A method name that is neither built in, nor an installed plugin, nor importable."""

    def __str__(self) -> str:  # KeyError would print the message with quotes
        return str(self.args[0])


class MethodClassError(TypeError):
    """A plugin class that does not implement the :class:`Method` interface."""


def installed_plugins() -> dict[str, str]:
    """Installed plugin methods: entry-point name -> ``module:Class`` (not imported)."""
    return {ep.name: ep.value for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def list_methods() -> list[str]:
    """Built-in method names, then installed plugins."""
    return [*BUILTIN, *(n for n in installed_plugins() if n not in BUILTIN)]


def _valid_names() -> str:
    return (f"valid methods: {', '.join(list_methods())}, or a plugin class as "
            "package.module:ClassName or path/to/file.py:ClassName")


def normalise_method(spec: str) -> str:
    """The form of ``spec`` stored in run configs: a file spec with an absolute path, every
    other name unchanged."""
    module, sep, attr = spec.rpartition(":")
    if sep and (module.endswith(".py") or "/" in module):
        return f"{Path(module).expanduser().resolve()}:{attr}"
    return spec


def _load_file(path: Path, spec: str):
    if not path.is_file():
        raise UnknownMethodError(f"method {spec!r}: no file {path}")
    name = "clfd_bench_plugin_" + re.sub(r"\W", "_", str(path.with_suffix("")))
    if name in sys.modules:
        return sys.modules[name]
    loader_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[name] = module
    try:
        loader_spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _import(spec: str) -> type:
    module_name, _, attr = spec.rpartition(":")
    if not module_name or not attr:
        raise UnknownMethodError(f"method {spec!r}: an import spec is module:ClassName; "
                                 + _valid_names())
    try:
        if module_name.endswith(".py") or "/" in module_name:
            module = _load_file(Path(module_name).expanduser().resolve(), spec)
        else:
            module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        raise UnknownMethodError(
            f"method {spec!r}: cannot import {exc.name!r} ({exc}); install the package "
            "(pip install -e path/to/it) or add its folder to PYTHONPATH"
        ) from None
    except UnknownMethodError:
        raise
    except Exception as exc:  # the plugin's own module fails while importing
        where = ""
        if isinstance(exc, SyntaxError):
            where = f" ({exc.filename}, line {exc.lineno})"
        raise MethodClassError(f"method {spec!r}: importing {module_name!r} raised "
                               f"{type(exc).__name__}: {exc}{where}") from exc
    target = module
    for part in attr.split("."):
        if not hasattr(target, part):
            found = sorted(n for n, v in vars(module).items()
                           if inspect.isclass(v) and issubclass(v, Method)
                           and v.__module__ == module.__name__)
            raise UnknownMethodError(
                f"method {spec!r}: module {module_name!r} has no {attr!r}; Method subclasses "
                f"in it: {', '.join(found) or 'none'}"
            )
        target = getattr(target, part)
    return target


def _overrides(cls: type, hook: str) -> bool:
    return getattr(cls, hook) is not getattr(Method, hook)


def check_method_class(cls: object, spec: str) -> type[Method]:
    """``cls`` if it implements the :class:`Method` interface, else
    :class:`MethodClassError` naming everything that is missing: a :class:`Method` subclass,
    a ``name`` (lower case, not a built-in's), the hooks ``field`` and ``trainable``,
    ``hyperparameters`` that are config keys, ``own_hyperparameters`` given as
    :class:`~clfd_bench.learning.part_config.Rule` objects under new names."""
    if not (inspect.isclass(cls) and issubclass(cls, Method)):
        raise MethodClassError(
            f"method {spec!r} is {cls!r}, not a subclass of clfd_bench.methods.Method; "
            "see docs/methods.md"
        )
    problems = []
    name = cls.name
    if not isinstance(name, str) or not _NAME.match(name):
        problems.append(f"a class attribute name = '...' (lower case letters, digits, _ or -; "
                        f"got {name!r})")
    elif name in BUILTIN and BUILTIN[name] is not cls:
        problems.append(f"a name other than the built-in method {name!r}")
    missing = [h for h in _REQUIRED_HOOKS if not _overrides(cls, h)]
    if missing:
        problems.append("the method(s) " + ", ".join(f"{h}(self, task)" for h in missing))
    keys = cls.hyperparameters
    if not isinstance(keys, frozenset | set) or not all(isinstance(k, str) for k in keys):
        problems.append(f"hyperparameters as a frozenset of config keys (got {keys!r})")
    else:
        unknown = sorted(set(keys) - set(PART_FIELDS))
        if unknown:
            problems.append(f"hyperparameters that are config keys ({', '.join(unknown)} are "
                            "not; declare a method's own keys in own_hyperparameters)")
    own = cls.own_hyperparameters
    if not isinstance(own, Mapping) or not all(
            isinstance(k, str) and isinstance(r, Rule) for k, r in own.items()):
        problems.append("own_hyperparameters as a dict of name -> clfd_bench.methods.Rule "
                        f"(got {own!r})")
    else:
        clash = sorted(set(own) & set(PART_FIELDS))
        if clash:
            problems.append(f"own_hyperparameters with new names ({', '.join(clash)} are "
                            "already config keys: list them in hyperparameters instead)")
    if problems:
        raise MethodClassError(f"method class {cls.__module__}.{cls.__qualname__} ({spec!r}) "
                               "needs " + "; ".join(problems) + " (docs/methods.md)")
    return cls


def get_method_class(name: str) -> type[Method]:
    """The method class named ``name`` (built-in, installed plugin or import spec).

    Raises:
        UnknownMethodError: no such method; the message lists the valid names.
        MethodClassError: the class found does not implement the interface.
    """
    if name in BUILTIN:
        return BUILTIN[name]
    plugins = installed_plugins()
    if name in plugins:
        return check_method_class(_import(plugins[name]), name)
    if ":" in name:
        return check_method_class(_import(normalise_method(name)), name)
    raise UnknownMethodError(f"unknown CL method {name!r}; {_valid_names()}")


def own_config_file(cls: type[Method]) -> Path | None:
    """A plugin class's own hyperparameter file (its ``config_file``, relative to its
    module's folder), or None when it names none."""
    if not cls.config_file:
        return None
    path = Path(cls.config_file)
    return path if path.is_absolute() else Path(inspect.getfile(cls)).resolve().parent / path
