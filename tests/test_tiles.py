"""Tiled reconstruction on a dask.distributed cluster: the same mesh as without tiles."""

import ast
import importlib
import json
import os
from pathlib import Path

import distributed
import numpy as np
import pytest

import zeroset.tiles
from tests.meshes import assert_same_mesh, face_rows
from tests.test_sheets import pipe_rack
from zeroset import (
    ReconstructionConfig,
    ReconstructionError,
    SurfaceWarning,
    io,
    reconstruct,
    topology,
)
from zeroset.cli import main
from zeroset.evaluate import points_to_mesh_distance
from zeroset.neighbours import spatial_order
from zeroset.refine import refine_mesh
from zeroset.stages import choose_parameters
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_tee, sample_torus, scan_pipe
from zeroset.tile_output import cut, read_tile_meshes, weld
from zeroset.tiles import (
    REFINE_RINGS,
    _counts,
    _estimate_sampled,
    _refine_part,
    _with_rings,
    dask_client,
    plan_tiles,
    reconstruct_tiled,
)
from zeroset.types import Mesh


@pytest.fixture(scope="module")
def client():
    """A local cluster of two worker processes, one thread each."""
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


def _wavy_sheet(n, seed):
    """An open sheet z = 0.15 sin 3x cos 2y over [-1, 1]^2 with 3 mm noise: its tiles'
    own roots point up in some, down in others, so they must be flipped to agree."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1.0, 1.0, (n, 2))
    z = 0.15 * np.sin(3 * xy[:, 0]) * np.cos(2 * xy[:, 1]) + rng.normal(0.0, 0.003, n)
    return np.column_stack([xy, z])


def _sheet_with_a_sparse_strip(n, seed):
    """A wavy sheet whose strip x > 0.3 holds a seventh of the density elsewhere: there the
    neighbourhoods of a count of points reach further than the halo allows for."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1.0, 1.0, (n, 2))
    xy = xy[(xy[:, 0] <= 0.3) | (rng.random(n) < 0.15)]
    z = 0.05 * np.sin(3 * xy[:, 0]) + rng.normal(0.0, 0.002, xy.shape[0])
    return np.column_stack([xy, z])


def test_pieces_refined_apart_with_their_rings_weld_into_the_refined_mesh():
    # An open pipe cut into four pieces across its axis and around it: each refined with
    # the rings around it on the whole surface, as a tile's task does, kept to its own.
    points = sample_cylinder(6_000, radius=0.25, length=1.0, noise=0.002, rng=2).points
    coarse = reconstruct(points, refine_levels=0, tolerance=0.0)
    mesh = Mesh(vertices=coarse.dense_mesh.vertices - coarse.offset, faces=coarse.dense_mesh.faces)
    noise = coarse.parameters.noise
    whole, counts = refine_mesh(mesh, coarse.surface, noise=noise)
    assert counts["edges_split"] > mesh.n_faces  # it splits, more than once some
    centroids = mesh.vertices[mesh.faces].mean(axis=1)
    owner = (centroids[:, 0] > 0.0) + 2 * (centroids[:, 2] > 0.0)
    done = []
    for k, part in enumerate(_with_rings(mesh.faces, owner, 4, REFINE_RINGS)):
        own = owner == k
        assert part[own].all() and part.sum() > own.sum()  # its faces and rings of others
        ((piece, used),) = cut(mesh, np.where(part, 0, -1), 1)
        done.append(_refine_part((piece, used, own[part]), (None, coarse.surface), noise, None))
        # Each face kept lies in one of the piece's own faces; its parent says which.
        assert done[-1].parent.size == done[-1].mesh.n_faces
        assert own[np.flatnonzero(part)[done[-1].parent]].all()
    welded, index = weld([p.mesh for p in done], [p.keys for p in done])
    copies = np.concatenate([p.mesh.vertices for p in done])
    assert np.abs(copies - welded.vertices[index]).max() == 0.0  # seam vertices agree
    assert_same_mesh(welded, whole)


