"""Each rule of phase 1 (docs/rules.md) switched off in turn, on every benchmark cloud.

Run by hand from the repository root::

    python benchmarks/bench_ablation.py [--clouds pipe bunny ...] [--rules R6 R30 ...]

Each run's row is appended to ``--rows`` (JSON lines) as it is measured; a second start reads
them back and runs only what is missing, so an interrupted run goes on where it stopped.

A rule is switched off by a configuration field where one exists, else by setting the
constant or replacing the function that carries it, for the run only. Every run is
measured by its Chamfer-L1 distance: the mean of the two mean distances, mesh to reference
and reference to mesh (50,000 area-uniform samples of each surface), where the reference is
the true surface of a synthetic cloud and the points of a real scan; by its components,
boundary loops and seconds; and on a synthetic cloud by the share of its area that faces as
the true surface does. The clouds of ``HELD_OUT`` were never used to choose a threshold and
are reported apart; keep them out of every future choice. The section between
``<!-- ablation:begin -->`` and ``<!-- ablation:end -->`` of docs/benchmarks.md is replaced.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import tempfile
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from unittest import mock

import numpy as np
from _docfile import replace_section
from bench_peers import DATASETS, DEFAULT_DATA, Cloud, load
from bench_phase1 import DEFAULT_OUTPUT, machine_info, reproduce_lines

import zeroset
import zeroset.orientation
from zeroset import topology
from zeroset.errors import SurfaceWarning, ZerosetError
from zeroset.evaluate import closest_points_on_mesh, points_to_mesh_distance, sample_surface
from zeroset.io import read_points

#: Points of the synthetic clouds.
SIZE = 20_000
#: Samples of each surface for the Chamfer distance.
SAMPLES = 50_000
#: Clouds the rules were tuned or measured on (bench_peers' datasets).
TUNED = ("pipe", "scan", "sphere", "torus", "bunny", "gargoyle", "sick")
#: Real scans no threshold was ever chosen on: a range scan of the Stanford dragon on its
#: stand, and ground points of an airborne lidar survey (ISPRS). Never tune on them.
HELD_OUT = {
    "dragon": "stanford_dragon_stand/scans/dragonStandRight_0.ply",
    "terrain": "isprs_terrain_pcl/samp11-utm-ground.pcd",
}
#: A change of the Chamfer distance below this share, with the same components and loops
#: and no more of the area facing the other way, is no change.
UNCHANGED = 0.005


def _uniform_radii(spacing, *, rho_delta, margin):
    return np.full(np.shape(spacing), rho_delta)


def _no_range_noise(points, neighbours, viewpoints, *, noise):
    return noise, None


def _uncapped_orientation(*args, max_edge=None, **kwargs):
    return zeroset.orientation.orient_normals(*args, **kwargs)


def _unrefined(mesh, surface, parameters, config):
    return mesh, {}


def _isotropic_spacing(points, indices, distances):
    return np.zeros(len(indices))


def _no_joins(centroids, normals, component, reach):
    from scipy import sparse

    return sparse.csr_matrix((len(centroids), len(centroids)))


def _root_up(alignment):
    # Hoppe's root: the point of largest z, its normal turned to +z (direction 4 of six).
    return np.full(len(alignment), 4), np.where(alignment[:, 4] >= 0.0, 1.0, -1.0)


@dataclass(frozen=True)
class Ablation:
    """Rule `rule` off: `config` overrides and `patches` (target -> value) for the run, and
    the cloud's sensor positions withheld unless `sensors`."""

    rule: str
    off: str
    config: dict = field(default_factory=dict)
    patches: dict = field(default_factory=dict)
    sensors: bool = True


