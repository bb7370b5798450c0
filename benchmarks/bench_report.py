"""Pictures and HTML reports of large meshes: time, size and load time; writes its section.

Run by hand from the repository root (needs chromium and chromium-driver, as the tests do)::

    python benchmarks/bench_report.py

For each size, a noisy open pipe is reconstructed with a cube size that gives about that many
triangles; then `zeroset.viz.preview` (with the points drawn) and
`zeroset.htmlreport.write_html_report` (distances from the 200,000 embedded points) are timed,
and the report is opened in headless Chromium with the network off and timed until its viewer
says it is ready (decoded, built and drawn once). The section between
``<!-- report:begin -->`` and ``<!-- report:end -->`` of docs/benchmarks.md is replaced.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _docfile import replace_section
from bench_phase1 import CYLINDER, DEFAULT_OUTPUT, machine_info, reproduce_lines

import zeroset
from zeroset.htmlreport import write_html_report
from zeroset.synthetic import sample_cylinder
from zeroset.viz import preview

# triangles wanted: (points, cube size), measured on this pipe
CASES = {100_000: (1_000_000, 0.0082), 1_000_000: (1_000_000, 0.0026)}
REPEAT = 3


def _browser():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_htmlreport import _browser as browser

    return browser()


def _load_seconds(browser, path: Path) -> float:
    """Seconds from navigation until the viewer is ready, network off."""
    from selenium.webdriver.support.ui import WebDriverWait

    browser.get("about:blank")
    begin = time.perf_counter()
    browser.get(path.as_uri())
    WebDriverWait(browser, 300, poll_frequency=0.05).until(
        lambda b: b.execute_script(
            "return (window.zerosetViewer && window.zerosetViewer.ready) "
            "|| document.body.dataset.error"
        )
    )
    seconds = time.perf_counter() - begin
    error = browser.execute_script("return document.body.dataset.error || null")
    if error:
        raise RuntimeError(f"the viewer failed on {path}: {error}")
    return seconds


def run(folder: Path) -> list[dict]:
    rows = []
    browser = _browser()
    browser.set_network_conditions(
        offline=True, latency=0, download_throughput=0, upload_throughput=0
    )
    try:
        for wanted, (n, cube) in CASES.items():
            sample = sample_cylinder(n, **CYLINDER)
            result = zeroset.reconstruct(sample.points, cube_size=cube, tolerance=0)
            picture, page = folder / f"{wanted}.png", folder / f"{wanted}.html"
            render_s, report_s, load_s = [], [], []
            for _ in range(REPEAT):
                begin = time.perf_counter()
                preview(result.mesh, picture, points=sample.points)
                render_s.append(time.perf_counter() - begin)
                begin = time.perf_counter()
                write_html_report(page, result, points=sample.points, source="pipe.ply")
                report_s.append(time.perf_counter() - begin)
                load_s.append(_load_seconds(browser, page))
            rows.append(
                {
                    "points": n,
                    "faces": result.mesh.n_faces,
                    "vertices": result.mesh.n_vertices,
                    "render": statistics.median(render_s),
                    "write": statistics.median(report_s),
                    "size": page.stat().st_size,
                    "load": statistics.median(load_s),
                }
            )
            row = rows[-1]
            print(
                f"{row['faces']:,} faces: picture {row['render']:.2f} s, report "
                f"{row['write']:.2f} s, {row['size'] / 2**20:.1f} MiB, "
                f"loads in {row['load']:.2f} s",
                flush=True,
            )
    finally:
        browser.quit()
    return rows


def render(rows: list[dict], machine: dict, command: str) -> str:
    out = [
        "## Pictures and HTML reports of large meshes",
        "",
        "Phase-1 meshes of a noisy open pipe "
        f"(`sample_cylinder(n, radius={CYLINDER['radius']}, length={CYLINDER['length']}, "
        f"noise={CYLINDER['noise']})`, cube size chosen for the triangle count). Picture: "
        "`zeroset.viz.preview(mesh, path, points=points)`, two 1200 × 600 views, every point "
        "given (at most 500,000 drawn). Report: `write_html_report(path, result, points=points)` "
        "(200,000 points embedded, the distances colouring the mesh measured from them). "
        "Load: headless Chromium (software WebGL, SwiftShader), network off, from navigation "
        "until the viewer has "
        f"decoded, built and drawn everything. Medians of {REPEAT}.",
        "",
        *reproduce_lines(command, machine),
        "",
        "| points | triangles | vertices | picture s | report written s | report MiB | "
        "report loads s |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        out.append(
            f"| {r['points']:,} | {r['faces']:,} | {r['vertices']:,} | {r['render']:.2f} "
            f"| {r['write']:.2f} | {r['size'] / 2**20:.1f} | {r['load']:.2f} |"
        )
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        rows = run(Path(folder))
    replace_section(
        args.output, "report", render(rows, machine_info(), "python benchmarks/bench_report.py")
    )
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
