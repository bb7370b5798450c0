"""Every hostile input in tests/hostile.py ends cleanly, quickly and the same way everywhere.

Each case runs through the command line in-process (``zeroset.cli.main``) under a time limit,
and through the Python API (``io.read_points``, then ``reconstruct``, or ``io.write_mesh`` for
output problems). A few run through a real ``python -m zeroset`` process as well.
"""

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager

import numpy as np
import pytest
from scipy.spatial import cKDTree

from zeroset import io, reconstruct
from zeroset.cli import main
from zeroset.errors import InputError, ReconstructionError, ZerosetError
from zeroset.types import Mesh

from .hostile import CASES, Case

#: Seconds any case may take, in-process or in a subprocess.
LIMIT = 60
#: Cases also run through ``python -m zeroset``: a reader, the pipeline, an output, a mesh.
SUBPROCESS_CASES = (
    "binary_ply_claims_1e9_vertices",
    "nearly_collinear",
    "output_under_a_file",
    "flat_square",
)
#: Mesh vertices lie within this share of the cloud's bounding-box diagonal of a point,
#: and inside the box grown by it. The box spans the 1st to 99th percentiles, so that a
#: far outlier does not widen it.
MESH_TOLERANCE = 0.05

BY_NAME = {case.name: case for case in CASES}


@contextmanager
def time_limit(seconds: int = LIMIT):
    """Fail the test if the block runs longer than `seconds` (SIGALRM, main thread)."""

    def expire(signum, frame):
        pytest.fail(f"took longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    start = time.monotonic()
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert time.monotonic() - start < seconds  # a C call can hold the signal back


def _paths(case: Case, folder):
    """Build the case's files; return its input, its output and the path errors must name."""
    source = case.write(folder)
    output = folder / case.output
    return source, output, source if case.blame == "input" else output


def _check_one_line(err: str, blamed) -> None:
    """stderr is one line: ``zeroset: error: <blamed path>: ...``, no traceback, no bug."""
    assert "Traceback" not in err and "internal error" not in err, err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert err.startswith(f"zeroset: error: {blamed}: "), err


def _check_error_line(err: str, case: Case, blamed) -> None:
    """stderr is one line: ``zeroset: error: <blamed path>: ...<the case's message>...``."""
    _check_one_line(err, blamed)
    assert case.message in err, err


def _check_mesh(mesh: Mesh, points: np.ndarray) -> None:
    """The mesh has faces, and every vertex lies near the points and inside their extent."""
    assert mesh.n_faces > 0
    low, high = np.percentile(points, [1, 99], axis=0)
    slack = MESH_TOLERANCE * float(np.linalg.norm(high - low))
    distances, _ = cKDTree(points).query(mesh.vertices)
    assert distances.max() < slack
    assert np.all(mesh.vertices >= low - slack) and np.all(mesh.vertices <= high + slack)


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
@pytest.mark.slow
def test_command_line_ends_cleanly(case, tmp_path, capsys):
    source, output, blamed = _paths(case, tmp_path)
    before = output.read_bytes() if output.is_file() else None
    with time_limit():
        code = main(["reconstruct", str(source), "-o", str(output), "--quiet"])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    if case.expect == "mesh":
        assert code == 0, err
        _check_mesh(io.read_mesh(output), io.read_points(source).points)
    else:
        assert code == case.code, err
        _check_error_line(err, case, blamed)
        assert (output.read_bytes() if output.is_file() else None) == before


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
@pytest.mark.slow
def test_python_api_raises_zeroset_errors(case, tmp_path):
    source, output, blamed = _paths(case, tmp_path)
    expected = ReconstructionError if case.code == 1 else InputError
    if not case.api:
        pytest.skip("a refusal of the command line; the API replaces outputs by design")
    with time_limit():
        if case.blame == "output":
            cloud = io.read_points(source)
            mesh = Mesh(cloud.points[:3], np.array([[0, 1, 2]]))
            with pytest.raises(InputError) as info:
                io.write_mesh(output, mesh)
            assert str(info.value).startswith(f"{blamed}: ")
            return
        try:
            cloud = io.read_points(source)
        except ZerosetError as exc:
            assert case.expect != "mesh", exc
            assert type(exc) is InputError and str(exc).startswith(f"{blamed}: ")
            assert case.message in str(exc)
            return
        if case.expect == "mesh":
            _check_mesh(reconstruct(cloud.points).mesh, cloud.points)
            return
        with pytest.raises(expected) as info:
            reconstruct(cloud.points)
    assert case.message in str(info.value)


@pytest.mark.parametrize("name", SUBPROCESS_CASES)
@pytest.mark.slow
def test_real_entry_point_prints_no_traceback(name, tmp_path):
    case = BY_NAME[name]
    source, output, blamed = _paths(case, tmp_path)
    run = subprocess.run(
        [sys.executable, "-m", "zeroset", "reconstruct", str(source), "-o", str(output), "--quiet"],
        capture_output=True,
        text=True,
        timeout=LIMIT,
    )
    if case.expect == "mesh":
        assert run.returncode == 0, run.stderr
        assert output.is_file() and "Traceback" not in run.stderr
    else:
        assert run.returncode == case.code
        _check_error_line(run.stderr, case, blamed)
        assert run.stdout == ""


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes through any permission bits")
def test_unwritable_output_folder(tmp_path, capsys):
    source = BY_NAME["flat_square"].write(tmp_path)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code = main(["reconstruct", str(source), "-o", str(locked / "mesh.ply"), "--quiet"])
    finally:
        locked.chmod(0o700)
    assert code == 2
    _check_one_line(capsys.readouterr().err, locked / "mesh.ply")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads through any permission bits")
def test_unreadable_input(tmp_path, capsys):
    source = BY_NAME["flat_square"].write(tmp_path)
    source.chmod(0)
    try:
        code = main(["reconstruct", str(source), "-o", str(tmp_path / "mesh.ply"), "--quiet"])
    finally:
        source.chmod(0o600)
    assert code == 2
    _check_one_line(capsys.readouterr().err, source)


def test_the_corpus_is_large_and_its_names_unique():
    assert len(CASES) >= 30 and len(BY_NAME) == len(CASES)
    assert {case.expect.split(":")[0] for case in CASES} == {"mesh", "error"}
    assert {case.blame for case in CASES} == {"input", "output"}


@pytest.mark.parametrize(
    ("error", "code", "message"),
    [
        (ReconstructionError("no surface\nat all"), 1, "{input}: no surface at all"),
        (MemoryError("Unable to allocate 9 TiB"), 2, "{input}: out of memory (Unable to allocate"),
        (KeyError("bug"), 1, "internal error, please report it: KeyError: 'bug'"),
    ],
)
def test_any_failure_is_one_line(error, code, message, tmp_path, capsys, monkeypatch):
    def fail(args):
        raise error

    monkeypatch.setattr("zeroset.cli._run_reconstruct", fail)
    source = tmp_path / "scan.xyz"
    assert main(["reconstruct", str(source), "-o", str(tmp_path / "mesh.ply")]) == code
    err = capsys.readouterr().err
    assert err.startswith("zeroset: error: ") and err.count("\n") == 1
    assert message.format(input=source) in err
