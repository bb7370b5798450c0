"""Synthetic samples: ground truth meshes, exact distances, the simulated pipe scan, outliers."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from zeroset import io, topology
from zeroset.errors import InputError
from zeroset.evaluate import points_to_mesh_distance
from zeroset.synthetic import (
    MAX_FACES,
    Sample,
    add_outliers,
    hokuyo_accuracy,
    sample_cylinder,
    sample_elbow,
    sample_sphere,
    sample_tee,
    sample_torus,
    scan_pipe,
    scan_pipe_size,
    two_spheres,
    write_sample,
)

# name: (generator(rng, **keywords), boundary loops, a coarse truth spacing for quick checks)
GENERATORS = {
    "cylinder": (lambda rng, **kw: sample_cylinder(3000, rng=rng, **kw), 2, 0.02),
    "holed cylinder": (
        lambda rng, **kw: sample_cylinder(3000, hole=(1.0, 0.4, 0.08), rng=rng, **kw),
        3,
        0.02,
    ),
    "sphere": (lambda rng, **kw: sample_sphere(3000, rng=rng, **kw), 0, 0.04),
    "torus": (lambda rng, **kw: sample_torus(3000, rng=rng, **kw), 0, 0.04),
    "two spheres": (lambda rng, **kw: two_spheres(3000, rng=rng, **kw), 0, 0.04),
    "elbow": (lambda rng, **kw: sample_elbow(3000, rng=rng, **kw), 2, 0.02),
    "tee": (lambda rng, **kw: sample_tee(3000, rng=rng, **kw), 3, 0.02),
    # For the scan, noise=0.005 means the Hokuyo range noise at full scale (sigma 5 mm < 1 m).
    "scan": (
        lambda rng, noise=0.0, **kw: scan_pipe(
            rotation_step=20.0, noise_scale=noise / 0.005, rng=rng, **kw
        ),
        2,
        0.02,
    ),
}
NAMES = list(GENERATORS)


def _make(name, rng=0, **keywords):
    return GENERATORS[name][0](rng, **keywords)


def _mesh_area(mesh):
    tri = mesh.vertices[mesh.faces]
    return (
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )


def _face_normals(mesh):
    tri = mesh.vertices[mesh.faces]
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])


# --- every generator ------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_points_and_the_default_truth_mesh_lie_on_the_surface(name):
    sample = _make(name)
    mesh = sample.truth
    assert mesh is sample.truth  # built once
    assert sample.distance(sample.points).max() < 1e-9
    assert sample.distance(mesh.vertices).max() < 1e-9
    # Dense (edges about 1/300 of the bounding-box diagonal) but capped.
    assert 50_000 < mesh.n_faces < MAX_FACES
    assert _mesh_area(mesh) == pytest.approx(sample.area, rel=0.01)
    edges = mesh.vertices[mesh.faces[:10_000, 1]] - mesh.vertices[mesh.faces[:10_000, 0]]
    diagonal = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    assert np.median(np.linalg.norm(edges, axis=1)) < diagonal / 150


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_points_lie_on_the_default_truth_mesh(name):
    sample = _make(name)
    assert points_to_mesh_distance(sample.points, sample.truth).max() < 1e-3


@pytest.mark.parametrize("name", NAMES)
def test_truth_mesh_is_a_manifold_with_the_right_boundary(name):
    sample = _make(name)
    _, loops, spacing = GENERATORS[name]
    mesh = sample.truth_mesh(spacing)
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    assert len(topology.boundary_loops(mesh.faces)) == loops
    assert _mesh_area(mesh) == pytest.approx(sample.area, rel=0.01)
    assert sample.distance(mesh.vertices).max() < 1e-9
    assert points_to_mesh_distance(sample.points, mesh).max() < 1e-3  # even this coarse
    if loops == 0:
        assert topology.signed_volume(mesh) > 0


@pytest.mark.parametrize("name", NAMES)
def test_truth_mesh_faces_the_way_the_sample_normals_do(name):
    sample = _make(name)
    mesh = sample.truth_mesh(GENERATORS[name][2])
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    # The sample point nearest each face centre tells which way the face should look.
    nearest = cKDTree(sample.points).query(centres)[1]
    agree = np.einsum("ij,ij->i", _face_normals(mesh), sample.normals[nearest]) > 0
    assert agree.mean() > 0.99


@pytest.mark.parametrize("name", NAMES)
def test_normals_are_the_true_unit_normals(name):
    sample = _make(name)
    normals = sample.normals
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    # Stepping off the surface along the normal moves away from it at unit speed.
    step = 1e-4
    moved = sample.distance(sample.points + step * normals)
    assert np.mean(np.abs(moved - step) < 1e-8) > 0.99


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_sample_and_other_seed_differs(name):
    a, b, c = (_make(name, rng=seed, noise=0.005) for seed in (3, 3, 4))
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.normals, b.normals)
    if a.viewpoints is not None:
        np.testing.assert_array_equal(a.viewpoints, b.viewpoints)
    assert not np.array_equal(a.points, c.points)


@pytest.mark.parametrize("name", [name for name in NAMES if name != "scan"])
def test_noisy_points_lie_within_a_few_sigma(name):
    sigma = 0.005
    sample = _make(name, rng=5, noise=sigma)
    distance = sample.distance(sample.points)
    assert distance.max() < 6 * sigma
    assert np.sqrt(np.mean(distance**2)) == pytest.approx(sigma, rel=0.15)


@pytest.mark.parametrize("name", NAMES)
def test_sample_arrays_are_read_only(name):
    sample = _make(name)
    with pytest.raises(ValueError, match="read-only"):
        sample.points[0, 0] = 1.0
    assert sample.is_outlier.shape == (sample.points.shape[0],) and not sample.is_outlier.any()


@pytest.mark.parametrize(
    "sample",
    [
        sample_cylinder(10, hole=(0.3, 0.5, 0.1), rng=0),
        sample_elbow(10, rng=0),
        sample_tee(10, rng=0),
        sample_tee(10, radius=0.3, branch_radius=0.28, length=0.8, rng=0),
    ],
    ids=["holed cylinder", "elbow", "tee", "tee, branch nearly as wide"],
)
def test_distance_is_exact_off_the_surface(sample):
    # Against a fine truth mesh: the only difference is the chords' sagitta, h^2 / (8 r).
    mesh = sample.truth_mesh(0.008)
    rng = np.random.default_rng(0)
    lo, hi = mesh.vertices.min(axis=0) - 0.2, mesh.vertices.max(axis=0) + 0.2
    near = mesh.vertices[rng.integers(0, mesh.n_vertices, 1500)] + rng.normal(0, 0.02, (1500, 3))
    x = np.concatenate([rng.uniform(lo, hi, (1500, 3)), near])
    np.testing.assert_allclose(sample.distance(x), points_to_mesh_distance(x, mesh), atol=8e-5)


def test_tee_seam_is_shared_by_both_walls():
    sample = sample_tee(10, rng=0)
    mesh = sample.truth_mesh(0.01)
    x, y, z = mesh.vertices.T
    on_seam = (np.abs(np.hypot(x, y) - 0.25) < 1e-12) & (
        np.abs(np.hypot(y, z - 0.6) - 0.15) < 1e-12
    )
    assert on_seam.sum() > 100
    loops = topology.boundary_loops(mesh.faces)
    assert not any(on_seam[loop].any() for loop in loops)
    assert sorted(len(loop) for loop in loops)[0] > 50


def test_elbow_and_tee_sampling_is_uniform_in_area():
    elbow = sample_elbow(100_000, rng=1)
    x, _, z = elbow.points.T
    bend = (z > 0.5) & (x < 0.6)
    expected = (0.5 * math.pi * 0.6) / (2 * 0.5 + 0.5 * math.pi * 0.6)
    assert bend.mean() == pytest.approx(expected, abs=0.01)
    # Inner and outer halves of the bend in proportion to their areas.
    inner = bend & (np.hypot(x - 0.6, z - 0.5) < 0.6)
    ratio = 2 * 0.25 / (math.pi * 0.6)  # (outer - inner) / (outer + inner) for a half-torus
    assert (bend.sum() - 2 * inner.sum()) / bend.sum() == pytest.approx(ratio, abs=0.02)
    tee = sample_tee(40_000, rng=1)
    branch = tee.points[:, 0] > 0.25
    outside = 0.15 * (2 * math.pi * 0.75 - 2 * math.pi * 0.25)
    assert branch.mean() == pytest.approx(outside / tee.area, abs=0.01)


# --- the simulated scan ---------------------------------------------------------------------


def _front_line(scan, line=0):
    """Noise-free points of one scan line on the scanner's side of the axis, in beam order."""
    vp = scan.viewpoints
    first = np.flatnonzero(np.all(vp == vp[0], axis=1)).size
    points = scan.points[line * first : (line + 1) * first]
    radial = points[:, :2] @ (vp[line * first, :2] / np.linalg.norm(vp[line * first, :2]))
    return points[radial > 0]


