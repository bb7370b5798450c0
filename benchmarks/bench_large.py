"""A 100M-point LAZ reconstructed at reduced density on one machine; writes its section.

Run by hand from the repository root (about 10 minutes and 1 GB of disk)::

    python benchmarks/bench_large.py

A long noisy pipe (radius 0.25 m, length 20 m, noise 2 mm, at UTM-like coordinates) is
written as LAZ, a few million points at a time, into a scratch folder. Then
``zeroset reconstruct BIG.laz -o mesh.ply --voxel V --report report.json`` runs in a child
process, which reads the file in chunks and keeps one point per voxel while reading. Its wall
time and peak resident memory (``getrusage`` of the child) are recorded, with the stage
seconds and counts from its report and the mesh's distance to the true pipe. The section
between ``<!-- large:begin -->`` and ``<!-- large:end -->`` of docs/benchmarks.md is replaced.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines

from zeroset.io import read_mesh

RADIUS, LENGTH, NOISE = 0.25, 20.0, 0.002
OFFSET = np.array([500_000.0, 5_000_000.0, 300.0])
WRITE_CHUNK = 5_000_000


def write_pipe_laz(path: Path, n: int, seed: int = 0) -> None:
    """Write `n` noisy points of a z-axis pipe at `OFFSET` as LAZ (0.1 mm grid), in chunks."""
    import laspy

    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales, header.offsets = [1e-4] * 3, OFFSET
    rng = np.random.default_rng(seed)
    with laspy.open(path, mode="w", header=header) as writer:
        for start in range(0, n, WRITE_CHUNK):
            m = min(WRITE_CHUNK, n - start)
            angle, z = rng.uniform(0, 2 * np.pi, m), rng.uniform(0, LENGTH, m)
            wall = np.column_stack([RADIUS * np.cos(angle), RADIUS * np.sin(angle), z])
            points = wall + rng.normal(0, NOISE, (m, 3)) + OFFSET
            record = laspy.ScaleAwarePointRecord.zeros(m, header=header)
            record.x, record.y, record.z = points.T
            writer.write_points(record)


def pipe_distance(points: np.ndarray) -> np.ndarray:
    """(N,) distance of points (in the file's frame) to the open pipe wall."""
    local = points - OFFSET
    radial = np.abs(np.hypot(local[:, 0], local[:, 1]) - RADIUS)
    beyond = np.maximum(0.0, np.maximum(-local[:, 2], local[:, 2] - LENGTH))
    return np.hypot(radial, beyond)


def run(folder: Path, n: int, voxel: float) -> dict:
    laz = folder / "pipe.laz"
    begin = time.perf_counter()
    write_pipe_laz(laz, n)
    write_s = time.perf_counter() - begin
    print(f"wrote {n:,} points to {laz} ({laz.stat().st_size / 2**20:.0f} MiB) in {write_s:.0f} s")
    mesh, report = folder / "mesh.ply", folder / "report.json"
    command = [sys.executable, "-m", "zeroset", "reconstruct", str(laz), "-o", str(mesh),
               "--voxel", str(voxel), "--report", str(report), "--quiet"]  # fmt: skip
    begin = time.perf_counter()
    subprocess.run(command, check=True)
    wall = time.perf_counter() - begin
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    data = json.loads(report.read_text())
    vertices = read_mesh(mesh).vertices
    distance = pipe_distance(vertices)
    row = {
        "points": n,
        "file_mib": laz.stat().st_size / 2**20,
        "voxel": voxel,
        "kept": data["stats"]["input_points"],
        "wall": wall,
        "peak_mib": peak,
        "timings": data["timings"],
        "faces": data["stats"]["faces"],
        "loops": data["stats"]["boundary_loops"],
        "components": data["stats"]["mesh_components"],
        "mean_mm": 1000 * distance.mean(),
        "p95_mm": 1000 * np.percentile(distance, 95),
    }
    print(json.dumps(row, indent=1))
    return row


def render(row: dict, machine: dict, command: str) -> str:
    read = row["timings"]["read"]
    rest = ", ".join(f"{k} {v:.1f}" for k, v in row["timings"].items() if k != "read")
    raw_gib = row["points"] * 3 * 8 / 2**30
    return "\n".join(
        [
            "## Larger than memory: a 100M-point LAZ at reduced density",
            "",
            f"A noisy open pipe (radius {RADIUS} m, length {LENGTH:g} m, noise {NOISE * 1000:g} "
            "mm per axis) at UTM-like coordinates, written as LAZ 1.2 (0.1 mm grid), "
            f"reconstructed by `zeroset reconstruct pipe.laz -o mesh.ply --voxel {row['voxel']:g}`"
            " in a child process. The file is read 4,000,000 points at a time, twice (once for "
            "the voxel centroids, once to keep the point nearest each), and only the kept points "
            "stay in memory. Peak memory is the child's peak resident set (`getrusage`). "
            "Accuracy is the distance of the mesh's vertices to the true pipe wall.",
            "",
            *reproduce_lines(command, machine, "about 10 minutes"),
            "",
            "| points in file | LAZ MiB | voxel m | points kept | wall s | read s | peak MiB | "
            "triangles | loops | components | mean mm | 95 % mm |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
            f"| {row['points']:,} | {row['file_mib']:.0f} | {row['voxel']:g} | {row['kept']:,} | "
            f"{row['wall']:.0f} | {read:.0f} | {row['peak_mib']:,.0f} | {row['faces']:,} | "
            f"{row['loops']} | {row['components']} | {row['mean_mm']:.2f} | "
            f"{row['p95_mm']:.2f} |",
            "",
            f"- Stage seconds after reading: {rest}.",
            f"- The coordinates alone would take {raw_gib:.1f} GiB as float64 if the cloud were "
            "loaded whole; the run's peak is the table's.",
        ]
    ) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--points", type=int, default=100_000_000)
    parser.add_argument("--voxel", type=float, default=0.01)
    parser.add_argument("--folder", type=Path, help="scratch folder (default: a temporary one)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(dir=args.folder) as folder:
        row = run(Path(folder), args.points, args.voxel)
    command = "python benchmarks/bench_large.py" + (
        f" --points {args.points}" if args.points != 100_000_000 else ""
    )
    replace_section(args.output, "large", render(row, machine_info(), command))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