@pytest.mark.parametrize(
    "points, tiles, closed",
    [
        (sample_torus(30_000, noise=0.005, rng=3).points, (3, 3, 3), True),
        (sample_torus(30_000, noise=0.005, rng=3).points, (2, 2, 2), True),
        (sample_tee(40_000, rng=4).points, (3, 3, 3), False),
        (sample_tee(40_000, rng=4).points, (2, 2, 2), False),
        (_wavy_sheet(40_000, 1), (4, 4, 1), False),
        (scan_pipe(radius=0.35, rotation_step=4.0, offset=0.05, rng=5).points, (2, 2, 2), False),
        (scan_pipe(radius=0.35, rotation_step=4.0, offset=0.05, rng=5).points, (3, 3, 3), False),
        (pipe_rack(64_000, 2), (3, 3, 1), False),
    ],
    ids=["torus", "torus-2", "tee", "tee-2", "sheet", "sparse-scan-2", "sparse-scan-3", "rack"],
)
@pytest.mark.slow
def test_tiled_mesh_is_the_untiled_mesh(client, points, tiles, closed):
    # With default options: the tiles take the parameters reconstruct chooses.
    # The dense meshes (tolerance=0): the simplification after them decides at its
    # tolerance, where the tiles' last bits (1e-12) may tip a collapse.
    untiled = reconstruct(points, tolerance=0.0)
    tiled = reconstruct_tiled(points, tiles=tiles, client=client, tolerance=0.0)
    assert tiled.parameters == untiled.parameters
    assert_same_mesh(tiled.mesh, untiled.mesh)
    for count in ("refine_levels", "edges_split", "projection_held"):
        assert tiled.stats[count] == untiled.stats[count]
    assert tiled.stats["seam_vertex_gap"] <= 1e-9 * tiled.parameters.cube_size
    assert tiled.stats["tiles"] == np.prod(tiles) and tiled.stats["seam_disagreement"] == 0.0
    if tiles == (4, 4, 1):
        assert tiled.stats["tile_components_flipped"] > 0
    assert topology.is_edge_manifold(tiled.mesh.faces)
    assert topology.is_consistently_oriented(tiled.mesh.faces)
    if closed:  # no boundary edge anywhere, so none along the seams
        assert topology.boundary_loops(tiled.mesh.faces) == []
    # The surface does cross the seams: every cut plane has vertices within a cube of it.
    lattice = (tiled.mesh.vertices - tiled.offset) / tiled.parameters.cube_size
    cuts = {(a, int(t.owned[0][a])) for t in tiled.tiles for a in range(3) if t.index[a] > 0}
    assert cuts and all(np.any(np.abs(lattice[:, a] - cut) < 1.0) for a, cut in cuts)


