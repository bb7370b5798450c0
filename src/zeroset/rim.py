"""Open boundaries where the data stop: the mesh cut smoothly at the edge of the sampling.

A lattice cube is contoured when its eight corners are defined, and a corner is defined
when its foot point lies within a point's radius of the data. So an open end or a hole
comes out one or two radii past the last points, in whole cubes: a saw-tooth rim beyond
the data. Here every vertex near a boundary is tested against the data around it: the
centroid of the points within a radius R of a vertex lies beside the vertex, in the
tangent plane, by ``4 R / (3 pi)`` (0.42 R) when the vertex sits on the straight edge of
evenly sampled data, by less inside and by more outside (Adamson & Alexa 2004 bound
point-set surfaces the same way). The mesh is cut along the line where that offset
crosses ``4 R / (3 pi)``, each cut point interpolated along its edge, so the rim follows
the edge of the data within a fraction of the spacing, without steps.

The centroid test assumes a straight edge: around a round hole the data fill more than
half of the disc at the hole's edge, and the rim comes out inside the hole. A hole wider
than the gaps the bridges may cross has room for an empty ball (one with no measured point
inside) of half the longest bridge, and every vertex within such a ball is outside: the
union of these balls reaches the hole's last points, whatever its shape (an alpha shape,
Edelsbrunner & Mücke 1994), and chords that cross the hole off its centre are cut away
with it. The points must surround such a ball both in the mesh's plane and in the tangent
plane of the point it reaches to, so that a ball beside a narrow object, which the points of
a wall behind it seem to surround, opens no hole.
"""

from __future__ import annotations

import numpy as np

from ._unique import distinct
from .neighbours import ball_pairs, build_tree, query_workers
from .repair import fan_samples
from .thresholds import (
    BAND,
    CLIMB,
    CLIMB_STEPS,
    CROSSING_STEPS,
    DISC,
    DISC_POINTS,
    EDGE_OFFSET,
    ENCLOSE,
    FAR,
    OPEN_ANGLE,
    SNAP,
    THIN,
)
from .topology import (
    boundary_edges,
    corner_fans,
    edge_ids,
    face_area_vectors,
    undirected_edges,
    undo_turned_faces,
    vertex_normals,
)
from .types import Mesh

__all__ = [
    "cut_mesh",
    "data_edge",
    "empty_ball_depth",
    "empty_balls",
    "no_empty_ball",
    "trim_to_data",
]


def data_edge(
    points, radii, vertices, normals, *, reach=None, tree=None, hollow=None
) -> np.ndarray:
    """Signed position (V,) of each vertex across the edge of the data, in disc radii.

    For a vertex v with unit normal n, R is ``DISC`` times the radius of the data point
    nearest v, and c the centroid of the points within R of v. The value is
    ``|(c - v) - ((c - v) . n) n| / R - EDGE_OFFSET``: negative inside the data, zero on a
    straight edge of evenly spaced points, positive beyond it; 1 where fewer than
    ``DISC_POINTS`` points lie within R. Where the points in the disc spread less than
    ``THIN R^2`` (variance) across their main direction in the tangent plane, they sample
    a curve, and the value is at least ``1 - variance / (THIN R^2)``. It is also at least
    ``d / r - 1``, with d the distance to the nearest point and r its `reach`: the surface
    reaches no further from the data than the signed distance is defined.

    Parameters
    ----------
    points : (N, 3) float64
    radii : (N,) float64
        Neighbourhood radius of each point (`zeroset.density.point_radii`), data units.
    vertices, normals : (V, 3) float64
        Positions and unit normals where the edge is tested.
    reach : (N,) float64, optional
        How far from each point the surface may reach; `radii` by default.
    tree : cKDTree, optional
        A tree over `points`, to reuse one already built.
    hollow : (V,) float64, optional
        How deep each vertex lies in an empty ball (`empty_ball_depth`), data units; the
        value is at least that over R.
    """
    tree = build_tree(points) if tree is None else tree
    reach = radii if reach is None else reach
    gap, nearest = tree.query(vertices, workers=query_workers())
    radius = DISC * radii[nearest]
    rows, flat, counts = ball_pairs(tree, vertices, radius)
    inside = np.maximum(counts, 1)[:, None]
    centroid = np.zeros_like(vertices)
    np.add.at(centroid, rows, points[flat])
    centroid /= inside
    offset = centroid - vertices
    offset -= np.einsum("ij,ij->i", offset, normals)[:, None] * normals
    value = np.linalg.norm(offset, axis=1) / radius - EDGE_OFFSET
    # The spread across the data in the tangent plane: a curve of points has none.
    spread = points[flat] - centroid[rows]
    spread -= np.einsum("ij,ij->i", spread, normals[rows])[:, None] * normals[rows]
    moments = np.zeros((vertices.shape[0], 3, 3))
    np.add.at(moments, rows, spread[:, :, None] * spread[:, None, :])
    narrow = np.linalg.eigvalsh(moments / inside[:, :, None])[:, 1] / radius**2
    value = np.maximum(value, 1.0 - narrow / THIN)
    # Beyond the reach of the nearest point, the surface is not defined at all.
    value = np.maximum(value, gap / reach[nearest] - 1.0)
    if hollow is not None:
        value = np.maximum(value, hollow / radius)
    return np.where(counts >= DISC_POINTS, value, 1.0)


