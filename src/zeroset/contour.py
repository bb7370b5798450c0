"""Contouring on a sparse band: marching cubes, and the Method of Cubes (one vertex per patch).

Both skip every cube with an undefined corner, so the surface ends where the data end, and
both turn their faces towards positive values (outside).
"""

from __future__ import annotations

import numpy as np

from . import _lattice
from ._mc_table import (
    CENTRE,
    CORNER_OFFSETS,
    EDGE_AXIS,
    EDGE_CORNER,
    FACE_CORNERS,
    JOIN_SHIFT,
    alternating,
    case_table,
    joined_faces,
    patch_table,
)
from ._validate import as_points
from .errors import InputError
from .thresholds import MAX_JUMP
from .types import DistanceField, Mesh

__all__ = ["keyed_marching_cubes", "marching_cubes", "mean_by", "method_of_cubes"]


#: Cyclic position, counter-clockwise about the edge's axis, of the four cubes around a
#: lattice edge, indexed by the bits (axis + 1, axis + 2) of the edge's lower corner in each.
_AROUND_EDGE = np.array([[2, 1], [3, 0]], dtype=np.int64)


def marching_cubes(field: DistanceField) -> Mesh:
    """Extract the zero set of a sparse signed distance field as a triangle mesh.

    Every cube whose eight corners are evaluated and defined, and whose values change
    sign, is triangulated; cubes with a missing or undefined corner are skipped, so the
    surface ends where the data end. Vertices on shared cube edges are shared, so the
    mesh is welded, edge-manifold and consistently oriented, with faces turned towards
    positive values (outside).

    Parameters
    ----------
    field : DistanceField
        From :func:`zeroset.distance.signed_distance`.

    Returns
    -------
    Mesh
        ``vertices`` (M, 3) float64 and ``faces`` (F, 3) int64.

    See Also
    --------
    zeroset.distance.signed_distance : builds the field.
    method_of_cubes : one vertex per cube instead of one per crossed edge.

    Notes
    -----
    Lorensen & Cline 1987, with the case table of :mod:`zeroset._mc_table`, which joins
    crossings face by face so that neighbouring cubes always agree (no cracks), ambiguous
    faces by the asymptotic decider (Nielson & Hamann 1991), so that the field and its
    negative give the same surface; Hoppe et al. 1992, §3.5 (cubes with undefined corners
    are skipped).
    """
    _, vertices, faces, _ = keyed_marching_cubes(field)
    return Mesh(vertices=vertices, faces=faces)


def keyed_marching_cubes(field: DistanceField, *, owned=None):
    """Marching cubes with the global lattice keys of what it made, to weld tiles exactly.

    Parameters
    ----------
    field : DistanceField
    owned : ((3,), (3,)) int64 lattice indices, optional
        Contour only the cubes whose lower corner (i, j, k) lies in ``[owned[0], owned[1])``.

    Returns
    -------
    edge_keys : (V,) int64
        Sorted global key of the lattice edge each vertex lies on: two pieces of one lattice
        that share an edge share its key and, from the same corner values, its vertex. A
        loop's centre vertex has its cube's key, with axis `CENTRE_AXIS`.
    vertices : (V, 3) float64
    faces : (F, 3) int64
        In the order of their cubes' keys, each cube's triangles in table order.
    cube_keys : (F,) int64
        The key of the cube each face was made in.
    """
    keys = _lattice.encode(field.vertices_ijk)
    cube_keys, values, config = _crossed_cubes(field, keys)
    if owned is not None:
        ijk = _lattice.decode(cube_keys)
        inside = np.all((ijk >= owned[0]) & (ijk < owned[1]), axis=1)
        cube_keys, config, values = cube_keys[inside], config[inside], values[inside]
    table, counts, centre = case_table()
    case = config | (joined_faces(values) << JOIN_SHIFT)
    per_cube = counts[case]
    cube_of_tri = np.repeat(np.arange(cube_keys.size), per_cube)
    rank = np.arange(cube_of_tri.size) - np.repeat(np.cumsum(per_cube) - per_cube, per_cube)
    edges = table[case[cube_of_tri], rank]  # (T, 3) cube edge ids, or CENTRE
    tri_keys = _cube_edge_keys(cube_keys[cube_of_tri][:, None], edges)
    unique_keys, faces = np.unique(tri_keys, return_inverse=True)
    vertices = np.empty((unique_keys.size, 3))
    on_edge = (unique_keys & 3) != CENTRE_AXIS
    vertices[on_edge] = _edge_points(unique_keys[on_edge], keys, field)
    # A loop fanned from its centre: the mean of its crossings (vertices of its fan, so
    # among those just placed), keyed by its cube.
    cube = np.searchsorted(cube_keys, unique_keys[~on_edge] >> 2)
    row, edge = np.nonzero(centre[case[cube]])
    crossings = np.searchsorted(unique_keys, _cube_edge_keys(cube_keys[cube[row]], edge))
    vertices[~on_edge] = mean_by(row, vertices[crossings], cube.size)
    return unique_keys, vertices, faces.reshape(-1, 3).astype(np.int64), cube_keys[cube_of_tri]


