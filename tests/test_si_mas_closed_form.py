"""SI's path integral and MAS's importance against closed forms computed by hand.

SI (``clfd_bench.methods.si``) is driven through its hooks in the order
:func:`clfd_bench.harness.loop.train_task` calls them in every iteration::

    zero_grad; task_loss.backward(); extra_loss(ctx).backward(); optimizer.step(); after_step()

so the gradient ``after_step`` reads from ``w.grad`` is the one the step used: evaluated at
the weights *before* the step, task loss *plus* penalty. The path integral of task ``l`` is
``omega_k = -sum_t g_k(t) (theta_k(t+1) - theta_k(t))``, the importance at its end
``Omega_k += omega_k / (Delta_k^2 + xi)`` with ``Delta_k`` the change over the task and ``xi``
= ``cfg.si_xi`` (no clamping of a negative ``omega``), the penalty
``c * sum_k Omega_k (theta_k - theta*_k)^2`` (no 1/2; gradient ``2 c Omega (theta - theta*)``).

MAS (``clfd_bench.methods.mas``): the importance of a task is, per weight, the mean over the
task's data points (per sample, then averaged) of ``|d ||f(t_n, y_n)||^2 / d theta|`` with
``f`` the task's vector field itself (no ODE integration); importances of successive tasks
add up, the anchor is the weights after the last task, the penalty is
``lambda * sum_k Omega_k (theta_k - theta*_k)^2``.

Everything runs in float64 with tight tolerances; the numbers are chosen non-symmetric (and
some guards assert that plausible wrong formulas would give a clearly different value).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from clfd_bench.harness.config import PartConfig
from clfd_bench.learning.mlp import split_flat
from clfd_bench.learning.node import NodeSpec
from clfd_bench.methods import StepContext, TaskData
from clfd_bench.methods import mas as mas_module
from clfd_bench.methods.mas import MemoryAwareSynapses, output_norm_importance
from clfd_bench.methods.si import SynapticIntelligence

torch.set_num_threads(1)

RTOL, ATOL = 1e-11, 1e-13


def _close(actual, expected, rtol: float = RTOL, atol: float = ATOL) -> None:
    actual = actual.detach().numpy() if isinstance(actual, torch.Tensor) else actual
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol)


def _flat(tensors) -> np.ndarray:
    return torch.cat([t.detach().reshape(-1) for t in tensors]).numpy()


def _buffers(method, kind: str) -> np.ndarray:
    return _flat(method.get_buffer(f"{kind}_{i}") for i in range(len(method.weights)))


def _set_weights(method, flat: np.ndarray) -> None:
    parts = split_flat(torch.from_numpy(flat), method.node_spec.param_shapes())
    with torch.no_grad():
        for w, p in zip(method.weights, parts, strict=True):
            w.copy_(p)


def _build(cls, spec: NodeSpec, cfg: PartConfig, theta0: np.ndarray, monkeypatch):
    """``cls(spec, cfg)`` whose NODE weights are initialised to ``theta0`` (float64), so the
    anchor the constructor records is ``theta0`` as well."""

    def init(shapes, generator=None, dtype=torch.float32):
        return [p.clone() for p in split_flat(torch.from_numpy(theta0.copy()), shapes)]

    monkeypatch.setattr("clfd_bench.learning.node.init_mlp_weights", init)
    method = cls(spec, cfg)
    assert all(w.dtype == torch.float64 for w in method.weights)
    return method


def _ctx(task: int, optimizer=None) -> StepContext:
    return StepContext(task=task, iteration=0, optimizer=optimizer,
                       generator=torch.Generator().manual_seed(0))


def _check_penalty(method, strength: float, theta: np.ndarray, importance: np.ndarray,
                   anchor: np.ndarray, task: int) -> None:
    """Penalty value and gradient at ``theta``: ``s sum Omega (theta - theta*)^2`` and
    ``2 s Omega (theta - theta*)``."""
    _set_weights(method, theta)
    extra = method.extra_loss(_ctx(task))
    expected = strength * np.sum(importance * (theta - anchor) ** 2)
    _close(extra, expected)
    grads = torch.autograd.grad(extra, list(method.weights))
    _close(_flat(grads), 2.0 * strength * importance * (theta - anchor))


# -- SI -----------------------------------------------------------------------------------

# NODE^T with 1 state dimension, one hidden unit and a 1-D embedding: W0 [1, 3] (embedding,
# y, t), b0 [1], W1 [1, 1], b1 [1] -- six scalar weights theta_0..theta_5 in this order.
SI_SPEC = NodeSpec(dim=1, hidden=(1,), time_input=True)
SI_SHAPES = [(1, 3), (1,), (1, 1), (1,)]  # the method adds cond_dim=1
SI_TASK = TaskData(torch.zeros(1, 2, 1), torch.tensor([0.0, 1.0]))  # SI ignores the data


def _si(monkeypatch, theta0: np.ndarray, xi: float, c: float = 0.4, merge: str = "per_task"):
    cfg = PartConfig(iterations=1, lr=0.1, node_hidden=(1,), task_emb_dim=1, si_c=c, si_xi=xi,
                     importance_merge=merge)
    method = _build(SynapticIntelligence, SI_SPEC, cfg, theta0, monkeypatch)
    assert method.node_spec.param_shapes() == SI_SHAPES
    method.add_task()
    return method.double()  # the new embedding too


def test_si_scripted_path_integral_by_hand(monkeypatch):
    """Three scripted steps with hand-picked gradients, some going against the motion so
    that terms of both signs appear; one weight ends where it started (Delta = 0) and one
    has a negative path integral (SI does not clamp it)."""
    theta0 = np.array([0.5, -1.0, 2.0, 0.0, 1.5, -0.5])
    moves = np.array([[0.5, 0.25, -1.0, 0.5, 0.0, 1.0],
                      [-0.25, 0.5, 0.5, -0.5, 0.5, 1.0],
                      [1.0, -0.25, 0.25, 0.0, -1.0, 0.5]])
    grads = np.array([[-2.0, 1.0, 3.0, 1.0, 4.0, -0.5],
                      [4.0, -2.0, 1.0, -2.0, -1.0, -1.0],
                      [-1.0, 2.0, -2.0, 0.5, 2.0, -3.0]])
    xi = 0.25
    method = _si(monkeypatch, theta0, xi)
    method.on_task_start(0, SI_TASK)

    theta = theta0.copy()
    for move, grad in zip(moves, grads, strict=True):
        # what the loop leaves behind: w.grad = gradient at the pre-step weights, w moved
        theta = theta + move
        _set_weights(method, theta)
        for w, g in zip(method.weights, split_flat(torch.from_numpy(grad), SI_SHAPES),
                        strict=True):
            w.grad = g.clone()
        method.after_step()

    # omega_k = -sum_t g_k(t) * move_k(t), worked out by hand:
    #   k=0: -[(-2)(.5) + 4(-.25) + (-1)(1)]    = 3       k=1: -[.25 - 1 - .5]     = 1.25
    #   k=2: -[(3)(-1) + (1)(.5) + (-2)(.25)]   = 3       k=3: -[.5 + 1 + 0]       = -1.5
    #   k=4: -[0 + (-1)(.5) + (2)(-1)]          = 2.5     k=5: -[-.5 - 1 - 1.5]    = 3
    omega = np.array([3.0, 1.25, 3.0, -1.5, 2.5, 3.0])
    _close(_buffers(method, "omega"), omega)
    _close(_buffers(method, "previous"), theta)
    np.testing.assert_array_equal(_buffers(method, "importance"), 0.0)  # only at the task end

    method.on_task_end(0, SI_TASK)
    # Delta = theta_3 - theta_0 = [1.25, .5, -.25, 0, -.5, 2.5]; Delta^2 + xi =
    # [1.8125, .5, .3125, .25, .5, 6.5]
    importance = np.array([3.0 / 1.8125, 2.5, 9.6, -6.0, 5.0, 3.0 / 6.5])
    _close(_buffers(method, "importance"), importance)
    _close(_buffers(method, "anchor"), theta)
    np.testing.assert_array_equal(_buffers(method, "omega"), 0.0)  # restarts for each task

    assert method.extra_loss(_ctx(0)) is None  # no penalty while learning the first task
    probe = np.array([1.0, 0.25, -0.5, 1.0, 2.0, 0.0])
    _check_penalty(method, 0.4, probe, importance, theta, task=1)


# Plain gradient descent (step eta) on L = 1/2 sum_k a_k (theta_k - c_k)^2: the gradient
# g(t) = a (theta(t) - c) = a r^t d with r = 1 - eta a and d = theta(0) - c, every step moves
# theta by -eta g(t), so (per weight)
#   omega = eta sum_{t<T} g(t)^2 = eta a^2 d^2 (1 - r^(2T)) / (1 - r^2),
#   Delta = theta(T) - theta(0) = (r^T - 1) d.
# While learning task 1 the loss is 1/2 sum a' (theta - c')^2 + s sum Omega (theta - theta*)^2,
# whose gradient a' (theta - c') + 2 s Omega (theta - theta*) = A (theta - C) is again linear
# with A = a' + 2 s Omega, C = (a' c' + 2 s Omega theta*) / A: the same closed form holds.
ETA, XI, C_SI = 0.25, 0.3, 0.4
THETA0 = np.array([0.5, -1.2, 0.9, 0.3, -0.4, 1.1])
CURV = (np.array([0.8, 1.5, 2.6, 0.35, 1.1, 5.2]),  # a: eta*a > 1 for the last (oscillates)
        np.array([1.9, 0.6, 1.2, 2.3, 0.45, 0.9]))
TARGET = (np.array([1.7, 0.4, -0.6, 2.2, -1.9, 0.2]),
          np.array([-0.8, 1.3, 0.5, -1.4, 0.9, 1.6]))
STEPS = (6, 5)


def _gd_closed_form(A, C, theta, steps):
    """(omega, Delta, theta at the end) of ``steps`` GD steps on 1/2 A (theta - C)^2."""
    d, r = theta - C, 1.0 - ETA * A
    omega = ETA * A**2 * d**2 * (1.0 - r ** (2 * steps)) / (1.0 - r**2)
    return omega, (r**steps - 1.0) * d, C + r**steps * d


def _gd_steps(A, C, theta, steps):
    """The same trajectory step by step: [theta(0..T)], [g(0..T-1)]."""
    thetas, grads = [theta], []
    for _ in range(steps):
        grads.append(A * (thetas[-1] - C))
        thetas.append(thetas[-1] - ETA * grads[-1])
    return np.array(thetas), np.array(grads)


def _si_expected(merge: str = "per_task"):
    """Omega and anchor after each of the two tasks, by the closed form; ``cumulative``: the
    released code's, whose path integral of task 1 still holds task 0's."""
    omega0, delta, theta = _gd_closed_form(CURV[0], TARGET[0], THETA0, STEPS[0])
    importance = [omega0 / (delta**2 + XI)]
    anchors = [theta]
    a, c = CURV[1], TARGET[1]
    A = a + 2.0 * C_SI * importance[0]
    C = (a * c + 2.0 * C_SI * importance[0] * anchors[0]) / A
    omega, delta, theta = _gd_closed_form(A, C, anchors[0], STEPS[1])
    if merge == "cumulative":
        omega = omega + omega0
    importance.append(importance[0] + omega / (delta**2 + XI))
    anchors.append(theta)
    return importance, anchors, (A, C)


def test_si_closed_form_is_right_and_discriminating():
    """Self-check of the closed form against the step-by-step sums, and that plausible wrong
    variants of SI give clearly different importances with these numbers."""
    importance, anchors, (A, C) = _si_expected()
    thetas, grads = _gd_steps(CURV[0], TARGET[0], THETA0, STEPS[0])
    omega0 = -np.sum(grads * np.diff(thetas, axis=0), axis=0)
    _close(omega0 / ((thetas[-1] - THETA0) ** 2 + XI), importance[0])
    _close(thetas[-1], anchors[0])
    thetas1, grads1 = _gd_steps(A, C, anchors[0], STEPS[1])
    moves1 = np.diff(thetas1, axis=0)
    omega1 = -np.sum(grads1 * moves1, axis=0)
    denominator = (thetas1[-1] - anchors[0]) ** 2 + XI
    _close(importance[0] + omega1 / denominator, importance[1])

    def far(wrong, right):
        assert np.min(np.abs(wrong - right) / np.abs(right)) > 1e-2

    # the gradient after the step instead of the one the step used
    post = CURV[0] * (thetas[1:] - TARGET[0])
    far(-np.sum(post * np.diff(thetas, axis=0), axis=0) / ((thetas[-1] - THETA0) ** 2 + XI),
        importance[0])
    # Delta not squared / no xi
    far(omega0 / (np.abs(thetas[-1] - THETA0) + XI), importance[0])
    far(omega0 / (thetas[-1] - THETA0) ** 2, importance[0])
    # task 1: only the task loss's gradient in omega (penalty gradient left out)
    task_only = CURV[1] * (thetas1[:-1] - TARGET[1])
    far(importance[0] - np.sum(task_only * moves1, axis=0) / denominator, importance[1])
    # task 1: omega not restarted (the original code's accumulation)
    far(importance[0] + (omega0 + omega1) / denominator, importance[1])
    # task 1: Delta measured from the initial weights instead of the task's start
    far(importance[0] + omega1 / ((thetas1[-1] - THETA0) ** 2 + XI), importance[1])


@pytest.mark.parametrize("merge", ["per_task", "cumulative"])
def test_si_gradient_descent_two_tasks_closed_form(monkeypatch, merge):
    """Two tasks of plain SGD on quadratics through SI's hooks (loop order), the second one
    with SI's own penalty in the loss: path integral, Omega (summed over tasks), anchors and
    the penalty match the closed form; ``cumulative`` keeps the path integral across tasks as
    the released code (and its Omega of task 1 differs clearly from ``per_task``'s)."""
    importance, anchors, _ = _si_expected(merge)
    other, _, _ = _si_expected("cumulative" if merge == "per_task" else "per_task")
    assert np.min(np.abs(importance[1] - other[1]) / np.abs(other[1])) > 1e-2
    method = _si(monkeypatch, THETA0, XI, C_SI, merge)
    _close(_buffers(method, "anchor"), THETA0)

    for task in (0, 1):
        if task:
            method.add_task()
            method.double()
        a, c = (torch.from_numpy(x) for x in (CURV[task], TARGET[task]))
        method.on_task_start(task, SI_TASK)
        optimizer = torch.optim.SGD(method.trainable(task), lr=ETA)
        for _ in range(STEPS[task]):
            optimizer.zero_grad(set_to_none=True)
            theta = torch.cat([w.reshape(-1) for w in method.weights])
            (0.5 * (a * (theta - c) ** 2).sum()).backward()
            extra = method.extra_loss(_ctx(task, optimizer))
            assert (extra is None) == (task == 0)
            if extra is not None:
                extra.backward()
            optimizer.step()
            method.after_step()
        method.on_task_end(task, SI_TASK)
        _close(_flat(method.weights), anchors[task])
        _close(_buffers(method, "anchor"), anchors[task])
        _close(_buffers(method, "importance"), importance[task])
        if merge == "per_task":
            np.testing.assert_array_equal(_buffers(method, "omega"), 0.0)

    probe = np.array([0.2, -0.7, 1.3, 0.0, -1.1, 0.6])
    _check_penalty(method, C_SI, probe, importance[1], anchors[1], task=2)


# -- MAS ----------------------------------------------------------------------------------

# f(t, y) = W y + b + t u: per sample, d||f||^2/dW = 2 f y^T, d/db = 2 f, d/du = 2 t f.
LIN_W = np.array([[1.2, -0.7], [0.4, 0.9]])
LIN_B = np.array([-0.3, 0.5])
LIN_U = np.array([0.8, -1.1])
LIN_Y = np.array([[0.5, 1.0], [-1.5, 0.25], [2.0, -0.5], [0.1, -1.2], [-0.7, -0.3]])
LIN_T = np.array([0.0, 0.3, 0.6, 1.4, 2.0])


def _linear_expected():
    f = LIN_Y @ LIN_W.T + LIN_B + LIN_T[:, None] * LIN_U  # [N, 2]
    per_sample = [2 * f[:, :, None] * LIN_Y[:, None, :], 2 * f, 2 * LIN_T[:, None] * f]
    return per_sample


@pytest.mark.parametrize("chunk_floats", [2**25, 16, 1])  # 1 chunk, chunks of 2 (+1), of 1
def test_mas_importance_linear_field(monkeypatch, chunk_floats):
    """``output_norm_importance`` on a linear field, whatever the chunking of the samples:
    ``1/N sum_n |d ||f(t_n, y_n)||^2 / d theta|`` per weight."""
    per_sample = _linear_expected()
    expected = [np.abs(g).mean(0) for g in per_sample]
    # with these points the gradients change sign across samples: the mean of |g| differs
    # from |mean g| (the absolute value of a batch gradient)
    assert all(np.max(np.abs(e - np.abs(g.mean(0)))) > 0.1
               for e, g in zip(expected, per_sample, strict=True))

    monkeypatch.setattr(mas_module, "_CHUNK_FLOATS", chunk_floats)
    weights = [torch.from_numpy(x.copy()).requires_grad_() for x in (LIN_W, LIN_B, LIN_U)]

    def field_of(ws):
        W, b, u = ws
        return lambda t, y: y @ W.T + b + t * u

    got = output_norm_importance(field_of, weights, torch.from_numpy(LIN_Y),
                                 torch.from_numpy(LIN_T))
    for g, e in zip(got, expected, strict=True):
        assert g.shape == e.shape and g.dtype == torch.float64
        _close(g, e)
    # hand check of one entry: d/db_0 = 2 f_0(n); f_0 = 1.2 y0 - .7 y1 - .3 + .8 t
    f0 = [1.2 * 0.5 - 0.7 * 1.0 - 0.3, 1.2 * -1.5 - 0.7 * 0.25 - 0.3 + 0.8 * 0.3,
          1.2 * 2.0 + 0.35 - 0.3 + 0.8 * 0.6, 0.12 + 0.84 - 0.3 + 0.8 * 1.4,
          -0.84 + 0.21 - 0.3 + 1.6]
    _close(got[1][0], 2 * np.mean(np.abs(f0)))


# The conditioned NODE itself: state dim 2, one hidden layer of 2 ELUs, 1-D embedding, time
# input; input x = [e, y_1, y_2, t]. The weights keep every hidden pre-activation positive on
# the data, where ELU is the identity (derivative 1), so f = W1 (W0 x + b0) + b1 and
#   d||f||^2/dW1 = 2 f h^T, d/db1 = 2 f, d/dW0 = (2 W1^T f) x^T, d/db0 = 2 W1^T f.
MAS_SPEC = NodeSpec(dim=2, hidden=(2,), time_input=True)
MAS_SHAPES = [(2, 4), (2,), (2, 2), (2,)]  # the method adds cond_dim=1
MAS_LAMBDA = 0.35
MAS_THETA = (  # [W0 (2x4), b0, W1 (2x2), b1] after task 0 and after task 1
    np.array([0.3, 0.5, -0.2, 0.4, -0.1, 0.2, 0.6, -0.3, 2.0, 1.5,
              0.9, 0.4, -0.7, 0.3, -2.5, 1.0]),
    np.array([-0.2, 0.35, 0.1, -0.45, 0.25, -0.4, 0.3, 0.5, 1.8, 2.2,
              -0.6, 1.1, 0.8, -0.5, -0.9, -0.6]),
)
MAS_EMB = (np.array([0.7]), np.array([-1.3]))
MAS_TIMES = np.array([0.0, 0.5, 1.0])
MAS_DEMOS = (  # [n=2 demos, T=3, D=2]
    np.array([[[0.2, -0.4], [0.9, 0.1], [1.3, 0.8]], [[-0.6, 0.5], [-0.1, 1.2], [0.4, 1.6]]]),
    np.array([[[1.1, 0.3], [0.6, -0.8], [-0.2, -1.0]], [[0.0, -0.3], [0.7, 0.2], [1.5, 0.4]]]),
)
# mas_points=4 of the 6 samples: round(linspace(0, 5, 4)) = [0, 2, 3, 5], i.e. the first and
# last sample of each demo
MAS_SELECTED = {0: [0, 1, 2, 3, 4, 5], 4: [0, 2, 3, 5]}


def _node_mas_expected(theta, emb, demos, selected):
    W0, b0, W1, b1 = (x.numpy() for x in split_flat(torch.from_numpy(theta), MAS_SHAPES))
    ys = demos.reshape(-1, 2)[selected]
    ts = np.tile(MAS_TIMES, demos.shape[0])[selected]
    total = [np.zeros_like(W0), np.zeros_like(b0), np.zeros_like(W1), np.zeros_like(b1)]
    signs = []
    for y, t in zip(ys, ts, strict=True):
        x = np.concatenate([emb, y, [t]])
        h = W0 @ x + b0
        assert np.all(h > 0.2), h  # ELU's linear region
        f = W1 @ h + b1
        signs.append(np.sign(f))
        gh = 2 * W1.T @ f
        for acc, g in zip(total, [np.outer(gh, x), gh, 2 * np.outer(f, h), 2 * f], strict=True):
            acc += np.abs(g)
    assert len({tuple(s) for s in signs}) > 1  # f changes sign: mean |g| != |mean g|
    return np.concatenate([(acc / len(ys)).reshape(-1) for acc in total])


@pytest.mark.parametrize(("mas_points", "merge"),
                         [(0, "per_task"), (4, "per_task"), (0, "cumulative")])
def test_mas_node_importance_two_tasks(monkeypatch, mas_points, merge):
    """MAS's end-of-task hook on the real NODE: the importance of each task (its own
    embedding and data points, ``mas_points`` of them), their sum over tasks, the anchor,
    and the penalty. ``cumulative`` (the released code's merge) adds task 0's importance a
    second time at the end of task 1, and keeps one more buffer (counted in the size)."""
    cfg = PartConfig(iterations=1, lr=0.1, node_hidden=(2,), task_emb_dim=1,
                     mas_lambda=MAS_LAMBDA, mas_points=mas_points, importance_merge=merge)
    method = _build(MemoryAwareSynapses, MAS_SPEC, cfg, MAS_THETA[0], monkeypatch)
    assert method.node_spec.param_shapes() == MAS_SHAPES
    expected = []
    for task in (0, 1):
        method.add_task()
        method.double()
        with torch.no_grad():
            method.embeddings[task].copy_(torch.from_numpy(MAS_EMB[task]))
        _set_weights(method, MAS_THETA[task])  # "trained" weights at the end of the task
        data = TaskData(torch.from_numpy(MAS_DEMOS[task]), torch.from_numpy(MAS_TIMES))
        method.on_task_end(task, data)
        expected.append(_node_mas_expected(MAS_THETA[task], MAS_EMB[task], MAS_DEMOS[task],
                                           MAS_SELECTED[mas_points]))
        if merge == "cumulative" and task == 1:
            expected[1] = expected[1] + expected[0]
        _close(_buffers(method, "importance"), sum(expected))
        _close(_buffers(method, "anchor"), MAS_THETA[task])
    # the second task's own importance differs clearly from the first's (so a sum is visible)
    assert np.min(np.abs(expected[1] - expected[0])) > 1e-3
    weights = sum(w.numel() for w in method.weights)
    buffers = 3 if merge == "cumulative" else 2  # importance, anchor (+ running)
    assert method.num_params() == weights * (1 + buffers) + 2  # + the two embeddings

    assert method.extra_loss(_ctx(0)) is None
    probe = MAS_THETA[1] + np.linspace(-0.6, 0.9, MAS_THETA[1].size)
    _check_penalty(method, MAS_LAMBDA, probe, sum(expected), MAS_THETA[1], task=2)
