"""Distinct values of an integer array, by sorting."""

from __future__ import annotations

import numpy as np

__all__ = ["distinct"]


def distinct(values: np.ndarray) -> np.ndarray:
    """The sorted distinct values (K,) of an integer array of any shape.

    The same as ``np.unique(values)``, by one sort: on millions of values many times
    faster than the hash table recent NumPy uses for integers (numpy/numpy#31970).
    """
    flat = np.sort(np.asarray(values).reshape(-1))
    keep = np.ones(flat.size, dtype=bool)
    np.not_equal(flat[1:], flat[:-1], out=keep[1:])
    return flat[keep]
