"""Tests for zeroset.io: point readers, mesh round trips, atomic writes and error messages."""

from __future__ import annotations

import os
import re
import stat
import time
from types import SimpleNamespace

import numpy as np
import plyfile
import pytest

from zeroset import io as zio
from zeroset.errors import InputError
from zeroset.types import Mesh

# Octahedron whose vertices appear in the faces in index order, so formats that store corners
# per triangle (STL) read back with the same numbering. Faces are counter-clockwise outside.
_OCTA_VERTICES = np.array(
    [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], dtype=float
)
_OCTA_FACES = np.array(
    [[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2], [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]]
)


def _cloud(n=50, seed=0):
    """Return (points, unit normals) drawn with a fixed seed."""
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3))
    return points, points / np.linalg.norm(points, axis=1, keepdims=True)


def _octahedron(offset=0.0, seed=0):
    """Return a randomly scaled octahedron Mesh translated by `offset`."""
    rng = np.random.default_rng(seed)
    vertices = _OCTA_VERTICES * rng.uniform(0.5, 2.0, size=(6, 1)) + offset
    return Mesh(vertices=vertices, faces=_OCTA_FACES.copy())


def _write_ply(path, columns, *, encoding="binary_little_endian", extra=()):
    """Write a PLY `vertex` element from {name: (values, dtype)} with plyfile directly."""
    n = len(next(iter(columns.values()))[0])
    vertex = np.zeros(n, dtype=[(name, dtype) for name, (_, dtype) in columns.items()])
    for name, (values, _) in columns.items():
        vertex[name] = values
    text = encoding == "ascii"
    byte_order = ">" if encoding == "binary_big_endian" else "<"
    elements = [plyfile.PlyElement.describe(vertex, "vertex"), *extra]
    plyfile.PlyData(elements, text=text, byte_order=byte_order).write(str(path))
    return path


def _xyz_columns(values, dtype="f4", names=("x", "y", "z")):
    return {name: (values[:, i], dtype) for i, name in enumerate(names)}


# --- reading points -------------------------------------------------------------------------


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("with_normals", [False, True])
def test_read_ply_points(tmp_path, encoding, with_normals):
    points, normals = _cloud()
    rng = np.random.default_rng(0)
    columns = _xyz_columns(points)
    if with_normals:
        columns |= _xyz_columns(normals, names=("nx", "ny", "nz"))
    columns |= {c: (rng.integers(0, 256, len(points)), "u1") for c in ("red", "green", "blue")}
    path = _write_ply(tmp_path / "scan.ply", columns, encoding=encoding)
    before = path.read_bytes()

    cloud = zio.read_points(path)

    assert cloud.points.dtype == np.float64 and cloud.points.shape == (50, 3)
    np.testing.assert_array_equal(cloud.points, points.astype(np.float32))
    if with_normals:
        np.testing.assert_array_equal(cloud.normals, normals.astype(np.float32))
    else:
        assert cloud.normals is None
    assert cloud.viewpoints is None
    assert cloud.source == str(path)
    assert path.read_bytes() == before


@pytest.mark.parametrize(
    "names", [("vp_x", "vp_y", "vp_z"), ("viewpoint_x", "viewpoint_y", "viewpoint_z")]
)
def test_read_ply_viewpoints(tmp_path, names):
    points, _ = _cloud()
    sensors = np.repeat([[0.0, 0.0, 10.0], [5.0, 5.0, 10.0]], 25, axis=0)
    columns = _xyz_columns(points, "f8") | _xyz_columns(sensors, "f8", names)
    cloud = zio.read_points(_write_ply(tmp_path / "scan.ply", columns))
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.viewpoints, sensors)


