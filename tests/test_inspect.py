"""Pipe inspection: centreline, clock, deviation, ovality, defects and branches, measured
against the truth the damaged-pipe generators record."""

import csv
import json
import re
from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

from zeroset import io, reconstruct
from zeroset.cli import main
from zeroset.errors import InspectionError
from zeroset.inspect import (
    Joint,
    Unreliable,
    clock_label,
    deviation,
    deviation_map,
    find_defects,
    fit_pipe,
    inspect_pipe,
    inspection_lines,
    inspection_summary,
    ovality,
    unroll,
    write_defects_csv,
    write_joints_csv,
    write_ovality_csv,
)
from zeroset.inspect._bump import along_beams, bump, covariance, fit_along_beams, raised_cosine
from zeroset.inspect._centreline import (
    MAX_FIT_VERTICES,
    _evenly,
    _pipe_along,
    _radius_and_side,
    _straight_run,
    section_fits,
)
from zeroset.inspect._defects import _significance
from zeroset.inspect._files import length_agrees
from zeroset.inspect._pictures import (
    NOISE_BAND,
    TICK_GAP,
    colour_range,
    colour_ticks,
    deviation_norm,
    place_labels,
    stretch,
)
from zeroset.synthetic import (
    Defect,
    PipePath,
    damaged_pipe,
    pipe_run,
    sample_sphere,
    sample_tee,
    scan_damaged_pipe,
    scan_pipe_run,
)
from zeroset.synthetic import Joint as SyntheticJoint
from zeroset.types import Mesh

#: Dents of the issue: 5 and 15 mm deep, 6 cm wide, in a 0.5 m pipe.
DENTS = (Defect("dent", 0.7, 60.0, 0.005, 0.06), Defect("dent", 1.3, 200.0, 0.015, 0.06))
#: The robot stops every half metre of the 2 m pipe.
STATIONS = (0.5, 1.0, 1.5)


def _reconstructed(sample):
    """The phase-1 dense mesh of a sample (the one the CLI inspects), oriented by its
    viewpoints when it has them."""
    result = reconstruct(sample.points, viewpoints=sample.viewpoints, progress=False)
    return result.dense_mesh


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


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_clean_pipe_has_no_defect_and_no_ovality(clean_scan):
    sample, inspection = clean_scan
    assert inspection.defects.defects == ()
    assert inspection.defects.branches == ()
    assert np.nanmax(inspection.ovality.ovality) < 0.003
    # points' deviations are unbiased: the median is within 0.2 mm of the true wall
    assert abs(np.nanmedian(inspection.point_deviation)) < 2e-4


@pytest.mark.slow
def test_an_error_of_the_centreline_is_no_defect(clean_scan):
    """A centreline off its section's centre (as where a thin tail steered it) shifts
    every residual there by a wave round the wall; taken about the section, centre
    included, it leaves none."""
    sample, inspection = clean_scan
    pipe = inspection.pipe
    kink = 0.003 * np.exp(-0.5 * ((pipe.axial - 1.2) / 0.1) ** 2)  # metres, sideways
    bent = replace(pipe, centres=pipe.centres + kink[:, None] * [1.0, 0.0, 0.0])
    located = bent.locate(sample.points)
    sections = ovality(bent, sample.points, located=located)
    wall = unroll(bent, sections, sample.points, independent=True, located=located)
    found = find_defects(wall, bent, sections, sample.points, located=located)
    assert found.defects == ()
    stretch = np.abs(0.5 * (wall.axial_edges[1:] + wall.axial_edges[:-1]) - 1.2) < 0.1
    assert np.nanmax(np.abs(wall.residual[stretch])) < 0.0015  # metres: half the kink


