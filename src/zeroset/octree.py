"""Octree cells for the Method of Cubes: cubes merged where one vertex holds their surface.

The Method of Cubes (`zeroset.contour.method_of_cubes`) puts one vertex in every crossed
cube. Where the surface is flat and the data sparse, eight cubes can share one vertex:
their vertices are merged, level by level, into cells of 2, 4, 8 cubes a side, an octree
over the band built from the bottom. Merging the vertices of a welded dual mesh leaves no
crack and no T-junction: every face keeps its neighbours, and faces whose corners fall into
one cell vanish (Schaefer & Warren 2003, adaptive vertex clustering on octrees, the same
polygons as dual contouring on the octree of Ju et al. 2002).

A cell is merged only when

- every vertex in it allows the cell's size (`cell_levels`) and none lies on a boundary,
  so the boundaries are those of the cubes;
- the cells touching it are at most one level finer (a 2:1 graded octree, so no sliver
  joins a large cell to a small one);
- the surface in it is one disc (Euler characteristic 1), which keeps the topology;
- the mesh stays edge- and vertex-manifold and consistently oriented, and no face touching
  the cell folds against the surface or has an angle below ``MIN_ANGLE`` (Schaefer, Ju &
  Warren 2007 ask the same of manifold dual contouring).

Merges that fail the last test are undone, and the others tried again.
"""

from __future__ import annotations

import numpy as np

from . import _lattice
from .evaluate import smallest_angles
from .refine import sag_tolerance
from .topology import (
    boundary_edges,
    corner_fans,
    edge_ids,
    face_area_vectors,
    half_edges,
    undirected_edges,
    vertex_normals,
)
from .types import Mesh

__all__ = [
    "MAX_LEVEL",
    "MIN_ANGLE",
    "cell_levels",
    "cell_sizes",
    "mean_by",
    "merge_cells",
]

#: Coarsest cell: 2^MAX_LEVEL cubes a side.
MAX_LEVEL = 3
#: Smallest angle, in degrees, of a face made by a merge (before the flips of `flip_edges`).
MIN_ANGLE = 15.0
#: Largest angle, in degrees, between two faces whose common edge may be flipped.
FLIP_FOLD = 15.0
#: Rounds of edge flips after the merges.
FLIP_ROUNDS = 8
#: Largest turn, in degrees, of a merged face's normal from the surface's normal there.
MAX_TURN = 60.0
#: Rounds of undoing the merges that broke a test, per level.
MAX_ROUNDS = 20

#: Offsets, in cells one level finer, of the 56 cells touching a cell's 2 x 2 x 2 children.
_RING = np.array(
    [
        (i, j, k)
        for i in range(-1, 3)
        for j in range(-1, 3)
        for k in range(-1, 3)
        if not (0 <= i <= 1 and 0 <= j <= 1 and 0 <= k <= 1)
    ],
    dtype=np.int64,
)


def cell_sizes(curvature, spacing, *, noise: float, noise_factor: float, cube_factor: float):
    """(N,) side of the cell each point asks for, in data units.

    The data support a cell of ``cube_factor * (spacing + noise_factor * noise)``: the cube
    that the point's own spacing would choose (`zeroset.parameters.estimate_parameters`
    chooses the cloud's from its sparser points). Where the surface is flat the cell may be
    larger: a cell's flat faces cut the chords of a surface of curvature kappa, sagging by
    ``L^2 kappa / 8`` over a side L, and L may grow while that stays within the tolerance
    of `zeroset.refine` (`zeroset.refine.sag_tolerance`). Where the surface bends more than
    the data resolve, `zeroset.refine` splits the edges further.

    Parameters
    ----------
    curvature : (N,) array_like of float
        Largest absolute principal curvature at each point, in 1 / data units.
    spacing : (N,) array_like of float
        Spacing of the points around each one (`zeroset.density.local_spacing`); where it
        is not finite (a point at an edge) the cell is as small as the noise allows.
    noise : float
        Noise of one point, in data units.
    noise_factor, cube_factor : float
        rho+delta is spacing + `noise_factor` noise; the cube is `cube_factor` rho+delta.
    """
    kappa = np.maximum(np.asarray(curvature, dtype=np.float64), 1e-150)  # sizes stay finite
    tolerance = sag_tolerance(kappa, noise)
    spacing = np.asarray(spacing, dtype=np.float64)
    spacing = np.where(np.isfinite(spacing), spacing, 0.0)  # no neighbours around: an edge
    supported = cube_factor * (spacing + noise_factor * noise)
    return np.maximum(np.sqrt(8.0 * tolerance / kappa), supported)


