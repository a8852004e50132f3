"""The harness: configs, the one training loop, the sequential protocol, results, checkpoints.

* :mod:`~clfd_bench.harness.config` -- :func:`resolve_config`: a :class:`RunConfig` from
  ``baselines/<method>.toml`` and ``--set`` overrides.
* :mod:`~clfd_bench.harness.run_config` -- :class:`RunConfig` and its run-level values.
* :mod:`~clfd_bench.harness.baselines` -- finding and reading the hyperparameter files.
* :mod:`~clfd_bench.harness.loop` -- :func:`train_task`, the only training loop.
* :mod:`~clfd_bench.harness.learner` -- data <-> NODE space (normalisation, tangent map).
* :mod:`~clfd_bench.harness.protocol` -- :func:`run_training`, the sequential protocol.
* :mod:`~clfd_bench.harness.run` -- ``run``: one run from start to end (train or take
  predictions made elsewhere, execute in simulation, score), what ``clfd-bench train``, the
  grid's workers and ``clfd-bench score`` call.
* :mod:`~clfd_bench.harness.worker` -- a grid's worker process (``python -m``).
* :mod:`~clfd_bench.harness.predict` -- :func:`predict` from a run directory.
* :mod:`~clfd_bench.harness.external` -- :func:`score_predictions` made elsewhere.
* :mod:`~clfd_bench.harness.external_format` -- reading and checking predictions made
  elsewhere (their format).

Names are imported lazily so that importing one module does not pull in the others.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "ConfigError",
    "Learner",
    "RunConfig",
    "RunMismatchError",
    "load_learner",
    "predict",
    "resolve_config",
    "run_training",
    "score_predictions",
    "train_task",
]

_WHERE = {
    "ConfigError": "config",
    "RunConfig": "run_config",
    "resolve_config": "config",
    "train_task": "loop",
    "Learner": "learner",
    "RunMismatchError": "protocol",
    "load_learner": "protocol",
    "run_training": "protocol",
    "predict": "predict",
    "score_predictions": "external",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(f"clfd_bench.harness.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'clfd_bench.harness' has no attribute {name!r}")
