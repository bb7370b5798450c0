"""Closest points on a triangle mesh through a bounding-volume hierarchy (exact).

The hierarchy is a complete binary tree stored without pointers: node ``n`` has children
``2n`` and ``2n + 1`` (root 1) and the ``L`` leaves are nodes ``L .. 2L - 1``. It is built
top-down: each node splits its triangles at the median of their box centres along the
widest axis, so every leaf holds at most ``LEAF_SIZE`` triangles, stored contiguously.
Each query descends nearer child first and skips every box no nearer than the best
triangle so far. Box distances are lower bounds, so the answer is the exact minimum over
all triangles (Ericson 2005, §6.3 and §6.4), up to rounding.
"""

import numpy as np

from ..neighbours import spatial_order
from ._jit import jit, over_rows
from .triangles import closest_point_on_triangle, triangle_rows

LEAF_SIZE = 4


@jit
def _box_distance2(px, py, pz, boxes, node):
    # Squared distance from p to box (lo, hi) = boxes[node]; inf for an empty node.
    dx = max(boxes[node, 0] - px, 0.0, px - boxes[node, 3])
    dy = max(boxes[node, 1] - py, 0.0, py - boxes[node, 4])
    dz = max(boxes[node, 2] - pz, 0.0, pz - boxes[node, 5])
    return dx * dx + dy * dy + dz * dz


@jit
def _centre_distance2(px, py, pz, boxes, node):
    # Squared distance from p to the centre of the box of `node`: breaks ties between
    # children whose boxes both contain p.
    dx = 0.5 * (boxes[node, 0] + boxes[node, 3]) - px
    dy = 0.5 * (boxes[node, 1] + boxes[node, 4]) - py
    dz = 0.5 * (boxes[node, 2] + boxes[node, 5]) - pz
    return dx * dx + dy * dy + dz * dz


