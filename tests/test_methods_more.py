"""Online EWC, A-GEM and PackNet (clfd_bench/methods/{ewc,agem,packnet}.py): each method's core
step checked by hand on a tiny case, then what each does on HelloWorld against FT, and a
PackNet run killed with SIGKILL mid-task and resumed to the same results.

* EWC: the Fisher of a one-hidden-layer field integrated with one Euler step is the mean of
  squared per-demo gradients written out by hand (numpy backprop); the online update
  ``F <- gamma F + F_task`` and the penalty ``lambda/2 sum F (w - w*)^2``.
* A-GEM: the projection of hand-picked gradients (kept when ``g . g_ref >= 0``, projected
  onto the plane orthogonal to ``g_ref`` when negative), and the same through the method's
  ``before_step`` with the reference gradient of its memory.
* PackNet: how many weights each task owns after pruning, earlier tasks' weights and
  predictions bit-identical after a later task is trained.

On HelloWorld's first three letters (fast profile, 150 iterations per letter to fit the time):
A-GEM and PackNet end closer to letters 0-1 than FT (PackNet: bit-identical predictions);
EWC does not, for the reason its test states, and the test checks what it does instead.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest
import torch
from run_checks import cli, comparable, finish, kill_when

from clfd_bench.harness.config import PartConfig, resolve_config
from clfd_bench.harness.loop import train_task
from clfd_bench.learning.node import NodeSpec
from clfd_bench.learning.objective import batch_spec, trajectory_loss
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.methods import BUILTIN, StepContext, TaskData, get_method_class, list_methods
from clfd_bench.methods.agem import AveragedGEM, project_gradient
from clfd_bench.methods.ewc import OnlineEWC
from clfd_bench.methods.packnet import FREE, PackNet, prune_smallest
from clfd_bench.methods.registry import PAPER_METHODS

torch.set_num_threads(1)

SHARED = Path(__file__).resolve().parents[2] / "shared" / "datasets"


# ------------------------------------------------------------------------------ registry
def test_registered_after_the_papers_seven():
    assert list(BUILTIN)[:7] == list(PAPER_METHODS)
    assert list_methods()[7:10] == ["ewc", "agem", "packnet"]
    assert get_method_class("ewc") is OnlineEWC
    assert get_method_class("agem") is AveragedGEM
    assert get_method_class("packnet") is PackNet
    for name in ("ewc", "agem", "packnet"):
        cls = BUILTIN[name]
        assert cls.own_hyperparameters and cls.__module__.endswith(name)
        for profile in ("paper", "fast", "smoke"):
            for dataset in ("lasa", "helloworld", "robotasks"):
                cfg = resolve_config(name, dataset, profile)
                for kind, part in cfg.parts:  # only the method's own keys differ from FT's
                    ft = resolve_config("ft", dataset, profile).part(kind)
                    assert dataclasses.replace(part, extras=()) == ft
                    assert {k for k, _v in part.extras} == set(cls.own_hyperparameters)


# ----------------------------------------------------------------------------------- EWC
# One hidden layer of 2 ELU units, a 1-D state, a 1-D embedding; batches are the whole
# 2-sample trajectories (one Euler step of h = 0.5), so a demo's loss is r^2 / 2 with
# r = y0 + h f(e, y0, 0) - y1 (the MSE over its 2 samples, the first exact).
TINY = NodeSpec(dim=1, hidden=(2,), time_input=True)
H = 0.5


def _tiny_cfg(**extras) -> PartConfig:
    return PartConfig(iterations=3, lr=1e-2, node_hidden=(2,), task_emb_dim=1,
                      batch="trajectories", points=2, solver="euler", extras=extras)


def _hand_gradients(weights, e: float, y0: float, y1: float) -> list[np.ndarray]:
    """d(r^2 / 2)/d[W0, b0, W1, b1] by hand (float64)."""
    w0, b0, w1, b1 = (np.asarray(w.detach(), dtype=np.float64) for w in weights)
    x = np.array([e, y0, 0.0])  # [embedding, y, t]
    a = w0 @ x + b0  # [2]
    z = np.where(a > 0, a, np.expm1(a))  # elu
    f = w1 @ z + b1  # [1]
    r = y0 + H * f[0] - y1
    g_f = r * H  # d loss / d f
    d_z = w1[0] * g_f
    d_a = d_z * np.where(a > 0, 1.0, np.exp(a))
    return [np.outer(d_a, x), d_a, g_f * z[None, :], np.array([g_f])]


def _hand_fisher(method: OnlineEWC, task: int, demos: torch.Tensor) -> list[np.ndarray]:
    e = float(method.embeddings[task].detach()[0])
    grads = [_hand_gradients(method.weights, e, float(d[0, 0]), float(d[1, 0])) for d in demos]
    return [np.mean([g[i] ** 2 for g in grads], axis=0) for i in range(4)]


def _tiny_data(seed: int) -> TaskData:
    g = torch.Generator().manual_seed(seed)
    return TaskData(torch.randn(3, 2, 1, generator=g), torch.tensor([0.0, H]))


def test_ewc_fisher_is_the_mean_of_squared_per_demo_gradients_and_updates_online():
    torch.manual_seed(1)
    method = OnlineEWC(TINY, _tiny_cfg(ewc_lambda=2.0, ewc_gamma=0.5, ewc_batches=1))
    method.add_task()
    data0 = _tiny_data(0)
    f0 = _hand_fisher(method, 0, data0.demos)
    assert all(float(np.abs(f).sum()) > 0 for f in f0)
    for got, want in zip(method.task_fisher(0, data0), f0, strict=True):
        np.testing.assert_allclose(got.numpy(), want, rtol=1e-5, atol=1e-9)
    method.on_task_end(0, data0)
    anchor = [w.detach().clone() for w in method.weights]

    method.add_task()
    with torch.no_grad():  # as if task 1 had moved the weights
        for w in method.weights:
            w.add_(0.1 * torch.randn_like(w))
    data1 = _tiny_data(1)
    f1 = _hand_fisher(method, 1, data1.demos)
    opt = torch.optim.Adam(method.trainable(1))
    ctx = StepContext(task=1, iteration=0, optimizer=opt, generator=torch.Generator())
    penalty = sum(float((torch.as_tensor(f) * (w.detach().double() - a.double()) ** 2).sum())
                  for f, w, a in zip(f0, method.weights, anchor, strict=True))
    assert float(method.extra_loss(ctx).detach()) == pytest.approx(0.5 * 2.0 * penalty, rel=1e-5)
    assert method.extra_loss(dataclasses.replace(ctx, task=0)) is None

    method.on_task_end(1, data1)  # F <- 0.5 F0 + F1, anchor <- the moved weights
    for i in range(4):
        np.testing.assert_allclose(getattr(method, f"fisher_{i}").numpy(),
                                   0.5 * f0[i] + f1[i], rtol=1e-5, atol=1e-9)
        assert torch.equal(getattr(method, f"anchor_{i}"), method.weights[i].detach())
    node = sum(w.numel() for w in method.weights)
    assert method.num_params() == 3 * node + 2 * TINY.dim  # NODE + Fisher + anchor + 2 embs


# --------------------------------------------------------------------------------- A-GEM
def test_agem_projection_by_hand():
    g_ref = [torch.tensor([-1.0, 1.0])]
    kept, changed = project_gradient([torch.tensor([1.0, 2.0])], g_ref)  # dot = 1 >= 0
    assert not changed and torch.equal(kept[0], torch.tensor([1.0, 2.0]))
    kept, changed = project_gradient([torch.tensor([1.0, 1.0])], g_ref)  # dot = 0
    assert not changed and torch.equal(kept[0], torch.tensor([1.0, 1.0]))
    # dot = -1: g - (-1 / 2) g_ref = (1, 0) + 0.5 (-1, 1) = (0.5, 0.5), orthogonal to g_ref
    out, changed = project_gradient([torch.tensor([1.0, 0.0])], g_ref)
    assert changed and torch.equal(out[0], torch.tensor([0.5, 0.5]))
    assert float(out[0] @ g_ref[0]) == 0.0
    # split over two tensors (two parameters): the same vector maths
    g = [torch.tensor([3.0, -1.0]), torch.tensor([[2.0]])]
    ref = [torch.tensor([-1.0, 0.0]), torch.tensor([[-1.0]])]  # dot = -5, |ref|^2 = 2
    out, changed = project_gradient(g, ref)
    assert changed
    assert torch.allclose(out[0], torch.tensor([0.5, -1.0])) and torch.allclose(
        out[1], torch.tensor([[-0.5]]))
    assert abs(sum(float((a * b).sum()) for a, b in zip(out, ref, strict=True))) < 1e-6


SMALL = NodeSpec(dim=2, hidden=(8, 8), time_input=True)


def _small_cfg(**extras) -> PartConfig:
    return PartConfig(iterations=8, lr=1e-2, node_hidden=(8, 8), task_emb_dim=3,
                      batch="trajectories", points=8, solver="rk4", extras=extras)


def _small_data(seed: int) -> TaskData:
    g = torch.Generator().manual_seed(seed)
    demos = torch.cumsum(torch.randn(3, 30, 2, generator=g) * 0.1, dim=1)
    return TaskData(demos, torch.linspace(0, 2, 30))


def _learn(method, task: int) -> TaskData:
    data = _small_data(task)
    method.add_task()
    train_task(method, task, data, method.cfg, torch.Generator().manual_seed(task))
    return data


def test_agem_before_step_projects_against_its_memory_gradient():
    torch.manual_seed(0)
    method = AveragedGEM(SMALL, _small_cfg(agem_memory=2, agem_ref_tasks=1))
    _learn(method, 0)
    assert method.stored_samples() == 2 * 30  # 2 of the 3 demos, every time step
    assert method.num_params() == sum(p.numel() for p in method.parameters())
    method.add_task()
    method.on_task_start(1, _small_data(1))
    params = method.trainable(1)
    # the reference gradient: memory of task 0, whole trajectories (no randomness)
    memory = method.memory(0)
    sampler = memory.sampler(batch_spec(method.cfg), method.cfg.iterations)
    t, y = sampler.sample(0, torch.Generator())
    g_ref = torch.autograd.grad(
        trajectory_loss(method.field(0), t, y, SolverSpec("rk4")), params, allow_unused=True)
    g_ref = [torch.zeros_like(p) if r is None else r for p, r in zip(params, g_ref, strict=True)]
    assert float(g_ref[-1].abs().sum()) == 0  # task 1's embedding: no memory gradient
    flat_ref = torch.cat([r.flatten() for r in g_ref])

    gen = torch.Generator().manual_seed(5)
    for sign in (1.0, -1.0):  # g along +g_ref (kept) or mostly against it (projected)
        noise = [torch.randn(p.shape, generator=gen) * 1e-3 for p in params]
        for p, r, n in zip(params, g_ref, noise, strict=True):
            p.grad = sign * r + n
        g = torch.cat([p.grad.flatten() for p in params])
        opt = torch.optim.Adam(params)
        method.before_step(StepContext(1, 0, opt, torch.Generator()))
        after = torch.cat([p.grad.flatten() for p in params])
        if sign > 0:
            assert torch.equal(after, g)
        else:
            dot = (g.double() @ flat_ref.double()) / (flat_ref.double() @ flat_ref.double())
            want = g.double() - dot * flat_ref.double()
            assert torch.allclose(after.double(), want, atol=1e-6)
            assert abs(float(after.double() @ flat_ref.double())) < 1e-6 * float(
                flat_ref.norm() * g.norm())
    assert method.projections == 1


# ------------------------------------------------------------------------------- PackNet
def test_prune_smallest_releases_the_smallest_magnitudes():
    weight = torch.tensor([[0.1, -3.0, 0.4], [2.0, -0.05, 1.0]])
    owner = torch.tensor([[0, 0, 1], [0, 0, 0]], dtype=torch.int16)
    assert prune_smallest(weight, owner, task=0, fraction=0.5) == 3  # floor(0.5 * 5 + 0.5)
    assert owner.tolist() == [[FREE, 0, 1], [0, FREE, FREE]]  # 0.1, -0.05, 1.0 released


def _owned_after(n_free: list[int], fraction: float) -> tuple[list[int], list[int]]:
    kept = [n - int(np.floor(fraction * n + 0.5)) for n in n_free]
    return kept, [n - k for n, k in zip(n_free, kept, strict=True)]


def test_packnet_masks_freeze_earlier_tasks_bit_for_bit():
    torch.manual_seed(0)
    method = PackNet(SMALL, _small_cfg(packnet_prune=0.6, packnet_retrain=0.25))
    sizes = [method.weights[i].numel() for i in method.matrices]
    _learn(method, 0)
    kept0, free0 = _owned_after(sizes, 0.6)
    assert [int((method.owner(i) == 0).sum()) for i in method.matrices] == kept0
    assert [int((method.owner(i) == FREE).sum()) for i in method.matrices] == free0
    for i in method.matrices:  # released weights are zero, free for the next task
        assert float(method.weights[i].detach()[method.owner(i) == FREE].abs().sum()) == 0.0
    before = [w.detach().clone() for w in method.weights]
    owners = [method.owner(i).clone() for i in method.matrices]
    y0, t = _small_data(0).demos[:, 0], torch.linspace(0, 2, 30)
    with torch.no_grad():
        pred0 = integrate(method.field(0), y0, t, SolverSpec("rk4"))

    _learn(method, 1)
    kept1, free1 = _owned_after(free0, 0.6)
    assert [int((method.owner(i) == 1).sum()) for i in method.matrices] == kept1
    assert [int((method.owner(i) == FREE).sum()) for i in method.matrices] == free1
    for k, i in enumerate(method.matrices):
        mine = owners[k] == 0
        assert torch.equal(method.owner(i)[mine], owners[k][mine])  # task 0 keeps its weights
        assert torch.equal(method.weights[i].detach()[mine], before[i][mine])  # untouched
        assert not torch.equal(method.weights[i].detach(), before[i])  # task 1 trained
    for i in range(1, len(method.weights), 2):
        assert torch.equal(method.weights[i].detach(), before[i])  # biases: task 0's
    with torch.no_grad():
        assert torch.equal(integrate(method.field(0), y0, t, SolverSpec("rk4")), pred0)
        assert not torch.equal(integrate(method.field(1), y0, t, SolverSpec("rk4")), pred0)
    n_weights = sum(sizes)
    assert method.num_params() == sum(p.numel() for p in method.parameters()) + n_weights


# ------------------------------------------------------------- behaviour on HelloWorld
BEHAVIOUR_ITERATIONS = 150  # the fast profile otherwise (400 in baselines/*.toml), to fit


@pytest.fixture(scope="module")
def helloworld_runs(tmp_path_factory):
    """FT and the three methods on HelloWorld's first three letters ('h', 'e', 'l'): fast
    profile with fewer iterations, seed 0, no simulation, checkpoints after every task."""
    if "CLFD_DATA_DIR" not in os.environ and SHARED.is_dir():
        os.environ["CLFD_DATA_DIR"] = str(SHARED)
    from clfd_bench.harness.protocol import run_training

    out = {}
    for method in ("ft", "ewc", "agem", "packnet"):
        cfg = resolve_config(method, "helloworld", "fast", seed=0, tasks=3,
                             overrides=[f"iterations={BEHAVIOUR_ITERATIONS}"])
        run_dir = tmp_path_factory.mktemp(method)
        out[method] = (run_training(cfg, run_dir, threads=1, log=None, keep_checkpoints=True),
                       run_dir)
    return out


def _dtw(results, after: int, letter: int) -> float:
    """Mean DTW (m) over the demos of ``letter`` after letter ``after`` is learned."""
    return float(np.mean(results["errors"]["dtw"][after][letter]))


def _final_error(results) -> float:
    """Mean DTW (m) of letters 0 and 1 after the third letter is learned."""
    return (_dtw(results, 2, 0) + _dtw(results, 2, 1)) / 2


def test_packnet_forgets_nothing_and_less_than_finetuning(helloworld_runs):
    from clfd_bench.runs import RunDir

    results, run_dir = helloworld_runs["packnet"]
    ft = helloworld_runs["ft"][0]
    assert _final_error(results) < 0.7 * _final_error(ft), (_final_error(results),
                                                            _final_error(ft))
    assert results["cl_metrics"]["REM"] == 1.0 > ft["cl_metrics"]["REM"]
    run = RunDir(run_dir)  # every letter's prediction is the one right after it was learned
    for j in (0, 1):
        for i in range(j + 1, 3):
            assert np.array_equal(run.load_predictions(i)[j], run.load_predictions(j)[j])


def test_agem_forgets_less_than_finetuning(helloworld_runs):
    results, ft = helloworld_runs["agem"][0], helloworld_runs["ft"][0]
    assert _final_error(results) < _final_error(ft), (_final_error(results), _final_error(ft))
    assert _dtw(results, 1, 0) < 0.5 * _dtw(ft, 1, 0)  # 'h' after 'e': FT forgets it
    assert results["cl_metrics"]["REM"] >= ft["cl_metrics"]["REM"]


def test_ewc_keeps_its_fisher_weighted_drift_small_but_not_the_older_letters(helloworld_runs):
    """EWC does not end closer to letters 0-1 than FT here; the reason (module docstring of
    clfd_bench/methods/ewc.py, numbers in baselines/ewc.toml): the penalty holds the weights
    the diagonal Fisher deems important (the last layer) and the new letter is learned by
    moving the others, which through the integration distorts the older letters as much as
    fine-tuning or more. What it does do: the weights move ~300x less than FT's in the
    Fisher's metric, and the letter just before the last one ('e', protected by the latest
    anchor) ends closer to its demos than under FT."""
    from clfd_bench.harness.checkpoint import decode_checkpoint

    def tensors(method: str, task: int) -> dict[str, torch.Tensor]:
        path = helloworld_runs[method][1] / "checkpoints" / f"after_task_{task}.pt"
        return decode_checkpoint(path.read_bytes())[1]

    ewc0, ewc1, ft0, ft1 = tensors("ewc", 0), tensors("ewc", 1), tensors("ft", 0), tensors("ft", 1)
    n = sum(1 for k in ewc0 if k.startswith("position/fisher_"))
    weights = [f"position/weights.{i}" for i in range(n)]
    assert all(torch.equal(ewc0[k], ft0[k]) for k in weights)  # the same first letter

    def drift(after: dict[str, torch.Tensor]) -> float:  # sum F_0 (theta_1 - theta*_0)^2
        return sum(float((ewc0[f"position/fisher_{i}"] * (after[k] - ewc0[k]) ** 2).sum())
                   for i, k in enumerate(weights))

    assert drift(ewc1) < 0.05 * drift(ft1), (drift(ewc1), drift(ft1))
    results, ft = helloworld_runs["ewc"][0], helloworld_runs["ft"][0]
    assert _dtw(results, 2, 1) < _dtw(ft, 2, 1), (_dtw(results, 2, 1), _dtw(ft, 2, 1))


def test_method_state_is_accounted(helloworld_runs):
    ft = helloworld_runs["ft"][0]
    ewc, agem, packnet = (helloworld_runs[m][0] for m in ("ewc", "agem", "packnet"))
    node = ft["num_params"][0] - 32  # the NODE without task 0's embedding
    assert ewc["num_params"] == [n + 2 * node for n in ft["num_params"]]  # Fisher + anchor
    assert agem["num_params"] == ft["num_params"] and ft["stored_samples"] == [0, 0, 0]
    memory = resolve_config("agem", "helloworld", "fast").part("position").extra("agem_memory")
    assert agem["stored_samples"] == [memory * 1000 * (i + 1) for i in range(3)]
    weights = 128 * 35 + 2 * 128 * 128 + 2 * 128  # W0, W1, W2, W3 of the 3 x 128 NODE
    assert packnet["num_params"] == [n + weights for n in ft["num_params"]]


# ----------------------------------------------------------------------- kill and resume
TRAIN = ["train", "--method", "packnet", "--dataset", "helloworld", "--profile", "smoke",
         "--tasks", "3", "--no-sim", "--quiet", "--set", "iterations=150"]
_TIMING = frozenset({"train_time_s", "train_time_s_by_part", "train_cpu_s",
                     "iterations_per_s_by_part", "TE", "CL_score", "CL_stability", "rank",
                     "wall_s"})


def _cli(*args: str):
    """The CLI, with the shared datasets when ``CLFD_DATA_DIR`` is not set."""
    if "CLFD_DATA_DIR" not in os.environ and SHARED.is_dir():
        return cli(*args, env={"CLFD_DATA_DIR": str(SHARED)})
    return cli(*args)


def _tensors(run_dir: Path) -> dict[str, torch.Tensor]:
    from clfd_bench.harness.checkpoint import decode_checkpoint
    from clfd_bench.runs import RunDir

    return decode_checkpoint(RunDir(run_dir).read_checkpoint())[1]


def test_packnet_killed_mid_task_resumes_to_identical_results(tmp_path):
    """SIGKILL while the second letter trains (0.2 s after task 0's files are written: here
    in the middle of task 1), resume: results, predictions and every tensor of the checkpoint
    (weights, embeddings, owner maps) equal an uninterrupted run's."""
    from clfd_bench.runs import RunDir

    ref_dir, run_dir = tmp_path / "reference", tmp_path / "killed"
    reference = _cli(*TRAIN, "--out", str(ref_dir))
    finish(reference, timeout=300)

    proc = _cli(*TRAIN, "--out", str(run_dir))
    run = RunDir(run_dir)

    def task_0_done() -> bool:
        try:
            return (run.read_results() or {}).get("tasks_done") == 1
        except ValueError:  # results.json being replaced
            return False

    # 0.2 s into task 1's iterations (1-2 s of them on a shared 2-core machine)
    kill_when(proc, task_0_done, timeout=300, then=0.2)
    assert json.loads((run_dir / "results.json").read_text())["tasks_done"] < 3

    resumed = _cli(*TRAIN, "--out", str(run_dir))
    finish(resumed, timeout=300)
    assert comparable(RunDir(run_dir).load_results(), _TIMING) == comparable(
        RunDir(ref_dir).load_results(), _TIMING)
    for i in range(3):
        for a, b in zip(RunDir(run_dir).load_predictions(i), RunDir(ref_dir).load_predictions(i),
                        strict=True):
            assert np.array_equal(a, b)
    got, want = _tensors(run_dir), _tensors(ref_dir)
    assert got.keys() == want.keys() and any(k.startswith("position/owner_") for k in got)
    assert all(torch.equal(got[k], want[k]) for k in got)
