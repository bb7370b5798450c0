"""What a run reports (``Reconstruction.stats``): every count a stage or a tile may add, what
it means, and how the counts of several stages or tiles combine.

A count not declared in ``SCHEMA`` is a programming error: `add_counts` and `declared`
raise on it, so a report holds no key a reader cannot look up here.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SCHEMA", "Count", "add_counts", "declared"]

#: How two values of one count combine: added up, the larger kept, or set once only.
COMBINES = ("sum", "largest", "once")


@dataclass(frozen=True)
class Count:
    """One key of a run's stats: its meaning, and how two values of it combine
    (``COMBINES``)."""

    meaning: str
    combine: str = "sum"


#: Every key of ``Reconstruction.stats``, by the stage that sets it.
SCHEMA = {
    # prepare (zeroset.prepare.reduce_chunks)
    "input_points": Count("points in the input"),
    "cropped": Count("points outside the crop box"),
    "sampled_out": Count("points the random sample left out"),
    "voxel_merged": Count("points merged into their voxel's representative"),
    # outliers
    "outliers": Count("points with too few neighbours within their radius, dropped"),
    "phase1_points": Count("points the tangent planes are fitted to"),
    "widened_radii": Count("points whose radius exceeds rho+delta (sparse or noisy there)"),
    "noise_model": Count("noise against range: intercept and slope, with sensors", "once"),
    # orientation
    "orientation_components": Count("components of the orientation graph, each oriented alone"),
    "orientation_turned": Count("components turned so that no two sheets face one way"),
    "viewpoints_untrusted": Count("runs (or tiles) where the sensors and the tree disagree"),
    "orientation_disagreement": Count("share of points where sensors and tree disagree", "once"),
    # local fits
    "surface_function": Count("the local surface contoured, in words", "once"),
    "jets": Count("quadric fits whose blend is the surface"),
    "fit_support": Count("median support radius of the jets, data units", "once"),
    "fit_notes": Count("how the jets' supports were chosen", "once"),
    # signed distance
    "gap_bridge_points": Count("points along chords across gaps in the sampling"),
    "grid_vertices": Count("lattice vertices the signed distance was evaluated at"),
    "undefined_grid_vertices": Count("of them, those too far from the data: undefined"),
    # repair and rim
    "bowtie_vertices_split": Count("vertices shared by two fans of faces, split"),
    "small_holes_filled": Count("small boundary loops closed"),
    "widest_hole_filled": Count("width of the widest hole closed, data units", "largest"),
    "small_components_dropped": Count("components of too few faces dropped"),
    "rim_vertices_tested": Count("boundary vertices tested against the edge of the data"),
    "rim_faces_removed": Count("faces past the edge of the data removed"),
    "rim_edges_cut": Count("edges cut where the data stop"),
    "rim_hole_vertices": Count("vertices opened to the measured points of a hole"),
    # refine
    "refine_levels": Count("rounds of edge splits", "largest"),
    "edges_split": Count("edges split where their chords sagged"),
    "projection_held": Count("vertices held back so that no triangle turned over"),
    # simplify
    "tolerance": Count("largest distance of the mesh from the dense mesh, data units", "once"),
    "tolerance_note": Count("how the tolerance was chosen", "once"),
    "dense_faces": Count("faces of the dense mesh before simplification", "once"),
    "simplify_collapses": Count("edges collapsed within the tolerance"),
    "simplify_splits": Count("edges split where a triangle strayed past the tolerance"),
    "simplify_strays": Count("triangles still farther than the tolerance, after the checks"),
    # the mesh
    "vertices": Count("vertices of the mesh", "once"),
    "faces": Count("faces of the mesh", "once"),
    "boundary_loops": Count("boundary loops of the mesh", "once"),
    "mesh_components": Count("connected components of the mesh", "once"),
    "euler_characteristic": Count("Euler characteristic of the mesh", "once"),
    # phase 2
    "phase2_points": Count("points phase 2 fitted the mesh to"),
    "phase2_points_ignored": Count("points phase 2 ignored (too far from the mesh)"),
    "phase2_tolerance": Count("largest distance of phase 2's mesh from the dense mesh", "once"),
    "phase2_tolerance_splits": Count("edges split where phase 2's triangles strayed"),
    "phase2_tolerance_strays": Count("phase 2's triangles still farther than the tolerance"),
    # tiles
    "tiles": Count("tiles planned", "once"),
    "tiles_failed": Count("tiles left out, a gap in the mesh", "once"),
    "tiles_grown": Count("tiles whose halo was widened"),
    "tile_grid": Count("tiles along x, y and z", "once"),
    "tile_components_flipped": Count("tile components turned to agree with the others", "once"),
    "seam_disagreement": Count("share of seam points whose tiles' normals disagree", "once"),
    "seam_vertex_gap": Count("farthest two tiles put one vertex apart, data units", "once"),
    "worker_peak_mib": Count("peak memory of each Dask worker, MiB", "once"),
    # live (zeroset.live)
    "scans": Count("scans given"),
    "scans_skipped": Count("scans left out whole: no usable points, or a sensor far off"),
    "late_points": Count("points that fell into sealed blocks, left out"),
    "nonfinite_points": Count("points of the scans that were not finite, left out"),
    "blocks_finished": Count("blocks whose final mesh is made", "once"),
    "block_dense_faces": Count("faces of the blocks' dense meshes before simplification"),
    "blocks_failed": Count("blocks left out, a gap in the mesh: their fit or rim found no surface"),
    "blocks_moved_at_seams": Count("blocks whose seam vertices were moved past rounding"),
    "blocks_drifted": Count("blocks whose own points would choose other parameters", "once"),
    "peak_mib": Count("peak memory of the process so far, MiB", "once"),
}


def add_counts(total: dict, counts: dict) -> dict:
    """Add `counts` to `total` in place, each as its ``SCHEMA`` entry says, and return it."""
    for name, value in counts.items():
        combine = _count(name).combine
        if name not in total:
            total[name] = value
        elif combine == "sum":
            total[name] += value
        elif combine == "largest":
            total[name] = max(total[name], value)
        else:
            raise ValueError(f"count {name!r} is set once, and was set twice")
    return total


def declared(stats: dict) -> dict:
    """`stats`, once every key of it is found in ``SCHEMA``."""
    for name in stats:
        _count(name)
    return stats


def _count(name: str) -> Count:
    """The ``SCHEMA`` entry of `name`; a KeyError that says so where there is none."""
    try:
        return SCHEMA[name]
    except KeyError:
        raise KeyError(f"count {name!r} is not declared in zeroset.stats.SCHEMA") from None
