"""Mesh repair after contouring: bow-tie vertices, small holes, tiny components."""

from __future__ import annotations

import numpy as np

from ._unique import distinct
from .thresholds import FAN_FRACTIONS
from .topology import boundary_loops, corner_fans, edge_ids, face_components, vertex_normals
from .types import Mesh

__all__ = [
    "fan_samples",
    "fill_small_holes",
    "keep_faces",
    "remove_small_components",
    "split_nonmanifold_vertices",
]


def keep_faces(mesh: Mesh, keep: np.ndarray) -> Mesh:
    """Return the mesh of the faces where `keep` (F,) is true, with unused vertices dropped."""
    faces = mesh.faces[keep]
    used, inverse = np.unique(faces, return_inverse=True)
    return Mesh(vertices=mesh.vertices[used], faces=inverse.reshape(-1, 3).astype(np.int64))


def remove_small_components(mesh: Mesh, min_faces: int) -> tuple[Mesh, int]:
    """Drop components with fewer than `min_faces` faces; return the mesh and how many went."""
    n_components, label = face_components(mesh.faces, mesh.n_vertices)
    if n_components == 0:
        return mesh, 0
    sizes = np.bincount(label, minlength=n_components)
    keep = sizes[label] >= min_faces
    dropped = int(np.count_nonzero(sizes < min_faces))
    return (keep_faces(mesh, keep) if dropped else mesh), dropped


def split_nonmanifold_vertices(mesh: Mesh) -> tuple[Mesh, int]:
    """Give every fan of faces around a vertex its own copy of the vertex.

    Where two face fans touch at a single vertex (a bow-tie, as marching cubes leaves on
    an open boundary), the vertex is duplicated, so that the mesh becomes vertex-manifold
    and each boundary is a simple loop.

    Returns
    -------
    mesh : Mesh
    added : int
        Vertices added.
    """
    faces = mesh.faces
    fan, n_fans = corner_fans(faces, edge_ids(faces, mesh.n_vertices)[0])
    # Number the fans in order of first corner, so unaffected vertices keep their order.
    _, first = np.unique(fan, return_index=True)
    order = np.argsort(first)
    remap = np.empty(n_fans, dtype=np.int64)
    remap[order] = np.arange(n_fans)
    corner_vertex = faces.reshape(-1)
    vertices = mesh.vertices[corner_vertex[first[order]]]
    new_faces = remap[fan].reshape(-1, 3)
    added = n_fans - distinct(corner_vertex).size
    return Mesh(vertices=vertices, faces=new_faces), int(added)


def _width(mesh: Mesh, loop: np.ndarray) -> float:
    """Largest distance between two vertices of `loop`."""
    ring = mesh.vertices[loop]
    return float(np.linalg.norm(ring[:, None] - ring[None], axis=2).max())


def fan_samples(ring: np.ndarray) -> np.ndarray:
    """Points (S, 3) spread over the fan from the centroid of a loop `ring` (K, 3): at
    ``FAN_FRACTIONS`` of the way to each vertex and to each edge's midpoint."""
    centre = ring.mean(axis=0)
    targets = np.concatenate([ring, 0.5 * (ring + np.roll(ring, -1, axis=0))])
    fractions = np.asarray(FAN_FRACTIONS)[:, None, None]
    return (centre + fractions * (targets - centre)).reshape(-1, 3)


def _faces_the_mesh(ring: np.ndarray, normals: np.ndarray) -> bool:
    """Whether the fan over a loop `ring` (K, 3), against the loop's direction, faces the
    way of the unit vertex `normals` (K, 3) along it."""
    centre = ring.mean(axis=0)
    area = np.cross(ring - centre, np.roll(ring, -1, axis=0) - centre).sum(axis=0)
    return float(-area @ normals.sum(axis=0)) > 0.0


def fill_small_holes(
    mesh: Mesh, max_edges: int, *, max_width: float | None = None, closable=None
) -> tuple[Mesh, int, float]:
    """Close boundary loops of at most `max_edges` edges, at most `max_width` across and,
    given `closable`, that it accepts.

    A hole narrower than the data can resolve is a cube that contouring skipped, not a hole
    in the object: where the signed distance is defined within rho+delta of the data on
    either side, a hole up to 2 rho+delta across is closed by Hoppe's rule (thesis 3.2.1,
    3.4.6). The width of a loop is the largest distance between two of its vertices. A
    loop is a hole only if the fan over it faces the way the mesh around it does: the outer
    edge of a patch runs the other way round, and its fan would fold back over the patch.
    A loop of three edges becomes a triangle, a longer one a fan about a new vertex at its
    centroid (no new edge can then duplicate one the mesh has). The mesh must be
    vertex-manifold.

    Parameters
    ----------
    mesh : Mesh
    max_edges : int
    max_width : float, optional
        Data units.
    closable : callable, optional
        ``closable(ring (K, 3)) -> bool`` for the positions of a loop's vertices.

    Returns
    -------
    mesh : Mesh
    filled : int
        Loops closed.
    widest : float
        The largest width of a loop closed, in data units; 0 when none was.
    """
    apexes, new_faces, normals = [], [], None
    filled, widest = 0, 0.0
    for loop in boundary_loops(mesh.faces):
        if len(loop) > max_edges:
            continue
        width = _width(mesh, loop)
        if max_width is not None and not width <= max_width:
            continue
        ring = mesh.vertices[loop]
        if normals is None:
            normals = vertex_normals(mesh)
        if not _faces_the_mesh(ring, normals[loop]):
            continue
        if closable is not None and not closable(ring):
            continue
        # Boundary edges run (v_i, v_i+1) in their faces; the fill runs against them.
        if len(loop) == 3:
            new_faces.append(loop[[0, 2, 1]][None])
        else:
            apex = mesh.n_vertices + len(apexes)
            apexes.append(ring.mean(axis=0))
            new_faces.append(np.column_stack([np.full(len(loop), apex), np.roll(loop, -1), loop]))
        filled += 1
        widest = max(widest, width)
    if not new_faces:
        return mesh, 0, 0.0
    vertices = np.concatenate([mesh.vertices, np.reshape(apexes, (-1, 3))])
    faces = np.concatenate([mesh.faces, *new_faces]).astype(np.int64)
    return Mesh(vertices=vertices, faces=faces), filled, widest
