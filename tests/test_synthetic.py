"""Synthetic samples: ground truth meshes, exact distances, the simulated pipe scan, outliers,
damaged pipes and their truth records."""

import json
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from zeroset import io, topology
from zeroset.cli import main
from zeroset.errors import InputError
from zeroset.evaluate import points_to_mesh_distance
from zeroset.synthetic import (
    MAX_FACES,
    Defect,
    Sample,
    add_outliers,
    damaged_pipe,
    hokuyo_accuracy,
    sample_cylinder,
    sample_elbow,
    sample_sphere,
    sample_tee,
    sample_torus,
    scan_damaged_pipe,
    scan_pipe,
    scan_pipe_size,
    two_spheres,
    write_sample,
)

# A dent, a bulge and a 3 % ovality on part of the pipe, for the damaged generators.
DAMAGE = {
    "defects": [
        Defect("dent", axial=0.8, clock=90.0, depth=0.01, width=0.2),
        Defect("bulge", axial=1.3, clock=200.0, depth=0.006, width=0.15),
    ],
    "ovality": 0.03,
    "ovality_clock": 30.0,
    "ovality_span": (0.2, 0.9),
}

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
    "damaged pipe": (lambda rng, **kw: damaged_pipe(3000, rng=rng, **DAMAGE, **kw), 2, 0.02),
    "damaged elbow": (
        lambda rng, **kw: damaged_pipe(3000, shape="elbow", rng=rng, **DAMAGE, **kw),
        2,
        0.02,
    ),
    "damaged scan": (
        lambda rng, noise=0.0, **kw: scan_damaged_pipe(
            rotation_step=20.0,
            stations=(0.7, 1.3),
            noise_scale=noise / 0.005,
            rng=rng,
            **DAMAGE,
            **kw,
        ),
        2,
        0.02,
    ),
    "damaged elbow scan": (
        lambda rng, noise=0.0, **kw: scan_damaged_pipe(
            shape="elbow",
            rotation_step=30.0,
            stations=(0.3, 1.2),
            noise_scale=noise / 0.005,
            rng=rng,
            **DAMAGE,
            **kw,
        ),
        2,
        0.02,
    ),
}
NAMES = list(GENERATORS)
SCANS = ("scan", "damaged scan", "damaged elbow scan")


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


@pytest.mark.sweep
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


@pytest.mark.parametrize("name", [name for name in NAMES if name not in SCANS])
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


# --- damaged pipes ---------------------------------------------------------------------------

R = 0.25


def _clock(points):
    """Clock angles in degrees of points around the z axis: 12 o'clock +y, 3 o'clock -x."""
    return np.degrees(np.arctan2(points[:, 1], points[:, 0]) - 0.5 * np.pi) % 360.0


