"""Marching cubes and the Method of Cubes: topology, orientation, accuracy, undefined cubes."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import zeroset
from zeroset import _lattice, topology
from zeroset._mc_table import (
    CENTRE,
    EDGE_AXIS,
    EDGE_CORNER,
    FACE_CORNERS,
    JOIN_SHIFT,
    case_table,
    patch_table,
)
from zeroset.contour import marching_cubes, method_of_cubes
from zeroset.repair import split_nonmanifold_vertices
from zeroset.synthetic import sample_sphere, sample_torus
from zeroset.types import DistanceField

from .fields import grid_field, tilted_plane


def _field(values_of, half_width, cube, band=None):
    steps = np.arange(-half_width, half_width + 1)
    ijk = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    values = values_of(cube * ijk.astype(float))
    keep = np.ones(len(ijk), bool) if band is None else np.abs(values) < band
    order = np.argsort(_lattice.encode(ijk[keep]))
    return DistanceField(
        vertices_ijk=ijk[keep][order],
        values=values[keep][order],
        origin=np.zeros(3),
        cube_size=cube,
    )


def _sphere(x):
    return np.linalg.norm(x - 0.0137, axis=1) - 1.0


def _no_planes():
    """One data point far from every cube: each vertex stays at its crossings' mean."""
    far = np.full((1, 3), 1e3)
    return far, far, np.array([[0.0, 0.0, 1.0]])


def _assert_valid(mesh):
    assert mesh.faces.min(initial=0) >= 0 and mesh.faces.max(initial=-1) < mesh.n_vertices
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    ordered = np.sort(mesh.faces, axis=1)
    assert np.all(ordered[:, :2] != ordered[:, 1:])
    assert np.unique(ordered, axis=0).shape[0] == mesh.n_faces


def _random_field(seed, size, undefined, cube):
    """Random signs on a size^3 grid (every configuration, ambiguous faces included)."""
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(size, size, size)) * 0.3 * cube
    values[rng.random(values.shape) < undefined] = np.nan
    return grid_field(values, cube)


FIELDS = given(
    seed=st.integers(0, 2**32 - 1),
    size=st.integers(2, 9),
    undefined=st.floats(0.0, 0.3),
    cube=st.floats(0.01, 100.0),
)


def _ambiguous_faces(config: int) -> int:
    """Bits of the faces of a sign configuration whose signs alternate around them."""
    bits = 0
    for face, ring in enumerate(FACE_CORNERS):
        s = [config >> c & 1 for c in ring]
        bits |= (s[0] == s[2] != s[1] == s[3]) << face
    return bits


def test_case_table_triangulates_every_sign_change_and_nothing_else():
    table, counts, centre = case_table()
    config = np.arange(counts.size) & 255
    assert np.all((counts > 0) == ((config > 0) & (config < 255)))
    # Every crossed edge is used, and only those; a centre vertex only with its loop.
    for case in range(counts.size):
        used = set(table[case, : counts[case]].ravel())
        crossed = {
            e
            for e in range(12)
            if (case >> EDGE_CORNER[e] & 1) != (case >> (EDGE_CORNER[e] + (1 << EDGE_AXIS[e])) & 1)
        }
        assert used - {CENTRE} == crossed
        assert (CENTRE in used) == centre[case].any()


def test_a_case_and_its_complement_cut_the_same_patches():
    # The complement of a case swaps the signs and joins what the case separates: the
    # field's negative, under the asymptotic decider. Its patches are the same.
    patch, counts = patch_table()
    for case in range(counts.size):
        config, joined = case & 255, case >> JOIN_SHIFT
        ambiguous = _ambiguous_faces(config)
        other = (255 - config) | ((joined ^ ambiguous) & ambiguous) << JOIN_SHIFT
        groups = {frozenset(np.flatnonzero(patch[case] == p)) for p in range(counts[case])}
        others = {frozenset(np.flatnonzero(patch[other] == p)) for p in range(counts[other])}
        assert groups == others


def test_joining_a_face_merges_the_patches_it_separated():
    # Corners 0 and 3 positive: face z = 0 alternates. Separated, each positive corner is
    # a patch of its own; joined through the face, they are one.
    _, counts = patch_table()
    config = 0b1001
    assert _ambiguous_faces(config) == 1 << 4
    assert counts[config] == 2
    assert counts[config | 1 << (JOIN_SHIFT + 4)] == 1


