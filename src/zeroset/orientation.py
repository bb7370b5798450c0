"""Consistent normal orientation: MST propagation per component, or towards a sensor; and
the agreement of parts oriented on their own (tiles) where they overlap."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

from ._kernels.orientation import component_extremes, propagate_signs
from ._validate import as_points, as_viewpoints, positive
from .errors import InputError
from .neighbours import build_tree, knn, off_plane, query_workers, step_cosines
from .thresholds import (
    ABRUPT,
    DECISIVE,
    FACING,
    ON_ONE_SURFACE,
    STACK_COMPONENTS,
    STACK_REACH,
    STACK_SAMPLES,
    UNTRUSTED,
)
from .types import VIEWPOINTS_UNTRUSTED, Neighbourhoods, Orientation

__all__ = ["agree_parts", "orient_normals", "part_extremes"]

#: Weight of the tree edges joining the virtual root to the anchored points: below every
#: graph edge (whose weights are at least 1e-9), so that each anchor hangs from the root.
_ANCHOR_WEIGHT = 1e-12

#: The six directions of the root rule, in the order of `component_extremes`.
DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def orient_normals(
    centroids,
    normals,
    *,
    k: int = 8,
    max_edge: float | None = None,
    neighbours: Neighbourhoods | None = None,
    viewpoints=None,
) -> Orientation:
    """Flip normals so that neighbouring tangent planes agree and closed surfaces face out.

    Without viewpoints, the Riemannian graph joins each centroid to its `k` nearest
    centroids (edges longer than `max_edge` dropped) with cost ``1 - |n_i . n_j|``; its
    minimum spanning tree is walked from one root per connected component, flipping each
    normal to agree with its parent. The root is the component's most extreme point along
    one of the six axis directions (the one whose normal is most parallel to it), oriented
    along that direction: at an extreme point of a closed surface that is outward.

    With viewpoints (sensor positions), each normal that faces its sensor clearly (|cosine|
    between it and the direction to the sensor at least ``FACING``) is turned towards it,
    and the tree is re-rooted at these anchors: every other normal takes its sign from the
    nearest anchor through the tree. Beams that graze the surface (far down a pipe) leave
    the sign of n . (v - c) to noise, so those points, and points with no known sensor,
    follow the tree instead. A component with no anchor follows the vote of the whole cloud.
    Where the sensors and the tree disagree on more than ``UNTRUSTED`` of the anchored
    points, one of them is wrong. If they part abruptly between neighbours that both face
    their sensors (``ABRUPT``), the tree joined two sheets and the sensors orient as above;
    if only across grazing points, the sensors are not where they are said to be: no point
    is anchored, the tree orients every normal, and the sensors' vote only sets each
    component's sign (``method`` says so).

    Parameters
    ----------
    centroids : (N, 3) array_like of float
    normals : (N, 3) array_like of float
        Unit normals, any sign.
    k : int
        Graph neighbours per centroid, itself included.
    max_edge : float or (N,) array_like of float, optional
        Longest graph edge, one for all points or one per point (an edge from i is kept if
        no longer than ``max_edge[i]``). A component left apart is joined to a larger one
        (`_bridges`) by its closest pair of points if they lie within twice the max_edge of
        its point there; farther ones stay separate components.
    neighbours : Neighbourhoods, optional
        Precomputed neighbours to use for the graph (those of the data points serve as
        well as the centroids', thesis §3.2.8).
    viewpoints : (3,) or (N, 3) array_like of float, optional
        Sensor position, one for all or one per point; a row of NaN where a point's sensor
        is not known.

    Returns
    -------
    Orientation
        ``normals`` (N, 3), ``flipped`` (N,), ``component`` (N,), ``roots`` (C,), ``method``
        and, with viewpoints, ``disagreement``: the share of anchored points whose sensor
        and the tree alone orient oppositely, the tree's sign in each component set by the
        vote of its sensors (so a sign convention is no disagreement, an inconsistency is).

    Notes
    -----
    Hoppe et al. 1992, §3.3; thesis §3.2.3. Hoppe seeds at the largest z with +z, which
    fails on a z-axis cylinder (its top normal is horizontal); the six-direction root
    does not.
    """
    centroids = as_points(centroids, "centroids")
    normals = as_points(normals, "normals")
    if normals.shape != centroids.shape:
        raise InputError(f"normals must match centroids {centroids.shape}; got {normals.shape}")
    n = centroids.shape[0]
    if viewpoints is not None:
        viewpoints = as_viewpoints(viewpoints, n)

    k = positive(k, "k", integer=True)
    if neighbours is None:
        neighbours = knn(centroids, k)
    cols = neighbours.indices[:, 1:k]
    rows = np.broadcast_to(np.arange(n)[:, None], cols.shape)
    valid = cols >= 0
    if max_edge is not None:
        max_edge = np.broadcast_to(np.asarray(max_edge, dtype=np.float64), (n,))
        valid &= neighbours.distances[:, 1:k] <= max_edge[:, None]
    rows, cols = rows[valid], cols[valid]
    # Cost 1 - |n_i . n_j|, shifted off zero because sparse graphs drop zero weights.
    cost = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + 1e-9
    graph = sparse.coo_matrix((cost, (rows, cols)), shape=(n, n)).tocsr()
    n_components, component = connected_components(graph, directed=False)
    if n_components > 1 and max_edge is not None:
        graph = graph + _bridges(centroids, normals, component, 2.0 * max_edge)
        n_components, component = connected_components(graph, directed=False)
    component = component.astype(np.int64)

    extremes = component_extremes(centroids, component, n_components)
    best, sign = root_rule(np.einsum("cdk,dk->cd", normals[extremes], DIRECTIONS))
    roots = extremes[np.arange(n_components), best]
    root_sign = np.zeros(n)
    root_sign[roots] = sign

    # One virtual node joined to every root makes a single tree of all components.
    virtual = sparse.coo_matrix(
        (np.ones(n_components), (np.full(n_components, n), roots)), shape=(n + 1, n + 1)
    )
    tree = minimum_spanning_tree(sparse.block_diag([graph, sparse.csr_matrix((1, 1))]) + virtual)
    signs = _walk(tree, normals, root_sign)
    turned = 0
    if viewpoints is None and n_components > 1 and max_edge is not None:
        turn = _unstack(centroids, normals * signs[:, None], component, STACK_REACH * max_edge)
        signs *= turn[component]
        turned = int(np.count_nonzero(turn < 0))
    disagreement, trusted = None, True
    if viewpoints is not None:
        cosine = _sensor_cosine(centroids, normals, viewpoints)
        signs *= _viewpoint_vote(cosine * signs, component)
        anchored = np.abs(cosine) >= FACING
        if anchored.any():
            agree = signs * cosine > 0.0
            disagreement = float(np.mean(~agree[anchored]))
            trusted = disagreement <= UNTRUSTED or _abrupt(agree, anchored, rows, cols) > ABRUPT
            if trusted:
                signs = _anchored_signs(tree[:n, :n], normals, cosine, anchored, component, signs)
    method = "mst"
    if viewpoints is not None:
        method = "mst+viewpoints" if trusted else VIEWPOINTS_UNTRUSTED
    return Orientation(
        normals=normals * signs[:, None],
        flipped=signs < 0,
        component=component,
        roots=roots.astype(np.int64),
        method=method,
        disagreement=disagreement,
        turned=turned,
    )


def part_extremes(centroids, normals, component, n_components: int) -> np.ndarray:
    """Each component's extreme points, as the root rule of `orient_normals` reads them.

    Parameters
    ----------
    centroids, normals : (N, 3) float64
        Oriented tangent planes.
    component : (N,) int64
        Component of each plane, below `n_components`.

    Returns
    -------
    (C, 6, 2) float64
        Per component and direction +x, -x, +y, -y, +z, -z: the coordinate of its centroid
        farthest that way (`component_extremes`) and the cosine of that one's normal with
        the direction; -inf for a component with no plane.
    """
    out = np.full((n_components, 6, 2), -np.inf)
    extremes = component_extremes(centroids, component, n_components)
    found = extremes >= 0
    point, direction = extremes[found], DIRECTIONS[np.nonzero(found)[1]]
    out[found, 0] = np.einsum("ik,ik->i", centroids[point], direction)
    out[found, 1] = np.einsum("ik,ik->i", normals[point], direction)
    return out


def agree_parts(keys, part, normals, extremes, *, by_sensors: bool = False):
    """Signs that make parts oriented on their own agree, as `orient_normals` would have
    oriented their union.

    Each part (a tile's component) is a node; two parts that hold the same points are
    joined, agreeing where most of those points' normals point alike. A spanning forest,
    largest majorities first, fixes each part's sign relative to its group; each group then
    takes the sign of its most extreme point along one of +-x, +-y, +-z (`root_rule`),
    unless the sensors have set every part's sign (`by_sensors`).

    Parameters
    ----------
    keys : (M,) array
        Identity of each overlap point: a point two parts hold appears twice, with equal
        keys.
    part : (M,) int64
        Part holding each, below P.
    normals : (M, 3) float64
        Its normal as its part oriented it.
    extremes : (P, 6, 2) float64
        `part_extremes` of each part (-inf rows for a part with no points of its own).

    Returns
    -------
    sign : (P,) float64
        +1 or -1 per part.
    group : (P,) int64
        Label of the group of parts joined through overlaps.
    disagreement : float or None
        Share of the overlap pairs whose normals still point apart; None without overlap.
    """
    order = np.argsort(keys, kind="stable")
    same = keys[order][1:] == keys[order][:-1]
    a, b = order[:-1][same], order[1:][same]
    a, b = a[part[a] != part[b]], b[part[a] != part[b]]
    alike = np.einsum("ij,ij->i", normals[a], normals[b]) >= 0.0
    sign, group = _spanning_signs(part[a], part[b], alike, extremes.shape[0])
    if by_sensors:
        sign[:] = 1.0
    else:
        _root_signs(extremes, sign, group)
    disagreement = None
    if a.size:
        disagreement = float(np.mean((sign[part[a]] * sign[part[b]] > 0) != alike))
    return sign, group, disagreement


def _spanning_signs(u, v, alike, n_parts: int) -> tuple[np.ndarray, np.ndarray]:
    """Sign (P,) and group (P,) of each part from matched points (u, v, alike), the pairs
    of parts with the largest majorities first (Kruskal's order), by a union-find with
    parity."""
    parent, parity = np.arange(n_parts), np.zeros(n_parts, dtype=np.int64)

    def find(x):
        flip = 0
        while parent[x] != x:
            flip ^= parity[x]
            x = parent[x]
        return x, flip

    pairs, inverse = np.unique(
        np.sort(np.stack([u, v], axis=1), axis=1), axis=0, return_inverse=True
    )
    votes = np.bincount(inverse.ravel(), weights=np.where(alike, 1.0, -1.0), minlength=len(pairs))
    for (p, q), vote in sorted(
        zip(pairs.tolist(), votes.tolist(), strict=True), key=lambda e: -abs(e[1])
    ):
        (rp, fp), (rq, fq) = find(p), find(q)
        if rp != rq:
            parent[rq], parity[rq] = rp, fp ^ fq ^ (0 if vote >= 0 else 1)
    sign, group = np.ones(n_parts), np.arange(n_parts)
    for x in range(n_parts):
        root, flip = find(x)
        group[x], sign[x] = root, -1.0 if flip else 1.0
    return sign, group


def _root_signs(extremes, sign, group) -> None:
    """Turn each group so that its most extreme point's normal points outward."""
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        coordinate = extremes[members, :, 0]
        best = np.argmax(coordinate, axis=0)  # per direction, the member farthest that way
        found = np.isfinite(coordinate[best, np.arange(6)])
        if not found.any():
            continue
        alignment = np.where(found, extremes[members[best], np.arange(6), 1], 0.0)
        _, turn = root_rule((alignment * sign[members[best]])[None])
        sign[members] *= turn[0]


def _unstack(centroids, normals, component, reach) -> np.ndarray:
    """Sign (C,) per component: -1 for the components to turn so that no two neighbouring
    components point the same way across the gap between them.

    Between two sheets whose oriented `normals` point the same way (two plates both up, two
    pipes one inside the other both outward), one side's distance is positive and the
    other's negative, so any field passes through zero between them: contouring draws a
    surface there, or breaks the sheets where a cube's corner lies past the middle. Facing
    each other (an air gap) or away (the two faces of a slab), they agree in sign across
    it, and closed surfaces already do either. Points are paired with the nearest point of
    another component within their `reach` (N,), where that pairing is mutual (so the two
    face each other); each pair whose step d from i to j crosses both tangent planes (more
    than `ON_ONE_SURFACE` degrees from each; a step along one surface, between two pieces
    of it, says nothing) votes sign(n_i . d) sign(-n_j . d), and the components are
    turned from the largest, along the strongest votes, so that every vote followed is
    positive.
    """
    sizes = np.bincount(component)
    taking = np.argsort(-sizes, kind="stable")[:STACK_COMPONENTS]
    slot = np.full(sizes.size, -1)
    slot[taking] = np.arange(taking.size)
    rng = np.random.default_rng(0)
    members = []
    for c in taking:
        points = np.flatnonzero(component == c)
        if points.size > STACK_SAMPLES:
            points = np.sort(rng.choice(points, STACK_SAMPLES, replace=False))
        members.append(points)
    # Each point's nearest point of another component within its reach.
    partner, gap = np.full(component.size, -1), np.full(component.size, np.inf)
    for b, own in enumerate(members):
        others = np.concatenate([m for a, m in enumerate(members) if a != b])
        if others.size == 0:
            continue
        distance, nearest = build_tree(centroids[own]).query(
            centroids[others],
            distance_upper_bound=float(reach[others].max()),
            workers=query_workers(),
        )
        closer = (distance <= reach[others]) & (distance < gap[others])
        partner[others[closer]], gap[others[closer]] = own[nearest[closer]], distance[closer]
    # Only mutual pairs face each other across the gap: from the far side of a pipe, the
    # nearest point of the pipe beside it lies beyond the pipe's own near side.
    i = np.flatnonzero(partner >= 0)
    i = i[partner[partner[i]] == i]
    j = partner[i]
    cos_i, cos_j = step_cosines(centroids[j] - centroids[i], normals[i], normals[j])
    across = np.minimum(off_plane(cos_i), off_plane(cos_j)) > ON_ONE_SURFACE
    # n_i . d > 0: i faces j; -n_j . d > 0: j faces i; facing alike agrees
    votes = np.zeros((taking.size, taking.size))  # between the components taking part
    np.add.at(
        votes,
        (slot[component[i[across]]], slot[component[j[across]]]),
        -np.sign(cos_i * cos_j)[across],
    )
    sign = np.zeros(taking.size)
    sign[0] = 1.0
    while True:
        weight = np.abs(votes) * ((sign != 0.0)[:, None] & (sign == 0.0)[None, :])
        if not weight.any():
            break
        a, b = np.unravel_index(np.argmax(weight), weight.shape)
        sign[b] = sign[a] * np.sign(votes[a, b])
    turn = np.ones(sizes.size)
    turn[taking] = np.where(sign == 0.0, 1.0, sign)
    return turn


def root_rule(alignment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The root of each component: of its points farthest along +x, -x, +y, -y, +z, -z,
    the one whose normal is most parallel to its direction, oriented along it.

    Parameters
    ----------
    alignment : (C, 6) float64
        Cosine of each component's extreme normal with each direction (0 where none).

    Returns
    -------
    direction : (C,) int64
    sign : (C,) float64
        +1 where that normal already points along its direction, -1 where it must turn.
    """
    direction = np.argmax(np.abs(alignment), axis=1)
    cosine = alignment[np.arange(alignment.shape[0]), direction]
    return direction, np.where(cosine >= 0.0, 1.0, -1.0)


def _abrupt(agree, anchored, rows, cols) -> float:
    """Share of the graph edges (`rows`, `cols`) between two anchored points, at least one
    of which disagrees with the tree, whose ends do not agree alike: where the tree joined
    two sheets, sensors and tree part abruptly between neighbours that both face their
    sensors; wrong sensors part from the tree only across grazing points."""
    both = anchored[rows] & anchored[cols]
    touched = both & ~(agree[rows] & agree[cols])
    parted = touched & (agree[rows] != agree[cols])
    return np.count_nonzero(parted) / max(np.count_nonzero(touched), 1)


def _walk(tree: sparse.spmatrix, normals: np.ndarray, root_sign: np.ndarray) -> np.ndarray:
    """Signs (N,) spreading `root_sign` from the tree's last node, a virtual root, down."""
    n = normals.shape[0]
    order, predecessors = breadth_first_order(tree, n, directed=False, return_predecessors=True)
    return propagate_signs(
        order.astype(np.int64), predecessors.astype(np.int64), normals, root_sign
    )


def _anchored_signs(tree, normals, cosine, anchored, component, signs) -> np.ndarray:
    """Signs (N,) from the anchors' sensors, spread through the orientation tree.

    The tree is re-rooted: a virtual root joins every anchor by an edge lighter than any
    tree edge, and the root of each component without an anchor by a heavier one, so the
    minimum spanning tree of the tree and these edges hangs every point from its nearest
    anchor. Anchors take the sign of their cosine; unanchored components keep `signs`.
    """
    n = normals.shape[0]
    free = np.flatnonzero(~np.isin(np.arange(component.max() + 1), component[anchored]))
    firsts = np.unique(component, return_index=True)[1][free]
    ends = np.concatenate([np.flatnonzero(anchored), firsts])
    weights = np.concatenate(
        [np.full(np.count_nonzero(anchored), _ANCHOR_WEIGHT), np.full(firsts.size, 2.0)]
    )
    star = sparse.coo_matrix((weights, (np.full(ends.size, n), ends)), shape=(n + 1, n + 1))
    rerooted = minimum_spanning_tree(sparse.block_diag([tree, sparse.csr_matrix((1, 1))]) + star)
    root_sign = np.where(anchored, np.sign(cosine), signs)
    return _walk(rerooted, normals, root_sign)


def _bridges(centroids, normals, component, reach) -> sparse.csr_matrix:
    """Edges (N, N) joining each component to a larger one, where within `reach`.

    Sparse parts of a scan (far down a pipe) fall apart into small components that belong
    to the surface next to them, and a wall seen through sparse scan lines into pieces; each
    is joined by its closest pair of points to one of the ``STACK_COMPONENTS`` largest
    components larger than itself, as Hoppe's Euclidean minimum spanning tree would join
    it, if that pair lies on one surface: the step between them within `ON_ONE_SURFACE`
    degrees of both tangent planes. Separate objects stay
    apart, and so do two sheets facing each other across a gap (two plates, two pipes one
    inside the other).
    """
    n = centroids.shape[0]
    sizes = np.bincount(component)
    rank = np.empty(sizes.size, dtype=np.int64)
    rank[np.argsort(-sizes, kind="stable")] = np.arange(sizes.size)
    # Each point's closest partner on one surface in a larger component, and its distance.
    partner, gap = np.full(n, -1), np.full(n, np.inf)
    for target in np.argsort(-sizes, kind="stable")[:STACK_COMPONENTS]:
        own = np.flatnonzero(component == target)
        others = np.flatnonzero(rank[component] > rank[target])
        if others.size == 0:
            break
        distance, nearest = build_tree(centroids[own]).query(
            centroids[others],
            distance_upper_bound=float(reach[others].max()),
            workers=query_workers(),
        )
        found = (distance <= reach[others]) & (distance < gap[others])
        mate = own[np.where(found, nearest, 0)]
        cos_a, cos_b = step_cosines(
            centroids[mate] - centroids[others], normals[others], normals[mate]
        )
        found &= np.maximum(off_plane(cos_a), off_plane(cos_b)) <= ON_ONE_SURFACE
        partner[others[found]], gap[others[found]] = mate[found], distance[found]
    # The closest pair of each component.
    joined = np.flatnonzero(partner >= 0)
    order = joined[np.lexsort((gap[joined], component[joined]))]
    first = np.ones(order.size, dtype=bool)
    first[1:] = component[order][1:] != component[order][:-1]
    rows = order[first]
    cols = partner[rows]
    cost = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + 1e-9
    return sparse.coo_matrix((cost, (rows, cols)), shape=(n, n)).tocsr()


def _sensor_cosine(centroids, normals, viewpoints) -> np.ndarray:
    """Cosine (N,) between each normal and the direction to its sensor; 0 where unknown."""
    towards = viewpoints - centroids
    length = np.linalg.norm(towards, axis=1)
    cosine = np.einsum("ij,ij->i", normals, towards) / np.maximum(length, 1e-300)
    return np.where(np.isfinite(cosine), cosine, 0.0)


def _viewpoint_vote(cosine, component) -> np.ndarray:
    """Sign (N,) per point: -1 in components whose normals face away from their sensors.

    Each normal votes with its `cosine` (N,) to the direction of its sensor, so points seen
    head-on count fully and grazing ones, whose sign noise decides, hardly. A component
    seen only at grazing angles (mean |cosine| below ``DECISIVE``, such as a sparse ring far
    down a pipe) follows the vote of the whole cloud, whose components all share the
    outward convention of the extreme-point roots.
    """
    size = int(component.max()) + 1
    votes = np.bincount(component, weights=cosine, minlength=size)
    strength = np.bincount(component, weights=np.abs(cosine), minlength=size) / np.maximum(
        np.bincount(component, minlength=size), 1
    )
    flip = np.where(strength >= DECISIVE, votes < 0.0, votes.sum() < 0.0)
    return np.where(flip[component], -1.0, 1.0)
