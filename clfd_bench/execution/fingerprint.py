"""What simulator produced an execution result: a fingerprint of its code and assets, and the
provenance block (env ids and versions, library versions) results files record."""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.metadata
import io
import tokenize
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

__all__ = ["sim_fingerprint", "sim_provenance"]


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


#: Modules under ``clfd_bench/sim`` and ``clfd_bench/envs`` that no env runs, left out of the
#: fingerprint: the build-time derivations of the task specs (``robotasks/derive.py``,
#: ``robotasks/derive_common.py``, every ``robotasks/<task>/derive.py``, ``writing/derive.py``:
#: what they produce, ``tasks/*.toml``, is hashed, so a change to them that changes no spec
#: changes no execution), the tasks' own trajectory variants (``variants.py``: evaluation, not
#: simulation) and the tasks' words (``doc.py``: the env's docstring and tasks/README.md).
_NOT_RUN = ("derive.py", "derive_common.py", "variants.py", "doc.py")


def _runs(path: Path) -> bool:
    """Whether an env runs the module at `path` (see `_NOT_RUN`)."""
    return path.name not in _NOT_RUN


def _module_file(pkg: Path, name: str) -> Path | None:
    """The file of module `name` (``clfd_bench.metrics.trajectory``) under `pkg`, the
    ``clfd_bench`` folder, or None when it is not one of ours."""
    parts = name.split(".")
    if parts[0] != pkg.name:
        return None
    base = pkg.joinpath(*parts[1:])
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imported(pkg: Path, path: Path) -> set[Path]:
    """The files of the ``clfd_bench`` modules that the module at `path` imports, wherever in it
    (a function's lazy import too): for ``from M import N``, N's file when N is a module, else
    M's. Read from the source (nothing is imported)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_bytes())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            subs = {_module_file(pkg, f"{node.module}.{a.name}") for a in node.names} - {None}
            out |= subs or {_module_file(pkg, node.module)}
        elif isinstance(node, ast.Import):
            out |= {_module_file(pkg, a.name) for a in node.names}
    return out - {None}


def _sim_files() -> Iterator[tuple[str, Path]]:
    """Files that define the simulator: its code, the task scenes and specs, robot assets, as
    ``(name, path)``. The code is every module of ``clfd_bench/sim`` and ``clfd_bench/envs``,
    sub-folders included (each RoboTasks task has its own), that an env runs (`_NOT_RUN` lists
    those it does not), ``execution/rollout.py`` (what runs after the trajectory decides
    success too), and every other module of the package these import, transitively (but
    not those `_NOT_RUN` names) (the
    demos' loading and resampling, the writing judges' DTW and thresholds): a change in any of
    them can change a verdict. The name is the same in a source checkout and in an installed
    wheel (``sim/robot.py``, ``envs/robotasks/openbox/scene.py``, ``tasks/openbox.xml``), so a
    run executed in one is current in the other (the wheel keeps ``tasks/`` under
    ``clfd_bench/_share/``)."""
    from clfd_bench.resources import resource_root

    pkg = Path(__file__).resolve().parent.parent
    code = {p for folder in (pkg / "sim", pkg / "envs") for p in folder.rglob("*.py") if _runs(p)}
    code.add(pkg / "execution" / "rollout.py")
    todo = list(code)
    while todo:
        for dep in _imported(pkg, todo.pop()) - code:
            if not _runs(dep):  # e.g. env.py builds its docstring with doc.py
                continue
            code.add(dep)
            todo.append(dep)
    for path in sorted(code, key=lambda p: p.relative_to(pkg).as_posix()):
        yield path.relative_to(pkg).as_posix(), path
    for name in ("tasks", "assets"):
        root = resource_root(name)
        for path in sorted(p for p in root.rglob("*") if p.is_file() and p.suffix != ".md"):
            yield f"{name}/{path.relative_to(root).as_posix()}", path


def _not_run_spans(source: str) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The comments and docstrings (module, class, function) of `source`, as ((line, column),
    (end line, end column)) spans, lines from 1."""
    lines = source.splitlines()

    def column(line: int, byte_offset: int) -> int:  # ast counts UTF-8 bytes, tokenize characters
        return len(lines[line - 1].encode()[:byte_offset].decode())

    spans = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                spans.append(((first.lineno, column(first.lineno, first.col_offset)),
                              (first.end_lineno, column(first.end_lineno, first.end_col_offset))))
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            spans.append((tok.start, tok.end))
    return spans


def _hashed_bytes(path: Path) -> bytes:
    """What of the file at `path` the fingerprint hashes. For Python code, what it runs: the
    source without its comments, docstrings, trailing spaces and blank lines, so that a
    reworded comment leaves every execution result current (the execution layer's cache is
    reused only under the same fingerprint). The same on every Python version: only spans
    are cut out, nothing is re-rendered. Anything else, and a ``.py`` file that does not
    parse, whole."""
    data = path.read_bytes()
    if path.suffix != ".py":
        return data
    try:
        source = data.decode()
        lines = source.splitlines()
        for (line, col), (end_line, end_col) in sorted(_not_run_spans(source), reverse=True):
            head, tail = lines[line - 1][:col], lines[end_line - 1][end_col:]
            lines[line - 1:end_line] = [head + tail]
    except (SyntaxError, UnicodeDecodeError, tokenize.TokenError):
        return data
    return "\n".join(kept for kept in (t.rstrip() for t in lines) if kept).encode()


@functools.lru_cache(maxsize=1)
def sim_fingerprint() -> str:
    """sha256 (hex, first 16 digits) of the simulator: the modules of ``clfd_bench/sim`` and
    ``clfd_bench/envs`` an env runs, ``clfd_bench/execution/rollout.py`` and the package's
    modules they import (`_sim_files`), ``tasks/`` and ``assets/`` and the mujoco, mink,
    gymnasium versions; of the code, what runs (`_hashed_bytes`: comments and docstrings are
    left out). Execution results are
    reused only under the same fingerprint."""
    digest = hashlib.sha256()
    for dist in ("mujoco", "mink", "gymnasium"):
        digest.update(f"{dist}={_version(dist)}\n".encode())
    for rel, path in _sim_files():
        digest.update(rel.encode() + b"\0" + _hashed_bytes(path) + b"\0")
    return digest.hexdigest()[:16]


def sim_provenance(dataset: str, task_names: Sequence[str]) -> dict[str, Any]:
    """The ``sim`` block: env id and version of each task, library versions, fingerprint.

    Tasks without an env get ``None`` as id.
    """
    import gymnasium as gym

    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.version import __version__

    env_ids: dict[str, str | None] = {}
    for name in task_names:
        try:
            env_ids[name] = env_id_for(dataset, name)
        except KeyError:
            env_ids[name] = None
    versions = {}
    for env_id in sorted({e for e in env_ids.values() if e}):
        spec = gym.spec(env_id)
        versions[env_id] = spec.version
    return {
        "env_ids": env_ids,
        "env_versions": versions,
        "clfd_bench": __version__,
        "mujoco": _version("mujoco"),
        "mink": _version("mink"),
        "gymnasium": _version("gymnasium"),
        "fingerprint": sim_fingerprint(),
    }
