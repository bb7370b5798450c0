"""Rigid motions as 4x4 matrices ``[[R, t], [0, 1]]``: ``p -> R p + t``."""

from __future__ import annotations

import numpy as np


def transform(pose: np.ndarray, points: np.ndarray, *, rotate_only: bool = False) -> np.ndarray:
    """Points (N, 3) moved by a rigid (4, 4) `pose`: ``R p + t`` (``R p`` with `rotate_only`)."""
    moved = points @ pose[:3, :3].T
    return moved if rotate_only else moved + pose[:3, 3]
