"""Phase-1 speed and memory benchmark; writes its section of docs/benchmarks.md.

Run by hand from the repository root::

    python benchmarks/bench_phase1.py --sizes 20000 200000 1000000 --repeat 3

Every size runs in a fresh child process (this script with the hidden ``--child N`` flag),
so that the peak resident set size is that of one size alone. The child generates a noisy
open pipe with `zeroset.synthetic.sample_cylinder`, runs one small warm-up reconstruction so
that Numba JIT compilation is excluded, then times `repeat` full reconstructions and prints
one JSON line. The parent takes medians and replaces the section between
``<!-- phase1:begin -->`` and ``<!-- phase1:end -->`` of the Markdown report atomically,
keeping the rest of the file (see ``_docfile.py``).
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _docfile import replace_section

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUTPUT = ROOT / "docs" / "benchmarks.md"
DEFAULT_SIZES = (20_000, 200_000, 1_000_000)
WARMUP_POINTS = 5_000
CYLINDER = {"radius": 0.25, "length": 1.0, "noise": 0.002, "rng": 0}

TARGET_POINTS = 1_000_000
TARGET_SECONDS = 10.0
TARGET_KNN_RATIO = 2.5  # phase 1 over one k-d tree build and 16-NN query
TARGET_MIB = 4 * 1024
TARGET_CORES = 2
TARGET_TEXT = "1M points through phase 1 in <= 10 s wall and <= 4 GiB peak memory on 2 cores"

OUTSIDE = "(outside stages)"


def _peak_rss_mib() -> float:
    """Peak resident set size of this process so far, in MiB."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024  # bytes vs kB


def _cloud(n: int):
    from zeroset.synthetic import sample_cylinder

    return sample_cylinder(n, **CYLINDER).points


def run_child(n: int, repeat: int) -> dict:
    """Time `repeat` reconstructions of an `n`-point pipe in this process."""
    import zeroset

    rss_import = _peak_rss_mib()
    zeroset.reconstruct(_cloud(WARMUP_POINTS), tolerance=0)  # compile every kernel first
    rss_warm = _peak_rss_mib()
    start = time.perf_counter()
    points = _cloud(n)
    generate_s = time.perf_counter() - start
    runs = []
    stats: dict = {}
    for _ in range(repeat):
        gc.collect()
        start = time.perf_counter()
        result = zeroset.reconstruct(points, tolerance=0)  # phase 1's dense mesh
        total = time.perf_counter() - start
        runs.append({"total": total, "stages": dict(result.timings), "knn": _knn_seconds(points)})
        stats = {  # the counts; notes and scales are reported elsewhere
            key: int(value)
            for key, value in result.stats.items()
            if isinstance(value, int) or getattr(value, "dtype", None) is not None
            and value.dtype.kind in "iu"
        }
        del result
    return {
        "n": n,
        "repeat": repeat,
        "generate_s": generate_s,
        "runs": runs,
        "stats": stats,
        "rss_after_import_mib": rss_import,
        "rss_after_warmup_mib": rss_warm,
        "peak_rss_mib": _peak_rss_mib(),
    }


def _knn_seconds(points) -> float:
    """Seconds to build one k-d tree over `points` and query their 16 nearest neighbours: the
    least any method that looks at every point's neighbourhood must spend."""
    from scipy.spatial import cKDTree

    start = time.perf_counter()
    cKDTree(points).query(points, k=16, workers=-1)
    return time.perf_counter() - start


def run_size(n: int, repeat: int) -> dict:
    """Run one size in a fresh interpreter and return its JSON report."""
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--child",
        str(n),
        "--repeat",
        str(repeat),
    ]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"child for n={n} failed ({done.returncode}):\n{done.stderr}")
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if not lines:
        raise RuntimeError(f"child for n={n} printed no JSON:\n{done.stdout}\n{done.stderr}")
    return json.loads(lines[-1])


