"""A learned letter that runs on past its end, beside the `overrun` family that must fail.

    python eval/writing_overrun.py RUN_DIR --task w [--after K] [--demo J] \
        [--figure docs/figures/writing_overrun.png]
    python eval/writing_overrun.py --what-if RESULTS_DIR [RESULTS_DIR ...]

Executes, on the task's writing env and against demo J: the demo itself, the prediction the
run made for the task after learning task K (default: its last), and the `overrun` family of
demo J (`clfd_bench.execution.perturb`: the demo, then on past its end by the drift's
distance). Prints each one's end-point value against its bound and every failed check, and
draws the three side by side (ink against target, the end bound as a circle). It is the
picture docs/execution.md ("Running on past the end") shows for HN `full` seed 1's 'w'.

`--what-if` measures what forgiving a run-on would change. For every learned execution of the
writing runs under the folders (the runs' execution caches, as `clfd-bench gallery` reads
them) that fails the end check, it executes the prediction again and measures the closest the
ink comes to the end point after the ink has covered the target as the coverage check counts
it (`min_coverage` of its arc length within `coverage_radius`). Where that is within the end
bound the ink reached the end and ran on; elsewhere it stopped short. Prints, per profile and
method, the executions failing the end check, those failing it alone, and how many of each
ran on. A rule that forgave running on would turn the ones failing the end check alone that
ran on into successes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def reached_end(ink: np.ndarray, target: np.ndarray, goal: np.ndarray, coverage_radius: float,
                min_coverage: float) -> float:
    """The closest `ink` [K, 2] comes to `goal` [2] from the step at which it has covered
    `min_coverage` of `target` [T, 2]'s arc length within `coverage_radius` (data units; the
    last ink point's distance when it never does)."""
    near = np.linalg.norm(ink[:, None, :] - target[None, :, :], axis=2) <= coverage_radius
    first = np.where(near.any(axis=0), near.argmax(axis=0), len(ink))  # first ink step near
    seg = np.linalg.norm(np.diff(target, axis=0), axis=1)
    covered_at = np.maximum(first[1:], first[:-1])  # a segment counts once both ends are near
    order = np.argsort(covered_at, kind="stable")
    share = np.cumsum(seg[order]) / seg.sum()
    k = int(np.searchsorted(share, min_coverage - 1e-12))
    start = len(ink) - 1
    if k < len(share) and covered_at[order][k] < len(ink):
        start = int(covered_at[order][k])
    return float(np.linalg.norm(ink[start:] - goal, axis=1).min())


