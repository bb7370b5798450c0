"""Ground-truth triangle meshes built from the analytic parametrisations.

Every vertex lies on the true surface (to rounding), faces are oriented so their normals
point the way the sample normals do, and open surfaces end in exact boundary circles. The
meshes are structured grids in the surface parameters; a hole in a pipe wall is meshed with
an O-grid whose inner ring lies on the hole's rim, so the rim is exact at every vertex.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .._validate import positive
from ..errors import InputError
from ..types import Mesh

__all__ = [
    "MAX_FACES",
    "elbow_mesh",
    "grid_mesh",
    "join",
    "resolve_spacing",
    "sphere_mesh",
    "tee_mesh",
    "torus_mesh",
    "tube_mesh",
]

#: Default truth meshes stay below this many faces (the spacing grows to keep them there).
MAX_FACES = 300_000
_TARGET_FACES = 270_000
# An explicit spacing that would need more faces than this is refused.
_HARD_LIMIT_FACES = 20_000_000

# A hole in a pipe wall: (theta_c, z_c, half_u, half_v, rim) with the hole centred at polar
# angle theta_c and height z_c, extending half_u along the unrolled circumference and half_v
# along z; rim(alpha, limit) returns the distance from the centre to the rim in the unrolled
# (u, v) plane along polar angle alpha, knowing it is below limit.
Hole = tuple[float, float, float, float, Callable[[np.ndarray, np.ndarray], np.ndarray]]


def resolve_spacing(spacing: float | None, *, diagonal: float, area: float) -> float:
    """Return the edge length of a truth mesh: `spacing`, or diagonal / 300 capped by faces."""
    if spacing is None:
        return max(diagonal / 300.0, math.sqrt(2.0 * area / _TARGET_FACES))
    spacing = positive(spacing, "spacing")
    if 2.0 * area / spacing**2 > _HARD_LIMIT_FACES:
        raise InputError(
            f"spacing={spacing!r} would need about {2.0 * area / spacing**2:.3g} faces; "
            f"use a spacing >= {math.sqrt(2.0 * area / _HARD_LIMIT_FACES):.3g}"
        )
    return spacing


def _quad_faces(index: np.ndarray, keep: np.ndarray | None = None) -> np.ndarray:
    """Split the quads between consecutive rows of `index` (R, C), columns periodic, in two.

    `keep` (R - 1, C) bool selects cells; the result is (2 * cells, 3) int64.
    """
    a = index[:-1]
    b = np.roll(a, -1, axis=1)
    d = index[1:]
    c = np.roll(d, -1, axis=1)
    tris = np.stack([np.stack([a, b, c], axis=-1), np.stack([a, c, d], axis=-1)], axis=2)
    if keep is not None:
        tris = tris[keep]
    return tris.reshape(-1, 3).astype(np.int64)


def _orient(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Reverse the faces whose geometric normal disagrees with the vertex normals (N, 3)."""
    tri = vertices[faces]
    face_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", face_normal, normals[faces].sum(axis=1)) < 0.0
    faces = faces.copy()
    faces[flip] = faces[flip][:, ::-1]
    return faces


def join(*meshes: Mesh) -> Mesh:
    """Return the disjoint union of meshes."""
    offsets = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
    return Mesh(
        vertices=np.concatenate([m.vertices for m in meshes]),
        faces=np.concatenate([m.faces + o for m, o in zip(meshes, offsets, strict=True)]),
    )


def grid_mesh(points: np.ndarray, normals: np.ndarray, keep: np.ndarray | None = None) -> Mesh:
    """Mesh a grid of points (R, C, 3), rows open and columns periodic, oriented like the
    normals (R, C, 3); `keep` (R - 1, C) bool selects cells, unused points are dropped."""
    rows, cols = points.shape[:2]
    vertices, normals = points.reshape(-1, 3), normals.reshape(-1, 3)
    index = np.arange(rows * cols).reshape(rows, cols)
    faces = _orient(vertices, _quad_faces(index, keep), normals)
    used, inverse = np.unique(faces, return_inverse=True)
    return Mesh(vertices=vertices[used], faces=inverse.reshape(-1, 3).astype(np.int64))


