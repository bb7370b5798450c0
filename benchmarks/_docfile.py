"""Shared by the benchmark scripts: each owns one section of docs/benchmarks.md.

A section is the text between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``. A script
replaces its own section and keeps everything else in the file byte for byte: the shared
introduction at the top and the other scripts' sections. A missing section is added in the
order of `SECTIONS`; a missing file starts with `INTRO`. Every write goes through a temporary
file in the same folder and `os.replace`, so an interrupted run leaves the old file intact.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

SECTIONS = (
    "accuracy",
    "ablation",
    "first-run",
    "phase1",
    "phase2",
    "cubes",
    "simplify",
    "report",
    "large",
    "tiles",
    "tile-rings",
    "scans",
    "registered",
    "inspection",
    "runs",
    "real",
    "peers",
    "holes",
    "live",
    "live-robot",
)

INTRO = """# Benchmarks

Measured by the scripts in `benchmarks/`, run by hand. Each script rewrites only its own
section of this file, between the HTML comments `<!-- NAME:begin -->` and `<!-- NAME:end -->`,
and keeps the rest (this introduction included):

- [Accuracy](#accuracy-of-the-surface-planes-and-jets): bias and error of Hoppe's planes and
  the blended jets against the truth, an open pipe from 5k to 1M points and spheres of five
  radii (`benchmarks/bench_accuracy.py`).
- [Ablation](#ablation-each-rule-of-phase-1-switched-off): each rule of phase 1 switched off
  in turn on the benchmark clouds and on two held-out real scans
  (`benchmarks/bench_ablation.py`).
- [First run](#first-run-compiling-on-a-fresh-install): `zeroset demo` with no compiled
  kernels, as after `pip install`, beside a warm run (`benchmarks/bench_first_run.py`).
- [Phase 1](#phase-1-speed-and-memory): speed and memory of `zeroset.reconstruct()` on a noisy
  open pipe, 20k to 1M points (`benchmarks/bench_phase1.py`).
- [Phase 2](#phase-2-mesh-optimisation): speed, memory and accuracy of `zeroset.optimize()`
  on phase-1 meshes of a noisy open pipe, 10k faces with 100k points and 100k faces with 1M
  points (`benchmarks/bench_phase2.py`).
- [Method of Cubes](#method-of-cubes-against-marching-cubes): the two contourings of phase 1
  side by side, and phase 2 started from each (`benchmarks/bench_cubes.py`).
- [Few triangles within a tolerance](#few-triangles-within-a-tolerance-simplify): the default
  simplified mesh against the dense one and Open3D's quadric decimation, and Chamfer-L1
  against faces (`benchmarks/bench_simplify.py`).
- [Pictures and HTML reports](#pictures-and-html-reports-of-large-meshes): time to draw a
  picture and write a report of up to 1M triangles, the report's size and its load time in a
  browser (`benchmarks/bench_report.py`).
- [Larger than memory](#larger-than-memory-a-100m-point-laz-at-reduced-density): a
  100M-point LAZ read in chunks and voxel-sampled while read, wall time and peak memory
  (`benchmarks/bench_large.py`).
- [Tiled on Dask](#tiled-on-dask-a-20m-point-pipe-network): a 20M-point pipe rack
  reconstructed in tiles on a local Dask cluster of one and two worker processes, wall
  time and peak memory per worker (`benchmarks/bench_tiles.py`).
- [Refinement rings in tiles](#refinement-rings-in-tiles): with how many rings of faces
  around its own a tile refines to give the untiled mesh (`benchmarks/bench_tile_rings.py`).
- [Anisotropic laser scans](#anisotropic-laser-scans): simulated in-pipe scans and real
  rotating-laser scans, zeroset beside Open3D and PyMeshLab (`benchmarks/bench_scans.py`,
  needs the `bench` extra).
- [Several scans with poses](#several-scans-with-poses): the ten Stanford bunny range scans
  with their poses, as given and registered, against Stanford's reconstruction; how often the
  sensors and the spanning tree orient a normal differently (`benchmarks/bench_registered.py`).
- [Inspection](#inspection): dents, bulges and ovality found in simulated in-pipe scans and
  elbows against the recorded truth, clean pipes and a tee, and a 20 m pipe of 2.26M points
  reconstructed and inspected in one run (`benchmarks/bench_inspect.py`).
- [Inspection of pipe runs](#inspection-of-pipe-runs): random runs with bends, tees, joints
  and defects, scanned by the in-pipe model, against their truth: the centreline, defects,
  false defects and branches, joints, ovality, the threshold with and without joints, and
  the time of a 1M-point inspection (`benchmarks/bench_runs.py`).
- [Inspection of real scans](#inspection-of-real-scans): the real sewer pipe in shared/data
  as it is, moved, reversed and halved, and with dents, bulges, deformations and joints of
  known size put into its points (`benchmarks/bench_real.py`).
- [Peers](#peers-zeroset-against-open3d-pymeshlab-poissonrecon-and-vtk): zeroset against the
  tools a user would otherwise pick (Open3D, PyMeshLab, Kazhdan's PoissonRecon with its
  trimming, VTK) on synthetic pipes, a sphere and a torus with exact ground truth and on real
  scans (`benchmarks/bench_peers.py`, needs the `bench` extra; Open3D also needs Debian's
  `libusb-1.0-0`).
- [Holes in real scans](#holes-in-real-scans-beside-poissonrecons): each boundary loop of
  zeroset's bunny and gargoyle beside the rims of PoissonRecon's trimmed meshes
  (`benchmarks/bench_holes.py`, needs the `bench` extra).
"""


def markers(name: str) -> tuple[str, str]:
    """The begin and end comments of section `name`."""
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write `data` (text as UTF-8) to `path` through a temporary file and os.replace."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as file:
            file.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.chmod(temporary, 0o644)  # mkstemp makes it private; a document is world-readable
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def replace_section(path: Path, name: str, body: str) -> None:
    """Put `body` between the markers of section `name` in `path`, keeping the rest."""
    if name not in SECTIONS:
        raise ValueError(f"unknown section {name!r}; expected one of {SECTIONS}")
    begin, end = markers(name)
    block = f"{begin}\n{body.strip()}\n{end}"
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    if text.strip() and not any(markers(other)[0] in text for other in SECTIONS):
        raise ValueError(
            f"{path} has no section markers such as {begin!r}; add them around the generated "
            "text, or move the file away, before running this script"
        )
    if not text.strip():
        text = INTRO
    if begin in text:
        start = text.index(begin)
        stop = text.find(end, start)
        if stop < 0:
            raise ValueError(f"{path} has {begin!r} but no {end!r} after it")
        text = text[:start] + block + text[stop + len(end) :]
    else:
        later = [
            text.index(markers(other)[0])
            for other in SECTIONS[SECTIONS.index(name) + 1 :]
            if markers(other)[0] in text
        ]
        if later:
            at = min(later)
            text = text[:at] + block + "\n\n" + text[at:]
        else:
            text = text.rstrip() + "\n\n" + block + "\n"
    write_atomic(path, text)