def test_scan_size_follows_the_rotation_step():
    for step in (4.0, 1.0, 0.25):
        assert scan_pipe_size(rotation_step=step) == 511 * round(360 / step)
    scan = scan_pipe(rotation_step=4.0, noise_scale=0.0)
    assert scan.points.shape == (scan_pipe_size(rotation_step=4.0), 3) == (45_990, 3)
    assert scan.viewpoints.shape == scan.points.shape
    assert scan_pipe_size(rotation_step=180.0) == 1022  # the smallest useful scan


def test_scan_spacing_along_a_line_grows_with_axial_distance():
    scan = scan_pipe(rotation_step=30.0, noise_scale=0.0)
    line = _front_line(scan)
    dz = line[:, 2] - 1.0
    gaps = np.diff(line[:, 2])
    mid = 0.5 * (dz[1:] + dz[:-1])
    depth = 0.25 - 0.05
    step = math.radians(0.36)
    for at in (0.1, 0.8):
        measured = gaps[np.argmin(np.abs(mid - at))]
        assert measured == pytest.approx(step * (depth + at**2 / depth), rel=0.1)
    # Near the scanner the points are about a millimetre apart.
    assert gaps[np.argmin(np.abs(mid))] == pytest.approx(1.26e-3, rel=0.01)


