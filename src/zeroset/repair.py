"""Mesh repair after contouring: bow-tie vertices, small holes, tiny components."""

from __future__ import annotations

import numpy as np

from .topology import boundary_loops, corner_fans, edge_face_counts, edge_ids, face_components
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
    added = n_fans - np.unique(corner_vertex).size
    return Mesh(vertices=vertices, faces=new_faces), int(added)


#: Most edges of a loop that the rim cut may close (`zeroset.pipeline.trim_rim`).
WIDTH_EDGES = 64


def _width(mesh: Mesh, loop: np.ndarray) -> float:
    """Largest distance between two vertices of `loop`."""
    ring = mesh.vertices[loop]
    return float(np.linalg.norm(ring[:, None] - ring[None], axis=2).max())


def fill_small_holes(
    mesh: Mesh, max_edges: int, *, max_width: float | None = None
) -> tuple[Mesh, int, float]:
    """Close boundary loops of at most `max_edges` edges and at most `max_width` across
    with a fan of triangles.

    A hole narrower than the data can resolve is a cube that contouring skipped, not a hole
    in the object: where the signed distance is defined within rho+delta of the data on
    either side, a hole up to 2 rho+delta across is closed by Hoppe's rule (thesis 3.2.1,
    3.4.6). The width of a loop is the largest distance between two of its vertices.
    The fan's apex is chosen so that no new edge duplicates an existing one; a loop with
    no such apex is left open. The mesh must be vertex-manifold.

    Returns
    -------
    mesh : Mesh
    filled : int
        Loops closed.
    widest : float
        The largest width of a loop closed, in data units; 0 when none was.
    """
    edges = edge_face_counts(mesh.faces)[0]
    existing = set(zip(edges[:, 0].tolist(), edges[:, 1].tolist(), strict=True))
    new_faces = []
    filled, widest = 0, 0.0
    for loop in boundary_loops(mesh.faces):
        if len(loop) > max_edges:
            continue
        width = _width(mesh, loop)
        if max_width is not None and not width <= max_width:
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
                widest = max(widest, width)
                break
    if not new_faces:
        return mesh, 0, 0.0
    faces = np.concatenate([mesh.faces, np.array(new_faces, dtype=np.int64)])
    return Mesh(vertices=mesh.vertices, faces=faces), filled, widest
