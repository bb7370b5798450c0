"""Marching cubes on analytic fields: topology, orientation, accuracy, undefined cubes."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from zeroset import _lattice, topology
from zeroset._mc_table import case_table
from zeroset.contour import marching_cubes
from zeroset.types import DistanceField


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


def test_case_table_triangulates_every_sign_change_and_nothing_else():
    table, counts = case_table()
    assert counts[0] == 0 and counts[255] == 0
    assert np.all(counts[1:255] > 0)
    # Complementary configurations cut the same edges.
    for config in range(256):
        edges = set(table[config, : counts[config]].ravel())
        other = set(table[255 - config, : counts[255 - config]].ravel())
        assert edges == other


def test_sphere_field_gives_closed_outward_genus_zero_mesh():
    mesh = marching_cubes(_field(_sphere, 30, 0.05, band=0.2))
    assert topology.boundary_loops(mesh.faces) == []
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    assert topology.euler_characteristic(mesh) == 2
    assert topology.signed_volume(mesh) == pytest.approx(4 / 3 * np.pi, rel=0.01)
    assert np.abs(_sphere(mesh.vertices)).max() < 0.05**2


@given(
    seed=st.integers(0, 2**32 - 1),
    size=st.integers(2, 9),
    undefined=st.floats(0.0, 0.3),
    cube=st.floats(0.01, 100.0),
)
def test_any_field_gives_a_valid_edge_manifold_oriented_mesh(seed, size, undefined, cube):
    rng = np.random.default_rng(seed)
    steps = np.arange(size)
    ijk = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    values = rng.normal(size=len(ijk)) * cube
    values[rng.random(len(ijk)) < undefined] = np.nan
    field = DistanceField(vertices_ijk=ijk, values=values, origin=np.zeros(3), cube_size=cube)
    mesh = marching_cubes(field)
    assert mesh.faces.min(initial=0) >= 0 and mesh.faces.max(initial=-1) < mesh.n_vertices
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    ordered = np.sort(mesh.faces, axis=1)
    assert np.all(ordered[:, :2] != ordered[:, 1:])  # three distinct vertices per face
    assert np.unique(ordered, axis=0).shape[0] == mesh.n_faces
    # Every vertex lies on a lattice edge inside the grid.
    grid = mesh.vertices / cube
    assert np.all((grid >= -1e-9) & (grid <= size - 1 + 1e-9))
    assert np.all(np.sum(np.abs(grid - np.round(grid)) > 1e-9, axis=1) <= 1)


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
