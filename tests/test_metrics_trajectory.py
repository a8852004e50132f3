"""Trajectory metrics (DTW, discrete Fréchet, swept area) against hand-computed cases and a
plain O(T^2) reference loop (to the bit)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clfd_bench.metrics import (
    TRAJECTORY_METRICS,
    dtw,
    dtw_batch,
    frechet,
    frechet_batch,
    swept_area,
    swept_area_batch,
    trajectory_errors,
)


def _reference_dp(a: np.ndarray, b: np.ndarray, kind: str) -> float:
    """Textbook DTW / discrete Fréchet recursion, cell by cell, in Python floats (the
    squared differences summed in coordinate order)."""
    n, m = len(a), len(b)
    acc = np.full((n, m), np.inf)
    for i in range(n):
        for j in range(m):
            cost = math.sqrt(sum((float(q) - float(p)) * (float(q) - float(p))
                                 for p, q in zip(a[i], b[j], strict=True)))
            if i == 0 and j == 0:
                acc[i, j] = cost
                continue
            best = min(
                acc[i - 1, j] if i > 0 else np.inf,
                acc[i, j - 1] if j > 0 else np.inf,
                acc[i - 1, j - 1] if i > 0 and j > 0 else np.inf,
            )
            acc[i, j] = cost + best if kind == "dtw" else max(cost, best)
    return float(acc[-1, -1])


def test_parallel_lines_by_hand():
    # pred runs along y = 0, ref along y = 1, same x steps: the diagonal coupling pairs
    # points 1 apart, so DTW = 1 + 1 + 1 = 3 and Fréchet = 1. The swept area is two unit
    # squares: 2.
    pred = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    ref = np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]])
    assert dtw(pred, ref) == pytest.approx(3.0)
    assert frechet(pred, ref) == pytest.approx(1.0)
    assert swept_area(pred, ref) == pytest.approx(2.0)


def test_warping_by_hand_unequal_lengths():
    # 1-D pred (0, 1, 2, 3) against ref (0, 2, 3). Cost |p_i - r_j|:
    #        r=0  r=2  r=3
    #  p=0    0    2    3
    #  p=1    1    1    2
    #  p=2    2    0    1
    #  p=3    3    1    0
    # Accumulated DTW matrix (rows p, columns r):
    #   0 2 5 / 1 1 3 / 3 1 2 / 6 2 1  -> DTW = 1, path (0,0) (1,0|1) (2,1) (3,2).
    # Fréchet: every coupling passes row p=1, whose cheapest cell costs 1 -> 1.
    pred = np.array([[0.0], [1.0], [2.0], [3.0]])
    ref = np.array([[0.0], [2.0], [3.0]])
    assert dtw(pred, ref) == pytest.approx(1.0)
    assert frechet(pred, ref) == pytest.approx(1.0)
    # Shifting pred by 0.5 everywhere: path (0,0)=0.5, (1,0)=1.5 or (1,1)=0.5, (2,1)=0.5,
    # (3,1)=1.5 or (3,2)=0.5 -> DTW = 0.5 * 4 = 2, Fréchet = 0.5.
    assert dtw(pred + 0.5, ref) == pytest.approx(2.0)
    assert frechet(pred + 0.5, ref) == pytest.approx(0.5)


def test_swept_area_by_hand():
    # Trapezoid with parallel sides 1 and 3, width 2: area (1 + 3) / 2 * 2 = 4.
    pred = np.array([[0.0, 0.0], [2.0, 0.0]])
    ref = np.array([[0.0, 1.0], [2.0, 3.0]])
    assert swept_area(pred, ref) == pytest.approx(4.0)
    assert swept_area(ref, pred) == pytest.approx(4.0)
    # A crossing ("bow tie") segment: the released shoelace code gives the difference of the
    # two triangles, here 0; so does this implementation.
    bow_pred = np.array([[0.0, 0.0], [1.0, 0.0]])
    bow_ref = np.array([[0.0, 1.0], [1.0, -1.0]])
    assert swept_area(bow_pred, bow_ref) == pytest.approx(0.0, abs=1e-12)


def test_swept_area_3d_planar_matches_2d():
    rng = np.random.default_rng(3)
    pred2 = np.cumsum(rng.normal(size=(50, 2)), axis=0)
    ref2 = pred2 + rng.normal(scale=0.3, size=(50, 2))
    expected = swept_area(pred2, ref2)
    # Embed the plane in 3-D with a random rotation and offset: the area is unchanged.
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    offset = rng.normal(size=3)

    def lift(x):
        return np.c_[x, np.zeros(len(x))] @ q.T + offset

    assert swept_area(lift(pred2), lift(ref2)) == pytest.approx(expected, rel=1e-10)
    # A unit square standing in the x-z plane has area 1 (x-y only would say 0).
    assert swept_area(
        np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    ) == pytest.approx(1.0)


def test_identity_gives_zero_and_dtw_is_symmetric():
    rng = np.random.default_rng(0)
    a = np.cumsum(rng.normal(size=(200, 3)), axis=0)
    b = np.cumsum(rng.normal(size=(150, 3)), axis=0)
    assert dtw(a, a) == 0.0
    assert frechet(a, a) == 0.0
    assert swept_area(a, a) == 0.0
    assert dtw(a, b) == pytest.approx(dtw(b, a), rel=1e-12)
    assert frechet(a, b) == pytest.approx(frechet(b, a), rel=1e-12)
    assert dtw(a, b) > 0 and frechet(a, b) > 0


@pytest.mark.parametrize("seed", range(6))
def test_matches_reference_loop_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    # Many small shapes (including 1 x m and n x 1), up to 9-D points, plus two larger ones.
    shapes = [(int(rng.integers(1, 12)), int(rng.integers(1, 12))) for _ in range(20)]
    shapes += [(int(rng.integers(30, 60)), int(rng.integers(30, 60))), (120, 7)]
    for n, m in shapes:
        d = int(rng.integers(1, 10))
        a = rng.normal(size=(n, d)) * 10.0 ** rng.uniform(-3, 3)
        b = rng.normal(size=(m, d))
        assert dtw(a, b) == _reference_dp(a, b, "dtw"), (n, m, d)
        assert frechet(a, b) == _reference_dp(a, b, "frechet"), (n, m, d)


def test_batch_equals_single_to_the_bit():
    """Pairs of a batch share the kernel's scratch rows: each must still be its own pair's
    value, whatever its neighbours' lengths and values."""
    rng = np.random.default_rng(1)
    pred = np.cumsum(rng.normal(size=(20, 40, 2)), axis=1)
    ref = np.cumsum(rng.normal(size=(20, 33, 2)), axis=1)
    d = dtw_batch(pred, ref)
    f = frechet_batch(pred, ref)
    assert d.shape == f.shape == (20,)
    for k in range(20):
        assert d[k] == dtw(pred[k], ref[k])
        assert f[k] == frechet(pred[k], ref[k])
    # Non-contiguous views give the same values as their copies.
    assert np.array_equal(dtw_batch(pred[:, ::2], ref[::-1]),
                          dtw_batch(pred[:, ::2].copy(), ref[::-1].copy()))