@pytest.mark.slow
def test_threshold_comes_from_the_points_noise_not_from_real_geometry():
    """Ovality and dents are real geometry: they leave the points' noise about the local
    wall, and so the threshold, where they were (the wall map's dispersion would not)."""
    noise, found = 0.002, {}
    for name, damage in (("clean", {}), ("real", {"ovality": 0.03, "defects": DENTS})):
        sample = damaged_pipe(80_000, noise=noise, rng=3, **damage)
        inspection = inspect_pipe(sample.truth_mesh(0.01), sample.points)
        wall = inspection.wall
        defined = np.isfinite(wall.error)
        # isotropic noise of 2 mm per axis is 2 mm along the radius
        assert np.median(wall.noise[defined]) == pytest.approx(noise, rel=0.1)
        found[name] = inspection.defects
    assert found["real"].threshold == pytest.approx(found["clean"].threshold, rel=0.1)
    assert found["clean"].defects == ()
    assert len(found["real"].defects) == len(DENTS)
    assert "noise about the local wall" in found["real"].basis


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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_deviation_is_signed_inward_negative(dented_scan):
    sample, mesh, inspection = dented_scan
    truth = sample.truth_record["defects"][1]  # 15 mm
    centre = np.array(truth["centre"]) * (1 - 0.015 / 0.25)  # moved onto the dent's bottom
    assert deviation(inspection.pipe, centre[None])[0] == pytest.approx(-0.015, abs=5e-4)
    outside = np.array([[0.0, 0.26, 1.0]])
    assert deviation(inspection.pipe, outside)[0] == pytest.approx(0.01, abs=5e-4)
    assert inspection.vertex_deviation.shape == (mesh.n_vertices,)
    assert np.nanmin(inspection.vertex_deviation) < -0.01  # the mesh shows the dent


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_tee_reports_its_branch_and_no_defect_at_the_opening():
    sample = sample_tee(150_000, noise=0.002, rng=5)
    inspection = inspect_pipe(_reconstructed(sample), sample.points)
    assert inspection.defects.defects == ()
    (branch,) = inspection.defects.branches
    assert abs(branch.axial - 0.6) < 0.03  # the branch's axis meets the main one at z = 0.6
    # the branch leaves towards +x, which is 9 o'clock on a pipe running up z
    assert abs(branch.clock - 270.0) < 10.0


def test_the_run_passes_the_last_station_when_its_nearest_axis_cell_is_a_twig(rng):
    # Axis points of a run 2 m along z with a twig 8 cm long at z = 1.5 (a groove's
    # scatter); the robot's last station lies at the twig's tip. The run is the one that
    # passes by the station to the end beyond it, not the twig (it stopped there).
    t = rng.uniform(0.0, 1.0, 8_000)
    run = np.column_stack([np.zeros_like(t), np.zeros_like(t), 2.0 * t])
    twig = np.column_stack([0.08 * t[:400], np.zeros(400), np.full(400, 1.5)])
    axis = np.concatenate([run, twig]) + rng.normal(scale=0.003, size=(8_400, 3))
    stations = np.array([[0.0, 0.0, 0.3], [0.08, 0.0, 1.5]])
    path = _straight_run(axis, radius=0.1, stations=stations)
    assert path[-1, 2] > 1.9 and path[0, 2] < 0.1


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


@pytest.mark.parametrize("sides, rings", [(12, 3), (16, 3), (24, 5)])
def test_the_first_radius_holds_on_a_tube_of_long_triangles(sides, rings):
    # A prism of `sides` facets in `rings` - 1 bands of 1 or 0.5 m, as phase 2 leaves a
    # pipe: three triangles reach farther than the radius, where the pairs of samples no
    # longer lie in a tangent plane (the guess was 0.71 m on 16 facets).
    angle = np.arange(sides) * 2 * np.pi / sides
    z = np.linspace(0.0, 2.0, rings)
    t, h = np.meshgrid(angle, z, indexing="ij")
    vertices = np.stack([0.25 * np.cos(t), 0.25 * np.sin(t), h], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(sides), np.arange(rings - 1), indexing="ij")
    a, b = i * rings + j, (i + 1) % sides * rings + j
    faces = np.concatenate(
        [np.stack(c, -1).reshape(-1, 3) for c in ((a, b, b + 1), (a, b + 1, a + 1))]
    )
    radius, side = _radius_and_side(Mesh(vertices=vertices, faces=faces), np.random.default_rng(0))
    inscribed = 0.25 * np.cos(np.pi / sides)
    assert inscribed - 0.01 < radius < 0.25 + 0.01
    assert side == -1.0  # the facets' normals point away from the axis


@pytest.mark.slow
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


@pytest.mark.slow
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
    with pytest.raises(InspectionError, match="pipe"):
        fit_pipe(_reconstructed(sample))


@pytest.mark.slow
def test_summary_is_json_and_matches_the_defects(dented_scan):
    _, _, inspection = dented_scan
    facts = json.loads(json.dumps(inspection_summary(inspection)))
    assert [d["depth"] for d in facts["defects"]] == [d.depth for d in inspection.defects.defects]
    assert facts["nominal_diameter"] == pytest.approx(0.5, abs=1e-3)
    assert facts["defects"][0]["clock_time"] == clock_label(inspection.defects.defects[0].clock)


@pytest.mark.slow
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
    assert (out / "joints.csv").read_text().startswith("number,kind,axial_m,size_mm")
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