@jit
def _select(keys, items, lo, hi, k):
    # Hoare's FIND (quickselect): reorder keys[lo:hi] and items[lo:hi] alike so that
    # keys[k] is in its sorted place, no larger key before it and no smaller one after.
    while hi - lo > 1:
        a, b, c = keys[lo], keys[(lo + hi) // 2], keys[hi - 1]
        pivot = max(min(a, b), min(max(a, b), c))  # median of three
        i, j = lo, hi - 1
        while i <= j:
            while keys[i] < pivot:
                i += 1
            while keys[j] > pivot:
                j -= 1
            if i <= j:
                keys[i], keys[j] = keys[j], keys[i]
                items[i], items[j] = items[j], items[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j + 1
        elif k >= i:
            lo = i
        else:
            return


@jit
def _median_split(centres, order, start, count):
    # Top-down build: node n holds order[start[n] : start[n] + count[n]]; its first
    # ceil(count / 2) triangles by the centre coordinate along the widest axis go left.
    # Plain loops, not np.full and np.argmax: each would add a fraction of a second of
    # compiling on a fresh install.
    keys = np.zeros(centres.shape[0])
    lo, hi = np.empty(3), np.empty(3)
    n_leaves = start.shape[0] // 2
    count[1] = centres.shape[0]
    for node in range(1, n_leaves):
        s, c = start[node], count[node]
        half = (c + 1) // 2
        if c > 1:
            for axis in range(3):
                lo[axis], hi[axis] = np.inf, -np.inf
            for j in range(s, s + c):
                for axis in range(3):
                    lo[axis] = min(lo[axis], centres[order[j], axis])
                    hi[axis] = max(hi[axis], centres[order[j], axis])
            axis = 0
            for other in (1, 2):
                if hi[other] - lo[other] > hi[axis] - lo[axis]:
                    axis = other
            for j in range(s, s + c):
                keys[j] = centres[order[j], axis]
            _select(keys, order, s, s + c, s + half)
        start[2 * node], count[2 * node] = s, half
        start[2 * node + 1], count[2 * node + 1] = s + half, c - half


@jit
def _closest_face_rows(
    start, stop, points, triangles, degenerate, boxes, leaf_start, leaf_count, slot, bary, distance2
):
    # For each point, the minimum over triangles T of |p - q(p, T)|^2, found by branch and
    # bound over the boxes: a subtree is skipped when its box is no nearer than the best
    # triangle so far. `triangles` (S, 15) are the rows of closest_point_on_triangle in
    # leaf order, `degenerate` (S,) their flags; `slot` holds a row to start from (-1:
    # none) and gets the row of the closest point, `bary` its barycentric coordinates;
    # `distance2` holds a bound (inf: none), only a nearer triangle is looked for, and
    # gets the squared distance (the bound, and slot -1, where no triangle is nearer).
    n_leaves = leaf_start.shape[0]
    stack = np.zeros(128, dtype=np.int64)  # depth <= log2(n_leaves) + 1 < 64
    stack_distance = np.zeros(128)
    for i in range(start, stop):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        best, best_slot = distance2[i], -1
        bu, bv, bw = 1.0, 0.0, 0.0
        if slot[i] >= 0:
            d2, u, v, w = closest_point_on_triangle(
                px, py, pz, triangles, slot[i], degenerate[slot[i]]
            )
            if d2 < best:
                best, best_slot, bu, bv, bw = d2, slot[i], u, v, w
        stack[0], stack_distance[0] = 1, 0.0
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if stack_distance[top] >= best:
                continue
            if node >= n_leaves:
                first = leaf_start[node - n_leaves]
                for s in range(first, first + leaf_count[node - n_leaves]):
                    d2, u, v, w = closest_point_on_triangle(px, py, pz, triangles, s, degenerate[s])
                    if d2 < best:
                        best, best_slot = d2, s
                        bu, bv, bw = u, v, w
                continue
            near, far = 2 * node, 2 * node + 1
            d_near = _box_distance2(px, py, pz, boxes, near)
            d_far = _box_distance2(px, py, pz, boxes, far)
            if d_far < d_near or (
                d_far == d_near
                and _centre_distance2(px, py, pz, boxes, far)
                < _centre_distance2(px, py, pz, boxes, near)
            ):
                near, far, d_near, d_far = far, near, d_far, d_near
            if d_far < best:
                stack[top], stack_distance[top] = far, d_far
                top += 1
            if d_near < best:
                stack[top], stack_distance[top] = near, d_near
                top += 1
        slot[i] = best_slot
        bary[i, 0], bary[i, 1], bary[i, 2] = bu, bv, bw
        distance2[i] = best


def build_hierarchy(vertices, faces):
    """Return the hierarchy over (F, 3) `faces`: triangles in leaf order and node boxes.

    Returns ``triangles`` (F, 15) float64 (the rows of
    :func:`~zeroset._kernels.triangles.closest_point_on_triangle`) with their
    ``degenerate`` flags (F,) bool, ``order`` (F,) int64 (the face of each row), ``boxes``
    (2L, 6) float64 (lo, hi per node; inverted for an empty node, so no query enters it),
    and ``leaf_start``, ``leaf_count`` (L,) int64.
    """
    corners = vertices[faces]
    tri_lo, tri_hi = corners.min(axis=1), corners.max(axis=1)
    n_faces = faces.shape[0]
    n_leaves = 1 << max(int(-(-n_faces // LEAF_SIZE) - 1).bit_length(), 0)
    order = np.arange(n_faces, dtype=np.int64)
    start = np.zeros(2 * n_leaves, dtype=np.int64)
    count = np.zeros(2 * n_leaves, dtype=np.int64)
    _median_split(0.5 * (tri_lo + tri_hi), order, start, count)
    leaf_start, leaf_count = start[n_leaves:].copy(), count[n_leaves:].copy()
    boxes = np.concatenate(
        [np.full((2 * n_leaves, 3), np.inf), np.full((2 * n_leaves, 3), -np.inf)], axis=1
    )
    used = leaf_count > 0
    boxes[n_leaves:][used, :3] = np.minimum.reduceat(tri_lo[order], leaf_start[used], axis=0)
    boxes[n_leaves:][used, 3:] = np.maximum.reduceat(tri_hi[order], leaf_start[used], axis=0)
    width = n_leaves // 2
    while width >= 1:
        nodes = np.arange(width, 2 * width)
        boxes[nodes, :3] = np.minimum(boxes[2 * nodes, :3], boxes[2 * nodes + 1, :3])
        boxes[nodes, 3:] = np.maximum(boxes[2 * nodes, 3:], boxes[2 * nodes + 1, 3:])
        width //= 2
    a, b, c = (np.ascontiguousarray(corners[order, k]) for k in range(3))
    triangles, degenerate = np.zeros((n_faces, 15)), np.zeros(n_faces, dtype=np.bool_)
    triangle_rows(a, b, c, triangles, degenerate)
    return triangles, degenerate, order, boxes, leaf_start, leaf_count


def closest_points_on_mesh(
    points, vertices, faces, guess=None, in_order=False, hierarchy=None, within=None
):
    """Return the face (N,) int64 holding the closest point to each point, the point's
    barycentric coordinates (N, 3) in it (corner order) and the squared distance (N,).

    `points` (N, 3) and `vertices` (M, 3) are float64, `faces` (F, 3) int64 with F >= 1;
    a degenerate face counts as its three edges. Queries run in Morton order, so
    neighbouring iterations walk the same part of the tree; `in_order` says that the
    points are in that order already (:func:`~zeroset.neighbours.spatial_order`).
    `guess` (N,) int64, a face per point likely to hold its closest point (a previous
    projection's), starts each search with a bound, so that it visits less of the tree;
    the result is the same but where two faces are equally close. `hierarchy`, the
    :func:`build_hierarchy` of `vertices` and `faces`, saves building it again for
    another query on the same mesh. `within` (N,) float64 bounds the search: only a face
    nearer than ``within[i]`` is looked for, and a point with none gets face -1 and the
    squared bound, so that a query for what changed skips what lies far from it.
    """
    if hierarchy is None:
        hierarchy = build_hierarchy(vertices, faces)
    triangles, degenerate, face_of_slot, boxes, leaf_start, leaf_count = hierarchy
    n = points.shape[0]
    query = None if in_order else spatial_order(points)
    slot = np.full(n, -1, dtype=np.int64)
    if guess is not None:
        slot_of_face = np.zeros(faces.shape[0], dtype=np.int64)
        slot_of_face[face_of_slot] = np.arange(faces.shape[0])
        slot = slot_of_face[guess if in_order else guess[query]]
    bary = np.zeros((n, 3))
    if within is None:
        distance2 = np.full(n, np.inf)
    else:
        distance2 = np.square(within if in_order else within[query], dtype=np.float64)
    over_rows(
        _closest_face_rows,
        n,
        points if in_order else np.ascontiguousarray(points[query]),
        triangles,
        degenerate,
        boxes,
        leaf_start,
        leaf_count,
        slot,
        bary,
        distance2,
    )
    face = np.where(slot >= 0, face_of_slot[slot], -1)
    if in_order:
        return face, bary, distance2
    out_face, out_bary, out_distance2 = np.zeros(n, np.int64), np.zeros((n, 3)), np.zeros(n)
    out_face[query], out_bary[query], out_distance2[query] = face, bary, distance2
    return out_face, out_bary, out_distance2
