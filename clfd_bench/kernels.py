"""The floating-point kernels a run computes with: made thread-invariant, and recorded.

Training is chaotic at the level of rounding: the same fast HN HelloWorld run trained with two
float-rounding variants of one matrix product ends with predictions up to 2 cm apart
(measured 2026-12-05). So what decides the kernels is part of a result's provenance.

- **Threads.** MKL (PyTorch's BLAS on x86) splits work between threads in ways that change the
  order of float sums, so ``--threads 2`` gave other predictions than ``--threads 1`` (HN smoke:
  4e-8; CHN smoke: 6e-7; SG fast: 1.7e-4). MKL's conditional numerical reproducibility mode
  ``MKL_CBWR=AUTO,STRICT`` makes its results independent of the thread count (on the same
  CPU), at no speed cost measured at one thread. :func:`pin_thread_invariant_kernels` sets it
  when the package is imported, unless the user set ``MKL_CBWR`` already. MKL reads it at its
  first call, so it holds when ``clfd_bench`` is imported before any torch computation (the
  CLI always is); a process that multiplied tensors first keeps the mode it started with.
- **CPUs.** Across CPUs the kernels differ by instruction set (PyTorch's vector kernels and
  MKL's dispatch: AVX2, AVX-512), so results are reproducible on one machine, not across
  machines: :func:`blas_provenance` records the CPU capability and the BLAS libraries beside
  the CPU model (``harness.evaluation.cpu_provenance``).
"""

from __future__ import annotations

import os
import re
from typing import Any

__all__ = ["MKL_CBWR_DEFAULT", "blas_provenance", "pin_thread_invariant_kernels"]

#: MKL's reproducibility mode clfd-bench runs with: the CPU's best code path, results
#: independent of the number of threads.
MKL_CBWR_DEFAULT = "AUTO,STRICT"


def pin_thread_invariant_kernels() -> str:
    """Sets ``MKL_CBWR`` to :data:`MKL_CBWR_DEFAULT` unless it is set; returns its value."""
    return os.environ.setdefault("MKL_CBWR", MKL_CBWR_DEFAULT)


def blas_provenance() -> dict[str, Any]:
    """The linear-algebra libraries of this process (imports torch and numpy).

    Returns ``{"torch_blas", "torch_lapack", "torch_mkl", "torch_cpu_capability",
    "numpy_blas", "mkl_cbwr"}``: PyTorch's build-time BLAS and LAPACK (``BLAS_INFO``,
    ``LAPACK_INFO``), its MKL version line, the CPU capability it dispatches to, numpy's BLAS
    (name and version) and the ``MKL_CBWR`` mode in the environment (None when unset).
    Entries that cannot be read are ``"unknown"``.
    """
    import numpy as np
    import torch

    config = torch.__config__.show()

    def field(pattern: str) -> str:
        m = re.search(pattern, config)
        return m.group(1).strip() if m else "unknown"

    try:
        blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
        numpy_blas = f"{blas.get('name', 'unknown')} {blas.get('version', '')}".strip()
    except (KeyError, TypeError, ValueError):
        numpy_blas = "unknown"
    return {
        "torch_blas": field(r"BLAS_INFO=([^,\s]+)"),
        "torch_lapack": field(r"LAPACK_INFO=([^,\s]+)"),
        "torch_mkl": field(r"(Intel\(R\)[^\n]*Math Kernel Library[^\n]*)"),
        "torch_cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "numpy_blas": numpy_blas,
        "mkl_cbwr": os.environ.get("MKL_CBWR"),
    }
