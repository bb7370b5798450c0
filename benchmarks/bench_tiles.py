"""Tiled reconstruction on Dask: a 20M-point pipe network on 1 and 2 workers; writes its
section of docs/benchmarks.md.

Run by hand from the repository root (needs the ``tiles`` extra; about 15 minutes and
8 GiB of disk-backed memory on 2 cores)::

    python benchmarks/bench_tiles.py [--points 20000000] [--tiles 2x2x1] [--untiled]

The cloud is a pipe rack: eight open pipes of radius 0.15 m and 8 m length, four along x
and four along y a metre above them, sampled uniformly with 2 mm of noise (seeded), written
as a binary PLY. Each run starts the CLI's local cluster (`zeroset.tiles.dask_client`) of
the workers asked for, one task at a time each and the cores shared out among them, and
reconstructs the file with ``tiles="auto"`` (or the grid given): every tile reads its
own points from the file (memory-mapped, a chunk at a time), so the client never holds
the cloud. Wall time is for the whole run; peak memory is each worker process's resident
peak, as the process reports it. *After weld* is the time of the stages run on the welded
mesh, and its share of the run: repair and the rim cut in the client, the refinement's and
the simplification's tasks on the workers, and then the simplification's band across the
seams in the client; *in the client* is that time less the waits for the tasks.
With ``--untiled`` the same file is also reconstructed without tiles, in this process, for
its wall time and mesh, and again on one thread (``NUMBA_NUM_THREADS=1``, in a process
of its own): what the kernels gain from threads bounds what workers can add.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_phase1 import DEFAULT_OUTPUT, machine_info, machine_lines

import zeroset
from zeroset import io, topology
from zeroset.tiles import dask_client, reconstruct_tiled

#: Pipes of the rack: radius and length (m), spacing between neighbours (m), noise (m).
RADIUS, LENGTH, SPACING, NOISE = 0.15, 8.0, 1.0, 0.002


def pipe_rack(n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) points on eight pipes, four along x at z = 0 and four along y at z = 1."""
    rng = np.random.default_rng(seed)
    pipe = rng.integers(0, 8, n)
    along = rng.uniform(0.0, LENGTH, n)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    radius = RADIUS + rng.normal(0.0, NOISE, n)
    across = (pipe % 4) * SPACING + 2.0 + radius * np.cos(angle)
    height = (pipe // 4) * SPACING + radius * np.sin(angle)
    along_x = pipe < 4
    return np.column_stack(
        [np.where(along_x, along, across), np.where(along_x, across, along), height]
    )


def run(path: Path, workers: int, tiles="auto") -> dict:
    start = time.perf_counter()
    with dask_client(workers=workers) as client:  # the CLI's cluster: cores shared out
        result = reconstruct_tiled(path, tiles=tiles, client=client)
    seconds = time.perf_counter() - start
    mesh = result.mesh
    return {
        "workers": workers,
        "seconds": seconds,
        "timings": result.timings,
        "waits": result.waits,
        "peaks": sorted(result.stats["worker_peak_mib"].values()),
        "tiles": result.stats["tile_grid"],
        "faces": mesh.n_faces,
        "loops": len(topology.boundary_loops(mesh.faces)),
        "components": topology.face_components(mesh.faces, mesh.n_vertices)[0],
        "flipped": result.stats["tile_components_flipped"],
        "disagreement": result.stats["seam_disagreement"],
        "grown": result.stats["tiles_grown"],
        "gap": result.stats["seam_vertex_gap"],
        "rho_delta": result.parameters.rho_delta,
    }


#: Passes of a tiled run on the welded mesh.
AFTER_WELD = ("repair", "rim", "refine", "simplify")


def run_untiled(path: Path) -> dict:
    """The file reconstructed without tiles: wall time (reading included) and faces, on
    every core and, in a second process, on one thread."""
    start = time.perf_counter()
    mesh = zeroset.reconstruct(io.read_points(path).points).mesh
    seconds = time.perf_counter() - start
    one = subprocess.run(
        [sys.executable, "-c", ONE_THREAD, str(path)],
        env=os.environ | {"NUMBA_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        check=True,
    )
    return {"seconds": seconds, "faces": mesh.n_faces, "one_thread": float(one.stdout.split()[-1])}


#: The untiled run on one thread, in a process of its own (Numba reads its threads once).
ONE_THREAD = """
import sys, time, warnings
import zeroset
from zeroset import io
warnings.simplefilter("ignore")
start = time.perf_counter()
zeroset.reconstruct(io.read_points(sys.argv[1]).points)
print(time.perf_counter() - start)
"""


def _share(value: float | None) -> str:
    return "no seams" if value is None else f"{value:.2%}"


def section(
    n_points: int, runs: list[dict], write_seconds: float, tiles="auto", untiled=None
) -> str:
    one = next(r for r in runs if r["workers"] == 1)
    cores = os.cpu_count() or 1
    rows = []
    for r in runs:
        timings = r["timings"]
        passes = ", ".join(f"{name} {sec:.0f}" for name, sec in timings.items())
        peaks = " / ".join(f"{p:,.0f}" for p in r["peaks"])
        after = sum(timings.get(name, 0.0) for name in AFTER_WELD)
        client = after - sum(r["waits"].values())
        rows.append(
            f"| {r['workers']} | {'x'.join(map(str, r['tiles']))} | {r['seconds']:.0f} | "
            f"{one['seconds'] / r['seconds']:.2f} | {passes} | "
            f"{after:.0f} ({after / r['seconds']:.0%}) | "
            f"{client:.1f} ({client / r['seconds']:.0%}) | {peaks} | {r['faces']:,} | "
            f"{r['components']} / {r['loops']} | {r['flipped']} / {_share(r['disagreement'])} | "
            f"{r['grown']} / {r['gap']:.1e} |"
        )
    client_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    grid = tiles if tiles == "auto" else "x".join(map(str, tiles))
    return "\n".join(
        [
            f"## Tiled on Dask: a {n_points / 1e6:g}M-point pipe network",
            "",
            "```",
            f"python benchmarks/bench_tiles.py --points {n_points}"
            + ("" if tiles == "auto" else f" --tiles {grid}")
            + ("" if untiled is None else " --untiled"),
            "```",
            "",
            f"{n_points:,} points on a pipe rack (eight open pipes, radius 0.15 m, 8 m long, in",
            "two layers a metre apart, 2 mm noise), a binary PLY read by every tile for its own",
            f"box (writing it took {write_seconds:.0f} s). "
            + (
                '`tiles="auto"` aims at 2M points a tile, and at a tile a worker down to 500k.'
                if tiles == "auto"
                else f"Tiles {grid}."
            )
            + " Passes (s): bounds of the file, parameters (measured at 20,000 points drawn",
            "in one pass over the file, on the points near them read in a second), fitting and",
            "orienting planes, contouring the owned cubes, welding, then the stages run on the",
            "welded mesh (the refinement's and the simplification's tasks on the workers). In",
            "the client: the part of those stages that is not waiting for the tasks (repair,",
            "rim, cutting and welding the tiles' parts, the band across the seams). Peak",
            "memory is each worker process's resident peak (MiB). Flips: tile",
            "components turned to agree with their neighbours / share of shared seam points",
            "still disagreeing. Halos: tiles that widened theirs for neighbourhoods reaching",
            "further / largest distance between two tiles' copies of a shared vertex (m).",
            "",
            "| workers | tiles | seconds | speed-up | passes (s) | after weld s (share) | "
            "in the client s (share) | peak per worker (MiB) | triangles | components / loops "
            "| flips / disagreement | halos |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
            *rows,
            "",
            *(
                []
                if untiled is None
                else [
                    f"Without tiles, in one process: {untiled['seconds']:.0f} s, "
                    f"{untiled['faces']:,} triangles; on one thread "
                    f"{untiled['one_thread']:.0f} s, so its kernels gain "
                    f"{untiled['one_thread'] / untiled['seconds']:.2f}x from the machine's "
                    f"cores already. {cores} single-threaded workers take no less than that "
                    f"time shared out, {untiled['one_thread'] / cores:.0f} s (and what the "
                    "halos repeat): at most "
                    f"{cores * untiled['seconds'] / untiled['one_thread']:.2f}x faster than "
                    f"the run without tiles, {cores * one['seconds'] / untiled['one_thread']:.2f}x "
                    "than one worker.",
                    "",
                ]
            ),
            f"The client process peaked at {client_peak:,.0f} MiB (it generated and wrote the",
            "cloud too). Each pipe should come out as one component with two boundary loops.",
            "",
            *machine_lines(machine_info()),
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=20_000_000)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--tiles", default="auto", help='"auto" or a grid such as 2x2x1')
    parser.add_argument("--untiled", action="store_true", help="also run without tiles")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args()
    tiles = args.tiles if args.tiles == "auto" else tuple(map(int, args.tiles.split("x")))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rack.ply"
        start = time.perf_counter()
        io.write_points(path, pipe_rack(args.points))
        write_seconds = time.perf_counter() - start
        runs = []
        for workers in args.workers:
            runs.append(run(path, workers, tiles))
            print(runs[-1], flush=True)
        untiled = run_untiled(path) if args.untiled else None
    text = section(args.points, runs, write_seconds, tiles, untiled)
    replace_section(args.output, "tiles", text)
    print(text)


if __name__ == "__main__":
    main()
