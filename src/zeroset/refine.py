"""Vertices onto the surface, and triangles small enough for its curvature.

Marching cubes puts each vertex where the field, interpolated linearly along a lattice
edge, changes sign, and its flat triangles cut the chords of a curved surface: a convex
surface comes out too small by up to L^2 kappa / 8 for edges of length L. Projecting the
vertices onto the zero set of a smooth local surface (`zeroset.surface`, the blended jets
by default) removes the first error;
splitting the edges that sag too far and projecting the new vertices removes the second,
only where the surface bends. Topology and boundaries are kept: a split
edge keeps its faces, a boundary edge stays a boundary.
"""

from __future__ import annotations

import numpy as np

from .surface import Surface
from .thresholds import CHORD_NOISE, CHORD_RELATIVE, MAX_LEVELS, PROJECTION_STEPS
from .topology import face_area_vectors, undirected_edges, undo_turned_faces
from .types import Mesh

__all__ = ["project_to_surface", "refine_mesh", "sag_tolerance", "sagging_edges", "split_edges"]


def sag_tolerance(curvature, noise: float) -> np.ndarray:
    """(N,) chord sag allowed, in data units, where the largest curvature is `curvature` (N,).

    ``CHORD_RELATIVE / kappa`` or ``CHORD_NOISE * noise``, whichever is larger.
    """
    kappa = np.maximum(np.asarray(curvature, dtype=np.float64), 1e-300)
    return np.maximum(CHORD_RELATIVE / kappa, CHORD_NOISE * noise)


def project_to_surface(mesh: Mesh, surface: Surface, *, steps: int = PROJECTION_STEPS):
    """Move every vertex onto the zero set of `surface`; no triangle may turn over.

    Each step is ``x <- x - f(x) g / |g|^2`` with f the surface's distance and g its
    gradient. A triangle whose normal turns by more than 90 degrees brings its three
    vertices back to where they were before the step; this repeats until no triangle turns.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface

    Returns
    -------
    mesh : Mesh
        The same faces with projected vertices.
    held : int
        Vertices kept back so that no triangle turned over.
    """
    vertices = mesh.vertices.copy()
    faces = mesh.faces
    before = face_area_vectors(vertices, faces)
    held = np.zeros(vertices.shape[0], dtype=bool)
    for _ in range(steps):
        values, gradients = surface.evaluate(vertices)
        squared = np.einsum("ij,ij->i", gradients, gradients)
        step = np.where(squared > 0.25, values / np.maximum(squared, 0.25), 0.0)
        moved = vertices - step[:, None] * gradients
        moved[held] = vertices[held]
        vertices, back = undo_turned_faces(moved, vertices, faces, before)
        held |= back
    return Mesh(vertices=vertices, faces=faces), int(np.count_nonzero(held))