def method_of_cubes(field: DistanceField, points, centroids, normals) -> Mesh:
    """Contour a sparse signed distance field with one vertex per surface patch of a cube.

    The thesis' Method of Cubes: the data points are projected onto their tangent planes;
    in every crossed cube the projections and the oriented normals are averaged into one
    plane, and the cube's vertex is put on that plane, at the foot of the mean of the
    cube's edge crossings, clamped to the cube. Faces join the vertices of the four cubes
    around every crossed lattice edge (a dual construction), so the mesh is connected by
    construction; a quad is split along its shorter diagonal unless that folds it.

    Where the dual construction would not be a manifold it is resolved: a cube whose sign
    pattern holds several separate patches of surface gets a vertex per patch (the one
    plane is then not used), and where two cubes' patches meet twice across their common
    face, each meeting gets a vertex of its own on that face. Cubes with an undefined
    corner, or a jump, are skipped as in marching cubes, leaving boundaries; bow-tie
    vertices there are for :func:`zeroset.repair.split_nonmanifold_vertices`.

    Parameters
    ----------
    field : DistanceField
        From :func:`zeroset.distance.signed_distance`.
    points : (N, 3) array_like of float
        The points the tangent planes were fitted to.
    centroids : (N, 3) array_like of float
        Tangent-plane origin of each point.
    normals : (N, 3) array_like of float
        Consistently oriented unit normal of each point's plane.

    Returns
    -------
    Mesh
        ``vertices`` (M, 3) float64 and ``faces`` (F, 3) int64, edge-manifold and turned
        towards positive values.

    See Also
    --------
    marching_cubes : the default contouring, one vertex per crossed lattice edge.

    Notes
    -----
    Thesis §3.4 (Method of Cubes: averaged planes in cubes); the faces are the dual of the
    marching-cubes patches (Nielsen 2004, dual marching cubes), which is what keeps the
    thesis' overlaps, unfolded triangles and 4-vertex gaps (figs. 3.38-3.39) out.
    """
    points = as_points(points)
    centroids = as_points(centroids, "centroids")
    normals = as_points(normals, "normals")
    if not points.shape == centroids.shape == normals.shape:
        raise InputError(
            f"points, centroids and normals must have one row each per point; got "
            f"{points.shape}, {centroids.shape} and {normals.shape}"
        )
    return _dual_mesh(field, points, centroids, normals)


def mean_by(group: np.ndarray, rows: np.ndarray, n_groups: int) -> np.ndarray:
    """(G, 3) mean of the (K, 3) `rows` in each of `n_groups` groups (zero where empty)."""
    count = np.bincount(group, minlength=n_groups)
    total = np.stack([np.bincount(group, rows[:, i], n_groups) for i in range(3)], axis=1)
    return total / np.maximum(count, 1)[:, None]


