"""Anisotropic laser scans: zeroset beside its peers; writes its section of docs/benchmarks.md.

Run by hand from the repository root (needs the ``bench`` extra; about 10 minutes on 2 cores)::

    python benchmarks/bench_scans.py

Clouds: simulated in-pipe scans of a rotating 2D laser (`zeroset.synthetic.scan_pipe`, fixed
seeds) across pipe radii, angular steps between scan lines and scanner offsets, with an exact
truth; and the real rotating-laser scans of the shared data folder (the three 3DTK SICK scans,
sensor at the origin of each, and the two ASL apartment scans of libpointmatcher, sensor
unknown) without one. Every tool runs with its defaults in a child process of
``bench_peers.py`` (the same settings and limits as its section), and zeroset's meshes of
the real scans are drawn with `zeroset.viz` into ``docs/images/``. Ball pivoting is left out:
on the SICK scans it runs for minutes and leaves tens of pieces (see the peers section).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_peers import (
    DEFAULT_DATA,
    DEFAULT_IMAGES,
    DEFAULT_MEMORY_GIB,
    DEFAULT_OUTPUT,
    JOBS,
    Cloud,
    Dataset,
    machine_info,
    read_sick,
    run_cloud,
)
from bench_phase1 import machine_lines

#: Simulated scans: pipe radius (m), degrees between scan lines, scanner offset (m), seed.
SIMULATED = (
    (0.1, 1.0, 0.0, 0),
    (0.1, 4.0, 0.0, 0),
    (0.25, 2.0, 0.05, 0),
    (0.35, 4.0, 0.05, 0),
)
REAL = (
    ("sick-0", "3dtk_rotating_sick/scan000.3d"),
    ("sick-1", "3dtk_rotating_sick/scan001.3d"),
    ("sick-2", "3dtk_rotating_sick/scan002.3d"),
    ("apartment-0", "libpointmatcher/apartment_icp_tutorial/cloud_0.vtk"),
    ("apartment-1", "libpointmatcher/apartment_icp_tutorial/cloud_1.vtk"),
)
#: Seconds per tool and cloud.
TIMEOUT = 120.0
TOOLS = ("zeroset", "zeroset-viewpoints", "open3d-poisson8", "pymeshlab-poisson")


def read_vtk(path: Path) -> np.ndarray:
    """The points of a legacy VTK file, read by VTK itself."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader

    reader = vtkPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return np.array(vtk_to_numpy(reader.GetOutput().GetPoints().GetData()), dtype=np.float64)


def clouds(data: Path):
    """(name, description, Cloud) for every case, simulated first."""
    from zeroset.synthetic import scan_pipe

    for radius, step, offset, seed in SIMULATED:
        sample = scan_pipe(radius=radius, rotation_step=step, offset=offset, rng=seed)
        name = f"pipe-r{radius:g}-{step:g}deg-offset{offset * 100:g}cm"
        yield name, Cloud(np.array(sample.points), np.array(sample.viewpoints), sample.truth)
    for name, relative in REAL:
        path = data / relative
        if not path.is_file():
            print(f"{name}: skipped, no file {path}", flush=True)
            continue
        if path.suffix == ".3d":
            points = read_sick(path)
            yield name, Cloud(points, np.zeros_like(points), None, relative)
        else:
            yield name, Cloud(read_vtk(path), None, None, relative)


def _note(cloud: Cloud) -> str:
    """Where a cloud comes from, for its heading."""
    if cloud.truth is not None:
        return "Truth: the pipe wall."
    sensor = "sensor at the origin" if cloud.viewpoints is not None else "sensor position unknown"
    return f"`{cloud.note}`, {sensor}."


def _cell(row, key: str) -> str:
    """One table cell of a row's metrics."""
    if row.status != "ok":
        return row.status
    quality = row.metrics["quality"]
    if key == "topology":
        return (
            f"{quality['components']} / {quality['boundary_loops']} / "
            f"{quality['non_manifold_edges']}"
        )
    if key == "distance":
        if "reference" in row.metrics:
            return f"{row.metrics['reference']['accuracy']['mean'] * 1000:.2f}"
        distance = row.metrics["points"]["distance"]
        return f"{distance['mean'] * 1000:.1f} / {distance['median'] * 1000:.1f}"
    if key == "coverage":
        if "reference" in row.metrics:
            return f"{row.metrics['reference']['thresholds'][0]['recall']:.3f}"
        return f"{row.metrics['points']['coverage']:.3f}"
    raise KeyError(key)


