"""The clock convention: where 12 o'clock is, carried along a centreline."""

from __future__ import annotations

import numpy as np

__all__ = ["UP", "clock_angles", "transport_frames", "unit"]

#: The default "up" of the world: 12 o'clock lies towards it.
UP = (0.0, 0.0, 1.0)
#: A pipe starting closer than this to `UP` (degrees) takes +y as its 12 o'clock instead.
STEEP = 30.0


def unit(v: np.ndarray) -> np.ndarray:
    """`v` (..., 3) scaled to unit length along its last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def transport_frames(tangents: np.ndarray, up=UP) -> np.ndarray:
    """(M, 3) unit 12 o'clock directions along a centreline with (M, 3) unit `tangents`.

    The first is `up` projected onto the first cross-section, or +y when the pipe starts
    within `STEEP` degrees of `up` (a vertical pipe); each next one is the previous
    projected onto the next cross-section (parallel transport), so the frame does not
    twist along bends.
    """
    up = unit(np.asarray(up, dtype=np.float64))
    if abs(float(up @ tangents[0])) > np.cos(np.radians(STEEP)):
        up = np.array([0.0, 1.0, 0.0]) if abs(tangents[0, 1]) < 0.9 else np.array([1.0, 0, 0])
    frames = np.empty_like(tangents)
    current = up
    for index, t in enumerate(tangents):
        current = unit(current - (current @ t) * t)
        frames[index] = current
    return frames


def clock_angles(radial: np.ndarray, tangents: np.ndarray, ups: np.ndarray) -> np.ndarray:
    """(N,) clock angles in degrees [0, 360) of (N, 3) `radial` directions.

    0 is 12 o'clock (`ups`), and the angle grows clockwise seen looking along the
    centreline (`tangents`), so 90 degrees (3 o'clock) is ``tangent x up``.
    """
    right = np.cross(tangents, ups)
    angle = np.degrees(
        np.arctan2(np.einsum("ij,ij->i", radial, right), np.einsum("ij,ij->i", radial, ups))
    )
    return np.mod(angle, 360.0)