def _dual_mesh(field: DistanceField, points, centroids, normals) -> Mesh:
    """The Method of Cubes: a vertex per surface patch of every crossed cube."""
    cube_keys, values, config = _crossed_cubes(field, _lattice.encode(field.vertices_ijk))
    if cube_keys.size == 0:
        return Mesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64))
    patch, n_patches = patch_table()
    case = config | (joined_faces(values) << JOIN_SHIFT)
    per_cube = n_patches[case]
    cube, edge = np.nonzero(patch[case] >= 0)  # (K,) every crossing, seen from each cube
    vertex = (np.cumsum(per_cube) - per_cube)[cube] + patch[case[cube], edge]
    corner, axis = EDGE_CORNER[edge], EDGE_AXIS[edge]

    f0 = values[cube, corner]
    t = f0 / (f0 - values[cube, corner | (1 << axis)])
    lower_ijk = _lattice.decode(cube_keys[cube]) + CORNER_OFFSETS[corner]
    crossing = lower_ijk.astype(np.float64)
    crossing[np.arange(t.size), axis] += t
    crossing = field.origin + field.cube_size * crossing

    n_vertices = int(per_cube.sum())
    cube_of_vertex = np.repeat(np.arange(cube_keys.size), per_cube)
    centre = mean_by(vertex, crossing, n_vertices)
    gradient = _cube_gradients(values)
    vertices = _place_on_planes(
        centre, cube_keys, cube_of_vertex, per_cube, gradient, field, points, centroids, normals
    )

    lower_positive = (config[cube] >> corner) & 1
    edge_keys = _edge_keys(cube_keys[cube] + _lattice.offset_keys(CORNER_OFFSETS)[corner], axis)
    around = _AROUND_EDGE[(corner >> (axis + 1) % 3) & 1, (corner >> (axis + 2) % 3) & 1]
    order = np.lexsort((around, edge_keys))
    starts, sizes = np.unique(edge_keys[order], return_index=True, return_counts=True)[1:]
    first = order[starts[sizes == 4]]  # one crossing of each edge with four crossed cubes
    quads = vertex[order[starts[sizes == 4, None] + np.arange(4)]]
    flip = lower_positive[first] == 1  # positive side below: the quad faces -axis
    quads[flip] = quads[flip][:, ::-1]
    reference = gradient[cube_of_vertex][quads].sum(axis=1)
    meeting = _meetings(
        quads, cube_keys, case, cube_of_vertex, edge_keys[first], lower_positive[first]
    )
    return _triangulate(vertices, quads, reference, meeting, crossing[first])