def test_local_workers_share_the_cores_out():
    # Each of two local workers runs its kernels and k-d tree queries on half the cores (at
    # least one): together they ask for the machine's cores, not twice as many.
    from zeroset.neighbours import query_workers

    with dask_client(workers=2) as client:
        threads = client.run(query_workers)
    assert list(threads.values()) == [max(1, (os.cpu_count() or 1) // 2)] * 2


def test_no_query_asks_for_every_core():
    # A k-d tree query with workers=-1 would take every core from inside each worker.
    package = Path(zeroset.tiles.__file__).parent
    greedy = [
        f"{path.relative_to(package)}:{node.lineno}"
        for path in package.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.keyword)
        and node.arg == "workers"
        and isinstance(node.value, ast.UnaryOp)
    ]
    assert greedy == []


def test_tiles_import_only_public_names():
    # The tiles run the stages of zeroset.stages, as reconstruct does, through their
    # public names: each name they import from the package is in its module's __all__
    # (or, in a module without one, such as the thresholds, not marked private).
    tree = ast.parse(Path(zeroset.tiles.__file__).read_text())
    imported = [
        (node.module, alias.name)
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module
        for alias in node.names
    ]
    assert ("stages", "fit") in imported and ("orientation", "agree_parts") in imported
    private = [
        f"{module}.{name}"
        for module, name in imported
        if name
        not in getattr(importlib.import_module(f"zeroset.{module}"), "__all__", [name.lstrip("_")])
    ]
    assert private == []


def test_every_cube_belongs_to_one_tile():
    untiled = reconstruct(sample_torus(5_000, rng=1).points)
    p = untiled.parameters
    tiles = plan_tiles(
        np.array([-1.5, -1.5, -0.5]), np.array([1.5, 1.5, 0.5]), np.zeros(3), p, (3, 2, 4)
    )
    rng = np.random.default_rng(0)
    cubes = rng.integers(-200, 200, size=(5000, 3))
    owners = sum(np.all((cubes >= t.owned[0]) & (cubes < t.owned[1]), axis=1) for t in tiles)
    assert np.all(owners == 1)
    # Each tile reads its own box and a halo around it, not the whole cloud.
    widths = np.array([t.box[3:] - t.box[:3] for t in tiles])
    assert np.all(widths[:, 0] < 3.0 / 3 + 2 * (8 * p.rho_delta + 3 * p.cube_size))


def test_auto_tiles_give_every_thread_a_tile_of_enough_points():
    low, high = np.zeros(3), np.array([8.0, 4.0, 1.0])  # the rack's proportions
    # 2M points a tile by default, the longest axis cut first.
    assert _counts("auto", low, high, 4_000_000).tolist() == [2, 1, 1]
    assert _counts("auto", low, high, 20_000_000).tolist() == [5, 2, 1]
    # As many tiles as threads while each keeps 500k points, no more.
    assert _counts("auto", low, high, 4_000_000, threads=8).tolist() == [4, 2, 1]
    many = _counts("auto", low, high, 20_000_000, threads=16)  # the 16-core machine's run
    assert many.prod() >= 16 and 20_000_000 / many.prod() >= 500_000
    assert _counts("auto", low, high, 1_000_000, threads=16).prod() == 2
    assert _counts("auto", low, high, 100_000, threads=16).prod() == 1
    assert _counts("3x1x1", low, high, 100_000, threads=16).tolist() == [3, 1, 1]


@pytest.mark.slow
def test_cli_tiles_from_a_file_on_a_scheduler(client, tmp_path, capsys):
    path = io.write_points(tmp_path / "torus.ply", sample_torus(30_000, noise=0.005, rng=5).points)
    out, report = tmp_path / "mesh.ply", tmp_path / "r.json"
    address = client.scheduler.address
    args = [str(path), "-o", str(out), "--tiles", "2x2x1", "--scheduler", address]
    assert main(["reconstruct", *args, "--report", str(report)]) == 0
    mesh = io.read_mesh(out)
    assert topology.boundary_loops(mesh.faces) == [] and topology.euler_characteristic(mesh) == 0
    stats = json.loads(report.read_text())["stats"]
    assert stats["tile_grid"] == [2, 2, 1] and len(stats["worker_peak_mib"]) >= 1
    assert "tiles       4 (2x2x1)" in capsys.readouterr().out


@pytest.mark.slow
def test_cli_per_tile_output_reloads_into_the_one_file_mesh(client, tmp_path, capsys):
    path = io.write_points(tmp_path / "torus.ply", sample_torus(30_000, noise=0.005, rng=5).points)
    common = [str(path), "--tiles", "2x2x1", "--scheduler", client.scheduler.address]
    assert main(["reconstruct", *common, "-o", str(tmp_path / "one.ply")]) == 0
    assert main(["reconstruct", *common, "-o", str(tmp_path / "tiles"), "--per-tile"]) == 0
    assert "one file a tile, and tiles.json" in capsys.readouterr().out
    one, tiled = io.read_mesh(tmp_path / "one.ply"), read_tile_meshes(tmp_path / "tiles")
    assert (tiled.n_vertices, tiled.n_faces) == (one.n_vertices, one.n_faces)
    # The same vertices, and the same faces once the vertices are matched.
    order_one, order_tiled = np.lexsort(one.vertices.T), np.lexsort(tiled.vertices.T)
    np.testing.assert_array_equal(one.vertices[order_one], tiled.vertices[order_tiled])
    rename = np.empty(tiled.n_vertices, dtype=np.int64)
    rename[order_tiled] = order_one
    np.testing.assert_array_equal(face_rows(rename[tiled.faces]), face_rows(one.faces))
    manifest = json.loads((tmp_path / "tiles" / "tiles.json").read_text())
    assert manifest["grid"] == [2, 2, 1] and len(manifest["seams"]) >= 4


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--tiles", "2x2"], "NxMxK"),
        (["--tiles", "auto", "--report", "r.html"], "write the report as .json"),
        (["--tiles", "auto", "--optimize"], "--tiles takes one input"),
        (["--workers", "2"], "go with --tiles"),
        (["--tiles", "auto", "missing.ply"], "missing.ply: no such file"),
    ],
)
def test_tile_options_are_checked_before_any_cluster_starts(tmp_path, capsys, extra, message):
    path = io.write_points(tmp_path / "s.ply", sample_torus(2_000, rng=1).points)
    if extra[-1] == "missing.ply":
        path, extra = tmp_path / extra[-1], extra[:-1]
    extra = [str(tmp_path / e) if e.endswith(".html") else e for e in extra]
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "m.ply"), *extra]) == 2
    error = capsys.readouterr().err
    assert error.startswith("zeroset: error: ") and message in error
    assert error.count("\n") == 1  # one line: no cluster was started to fail in a task