def test_read_ply_integer_points_ignore_faces_and_range_grid(tmp_path):
    points = np.random.default_rng(0).integers(-1000, 1000, size=(20, 3))
    face = np.zeros(2, dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = [[0, 1, 2], [2, 3, 4]]
    grid = np.zeros(4, dtype=[("vertex_indices", "O")])
    grid["vertex_indices"] = [
        np.array([0], "i4"),
        np.array([], "i4"),
        np.array([1], "i4"),
        np.array([2], "i4"),
    ]
    extra = (
        plyfile.PlyElement.describe(face, "face"),
        plyfile.PlyElement.describe(grid, "range_grid"),
    )
    path = _write_ply(tmp_path / "scan.ply", _xyz_columns(points, "i4"), extra=extra)
    cloud = zio.read_points(path)
    assert cloud.points.dtype == np.float64
    np.testing.assert_array_equal(cloud.points, points)


@pytest.mark.parametrize("vertex_list", [False, True])
def test_ascii_ply_vertices_read_by_numpy_match_plyfile(tmp_path, monkeypatch, vertex_list):
    # Rows of the elements before the vertices (one line each) are skipped, those after
    # them never read; a vertex element with a list property is left to plyfile.
    rng = np.random.default_rng(1)
    points, normals = rng.normal(size=(30, 3)), rng.normal(size=(30, 3))
    columns = {**_xyz_columns(points, "f8"), **_xyz_columns(normals, "f8", ("nx", "ny", "nz"))}
    n = len(points)
    dtype = [(name, kind) for name, (_, kind) in columns.items()]
    dtype += [("labels", "O")] if vertex_list else []
    vertex = np.zeros(n, dtype=dtype)
    for name, (values, _) in columns.items():
        vertex[name] = values
    if vertex_list:
        vertex["labels"] = [np.arange(i % 3, dtype="i4") for i in range(n)]
    camera = np.zeros(2, dtype=[("f", "f4")])
    grid = np.zeros(3, dtype=[("vertex_indices", "O")])
    grid["vertex_indices"] = [np.array([0], "i4"), np.array([], "i4"), np.array([5, 6], "i4")]
    elements = [
        plyfile.PlyElement.describe(camera, "camera"),
        plyfile.PlyElement.describe(vertex, "vertex"),
        plyfile.PlyElement.describe(grid, "range_grid"),
    ]
    path = tmp_path / "scan.ply"
    plyfile.PlyData(elements, text=True).write(str(path))
    used = []
    monkeypatch.setattr(
        zio._ply,
        "_plyfile_vertices",
        lambda p, real=zio._ply._plyfile_vertices: used.append(p) or real(p),
    )
    cloud = zio.read_points(path)
    np.testing.assert_allclose(cloud.points, points, rtol=1e-12)
    np.testing.assert_allclose(cloud.normals, normals, rtol=1e-12)
    assert bool(used) == vertex_list


def test_read_binary_ply_in_one_go(tmp_path):
    # plyfile reads binary rows one at a time unless memory-mapped: 5 s per million rows.
    points = np.random.default_rng(0).random((1_000_000, 3))
    path = zio.write_points(tmp_path / "scan.ply", points)
    start = time.perf_counter()
    cloud = zio.read_points(path)
    assert time.perf_counter() - start < 2.0
    np.testing.assert_array_equal(cloud.points, points)


def test_read_ply_checks_the_length_before_reading(tmp_path):
    path = tmp_path / "scan.ply"
    lists = "".join(f"property list uchar float {axis}\n" for axis in "xyz")
    rows = "0 0 0\n0 0 0"  # two rows of empty lists, the last without its newline
    path.write_text(f"ply\nformat ascii 1.0\nelement vertex 2\n{lists}end_header\n{rows}")
    with pytest.raises(InputError, match="'vertex' properties x, y, z are lists, not numbers"):
        zio.read_points(path)
    path.write_text(f"ply\nformat ascii 1.0\nelement vertex 3\n{lists}end_header\n{rows}")
    with pytest.raises(InputError, match="declares 3 vertex rows, at least 18 bytes, but only 12"):
        zio.read_points(path)


def test_read_xyz_with_spaces(tmp_path):
    points, _ = _cloud()
    lines = [f"  {x:.17g}   {y:.17g}\t{z:.17g}  " for x, y, z in points]
    path = tmp_path / "scan.xyz"
    path.write_text("\n".join(lines) + "\n")
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    assert cloud.normals is None


def test_read_xyz_six_columns_are_normals(tmp_path):
    points, normals = _cloud()
    path = tmp_path / "scan.xyz"
    np.savetxt(path, np.hstack([points, normals]), fmt="%.17g")
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.normals, normals)