def empty_balls(mesh: Mesh, normals, tree, least, *, planes=None) -> tuple[np.ndarray, np.ndarray]:
    """Centres (C, 3) and radii (C,) of the balls centred on `mesh` that hold no point of
    `tree` (a k-d tree over the points), each reaching to its nearest point and at least
    as large as that point's `least` (N,), data units.

    Every vertex so far from the points is a centre. So is every vertex within ``CLIMB``
    of that after it climbs the distance to the points: it steps along its tangent plane
    (`normals` (V, 3), unit) away from its nearest point, halving the step where the
    distance does not grow, at most ``CLIMB`` times the `least` of its first nearest point
    in all. A centre inside a round hole so reaches the hole's middle, whose ball reaches
    all round to its last points, however coarse the mesh there. Only the balls that the
    points surround are kept (`_enclosed`): the rim test already places open ends, and the
    space between two sparse scan lines is no hole. With `planes` (N, 3), the unit normals
    of the points' tangent planes (any sign), the points must surround a ball in the plane
    of its nearest point too: beside an object narrower than a cube (a post in front of a
    wall), the lattice's surface reaches past the data at a slant, and in that surface's
    plane the points of the object and of the wall behind seem to surround a ball that lies
    beside the object, in no hole of it."""
    least = np.asarray(least, dtype=np.float64)
    gap, nearest = tree.query(mesh.vertices, workers=query_workers())
    start = np.flatnonzero(gap >= (1.0 - CLIMB) * least[nearest])
    centre, normal = mesh.vertices[start], normals[start]
    depth, near = gap[start], nearest[start]
    reach = CLIMB * least[near]
    step, travel = 0.5 * reach, np.zeros(start.size)
    for _ in range(CLIMB_STEPS):
        away = centre - tree.data[near]
        away -= np.einsum("ij,ij->i", away, normal)[:, None] * normal
        away /= np.maximum(np.linalg.norm(away, axis=1), 1e-300)[:, None]
        step = np.minimum(step, reach - travel)
        trial = centre + step[:, None] * away
        trial_depth, trial_near = tree.query(trial, workers=query_workers())
        better = trial_depth > depth
        centre[better], depth[better] = trial[better], trial_depth[better]
        near[better] = trial_near[better]
        travel[better] += step[better]
        step[~better] *= 0.5
    centres = np.concatenate([mesh.vertices, centre])
    radii = np.concatenate([gap, depth])
    normal = np.concatenate([normals, normal])
    nearest = np.concatenate([nearest, near])
    empty = np.flatnonzero(radii >= least[nearest])
    enclosed = _enclosed(centres[empty], radii[empty], normal[empty], tree)
    if planes is not None:
        plane = planes[nearest[empty]]
        enclosed &= _enclosed(centres[empty], radii[empty], plane, tree)
    return centres[empty[enclosed]], radii[empty[enclosed]]


