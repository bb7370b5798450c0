"""Live reconstruction: a pipe run replayed scan by scan, against the batch run.

Run by hand from the repository root (about 35 minutes on 2 cores)::

    python benchmarks/bench_live.py

A pipe run of radius 0.2 m with two bends (20 m, and 40 m for the memory), scanned by the
in-pipe model (`zeroset.synthetic.scan_pipe_run`) at a station every 0.5 m, each station's
scan made just before it is given to `zeroset.live.LiveReconstruction.add`, in a process
of its own, so that its peak memory is the live run's and one scan's. The batch run
(`zeroset.reconstruct` of every scan's points with their sensor positions) runs in another
process. Per scan: the seconds of `add` (median, 95th percentile, largest). The final mesh
against the batch one: components and boundary loops, the mean distance between them each
way (100,000 samples a surface), and each one's Chamfer-L1 to the true pipe; beside them,
the live run given the batch run's parameters and lattice, and the batch run given the live
run's (what the parameters alone change). The run has
four dents: where the live inspection (`zeroset.inspect.LiveInspection`) reported them and
when, against the final inspections of the live and the batch meshes with every point, and
the same with each scan cropped to a 2 m range. The section
between ``<!-- live:begin -->`` and ``<!-- live:end -->`` of docs/benchmarks.md is
replaced.

With ``--robot`` (about 40 minutes) it replays the 20 m and 40 m runs instead as the robot
makes them, one scan every `STATION_SECONDS` (the modelled scanner's turn), to a
``background`` live run, and once more the 20 m run back to back in the background; per
scan, the seconds of `add` and how long after it the scan's work ended (`ScanUpdate.done`).
It replaces the section ``live-robot``.
"""

from __future__ import annotations

import argparse
import json
import pickle
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines

from zeroset import reconstruct
from zeroset._progress import peak_mib
from zeroset.evaluate import compare_to_reference
from zeroset.inspect import LiveInspection, inspect_pipe
from zeroset.live import LiveReconstruction
from zeroset.synthetic import Defect, PipePath, scan_pipe_run
from zeroset.topology import boundary_loops, face_components
from zeroset.types import Mesh

RADIUS = 0.2
SPACING = 0.5
ROTATION_STEP = 2.3  # degrees: about 100,000 points a station
LENGTHS = (20.0, 40.0)
BEND_RADIUS = 1.2
PREVIEW = 1.0  # metres around the sensor whose open blocks a previewing run re-meshes
RANGE = 2.0  # metres: the scanner's range in the run whose points are cropped to it
#: Seconds the URG-04LX-like scanner of the model takes for one line: its motor turns at
#: 600 rpm (SCIP2.0 ``PP`` reply "SCAN: 600"), a line every 100 ms.
LINE_SECONDS = 0.1
#: Seconds a station's scan takes to make, its ``floor(360 / ROTATION_STEP)`` lines one
#: after the other; the robot's time to move on to the next station comes on top.
STATION_SECONDS = np.floor(360.0 / ROTATION_STEP) * LINE_SECONDS
#: Dents on a leg, in the first bend, on the second leg and in the second bend.
DENTS = (
    Defect("dent", 3.0, 90.0, 0.010, 0.10),
    Defect("dent", 6.6, 270.0, 0.008, 0.10),
    Defect("dent", 10.0, 45.0, 0.006, 0.08),
    Defect("dent", 14.2, 180.0, 0.012, 0.10),
)


def path_of(length: float) -> PipePath:
    """A run of `length` metres: a leg, a bend right, a leg, a bend left, a leg."""
    bends = 2 * (0.5 * np.pi * BEND_RADIUS)
    legs = (length - bends) * np.array([0.35, 0.35, 0.30])
    return PipePath.build(
        [("straight", legs[0]), ("bend", BEND_RADIUS, 90.0, 90.0),
         ("straight", legs[1]), ("bend", BEND_RADIUS, 90.0, 270.0), ("straight", legs[2])]
    )  # fmt: skip


def stations(length: float) -> np.ndarray:
    return np.arange(0.5 * SPACING, length - 0.25 * SPACING, SPACING)


def scan(path: PipePath, station: float, k: int):
    """The scan of station `station` (its own seed `k`)."""
    return scan_pipe_run(
        path, radius=RADIUS, stations=[station], rotation_step=ROTATION_STEP, defects=DENTS,
        rng=k,
    )  # fmt: skip