def _angle_between(a, b):
    """Difference of clock angles in degrees, in [-180, 180)."""
    return (np.asarray(a) - b + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("kind, clock", [("dent", 0.0), ("dent", 90.0), ("bulge", 235.0)])
def test_a_defect_peaks_where_its_record_says(kind, clock):
    defect = Defect(kind, axial=1.2, clock=clock, depth=0.012, width=0.15)
    sample = damaged_pipe(200_000, defects=[defect], rng=1)
    rho = np.hypot(sample.points[:, 0], sample.points[:, 1])
    sign = -1.0 if kind == "dent" else 1.0
    change = sign * (rho - R)
    peak = np.argmax(change)
    assert sample.points[peak, 2] == pytest.approx(1.2, abs=0.006)  # points are ~4 mm apart
    assert abs(_angle_between(_clock(sample.points[peak : peak + 1])[0], clock)) < 1.5
    assert change[peak] == pytest.approx(0.012, abs=2e-4)
    # The patch is round and centred there: its weighted centre is within a millimetre.
    arc = R * np.radians(_angle_between(_clock(sample.points), clock))
    weight = np.maximum(change - 0.006, 0.0)
    assert np.average(arc, weights=weight) == pytest.approx(0.0, abs=1e-3)
    assert np.average(sample.points[:, 2], weights=weight) == pytest.approx(1.2, abs=1e-3)
    # 12 o'clock is +y and 3 o'clock -x on a pipe along +z.
    c = math.radians(clock)
    np.testing.assert_allclose(
        sample.points[peak, :2] / rho[peak], [-math.sin(c), math.cos(c)], atol=0.03
    )
    (record,) = sample.truth_record["defects"]
    assert record["kind"] == kind and record["clock"] == clock and record["depth"] == 0.012
    np.testing.assert_allclose(
        record["centre"], [-R * math.sin(c), R * math.cos(c), 1.2], atol=1e-12
    )
    # Beyond the patch the wall is untouched.
    outside = np.hypot(arc, sample.points[:, 2] - 1.2) > 0.075
    assert np.abs(rho[outside] - R).max() < 1e-12


def test_ovality_sets_the_diameters_on_its_span_and_fades_beyond():
    sample = damaged_pipe(300_000, ovality=0.03, ovality_clock=30.0, ovality_span=(0.6, 1.4), rng=2)
    z = sample.points[:, 2]
    rho = np.hypot(sample.points[:, 0], sample.points[:, 1])
    clock = _clock(sample.points)
    inside = (z > 0.65) & (z < 1.35)
    # D(clock) = r(clock) + r(clock + 180), from the mean radius in 2 degree bins.
    bins = np.bincount((clock[inside] // 2).astype(int), weights=rho[inside], minlength=180)
    bins /= np.bincount((clock[inside] // 2).astype(int), minlength=180)
    diameter = bins[:90] + bins[90:]
    assert diameter.max() - diameter.min() == pytest.approx(0.03 * 2 * R, rel=0.01)
    assert abs(_angle_between(2.0 * np.argmax(diameter) + 1.0, 30.0)) <= 2.0
    # One radius beyond the span the pipe is round again.
    beyond = (z < 0.6 - R) | (z > 1.4 + R)
    assert beyond.sum() > 50_000 and np.abs(rho[beyond] - R).max() < 1e-12
    assert np.abs(rho - R).max() <= 0.5 * 0.03 * R + 1e-12
    assert sample.truth_record["ovality"] == {
        "value": 0.03,
        "clock": 30.0,
        "span": [0.6, 1.4],
        "taper": R,
    }


def test_elbow_defects_sit_on_the_undamaged_wall_at_their_clock():
    leg, bend_radius = 0.5, 0.6
    bend_45 = leg + bend_radius * math.pi / 4
    second_leg = leg + bend_radius * math.pi / 2 + 0.25
    defects = [
        Defect("dent", axial=0.3, clock=270.0, depth=0.01, width=0.1),
        Defect("dent", axial=bend_45, clock=0.0, depth=0.01, width=0.1),
        Defect("dent", axial=bend_45 + 0.2, clock=90.0, depth=0.01, width=0.1),
        Defect("dent", axial=second_leg, clock=90.0, depth=0.01, width=0.1),
    ]
    sample = damaged_pipe(200_000, shape="elbow", defects=defects, rng=3)
    h = math.sqrt(0.5)
    a = (bend_45 + 0.2 - leg) / bend_radius
    expected = [
        [R, 0.0, 0.3],  # 9 o'clock on the first leg is +x
        [bend_radius * (1 - h), R, leg + bend_radius * h],  # 12 o'clock is +y on the bend
        # 3 o'clock on the bend points away from the bend's centre
        [bend_radius - (bend_radius + R) * math.cos(a), 0.0, leg + (bend_radius + R) * math.sin(a)],
        [bend_radius + 0.25, 0.0, leg + bend_radius + R],  # and is +z on the second leg
    ]
    centres = np.array([d["centre"] for d in sample.truth_record["defects"]])
    np.testing.assert_allclose(centres, expected, atol=1e-12)
    assert sample.truth_record["kind"] == "damaged elbow"
    # Each dent's deepest point (measured against the undamaged elbow) is at its centre.
    undamaged = sample_elbow(10, radius=R, bend_radius=bend_radius, leg=leg, rng=0)
    depth = undamaged.distance(sample.points)
    for centre in centres:
        near = np.flatnonzero(np.linalg.norm(sample.points - centre, axis=1) < 0.05)
        deepest = near[np.argmax(depth[near])]
        assert np.linalg.norm(sample.points[deepest] - centre) < 0.016  # depth plus spacing
        assert depth[deepest] == pytest.approx(0.01, abs=2e-4)


def test_without_damage_the_damaged_pipes_are_the_plain_ones():
    for damaged, plain in [
        (damaged_pipe(2000, length=1.0, rng=4), sample_cylinder(2000, length=1.0, rng=4)),
        (damaged_pipe(2000, shape="elbow", rng=4), sample_elbow(2000, rng=4)),
    ]:
        np.testing.assert_allclose(damaged.points, plain.points, atol=1e-15)
        np.testing.assert_allclose(damaged.normals, plain.normals, atol=1e-15)


def test_damaged_scan_returns_the_first_wall_point_along_each_beam():
    dent = Defect("dent", axial=1.0, clock=0.0, depth=0.02, width=0.1)
    scan = scan_damaged_pipe(
        defects=[dent], stations=[0.1, 1.0, 1.9], rotation_step=30.0, noise_scale=0.0
    )

    def outside(points):
        """How far points are outside the dented wall, from the dent's definition."""
        arc = R * np.radians(_angle_between(_clock(points), 0.0))
        d = np.hypot(arc, points[:, 2] - 1.0)
        wall = R - 0.02 * np.cos(np.pi * d / 0.1) ** 2 * (d < 0.05)
        return np.hypot(points[:, 0], points[:, 1]) - wall

    assert np.abs(outside(scan.points)).max() < 1e-11
    assert scan.distance(scan.points).max() < 1e-11
    # No beam passes through the dent before its hit (a beam keeps its clock).
    seen = np.abs(R * np.radians(_angle_between(_clock(scan.points), 0.0))) < 0.05
    assert seen.sum() > 1000
    f = np.concatenate([np.linspace(0.0, 0.99, 300), 1.0 - np.geomspace(1e-2, 1e-3, 30)])
    start, end = scan.viewpoints[seen], scan.points[seen]
    path = start[:, None] + f[:, None] * (end - start)[:, None]
    worst = outside(path.reshape(-1, 3)).max()
    assert worst < 0.0
    # The deepest point the scanner sees is the dent's centre.
    rho = np.hypot(scan.points[:, 0], scan.points[:, 1])
    assert rho.min() == pytest.approx(R - 0.02, abs=5e-4)
    assert sorted(set(scan.viewpoints[:, 2])) == [0.1, 1.0, 1.9]


def test_scan_stations_are_concatenated_in_order():
    keywords = {"defects": DAMAGE["defects"], "rotation_step": 30.0, "noise_scale": 0.0}
    both = scan_damaged_pipe(stations=[1.3, 0.4], **keywords)
    parts = [scan_damaged_pipe(stations=[z0], **keywords) for z0 in (1.3, 0.4)]
    for field in ("points", "normals", "viewpoints"):
        np.testing.assert_array_equal(
            getattr(both, field), np.concatenate([getattr(part, field) for part in parts])
        )
    assert both.truth_record["stations"] == [1.3, 0.4]
    assert scan_damaged_pipe(**keywords).truth_record["stations"] == [1.0]


# The elbow of `damaged_pipe` and `scan_damaged_pipe`: legs of 0.5 m, bend radius 0.6 m; a dent
# on the outer side where the bend meets the second leg, a dent in the first leg, a bulge on the
# inner side mid-bend, and an ovality from the first leg into the bend.
LEG, BEND = 0.5, 0.6
ELBOW_LENGTH = 2 * LEG + 0.5 * np.pi * BEND
ELBOW_DAMAGE = {
    "defects": [
        Defect("dent", axial=LEG + 0.5 * np.pi * BEND, clock=90.0, depth=0.02, width=0.12),
        Defect("dent", axial=0.35, clock=0.0, depth=0.015, width=0.1),
        Defect("bulge", axial=LEG + 0.25 * np.pi * BEND, clock=270.0, depth=0.008, width=0.15),
    ],
    "ovality": 0.03,
    "ovality_clock": 30.0,
    "ovality_span": (0.2, 0.9),
}


def _elbow_centreline(s):
    """Centreline points, in-plane normals and unit tangents (M, 3) of the elbow at arc
    lengths s (M,)."""
    a = np.clip(s - LEG, 0.0, 0.5 * np.pi * BEND) / BEND
    beyond = np.maximum(s - LEG - 0.5 * np.pi * BEND, 0.0)
    first = np.clip(s, 0.0, LEG)
    zero = np.zeros_like(s)
    centre = np.stack([BEND - BEND * np.cos(a) + beyond, zero, first + BEND * np.sin(a)], -1)
    e_n = np.stack([np.cos(a), zero, -np.sin(a)], -1)
    return centre, e_n, np.stack([np.sin(a), zero, np.cos(a)], -1)


def _elbow_tube(points):
    """Arc length s, clock (degrees) and distance rho from the centreline (M,) of points (M, 3)
    in the elbow: the nearest of centreline samples 1 cm apart, refined by Newton's method on
    ``(x - centre(s)) . tangent(s) = 0``."""
    s_grid = np.linspace(0.0, ELBOW_LENGTH, 200)
    s = s_grid[cKDTree(_elbow_centreline(s_grid)[0]).query(points)[1]]
    for _ in range(6):
        centre, e_n, tangent = _elbow_centreline(s)
        v = points - centre
        curvature = ((s > LEG) & (s < LEG + 0.5 * np.pi * BEND)) / BEND
        along, inward = np.einsum("ij,ij->i", v, tangent), np.einsum("ij,ij->i", v, e_n)
        step = along / (1.0 - curvature * inward)
        s = np.clip(s + step, 0.0, ELBOW_LENGTH)
    centre, e_n, _ = _elbow_centreline(s)
    v = points - centre
    clock = np.degrees(np.arctan2(v[:, 1], np.einsum("ij,ij->i", v, e_n))) - 90.0
    return s, clock % 360.0, np.linalg.norm(v, axis=1)


def _elbow_radius(s, clock, damage):
    """The damaged wall's radius (M,) at arc lengths s and clocks in degrees (M,), from the
    definitions in `Defect` and `damaged_pipe`."""
    r = np.full(s.shape, R)
    for defect in damage.get("defects", ()):
        d = np.hypot(R * np.radians(_angle_between(clock, defect.clock)), s - defect.axial)
        sign = -1.0 if defect.kind == "dent" else 1.0
        r += sign * defect.depth * np.cos(np.pi * d / defect.width) ** 2 * (d < defect.width / 2)
    s0, s1 = damage.get("ovality_span", (0.0, ELBOW_LENGTH))
    beyond = np.clip(np.maximum(s0 - s, s - s1), 0.0, R)  # tapers over one radius
    weight = np.cos(0.5 * np.pi * beyond / R) ** 2 * (beyond < R)
    phase = 2.0 * np.radians(clock - damage.get("ovality_clock", 0.0))
    return r + 0.5 * R * damage.get("ovality", 0.0) * np.cos(phase) * weight


def _in_patch(s, clock, defect):
    """Which wall points (M,), at arc lengths s and clocks (M,), the defect moves."""
    d = np.hypot(R * np.radians(_angle_between(clock, defect.clock)), s - defect.axial)
    return d < 0.5 * defect.width


@pytest.mark.slow
def test_damaged_elbow_scan_returns_the_first_wall_point_along_each_beam():
    stations = [0.2, LEG + 0.25 * np.pi * BEND, LEG + 0.5 * np.pi * BEND, ELBOW_LENGTH]
    scan = scan_damaged_pipe(
        shape="elbow", stations=stations, rotation_step=30.0, noise_scale=0.0, **ELBOW_DAMAGE
    )
    s, clock, rho = _elbow_tube(scan.points)
    assert np.abs(rho - _elbow_radius(s, clock, ELBOW_DAMAGE)).max() < 1e-9
    near = np.zeros(s.size, dtype=bool)
    for defect in ELBOW_DAMAGE["defects"]:
        patch = _in_patch(s, clock, defect)
        assert patch.sum() > 20, defect
        near |= patch
    # March a sample of the beams, a third of those that meet a defect and one in 30 of the
    # rest, in steps of 0.5 mm up to the hit: every step is inside the wall.
    chosen = np.union1d(np.flatnonzero(near)[::3], np.flatnonzero(~near)[::30])
    start, end = scan.viewpoints[chosen], scan.points[chosen]
    steps = np.ceil(np.linalg.norm(end - start, axis=1) / 5e-4).astype(np.int64)
    beam = np.repeat(np.arange(chosen.size), steps)
    f = (np.arange(beam.size) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[beam]
    s, clock, rho = _elbow_tube(start[beam] + f[:, None] * (end - start)[beam])
    assert (rho - _elbow_radius(s, clock, ELBOW_DAMAGE)).max() < 0.0
    # The scanners sit `offset` from the centreline in the cross-sections of their stations;
    # the one at the second leg's open end sees only the pipe behind it.
    for s0 in stations:
        centre, _, tangent = _elbow_centreline(np.array([s0]))
        v = scan.viewpoints - centre
        mine = (np.abs(np.linalg.norm(v, axis=1) - 0.05) < 1e-12) & (np.abs(v @ tangent[0]) < 1e-12)
        assert mine.sum() > 1000
    assert ((scan.points[mine] - centre) @ tangent[0]).max() < 1e-12


@pytest.mark.parametrize("s0", [0.2, ELBOW_LENGTH])
def test_elbow_scan_in_a_leg_matches_the_straight_scan_there(s0):
    # Damaged by arc length, the straight pipe of the elbow's length is the elbow up to the
    # bend, and, turned onto the second leg, beyond it. A scanner in a leg takes the same
    # scan lines in both, so the beams that hit that leg return the same points, and beams
    # missing from one are missing from the other.
    keywords = {"stations": [s0], "rotation_step": 30.0, "noise_scale": 0.0, **ELBOW_DAMAGE}
    elbow = scan_damaged_pipe(shape="elbow", **keywords).points
    straight = scan_damaged_pipe(length=ELBOW_LENGTH, **keywords).points
    centre, e_n, tangent = _elbow_centreline(np.array([s0]))
    frame = np.stack([e_n[0], [0.0, 1.0, 0.0], tangent[0]])
    straight = centre + (straight - [0.0, 0.0, s0]) @ frame
    lo, hi = (0.0, LEG) if s0 < LEG else (LEG + 0.5 * np.pi * BEND, ELBOW_LENGTH)
    leg = [(s >= lo) & (s <= hi) for s in (_elbow_tube(elbow)[0], _elbow_tube(straight)[0])]
    assert leg[0].sum() > 2000 and (~leg[0]).sum() > 1000
    np.testing.assert_allclose(elbow[leg[0]], straight[leg[1]], atol=1e-9)


def test_a_scan_in_the_bend_sees_both_legs_and_the_bend():
    scan = scan_damaged_pipe(shape="elbow", rotation_step=20.0, noise_scale=0.0)
    bend_end = LEG + 0.5 * np.pi * BEND
    assert scan.truth_record["stations"] == [pytest.approx(LEG + 0.25 * np.pi * BEND)]
    s, _, rho = _elbow_tube(scan.points)
    np.testing.assert_allclose(rho, R, atol=1e-9)
    parts = [(s < LEG).sum(), ((s > LEG) & (s < bend_end)).sum(), (s > bend_end).sum()]
    assert min(parts) > 1000, parts
    np.testing.assert_allclose(np.linalg.norm(scan.normals, axis=1), 1.0)
    # Without damage the normals point away from the centreline.
    centre, _, _ = _elbow_centreline(s)
    np.testing.assert_allclose(scan.normals, (scan.points - centre) / R, atol=1e-9)


def test_damaged_elbow_scan_truth_record_is_the_damaged_elbows_plus_the_scan():
    keywords = {"shape": "elbow", "rng": 3, **ELBOW_DAMAGE}
    scan = scan_damaged_pipe(stations=[0.2, 1.0], rotation_step=40.0, **keywords)
    record = scan.truth_record
    wall = damaged_pipe(10, **keywords).truth_record
    assert record["kind"] == "damaged elbow scan" and wall["kind"] == "damaged elbow"
    for key in ("radius", "leg", "bend_radius", "clock_convention", "ovality", "defects", "seed"):
        assert record[key] == wall[key], key
    scanned = {"stations": [0.2, 1.0], "offset": 0.05, "rotation_step": 40.0, "noise_scale": 1.0}
    assert {key: record[key] for key in scanned} == scanned
    assert set(record) == set(wall) - {"noise"} | set(scanned)
    json.dumps(record)  # JSON-able
    # A defect's centre lies on the undamaged elbow at its arc length and clock.
    for defect in record["defects"]:
        s, clock, rho = _elbow_tube(np.array([defect["centre"]]))
        assert s[0] == pytest.approx(defect["axial"], abs=1e-9)
        assert abs(_angle_between(clock[0], defect["clock"])) < 1e-6
        assert rho[0] == pytest.approx(R, abs=1e-9)


def test_damaged_elbow_scan_is_reproducible():
    keywords = {"shape": "elbow", "rotation_step": 40.0, **ELBOW_DAMAGE}
    one, two = (scan_damaged_pipe(rng=3, **keywords) for _ in range(2))
    for field in ("points", "normals", "viewpoints"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
    assert not np.array_equal(one.points, scan_damaged_pipe(rng=4, **keywords).points)


def test_write_sample_writes_the_truth_record_as_json(tmp_path):
    sample = damaged_pipe(500, shape="elbow", noise=0.001, rng=7, **DAMAGE)
    write_sample(sample, tmp_path / "elbow.ply", spacing=0.03)
    record = json.loads((tmp_path / "elbow-truth.json").read_text())
    assert record == sample.truth_record
    assert (record["kind"], record["seed"], record["noise"]) == ("damaged elbow", 7, 0.001)
    assert [d["kind"] for d in record["defects"]] == ["dent", "bulge"]
    assert "12 o'clock (0) is +y" in record["clock_convention"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "elbow-truth.json",
        "elbow-truth.ply",
        "elbow.ply",
    ]
    assert "seed" not in damaged_pipe(10, rng=np.random.default_rng(0)).truth_record


def test_cli_synth_writes_a_damaged_scan_and_its_truth_record(tmp_path, capsys):
    out = tmp_path / "scan.ply"
    damage = ["--dent", "1.0,90,0.01,0.2", "--bulge", "0.5,180,0.005,0.1", "--ovality", "0.02,45"]
    argv = ["--stations", "0.8,1.2", "--rotation-step", "30", "--seed", "3"]
    assert main(["synth", "damaged-pipe-scan", "-o", str(out), *damage, *argv]) == 0
    assert "scan-truth.json" in capsys.readouterr().out
    record = json.loads((tmp_path / "scan-truth.json").read_text())
    assert [(d["kind"], d["axial"], d["clock"]) for d in record["defects"]] == [
        ("dent", 1.0, 90.0),
        ("bulge", 0.5, 180.0),
    ]
    assert record["ovality"]["value"] == 0.02 and record["ovality"]["clock"] == 45.0
    assert record["stations"] == [0.8, 1.2] and record["seed"] == 3
    expected = scan_damaged_pipe(
        defects=[Defect("dent", 1.0, 90.0, 0.01, 0.2), Defect("bulge", 0.5, 180.0, 0.005, 0.1)],
        ovality=0.02,
        ovality_clock=45.0,
        stations=[0.8, 1.2],
        rotation_step=30.0,
        rng=3,
    )
    cloud = io.read_points(out)
    np.testing.assert_array_equal(cloud.points, expected.points)
    np.testing.assert_array_equal(cloud.viewpoints, expected.viewpoints)
    assert io.read_mesh(tmp_path / "scan-truth.ply").n_faces > 1000


def test_cli_synth_writes_a_damaged_elbow_scan(tmp_path, capsys):
    out = tmp_path / "elbow.ply"
    argv = ["--dent", "1.2,90,0.01,0.1", "--stations", "0.25,1.2", "--rotation-step", "30"]
    assert main(["synth", "damaged-elbow-scan", "-o", str(out), *argv, "--seed", "3"]) == 0
    assert "elbow-truth.json" in capsys.readouterr().out
    record = json.loads((tmp_path / "elbow-truth.json").read_text())
    assert record["kind"] == "damaged elbow scan" and record["stations"] == [0.25, 1.2]
    assert (record["leg"], record["bend_radius"]) == (LEG, BEND)
    expected = scan_damaged_pipe(
        shape="elbow",
        defects=[Defect("dent", 1.2, 90.0, 0.01, 0.1)],
        stations=[0.25, 1.2],
        rotation_step=30.0,
        rng=3,
    )
    cloud = io.read_points(out)
    np.testing.assert_array_equal(cloud.points, expected.points)
    np.testing.assert_array_equal(cloud.viewpoints, expected.viewpoints)
    assert io.read_mesh(tmp_path / "elbow-truth.ply").n_faces > 1000


def test_cli_synth_help_names_the_scan_kinds_and_their_stations(capsys):
    with pytest.raises(SystemExit):
        main(["synth", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "damaged-elbow-scan" in text
    assert "scanner positions in metres along the centreline (damaged-pipe-scan," in text


@pytest.mark.parametrize(
    "kind, options, message",
    [
        ("damaged-pipe-scan", ["--dent", "1.0,90,0.01"], "--dent must be AXIAL,CLOCK,DEPTH,WIDTH"),
        ("damaged-pipe", ["--bulge", "1,2,x,4"], "--bulge must be AXIAL,CLOCK,DEPTH,WIDTH"),
        ("damaged-pipe", ["--dent", "1,400,0.01,0.2"], "--dent 1,400,0.01,0.2: defect clock"),
        ("damaged-elbow", ["--ovality", "0.1,2,3"], "--ovality must be VALUE or VALUE,CLOCK"),
        ("damaged-pipe-scan", ["--stations", "0.5,9"], r"stations must be heights in \[0, "),
        (
            "damaged-elbow-scan",
            ["--stations", "0.5,2"],
            r"stations must be arc lengths in \[0, 1.94248 ",
        ),
        ("damaged-pipe", ["--stations", "0.5"], "--stations goes with damaged-pipe-scan and"),
        ("pipe-scan", ["--stations", "0.5"], "--stations goes with damaged-pipe-scan and"),
        ("damaged-elbow-scan", ["--length", "3"], "--length does not apply to damaged-elbow-scan"),
        ("sphere", ["--dent", "1,0,0.01,0.2"], "--dent and --bulge go with the damaged-"),
        ("sphere", ["--ovality", "0.01"], "--ovality goes with the damaged-"),
        ("sphere", ["--joint", "gap,1,0.01"], "--joint, --mesh and --up go with inject"),
        ("inject", [], "a scan goes with inject, and inject needs one"),
        ("damaged-elbow", ["--length", "3"], "--length does not apply to damaged-elbow"),
    ],
)
def test_cli_synth_refuses_bad_damage_in_one_line(kind, options, message, tmp_path, capsys):
    assert main(["synth", kind, "-o", str(tmp_path / "s.ply"), "--points", "100", *options]) == 2
    error = capsys.readouterr().err
    assert error.startswith("zeroset: error: ") and error.count("\n") == 1
    assert re.search(message, error)
    assert list(tmp_path.iterdir()) == []


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
        (lambda: Defect("crack", 1.0, 0.0, 0.01, 0.1), "defect kind must be one of"),
        (lambda: Defect("dent", 1.0, 360.0, 0.01, 0.1), r"clock must be degrees in \[0, 360\)"),
        (lambda: Defect("dent", -1.0, 0.0, 0.01, 0.1), "defect axial must be a distance >= 0"),
        (lambda: Defect("dent", 1.0, 0.0, 0.0, 0.1), "defect depth must be a positive number"),
        (lambda: damaged_pipe(10, shape="tee"), "shape must be 'straight' or 'elbow'"),
        (
            lambda: damaged_pipe(10, defects=[Defect("dent", 2.5, 0.0, 0.01, 0.1)]),
            "beyond the centreline's end",
        ),
        (
            lambda: damaged_pipe(10, defects=[Defect("dent", 1.0, 0.0, 0.3, 0.1)]),
            "through the axis",
        ),
        (
            lambda: damaged_pipe(10, shape="elbow", defects=[Defect("bulge", 0.5, 0.0, 0.4, 0.1)]),
            "beyond bend_radius",
        ),
        (lambda: damaged_pipe(10, ovality=1.5), r"ovality must be a number in \[0, 1\)"),
        (lambda: damaged_pipe(10, ovality_span=(1.5, 0.5)), "ovality_span must satisfy"),
        (
            lambda: scan_damaged_pipe(offset=0.2, defects=[Defect("dent", 1.0, 0.0, 0.06, 0.1)]),
            "offset must be below radius less",
        ),
        (lambda: scan_damaged_pipe(stations=[3.0]), r"stations must be heights in \[0, "),
        (
            lambda: scan_damaged_pipe(shape="elbow", stations=[3.0]),
            r"stations must be arc lengths in \[0, 1.94248 \(the centreline's length\)\]",
        ),
        (lambda: scan_damaged_pipe(shape="bent"), "shape must be 'straight' or 'elbow'"),
    ],
)
def test_bad_input_is_refused_with_a_message(make, message):
    with pytest.raises(InputError, match=message):
        make()


def test_defects_must_be_defects():
    with pytest.raises(TypeError, match="defects must be Defect instances"):
        damaged_pipe(10, defects=[("dent", 1.0, 0.0, 0.01, 0.1)])


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