def test_read_3dtk_scan_ignores_colour_columns(tmp_path):
    points, _ = _cloud()
    colours = np.tile([255.0, 128.0, 0.0], (len(points), 1))
    path = tmp_path / "scan000.3d"
    np.savetxt(path, np.hstack([points * 100.0, colours]), fmt="%.17g")
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points * 100.0)
    assert cloud.normals is None


def test_read_csv_with_header(tmp_path):
    points, normals = _cloud()
    path = tmp_path / "scan.csv"
    np.savetxt(
        path,
        np.hstack([points, normals]),
        fmt="%.17g",
        delimiter=", ",
        header="x,y,z,nx,ny,nz",
        comments="",
    )
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.normals, normals)


def test_read_csv_colour_header_is_not_normals(tmp_path):
    points, _ = _cloud()
    colours = np.random.default_rng(0).integers(0, 256, size=(50, 3))
    path = tmp_path / "scan.csv"
    np.savetxt(
        path,
        np.hstack([points, colours]),
        fmt="%.17g",
        delimiter=",",
        header="//X,Y,Z,R,G,B",
        comments="",
    )
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    assert cloud.normals is None


def test_read_txt_with_comments(tmp_path):
    points, _ = _cloud(n=4)
    intensity = np.arange(4)
    lines = ["# exported by a scanner", "", "# x y z intensity"]
    lines += [
        f"{x:.17g} {y:.17g} {z:.17g} {i}  # point {i}"
        for (x, y, z), i in zip(points, intensity, strict=True)
    ]
    lines.insert(5, "# a comment between rows")
    path = tmp_path / "scan.txt"
    path.write_text("\n".join(lines) + "\n")
    np.testing.assert_array_equal(zio.read_points(path).points, points)


def test_read_pts_skips_count_line(tmp_path):
    points, _ = _cloud(n=10)
    rgb = np.zeros((10, 4))
    path = tmp_path / "scan.pts"
    np.savetxt(path, np.hstack([points, rgb]), fmt="%.17g", header="10", comments="")
    np.testing.assert_array_equal(zio.read_points(path).points, points)


@pytest.mark.parametrize("columns", [3, 6, 7])
def test_read_npy(tmp_path, columns):
    table = np.random.default_rng(0).normal(size=(30, columns))
    path = tmp_path / "scan.npy"
    np.save(path, table)
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, table[:, :3])
    if columns == 6:
        np.testing.assert_array_equal(cloud.normals, table[:, 3:])
    else:
        assert cloud.normals is None


def test_read_npz(tmp_path):
    points, normals = _cloud()
    path = tmp_path / "scan.npz"
    np.savez(path, extra=np.zeros(2), points=points, normals=normals, viewpoints=np.ones(3))
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.normals, normals)
    np.testing.assert_array_equal(cloud.viewpoints, np.ones((50, 3)))


def test_read_npz_first_array_without_points_key(tmp_path):
    points, _ = _cloud()
    path = tmp_path / "scan.npz"
    np.savez(path, points.astype(np.float32))
    np.testing.assert_array_equal(zio.read_points(path).points, points.astype(np.float32))


def test_read_points_result_is_read_only(tmp_path):
    path = tmp_path / "scan.npy"
    np.save(path, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="read-only"):
        zio.read_points(path).points[0, 0] = 1.0


# --- writing points -------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".ply", ".xyz", ".npy"])
@pytest.mark.parametrize("with_normals", [False, True])
def test_write_points_round_trip(tmp_path, suffix, with_normals):
    points, normals = _cloud()
    points = points * 1e6 + 6e6
    path = tmp_path / f"out{suffix}"
    returned = zio.write_points(str(path), points, normals=normals if with_normals else None)
    assert returned == path
    cloud = zio.read_points(path)
    np.testing.assert_array_equal(cloud.points, points)
    if with_normals:
        np.testing.assert_array_equal(cloud.normals, normals)
    else:
        assert cloud.normals is None


