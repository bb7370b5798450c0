"""Inspection of pipe runs: random runs with bends, tees, joints and defects, scanned by the
in-pipe model, against their recorded truth; writes its section of docs/benchmarks.md and
the unrolled map of a run to docs/images/inspection-run.png.

Run by hand from the repository root::

    python benchmarks/bench_runs.py --runs 20 --joint-runs 5

Each run is drawn by `zeroset.synthetic.random_pipe_run` (seed = run number; 2-4 bends of
radius 1-3 D, legs 1-5 D, D = 0.4 m; runs 0-4 with a bend out of plane, 5-7 with a tee),
scanned at its stations (0.5-1.5 m apart), reconstructed with the defaults and inspected
with `inspect_pipe(mesh, points, viewpoints=...)`. The same run without damage gives the
false defects and branches. A found defect is matched to the truth by position (3 cm
along, 10 degrees round); the centreline's error is the largest distance of the true
centreline, where data cover it, from the fitted one. Beside each defect's depth error
and reported interval stands the interval its points allow at best (`_depth_bound`, the
Cramer-Rao bound with its shape and place unknown): where that is wider than the target,
the target cannot be met from those points.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _docfile import replace_section
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUTPUT = ROOT / "docs" / "benchmarks.md"
PICTURE = ROOT / "docs" / "images" / "inspection-run.png"
#: Matching a found defect or joint to the truth: along (m) and round (degrees).
AXIAL_MATCH, CLOCK_MATCH = 0.03, 10.0
JOINT_MATCH = 0.05
TARGET_SECONDS = 30.0


def _inspect(sample):
    """Reconstruct and inspect a scanned sample; the inspection and both times (s)."""
    from zeroset import reconstruct
    from zeroset.inspect import inspect_pipe

    start = time.perf_counter()
    mesh = reconstruct(sample.points, viewpoints=sample.viewpoints, progress=False).dense_mesh
    middle = time.perf_counter()
    inspection = inspect_pipe(mesh, sample.points, viewpoints=sample.viewpoints)
    return inspection, middle - start, time.perf_counter() - middle


def _centreline_error(inspection, sample) -> tuple[float, float]:
    """The largest distance (m) of the true centreline from the fitted one, where the
    data cover it (between the first and last positions along the truth that scan points
    lie nearest to), and between the first and last station only."""
    truth = np.array(sample.truth_record["centreline"])
    nearest = truth[cKDTree(truth[:, 1:]).query(sample.points)[1], 0]
    covered = (truth[:, 0] >= nearest.min()) & (truth[:, 0] <= nearest.max())
    gaps = cKDTree(inspection.pipe.centres).query(truth[:, 1:])[0]
    stations = sample.truth_record["stations"]
    between = (truth[:, 0] >= min(stations)) & (truth[:, 0] <= max(stations))
    return float(gaps[covered].max()), float(gaps[covered & between].max())


def _defect_rows(inspection, truth: list[dict]) -> list[dict]:
    """Per true defect: the nearest found one within the match, and its errors."""
    pipe, rows = inspection.pipe, []
    for defect in truth:
        axial, clock, _ = pipe.locate(np.array([defect["centre"]]))
        near = [
            d
            for d in inspection.defects.defects
            if abs(d.axial - axial[0]) <= AXIAL_MATCH
            and abs((d.clock - clock[0] + 180) % 360 - 180) <= CLOCK_MATCH
        ]
        found = min(near, key=lambda d: abs(d.axial - axial[0]), default=None)
        sign = -1.0 if defect["kind"] == "dent" else 1.0
        rows.append(
            {
                "truth": defect,
                "found": found,
                "depth": None if found is None else sign * found.depth - defect["depth"],
                "axial": None if found is None else found.axial - axial[0],
                "clock": None if found is None else (found.clock - clock[0] + 180) % 360 - 180,
            }
        )
    return rows


def _depth_bound(inspection, located, defect: dict) -> tuple[float, int]:
    """The Cramer-Rao bound (m, one standard deviation) of a true `defect`'s depth from
    the scan points `located` on the fitted pipe (``pipe.locate``), and how many lie on
    its footprint: the least error any unbiased estimate of its depth can have, with the
    defect's shape (the raised cosine a defect is fitted with, its six parameters
    unknown) and Gaussian noise along the radius at the points' measured noise there
    (`WallMap.noise_along`). Points within 1.5 widths of its centre count."""
    from zeroset.inspect._bump import bump

    pipe = inspection.pipe
    axial, clock, _ = pipe.locate(np.array([defect["centre"]]))
    a = located[0] - axial[0]
    b = np.radians((located[1] - clock[0] + 180.0) % 360.0 - 180.0) * pipe.radius
    near = np.hypot(a, b) < 1.5 * defect["width"]
    a, b = a[near], b[near]
    half = np.log(0.5 * defect["width"])
    q = np.array([0.0, defect["depth"], 0.0, 0.0, half, half])
    steps = np.diag([1e-6, 1e-6, 1e-6, 1e-6, 1e-4, 1e-4])
    columns = [(bump(q + h)(a, b) - bump(q - h)(a, b)) / (2 * h.sum()) for h in steps]
    jacobian = np.stack(columns, axis=1)
    sigma = float(inspection.wall.noise_along(axial)[0])
    footprint = int(np.count_nonzero(np.hypot(a, b) < 0.5 * defect["width"]))
    try:
        spread = np.linalg.inv(jacobian.T @ jacobian) * sigma**2
    except np.linalg.LinAlgError:
        return float("inf"), footprint
    return float(np.sqrt(max(spread[0, 0] + spread[1, 1] + 2 * spread[0, 1], 0.0))), footprint


def _spacing(stations, axial: float) -> float:
    """The distance (m) between the stations on either side of arc length `axial`; beyond
    the first or last, twice the distance to it."""
    stations = np.sort(stations)
    after = int(np.searchsorted(stations, axial))
    if after == 0:
        return float(2 * (stations[0] - axial))
    if after == stations.size:
        return float(2 * (axial - stations[-1]))
    return float(stations[after] - stations[after - 1])


def _joint_rows(inspection, truth: list[dict]) -> list[dict]:
    """Per true joint: the nearest found one within `JOINT_MATCH` and its errors."""
    rows = []
    for joint in truth:
        axial = float(inspection.pipe.locate(np.array([joint["centre"]]))[0][0])
        near = [j for j in inspection.joints if abs(j.axial - axial) <= JOINT_MATCH]
        found = min(near, key=lambda j: abs(j.axial - axial), default=None)
        rows.append(
            {
                "truth": joint,
                "found": found,
                "kind": found is not None and found.kind == joint["kind"],
                "axial": None if found is None else found.axial - axial,
                "size": None if found is None else found.size - joint["size"],
            }
        )
    return rows


def _runs(count: int, rotation_step: float) -> tuple[list[str], list[dict]]:
    """The table of the random runs, one row each."""
    from zeroset.synthetic import random_pipe_run

    lines = [
        "| run | bends | tee | points | centreline error, mm (between stations) | defects "
        "found | depth errors, mm (reported ± 95 %; bound ± 95 %) | false defects, damaged "
        "| false defects / branches / joints, undamaged | threshold, mm | inspect, s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    results = []
    for seed in range(count):
        spec = random_pipe_run(seed, defects=3, out_of_plane=seed < 5, tee=5 <= seed < 8)
        sample = spec.scan(rotation_step=rotation_step)
        inspection, _, seconds = _inspect(sample)
        clean_sample = spec.without_damage().scan(rotation_step=rotation_step)
        clean = _inspect(clean_sample)[0]
        error, between = _centreline_error(inspection, sample)
        rows = _defect_rows(inspection, sample.truth_record["defects"])
        located = inspection.pipe.locate(sample.points)
        for row in rows:
            row["spacing"] = _spacing(spec.stations, row["truth"]["axial"])
            row["bound"], row["footprint"] = _depth_bound(inspection, located, row["truth"])
        bends = sum(piece[0] == "bend" for piece in sample.truth_record["path"]["pieces"])
        false_branches = len(clean.defects.branches) - len(spec.tees)
        matched = {id(r["found"]) for r in rows if r["found"] is not None}
        extra = sum(id(d) not in matched for d in inspection.defects.defects)
        results.append(
            {
                "seed": seed,
                "rows": rows,
                "error": error,
                "between": between,
                "false": len(clean.defects.defects),
                "extra": extra,
                "false_joints": len(clean.joints) + len(inspection.joints),  # runs without
                "false_branches": max(false_branches, 0),
                "missed_branches": max(-false_branches, 0),
                "seconds": seconds,
                "points": sample.points.shape[0],
            }
        )
        depths = ", ".join(
            f"missed ({r['footprint']} points, bound ±{1960 * r['bound']:.1f})"
            if r["found"] is None
            else f"{1000 * r['depth']:+.1f} (±{1960 * r['found'].uncertainty:.1f}; "
            f"±{1960 * r['bound']:.1f})"
            for r in rows
        )
        lines.append(
            f"| {seed} | {bends} | {'yes' if spec.tees else ''} | "
            f"{sample.points.shape[0]:,} | {1000 * error:.1f} ({1000 * between:.1f}) | "
            f"{sum(r['found'] is not None for r in rows)}/{len(rows)} | {depths} | {extra} | "
            f"{len(clean.defects.defects)} / {max(false_branches, 0)} / {len(clean.joints)} | "
            f"{1000 * inspection.defects.threshold:.2f} | {seconds:.1f} |"
        )
        print(lines[-1], flush=True)
    return lines, results


def _missed(row: dict) -> str:
    """A missed defect in words: its truth, the points on it and its depth's bound."""
    truth = row["truth"]
    return (
        f"the {1000 * truth['depth']:.1f} mm {truth['kind']}, {100 * truth['width']:.1f} cm "
        f"wide, with {row['footprint']} points on it (bound ±{1960 * row['bound']:.1f} mm)"
    )


