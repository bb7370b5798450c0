"""Synthetic pipe runs: the centreline and its frame, joints, tees, the in-pipe scan of a
run, random runs and their truth records."""

import json
import math

import numpy as np
import pytest

from zeroset import io
from zeroset.cli import main
from zeroset.errors import InputError
from zeroset.synthetic import (
    Defect,
    Joint,
    PipePath,
    Tee,
    pipe_run,
    random_pipe_run,
    scan_damaged_pipe,
    scan_pipe_run,
    write_sample,
)
from zeroset.synthetic._runs import _run

R = 0.15
# A run leaving the horizontal plane in its second bend, with damage of every kind.
PATH = PipePath.build(
    [
        ("straight", 1.2),
        ("bend", 0.6, 70.0, 90.0),
        ("straight", 0.8),
        ("bend", 0.5, 60.0, 30.0),
        ("straight", 0.7),
    ]
)
DAMAGE = {
    "defects": [
        Defect("dent", 0.5, 30.0, 0.01, 0.08),
        Defect("bulge", 1.5, 200.0, 0.008, 0.06),
        Defect("dent", 2.9, 100.0, 0.012, 0.07),
    ],
    "joints": [
        Joint("gap", 0.3, 0.012, depth=0.006),
        Joint("offset", 0.95, 0.008, clock=60.0),
        Joint("bead", 2.3, 0.004),
        Joint("offset", 2.45, 0.005, clock=250.0),
    ],
    "tees": [Tee(0.75, 270.0, 0.07, 0.3)],
    "ovality": 0.02,
    "ovality_span": (1.4, 2.0),
}
STATIONS = [0.0, 0.75, 1.6, 2.4, PATH.length]


@pytest.fixture(scope="module")
def scan():
    return scan_pipe_run(
        PATH, radius=R, stations=STATIONS, rotation_step=30.0, noise_scale=0.0, **DAMAGE
    )


def _radial(frame, clock_deg):
    """Unit radial directions (M, 3) at clocks (M,) in degrees of a path's frame."""
    _, tangent, up, _ = frame
    c = np.radians(clock_deg)[:, None]
    return np.cos(c) * up + np.sin(c) * np.cross(tangent, up)


@pytest.mark.parametrize(
    "roll, end",
    [
        (90.0, lambda a: (1.0 + 0.8 * math.sin(a), -0.8 * (1.0 - math.cos(a)), 0.0)),
        (0.0, lambda a: (1.0 + 0.8 * math.sin(a), 0.0, 0.8 * (1.0 - math.cos(a)))),
    ],
)
def test_a_bend_has_the_exact_arc_length_and_end(roll, end):
    # Starting along +x with up +z, roll 90 turns right (towards -y), roll 0 up.
    angle = 50.0
    path = PipePath.build([("straight", 1.0), ("bend", 0.8, angle, roll)])
    assert path.length == pytest.approx(1.0 + 0.8 * math.radians(angle), abs=1e-15)
    centre, tangent, _, curvature = path.frame([path.length])
    np.testing.assert_allclose(centre[0], end(math.radians(angle)), atol=1e-15)
    assert np.linalg.norm(tangent[0]) == pytest.approx(1.0)
    assert curvature[0] == pytest.approx(1.0 / 0.8)
    assert path.frame([0.5])[3][0] == 0.0


