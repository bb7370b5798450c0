"""Several scans with poses: registration, merging and orientation; writes its section of
docs/benchmarks.md.

Run by hand from the repository root (a few minutes on 2 cores)::

    python benchmarks/bench_registered.py

Clouds: the ten Stanford bunny range scans of the shared data folder with their ``bun.conf``
poses, measured against Stanford's own reconstruction ``bun_zipper.ply``: with the poses as
given, refined by ``register_scans``, and refined from poses spoiled by 2 degrees and 2 cm
(seeded). Then the share of normals on which the sensors and the spanning tree disagree, on
the bunny and on simulated in-pipe scans and a two-scan sphere with sensor positions.
"""

from __future__ import annotations

import argparse
import resource
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_peers import DEFAULT_DATA, DEFAULT_IMAGES, DEFAULT_OUTPUT
from bench_phase1 import machine_info, machine_lines
from scipy.spatial.transform import Rotation

from zeroset import io, reconstruct
from zeroset.evaluate import compare_to_reference
from zeroset.merge import match_poses, merge_scans
from zeroset.registration import register_scans
from zeroset.synthetic import sample_sphere, scan_pipe
from zeroset.viz import preview

#: The picture of the bunny reconstructed with the poses of bun.conf.
PICTURE = "registered-bunny.png"
#: The Cyberware scanner looks along -z of each scan frame: its position there.
BUNNY_SENSOR = (0.0, 0.0, 1.0)
#: Simulated pipe scans: radius (m), degrees between scan lines, scanner offset (m), seed.
PIPES = ((0.1, 1.0, 0.0, 0), (0.25, 2.0, 0.05, 0), (0.35, 4.0, 0.05, 0))