# --- meshes ---------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", zio.MESH_FORMATS)
@pytest.mark.parametrize("binary", [True, False])
def test_mesh_round_trip(tmp_path, suffix, binary):
    mesh = _octahedron(offset=np.random.default_rng(1).normal(size=3))
    path = zio.write_mesh(tmp_path / f"mesh{suffix}", mesh, binary=binary)
    back = zio.read_mesh(path)
    assert back.vertices.dtype == np.float64 and back.faces.dtype == np.int64
    np.testing.assert_array_equal(back.faces, mesh.faces)
    if suffix == ".ply":
        np.testing.assert_array_equal(back.vertices, mesh.vertices)
    else:
        np.testing.assert_allclose(back.vertices, mesh.vertices, rtol=1e-6, atol=1e-12)


def test_ply_mesh_keeps_precision_of_large_coordinates(tmp_path):
    rng = np.random.default_rng(0)
    offset = np.array([6e6, 6e6, 100.0]) + rng.uniform(0, 1, size=3)
    mesh = _octahedron(offset=offset)
    path = zio.write_mesh(tmp_path / "site.ply", mesh)
    assert b"property double x" in path.read_bytes()[:300]
    back = zio.read_mesh(path)
    assert np.abs(back.vertices - mesh.vertices).max() < 1e-6
    np.testing.assert_array_equal(back.faces, mesh.faces)


def test_ascii_ply_mesh(tmp_path):
    path = zio.write_mesh(tmp_path / "mesh.ply", _octahedron(), binary=False)
    assert b"format ascii 1.0" in path.read_bytes()[:40]


def test_write_mesh_accepts_any_object_with_vertices_and_faces(tmp_path):
    class Soup:
        vertices = _OCTA_VERTICES.tolist()
        faces = _OCTA_FACES.tolist()

    back = zio.read_mesh(zio.write_mesh(tmp_path / "mesh.off", Soup()))
    np.testing.assert_array_equal(back.faces, _OCTA_FACES)


# --- atomic writes --------------------------------------------------------------------------


def _failing_writer(path, *args, **kwargs):
    """Write half a file to the temporary path, then fail."""
    assert path.exists()
    path.write_bytes(b"half a file")
    raise RuntimeError("disk on fire")


@pytest.mark.parametrize(
    ("table", "write", "name"),
    [
        ("_MESH_WRITERS", lambda p: zio.write_mesh(p, _octahedron()), "mesh.ply"),
        ("_POINT_WRITERS", lambda p: zio.write_points(p, np.zeros((3, 3))), "points.xyz"),
    ],
)
def test_failed_write_leaves_target_untouched(tmp_path, monkeypatch, table, write, name):
    target = tmp_path / name
    target.write_bytes(b"previous contents")
    monkeypatch.setitem(getattr(zio, table), target.suffix, _failing_writer)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write(target)
    assert target.read_bytes() == b"previous contents"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_write_replaces_existing_file_and_keeps_its_permissions(tmp_path):
    target = tmp_path / "mesh.obj"
    target.write_text("old")
    target.chmod(0o640)
    zio.write_mesh(target, _octahedron())
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mesh.obj"]
    assert zio.read_mesh(target).n_faces == 8


def test_new_file_gets_umask_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        path = zio.write_points(tmp_path / "points.npy", np.zeros((3, 3)))
    finally:
        os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


# --- errors ---------------------------------------------------------------------------------


def _ply_text(header_lines, rows=("0 0 0",)):
    return "\n".join(["ply", "format ascii 1.0", *header_lines, "end_header", *rows, ""])


_NAN_ROWS = np.zeros((20, 3))
_NAN_ROWS[17] = np.nan  # three values
_NAN_ROWS[19, 1] = np.inf  # and one more

