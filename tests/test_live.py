"""Live reconstruction: blocks built scan by scan equal blocks built in one run, the batch
mesh is reproduced on its lattice, a kill leaves whole files, bad scans are reported."""

import json
import signal
import subprocess
import sys
import threading
import time
import warnings
from dataclasses import replace

import numpy as np
import pytest

import zeroset
from tests.meshes import assert_same_mesh
from zeroset import io as zio
from zeroset.cli import main
from zeroset.errors import InputError, SurfaceWarning
from zeroset.evaluate import closest_points_on_mesh
from zeroset.live import QUEUE, LiveReconstruction
from zeroset.scans import follow, split_scans
from zeroset.synthetic import Defect, PipePath, scan_pipe_run
from zeroset.tile_output import MANIFEST, read_tile_meshes
from zeroset.topology import (
    boundary_loops,
    face_components,
    is_consistently_oriented,
    is_edge_manifold,
)

RADIUS = 0.2
#: The scans' range: each keeps its points within this of its sensor, so that a block
#: farther than it from the newest sensor can get no more.
RANGE = 1.0
LENGTH = 4.0
BLOCK_CUBES = 16


def _scans(rotation_step=8.0, defects=(), length=LENGTH):
    """Scans of a straight open pipe along x, a station every 0.5 m, each within RANGE."""
    path = PipePath.build([("straight", length)])
    scans = []
    for k, station in enumerate(np.arange(0.25, length, 0.5)):
        scan = scan_pipe_run(
            path,
            radius=RADIUS,
            stations=[station],
            rotation_step=rotation_step,
            defects=defects,
            rng=k,
        )
        near = np.linalg.norm(scan.points - scan.viewpoints, axis=1) <= RANGE
        scans.append((scan.points[near], scan.viewpoints[near]))
    return scans


@pytest.fixture(scope="module")
def scans():
    return _scans()


@pytest.fixture(scope="module")
def live_run(scans):
    """The scans given one at a time: the live object and each block's final mesh."""
    live = LiveReconstruction(reach=RANGE, block_cubes=BLOCK_CUBES)
    blocks, during = {}, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for points, viewpoints in scans:
            update = live.add(points, viewpoints)
            assert update.skipped is None and update.late_points == 0
            blocks.update(update.finished)
            during += len(update.finished)
        blocks.update(live.close().finished)
    return live, blocks, during


def _radial(vertices):
    return np.hypot(vertices[:, 1], vertices[:, 2]) - RADIUS