def spoiled(poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Poses (S, 4, 4), all but the first turned by 2 degrees about their scan's centre
    line and moved by 2 cm, in random directions."""
    out = poses.copy()
    for pose in out[1:]:
        axis, direction = rng.normal(size=(2, 3))
        turn = Rotation.from_rotvec(np.radians(2.0) * axis / np.linalg.norm(axis)).as_matrix()
        pose[:3, :3] = turn @ pose[:3, :3]
        pose[:3, 3] += 0.02 * direction / np.linalg.norm(direction)
    return out


def pose_change(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Largest rotation (degrees) and translation between two sets of poses."""
    angles = [
        np.degrees(np.arccos(np.clip((np.trace(p[:3, :3].T @ q[:3, :3]) - 1) / 2, -1, 1)))
        for p, q in zip(a, b, strict=True)
    ]
    return max(angles), float(np.linalg.norm(a[:, :3, 3] - b[:, :3, 3], axis=1).max())


def bunny_rows(data: Path, images: Path) -> tuple[list[str], list[str]]:
    """Rows of the bunny table and of the agreement table, for each way of placing the scans."""
    folder = data / "stanford_bunny"
    paths = sorted((folder / "data").glob("*.ply"))
    start = time.perf_counter()
    clouds = [io.read_points(path) for path in paths]
    read = time.perf_counter() - start
    names, matrices = io.read_poses(folder / "data" / "bun.conf")
    given = match_poses([p.name for p in paths], names, matrices, source="bun.conf")
    reference = io.read_mesh(folder / "reconstruction" / "bun_zipper.ply")
    cases = [("poses of bun.conf", given, False), ("bun.conf, registered", given, True)]
    cases.append(
        ("spoiled by 2° / 2 cm, registered", spoiled(given, np.random.default_rng(0)), True)
    )
    rows, agreement, registered = [], [], None
    for label, poses, register in cases:
        start = time.perf_counter()
        residual = ""
        if register:
            result = register_scans(
                [c.points for c in clouds], poses, names=[p.name for p in paths]
            )
            before, after = result.residual_before * 1e3, result.residual_after * 1e3
            turn, shift = pose_change(result.poses, given)
            residual = (
                f"{np.median(before):.3f} → {np.median(after):.3f} "
                f"(worst {before.max():.3f} → {after.max():.3f}); "
                f"{turn:.2f}° / {shift * 1e3:.2f} mm from bun.conf"
            )
            if registered is not None:
                turn, shift = pose_change(result.poses, registered)
                residual += f", {turn:.3f}° / {shift * 1e3:.3f} mm from the row above"
            poses = registered = result.poses
        registering = time.perf_counter() - start
        cloud = merge_scans(clouds, poses, viewpoint=BUNNY_SENSOR)
        start = time.perf_counter()
        recon = reconstruct(cloud.points, viewpoints=cloud.viewpoints)
        seconds = time.perf_counter() - start
        scores = compare_to_reference(recon.mesh, reference)
        stats = recon.stats
        f_scores = " / ".join(f"{t['f_score']:.4f}" for t in scores["thresholds"])
        rows.append(
            f"| {label} | {residual or '—'} | {read:.1f} + {registering:.1f} + {seconds:.1f} | "
            f"{scores['accuracy']['mean'] * 1e3:.3f} / {scores['accuracy']['p95'] * 1e3:.3f} | "
            f"{scores['completeness']['mean'] * 1e3:.3f} / "
            f"{scores['completeness']['p95'] * 1e3:.3f} | {f_scores} | "
            f"{scores['normal_consistency']:.4f} | {stats['mesh_components']} / "
            f"{stats['boundary_loops']} | {stats['orientation_disagreement']:.2%} |"
        )
        if not register:
            preview(recon.mesh, images / PICTURE, title="Stanford bunny, 10 scans, bun.conf")
            agreement.append(
                f"| Stanford bunny, 10 scans ({cloud.points.shape[0]:,} points) | "
                f"{stats['orientation_disagreement']:.2%} |"
            )
            wrong = merge_scans(clouds, poses)  # the sensor at each scan frame's origin
            stats = reconstruct(wrong.points, viewpoints=wrong.viewpoints).stats
            agreement.append(
                "| the same, sensor wrongly at each scan frame's origin (inside the bunny) | "
                f"{stats['orientation_disagreement']:.2%} |"
            )
    return rows, agreement


def simulated_agreement() -> list[str]:
    """Agreement rows for simulated in-pipe scans and a sphere seen by two sensors."""
    rows = []
    for radius, step, offset, seed in PIPES:
        scan = scan_pipe(radius=radius, rotation_step=step, offset=offset, rng=seed)
        stats = reconstruct(scan.points, viewpoints=scan.viewpoints).stats
        rows.append(
            f"| in-pipe scan, radius {radius:g} m, {step:g}° between lines, scanner "
            f"{offset * 100:g} cm off the axis ({scan.points.shape[0]:,} points) | "
            f"{stats['orientation_disagreement']:.2%} |"
        )
    rng = np.random.default_rng(0)
    sphere = sample_sphere(100_000, radius=0.5, rng=rng).points
    parts = []
    for sensor in ([2.0, 0.0, 0.0], [0.0, 2.0, 0.0]):
        seen = sphere[np.einsum("ij,ij->i", sphere, np.array(sensor) - sphere) > 0.1]
        parts.append(
            (seen + rng.normal(0.0, 0.001, seen.shape), np.broadcast_to(sensor, seen.shape))
        )
    points = np.vstack([p for p, _ in parts])
    stats = reconstruct(points, viewpoints=np.vstack([v for _, v in parts])).stats
    rows.append(
        f"| sphere seen by two sensors ({points.shape[0]:,} points) | "
        f"{stats['orientation_disagreement']:.2%} |"
    )
    return rows


def section(data: Path, images: Path) -> str:
    bunny, agreement = bunny_rows(data, images)
    agreement += simulated_agreement()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return "\n".join(
        [
            "## Several scans with poses",
            "",
            "```",
            "python benchmarks/bench_registered.py",
            "```",
            "",
            "The ten Stanford bunny range scans (Cyberware 3030MS, 362,272 points, noise 50-60 µm)",
            "with the poses of `bun.conf`, the scanner at 0,0,1 in each scan's frame, against",
            "Stanford's own reconstruction `bun_zipper.ply` (100,000 samples per surface). The",
            "residual is the median (and worst) over the scans of the RMS distance of a scan's",
            "points from the tangent planes of the others, in mm, before and after",
            "`register_scans`. Seconds: reading + registration + `reconstruct`. Distances in",
            "mm, mean / 95th percentile; F-score within 1 % / 0.5 % of the diagonal (2.5 / 1.25",
            "mm).",
            "",
            "| poses | residual (mm) | seconds | accuracy | completeness | F-score | "
            "normal consistency | components / loops | disagreement |",
            "|---|---|---|---|---|---|---|---|---|",
            *bunny,
            "",
            f"![The bunny from its ten scans and bun.conf's poses](images/{PICTURE})",
            "",
            "Sensors against the spanning tree: the share of the normals that face their sensor",
            "within 60° whose sign the sensor and the spanning tree alone (each component turned",
            "by its sensors' vote) set oppositely. Over 1 % the report asks whether the sensor",
            "positions are right.",
            "",
            "| cloud | disagreement |",
            "|---|---|",
            *agreement,
            "",
            f"Peak memory of the whole run: {peak:,.0f} MiB.",
            "",
            *machine_lines(machine_info(), f", small_gicp {version('small_gicp')}"),
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="shared data folder")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="benchmarks.md")
    parser.add_argument("--images", type=Path, default=DEFAULT_IMAGES, help="picture folder")
    args = parser.parse_args()
    text = section(args.data, args.images)
    replace_section(args.output, "registered", text)
    print(text)


if __name__ == "__main__":
    main()
