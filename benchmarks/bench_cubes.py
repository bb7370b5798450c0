"""Method of Cubes against marching cubes; writes its section of docs/benchmarks.md.

Run by hand from the repository root (about ten minutes on 2 cores)::

    python benchmarks/bench_cubes.py --seeds 3

Phase 1: four clouds with exact truth (a noisy open pipe, a sphere, a torus and a simulated
in-pipe laser scan) are reconstructed with ``contour="marching"`` and ``contour="cubes"`` at
the same, estimated cube size, and once more with the Method of Cubes at sqrt(2) times that
cube size (which halves the triangles). Each mesh is compared with the truth (accuracy: mesh
to truth; completeness: truth to mesh), its topology counted, its smallest angles binned,
and each contouring call timed alone on the same field (median of 3).

Phase 2: `zeroset.optimize` runs from both phase-1 meshes of the 100k-point pipe (the ``small``
case of bench_phase2.py, cube size 0.0201), once per seed, after one warm-up run that
compiles the kernels. The section between ``<!-- cubes:begin -->`` and ``<!-- cubes:end -->``
is replaced atomically (see ``_docfile.py``).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_phase1 import CYLINDER, DEFAULT_OUTPUT, WARMUP_POINTS, machine_info, reproduce_lines

import zeroset
from zeroset import evaluate, topology
from zeroset.contour import marching_cubes, method_of_cubes
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_torus, scan_pipe

METHODS = ("marching", "cubes")
ANGLE_BINS = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0)
REFERENCE_SAMPLES = 200_000
PHASE2_POINTS, PHASE2_CUBE = 100_000, 0.0201


def _clouds() -> dict:
    """name: (description, Sample) of the phase-1 cases."""
    return {
        "pipe": (
            "`sample_cylinder(200_000, radius=0.25, length=1, noise=0.002)`",
            sample_cylinder(200_000, **CYLINDER),
        ),
        "sphere": (
            "`sample_sphere(100_000, noise=0.005)`, r = 1 m",
            sample_sphere(100_000, noise=0.005, rng=0),
        ),
        "torus": (
            "`sample_torus(100_000, noise=0.005)`, radii 1 and 0.35 m",
            sample_torus(100_000, noise=0.005, rng=0),
        ),
        "scan": ("`scan_pipe()`: simulated Hokuyo scan inside a 0.25 m pipe", scan_pipe(rng=0)),
    }


def _contour_seconds(result, method: str) -> float:
    """Median seconds of three contouring calls on the reconstruction's own field."""
    if method == "cubes":
        args = (result.field, result.points, result.planes.centroids, result.normals)
        call = method_of_cubes
    else:
        args, call = (result.field,), marching_cubes
    times = []
    for _ in range(3):
        begin = time.perf_counter()
        call(*args)
        times.append(time.perf_counter() - begin)
    return statistics.median(times)


def _measure(sample, method: str, cube_size: float | None) -> dict:
    """Reconstruct `sample` with one contouring method and measure the mesh."""
    result = zeroset.reconstruct(
        sample.points, viewpoints=sample.viewpoints, contour=method, cube_size=cube_size
    )
    mesh = result.mesh
    reference = evaluate.compare_to_reference(
        mesh, sample.truth, n_samples=REFERENCE_SAMPLES, rng=0
    )
    angles = evaluate.smallest_angles(mesh)
    histogram = np.histogram(angles, bins=ANGLE_BINS)[0] / angles.size
    return {
        "cube_size": result.parameters.cube_size,
        "faces": mesh.n_faces,
        "loops": len(topology.boundary_loops(mesh.faces)),
        "euler": topology.euler_characteristic(mesh),
        "components": result.stats["mesh_components"],
        "manifold": topology.is_edge_manifold(mesh.faces)
        and topology.is_consistently_oriented(mesh.faces),
        "accuracy": reference["accuracy"]["mean"],
        "completeness": reference["completeness"]["mean"],
        "angle_p5": float(np.percentile(angles, 5)),
        "angle_min": float(angles.min()),
        "histogram": histogram.tolist(),
        "seconds": _contour_seconds(result, method),
    }


def run_phase1() -> list[dict]:
    rows = []
    for name, (description, sample) in _clouds().items():
        marching = _measure(sample, "marching", None)
        cubes = _measure(sample, "cubes", None)
        coarse = _measure(sample, "cubes", marching["cube_size"] * np.sqrt(2.0))
        rows.append(
            {
                "case": name,
                "description": description,
                "marching": marching,
                "cubes": cubes,
                "coarse": coarse,
            }
        )
        print(
            f"{name:>6}: {marching['faces']:,} / {cubes['faces']:,} / {coarse['faces']:,} faces; "
            f"accuracy {marching['accuracy'] * 1e3:.3f} / {cubes['accuracy'] * 1e3:.3f} / "
            f"{coarse['accuracy'] * 1e3:.3f} mm",
            flush=True,
        )
    return rows


