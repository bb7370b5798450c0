"""Holes in real scans: zeroset's boundary loops beside PoissonRecon's trimmed rims.

Run by hand from the repository root (needs the ``bench`` extra; about two minutes)::

    python benchmarks/bench_holes.py

A closed object scanned from a few directions has places no beam reached, and a single
range scan has its own edge. zeroset leaves a hole where the data leave one (its rim rule,
docs/method.md §7d); PoissonRecon closes everything and its trimming (SurfaceTrimmer) cuts
the surface back where the points are sparse. On the Stanford bunny's first range scan and
the SRB gargoyle, each of zeroset's loops is set beside the rims of PoissonRecon at depths 8
and 9, trimmed at 6 and 7 (`bench_peers.poissonrecon`, the same calls as the peers'
benchmark): the share of the loop's vertices that lie within 2 rho+delta of a Poisson rim.
A share near 1 is a hole that Poisson leaves too. The section between
``<!-- holes:begin -->`` and ``<!-- holes:end -->`` of docs/benchmarks.md is replaced.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_peers import (
    DEFAULT_DATA,
    open3d_normals,
    poissonrecon,
    poissonrecon_trim,
)
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines
from scipy.spatial import cKDTree

import zeroset
from zeroset import topology
from zeroset.io import read_points

SCANS = {
    "bunny": "stanford_bunny/data/bun000.ply",
    "gargoyle": "srb_gargoyle_scan/gargoyle.ply",
}
POISSON = [(depth, trim) for depth in (8, 9) for trim in (6, 7)]
#: A zeroset rim vertex this many rho+delta from a Poisson rim vertex lies on that rim.
NEAR = 2.0


def loops(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray]:
    """The (K, 3) vertices of each boundary loop."""
    return [vertices[np.asarray(loop)] for loop in topology.boundary_loops(faces)]


def across(loop: np.ndarray) -> float:
    """Twice the median distance of a loop's vertices from their centroid."""
    return float(2 * np.median(np.linalg.norm(loop - loop.mean(axis=0), axis=1)))


def shared(mine: list[np.ndarray], theirs: list[np.ndarray], reach: float) -> list[float]:
    """Per loop of `mine`, the share of its vertices within `reach` of a loop of `theirs`."""
    if not theirs:
        return [0.0] * len(mine)
    tree = cKDTree(np.concatenate(theirs))
    return [float(np.mean(tree.query(loop)[0] <= reach)) for loop in mine]


def measure(name: str, points: np.ndarray) -> dict:
    """zeroset's loops and, per PoissonRecon depth and trim, its loops and the shares."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", zeroset.SurfaceWarning)
        result = zeroset.reconstruct(points)
    rho_delta = result.parameters.rho_delta
    mine = loops(result.mesh.vertices, result.mesh.faces)
    row = {
        "name": name,
        "points": points.shape[0],
        "rho_delta": rho_delta,
        "loops": [(loop.shape[0], across(loop) / rho_delta) for loop in mine],
        "components": result.stats["mesh_components"],
        "poisson": [],
    }
    normals = open3d_normals(points)[0]
    for depth in sorted({d for d, _ in POISSON}):
        vertices, faces, values, _, _ = poissonrecon(points, normals, depth)
        for trim in [t for d, t in POISSON if d == depth]:
            tv, tf, _, _ = poissonrecon_trim(vertices, faces, values, trim)
            theirs = loops(tv, tf)
            row["poisson"].append(
                {
                    "depth": depth,
                    "trim": trim,
                    "loops": len(theirs),
                    "shared": shared(mine, theirs, NEAR * rho_delta),
                }
            )
        print(f"{name}: depth {depth} done", flush=True)
    return row


def render(rows: list[dict], machine: dict, command: str) -> str:
    out = [
        "## Holes in real scans beside PoissonRecon's",
        "",
        *reproduce_lines(command, machine, "about two minutes"),
        "",
        "Each of zeroset's boundary loops (default settings) against the rims of PoissonRecon "
        "trimmed as in the peers' benchmark: the share of the loop's vertices within "
        f"{NEAR:g} rho+delta of a Poisson rim. A share near 1 is a hole Poisson leaves too; "
        "*across* is twice the median distance of the loop's vertices from their centroid.",
        "",
    ]
    for row in rows:
        out += [
            f"### {row['name']} ({row['points']:,} points, rho+delta {row['rho_delta']:.4g})",
            "",
            f"zeroset: {row['components']} component(s), {len(row['loops'])} boundary loop(s).",
            "",
        ]
        head = "| zeroset loop | edges | across, rho+delta |"
        rule = "|---:|---:|---:|"
        for p in row["poisson"]:
            head += f" d{p['depth']} t{p['trim']} ({p['loops']} loops) |"
            rule += "---:|"
        out += [head, rule]
        for i, (edges, width) in enumerate(row["loops"]):
            line = f"| {i + 1} | {edges:,} | {width:.1f} |"
            for p in row["poisson"]:
                line += f" {p['shared'][i]:.2f} |"
            out.append(line)
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="Markdown report")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder")
    args = parser.parse_args(argv)
    rows = []
    for name, path in SCANS.items():
        points = np.array(read_points(args.data / path).points)  # Open3D wants a writable copy
        rows.append(measure(name, points))
    command = "python benchmarks/bench_holes.py"
    replace_section(args.output, "holes", render(rows, machine_info(), command))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