def _summary(results: list[dict]) -> list[str]:
    """The targets of the runs, met or not, in a few lines."""
    rows = [r for result in results for r in result["rows"]]
    found = [r for r in rows if r["found"] is not None]
    close = [r for r in found if r["spacing"] <= 1.0]
    inside = [r for r in found if abs(r["depth"]) <= 1.96 * r["found"].uncertainty]
    narrow = [r for r in found if 1.96 * r["found"].uncertainty <= 0.003]
    beyond = [r for r in found if 1.96 * r["found"].uncertainty > 0.003]
    bounded = [r for r in beyond if 1.96 * r["bound"] > 0.003]
    missed = [r for r in rows if r["found"] is None]
    bounds = ", ".join(f"±{1960 * r['bound']:.1f}" for r in bounded)
    bounds = f" ({bounds} mm)" if bounds else ""
    worst = max(result["error"] for result in results)
    seconds = [result["seconds"] for result in results]
    return [
        f"- **Centreline**: largest error {1000 * worst:.1f} mm over the data of "
        f"{len(results)} runs ({sum(r['error'] <= 0.005 for r in results)} within 5 mm); "
        "between the first and last station "
        f"{1000 * max(r['between'] for r in results):.1f} mm.",
        f"- **Defects**: {len(found)}/{len(rows)} found within {100 * AXIAL_MATCH:.0f} cm and "
        f"{CLOCK_MATCH:.0f} degrees; depth within 1.5 mm for "
        f"{sum(abs(r['depth']) <= 0.0015 for r in close)}/{len(close)} of those found between "
        f"stations at most 1 m apart; inside the reported 95 % interval "
        f"{len(inside)}/{len(found)} (exact 95 % intervals would hold all of them with "
        f"probability {100 * 0.95 ** len(found):.1f} %); interval no wider than ±3 mm "
        f"{len(narrow)}/{len(found)}.",
        f"- **What the points allow** (the bound: the Cramer-Rao bound of the depth, see "
        f"`_depth_bound`): of the {len(beyond)} intervals wider than ±3 mm, the bound is "
        f"wider than ±3 mm too for {len(bounded)}{bounds}: there no unbiased estimate from "
        "the points meets the target. Missed: " + (", ".join(map(_missed, missed)) or "none") + ".",
        f"- **Undamaged runs**: {sum(r['false'] for r in results)} false defects, "
        f"{sum(r['false_branches'] for r in results)} false branches, "
        f"{sum(r['missed_branches'] for r in results)} tees missed. Beside the true defects "
        f"of the damaged runs, {sum(r['extra'] for r in results)} false ones. Joints (none "
        f"in these runs) reported on both: {sum(r['false_joints'] for r in results)}.",
        f"- **Inspection time** of these runs: {statistics.median(seconds):.1f} s "
        f"median, {max(seconds):.1f} s at most (largest run "
        f"{max(r['points'] for r in results):,} points); the target is "
        f"{TARGET_SECONDS:.0f} s for 1M points on 2 cores.",
    ]