def tube_mesh(
    radius: float, length: float, spacing: float, *, hole: Hole | None = None
) -> tuple[Mesh, np.ndarray]:
    """Mesh the open wall x^2 + y^2 = radius^2, 0 <= z <= length, normals away from the axis.

    Returns the mesh and the vertex indices (K,) of the hole's rim in counter-clockwise order
    seen from outside (empty without a hole).
    """
    n_theta = max(32, math.ceil(2.0 * math.pi * radius / spacing))
    n_z = max(1, math.ceil(length / spacing))
    theta_c = 0.0 if hole is None else hole[0]
    theta = theta_c + 2.0 * math.pi * np.arange(n_theta) / n_theta
    z = np.linspace(0.0, length, n_z + 1)
    vertices = np.stack(
        [
            np.broadcast_to(radius * np.cos(theta), (n_z + 1, n_theta)),
            np.broadcast_to(radius * np.sin(theta), (n_z + 1, n_theta)),
            np.broadcast_to(z[:, None], (n_z + 1, n_theta)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    index = np.arange(vertices.shape[0]).reshape(n_z + 1, n_theta)
    keep = np.ones((n_z, n_theta), dtype=bool)
    extra_faces = np.zeros((0, 3), dtype=np.int64)
    rim = np.zeros(0, dtype=np.int64)
    if hole is not None:
        ring_vertices, extra_faces, rim = _o_grid(radius, z, n_theta, index, keep, hole, spacing)
        vertices = np.concatenate([vertices, ring_vertices])
    faces = np.concatenate([_quad_faces(index, keep), extra_faces])
    normals = vertices * np.array([1.0, 1.0, 0.0]) / radius
    faces = _orient(vertices, faces, normals)
    used, inverse = np.unique(faces, return_inverse=True)
    mesh = Mesh(vertices=vertices[used], faces=inverse.reshape(-1, 3).astype(np.int64))
    return mesh, np.searchsorted(used, rim)


def _o_grid(radius, z, n_theta, index, keep, hole: Hole, spacing):
    """Cut a hole out of a tube grid and mesh the ring between a square of grid nodes and it.

    Clears the grid cells inside the square in `keep` (in place) and returns the new vertices,
    the ring faces and the indices of the rim vertices.
    """
    theta_c, z_c, half_u, half_v, rim_distance = hole
    step_u = 2.0 * math.pi * radius / n_theta
    n_z = z.size - 1
    margin = 0.5 * max(half_u, half_v)
    a = min(math.ceil((half_u + margin) / step_u), (n_theta - 2) // 2)
    j0 = max(0, math.floor((z_c - half_v - margin) / z[1]))
    j1 = min(n_z, math.ceil((z_c + half_v + margin) / z[1]))
    if a * step_u <= half_u or z[j0] >= z_c - half_v or z[j1] <= z_c + half_v:
        raise InputError("the hole does not fit inside the pipe wall; make it smaller")
    keep[j0:j1, np.arange(-a, a) % n_theta] = False
    # The square's boundary nodes, counter-clockwise in the unrolled (u, v) plane.
    cols = np.concatenate(
        [np.arange(-a, a), np.full(j1 - j0, a), np.arange(a, -a, -1), np.full(j1 - j0, -a)]
    )
    rows = np.concatenate(
        [np.full(2 * a, j0), np.arange(j0, j1), np.full(2 * a, j1), np.arange(j1, j0, -1)]
    )
    u = step_u * cols
    v = z[rows] - z_c
    alpha = np.arctan2(v, u)
    limit = np.hypot(u, v)
    rho = rim_distance(alpha, limit)
    rim_u, rim_v = rho * np.cos(alpha), rho * np.sin(alpha)
    n_layers = max(2, math.ceil(float(np.max(limit - rho)) / spacing))
    fraction = (np.arange(n_layers) / n_layers)[:, None]
    layer_u = rim_u + fraction * (u - rim_u)
    layer_v = rim_v + fraction * (v - rim_v)
    angle = theta_c + layer_u / radius
    ring_vertices = np.stack(
        [radius * np.cos(angle), radius * np.sin(angle), z_c + layer_v], axis=-1
    ).reshape(-1, 3)
    start = index.size
    ring_index = np.vstack(
        [
            start + np.arange(ring_vertices.shape[0]).reshape(n_layers, -1),
            index[rows, cols % n_theta],
        ]
    )
    return ring_vertices, _quad_faces(ring_index), ring_index[0]


def sphere_mesh(radius: float, centre: np.ndarray, spacing: float) -> Mesh:
    """Mesh a sphere as a geodesic icosahedron of frequency ~1.05 radius / spacing, outward."""
    frequency = max(1, math.ceil(1.0515 * radius / spacing))
    phi = (1.0 + math.sqrt(5.0)) / 2.0
    corners = np.array(
        [
            [-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0],
            [0, -1, phi], [0, 1, phi], [0, -1, -phi], [0, 1, -phi],
            [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1],
        ],
        dtype=np.float64,
    )  # fmt: skip
    ico_faces = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ]
    )  # fmt: skip
    # Barycentric lattice of one face: weights (w0, w1, w2), w0 + w1 + w2 = frequency.
    i, j = np.triu_indices(frequency + 1)
    i, j = j - i, i  # all pairs with i + j <= frequency
    w = np.stack([frequency - i - j, i, j], axis=1).astype(np.float64)
    local = -np.ones((frequency + 2, frequency + 2), dtype=np.int64)
    local[i, j] = np.arange(i.size)
    up = (i + j) <= frequency - 1
    down = (i + j) <= frequency - 2
    tris = np.concatenate(
        [
            np.stack([local[i, j], local[i + 1, j], local[i, j + 1]], axis=1)[up],
            np.stack([local[i + 1, j], local[i + 1, j + 1], local[i, j + 1]], axis=1)[down],
        ]
    )
    # Corners sorted by index, so points on a shared edge are summed in the same order on
    # both faces and come out bit-identical.
    ordered = np.sort(ico_faces, axis=1)
    p = corners[ordered]  # (20, 3 corners, 3)
    flat = (
        w[None, :, 0, None] * p[:, None, 0]
        + w[None, :, 1, None] * p[:, None, 1]
        + w[None, :, 2, None] * p[:, None, 2]
    ).reshape(-1, 3) + 0.0  # + 0.0 turns -0.0 into 0.0 for the exact comparison below
    faces = (tris[None] + (np.arange(20) * i.size)[:, None, None]).reshape(-1, 3)
    order = np.lexsort(flat.T[::-1])
    ordered_points = flat[order]
    first = np.concatenate([[True], np.any(np.diff(ordered_points, axis=0) != 0.0, axis=1)])
    inverse = np.zeros(flat.shape[0], dtype=np.int64)
    inverse[order] = np.cumsum(first) - 1
    unique = ordered_points[first]
    directions = unique / np.linalg.norm(unique, axis=1, keepdims=True)
    faces = _orient(directions, inverse[faces], directions)
    return Mesh(vertices=centre + radius * directions, faces=faces)


def torus_mesh(major: float, minor: float, spacing: float) -> Mesh:
    """Mesh the z-axis torus with a (u, v) grid, outward normals."""
    n_u = max(16, math.ceil(2.0 * math.pi * major / spacing))
    n_v = max(8, math.ceil(2.0 * math.pi * minor / spacing))
    u = 2.0 * math.pi * np.arange(n_u) / n_u
    v = 2.0 * math.pi * np.arange(n_v) / n_v
    uu, vv = np.meshgrid(u, v, indexing="ij")
    normals = np.stack([np.cos(vv) * np.cos(uu), np.cos(vv) * np.sin(uu), np.sin(vv)], axis=-1)
    ring = np.stack([major * np.cos(uu), major * np.sin(uu), np.zeros_like(uu)], axis=-1)
    vertices = (ring + minor * normals).reshape(-1, 3)
    index = np.arange(n_u * n_v).reshape(n_u, n_v)
    faces = _quad_faces(np.vstack([index, index[:1]]))
    return Mesh(vertices=vertices, faces=_orient(vertices, faces, normals.reshape(-1, 3)))


def elbow_mesh(
    radius: float,
    bend_radius: float,
    leg: float,
    spacing: float,
    axis: Callable[[int, np.ndarray], tuple[np.ndarray, np.ndarray]],
) -> Mesh:
    """Mesh an elbow pipe along its axis; `axis(part, q)` gives axis points and in-plane normals."""
    n_phi = max(16, math.ceil(2.0 * math.pi * radius / spacing))
    n_leg = max(1, math.ceil(leg / spacing))
    bend = 0.5 * math.pi * bend_radius
    n_bend = max(2, math.ceil(bend / spacing))
    stations = [
        axis(0, np.linspace(0.0, leg, n_leg + 1)),
        axis(1, np.linspace(0.0, bend, n_bend + 1)[1:-1]),
        axis(2, np.linspace(0.0, leg, n_leg + 1)),
    ]
    centre = np.concatenate([c for c, _ in stations])
    e_n = np.concatenate([e for _, e in stations])
    phi = 2.0 * math.pi * np.arange(n_phi) / n_phi
    normals = (
        np.cos(phi)[None, :, None] * e_n[:, None, :]
        + np.sin(phi)[None, :, None] * np.array([0.0, 1.0, 0.0])
    ).reshape(-1, 3)
    vertices = np.repeat(centre, n_phi, axis=0) + radius * normals
    index = np.arange(vertices.shape[0]).reshape(-1, n_phi)
    return Mesh(vertices=vertices, faces=_orient(vertices, _quad_faces(index), normals))


def tee_mesh(
    radius: float,
    branch_radius: float,
    length: float,
    branch_end: float,
    spacing: float,
) -> Mesh:
    """Mesh a T-junction: the main wall (z axis) with a hole, the branch wall (+x) on its rim.

    The hole's rim is the intersection curve of the two cylinders; its vertices are shared by
    both walls, so the union is one edge-manifold surface with three boundary loops.
    """
    big, small = radius, branch_radius
    z_c = 0.5 * length

    def rim_distance(alpha: np.ndarray, limit: np.ndarray) -> np.ndarray:
        # Along polar angle alpha of the unrolled main wall, find rho with
        # (rho sin alpha)^2 + (R sin(rho cos alpha / R))^2 = r^2: the point's distance from
        # the branch axis equals the branch radius. Bisection; increasing while
        # |rho cos alpha| <= pi R / 2.
        ca, sa = np.cos(alpha), np.sin(alpha)
        with np.errstate(divide="ignore"):
            hi = np.minimum(limit, 0.5 * math.pi * big / np.abs(ca))
        lo = np.zeros_like(hi)
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            below = (mid * sa) ** 2 + (big * np.sin(mid * ca / big)) ** 2 < small**2
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        return 0.5 * (lo + hi)

    hole = (0.0, z_c, big * math.asin(small / big), small, rim_distance)
    main, rim = tube_mesh(radius, length, spacing, hole=hole)
    seam = main.vertices[rim]
    n_s = max(1, math.ceil((branch_end - float(seam[:, 0].min())) / spacing))
    fraction = (np.arange(1, n_s + 1) / n_s)[:, None]
    x = seam[:, 0] + fraction * (branch_end - seam[:, 0])
    x[-1] = branch_end
    new = np.stack(
        [x, np.broadcast_to(seam[:, 1], x.shape), np.broadcast_to(seam[:, 2], x.shape)], axis=-1
    ).reshape(-1, 3)
    vertices = np.concatenate([main.vertices, new])
    index = np.vstack([rim, main.n_vertices + np.arange(new.shape[0]).reshape(n_s, -1)])
    normals = (vertices - np.array([0.0, 0.0, z_c])) * np.array([0.0, 1.0, 1.0]) / small
    branch_faces = _orient(vertices, _quad_faces(index), normals)
    return Mesh(vertices=vertices, faces=np.concatenate([main.faces, branch_faces]))
