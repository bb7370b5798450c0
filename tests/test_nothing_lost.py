"""Nothing lost: inputs are never written, outputs are replaced atomically and only on request."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from zeroset import io as zio
from zeroset.cli import main
from zeroset.synthetic import sample_sphere

KILL_SCRIPT = """
import sys
import numpy as np
from zeroset import io
from zeroset.types import Mesh

n = 2_000_000
vertices = np.random.default_rng(0).random((n, 3))
faces = np.random.default_rng(1).integers(0, n, (2 * n, 3))
print("writing", flush=True)
io.write_mesh(sys.argv[1], Mesh(vertices=vertices, faces=faces), binary=False)
print("written", flush=True)
"""


@pytest.fixture
def cloud_file(tmp_path):
    path = tmp_path / "sphere.ply"
    zio.write_points(path, sample_sphere(3000, noise=0.003, rng=3).points)
    return path


def test_sigkill_while_writing_leaves_the_previous_output_whole(tmp_path, tetra_mesh):
    target = zio.write_mesh(tmp_path / "mesh.ply", tetra_mesh)
    before = target.read_bytes()
    writer = subprocess.Popen(
        [sys.executable, "-c", KILL_SCRIPT, str(target)], stdout=subprocess.PIPE
    )
    try:
        assert writer.stdout.readline() == b"writing\n"
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:  # until a megabyte is written, wherever it goes
            if any(p.stat().st_size > 1 << 20 for p in tmp_path.iterdir()):
                break
            time.sleep(0.005)
        else:
            pytest.fail("the writer wrote nothing in 120 s")
        writer.send_signal(signal.SIGKILL)
    finally:
        writer.kill()
        writer.wait()
    assert writer.returncode == -signal.SIGKILL
    assert target.read_bytes() == before  # the old mesh, whole
    assert zio.read_mesh(target).n_faces == tetra_mesh.n_faces
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == [
        "mesh.ply"
    ]


def _reconstruct(cloud_file, out, *extra):
    return main(["reconstruct", str(cloud_file), "-o", str(out), "--quiet", *extra])


def test_existing_output_needs_force(cloud_file, tmp_path, capsys):
    out = tmp_path / "mesh.ply"
    out.write_bytes(b"precious")
    assert _reconstruct(cloud_file, out) == 2
    assert capsys.readouterr().err.strip() == (
        f"zeroset: error: {out}: exists; add --force to replace it"
    )
    assert out.read_bytes() == b"precious"
    assert _reconstruct(cloud_file, out, "--force") == 0
    assert zio.read_mesh(out).n_faces > 100


@pytest.mark.parametrize("alias", ["same", "dotted", "symlink", "hardlink"])
def test_the_input_is_never_an_output(cloud_file, tmp_path, capsys, alias):
    before = cloud_file.read_bytes()
    out = {
        "same": cloud_file,
        "dotted": tmp_path / "." / cloud_file.name,
        "symlink": tmp_path / "link.ply",
        "hardlink": tmp_path / "hard.ply",
    }[alias]
    if alias == "symlink":
        out.symlink_to(cloud_file)
    if alias == "hardlink":
        os.link(cloud_file, out)
    assert _reconstruct(cloud_file, out, "--force") == 2
    assert f"{out}: is the input file {cloud_file}" in capsys.readouterr().err
    assert cloud_file.read_bytes() == before


def test_one_file_for_two_outputs_is_refused(cloud_file, tmp_path, capsys):
    out = tmp_path / "mesh.ply"
    assert _reconstruct(cloud_file, out, "--preview", str(out)) == 2
    assert "named for two outputs" in capsys.readouterr().err
    assert not out.exists()


def test_reconstruct_leaves_its_input_untouched(cloud_file, tmp_path):
    before, stat = cloud_file.read_bytes(), cloud_file.stat()
    assert _reconstruct(cloud_file, tmp_path / "mesh.ply", "--voxel", "0.02") == 0
    assert cloud_file.read_bytes() == before
    assert cloud_file.stat().st_mtime_ns == stat.st_mtime_ns
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mesh.ply", "sphere.ply"]


def test_other_commands_refuse_to_overwrite(cloud_file, tmp_path, capsys, tetra_mesh):
    mesh = zio.write_mesh(tmp_path / "tetra.ply", tetra_mesh)
    taken = tmp_path / "taken.json"
    taken.write_text("{}")
    assert main(["evaluate", str(mesh), "--json", str(taken), "--quiet"]) == 2
    assert main(["synth", "sphere", "-o", str(cloud_file), "--quiet"]) == 2
    assert main(["optimize", str(mesh), str(cloud_file), "-o", str(mesh), "--force"]) == 2
    err = capsys.readouterr().err
    assert f"{taken}: exists" in err and f"{cloud_file}: exists" in err
    assert f"{mesh}: is the input file" in err
    assert taken.read_text() == "{}"
    np.testing.assert_array_equal(zio.read_mesh(mesh).faces, tetra_mesh.faces)