def test_scan_lines_are_radius_times_rotation_step_apart():
    step = 2.0
    scan = scan_pipe(rotation_step=step, noise_scale=0.0)
    first, second = _front_line(scan, 0), _front_line(scan, 1)
    gap = np.linalg.norm(first - second, axis=1)
    np.testing.assert_allclose(gap, 0.25 * math.radians(step), rtol=0.1)


def test_scan_has_no_points_beyond_the_ends_or_the_range_limits():
    scan = scan_pipe(rotation_step=10.0, noise_scale=0.0)
    assert scan.points[:, 2].min() >= 0.0 and scan.points[:, 2].max() <= 2.0
    # Close to the wall, the beams near beta = 0 are nearer than 0.02 m and return nothing.
    close = scan_pipe(offset=0.24, rotation_step=10.0, noise_scale=0.0)
    ranges = np.linalg.norm(close.points - close.viewpoints, axis=1)
    assert ranges.min() >= 0.02
    front = _front_line(close)
    assert np.abs(front[:, 2] - 1.0).min() >= 0.01 * math.tan(math.radians(60)) - 1e-12
    # In a long pipe nothing returns from beyond 5.6 m.
    long = scan_pipe(length=20.0, rotation_step=10.0, noise_scale=0.0)
    ranges = np.linalg.norm(long.points - long.viewpoints, axis=1)
    assert 5.0 < ranges.max() <= 5.6
    assert np.abs(long.points[:, 2] - 10.0).max() <= 5.6