ABLATIONS = (
    Ablation(
        "R3",
        "spacing from the 12th neighbour alone",
        patches={"zeroset.parameters.sector_radius": _isotropic_spacing},
    ),
    Ablation("R4", "no noise margin: rho+delta = spacing", {"noise_factor": 0.0}),
    Ablation("R6", "no averaging in cells", {"averaging_cell": 0.0}),
    Ablation(
        "R8", "rho+delta for every point", patches={"zeroset.stages.point_radii": _uniform_radii}
    ),
    Ablation("R9", "no range-noise model", patches={"zeroset.stages.range_noise": _no_range_noise}),
    Ablation("R10", "only isolated points dropped", {"min_neighbours": 1}),
    Ablation("R11", "planes on the radius alone (3 points at least)", {"k_min": 3}),
    Ablation(
        "R12",
        "orientation edges uncapped",
        patches={"zeroset.stages.orient_normals": _uncapped_orientation},
    ),
    Ablation("R13", "no joins of components", patches={"zeroset.orientation._bridges": _no_joins}),
    Ablation(
        "R14", "root at the largest z (Hoppe)", patches={"zeroset.orientation.root_rule": _root_up}
    ),
    Ablation("R15", "no sheets turned apart", patches={"zeroset.orientation.STACK_REACH": 0.0}),
    Ablation("R7+R9+R16-R18", "sensor positions withheld", sensors=False),
    Ablation("R19", "nearest plane, no jets", {"surface": "planes"}),
    Ablation("R21", "one support for all jets (the default's median)", {"fit_support": "median"}),
    Ablation("R22", "no detail measured", patches={"zeroset.jets.DETAIL_MARGIN": np.inf}),
    Ablation("R24", "no refits on half the support", patches={"zeroset.jets.MISFIT_HALVINGS": 0}),
    Ablation("R25", "jets fitted across sheets", patches={"zeroset.jets.SHEET": np.inf}),
    Ablation(
        "R26", "jets oriented by the nearest plane alone", patches={"zeroset.jets.ORIENT_K": 1}
    ),
    Ablation("R28", "one candidate plane", patches={"zeroset.distance.CANDIDATES": 1}),
    Ablation("R29", "no zero nudge", patches={"zeroset.distance.ZERO_NUDGE": 1e-12}),
    Ablation("R30", "no gap bridges", {"gap_bridges": False}),
    Ablation("R31", "bridges leave on any side", patches={"zeroset.density.CROSSING": -1.0}),
    Ablation("R32", "bridges off their surface too", patches={"zeroset.density.ALONG": 180.0}),
    Ablation("R34", "jumps contoured", patches={"zeroset.contour.MAX_JUMP": np.inf}),
    Ablation("R38+R43", "no holes closed", {"max_hole_edges": 0}),
    Ablation("R39", "no small components dropped", {"min_component_faces": 0}),
    Ablation("R27+R40-R43", "rims at whole cubes", {"rim": "cubes"}),
    Ablation("R45", "no edge splits", {"refine_levels": 0}),
    Ablation("R44+R45", "no refinement", patches={"zeroset.stages.refine": _unrefined}),
)


@dataclass
class Row:
    """What one run gave."""

    chamfer: float | None = None
    components: int | None = None
    loops: int | None = None
    seconds: float | None = None
    failure: str = ""
    fit_support: float | None = None
    facing: float | None = None


def clouds(names, data: Path):
    """(name, Cloud) for each of `names`."""
    by_name = {d.name: d for d in DATASETS}
    for name in names:
        if name in HELD_OUT:
            yield name, Cloud(read_points(data / HELD_OUT[name]).points, None, None)
        else:
            yield name, load(by_name[name], SIZE, data)


