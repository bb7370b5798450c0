"""A tiled mesh as one file per tile and a manifest: written, read back whole."""

import json

import numpy as np
import pytest

from zeroset import InputError, io, reconstruct, topology
from zeroset.cli import main
from zeroset.synthetic import sample_torus
from zeroset.tile_output import MANIFEST, face_tiles, read_tile_meshes, write_tile_meshes
from zeroset.tiles import plan_tiles
from zeroset.types import Mesh


@pytest.fixture(scope="module")
def torus():
    """A closed torus (major radius 1 m, minor 0.35 m) and a plan of 3 x 2 x 1 tiles."""
    result = reconstruct(sample_torus(5_000, rng=1).points)
    mesh, p = result.mesh, result.parameters
    low, high = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    tiles = plan_tiles(low, high, result.offset, p, (3, 2, 1))
    return mesh, tiles, result.offset, p.cube_size


def _triangles(mesh: Mesh) -> np.ndarray:
    """(F, 9) each triangle's corners from its lexicographically first one, orientation
    kept, the rows sorted: the same for two meshes that differ only in the order of their
    vertices and faces."""
    rank = np.empty(mesh.n_vertices, dtype=np.int64)
    rank[np.lexsort(mesh.vertices.T[::-1])] = np.arange(mesh.n_vertices)
    faces = mesh.faces
    turn = np.argmin(rank[faces], axis=1)
    faces = np.take_along_axis(faces, (turn[:, None] + np.arange(3)) % 3, axis=1)
    corners = mesh.vertices[faces].reshape(-1, 9)
    return corners[np.lexsort(corners.T[::-1])]


def test_per_tile_files_reload_into_the_same_mesh(torus, tmp_path):
    mesh, tiles, offset, cube = torus
    manifest_path = write_tile_meshes(tmp_path / "out", mesh, tiles, offset, cube)
    manifest = json.loads(manifest_path.read_text())
    back = read_tile_meshes(tmp_path / "out")
    assert (back.n_vertices, back.n_faces) == (mesh.n_vertices, mesh.n_faces)
    np.testing.assert_array_equal(_triangles(back), _triangles(mesh))
    assert topology.boundary_loops(back.faces) == [] and topology.is_consistently_oriented(
        back.faces
    )
    # Each face in one file, each file only the vertices its faces use.
    pieces = [io.read_mesh(tmp_path / "out" / t["file"]) for t in manifest["tiles"]]
    assert sum(p.n_faces for p in pieces) == mesh.n_faces
    assert all(np.unique(p.faces).size == p.n_vertices for p in pieces)
    # Every tile of a torus cut 3 x 2 holds a piece that ends where its owned box does.
    for entry, piece in zip(manifest["tiles"], pieces, strict=True):
        low, high = (np.array([np.nan if v is None else v for v in b]) for b in entry["owned"])
        centroids = piece.vertices[piece.faces].mean(axis=1)
        assert not np.any(centroids < low) and not np.any(centroids >= high)
        np.testing.assert_allclose(entry["bounds"][:3], piece.vertices.min(axis=0))
    # Seams join tiles side by side in the grid, and their shared vertices are the pieces'.
    index = [tuple(t["index"]) for t in manifest["tiles"]]
    for seam in manifest["seams"]:
        a, b = (np.array(index[t]) for t in seam["tiles"])
        assert np.abs(a - b).max() == 1
        shared = {tuple(v) for v in pieces[seam["tiles"][0]].vertices} & {
            tuple(v) for v in pieces[seam["tiles"][1]].vertices
        }
        assert len(shared) == seam["vertices"] > 0


def test_every_face_goes_to_the_tile_that_owns_its_centroid(torus):
    mesh, tiles, offset, cube = torus
    owner = face_tiles(mesh, tiles, offset, cube)
    cubes = np.floor((mesh.vertices[mesh.faces].mean(axis=1) - offset) / cube)
    for position, tile in enumerate(tiles):
        inside = np.all((cubes >= tile.owned[0]) & (cubes < tile.owned[1]), axis=1)
        np.testing.assert_array_equal(owner == position, inside)


def test_a_changed_tile_file_is_refused_by_name(torus, tmp_path):
    mesh, tiles, offset, cube = torus
    manifest_path = write_tile_meshes(tmp_path / "out", mesh, tiles, offset, cube)
    first = json.loads(manifest_path.read_text())["tiles"][0]["file"]
    piece = io.read_mesh(tmp_path / "out" / first)
    io.write_mesh(tmp_path / "out" / first, Mesh(vertices=piece.vertices, faces=piece.faces[1:]))
    with pytest.raises(InputError, match=f"^{manifest_path}: the tiles weld into"):
        read_tile_meshes(manifest_path)
    (tmp_path / "none").mkdir()
    with pytest.raises(InputError, match=f"{MANIFEST}: cannot read"):
        read_tile_meshes(tmp_path / "none")


def test_cli_per_tile_options_are_checked_before_any_work(tmp_path, capsys):
    path = io.write_points(tmp_path / "s.ply", sample_torus(2_000, rng=1).points)
    (tmp_path / "file").write_text("")
    for extra, message in [
        (["-o", str(tmp_path / "out"), "--per-tile"], "--per-tile goes with --tiles"),
        (["-o", str(tmp_path / "file"), "--per-tile", "--tiles", "auto"], "is a file"),
        (["-o", str(tmp_path / "no" / "out"), "--per-tile", "--tiles", "auto"], "does not exist"),
    ]:
        assert main(["reconstruct", str(path), *extra]) == 2
        error = capsys.readouterr().err
        assert error.startswith("zeroset: error: ") and message in error
        assert error.count("\n") == 1
