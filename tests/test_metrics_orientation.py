"""The paper's quaternion error E_q = 1/(3T) sum_t |2 Log(q_t * conj(q̂_t))|_1."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.metrics import quaternion_error, trajectory_errors
from clfd_bench.metrics.orientation import rotation_vectors


def _axis_angle(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.r_[np.cos(angle / 2), np.sin(angle / 2) * axis]


def _hamilton(p, q):
    """Quaternion product for checking only (w, x, y, z)."""
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _paper_literal(pred, ref):
    """The paper's formula with its Log(q) = arccos(w) u/|u| (valid for w >= 0)."""
    total = 0.0
    for p, r in zip(pred, ref, strict=True):
        q = _hamilton(r, p * np.array([1, -1, -1, -1]))
        u = q[1:]
        norm = np.linalg.norm(u)
        log = np.arccos(np.clip(q[0], -1, 1)) * u / norm if norm > 0 else np.zeros(3)
        total += np.abs(2 * log).sum()
    return total / (3 * len(pred))


def test_rotation_about_one_axis_closed_form():
    # Prediction off by angle a about z at every step: e_q = (0, 0, -a), so E_q = a / 3.
    a = np.radians(30.0)
    ref = np.tile([1.0, 0.0, 0.0, 0.0], (7, 1))
    pred = np.tile(_axis_angle([0, 0, 1], a), (7, 1))
    assert quaternion_error(pred, ref) == pytest.approx(10.0)
    assert quaternion_error(pred, ref, degrees=False) == pytest.approx(a / 3)
    np.testing.assert_allclose(rotation_vectors(ref, pred), np.tile([0, 0, -a], (7, 1)), atol=1e-12)
    # About (1, 1, 0)/sqrt(2): |e_q|_1 = a * sqrt(2), so E_q = a sqrt(2) / 3.
    pred = np.tile(_axis_angle([1, 1, 0], a), (7, 1))
    assert quaternion_error(pred, ref, degrees=False) == pytest.approx(a * np.sqrt(2) / 3)


def test_world_frame_difference():
    # q_t = Rz(45 deg); prediction = q_t * Rx(b), off by b about the *body* x axis. The
    # paper's q_t * conj(q̂_t) is a rotation by -b about the world axis Rz(45) x =
    # (1, 1, 0)/sqrt(2): |e|_1 = b sqrt(2). (conj(q̂_t) * q_t, the body-frame difference,
    # would give b.)
    b = np.radians(12.0)
    q = _axis_angle([0, 0, 1], np.radians(45.0))
    pred = _hamilton(q, _axis_angle([1, 0, 0], b))[None]
    assert quaternion_error(pred, q[None], degrees=False) == pytest.approx(b * np.sqrt(2) / 3)


def test_sign_invariance_and_identity():
    rng = np.random.default_rng(0)
    ref = rng.normal(size=(50, 4))
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    assert quaternion_error(ref, ref) == pytest.approx(0.0, abs=1e-12)
    # -q is the same orientation: no error, and flipping signs changes nothing.
    assert quaternion_error(-ref, ref) == pytest.approx(0.0, abs=1e-12)
    pred = ref + rng.normal(scale=0.05, size=ref.shape)
    flips = np.where(rng.random(50) < 0.5, -1.0, 1.0)[:, None]
    assert quaternion_error(pred * flips, ref) == pytest.approx(quaternion_error(pred, ref))
    # Not necessarily unit: only the direction of each quaternion matters.
    assert quaternion_error(3.0 * pred, ref) == pytest.approx(quaternion_error(pred, ref))


def test_equals_paper_literal_formula_in_same_hemisphere():
    rng = np.random.default_rng(1)
    ref = rng.normal(size=(40, 4))
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    pred = ref + rng.normal(scale=0.2, size=ref.shape)
    pred /= np.linalg.norm(pred, axis=1, keepdims=True)
    # Same hemisphere (scalar part of q_t * conj(q̂_t) >= 0): both definitions agree.
    scalars = [_hamilton(r, p * [1, -1, -1, -1])[0] for p, r in zip(pred, ref, strict=True)]
    assert min(scalars) > 0
    assert quaternion_error(pred, ref, degrees=False) == pytest.approx(_paper_literal(pred, ref))
    # The literal formula is not sign invariant (it goes the long way round for -q̂).
    assert _paper_literal(-pred, ref) > 10 * _paper_literal(pred, ref)


def test_batched_via_trajectory_errors():
    rng = np.random.default_rng(2)
    ref = rng.normal(size=(3, 20, 4))
    pred = ref + rng.normal(scale=0.1, size=ref.shape)
    out = trajectory_errors(pred, ref, metrics=("quaternion",))
    expected = [quaternion_error(p, r) for p, r in zip(pred, ref, strict=True)]
    np.testing.assert_allclose(out["quaternion"], expected)


def test_input_errors():
    good = np.tile([1.0, 0, 0, 0], (5, 1))
    with pytest.raises(ValueError, match=r"shape \[T, 4\]"):
        quaternion_error(np.zeros((5, 3)), good)
    with pytest.raises(ValueError, match="same shape"):
        quaternion_error(good[:4], good)
    with pytest.raises(ValueError, match="zero quaternion"):
        quaternion_error(np.zeros((5, 4)), good)