@pytest.mark.slow
def test_cli_inspect_writes_the_joints_and_shows_what_was_found(
    tmp_path, dented_scan, presented, monkeypatch, capsys
):
    import zeroset.inspect

    _, mesh, _ = dented_scan
    monkeypatch.setattr(zeroset.inspect, "inspect_pipe", lambda *args, **options: presented)
    mesh_path = io.write_mesh(tmp_path / "pipe.ply", mesh)
    out = tmp_path / "inspection"
    out.mkdir()
    (out / "joints.csv").write_text("")  # checked before any work, like every output
    assert main(["inspect", str(mesh_path), "-o", str(out)]) == 2
    assert "joints.csv: exists; add --force" in capsys.readouterr().err
    assert main(["inspect", str(mesh_path), "-o", str(out), "--force"]) == 0
    printed = capsys.readouterr().out
    assert "joints      3" in printed and "B31.8" in printed and "the data extend" in printed
    assert [r["kind"] for r in _rows(out / "joints.csv")] == ["gap", "offset", "bead"]
    facts = json.loads((out / "inspection.json").read_text())
    assert facts["joints"] == inspection_summary(presented)["joints"]
    assert facts["stations"]["count"] > 0 and facts["threshold_basis"]
    assert "joints.csv" in printed.splitlines()[-1]  # "inspection  written to ..."


@pytest.mark.slow
def test_cli_inspect_rejects_what_is_not_a_pipe(tmp_path, capsys):
    sphere = _reconstructed(sample_sphere(20_000, noise=0.001, rng=8))
    path = io.write_mesh(tmp_path / "ball.ply", Mesh(sphere.vertices, sphere.faces))
    assert main(["inspect", str(path), "-o", str(tmp_path / "out")]) == 3  # not bad input
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and error[0].startswith(f"zeroset: error: {path}") and "pipe" in error[0]
    assert not (tmp_path / "out" / "defects.csv").exists()


def test_reconstruct_writes_the_mesh_and_report_before_an_inspection_that_cannot_run(
    tmp_path, capsys
):
    points = io.write_points(tmp_path / "ball.ply", sample_sphere(8_000, noise=0.001, rng=8).points)
    mesh, report, out = tmp_path / "m.ply", tmp_path / "r.html", tmp_path / "out"
    argv = ["reconstruct", str(points), "-o", str(mesh), "--report", str(report), "--quiet"]
    assert main([*argv, "--inspect", str(out)]) == 3
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and error[0].startswith(f"zeroset: error: {points}")
    assert f"the mesh is written to {mesh}" in error[0] and "pipe" in error[0]
    ball = io.read_mesh(mesh)  # the whole sphere, as without --inspect
    assert abs(np.linalg.norm(ball.vertices, axis=1) - 1.0).max() < 0.01
    assert "zeroset-layers" in report.read_text(encoding="utf-8")
    assert not (out / "defects.csv").exists()


@pytest.fixture(scope="module")
def presented(dented_scan):
    """The dented scan's inspection with all the presentation shows: depths in % D (the
    deepest assessed), a joint of each kind, the data's extent, an unreliable stretch and
    the threshold's basis."""
    _, _, inspection = dented_scan
    deepest, *others = inspection.defects.defects
    defects = replace(
        inspection.defects,
        defects=(
            replace(deepest, depth_percent=6.4, assess=True),
            *(replace(d, depth_percent=2.1, assess=False) for d in others),
        ),
        basis="4.9 standard errors of a cell's mean, 0.30 mm: 1.47 mm",
    )
    joints = (
        Joint("gap", 0.4, 0.012, 0.001, depth=0.003),
        Joint("offset", 1.0, 0.004, 0.0005, clock=90.0),
        Joint("bead", 1.6, 0.002, 0.0003),
    )
    pipe = replace(
        inspection.pipe,
        extent=inspection.pipe.length + 0.01,
        unreliable=(Unreliable(0.9, 1.1, "the sections are not ellipses"),),
    )
    return replace(inspection, pipe=pipe, defects=defects, joints=joints)


