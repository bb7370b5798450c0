import json
import re

import numpy as np
import pytest

from zeroset import io, topology
from zeroset.cli import main
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_torus, scan_pipe
from zeroset.within import two_sided_errors


@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("in") / "sphere.ply"
    io.write_points(path, sample_sphere(4000, noise=0.005, rng=0).points)
    return path


def test_reconstruct_writes_mesh_report_and_preview(sphere_file, tmp_path, capsys):
    out = tmp_path / "mesh.obj"
    code = main(
        [
            "reconstruct",
            str(sphere_file),
            "-o",
            str(out),
            "--report",
            str(tmp_path / "r.json"),
            "--preview",
            str(tmp_path / "p.png"),
            "--seed",
            "3",
        ]
    )
    assert code == 0
    mesh = io.read_mesh(out)
    assert topology.euler_characteristic(mesh) == 2
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["stats"]["faces"] == mesh.n_faces
    assert report["config"]["seed"] == 3
    assert report["fit"]["coverage"] > 0.95 and report["fit"]["distance"]["mean"] < 0.01
    assert set(report["timings"]) >= {"tangent planes", "orientation", "contour"}
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    assert "rho_delta" in printed and "boundary loop" in printed and "seconds" in printed


def test_tolerance_chooses_between_the_dense_and_the_simplified_mesh(sphere_file, tmp_path, capsys):
    dense, simple = tmp_path / "dense.ply", tmp_path / "simple.ply"
    assert main(["reconstruct", str(sphere_file), "-o", str(dense), "--tolerance", "0"]) == 0
    assert "\nsimplify " not in capsys.readouterr().out
    assert main(["reconstruct", str(sphere_file), "-o", str(simple), "--report",
                 str(tmp_path / "r.json")]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    report = json.loads((tmp_path / "r.json").read_text())
    dense_mesh, simple_mesh = io.read_mesh(dense), io.read_mesh(simple)
    assert simple_mesh.n_faces < dense_mesh.n_faces == report["stats"]["dense_faces"]
    assert "\nsimplify " in printed and "uncertainty" in report["stats"]["tolerance_note"]
    assert topology.euler_characteristic(simple_mesh) == 2
    bad = tmp_path / "bad.ply"
    assert main(["reconstruct", str(sphere_file), "-o", str(bad), "--tolerance", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("zeroset: error: ") and "tolerance must be" in err
    assert err.count("\n") == 1
    assert not bad.exists()


def test_options_reach_the_pipeline(sphere_file, tmp_path):
    out = tmp_path / "mesh.ply"
    code = main(
        [
            "reconstruct",
            str(sphere_file),
            "-o",
            str(out),
            "--rho-delta",
            "0.2",
            "--cube-size",
            "0.12",
            "--sample",
            "0.5",
            "--report",
            str(tmp_path / "r.json"),
            "--quiet",
        ]
    )
    assert code == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["parameters"]["rho_delta"] == 0.2
    assert report["parameters"]["cube_size"] == 0.12
    # Sampled while reading: each of the 4000 points kept with probability 0.5.
    reading = report["reading"]
    assert reading["input_points"] == 4000 and abs(reading["sampled_out"] - 2000) < 150
    assert report["stats"]["input_points"] == 4000 - reading["sampled_out"]
    assert "read" in report["timings"] and report["peak_mib"] > 0


@pytest.mark.parametrize("flag, bridges", [("--gap-bridges", True), ("--no-gap-bridges", False)])
@pytest.mark.slow
def test_gap_bridges_flag_reaches_the_pipeline(flag, bridges, tmp_path):
    path = tmp_path / "scan.ply"
    io.write_points(path, scan_pipe(radius=0.1, rotation_step=1.0, rng=3).points)
    report = tmp_path / "r.json"
    argv = ["reconstruct", str(path), "-o", str(tmp_path / "m.ply"), flag, "--quiet"]
    assert main([*argv, "--report", str(report)]) == 0
    stats = json.loads(report.read_text())["stats"]
    assert (stats["gap_bridge_points"] > 0) == bridges


def test_viewpoint_option_orients_towards_the_sensor(tmp_path):
    path = tmp_path / "pipe.xyz"
    io.write_points(path, sample_cylinder(6000, noise=0.002, rng=1).points)
    assert (
        main(
            [
                "reconstruct",
                str(path),
                "-o",
                str(tmp_path / "m.ply"),
                "--viewpoint",
                "0,0,0.5",
                "--quiet",
            ]
        )
        == 0
    )
    mesh = io.read_mesh(tmp_path / "m.ply")
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    # Seen from the axis, the faces look inwards.
    assert np.mean(np.einsum("ij,ij->i", normals[:, :2], tri.mean(axis=1)[:, :2]) < 0) > 0.99


@pytest.mark.parametrize("quiet", [False, True])
@pytest.mark.slow
def test_surface_warnings_print_one_line_each(quiet, tmp_path, capsys):
    path = tmp_path / "torus.xyz"
    io.write_points(path, sample_torus(20_000, major=0.42, minor=0.13, noise=0.002, rng=0).points)
    argv = ["reconstruct", str(path), "-o", str(tmp_path / "m.ply"), "--viewpoint", "0,0,0"]
    assert main(argv + (["--quiet"] if quiet else [])) == 0
    err = capsys.readouterr().err
    if quiet:
        assert err == ""
    else:
        lines = [line for line in err.splitlines() if "spanning tree disagree" in line]
        assert len(lines) == 1 and lines[0].startswith("zeroset: warning: the sensor positions")
        assert "Warning" not in err  # no Python warning text beside the line


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "no such file"),
        ("", "no points"),
        ("0 0 0\n1 1 nan\n" + "1 2 3\n" * 40, "non-finite"),
        ("".join(f"{t} {2 * t} {3 * t}\n" for t in range(100)), "collinear"),
        ("0 0 0\n1 0 0\n0 1 0\n", "at least"),
    ],
)
def test_bad_input_exits_2_with_one_line(content, message, tmp_path, capsys):
    path = tmp_path / "scan.xyz"
    if content is not None:
        path.write_text(content)
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "m.ply")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("zeroset: error: ") and message in err
    assert err.count("\n") == 1
    assert not (tmp_path / "m.ply").exists()