def what_if(roots: list[str]) -> int:
    """Prints the `--what-if` table for the runs under `roots`."""
    from collections import Counter

    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.execution.final_checks import gather_executions
    from clfd_bench.runs import RunDir, find_runs
    from clfd_bench.viz.gallery import execute_writing

    dirs = [r.path for root in roots for r in find_runs(root)]
    if not dirs:
        print(f"error: no run under {roots}", file=sys.stderr)
        return 2
    gathered = gather_executions(dirs)
    counts: Counter = Counter()
    seen: set[str] = set()
    held: dict[tuple[str, int], dict] = {}
    for ex in gathered.executions:
        goal = ex.check("goal")
        if ex.key in seen or not ex.complete or goal is None or goal.passed \
                or goal.value is None:
            continue
        seen.add(ex.key)
        lab = ex.label
        key = (str(lab["run"]), int(lab["after_task"]))
        if key not in held:
            held = {key: RunDir(key[0]).load_predictions(key[1])}
        env = get_env(str(lab["env_id"]))
        tol = env.unwrapped.tolerances
        d = execute_writing(env, held[key][int(lab["task_index"])][int(lab["demo"])],
                            int(lab["demo"]))
        ran_on = reached_end(d["ink"], d["target"], d["goal"], tol.coverage_radius,
                             tol.min_coverage) <= tol.goal_tolerance
        alone = [c.name for c in ex.checks if not c.passed] == ["goal"]
        profile = Path(str(lab["run"])).name.split("_")[0]
        row = (str(lab["dataset"]), profile, str(lab["method"]))
        counts[row + ("fail",)] += 1
        counts[row + ("ran_on",)] += ran_on
        counts[row + ("alone",)] += alone
        counts[row + ("alone_ran_on",)] += alone and ran_on
    print("| dataset | profile | method | fail the end check | of them ran on | fail it alone "
          "| of them ran on (a forgiving rule passes these) |")
    print("|---|---|---|---|---|---|---|")
    for row in sorted({k[:3] for k in counts}):
        c = [counts[row + (k,)] for k in ("fail", "ran_on", "alone", "alone_ran_on")]
        print("| " + " | ".join(row) + " | " + " | ".join(map(str, c)) + " |")
    print(f"(distinct executions; {len(gathered.runs)} runs; skipped: {gathered.skipped or 0})")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", nargs="?", help="a run directory (runs/<dataset>/<method>/<run>)")
    p.add_argument("--task", help="the task (letter or shape) to draw")
    p.add_argument("--after", type=int, default=None,
                   help="the run's predictions after learning this task (default: its last)")
    p.add_argument("--demo", type=int, default=0, help="demo j (default 0)")
    p.add_argument("--figure", default=None, help="write the picture here (PNG)")
    p.add_argument("--what-if", nargs="+", metavar="RESULTS_DIR", default=None,
                   help="instead: per method, the executions failing the end check that "
                   "reached the end and ran on, in the runs under these folders")
    args = p.parse_args(argv)
    if args.what_if is not None:
        if args.run or args.task:
            p.error("--what-if takes results folders only, no RUN_DIR or --task")
        return what_if(args.what_if)
    if not args.run or not args.task:
        p.error("RUN_DIR and --task are required (or --what-if RESULTS_DIR ...)")

    import clfd_bench  # noqa: F401 - registers the envs
    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.execution.perturb import PerturbContext, perturb
    from clfd_bench.execution.saved_run import load_run, load_run_predictions
    from clfd_bench.viz.gallery import draw_writing, execute_writing

    run = load_run(args.run)
    if args.task not in run.task_names:
        print(f"error: the run has no task {args.task!r}; its tasks: {run.task_names}",
              file=sys.stderr)
        return 2
    after = run.num_learned - 1 if args.after is None else args.after
    if not 0 <= after < run.num_learned:
        print(f"error: --after must lie in 0..{run.num_learned - 1} (tasks learned)",
              file=sys.stderr)
        return 2
    index = run.task_names.index(args.task)
    predictions = load_run_predictions(args.run, after)
    if index not in predictions:
        print(f"error: no prediction of {args.task!r} after task {after} (not learned yet)",
              file=sys.stderr)
        return 2
    env_id = env_id_for(run.dataset, args.task)
    env = get_env(env_id)
    base = env.unwrapped
    demo = np.asarray(base.demos[args.demo], float)
    units = 1.0 / float(base.sim_scale) if run.dataset == "lasa" else 1.0
    variants = [
        ("demo", demo),
        (f"{run.method} after task {after}", np.asarray(predictions[index][args.demo], float)),
        ("overrun (must fail)", perturb("overrun", demo, PerturbContext(args.demo, units))),
    ]
    drawn = []
    print(f"{env_id}, demo {args.demo}:")
    for name, traj in variants:
        d = execute_writing(env, traj, args.demo)
        goal = next(c for c in d["checks"] if c.name == "goal")
        failed = [c.name for c in d["checks"] if not c.passed]
        print(f"  {name}: end point {goal.value:.4f} m against {goal.bound:.4f} m "
              f"({goal.value / goal.bound:.2f}x the bound); failed: {failed or 'none'}")
        drawn.append((name, d, goal, failed))
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 3, figsize=(15, 5.4), dpi=100)
        for ax, (name, d, goal, failed) in zip(axes, drawn, strict=True):
            draw_writing(ax, d, goal)
            verdict = "succeeds" if not failed else "fails: " + ", ".join(failed)
            ax.set_title(f"{name}\nend {100 * goal.value:.2f} cm, bound "
                         f"{100 * goal.bound:.2f} cm: {verdict}", fontsize=10,
                         color="#1e9e46" if not failed else "#d62728")
        fig.suptitle(f"{env_id}, demo {args.demo}: the end point is where the pen stops, "
                     "short of the letter's end or past it", fontsize=11)
        fig.tight_layout()
        Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.figure)
        plt.close(fig)
        print(f"wrote {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