def no_empty_ball(points, least, *, tree=None):
    """A test for `zeroset.repair.fill_small_holes`: whether the fan over a loop
    (`zeroset.repair.fan_samples`) lies everywhere within `least` (N,) of the nearest of
    the `points` (N, 3), so that the hole has room for no empty ball: a gap in the
    sampling, not a hole. The k-d `tree` over the points is built at the first loop tested
    unless given."""

    def closable(ring: np.ndarray) -> bool:
        nonlocal tree
        tree = build_tree(points) if tree is None else tree
        gap, nearest = tree.query(fan_samples(ring), workers=query_workers())
        return bool(np.all(gap < least[nearest]))

    return closable


def _enclosed(centres, radii, normals, tree) -> np.ndarray:
    """Whether (C,) the points within ``ENCLOSE`` radii of each empty ball surround it: no
    angle between two of them, about the ball's centre in its tangent plane (`normals`
    (C, 3)), is wider than ``OPEN_ANGLE``. A hole is surrounded by its data; the space past
    an open end, or between two scan lines, is not."""
    if centres.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    rows, flat, counts = ball_pairs(tree, centres, ENCLOSE * radii)
    axis = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    u = np.cross(normals, axis)
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(normals, u)
    offset = tree.data[flat] - centres[rows]
    angle = np.arctan2(
        np.einsum("ij,ij->i", offset, v[rows]), np.einsum("ij,ij->i", offset, u[rows])
    )
    order = np.lexsort((angle, rows))
    rows, angle = rows[order], angle[order]
    gap = np.zeros(centres.shape[0])
    inner = rows[1:] == rows[:-1]
    np.maximum.at(gap, rows[1:][inner], np.diff(angle)[inner])
    has = counts > 0
    first, last = np.cumsum(counts) - counts, np.cumsum(counts) - 1
    wrap = np.full(centres.shape[0], 2.0 * np.pi)
    wrap[has] = angle[first[has]] + 2.0 * np.pi - angle[last[has]]
    gap = np.maximum(gap, wrap)
    return gap <= OPEN_ANGLE


def empty_ball_depth(positions, centres, radii, tree=None) -> np.ndarray:
    """How deep (P,) each position lies in the union of the balls (C,) of `centres` (C, 3)
    and `radii` (C,): the largest ``radius - distance to the centre``, data units; negative
    or -inf outside every ball.

    `tree` is a k-d tree over `centres`, to reuse one already built."""
    positions = np.asarray(positions, dtype=np.float64)
    depth = np.full(positions.shape[0], -np.inf)
    if centres.shape[0] == 0:
        return depth
    tree = build_tree(centres) if tree is None else tree
    rows, flat, _ = ball_pairs(tree, positions, radii.max())
    inside = radii[flat] - np.linalg.norm(positions[rows] - centres[flat], axis=1)
    np.maximum.at(depth, rows, inside)
    return depth