@pytest.mark.slow
def test_tiles_read_from_a_file_with_a_crop_give_the_untiled_mesh(client, tmp_path):
    # Each tile reads its own box of the file, cut by the crop.
    points = sample_torus(30_000, noise=0.005, rng=6).points
    path = io.write_points(tmp_path / "torus.ply", points)
    box = (-1.5, -1.5, -1.0, 0.4, 1.5, 1.0)
    untiled = reconstruct(points, crop=box, tolerance=0.0)
    tiled = reconstruct_tiled(
        path, tiles=(4, 2, 1), client=client, parameters=untiled.parameters, crop=box,
        tolerance=0.0,
    )  # fmt: skip
    assert_same_mesh(tiled.mesh, untiled.mesh)
    assert tiled.stats["input_points"] == untiled.stats["input_points"] - untiled.stats["cropped"]


@pytest.mark.slow
def test_the_tiled_default_mesh_lies_within_its_tolerance_of_the_untiled_dense_mesh(client):
    points = sample_torus(30_000, noise=0.005, rng=3).points
    untiled = reconstruct(points)
    tiled = reconstruct_tiled(points, tiles=(2, 2, 2), client=client)
    assert tiled.stats["tolerance"] == pytest.approx(untiled.stats["tolerance"], rel=1e-9)
    assert tiled.mesh.n_faces == pytest.approx(untiled.mesh.n_faces, rel=0.05)
    assert tiled.mesh.n_faces < untiled.dense_mesh.n_faces / 3
    away = points_to_mesh_distance(tiled.mesh.vertices, untiled.dense_mesh)
    assert away.max() <= untiled.stats["tolerance"]
    # The waits for the tasks are part of their stages, not stages of their own.
    assert set(tiled.waits) == {"refine", "simplify"} and not set(tiled.waits) - set(tiled.timings)
    assert all(0.0 < tiled.waits[name] <= tiled.timings[name] for name in tiled.waits)


def _torus_and_scatter():
    """A torus (x within 0.55 m of 0) and 300 points scattered over a cube from x = 10 m:
    every one an outlier, so a tile holding only them fails to fit."""
    rng = np.random.default_rng(7)
    scatter = rng.uniform([10.0, -0.5, -0.5], [11.0, 0.5, 0.5], (300, 3))
    return np.vstack([sample_torus(30_000, noise=0.003, rng=5).points, scatter])


