"""clfd-bench: a simulation benchmark for continual learning from demonstration.

Importing the package registers the Gymnasium environments (namespace ``clfd``), so
``gymnasium.make("clfd/PlateStacking-v2")`` works after ``import clfd_bench``. Registration
uses string entry points: nothing heavy (MuJoCo, torch) is imported until an env is made.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]


def _register_envs() -> None:
    try:
        from clfd_bench.envs.registration import register_envs
    except ModuleNotFoundError as exc:  # pragma: no cover - only in a broken install
        if exc.name and exc.name.startswith("clfd_bench"):
            raise
        raise ModuleNotFoundError(
            f"clfd_bench needs {exc.name!r} to register its environments; "
            "reinstall with `pip install clfd-bench`"
        ) from exc
    register_envs()


_register_envs()