def run(cloud: Cloud, reference, ablation: Ablation | None, baseline: Row | None) -> Row:
    """Reconstruct `cloud` with `ablation` (None: as by default) and measure it."""
    # Phase 1's dense mesh: the rules of phase 1 are measured without the simplification.
    overrides = {"tolerance": 0.0, **(ablation.config if ablation else {})}
    if overrides.get("fit_support") == "median":
        overrides["fit_support"] = baseline.fit_support
    with contextlib.ExitStack() as stack:
        for target, value in (ablation.patches if ablation else {}).items():
            stack.enter_context(mock.patch(target, value))
        warnings.simplefilter("ignore", SurfaceWarning)
        start = time.perf_counter()
        try:
            sensors = cloud.viewpoints if ablation is None or ablation.sensors else None
            result = zeroset.reconstruct(cloud.points, viewpoints=sensors, **overrides)
        except ZerosetError as error:
            return Row(failure=str(error).split(";")[0])
        except Exception as error:  # a rule the rest of the method cannot do without
            return Row(failure=f"{type(error).__name__}: {error}")
        seconds = time.perf_counter() - start
    mesh = result.mesh
    on_mesh, normals = sample_surface(mesh, SAMPLES, rng=0)
    chamfer = 0.5 * (
        points_to_mesh_distance(reference, mesh).mean() + _to_reference(cloud, on_mesh).mean()
    )
    row = Row(
        chamfer=float(chamfer),
        components=topology.face_components(mesh.faces, mesh.n_vertices)[0],
        loops=len(topology.boundary_loops(mesh.faces)),
        seconds=seconds,
        fit_support=result.stats.get("fit_support"),
        facing=_facing(cloud, on_mesh, normals),
    )
    return row


def _facing(cloud: Cloud, positions: np.ndarray, normals: np.ndarray) -> float | None:
    """Share of the mesh's area (its samples `positions` with their `normals`) that faces
    the way the true surface does at its closest point; None for a real scan."""
    if cloud.truth is None:
        return None
    _, face, _ = closest_points_on_mesh(positions, cloud.truth)
    truth = topology.face_area_vectors(cloud.truth.vertices, cloud.truth.faces)[face]
    return float(np.mean(np.einsum("ij,ij->i", normals, truth) > 0.0))


def _reference(cloud: Cloud) -> np.ndarray:
    """Points of the reference: samples of the true surface, or the scan's points."""
    if cloud.truth is None:
        return cloud.points
    return sample_surface(cloud.truth, SAMPLES, rng=1)[0]


def _to_reference(cloud: Cloud, positions: np.ndarray) -> np.ndarray:
    """Distance of each position to the true surface, or to the nearest scan point."""
    if cloud.truth is not None:
        return points_to_mesh_distance(positions, cloud.truth)
    from scipy.spatial import cKDTree

    return cKDTree(cloud.points).query(positions, workers=-1)[0]


def measure(names, rules, data: Path, saved: Path) -> dict:
    """{cloud: {rule or "default": Row}}, with the rows `saved` (JSON lines) holds already;
    each new row is appended to it."""
    chosen = [a for a in ABLATIONS if a.rule in rules] if rules else list(ABLATIONS)
    results: dict = {}
    if saved.exists():
        for line in saved.read_text().splitlines():
            row = json.loads(line)
            cloud, rule = row.pop("cloud"), row.pop("rule")
            results.setdefault(cloud, {})[rule] = Row(**row)
    for name, cloud in clouds(names, data):
        done = results.setdefault(name, {})
        missing = [a for a in [None, *chosen] if (a.rule if a else "default") not in done]
        if not missing:
            continue
        reference = _reference(cloud)
        for ablation in missing:
            rule = ablation.rule if ablation else "default"
            done[rule] = run(cloud, reference, ablation, done.get("default"))
            with saved.open("a") as file:
                file.write(json.dumps({"cloud": name, "rule": rule, **asdict(done[rule])}) + "\n")
            print(f"{name}: {rule} {done[rule]}", flush=True)
    return {name: results[name] for name in names if name in results}


def _cell(row: Row, base: Row) -> str:
    """Change against the default: Chamfer in percent, then components and loops, then
    the points of area that face the other way."""
    if row.failure:
        return "fails"
    change = 100.0 * (row.chamfer / base.chamfer - 1.0)
    parts = [f"{change:+.1f} %"]
    if row.components != base.components:
        parts.append(f"c {row.components - base.components:+d}")
    if row.loops != base.loops:
        parts.append(f"l {row.loops - base.loops:+d}")
    if _turned(row, base) >= UNCHANGED:
        parts.append(f"o {100.0 * _turned(row, base):.0f} %")
    return ", ".join(parts)