def _facing_the_axis(mesh):
    """The share of faces whose normal points towards the pipe's axis (the x axis)."""
    corners = mesh.vertices[mesh.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return np.mean(np.einsum("ij,ij->i", normals[:, 1:], corners.mean(axis=1)[:, 1:]) < 0)


@pytest.mark.slow
def test_blocks_built_live_equal_blocks_built_in_one_run(scans, live_run):
    live, blocks, during = live_run
    assert during >= 2  # blocks were finished while the scans came, not only at the end
    whole = LiveReconstruction(
        reach=RANGE,
        block_cubes=BLOCK_CUBES,
        parameters=live.parameters,
        origin=live.offset,
        tolerance=live.summary()["tolerance"],
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        whole.add(np.concatenate([s[0] for s in scans]), np.concatenate([s[1] for s in scans]))
        at_once = whole.close().finished
    assert sorted(blocks) == sorted(at_once) and len(blocks) >= 4
    for index, mesh in blocks.items():
        assert_same_mesh(mesh, at_once[index])


@pytest.mark.slow
def test_work_left_by_the_budget_waits_and_gives_the_same_blocks(scans, live_run):
    live, blocks, _ = live_run
    lagging = LiveReconstruction(reach=RANGE, block_cubes=BLOCK_CUBES, budget=0.0)
    later, waiting = {}, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for points, viewpoints in scans:
            update = lagging.add(points, viewpoints)
            later.update(update.finished)
            waiting.append(update.waiting)
        later.update(lagging.close().finished)
    assert max(waiting) >= 2 and lagging.waiting() == 0  # one block's work a scan
    assert sorted(later) == sorted(blocks)
    for index, mesh in blocks.items():
        assert_same_mesh(mesh, later[index])


@pytest.mark.slow
def test_in_the_background_the_blocks_are_those_made_without_it(scans, live_run):
    _, blocks, _ = live_run
    live = LiveReconstruction(reach=RANGE, block_cubes=BLOCK_CUBES, background=True)
    behind, done = {}, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for points, viewpoints in scans:
            update = live.add(points, viewpoints)
            assert update.skipped is None and update.points == points.shape[0]
            behind.update(update.finished)
            done += update.done
        closing = live.close()
    behind.update(closing.finished)
    done += closing.done
    assert [k for k, _ in done] == list(range(len(scans)))  # each scan's work ends once
    assert all(seconds > 0.0 for _, seconds in done)
    assert sorted(behind) == sorted(blocks)
    for index, mesh in blocks.items():
        assert_same_mesh(mesh, behind[index])
    assert live.summary()["scans"] == len(scans) and live.waiting() == 0


def _held_worker(monkeypatch):
    """Hold the background worker at each scan until the event returned is set."""
    release = threading.Event()
    take = LiveReconstruction._take

    def held(self, scan, deadline):
        assert release.wait(60), "the test never released the worker"
        return take(self, scan, deadline)

    monkeypatch.setattr(LiveReconstruction, "_take", held)
    return release


def test_in_the_background_add_waits_only_once_the_queue_is_full(scans, monkeypatch):
    release = _held_worker(monkeypatch)
    live = LiveReconstruction(rho_delta=0.03, cube_size=0.045, reach=RANGE, background=True)
    # The worker holds the first scan; QUEUE more wait for it, and add returned each time.
    for points, viewpoints in scans[: QUEUE + 1]:
        assert live.add(points, viewpoints).done == ()
    blocked = threading.Thread(target=live.add, args=scans[QUEUE + 1], daemon=True)
    blocked.start()
    blocked.join(0.5)
    assert blocked.is_alive()  # waiting for the worker to take a scan
    release.set()
    blocked.join(60)
    assert not blocked.is_alive()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        closing = live.close()
    assert [k for k, _ in closing.done][-1] == QUEUE + 1  # close waited for every scan
    assert live.summary()["scans"] == QUEUE + 2 and live.waiting() == 0


def test_an_error_of_the_worker_is_raised_by_the_next_call(scans, monkeypatch):
    def fails(self, scan, deadline):
        raise RuntimeError(f"scan {scan.number} failed")

    monkeypatch.setattr(LiveReconstruction, "_take", fails)
    live = LiveReconstruction(rho_delta=0.03, cube_size=0.045, reach=RANGE, background=True)
    live.add(*scans[0])
    with pytest.raises(RuntimeError, match="scan 0 failed"):
        live.close()
    with pytest.raises(InputError, match="closed"):
        live.add(*scans[1])


@pytest.mark.slow
def test_the_live_mesh_is_the_open_pipe(scans, live_run):
    live, blocks, _ = live_run
    mesh = live.mesh()
    assert mesh.n_faces == sum(m.n_faces for m in blocks.values())
    assert is_edge_manifold(mesh.faces) and is_consistently_oriented(mesh.faces)
    assert face_components(mesh.faces, mesh.n_vertices)[0] == 1
    assert len(boundary_loops(mesh.faces)) == 2  # the two open ends, no seam left open
    error = _radial(mesh.vertices)
    assert abs(error.mean()) < 0.5e-3 and np.quantile(np.abs(error), 0.99) < 3e-3
    assert _facing_the_axis(mesh) > 0.999  # towards the sensors, as the batch mesh
    stats = live.summary()
    assert stats["scans"] == len(scans) and stats["late_points"] == 0
    assert stats["faces"] == mesh.n_faces and stats["vertices"] == mesh.n_vertices


@pytest.mark.slow
def test_on_the_batch_lattice_the_live_mesh_is_the_batch_mesh(scans):
    points = np.concatenate([s[0] for s in scans])
    viewpoints = np.concatenate([s[1] for s in scans])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        batch = zeroset.reconstruct(points, viewpoints=viewpoints, tolerance=0)
        model = batch.stats["noise_model"]
        held = replace(batch.parameters, noise_model=(model["intercept"], model["slope"]))
        live = LiveReconstruction(reach=RANGE, parameters=held, origin=batch.offset, tolerance=0)
        for scan in scans:
            live.add(*scan)
        live.close()
    assert_same_mesh(live.mesh(), batch.mesh)  # the same vertices to 1e-9, the same faces
    assert live.summary()["seam_vertex_gap"] < 1e-12
    # Each block fitting its own range-noise model, the blocks' radii differ a little.
    alone = LiveReconstruction(
        reach=RANGE, parameters=batch.parameters, origin=batch.offset, tolerance=0
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for scan in scans:
            alone.add(*scan)
        alone.close()
    assert closest_points_on_mesh(alone.mesh().vertices, batch.mesh)[2].max() > 1e-6


@pytest.mark.parametrize("background", [False, True])
def test_bad_scans_are_reported_and_skipped(scans, background):
    points, viewpoints = scans[0]
    live = LiveReconstruction(rho_delta=0.03, cube_size=0.045, reach=RANGE, background=background)
    with pytest.warns(SurfaceWarning, match="scan 0 skipped: no usable points"):
        update = live.add(np.full((100, 3), np.nan), np.zeros(3))
    assert update.skipped is not None and update.points == 0
    live.add(points, viewpoints)
    with pytest.warns(SurfaceWarning, match="scan 2 skipped: its sensor lies 100 from"):
        far = live.add(points + [100.0, 0, 0], viewpoints + [100.0, 0, 0])
    assert "max_jump" in far.skipped
    with pytest.warns(SurfaceWarning, match="scan 3 skipped: its sensor position is not"):
        live.add(points, np.full(3, np.inf))
    with pytest.raises(InputError, match=r"points must have shape \(N, 3\)"):
        live.add(points[:, :2], viewpoints)
    with pytest.raises(InputError, match="viewpoint must be"):
        live.add(points, viewpoints[:5])
    holes = points.copy()
    holes[:7] = np.nan  # beams with no return
    assert live.add(holes, viewpoints).points == points.shape[0] - 7
    stats = live.summary()
    assert stats["scans"] == 7 and stats["scans_skipped"] == 3
    assert stats["nonfinite_points"] == 7  # the first scan's 100 went with the scan
    assert [k for k, _ in live.skipped] == [0, 2, 3]
    with pytest.warns(SurfaceWarning, match="7 point.s. of the scans were not finite"):
        live.close()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"sample": 0.5}, "sample and voxel_size"),
        ({"contour": "cubes"}, "marching cubes only"),
        ({"block_cubes": 2}, "block_cubes must be an integer >= 4"),
        ({"reach": -1.0}, "reach must be a positive distance"),
        ({"preview": float("inf")}, "preview must be a distance"),
    ],
)
def test_bad_options_are_refused(options, message):
    with pytest.raises(InputError, match=message):
        LiveReconstruction(**options)


