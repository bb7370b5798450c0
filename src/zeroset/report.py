"""What a reconstruction chose, counted and spent: as a dict for JSON and as text for a terminal."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ._validate import as_points, require_rng
from .evaluate import compare_to_points
from .optimization import OptimizationResult
from .pipeline import Reconstruction
from .thresholds import UNTRUSTED

__all__ = [
    "format_report",
    "optimization_lines",
    "optimization_report",
    "reconstruction_report",
    "registration_report",
]


#: Points used to measure the fit of the mesh to the data in a report.
FIT_SAMPLES = 200_000


def reconstruction_report(
    result: Reconstruction,
    *,
    source: str | None = None,
    points=None,
    reading: dict | None = None,
    registration: dict | None = None,
    rng=0,
) -> dict:
    """Return a JSON-ready summary of `result`: parameters and why, counts, timings, fit.

    Parameters
    ----------
    result : Reconstruction or zeroset.tiles.TiledReconstruction
    source : str, optional
        Where the points came from, for the record.
    points : (N, 3) array_like of float, optional
        The input points; when given, the report measures their distance to the mesh (on a
        seeded sample of at most ``FIT_SAMPLES``).
    reading : dict, optional
        How the points were read: ``seconds``, and the counts of a reduction while reading
        (`zeroset.types.PointCloud.reduction`) when one ran.
    registration : dict, optional
        How the scans were registered, from :func:`registration_report`.
    rng : numpy.random.Generator or int or None
        Chooses that sample.

    Returns
    -------
    dict
        Keys ``source``, ``parameters`` (values and ``notes``), ``config``, ``stats``,
        ``timings`` (seconds per stage, ``read`` and ``register`` first when given),
        ``total_seconds``, with `reading` ``reading`` (its counts), with `registration`
        ``registration``, with phase 2 ``optimization``
        (see :func:`optimization_report`) and, with `points`, ``fit`` (see
        :func:`zeroset.evaluate.compare_to_points`).
    """
    params = result.parameters
    timings = dict(result.timings)
    if registration is not None:
        timings = {"register": registration["seconds"], **timings}
    if reading is not None:
        timings = {"read": reading["seconds"], **timings}
    report = {
        "source": source,
        "parameters": {
            "rho_delta": params.rho_delta,
            "cube_size": params.cube_size,
            "spacing": params.spacing,
            "noise": params.noise,
            "quadric_noise": params.quadric_noise,
            "averaging_cell": params.averaging_cell,
            "min_neighbours": params.min_neighbours,
            "notes": list(params.notes),
        },
        "config": asdict(result.config),
        "stats": dict(result.stats),
        "timings": {name: round(seconds, 4) for name, seconds in timings.items()},
        "total_seconds": round(sum(timings.values()), 4),
    }
    if reading is not None:
        report["reading"] = {name: v for name, v in reading.items() if name != "seconds"}
    if registration is not None:
        report["registration"] = {k: v for k, v in registration.items() if k != "seconds"}
    if getattr(result, "optimization", None) is not None:
        report["optimization"] = optimization_report(result.optimization)
    if points is not None:
        points = as_points(points)
        if points.shape[0] > FIT_SAMPLES:
            rows = require_rng(rng).choice(points.shape[0], FIT_SAMPLES, replace=False)
            points = points[np.sort(rows)]
        report["fit"] = compare_to_points(result.mesh, points)
    return report


def registration_report(registration, names, seconds: float) -> dict:
    """JSON-ready summary of a `zeroset.registration.Registration` of the scans `names`."""
    return {
        "seconds": seconds,
        "max_distance": registration.max_distance,
        "rounds": registration.rounds,
        "scans": [
            {
                "name": name,
                "residual_before": float(registration.residual_before[i]),
                "residual_after": float(registration.residual_after[i]),
                "overlap_before": float(registration.overlap_before[i]),
                "overlap_after": float(registration.overlap_after[i]),
            }
            for i, name in enumerate(names)
        ],
    }


def optimization_report(result: OptimizationResult) -> dict:
    """Return a JSON-ready summary of a phase-2 run: parameters, energies, moves, history."""
    return {
        "parameters": dict(result.parameters),
        "energy_before": result.energy_before.as_dict(),
        "energy": result.energy.as_dict(),
        "moves": result.moves,
        "stats": dict(result.stats),
        "timings": {name: round(seconds, 4) for name, seconds in result.timings.items()},
        "history": list(result.history),
    }


def optimization_lines(report: dict) -> list[str]:
    """A few lines of text on a phase-2 run, from :func:`optimization_report`."""
    stats, before, after = report["stats"], report["energy_before"], report["energy"]
    moves = "; ".join(
        f"{kind} {counts['accepted']:,} of {sum(counts.values()):,}"
        for kind, counts in report["moves"].items()
    )
    return [
        *(f"phase 2     {note}" for note in report["parameters"]["notes"]),
        f"phase 2     {stats['faces_before']:,} -> {stats['faces']:,} triangles; "
        f"{stats['points_used']:,} points, {stats['points_ignored']:,} left out as outliers",
        "phase 2     energy (normalised) distance + representation + spring: "
        f"{before['distance']:.4g} + {before['representation']:.4g} + {before['spring']:.4g} "
        f"= {before['total']:.4g} -> {after['distance']:.4g} + {after['representation']:.4g} "
        f"+ {after['spring']:.4g} = {after['total']:.4g}",
        f"phase 2     moves accepted: {moves}",
    ]


#: Share of disagreeing normals (`zeroset.types.Orientation.disagreement`) from which the
#: report asks whether the sensor positions are right: right ones leave well under 1 %
#: (0.06 % on the Stanford bunny's ten scans), a sensor on the wrong side of its scan 3 %.
DISAGREEMENT_WARNING = 0.01

#: How the report names the points each reduction step removed.
_REMOVED = {"cropped": "cropped", "sampled_out": "sampled out", "voxel_merged": "merged by voxels"}

#: How the report names each contouring method.
CONTOUR_NAMES = {"marching": "marching cubes", "cubes": "Method of Cubes"}


def format_report(report: dict) -> str:
    """Render a report from :func:`reconstruction_report` as a few aligned lines of text."""
    stats = report["stats"]
    removed = _removed(stats)
    cells = stats["phase1_points"] + stats["outliers"]
    lines = [
        *_reading_lines(report.get("reading")),
        f"points      {stats['input_points']:,} in"
        + "".join(f"; {item}" for item in removed)
        + (f"; averaged into {cells:,} cells" if report["parameters"]["averaging_cell"] else "")
        + f"; {stats['outliers']:,} outliers dropped; {stats['phase1_points']:,} fit planes"
        + (" (summed over the tiles, halos included)" if "tile_grid" in stats else ""),
        *_registration_lines(report.get("registration")),
        *(f"parameter   {note}" for note in report["parameters"]["notes"]),
        *_density_lines(stats),
        *_surface_lines(stats),
        *_tile_lines(stats),
        f"orientation {stats['orientation_components']} component(s)"
        + (
            f", {stats['orientation_turned']} turned so that no two sheets across a gap "
            "point the same way"
            if stats.get("orientation_turned")
            else ""
        )
        + _disagreement(stats.get("orientation_disagreement"), stats.get("viewpoints_untrusted")),
        f"grid        {stats['grid_vertices']:,} vertices evaluated, "
        f"{stats['undefined_grid_vertices']:,} undefined",
        f"mesh        {_mesh_origin(report)}: "
        f"{stats['vertices']:,} vertices, {stats['faces']:,} triangles, "
        f"{stats['boundary_loops']} boundary loop(s), {stats['mesh_components']} component(s), "
        f"Euler characteristic {stats['euler_characteristic']}",
        _rim_line(stats),
        f"repairs     {stats['small_holes_filled']} small hole(s) closed"
        + (
            f" (the widest {stats['widest_hole_filled']:.4g} across)"
            if stats.get("widest_hole_filled")
            else ""
        )
        + ", "
        f"{stats['small_components_dropped']} tiny component(s) dropped, "
        f"{stats['bowtie_vertices_split']} bow-tie vertex(es) split",
        *(optimization_lines(report["optimization"]) if "optimization" in report else []),
        *_fit_lines(report.get("fit")),
        "seconds     "
        + ", ".join(f"{name} {sec:.2f}" for name, sec in report["timings"].items())
        + f"; total {report['total_seconds']:.2f}"
        + (f"; peak memory {report['peak_mib']:,.0f} MiB" if "peak_mib" in report else ""),
    ]
    return "\n".join(lines)


def _surface_lines(stats: dict) -> list[str]:
    """Which surface function was contoured (`zeroset.surface.Surface.describe`), how the
    vertices were refined onto it, and how the mesh was simplified within its tolerance."""
    lines = [f"surface     {stats['surface_function']}"]
    if "refine_levels" in stats:
        lines.append(
            f"refine      vertices projected onto the surface ({stats['projection_held']:,} held "
            f"back so that no triangle turns over); {stats['edges_split']:,} edges split in "
            f"{stats['refine_levels']} round(s) where their chords sagged"
        )
    if stats.get("tolerance"):
        lines.append(
            f"simplify    {stats['dense_faces']:,} triangles -> {stats['faces']:,} within "
            f"{stats['tolerance']:.4g} of them ({stats['tolerance_note']}); "
            f"{stats['simplify_collapses']:,} edges collapsed, {stats['simplify_splits']:,} "
            f"split where a triangle strayed"
        )
    return lines


def _mesh_origin(report: dict) -> str:
    """How the mesh written came about: the contouring, then the simplification or phase 2."""
    origin = CONTOUR_NAMES[report["config"]["contour"]]
    if "optimization" in report:
        return f"{origin}, optimised by phase 2"
    stats = report["stats"]
    simplified = stats.get("tolerance") and stats["faces"] < stats["dense_faces"]
    return f"{origin}, simplified" if simplified else origin


def _rim_line(stats: dict) -> str:
    """Where the open boundaries were put: at the edge of the data, or at whole cubes."""
    if "rim_edges_cut" not in stats:
        return "rim         whole cubes whose corners lie within reach of the data"
    return (
        f"rim         cut where the data stop: {stats['rim_vertices_tested']:,} vertices "
        f"tested, {stats['rim_faces_removed']:,} triangles past the data removed, "
        f"{stats['rim_edges_cut']:,} edges cut"
    )


def _density_lines(stats: dict) -> list[str]:
    """What the per-point radii, the range noise model and the gap bridges did."""
    line = (
        f"density     {stats['widened_radii']:,} radii widened past rho_delta; "
        f"{stats['gap_bridge_points']:,} gap bridge points"
    )
    model = stats.get("noise_model")
    if model:
        line += f"; noise = {model['intercept']:.4g} + {model['slope']:.4g} x range"
    return [line]


def _registration_lines(registration: dict | None) -> list[str]:
    """One line per registered scan: its residual and overlap before and after."""
    if not registration:
        return []
    return [
        f"register    {scan['name']}: residual {scan['residual_before']:.4g} -> "
        f"{scan['residual_after']:.4g}, overlap {scan['overlap_before']:.0%} -> "
        f"{scan['overlap_after']:.0%} (pairs within {registration['max_distance']:.4g})"
        for scan in registration["scans"]
    ]


def _tile_lines(stats: dict) -> list[str]:
    """One line on a tiled run: the tiles, the flips that joined them, worker memory."""
    if "tile_grid" not in stats:
        return []
    peaks = stats["worker_peak_mib"].values()
    share = stats["seam_disagreement"]
    return [
        f"tiles       {stats['tiles']} ({'x'.join(map(str, stats['tile_grid']))}); "
        f"{stats['tile_components_flipped']} tile component(s) flipped to agree at the seams"
        + ("" if share is None else f", where {share:.2%} of the shared points still disagree")
        + (
            f"; peak memory per worker {min(peaks):,.0f}-{max(peaks):,.0f} MiB on "
            f"{len(peaks)} worker(s)"
            if peaks
            else ""  # a platform that does not say
        )
    ]


def _disagreement(share: float | None, untrusted: int | None) -> str:
    """How often the sensors and the spanning tree alone orient a point oppositely."""
    if share is None:
        return ""
    line = f"; sensors and spanning tree disagree on {share:.2%} of the points facing a sensor"
    if untrusted:
        line += f" (over {UNTRUSTED:.0%}, smoothly: sensors not trusted, the tree orients)"
    elif share > DISAGREEMENT_WARNING:
        line += f" (over {DISAGREEMENT_WARNING:.0%}: are the sensors where --viewpoint says?)"
    return line


def _reading_lines(reading: dict | None) -> list[str]:
    """One line on a reduction while reading, when one ran."""
    if not reading:
        return []
    removed = "; ".join(_removed(reading))
    return [f"reading     {reading['input_points']:,} points in the file; {removed} while reading"]


def _removed(counts: dict) -> list[str]:
    """Phrases like "120 cropped" for the reduction steps in `counts`."""
    return [f"{counts[key]:,} {label}" for key, label in _REMOVED.items() if key in counts]


def _fit_lines(fit: dict | None) -> list[str]:
    """One line on how far the input points lie from the mesh, when measured."""
    if fit is None:
        return []
    distance = fit["distance"]
    return [
        f"fit         points lie {distance['mean']:.4g} (mean), {distance['p95']:.4g} (95 %) "
        f"from the mesh; {fit['coverage']:.1%} within {fit['tau']:.4g} (1 % of their extent)"
    ]