def test_unknown_output_format_exits_2(sphere_file, tmp_path, capsys):
    assert main(["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.xyz")]) == 2
    assert "unknown mesh format" in capsys.readouterr().err


def test_no_surface_exits_1(sphere_file, tmp_path, capsys):
    assert (
        main(
            ["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply"), "--rho-delta", "1e-5"]
        )
        == 1
    )
    assert "rho_delta" in capsys.readouterr().err


@pytest.mark.parametrize(
    "args, old, new",
    [
        (["reconstruct", "in.ply", "-o", "m.ply", "--radius", "0.1"], "--radius", "--rho-delta"),
        (["reconstruct", "in.ply", "--threshold=5"], "--threshold", "--threshold-mm"),
        (["inspect", "m.ply", "-o", "out", "--threshold", "5"], "--threshold", "--threshold-mm"),
        (["evaluate", "m.ply", "--points", "in.ply"], "--points", "--scan"),
    ],
)
def test_a_renamed_option_names_its_new_name(args, old, new, capsys):
    assert main(args) == 2
    assert capsys.readouterr().err == f"zeroset: error: {old} is now {new}\n"


def test_options_are_not_abbreviated(sphere_file, tmp_path, capsys):
    # "--quant" would otherwise be taken for --quantile, and "--radius" for --radius-k.
    with pytest.raises(SystemExit) as exit_info:
        main(["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply"), "--quant", "0.5"])
    assert exit_info.value.code == 2
    assert "unrecognized arguments: --quant" in capsys.readouterr().err


def test_version_prints_the_package_version(capsys):
    from zeroset import __version__

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"zeroset {__version__}"


@pytest.mark.parametrize("error", [ValueError, TypeError, IndexError])
def test_a_library_bug_is_an_internal_error_not_bad_input(
    error, sphere_file, tmp_path, capsys, monkeypatch
):
    from zeroset import pipeline

    def broken(*args, **kwargs):
        raise error("index 7 is out of bounds for axis 0 with size 3")

    monkeypatch.setattr(pipeline, "reconstruct", broken)
    assert main(["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply")]) == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"zeroset: error: internal error, please report it: {error.__name__}")
    assert not (tmp_path / "m.ply").exists()


