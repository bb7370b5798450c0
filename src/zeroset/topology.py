"""Mesh topology: edges, boundary loops, components, Euler characteristic, orientation."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from ._unique import distinct
from .types import Mesh

__all__ = [
    "corner_fans",
    "edge_ids",
    "edge_keys",
    "half_edges",
    "boundary_edges",
    "boundary_loops",
    "edge_face_counts",
    "edge_face_pairs",
    "fold_cosines",
    "euler_characteristic",
    "face_area_vectors",
    "face_components",
    "is_consistently_oriented",
    "is_edge_manifold",
    "undirected_edges",
    "undo_turned_faces",
    "signed_volume",
    "vertex_normals",
]


def half_edges(faces: np.ndarray) -> np.ndarray:
    """Return the (3F, 2) int64 directed edges (a, b) of every face, in face order."""
    return np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)


def edge_face_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the unique undirected edges (E, 2) and how many faces hold each (E,)."""
    edges, _, counts = undirected_edges(faces)
    return edges, counts


def undirected_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the unique undirected edges (E, 2), lower index first, the edge of each
    half-edge (F, 3) (corner i to corner i + 1 of each face), and each edge's face count (E,)."""
    half = np.sort(half_edges(faces), axis=1)
    edge_of_half, counts = edge_ids(faces, int(faces.max(initial=-1)) + 1)
    edges = np.zeros((counts.size, 2), dtype=np.int64)
    edges[edge_of_half] = half
    return edges, edge_of_half.reshape(faces.shape), counts


def edge_keys(pairs: np.ndarray, n_vertices: int) -> np.ndarray:
    """(E,) int64 one key per vertex pair (E, 2), ordered as the pairs are
    lexicographically: a 1-D unique of them is many times faster than ``unique(axis=0)``."""
    return pairs[:, 0] * np.int64(n_vertices) + pairs[:, 1]


def edge_ids(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the undirected edge id of each half-edge (3F,) and each edge's face count (E,)."""
    half = np.sort(half_edges(faces), axis=1)
    _, edge_of_half, counts = np.unique(
        edge_keys(half, n_vertices), return_inverse=True, return_counts=True
    )
    return edge_of_half.reshape(-1), counts


def edge_face_pairs(faces: np.ndarray) -> np.ndarray:
    """Return the (P, 2) int64 pairs of faces that share an edge, one row per interior edge.

    On an edge-manifold mesh every edge with two faces gives one pair.
    """
    edge_of_half, _ = edge_ids(faces, int(faces.max(initial=-1)) + 1)
    face_of_half = np.repeat(np.arange(faces.shape[0]), 3)
    order = np.argsort(edge_of_half, kind="stable")
    shared = edge_of_half[order[1:]] == edge_of_half[order[:-1]]
    return np.column_stack([face_of_half[order[:-1][shared]], face_of_half[order[1:][shared]]])


def fold_cosines(vertices: np.ndarray, faces: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Return the cosine (P,) between the unit normals of each face pair (P, 2).

    1 where the two faces are coplanar, -1 where one is folded back onto the other; NaN
    where a face is degenerate (no normal).
    """
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.full_like(normals, np.nan), where=length > 0)
    return np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]])


def corner_fans(faces: np.ndarray, edge_of_half: np.ndarray) -> tuple[np.ndarray, int]:
    """Return the fan label (3F,) of every face corner, and the number of fans.

    Corner ``3f + i`` is vertex ``faces[f, i]`` in face f. Two corners of one vertex are in
    one fan when their faces share an edge at that vertex, whatever the orientation and
    however many faces hold the edge. A vertex with more than one fan is a bow tie.
    """
    n_corners = faces.size
    half = half_edges(faces)
    tail = np.arange(n_corners)
    head = 3 * (tail // 3) + (tail % 3 + 1) % 3
    # Corner of the lower and of the higher vertex id of each half-edge's edge.
    forward = half[:, 0] < half[:, 1]
    low, high = np.where(forward, tail, head), np.where(forward, head, tail)
    # Chain the half-edges of each edge: consecutive ones in edge order share it.
    order = np.argsort(edge_of_half, kind="stable")
    same = edge_of_half[order[1:]] == edge_of_half[order[:-1]]
    first, second = order[:-1][same], order[1:][same]
    loops = half[:, 0] == half[:, 1]  # a repeated vertex: its two corners are one fan
    rows = np.concatenate([low[first], high[first], tail[loops]])
    cols = np.concatenate([low[second], high[second], head[loops]])
    graph = sparse.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_corners, n_corners))
    n_fans, fan = connected_components(graph, directed=False)
    return fan.astype(np.int64), int(n_fans)


def is_edge_manifold(faces: np.ndarray) -> bool:
    """Whether every edge belongs to one or two faces."""
    return bool(np.all(edge_face_counts(faces)[1] <= 2))


def is_consistently_oriented(faces: np.ndarray) -> bool:
    """Whether no directed edge occurs twice (neighbouring faces run shared edges oppositely)."""
    half = half_edges(faces)
    return distinct(edge_keys(half, faces.max(initial=-1) + 1)).shape[0] == half.shape[0]


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Return the (B, 2) int64 boundary edges (a, b), directed as in their one face."""
    half = half_edges(faces)
    edge_of_half, counts = edge_ids(faces, int(faces.max(initial=-1)) + 1)
    return half[counts[edge_of_half] == 1]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Return the closed boundary loops, each an array of vertex indices in face order.

    A boundary edge belongs to one face only. The mesh must be vertex-manifold (see
    :func:`split_nonmanifold_vertices`), so every boundary vertex starts one boundary edge.
    """
    border = boundary_edges(faces)
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
    n_edges = edge_ids(mesh.faces, mesh.n_vertices)[1].size
    return int(distinct(mesh.faces).size - n_edges + mesh.faces.shape[0])


def face_area_vectors(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) normal of every face with twice its area as length (zero for a degenerate face)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return np.cross(b - a, c - a)


def undo_turned_faces(moved: np.ndarray, previous: np.ndarray, faces: np.ndarray, reference):
    """Bring vertices back until no face of `moved` (V, 3) turns against `reference`.

    A face whose area vector makes an angle of 90 degrees or more with its `reference`
    (F, 3) area vector sends its vertices that moved back to `previous` (V, 3), repeatedly,
    until no face is turned. Returns the vertices and a (V,) bool mask of those sent back.
    """
    moved = moved.copy()
    sent_back = np.zeros(moved.shape[0], dtype=bool)
    while True:
        turned = np.einsum("ij,ij->i", face_area_vectors(moved, faces), reference) <= 0.0
        back = distinct(faces[turned])
        back = back[np.any(moved[back] != previous[back], axis=1)]
        if back.size == 0:
            return moved, sent_back
        moved[back] = previous[back]
        sent_back[back] = True


def vertex_normals(mesh: Mesh) -> np.ndarray:
    """(V, 3) area-weighted unit vertex normals (zero where a vertex has no face)."""
    area = face_area_vectors(mesh.vertices, mesh.faces)
    normals = np.stack(
        [
            np.bincount(mesh.faces.reshape(-1), np.repeat(area[:, i], 3), mesh.n_vertices)
            for i in range(3)
        ],
        axis=1,
    )
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def signed_volume(mesh: Mesh) -> float:
    """Signed volume enclosed by the faces (positive for a closed outward-facing mesh)."""
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))
    centre = mesh.vertices.mean(axis=0) if mesh.n_vertices else np.zeros(3)
    return float(np.einsum("ij,ij->i", a - centre, np.cross(b - centre, c - centre)).sum() / 6.0)