def test_sphere_field_gives_closed_outward_genus_zero_mesh():
    mesh = marching_cubes(_field(_sphere, 30, 0.05, band=0.2))
    assert topology.boundary_loops(mesh.faces) == []
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    assert topology.euler_characteristic(mesh) == 2
    assert topology.signed_volume(mesh) == pytest.approx(4 / 3 * np.pi, rel=0.01)
    assert np.abs(_sphere(mesh.vertices)).max() < 0.05**2


@FIELDS
def test_any_field_gives_a_valid_edge_manifold_oriented_mesh(seed, size, undefined, cube):
    mesh = marching_cubes(_random_field(seed, size, undefined, cube))
    _assert_valid(mesh)
    # Every vertex lies inside the grid on a lattice edge, but the centres of loops that
    # wind through joined faces: one in a cube at most.
    grid = mesh.vertices / cube
    assert np.all((grid >= -1e-9) & (grid <= size - 1 + 1e-9))
    centres = grid[np.sum(np.abs(grid - np.round(grid)) > 1e-9, axis=1) > 1]
    assert np.unique(np.floor(centres), axis=0).shape[0] == centres.shape[0]


def _shape(mesh):
    return (
        topology.face_components(mesh.faces, mesh.n_vertices)[0],
        topology.euler_characteristic(mesh),
    )


@FIELDS
def test_a_field_and_its_negative_give_the_same_surface(seed, size, undefined, cube):
    # The sign convention of the normals must not decide the topology: ambiguous faces
    # are resolved by the values (asymptotic decider), not by which side is positive.
    field = _random_field(seed, size, undefined, cube)
    negative = DistanceField(
        vertices_ijk=field.vertices_ijk, values=-field.values, origin=field.origin, cube_size=cube
    )
    for contour in (marching_cubes, lambda f: method_of_cubes(f, *_no_planes())):
        mesh, other = contour(field), contour(negative)
        assert _shape(mesh) == _shape(other)
        np.testing.assert_allclose(
            np.sort(mesh.vertices, axis=0), np.sort(other.vertices, axis=0), atol=1e-9 * cube
        )


def test_cubes_with_an_undefined_corner_are_skipped():
    field = _field(lambda x: x[:, 2] - 0.013, 5, 0.1)
    hole = np.flatnonzero(np.all(field.vertices_ijk == [0, 0, 0], axis=1))
    values = field.values.copy()
    values[hole] = np.nan
    holed = DistanceField(
        vertices_ijk=field.vertices_ijk, values=values, origin=np.zeros(3), cube_size=0.1
    )
    full, mesh = marching_cubes(field), marching_cubes(holed)
    # The plane z = 0.013 crosses 10 x 10 cubes; the four around (0, 0, 0) are skipped.
    assert full.n_faces == 2 * 100 and mesh.n_faces == 2 * 96
    assert len(topology.boundary_loops(mesh.faces)) == 2
    assert np.all(mesh.vertices[:, 2] == pytest.approx(0.013))


def test_jump_between_two_planes_is_not_contoured():
    # The sign flips between x = -0.05 and x = 0.05 with values +-1, far beyond one cube size.
    field = _field(lambda x: np.where(x[:, 0] < 0, 1.0, -1.0), 4, 0.1)
    assert marching_cubes(field).n_faces == 0


def test_vertices_sit_at_the_linear_zero_crossing():
    mesh = marching_cubes(_field(lambda x: x @ np.array([0.3, -0.2, 0.9]) - 0.01, 4, 0.25))
    np.testing.assert_allclose(mesh.vertices @ np.array([0.3, -0.2, 0.9]), 0.01, atol=1e-12)
    normals = np.cross(
        *(mesh.vertices[mesh.faces[:, i]] - mesh.vertices[mesh.faces[:, 0]] for i in (1, 2))
    )
    assert np.all(normals @ np.array([0.3, -0.2, 0.9]) > 0)


# Method of Cubes


