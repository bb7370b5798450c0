"""Inspection of real scans: each real pipe scan in ../shared/data as it is, moved, reversed
and halved, and with dents, bulges, deformations and joints of known size put into its
points (`zeroset.synthetic.inject`); writes its section of docs/benchmarks.md.

Run by hand from the repository root::

    python benchmarks/bench_real.py

Every cloud is reconstructed with the defaults (the dense mesh, as `reconstruct --inspect`
inspects it) and inspected with `inspect_pipe(mesh, points)`. The scans carry no sensor
positions, so the features are put in by moving the points towards the axis of the pipe
fitted to the scan as it is. A found defect matches an injected one of its kind within 3 cm
or a tenth of its width along the pipe and 10 degrees round it; a joint within 2 cm. An
injected defect counts towards the target where at least 30 points lie on it (within half
its width of its centre on the unrolled wall). Places and sizes are drawn with a seed; no
threshold of the inspection was chosen on them.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time
from pathlib import Path

import numpy as np
from _docfile import replace_section

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUTPUT = ROOT / "docs" / "benchmarks.md"
DATA = ROOT.parent / "shared" / "data"
SCANS = {"s3dss_sewer_pipe": "s3dss_sewer_pipe/3_real_459_viz.ply"}
#: Matching found features to injected ones: along (m, or a tenth of the width), round
#: (degrees); joints along (m); the same finding in two runs (m, on the wall).
AXIAL_MATCH, CLOCK_MATCH, JOINT_MATCH, SAME = 0.03, 10.0, 0.02, 0.05
MIN_POINTS = 30
#: Injected depths: multiples of the scan's threshold, and deep ones (m).
MULTIPLES = (1.0, 1.5, 2.0, 3.0, 5.0)
DEEP = (0.025, 0.040)


def _inspect(points):
    """The dense mesh's inspection of `points`, and the seconds of both stages."""
    from zeroset import reconstruct
    from zeroset.inspect import inspect_pipe

    start = time.perf_counter()
    mesh = reconstruct(points, tolerance=0.0, progress=False).dense_mesh
    middle = time.perf_counter()
    inspection = inspect_pipe(mesh, points)
    return mesh, inspection, middle - start, time.perf_counter() - middle


def _findings(inspection, motion=None) -> list[tuple[str, np.ndarray, float]]:
    """Every joint and defect as (kind, position on the wall (3,), size m), taken back
    through the inverse of `motion` (R, t) where given."""
    pipe = inspection.pipe
    out = [(j.kind, pipe.position([j.axial], 0.0, 0.0)[0], j.size) for j in inspection.joints]
    out += [(d.kind, pipe.position([d.axial], d.clock)[0], d.depth)
            for d in inspection.defects.defects]  # fmt: skip
    if motion is not None:
        rotation, shift = motion
        out = [(k, (p - shift) @ rotation, s) for k, p, s in out]
    return out


def _same(a, b) -> tuple[int, int, float]:
    """How many of the findings `a` have one of their kind in `b` within `SAME` (joints'
    positions are on the axis), of how many; the largest size difference (m) among them."""
    matched, worst = 0, 0.0
    for kind, position, size in a:
        near = [s for k, p, s in b if k == kind and np.linalg.norm(p - position) < SAME]
        if near:
            matched += 1
            worst = max(worst, min(abs(s - size) for s in near))
    return matched, len(a), worst


def _plan(pipe, base, threshold: float, rng: np.random.Generator, clouds: int):
    """Per cloud, the defects and joints to inject: slots along the pipe away from its
    ends and from the joints found, a joint in one slot, two defects (or a deformation)
    in each other."""
    from zeroset.synthetic import Defect, Joint

    slot = 0.3
    edges = np.arange(0.1, pipe.length - 0.1 - slot, slot)
    taken = [j.axial for j in base.joints]
    free = [e for e in edges if all(abs(e + 0.5 * slot - t) > 0.5 * slot + 0.1 for t in taken)]
    depths = [threshold * m for m in MULTIPLES] + list(DEEP)
    plans = []
    for cloud in range(clouds):
        order = rng.permutation(len(free))
        defects, joints = [], []
        joint_slot = free[order[0]]
        at = joint_slot + 0.5 * slot
        if cloud % 2 == 0:
            joints.append(Joint("offset", at, float(rng.choice([0.003, 0.008, 0.015])),
                                clock=float(rng.uniform(0, 360))))  # fmt: skip
        else:
            joints.append(Joint("gap", at, float(rng.choice([0.005, 0.01, 0.02])), depth=0.01))
        for k in order[1:]:
            middle = free[k] + 0.5 * slot
            if rng.random() < 0.2:  # a deformation: 3 % of the diameter over 0.3-0.4 m
                width = float(rng.uniform(0.3, 0.4))
                depth = 0.03 * 2 * pipe.radius
                defects.append(Defect("dent", middle, float(rng.uniform(0, 360)), depth, width))
                continue
            clock = float(rng.uniform(0, 360))
            for turn in (0.0, 180.0):
                kind = "dent" if rng.random() < 0.6 else "bulge"
                depth = float(rng.choice(depths))
                width = float(rng.uniform(0.05, 0.15))
                shift = float(rng.uniform(-0.05, 0.05))
                defects.append(Defect(kind, middle + shift, (clock + turn) % 360.0, depth, width))
        plans.append((defects, joints))
    return plans


