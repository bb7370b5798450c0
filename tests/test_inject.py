"""Known truth put into a scan's points: `zeroset.synthetic.inject` and `zeroset synth inject`."""

import json

import numpy as np
import pytest

from zeroset import io
from zeroset.cli import main
from zeroset.errors import InputError
from zeroset.inspect import fit_pipe
from zeroset.synthetic import Defect, Joint, inject, sample_cylinder

RADIUS = 0.25


@pytest.fixture(scope="module")
def straight():
    """A noise-free open cylinder along +z (0 to 1 m) and the pipe fitted to its truth mesh:
    the pipe runs towards +z from z = 0, 12 o'clock +y (it starts along the world's up)."""
    sample = sample_cylinder(30_000, radius=RADIUS, length=1.0, rng=3)
    return sample.points, fit_pipe(sample.truth_mesh(0.01), sample.points)


def _radius(points):
    return np.hypot(points[:, 0], points[:, 1])


def test_a_dent_moves_the_wall_towards_the_axis_by_its_profile(straight):
    points, pipe = straight
    dent = Defect("dent", axial=0.5, clock=90.0, depth=0.01, width=0.12)
    moved, truth = inject(points, pipe, defects=[dent])
    axial, clock, _ = pipe.locate(points)
    u = RADIUS * np.radians((clock - 90.0 + 180.0) % 360.0 - 180.0)
    d = np.hypot(u, axial - 0.5)
    expected = np.where(d < 0.06, -0.01 * np.cos(np.pi * d / 0.12) ** 2, 0.0)
    change = _radius(moved) - _radius(points)
    assert np.abs(change - expected).max() < 2e-4  # metres: the fitted axis, not the truth
    assert np.all(change[d >= 0.06] == 0.0)  # nothing moves beyond the patch
    assert truth["moved"] == np.count_nonzero(np.abs(expected) > 1e-6)
    (record,) = truth["defects"]
    assert record["kind"] == "dent" and record["depth"] == 0.01
    centre = np.array(record["centre"])  # on the wall at the dent's clock and height
    assert abs(np.hypot(*centre[:2]) - RADIUS) < 2e-3
    assert abs(centre[2] - (points[:, 2].min() + 0.5)) < 3e-3  # axial from where data start
    # 3 o'clock is tangent x up = +z x +y = -x
    assert centre[0] < -0.24 and abs(centre[1]) < 0.01


def test_along_the_beams_the_points_stay_on_them(straight):
    points, pipe = straight
    sensor = np.array([0.05, 0.0, 0.3])
    bulge = Defect("bulge", axial=0.4, clock=0.0, depth=0.008, width=0.15)
    moved, _ = inject(points, pipe, defects=[bulge], viewpoints=sensor)
    before, after = points - sensor, moved - sensor
    cross = np.linalg.norm(np.cross(before, after), axis=1) / np.linalg.norm(before, axis=1)
    assert cross.max() < 1e-9  # metres off the beam: moved along it
    changed = np.abs(_radius(moved) - _radius(points)) > 1e-6
    assert changed.any() and np.all(_radius(moved)[changed] > _radius(points)[changed])


def test_joints_shape_the_wall_beyond_and_across_them(straight):
    points, pipe = straight
    start = points[:, 2].min()
    gap = Joint("gap", axial=0.3, size=0.01, depth=0.004)
    offset = Joint("offset", axial=0.7, size=0.006, clock=0.0)
    moved, truth = inject(points, pipe, joints=[gap, offset])
    axial = pipe.locate(points)[0]
    change = _radius(moved) - _radius(points)
    inside = np.abs(axial - 0.3) < 0.0045  # the recess, within its ramps
    assert np.allclose(change[inside], 0.004, atol=2e-4)
    beyond = axial > 0.702
    up = points[beyond, 1] / _radius(points[beyond])  # cos of the clock from +y
    assert np.abs(change[beyond] - 0.006 * up).max() < 3e-4  # the next pipe moved 6 mm up
    assert np.all(change[(axial < 0.29) | ((axial > 0.31) & (axial < 0.698))] == 0.0)
    assert [j["kind"] for j in truth["joints"]] == ["gap", "offset"]
    assert abs(truth["joints"][0]["centre"][2] - (start + 0.3)) < 3e-3


def test_features_off_the_pipe_are_refused(straight):
    points, pipe = straight
    with pytest.raises(InputError, match="beyond the scan's pipe"):
        inject(points, pipe, defects=[Defect("dent", 3.0, 0.0, 0.01, 0.1)])
    with pytest.raises(InputError, match="zeroset.synthetic.Defect"):
        inject(points, pipe, defects=[("dent", 0.5, 0.0, 0.01, 0.1)])


def test_cli_synth_inject_writes_the_moved_scan_and_its_truth(tmp_path, straight, capsys):
    sample = sample_cylinder(30_000, radius=RADIUS, length=1.0, rng=3)
    scan = io.write_points(tmp_path / "scan.ply", sample.points)
    mesh = io.write_mesh(tmp_path / "mesh.ply", sample.truth_mesh(0.01))
    before = scan.read_bytes()
    out = tmp_path / "dented.ply"
    argv = ["synth", "inject", str(scan), "-o", str(out), "--mesh", str(mesh)]
    assert main([*argv, "--dent", "0.5,90,0.01,0.12", "--joint", "gap,0.3,0.01,0,0.004"]) == 0
    assert "moved" in capsys.readouterr().out
    assert scan.read_bytes() == before  # the input is never modified
    moved = io.read_points(out).points
    truth = json.loads((tmp_path / "dented-truth.json").read_text())
    assert truth["source"] == str(scan) and len(truth["defects"]) == len(truth["joints"]) == 1
    change = _radius(moved) - _radius(sample.points)
    assert -0.0101 < change.min() < -0.0095 and 0.0039 < change.max() < 0.0041
    assert main([*argv, "--joint", "ring,0.3,0.01"]) == 2
    assert "--joint ring,0.3,0.01: joint kind must be one of" in capsys.readouterr().err
