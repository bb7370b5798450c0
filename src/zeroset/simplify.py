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
Last, every triangle is checked against the dense mesh over its whole area, and the
longest edge of one that strays, a boundary edge excepted, is split
(`zeroset.within.hold_within`). Boundary vertices stay where they are and boundary edges
are kept: the boundary loops are the dense mesh's own, vertex for vertex, so that pieces of
one mesh simplified apart still meet (`zeroset.tiles`, which then simplifies the band
across their seams against the dense faces beneath it: ``simplify_mesh(reference=)``).
"""

from __future__ import annotations

import numpy as np

from ._kernels._ahead import await_simplify_kernels
from ._kernels.evaluate import closest_points_on_mesh
from ._unique import distinct
from .errors import InputError
from .evaluate import closest_on_arrays
from .neighbours import spatial_order
from .optimization import MeshState, Projection, on_itself
from .surface import Surface
from .thresholds import MAX_FOLD_DEGREES_SIMPLIFY, SAMPLE_MARGIN, UNCERTAINTIES
from .topology import (
    boundary_edges,
    face_area_vectors,
    is_consistently_oriented,
    is_edge_manifold,
)
from .types import Mesh
from .within import dense_points, hold_within

__all__ = ["choose_tolerance", "simplify_mesh", "unbias"]


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


def simplify_mesh(
    mesh: Mesh, tolerance: float, *, reference: Mesh | None = None, under=None
) -> tuple[Mesh, dict]:
    """Few triangles, each within `tolerance` of `mesh` over its whole area.

    Parameters
    ----------
    mesh : Mesh
        Dense, edge-manifold and consistently oriented.
    tolerance : float
        Largest distance allowed between the two meshes, both ways, in data units; 0
        returns `mesh` as it is.
    reference : Mesh, optional
        The dense mesh to stay within `tolerance` of, where `mesh` is already simplified
        from it (a band across the tiles' seams, `zeroset.tiles`); `mesh` itself by
        default.
    under : (F_ref,) bool, optional
        With `reference`: its faces that lie under `mesh`, whose vertices and centroids
        within the margin (``SAMPLE_MARGIN`` times `tolerance`) of `mesh` are the samples;
        the others only continue the reference past `mesh`'s edges, so that triangles
        there are measured against a surface that goes on. All by default.

    Returns
    -------
    mesh : Mesh
        The same boundary loops, vertex for vertex, edge-manifold and oriented like
        `mesh`, without the vertices of no face; `mesh` itself (less those vertices) where
        no fewer triangles stay within the tolerance.
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
    if reference is None:
        samples, on_mesh, normals = _own_samples(mesh)
        points = None
    else:
        under = np.ones(reference.n_faces, dtype=bool) if under is None else under
        reach = SAMPLE_MARGIN * tolerance
        samples, on_mesh, normals = _samples_of(reference, reference.faces[under], mesh, reach)
        points = dense_points(reference, reference.faces[under])
        points = points[closest_on_arrays(points, mesh.vertices, mesh.faces)[2] <= reach]
    # In spatial order, the samples of neighbouring faces lie near in memory.
    order = spatial_order(samples)
    samples, normals, on_mesh = samples[order], normals[order], on_mesh.take(order)
    await_simplify_kernels()  # on a fresh install, while a second process compiles them
    state = MeshState(
        mesh.vertices, mesh.faces, samples, on_mesh,
        kappa=0.0, c_rep=0.0, max_fold_degrees=MAX_FOLD_DEGREES_SIMPLIFY, spare=0.0,
        limits=np.full(samples.shape[0], SAMPLE_MARGIN * tolerance),
    )  # fmt: skip
    counts["simplify_collapses"] = state.collapse_within(normals)
    simple = unbias(state.to_mesh(), samples)
    simple, counts["simplify_splits"], counts["simplify_strays"] = hold_within(
        simple, mesh if reference is None else reference, tolerance,
        split_boundary=False, points=points,
    )  # fmt: skip
    if simple.n_faces >= mesh.n_faces:  # a tolerance too fine for the surface's bends
        return mesh, dict.fromkeys(counts, 0)
    return simple, counts


def _own_samples(mesh: Mesh) -> tuple[np.ndarray, Projection, np.ndarray]:
    """The samples of a dense `mesh`: its vertices and centroids (N, 3), on its own faces,
    and their unit normals (N, 3)."""
    samples, itself = on_itself(mesh.vertices, mesh.faces)
    area_vectors = face_area_vectors(mesh.vertices, mesh.faces)
    normals = np.concatenate(
        [_vertex_normals(mesh.faces, mesh.n_vertices, area_vectors), area_vectors]
    )
    return samples, itself, normals / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]


def _samples_of(reference: Mesh, faces: np.ndarray, mesh: Mesh, reach: float):
    """The samples of the `faces` (F', 3) of `reference`: their vertices and centroids
    (N, 3) within `reach` of `mesh`, projected onto its closest faces, and their unit
    normals (N, 3). Where `mesh` was simplified from `reference` within `reach`, one
    farther lies past its edge, closer to the faces around it."""
    area_vectors = face_area_vectors(reference.vertices, faces)
    corners = distinct(faces)
    normals = np.concatenate(
        [_vertex_normals(faces, reference.n_vertices, area_vectors)[corners], area_vectors]
    )
    samples = np.concatenate([reference.vertices[corners], reference.vertices[faces].mean(axis=1)])
    face, bary, distance2 = closest_points_on_mesh(samples, mesh.vertices, mesh.faces)
    near = distance2 <= reach**2
    on_mesh = Projection(face=face[near], bary=bary[near], distance2=distance2[near])
    normals = normals[near] / np.maximum(np.linalg.norm(normals[near], axis=1), 1e-300)[:, None]
    return samples[near], on_mesh, normals


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
    shift[boundary_edges(faces).ravel()] = 0.0
    return Mesh(vertices=vertices + shift[:, None] * vertex_normals, faces=faces)


def _vertex_normals(faces: np.ndarray, n_vertices: int, area_vectors: np.ndarray) -> np.ndarray:
    """(V, 3) the sum of the area vectors (F, 3) of each vertex's faces (not normalised)."""
    corners = faces.reshape(-1)
    return np.column_stack(
        [np.bincount(corners, np.repeat(area_vectors[:, k], 3), n_vertices) for k in range(3)]
    )
