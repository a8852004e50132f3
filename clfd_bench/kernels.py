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
  MKL honours the strict mode only on its AVX2 and AVX-512 code paths, which it takes on Intel
  CPUs: on an AMD EPYC (2026-12-07) ``AUTO,STRICT`` gave the same products as ``OFF``, and a
  7x64 by 64x16 ``sgemm`` (small ``m`` and ``n``; ``k`` apparently split between threads)
  differed by 4e-6 between 1 and 2 threads; it was the only operation of a CHN smoke run
  whose result depended on the thread count (every operation's inputs and outputs hashed at
  1 and 2 threads). :func:`gemm_thread_probe` measures whether this machine's products depend
  on the thread count; where they do, :func:`set_threads` (which training uses instead of
  ``torch.set_num_threads``) holds MKL to one thread, which makes them identical again, while
  torch's own kernels keep ``--threads``. The provenance records the probe, so a reader
  knows whether ``--threads`` could have moved a result. Training's default is one thread,
  where none of this arises.
- **CPUs.** Across CPUs the kernels differ by instruction set (PyTorch's vector kernels and
  MKL's dispatch: AVX2, AVX-512), so results are reproducible on one machine, not across
  machines: :func:`blas_provenance` records the CPU capability and the BLAS libraries beside
  the CPU model (``harness.evaluation.cpu_provenance``).
"""

from __future__ import annotations

import functools
import os
import re
from typing import Any

__all__ = ["MKL_CBWR_DEFAULT", "THREAD_INVARIANT_ENV", "blas_provenance", "gemm_thread_probe",
           "pin_thread_invariant_kernels", "set_threads", "thread_invariance_wanted"]

#: MKL's reproducibility mode clfd-bench runs with: the CPU's best code path, results
#: independent of the number of threads.
MKL_CBWR_DEFAULT = "AUTO,STRICT"


def pin_thread_invariant_kernels() -> str:
    """Sets ``MKL_CBWR`` to :data:`MKL_CBWR_DEFAULT` unless it is set; returns its value."""
    return os.environ.setdefault("MKL_CBWR", MKL_CBWR_DEFAULT)


#: Set to ``0`` to keep MKL's own threads where that makes ``--threads`` move results (speed
#: over bit-identity across thread counts; :func:`set_threads` has the measured cost).
THREAD_INVARIANT_ENV = "CLFD_THREAD_INVARIANT"
_ON, _OFF = ("", "1", "true", "yes", "on"), ("0", "false", "no", "off")


def thread_invariance_wanted() -> bool:
    """Whether ``CLFD_THREAD_INVARIANT`` asks for results that ``--threads`` does not move:
    unset, empty, 1/true/yes/on (any case) yes; 0/false/no/off no.

    Raises:
        ValueError: any other value (a typo must not silently keep the default).
    """
    raw = os.environ.get(THREAD_INVARIANT_ENV, "").strip().lower()
    if raw in _ON or raw in _OFF:
        return raw in _ON
    raise ValueError(f"{THREAD_INVARIANT_ENV}={os.environ[THREAD_INVARIANT_ENV]!r} is not "
                     "understood: set it to 0 (keep MKL's threads: faster at --threads > 1, "
                     "results may move with the thread count) or 1 (the default), or unset it")


#: ``(m, k, n, bias)`` of the products :func:`gemm_thread_probe` computes: MKL's small-``m``,
#: small-``n`` path that splits ``k`` between threads (the one measured to differ on an AMD
#: EPYC), a bias-added product, and square and tall ones as the NODEs' layers have.
GEMM_PROBE_SHAPES: tuple[tuple[int, int, int, bool], ...] = (
    (7, 64, 16, False), (7, 1000, 16, False), (27, 16, 16, True), (100, 100, 100, True),
    (300, 64, 64, True))


@functools.lru_cache(maxsize=1)
def _mkl_set_local_threads() -> Any:
    """MKL's ``MKL_Set_Num_Threads_Local`` (one ``int`` by value) as exported by PyTorch's
    CPU library, or None where there is none (no MKL: ARM, macOS; another build). Looked up
    once per process."""
    import ctypes

    import torch

    lib_dir = os.path.join(os.path.dirname(torch.__file__), "lib")
    for name in ("libtorch_cpu.so", "libtorch_cpu.dylib", "torch_cpu.dll"):
        path = os.path.join(lib_dir, name)
        if os.path.exists(path):
            try:
                fn = ctypes.CDLL(path).MKL_Set_Num_Threads_Local
            except (OSError, AttributeError):
                return None
            fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
            return fn
    return None


def _products_max_diff(single_threaded_mkl: bool) -> float:
    """Largest difference of :data:`GEMM_PROBE_SHAPES`' products between 1 and 2 torch
    threads, with MKL's own threads left to torch or held at one (the caller restores the
    thread count)."""
    import torch

    pin = _mkl_set_local_threads() if single_threaded_mkl else None
    gen = torch.Generator().manual_seed(0)
    worst = 0.0
    for m, k, n, bias in GEMM_PROBE_SHAPES:
        a, b = torch.randn(m, k, generator=gen), torch.randn(k, n, generator=gen)
        c = torch.randn(n, generator=gen)
        out = []
        for threads in (1, 2):
            torch.set_num_threads(threads)
            if pin is not None:
                pin(1)
            out.append(torch.addmm(c, a, b) if bias else a @ b)
        worst = max(worst, float((out[0] - out[1]).abs().max()))
    return worst


@functools.lru_cache(maxsize=1)
def gemm_thread_probe() -> dict[str, Any]:
    """Whether this process's matrix products depend on the number of threads, and the
    remedy :func:`set_threads` applies.

    Computes each product of :data:`GEMM_PROBE_SHAPES` (float32, fixed random inputs) with 1
    and with 2 torch threads and compares them bit for bit. Where they differ (MKL's strict
    mode does not hold: an AMD EPYC, 2026-12-07) and MKL's per-thread setting is available, it
    measures again with MKL's products held to one thread while torch keeps its threads for
    its own kernels; if that makes them identical, :func:`set_threads` holds MKL to one
    thread from then on. The thread count is restored after. Measured once per process (MKL's
    mode is fixed at its first call), in tens of milliseconds.

    Returns ``{"threads": [1, 2], "identical": bool, "max_abs_diff": float,
    "mkl_single_threaded": bool, "unpinned_max_abs_diff": float}``: ``identical`` and
    ``max_abs_diff`` describe the products as this process computes them (after the remedy),
    ``unpinned_max_abs_diff`` MKL's own behaviour, ``mkl_single_threaded`` whether the remedy
    is on. ``identical`` false means ``--threads`` can move a result at rounding level here.
    It probes these shapes only: it cannot prove every product invariant, but a false is a
    measured counterexample.
    """
    import torch

    previous = torch.get_num_threads()
    try:
        unpinned = _products_max_diff(single_threaded_mkl=False)
        wanted = thread_invariance_wanted()
        pinned = (_products_max_diff(single_threaded_mkl=True)
                  if wanted and unpinned > 0.0 and _mkl_set_local_threads() is not None
                  else None)
    finally:
        torch.set_num_threads(previous)
    single = pinned == 0.0
    worst = 0.0 if single else unpinned
    if single:
        _mkl_set_local_threads()(1)
    return {"threads": [1, 2], "identical": worst == 0.0, "max_abs_diff": worst,
            "mkl_single_threaded": single, "unpinned_max_abs_diff": unpinned}


def set_threads(threads: int) -> None:
    """Sets torch's CPU threads for this thread's work, keeping matrix products independent
    of the count.

    ``torch.set_num_threads(threads)``; then, where :func:`gemm_thread_probe` found MKL's
    products thread-dependent and curable, MKL is held to one thread for the calling thread
    (torch resets MKL's threads on every ``set_num_threads``, so call this instead of it).
    torch's own kernels keep ``threads``; only MKL's products lose their parallelism, on CPUs
    where MKL's strict mode does not hold. Measured on a 2-core AMD EPYC, paper-size HelloWorld
    models (``clfd-bench bench train --methods hn sg --profile full --threads 2 --iterations
    10``, 2026-12-07), with ``CLFD_THREAD_INVARIANT=0``: SG 2.8-3.0 it/s held against 4.0-4.3
    with MKL's two threads (one thread 2.7-3.0), HN 23.9/18.3 against 29.2/20.7 (task 0/1); an
    earlier measurement with a patched copy instead of the switch gave SG 2.3-2.8 against
    5.2-5.3. Where speed at several threads matters more than bit-identity across thread
    counts, set ``CLFD_THREAD_INVARIANT=0`` (:data:`THREAD_INVARIANT_ENV`); the probe then
    records ``mkl_single_threaded: false`` and ``identical: false``. At one thread MKL has one
    thread already, so nothing is probed or held there (predictions from saved runs,
    evaluation).
    """
    import torch

    torch.set_num_threads(threads)
    if threads > 1 and gemm_thread_probe()["mkl_single_threaded"]:
        _mkl_set_local_threads()(1)


def blas_provenance() -> dict[str, Any]:
    """The linear-algebra libraries of this process (imports torch and numpy).

    Returns ``{"torch_blas", "torch_lapack", "torch_mkl", "torch_cpu_capability",
    "numpy_blas", "mkl_cbwr", "gemm_thread_probe"}``: PyTorch's build-time BLAS and LAPACK
    (``BLAS_INFO``, ``LAPACK_INFO``), its MKL version line, the CPU capability it dispatches
    to, numpy's BLAS (name and version), the ``MKL_CBWR`` mode in the environment (None when
    unset) and whether products depend on the thread count here (:func:`gemm_thread_probe`).
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
        "gemm_thread_probe": gemm_thread_probe(),
    }