READ_ERRORS = [
    (
        "scan.ply",
        _ply_text(["element vertex 1", "property float x", "property flot y", "property float z"]),
        r"not a valid PLY file \(line 5: field type 'flot'",
    ),
    (
        "scan.ply",
        _ply_text(["element vertex 3", "property float x", "property float y", "property float z"]),
        "header declares 3 vertex rows, at least 18 bytes, but only 7 bytes follow it; "
        "the file is truncated",
    ),
    ("scan.ply", "", r"is empty \(0 bytes\)"),
    ("scan.ply", "x y z\n1 2 3\n", "not a valid PLY file: it is text"),
    (
        "scan.ply",
        _ply_text(
            ["element vertex 0", "property float x", "property float y", "property float z"],
            rows=(),
        ),
        "contains no points",
    ),
    (
        "scan.ply",
        _ply_text(["element face 0", "property list uchar int vertex_indices"], rows=()),
        "has no 'vertex' element",
    ),
    (
        "scan.ply",
        _ply_text(
            [
                "element vertex 1",
                "property float x",
                "property float y",
                "property float z",
                "property float nx",
            ],
            rows=("0 0 0 1",),
        ),
        "has 'vertex' properties nx but not ny, nz",
    ),
    (
        "scan.ply",
        _ply_text(["element vertex 1", "property float u", "property float v", "property float w"]),
        "no x, y, z properties",
    ),
    ("scan.xyz", "", "contains no points"),
    ("scan.txt", "# nothing\n\n# here\n", "contains no points"),
    (
        "scan.xyz",
        "\n".join(" ".join(map(str, row)) for row in _NAN_ROWS),
        r"4 non-finite values in 2 rows \(first at row 17\); drop or impute them first",
    ),
    ("scan.csv", "x,y,z\n1,2,3\n4,5,6\n7,8\n", "line 4 has 2 columns; expected at least 3"),
    ("scan.xyz", "1 2\n3 4\n", "line 1 has 2 columns; expected at least 3"),
    ("scan.xyz", "x y z\n1\n", "line 2 has 1 column; expected at least 3"),
    ("scan.xyz", "1 2 3 4 5 6\n1 2 3\n", "line 2 has 3 columns; expected at least 6"),
    ("scan.xyz", "1 2 3\n4 five 6\n", "line 2: cannot read 'five' as a number"),
    ("scan.xyz", b"\xff\xfe\x00\x01garbage", "it is UTF-16 text; save it as UTF-8"),
    ("scan.xyz", b"1 2 3\n" + "4 5 6 # é\n".encode("latin-1"), "not a UTF-8 text file"),
    ("scan.xyz", b"ply\nformat ascii 1.0\n", "it is a PLY file; rename it to .ply"),
    ("scan.npy", b"not numpy at all", "not a valid NPY or NPZ file"),
    ("scan.npy", b"\x93NUMPY\x01\x00\x76\x00{'descr'", "not a valid NPY or NPZ file"),
]


@pytest.mark.parametrize(("name", "content", "message"), READ_ERRORS)
def test_read_points_errors(tmp_path, name, content, message):
    path = tmp_path / name
    if isinstance(content, str):
        path.write_text(content)
    else:
        path.write_bytes(content)
    with pytest.raises(InputError, match=message) as info:
        zio.read_points(path)
    assert str(info.value).startswith(f"{path}: ")


@pytest.mark.parametrize(
    ("table", "message"),
    [
        (np.zeros((5, 2)), r"points must have shape \(N, 3\); got \(5, 2\)"),
        (np.zeros((0, 3)), "contains no points"),
        (np.array(["a", "b", "c"]), "points must be an array of real numbers"),
    ],
)
def test_read_npy_errors(tmp_path, table, message):
    path = tmp_path / "scan.npy"
    np.save(path, table)
    with pytest.raises(InputError, match=f"^{re.escape(str(path))}: {message}"):
        zio.read_points(path)


def test_read_npz_errors(tmp_path):
    empty = tmp_path / "empty.npz"
    np.savez(empty)
    with pytest.raises(InputError, match="empty.npz: contains no arrays"):
        zio.read_points(empty)
    mismatched = tmp_path / "bad.npz"
    np.savez(mismatched, points=np.zeros((4, 3)), normals=np.zeros((3, 3)))
    with pytest.raises(InputError, match="bad.npz: has 4 points but 3 normals"):
        zio.read_points(mismatched)