def test_a_bad_option_of_the_library_is_bad_input(sphere_file, tmp_path, capsys):
    code = main(["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply"), "--k-max", "3"])
    assert code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("zeroset: error: ") and "k_max must exceed" in line


def test_reports_without_a_peak_memory_where_the_platform_gives_none(
    sphere_file, tmp_path, monkeypatch
):
    from zeroset import _progress

    monkeypatch.setattr(_progress, "resource", None)  # as on Windows
    report = tmp_path / "r.json"
    args = ["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply"), "--report"]
    assert main([*args, str(report), "--quiet"]) == 0
    assert "peak_mib" not in json.loads(report.read_text())


def test_bad_option_value_is_an_argparse_error(sphere_file, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        main(["reconstruct", str(sphere_file), "-o", str(tmp_path / "m.ply"), "--viewpoint", "1,2"])
    assert exit_info.value.code == 2


def test_contour_option_chooses_the_method_of_cubes(sphere_file, tmp_path, capsys):
    out = tmp_path / "mesh.ply"
    assert main(["reconstruct", str(sphere_file), "-o", str(out), "--contour", "cubes"]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"^mesh        Method of Cubes(, simplified)?: ", printed, re.MULTILINE)
    mesh = io.read_mesh(out)
    assert topology.euler_characteristic(mesh) == 2 and topology.is_edge_manifold(mesh.faces)
    with pytest.raises(SystemExit) as exit_info:
        main(["reconstruct", str(sphere_file), "-o", str(out), "--contour", "dual"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'dual'" in capsys.readouterr().err


def test_the_summary_names_the_mesh_it_wrote(tmp_path, capsys):
    cloud = tmp_path / "pipe.ply"
    io.write_points(
        cloud, sample_cylinder(4000, radius=0.25, length=1.0, noise=0.002, rng=0).points
    )
    for options, origin in (
        ([], "marching cubes, simplified"),
        (["--tolerance", "0"], "marching cubes"),
    ):
        out = tmp_path / f"mesh{len(options)}.ply"
        assert main(["reconstruct", str(cloud), "-o", str(out), *options]) == 0
        line = re.search(
            r"^mesh        (.*): [\d,]+ vertices, ([\d,]+) triangles",
            capsys.readouterr().out,
            re.MULTILINE,
        )
        assert line.group(1) == origin
        assert int(line.group(2).replace(",", "")) == io.read_mesh(out).n_faces


def test_report_suffix_chooses_html(sphere_file, tmp_path):
    out = tmp_path / "report.html"
    code = main(
        [
            "reconstruct",
            str(sphere_file),
            "-o",
            str(tmp_path / "m.ply"),
            "--report",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    page = out.read_text()
    assert page.startswith("<!doctype html>") and 'id="zeroset-layers"' in page


def test_render_draws_a_mesh_with_its_points(tmp_path, capsys):
    points = tmp_path / "pipe.ply"
    assert (
        main(
            [
                "synth",
                "cylinder",
                "-o",
                str(points),
                "--points",
                "6000",
                "--noise",
                "0.002",
                "--quiet",
            ]
        )
        == 0
    )
    mesh = tmp_path / "mesh.ply"
    assert main(["reconstruct", str(points), "-o", str(mesh), "--quiet"]) == 0
    picture = tmp_path / "mesh.png"
    assert (
        main(
            [
                "render",
                str(mesh),
                str(points),
                "-o",
                str(picture),
                "--distance",
                "--normals",
                "--size",
                "320x160",
            ]
        )
        == 0
    )
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "picture     written" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["-o", "x.jpg"], "must be a .png file"),
        (["-o", "x.png", "--size", "big"], "WIDTHxHEIGHT"),
        (["-o", "x.png", "--size", "4x4"], "between 16 and 8192"),
        (["-o", "x.png", "--distance"], "need a POINTS file"),
    ],
)
def test_render_rejects_bad_options(extra, message, tmp_path, capsys):
    mesh = tmp_path / "t.ply"
    io.write_mesh(mesh, _triangle())
    extra = [str(tmp_path / e) if e.endswith((".png", ".jpg")) else e for e in extra]
    assert main(["render", str(mesh), *extra]) == 2
    assert message in capsys.readouterr().err


def _triangle():
    from zeroset.types import Mesh

    return Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]]))


