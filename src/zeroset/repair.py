"""Mesh repair after contouring: bow-tie vertices, small holes, tiny components."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from .topology import boundary_loops, edge_face_counts, face_components, half_edges
from .types import Mesh

__all__ = [
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
    and each boundary is a simple loop. Requires an edge-manifold, consistently oriented mesh.

    Returns
    -------
    mesh : Mesh
    added : int
        Vertices added.
    """
    faces = mesh.faces
    n_corners = faces.size
    half = half_edges(faces)
    tail_corner = np.arange(n_corners)
    head_corner = 3 * (tail_corner // 3) + (tail_corner % 3 + 1) % 3
    key = half[:, 0] * np.int64(mesh.n_vertices) + half[:, 1]
    twin_key = half[:, 1] * np.int64(mesh.n_vertices) + half[:, 0]
    order = np.argsort(key)
    slot = np.minimum(np.searchsorted(key[order], twin_key), n_corners - 1)
    has_twin = key[order][slot] == twin_key
    h1 = tail_corner[has_twin]
    h2 = order[slot[has_twin]]
    # Half-edge h1 = (a, b) and its twin h2 = (b, a) join the corners of a, and of b.
    rows = np.concatenate([tail_corner[h1], head_corner[h1]])
    cols = np.concatenate([head_corner[h2], tail_corner[h2]])
    graph = sparse.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_corners, n_corners))
    _, fan = connected_components(graph, directed=False)
    fans, first = np.unique(fan, return_index=True)
    corner_vertex = faces.reshape(-1)
    remap = np.empty(fans.size, dtype=np.int64)
    remap[np.searchsorted(fans, fan[first])] = np.arange(fans.size)
    new_faces = remap[np.searchsorted(fans, fan)].reshape(-1, 3)
    vertices = mesh.vertices[corner_vertex[first]]
    added = fans.size - np.unique(corner_vertex).size
    return Mesh(vertices=vertices, faces=new_faces), int(added)


def fill_small_holes(mesh: Mesh, max_edges: int) -> tuple[Mesh, int]:
    """Close boundary loops of at most `max_edges` edges with a fan of triangles.

    A gap of a few edges is a cube that contouring skipped, not a hole in the object:
    a hole narrower than rho+delta cannot be resolved from the data (thesis 3.2.1, 3.4.6).
    The fan's apex is chosen so that no new edge duplicates an existing one; a loop with
    no such apex is left open. The mesh must be vertex-manifold.

    Returns
    -------
    mesh : Mesh
    filled : int
        Loops closed.
    """
    edges = edge_face_counts(mesh.faces)[0]
    existing = set(zip(edges[:, 0].tolist(), edges[:, 1].tolist(), strict=True))
    new_faces = []
    filled = 0
    for loop in boundary_loops(mesh.faces):
        if len(loop) > max_edges:
            continue
        loop = loop.tolist()
        for shift in range(len(loop)):
            ring = loop[shift:] + loop[:shift]
            diagonals = {tuple(sorted((ring[0], v))) for v in ring[2:-1]}
            if not diagonals & existing:
                # Boundary edges run (v_i, v_i+1) in their faces; the fill runs against them.
                new_faces.extend((ring[0], ring[i + 1], ring[i]) for i in range(1, len(ring) - 1))
                existing |= diagonals
                filled += 1
                break
    if not new_faces:
        return mesh, 0
    faces = np.concatenate([mesh.faces, np.array(new_faces, dtype=np.int64)])
    return Mesh(vertices=mesh.vertices, faces=faces), filled
