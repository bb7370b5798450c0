"""Mesh topology: edges, boundary loops, components, Euler characteristic, orientation."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from .types import Mesh

__all__ = [
    "half_edges",
    "boundary_loops",
    "edge_face_counts",
    "euler_characteristic",
    "face_components",
    "is_consistently_oriented",
    "is_edge_manifold",
    "signed_volume",
]


def half_edges(faces: np.ndarray) -> np.ndarray:
    """Return the (3F, 2) int64 directed edges (a, b) of every face, in face order."""
    return np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)


def edge_face_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the unique undirected edges (E, 2) and how many faces hold each (E,)."""
    half = np.sort(half_edges(faces), axis=1)
    edges, counts = np.unique(half, axis=0, return_counts=True)
    return edges, counts


def is_edge_manifold(faces: np.ndarray) -> bool:
    """Whether every edge belongs to one or two faces."""
    return bool(np.all(edge_face_counts(faces)[1] <= 2))


def is_consistently_oriented(faces: np.ndarray) -> bool:
    """Whether no directed edge occurs twice (neighbouring faces run shared edges oppositely)."""
    half = half_edges(faces)
    return np.unique(half, axis=0).shape[0] == half.shape[0]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Return the closed boundary loops, each an array of vertex indices in face order.

    A boundary edge belongs to one face only. The mesh must be vertex-manifold (see
    :func:`split_nonmanifold_vertices`), so every boundary vertex starts one boundary edge.
    """
    half = half_edges(faces)
    _, inverse, counts = np.unique(
        np.sort(half, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    border = half[counts[inverse.reshape(-1)] == 1]
    if border.shape[0] == 0:
        return []
    order = np.argsort(border[:, 0], kind="stable")
    # Successor of boundary edge (a, b): the boundary edge leaving b.
    nxt = order[np.searchsorted(border[order, 0], border[:, 1])]
    m = border.shape[0]
    graph = sparse.coo_matrix((np.ones(m), (np.arange(m), nxt)), shape=(m, m))
    n_loops, label = connected_components(graph, directed=False)
    loops = []
    for loop in range(n_loops):
        walk = [int(np.flatnonzero(label == loop)[0])]
        for _ in range(int(np.count_nonzero(label == loop)) - 1):
            walk.append(int(nxt[walk[-1]]))
        loops.append(border[walk, 0])
    return loops


def face_components(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Return the number of vertex-connected face components and each face label (F,)."""
    if faces.shape[0] == 0:
        return 0, np.zeros(0, dtype=np.int64)
    rows = np.repeat(faces[:, 0], 2)
    cols = faces[:, 1:].reshape(-1)
    graph = sparse.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_vertices, n_vertices))
    count, vertex_label = connected_components(graph, directed=False)
    labels = vertex_label[faces[:, 0]]
    used, labels = np.unique(labels, return_inverse=True)
    return int(used.size), labels.astype(np.int64)


def euler_characteristic(mesh: Mesh) -> int:
    """V - E + F over the vertices that faces use."""
    n_edges = edge_face_counts(mesh.faces)[0].shape[0]
    return int(np.unique(mesh.faces).size - n_edges + mesh.faces.shape[0])


def signed_volume(mesh: Mesh) -> float:
    """Signed volume enclosed by the faces (positive for a closed outward-facing mesh)."""
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))
    centre = mesh.vertices.mean(axis=0) if mesh.n_vertices else np.zeros(3)
    return float(np.einsum("ij,ij->i", a - centre, np.cross(b - centre, c - centre)).sum() / 6.0)