@pytest.mark.slow
def test_a_failed_tile_stops_the_run_unless_gaps_are_allowed(client, tmp_path, capsys):
    points = _torus_and_scatter()
    with pytest.raises(ReconstructionError, match=r"tile \(1, 0, 0\) of 2x1x1: only"):
        reconstruct_tiled(points, tiles=(2, 1, 1), client=client)
    with pytest.warns(SurfaceWarning, match=r"left out, a gap in the mesh: tile \(1, 0, 0\)"):
        tiled = reconstruct_tiled(points, tiles=(2, 1, 1), client=client, allow_gaps=True)
    assert tiled.stats["tiles_failed"] == 1
    assert topology.euler_characteristic(tiled.mesh) == 0 and tiled.stats["boundary_loops"] == 0
    path = io.write_points(tmp_path / "cloud.ply", points)
    command = ["reconstruct", str(path), "-o", str(tmp_path / "m.ply"), "--tiles", "2x1x1"]
    command += ["--scheduler", client.scheduler.address]
    assert main(command) == 1
    error = capsys.readouterr().err
    assert "tile (1, 0, 0) of 2x1x1" in error and not (tmp_path / "m.ply").exists()
    assert main([*command, "--allow-gaps"]) == 0
    assert (
        "zeroset: warning: left out, a gap in the mesh: tile (1, 0, 0)" in capsys.readouterr().err
    )


@pytest.mark.slow
def test_tiles_oriented_towards_a_sensor_agree_with_the_untiled_run(client):
    # One sensor at the sphere's centre: the normals point inward, in every tile.
    points = sample_sphere(20_000, noise=0.003, rng=6).points
    untiled = reconstruct(points, viewpoint=(0.0, 0.0, 0.0)).mesh
    tiled = reconstruct_tiled(points, tiles=(2, 2, 2), client=client, viewpoint=(0.0, 0.0, 0.0))
    for mesh in (tiled.mesh, untiled):
        assert topology.boundary_loops(mesh.faces) == []
        assert topology.is_edge_manifold(mesh.faces)
        assert topology.is_consistently_oriented(mesh.faces)
        corners = mesh.vertices[mesh.faces]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        assert np.all(np.einsum("ij,ij->i", normals, corners.mean(axis=1)) < 0.0)
        assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 1.0).max() < 0.01
    assert tiled.stats["viewpoints_untrusted"] == 0 and tiled.stats["orientation_components"] == 1


@pytest.mark.slow
def test_tiles_whose_neighbourhoods_reach_further_widen_their_halos(client):
    points = _sheet_with_a_sparse_strip(40_000, 0)
    untiled = reconstruct(points, tolerance=0.0)
    tiled = reconstruct_tiled(points, tiles=(4, 4, 1), client=client, tolerance=0.0)
    assert tiled.stats["tiles_grown"] > 0 and tiled.stats["tiles_failed"] == 0
    assert tiled.stats["seam_vertex_gap"] < 1e-12
    assert_same_mesh(tiled.mesh, untiled.mesh)


@pytest.mark.parametrize("from_file", [False, True], ids=["array", "file"])
@pytest.mark.slow
def test_a_cloud_too_large_to_hold_gets_the_parameters_of_all_its_points(tmp_path, from_file):
    # Measured at 20,000 points drawn in one pass, on the points near them read in another.
    points = sample_torus(300_000, noise=0.003, rng=7).points
    offset = (points.min(axis=0) + points.max(axis=0)) / 2.0
    config = ReconstructionConfig()
    local = points - offset
    whole = choose_parameters(local[spatial_order(local)], config)[0]
    source = io.write_points(tmp_path / "cloud.ply", points) if from_file else points
    sampled, drawn = _estimate_sampled(source, len(points), offset, config, chunk_points=50_000)
    assert drawn.shape == (20_000, 3)  # drawn from the cloud, in its local frame
    assert np.all(np.isin(drawn.view([("", float)] * 3), local.view([("", float)] * 3)))
    for name in ("spacing", "noise", "rho_delta", "cube_size", "quadric_noise"):
        assert getattr(sampled, name) == pytest.approx(getattr(whole, name), rel=0.03), name
