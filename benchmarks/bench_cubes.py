"""Method of Cubes against marching cubes; writes its section of docs/benchmarks.md.

Run by hand from the repository root (about five minutes on 2 cores)::

    python benchmarks/bench_cubes.py --seeds 3

Phase 1: six clouds (a noisy open pipe, a simulated in-pipe laser scan, a pipe elbow, a pipe
tee, a torus, all with exact truth, and the Stanford bunny's first range scan) are
reconstructed with the defaults twice: ``contour="marching"`` and ``contour="cubes"`` (the
Method of Cubes). Each mesh is compared with the truth
(Chamfer-L1: the mean of accuracy, mesh to truth, and completeness, truth to mesh) or, for the
bunny, with its points (mean distance from a point to the mesh); its topology is counted, its
smallest angles binned. A mesh of the true pipe with vertices
exactly on it and a quarter of marching cubes' triangles (`Sample.truth_mesh`) shows what any
mesh of flat, round triangles that few can reach. Pictures of the pipe and the elbow in both
contourings go to docs/images/.

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
from bench_peers import DEFAULT_DATA
from bench_phase1 import CYLINDER, DEFAULT_OUTPUT, WARMUP_POINTS, machine_info, reproduce_lines

import zeroset
from zeroset import evaluate, topology
from zeroset.io import read_points
from zeroset.synthetic import sample_cylinder, sample_elbow, sample_tee, sample_torus, scan_pipe
from zeroset.viz import distance_colours, preview

METHODS = ("marching", "cubes")
LABELS = {"marching": "marching cubes", "cubes": "Method of Cubes"}
ANGLE_BINS = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0)
REFERENCE_SAMPLES = 200_000
PHASE2_POINTS, PHASE2_CUBE = 100_000, 0.0201
BUNNY = "stanford_bunny/data/bun000.ply"
PICTURES = ("pipe", "elbow")
IMAGES = DEFAULT_OUTPUT.parent / "images"
#: Largest Chamfer-L1 of the Method of Cubes, over marching cubes', that counts as equal.
EQUAL = 1.1


def _clouds(data: Path) -> dict:
    """name: (description, points, viewpoints, Sample or None) of the phase-1 cases."""
    pipe = sample_cylinder(200_000, **CYLINDER)
    scan = scan_pipe(rng=0)
    elbow = sample_elbow(200_000, noise=0.002, rng=0)
    tee = sample_tee(200_000, noise=0.002, rng=0)
    torus = sample_torus(100_000, noise=0.005, rng=0)
    clouds = {
        "pipe": ("`sample_cylinder(200_000, radius=0.25, length=1, noise=0.002)`", pipe),
        "scan": ("`scan_pipe()`: simulated Hokuyo scan inside a 0.25 m pipe", scan),
        "elbow": ("`sample_elbow(200_000, noise=0.002)`", elbow),
        "tee": ("`sample_tee(200_000, noise=0.002)`", tee),
        "torus": ("`sample_torus(100_000, noise=0.005)`, radii 1 and 0.35 m", torus),
    }
    out = {k: (d, s.points, s.viewpoints, s) for k, (d, s) in clouds.items()}
    if (data / BUNNY).is_file():
        bunny = read_points(data / BUNNY).points
        out["bunny"] = (f"`{BUNNY}` (40,256 points, no truth)", bunny, None, None)
    else:
        print(f"bunny: skipped, no file {data / BUNNY}", flush=True)
    return out


def _chamfer(mesh, points, sample) -> float:
    """Chamfer-L1 to the truth, or the mean distance from the points without one."""
    if sample is None:
        return float(evaluate.points_to_mesh_distance(points, mesh).mean())
    reference = evaluate.compare_to_reference(
        mesh, sample.truth, n_samples=REFERENCE_SAMPLES, rng=0
    )
    return (reference["accuracy"]["mean"] + reference["completeness"]["mean"]) / 2


def _measure(name, points, viewpoints, sample, method: str) -> dict:
    """Reconstruct one cloud with one contouring and measure the mesh."""
    begin = time.perf_counter()
    result = zeroset.reconstruct(points, viewpoints=viewpoints, contour=method, tolerance=0)
    seconds = time.perf_counter() - begin
    mesh = result.mesh
    angles = evaluate.smallest_angles(mesh)
    if name in PICTURES and sample is not None:
        distance = np.abs(sample.distance(mesh.vertices))
        preview(
            mesh,
            IMAGES / f"cubes-{name}-{method}.png",
            title=f"{name}, {LABELS[method]}: {mesh.n_faces:,} triangles; vertex distance "
            "to the true surface from 0 (dark) to 0.5 mm (yellow)",
            colours=distance_colours(distance, limit=0.0005),
            width=1400,
            height=500,
        )
    return {
        "faces": mesh.n_faces,
        "chamfer": _chamfer(mesh, points, sample),
        "loops": len(topology.boundary_loops(mesh.faces)),
        "euler": topology.euler_characteristic(mesh),
        "components": result.stats["mesh_components"],
        "manifold": topology.is_edge_manifold(mesh.faces)
        and topology.is_consistently_oriented(mesh.faces),
        "angle_p5": float(np.percentile(angles, 5)),
        "angle_min": float(angles.min()),
        "histogram": (np.histogram(angles, bins=ANGLE_BINS)[0] / angles.size).tolist(),
        "refined": result.stats.get("edges_split", 0),
        "seconds": seconds,
    }


def _ideal(sample, faces: int) -> dict:
    """The true pipe meshed with about `faces` triangles, vertices on it: its Chamfer-L1."""
    spacing = np.sqrt(4.0 * sample.area / (np.sqrt(3.0) * faces))
    mesh = sample.truth_mesh(spacing)
    angles = evaluate.smallest_angles(mesh)
    return {
        "faces": mesh.n_faces,
        "chamfer": _chamfer(mesh, None, sample),
        "angle_p5": float(np.percentile(angles, 5)),
        "spacing": float(spacing),
    }


def run_phase1(data: Path) -> tuple[list[dict], dict]:
    rows, ideal = [], {}
    for name, (description, points, viewpoints, sample) in _clouds(data).items():
        row = {"case": name, "description": description}
        for method in METHODS:
            row[method] = _measure(name, points, viewpoints, sample, method)
        rows.append(row)
        m, c = row["marching"], row["cubes"]
        print(
            f"{name:>6}: {m['faces']:,} / {c['faces']:,} faces; Chamfer-L1 "
            f"{m['chamfer'] * 1e3:.4f} / {c['chamfer'] * 1e3:.4f} mm",
            flush=True,
        )
        if name == "pipe":
            ideal = _ideal(sample, m["faces"] // 4)
            print(f"  ideal pipe mesh: {ideal['faces']:,} faces, {ideal['chamfer'] * 1e3:.4f} mm")
    return rows, ideal


def run_phase2(seeds: int) -> list[dict]:
    warm = sample_cylinder(WARMUP_POINTS, **CYLINDER).points
    zeroset.optimize(zeroset.reconstruct(warm, tolerance=0).mesh, warm, rng=0)  # compile first
    sample = sample_cylinder(PHASE2_POINTS, **CYLINDER)
    starts = {
        m: zeroset.reconstruct(
            sample.points, cube_size=PHASE2_CUBE, contour=m, refine_levels=0, tolerance=0
        ).mesh
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


def render(phase1, ideal, phase2, machine: dict, command: str) -> str:
    """The Markdown text of the Method-of-Cubes section."""
    bins = [f"{lo:g}-{hi:g}°" for lo, hi in zip(ANGLE_BINS[:-1], ANGLE_BINS[1:], strict=True)]
    out = [
        "## Method of Cubes against marching cubes",
        "",
        "`zeroset reconstruct --contour cubes` (one vertex per surface patch of a cube, "
        "on the averaged tangent plane, then projected onto the jets; faces around every "
        "crossed lattice edge) against the default marching cubes, both with every other "
        "default (the refinement splits the edges whose chords sag too far).",
        "",
        f"- Chamfer-L1: the mean of accuracy and completeness against the true surface "
        f"({REFERENCE_SAMPLES:,} area-uniform samples each way, "
        "`zeroset.evaluate.compare_to_reference`); for the bunny, which has no truth, the "
        "mean distance from its points to the mesh. In mm.",
        f"- Equal: the Method of Cubes' Chamfer-L1 at most {EQUAL:g} times marching cubes'.",
        "- Seconds: the whole reconstruction.",
        "",
        *reproduce_lines(command, machine),
        "",
        "### Phase 1: triangles at equal accuracy",
        "",
        "| cloud | method | faces | faces, marching / cubes | Chamfer-L1 mm | equal "
        "| loops | Euler | components | manifold, oriented | smallest angle: min / 5 % "
        "| edges split | s |",
        "|---|---|---:|---:|---:|---|---:|---:|---:|---|---:|---:|---:|",
    ]
    for row in phase1:
        ratio = row["marching"]["faces"] / row["cubes"]["faces"]
        equal = row["cubes"]["chamfer"] <= EQUAL * row["marching"]["chamfer"]
        for key in METHODS:
            m = row[key]
            out.append(
                f"| {row['case']} | {LABELS[key]} | {m['faces']:,} "
                f"| {f'{ratio:.2f}' if key == 'cubes' else ''} | {m['chamfer'] * 1e3:.4f} "
                f"| {('yes' if equal else 'no') if key == 'cubes' else ''} "
                f"| {m['loops']} | {m['euler']} | {m['components']} | {m['manifold']} "
                f"| {m['angle_min']:.1f}° / {m['angle_p5']:.1f}° | {m['refined']:,} "
                f"| {m['seconds']:.1f} |"
            )
    out += [
        "",
        "Clouds: " + "; ".join(f"{r['case']}: {r['description']}" for r in phase1) + ".",
        "",
    ]
    if ideal:
        marching = next(r for r in phase1 if r["case"] == "pipe")["marching"]
        out += [
            "### What a quarter of the triangles can reach on the pipe",
            "",
            f"The true pipe meshed with near-equilateral triangles of side "
            f"{ideal['spacing'] * 1e3:.1f} mm whose vertices lie exactly on it "
            f"(`Sample.truth_mesh`): {ideal['faces']:,} faces, about a quarter of marching "
            f"cubes' {marching['faces']:,}, and a Chamfer-L1 of {ideal['chamfer'] * 1e3:.4f} mm "
            f"against marching cubes' {marching['chamfer'] * 1e3:.4f} mm (5 % of its triangles "
            f"under {ideal['angle_p5']:.1f}°). Flat triangles that large sag that far from a "
            "pipe of radius 0.25 m with no noise at all, so no mesh with its vertices on the "
            "surface and triangles that round has four times fewer faces at equal accuracy.",
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
            out.append(f"| {row['case']} | {LABELS[key]} | {shares} |")
    out += ["", "### Pictures", ""]
    for name in PICTURES:
        for key in METHODS:
            out.append(f"![{name}, {LABELS[key]}](images/cubes-{name}-{key}.png)")
            out.append("")
    out += [
        "### Phase 2 from each start",
        "",
        f"`zeroset.optimize(start, points, rng=seed)` on the {PHASE2_POINTS:,}-point pipe, both "
        f"starts contoured at cube size {PHASE2_CUBE * 1e3:.1f} mm and not refined (as in "
        "bench_phase2.py), runs interleaved.",
        "",
        "| seed | start | faces before -> after | E before -> after | seconds | accuracy mm |",
        "|---:|---|---:|---:|---:|---:|",
    ]
    for run in phase2:
        out.append(
            f"| {run['seed']} | {LABELS[run['method']]} "
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
            f"| {LABELS[method]} | {statistics.median(r['seconds'] for r in mine):.1f} "
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
    parser.add_argument(
        "--data", type=Path, default=DEFAULT_DATA, help="the shared data folder (for the bunny)"
    )
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be positive")
    phase1, ideal = run_phase1(args.data)
    phase2 = run_phase2(args.seeds)
    command = f"python benchmarks/bench_cubes.py --seeds {args.seeds}"
    replace_section(args.output, "cubes", render(phase1, ideal, phase2, machine_info(), command))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