@pytest.mark.parametrize("read", [zio.read_points, zio.read_mesh])
def test_read_missing_file_and_directory(tmp_path, read):
    missing = tmp_path / "missing.ply"
    with pytest.raises(InputError, match=f"^{re.escape(str(missing))}: no such file$"):
        read(missing)
    folder = tmp_path / "folder.ply"
    folder.mkdir()
    with pytest.raises(InputError, match="folder.ply: is a directory"):
        read(folder)


def test_unknown_suffixes(tmp_path):
    with pytest.raises(
        InputError,
        match=r"scan.xyz2: unknown point format '.xyz2'; "
        r"supported: .3d, .csv, .e57, .las, .laz, .npy, .npz, .pcd, .ply, .pts",
    ):
        zio.read_points(tmp_path / "scan.xyz2")
    with pytest.raises(InputError, match="scan: has no suffix; supported"):
        zio.read_points(tmp_path / "scan")
    with pytest.raises(InputError, match=r"unknown mesh format '.xyz'; supported: .obj, .off"):
        zio.read_mesh(tmp_path / "mesh.xyz")
    with pytest.raises(InputError, match=r"unknown mesh format '.glb'"):
        zio.write_mesh(tmp_path / "mesh.glb", _octahedron())
    with pytest.raises(InputError, match=r"unknown point format '.csv'; supported: .npy, .ply"):
        zio.write_points(tmp_path / "points.csv", np.zeros((3, 3)))


def test_suffix_is_case_insensitive(tmp_path):
    path = zio.write_mesh(tmp_path / "MESH.PLY", _octahedron())
    assert zio.read_mesh(path).n_vertices == 6


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("mesh.off", "garbage\n", "not a valid OFF file"),
        ("mesh.stl", "garbage", "contains no triangles"),
        ("mesh.obj", "", "contains no triangles"),
        ("mesh.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 4\n", "non-finite"),
    ],
)
def test_read_mesh_errors(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(InputError, match=f"^{re.escape(str(path))}: .*{message}"):
        zio.read_mesh(path)


def test_read_mesh_of_point_ply_has_no_triangles(tmp_path):
    path = zio.write_points(tmp_path / "points.ply", np.eye(3))
    with pytest.raises(InputError, match="points.ply: contains no triangles"):
        zio.read_mesh(path)


def test_write_errors(tmp_path):
    with pytest.raises(InputError, match=r"mesh.ply: directory .*nowhere does not exist"):
        zio.write_mesh(tmp_path / "nowhere" / "mesh.ply", _octahedron())
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(InputError, match="dir.ply: is a directory"):
        zio.write_points(tmp_path / "dir.ply", np.zeros((3, 3)))
    with pytest.raises(InputError, match="mesh.ply: mesh has no faces"):
        zio.write_mesh(tmp_path / "mesh.ply", Mesh(np.zeros((3, 3)), np.zeros((0, 3), int)))
    # a Mesh checks its faces itself; any object with vertices and faces is checked here
    broken = SimpleNamespace(vertices=np.zeros((3, 3)), faces=np.array([[0, 1, 3]]))
    with pytest.raises(InputError, match=r"mesh.ply: mesh faces index vertices outside"):
        zio.write_mesh(tmp_path / "mesh.ply", broken)
    with pytest.raises(InputError, match=r"points.xyz: points contain 1 non-finite"):
        zio.write_points(tmp_path / "points.xyz", [[0, 0, np.nan]])
    with pytest.raises(InputError, match=r"points.xyz: 1 points but 2 normals"):
        zio.write_points(tmp_path / "points.xyz", np.zeros((1, 3)), normals=np.zeros((2, 3)))
    with pytest.raises(TypeError, match="mesh must have vertices and faces"):
        zio.write_mesh(tmp_path / "mesh.ply", np.zeros((3, 3)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.ply"]