def _joints(count: int, rotation_step: float) -> list[str]:
    """Runs with joints and 3 % ovality: joints, ovality and the threshold beside the same
    runs without them."""
    from zeroset.synthetic import random_pipe_run

    joint_rows, ovality, thresholds, joint_defects, false_joints = [], [], [], 0, 0
    for seed in range(100, 100 + count):
        spec = random_pipe_run(seed, defects=3, joints=(1.0, 3.0), ovality=0.03)
        sample = spec.scan(rotation_step=rotation_step)
        inspection = _inspect(sample)[0]
        plain = replace(spec, joints=(), ovality=0.0)  # the same run, defects and stations
        plain_inspection = _inspect(plain.scan(rotation_step=rotation_step))[0]
        rows = _joint_rows(inspection, sample.truth_record["joints"])
        joint_rows.extend(rows)
        matched = {id(r["found"]) for r in rows if r["found"] is not None}
        false_joints += sum(id(j) not in matched for j in inspection.joints)
        for joint in sample.truth_record["joints"]:
            axial = inspection.pipe.locate(np.array([joint["centre"]]))[0][0]
            joint_defects += sum(
                abs(d.axial - axial) <= 0.5 * max(joint["size"], 0.02) + AXIAL_MATCH
                for d in inspection.defects.defects
            )
        fitted = inspection.ovality.ovality
        ovality.append(100 * (float(np.nanmedian(fitted)) - 0.03))
        thresholds.append((plain_inspection.defects.threshold, inspection.defects.threshold))
    lines = [
        "| joint | found | kind right | axial error, mm | size error, mm |",
        "|---|---|---|---|---|",
    ]
    for kind in ("gap", "offset", "bead"):
        mine = [r for r in joint_rows if r["truth"]["kind"] == kind]
        hits = [r for r in mine if r["found"] is not None]
        if not mine:
            continue
        lines.append(
            f"| {kind} | {len(hits)}/{len(mine)} | {sum(r['kind'] for r in hits)}/{len(hits)} | "
            + (
                f"{max(1000 * abs(r['axial']) for r in hits):.1f} max | "
                f"{statistics.mean(1000 * r['size'] for r in hits):+.2f} mean, "
                f"{max(1000 * abs(r['size']) for r in hits):.2f} max |"
                if hits
                else "| |"
            )
        )
    within = sum(
        r["found"] is not None and abs(r["axial"]) <= 0.02 and abs(r["size"]) <= 0.0015
        for r in joint_rows
    )
    return [
        *lines,
        "",
        f"- Joints found within 2 cm with their size within 1.5 mm: {within}/{len(joint_rows)};"
        f" defects reported at a joint: {joint_defects}; joints reported where there is none:"
        f" {false_joints}.",
        f"- Ovality 3 %: the median over the stations off by "
        f"{statistics.mean(ovality):+.2f} points on average, at most "
        f"{max(map(abs, ovality)):.2f}.",
        "- Threshold without / with the joints and ovality, mm: "
        + ", ".join(f"{1000 * a:.2f} / {1000 * b:.2f}" for a, b in thresholds)
        + f" (largest change {100 * max(abs(b / a - 1) for a, b in thresholds):.1f} %).",
    ]