def cut_mesh(mesh: Mesh, value: np.ndarray, *, locate=None) -> tuple[Mesh, int]:
    """Keep the part of `mesh` where the per-vertex `value` (V,) is negative.

    The mesh is cut along the zero line of `value`: each edge whose ends lie on either
    side is crossed where `value`, linear along the edge, is zero, or where `locate`
    puts the crossing. Where that lies within ``SNAP`` of the edge's length from one end,
    the end moves onto the crossing instead (as isosurface stuffing warps its lattice,
    Labelle & Shewchuk 2007), so no sliver is made, unless the move would turn a triangle
    over, pinch two stretches of rim into one vertex, or leave a strip one edge wide (an
    inside edge whose faces all have their third corner outside) no area. Every other
    crossed edge gets one new vertex, shared by the faces on both sides. Orientation is
    kept, and faces wholly outside go.

    Parameters
    ----------
    mesh : Mesh
    value : (V,) float64
    locate : callable, optional
        ``locate(inner (C,), outer (C,), t (C,)) -> t (C,)``: where, as a fraction from
        vertex `inner` to vertex `outer`, each crossed edge meets the zero line, given the
        linear guess `t`.

    Returns
    -------
    mesh : Mesh
        The kept part: the vertices kept in their order, then one per cut edge.
    cut : int
        Edges crossed.
    """
    edges, corner_edge, _ = undirected_edges(mesh.faces)
    # Orient each crossed edge from its inner end a to its outer end b.
    a, b = edges[:, 0], edges[:, 1]
    flip = value[a] >= 0.0
    a, b = np.where(flip, b, a), np.where(flip, a, b)
    crossed = (value[a] < 0.0) & (value[b] >= 0.0)
    t = np.zeros(edges.shape[0])
    t[crossed] = value[a[crossed]] / (value[a[crossed]] - value[b[crossed]])
    if locate is not None and crossed.any():
        t[crossed] = np.clip(locate(a[crossed], b[crossed], t[crossed]), 0.0, 1.0)
    # The ends of an inside edge whose faces all have their third corner outside stay: the
    # kept strip along it is one edge wide (a post, a pole narrower than a cube), and moving
    # both ends onto the cut would leave it no area.
    inside = value < 0.0
    flanked = np.zeros(edges.shape[0], dtype=bool)
    flanked[corner_edge[inside[mesh.faces[:, [2, 0, 1]]]]] = True
    pinned = np.zeros(mesh.n_vertices, dtype=bool)
    pinned[edges[inside[edges].all(axis=1) & ~flanked]] = True
    vertices, kept, moved = _cut_faces(mesh, value, edges, corner_edge, a, b, t, pinned)
    # An end moved onto the cut can pinch two stretches of rim into one vertex (a bow
    # tie): such ends stay, and their edges are cut instead.
    pinch = moved & _bow_ties(kept, vertices.shape[0])[: mesh.n_vertices]
    if pinch.any():
        vertices, kept, _ = _cut_faces(mesh, value, edges, corner_edge, a, b, t, pinch | pinned)
    used, inverse = np.unique(kept, return_inverse=True)
    mesh = Mesh(vertices=vertices[used], faces=inverse.reshape(-1, 3).astype(np.int64))
    return mesh, int(np.count_nonzero(crossed))