@FIELDS
def test_cubes_on_any_field_give_an_edge_manifold_oriented_mesh(seed, size, undefined, cube):
    rng = np.random.default_rng(seed)
    points = rng.uniform(0.0, (size - 1) * cube, (200, 3))
    normals = rng.normal(size=(200, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    field = _random_field(seed, size, undefined, cube)
    mesh = method_of_cubes(field, points, points + 0.1 * cube, normals)
    _assert_valid(mesh)
    grid = mesh.vertices / cube
    assert np.all((grid >= -1e-9) & (grid <= size - 1 + 1e-9))  # clamped to their cubes
    split, _ = split_nonmanifold_vertices(mesh)
    edges = topology.edge_ids(split.faces, split.n_vertices)[0]
    assert topology.corner_fans(split.faces, edges)[1] == np.unique(split.faces).size


def test_cubes_give_one_vertex_per_cube_on_the_averaged_plane():
    # The plane z = 0.3 + 0.1 x through a 6 x 6 x 3 grid; the data lie on z = 0.35 + 0.1 x.
    field, points, normals = tilted_plane((6, 6, 3), 0.3, lift=0.05)
    mesh = method_of_cubes(field, points, points, normals)
    assert mesh.n_vertices == 5 * 5  # the crossed cubes
    assert mesh.n_faces == 2 * 4 * 4  # two triangles around each inner vertical edge
    np.testing.assert_allclose(mesh.vertices[:, 2], 0.35 + 0.1 * mesh.vertices[:, 0], atol=1e-12)
    normals = np.cross(
        *(mesh.vertices[mesh.faces[:, i]] - mesh.vertices[mesh.faces[:, 0]] for i in (1, 2))
    )
    assert np.all(normals[:, 2] > 0)  # towards positive values


def test_cubes_sphere_field_is_closed_outward_and_on_the_sphere():
    field = _field(_sphere, 30, 0.05, band=0.2)
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(50_000, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    points = 0.0137 + normals
    mesh = method_of_cubes(field, points, points, normals)
    _assert_valid(mesh)
    assert topology.boundary_loops(mesh.faces) == []
    assert topology.euler_characteristic(mesh) == 2
    assert topology.signed_volume(mesh) == pytest.approx(4 / 3 * np.pi, rel=0.01)
    assert np.abs(_sphere(mesh.vertices)).max() < 0.05**2
    # Two triangles per crossed lattice edge, where marching cubes has one vertex per crossed
    # edge: on a closed surface Euler's formula gives F_cubes = 2 E_crossed = F_marching + 2 chi.
    assert mesh.n_faces == marching_cubes(field).n_faces + 2 * 2


def test_cubes_split_the_vertex_of_a_cube_holding_two_sheets():
    # A slab one cube diagonal thick across the grid's diagonal, negative inside: the cubes
    # centred on its mid-plane have only their two far corners outside, so each holds both
    # sheets. One vertex per cube would pinch the sheets together on the mid-plane; a
    # vertex per patch keeps two separate planes.
    ijk = np.meshgrid(*[np.arange(8.0)] * 3, indexing="ij")
    height = (sum(ijk) - 7.5) / np.sqrt(3.0)
    mesh = method_of_cubes(grid_field(np.abs(height) - 0.5), *_no_planes())
    _assert_valid(mesh)
    assert topology.face_components(mesh.faces, mesh.n_vertices)[0] == 2
    distance = np.abs(np.abs((mesh.vertices.sum(axis=1) - 7.5) / np.sqrt(3.0)) - 0.5)
    assert distance.max() < 0.1


def test_cubes_meeting_twice_across_an_ambiguous_face_stay_manifold():
    # Two stacked cubes whose single patches both cross their common face twice (the face
    # has positive corners on one diagonal): joined directly, their two vertices would share
    # one edge between four triangles.
    _, counts = patch_table()
    assert counts[157] == counts[217] == 1
    rng = np.random.default_rng(7)
    values = rng.normal(size=(4, 4, 5)) * 0.3
    for base, config in (((1, 1, 1), 157), ((1, 1, 2), 217)):
        for c in range(8):
            i, j, k = np.add(base, [(c & 1), (c >> 1) & 1, (c >> 2) & 1])
            values[i, j, k] = abs(values[i, j, k]) * (1 if config >> c & 1 else -1)
    mesh = method_of_cubes(grid_field(values), *_no_planes())
    _assert_valid(mesh)
    # Each of the two meetings got its own vertex on the shared face z = 2.
    on_face = np.isclose(mesh.vertices[:, 2], 2.0) & np.all(
        (mesh.vertices[:, :2] > 1) & (mesh.vertices[:, :2] < 2), axis=1
    )
    assert np.count_nonzero(on_face) == 2


def test_cubes_with_an_undefined_corner_leave_a_boundary():
    x, y, z = np.meshgrid(np.arange(11.0), np.arange(11.0), np.arange(3.0), indexing="ij")
    values = z - 0.8
    values[5, 5, 1] = np.nan  # the eight cubes around it are skipped
    mesh = method_of_cubes(grid_field(values), *_no_planes())
    _assert_valid(mesh)
    assert len(topology.boundary_loops(mesh.faces)) == 2


def test_cubes_reject_mismatched_planes():
    with pytest.raises(ValueError, match="one row each per point"):
        method_of_cubes(
            grid_field(np.ones((2, 2, 2))), np.zeros((3, 3)), np.zeros((2, 3)), np.ones((3, 3))
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
