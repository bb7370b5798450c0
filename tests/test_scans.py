"""Simulated in-pipe laser scans: anisotropic scan lines, range noise, sensor positions."""

import numpy as np
import pytest

from zeroset import reconstruct, topology
from zeroset.evaluate import points_to_mesh_distance
from zeroset.synthetic import hokuyo_accuracy, scan_pipe

CASES = [
    # radius, degrees between scan lines, scanner offset from the axis, seed
    (0.25, 1.0, 0.05, 0),
    (0.25, 4.0, 0.0, 1),
    (0.35, 2.0, 0.05, 2),
    # The narrowest pipe, scanner on the axis: far down the pipe every beam angle gives one
    # ring of points, smeared by range noise into a band with gaps wider than rho+delta.
    (0.1, 1.0, 0.0, 3),
]
SLOW_CASES = [
    (radius, step, offset, seed)
    for radius in (0.1, 0.15, 0.25, 0.35)
    for step in (1.0, 2.0, 3.0, 4.0)
    for offset in (0.0, 0.05)
    for seed in (3, 4)
]


def _check_scan(radius, step, offset, seed, use_viewpoints):
    scan = scan_pipe(radius=radius, rotation_step=step, offset=offset, rng=seed)
    viewpoints = scan.viewpoints if use_viewpoints else None
    mesh = reconstruct(scan.points, viewpoints=viewpoints).mesh
    n_components, _ = topology.face_components(mesh.faces, mesh.n_vertices)
    assert n_components == 1
    assert len(topology.boundary_loops(mesh.faces)) == 2
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    # Below the sensor noise: the Hokuyo's accuracy is 10 mm up to 1 m.
    assert scan.distance(mesh.vertices).mean() < hokuyo_accuracy(0.5) / 2
    wall = scan_pipe(radius=radius, rotation_step=step, offset=offset, rng=seed, noise_scale=0.0)
    assert np.mean(points_to_mesh_distance(wall.points[::4], mesh) < 0.01) >= 0.98
    return scan, mesh


@pytest.mark.parametrize("radius, step, offset, seed", CASES)
@pytest.mark.slow
def test_scan_reconstructs_in_one_piece_with_two_boundary_loops(radius, step, offset, seed):
    _check_scan(radius, step, offset, seed, use_viewpoints=False)


@pytest.mark.sweep
@pytest.mark.parametrize("radius, step, offset, seed", SLOW_CASES)
@pytest.mark.parametrize("use_viewpoints", [False, True])
def test_scan_sweep(radius, step, offset, seed, use_viewpoints):
    _check_scan(radius, step, offset, seed, use_viewpoints)


def test_sensor_positions_turn_the_pipe_wall_towards_the_sensor():
    scan, mesh = _check_scan(0.25, 2.0, 0.05, 5, use_viewpoints=True)
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    radial = np.einsum("ij,ij->i", normals[:, :2], tri.mean(axis=1)[:, :2])
    assert np.mean(radial < 0) > 0.99  # facing the axis, where the scanner is