def cell_levels(sizes: np.ndarray, cube_size: float, max_level: int = MAX_LEVEL) -> np.ndarray:
    """(N,) int64 coarsest level whose cells (``cube_size * 2**level`` a side) fit `sizes` (N,)."""
    ratio = np.maximum(np.asarray(sizes, dtype=np.float64) / cube_size, 1.0)
    return np.minimum(np.floor(np.log2(ratio) + 1e-9), max_level).astype(np.int64)


def merge_cells(
    mesh: Mesh, cubes: np.ndarray, levels: np.ndarray, *, max_level: int = MAX_LEVEL
) -> tuple[Mesh, np.ndarray, dict]:
    """Merge the vertices of a dual mesh into octree cells, where each allows it.

    Parameters
    ----------
    mesh : Mesh
        Edge-manifold, consistently oriented dual mesh, one vertex per surface patch of a
        cube (`zeroset.contour.method_of_cubes`).
    cubes : (V, 3) int64
        Lattice index of the cube each vertex lies in.
    levels : (V,) int
        Coarsest level each vertex may be merged into (0: its own cube).
    max_level : int

    Returns
    -------
    mesh : Mesh
        One vertex per cell, at the mean of the vertices merged into it.
    level : (M,) int64
        Level of each vertex's cell: its side is ``2**level`` cubes.
    counts : dict
        ``cells_merged``: merges kept per level; ``merges_undone``: merges that broke a test.
    """
    faces = mesh.faces
    n = mesh.n_vertices
    allowed = np.asarray(levels, dtype=np.int64).copy()
    allowed[_pinned(faces, cubes, n)] = 0
    level = np.zeros(n, dtype=np.int64)
    if allowed.max(initial=0) == 0:
        return mesh, level, {"cells_merged": [], "merges_undone": 0}
    normals = vertex_normals(mesh)
    cluster = np.arange(n)
    merged, undone = [], 0
    for lv in range(1, max_level + 1):
        keys, of_vertex = np.unique(_lattice.encode(cubes >> lv), return_inverse=True)
        ready = _all(of_vertex, (allowed >= lv) & (level == lv - 1), keys.size)
        child_keys, of_child = np.unique(_lattice.encode(cubes >> (lv - 1)), return_inverse=True)
        ready &= _graded(keys, child_keys, _all(of_child, level >= lv - 1, child_keys.size))
        ready &= _discs(faces, cluster, of_vertex, keys.size) == 1
        several = np.bincount(of_vertex, minlength=keys.size) > 1  # one vertex: nothing moves
        for _ in range(MAX_ROUNDS if (ready & several).any() else 0):
            trial = np.where(ready[of_vertex], n + of_vertex, cluster)
            bad = _broken(mesh, normals, trial, (ready & several)[of_vertex])
            if not bad.any():
                break
            blamed = np.unique(of_vertex[bad & ready[of_vertex]])
            ready[blamed] = False
            undone += blamed.size
        else:
            ready &= ~several  # rounds ran out: only the lone vertices move up a level
        cluster = np.where(ready[of_vertex], n + of_vertex, cluster)
        cluster = np.unique(cluster, return_inverse=True)[1]
        level[ready[of_vertex]] = lv
        merged.append(int(np.count_nonzero(ready & several)))
    vertices, faces_out, ids = _collapse(mesh, cluster)
    out_level = np.zeros(vertices.shape[0], dtype=np.int64)
    out_level[ids] = level
    if level.any():
        faces_out = flip_edges(vertices, faces_out, out_level[faces_out].any(axis=1))
    return (
        Mesh(vertices=vertices, faces=faces_out),
        out_level,
        {"cells_merged": merged, "merges_undone": int(undone)},
    )


def _pinned(faces: np.ndarray, cubes: np.ndarray, n: int) -> np.ndarray:
    """(V,) bool: vertices on a boundary edge, or sharing their cube with another patch."""
    pinned = np.zeros(n, dtype=bool)
    pinned[boundary_edges(faces).reshape(-1)] = True
    keys = _lattice.encode(cubes)
    _, inverse, count = np.unique(keys, return_inverse=True, return_counts=True)
    return pinned | (count[inverse] > 1)


def _all(group: np.ndarray, flag: np.ndarray, n_groups: int) -> np.ndarray:
    """(G,) bool: whether `flag` (V,) holds for every member of each group."""
    return np.bincount(group, weights=~flag, minlength=n_groups) == 0