def _timing() -> list[str]:
    """Inspecting a run of about 1M points: the median of three, with its stages."""
    from zeroset import reconstruct
    from zeroset.inspect import inspect_pipe
    from zeroset.synthetic import random_pipe_run

    sample = random_pipe_run(0, defects=3).scan(rotation_step=1.8)
    mesh = reconstruct(sample.points, viewpoints=sample.viewpoints, progress=False).dense_mesh
    runs = []
    for _ in range(3):
        start = time.perf_counter()
        inspection = inspect_pipe(mesh, sample.points, viewpoints=sample.viewpoints)
        runs.append((time.perf_counter() - start, inspection.timings))
    seconds, stages = sorted(runs, key=lambda run: run[0])[1]
    verdict = "meets" if seconds <= TARGET_SECONDS else "misses"
    return [
        f"- **Time**: inspecting run 0 scanned with 1.8 degrees between lines "
        f"({sample.points.shape[0]:,} points) takes **{seconds:.1f} s** (median of 3), "
        f"which {verdict} the target of {TARGET_SECONDS:.0f} s on 2 cores; stages: "
        + ", ".join(f"{name} {value:.1f} s" for name, value in stages.items())
        + "."
    ]


def _picture(rotation_step: float) -> list[str]:
    """The unrolled map of a run with two bends, joints and dents, for the README."""
    from zeroset.inspect import deviation_map
    from zeroset.synthetic import random_pipe_run

    spec = random_pipe_run(7, bends=(2, 2), defects=3, joints=(1.0, 2.0), ovality=0.01)
    inspection = _inspect(spec.scan(rotation_step=rotation_step))[0]
    PICTURE.parent.mkdir(parents=True, exist_ok=True)
    PICTURE.write_bytes(
        deviation_map(inspection, title="a pipe run with two bends, joints and dents, unrolled")
    )
    return [f"![The unrolled map of a pipe run](images/{PICTURE.name})"]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--joint-runs", type=int, default=5)
    parser.add_argument("--rotation-step", type=float, default=1.0, help="degrees")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    table, results = _runs(args.runs, args.rotation_step)
    lines = [
        "## Inspection of pipe runs",
        "",
        f"Run {datetime.date.today()} on {platform.machine()} with {os.cpu_count()} cores: "
        f"`python benchmarks/bench_runs.py --runs {args.runs} --joint-runs "
        f"{args.joint_runs} --rotation-step {args.rotation_step:g}`. Random runs of 0.4 m "
        "diameter (`random_pipe_run`, seed = run), each scanned by the in-pipe model at its "
        f"stations with {args.rotation_step:g} degrees between scan lines, reconstructed with "
        "the defaults and inspected with the scanner's positions; each again without its "
        "damage for the false defects and branches. Runs 0-4 have a bend out of plane, 5-7 "
        "a tee.",
        "",
        *table,
        "",
        *_summary(results),
        *_timing(),
        "",
        f"**Joints and ovality** ({args.joint_runs} runs with joints every 1-3 m and 3 % "
        "ovality, seeds 100 on; the threshold beside the same runs without them):",
        "",
        *_joints(args.joint_runs, args.rotation_step),
        "",
        *_picture(args.rotation_step),
    ]
    replace_section(args.output, "runs", "\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
