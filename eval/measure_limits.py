"""Re-runs the measurement behind the executability bounds of `clfd_bench.sim.limits`.

    python eval/measure_limits.py [--envs clfd/Pouring-v3 ...] [--json FILE]
    python eval/measure_limits.py --load FILE      # the table of a saved measurement

Every demo of every env (RoboTasks, HelloWorld letters, LASA shapes), as recorded, 2× slower
and 1.5× faster, is replayed with every bound infinite; the script prints the measured worst
values (tracking error, robot-scene contact force, raw and filtered command peaks over the
cutoff grids) next to the constants of `clfd_bench.sim.limits` and exits 1 when the full
measurement does not reproduce them (relative tolerance 2 %; cutoffs exactly). The procedure is
`clfd_bench.execution.limit_calibration` (what it derives: `limit_derivation`). ~20 min on 2
cores; a tqdm bar shows the progress unless CLFD_NO_PROGRESS=1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from clfd_bench.execution.limit_calibration import FAMILIES, measure
from clfd_bench.execution.limit_derivation import RTOL, Calibration, Extreme, compare
from clfd_bench.io import atomic_write_json


def _fmt(v: object) -> str:
    if v is None:
        return "None (raw)"
    if isinstance(v, float):
        return f"{v:.5g}" if math.isfinite(v) else str(v)
    return str(v)


def _extreme_row(name: str, e: Extreme, unit: str) -> str:
    ratio = f"{e.ratio:.3f} × limit" if math.isfinite(e.ratio) else ""
    where = e.where + (f" step {e.step}" if e.step is not None and e.env_id else "")
    return f"  {name:<34} {e.value:>10.4g} {unit:<4} {ratio:<15} {e.quantity:<28} {where}"


def format_report(cal: Calibration, rtol: float = RTOL) -> str:
    """The measured worst values and the comparison with the constants, as text."""
    d = cal.derive()
    out = [f"{d.n_rollouts} rollouts ({d.n_successes} successful), "
           f"{cal.wall_s / 60:.1f} min", ""]
    out.append("Measured worst values (value, ratio to its limit or bound, quantity, where):")
    for fam, (p, r) in d.tracking_by_family.items():
        out.append(_extreme_row(f"tracking position [{fam}]", p, "m"))
        out.append(_extreme_row(f"tracking rotation [{fam}]", r, "rad"))
    out.append(_extreme_row("robot-scene contact force", d.collision_force_measured, "N"))
    for e in d.translation_raw:
        out.append(_extreme_row(f"raw {e.quantity}", e, ""))
    for e in d.rotation_raw:
        out.append(_extreme_row(f"raw {e.quantity}", e, ""))
    for e in d.joint_raw:
        out.append(_extreme_row(f"raw joint {e.quantity.split()[-1]}", e, ""))
    for f, e in zip(d.rotation_grid, d.rotation_worst, strict=True):
        mark = "  <- chosen" if f == d.rotation_filter_hz else ""
        out.append(_extreme_row(f"rotation filtered at {f:g} Hz", e, "") + mark)
    for f, e in zip(d.joint_grid, d.joint_worst, strict=True):
        mark = "  <- chosen" if f == d.joint_filter_hz else ""
        out.append(_extreme_row(f"joints filtered at {f:g} Hz", e, "") + mark)
    out.append(_extreme_row("reach from the shoulder", d.peak_reach, "m"))
    out.append(_extreme_row("lowest command above the floor", d.floor_clearance, "m"))
    if d.failures:
        out.append("Failed rollouts: " + "; ".join(d.failures))
    out += ["", f"Derived vs clfd_bench.sim.limits (relative tolerance {rtol:.0%}):"]
    out.append(f"  {'constant':<28} {'measured':>12} {'constant':>12}  {'':<6} where / note")
    for c in compare(d, rtol):
        out.append(f"  {c.name:<28} {_fmt(c.measured):>12} {_fmt(c.constant):>12}  "
                   f"{'ok' if c.ok else 'DIFFER':<6} {c.where}{' — ' if c.where else ''}{c.note}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=None, metavar="ID",
                        help="a subset of env ids (e.g. clfd/HelloWorld-l-v3); the comparison "
                             "then only informs (exit 0)")
    parser.add_argument("--demos", nargs="+", type=int, default=None, metavar="J",
                        help="a subset of demo indices (quick runs; exit 0)")
    parser.add_argument("--families", nargs="+", default=list(FAMILIES),
                        help=f"replay families (default {' '.join(FAMILIES)})")
    parser.add_argument("--json", default=None, metavar="FILE",
                        help="write every rollout's measurements to FILE")
    parser.add_argument("--load", default=None, metavar="FILE",
                        help="report a measurement saved with --json instead of measuring")
    parser.add_argument("--rtol", type=float, default=RTOL,
                        help=f"relative tolerance of the comparison (default {RTOL})")
    args = parser.parse_args(argv)

    full = args.envs is None and args.demos is None and tuple(args.families) == FAMILIES
    if args.load:
        with open(args.load, encoding="utf-8") as fh:
            data = json.load(fh)
        cal = Calibration.from_json(data)
        full = bool(data.get("full", False))
    else:
        t0 = time.perf_counter()
        cal = measure(args.envs, families=tuple(args.families), demos=args.demos,
                      progress=True)
        cal.wall_s = time.perf_counter() - t0
        if args.json:
            atomic_write_json(args.json, {"full": full, **cal.to_json()})
            print(f"wrote {args.json}")
    print(format_report(cal, args.rtol))
    bad = [c.name for c in compare(cal, args.rtol) if not c.ok]
    if not full:
        print("\n(a subset: the constants come from the full measurement; not judged)")
        return 0
    if bad:
        print(f"\nThe measurement does NOT reproduce clfd_bench.sim.limits: {', '.join(bad)}")
        return 1
    print("\nThe measurement reproduces clfd_bench.sim.limits.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
