"""``clfd-bench data``: list datasets, their tasks, demo counts and where they were loaded from."""

from __future__ import annotations

import argparse
import json
from typing import Any

__all__ = ["register", "summarise"]


def summarise(names: list[str] | None = None, order: int = 0) -> list[dict[str, Any]]:
    """One dict per dataset: name, order, tasks (name, demos, steps, dim, units), source.

    A dataset that cannot be loaded gets ``"error"`` instead of its tasks.
    """
    from clfd_bench.data import DATASETS, load_dataset

    rows = []
    for name in names or list(DATASETS):
        info = DATASETS[name] if name in DATASETS else None
        row: dict[str, Any] = {"name": name}
        try:
            ds = load_dataset(name, order=min(order, (info.num_orders - 1) if info else 0))
        except Exception as exc:  # reported per dataset, so one bad dataset hides nothing
            row["error"] = f"{type(exc).__name__}: {exc}"
            rows.append(row)
            continue
        row.update(
            description=info.description if info else "",
            order=ds.order,
            num_orders=info.num_orders if info else 1,
            num_tasks=len(ds),
            source=ds.source,
            tasks=[
                {
                    "name": t.name,
                    "num_demos": t.num_demos,
                    "num_steps": t.num_steps,
                    "dim": t.dim,
                    "units": t.units,
                    "duration_s": round(float(t.times[-1]), 4),
                    "sha256": t.sha256,
                }
                for t in ds
            ],
        )
        rows.append(row)
    return rows


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.cli.common import unknown_dataset

    names = args.datasets or None
    if unknown_dataset("data", names or []):
        return 2
    rows = summarise(names, args.order)
    if not args.json:
        from clfd_bench.settings import setting_sources

        for key, (value, where) in setting_sources().items():
            print(f"{key}: {value} ({where})" if value else f"{key}: not set")
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        for row in rows:
            if "error" in row:
                print(f"{row['name']}: NOT AVAILABLE: {row['error']}")
                continue
            first = row["tasks"][0]
            print(
                f"{row['name']} (order {row['order']}): {row['num_tasks']} tasks x "
                f"{first['num_demos']} demos x {first['num_steps']} x {first['dim']} "
                f"[{first['units']}]  from {row['source']}"
            )
            print("  " + ", ".join(t["name"] for t in row["tasks"]))
    return 1 if any("error" in r for r in rows) else 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``data`` subcommand."""
    p = subparsers.add_parser(
        "data",
        help="list datasets, tasks, demo counts and where they were loaded from",
        description="List datasets, their tasks in a task order, demo counts and sources. "
        "Set CLFD_DATA_DIR to read a local copy instead of downloading.",
    )
    p.add_argument("datasets", nargs="*", help="datasets to show (default: all)")
    p.add_argument("--order", type=int, default=0, help="task order 0, 1 or 2 (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_run)
