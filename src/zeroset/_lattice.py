"""Integer keys for vertices of the global lattice ``x = origin + cube_size * (i, j, k)``."""

from __future__ import annotations

import numpy as np

from .errors import ReconstructionError

__all__ = ["LIMIT", "decode", "encode", "offset_keys"]

_BITS = 20  # 3 x 20 bits, so an edge key (key << 2 | axis) fits in int64
_BIAS = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1
#: Largest |index| a key can hold, with room for the offsets of a cube's corners and edges.
LIMIT = _BIAS - 64


def encode(ijk: np.ndarray) -> np.ndarray:
    """Return (N,) int64 keys of (N, 3) int64 lattice indices; key order is (i, j, k) order."""
    if ijk.size and (ijk.min() < -LIMIT or ijk.max() >= LIMIT):
        raise ReconstructionError(
            f"the grid would need indices up to {int(np.abs(ijk).max())} (at most {LIMIT}); "
            "the cube size is too small for the cloud's extent: increase cube_size"
        )
    shifted = ijk + _BIAS
    return (shifted[:, 0] << (2 * _BITS)) | (shifted[:, 1] << _BITS) | shifted[:, 2]


def decode(keys: np.ndarray) -> np.ndarray:
    """Return (N, 3) int64 lattice indices of (N,) int64 keys."""
    return (
        np.stack([(keys >> (2 * _BITS)) & _MASK, (keys >> _BITS) & _MASK, keys & _MASK], axis=1)
        - _BIAS
    )


def offset_keys(offsets: np.ndarray) -> np.ndarray:
    """Return (M,) int64 key steps of small (M, 3) offsets: key(a + d) = key(a) + step(d)."""
    return (offsets[:, 0] << (2 * _BITS)) + (offsets[:, 1] << _BITS) + offsets[:, 2]
