"""Pipe inspection: centreline, clock, deviation, ovality, defects and branches, measured
against the truth the damaged-pipe generators record."""

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage

from zeroset import io, reconstruct
from zeroset.cli import main
from zeroset.errors import InputError
from zeroset.inspect import (
    clock_label,
    deviation,
    find_defects,
    fit_pipe,
    inspect_pipe,
    inspection_summary,
)
from zeroset.inspect._centreline import _straight_run
from zeroset.inspect._defects import _significance
from zeroset.synthetic import (
    Defect,
    damaged_pipe,
    sample_sphere,
    sample_tee,
    scan_damaged_pipe,
)
from zeroset.types import Mesh

#: Dents of the issue: 5 and 15 mm deep, 6 cm wide, in a 0.5 m pipe.
DENTS = (Defect("dent", 0.7, 60.0, 0.005, 0.06), Defect("dent", 1.3, 200.0, 0.015, 0.06))
#: The robot stops every half metre of the 2 m pipe.
STATIONS = (0.5, 1.0, 1.5)


def _reconstructed(sample):
    """The phase-1 mesh of a sample, oriented by its viewpoints when it has them."""
    return reconstruct(sample.points, viewpoints=sample.viewpoints, progress=False).mesh


def _found(inspection, truth: dict):
    """The defect found nearest the true one, and the true centre located on the pipe."""
    axial, clock, _ = inspection.pipe.locate(np.array([truth["centre"]]))
    nearest = min(
        inspection.defects.defects,
        key=lambda d: abs(d.axial - axial[0]) + abs((d.clock - clock[0] + 180) % 360 - 180) / 360,
    )
    return nearest, float(axial[0]), float(clock[0])


@pytest.fixture(scope="module")
def dented_scan():
    sample = scan_damaged_pipe(defects=DENTS, stations=STATIONS, rng=0)
    mesh = _reconstructed(sample)
    return sample, mesh, inspect_pipe(mesh, sample.points, viewpoints=sample.viewpoints)


@pytest.fixture(scope="module")
def clean_scan():
    sample = scan_damaged_pipe(stations=STATIONS, rotation_step=2.0, rng=1)
    return sample, inspect_pipe(_reconstructed(sample), sample.points)


def test_clock_label_reads_a_clock_face():
    assert [clock_label(c) for c in (0.0, 90.0, 15.0, 187.5, 359.9, 270.0)] == [
        "12:00",
        "3:00",
        "12:30",
        "6:15",
        "12:00",
        "9:00",
    ]