def summarise(report: dict) -> dict:
    """Median seconds per stage (pipeline order), median total and the slowest stage."""
    runs = report["runs"]
    stages = list(runs[0]["stages"])
    medians = {name: statistics.median(run["stages"][name] for run in runs) for name in stages}
    medians[OUTSIDE] = statistics.median(run["total"] - sum(run["stages"].values()) for run in runs)
    slowest = max(stages, key=medians.__getitem__)
    return {
        "stages": medians,
        "total": statistics.median(run["total"] for run in runs),
        "total_min": min(run["total"] for run in runs),
        "total_max": max(run["total"] for run in runs),
        "knn": statistics.median(run.get("knn", float("nan")) for run in runs),
        "slowest": slowest,
    }


def reproduce_lines(command: str, machine: dict, duration: str = "") -> list[str]:
    """The command that reproduces a report, then the machine it ran on; `duration` says how
    long it takes, in words."""
    when = f" ({duration})" if duration else ""
    return [
        f"Reproduce from the repository root{when}:",
        "",
        "```",
        command,
        "```",
        "",
        *machine_lines(machine),
    ]


def machine_lines(machine: dict, extra: str = "") -> list[str]:
    """The "Machine" subsection of a report from `machine_info()`; `extra` ends the versions."""
    return [
        "### Machine",
        "",
        f"- Date: {machine['date']}",
        f"- CPU: {machine['cpu']}; `os.cpu_count()` = {machine['cpu_count']}, "
        f"usable = {machine['usable_cpus']}, Numba threads = {machine['numba_threads']}",
        f"- Platform: {machine['platform']}",
        f"- Python {machine['python']}, NumPy {machine['numpy']}, SciPy {machine['scipy']}, "
        f"Numba {machine['numba']}, zeroset {machine['zeroset']}{extra}",
    ]


def machine_info() -> dict:
    import numba
    import numpy
    import scipy

    import zeroset

    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "cpu": model,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "zeroset": getattr(zeroset, "__version__", "unknown"),
    }