def _cut_faces(mesh, value, edges, corner_edge, a, b, t, pinned):
    """The cut of `cut_mesh` for crossings at fractions `t` (E,) from inner ends `a` (E,) to
    outer ends `b` (E,) of the `edges`: the vertices (V + C, 3), the kept faces (K, 3) into
    them, and which of the mesh's vertices moved onto a crossing (V,). Ends marked
    `pinned` (V,) do not move."""
    faces, vertices = mesh.faces, mesh.vertices.copy()
    crossed = (value[a] < 0.0) & (value[b] >= 0.0)
    position = vertices[a] + t[:, None] * (vertices[b] - vertices[a])
    # Each end moves to the nearest crossing within SNAP of it, if any.
    rows = np.flatnonzero(crossed)
    end = np.concatenate([a[rows], b[rows]])
    near = np.concatenate([t[rows], 1.0 - t[rows]])
    close = np.flatnonzero((near < SNAP) & ~pinned[end])
    close = close[np.argsort(near[close], kind="stable")]
    moved, first = np.unique(end[close], return_index=True)
    vertices[moved] = position[np.concatenate([rows, rows])[close[first]]]
    # A move that would turn a triangle over is undone (the edge is cut instead).
    reference = face_area_vectors(mesh.vertices, faces)
    vertices, _ = undo_turned_faces(vertices, mesh.vertices, faces, reference)
    moved = np.any(vertices != mesh.vertices, axis=1)
    value = np.where(moved, 0.0, value)
    # Cut what is still crossed: each edge with one end inside and one outside.
    inside, outside = value < 0.0, value > 0.0
    cut = inside[a] & outside[b]
    crossing = np.full(edges.shape[0], -1, dtype=np.int64)
    crossing[cut] = mesh.n_vertices + np.arange(np.count_nonzero(cut))
    vertices = np.concatenate([vertices, position[cut]])
    # Edge i of a face joins its corners i and i + 1; its cut vertex or -1.
    mid = crossing[corner_edge]
    n_in, n_out = inside[faces].sum(axis=1), outside[faces].sum(axis=1)
    # Turn each face so that its corner 0 is the one inside (one inside) or outside (two).
    first = np.where(n_in == 2, np.argmax(outside[faces], axis=1), np.argmax(inside[faces], axis=1))
    order = (np.arange(3)[None, :] + first[:, None]) % 3
    p, q, r = np.take_along_axis(faces, order, axis=1).T
    pq, _, rp = np.take_along_axis(mid, order, axis=1).T
    pieces = [faces[n_out == 0]]
    pieces.append(np.stack([p, pq, rp], axis=1)[(n_in == 1) & (n_out == 2)])
    # One inside, one on the line, one outside.
    one = (n_in == 1) & (n_out == 1)
    pieces.append(np.stack([p, q, rp], axis=1)[one & outside[r]])
    pieces.append(np.stack([p, pq, r], axis=1)[one & outside[q]])
    # Corner p outside: the quad pq, q, r, rp, cut along its shorter diagonal.
    two = (n_in == 2) & (n_out == 1)
    short = np.linalg.norm(vertices[pq] - vertices[r], axis=1) <= np.linalg.norm(
        vertices[q] - vertices[rp], axis=1
    )
    pieces += [np.stack(f, axis=1)[two & short] for f in ((pq, q, r), (pq, r, rp))]
    pieces += [np.stack(f, axis=1)[two & ~short] for f in ((pq, q, rp), (q, r, rp))]
    return vertices, np.concatenate(pieces), moved