def test_a_closed_run_takes_no_scan(scans):
    live = LiveReconstruction(rho_delta=0.03, cube_size=0.045)
    live.close()
    with pytest.raises(InputError, match="closed"):
        live.add(*scans[0])


def test_split_scans_by_sensor_and_by_column():
    viewpoints = np.repeat([[0.0, 0, 0], [0.01, 0, 0], [0.6, 0, 0], [0.61, 0, 0], [1.3, 0, 0]],
                           [3, 2, 4, 1, 2], axis=0)  # fmt: skip
    rows = split_scans(viewpoints, every=0.3)
    assert [r.tolist() for r in rows] == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9], [10, 11]]
    time_ = np.array([0.0, 0.4, 1.2, 1.3, 2.5])
    assert [r.tolist() for r in split_scans(None, column=time_, every=1.0)] == [[0, 1], [2, 3], [4]]
    index = np.array([3, 3, 1, 1, 1])
    assert [r.size for r in split_scans(None, column=index)] == [2, 3]
    with pytest.raises(InputError, match="needs --split-every"):
        split_scans(viewpoints)
    with pytest.raises(InputError, match="positive"):
        split_scans(viewpoints, every=0.0)


def test_follow_takes_new_files_in_order_once_still(tmp_path):
    names = ["scan-002.ply", "scan-001.ply", "notes.txt.tmp", ".scan-003.ply.part"]

    def write():
        for name in names:
            (tmp_path / name).write_bytes(b"x" * 10)
            time.sleep(0.05)

    writer = threading.Thread(target=write)
    writer.start()
    found = [p.name for p in follow(tmp_path, (".ply",), idle=0.5, poll=0.05)]
    writer.join()
    assert sorted(found) == ["scan-001.ply", "scan-002.ply"]  # each once, no hidden one
    with pytest.raises(InputError, match="is not a folder"):
        next(follow(tmp_path / "nowhere", (".ply",), idle=0.1))


def _scan_file(tmp_path, scans):
    path = tmp_path / "run.ply"
    points = np.concatenate([s[0] for s in scans])
    zio.write_points(path, points, viewpoints=np.concatenate([s[1] for s in scans]))
    return path


