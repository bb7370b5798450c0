"""Every triangle of a mesh within a distance of a dense mesh, measured over its whole area.

A mesh made of few triangles from a dense one (stage "simplify", phase 2 with a
tolerance) is checked against it both ways: each triangle's own points, on a grid no
coarser than the dense mesh's edges, against the dense mesh, and the dense mesh's points
against the triangles they lie closest to (`two_sided_errors`). `hold_within` splits the
longest edge of every triangle that strays, each new vertex on the dense mesh, and measures
again what the split changed, round after round.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._kernels.evaluate import build_hierarchy, closest_points_on_mesh
from ._unique import distinct
from .evaluate import closest_on_arrays
from .neighbours import spatial_order
from .refine import split_edges
from .thresholds import CHECK_ROUNDS, SAMPLE_MARGIN
from .topology import undirected_edges
from .types import Mesh

__all__ = ["dense_points", "hold_within", "triangle_grid", "two_sided_errors"]


def hold_within(
    simple: Mesh, dense: Mesh, tolerance: float, *, split_boundary=True, points=None
) -> tuple[Mesh, int, int]:
    """`simple` with the longest edge of every triangle farther than ``SAMPLE_MARGIN``
    times `tolerance` from `dense` (`two_sided_errors`) split, each new vertex moved to
    its closest point on `dense`, in rounds until none is, at most ``CHECK_ROUNDS``.
    Without `split_boundary` the longest edge that is not a boundary edge: the boundary
    loops stay vertex for vertex (a triangle of boundary edges only stays as it is).
    `points` (P, 3), when given, are the points of `dense` measured back onto `simple`
    in place of all of its own (`dense` may then reach beyond `simple`).

    Every measured point within the margin, so that what lies between them stays within
    the tolerance. Returns the mesh, the edges split, and the triangles still farther than
    `tolerance` itself after the last round.
    """
    check = _Check.of(simple, dense, points)
    splits = 0
    for _ in range(CHECK_ROUNDS):
        strays = check.errors() > SAMPLE_MARGIN * tolerance
        if not strays.any():
            break
        simple, split, kept = _split_strays(check, strays, split_boundary)
        if split == 0:
            break
        splits += split
        check = check.after_split(simple, kept)
    return simple, splits, int(np.count_nonzero(check.errors() > tolerance))


def two_sided_errors(simple: Mesh, dense: Mesh) -> np.ndarray:
    """(F,) for each triangle of `simple`, the larger of two distances, in data units: the
    farthest of its points from `dense`, and the farthest of the points of `dense` (its
    vertices, edge midpoints and face centroids) whose closest point on `simple` lies on
    it.

    A triangle's points are a grid along its two sides from a corner of its shortest side,
    no coarser than the dense mesh's median edge either way: as many as its area needs,
    also for a long thin triangle.
    """
    return _Check.of(simple, dense).errors()


class _Check(NamedTuple):
    """`two_sided_errors`' two halves, kept so that a split re-measures only what changed:
    `away` (F,) the farthest grid point of each face of `simple` from `dense`; `face`,
    `back` (S,) the face of `simple` closest to each point of `dense` and its distance;
    `points` (S, 3) those points, in `spatial_order`; `spacing` the grid's; `tree` the
    bounding-volume hierarchy of `dense` (`_kernels.evaluate.build_hierarchy`)."""

    simple: Mesh
    dense: Mesh
    tree: tuple
    spacing: float
    away: np.ndarray
    points: np.ndarray
    face: np.ndarray
    back: np.ndarray

    @classmethod
    def of(cls, simple: Mesh, dense: Mesh, points=None) -> _Check:
        """Measure every triangle of `simple` against `dense`; `points` of `dense` in place
        of its vertices, edge midpoints and centroids, when given."""
        length = np.linalg.norm(dense.vertices[dense.faces[:, 1]]
                                - dense.vertices[dense.faces[:, 0]], axis=1)  # fmt: skip
        spacing = max(float(np.median(length)), 1e-300)
        if points is None:
            points = dense_points(dense)
        points = np.ascontiguousarray(points[spatial_order(points)])
        _, face, back = closest_on_arrays(points, simple.vertices, simple.faces, in_order=True)
        tree = build_hierarchy(dense.vertices, dense.faces)
        away = _farthest_from(simple, np.arange(simple.n_faces), dense, tree, spacing)
        return cls(simple, dense, tree, spacing, away, points, face, back)

    def errors(self) -> np.ndarray:
        """(F,) the two-sided error of each face of `simple`."""
        error = self.away.copy()
        np.maximum.at(error, self.face, self.back)
        return error

    def after_split(self, simple: Mesh, kept: np.ndarray) -> _Check:
        """The check of `simple`, the old mesh split by `_split_strays`: `kept` (F_old,)
        gives each old face's index in `simple`, -1 where it was split; the faces after
        the kept ones are new. A point of `dense` keeps its kept face unless a new face is
        closer; a point on a split face is measured again against all of `simple`."""
        n_kept = np.count_nonzero(kept >= 0)
        new = np.arange(n_kept, simple.n_faces)
        face, back = kept[self.face], self.back.copy()
        lost = face < 0
        _, face[lost], back[lost] = closest_on_arrays(
            self.points[lost], simple.vertices, simple.faces, in_order=True
        )
        near_face, _, near2 = closest_points_on_mesh(
            self.points, simple.vertices, simple.faces[new], in_order=True, within=back
        )
        closer = near_face >= 0
        face[closer], back[closer] = new[near_face[closer]], np.sqrt(near2[closer])
        away = np.empty(simple.n_faces)
        away[kept[kept >= 0]] = self.away[kept >= 0]
        away[new] = _farthest_from(simple, new, self.dense, self.tree, self.spacing)
        return self._replace(simple=simple, away=away, face=face, back=back)


def _farthest_from(
    mesh: Mesh, rows: np.ndarray, dense: Mesh, tree: tuple, spacing: float
) -> np.ndarray:
    """(R,) for each face `rows` (R,) of `mesh`, the farthest point of its grid
    (`triangle_grid` at `spacing`) from `dense`, whose hierarchy is `tree`."""
    points, face = triangle_grid(Mesh(vertices=mesh.vertices, faces=mesh.faces[rows]), spacing)
    _, _, away = closest_on_arrays(points, dense.vertices, dense.faces, hierarchy=tree)
    farthest = np.zeros(rows.size)
    np.maximum.at(farthest, face, away)
    return farthest


def triangle_grid(mesh: Mesh, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (P, 3) on every triangle of `mesh`, and the face (P,) of each: the points of
    each side at most `spacing` apart (corners included), and inside a grid of at most
    `spacing` along the longest side and across it, so that a long thin triangle takes
    about its area over the spacing squared."""
    corners = mesh.vertices[mesh.faces]
    sides = corners[:, [1, 2, 0]] - corners  # side k runs from corner k to corner k + 1
    length = np.linalg.norm(sides, axis=2)
    # Along each side.
    steps = np.maximum(1, np.ceil(length / spacing)).astype(np.int64).ravel()
    side = np.repeat(np.arange(steps.size), steps)
    fraction = (np.arange(side.size) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[side]
    on_sides = corners.reshape(-1, 3)[side] + fraction[:, None] * sides.reshape(-1, 3)[side]
    # Inside: (u, v) along the longest side ab and across it, towards the corner c.
    rows = np.arange(mesh.n_faces)
    k = np.argmax(length, axis=1)
    a, c = corners[rows, k], corners[rows, (k + 2) % 3]
    base = length[rows, k]
    along = sides[rows, k] / np.maximum(base, 1e-300)[:, None]
    c_u = np.einsum("ij,ij->i", c - a, along)
    across = (c - a) - c_u[:, None] * along
    height = np.linalg.norm(across, axis=1)
    across /= np.maximum(height, 1e-300)[:, None]
    n_u = np.maximum(1, np.ceil(base / spacing)).astype(np.int64)
    n_v = np.maximum(1, np.ceil(height / spacing)).astype(np.int64)
    counts = (n_u + 1) * (n_v + 1)
    face = np.repeat(rows, counts)
    index = np.arange(face.size) - np.repeat(np.cumsum(counts) - counts, counts)
    u = (index // (n_v + 1)[face]) * (base / n_u)[face]
    v = (index % (n_v + 1)[face]) * (height / n_v)[face]
    slack = 1e-12 * base[face] * height[face]
    keep = (v * c_u[face] <= height[face] * u + slack) & (
        v * (base - c_u)[face] <= height[face] * (base[face] - u) + slack
    )
    face, u, v = face[keep], u[keep, None], v[keep, None]
    inside = a[face] + u * along[face] + v * across[face]
    return np.concatenate([on_sides, inside]), np.concatenate([side // 3, face])


def dense_points(mesh: Mesh, faces=None) -> np.ndarray:
    """(P, 3) the points of `mesh` a check measures back: the vertices, edge midpoints
    and centroids of its `faces` (F', 3) (all of them, and every vertex, by default)."""
    corners = mesh.vertices if faces is None else mesh.vertices[distinct(faces)]
    faces = mesh.faces if faces is None else faces
    edges = undirected_edges(faces)[0]
    return np.concatenate([corners, mesh.vertices[edges].mean(axis=1),
                           mesh.vertices[faces].mean(axis=1)])  # fmt: skip


def _split_strays(
    check: _Check, strays: np.ndarray, split_boundary: bool
) -> tuple[Mesh, int, np.ndarray]:
    """Split the longest edge (other than a boundary edge, unless `split_boundary`) of
    every straying triangle (F,) bool of ``check.simple``; each new vertex goes to its
    closest point on ``check.dense``. Returns the mesh, the edges split, and each old
    face's index in the new mesh (-1 where it was split; `split_edges` keeps the others
    first, in order)."""
    simple, dense = check.simple, check.dense
    edges, corner_edge, face_count = undirected_edges(simple.faces)
    corners = simple.vertices[simple.faces]
    length = np.linalg.norm(corners[:, [1, 2, 0]] - corners, axis=2)
    if not split_boundary:
        length[face_count[corner_edge] < 2] = -1.0
    rows = np.arange(simple.n_faces)
    pick = np.argmax(length, axis=1)
    marked = np.zeros(edges.shape[0], dtype=bool)
    marked[corner_edge[rows, pick][strays & (length[rows, pick] >= 0.0)]] = True
    split = split_edges(simple, marked)
    vertices = split.vertices.copy()
    new = np.arange(simple.n_vertices, split.n_vertices)
    vertices[new] = closest_on_arrays(
        vertices[new], dense.vertices, dense.faces, hierarchy=check.tree
    )[0]
    unchanged = ~marked[corner_edge].any(axis=1)
    kept = np.where(unchanged, np.cumsum(unchanged) - 1, -1)
    return Mesh(vertices=vertices, faces=split.faces), int(np.count_nonzero(marked)), kept
