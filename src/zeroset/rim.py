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
"""

from __future__ import annotations

import numpy as np

from .neighbours import build_tree
from .topology import (
    boundary_edges,
    face_area_vectors,
    undirected_edges,
    undo_turned_faces,
    vertex_normals,
)
from .types import Mesh

__all__ = ["EDGE_OFFSET", "cut_mesh", "data_edge", "trim_to_data"]

#: Tangential offset of the centroid of a half disc of radius 1 from its centre.
EDGE_OFFSET = 4.0 / (3.0 * np.pi)
#: Radius of the disc whose centroid is taken, over the radius of the nearest point.
DISC = 1.5
#: Smallest variance across the data in a disc, over its radius squared: 1/4 for a full
#: disc, 0.07 for a half disc; less is a curve of points, not a surface.
THIN = 0.02
#: Fewest points in a disc for its centroid to count; with fewer the vertex is outside.
MIN_POINTS = 3
#: Vertices within this many largest radii (plus one cube) of a boundary vertex are
#: tested: the lattice defines the surface at most a radius and a cube past the data.
BAND = 2.5
#: Vertices farther than this many radii from the nearest point are tested too: a hole
#: in the data that the lattice closed.
FAR = 0.5
#: Steps of regula falsi that place each crossing on its edge.
CROSSING_STEPS = 2
#: A cut this close to an end of its edge, over the edge's length, moves that end.
SNAP = 0.2


def data_edge(points, radii, vertices, normals, *, reach=None, tree=None) -> np.ndarray:
    """Signed position (V,) of each vertex across the edge of the data, in disc radii.

    For a vertex v with unit normal n, R is ``DISC`` times the radius of the data point
    nearest v, and c the centroid of the points within R of v. The value is
    ``|(c - v) - ((c - v) . n) n| / R - EDGE_OFFSET``: negative inside the data, zero on a
    straight edge of evenly spaced points, positive beyond it; 1 where fewer than
    ``MIN_POINTS`` points lie within R. Where the points in the disc spread less than
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
    """
    tree = build_tree(points) if tree is None else tree
    reach = radii if reach is None else reach
    gap, nearest = tree.query(vertices, workers=-1)
    radius = DISC * radii[nearest]
    members = tree.query_ball_point(vertices, radius, workers=-1, return_sorted=False)
    counts = np.fromiter((len(m) for m in members), dtype=np.int64, count=len(members))
    rows = np.repeat(np.arange(vertices.shape[0]), counts)
    flat = np.fromiter((i for m in members for i in m), dtype=np.int64, count=int(counts.sum()))
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
    return np.where(counts >= MIN_POINTS, value, 1.0)


def cut_mesh(mesh: Mesh, value: np.ndarray, *, locate=None) -> tuple[Mesh, int]:
    """Keep the part of `mesh` where the per-vertex `value` (V,) is negative.

    The mesh is cut along the zero line of `value`: each edge whose ends lie on either
    side is crossed where `value`, linear along the edge, is zero, or where `locate`
    puts the crossing. Where that lies within ``SNAP`` of the edge's length from one end,
    the end moves onto the crossing instead (as isosurface stuffing warps its lattice,
    Labelle & Shewchuk 2007), so no sliver is made, unless the move would turn a triangle
    over. Every other crossed edge gets one new vertex, shared by the faces on both
    sides. Orientation is kept, and faces wholly outside go.

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
    faces, vertices, value = mesh.faces, mesh.vertices.copy(), value.copy()
    edges, corner_edge, _ = undirected_edges(faces)
    # Orient each crossed edge from its inner end a to its outer end b.
    a, b = edges[:, 0], edges[:, 1]
    flip = value[a] >= 0.0
    a, b = np.where(flip, b, a), np.where(flip, a, b)
    crossed = (value[a] < 0.0) & (value[b] >= 0.0)
    t = np.zeros(edges.shape[0])
    t[crossed] = value[a[crossed]] / (value[a[crossed]] - value[b[crossed]])
    if locate is not None and crossed.any():
        t[crossed] = np.clip(locate(a[crossed], b[crossed], t[crossed]), 0.0, 1.0)
    position = vertices[a] + t[:, None] * (vertices[b] - vertices[a])
    # Each end moves to the nearest crossing within SNAP of it, if any.
    rows = np.flatnonzero(crossed)
    end = np.concatenate([a[rows], b[rows]])
    near = np.concatenate([t[rows], 1.0 - t[rows]])
    close = np.flatnonzero(near < SNAP)
    close = close[np.argsort(near[close], kind="stable")]
    moved, first = np.unique(end[close], return_index=True)
    vertices[moved] = position[np.concatenate([rows, rows])[close[first]]]
    # A move that would turn a triangle over is undone (the edge is cut instead).
    reference = face_area_vectors(mesh.vertices, faces)
    vertices, _ = undo_turned_faces(vertices, mesh.vertices, faces, reference)
    value[np.any(vertices != mesh.vertices, axis=1)] = 0.0
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
    kept = np.concatenate(pieces)
    used, inverse = np.unique(kept, return_inverse=True)
    mesh = Mesh(vertices=vertices[used], faces=inverse.reshape(-1, 3).astype(np.int64))
    return mesh, int(np.count_nonzero(crossed))