def test_units_scaling():
    # DTW and Fréchet are lengths (scale 100 from m to cm), the swept area an area (10^4).
    rng = np.random.default_rng(2)
    a = np.cumsum(rng.normal(size=(60, 2)), axis=0)
    b = a + rng.normal(scale=0.2, size=(60, 2))
    assert dtw(100 * a, 100 * b) == pytest.approx(100 * dtw(a, b), rel=1e-10)
    assert frechet(100 * a, 100 * b) == pytest.approx(100 * frechet(a, b), rel=1e-10)
    assert swept_area(100 * a, 100 * b) == pytest.approx(1e4 * swept_area(a, b), rel=1e-10)


def test_trajectory_errors_batched():
    rng = np.random.default_rng(4)
    pred = np.cumsum(rng.normal(size=(3, 30, 2)), axis=1)
    ref = pred + rng.normal(scale=0.1, size=pred.shape)
    out = trajectory_errors(pred, ref)
    assert list(out) == ["dtw", "frechet", "swept_area"]
    np.testing.assert_allclose(out["dtw"], dtw_batch(pred, ref))
    np.testing.assert_allclose(out["frechet"], frechet_batch(pred, ref))
    np.testing.assert_allclose(out["swept_area"], swept_area_batch(pred, ref))
    with pytest.raises(ValueError, match="unknown trajectory metric.*valid"):
        trajectory_errors(pred, ref, metrics=("dtw", "hausdorff"))
    assert set(TRAJECTORY_METRICS) == {"dtw", "frechet", "swept_area", "quaternion"}