def _crossed_cubes(
    field: DistanceField, keys: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubes that are contoured: all corners defined, a sign change, no jump.

    `keys` (V,) are the field's grid vertex keys. Returns the cubes' sorted (C,) keys, (C, 8)
    corner values and (C,) sign configurations.
    """
    corner_keys = keys[:, None] + _lattice.offset_keys(CORNER_OFFSETS)[None, :]
    slot = np.minimum(np.searchsorted(keys, corner_keys), keys.size - 1)
    values = np.where(keys[slot] == corner_keys, field.values[slot], np.nan)
    positive = values > 0.0
    defined = ~np.isnan(values).any(axis=1)
    cubes = np.flatnonzero(defined & positive.any(axis=1) & ~positive.all(axis=1))
    spread = values[cubes].max(axis=1) - values[cubes].min(axis=1)
    cubes = cubes[spread <= MAX_JUMP * np.sqrt(3.0) * field.cube_size]
    config = (positive[cubes] << np.arange(8)).sum(axis=1)
    return keys[cubes], values[cubes], config


def _edge_keys(lower_keys: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Global key of a lattice edge: its lower vertex's key, shifted, with its axis."""
    return (lower_keys << 2) | axis


#: The "axis" in the key of a cube's centre vertex (`_cube_edge_keys`): no lattice edge's.
CENTRE_AXIS = 3


def _cube_edge_keys(cube_keys: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Global keys of cube edges `edges` (0-11, or `CENTRE` for the cube's centre vertex)
    of the cubes `cube_keys`, broadcast together."""
    centre = edges == CENTRE
    edges = np.where(centre, 0, edges)
    lower = cube_keys + _lattice.offset_keys(CORNER_OFFSETS)[EDGE_CORNER[edges]]
    return np.where(centre, _edge_keys(cube_keys, CENTRE_AXIS), _edge_keys(lower, EDGE_AXIS[edges]))


def _edge_points(edge_keys: np.ndarray, keys: np.ndarray, field: DistanceField) -> np.ndarray:
    """Linearly interpolated zero crossing (E, 3) on each lattice edge; `keys` as the field's."""
    lower, axis = edge_keys >> 2, edge_keys & 3
    upper = lower + _lattice.offset_keys(np.eye(3, dtype=np.int64))[axis]
    f0 = field.values[np.searchsorted(keys, lower)]
    f1 = field.values[np.searchsorted(keys, upper)]
    t = f0 / (f0 - f1)
    ijk = _lattice.decode(lower).astype(np.float64)
    ijk[np.arange(ijk.shape[0]), axis] += t
    return field.origin + field.cube_size * ijk


def _cube_gradients(values: np.ndarray) -> np.ndarray:
    """(C, 3) unit direction of increasing value in each cube, from its (C, 8) corners."""
    bits = CORNER_OFFSETS.astype(np.float64)  # (8, 3)
    gradient = values @ (2.0 * bits - 1.0) / 4.0
    return gradient / np.maximum(np.linalg.norm(gradient, axis=1), 1e-300)[:, None]


def _place_on_planes(
    centre, cube_keys, cube_of_vertex, per_cube, gradient, field, points, centroids, normals
) -> np.ndarray:
    """Move each single-patch cube's vertex onto the cube's averaged tangent plane.

    The data points are projected onto their own tangent planes (thesis §3.4.1); the
    projections falling into a cube and their oriented normals are averaged (§3.4.2). The
    vertex goes to the foot of `centre` on that plane, clamped to the cube. Cubes with
    several patches, no projected point, or a plane facing against the field keep `centre`.
    """
    offset = np.einsum("ij,ij->i", points - centroids, normals)
    projected = points - offset[:, None] * normals
    cells = np.floor((projected - field.origin) / field.cube_size).astype(np.int64)
    inside = np.all(np.abs(cells) < 2**18, axis=1)  # far points cannot be in a band cube
    cell_keys = _lattice.encode(cells[inside])
    slot = np.minimum(np.searchsorted(cube_keys, cell_keys), cube_keys.size - 1)
    hit = cube_keys[slot] == cell_keys
    cube = slot[hit]
    n_cubes = cube_keys.size
    count = np.bincount(cube, minlength=n_cubes)
    mean = mean_by(cube, projected[inside][hit], n_cubes)
    direction = mean_by(cube, normals[inside][hit], n_cubes)
    length = np.linalg.norm(direction, axis=1)
    plane_normal = direction / np.maximum(length, 1e-300)[:, None]
    usable = (count > 0) & (per_cube == 1) & (np.einsum("ij,ij->i", plane_normal, gradient) > 0)

    vertices = centre.copy()
    on = usable[cube_of_vertex]
    c = cube_of_vertex[on]
    height = np.einsum("ij,ij->i", centre[on] - mean[c], plane_normal[c])
    low = field.origin + field.cube_size * _lattice.decode(cube_keys[c])
    vertices[on] = np.clip(
        centre[on] - height[:, None] * plane_normal[c], low, low + field.cube_size
    )
    return vertices


def _meetings(quads, cube_keys, case, cube_of_vertex, edge_keys, lower_positive) -> np.ndarray:
    """(Q, 4) which segment of its cube face each quad side crosses; -1 if the face has one.

    On a face whose signs alternate around it, the face rule cuts each positive corner
    off on its own, or each negative one where the face joins its positive corners, so a
    segment is named by the corner it cuts off: that end of the quad's lattice edge.
    """
    ijk = _lattice.decode(cube_keys)
    cube = cube_of_vertex[quads]  # (Q, 4)
    step = ijk[np.roll(cube, -1, axis=1)] - ijk[cube]  # (Q, 4, 3): to the next cube
    axis = np.abs(step).argmax(axis=2)
    face = 2 * axis + (step.max(axis=2) > 0)
    ambiguous = alternating((case[cube][..., None] >> FACE_CORNERS[face]) & 1)  # (Q, 4)
    joined = (case[cube] >> (JOIN_SHIFT + face)) & 1  # (Q, 4), the same from either cube
    upper = _lattice.offset_keys(np.eye(3, dtype=np.int64))[edge_keys & 3][:, None]
    lower_cut = (lower_positive[:, None] == 1) != (joined == 1)  # the cut-off end is lower
    corner = (edge_keys >> 2)[:, None] + np.where(lower_cut, 0, upper)
    return np.where(ambiguous, corner, -1)


def _triangulate(vertices, quads, reference, meeting, crossing) -> Mesh:
    """Split the dual quads into triangles; give a side that two segments cross a vertex each.

    Two face-adjacent cubes whose patches meet in two separate segments of their common
    face would share one side between up to four quads. Each segment instead gets a vertex
    at the mean of its crossings; its quads run through it and are fanned from it.
    """
    n = vertices.shape[0]
    sides = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2), axis=2) @ [n, 1]
    keys, inverse = np.unique(
        np.stack([sides, meeting], axis=2).reshape(-1, 2), axis=0, return_inverse=True
    )
    side_of_key = np.unique(keys[:, 0], return_inverse=True)[1]
    twice = np.bincount(side_of_key) > 1  # sides crossed by two different segments
    split = twice[side_of_key][inverse].reshape(quads.shape)
    plain = ~split.any(axis=1)
    faces = [_split_quads(vertices, quads[plain], reference[plain])]
    if not plain.all():
        q, s = np.nonzero(split)
        used, extra = np.unique(inverse.reshape(quads.shape)[q, s], return_inverse=True)
        vertices = np.concatenate([vertices, mean_by(extra, crossing[q], used.size)])
        inserted = np.full(quads.shape, -1)
        inserted[q, s] = n + extra
        faces.append(_fan_polygons(quads[~plain], inserted[~plain]))
    return Mesh(vertices=vertices, faces=np.concatenate(faces).astype(np.int64))


def _split_quads(vertices, quads, reference) -> np.ndarray:
    """(2Q, 3) triangles of (Q, 4) quads, along the shorter diagonal unless that folds one."""
    a, b, c, d = (vertices[quads[:, i]] for i in range(4))

    def unfolded(p, q, r, s):  # triangles (p, q, r) and (p, r, s) both face `reference`
        first = np.einsum("ij,ij->i", np.cross(q - p, r - p), reference) > 0
        return first & (np.einsum("ij,ij->i", np.cross(r - p, s - p), reference) > 0)

    ok_ac, ok_bd = unfolded(a, b, c, d), unfolded(b, c, d, a)
    shorter_ac = np.einsum("ij,ij->i", c - a, c - a) <= np.einsum("ij,ij->i", d - b, d - b)
    use_ac = np.where(ok_ac == ok_bd, shorter_ac, ok_ac)
    rolled = np.where(use_ac[:, None], quads, np.roll(quads, -1, axis=1))
    return np.concatenate([rolled[:, [0, 1, 2]], rolled[:, [0, 2, 3]]])


def _fan_polygons(quads: np.ndarray, inserted: np.ndarray) -> np.ndarray:
    """Triangles of quads with vertices inserted after some corners, fanned from the first."""
    triangles = []
    for quad, extra in zip(quads.tolist(), inserted.tolist(), strict=True):
        ring, apex = [], None
        for corner, after in zip(quad, extra, strict=True):
            ring.append(corner)
            if after >= 0:
                apex = len(ring) if apex is None else apex
                ring.append(after)
        ring = ring[apex:] + ring[:apex]
        triangles += [(ring[0], ring[i], ring[i + 1]) for i in range(1, len(ring) - 1)]
    return np.array(triangles, dtype=np.int64).reshape(-1, 3)