def _graded(keys: np.ndarray, child_keys: np.ndarray, complete: np.ndarray) -> np.ndarray:
    """(G,) bool: cells (keys) whose 56 touching cells one level finer (sorted `child_keys`)
    are all `complete` (merged to that level) or empty: a 2:1 graded octree."""
    around = _lattice.encode(2 * _lattice.decode(keys))[:, None] + _lattice.offset_keys(_RING)
    slot = np.minimum(np.searchsorted(child_keys, around), child_keys.size - 1)
    blocked = (child_keys[slot] == around) & ~complete[slot]
    return ~blocked.any(axis=1)


def _discs(faces: np.ndarray, cluster: np.ndarray, of_vertex: np.ndarray, n_cells: int):
    """(G,) Euler characteristic of the mesh of `cluster`'s vertices inside each cell."""
    cell_of_cluster = np.zeros(cluster.max() + 1, dtype=np.int64)
    cell_of_cluster[cluster] = of_vertex
    labelled = cluster[faces]
    labelled = labelled[_proper(labelled)]
    cell = cell_of_cluster[labelled]
    inside = (cell[:, 0] == cell[:, 1]) & (cell[:, 1] == cell[:, 2])
    ends = cell_of_cluster[undirected_edges(labelled)[0]]
    n_v = np.bincount(cell_of_cluster, minlength=n_cells)
    n_e = np.bincount(ends[ends[:, 0] == ends[:, 1], 0], minlength=n_cells)
    n_f = np.bincount(cell[inside, 0], minlength=n_cells)
    return n_v - n_e + n_f


def _proper(faces: np.ndarray) -> np.ndarray:
    """(F,) bool: faces with three different vertices."""
    ordered = np.sort(faces, axis=1)
    return (ordered[:, 0] != ordered[:, 1]) & (ordered[:, 1] != ordered[:, 2])


def mean_by(group: np.ndarray, rows: np.ndarray, n_groups: int) -> np.ndarray:
    """(G, 3) mean of the (K, 3) `rows` in each of `n_groups` groups (zero where empty)."""
    count = np.bincount(group, minlength=n_groups)
    total = np.stack([np.bincount(group, rows[:, i], n_groups) for i in range(3)], axis=1)
    return total / np.maximum(count, 1)[:, None]


def _collapse(mesh: Mesh, cluster: np.ndarray):
    """Vertices (M, 3) at the means of the clusters, faces (F', 3) without collapsed ones,
    and the compact id (V,) of each input vertex."""
    ids, inverse = np.unique(cluster, return_inverse=True)
    faces = inverse[mesh.faces]
    return mean_by(inverse, mesh.vertices, ids.size), faces[_proper(faces)], inverse


def _broken(mesh: Mesh, normals: np.ndarray, trial: np.ndarray, moved: np.ndarray):
    """(V,) bool: input vertices whose cluster in `trial` is in a face that breaks a test.

    Tests: no face twice, no edge in three faces, no directed edge twice (orientation), one
    fan of faces per vertex; faces with a `moved` (V,) vertex must not turn more than
    ``MAX_TURN`` from the mean vertex normal nor have an angle under ``MIN_ANGLE``.
    """
    vertices, faces, inverse = _collapse(mesh, trial)
    if faces.shape[0] == 0:  # everything collapsed: no merge may stand
        return moved.copy()
    m = vertices.shape[0]
    bad_vertex = np.zeros(m, dtype=bool)
    bad_face = np.zeros(faces.shape[0], dtype=bool)
    # The same three vertices twice, whichever the order.
    triple = np.sort(faces, axis=1)
    key = (triple[:, 0] * m + triple[:, 1]) * m + triple[:, 2]
    _, first, count = np.unique(key, return_inverse=True, return_counts=True)
    bad_face |= count[first] > 1
    # Edges in three faces or more, or run twice the same way.
    edge_of_half, edge_count = edge_ids(faces, m)
    half = half_edges(faces)
    directed = np.unique(half[:, 0] * m + half[:, 1], return_inverse=True, return_counts=True)
    bad_half = (edge_count[edge_of_half] > 2) | (directed[2][directed[1]] > 1)
    bad_face |= bad_half.reshape(-1, 3).any(axis=1)
    # Bow ties: a vertex with two fans of faces.
    fan, _ = corner_fans(faces, edge_of_half)
    corner_vertex = faces.reshape(-1)
    fans_per_vertex = np.bincount(corner_vertex[np.unique(fan, return_index=True)[1]], minlength=m)
    bad_vertex |= fans_per_vertex > 1
    # Folds and slivers, only where this level merges.
    moved_cluster = np.zeros(m, dtype=bool)
    moved_cluster[inverse[moved]] = True
    touched = moved_cluster[faces].any(axis=1)
    reference = mean_by(inverse, normals, m)
    area = face_area_vectors(vertices, faces)
    ref = reference[faces].sum(axis=1)
    cos_turn = np.einsum("ij,ij->i", area, ref) / np.maximum(
        np.linalg.norm(area, axis=1) * np.linalg.norm(ref, axis=1), 1e-300
    )
    sharp = smallest_angles(Mesh(vertices=vertices, faces=faces)) < MIN_ANGLE
    bad_face |= touched & ((cos_turn < np.cos(np.radians(MAX_TURN))) | sharp)
    bad_vertex[faces[bad_face].reshape(-1)] = True
    return bad_vertex[inverse]


