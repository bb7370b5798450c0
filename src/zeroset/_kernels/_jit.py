"""The one place where Numba options are set."""

from __future__ import annotations

import numba

__all__ = ["jit", "jit_parallel", "prange"]

_OPTIONS = {"cache": True, "fastmath": False, "nogil": True}

jit = numba.njit(**_OPTIONS)
jit_parallel = numba.njit(parallel=True, **_OPTIONS)
prange = numba.prange
