"""Accuracy of the two surfaces of phase 1 against the truth; writes its section of
docs/benchmarks.md and the figure docs/images/accuracy.png (shown in docs/method.md).

Run by hand from the repository root (about five minutes on 2 cores)::

    python benchmarks/bench_accuracy.py

Two measurements, defaults otherwise, fixed seeds:

- error against density: the open pipe of the peers benchmark (radius 0.25 m, length 1 m,
  noise 2 mm per axis) from 5,000 to 1,000,000 points, with Hoppe's nearest tangent plane
  (``surface="planes"``) and the blended jets (the default);
- bias against radius: spheres of radius 0.1 to 1 m, 20,000 points, noise 1 mm.

Speed is measured by `bench_phase1.py`, not here. Errors are signed distances to the
analytic surface, positive outside, over 200,000 points
drawn uniformly by area from the mesh (for the pipe, the middle 80 % of its length, away
from the open ends): the signed mean is the bias, the mean of the absolute values the error.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _docfile import replace_section
from bench_phase1 import machine_info, machine_lines

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUTPUT = ROOT / "docs" / "benchmarks.md"
DEFAULT_FIGURE = ROOT / "docs" / "images" / "accuracy.png"
PIPE_SIZES = (5_000, 20_000, 80_000, 200_000, 1_000_000)
SPHERE_RADII = (0.1, 0.2, 0.37, 0.6, 1.0)
SURFACES = ("planes", "jets")
SAMPLES = 200_000


def signed_errors(mesh, signed, keep=None) -> tuple[float, float]:
    """Signed mean and mean absolute of `signed` over area samples of `mesh`, in metres."""
    from zeroset.evaluate import sample_surface

    x, _ = sample_surface(mesh, SAMPLES, rng=0)
    if keep is not None:
        x = x[keep(x)]
    d = signed(x)
    return float(d.mean()), float(np.abs(d).mean())


def pipe_rows(sizes) -> list[dict]:
    import zeroset
    from zeroset.synthetic import sample_cylinder

    rows = []
    for n in sizes:
        points = sample_cylinder(n, radius=0.25, length=1.0, noise=0.002, rng=0).points
        for surface in SURFACES:
            result = zeroset.reconstruct(points, surface=surface, tolerance=0)
            bias, error = signed_errors(
                result.mesh,
                lambda x: np.hypot(x[:, 0], x[:, 1]) - 0.25,
                keep=lambda x: np.abs(x[:, 2] - 0.5) < 0.4,
            )
            rows.append(
                {
                    "n": n,
                    "surface": surface,
                    "bias": bias,
                    "error": error,
                    "faces": result.mesh.n_faces,
                    "support": result.stats.get("fit_support"),
                    "rho_delta": result.parameters.rho_delta,
                }
            )
            print(rows[-1], flush=True)
    return rows


def sphere_rows(radii) -> list[dict]:
    import zeroset
    from zeroset.synthetic import sample_sphere

    rows = []
    for radius in radii:
        points = sample_sphere(20_000, radius=radius, noise=0.001, rng=0).points
        for surface in SURFACES:
            result = zeroset.reconstruct(points, surface=surface, tolerance=0)
            bias, error = signed_errors(
                result.mesh, lambda x, r=radius: np.linalg.norm(x, axis=1) - r
            )
            rows.append({"radius": radius, "surface": surface, "bias": bias, "error": error})
            print(rows[-1], flush=True)
    return rows


def draw(pipes, spheres, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for surface, colour in zip(SURFACES, ("#d62728", "#1f77b4"), strict=True):
        rows = [r for r in pipes if r["surface"] == surface]
        n = [r["n"] for r in rows]
        left.loglog(n, [r["error"] * 1e3 for r in rows], "o-", color=colour,
                    label=f"{surface}: mean |error|")
        left.loglog(n, [max(abs(r["bias"]), 1e-6) * 1e3 for r in rows], "s--", color=colour,
                    label=f"{surface}: |bias|")
        rows = [r for r in spheres if r["surface"] == surface]
        right.plot([r["radius"] for r in rows], [r["bias"] * 1e3 for r in rows], "o-",
                   color=colour, label=surface)
    left.set_xlabel("points")
    left.set_ylabel("mm")
    left.set_title("Open pipe r = 0.25 m, noise 2 mm")
    left.legend(fontsize=8)
    left.grid(True, which="both", alpha=0.3)
    right.axhline(0.0, color="#9a9a9a", lw=0.8)
    right.set_xlabel("sphere radius (m)")
    right.set_ylabel("signed mean distance (mm)")
    right.set_title("Spheres, 20,000 points, noise 1 mm")
    right.legend(fontsize=8)
    right.grid(True, alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def _pairs(rows, key):
    """(value of `key`, planes row, jets row) for every value of `key`, ascending."""
    for value in sorted({r[key] for r in rows}):
        pair = {r["surface"]: r for r in rows if r[key] == value}
        yield value, pair["planes"], pair["jets"]


def _errors(planes, jets) -> str:
    """Bias and error of both surfaces as four table cells, in mm."""
    return " | ".join(
        f"{r['bias'] * 1e3:+.3f} | {r['error'] * 1e3:.3f}" for r in (planes, jets)
    )


def section(pipes, spheres, machine) -> str:
    lines = [
        "## Accuracy of the surface: planes and jets",
        "",
        "`python benchmarks/bench_accuracy.py`. Signed distances to the analytic surface over",
        f"{SAMPLES:,} area samples of the mesh, positive outside; for the pipe only its middle",
        "80 %. Bias is the signed mean, error the mean absolute value, both in mm. *planes* is",
        "Hoppe's nearest tangent plane (`--surface planes`), *jets* the default.",
        "",
        "![error against density and bias against radius](images/accuracy.png)",
        "",
        "### Open pipe (radius 0.25 m, noise 2 mm): error against density",
        "",
        "| points | planes bias | planes error | jets bias | jets error | jets faces "
        "| jets support / rho+delta |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n, p, j in _pairs(pipes, "n"):
        lines.append(
            f"| {n:,} | {_errors(p, j)} | {j['faces']:,} | {j['support'] / j['rho_delta']:.2f} |"
        )
    lines += [
        "",
        "### Spheres (20,000 points, noise 1 mm): bias against radius",
        "",
        "| radius m | planes bias | planes error | jets bias | jets error |",
        "|---:|---:|---:|---:|---:|",
    ]
    lines += [f"| {radius:g} | {_errors(p, j)} |" for radius, p, j in _pairs(spheres, "radius")]
    lines += ["", *machine_lines(machine), ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=PIPE_SIZES)
    parser.add_argument("--radii", type=float, nargs="+", default=SPHERE_RADII)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--figure", type=Path, default=DEFAULT_FIGURE)
    args = parser.parse_args(argv)
    pipes, spheres = pipe_rows(args.sizes), sphere_rows(args.radii)
    draw(pipes, spheres, args.figure)
    replace_section(args.output, "accuracy", section(pipes, spheres, machine_info()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
