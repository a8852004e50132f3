"""The Adam step as one compiled pass (numba): the hypernetworks' look-ahead ``dh``.

At the paper's sizes HN's hypernetwork has 4.3 M parameters (its output layer 20 802 x 200), so
every full pass over them costs about as much as the target NODE's whole training step. The
look-ahead reads the gradient and Adam's two moments and writes ``dh``: four passes here,
instead of copying the parameters and both moments, running torch's Adam kernel on the copies
and subtracting (sixteen). Imported lazily by :mod:`clfd_bench.learning.hnet_reg`, so importing
the package does not import numba.
"""

from __future__ import annotations

import math

import numpy as np

from clfd_bench.compiled import njit


# error_model="numpy": a division by zero gives inf/nan as in torch, and no check of the
# divisor in the loop, which would keep it from being vectorised (12 ms -> 2.7 ms here).
@njit(nogil=True, error_model="numpy")
def adam_delta(grad: np.ndarray, exp_avg: np.ndarray, exp_avg_sq: np.ndarray, out: np.ndarray,
               beta1: float, beta2: float, step_size: float, bc2_sqrt: float,
               eps: float) -> None:
    """``out = -step_size * (m' / (sqrt(v') / bc2_sqrt + eps))`` with ``m' = m + (1 - beta1)
    (g - m)`` (torch's ``lerp``) and ``v' = beta2 v + (1 - beta2) g^2``, elementwise over
    flat float32 arrays of one size (``exp_avg``/``exp_avg_sq`` are read, not changed; None
    state is passed as zeros). ``step_size = lr / (1 - beta1^k)``, ``bc2_sqrt = sqrt(1 -
    beta2^k)`` for the step ``k`` about to be taken. In float32, as torch's kernel."""
    w1 = np.float32(1.0 - beta1)
    b2 = np.float32(beta2)
    w2 = np.float32(1.0 - beta2)
    ss = np.float32(-step_size)
    inv = np.float32(bc2_sqrt)
    e = np.float32(eps)
    for i in range(grad.size):
        g = grad[i]
        m = exp_avg[i] + w1 * (g - exp_avg[i])
        v = b2 * exp_avg_sq[i] + w2 * (g * g)
        out[i] = ss * (m / (math.sqrt(v) / inv + e))