def test_input_errors_are_explained():
    a = np.zeros((5, 2))
    with pytest.raises(ValueError, match=r"shape \[T, D\]"):
        dtw(np.zeros(5), a)
    with pytest.raises(ValueError, match="same number of trajectories N and the same point"):
        dtw(a, np.zeros((5, 3)))
    with pytest.raises(ValueError, match="NaN or inf"):
        frechet(np.full((5, 2), np.nan), a)
    with pytest.raises(ValueError, match="same shape"):
        swept_area(a, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="2-D or 3-D"):
        swept_area(np.zeros((5, 4)), np.zeros((5, 4)))


def test_self_crossings_counts_the_loops_a_curve_draws():
    from clfd_bench.metrics.trajectory import self_crossings

    # A figure eight crosses itself once (at the origin, between samples here).
    t = np.linspace(0.1, 2 * np.pi + 0.1, 1001)
    assert self_crossings(np.c_[np.sin(t), np.sin(2 * t)]) == 1
    # A prolate trochoid x = t - a sin t, y = -a cos t (a > 1) closes one loop around every
    # t = 2 pi k; over [0, 6 pi] the loops at k = 1, 2 close (k = 0, 3 are cut in half).
    t = np.linspace(0, 6 * np.pi, 3000)
    assert self_crossings(np.c_[t - 2.0 * np.sin(t), -2.0 * np.cos(t)]) == 2
    # a < 1: a wave without loops; a converging spiral never meets itself.
    assert self_crossings(np.c_[t - 0.5 * np.sin(t), -0.5 * np.cos(t)]) == 0
    r = np.exp(-0.2 * t)
    assert self_crossings(np.c_[r * np.cos(t), r * np.sin(t)]) == 0
    # Jitter while resting at the end crosses itself; min_step removes it.
    rest = np.array([[1.0, 0.0], [1.0 + 1e-5, 1e-5], [1.0, 1e-5], [1.0 + 1e-5, 0.0]])
    line = np.r_[np.c_[np.linspace(0, 1, 50), np.zeros(50)], rest]
    assert self_crossings(line) == 1
    assert self_crossings(line, min_step=1e-3) == 0
    with pytest.raises(ValueError, match="planar"):
        self_crossings(np.zeros((10, 3)))


def test_large_pairs_keep_the_values_of_the_numpy_sweep_to_the_bit():
    """Pairs too large for the Python reference loop: the values the anti-diagonal numpy sweep
    (the implementation before the compiled kernel, be91939..9031b26) gave, as float.hex.
    Random walks from fixed seeds; the same arithmetic per cell gives the same bits on any
    IEEE-754 machine."""
    rng = np.random.default_rng(7)
    pinned = {(1000, 1000): ("0x1.c700b431c18eap+15", "0x1.36bdbed896203p+6"),
              (700, 1000): ("0x1.20259008ca2a2p+15", "0x1.1dc46ec4be02bp+6"),
              (1000, 300): ("0x1.ce4e84244df87p+13", "0x1.43ad9b79adc12p+5")}
    for (n, m), (d_hex, f_hex) in pinned.items():
        a = np.cumsum(rng.normal(size=(n, 2)), 0)
        b = np.cumsum(rng.normal(size=(m, 2)), 0)
        assert dtw(a, b).hex() == d_hex and frechet(a, b).hex() == f_hex, (n, m)
    rng = np.random.default_rng(8)
    a = np.cumsum(rng.normal(size=(3, 900, 3)), 1)
    b = np.cumsum(rng.normal(size=(3, 1100, 3)), 1)
    assert [x.hex() for x in dtw_batch(a, b)] == [
        "0x1.1837cd31b6bb0p+15", "0x1.d7b8226cd8b65p+15", "0x1.c1b5ac817e34cp+14"]
    assert [x.hex() for x in frechet_batch(a, b)] == [
        "0x1.48d41e0a0bd8dp+5", "0x1.8e8309c5c535cp+6", "0x1.ea23f802230f8p+5"]