def _footprint(pipe, located, defect) -> int:
    """How many points lie within half the defect's width of its centre on the wall."""
    a = located[0] - defect.axial
    b = np.radians((located[1] - defect.clock + 180.0) % 360.0 - 180.0) * pipe.radius
    return int(np.count_nonzero(np.hypot(a, b) < 0.5 * defect.width))


def _recovered(inspection, truth, defects, joints, located, pipe) -> tuple[list, list]:
    """Rows per injected defect and joint: found or not, and the errors."""
    rows = []
    for defect, record in zip(defects, truth["defects"], strict=True):
        axial, clock, _ = inspection.pipe.locate(np.array([record["centre"]]))
        reach = max(AXIAL_MATCH, 0.1 * defect.width)
        near = [
            d for d in inspection.defects.defects
            if d.kind == defect.kind and abs(d.axial - axial[0]) <= reach
            and abs((d.clock - clock[0] + 180) % 360 - 180) <= CLOCK_MATCH
        ]  # fmt: skip
        found = min(near, key=lambda d: abs(d.axial - axial[0]), default=None)
        rows.append({
            "defect": defect,
            "points": _footprint(pipe, located, defect),
            "found": found,
            "depth": None if found is None else abs(found.depth) - defect.depth,
            "axial": None if found is None else found.axial - axial[0],
        })  # fmt: skip
    joint_rows = []
    for joint, record in zip(joints, truth["joints"], strict=True):
        axial = float(inspection.pipe.locate(np.array([record["centre"]]))[0][0])
        near = [j for j in inspection.joints if abs(j.axial - axial) <= JOINT_MATCH]
        found = min(near, key=lambda j: abs(j.axial - axial), default=None)
        joint_rows.append({"joint": joint, "found": found,
                           "axial": None if found is None else found.axial - axial})  # fmt: skip
    return rows, joint_rows


def _extra(inspection, base, truth, motion=None) -> int:
    """Defects found that are neither injected nor found on the scan as it is."""
    known = [p for k, p, _ in _findings(base) if k in ("dent", "bulge")]
    known += [np.array(r["centre"]) for r in truth["defects"]]
    count = 0
    for kind, position, _ in _findings(inspection, motion):
        if kind in ("dent", "bulge") and all(np.linalg.norm(position - p) > 0.1 for p in known):
            count += 1
    return count