def test_scan_range_noise_follows_the_hokuyo_model():
    scan = scan_pipe(length=12.0, rotation_step=2.0, rng=7)
    offset = scan.points - scan.viewpoints
    measured = np.linalg.norm(offset, axis=1)
    radial = scan.viewpoints[:, :2] / np.linalg.norm(scan.viewpoints[:, :2], axis=1)[:, None]
    cos_beta = np.einsum("ij,ij->i", offset[:, :2], radial) / measured
    true = (0.25 - np.sign(cos_beta) * 0.05) / np.abs(cos_beta)  # along the same beam
    residual = measured - true
    near, far = true < 1.0, true > 1.0
    assert near.sum() > 10_000 and far.sum() > 10_000
    assert np.std(residual[near]) == pytest.approx(0.005, rel=0.1)
    assert np.std(residual[far] / (0.005 * true[far])) == pytest.approx(1.0, rel=0.1)
    assert np.mean(np.abs(residual) <= hokuyo_accuracy(true)) == pytest.approx(0.954, abs=0.01)


def test_exact_scan_lies_on_the_wall_and_viewpoints_circle_the_axis():
    scan = scan_pipe(offset=0.07, z0=0.5, rotation_step=5.0, noise_scale=0.0, rng=0)
    assert scan.distance(scan.points).max() < 1e-9
    np.testing.assert_allclose(np.hypot(*scan.viewpoints[:, :2].T), 0.07, rtol=1e-12)
    np.testing.assert_array_equal(scan.viewpoints[:, 2], 0.5)
    assert np.all(np.einsum("ij,ij->i", scan.normals[:, :2], scan.points[:, :2]) > 0)
    # Both sides of the axis are seen: the far wall through the back of the field of view.
    radial = np.einsum("ij,ij->i", scan.points[:, :2], scan.viewpoints[:, :2])
    assert (radial < 0).sum() > 1000


# --- outliers, writing, errors --------------------------------------------------------------


def test_add_outliers_fraction_and_bounding_box():
    points = sample_sphere(9000, radius=2.0, centre=(1.0, 0.0, 5.0), rng=0).points
    result, is_outlier = add_outliers(points, 0.1, rng=1)
    assert result.shape == (10_000, 3) and is_outlier.sum() == 1000
    np.testing.assert_array_equal(result[~is_outlier], points)
    lo, hi = points.min(axis=0), points.max(axis=0)
    margin = 0.05 * (hi - lo)
    outliers = result[is_outlier]
    assert np.all(outliers >= lo - margin) and np.all(outliers <= hi + margin)
    # Uniform in the enlarged box: they reach close to every face of it.
    assert np.all(outliers.min(axis=0) < lo - 0.8 * margin)
    assert np.all(outliers.max(axis=0) > hi + 0.8 * margin)
    again, _ = add_outliers(points, 0.1, rng=1)
    np.testing.assert_array_equal(again, result)
    assert add_outliers(points, 0.0, rng=1)[0].shape == points.shape


def test_generators_add_outliers_after_the_clean_points():
    clean = sample_tee(2000, noise=0.002, rng=3)
    noisy = sample_tee(2000, noise=0.002, outliers=0.2, rng=3)
    assert noisy.points.shape == (2500, 3) and noisy.is_outlier.sum() == 500
    np.testing.assert_array_equal(noisy.points[:2000], clean.points)
    np.testing.assert_array_equal(noisy.normals[noisy.is_outlier], 0.0)
    scan = scan_pipe(rotation_step=30.0, outliers=0.05, rng=3)
    vp = scan.viewpoints
    lines = {tuple(row) for row in vp[~scan.is_outlier]}
    assert all(tuple(row) in lines for row in vp[scan.is_outlier])
    assert scan.is_outlier.mean() == pytest.approx(0.05, abs=1e-3)