def test_centreline_of_a_straight_scan_is_its_axis(clean_scan):
    sample, inspection = clean_scan
    pipe = inspection.pipe
    centres = pipe.position(np.linspace(0.05, pipe.length - 0.05, 50), 0.0, distance=0.0)
    assert np.hypot(centres[:, 0], centres[:, 1]).max() < 5e-4  # on the z axis, metres
    assert abs(pipe.radius - 0.25) < 5e-4
    assert pipe.tangents[len(pipe.tangents) // 2] @ [0, 0, 1] > 0.999  # runs towards +z
    assert abs(pipe.length - 2.0) < 0.03
    # the clock of the truth record: 12 o'clock +y, 3 o'clock t x y = -x
    _, clock, distance = pipe.locate(np.array([[0.0, 0.25, 1.0], [-0.25, 0.0, 1.0]]))
    np.testing.assert_allclose((clock - [0.0, 90.0] + 180.0) % 360.0 - 180.0, 0.0, atol=0.5)
    np.testing.assert_allclose(distance, 0.25, atol=1e-3)


def test_a_clean_pipe_has_no_defect_and_no_ovality(clean_scan):
    sample, inspection = clean_scan
    assert inspection.defects.defects == ()
    assert inspection.defects.branches == ()
    assert np.nanmax(inspection.ovality.ovality) < 0.003
    # points' deviations are unbiased: the median is within 0.2 mm of the true wall
    assert abs(np.nanmedian(inspection.point_deviation)) < 2e-4


def test_understated_errors_of_the_wall_map_raise_no_false_defect(clean_scan):
    sample, inspection = clean_scan
    wall = replace(inspection.wall, error=0.5 * inspection.wall.error)
    found = find_defects(wall, inspection.pipe, inspection.ovality, sample.points)
    assert found.defects == ()
    # the wall's own dispersion scales the halved errors back: the same threshold, within 10 %
    assert found.threshold == pytest.approx(inspection.defects.threshold, rel=0.1)
    assert found.significance == pytest.approx(2.0 * inspection.defects.significance, rel=0.1)
    assert inspection.defects.significance > 4.5  # a 2 m pipe's z, times at least 1


def test_significance_gives_the_false_alarms_of_smoothed_noise():
    """Over fields of smoothed white noise, regions beyond +-z number as many as asked."""
    kernel, size, fields, asked = 2.0, 256, 12, 2.0
    z = _significance(float(size * size), kernel, false_alarms=asked)
    assert z > _significance(float(size * size) / 4, kernel, false_alarms=asked)
    rng = np.random.default_rng(7)
    regions = 0
    for _ in range(fields):
        field = ndimage.gaussian_filter(rng.standard_normal((size, size)), kernel, mode="wrap")
        field /= 1.0 / (2.0 * np.sqrt(np.pi) * kernel)  # its standard deviation
        for sign in (1.0, -1.0):
            regions += ndimage.label(sign * field > z, structure=np.ones((3, 3)))[1]
    assert 0.6 * asked * fields < regions < 1.5 * asked * fields


def test_dents_in_a_scanned_pipe_are_found_with_depth_position_and_clock(dented_scan):
    sample, _, inspection = dented_scan
    assert len(inspection.defects.defects) == len(DENTS)
    for truth in sample.truth_record["defects"]:
        found, axial, clock = _found(inspection, truth)
        assert found.kind == "dent"
        assert abs(-found.depth - truth["depth"]) < 1.5e-3
        assert abs(found.axial - axial) < 0.03
        assert abs((found.clock - clock + 180.0) % 360.0 - 180.0) < 15.0
        assert abs(found.clock - truth["clock"]) < 15.0  # one clock with the generator's
        assert 0 < found.uncertainty < 1.5e-3
        assert found.axial_start < found.axial < found.axial_end
        assert 0 < found.area < np.pi * truth["width"] ** 2


def test_depths_fitted_along_the_beams_are_unbiased_where_radial_ones_are_shallow(dented_scan):
    # Range noise along oblique beams blurs a dent and bunches the beams on its near flank,
    # so residuals measured radially read shallower; along the beams they do not.
    sample, mesh, along_beams = dented_scan
    radially = inspect_pipe(mesh, sample.points)
    errors = {}
    for name, inspection in (("beams", along_beams), ("radial", radially)):
        errors[name] = [
            -_found(inspection, truth)[0].depth - truth["depth"]
            for truth in sample.truth_record["defects"]
        ]
    assert np.abs(errors["beams"]).max() < 0.75e-3
    assert np.mean(errors["radial"]) < np.mean(errors["beams"]) - 0.25e-3


def test_deviation_is_signed_inward_negative(dented_scan):
    sample, mesh, inspection = dented_scan
    truth = sample.truth_record["defects"][1]  # 15 mm
    centre = np.array(truth["centre"]) * (1 - 0.015 / 0.25)  # moved onto the dent's bottom
    assert deviation(inspection.pipe, centre[None])[0] == pytest.approx(-0.015, abs=5e-4)
    outside = np.array([[0.0, 0.26, 1.0]])
    assert deviation(inspection.pipe, outside)[0] == pytest.approx(0.01, abs=5e-4)
    assert inspection.vertex_deviation.shape == (mesh.n_vertices,)
    assert np.nanmin(inspection.vertex_deviation) < -0.01  # the mesh shows the dent


def test_ovality_of_three_percent_is_measured_within_three_tenths_of_a_percent():
    sample = scan_damaged_pipe(ovality=0.03, ovality_clock=30.0, rotation_step=2.0, rng=2)
    inspection = inspect_pipe(_reconstructed(sample), sample.points)
    found = inspection.ovality
    inside = (found.axial > 0.2) & (found.axial < 1.8)
    assert abs(np.nanmedian(found.ovality[inside]) - 0.03) < 0.003
    clock = np.nanmedian(found.major_clock[inside])
    assert abs((clock - 30.0 + 90.0) % 180.0 - 90.0) < 5.0
    # ovality is not a defect: nothing as deep as the ovality's 3.75 mm
    assert all(abs(d.depth) < 3.75e-3 for d in inspection.defects.defects)


def test_elbow_dents_and_bulges_are_found_and_a_clean_elbow_has_none():
    defects = (Defect("dent", 1.0, 90.0, 0.008, 0.08), Defect("bulge", 0.3, 270.0, 0.01, 0.08))
    damaged = damaged_pipe(150_000, shape="elbow", noise=0.002, defects=defects, rng=3)
    inspection = inspect_pipe(_reconstructed(damaged), damaged.points)
    assert len(inspection.defects.defects) == 2
    for truth in damaged.truth_record["defects"]:
        found, axial, clock = _found(inspection, truth)
        assert found.kind == truth["kind"]
        # 2 mm: with 2 mm noise on 150k points a bump's depth scatters by about 0.8 mm
        assert abs(abs(found.depth) - truth["depth"]) < 2e-3
        assert abs(found.axial - truth["axial"]) < 0.03
        assert abs((found.clock - truth["clock"] + 180.0) % 360.0 - 180.0) < 15.0
    clean = damaged_pipe(150_000, shape="elbow", noise=0.002, rng=4)
    clean_inspection = inspect_pipe(_reconstructed(clean), clean.points)
    assert clean_inspection.defects.defects == ()
    assert abs(clean_inspection.pipe.length - (1.0 + 0.3 * np.pi)) < 0.03


def test_a_clean_elbow_scanned_along_its_centreline_has_no_defect():
    """The scan lines pile onto the outer wall of the bend, and the curvature jumps where the
    bend meets a leg: neither is a defect."""
    stations = tuple(0.25 * k for k in range(1, 8))  # along the 1.94 m centreline
    sample = scan_damaged_pipe(shape="elbow", stations=stations, rotation_step=2.0, rng=11)
    inspection = inspect_pipe(_reconstructed(sample), sample.points, viewpoints=sample.viewpoints)
    assert inspection.defects.defects == ()
    assert abs(inspection.pipe.radius - 0.25) < 5e-4
    record = sample.truth_record
    centreline = 2 * record["leg"] + record["bend_radius"] * np.pi / 2
    assert abs(inspection.pipe.length - centreline) < 0.03


def test_a_tee_reports_its_branch_and_no_defect_at_the_opening():
    sample = sample_tee(150_000, noise=0.002, rng=5)
    inspection = inspect_pipe(_reconstructed(sample), sample.points)
    assert inspection.defects.defects == ()
    (branch,) = inspection.defects.branches
    assert abs(branch.axial - 0.6) < 0.03  # the branch's axis meets the main one at z = 0.6
    # the branch leaves towards +x, which is 9 o'clock on a pipe running up z
    assert abs(branch.clock - 270.0) < 10.0


def test_the_centreline_follows_the_straight_run_of_a_tee(rng):
    # Axis points of a tee: a run 1.2 m along z, a branch 0.9 m along +x from its middle.
    # The path into the branch is the longer (1.5 m), but its ends lie 1.08 m apart against
    # the run's 1.2 m: the run is the pipe, the branch what leaves it.
    t = rng.uniform(0.0, 1.0, 6_000)
    run = np.column_stack([np.zeros_like(t), np.zeros_like(t), 1.2 * t])
    branch = np.column_stack([0.9 * t[:3_000], np.zeros(3_000), np.full(3_000, 0.6)])
    axis = np.concatenate([run, branch]) + rng.normal(scale=0.005, size=(9_000, 3))
    path = _straight_run(axis, radius=0.1)
    assert np.abs(path[:, 0]).max() < 0.05
    assert np.ptp(path[:, 2]) > 1.1


def test_a_mesh_far_from_the_origin_is_inspected_without_its_points():
    defects = (Defect("dent", 1.0, 90.0, 0.015, 0.08),)
    sample = damaged_pipe(40_000, noise=0.002, defects=defects, rng=6)
    shift = np.array([1000.0, 2000.0, 0.0])
    result = reconstruct(sample.points + shift, optimize=True, progress=False, seed=0)
    inspection = inspect_pipe(result.initial_mesh)
    assert inspection.point_deviation is None
    assert abs(inspection.pipe.radius - 0.25) < 1e-3
    (found,) = inspection.defects.defects
    assert found.kind == "dent" and abs(found.axial - 1.0) < 0.03
    assert abs(-found.depth - 0.015) < 3e-3
    # phase 2's few, large triangles still give the pipe (their facets are the noise)
    coarse = inspect_pipe(result.mesh)
    assert result.mesh.n_faces < result.initial_mesh.n_faces / 2
    assert abs(coarse.pipe.radius - 0.25) < 2e-3
    centres = coarse.pipe.position(np.linspace(0.1, 1.9, 20), 0.0, distance=0.0) - shift
    assert np.hypot(centres[:, 0], centres[:, 1]).max() < 2e-3


def test_nominal_diameter_and_threshold_are_used_as_given(dented_scan):
    sample, mesh, _ = dented_scan
    inspection = inspect_pipe(mesh, sample.points, nominal_diameter=0.51, threshold=0.008)
    assert inspection.pipe.radius == 0.255
    assert abs(inspection.pipe.measured_radius - 0.25) < 5e-4
    (deep,) = inspection.defects.defects  # the 15 mm dent only
    assert abs(-deep.depth - 0.015) < 1.5e-3
    assert inspection.defects.threshold == 0.008


def test_a_sphere_is_not_a_pipe():
    sample = sample_sphere(20_000, noise=0.001, rng=7)
    with pytest.raises(InputError, match="pipe"):
        fit_pipe(_reconstructed(sample))


def test_summary_is_json_and_matches_the_defects(dented_scan):
    _, _, inspection = dented_scan
    facts = json.loads(json.dumps(inspection_summary(inspection)))
    assert [d["depth"] for d in facts["defects"]] == [d.depth for d in inspection.defects.defects]
    assert facts["nominal_diameter"] == pytest.approx(0.5, abs=1e-3)
    assert facts["defects"][0]["clock_time"] == clock_label(inspection.defects.defects[0].clock)


def test_cli_inspect_writes_tables_pictures_and_report(tmp_path, dented_scan, capsys):
    sample, mesh, inspection = dented_scan
    mesh_path = io.write_mesh(tmp_path / "pipe.ply", mesh)
    points_path = io.write_points(tmp_path / "scan.ply", sample.points)
    out = tmp_path / "inspection"
    assert main(["inspect", str(mesh_path), str(points_path), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "2 beyond" in printed and "dent" in printed
    rows = (out / "defects.csv").read_text().splitlines()
    assert rows[0].startswith("number,kind,axial_m,clock_deg")
    assert len(rows) == 1 + len(inspection.defects.defects)
    facts = json.loads((out / "inspection.json").read_text())
    assert len(facts["defects"]) == 2
    for name in ("deviation-map.png", "ovality.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "data:image/png;base64," in (out / "report.html").read_text()
    # a second run needs --force and does not touch the files
    before = (out / "defects.csv").stat().st_mtime_ns
    assert main(["inspect", str(mesh_path), "-o", str(out)]) == 2
    assert "exists; add --force" in capsys.readouterr().err
    assert (out / "defects.csv").stat().st_mtime_ns == before


def test_cli_inspect_rejects_what_is_not_a_pipe(tmp_path, capsys):
    sphere = _reconstructed(sample_sphere(20_000, noise=0.001, rng=8))
    path = io.write_mesh(tmp_path / "ball.ply", Mesh(sphere.vertices, sphere.faces))
    assert main(["inspect", str(path), "-o", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and error[0].startswith(f"zeroset: error: {path}") and "pipe" in error[0]
    assert not (tmp_path / "out" / "defects.csv").exists()
