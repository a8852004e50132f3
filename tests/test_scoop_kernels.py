"""The Scoop sweep's compiled point-in-box tests give the masks of the numpy expressions they
replaced, on points in, out, on the faces and non-finite."""

from __future__ import annotations

import numpy as np

from clfd_bench.envs.robotasks.scoop import kernels


def _numpy_in_box(p: np.ndarray, box: np.ndarray) -> np.ndarray:
    m = (p >= box[0]) & (p <= box[1])
    return m[..., 0] & m[..., 1] & m[..., 2]


def _points(rng: np.random.Generator, k: int, box: np.ndarray) -> np.ndarray:
    """Points around `box` [2, 3], a third of their coordinates exactly on a face."""
    p = rng.uniform(box[0] - 0.02, box[1] + 0.02, size=(k, 3))
    on = rng.random((k, 3)) < 1 / 3
    p[on] = box[rng.integers(0, 2, size=on.sum()), np.nonzero(on)[1]]
    p[rng.random(k) < 0.02, 0] = np.nan
    p[rng.random(k) < 0.01, 2] = -np.inf
    return p


def test_masks_equal_the_numpy_expressions():
    rng = np.random.default_rng(3)
    outer = np.array([[-0.05, -0.04, -0.01], [0.05, 0.04, 0.03]])
    cavity = np.array([[-0.04, -0.03, 0.0], [0.04, 0.03, 0.03]])  # shares the top face
    for k in (0, 1, 7, 300):
        local, prev = _points(rng, k, outer), _points(rng, k, outer)
        assert np.array_equal(kernels.in_box(local, cavity), _numpy_in_box(local, cavity))
        o, c = _numpy_in_box(local, outer), _numpy_in_box(local, cavity)
        inside, solid, n_o, n_c, n_s = kernels.classify(local, outer, cavity)
        assert np.array_equal(inside, c) and np.array_equal(solid, o & ~c)
        assert (n_o, n_c, n_s) == (o.sum(), c.sum(), (o & ~c).sum())
        entered, gone, n_e, n_g = kernels.entered(inside, solid, prev, cavity)
        e = c & ~_numpy_in_box(prev, cavity)
        assert np.array_equal(entered, e) and np.array_equal(gone, (o & ~c) | e)
        assert (n_e, n_g) == (e.sum(), ((o & ~c) | e).sum())
    # the faces belong to the box; just outside does not
    face = np.array([[0.04, 0.03, 0.0], [np.nextafter(0.04, 1.0), 0.0, 0.01]])
    assert kernels.in_box(face, cavity).tolist() == [True, False]