def test_demo_writes_its_folder(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--points", "8000"]) == 0
    assert {p.name for p in out.iterdir()} == {
        "pipe-points.ply",
        "mesh.ply",
        "preview.png",
        "report.json",
        "report.html",
    }
    report = json.loads((out / "report.json").read_text())
    assert report["stats"]["boundary_loops"] == 2
    page = (out / "report.html").read_text()
    assert '"boundary_loops": 2' in page and "var THREE=" in page
    printed = capsys.readouterr().out
    assert "outliers dropped" in printed and "triangles" in printed and str(out) in printed
    mean = re.search(r"the mesh lies ([\d.]+) mm \(mean over its area\)", printed)
    assert mean is not None and float(mean.group(1)) < 0.5  # noise 2 mm


@pytest.mark.parametrize(
    "kind, extra",
    [("tee", ["--points", "3000", "--noise", "0.002"]), ("pipe-scan", ["--rotation-step", "8"])],
)
def test_synth_writes_points_and_truth_that_reconstruct_reads(kind, extra, tmp_path):
    out = tmp_path / f"{kind}.ply"
    assert main(["synth", kind, "-o", str(out), "--quiet", *extra]) == 0
    cloud = io.read_points(out)
    truth = io.read_mesh(tmp_path / f"{kind}-truth.ply")
    assert cloud.points.shape[0] > 1000 and truth.n_faces > 1000
    assert (cloud.viewpoints is not None) == (kind == "pipe-scan")
    expected_loops = {"tee": 3, "pipe-scan": 2}[kind]
    assert len(topology.boundary_loops(truth.faces)) == expected_loops


@pytest.mark.slow
def test_evaluate_reports_reference_points_and_quality(tmp_path, capsys):
    points = tmp_path / "tee.ply"
    assert (
        main(["synth", "tee", "-o", str(points), "--points", "6000", "--noise", "0.002", "--quiet"])
        == 0
    )
    mesh = tmp_path / "mesh.ply"
    assert main(["reconstruct", str(points), "-o", str(mesh), "--quiet"]) == 0
    out = tmp_path / "eval.json"
    code = main(
        [
            "evaluate",
            str(mesh),
            "--reference",
            str(tmp_path / "tee-truth.ply"),
            "--scan",
            str(points),
            "--samples",
            "20000",
            "--json",
            str(out),
        ]
    )
    assert code == 0
    report = json.loads(out.read_text())
    assert report["quality"]["boundary_loops"] == 3
    assert report["quality"]["non_manifold_edges"] == 0
    assert report["reference"]["chamfer_l1"] < 0.01
    assert all(t["f_score"] > 0.9 for t in report["reference"]["thresholds"])
    assert report["points"]["coverage"] > 0.95
    printed = capsys.readouterr().out
    assert "F-score" in printed and "coverage" in printed and "boundary loops" in printed


def test_evaluate_missing_mesh_exits_2(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path / "nothing.ply")]) == 2
    assert "no such file" in capsys.readouterr().err


@pytest.mark.slow
def test_reconstruct_with_optimize_runs_phase_two_on_every_point(sphere_file, tmp_path, capsys):
    out, report_path = tmp_path / "mesh.ply", tmp_path / "r.json"
    code = main(
        ["reconstruct", str(sphere_file), "-o", str(out), "--optimize", "--sample", "0.5"]
        + ["--report", str(report_path)]
    )
    assert code == 0
    mesh = io.read_mesh(out)
    report = json.loads(report_path.read_text())
    phase2 = report["optimization"]
    assert phase2["stats"]["faces"] == mesh.n_faces < phase2["stats"]["faces_before"]
    # Phase 1 saw half the points, phase 2 all of them but its outliers.
    used = phase2["stats"]["points_used"] + phase2["stats"]["points_ignored"]
    assert used == 4000 and abs(report["stats"]["sampled_out"] - 2000) < 150
    assert phase2["energy"]["total"] < phase2["energy_before"]["total"]
    assert topology.euler_characteristic(mesh) == 2
    assert "optimize" in report["timings"]
    assert "moves accepted" in capsys.readouterr().out


