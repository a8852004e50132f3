"""clfd-bench: a simulation benchmark for continual learning from demonstration.

Importing the package registers the Gymnasium environments (namespace ``clfd``), so
``gymnasium.make("clfd/PlateStacking-v3")`` works after ``import clfd_bench``. Registration
uses string entry points: nothing heavy (MuJoCo, torch) is imported until an env is made.

Importing it also applies the installation's settings file (:mod:`clfd_bench.settings`):
``CLFD_DATA_DIR`` and ``MENAGERIE_ROOT`` are found without exports; and on a Linux machine
without a display it sets ``MUJOCO_GL=egl`` where unset (:mod:`clfd_bench.headless`), so
videos render offscreen.

``clfd_bench.score_predictions(...)`` scores predictions made elsewhere into a run directory
(:func:`clfd_bench.harness.external.score_predictions`, imported on first use).
"""

from __future__ import annotations

from typing import Any

from clfd_bench.headless import default_gl_backend
from clfd_bench.kernels import pin_thread_invariant_kernels
from clfd_bench.settings import apply_settings
from clfd_bench.version import __version__

# Before any torch computation: MKL's results independent of the thread count (kernels.py).
pin_thread_invariant_kernels()
# CLFD_DATA_DIR and MENAGERIE_ROOT from the venv's settings file where not exported
# (settings.py; `bash run.sh setup` writes it).
apply_settings()
# Before anything imports MuJoCo: EGL where no display is and MUJOCO_GL is unset (headless.py).
default_gl_backend()

__all__ = ["__version__", "score_predictions"]


def __getattr__(name: str) -> Any:
    if name == "score_predictions":
        from clfd_bench.harness.external import score_predictions

        return score_predictions
    raise AttributeError(f"module 'clfd_bench' has no attribute {name!r}")


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