def _scan_section(name: str, path: Path, clouds: int, seed: int) -> list[str]:
    from zeroset import io
    from zeroset.synthetic import inject

    points = io.read_points(path).points
    mesh, base, rec, ins = _inspect(points)
    pipe = base.pipe
    unjudged = sum(u.axial_end - u.axial_start for u in pipe.unreliable)
    noise = float(np.median(base.wall.noise[np.isfinite(base.wall.noise)]))
    threshold = base.defects.threshold
    lines = [
        f"**{name}** (`{path.relative_to(DATA)}`, {points.shape[0]:,} points, no sensor "
        f"positions): reconstruct {rec:.1f} s, inspect {ins:.1f} s; fitted {pipe.length:.2f} m "
        f"of diameter {2000 * pipe.radius:.1f} mm; not judged {unjudged:.2f} m "
        f"({100 * unjudged / pipe.length:.0f} %); noise {1000 * noise:.2f} mm; threshold "
        f"{1000 * threshold:.2f} mm.",
        "",
        "As it is: joints " + (", ".join(
            f"{j.kind} at {j.axial:.3f} m ({1000 * j.size:.1f} mm)" for j in base.joints
        ) or "none") + f"; {len(base.defects.defects)} defects, the deepest "
        + ", ".join(f"{d.kind} {1000 * d.depth:+.1f} mm at {d.axial:.2f} m, {d.clock:.0f} deg"
                    for d in base.defects.defects[:4]) + ".",
        "",
        "| the scan | joints the same | defects the same | largest size difference, mm "
        "| inspect, s |",
        "|---|---|---|---|---|",
    ]  # fmt: skip
    rng = np.random.default_rng(seed)
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    rotation *= np.sign(np.linalg.det(rotation))
    motion = (rotation, rng.uniform(-10, 10, 3))
    half = np.sort(rng.choice(points.shape[0], points.shape[0] // 2, replace=False))
    variants = {
        "moved (a random rotation, up to 10 m)": (points @ rotation.T + motion[1], motion),
        "in reverse order": (points[::-1], None),
        "half of its points": (points[half], None),
    }
    base_found = _findings(base)
    for label, (cloud, moved) in variants.items():
        _, other, _, seconds = _inspect(cloud)
        found = _findings(other, moved)
        joints = _same([f for f in base_found if f[0] in ("gap", "offset", "bead")], found)
        defects = _same([f for f in base_found if f[0] in ("dent", "bulge")], found)
        lines.append(f"| {label} | {joints[0]}/{joints[1]} | {defects[0]}/{defects[1]} | "
                     f"{1000 * max(joints[2], defects[2]):.1f} | {seconds:.1f} |")  # fmt: skip
    rows, joint_rows, extra = [], [], 0
    for defects, joints in _plan(pipe, base, threshold, rng, clouds):
        moved, truth = inject(points, pipe, defects=defects, joints=joints)
        _, found, _, _ = _inspect(moved)
        located = pipe.locate(points)
        more, more_joints = _recovered(found, truth, defects, joints, located, pipe)
        rows += more
        joint_rows += more_joints
        extra += _extra(found, base, truth)
    lines += [
        "",
        f"Injected into {clouds} copies (seed {seed}): found against depth, in units of the "
        f"noise ({1000 * noise:.2f} mm) and of the threshold:",
        "",
        "| depth | in noise widths | defects with 30 points or more: found | depth error, mm: "
        "median / max abs | axial error max, mm | fewer points: found |",
        "|---|---|---|---|---|---|",
    ]
    for depth in sorted({r["defect"].depth for r in rows}):
        at = [r for r in rows if r["defect"].depth == depth]
        full = [r for r in at if r["points"] >= MIN_POINTS]
        hit = [r for r in full if r["found"] is not None]
        few = [r for r in at if r["points"] < MIN_POINTS]
        errors = [1000 * abs(r["depth"]) for r in hit]
        label = ("deformation " if any(r["defect"].width >= 0.3 for r in at) else "") + (
            f"{1000 * depth:.1f} mm ({depth / threshold:.1f} x threshold)")  # fmt: skip
        lines.append(
            f"| {label} | {depth / noise:.0f} | {len(hit)}/{len(full)} | "
            + (f"{np.median(errors):.1f} / {max(errors):.1f}" if errors else "-")
            + " | " + (f"{max(1000 * abs(r['axial']) for r in hit):.0f}" if hit else "-")
            + f" | {sum(r['found'] is not None for r in few)}/{len(few)} |"
        )  # fmt: skip
    missed = [r for r in rows if r["found"] is None and r["points"] >= MIN_POINTS]
    lines += ["", "Missed with 30 points or more: " + ("; ".join(
        f"{r['defect'].kind} {1000 * r['defect'].depth:.1f} mm, {100 * r['defect'].width:.0f} cm "
        f"wide at {r['defect'].axial:.2f} m, {r['defect'].clock:.0f} deg ({r['points']} points)"
        for r in missed) or "none") + "."]  # fmt: skip
    lines += ["", "| joint | found within 2 cm | axial error, mm | read, mm |", "|---|---|---|---|"]
    for row in joint_rows:
        joint, found = row["joint"], row["found"]
        lines.append(
            f"| {joint.kind} {1000 * joint.size:.0f} mm at {joint.axial:.2f} m | "
            + ("no" if found is None else f"yes ({found.kind})") + " | "
            + ("-" if found is None else f"{1000 * row['axial']:+.0f}") + " | "
            + ("-" if found is None else f"{1000 * found.size:.1f}") + " |"
        )  # fmt: skip
    lines += ["", f"Defects found that are neither injected nor on the scan as it is: {extra}."]
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clouds", type=int, default=6, help="injected copies of each scan")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    lines = []
    for name, relative in SCANS.items():
        lines += _scan_section(name, DATA / relative, args.clouds, args.seed) + [""]
    today = datetime.date.today().isoformat()
    text = "\n".join([
        "## Inspection of real scans",
        "",
        f"Run {today} on {platform.machine()} with {os.cpu_count()} cores: `python "
        f"benchmarks/bench_real.py --clouds {args.clouds} --seed {args.seed}` "
        f"({(time.perf_counter() - started) / 60:.0f} min). "
        + " ".join(__doc__.split("\n\n")[3].split()),
        "",
        *lines,
    ])  # fmt: skip
    replace_section(args.output, "real", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