@pytest.mark.slow
def test_optimize_command_writes_a_smaller_mesh_and_a_report(sphere_file, tmp_path, capsys):
    start = tmp_path / "start.ply"
    assert main(["reconstruct", str(sphere_file), "-o", str(start), "--quiet"]) == 0
    out, report_path = tmp_path / "fine.off", tmp_path / "o.json"
    code = main(
        ["optimize", str(start), str(sphere_file), "-o", str(out), "--report", str(report_path)]
        + ["--c-rep", "1e-4", "--seed", "2"]
    )
    assert code == 0
    before, after = io.read_mesh(start), io.read_mesh(out)
    assert after.n_faces < before.n_faces
    assert topology.euler_characteristic(after) == 2
    report = json.loads(report_path.read_text())
    assert report["parameters"]["c_rep"] == 1e-4
    assert report["files"]["mesh"] == str(start)
    totals = [entry["total"] for entry in report["history"]]
    assert all(b <= a for a, b in zip(totals, totals[1:], strict=False))
    assert "phase 2" in capsys.readouterr().out


@pytest.mark.slow
def test_optimize_command_holds_a_tolerance_of_the_starting_mesh(sphere_file, tmp_path):
    start, out, report = tmp_path / "start.ply", tmp_path / "held.ply", tmp_path / "r.json"
    assert main(["reconstruct", str(sphere_file), "-o", str(start), "--tolerance", "0"]) == 0
    argv = ["optimize", str(start), str(sphere_file), "-o", str(out), "--tolerance", "0.01"]
    assert main(argv + ["--quiet", "--report", str(report)]) == 0
    before, after = io.read_mesh(start), io.read_mesh(out)
    assert after.n_faces < before.n_faces / 2
    # Within the tolerance everywhere but the triangles counted (and warned) as strays.
    strays = np.count_nonzero(two_sided_errors(after, before) > 0.01)
    assert strays == json.loads(report.read_text())["stats"]["tolerance_strays"]
    assert strays <= 0.001 * after.n_faces
    assert topology.euler_characteristic(after) == 2


@pytest.mark.parametrize(
    "argv, message",
    [
        (["optimize", "{mesh}", "{points}", "-o", "{tmp}/out.xyz"], "unknown mesh format"),
        (["optimize", "{mesh}", "{points}", "-o", "{tmp}/no/out.ply"], "does not exist"),
        (["optimize", "{tmp}/missing.ply", "{points}", "-o", "{tmp}/out.ply"], "missing.ply"),
        (["optimize", "{mesh}", "{points}", "-o", "{tmp}/o.ply", "--c-rep", "-1"], "c_rep"),
        (["optimize", "{mesh}", "{points}", "-o", "{tmp}/o.ply", "--tolerance", "0"], "tolerance"),
    ],
)
def test_optimize_command_errors(argv, message, sphere_file, tmp_path, capsys):
    mesh = tmp_path / "start.ply"
    assert main(["reconstruct", str(sphere_file), "-o", str(mesh), "--quiet"]) == 0
    capsys.readouterr()
    filled = [a.format(mesh=mesh, points=sphere_file, tmp=tmp_path) for a in argv]
    assert main(filled) == 2
    err = capsys.readouterr().err
    assert err.startswith("zeroset: error:") and message in err and len(err.splitlines()) == 1


