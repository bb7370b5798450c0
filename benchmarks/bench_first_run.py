"""The first run after installing: `zeroset demo` with no compiled kernels, beside a warm run.

Run by hand from the repository root::

    python benchmarks/bench_first_run.py

Each round runs ``zeroset demo`` in a fresh process with an empty Numba cache (a fresh
install: every kernel it uses is compiled), then again with the cache that run filled (every
later run). Wall time of the whole command and the seconds of each stage it reports are the
medians over the rounds. The section between ``<!-- first-run:begin -->`` and
``<!-- first-run:end -->`` of docs/benchmarks.md is replaced.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _docfile import replace_section
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines

ROUNDS = 3
#: The stages line of the demo's report: "seconds     prepare 0.03, ...; total 2.09; ...".
SECONDS = re.compile(r"^seconds\s+(.*?); total ([0-9.]+)", re.MULTILINE)


def run_demo(cache: Path, out: Path) -> tuple[float, dict[str, float]]:
    """Wall seconds of one ``zeroset demo`` with Numba's cache in `cache`, and the seconds
    of each stage it reports (the stages' total under "total")."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    command = [sys.executable, "-m", "zeroset", "demo", "--out", str(out)]
    start = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    found = SECONDS.search(done.stdout)
    if found is None:
        raise RuntimeError(f"no stage timings in the demo's output:\n{done.stdout}")
    stages = {
        name: float(seconds)
        for name, seconds in (item.rsplit(" ", 1) for item in found.group(1).split(", "))
    }
    stages["total"] = float(found.group(2))
    return wall, stages


def measure(rounds: int) -> dict:
    """Median wall and stage seconds of cold and warm runs over `rounds` rounds."""
    runs: dict[str, list] = {"cold": [], "warm": []}
    for round_ in range(rounds):
        with tempfile.TemporaryDirectory() as folder:
            cache = Path(folder) / "numba"
            for kind in ("cold", "warm"):
                runs[kind].append(run_demo(cache, Path(folder) / kind))
                print(f"round {round_ + 1} {kind}: {runs[kind][-1][0]:.1f} s", flush=True)
    result = {}
    for kind, measured in runs.items():
        stages = {name: statistics.median(m[1][name] for m in measured) for name in measured[0][1]}
        result[kind] = {"wall": statistics.median(m[0] for m in measured), "stages": stages}
    return result


def report(result: dict, rounds: int, machine: dict) -> str:
    cold, warm = result["cold"], result["warm"]
    lines = [
        "## First run: compiling on a fresh install",
        "",
        f"`zeroset demo` (20,000 points) in a fresh process, medians of {rounds} rounds: cold "
        "with an empty Numba cache, as after `pip install`, then warm with the cache that run "
        "filled.",
        "",
        "| | cold | warm | cold − warm |",
        "|---|---:|---:|---:|",
        f"| wall, whole command (s) | {cold['wall']:.1f} | {warm['wall']:.1f} "
        f"| {cold['wall'] - warm['wall']:.1f} |",
    ]
    for name, seconds in cold["stages"].items():
        if max(seconds, warm["stages"][name]) >= 0.1 or name == "total":
            label = "stages' total" if name == "total" else f"stage {name}"
            lines.append(
                f"| {label} (s) | {seconds:.2f} | {warm['stages'][name]:.2f} "
                f"| {seconds - warm['stages'][name]:.2f} |"
            )
    lines += [
        "",
        "Every kernel is a plain Numba function over a range of rows, compiled for one "
        "signature (`zeroset._kernels._jit.inputs`); threads share its rows out "
        "(`zeroset._kernels._jit.over_rows`), since Numba's own parallel loops cost seconds of "
        "compiling each. The kernels of the later stages (the simplification's collapses and "
        "swaps first, then the orientation's, the jets' blend, the closest points on the mesh "
        "behind the report's distances) are compiled meanwhile by a second process on another "
        "core (`zeroset._kernels._ahead`); stage simplify waits for its kernels rather than "
        "compile them a second time, and the first run loads them from the cache. Most of a "
        "first run is that wait: the simplification's kernels take about half a minute to "
        "compile on one core. The rest is the first stages' kernels, mostly the jets' fit "
        "(stage parameters measures the noise with jets).",
        "",
    ]
    lines += reproduce_lines("python benchmarks/bench_first_run.py", machine, "about 4 minutes")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--rounds", type=int, default=ROUNDS)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args()
    result = measure(args.rounds)
    replace_section(args.output, "first-run", report(result, args.rounds, machine_info()))


if __name__ == "__main__":
    main()
