"""Scanner formats (LAS, LAZ, PCD, E57), reduction while reading, and large coordinates."""

import json

import laspy
import numpy as np
import plyfile
import pye57
import pytest
from pypcd4 import Encoding, MetaData
from pypcd4 import PointCloud as Pcd

from zeroset import InputError, reconstruct
from zeroset import io as zio
from zeroset.cli import main
from zeroset.evaluate import points_to_mesh_distance
from zeroset.prepare import reduce_chunks
from zeroset.synthetic import sample_cylinder

UTM = np.array([500_123.25, 5_000_456.5, 312.0])  # a georeferenced offset, in metres


def _write_las(path, points, intensity=None, normals=None, scale=1e-4, offset=UTM):
    """Write points as LAS 1.4 (LAZ by suffix) with optional normals as extra dimensions."""
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.offsets, header.scales = offset, [scale] * 3
    if normals is not None:
        header.add_extra_dims([laspy.ExtraBytesParams(n, np.float32) for n in ("nx", "ny", "nz")])
    las = laspy.LasData(header)
    las.x, las.y, las.z = points.T
    if intensity is not None:
        las.intensity = intensity
    if normals is not None:
        las.nx, las.ny, las.nz = normals.T
    las.write(path)
    return path


@pytest.fixture(scope="module")
def pipe_scan():
    """A noisy open pipe at UTM-like coordinates, quantised to the LAS grid of 0.1 mm."""
    sample = sample_cylinder(20_000, radius=0.25, length=1.0, noise=0.002, rng=7)
    points = np.round((sample.points + UTM - UTM) / 1e-4) * 1e-4 + UTM
    return sample, points


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_keeps_coordinates_intensity_and_normals(tmp_path, pipe_scan, suffix):
    sample, points = pipe_scan
    intensity = np.arange(len(points)) % 65536
    path = _write_las(tmp_path / f"scan{suffix}", points, intensity=intensity,
                      normals=sample.normals)  # fmt: skip
    cloud = zio.read_points(path)
    np.testing.assert_allclose(cloud.points, points, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(cloud.intensity, intensity)
    np.testing.assert_allclose(cloud.normals, sample.normals, atol=1e-6)
    assert cloud.viewpoints is None and cloud.reduction == {}


def _write_ply(path, points, intensity):
    """Write a binary PLY of double x, y, z and float intensity."""
    columns = [("x", "f8"), ("y", "f8"), ("z", "f8"), ("intensity", "f4")]
    table = np.zeros(len(points), dtype=columns)
    for axis, name in enumerate("xyz"):
        table[name] = points[:, axis]
    table["intensity"] = intensity
    plyfile.PlyData([plyfile.PlyElement.describe(table, "vertex")]).write(str(path))
    return path


@pytest.mark.parametrize("suffix", [".las", ".laz", ".ply"])
def test_reading_in_chunks_equals_reducing_in_memory(tmp_path, pipe_scan, suffix):
    _, points = pipe_scan
    write = _write_ply if suffix == ".ply" else _write_las
    path = write(tmp_path / f"scan{suffix}", points, intensity=np.arange(len(points)))
    options = dict(crop=(*UTM - [1, 1, 1], *UTM + [1, 1, 0.8]), sample=0.7, voxel_size=0.02,
                   seed=3)  # fmt: skip
    chunked = zio.read_points(path, **options, chunk_points=1234)
    whole = zio.read_points(path)
    expected = reduce_chunks(
        lambda: [{"points": whole.points, "intensity": whole.intensity}],
        crop_box=options["crop"], sample=0.7, voxel_size=0.02, seed=3,
    )  # fmt: skip
    np.testing.assert_array_equal(chunked.points, expected.columns["points"])
    np.testing.assert_array_equal(chunked.intensity, expected.rows)  # intensity = row number
    assert chunked.reduction == expected.counts
    assert chunked.reduction["input_points"] == len(points)
    assert 0 < chunked.reduction["cropped"] and 0 < chunked.reduction["voxel_merged"]


def test_mesh_from_a_georeferenced_las_is_in_its_frame(tmp_path, pipe_scan):
    sample, points = pipe_scan
    path = _write_las(tmp_path / "scan.laz", points)
    result = reconstruct(zio.read_points(path).points)
    out = zio.write_mesh(tmp_path / "mesh.ply", result.mesh)
    written = zio.read_mesh(out)
    np.testing.assert_array_equal(written.vertices, result.mesh.vertices)  # float64, exact
    near_origin = reconstruct(points - UTM)
    np.testing.assert_allclose(
        result.dense_mesh.vertices - UTM, near_origin.dense_mesh.vertices, rtol=0, atol=1e-6
    )
    # The simplified meshes may differ where a collapse sat at the tolerance (rounding in
    # the far frame), never by more than the tolerance from the dense mesh.
    away = points_to_mesh_distance(written.vertices - UTM, near_origin.dense_mesh)
    assert away.max() <= near_origin.stats["tolerance"]
    assert np.median(sample.distance(written.vertices - UTM)) < 0.001  # noise is 2 mm


def test_las_errors(tmp_path, pipe_scan):
    _, points = pipe_scan
    good = _write_las(tmp_path / "good.las", points[:1000]).read_bytes()
    (tmp_path / "cut.las").write_bytes(good[: len(good) - 5000])
    with pytest.raises(InputError, match=r"cut.las: is truncated: the header says 1000 points"):
        zio.read_points(tmp_path / "cut.las")
    (tmp_path / "junk.laz").write_bytes(b"LASF" + bytes(range(256)) * 4)
    with pytest.raises(InputError, match=r"junk.laz: not a valid LAS/LAZ file"):
        zio.read_points(tmp_path / "junk.laz")
    header = laspy.LasHeader(point_format=0, version="1.2")
    laspy.LasData(header).write(tmp_path / "empty.las")
    with pytest.raises(InputError, match=r"empty.las: contains no points"):
        zio.read_points(tmp_path / "empty.las")
    with pytest.raises(InputError, match=r"empty.las: contains no points"):
        zio.read_points(tmp_path / "empty.las", voxel_size=0.1)


def _pcd(points, *, normals=None, intensity=None, viewpoint=None):
    """A pypcd4 cloud of float fields, with an optional header VIEWPOINT."""
    columns, fields = [points], ["x", "y", "z"]
    if normals is not None:
        columns.append(normals)
        fields += ["normal_x", "normal_y", "normal_z"]
    if intensity is not None:
        columns.append(intensity[:, None])
        fields.append("intensity")
    table = np.hstack(columns)
    cloud = Pcd.from_points(table, fields, [np.float64] * len(fields))
    if viewpoint is not None:
        metadata = cloud.metadata.model_copy(update={"viewpoint": (*viewpoint, 1.0, 0, 0, 0)})
        cloud = Pcd(MetaData.model_validate(metadata.model_dump()), cloud.pc_data)
    return cloud


@pytest.mark.parametrize("encoding", [Encoding.ASCII, Encoding.BINARY, Encoding.BINARY_COMPRESSED])
def test_pcd_encodings(tmp_path, encoding, rng):
    points = np.round(rng.normal(size=(500, 3)), 3)  # rounded, so that LZF can compress them
    normals = np.round(rng.normal(size=(500, 3)), 3)
    points[[3, 77]] = np.nan  # organised clouds mark missing returns with NaN
    path = tmp_path / "scan.pcd"
    _pcd(points, normals=normals, intensity=np.arange(500.0), viewpoint=(1, 2, 3)).save(
        path, encoding=encoding
    )
    assert f"DATA {encoding.value}\n".encode() in path.read_bytes()
    cloud = zio.read_points(path)
    keep = np.ones(500, dtype=bool)
    keep[[3, 77]] = False
    atol = 1e-9 if encoding is Encoding.ASCII else 0
    np.testing.assert_allclose(cloud.points, points[keep], atol=atol)
    np.testing.assert_allclose(cloud.normals, normals[keep], atol=atol)
    np.testing.assert_array_equal(cloud.intensity, np.flatnonzero(keep))
    np.testing.assert_array_equal(cloud.viewpoints, np.tile([1.0, 2, 3], (498, 1)))


def test_pcd_default_viewpoint_is_no_viewpoint(tmp_path, rng):
    _pcd(rng.normal(size=(50, 3))).save(tmp_path / "scan.pcd")
    cloud = zio.read_points(tmp_path / "scan.pcd")
    assert cloud.viewpoints is None and cloud.normals is None and cloud.intensity is None


def test_pcd_errors(tmp_path, rng):
    _pcd(rng.normal(size=(100, 3))).save(tmp_path / "good.pcd", encoding=Encoding.BINARY)
    good = (tmp_path / "good.pcd").read_bytes()
    (tmp_path / "cut.pcd").write_bytes(good[:-120])
    with pytest.raises(InputError, match=r"cut.pcd: is truncated: the header says 100 points, "
                       r"it holds 95"):  # fmt: skip
        zio.read_points(tmp_path / "cut.pcd")
    (tmp_path / "huge.pcd").write_bytes(good.replace(b"POINTS 100", b"POINTS 1000000000"))
    with pytest.raises(InputError, match=r"huge.pcd: is truncated: the header says 1000000000"):
        zio.read_points(tmp_path / "huge.pcd")
    compressible = np.round(rng.normal(size=(100, 3)), 2)
    _pcd(compressible).save(tmp_path / "z.pcd", encoding=Encoding.BINARY_COMPRESSED)
    packed = (tmp_path / "z.pcd").read_bytes()
    (tmp_path / "zhuge.pcd").write_bytes(packed.replace(b"POINTS 100", b"POINTS 1000000000"))
    with pytest.raises(InputError, match=r"zhuge.pcd: is truncated or corrupt"):
        zio.read_points(tmp_path / "zhuge.pcd")
    (tmp_path / "zcut.pcd").write_bytes(packed[:-50])
    with pytest.raises(InputError, match=r"zcut.pcd: is truncated or corrupt"):
        zio.read_points(tmp_path / "zcut.pcd")
    (tmp_path / "bad.pcd").write_text("VERSION 0.7\nFIELDS a b c\nDATA ascii\n1 2 3\n")
    with pytest.raises(InputError, match=r"bad.pcd: "):
        zio.read_points(tmp_path / "bad.pcd")
    header = good[: good.index(b"DATA")].decode().replace("FIELDS x y z", "FIELDS a b c")
    (tmp_path / "abc.pcd").write_bytes(header.encode() + good[good.index(b"DATA") :])
    with pytest.raises(InputError, match=r"abc.pcd: has no x, y, z fields \(fields: a, b, c\)"):
        zio.read_points(tmp_path / "abc.pcd")


def test_e57_scans_carry_their_scanner_positions(tmp_path, rng):
    local = rng.normal(size=(300, 3))
    path = str(tmp_path / "site.e57")
    poses = [((1.0, 0, 0, 0), (10.0, 20, 30)), ((0.0, 0, 0, 1), (-5.0, 0, 2))]  # 180° about z
    with pye57.E57(path, mode="w") as e57:
        for rotation, translation in poses:
            data = {f"cartesian{a}": local[:, i] for i, a in enumerate("XYZ")}
            data["intensity"] = np.linspace(0, 1, 300)
            e57.write_scan_raw(data, rotation=np.array(rotation), translation=np.array(translation))
    cloud = zio.read_points(path)
    assert cloud.points.shape == (600, 3) and cloud.intensity.shape == (600,)
    np.testing.assert_allclose(cloud.points[:300], local + [10, 20, 30], atol=1e-5)  # float32
    np.testing.assert_allclose(cloud.points[300:], local * [-1, -1, 1] + [-5, 0, 2], atol=1e-5)
    np.testing.assert_array_equal(cloud.viewpoints[:300], np.tile([10.0, 20, 30], (300, 1)))
    np.testing.assert_array_equal(cloud.viewpoints[300:], np.tile([-5.0, 0, 2], (300, 1)))


def test_e57_errors(tmp_path):
    (tmp_path / "junk.e57").write_bytes(b"ASTM-E57" + bytes(2000))
    with pytest.raises(InputError, match=r"junk.e57: not a valid E57 file"):
        zio.read_points(tmp_path / "junk.e57")


def test_cli_reduces_a_laz_while_reading(tmp_path, pipe_scan):
    _, points = pipe_scan
    path = _write_las(tmp_path / "scan.laz", points)
    out, report = tmp_path / "mesh.ply", tmp_path / "report.json"
    args = ["reconstruct", str(path), "-o", str(out), "--voxel", "0.01", "--report", str(report)]
    assert main([*args, "--quiet"]) == 0
    written = json.loads(report.read_text())
    reading = written["reading"]
    assert reading["input_points"] == len(points) > written["stats"]["input_points"]
    assert reading["voxel_merged"] == len(points) - written["stats"]["input_points"]
    assert written["stats"]["boundary_loops"] == 2 and written["stats"]["mesh_components"] == 1
    assert np.abs(zio.read_mesh(out).vertices.mean(axis=0)[:2] - UTM[:2]).max() < 0.05


def test_cli_colours_points_by_intensity(tmp_path, pipe_scan, capsys):
    pytest.importorskip("moderngl")
    _, points = pipe_scan
    local = points - UTM
    mesh = zio.write_mesh(tmp_path / "mesh.ply", reconstruct(local).mesh)
    with_intensity = _write_ply(tmp_path / "scan.ply", local, np.arange(len(points)))
    without = zio.write_points(tmp_path / "plain.ply", local)
    picture = tmp_path / "p.png"
    args = ["render", str(mesh), "-o", str(picture), "--quiet"]
    code = main([*args[:2], str(without), *args[2:], "--intensity"])
    assert code == 2 and "carries no intensity" in capsys.readouterr().err
    code = main([*args[:2], str(with_intensity), *args[2:], "--intensity"])
    if code == 2 and "OpenGL" in capsys.readouterr().err:
        pytest.skip("no OpenGL context on this machine")
    assert code == 0 and picture.read_bytes()[:4] == b"\x89PNG"