def warm_up() -> None:
    """Compile the kernels on a short run, so that no scan's time holds compilation."""
    path = PipePath.build([("straight", 3.0)])
    live = LiveReconstruction(reach=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k, s in enumerate(np.arange(0.25, 3.0, 0.5)):
            part = scan_pipe_run(path, radius=RADIUS, stations=[s], rotation_step=8.0, rng=k)
            live.add(part.points, part.viewpoints)
        live.close()


def replay(
    length: float,
    out: Path,
    like: Path | None = None,
    preview: float = 0.0,
    reach=None,
    pace: float = 0.0,
    background: bool = False,
) -> None:
    """The live run of `length` metres, inspected as it goes; its figures to `out` (JSON),
    its mesh beside it. With `like`, the batch run's parameters, tolerance and lattice
    origin (a pickle), not inspected; with `preview`, the open blocks within it of the
    sensor previewed at every scan; with `reach`, each scan's points within it of its
    sensor (a scanner of that range), and that reach; with `pace`, scan k given no sooner
    than k * pace seconds after the first; with `background`, a background live run."""
    warm_up()
    path = path_of(length)
    seconds, points, finished, waiting, reported, done = [], 0, [], [], [], []
    given = {} if like is None else pickle.loads(like.read_bytes())
    inspection = LiveInspection() if like is None and not preview else None
    live = LiveReconstruction(
        preview=preview, inspection=inspection, reach=reach, background=background, **given
    )
    made, first = 0.0, time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for k, s in enumerate(stations(length)):
            start = time.perf_counter()
            part = scan(path, s, k)
            if reach is not None:
                near = np.linalg.norm(part.points - part.viewpoints, axis=1) <= reach
                part = replace(part, points=part.points[near], viewpoints=part.viewpoints[near])
            made += time.perf_counter() - start
            time.sleep(max(0.0, first + k * pace - time.perf_counter()))
            update = live.add(part.points, part.viewpoints)
            done += [t for _, t in update.done]
            seconds.append(update.seconds)
            finished.append(len(update.finished))
            waiting.append(update.waiting)
            for stretch in update.inspected:  # where the robot was when it was reported
                reported.append([stretch.axial_end, float(s), [d.axial for d in stretch.defects]])
            points += part.points.shape[0]
            del part
        closing = live.close()
        done += [t for _, t in closing.done]
    mesh = live.mesh()
    np.savez(out.with_suffix(".npz"), vertices=mesh.vertices, faces=mesh.faces)
    out.write_text(json.dumps({
        "length": length, "scans": len(seconds), "points": points, "seconds": seconds,
        "finished": finished, "waiting": waiting, "close": closing.seconds, "peak_mib": peak_mib(),
        "stats": live.summary(), "timings": {k: v for k, v in live.timings.items() if k != "scans"},
        "warnings": sorted({str(w.message) for w in caught}), "generated": made,
        "done": done, "pace": pace, "background": background,
        "parameters": [live.parameters.rho_delta, live.parameters.cube_size],
        "inspection": None if inspection is None else {
            "summary": inspection.summary(), "reported": reported,
            "defects": [[d.axial, d.clock, d.depth] for d in inspection.defects()],
        },
    }, default=float))  # fmt: skip


def _defects(mesh: Mesh, points, viewpoints) -> list:
    """[axial, clock, depth] of each defect `inspect_pipe` finds, by axial position."""
    found = inspect_pipe(mesh, points, viewpoints=viewpoints).defects.defects
    return sorted([d.axial, d.clock, d.depth] for d in found)


def batch(
    length: float, out: Path, live_mesh: Path | None = None, live_run: Path | None = None
) -> None:
    """The batch run of the same scans; its figures to `out`, its mesh beside it; the
    defects the final inspection finds on it and on `live_mesh`, with the points. With
    `live_run` (a replay's figures), given that run's rho+delta, cube size and tolerance,
    and not inspected."""
    path = path_of(length)
    parts = [scan(path, s, k) for k, s in enumerate(stations(length))]
    points = np.concatenate([p.points for p in parts])
    viewpoints = np.concatenate([p.viewpoints for p in parts])
    del parts
    given = {}
    if live_run is not None:
        held = json.loads(live_run.read_text())
        rho_delta, cube_size = held["parameters"]
        given = {"rho_delta": rho_delta, "cube_size": cube_size,
                 "tolerance": held["stats"]["tolerance"]}  # fmt: skip
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = reconstruct(points, viewpoints=viewpoints, **given)
    wall, peak = time.perf_counter() - start, peak_mib()
    mesh = result.mesh
    np.savez(out.with_suffix(".npz"), vertices=mesh.vertices, faces=mesh.faces)
    if live_run is not None:
        out.write_text(json.dumps({
            "seconds": wall, "peak_mib": peak,
            "parameters": [result.parameters.rho_delta, result.parameters.cube_size],
        }))  # fmt: skip
        return
    model = result.stats["noise_model"]
    held = replace(result.parameters, noise_model=(model["intercept"], model["slope"]))
    like = {"parameters": held, "origin": result.offset, "tolerance": result.stats["tolerance"]}
    out.with_suffix(".pickle").write_bytes(pickle.dumps(like))
    start = time.perf_counter()
    found = _defects(mesh, points, viewpoints)
    inspected = time.perf_counter() - start
    live_found = None if live_mesh is None else _defects(_mesh(live_mesh), points, viewpoints)
    out.write_text(json.dumps({
        "defects": found, "live_defects": live_found, "inspect_seconds": inspected,
        "seconds": wall, "points": int(points.shape[0]), "peak_mib": peak,
        "parameters": [result.parameters.rho_delta, result.parameters.cube_size],
        "stats": {k: v for k, v in result.stats.items() if isinstance(v, int | float)},
    }))  # fmt: skip


def _child(mode: str, length: float, folder: Path, *extra) -> dict:
    """Run `mode` for `length` in a process of its own; its figures."""
    out = folder / f"{mode}-{length:g}{'-' + extra[0].strip('-') if extra else ''}.json"
    subprocess.run(
        [sys.executable, __file__, f"--{mode}", str(length), "--json", str(out), *extra],
        check=True,
    )
    return json.loads(out.read_text()) | {"mesh": out.with_suffix(".npz")}


def _mesh(path: Path) -> Mesh:
    data = np.load(path)
    return Mesh(vertices=data["vertices"], faces=data["faces"])


def _shape(mesh: Mesh) -> str:
    components = face_components(mesh.faces, mesh.n_vertices)[0]
    return f"{components} / {len(boundary_loops(mesh.faces))}"


def report(
    runs, batch_run, batch_held, alike, previewed, ranged, truth: Mesh, machine: dict, command: str
) -> str:
    """The markdown section."""
    lines = ["## Live: a pipe run replayed scan by scan", ""]
    lines += reproduce_lines(command, machine, "about 35 minutes")[:6]
    first = runs[LENGTHS[0]]
    lines += [
        f"A pipe run of radius {RADIUS} m with two bends (bend radius {BEND_RADIUS} m), "
        f"scanned by the in-pipe model at a station every {SPACING} m (rotation step "
        f"{ROTATION_STEP} degrees), each scan given to `LiveReconstruction.add` with its "
        "sensor positions as soon as it is made (defaults: parameters measured from the "
        "first scans, reach the longest range seen, a budget of 1 s of block work a scan, "
        "no previews), and inspected as its blocks finish (`zeroset.inspect.LiveInspection`, "
        "defaults). The last rows are the 20 m run with each scan's points cropped to "
        f"{RANGE:g} m of its sensor and that reach (a scanner of that range), and the 20 m "
        "run given the batch run's parameters, without the inspection. Seconds per scan "
        "are those of `add`, making the scan left out; "
        "waiting: blocks sealed but not yet finished after the scan; peak memory is the "
        "process's resident peak.",
        "",
        "| run | scans | points | per scan median s | p95 s | largest s | most waiting | "
        "close s | blocks | triangles | peak MiB |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    named = [(f"{length:g} m", run) for length, run in runs.items()]
    named += [(f"{LENGTHS[0]:g} m, range {RANGE:g} m", ranged),
              (f"{LENGTHS[0]:g} m, not inspected", alike)]  # fmt: skip
    for name, run in named:
        s = np.asarray(run["seconds"])
        lines.append(
            f"| {name} | {run['scans']} | {run['points']:,} | {np.median(s):.2f} | "
            f"{np.quantile(s, 0.95):.2f} | {s.max():.2f} | {max(run['waiting'])} | "
            f"{run['close']:.1f} | {run['stats']['blocks_finished']} | "
            f"{run['stats']['faces']:,} | {run['peak_mib']:,.0f} |"
        )
    ratio = runs[LENGTHS[1]]["peak_mib"] / first["peak_mib"]
    shown = np.asarray(previewed["seconds"])
    lines += [
        "",
        f"Peak memory, {LENGTHS[1]:g} m over {LENGTHS[0]:g} m: {ratio:.2f}x. With the open "
        f"blocks within {PREVIEW:g} m of the sensor previewed at every scan, the "
        f"{LENGTHS[0]:g} m run's seconds per scan: median {np.median(shown):.2f}, p95 "
        f"{np.quantile(shown, 0.95):.2f}.",
        "",
    ]
    # "finish" holds "repair", "rim", "refine" and "simplify"
    work = sum(first["timings"].get(k, 0.0) for k in ("parameters", "contour", "finish", "inspect"))
    least = batch_run["seconds"] + batch_run["inspect_seconds"]
    lines += [
        f"Work a scan: the {LENGTHS[0]:g} m live run's stages took {work:.0f} s over its "
        f"{first['scans']} scans, {work / first['scans']:.1f} s a scan; the batch run's "
        f"reconstruction and inspection of the same points, {least:.0f} s, "
        f"{least / first['scans']:.1f} s a scan. Given faster than that, the work falls "
        "behind the scans: it is left to later scans and to `close`, and a background run's "
        '`add` waits once its queue is full ("Live at the robot\'s pace").',
        "",
    ]
    batch_mesh = _mesh(batch_run["mesh"])
    batch_truth = compare_to_reference(batch_mesh, truth, n_samples=100_000)["chamfer_l1"]
    stage_seconds = ", ".join(f"{k} {v:.0f}" for k, v in first["timings"].items())
    lines += [
        f"The {LENGTHS[0]:g} m run against the batch run of the same points "
        f"({batch_run['seconds']:.0f} s, peak {batch_run['peak_mib']:,.0f} MiB; the live "
        f"run's stages, s: {stage_seconds}; finish holds repair to simplify); the live run "
        "given the batch run's parameters, range-noise model, tolerance and lattice origin; "
        "and the batch run given the live run's held rho+delta, cube size and tolerance (on "
        "its own lattice "
        f"origin; {batch_held['seconds']:.0f} s):",
        "",
        "| | live | live on the batch's lattice | batch given the live run's parameters | batch |",
        "|---|---|---|---|---|",
    ]
    rows = {"rho+delta, cube (mm)": [], "triangles": [], "components / boundary loops": [],
            "mean distance to the batch mesh and back (mm)": [],
            "Chamfer-L1 to the truth (mm)": []}  # fmt: skip
    gaps, shapes, ratios = [], [], []  # each column's; the targets read the two live runs'
    for run in (first, alike, batch_held):
        mesh = _mesh(run["mesh"])
        between = compare_to_reference(mesh, batch_mesh, n_samples=100_000)
        gaps.append((between["accuracy"]["mean"], between["completeness"]["mean"]))
        shapes.append(_shape(mesh))
        rows["rho+delta, cube (mm)"].append(
            f"{run['parameters'][0] * 1e3:.1f}, {run['parameters'][1] * 1e3:.1f}"
        )
        rows["triangles"].append(f"{mesh.n_faces:,}")
        rows["components / boundary loops"].append(_shape(mesh))
        rows["mean distance to the batch mesh and back (mm)"].append(
            f"{between['accuracy']['mean'] * 1e3:.3f} / {between['completeness']['mean'] * 1e3:.3f}"
        )
        chamfer = compare_to_reference(mesh, truth, n_samples=100_000)["chamfer_l1"]
        rows["Chamfer-L1 to the truth (mm)"].append(
            f"{chamfer * 1e3:.3f} ({chamfer / batch_truth:.3f}x)"
        )
        ratios.append(chamfer / batch_truth)
    batch_cells = [
        f"{batch_run['parameters'][0] * 1e3:.1f}, {batch_run['parameters'][1] * 1e3:.1f}",
        f"{batch_mesh.n_faces:,}", _shape(batch_mesh), "", f"{batch_truth * 1e3:.3f}",
    ]  # fmt: skip
    for (name, cells), last in zip(rows.items(), batch_cells, strict=True):
        lines.append(f"| {name} | {' | '.join(cells)} | {last} |")
    counts = ("small_holes_filled", "small_components_dropped")
    lines += [
        "",
        "Holes closed and components dropped, batch: "
        + ", ".join(f"{batch_run['stats'].get(k, 0)}" for k in counts)
        + "; live, summed over the blocks' regions: "
        + ", ".join(f"{first['stats'].get(k, 0)}" for k in counts)
        + ".",
        "",
    ]
    lines += inspection_lines(first, batch_run, ranged)
    if first["warnings"]:
        lines += ["Warnings of the live run:", ""]
        lines += [f"- {w}" for w in first["warnings"]] + [""]
    lines += target_lines(first, ratio, gaps[:2], shapes[:2], _shape(batch_mesh), ratios[:2],
                          batch_run)  # fmt: skip
    lines += reproduce_lines(command, machine)[6:]
    return "\n".join(lines)


def target_lines(first, memory, gaps, shapes, batch_shape, ratios, batch_run) -> list[str]:
    """The targets of a live run against what the 20 m run measured, as markdown: `memory`
    the 40 m run's peak over the 20 m run's; `gaps`, `shapes` and `ratios` the mean
    distances to the batch mesh each way, components / loops and Chamfer-L1 over the
    batch's, of the live run and of the live run on the batch's lattice."""
    seconds = np.asarray(first["seconds"])

    def verdict(met: bool) -> str:
        return "met" if met else "**not met**"

    def found(defects) -> tuple[int, int]:
        near = sum(any(abs(f[0] - d.axial) < 0.1 for f in defects or []) for d in DENTS)
        return near, len(_elsewhere(defects))

    final = found(batch_run["live_defects"]), found(batch_run["defects"])
    median, p95 = np.median(seconds), np.quantile(seconds, 0.95)
    rows = [
        ("`add`, median a scan (given as made)", "<= 1 s", f"{median:.2f} s", median <= 1.0),
        ("`add`, 95th percentile a scan (given as made)", "<= 3 s", f"{p95:.2f} s", p95 <= 3.0),
    ]
    for name, gap, shape, chamfer in zip(("live", "live on the batch's lattice"), gaps, shapes,
                                         ratios, strict=True):  # fmt: skip
        rows += [
            (f"components / boundary loops, {name}", f"batch's, {batch_shape}", shape,
             shape == batch_shape),
            (f"mean distance to the batch mesh and back, {name}", "<= 0.05 mm",
             f"{gap[0] * 1e3:.3f} / {gap[1] * 1e3:.3f} mm", max(gap) <= 5e-5),
            (f"Chamfer-L1 to the truth over the batch's, {name}", "<= 1.05",
             f"{chamfer:.3f}", chamfer <= 1.05),
        ]  # fmt: skip
    rows += [
        (f"peak memory, {LENGTHS[1]:g} m over {LENGTHS[0]:g} m", "<= 1.2", f"{memory:.2f}",
         memory <= 1.2),
        ("final inspection of the live mesh: dents found, defects elsewhere",
         f"batch mesh's, {final[1][0]} and {final[1][1]}", f"{final[0][0]} and {final[0][1]}",
         final[0] == final[1]),
    ]  # fmt: skip
    lines = ["### Targets", "", "| criterion | target | measured | verdict |",
             "|---|---|---|---|"]  # fmt: skip
    lines += [f"| {a} | {b} | {c} | {verdict(d)} |" for a, b, c, d in rows]
    lines += ["", "Measured on 2 cores, as the targets say; `add` given the scans at the robot's "
              "pace, in the background: \"Live at the robot's pace\" below.", ""]  # fmt: skip
    return lines


def _cell(found) -> str:
    """A defect [axial, clock, depth] as "axial, clock, depth in mm", or "not found"."""
    return "not found" if found is None else (
        f"{found[0]:.3f}, {found[1]:.0f}, {-1e3 * found[2]:.2f}"
    )  # fmt: skip


def _elsewhere(found) -> list:
    """The defects of `found` ([axial, clock, depth]) farther than 0.1 m from every dent."""
    return [f for f in found or [] if all(abs(f[0] - d.axial) >= 0.1 for d in DENTS)]


def inspection_lines(run: dict, batch_run: dict, ranged: dict) -> list[str]:
    """The live inspections against the truth and the final inspections, as markdown."""
    lines = []
    for name, one in ((f"The {LENGTHS[0]:g} m run's", run),
                      (f"With a range of {RANGE:g} m, the", ranged)):  # fmt: skip
        summary = one["inspection"]["summary"]
        windows = np.array([w["seconds"] for w in summary["stretches"]])
        lines.append(
            f"{name} live inspection reported {len(summary['stretches'])} stretches, to "
            f"{summary['inspected_to']:.2f} m of the {one['length']:g} m run (windows "
            f"{np.median(windows):.1f} s median, {windows.max():.1f} s largest, "
            f"{one['timings'].get('inspect', 0):.0f} s in all, in the seconds per scan "
            f"above), holding a nominal diameter of {1e3 * summary['nominal_diameter']:.1f} mm "
            f"and a threshold of {1e3 * summary['threshold']:.2f} mm from its first window."
        )
    lines += [
        "",
        "Each dent as the live inspections reported it, with where the sensor was then "
        "along the run, and as the final inspection of each mesh with every point found it "
        "(axial m, clock degrees, depth mm):",
        "",
        "| dent | truth | live | reported, sensor at | live, range "
        f"{RANGE:g} m | reported, sensor at | final, live mesh | final, batch mesh |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def nearest(found, dent):
        near = [f for f in found or [] if abs(f[0] - dent.axial) < 0.1]
        return min(near, key=lambda f: abs(f[0] - dent.axial)) if near else None

    def when(one, dent):
        if nearest(one["inspection"]["defects"], dent) is None:
            return "never"
        reported = one["inspection"]["reported"]
        at = next((r[1] for r in reported if nearest([[a, 0, 0] for a in r[2]], dent)), None)
        return "at close" if at is None else f"{at:.2f} m"

    for k, dent in enumerate(DENTS, start=1):
        lines.append(
            f"| {k} | {dent.axial:.3f}, {dent.clock:.0f}, {1e3 * dent.depth:.2f} | "
            f"{_cell(nearest(run['inspection']['defects'], dent))} | {when(run, dent)} | "
            f"{_cell(nearest(ranged['inspection']['defects'], dent))} | {when(ranged, dent)} | "
            f"{_cell(nearest(batch_run['live_defects'], dent))} | "
            f"{_cell(nearest(batch_run['defects'], dent))} |"
        )
    others = []
    for name, found in (("live", run["inspection"]["defects"]),
                        (f"live, range {RANGE:g} m", ranged["inspection"]["defects"]),
                        ("final, live mesh", batch_run["live_defects"]),
                        ("final, batch mesh", batch_run["defects"])):  # fmt: skip
        false = _elsewhere(found)
        where = f" ({'; '.join(map(_cell, false))})" if false else ""
        others.append(f"{name} {len(false)}{where}")
    lines += [
        "",
        "Defects found where there is none: " + ", ".join(others) + ". The final inspection "
        f"of the batch mesh took {batch_run['inspect_seconds']:.0f} s.",
        "",
    ]
    return lines


def robot(output: Path, keep: Path | None = None) -> None:
    """The ``--robot`` runs and their section; with `keep`, the runs' figures and meshes
    are left in that folder."""
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary) if keep is None else keep
        folder.mkdir(parents=True, exist_ok=True)
        paced = ("--pace", f"{STATION_SECONDS:g}", "--background")
        runs = [(f"{length:g} m, a scan every {STATION_SECONDS:g} s", _child(
            "replay", length, folder, *paced)) for length in LENGTHS]  # fmt: skip
        runs.append((f"{LENGTHS[0]:g} m, back to back", _child(
            "replay", LENGTHS[0], folder, "--background")))  # fmt: skip
    text = robot_report(runs, machine_info(), "python benchmarks/bench_live.py --robot")
    replace_section(output, "live-robot", text)
    print(text)


def robot_report(runs, machine: dict, command: str) -> str:
    """The markdown section of the ``--robot`` runs."""
    lines = ["## Live at the robot's pace: the work in the background", ""]
    lines += reproduce_lines(command, machine, "about 40 minutes")[:6]
    lines += [
        "The runs of the section above (inspected live, defaults), given to a "
        "`LiveReconstruction(background=True)` as the robot makes them: the model's scanner "
        f"turns a line every {LINE_SECONDS:g} s (a URG-04LX's motor turns at 600 rpm), "
        f"{np.floor(360 / ROTATION_STEP):.0f} lines a station, so a station's scan takes "
        f"{STATION_SECONDS:g} s before the robot moves on; scan k is given "
        f"{STATION_SECONDS:g} k s after the first (its making included), or as soon as it is "
        "made in the last row. add: the seconds the call took; behind: the seconds from "
        "a scan's `add` to the end of its work in the worker (`ScanUpdate.done`), how old "
        "the mesh is; peak memory is the process's resident peak.",
        "",
        "| run | scans | add median s | p95 s | largest s | behind median s | p95 s | "
        "largest s | close s | peak MiB |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, run in runs:
        s, behind = np.asarray(run["seconds"]), np.asarray(run["done"])
        lines.append(
            f"| {name} | {run['scans']} | {np.median(s):.3f} | {np.quantile(s, 0.95):.3f} | "
            f"{s.max():.3f} | {np.median(behind):.2f} | {np.quantile(behind, 0.95):.2f} | "
            f"{behind.max():.2f} | {run['close']:.1f} | {run['peak_mib']:,.0f} |"
        )
    ratio = runs[1][1]["peak_mib"] / runs[0][1]["peak_mib"]
    lines += ["", f"Peak memory, {LENGTHS[1]:g} m over {LENGTHS[0]:g} m: {ratio:.2f}x.", ""]
    for name, run in runs:
        reported = run["inspection"]["reported"]
        found = run["inspection"]["defects"]
        when = []
        for dent in DENTS:
            at = next((r[1] for r in reported if any(abs(a - dent.axial) < 0.1 for a in r[2])),
                      None)  # fmt: skip
            if at is None:
                at = "at close" if any(abs(f[0] - dent.axial) < 0.1 for f in found) else "never"
            else:
                at = f"at {at:.2f} m"
            when.append(f"{dent.axial:g} m {at}")
        near = [f for f in found if f not in _elsewhere(found)]
        false = "; ".join(map(_cell, _elsewhere(found))) or "none"
        twice = [f"{d.axial:g} m ({n})" for d in DENTS
                 if (n := sum(abs(f[0] - d.axial) < 0.1 for f in found)) > 1]  # fmt: skip
        if twice:
            false += "; dents found more than once: " + ", ".join(twice)
        missed = [f"{d.axial:g} m" for d in DENTS
                  if not any(abs(f[0] - d.axial) < 0.1 for f in found)]  # fmt: skip
        if missed:
            false += "; dents not reported: " + ", ".join(missed)
        lines.append(
            f"- {name}: the live inspection found {len(found)} defects, {len(near)} within "
            f"0.1 m of a dent ({'; '.join(map(_cell, near))}); each dent reported with the "
            f"sensor at: {', '.join(when)}; defects where there is none (axial m, clock "
            f"degrees, depth mm): {false}."
        )
    lines += [""] + reproduce_lines(command, machine)[6:]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replay", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--batch", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--like", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--preview", type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument("--live-mesh", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--reach", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--pace", type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument("--background", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--robot", action="store_true", help="replay at the robot's pace, in the background"
    )
    parser.add_argument(
        "--keep", type=Path, metavar="DIR", help="with --robot: leave the runs' figures and "
        "meshes in DIR"
    )  # fmt: skip
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args()
    if args.replay is not None:
        return replay(
            args.replay, args.json, args.like, args.preview, args.reach, args.pace,
            args.background,
        )  # fmt: skip
    if args.robot:
        return robot(args.output, args.keep)
    if args.batch is not None:
        return batch(args.batch, args.json, args.live_mesh, args.like)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        runs = {length: _child("replay", length, folder) for length in LENGTHS}
        live_mesh = str(runs[LENGTHS[0]]["mesh"])
        batch_run = _child("batch", LENGTHS[0], folder, "--live-mesh", live_mesh)
        live_run = str(runs[LENGTHS[0]]["mesh"].with_suffix(".json"))
        batch_held = _child("batch", LENGTHS[0], folder, "--like", live_run)
        like = batch_run["mesh"].with_suffix(".pickle")
        alike = _child("replay", LENGTHS[0], folder, "--like", str(like))
        previewed = _child("replay", LENGTHS[0], folder, "--preview", str(PREVIEW))
        ranged = _child("replay", LENGTHS[0], folder, "--reach", str(RANGE))
        truth = scan_pipe_run(
            path_of(LENGTHS[0]), radius=RADIUS, stations=[1.0], rotation_step=30.0,
            defects=DENTS, rng=0,
        ).truth  # fmt: skip
        text = report(
            runs, batch_run, batch_held, alike, previewed, ranged, truth, machine_info(),
            "python benchmarks/bench_live.py",
        )  # fmt: skip
    replace_section(args.output, "live", text)
    print(text)


if __name__ == "__main__":
    main()