def _scans_of_a_sphere(folder, n_scans=3, seed=0):
    """A sphere (radius 0.5) seen by `n_scans` sensors around it, each scan written in its
    own frame (sensor at the origin, looking along +z); return the files and true poses."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    sphere = sample_sphere(60_000, radius=0.5, rng=rng).points
    files, poses = [], []
    for i in range(n_scans):
        angle = 2 * np.pi * i / n_scans
        sensor = 2.0 * np.array([np.cos(angle), np.sin(angle), 0.3])
        seen = sphere[np.einsum("ij,ij->i", sphere, sensor - sphere) > 0.1]
        seen = seen + rng.normal(0.0, 0.002, seen.shape)
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        pose[:3, 3] = sensor
        files.append(io.write_points(folder / f"scan{i}.ply", (seen - sensor) @ pose[:3, :3]))
        poses.append(pose)
    return files, np.array(poses)


def test_several_scans_with_poses_make_one_mesh(tmp_path, capsys):
    files, poses = _scans_of_a_sphere(tmp_path)
    # Named poses in another order than the scans: matched by file name.
    (tmp_path / "poses.json").write_text(
        json.dumps(
            {f.name: pose.tolist() for f, pose in reversed(list(zip(files, poses, strict=True)))}
        )
    )
    out, report_path = tmp_path / "mesh.ply", tmp_path / "r.json"
    args = [*map(str, files), "--poses", str(tmp_path / "poses.json"), "-o", str(out)]
    assert main(["reconstruct", *args, "--report", str(report_path)]) == 0
    mesh = io.read_mesh(out)
    assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 0.5).max() < 0.01
    assert topology.face_components(mesh.faces, mesh.n_vertices)[0] == 1
    report = json.loads(report_path.read_text())
    assert report["stats"]["input_points"] == sum(len(io.read_points(f).points) for f in files)
    assert report["stats"]["orientation_disagreement"] < 0.01
    # The sensors sit outside the sphere, so its normals point out.
    tri = mesh.vertices[mesh.faces]
    outward = np.einsum(
        "ij,ij->i", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), tri[:, 0]
    )
    assert np.all(outward > 0)
    assert "sensors and spanning tree disagree" in capsys.readouterr().out


@pytest.mark.parametrize(
    "poses_text, extra, message",
    [
        ("[]", [], "poses.json: holds no pose"),
        ('{"other.ply": ' + json.dumps(np.eye(4).tolist()) + "}", [], "has no pose for"),
        (json.dumps([np.eye(4).tolist()] * 3), [], "3 unnamed poses for 2 scans"),
        (None, ["--register"], "--register needs two or more scans"),
    ],
)
def test_bad_poses_and_options_end_in_one_line(tmp_path, capsys, poses_text, extra, message):
    files, _ = _scans_of_a_sphere(tmp_path, n_scans=2)
    args = ["reconstruct", *map(str, files), "-o", str(tmp_path / "m.ply"), *extra]
    if poses_text is None:
        args = ["reconstruct", str(files[0]), "-o", str(tmp_path / "m.ply"), *extra]
    else:
        (tmp_path / "poses.json").write_text(poses_text)
        args += ["--poses", str(tmp_path / "poses.json")]
    assert main(args) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("zeroset: error: ") and message in error and "\n" not in error
    assert not (tmp_path / "m.ply").exists()


@pytest.mark.slow
def test_register_refines_poses_and_reports_residuals(tmp_path, capsys):
    files, poses = _scans_of_a_sphere(tmp_path)
    off = poses.copy()
    off[1:, :3, 3] += [[0.02, 0.0, 0.0], [0.0, -0.015, 0.01]]  # 2 cm and 1.8 cm off
    (tmp_path / "poses.json").write_text(json.dumps([pose.tolist() for pose in off]))
    out, report_path = tmp_path / "mesh.ply", tmp_path / "r.json"
    args = [*map(str, files), "--poses", str(tmp_path / "poses.json"), "-o", str(out)]
    assert main(["reconstruct", *args, "--register", "--report", str(report_path)]) == 0
    mesh = io.read_mesh(out)
    assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 0.5).max() < 0.01
    scans = json.loads(report_path.read_text())["registration"]["scans"]
    assert [scan["name"] for scan in scans] == [f.name for f in files]
    assert all(scan["residual_after"] < 0.5 * scan["residual_before"] for scan in scans)
    assert "register    scan1.ply: residual" in capsys.readouterr().out
    # A scan placed a metre away overlaps nothing: refused, naming it.
    off[2, :3, 3] += 1.0
    (tmp_path / "poses.json").write_text(json.dumps([pose.tolist() for pose in off]))
    assert main(["reconstruct", *args, "--register", "--force"]) == 2
    assert "scan2.ply does not overlap the other scans" in capsys.readouterr().err
