"""What a reconstruction chose, counted and spent: as a dict for JSON and as text for a terminal."""

from __future__ import annotations

from dataclasses import asdict

from .pipeline import Reconstruction

__all__ = ["format_report", "reconstruction_report"]


def reconstruction_report(result: Reconstruction, *, source: str | None = None) -> dict:
    """Return a JSON-ready summary of `result`: parameters and why, counts, timings.

    Parameters
    ----------
    result : Reconstruction
    source : str, optional
        Where the points came from, for the record.

    Returns
    -------
    dict
        Keys ``source``, ``parameters`` (values and ``notes``), ``config``, ``stats``,
        ``timings`` (seconds per stage) and ``total_seconds``.
    """
    params = result.parameters
    return {
        "source": source,
        "parameters": {
            "rho_delta": params.rho_delta,
            "cube_size": params.cube_size,
            "spacing": params.spacing,
            "noise": params.noise,
            "averaging_cell": params.averaging_cell,
            "min_neighbours": params.min_neighbours,
            "notes": list(params.notes),
        },
        "config": asdict(result.config),
        "stats": dict(result.stats),
        "timings": {name: round(seconds, 4) for name, seconds in result.timings.items()},
        "total_seconds": round(sum(result.timings.values()), 4),
    }


def format_report(report: dict) -> str:
    """Render a report from :func:`reconstruction_report` as a few aligned lines of text."""
    stats = report["stats"]
    removed = [
        f"{stats[key]} {label}"
        for key, label in (
            ("cropped", "cropped"),
            ("sampled_out", "sampled out"),
            ("voxel_merged", "merged by voxels"),
            ("outliers", "outliers dropped"),
        )
        if key in stats
    ]
    lines = [
        f"points      {stats['input_points']:,} in; {', '.join(removed)}; "
        f"{stats['phase1_points']:,} used for tangent planes",
        *(f"parameter   {note}" for note in report["parameters"]["notes"]),
        f"orientation {stats['orientation_components']} component(s)",
        f"grid        {stats['grid_vertices']:,} vertices evaluated, "
        f"{stats['undefined_grid_vertices']:,} undefined",
        f"mesh        {stats['vertices']:,} vertices, {stats['faces']:,} triangles, "
        f"{stats['boundary_loops']} boundary loop(s), {stats['mesh_components']} component(s), "
        f"Euler characteristic {stats['euler_characteristic']}",
        f"repairs     {stats['small_holes_filled']} small hole(s) closed, "
        f"{stats['small_components_dropped']} tiny component(s) dropped, "
        f"{stats['bowtie_vertices_split']} bow-tie vertex(es) split",
        "seconds     "
        + ", ".join(f"{name} {sec:.2f}" for name, sec in report["timings"].items())
        + f"; total {report['total_seconds']:.2f}",
    ]
    return "\n".join(lines)