def _rows(path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.slow
def test_ovality_table_has_the_mean_diameter_and_the_unreliable_stretches(tmp_path, presented):
    rows = _rows(write_ovality_csv(tmp_path / "ovality.csv", presented))
    assert list(rows[0]) == [
        "axial_m", "ovality_percent", "d_max_mm", "d_mean_mm", "d_min_mm", "major_clock_deg",
        "unreliable",
    ]  # fmt: skip
    found = presented.ovality
    fitted = np.isfinite(found.ovality)
    assert len(rows) == np.count_nonzero(fitted)
    for name, metres in (("d_max_mm", found.d_max), ("d_mean_mm", found.d_mean),
                         ("d_min_mm", found.d_min)):  # fmt: skip
        np.testing.assert_allclose([float(r[name]) for r in rows], 1000 * metres[fitted], atol=1e-3)
    assert all(float(r["d_min_mm"]) < float(r["d_mean_mm"]) < float(r["d_max_mm"]) for r in rows)
    (stretch_,) = presented.pipe.unreliable
    axial = found.axial[fitted]
    inside = (axial >= stretch_.axial_start) & (axial <= stretch_.axial_end)
    assert 0 < np.count_nonzero(inside) < inside.size
    assert [r["unreliable"] for r in rows] == [stretch_.reason if i else "" for i in inside]


@pytest.mark.slow
def test_summary_gives_diameters_and_ovality_over_the_stations(presented):
    stations = inspection_summary(presented)["stations"]
    found = presented.ovality
    fitted = np.isfinite(found.ovality)
    assert stations["count"] == np.count_nonzero(fitted) > 0
    figures = {
        "d_min_mm": 1000 * found.d_min,
        "d_mean_mm": 1000 * found.d_mean,
        "d_max_mm": 1000 * found.d_max,
        # ASTM F3095, CSA Z662: (D_max - D_min) / D_nominal
        "ovality_percent": 100 * (found.d_max - found.d_min) / (2 * presented.pipe.radius),
    }
    for name, values in figures.items():
        values = values[fitted]
        assert stations[name] == pytest.approx(
            {"min": values.min(), "median": np.median(values), "max": values.max()}, rel=1e-9
        )


@pytest.mark.slow
def test_defects_give_their_depth_in_percent_and_b31_8_marks_those_to_assess(tmp_path, presented):
    defects = presented.defects.defects
    rows = _rows(write_defects_csv(tmp_path / "defects.csv", presented))
    assert [r["depth_percent"] for r in rows] == ["6.4"] + ["2.1"] * (len(defects) - 1)
    assert [r["assess"] for r in rows] == ["yes"] + [""] * (len(defects) - 1)
    written = inspection_summary(presented)["defects"]
    assert written[0]["depth_mm"] == pytest.approx(1000 * defects[0].depth)
    assert (written[0]["depth_percent"], written[0]["assess"]) == (6.4, True)
    lines = inspection_lines(presented)
    (marked,) = [line for line in lines if "B31.8" in line]
    assert marked.split()[0] == "1" and "(6.4 % D)" in marked and "> 6 % D, assess" in marked
    # not measured: an empty cell and no percent printed
    unmeasured = replace(
        presented,
        defects=replace(
            presented.defects, defects=(replace(defects[0], depth_percent=np.nan, assess=False),)
        ),
    )
    assert _rows(write_defects_csv(tmp_path / "bare.csv", unmeasured))[0]["depth_percent"] == ""
    assert not any("% D" in line for line in inspection_lines(unmeasured))


@pytest.mark.slow
def test_joints_are_tabled_summarised_and_printed_one_line_each(tmp_path, presented):
    rows = _rows(write_joints_csv(tmp_path / "joints.csv", presented))
    columns = ["number", "kind", "axial_m", "size_mm", "uncertainty_mm", "clock_deg", "clock",
               "depth_mm"]  # fmt: skip
    assert list(rows[0]) == columns
    assert [r["kind"] for r in rows] == ["gap", "offset", "bead"]
    assert (rows[1]["clock"], rows[1]["clock_deg"], rows[1]["depth_mm"]) == ("3:00", "90.0", "")
    gap, offset, bead = inspection_summary(presented)["joints"]
    assert gap == {
        "number": 1, "kind": "gap", "axial_m": 0.4, "size_mm": 12.0, "uncertainty_mm": 1.0,
        "clock_deg": None, "clock": None, "depth_mm": 3.0,
    }  # fmt: skip
    assert (offset["clock"], offset["clock_deg"], offset["depth_mm"]) == ("3:00", 90.0, None)
    assert (bead["size_mm"], bead["clock"], bead["depth_mm"]) == (2.0, None, None)
    lines = inspection_lines(presented)
    printed = [line.split()[:2] for line in lines[lines.index("joints      3") + 1 :][:3]]
    assert printed == [["1", "gap"], ["2", "offset"], ["3", "bead"]]
    assert any("offset at 1.000 m: 4.0 +- 0.5 mm step towards 3:00" in line for line in lines)


@pytest.mark.slow
def test_threshold_basis_and_the_centreline_check_are_shown(presented):
    facts = inspection_summary(presented)
    assert facts["threshold_mm"] == pytest.approx(1000 * facts["threshold"])
    assert facts["threshold_basis"] == presented.defects.basis
    pipe = presented.pipe
    assert (facts["extent"], facts["length_agrees"]) == (pipe.extent, True)
    assert facts["unreliable"] == [
        {"axial_start": 0.9, "axial_end": 1.1, "reason": "the sections are not ellipses"}
    ]
    text = "\n".join(inspection_lines(presented))
    assert f"beyond {facts['threshold_mm']:.2f} mm" in text and presented.defects.basis in text
    assert f"fitted {pipe.length:.2f} m; the data extend {pipe.extent:.2f} m" in text
    assert "0.900-1.100 m: the sections are not ellipses" in text and "(!)" not in text
    # 2 m: 2 % (4 cm) is less than a diameter; 40 m: a diameter (0.5 m) is less than 2 %
    for length, extent, agrees in ((2.0, 2.03, True), (2.0, 2.05, False), (40.0, 40.4, True),
                                   (40.0, 40.6, False), (2.0, np.nan, None)):  # fmt: skip
        assert length_agrees(replace(pipe, length=length, extent=extent)) is agrees
    far = replace(presented, pipe=replace(pipe, extent=pipe.length + 0.1))
    assert "(!) they differ by 0.10 m" in "\n".join(inspection_lines(far))
    unknown = replace(presented, pipe=replace(pipe, extent=np.nan))
    assert inspection_summary(unknown)["extent"] is None
    assert "the data's extent not measured" in "\n".join(inspection_lines(unknown))


@pytest.mark.slow
def test_colour_scale_is_pale_within_the_threshold_and_deepest_at_the_deepest_defect(presented):
    threshold, limit = colour_range(presented)
    assert threshold == presented.defects.threshold
    assert limit == pytest.approx(max(abs(d.depth) for d in presented.defects.defects))
    norm = deviation_norm(1.5, 20.0)  # mm
    assert norm(0.0) == pytest.approx(0.5)
    assert (norm(-1.5), norm(1.5)) == pytest.approx((0.5 - NOISE_BAND / 2, 0.5 + NOISE_BAND / 2))
    assert (norm(-20.0), norm(20.0)) == pytest.approx((0.0, 1.0))
    # logarithmic beyond the threshold: each factor of 2 takes the same share of the colours
    assert norm(12.0) - norm(6.0) == pytest.approx(norm(6.0) - norm(3.0))
    values = np.linspace(-30.0, 30.0, 601)
    assert np.all(np.diff(norm(values)) > 0)
    np.testing.assert_allclose(norm.inverse(norm(values)), values, atol=1e-9)
    ticks = colour_ticks(1.5, 20.0)
    np.testing.assert_array_equal(ticks, -ticks[::-1])
    assert set(ticks[ticks >= 0]) - {0.0, 1.5, 20.0} <= {2.0, 5.0, 10.0}  # 1, 2, 5 between
    assert {0.0, 1.5, 20.0} <= set(ticks)
    assert np.diff(stretch(ticks, 1.5, 20.0)).min() >= TICK_GAP


def _overlapping(boxes, others, gap=0.0) -> np.ndarray:
    """(K, M) whether each of `boxes` comes within `gap` of each of `others` (x0, y0, x1, y1)."""
    return (
        (boxes[:, None, 0] < others[None, :, 2] + gap)
        & (others[None, :, 0] < boxes[:, None, 2] + gap)
        & (boxes[:, None, 1] < others[None, :, 3] + gap)
        & (others[None, :, 1] < boxes[:, None, 3] + gap)
    )


def test_labels_go_beside_their_regions_clear_of_every_region_and_label(rng):
    bounds = np.array([0.0, 0.0, 1000.0, 400.0])  # pixels of the map
    corner = rng.uniform([40.0, 30.0], [900.0, 330.0], size=(12, 2))
    regions = np.hstack([corner, corner + rng.uniform(10.0, 60.0, size=(12, 2))])
    anchors = corner + rng.uniform(0.2, 0.8, size=(12, 2)) * (regions[:, 2:] - corner)
    sizes = np.tile([90.0, 14.0], (12, 1))
    gap = 3.0
    centres = place_labels(anchors, sizes, regions, bounds, gap=gap)
    boxes = np.hstack([centres - 0.5 * sizes, centres + 0.5 * sizes])
    assert not _overlapping(boxes, regions, gap - 1e-9).any()
    apart = _overlapping(boxes, boxes, gap - 1e-9)
    assert not apart[~np.eye(12, dtype=bool)].any()
    assert np.all(boxes[:, :2] >= bounds[:2]) and np.all(boxes[:, 2:] <= bounds[2:])
    assert np.linalg.norm(centres - anchors, axis=1).max() < 200.0  # beside, not anywhere
    # nowhere free: the place covering least, still inside the bounds
    (centre,) = place_labels([[50.0, 50.0]], [[20.0, 10.0]], [bounds], bounds)
    assert np.all(centre - 5.0 >= bounds[:2]) and np.all(centre + 5.0 <= bounds[2:])


@pytest.mark.slow
def test_deviation_map_draws_with_joints_stretches_and_labels_and_without(presented):
    from io import BytesIO

    from PIL import Image

    bare = replace(
        presented,
        joints=(),
        pipe=replace(presented.pipe, unreliable=()),
        defects=replace(presented.defects, defects=(), branches=()),
    )
    for inspection in (presented, bare):
        with Image.open(BytesIO(deviation_map(inspection))) as image:
            assert image.format == "PNG" and image.size == (1210, 506)


#: A straight run 3 m along +x with one joint of each kind, 0.4 m in diameter.
JOINTS = (
    SyntheticJoint("gap", 0.8, 0.012, depth=0.006),
    SyntheticJoint("offset", 1.6, 0.008, clock=90.0),
    SyntheticJoint("bead", 2.3, 0.004),
)


@pytest.fixture(scope="module")
def jointed_run():
    """Uniform samples of a straight run with joints and 3 % ovality, inspected on its true
    wall, and the same run without either."""
    path = PipePath.build([("straight", 3.0)])
    found = {}
    for name, extra in (("plain", {}), ("jointed", {"joints": JOINTS, "ovality": 0.03})):
        sample = pipe_run(path, 120_000, noise=0.002, rng=11, **extra)
        found[name] = sample, inspect_pipe(sample.truth_mesh(0.01), sample.points)
    return found


@pytest.mark.slow
def test_joints_are_found_where_and_as_big_as_they_are(jointed_run):
    sample, inspection = jointed_run["jointed"]
    truth = sample.truth_record["joints"]
    assert len(inspection.joints) == len(truth)
    for joint, found in zip(truth, inspection.joints, strict=True):
        axial = inspection.pipe.locate(np.array([joint["centre"]]))[0][0]
        assert found.kind == joint["kind"]
        assert abs(found.axial - axial) < 0.02  # metres
        assert abs(found.size - joint["size"]) < 0.0015
    offset = next(j for j in inspection.joints if j.kind == "offset")
    assert abs((offset.clock - 90.0 + 180.0) % 360.0 - 180.0) < 10.0
    assert jointed_run["plain"][1].joints == ()


@pytest.mark.slow
def test_joints_and_ovality_are_no_defects_and_leave_the_threshold(jointed_run):
    plain, jointed = jointed_run["plain"][1], jointed_run["jointed"][1]
    assert plain.defects.defects == () and jointed.defects.defects == ()
    assert jointed.defects.threshold == pytest.approx(plain.defects.threshold, rel=0.1)
    stations = np.isfinite(jointed.ovality.ovality)
    assert np.median(jointed.ovality.ovality[stations]) == pytest.approx(0.03, abs=0.003)


@pytest.mark.parametrize(
    "joint, stations, seed",
    [
        # Range noise along oblique beams smears a bead over centimetres: three rings'
        # mean reads this 3 mm bead below the threshold.
        (SyntheticJoint("bead", 1.25, 0.003), (0.6, 1.9), 3),
        # Seen 25 cm off, a recess' far edge hides most of its floor: the rings' means
        # read this 18 mm gap as no recess at all.
        (SyntheticJoint("gap", 1.3, 0.018, depth=0.006), (0.6, 1.55), 4),
    ],
    ids=["bead", "gap"],
)
@pytest.mark.slow
def test_a_scanned_ring_feature_is_fitted_along_the_beams(joint, stations, seed):
    path = PipePath.build([("straight", 2.5)])
    sample = scan_pipe_run(path, stations=stations, rotation_step=4.0, joints=(joint,), rng=seed)
    inspection = inspect_pipe(_reconstructed(sample), sample.points, viewpoints=sample.viewpoints)
    (found,) = inspection.joints
    axial = inspection.pipe.locate(np.array([sample.truth_record["joints"][0]["centre"]]))[0][0]
    assert found.kind == joint.kind and abs(found.axial - axial) < 0.02  # metres
    assert abs(found.size - joint.size) < 0.0015
    assert inspection.defects.defects == ()


@pytest.fixture(scope="module")
def bent_run():
    """A scanned run with two tight bends and a last leg of one diameter, the second bend
    far from the last station: the run whose centreline used to be cut short."""
    path = PipePath.build(
        [
            ("straight", 2.0),
            ("bend", 0.4, 90.0, 90.0),
            ("straight", 1.5),
            ("bend", 0.4, 90.0, 270.0),
            ("straight", 0.4),
        ]  # fmt: skip
    )
    sample = scan_pipe_run(path, stations=(0.4, 1.4, 2.6, 3.6), rotation_step=6.0, rng=2)
    inspection = inspect_pipe(_reconstructed(sample), sample.points, viewpoints=sample.viewpoints)
    return sample, inspection


@pytest.mark.slow
def test_the_centreline_follows_bends_and_runs_the_way_the_robot_went(bent_run):
    sample, inspection = bent_run
    truth = np.array(sample.truth_record["centreline"])
    stations = sample.truth_record["stations"]
    between = truth[(truth[:, 0] >= stations[0]) & (truth[:, 0] <= stations[-1]), 1:]
    gaps = cKDTree(inspection.pipe.centres).query(between)[0]
    assert gaps.max() < 0.005  # metres, between the first and the last station
    # axial positions count from where the robot started, along its way
    first = inspection.pipe.locate(np.array([truth[truth[:, 0] > stations[0]][0, 1:]]))
    assert first[0][0] == pytest.approx(stations[0], abs=0.05)
    assert inspection.pipe.length == pytest.approx(inspection.pipe.extent, rel=0.02)
    assert inspection.defects.defects == () and inspection.joints == ()


def test_a_large_scan_is_fitted_on_points_chosen_evenly_over_the_wall(rng):
    """A scan far denser near its stations keeps every point of its thin tail and of the
    sector its scan lines leave sparse, where a random choice would keep a third."""
    dense, tail, sparse = 300_000, 600, 3_000
    axial = np.r_[rng.uniform(0.0, 2.0, dense + sparse), rng.uniform(2.0, 2.3, tail)]
    clock = np.r_[rng.uniform(22.5, 360.0, dense), rng.uniform(0.0, 22.5, sparse + tail)]
    axial[:10] = np.nan  # beyond the centreline
    chosen = _evenly((axial, clock, np.full(axial.size, 0.2)), 0.02, rng)
    assert chosen.size <= MAX_FIT_VERTICES and np.all(np.diff(chosen) > 0)
    assert np.isin(np.arange(dense, dense + sparse + tail), chosen).all()
    known = chosen[np.isfinite(axial[chosen])]
    cells = np.floor(axial[known] / 0.02) * 16 + clock[known] // 22.5
    per_cell = np.unique(cells, return_counts=True)[1]
    assert per_cell.max() <= 2 * np.median(per_cell)  # the dense cells all hold the same


def test_a_station_seen_on_a_quarter_of_its_circle_is_centred_on_the_radius_around(rng):
    """A scan's thin tail shows an arc of its wall: too little for a circle of its own,
    enough for the centre of one with the radius of the complete sections before it."""
    radius, shift = 0.2, np.array([0.0015, -0.001, 0.0])  # the axis moves 1.8 mm at z = 0.6
    pipe = _pipe_along(np.c_[np.zeros(51), np.zeros(51), np.linspace(0, 1, 51)], radius,
                       radius, (0.0, 1.0, 0.0), margin=0.0)  # fmt: skip
    z = rng.uniform(0.0, 1.0, 60_000)
    angle = rng.uniform(0.0, 2 * np.pi, z.size)
    seen = (z < 0.6) | (angle < np.radians(100.0))  # beyond 0.6 m, 100 degrees of wall
    z, angle = z[seen], angle[seen]
    wall = radius + rng.normal(0.0, 5e-4, z.size)
    points = np.c_[wall * np.cos(angle), wall * np.sin(angle), z] + (z >= 0.6)[:, None] * shift
    fits = section_fits(pipe, pipe.locate(points))
    tail = fits["axial"] > 0.62
    assert fits["arc"][tail].all() and not fits["arc"][fits["axial"] < 0.58].any()
    centre, tangent, up = pipe._at(fits["axial"][tail])
    right = np.cross(tangent, up)
    moved = centre + fits["circle"][tail, 1:2] * up + fits["circle"][tail, 2:3] * right
    assert np.abs(moved - (centre + shift)).max() < 5e-4  # metres


def test_a_bump_is_met_along_each_beam_where_the_beam_first_reaches_it(rng):
    """At grazing incidence a beam can cross a bulge's pocket twice: the range the scanner
    measured is the first crossing, so the misfit of a sample moved by e along its beam
    is -e, wherever the beam meets the bump."""
    q = np.array([0.0, 0.012, 0.0, 0.0, np.log(0.025), np.log(0.025)])  # 12 mm, 5 cm wide
    n = 400
    slope = np.radians(rng.uniform(15.0, 60.0, n))  # between the beam and the wall
    turn = rng.uniform(-0.3, 0.3, n)
    steps = np.stack([np.cos(slope) * np.cos(turn), np.cos(slope) * np.sin(turn), np.sin(slope)])
    start = rng.uniform(-0.06, 0.02, n)  # where each beam would meet the unbumped wall
    # each beam marched from inside the bore in steps of 0.01 mm to its first hit
    t = np.arange(-0.1, 0.1, 1e-5)[:, None]
    a, b, height = start + t * steps[0], t * steps[1], t * steps[2]
    beyond = height >= q[1] * raised_cosine(q, a, b)
    first = np.argmax(beyond, axis=0)
    hit_a, hit_b, hit_r = (x[first, np.arange(n)] for x in (a, b, height))
    noise = rng.normal(0.0, 0.004, n)
    misfit = along_beams(
        bump(q),
        hit_a + noise * steps[0],
        hit_b + noise * steps[1],
        hit_r + noise * steps[2],
        steps,
        0.03,
    )
    assert np.abs(misfit + noise).max() < 5e-5  # metres
    inside = np.abs(hit_a) < 0.025
    assert np.count_nonzero(inside) > 50  # beams that met the pocket, far flank included


@pytest.mark.slow
def test_a_bulge_seen_at_grazing_incidence_is_fitted_to_its_depth_within_its_error(rng):
    """Beams from afar graze a bulge's near rim, and their first hits jump to the far flank
    as the fit moves the rim: 30 scans of an 8 mm bulge 6 cm wide, each beam rising 1 in
    5 from the wall, read 8 mm on average, inside their 95 % interval 8 times in 10 or
    more. (A least-squares or soft L1 fit, caught on those jumps, read 7.5 mm and held it
    in its interval 7 times in 10.)"""
    depth, half, noise = 0.008, 0.03, 0.005
    ring = np.log(1e3)  # all round: the bump changes along the pipe only

    def model(q):
        return bump(np.array([q[0], q[1], q[2], 0.0, q[3], ring]))

    wall, slope = model([0.0, depth, 0.0, np.log(half)]), 0.2
    t = np.linspace(-0.3, 0.3, 30_001)[:, None]  # beams marched in 0.02 mm steps
    read, inside = [], 0
    for _ in range(30):
        n = 400
        along = np.where(rng.random(n) < 0.5, 1.0, -1.0) * np.sqrt(1 - slope**2)
        steps = np.stack([along, np.zeros(n), np.full(n, slope)])
        start = rng.uniform(-0.08, 0.08, n)  # where each beam meets the unbumped wall
        beyond = t * slope >= wall(start + t * along, 0.0)
        met = beyond.any(axis=0)
        hit = t[np.argmax(beyond, axis=0), 0] + rng.normal(0.0, noise, n)
        a, values, steps = (start + hit * along)[met], (hit * slope)[met], steps[:, met]
        b = np.zeros(a.size)
        found = fit_along_beams(
            model, [0.0, 0.7 * depth, 0.0, np.log(1.3 * half)], a, b, values, steps
        )
        spread = covariance(found)
        read.append(found.x[0] + found.x[1])
        error = np.sqrt(spread[0, 0] + spread[1, 1] + 2 * spread[0, 1])
        inside += abs(read[-1] - depth) <= 1.96 * error
    assert abs(np.mean(read) - depth) < 3e-4  # metres
    assert inside >= 24


def test_only_the_data_leave_a_stretch_not_judged_and_it_says_how_much_they_cover():
    # A straight pipe whose points over 0.6 m (more than two radii) keep only a quarter
    # of the circle: that stretch is not judged, with the coverage its points show; the
    # rest, a 6 mm dent included, is.
    defects = (Defect("dent", 0.5, 90.0, 0.006, 0.08),)
    sample = damaged_pipe(60_000, noise=0.001, defects=defects, rng=4)
    points = sample.points
    angle = np.degrees(np.arctan2(points[:, 1], points[:, 0])) % 360.0
    shadow = (points[:, 2] > 1.1) & (points[:, 2] < 1.7) & (angle > 90.0)
    inspection = inspect_pipe(sample.truth_mesh(0.01), points[~shadow])
    (stretch,) = inspection.pipe.unreliable
    assert 1.0 < stretch.axial_start < 1.2 and 1.6 < stretch.axial_end < 1.8
    assert re.search(r"cover [3-5] of 16 sectors", stretch.reason)
    (dent,) = inspection.defects.defects
    assert abs(dent.axial - 0.5) < 0.01 and abs(-dent.depth - 0.006) < 1e-3


@pytest.mark.slow
def test_a_stretch_whose_wall_is_no_circle_is_reported_not_hidden():
    # A section crushed square over 0.2 m (corners 75 mm out, sides 20 mm in): its
    # stations' ellipses leave residuals of centimetres. Only the data may leave a
    # stretch not judged; the crushed wall is reported where it is.
    sample = damaged_pipe(60_000, noise=0.002, rng=8)
    points = sample.points.copy()
    crushed = (points[:, 2] > 0.9) & (points[:, 2] < 1.1)  # a square section there
    angle = np.arctan2(points[crushed, 1], points[crushed, 0])
    square = 0.25 / np.maximum(np.abs(np.cos(angle)), np.abs(np.sin(angle)))
    points[crushed, :2] *= (square / np.hypot(*points[crushed, :2].T))[:, None] * 0.92
    inspection = inspect_pipe(sample.truth_mesh(0.01), points)
    assert inspection.pipe.unreliable == ()
    found = inspection.defects.defects
    assert found and all(0.85 < d.axial_start and d.axial_end < 1.15 for d in found)
    corners = {round(d.clock / 90 - 0.5) % 4 for d in found if d.kind == "bulge" and
               abs((d.clock - 45) % 90 - 45) > 35 and d.depth > 0.04}  # fmt: skip
    sides = {round(d.clock / 90) % 4 for d in found if d.kind == "dent" and
             abs((d.clock + 45) % 90 - 45) < 10 and d.depth < -0.015}  # fmt: skip
    assert corners == {0, 1, 2, 3} and len(sides) >= 3
