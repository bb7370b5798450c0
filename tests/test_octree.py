"""Octree cells for the Method of Cubes: merged where allowed, with no crack, fold or pinch."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zeroset
from zeroset import _lattice, topology
from zeroset.contour import adaptive_cubes, method_of_cubes
from zeroset.evaluate import smallest_angles
from zeroset.octree import FLIP_FOLD, MAX_LEVEL, MIN_ANGLE, cell_levels, cell_sizes, flip_edges
from zeroset.repair import split_nonmanifold_vertices
from zeroset.synthetic import sample_sphere, sample_torus
from zeroset.types import DistanceField, Mesh

from .fields import grid_field, tilted_plane


def _shape_counts(mesh):
    """Boundary loops, components and Euler characteristic of a bow-tie-free mesh."""
    return (
        len(topology.boundary_loops(mesh.faces)),
        topology.face_components(mesh.faces, mesh.n_vertices)[0],
        topology.euler_characteristic(mesh),
    )


def _assert_manifold(mesh, checked=None):
    """Edge-manifold, oriented, no degenerate or repeated face, and one fan of faces (no
    pinch) around every vertex, or every `checked` (V,) one."""
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    ordered = np.sort(mesh.faces, axis=1)
    assert np.all(ordered[:, :2] != ordered[:, 1:])
    assert np.unique(ordered, axis=0).shape[0] == mesh.n_faces
    fan = topology.corner_fans(mesh.faces, topology.edge_ids(mesh.faces, mesh.n_vertices)[0])[0]
    corner = mesh.faces.reshape(-1)
    fans = np.bincount(corner[np.unique(fan, return_index=True)[1]], minlength=mesh.n_vertices)
    checked = np.ones(mesh.n_vertices, bool) if checked is None else checked
    assert np.all(fans[checked] <= 1)


def _smooth_field(seed, size, undefined):
    """A random smooth field: three spheres of a quarter to a whole grid side, some corners
    undefined."""
    rng = np.random.default_rng(seed)
    ijk = np.stack(np.meshgrid(*[np.arange(size, dtype=float)] * 3, indexing="ij"), -1)
    centres = rng.uniform(0, size - 1, (3, 3))
    radii = rng.uniform(size / 4.0, size, 3)
    values = (np.linalg.norm(ijk[..., None, :] - centres, axis=-1) - radii).min(axis=-1)
    values[rng.random(values.shape) < undefined] = np.nan
    return grid_field(values)


@settings(deadline=None, max_examples=60)
@given(
    seed=st.integers(0, 2**32 - 1),
    size=st.integers(6, 36),
    undefined=st.sampled_from([0.0, 0.0, 0.002, 0.02]),
    smooth=st.booleans(),
    ramp=st.booleans(),
    largest=st.integers(0, MAX_LEVEL),
)
@pytest.mark.slow
def test_merged_cells_keep_a_manifold_oriented_crack_free_mesh(
    seed, size, undefined, smooth, ramp, largest
):
    # Random fields (smooth spheres, or random signs with every ambiguous case) and random
    # cell sizes, per point or growing across the grid: the merges may leave no crack (the
    # same boundary loops, components and Euler characteristic as the single cubes), no
    # pinch, no flipped or sliver face, and cells at most one level apart along an edge.
    rng = np.random.default_rng(seed)
    if smooth:
        field = _smooth_field(seed, size, undefined)
    else:
        size = min(size, 16)
        values = rng.normal(size=(size,) * 3) * 0.3
        values[rng.random(values.shape) < undefined] = np.nan
        field = grid_field(values)
    points = rng.uniform(0.0, size - 1, (300, 3))
    planes = (points, points + [0.0, 0.0, 1e3], np.tile([0.0, 0.0, 1.0], (300, 1)))
    if ramp:
        direction = rng.normal(size=3)
        along = (points - size / 2) @ direction / (np.abs(direction).sum() * size) + 0.5
        sizes = 2.0 ** (largest * np.clip(along, 0.0, 1.0) + 0.5)
    else:
        sizes = 2.0 ** rng.uniform(0.0, largest + 1, 300)
    single = method_of_cubes(field, *planes)
    mesh, level, counts = adaptive_cubes(field, *planes, sizes=sizes)
    assert set(np.unique(level)) <= set(range(largest + 1))
    if mesh.n_faces == 0:
        assert single.n_faces == 0
        return
    _assert_manifold(mesh, checked=level > 0)  # the single cubes may pinch on a boundary
    before, _ = split_nonmanifold_vertices(single)
    after, _ = split_nonmanifold_vertices(mesh)
    assert _shape_counts(after) == _shape_counts(before)
    edges = topology.undirected_edges(mesh.faces)[0]
    assert np.abs(np.diff(level[edges], axis=1)).max() <= 1
    # A face the merges made (not one of the single cubes') is no sharper than MIN_ANGLE,
    # or than the sharpest of the single cubes' faces that a flip rounded into it.
    old = {tuple(sorted(map(tuple, single.vertices[f].round(12)))) for f in single.faces}
    made = np.array(
        [tuple(sorted(map(tuple, mesh.vertices[f].round(12)))) not in old for f in mesh.faces]
    )
    angles = zeroset.evaluate.smallest_angles(mesh)
    sharpest = zeroset.evaluate.smallest_angles(single).min()
    assert np.all(angles[made] >= min(MIN_ANGLE, sharpest) - 1e-9)
    assert mesh.n_faces <= single.n_faces
    assert sum(counts.get("cells_merged", [])) == 0 or mesh.n_vertices < single.n_vertices


def test_a_plane_merges_into_the_largest_cells_away_from_its_boundary():
    # The plane z = 1.3 + 0.1 x through a 34 x 34 x 8 grid, every point allowing 8 cubes.
    field, points, normals = tilted_plane((34, 34, 8), 1.3)
    single = method_of_cubes(field, points, points, normals)
    mesh, level, counts = adaptive_cubes(field, points, points, normals, sizes=np.full(4000, 8.0))
    _assert_manifold(mesh)
    assert _shape_counts(mesh) == _shape_counts(single) == (1, 1, 1)
    assert level.max() >= 2 and counts["cells_merged"][1] > 0
    assert mesh.n_faces < single.n_faces / 2
    # Merged vertices are means of vertices on the data's plane: on it too.
    np.testing.assert_allclose(mesh.vertices[:, 2], 1.3 + 0.1 * mesh.vertices[:, 0], atol=1e-9)
    # The boundary is the single cubes' boundary, vertex for vertex.
    rim = np.unique(topology.boundary_edges(mesh.faces))
    rim_single = np.unique(topology.boundary_edges(single.faces))
    np.testing.assert_allclose(
        np.sort(mesh.vertices[rim], axis=0), np.sort(single.vertices[rim_single], axis=0)
    )
    assert np.all(level[rim] == 0)


def test_cells_follow_the_sizes_the_points_allow():
    # Points allow one cube where x < 24 and eight beyond: the cells grow across the plane.
    x, y, z = np.meshgrid(np.arange(73.0), np.arange(49.0), np.arange(4.0), indexing="ij")
    field = grid_field(z - 1.5)
    rng = np.random.default_rng(1)
    points = np.c_[rng.uniform(0, 72, 20_000), rng.uniform(0, 48, 20_000), np.full(20_000, 1.5)]
    normals = np.tile([0.0, 0.0, 1.0], (20_000, 1))
    sizes = np.where(points[:, 0] < 24, 1.0, 8.0)
    mesh, level, _ = adaptive_cubes(field, points, points, normals, sizes=sizes)
    _assert_manifold(mesh)
    x, y = mesh.vertices[:, 0], mesh.vertices[:, 1]
    assert np.all(level[x < 23] == 0)
    # Vertices per unit area, away from the boundary: one per cube where the points allow
    # one cube; at most one per 4 x 4 cubes, on average, where they allow eight.
    middle = (y > 12) & (y < 36)
    fine = np.count_nonzero(middle & (x > 4) & (x < 20)) / (16 * 24)
    coarse = np.count_nonzero(middle & (x > 40) & (x < 64)) / (24 * 24)
    assert fine == pytest.approx(1.0)
    assert coarse <= fine / 16


def test_cell_sizes_follow_the_spacing_and_grow_only_where_the_sag_allows():
    kappa = np.array([0.0, 0.5, 4.0, 40.0])
    options = {"noise": 0.002, "noise_factor": 3.0, "cube_factor": 1.5}
    sizes = cell_sizes(kappa, np.full(4, 0.01), **options)
    supported = 1.5 * (0.01 + 3.0 * 0.002)  # the cube this spacing would choose
    # Flat: as large as the refinement's sag tolerance lets a chord be, and finite.
    assert np.isfinite(sizes[0]) and sizes[0] > 1e3
    # Curved: larger than the supported cube only while the chord's sag is in tolerance.
    tolerance = np.maximum(1e-4 / kappa[1:], 0.1 * 0.002)
    sag = sizes[1:] ** 2 * kappa[1:] / 8
    assert np.all((sag <= tolerance * (1 + 1e-12)) | np.isclose(sizes[1:], supported))
    assert sizes[3] == pytest.approx(supported)
    # Denser points ask for smaller cells; a point with no spacing (an edge) for the least.
    dense = cell_sizes(np.full(3, 40.0), np.array([0.004, 0.02, np.inf]), **options)
    assert dense[0] < dense[1] and dense[2] == pytest.approx(1.5 * 3.0 * 0.002)
    np.testing.assert_array_equal(
        cell_levels(np.array([0.01, 0.02, 0.05, 1.0]), 0.02), [0, 0, 1, 3]
    )


@pytest.mark.parametrize(
    "sample, distance, euler",
    [
        (sample_sphere(20_000, noise=0.002, rng=3), lambda x: np.linalg.norm(x, axis=1) - 1.0, 2),
        (
            sample_torus(30_000, noise=0.002, rng=4),
            lambda x: np.hypot(np.hypot(x[:, 0], x[:, 1]) - 1.0, x[:, 2]) - 0.35,
            0,
        ),
    ],
    ids=["sphere", "torus"],
)
@pytest.mark.slow
def test_method_of_cubes_vertices_lie_on_the_true_surface(sample, distance, euler):
    # Noise 2 mm on a sphere of radius 1 m and a torus of radii 1 m and 0.35 m: every
    # vertex lies within 2 mm (one noise sigma) of the analytic surface, with no bias
    # beyond 0.3 mm either way.
    result = zeroset.reconstruct(sample.points, contour="cubes")
    d = distance(result.mesh.vertices)
    assert np.abs(d).max() < 0.002
    assert abs(np.mean(d)) < 0.0003
    assert topology.euler_characteristic(result.mesh) == euler


def test_merged_vertices_on_a_sphere_lie_within_the_sag_of_their_cells():
    # A unit sphere's exact distance on a 0.05 lattice, data points on the sphere and every
    # point allowing 8 cubes: a merged vertex, the mean of vertices on the sphere within a
    # cell of side s, lies inside it by at most the depth 3 s^2 / 8 of a cap whose rim fits
    # in the cell, and never outside it by more than the single cubes' vertices do.
    cube = 0.05
    steps = np.arange(-24, 25)
    ijk = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3)
    values = np.linalg.norm(cube * ijk, axis=1) - 1.0
    keep = np.abs(values) < 0.2
    order = np.argsort(_lattice.encode(ijk[keep]))
    field = DistanceField(
        vertices_ijk=ijk[keep][order],
        values=values[keep][order],
        origin=np.zeros(3),
        cube_size=cube,
    )
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(50_000, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    sizes = np.full(50_000, 8 * cube)
    single = method_of_cubes(field, normals, normals, normals)
    mesh, level, _ = adaptive_cubes(field, normals, normals, normals, sizes=sizes)
    _assert_manifold(mesh)
    assert _shape_counts(mesh) == (0, 1, 2)
    assert level.max() >= 2 and mesh.n_vertices < single.n_vertices / 4
    d = np.linalg.norm(mesh.vertices, axis=1) - 1.0
    slack = np.abs(np.linalg.norm(single.vertices, axis=1) - 1.0).max()
    side = cube * 2.0**level
    assert np.all(d >= -(3 * side**2 / 8 + slack))
    assert np.all(d <= slack)
    assert topology.signed_volume(mesh) > 0


def _sliver_strip(n=20, height=0.05):
    """A flat strip of 2n slivers in z = 0: quads of side 1 by `height`, sheared by half a
    side, each cut along its long diagonal."""
    x = np.arange(n + 1, dtype=np.float64)
    bottom = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    top = np.column_stack([x + 0.5, np.full_like(x, height), np.zeros_like(x)])
    vertices = np.concatenate([bottom, top])
    i = np.arange(n)
    # Quad (i, i + 1, top i + 1, top i), cut from i to top i + 1; counter-clockwise from +z.
    faces = np.concatenate(
        [np.column_stack([i, i + 1, n + 2 + i]), np.column_stack([i, n + 2 + i, n + 1 + i])]
    )
    return Mesh(vertices=vertices, faces=faces)


def test_flips_round_slivers_and_keep_the_mesh_whole():
    mesh = _sliver_strip()
    faces = flip_edges(mesh.vertices, mesh.faces, np.ones(mesh.n_faces, dtype=bool))
    flipped = Mesh(vertices=mesh.vertices, faces=faces)
    assert not np.array_equal(faces, mesh.faces)
    assert smallest_angles(flipped).min() > smallest_angles(mesh).min() + 1.0
    assert topology.is_edge_manifold(faces) and topology.is_consistently_oriented(faces)
    assert topology.euler_characteristic(flipped) == topology.euler_characteristic(mesh)
    assert len(topology.boundary_loops(faces)) == 1
    before = topology.face_area_vectors(mesh.vertices, mesh.faces).sum(axis=0)
    after = topology.face_area_vectors(flipped.vertices, faces).sum(axis=0)
    np.testing.assert_allclose(after, before, atol=1e-12)  # same plane, same side, same area
    assert set(topology.boundary_loops(faces)[0].tolist()) == set(range(mesh.n_vertices))


def test_no_flip_across_a_fold_or_outside_the_movable_faces():
    folded = _sliver_strip()
    vertices = folded.vertices.copy()
    # Every other vertex up, the others down, by enough that the two faces on each
    # diagonal meet at more than the allowed fold.
    vertices[:, 2] = np.where(np.arange(vertices.shape[0]) % 2 == 0, 0.1, -0.1)
    normals = topology.face_area_vectors(vertices, folded.faces)
    n = normals.shape[0] // 2
    cosine = np.einsum("ij,ij->i", normals[:n], normals[n:]) / (
        np.linalg.norm(normals[:n], axis=1) * np.linalg.norm(normals[n:], axis=1)
    )
    assert np.all(cosine < np.cos(np.radians(FLIP_FOLD)))
    faces = flip_edges(vertices, folded.faces, np.ones(folded.n_faces, dtype=bool))
    assert np.array_equal(faces, folded.faces)

    mesh = _sliver_strip()
    movable = np.zeros(mesh.faces.shape[0], dtype=bool)
    movable[:10] = True  # the lower triangles of ten quads only: no pair is movable
    assert np.array_equal(flip_edges(mesh.vertices, mesh.faces, movable), mesh.faces)