def _verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def render(reports: list[dict], machine: dict, command: str, repeat: int) -> str:
    """The Markdown text of the phase-1 section."""
    summaries = [summarise(report) for report in reports]
    out = [
        "## Phase 1: speed and memory",
        "",
        "Phase-1 speed and memory of `zeroset.reconstruct()` on a noisy open pipe:",
        f"`zeroset.synthetic.sample_cylinder(n, radius={CYLINDER['radius']}, "
        f"length={CYLINDER['length']}, noise={CYLINDER['noise']}, rng={CYLINDER['rng']})`, "
        "default configuration but `tolerance=0`: phase 1's dense mesh, without the "
        "simplification (measured in its own section).",
        "",
        "- Every size runs in a fresh child process. Before timing, the child reconstructs a "
        f"{WARMUP_POINTS:,}-point pipe once so that Numba JIT compilation is excluded.",
        f"- Each size is reconstructed {repeat} time(s); the tables give the **median**. "
        "Stage times come from `Reconstruction.timings`; the total is `time.perf_counter()` "
        "around `reconstruct()`, and the row *(outside stages)* is the total minus the sum "
        "of the stages (input checks and the final mesh statistics).",
        "- Generating the synthetic cloud is **excluded** from every time.",
        "- Peak RSS is the child's `ru_maxrss` (whole process: interpreter, imports, JIT "
        "code, the input cloud and the reconstructions), in MiB.",
        "- *Phase-1 points* is `stats['phase1_points']`, the points the tangent planes are "
        "fitted to after phase-1 sampling and outlier removal.",
        "",
        *reproduce_lines(command, machine, "takes a few minutes"),
        "",
        "### Summary",
        "",
        "*k-d tree + 16-NN* is one `cKDTree` build and a 16-nearest-neighbour query of every "
        "point, timed in the same process after each run (median): the ratio says how many "
        "such passes phase 1 costs.",
        "",
        "| points | total median s | min-max s | k-d tree + 16-NN s | ratio | peak RSS MiB "
        "| slowest stage | phase-1 points | faces | boundary loops |",
        "|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|",
    ]
    for report, summary in zip(reports, summaries, strict=True):
        stats = report["stats"]
        out.append(
            f"| {report['n']:,} | {summary['total']:.3f} | "
            f"{summary['total_min']:.3f}-{summary['total_max']:.3f} | "
            f"{summary['knn']:.3f} | {summary['total'] / summary['knn']:.2f} | "
            f"{report['peak_rss_mib']:.0f} | {summary['slowest']} "
            f"({summary['stages'][summary['slowest']]:.3f} s) | "
            f"{stats.get('phase1_points', 0):,} | {stats.get('faces', 0):,} | "
            f"{stats.get('boundary_loops', 0)} |"
        )

    out += ["", "### Targets", "", f"Target: {TARGET_TEXT}.", ""]
    target = next(
        (pair for pair in zip(reports, summaries, strict=True) if pair[0]["n"] == TARGET_POINTS),
        None,
    )
    if target is None:
        out.append(f"Not measured: run with `--sizes {TARGET_POINTS}`.")
    else:
        report, summary = target
        out += [
            "| criterion | target | measured | verdict |",
            "|---|---:|---:|---|",
            f"| wall time, {TARGET_POINTS:,} points | <= {TARGET_SECONDS:.0f} s | "
            f"{summary['total']:.2f} s | {_verdict(summary['total'] <= TARGET_SECONDS)} |",
            f"| wall time over k-d tree + 16-NN, {TARGET_POINTS:,} points | "
            f"<= {TARGET_KNN_RATIO:g} | {summary['total'] / summary['knn']:.2f} | "
            f"{_verdict(summary['total'] / summary['knn'] <= TARGET_KNN_RATIO)} |",
            f"| peak memory, {TARGET_POINTS:,} points | <= {TARGET_MIB} MiB | "
            f"{report['peak_rss_mib']:.0f} MiB | "
            f"{_verdict(report['peak_rss_mib'] <= TARGET_MIB)} |",
        ]
        cores = machine["usable_cpus"]
        if cores != TARGET_CORES:
            out += [
                "",
                f"Measured on {cores} usable cores, not {TARGET_CORES}: the verdicts "
                "hold for this machine only.",
            ]
        else:
            out += ["", f"Measured on {cores} cores, as the target specifies."]

    out += ["", "### Stages", ""]
    for report, summary in zip(reports, summaries, strict=True):
        stats = report["stats"]
        out += [
            f"#### {report['n']:,} points",
            "",
            f"{stats.get('phase1_points', 0):,} phase-1 points, "
            f"{stats.get('outliers', 0)} outliers, {stats.get('grid_vertices', 0):,} grid "
            f"vertices, {stats.get('vertices', 0):,} mesh vertices, "
            f"{stats.get('faces', 0):,} faces, {stats.get('boundary_loops', 0)} boundary "
            f"loops, {stats.get('mesh_components', 0)} mesh component(s). "
            f"Cloud generation (excluded): {report['generate_s']:.2f} s. "
            f"RSS after imports {report['rss_after_import_mib']:.0f} MiB, after warm-up "
            f"{report['rss_after_warmup_mib']:.0f} MiB.",
            "",
            "| stage | median s |",
            "|---|---:|",
        ]
        for name, seconds in summary["stages"].items():
            label = f"**{name}**" if name == summary["slowest"] else name
            out.append(f"| {label} | {seconds:.3f} |")
        out += [f"| **total** | **{summary['total']:.3f}** |", ""]
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=list(DEFAULT_SIZES),
        help="point counts (default: %(default)s)",
    )
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per size")
    parser.add_argument(
        "--output",
        type=Path,
        default=DEFAULT_OUTPUT,
        help="Markdown report (default: docs/benchmarks.md)",
    )
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.repeat < 1 or any(n < 1 for n in args.sizes):
        parser.error("--repeat and --sizes must be positive")

    if args.child is not None:
        print(json.dumps(run_child(args.child, args.repeat)), flush=True)
        return 0

    reports = []
    for n in args.sizes:
        print(f"{n:>10,} points ...", end=" ", flush=True)
        report = run_size(n, args.repeat)
        summary = summarise(report)
        print(
            f"median {summary['total']:.3f} s, peak RSS {report['peak_rss_mib']:.0f} MiB, "
            f"slowest stage {summary['slowest']}",
            flush=True,
        )
        reports.append(report)
    command = (
        "python benchmarks/bench_phase1.py --sizes "
        + " ".join(str(n) for n in args.sizes)
        + f" --repeat {args.repeat}"
    )
    replace_section(args.output, "phase1", render(reports, machine_info(), command, args.repeat))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
