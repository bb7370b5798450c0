"""The one place where Numba options are set, and where compiled loops share out their rows.

Numba's own parallel loops (``parallel=True``) cost several seconds of compiling each on a
fresh install; a plain kernel over a range of rows compiles in a fraction of that, and
since every kernel releases the GIL (``nogil``), threads run its chunks at once.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from functools import cache

import numba
import numpy as np

__all__ = ["CHUNK_ROWS", "inputs", "jit", "over_rows", "threads"]

_OPTIONS = {"cache": True, "fastmath": False, "nogil": True}

jit = numba.njit(**_OPTIONS)

#: Rows per chunk below which a kernel runs on the calling thread alone: a thread's start
#: costs about as much as this many rows of the lightest kernel.
CHUNK_ROWS = 2048


@cache
def _pool() -> ThreadPoolExecutor:
    """As many threads as Numba may use (``NUMBA_NUM_THREADS``, one per core by default),
    started on first use."""
    return ThreadPoolExecutor(numba.config.NUMBA_NUM_THREADS, thread_name_prefix="zeroset")


def threads() -> int:
    """Threads a kernel's rows are shared among: ``numba.get_num_threads()``, which
    ``numba.set_num_threads`` lowers, as it does for phase 2's moves."""
    return numba.get_num_threads()


def over_rows(kernel, n: int, *args) -> None:
    """Run ``kernel(start, stop, *args)`` on the rows 0..n-1, in chunks shared among
    `threads` threads (a few chunks per thread, so that uneven rows even out)."""
    chunks = min(4 * threads(), n // CHUNK_ROWS)
    if chunks <= 1:
        kernel(0, n, *args)
        return
    bounds = [n * c // chunks for c in range(chunks + 1)]
    starts, stops = bounds[:-1], bounds[1:]
    tasks = [_pool().submit(kernel, a, b, *args) for a, b in zip(starts, stops, strict=True)]
    for task in tasks:
        task.result()


def inputs(*arrays) -> list[np.ndarray]:
    """Contiguous read-only views of `arrays` (copies where they are not contiguous): a
    kernel then sees one type whether its caller's arrays are frozen (`zeroset.types.Frozen`)
    or not, and compiles once."""
    views = []
    for array in arrays:
        view = np.ascontiguousarray(array).view()
        view.flags.writeable = False
        views.append(view)
    return views
