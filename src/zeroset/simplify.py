"""Few triangles within a stated distance of the dense mesh.

Phase 1's dense mesh (after stage "refine": its vertices on the smooth local surface, its
chords within the refinement's sag) samples the surface finely. `simplify_mesh` collapses
its edges while every sample (its vertices and face centroids) stays within the tolerance
of the new triangles, on a triangle that faces within ``MAX_FOLD_DEGREES_SIMPLIFY`` of the
sample's own normal. Where the surface bends little an edge may be long, so triangles grow
long along the direction of least curvature (a pipe's axis) and stay short across it: the
error decides their shape, not a target edge length.

The collapse is phase 2's (`zeroset._kernels.optimize`: Hoppe et al. 1993, §4, with its
legality and fold tests), with the tolerance as the constraint in place of the energy, and
onto one of the edge's ends (a half-edge collapse): every vertex stays a vertex of the
dense mesh, on the surface, so no vertex strays between the samples. Where an edge does not
collapse, it is swapped for the other diagonal when that brings the samples nearer within
the same limits. The chords then lie inside a convex surface; `unbias` moves every vertex
along its normal by the mean sag of its faces, so that the signed error averages out.
Last, every triangle is checked against the dense mesh over its whole area
(`two_sided_errors`), and the longest edge of one that strays is split. Boundary vertices
stay where they are and boundary edges are kept: the boundary loops are the dense mesh's
own.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._kernels._ahead import await_simplify_kernels
from ._kernels.evaluate import build_hierarchy, closest_points_on_mesh
from ._unique import distinct
from .errors import InputError
from .evaluate import closest_on_arrays
from .neighbours import spatial_order
from .optimization import MeshState, Projection
from .refine import split_edges
from .surface import Surface
from .thresholds import (
    CHECK_ROUNDS,
    MAX_FOLD_DEGREES_SIMPLIFY,
    SAMPLE_MARGIN,
    UNCERTAINTIES,
)
from .topology import (
    boundary_loops,
    face_area_vectors,
    is_consistently_oriented,
    is_edge_manifold,
    undirected_edges,
)
from .types import Mesh

__all__ = ["choose_tolerance", "simplify_mesh", "triangle_grid", "two_sided_errors", "unbias"]


def choose_tolerance(
    surface: Surface, noise: float, chord: float, given: float | None
) -> tuple[float, str]:
    """The tolerance of `simplify_mesh` (data units) and one line on how it was chosen.

    `given` (data units) when not None; else ``UNCERTAINTIES`` times the surface's own
    uncertainty for points of noise level `noise` (`zeroset.surface.Surface.uncertainty`),
    a mesh that close to the fitted surface differing from it by less than the fit itself
    is known, but no less than `chord`, the sag the dense mesh's own chords may have
    (R45: `zeroset.refine.sag_tolerance` where the surface bends little): the dense mesh is not
    followed closer than it follows the surface. A surface that states no uncertainty
    keeps the dense mesh (0).
    """
    if given is not None:
        return float(given), f"tolerance = {float(given):.4g}: given"
    uncertainty = surface.uncertainty(noise)
    if uncertainty is None:
        return 0.0, "tolerance = 0: the surface states no uncertainty; the dense mesh is kept"
    tolerance = UNCERTAINTIES * uncertainty
    note = (
        f"{UNCERTAINTIES:g} x the surface's uncertainty {uncertainty:.4g} "
        f"(noise {noise:.4g} x sqrt(6 / points per jet))"
    )
    if chord > tolerance:
        return chord, f"tolerance = {chord:.4g}: the dense mesh's chord sag (above {note})"
    return tolerance, f"tolerance = {tolerance:.4g}: {note}"


def simplify_mesh(mesh: Mesh, tolerance: float) -> tuple[Mesh, dict]:
    """Few triangles, each within `tolerance` of `mesh` over its whole area.

    Parameters
    ----------
    mesh : Mesh
        Dense, edge-manifold and consistently oriented.
    tolerance : float
        Largest distance allowed between the two meshes, both ways, in data units; 0
        returns `mesh` as it is.

    Returns
    -------
    mesh : Mesh
        The same boundary loops, edge-manifold and oriented like `mesh`, without the
        vertices of no face; `mesh` itself (less those vertices) where no fewer triangles
        stay within the tolerance.
    counts : dict
        ``simplify_collapses``; ``simplify_splits``, edges split where a triangle strayed;
        ``simplify_strays``, triangles still farther than the tolerance after the last
        check round (see `two_sided_errors`).

    Raises
    ------
    InputError
        If `tolerance` is negative or not finite, or `mesh` is not edge-manifold and
        consistently oriented.
    """
    tolerance = float(tolerance)
    if not np.isfinite(tolerance) or tolerance < 0.0:
        raise InputError(f"tolerance must be a finite distance >= 0; got {tolerance!r}")
    counts = {"simplify_collapses": 0, "simplify_splits": 0, "simplify_strays": 0}
    if tolerance == 0.0 or mesh.n_faces == 0:
        return mesh, counts
    if not (is_edge_manifold(mesh.faces) and is_consistently_oriented(mesh.faces)):
        raise InputError("mesh is not edge-manifold and consistently oriented")
    used = distinct(mesh.faces)
    if used.size < mesh.n_vertices:  # a vertex of no face is no sample of the surface
        mesh = Mesh(vertices=mesh.vertices[used], faces=np.searchsorted(used, mesh.faces))
    samples = np.concatenate([mesh.vertices, mesh.vertices[mesh.faces].mean(axis=1)])
    area_vectors = face_area_vectors(mesh.vertices, mesh.faces)
    normals = np.concatenate(
        [_vertex_normals(mesh.faces, mesh.n_vertices, area_vectors), area_vectors]
    )
    normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    # In spatial order, the samples of neighbouring faces lie near in memory.
    order = spatial_order(samples)
    samples, normals, itself = samples[order], normals[order], _on_itself(mesh)
    on_itself = Projection(
        face=itself.face[order], bary=itself.bary[order], distance2=itself.distance2[order]
    )
    await_simplify_kernels()  # on a fresh install, while a second process compiles them
    state = MeshState(
        mesh.vertices, mesh.faces, samples, on_itself,
        kappa=0.0, c_rep=0.0, max_fold_degrees=MAX_FOLD_DEGREES_SIMPLIFY, spare=0.0,
    )  # fmt: skip
    counts["simplify_collapses"] = state.collapse_within(SAMPLE_MARGIN * tolerance, normals)
    simple = unbias(state.to_mesh(), samples)
    # Every measured point within the margin, so that what lies between them stays within
    # the tolerance; past the last round, what strays past the tolerance itself is counted.
    check = _Check.of(simple, mesh)
    for _ in range(CHECK_ROUNDS):
        strays = check.errors() > SAMPLE_MARGIN * tolerance
        if not strays.any():
            break
        simple, split, kept = _split_strays(check, strays)
        counts["simplify_splits"] += split
        check = check.after_split(simple, kept)
    errors = check.errors()
    counts["simplify_strays"] = int(np.count_nonzero(errors > tolerance))
    if simple.n_faces >= mesh.n_faces:  # a tolerance too fine for the surface's bends
        return mesh, dict.fromkeys(counts, 0)
    return simple, counts


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
    def of(cls, simple: Mesh, dense: Mesh) -> _Check:
        """Measure every triangle of `simple` against `dense`."""
        length = np.linalg.norm(dense.vertices[dense.faces[:, 1]]
                                - dense.vertices[dense.faces[:, 0]], axis=1)  # fmt: skip
        spacing = max(float(np.median(length)), 1e-300)
        edges = undirected_edges(dense.faces)[0]
        points = np.concatenate([dense.vertices, dense.vertices[edges].mean(axis=1),
                                 dense.vertices[dense.faces].mean(axis=1)])  # fmt: skip
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


def unbias(mesh: Mesh, samples: np.ndarray) -> Mesh:
    """The mesh with every vertex moved along its normal so that the `samples` (N, 3) of
    the surface it approximates lie as far outside its faces as inside, on average.

    Each face's offset is the mean signed distance of the samples whose closest point lies
    on it (along its normal); each vertex moves by the area-weighted mean offset of its
    faces. Chords of a convex surface lie inside it; this moves them out by their mean sag.
    Boundary vertices stay where they are.
    """
    vertices, faces = mesh.vertices, mesh.faces
    closest, face, _ = closest_on_arrays(samples, vertices, faces)
    area_vectors = face_area_vectors(vertices, faces)
    area = np.linalg.norm(area_vectors, axis=1)
    normals = area_vectors / np.maximum(area, 1e-300)[:, None]
    signed = np.einsum("ij,ij->i", samples - closest, normals[face])
    held = np.bincount(face, minlength=faces.shape[0])
    offset = np.bincount(face, signed, minlength=faces.shape[0]) / np.maximum(held, 1)
    weight = np.bincount(faces.reshape(-1), np.repeat(area, 3), minlength=mesh.n_vertices)
    shift = np.bincount(faces.reshape(-1), np.repeat(area * offset, 3), mesh.n_vertices)
    vertex_normals = _vertex_normals(faces, mesh.n_vertices, area_vectors)
    vertex_normals /= np.maximum(np.linalg.norm(vertex_normals, axis=1), 1e-300)[:, None]
    shift /= np.maximum(weight, 1e-300)
    shift[np.concatenate([np.zeros(0, dtype=np.int64), *boundary_loops(faces)])] = 0.0
    return Mesh(vertices=vertices + shift[:, None] * vertex_normals, faces=faces)


def _on_itself(mesh: Mesh) -> Projection:
    """The projection of the vertices (each of some face) and then the face centroids of
    `mesh` onto it: each vertex at a corner of one of its faces, each centroid at the
    middle of its face."""
    n_v, n_f = mesh.n_vertices, mesh.n_faces
    face_of_vertex = np.empty(n_v, dtype=np.int64)
    face_of_vertex[mesh.faces.ravel()] = np.repeat(np.arange(n_f), 3)
    corner = np.argmax(mesh.faces[face_of_vertex] == np.arange(n_v)[:, None], axis=1)
    bary = np.zeros((n_v, 3))
    bary[np.arange(n_v), corner] = 1.0
    return Projection(
        face=np.concatenate([face_of_vertex, np.arange(n_f)]),
        bary=np.concatenate([bary, np.full((n_f, 3), 1.0 / 3.0)]),
        distance2=np.zeros(n_v + n_f),
    )


def _vertex_normals(faces: np.ndarray, n_vertices: int, area_vectors: np.ndarray) -> np.ndarray:
    """(V, 3) the sum of the area vectors (F, 3) of each vertex's faces (not normalised)."""
    corners = faces.reshape(-1)
    return np.column_stack(
        [np.bincount(corners, np.repeat(area_vectors[:, k], 3), n_vertices) for k in range(3)]
    )