def render(results: dict) -> list[str]:
    """The section's Markdown lines."""
    lines = [
        "## Anisotropic laser scans",
        "",
        "Rotating 2D laser scans: points millimetres apart along a scan line and centimetres "
        "apart between lines, density falling and noise growing with range. zeroset with its "
        "defaults beside the peers of the section below (same settings, limits and metrics).",
        "",
        "```",
        "python benchmarks/bench_scans.py",
        "```",
        "",
        *machine_lines(results["machine"]),
        "",
        "Columns: *s* the reconstruction's seconds; *topology* components / boundary loops / "
        "non-manifold edges; *distance* for the simulated scans the mean distance from the mesh"
        " to the true pipe (mm), for the real scans the mean / median distance from the points "
        "to the mesh (mm); *coverage* for the simulated scans the share of the true pipe within"
        " 1 % of its diagonal of the mesh (recall; the truth is the whole wall, seen or not), "
        "for the real scans the share of the points within 1 % of the mesh's diagonal. The true"
        " pipes have 1 component and 2 boundary loops.",
        "",
    ]
    for case in results["cases"]:
        lines += [f"### {case['name']}", "", f"{case['points']:,} points. {case['note']}", ""]
        if case.get("image"):
            lines += [f"![zeroset's mesh of {case['name']}]({case['image']})", ""]
        lines += [
            "| tool | s | peak MiB | faces | topology | distance mm | coverage |",
            "|---|---:|---:|---:|---|---:|---:|",
        ]
        for row in case["rows"]:
            label = next(job.label for job in JOBS if job.key == row.job)
            seconds = f"{row.total:.2f}" if row.status == "ok" else "-"
            peak = f"{row.peak_rss_mib:.0f}" if row.peak_rss_mib else "-"
            faces = f"{row.faces:,}" if row.faces else "-"
            lines.append(
                f"| {label} | {seconds} | {peak} | {faces} | {_cell(row, 'topology')} | "
                f"{_cell(row, 'distance')} | {_cell(row, 'coverage')} |"
            )
        lines.append("")
    return lines


def picture(path: Path, cloud: Cloud, vertices, faces) -> None:
    """zeroset's mesh with the points, coloured by the points' distance to it."""
    from zeroset.types import Mesh
    from zeroset.viz import distance_colours, preview, vertex_distances

    mesh = Mesh(vertices=vertices, faces=faces)
    rng = np.random.default_rng(0)
    shown = cloud.points[rng.choice(len(cloud.points), min(20_000, len(cloud.points)), False)]
    colours = distance_colours(vertex_distances(mesh, cloud.points))
    preview(mesh, path, points=shown, colours=colours, width=1400, height=600)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="real scans folder")
    parser.add_argument("--tools", nargs="+", choices=[j.key for j in JOBS], default=TOOLS)
    parser.add_argument("--timeout", type=float, default=TIMEOUT, help="seconds per tool")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--images", type=Path, default=DEFAULT_IMAGES, help="PNG folder")
    args = parser.parse_args(argv)

    results = {"machine": machine_info(), "cases": []}
    args.images.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    for name, cloud in clouds(args.data):
        print(f"{name}: {len(cloud.points):,} points", flush=True)
        jobs = [
            job
            for job in JOBS
            if job.key in args.tools and (not job.viewpoints or cloud.viewpoints is not None)
        ]
        dataset = Dataset(name, name, "", cloud.truth is not None)
        if cloud.truth is None:
            dataset = replace(dataset, unit=(1000.0, "mm"))
        rows, meshes = run_cloud(
            dataset,
            len(cloud.points),
            cloud,
            jobs,
            (args.timeout, DEFAULT_MEMORY_GIB),
            {},
            keep_meshes=True,
        )
        case = {"name": name, "points": len(cloud.points), "rows": rows}
        case["note"] = _note(cloud)
        if "zeroset" in meshes:
            image = args.images / f"scans-{name}.png"
            picture(image, cloud, *meshes["zeroset"])
            case["image"] = f"images/{image.name}"
        results["cases"].append(case)
    replace_section(args.output, "scans", "\n".join(render(results)))
    print(f"wrote {args.output} in {time.perf_counter() - started:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
