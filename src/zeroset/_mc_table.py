"""Marching-cubes case table built from face rules, so neighbouring cubes always agree.

Each of the 256 sign configurations is triangulated by tracing the zero set over the
cube's six faces: on every face the crossings are joined so that each positive corner
run is cut off (a rule that depends on the face's four values only, so the two cubes
sharing a face draw the same segments). The segments chain into closed loops, and each
loop is fanned into triangles. Segments are directed consistently with the face's
outward orientation, so a shared face contributes opposite half-edges to its two cubes:
the result is an edge-manifold, consistently oriented mesh with no cracks.

Each loop is one patch of surface inside the cube; the Method of Cubes puts one vertex on
each patch (`patch_table`).
"""

from __future__ import annotations

from functools import cache

import numpy as np

__all__ = [
    "CORNER_OFFSETS",
    "EDGE_AXIS",
    "EDGE_CORNER",
    "FACE_CORNERS",
    "case_table",
    "patch_table",
]

#: (8, 3) int64 lattice offset of cube corner ``c = x + 2y + 4z``.
CORNER_OFFSETS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)], dtype=np.int64)

_EDGES = [(a, a | (1 << axis)) for axis in range(3) for a in range(8) if not a & (1 << axis)]
#: (12,) int64 lower corner of each cube edge.
EDGE_CORNER = np.array([a for a, _ in _EDGES], dtype=np.int64)
#: (12,) int64 axis (0, 1, 2) each cube edge runs along.
EDGE_AXIS = np.array([(b ^ a).bit_length() - 1 for a, b in _EDGES], dtype=np.int64)
_EDGE_ID = {frozenset(e): i for i, e in enumerate(_EDGES)}


def _faces() -> list[list[int]]:
    """Corners of the six faces, counter-clockwise seen from outside the cube."""
    faces = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            ring = [(0, 0), (1, 0), (1, 1), (0, 1)]
            corners = [(side << axis) | (a << u) | (b << v) for a, b in ring]
            faces.append(corners if side else corners[::-1])
    return faces


def _segments(config: int) -> list[tuple[int, int]]:
    """Directed zero-set segments (edge id, edge id) on the faces of one configuration."""
    segments = []
    for ring in _faces():
        positive = [bool(config >> c & 1) for c in ring]
        for k in range(4):
            # Start of a run of positive corners: walk to its end and join the two crossings.
            if positive[k] and not positive[k - 1]:
                end = k
                while positive[(end + 1) % 4]:
                    end = (end + 1) % 4
                enter = _EDGE_ID[frozenset((ring[k - 1], ring[k]))]
                leave = _EDGE_ID[frozenset((ring[end], ring[(end + 1) % 4]))]
                segments.append((leave, enter))
    return segments


def _loops(segments: list[tuple[int, int]]) -> list[list[int]]:
    """Chain directed segments into closed loops of edge ids."""
    following = dict(segments)
    loops = []
    while following:
        start, nxt = following.popitem()
        loop = [start]
        while nxt != start:
            loop.append(nxt)
            nxt = following.pop(nxt)
        loops.append(loop)
    return loops


def _shares_face(a: int, b: int) -> bool:
    """Whether cube edges a and b bound a common face."""
    corners = set(_EDGES[a]) | set(_EDGES[b])
    return any(corners <= set(ring) for ring in _faces())


def _fan(loop: list[int]) -> list[tuple[int, int, int]]:
    """Fan a loop into triangles from an apex whose diagonals leave the cube's faces.

    A diagonal lying in a face could be drawn by the neighbouring cube as well, which
    would give one edge four triangles; choosing the apex avoids that.
    """
    n = len(loop)
    for shift in range(n):
        ring = loop[shift:] + loop[:shift]
        if not any(_shares_face(ring[0], ring[i]) for i in range(2, n - 1)):
            return [(ring[0], ring[i], ring[i + 1]) for i in range(1, n - 1)]
    raise AssertionError(f"no face-free fan for loop {loop}")


#: (6, 4) int64 corners of cube face ``2 * axis + side`` (the face at ``axis = side``), in
#: order around the face.
FACE_CORNERS = np.array(_faces(), dtype=np.int64)


@cache
def case_table() -> tuple[np.ndarray, np.ndarray]:
    """Return the triangulation of every sign configuration.

    Returns
    -------
    triangles : (256, T, 3) int64
        Cube edge ids of each triangle; rows past ``counts[config]`` are -1.
    counts : (256,) int64
        Triangles per configuration. Bit ``c`` of a configuration is set when corner
        ``c`` has a positive value; triangles face the positive side.
    """
    per_config = [[t for loop in _loops(_segments(c)) for t in _fan(loop)] for c in range(256)]
    width = max(len(t) for t in per_config)
    triangles = np.full((256, width, 3), -1, dtype=np.int64)
    for config, tris in enumerate(per_config):
        if tris:
            triangles[config, : len(tris)] = tris
    return triangles, np.array([len(t) for t in per_config], dtype=np.int64)


@cache
def patch_table() -> tuple[np.ndarray, np.ndarray]:
    """Return which surface patch of its cube every crossed cube edge belongs to.

    Returns
    -------
    patch : (256, 12) int64
        Patch (loop of `case_table`) of each cube edge, -1 where the edge is not crossed.
    counts : (256,) int64
        Patches per configuration: 0 without a sign change, up to 4.
    """
    patch = np.full((256, 12), -1, dtype=np.int64)
    counts = np.zeros(256, dtype=np.int64)
    for config in range(256):
        loops = _loops(_segments(config))
        for index, loop in enumerate(loops):
            patch[config, loop] = index
        counts[config] = len(loops)
    return patch, counts