def _bow_ties(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Whether (V,) each vertex joins more than one fan of `faces` (a bow tie)."""
    fan, _ = corner_fans(faces, edge_ids(faces, n_vertices)[0])
    pairs = np.unique(np.c_[faces.reshape(-1), fan], axis=0)
    return np.bincount(pairs[:, 0], minlength=n_vertices) > 1


def trim_to_data(
    mesh: Mesh,
    points,
    radii,
    *,
    cube_size: float,
    reach=None,
    measured=None,
    hole=None,
    measured_tree=None,
    planes=None,
) -> tuple[Mesh, dict]:
    """Cut the mesh back to the edge of the data around its boundaries.

    Vertices within ``BAND`` largest radii plus one cube of a boundary vertex are tested
    (`data_edge`), and so are vertices farther than ``FAR`` radii from the nearest point
    (a hole the lattice closed); the others lie where the data surround them. With `hole`,
    every vertex at least `hole` radii from the nearest `measured` point is the centre of
    an empty ball reaching to that point (`empty_balls`), and the vertices within such a
    ball are tested and outside (`empty_ball_depth`, in disc radii). The cut crosses each
    edge where the test, not its linear interpolation, is zero (``CROSSING_STEPS`` of
    regula falsi).

    Parameters
    ----------
    mesh : Mesh
    points : (N, 3) float64
    radii : (N,) float64
        Neighbourhood radius of each point, data units.
    cube_size : float
        The lattice's cube, data units.
    reach : (N,) float64, optional
        How far from each point the surface may reach (`data_edge`); `radii` by default.
    measured : (N,) bool, optional
        The points that were measured (not gap bridges); all by default.
    hole : float, optional
        Radius of the smallest empty ball that opens a hole, over the radius of the point
        it reaches to; none by default.
    measured_tree : cKDTree, optional
        A tree over the `measured` points, to reuse one already built.
    planes : (N, 3) float64, optional
        Unit normal of each point's tangent plane, any sign: an empty ball is a hole only
        where the points surround it in its nearest point's plane too (`empty_balls`).

    Returns
    -------
    mesh : Mesh
    counts : dict
        ``rim_vertices_tested``, ``rim_faces_removed`` (faces wholly outside),
        ``rim_edges_cut`` and ``rim_hole_vertices`` (vertices in an empty ball).
    """
    tree = build_tree(points)
    gap, nearest = tree.query(mesh.vertices, workers=query_workers())
    tested = gap > FAR * radii[nearest]
    rim = distinct(boundary_edges(mesh.faces))
    if rim.size:
        distance, _ = build_tree(mesh.vertices[rim]).query(
            mesh.vertices,
            distance_upper_bound=BAND * radii.max() + cube_size,
            workers=query_workers(),
        )
        tested |= np.isfinite(distance)
    normals = vertex_normals(mesh)
    centres, depths = np.zeros((0, 3)), np.zeros(0)
    if hole is not None:
        solid = np.ones(points.shape[0], bool) if measured is None else measured
        solid_tree = tree if solid.all() else measured_tree
        solid_tree = build_tree(points[solid]) if solid_tree is None else solid_tree
        centres, depths = empty_balls(
            mesh,
            normals,
            solid_tree,
            hole * radii[solid],
            planes=None if planes is None else planes[solid],
        )
    balls, hollow = None, np.zeros(0, dtype=np.int64)
    if centres.shape[0]:
        balls = build_tree(centres)
        hollow = distinct(ball_pairs(build_tree(mesh.vertices), centres, depths)[1])
        tested[hollow] = True
    near = np.flatnonzero(tested)

    def test(positions, normals):
        depth = empty_ball_depth(positions, centres, depths, tree=balls)
        return data_edge(points, radii, positions, normals, reach=reach, tree=tree, hollow=depth)

    value = np.full(mesh.n_vertices, -1.0)
    value[near] = test(mesh.vertices[near], normals[near])
    outside = (value[mesh.faces] >= 0.0).all(axis=1)

    def locate(inner, outer, t):
        # Regula falsi on the edge test along each crossed edge, from the linear guess;
        # the Illinois rule halves the value kept at an end that two steps did not move.
        lo, hi, f_lo, f_hi = np.zeros_like(t), np.ones_like(t), value[inner], value[outer]
        side = np.zeros(t.shape, dtype=np.int8)
        for _ in range(CROSSING_STEPS):
            position = mesh.vertices[inner] + t[:, None] * (
                mesh.vertices[outer] - mesh.vertices[inner]
            )
            normal = (1.0 - t)[:, None] * normals[inner] + t[:, None] * normals[outer]
            normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
            f = test(position, normal)
            below = f < 0.0
            f_hi = np.where(below & (side < 0), 0.5 * f_hi, f_hi)
            f_lo = np.where(~below & (side > 0), 0.5 * f_lo, f_lo)
            lo, f_lo = np.where(below, t, lo), np.where(below, f, f_lo)
            hi, f_hi = np.where(below, hi, t), np.where(below, f_hi, f)
            side = np.where(below, -1, 1).astype(np.int8)
            t = lo + (hi - lo) * f_lo / (f_lo - f_hi)
        return t

    trimmed, cut = cut_mesh(mesh, value, locate=locate)
    return trimmed, {
        "rim_vertices_tested": int(near.size),
        "rim_faces_removed": int(np.count_nonzero(outside)),
        "rim_edges_cut": cut,
        "rim_hole_vertices": int(hollow.size),
    }