def _turned(row: Row, base: Row) -> float:
    """Change, against the default, of the share of the area that faces as the true surface
    does (0 where it is not measured)."""
    if row.facing is None or base.facing is None:
        return 0.0
    return abs(row.facing - base.facing)


def _unchanged(row: Row, base: Row) -> bool:
    return (
        not row.failure
        and abs(row.chamfer / base.chamfer - 1.0) < UNCHANGED
        and (row.components, row.loops) == (base.components, base.loops)
        and _turned(row, base) < UNCHANGED
    )


def table(results: dict, names: list[str]) -> list[str]:
    """One row per rule, one column per cloud, and the median time against the default."""
    names = [n for n in names if n in results]
    lines = [
        "| rule off | " + " | ".join(names) + " | time |",
        "|---|" + "---:|" * (len(names) + 1),
        "| default: Chamfer-L1, components, loops, seconds | "
        + " | ".join(
            f"{results[n]['default'].chamfer:.3g}, {results[n]['default'].components}, "
            f"{results[n]['default'].loops}, {results[n]['default'].seconds:.1f} s"
            for n in names
        )
        + " | |",
    ]
    for ablation in ABLATIONS:
        rows = [results[n].get(ablation.rule) for n in names]
        if all(r is None for r in rows):
            continue
        ratios = [
            r.seconds / results[n]["default"].seconds
            for n, r in zip(names, rows, strict=True)
            if r is not None and not r.failure
        ]
        cells = [
            "" if r is None else _cell(r, results[n]["default"])
            for n, r in zip(names, rows, strict=True)
        ]
        time_ = f"{np.median(ratios):.2f}x" if ratios else ""
        lines.append(f"| {ablation.rule} {ablation.off} | " + " | ".join(cells) + f" | {time_} |")
    return lines


def report(results: dict, machine: dict) -> str:
    tuned = [n for n in TUNED if n in results]
    held = [n for n in HELD_OUT if n in results]
    quiet = [
        a.rule
        for a in ABLATIONS
        if all(
            a.rule in results[n] and _unchanged(results[n][a.rule], results[n]["default"])
            for n in results
        )
    ]
    lines = [
        "## Ablation: each rule of phase 1 switched off",
        "",
        "Each rule of [the ledger](rules.md) switched off in turn (`benchmarks/bench_ablation.py`"
        " says how), against the default run. A cell gives the change of the Chamfer-L1 "
        "distance (mean of mesh-to-reference and reference-to-mesh, the reference being the "
        "true surface of a synthetic cloud and the points of a real scan), then the change of "
        "components (c) and boundary loops (l) where they change, and on synthetic clouds the "
        "share of the mesh's area that faces the other way than in the default run (o; the "
        'Chamfer distance does not see which way a mesh faces); "fails" where the run '
        "raised. Synthetic clouds have 20,000 points.",
        "",
        "### Clouds the rules were tuned on",
        "",
        *table(results, tuned),
        "",
        "### Held-out clouds (never used to choose a threshold)",
        "",
        "The Stanford dragon on its stand (`dragonStandRight_0.ply`, a range scan) and the "
        "ground points of an airborne lidar survey (ISPRS `samp11-utm-ground.pcd`).",
        "",
        *table(results, held),
        "",
        "Rules that change nothing measurable on any cloud (Chamfer within "
        f"{UNCHANGED:.1%}, same components, loops and facing): "
        + (", ".join(quiet) if quiet else "none")
        + ".",
        "",
    ]
    lines += reproduce_lines("python benchmarks/bench_ablation.py", machine, "about 30 minutes")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--clouds", nargs="+", default=[*TUNED, *HELD_OUT])
    parser.add_argument("--rules", nargs="+", default=None)
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument(
        "--rows", type=Path, default=Path(tempfile.gettempdir()) / "zeroset-ablation-rows.jsonl"
    )
    args = parser.parse_args()
    results = measure(args.clouds, args.rules, args.data, args.rows)
    replace_section(args.output, "ablation", report(results, machine_info()))


if __name__ == "__main__":
    main()