def split_edges(mesh: Mesh, marked: np.ndarray) -> Mesh:
    """Split the marked edges at their midpoints and re-triangulate each face (orientation kept).

    A face with three marked edges becomes four, with two becomes three (the quad cut by
    its shorter diagonal), with one becomes two. Faces on both sides of an edge see the
    same mark, so the result has no T-junction.

    Parameters
    ----------
    mesh : Mesh
    marked : (E,) bool
        One per edge of `zeroset.topology.undirected_edges(mesh.faces)`.

    Returns
    -------
    Mesh
        The old vertices first, then one per marked edge in edge order; the faces with no
        marked edge first, in their order, then the pieces of the others.
    """
    faces = mesh.faces
    edges, corner_edge, _ = undirected_edges(faces)
    middle = np.full(edges.shape[0], -1, dtype=np.int64)
    middle[marked] = mesh.n_vertices + np.arange(np.count_nonzero(marked))
    vertices = np.concatenate(
        [mesh.vertices, (mesh.vertices[edges[marked, 0]] + mesh.vertices[edges[marked, 1]]) / 2]
    )
    # Edge i of a face joins its corners i and i + 1; its midpoint or -1.
    mid = middle[corner_edge]
    count = np.count_nonzero(mid >= 0, axis=1)
    # Turn each face so that a single marked edge is edge 0 and a single unmarked one edge 2.
    lone = np.where(count == 1, np.argmax(mid >= 0, axis=1), np.argmax(mid < 0, axis=1) + 1)
    turn = np.where(count % 3 == 0, 0, lone % 3)
    order = (np.arange(3)[None, :] + turn[:, None]) % 3
    a, b, c = np.take_along_axis(faces, order, axis=1).T
    ab, bc, ca = np.take_along_axis(mid, order, axis=1).T
    pieces = [np.stack([a, b, c], axis=1)[count == 0]]
    one = count == 1
    pieces += [np.stack(t, axis=1)[one] for t in ((a, ab, c), (ab, b, c))]
    two = count == 2
    # The quad a, ab, bc, c: cut along ab-c or a-bc, whichever is shorter.
    short = np.linalg.norm(vertices[ab] - vertices[c], axis=1) <= np.linalg.norm(
        vertices[a] - vertices[bc], axis=1
    )
    pieces.append(np.stack([ab, b, bc], axis=1)[two])
    pieces += [np.stack(t, axis=1)[two & short] for t in ((a, ab, c), (ab, bc, c))]
    pieces += [np.stack(t, axis=1)[two & ~short] for t in ((a, ab, bc), (a, bc, c))]
    three = count == 3
    pieces += [
        np.stack(t, axis=1)[three] for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))
    ]
    return Mesh(vertices=vertices, faces=np.concatenate(pieces))


def sagging_edges(mesh: Mesh, surface: Surface, *, noise: float) -> np.ndarray:
    """(E,) bool: the edges of `zeroset.topology.undirected_edges` whose chords sag too far.

    A chord of length L sags ``L^2 kappa / 8``, with kappa the curvature of `surface` at its
    midpoint (`zeroset.surface.Surface.curvature_at`); it sags too far beyond
    `sag_tolerance`.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface
    noise : float
        Noise level sigma of one point, in data units.
    """
    ends = mesh.vertices[undirected_edges(mesh.faces)[0]]
    length = np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1)
    kappa = np.maximum(surface.curvature_at(ends.mean(axis=1)), 1e-300)
    return length**2 * kappa / 8.0 > sag_tolerance(kappa, noise)


def refine_mesh(mesh: Mesh, surface: Surface, *, noise: float, levels: int | None = None):
    """Project the vertices, then split and project the edges whose chords sag too far.

    A chord of length L on a surface of curvature kappa sags ``L^2 kappa / 8`` below it.
    An edge is split while that exceeds 0.01 % of the radius ``1 / kappa`` or 10 % of the
    `noise`, whichever is larger, with kappa the surface's curvature at the edge's
    midpoint (`sagging_edges`); at most three times.

    Parameters
    ----------
    mesh : Mesh
    surface : Surface
        Smooth (``surface.smooth``).
    noise : float
        Noise level sigma of one point, in data units.
    levels : int, optional
        Split every edge this many times instead.

    Returns
    -------
    mesh : Mesh
    counts : dict
        ``refine_levels`` (rounds of splits), ``edges_split`` and ``projection_held``
        (vertices held back so that no triangle turned over).
    """
    mesh, held = project_to_surface(mesh, surface)
    rounds, split = 0, 0
    for _ in range(MAX_LEVELS if levels is None else levels):
        if levels is None:
            marked = sagging_edges(mesh, surface, noise=noise)
        else:
            marked = np.ones(undirected_edges(mesh.faces)[0].shape[0], dtype=bool)
        if not marked.any():
            break
        mesh, more = project_to_surface(split_edges(mesh, marked), surface)
        rounds, split, held = rounds + 1, split + int(np.count_nonzero(marked)), held + more
    return mesh, {"refine_levels": rounds, "edges_split": split, "projection_held": held}