def _split_strays(check: _Check, strays: np.ndarray) -> tuple[Mesh, int, np.ndarray]:
    """Split the longest edge of every straying triangle (F,) bool of ``check.simple``;
    each new vertex goes to its closest point on ``check.dense``. Returns the mesh, the
    edges split, and each old face's index in the new mesh (-1 where it was split;
    `split_edges` keeps the others first, in order)."""
    simple, dense = check.simple, check.dense
    edges, corner_edge, _ = undirected_edges(simple.faces)
    corners = simple.vertices[simple.faces]
    length = np.linalg.norm(corners[:, [1, 2, 0]] - corners, axis=2)
    longest = corner_edge[np.arange(simple.n_faces), np.argmax(length, axis=1)]
    marked = np.zeros(edges.shape[0], dtype=bool)
    marked[longest[strays]] = True
    split = split_edges(simple, marked)
    vertices = split.vertices.copy()
    new = np.arange(simple.n_vertices, split.n_vertices)
    vertices[new] = closest_on_arrays(
        vertices[new], dense.vertices, dense.faces, hierarchy=check.tree
    )[0]
    unchanged = ~marked[corner_edge].any(axis=1)
    kept = np.where(unchanged, np.cumsum(unchanged) - 1, -1)
    return Mesh(vertices=vertices, faces=split.faces), int(np.count_nonzero(marked)), kept
