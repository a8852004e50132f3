"""Execution-based evaluation: predicted trajectories run on the simulated Panda.

:mod:`clfd_bench.evaluation.sim_eval` holds

* ``execute_predictions``: one task's predictions executed in its env;
* ``evaluate_run``: a saved run re-scored by execution (``clfd-bench evaluate``);
* ``execute_after_task`` and ``sim_fields``: the training protocol's hook and the
  ``success`` / ``sim_accuracy`` / ``sim_cl_metrics`` entries of ``results.json``.
"""

from clfd_bench.evaluation.sim_eval import (
    ExecResult,
    evaluate_run,
    execute_after_task,
    execute_predictions,
    sim_fields,
)

__all__ = [
    "ExecResult",
    "evaluate_run",
    "execute_after_task",
    "execute_predictions",
    "sim_fields",
]