def trim_to_data(
    mesh: Mesh, points, radii, *, cube_size: float, reach=None
) -> tuple[Mesh, dict]:
    """Cut the mesh back to the edge of the data around its boundaries.

    Vertices within ``BAND`` largest radii plus one cube of a boundary vertex are tested
    (`data_edge`), and so are vertices farther than ``FAR`` radii from the nearest point
    (a hole the lattice closed); the others lie where the data surround them. The cut
    crosses each edge where the test, not its linear interpolation, is zero
    (``CROSSING_STEPS`` of regula falsi).

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

    Returns
    -------
    mesh : Mesh
    counts : dict
        ``rim_vertices_tested``, ``rim_faces_removed`` (faces wholly outside) and
        ``rim_edges_cut``.
    """
    tree = build_tree(points)
    gap, nearest = tree.query(mesh.vertices, workers=-1)
    tested = gap > FAR * radii[nearest]
    rim = np.unique(boundary_edges(mesh.faces))
    if rim.size:
        distance, _ = build_tree(mesh.vertices[rim]).query(
            mesh.vertices, distance_upper_bound=BAND * radii.max() + cube_size, workers=-1
        )
        tested |= np.isfinite(distance)
    near = np.flatnonzero(tested)
    normals = vertex_normals(mesh)
    value = np.full(mesh.n_vertices, -1.0)
    value[near] = data_edge(
        points, radii, mesh.vertices[near], normals[near], reach=reach, tree=tree
    )
    outside = (value[mesh.faces] >= 0.0).all(axis=1)

    def locate(inner, outer, t):
        # Regula falsi on the edge test along each crossed edge, from the linear guess.
        lo, hi, f_lo, f_hi = np.zeros_like(t), np.ones_like(t), value[inner], value[outer]
        for _ in range(CROSSING_STEPS):
            position = mesh.vertices[inner] + t[:, None] * (
                mesh.vertices[outer] - mesh.vertices[inner]
            )
            normal = (1.0 - t)[:, None] * normals[inner] + t[:, None] * normals[outer]
            normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
            f = data_edge(points, radii, position, normal, reach=reach, tree=tree)
            below = f < 0.0
            lo, f_lo = np.where(below, t, lo), np.where(below, f, f_lo)
            hi, f_hi = np.where(below, hi, t), np.where(below, f_hi, f)
            t = lo + (hi - lo) * f_lo / (f_lo - f_hi)
        return t

    trimmed, cut = cut_mesh(mesh, value, locate=locate)
    return trimmed, {
        "rim_vertices_tested": int(near.size),
        "rim_faces_removed": int(np.count_nonzero(outside)),
        "rim_edges_cut": cut,
    }