def test_the_frame_is_orthonormal_continuous_and_does_not_twist():
    path = random_pipe_run(5, out_of_plane=True, bends=(4, 4)).path
    s = np.linspace(0.0, path.length, 4001)
    centre, tangent, up, curvature = path.frame(s)
    np.testing.assert_allclose(np.linalg.norm(tangent, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(up, axis=1), 1.0, atol=1e-12)
    assert np.abs(np.einsum("ij,ij->i", tangent, up)).max() < 1e-12
    # The centreline's derivative is the tangent, and up turns only towards the tangent,
    # never about it (parallel transport): central differences, 2nd order.
    h = 1e-5
    inner = s[1:-1]
    ahead, behind = path.frame(inner + h), path.frame(inner - h)
    np.testing.assert_allclose((ahead[0] - behind[0]) / (2 * h), tangent[1:-1], atol=1e-7)
    turn = np.einsum("ij,ij->i", (ahead[2] - behind[2]) / (2 * h), np.cross(tangent, up)[1:-1])
    assert np.abs(turn).max() < 1e-7
    # The frame is continuous across the junctions of the pieces.
    junctions = np.cumsum(
        [p[1] if p[0] == "straight" else p[1] * math.radians(p[2]) for p in path.pieces]
    )[:-1]
    before, after = path.frame(junctions - 1e-12), path.frame(junctions + 1e-12)
    for one, two in zip(before[:3], after[:3], strict=True):  # centre, tangent, up
        np.testing.assert_allclose(one, two, atol=1e-9)
    assert curvature.max() > 0.0 and curvature.min() == 0.0


def test_up_stays_vertical_on_a_level_run_and_the_clock_runs_clockwise():
    path = random_pipe_run(3).path  # bends in the horizontal plane
    s = np.linspace(0.0, path.length, 500)
    frame = path.frame(s)
    np.testing.assert_allclose(frame[2], np.broadcast_to([0.0, 0.0, 1.0], (s.size, 3)), atol=1e-12)
    np.testing.assert_allclose(frame[0][:, 2], 0.0, atol=1e-12)
    # Clock 90 (3 o'clock) is tangent x up: on the start along +x that is -y, the right.
    np.testing.assert_allclose(
        _radial(path.frame([0.0]), np.array([90.0])), [[0, -1, 0]], atol=1e-15
    )


def test_nearest_recovers_the_arc_length_of_points_around_the_centreline():
    path = random_pipe_run(8, out_of_plane=True).path
    rng = np.random.default_rng(1)
    s = rng.uniform(0.0, path.length, 3000)
    clock, rho = rng.uniform(0.0, 360.0, s.size), rng.uniform(0.0, 0.3, s.size)
    frame = path.frame(s)
    found, overshoot = path.nearest(frame[0] + rho[:, None] * _radial(frame, clock))
    np.testing.assert_allclose(found, s, atol=1e-9)
    assert overshoot.max() == 0.0
    # Beyond the open end, the overshoot is the distance past its plane.
    end, tangent, up, _ = path.frame([path.length])
    found, overshoot = path.nearest(end + 0.2 * tangent + 0.05 * up)
    assert found[0] == pytest.approx(path.length) and overshoot[0] == pytest.approx(0.2)


@pytest.mark.slow
def test_scanned_points_lie_on_the_true_wall_and_beams_stop_at_the_first_hit(scan):
    assert scan.points.shape[0] > 20_000
    assert scan.distance(scan.points).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(scan.normals, axis=1), 1.0, atol=1e-12)
    # March a sample of beams in 0.5 mm steps up to their hits: every step is inside.
    bore = _run(
        PATH,
        R,
        DAMAGE["defects"],
        DAMAGE["joints"],
        DAMAGE["tees"],
        0.02,
        0.0,
        DAMAGE["ovality_span"],
    )[0]
    chosen = np.random.default_rng(0).choice(scan.points.shape[0], 800, replace=False)
    start, end = scan.viewpoints[chosen], scan.points[chosen]
    steps = np.ceil(np.linalg.norm(end - start, axis=1) / 5e-4).astype(np.int64)
    beam = np.repeat(np.arange(chosen.size), steps)
    f = (np.arange(beam.size) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[beam]
    assert bore.gap(start[beam] + f[:, None] * (end - start)[beam])[0].max() < 0.0


@pytest.mark.slow
def test_viewpoints_circle_the_true_centreline_in_the_stations_cross_sections(scan):
    record = scan.truth_record
    line = np.array(record["centreline"])
    near = np.linalg.norm(scan.viewpoints[:, None] - line[None, ::5, 1:], axis=2).argmin(1)
    # The sampled centreline's chords sag by (5 cm)^2 / (8 x 0.5 m) = 0.6 mm at most.
    dense = line[:, 1:]
    rows = np.clip(5 * near[:, None] + np.arange(-6, 7), 0, dense.shape[0] - 1)
    distance = np.linalg.norm(scan.viewpoints[:, None] - dense[rows], axis=2).min(axis=1)
    assert np.abs(distance - 0.05).max() < 1e-4
    frame = PATH.frame(STATIONS)
    for k, s0 in enumerate(STATIONS):
        mine = np.abs(np.linalg.norm(scan.viewpoints - frame[0][k], axis=1) - 0.05) < 0.011
        mine &= np.abs((scan.viewpoints - frame[0][k]) @ frame[1][k]) < 1e-12
        assert mine.sum() > 1000, s0


def test_beams_stop_at_the_open_ends():
    path = PipePath.build([("straight", 1.5), ("bend", 0.5, 45.0, 270.0), ("straight", 1.5)])
    scan = scan_pipe_run(
        path, radius=R, stations=[0.0, 1.0, path.length], rotation_step=20.0, noise_scale=0.0
    )
    (start, end), (t0, t1) = path.frame([0.0, path.length])[:2]
    behind, beyond = (scan.points - start) @ t0, (scan.points - end) @ t1
    assert behind.min() > -1e-12 and beyond.max() < 1e-12
    # The wall is seen right up to both ends.
    assert (behind < 0.01).sum() > 50 and (beyond > -0.01).sum() > 50


def test_joints_change_the_radius_where_and_as_much_as_they_should():
    joints = [
        Joint("gap", 1.0, 0.01, depth=0.005),
        Joint("bead", 2.0, 0.004),
        Joint("offset", 3.0, 0.01, clock=90.0),
    ]
    path = PipePath.build([("straight", 4.0)])  # along +x, up +z: 3 o'clock is -y
    run = pipe_run(path, 60_000, radius=R, joints=joints, rng=2)
    s, (y, z) = run.points[:, 0], run.points[:, 1:].T
    rho = np.hypot(y, z)
    gap, bead = np.abs(s - 1.0), np.abs(s - 2.0)
    np.testing.assert_allclose(rho[gap < 0.0045], R + 0.005, atol=1e-12)
    np.testing.assert_allclose(rho[(gap > 0.0055) & (s < 1.5)], R, atol=1e-12)
    np.testing.assert_allclose(rho[(bead > 0.01) & (s > 1.5) & (s < 2.5)], R, atol=1e-12)
    ring = bead < 0.01  # a cos^2 ring 20 mm wide
    profile = R - 0.004 * np.cos(np.pi * (s[ring] - 2.0) / 0.02) ** 2
    np.testing.assert_allclose(rho[ring], profile, atol=1e-12)
    assert ring.sum() > 100
    # Beyond the offset the wall is the circle of radius R about the axis moved 1 cm to -y.
    beyond = s > 3.001
    np.testing.assert_allclose(np.hypot(y[beyond] + 0.01, z[beyond]), R, atol=1e-12)
    np.testing.assert_allclose(rho[(s < 2.999) & (s > 2.5)], R, atol=1e-12)
    record = run.truth_record
    assert [j["kind"] for j in record["joints"]] == ["gap", "bead", "offset"]
    assert record["joints"][2]["centre"] == pytest.approx([3.0, -0.005, 0.0], abs=1e-12)
    line = np.array(record["centreline"])
    np.testing.assert_allclose(line[line[:, 0] > 3.001, 2], -0.01, atol=1e-12)
    np.testing.assert_allclose(
        line[line[:, 0] < 2.999, 1:3],
        np.c_[line[line[:, 0] < 2.999, 0], np.zeros((line[:, 0] < 2.999).sum())],
        atol=1e-12,
    )


@pytest.mark.slow
def test_a_tees_branch_is_open_to_the_run_and_its_points_lie_on_its_wall(scan):
    tee = DAMAGE["tees"][0]
    record = scan.truth_record["tees"][0]
    bore = _run(
        PATH,
        R,
        DAMAGE["defects"],
        DAMAGE["joints"],
        DAMAGE["tees"],
        0.02,
        0.0,
        DAMAGE["ovality_span"],
    )[0]
    branch = bore.branches[0]
    np.testing.assert_allclose(record["centre"], branch.foot + R * branch.axis, atol=1e-12)
    along, across = branch.coordinates(scan.points)
    rho = np.linalg.norm(across, axis=1)
    out = (along > R + 0.001) & (rho < 2.0 * tee.radius)
    assert out.sum() > 100
    np.testing.assert_allclose(rho[out], tee.radius, atol=1e-9)
    assert along.max() < R + tee.length
    # No point of the run's wall lies in the opening.
    assert not np.any((rho < tee.radius - 1e-6) & (along > 0.0))
    run = pipe_run(PATH, 20_000, radius=R, tees=DAMAGE["tees"], rng=3)
    along, across = branch.coordinates(run.points)
    rho = np.linalg.norm(across, axis=1)
    assert (along > R).sum() > 200 and not np.any((rho < tee.radius - 1e-9) & (along > 0.0))
    mesh = run.truth_mesh(0.02)
    assert run.distance(mesh.vertices).max() < 1e-9


@pytest.mark.slow
def test_the_truth_record_describes_the_run(scan, tmp_path):
    record = scan.truth_record
    json.dumps(record)
    assert record["kind"] == "pipe run scan" and record["radius"] == R
    assert (
        PipePath.build(
            record["path"]["pieces"],
            start=record["path"]["start"],
            direction=record["path"]["direction"],
            up=record["path"]["up"],
        )
        == PATH
    )
    assert "12 o'clock (0) is the run's up" in record["clock_convention"]
    line = np.array(record["centreline"])
    assert line[0, 0] == 0.0 and line[-1, 0] == pytest.approx(PATH.length)
    assert np.diff(line[:, 0]).max() <= 0.01 + 1e-12
    assert record["stations"] == STATIONS and len(record["joints"]) == 4
    # A defect's centre lies on the circle of radius R about the true centreline.
    for defect in record["defects"]:
        s = defect["axial"]
        centre = line[np.argmin(np.abs(line[:, 0] - s)), 1:]
        assert np.linalg.norm(np.array(defect["centre"]) - centre) == pytest.approx(R, abs=2e-3)
    points, truth = write_sample(scan, tmp_path / "run.ply", spacing=0.03)
    assert json.loads((tmp_path / "run-truth.json").read_text()) == json.loads(json.dumps(record))
    assert io.read_mesh(truth).n_faces > 1000 and io.read_points(points).viewpoints is not None


def test_the_run_scan_of_an_elbow_is_the_damaged_elbow_scan():
    elbow = PipePath.build(
        [("straight", 0.5), ("bend", 0.6, 90.0, 270.0), ("straight", 0.5)],
        direction=(0, 0, 1),
        up=(0, 1, 0),
    )
    damage = {"defects": [Defect("dent", 1.0, 90.0, 0.01, 0.1)], "ovality": 0.02}
    keywords = {"stations": [0.3, 1.2], "rotation_step": 30.0, "rng": 4, **damage}
    run = scan_pipe_run(elbow, radius=0.25, **keywords)
    damaged = scan_damaged_pipe(shape="elbow", **keywords)
    np.testing.assert_array_equal(run.points, damaged.points)
    np.testing.assert_array_equal(run.normals, damaged.normals)


def test_the_same_seed_gives_the_same_run_and_another_seed_another():
    spec = random_pipe_run(4, defects=2, joints=(1.0, 3.0), tee=True)
    assert spec == random_pipe_run(4, defects=2, joints=(1.0, 3.0), tee=True)
    assert random_pipe_run(5, tee=True).path != spec.path
    one, two = (spec.scan(rotation_step=60.0, rng=1) for _ in range(2))
    for field in ("points", "normals", "viewpoints"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
    assert not np.array_equal(one.points, spec.scan(rotation_step=60.0, rng=2).points)
    # Damage is drawn apart from the geometry: switching it off keeps path, tee and stations.
    plain = random_pipe_run(4, tee=True)
    assert (plain.path, plain.tees, plain.stations) == (spec.path, spec.tees, spec.stations)
    assert spec.without_damage() == plain


@pytest.mark.parametrize("seed", range(6))
def test_random_runs_keep_to_their_ranges_and_spacings(seed):
    diameter = 0.4
    spec = random_pipe_run(
        seed, bends=(2, 3), out_of_plane=seed % 2 == 1, tee=True, defects=3, joints=(1.0, 2.0)
    )
    path = spec.path
    bends = [p for p in path.pieces if p[0] == "bend"]
    legs = [p[1] for p in path.pieces if p[0] == "straight"]
    assert 2 <= len(bends) <= 3 and len(legs) == len(bends) + 1
    assert all(diameter <= b[1] <= 3 * diameter and 30 <= b[2] <= 90 for b in bends)
    assert all(diameter <= leg <= 5 * diameter for leg in legs)
    rolls = {b[3] % 360.0 for b in bends}
    assert (rolls <= {90.0, 270.0}) == (seed % 2 == 0)
    ends = np.concatenate(
        [
            [0.0],
            np.cumsum(
                [p[1] if p[0] == "straight" else p[1] * math.radians(p[2]) for p in path.pieces]
            ),
        ]
    )
    kinds = [p[0] for p in path.pieces]

    def on_straight(s, margin):
        k = np.searchsorted(ends, s, side="right") - 1
        return kinds[k] == "straight" and ends[k] + margin <= s <= ends[k + 1] - margin

    assert len(spec.defects) == 3
    for i, d in enumerate(spec.defects):
        assert diameter <= d.axial <= path.length - diameter
        assert 0.005 <= d.depth <= 0.015 and 0.04 <= d.width <= 0.1
        assert all(abs(d.axial - j.axial) >= 2 * d.width for j in spec.joints)
        for e in spec.defects[i + 1 :]:
            turn = math.radians((d.clock - e.clock + 180.0) % 360.0 - 180.0)
            assert math.hypot(0.5 * diameter * turn, d.axial - e.axial) >= 2 * max(d.width, e.width)
    assert all(on_straight(j.axial, 0.5 * diameter) for j in spec.joints)
    assert np.all(np.diff([j.axial for j in spec.joints]) >= 1.0)
    (tee,) = spec.tees
    assert on_straight(tee.axial, tee.radius) and tee.radius < 0.5 * diameter
    gaps = np.diff(spec.stations)
    assert np.all((gaps >= 0.5) & (gaps <= 1.5)) and spec.stations[-1] <= path.length


def test_the_cli_writes_a_random_run_and_its_truth(tmp_path, capsys):
    out = tmp_path / "run.ply"
    argv = ["--seed", "7", "--tee", "--joints", "--rotation-step", "60"]
    assert main(["synth", "pipe-run", "-o", str(out), *argv]) == 0
    assert "run-truth.json" in capsys.readouterr().out
    record = json.loads((tmp_path / "run-truth.json").read_text())
    spec = random_pipe_run(7, tee=True, joints=(1.0, 3.0))
    assert record["kind"] == "pipe run scan" and len(record["tees"]) == 1
    assert record["stations"] == list(spec.stations) and record["seed"] == 7
    cloud = io.read_points(out)
    np.testing.assert_array_equal(cloud.points, spec.scan(rotation_step=60.0).points)
    assert io.read_mesh(tmp_path / "run-truth.ply").n_faces > 1000
    uniform = tmp_path / "uniform.ply"
    assert main(["synth", "pipe-run", "-o", str(uniform), "--uniform", "3000", "--quiet"]) == 0
    cloud = io.read_points(uniform)
    assert cloud.points.shape == (3000, 3) and cloud.viewpoints is None


@pytest.mark.parametrize(
    "argv, message",
    [
        (["synth", "tee", "--tee"], "--tee goes with pipe-run"),
        (["synth", "pipe-run", "--bends", "3"], "--bends must be MIN,MAX"),
        (["synth", "pipe-run", "--defects", "-1"], "defects must be a positive integer"),
    ],
)
def test_the_cli_refuses_bad_run_options_in_one_line(argv, message, tmp_path, capsys):
    assert main([*argv, "-o", str(tmp_path / "x.ply")]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "make, error, message",
    [
        (lambda: PipePath.build([]), InputError, "at least one piece"),
        (lambda: PipePath.build([("bend", 1.0, 200.0, 0.0)]), InputError, r"in \(0, 180\]"),
        (lambda: PipePath.build([("twist", 1.0)]), InputError, "each piece must be"),
        (lambda: PipePath.build([("straight", 1.0)], up=(1, 0, 0)), InputError, "parallel"),
        (lambda: PipePath.build([("straight", 1.0)]).frame([2.0]), InputError, r"in \[0, 1\]"),
        (lambda: Joint("crack", 1.0, 0.01), InputError, "joint kind must be one of"),
        (lambda: Joint("gap", 1.0, 0.0), InputError, "joint size must be a positive"),
        (lambda: Tee(1.0, 400.0, 0.1, 0.3), InputError, r"tee clock must be degrees"),
        (
            lambda: pipe_run(PATH, 10, radius=R, tees=[Tee(1.5, 0.0, 0.1, 0.3)]),
            InputError,
            "must leave a straight piece",
        ),
        (
            lambda: pipe_run(PATH, 10, radius=R, tees=[Tee(0.5, 0.0, 0.2, 0.3)]),
            InputError,
            "tee's radius must be below",
        ),
        (lambda: pipe_run(PATH, 10, radius=0.5), InputError, "beyond bend_radius"),
        (
            lambda: pipe_run(PATH, 10, joints=[Joint("gap", 9.0, 0.01)]),
            InputError,
            "beyond the centreline's end",
        ),
        (lambda: pipe_run("path", 10), TypeError, "path must be a zeroset.synthetic.PipePath"),
        (lambda: pipe_run(PATH, 10, joints=[("gap", 1.0, 0.01)]), TypeError, "joints must be"),
        (lambda: scan_pipe_run(PATH, stations=[9.0]), InputError, "stations must be arc"),
        (lambda: random_pipe_run(0, legs=(2.0, 1.0)), InputError, "legs must be positive"),
        (lambda: random_pipe_run(0, bend_radius=(0.5, 1.0)), InputError, "at least 1 diameter"),
    ],
)
def test_bad_input_is_refused_with_a_message(make, error, message):
    with pytest.raises(error, match=message):
        make()