def test_write_sample_round_trip(tmp_path):
    scan = scan_pipe(rotation_step=30.0, rng=0)
    points_path, truth_path = write_sample(scan, tmp_path / "scan.ply", spacing=0.02)
    assert truth_path == tmp_path / "scan-truth.ply"
    cloud = io.read_points(points_path)
    np.testing.assert_array_equal(cloud.points, scan.points)
    np.testing.assert_array_equal(cloud.normals, scan.normals)
    np.testing.assert_array_equal(cloud.viewpoints, scan.viewpoints)
    mesh = io.read_mesh(truth_path)
    np.testing.assert_array_equal(mesh.vertices, scan.truth_mesh(0.02).vertices)
    np.testing.assert_array_equal(mesh.faces, scan.truth_mesh(0.02).faces)
    sphere_path, _ = write_sample(sample_sphere(100, rng=0), tmp_path / "sphere.ply", spacing=0.1)
    assert io.read_points(sphere_path).viewpoints is None
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "scan-truth.ply",
        "scan.ply",
        "sphere-truth.ply",
        "sphere.ply",
    ]


def test_write_sample_and_write_points_refuse_other_formats(tmp_path):
    scan = scan_pipe(rotation_step=60.0, rng=0)
    with pytest.raises(InputError, match=r"\.ply"):
        write_sample(scan, tmp_path / "scan.xyz")
    with pytest.raises(InputError, match="viewpoints can only be written to .ply"):
        io.write_points(tmp_path / "scan.xyz", scan.points, viewpoints=scan.viewpoints)
    with pytest.raises(TypeError, match="Sample"):
        write_sample(scan.points, tmp_path / "scan.ply")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: sample_tee(10, branch_radius=0.25), "branch_radius must be below radius"),
        (lambda: sample_tee(10, length=0.2), "below length / 2"),
        (lambda: sample_elbow(10, bend_radius=0.2), "bend_radius must exceed radius"),
        (lambda: sample_cylinder(10, hole=(0.0, 0.02, 0.05)), "hole must lie inside"),
        (lambda: sample_torus(10, minor=1.0), "minor must be below major"),
        (lambda: sample_sphere(0), "n must be a positive integer"),
        (lambda: sample_sphere(10, outliers=1.0), r"outliers must be a number in \[0, 1\)"),
        (lambda: scan_pipe(offset=0.25), r"offset must be in \[0, radius"),
        (lambda: scan_pipe(z0=3.0), r"z0 must be in \[0, length"),
        (lambda: scan_pipe(rotation_step=0.0), "rotation_step must be a positive number"),
        (lambda: scan_pipe(noise_scale=-1.0), "noise_scale must be a number >= 0"),
        (lambda: add_outliers(np.zeros((0, 3)), 0.1), "points is empty"),
        (lambda: sample_sphere(10, rng=0).truth_mesh(1e-6), "would need about"),
    ],
)
def test_bad_input_is_refused_with_a_message(make, message):
    with pytest.raises(InputError, match=message):
        make()


def test_a_hand_made_sample_has_no_truth():
    sample = Sample(np.zeros((1, 3)), np.zeros((1, 3)), lambda x: np.zeros(len(x)), 0.0)
    with pytest.raises(AttributeError, match="without a truth mesh"):
        _ = sample.truth


@settings(max_examples=8, deadline=None)
@given(
    radius=st.floats(0.1, 0.5),
    share=st.floats(0.2, 0.95),
    length_factor=st.floats(2.2, 6.0),
    branch_length=st.floats(0.05, 1.0),
)
def test_tee_truth_is_one_manifold_for_any_proportions(radius, share, length_factor, branch_length):
    small = share * radius
    sample = sample_tee(
        500,
        radius=radius,
        branch_radius=small,
        length=length_factor * small,
        branch_length=branch_length,
        rng=0,
    )
    mesh = sample.truth_mesh(small / 6)
    assert topology.is_edge_manifold(mesh.faces)
    assert topology.is_consistently_oriented(mesh.faces)
    assert len(topology.boundary_loops(mesh.faces)) == 3
    assert sample.distance(mesh.vertices).max() < 1e-9
    assert sample.distance(sample.points).max() < 1e-9
    assert _mesh_area(mesh) == pytest.approx(sample.area, rel=0.02)