def run_phase2(seeds: int) -> list[dict]:
    warm = sample_cylinder(WARMUP_POINTS, **CYLINDER).points
    zeroset.optimize(zeroset.reconstruct(warm).mesh, warm, rng=0)  # compile every kernel first
    sample = sample_cylinder(PHASE2_POINTS, **CYLINDER)
    starts = {
        m: zeroset.reconstruct(sample.points, cube_size=PHASE2_CUBE, contour=m).mesh
        for m in METHODS
    }
    runs = []
    for seed in range(seeds):
        for method in METHODS:  # interleaved, so drift of the machine hits both alike
            begin = time.perf_counter()
            result = zeroset.optimize(starts[method], sample.points, rng=seed)
            seconds = time.perf_counter() - begin
            points, _ = evaluate.sample_surface(result.mesh, REFERENCE_SAMPLES, rng=0)
            runs.append(
                {
                    "seed": seed,
                    "method": method,
                    "faces_before": starts[method].n_faces,
                    "faces": result.mesh.n_faces,
                    "energy_before": result.energy_before.total,
                    "energy": result.energy.total,
                    "seconds": seconds,
                    "accuracy": float(np.abs(sample.distance(points)).mean()),
                }
            )
            run = runs[-1]
            print(
                f"phase 2 seed {seed} {method:>8}: {run['faces_before']:,} -> {run['faces']:,} "
                f"faces, E {run['energy']:.5g}, {seconds:.1f} s",
                flush=True,
            )
    return runs


def _mm(metres: float) -> str:
    return f"{metres * 1e3:.3f}"


def render(phase1: list[dict], phase2: list[dict], machine: dict, command: str) -> str:
    """The Markdown text of the Method-of-Cubes section."""
    bins = [f"{lo:g}-{hi:g}°" for lo, hi in zip(ANGLE_BINS[:-1], ANGLE_BINS[1:], strict=True)]
    out = [
        "## Method of Cubes against marching cubes",
        "",
        "`zeroset reconstruct --contour cubes` (one vertex per surface patch of a cube, on the "
        "cube's averaged tangent plane; faces around every crossed lattice edge) against the "
        "default marching cubes, at the cube size phase 1 estimates for each cloud.",
        "",
        f"- Accuracy: mean distance of {REFERENCE_SAMPLES:,} area-uniform samples of the mesh to "
        "the true surface's mesh; completeness: the same from the truth to the mesh "
        "(`zeroset.evaluate.compare_to_reference`), in mm.",
        "- Contour seconds: the contouring call alone on the same field, median of 3 "
        "(marching cubes' vertex interpolation, or the Method of Cubes with its plane averaging).",
        "- The last column group is the Method of Cubes at √2 × the cube size, which halves the "
        "triangles.",
        "",
        *reproduce_lines(command, machine),
        "",
        "### Phase 1: triangles, topology and accuracy",
        "",
        "| cloud | method | cube mm | faces | loops | Euler | components | manifold, oriented "
        "| accuracy mm | completeness mm | smallest angle: min / 5 % | contour s |",
        "|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|",
    ]
    labels = {
        "marching": "marching cubes",
        "cubes": "Method of Cubes",
        "coarse": "Method of Cubes, √2 cube",
    }
    for row in phase1:
        for key, label in labels.items():
            m = row[key]
            out.append(
                f"| {row['case']} | {label} | {m['cube_size'] * 1e3:.1f} | {m['faces']:,} "
                f"| {m['loops']} | {m['euler']} | {m['components']} | {m['manifold']} "
                f"| {_mm(m['accuracy'])} "
                f"| {_mm(m['completeness'])} | {m['angle_min']:.1f}° / {m['angle_p5']:.1f}° "
                f"| {m['seconds']:.3f} |"
            )
    out += [
        "",
        "Clouds: " + "; ".join(f"{r['case']}: {r['description']}" for r in phase1) + ".",
        "",
    ]
    out += [
        "### Smallest angle of each triangle (share of the triangles per bin)",
        "",
        "| cloud | method | " + " | ".join(bins) + " |",
        "|---|---" + "|---:" * len(bins) + "|",
    ]
    for row in phase1:
        for key in METHODS:
            shares = " | ".join(f"{share:.1%}" for share in row[key]["histogram"])
            out.append(f"| {row['case']} | {labels[key]} | {shares} |")
    out += [
        "",
        "### Phase 2 from each start",
        "",
        f"`zeroset.optimize(start, points, rng=seed)` on the {PHASE2_POINTS:,}-point pipe, both "
        f"starts contoured at cube size {PHASE2_CUBE * 1e3:.1f} mm, runs interleaved.",
        "",
        "| seed | start | faces before -> after | E before -> after | seconds | accuracy mm |",
        "|---:|---|---:|---:|---:|---:|",
    ]
    for run in phase2:
        out.append(
            f"| {run['seed']} | {labels[run['method']]} "
            f"| {run['faces_before']:,} -> {run['faces']:,} "
            f"| {run['energy_before']:.4f} -> {run['energy']:.4f} | {run['seconds']:.1f} "
            f"| {_mm(run['accuracy'])} |"
        )
    out += [
        "",
        "| start | median seconds | mean final E | mean faces after |",
        "|---|---:|---:|---:|",
    ]
    for method in METHODS:
        mine = [run for run in phase2 if run["method"] == method]
        out.append(
            f"| {labels[method]} | {statistics.median(r['seconds'] for r in mine):.1f} "
            f"| {statistics.mean(r['energy'] for r in mine):.4f} "
            f"| {statistics.mean(r['faces'] for r in mine):.0f} |"
        )
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", type=int, default=3, help="phase-2 runs per start")
    parser.add_argument(
        "--output",
        type=Path,
        default=DEFAULT_OUTPUT,
        help="Markdown report (default: docs/benchmarks.md)",
    )
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be positive")
    phase1 = run_phase1()
    phase2 = run_phase2(args.seeds)
    command = f"python benchmarks/bench_cubes.py --seeds {args.seeds}"
    replace_section(args.output, "cubes", render(phase1, phase2, machine_info(), command))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
