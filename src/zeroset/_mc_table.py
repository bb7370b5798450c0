"""Marching-cubes case table built from face rules, so neighbouring cubes always agree.

Each of the 256 sign configurations is triangulated by tracing the zero set over the
cube's six faces: on every face the crossings are joined so that each positive corner
run is cut off. A face whose signs alternate around it is ambiguous: its two positive
corners are either cut off one by one, or joined through the face's centre (each negative
corner cut off instead). Which, is a bit per face (`JOIN_SHIFT`), set by the asymptotic
decider (Nielson & Hamann 1991, `joined_faces`) from the face's four values only, so the
two cubes sharing a face draw the same segments, and a field and its negative give the
same surface. The segments chain into closed loops, and each loop is fanned into
triangles. Segments are directed consistently with the face's outward orientation, so a
shared face contributes opposite half-edges to its two cubes: the result is an
edge-manifold, consistently oriented mesh with no cracks.

A case is ``config | joined << JOIN_SHIFT``: bit ``c`` of ``config`` is set when corner
``c`` is positive, bit ``f`` of ``joined`` when face ``f`` joins its positive corners.

Each loop is one patch of surface inside the cube; the Method of Cubes puts one vertex on
each patch (`patch_table`).
"""

from __future__ import annotations

from functools import cache

import numpy as np

__all__ = [
    "CENTRE",
    "CORNER_OFFSETS",
    "EDGE_AXIS",
    "EDGE_CORNER",
    "FACE_CORNERS",
    "JOIN_SHIFT",
    "alternating",
    "case_table",
    "joined_faces",
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


def _segments(case: int) -> list[tuple[int, int]]:
    """Directed zero-set segments (edge id, edge id) on the faces of one case."""
    segments = []
    for face, ring in enumerate(_faces()):
        positive = [bool(case >> c & 1) for c in ring]
        runs = []  # (enter, leave) crossings of each run of positive corners, around the face
        for k in range(4):
            if positive[k] and not positive[k - 1]:
                end = k
                while positive[(end + 1) % 4]:
                    end = (end + 1) % 4
                enter = _EDGE_ID[frozenset((ring[k - 1], ring[k]))]
                leave = _EDGE_ID[frozenset((ring[end], ring[(end + 1) % 4]))]
                runs.append((enter, leave))
        # Each run's crossings are joined, cutting it off; a joined face's two runs are one,
        # so each run's leaving crossing is joined to the other's entering one.
        step = 1 if len(runs) == 2 and case >> (JOIN_SHIFT + face) & 1 else 0
        segments += [(runs[i][1], runs[(i + step) % len(runs)][0]) for i in range(len(runs))]
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


def _fan(loop: tuple[int, ...]) -> list[tuple[int, int, int]]:
    """Fan a loop into triangles from an apex whose diagonals leave the cube's faces.

    A diagonal lying in a face could be drawn by the neighbouring cube as well, which
    would give one edge four triangles; choosing the apex avoids that. A loop that winds
    through joined faces may have no such apex; it is fanned from its centre (`CENTRE`).
    """
    n = len(loop)
    for shift in range(n):
        ring = loop[shift:] + loop[:shift]
        if not any(_shares_face(ring[0], ring[i]) for i in range(2, n - 1)):
            return [(ring[0], ring[i], ring[i + 1]) for i in range(1, n - 1)]
    return [(CENTRE, loop[i], loop[(i + 1) % n]) for i in range(n)]


#: (6, 4) int64 corners of cube face ``2 * axis + side`` (the face at ``axis = side``), in
#: order around the face.
FACE_CORNERS = np.array(_faces(), dtype=np.int64)
#: Bit of a case from which its faces' join bits start (above the 8 corner signs).
JOIN_SHIFT = 8
#: Edge id standing for the mean of the crossings of the loop fanned from its centre.
CENTRE = 12
_CASES = 256 << 6


def alternating(positive: np.ndarray) -> np.ndarray:
    """Whether the signs (..., 4) around a face alternate (bool, ...): an ambiguous face."""
    same = (positive[..., 0] == positive[..., 2]) & (positive[..., 1] == positive[..., 3])
    return same & (positive[..., 0] != positive[..., 1])


def joined_faces(values: np.ndarray) -> np.ndarray:
    """Bits (C,) int64 of the faces of each cube (C, 8) that join their positive corners.

    A face joins them where its signs alternate and its bilinear interpolant is positive at
    its saddle point, ``(v0 v2 - v1 v3) / (v0 + v2 - v1 - v3)`` for values ``v0..v3``
    around it (the asymptotic decider, Nielson & Hamann 1991).
    """
    v = values[:, FACE_CORNERS]  # (C, 6, 4)
    saddle = v[..., 0] * v[..., 2] - v[..., 1] * v[..., 3]
    joined = alternating(v > 0.0) & (saddle * (v[..., 0] + v[..., 2] - v[..., 1] - v[..., 3]) > 0)
    return (joined << np.arange(6)).sum(axis=1)


def _canonical() -> np.ndarray:
    """(16384,) int64 each case with the join bits of faces that are not ambiguous cleared:
    the cases that differ only there are one."""
    ambiguous = alternating((np.arange(256)[:, None, None] >> FACE_CORNERS) & 1)  # (256, 6)
    mask = 255 | ((ambiguous << np.arange(6)).sum(axis=1) << JOIN_SHIFT)  # (256,)
    case = np.arange(_CASES)
    return case & mask[case & 255]


@cache
def _loops_of(case: int) -> tuple[tuple[int, ...], ...]:
    """The closed loops of edge ids of a case."""
    return tuple(tuple(loop) for loop in _loops(_segments(case)))


@cache
def case_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the triangulation of every case (``config | joined << JOIN_SHIFT``).

    Returns
    -------
    triangles : (16384, T, 3) int64
        Cube edge ids of each triangle, or `CENTRE`; rows past ``counts[case]`` are -1.
        Triangles face the positive side.
    counts : (16384,) int64
        Triangles per case.
    centre : (16384, 12) bool
        The edges of the loop fanned from its centre, if any (at most one per case).
    """
    canonical, case = np.unique(_canonical(), return_inverse=True)
    loops = [_loops_of(c) for c in canonical.tolist()]
    fans = [[_fan(loop) for loop in row] for row in loops]
    counts = np.array([sum(map(len, row)) for row in fans], dtype=np.int64)
    triangles = np.full((canonical.size, counts.max(), 3), -1, dtype=np.int64)
    centre = np.zeros((canonical.size, 12), dtype=bool)
    for row in range(canonical.size):
        if counts[row]:
            triangles[row, : counts[row]] = [t for fan in fans[row] for t in fan]
        for loop, fan in zip(loops[row], fans[row], strict=True):
            centre[row, list(loop)] |= fan[0][0] == CENTRE
    return triangles[case], counts[case], centre[case]


@cache
def patch_table() -> tuple[np.ndarray, np.ndarray]:
    """Return which surface patch of its cube every crossed cube edge belongs to.

    Returns
    -------
    patch : (16384, 12) int64
        Patch (loop of `case_table`) of each cube edge per case, -1 where the edge is not
        crossed.
    counts : (16384,) int64
        Patches per case: 0 without a sign change, up to 4.
    """
    canonical, case = np.unique(_canonical(), return_inverse=True)
    patch = np.full((canonical.size, 12), -1, dtype=np.int64)
    counts = np.zeros(canonical.size, dtype=np.int64)
    for row, loops in enumerate(map(_loops_of, canonical.tolist())):
        for index, loop in enumerate(loops):
            patch[row, list(loop)] = index
        counts[row] = len(loops)
    return patch[case], counts[case]
