"""Compiled kernels work where numba cannot write its cache (a read-only install and home):
they are compiled without it, with one warning, instead of failing to import."""

from __future__ import annotations

import warnings

import numba
import numpy as np
import pytest

from clfd_bench import compiled


def test_without_a_writable_cache_the_kernel_is_compiled_without_it(monkeypatch):
    real = numba.njit

    def refusing(*args, **options):
        if options.get("cache"):
            def decorate(fn):
                raise RuntimeError(f"cannot cache function {fn.__name__!r}: no locator available")
            return decorate
        return real(*args, **options)

    monkeypatch.setattr(compiled.numba, "njit", refusing)
    monkeypatch.setattr(compiled, "_warned", False)

    def total(a):
        s = 0.0
        for x in a:
            s += x
        return s

    with pytest.warns(RuntimeWarning, match="NUMBA_CACHE_DIR"):
        fast = compiled.njit(nogil=True)(total)
    assert fast(np.arange(5.0)) == 10.0
    assert fast.targetoptions.get("nogil")  # the options still reach numba
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the warning is said once per process
        again = compiled.njit()(total)
    assert again(np.ones(3)) == 3.0
