"""Re-executes saved runs and keeps every writing rollout's checks and ink.

    python eval/writing_checks.py RUN_DIR [RUN_DIR ...] --out DIR

Each run is scored by `clfd_bench.execution.evaluate.evaluate_run`, the function behind
`clfd-bench evaluate RUN_DIR` (so `results.json` and `sim_cache.json` are updated exactly as
that command updates them), with an observer that also writes, per run,

- `DIR/<method>_<run>.json`: one record per evaluation point {after_task, task, demo, success,
  failure_reason, checks (the env's `info["checks"]`)};
- `DIR/<method>_<run>_ink.npz`: the ink of each point, `a<after_task>_t<task>_d<demo>` ->
  [K, 2] pen tip points on the board (m).

With an observer every point is executed to its horizon (no stop on a decided failure), so a
rollout's checks are all measured. Used for docs/execution.md (writing: the end-point bound,
before and after, and the verdicts nearest it).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.execution.evaluate import evaluate_run
from clfd_bench.io import atomic_write_text


class ChecksCollector:
    """A `RolloutObserver` that keeps each point's success, checks and ink."""

    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []
        self.ink: dict[str, np.ndarray] = {}
        self._ink_of: dict[int, np.ndarray] = {}  # id(ExecResult) -> its ink

    def log_rollout(self, entity: str, base: Any, result: Any, prediction: np.ndarray,
                    demonstration: np.ndarray | None = None) -> None:
        after, task, demo = entity.split("/")
        # The env is reused: its ink is this rollout's only when the result is first seen.
        if id(result) not in self._ink_of:
            self._ink_of[id(result)] = np.asarray(base.ink_trace(), dtype=float)
        i, d = int(after.removeprefix("after_task_")), int(demo.removeprefix("demo_"))
        self.ink[f"a{i}_t{task}_d{d}"] = self._ink_of[id(result)]
        self.records.append({"after_task": i, "task": task, "demo": d,
                             "success": bool(result.success),
                             "failure_reason": result.failure_reason,
                             "checks": result.info.get("checks")})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for run_dir in args.run_dirs:
        collector = ChecksCollector()
        fields = evaluate_run(run_dir, observer=collector)
        stem = f"{run_dir.parent.name}_{run_dir.name}"
        atomic_write_text(args.out / f"{stem}.json", json.dumps(collector.records, indent=None))
        np.savez_compressed(args.out / f"{stem}_ink.npz", **collector.ink)
        print(f"{run_dir}: exec ACC {fields['sim_cl_metrics'].get('ACC')}, "
              f"{len(collector.records)} points -> {args.out / stem}.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