def test_cli_refuses_a_cloud_without_sensors(tmp_path, capsys, scans):
    path = tmp_path / "bare.ply"
    zio.write_points(path, scans[0][0])
    assert main(["live", str(path), "-o", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("zeroset: error: ") and "bare.ply: has no sensor positions" in err
    assert main(["live", str(tmp_path / "missing.ply"), "-o", str(tmp_path / "o")]) == 2
    assert "missing.ply" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_replays_a_cloud_split_by_its_sensors(tmp_path, scans, capsys):
    source = _scan_file(tmp_path, scans)
    before = source.read_bytes()
    out = tmp_path / "out"
    args = ["live", str(source), "-o", str(out), "--split-every", "0.3", "--reach", str(RANGE),
            "--block-cubes", str(BLOCK_CUBES)]  # fmt: skip
    assert main(args) == 0
    assert source.read_bytes() == before
    report = json.loads((out / "live.json").read_text())
    assert len(report["scans"]) == len(scans) and report["stats"]["scans_skipped"] == 0
    mesh = read_tile_meshes(out)
    assert mesh.n_faces == report["stats"]["faces"]
    assert len(boundary_loops(mesh.faces)) == 2
    assert main(args) == 2  # the folder holds a mesh: --force replaces it
    assert "add --force" in capsys.readouterr().err
    assert main([*args, "--force", "--quiet"]) == 0


KILL_AFTER_BLOCKS = 2


@pytest.mark.slow
def test_a_kill_leaves_every_finished_block_whole(tmp_path, scans):
    source = _scan_file(tmp_path, scans)
    out = tmp_path / "out"
    run = subprocess.Popen(
        [sys.executable, "-m", "zeroset", "live", str(source), "-o", str(out), "--quiet",
         "--split-every", "0.3", "--reach", str(RANGE), "--block-cubes", str(BLOCK_CUBES)],
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and run.poll() is None:
            manifest = out / MANIFEST
            done = manifest.exists() and json.loads(manifest.read_text())["tiles"]
            if done and len(done) >= KILL_AFTER_BLOCKS:
                break
            time.sleep(0.01)
        else:
            pytest.fail("no block was finished in time, or the run ended first")
        run.send_signal(signal.SIGKILL)
    finally:
        run.kill()
        run.wait()
    assert run.returncode == -signal.SIGKILL
    manifest = json.loads((out / MANIFEST).read_text())
    listed = {entry["file"] for entry in manifest["tiles"]}
    assert len(listed) >= KILL_AFTER_BLOCKS
    for path in out.iterdir():
        if not path.name.startswith("."):  # a writer's temporary file is hidden
            assert path.name in listed | {MANIFEST}
            if path.suffix == ".ply":
                assert zio.read_mesh(path).n_faces > 0
    mesh = read_tile_meshes(out)  # the pieces weld into what the manifest states
    assert mesh.n_faces == manifest["faces"]
    assert np.abs(_radial(mesh.vertices)).mean() < 1e-3


def test_a_block_whose_fit_fails_is_left_out_with_a_warning():
    # Scattered points, none with four others within rho+delta: every one an outlier.
    points = np.random.default_rng(2).uniform(0.0, 0.5, (80, 3))
    live = LiveReconstruction(rho_delta=0.01, cube_size=0.015)
    live.add(points, np.zeros(3))
    with pytest.warns(SurfaceWarning, match=r"block \(.*\) left out, a gap in the mesh"):
        update = live.close()
    assert update.finished == {} and live.summary()["blocks_failed"] >= 1
    assert live.mesh().n_faces == 0


@pytest.mark.slow
def test_the_final_inspection_finds_the_dent_the_batch_run_finds(tmp_path):
    dent = Defect("dent", 2.0, 90.0, 0.015, 0.1)
    source = _scan_file(tmp_path, _scans(rotation_step=4.0, defects=(dent,)))
    live, batch = tmp_path / "live", tmp_path / "batch"
    assert main(["live", str(source), "-o", str(tmp_path / "out"), "--split-every", "0.3",
                 "--reach", str(RANGE), "--block-cubes", str(BLOCK_CUBES), "--inspect",
                 str(live), "--quiet"]) == 0  # fmt: skip
    assert main(["reconstruct", str(source), "-o", str(tmp_path / "mesh.ply"), "--inspect",
                 str(batch), "--quiet"]) == 0  # fmt: skip
    rows = [
        np.genfromtxt(
            folder / "defects.csv", delimiter=",", names=True, dtype=None, encoding="utf-8", ndmin=1
        )  # fmt: skip
        for folder in (live, batch)
    ]
    assert [r.size for r in rows] == [1, 1] and all(r["kind"][0] == "dent" for r in rows)
    for r in rows:  # each where the dent is, as deep
        assert abs(r["axial_m"][0] - dent.axial) < 0.03
        assert abs(r["clock_deg"][0] - dent.clock) < 5.0
        assert abs(-r["depth_mm"][0] - 1e3 * dent.depth) < 1.0
    assert abs(rows[0]["depth_mm"][0] - rows[1]["depth_mm"][0]) < 0.5
    grown = np.genfromtxt(live / "live-defects.csv", delimiter=",", names=True, dtype=None,
                          encoding="utf-8", ndmin=1)  # fmt: skip
    assert grown.size == 1 and abs(grown["axial_m"][0] - dent.axial) < 0.03  # as it grew
    assert abs(grown["depth_mm"][0] - rows[1]["depth_mm"][0]) < 0.5
