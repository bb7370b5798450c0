"""The lean core: a quick import, and every optional feature naming the extra it needs."""

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from zeroset import InputError, MissingExtraError, io
from zeroset._extras import EXTRAS
from zeroset.cli import main
from zeroset.types import Mesh

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def _name(requirement: str) -> str:
    """The distribution a requirement names: 'laspy[lazrs]>=2.5' -> 'laspy'."""
    for mark in "[<>=!~ ;":
        requirement = requirement.split(mark)[0]
    return requirement.lower()


def test_import_loads_nothing_heavy():
    code = "import sys, zeroset; print(sorted({'numpy', 'scipy', 'numba'} & set(sys.modules)))"
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert loaded.strip() == "[]"


def test_every_optional_module_has_its_extra_and_none_is_core():
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    extras = project["optional-dependencies"]
    core = {_name(requirement) for requirement in project["dependencies"]}
    distributions = {"PIL": "pillow", "small_gicp": "small_gicp"}
    for module, extra in EXTRAS.items():
        declared = {_name(requirement) for requirement in extras[extra]}
        assert distributions.get(module, module).lower() in declared, (module, extra)
        assert distributions.get(module, module).lower() not in core
        assert extra in extras["all"][0]


def test_lazy_names_resolve():
    import zeroset

    for name in zeroset.__all__:
        assert getattr(zeroset, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        zeroset.nothing  # noqa: B018


def test_a_missing_extra_is_one_line_naming_it(tmp_path, monkeypatch, capsys):
    path = tmp_path / "scan.pcd"
    path.write_text(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
        "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n0 0 0\n"
    )
    monkeypatch.setitem(sys.modules, "pypcd4", None)  # as if not installed
    with pytest.raises(MissingExtraError, match=r"pip install 'zeroset\[pcd\]'"):
        io.read_points(path)
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "mesh.ply")]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert error == [
        "zeroset: error: reading .pcd files needs the 'pcd' extra: pip install 'zeroset[pcd]'"
    ]


def test_ply_meshes_need_no_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "trimesh", None)
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    io.write_mesh(tmp_path / "square.ply", Mesh(vertices=vertices, faces=faces))
    mesh = io.read_mesh(tmp_path / "square.ply")
    assert np.array_equal(mesh.vertices, vertices) and np.array_equal(mesh.faces, faces)
    with pytest.raises(MissingExtraError, match=r"'mesh' extra"):
        io.write_mesh(tmp_path / "square.obj", mesh)


def test_ply_polygons_become_fans(tmp_path):
    path = tmp_path / "quad.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 2\n4 0 1 2 3\n3 1 4 2\n"
    )
    assert io.read_mesh(path).faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]]


def test_results_copy_the_callers_arrays():
    vertices = np.zeros((3, 3))
    faces = np.array([[0, 1, 2]])
    mesh = Mesh(vertices=vertices, faces=faces)
    vertices[0] = 1.0  # still the caller's to change
    faces[0, 0] = 2
    assert mesh.vertices[0].tolist() == [0.0, 0.0, 0.0] and mesh.faces[0, 0] == 0
    with pytest.raises(ValueError, match="read-only"):
        mesh.vertices[0] = 1.0


@pytest.mark.parametrize(
    "blocked, options, extra",
    [
        ("trimesh", ["-o", "mesh.obj"], "mesh"),
        ("moderngl", ["-o", "m.ply", "--preview", "p.png"], "render"),
        ("matplotlib.figure", ["-o", "m.ply", "--inspect", "pipe"], "render"),
        ("moderngl", ["-o", "m.ply", "--inspect", "pipe"], "render"),
    ],
)
def test_a_missing_extra_stops_the_run_before_any_work(
    tmp_path, monkeypatch, capsys, blocked, options, extra
):
    cloud = tmp_path / "cloud.ply"
    io.write_points(cloud, np.random.default_rng(0).normal(size=(2000, 3)))
    monkeypatch.setitem(sys.modules, blocked, None)
    monkeypatch.chdir(tmp_path)
    assert main(["reconstruct", str(cloud), *options]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()  # no warning of a run: none ran
    assert line.endswith(f"needs the '{extra}' extra: pip install 'zeroset[{extra}]'")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["cloud.ply"]


def test_inspect_without_the_render_extra_stops_before_reading(tmp_path, monkeypatch, capsys):
    path = io.write_mesh(tmp_path / "m.ply", Mesh(vertices=np.eye(3), faces=[[0, 1, 2]]))
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    assert main(["inspect", str(path), "-o", str(tmp_path / "pipe")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith("needs the 'render' extra: pip install 'zeroset[render]'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.ply"]


def test_a_ply_mesh_without_end_header_is_refused_by_name(tmp_path):
    path = tmp_path / "cut.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n")
    with pytest.raises(InputError, match=r"cut.ply: not a valid PLY file \(no 'end_header'"):
        io.read_mesh(path)