def flip_edges(vertices: np.ndarray, faces: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Flip interior edges between two `movable` (F,) faces where that rounds the triangles.

    An edge is flipped when its two faces lie within ``FLIP_FOLD`` of one plane, the other
    diagonal is no edge yet, and the smaller angle of the pair grows. Each round flips a
    set of edges with no face in common, best first; orientation is kept.

    Returns the (F, 3) faces after ``FLIP_ROUNDS`` rounds.
    """
    faces = faces.copy()
    n = vertices.shape[0]
    for _ in range(FLIP_ROUNDS):
        half = half_edges(faces)
        f_of = np.repeat(np.arange(faces.shape[0]), 3)
        key = half[:, 0] * np.int64(n) + half[:, 1]
        order = np.argsort(key)
        existing = key[order]
        reverse = half[:, 1] * np.int64(n) + half[:, 0]
        twin = order[np.minimum(np.searchsorted(existing, reverse), key.size - 1)]
        h = np.flatnonzero((key[twin] == reverse) & (half[:, 0] < half[:, 1]))
        h = h[movable[f_of[h]] & movable[f_of[twin[h]]]]
        if h.size == 0:
            break
        g = twin[h]
        f, o = f_of[h], f_of[g]
        a, b = half[h, 0], half[h, 1]
        c = faces[f, (h % 3 + 2) % 3]
        d = faces[o, (g % 3 + 2) % 3]
        new = np.stack([np.stack([a, d, c], 1), np.stack([b, c, d], 1)], 1)  # (K, 2, 3)
        old = np.stack([faces[f], faces[o]], 1)
        gain = _pair_angle(vertices, new) - _pair_angle(vertices, old)
        normal = face_area_vectors(vertices, old.reshape(-1, 3)).reshape(-1, 2, 3)
        length = np.linalg.norm(normal, axis=2)
        flat = (
            np.einsum("ij,ij->i", normal[:, 0], normal[:, 1])
            >= np.cos(np.radians(FLIP_FOLD)) * length[:, 0] * length[:, 1]
        )
        turned = face_area_vectors(vertices, new.reshape(-1, 3)).reshape(-1, 2, 3)
        keeps = (np.einsum("ikj,ij->ik", turned, normal.sum(axis=1)) > 0).all(axis=1)
        diagonal = c * np.int64(n) + d
        found = existing[np.minimum(np.searchsorted(existing, diagonal), key.size - 1)]
        reversed_ = c + d * np.int64(n)
        found_r = existing[np.minimum(np.searchsorted(existing, reversed_), key.size - 1)]
        fresh = (found != diagonal) & (found_r != reversed_)
        ok = (gain > 1e-6) & flat & keeps & fresh & (c != d)
        f, o, new = f[ok], o[ok], new[ok]
        rank = np.empty(f.size, dtype=np.int64)
        rank[np.argsort(-gain[ok], kind="stable")] = np.arange(f.size)  # 0: the best
        best = np.full(faces.shape[0], f.size)
        np.minimum.at(best, f, rank)
        np.minimum.at(best, o, rank)
        chosen = (best[f] == rank) & (best[o] == rank)
        if not chosen.any():
            break
        faces[f[chosen]] = new[chosen, 0]
        faces[o[chosen]] = new[chosen, 1]
    return faces


def _pair_angle(vertices: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(K,) smallest angle, in degrees, of each pair (K, 2, 3) of triangles."""
    angles = smallest_angles(Mesh(vertices=vertices, faces=pairs.reshape(-1, 3)))
    return angles.reshape(-1, 2).min(axis=1)
