"""The phase-1 stages, each a function of arrays, and what passes between them.

One sequence serves one machine (`zeroset.pipeline.reconstruct`) and tiles
(`zeroset.tiles`), in three parts:

1. `fit`: "cell means", "neighbours", "radii", "outliers", "tangent planes",
   "orientation", "local fits" (the tiles then agree on their normals' signs,
   `zeroset.orientation.agree_parts`);
2. "signed distance" (`distance_field`) and "contour" (the tiles contour the cubes they
   own and weld the pieces);
3. `finish`: "repair", "rim", "refine".

"prepare" and "parameters" come before them and "optimize" after. Every stage returns its
result and a dict of counts; a run adds the counts up (`zeroset.stats.add_counts`) and
times each stage under its name (`zeroset._progress.Stages`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from . import topology
from ._progress import Stages
from .config import ReconstructionConfig
from .contour import marching_cubes, method_of_cubes
from .density import gap_bridges, local_spacing, point_radii, range_noise, sector_distances
from .distance import signed_distance
from .errors import InputError, ReconstructionError, SurfaceWarning
from .neighbours import build_tree, knn, restrict, spatial_order
from .normals import tangent_planes
from .optimization import optimize_mesh
from .orientation import orient_normals
from .parameters import estimate_parameters
from .prepare import cell_labels, crop, drop_outliers, group_means, group_viewpoints, reduce_chunks
from .refine import refine_mesh
from .repair import fill_small_holes, remove_small_components, split_nonmanifold_vertices
from .rim import no_empty_ball, trim_to_data
from .simplify import choose_tolerance, simplify_mesh
from .surface import Surface, surface_kind
from .thresholds import (
    BRIDGE_REACH,
    BRIDGE_STEP,
    BRIDGES_NOTED,
    CHORD_NOISE,
    HOLE_BALL,
    HOLE_WIDTH,
    SMOOTH_K,
    UNTRUSTED,
    WIDE_K,
    WIDTH_EDGES,
)
from .types import DistanceField, Mesh, Neighbourhoods, Orientation, Parameters, TangentPlanes

__all__ = [
    "STAGES",
    "OPTIMIZE_STAGE",
    "stage_names",
    "fit",
    "finish",
    "LocalCloud",
    "Cells",
    "Density",
    "FittedPlanes",
    "DataSupport",
    "prepare_points",
    "local_viewpoints",
    "choose_parameters",
    "average_in_cells",
    "find_neighbours",
    "measure_radii",
    "drop_sparse_points",
    "fit_tangent_planes",
    "orient",
    "fit_local_surface",
    "distance_field",
    "contour",
    "data_support",
    "repair",
    "trim_rim",
    "refine",
    "simplify",
    "optimize_surface",
    "fit_stats",
    "mesh_stats",
    "surface_changes",
    "warn_surface_changes",
]

STAGES = (
    "prepare",
    "parameters",
    "cell means",
    "neighbours",
    "radii",
    "outliers",
    "tangent planes",
    "orientation",
    "local fits",
    "signed distance",
    "contour",
    "repair",
    "rim",
    "refine",
    "simplify",
)
#: Stages that run only for a smooth local surface, and only for rims at the data.
SMOOTH_STAGES = ("refine", "simplify")
RIM_STAGES = ("rim",)
OPTIMIZE_STAGE = "optimize"
#: Largest coordinate magnitude and smallest extent accepted: squared distances between
#: points then stay far from float64's overflow (1.8e308) and underflow (2.2e-308).
MAX_COORDINATE = 1e100
MIN_EXTENT = 1e-100


def stage_names(config: ReconstructionConfig, optimize: bool = False) -> tuple[str, ...]:
    """The stages a run of `config` goes through, in order."""
    smooth = surface_kind(config.surface).smooth
    names = tuple(
        s
        for s in STAGES
        if (smooth or s not in SMOOTH_STAGES)
        and (config.rim == "data" or s not in RIM_STAGES)
        and not (optimize and s == "simplify")  # phase 2 chooses the triangles instead
    )
    return names + ((OPTIMIZE_STAGE,) if optimize else ())


def fit(cloud: LocalCloud, parameters: Parameters, config, stages: Stages) -> FittedPlanes:
    """Stages "cell means" to "local fits" on the points of `cloud`."""
    local = cloud.local
    cells = stages.run("cell means", average_in_cells, local, cloud.viewpoints, parameters, config)
    neighbours = stages.run("neighbours", find_neighbours, cells.points, config)
    density = stages.run("radii", measure_radii, cells, neighbours, parameters, config)
    cells, neighbours, density = stages.run(
        "outliers", drop_sparse_points, cells, neighbours, density, parameters, config
    )
    planes = stages.run(
        "tangent planes", fit_tangent_planes, cells.points, neighbours, density, config
    )
    orientation = stages.run(
        "orientation", orient, planes, neighbours, density, cells.viewpoints, config
    )
    surface = stages.run("local fits", fit_local_surface, local, cells, planes, parameters, config)
    return FittedPlanes(
        points=cells.points,
        density=density,
        planes=planes,
        orientation=orientation,
        surface=surface,
    )


def finish(
    mesh: Mesh,
    support,
    surface: Surface,
    parameters: Parameters,
    config,
    stages: Stages,
    *,
    refine_how=refine_mesh,
):
    """Stages "repair", "rim" and "refine" on a contoured mesh in the local frame, with the
    `DataSupport` the rim is cut back to and the oriented `surface` it is refined on (where
    it is smooth); `refine_how` as for `refine`."""
    mesh = stages.run("repair", repair, mesh, parameters, config)
    if config.rim == "data":
        mesh = stages.run("rim", trim_rim, mesh, support, parameters, config)
    if surface.smooth:
        mesh = stages.run("refine", refine, mesh, surface, parameters, config, how=refine_how)
    return mesh


# ------------------------------------------------------------------------------ results


@dataclass(frozen=True, eq=False)
class LocalCloud:
    """The points a run works on, in its local frame ``original = local + offset``.

    Attributes
    ----------
    local : (N, 3) float64
        Cropped, sampled and in spatial order.
    offset : (3,) float64
    viewpoints : (N, 3) or (3,) float64, or None
        Their sensor positions (rows of NaN where not known), or one for all, in the frame.
    """

    local: np.ndarray
    offset: np.ndarray
    viewpoints: np.ndarray | None

    @cached_property
    def tree(self) -> cKDTree:
        """The k-d tree of `local`, built once."""
        return build_tree(self.local)


@dataclass(frozen=True, eq=False)
class Cells:
    """The points the tangent planes are fitted to: one per averaging cell.

    Attributes
    ----------
    points : (M, 3) float64
        The mean of each cell's points.
    cell : (N,) int64
        Row of `points` each point of the run belongs to, -1 where its cell was dropped.
    viewpoints : (M, 3) or (3,) float64, or None
        Each cell's sensor position, or one for all.
    """

    points: np.ndarray
    cell: np.ndarray
    viewpoints: np.ndarray | None


@dataclass(frozen=True, eq=False)
class Density:
    """How densely the points lie around each one (`zeroset.density`).

    Attributes
    ----------
    radii : (M,) float64
        Per-point radius (`zeroset.density.point_radii`).
    sectors : (M, 8) float64
        Nearest distance per direction (`zeroset.density.sector_distances`).
    extent : (M, 2) float64
        Distance to its ``SMOOTH_K``-th nearest neighbour and to the farthest one found
        (`find_neighbours`): how far the neighbourhoods defined by a count of points reach.
    spacing : (M,) float64
        Spacing of the points around each one (`zeroset.density.local_spacing`).
    noise_model : (intercept, slope) of float, or None
        Noise as a straight-line function of range (`zeroset.density.range_noise`), when
        the sensor positions are known.
    """

    radii: np.ndarray
    sectors: np.ndarray
    extent: np.ndarray
    spacing: np.ndarray
    noise_model: tuple[float, float] | None = None


@dataclass(frozen=True, eq=False)
class FittedPlanes:
    """What phase 1 knows of the points once their tangent planes are oriented.

    Attributes
    ----------
    points : (N, 3) float64
        The points the planes were fitted to (averaged in cells, outliers dropped).
    density : Density
        Their radii, sectors and neighbourhoods' extent, and the range-noise model.
    planes : TangentPlanes
    orientation : Orientation
    surface : Surface
        The local surface (``config.surface``), not yet oriented.
    """

    points: np.ndarray
    density: Density
    planes: TangentPlanes
    orientation: Orientation
    surface: Surface

    @cached_property
    def tree(self) -> cKDTree:
        """The k-d tree of `points`, built once."""
        return build_tree(self.points)

    @cached_property
    def centroid_tree(self) -> cKDTree:
        """The k-d tree of the planes' centroids, built once."""
        return build_tree(self.planes.centroids)


@dataclass(frozen=True, eq=False)
class DataSupport:
    """Where the data are: the fitted points and the gap bridges between them.

    Attributes
    ----------
    points : (P, 3) float64
    radii : (P,) float64
        Each one's radius.
    reach : (P,) float64
        How far the surface reaches from it.
    measured : (P,) bool
        Whether it was measured, not bridged.
    planes : (P, 3) float64
        The unit normal of its tangent plane; zero for a bridge point.
    """

    points: np.ndarray
    radii: np.ndarray
    reach: np.ndarray
    measured: np.ndarray
    planes: np.ndarray

    @cached_property
    def measured_tree(self) -> cKDTree:
        """The k-d tree of the measured points, built once."""
        return build_tree(self.points[self.measured])

    def select(self, rows) -> DataSupport:
        """The support of `rows` (a mask or indices) only."""
        return DataSupport(*(getattr(self, f.name)[rows] for f in fields(DataSupport)))

    @staticmethod
    def concatenate(parts) -> DataSupport:
        """One support of all `parts`, in order."""
        return DataSupport(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(DataSupport))
        )


# ------------------------------------------------------------------------------- stages


def prepare_points(points, viewpoints, config: ReconstructionConfig) -> tuple[LocalCloud, dict]:
    """Stage "prepare": crop and sample the points (N, 3), put them in spatial order, reject
    a cloud no surface can come from, and move them and their `viewpoints` into a frame
    centred on them."""
    reduction = reduce_chunks(
        lambda: [{"points": points}],
        crop_box=config.crop,
        sample=config.sample,
        voxel_size=config.voxel_size,
        seed=config.seed,
    )
    counts = {k: v for k, v in reduction.counts.items() if k != "input_points"}
    rows = reduction.rows
    if rows.size < config.k_max:
        left = (
            f" of {points.shape[0]} left after cropping and sampling"
            if rows.size < points.shape[0]
            else ""
        )
        raise InputError(
            f"only {rows.size} point{'' if rows.size == 1 else 's'}{left}; "
            f"a neighbourhood needs at least k_max={config.k_max}"
        )
    rows = rows[spatial_order(points[rows])]
    kept = points[rows]
    _check_spread(kept)
    offset = (kept.min(axis=0) + kept.max(axis=0)) / 2.0
    return LocalCloud(
        kept - offset, offset, local_viewpoints(viewpoints, rows, offset, config)
    ), counts


def local_viewpoints(viewpoints, rows, offset, config: ReconstructionConfig):
    """The sensor positions of the points `rows` in the frame of `offset`: of each, from
    `viewpoints` (N, 3); else one for all from ``config.viewpoint``; else None."""
    if viewpoints is not None:
        return viewpoints[rows] - offset
    if config.viewpoint is not None:
        return np.asarray(config.viewpoint, dtype=np.float64) - offset
    return None


def choose_parameters(local: np.ndarray, config: ReconstructionConfig, tree=None, rows=None):
    """Stage "parameters": `zeroset.parameters.estimate_parameters` with `config`'s knobs,
    on points (N, 3) and their k-d `tree` where it is built, measured at the points `rows`
    where they are given."""
    parameters = estimate_parameters(
        local,
        tree=tree,
        rows=rows,
        k=config.radius_k,
        quantile=config.quantile,
        noise_factor=config.noise_factor,
        cube_factor=config.cube_factor,
        k_max=config.k_max,
        rho_delta=config.rho_delta,
        cube_size=config.cube_size,
        averaging_cell=config.averaging_cell,
        min_neighbours=config.min_neighbours,
        rng=config.seed,
    )
    return parameters, {}


def average_in_cells(local, viewpoints, parameters: Parameters, config) -> tuple[Cells, dict]:
    """Stage "cell means": the points (N, 3) averaged in cubic cells of
    ``parameters.averaging_cell``, or kept as they are when it is 0."""
    if parameters.averaging_cell <= 0.0:
        return Cells(local, np.arange(local.shape[0]), viewpoints), {}
    cell = cell_labels(local, parameters.averaging_cell)
    means = group_means(local, cell)[0]
    needed = max(config.k_max, SMOOTH_K)
    if means.shape[0] < needed:
        raise ReconstructionError(
            f"the {local.shape[0]} points fill only {means.shape[0]} averaging cells of "
            f"{parameters.averaging_cell:.4g}; a neighbourhood needs at least {needed}: the "
            f"cloud is too small for its spacing (set averaging_cell=0, or a smaller rho_delta)"
        )
    if viewpoints is not None and viewpoints.ndim == 2:
        viewpoints = group_viewpoints(local, viewpoints, cell)
    return Cells(means, cell, viewpoints), {}


def find_neighbours(points, config: ReconstructionConfig) -> tuple[Neighbourhoods, dict]:
    """Stage "neighbours": the nearest ``max(k_max, WIDE_K)`` of every point (M, 3)."""
    return knn(points, max(config.k_max, WIDE_K)), {}


def measure_radii(cells: Cells, neighbours, parameters: Parameters, config) -> tuple[Density, dict]:
    """Stage "radii": the sector distances and radius of every point, its noise margin
    from the sensor's range-noise model where the sensors are known."""
    noise, model = parameters.noise, None
    if cells.viewpoints is not None:
        noise, model = range_noise(
            cells.points,
            neighbours,
            cells.viewpoints,
            noise=noise,
            model=parameters.noise_model,
        )
    sectors, _ = sector_distances(cells.points, neighbours.indices, neighbours.distances)
    spacing = local_spacing(sectors, neighbours)
    radii = point_radii(spacing, rho_delta=parameters.rho_delta, margin=config.noise_factor * noise)
    extent = neighbours.distances[:, [SMOOTH_K - 1, -1]]
    return Density(radii, sectors, extent, spacing, model), {}


def drop_sparse_points(cells: Cells, neighbours, density: Density, parameters: Parameters, config):
    """Stage "outliers": drop the points with fewer than ``parameters.min_neighbours``
    neighbours within their radius; the cells, neighbourhoods and density of the rest."""
    keep = drop_outliers(neighbours, density.radii, parameters.min_neighbours)
    kept = int(np.count_nonzero(keep))
    counts = {
        "outliers": keep.size - kept,
        "phase1_points": kept,
        "widened_radii": int(np.count_nonzero(density.radii[keep] > parameters.rho_delta)),
    }
    if kept < config.k_max:
        raise ReconstructionError(
            f"only {kept} points are left after removing {keep.size - kept} "
            f"outliers (fewer than {parameters.min_neighbours} neighbours within their "
            f"radius, at least rho_delta={parameters.rho_delta:.4g}); increase rho_delta"
        )
    row = np.where(keep, np.cumsum(keep) - 1, -1)
    viewpoints = cells.viewpoints
    if viewpoints is not None and viewpoints.ndim == 2:
        viewpoints = viewpoints[keep]
    cells = Cells(cells.points[keep], row[cells.cell], viewpoints)
    density = Density(
        density.radii[keep],
        density.sectors[keep],
        density.extent[keep],
        density.spacing[keep],
        density.noise_model,
    )
    return (cells, restrict(neighbours, keep), density), counts


def fit_tangent_planes(points, neighbours, density: Density, config) -> tuple[TangentPlanes, dict]:
    """Stage "tangent planes": a plane through every point's neighbourhood within its radius."""
    planes = tangent_planes(
        points, radius=density.radii, k_min=config.k_min, k_max=config.k_max, neighbours=neighbours
    )
    return planes, {}


def orient(planes: TangentPlanes, neighbours, density: Density, viewpoints, config):
    """Stage "orientation": `zeroset.orientation.orient_normals` over edges of at most two
    radii, towards the sensors where they are known."""
    orientation = orient_normals(
        planes.centroids,
        planes.normals,
        k=config.orient_k,
        max_edge=2.0 * density.radii,
        neighbours=neighbours,
        viewpoints=viewpoints,
    )
    counts = {
        "orientation_components": orientation.n_components,
        "orientation_turned": orientation.turned,
    }
    if orientation.disagreement is not None:
        counts["viewpoints_untrusted"] = int(orientation.viewpoints_untrusted)
    return orientation, counts


def fit_local_surface(local, cells: Cells, planes, parameters: Parameters, config):
    """Stage "local fits": the local surface of ``config.surface`` (`zeroset.surface`) over
    every point (N, 3), each in its cell's plane."""
    return surface_kind(config.surface).fit(local, cells.cell, planes, parameters, config), {}


def distance_field(cloud: LocalCloud, fitted: FittedPlanes, normals, parameters, config):
    """Stage "signed distance": the field of the planes of `fitted` turned by `normals`
    around the points of `cloud`, the gap bridges (B, 3), and the local surface of `fitted`
    turned like the nearest planes, which values the field.

    Without ``config.gap_bridges`` there are none. For ``config.rim == "data"`` the field
    reaches one cube further than the points' radii, so that the cubes cover the edge of
    the data wherever the lattice lies; the rim is then cut back to that edge (`trim_rim`).
    """
    surface = fitted.surface.oriented(fitted.planes.centroids, normals, tree=fitted.centroid_tree)
    bridges = np.zeros((0, 3))
    if config.gap_bridges:
        bridges = gap_bridges(
            fitted.points,
            fitted.density.sectors,
            rho_delta=parameters.rho_delta,
            tree=fitted.tree,
            normals=normals,
        )
    field_ = signed_distance(
        cloud.local,
        fitted.planes.centroids,
        normals,
        cube_size=parameters.cube_size,
        radius=fitted.density.radii + (parameters.cube_size if config.rim == "data" else 0.0),
        bridges=bridges,
        bridge_reach=BRIDGE_REACH * parameters.rho_delta,
        surface=lambda x: surface.evaluate(x)[0],
        tree=cloud.tree,
        centroid_tree=fitted.centroid_tree,
    )
    counts = {
        "gap_bridge_points": bridges.shape[0],
        "grid_vertices": int(field_.values.size),
        "undefined_grid_vertices": int(np.count_nonzero(np.isnan(field_.values))),
    }
    return (field_, bridges, surface), counts


def contour(field_: DistanceField, fitted: FittedPlanes, normals, parameters, config):
    """Stage "contour": marching cubes, or the Method of Cubes on the points of `fitted`."""
    if config.contour != "cubes":
        return marching_cubes(field_), {}
    return method_of_cubes(field_, fitted.points, fitted.planes.centroids, normals), {}


def data_support(fitted: FittedPlanes, bridges: np.ndarray, parameters: Parameters):
    """The `DataSupport` of the points of `fitted` and the gap `bridges` (B, 3). The reach
    is a point's radius, and for a bridge point the step between bridge points, so that a
    chord covers a strip along itself and not the middle of a round hole off its end."""
    n_bridges = bridges.shape[0]
    return DataSupport(
        points=np.concatenate([fitted.points, bridges]),
        radii=np.r_[fitted.density.radii, np.full(n_bridges, BRIDGE_REACH * parameters.rho_delta)],
        reach=np.r_[fitted.density.radii, np.full(n_bridges, BRIDGE_STEP * parameters.rho_delta)],
        measured=np.r_[np.ones(fitted.points.shape[0], bool), np.zeros(n_bridges, bool)],
        planes=np.concatenate([fitted.planes.normals, np.zeros((n_bridges, 3))]),
    )


def repair(mesh: Mesh, parameters: Parameters, config) -> tuple[Mesh, dict]:
    """Stage "repair": split bow-tie vertices, close small holes, drop tiny components."""
    mesh, split = split_nonmanifold_vertices(mesh)
    mesh, filled, widest = fill_small_holes(
        mesh, config.max_hole_edges, max_width=HOLE_WIDTH * parameters.rho_delta
    )
    mesh, dropped = remove_small_components(mesh, config.min_component_faces)
    if mesh.n_faces == 0:
        raise ReconstructionError(
            f"no surface: no cube of size {parameters.cube_size:.4g} has eight defined "
            f"corners with a sign change; rho_delta={parameters.rho_delta:.4g} may be "
            "too small for the point spacing"
        )
    return mesh, {
        "bowtie_vertices_split": split,
        "small_holes_filled": filled,
        "widest_hole_filled": widest,
        "small_components_dropped": dropped,
    }


def trim_rim(mesh: Mesh, support: DataSupport, parameters: Parameters, config):
    """Stage "rim": cut the boundaries back to the edge of the data (`DataSupport`), and
    open every hole wider than the longest gap bridge to its measured points
    (``HOLE_BALL``); a hole the cut opened with room for no such ball is closed again."""
    mesh, counts = trim_to_data(
        mesh,
        support.points,
        support.radii,
        cube_size=parameters.cube_size,
        reach=support.reach,
        measured=support.measured,
        hole=HOLE_BALL,
        measured_tree=support.measured_tree,
        planes=support.planes,
    )
    # Where the cut's own line pinches two stretches of rim into one vertex, split it.
    mesh, counts["bowtie_vertices_split"] = split_nonmanifold_vertices(mesh)
    if config.max_hole_edges > 0:  # gaps with room for no empty ball are no holes
        measured = support.select(support.measured)
        closable = no_empty_ball(
            measured.points, HOLE_BALL * measured.radii, tree=support.measured_tree
        )
        mesh, filled, widest = fill_small_holes(mesh, WIDTH_EDGES, closable=closable)
        counts["small_holes_filled"], counts["widest_hole_filled"] = filled, widest
    mesh, counts["small_components_dropped"] = remove_small_components(
        mesh, config.min_component_faces
    )
    if mesh.n_faces == 0:
        raise ReconstructionError(
            "no surface: the points within reach of every vertex sample a curve or too "
            f"few directions (rho_delta={parameters.rho_delta:.4g})"
        )
    return mesh, counts


def refine(mesh: Mesh, surface: Surface, parameters: Parameters, config, *, how=refine_mesh):
    """Stage "refine": move the vertices onto the smooth `surface` (`zeroset.refine`).

    `how(mesh, surface, noise=, levels=)` returns the mesh and `refine_mesh`'s counts; the
    tiles pass one that refines a tile at a time (`zeroset.tiles`)."""
    return how(mesh, surface, noise=parameters.noise, levels=config.refine_levels)


def simplify(mesh: Mesh, surface: Surface, parameters: Parameters, config, *, how=simplify_mesh):
    """Stage "simplify": few triangles within the tolerance of the dense `mesh`
    (`zeroset.simplify`), the tolerance chosen from the `surface` unless given.

    `how(mesh, tolerance)` returns the mesh and `simplify_mesh`'s counts; the tiles pass
    one that simplifies a tile at a time (`zeroset.tiles`)."""
    chord = CHORD_NOISE * parameters.noise  # R45: the sag the dense chords may have
    tolerance, note = choose_tolerance(surface, parameters.quadric_noise, chord, config.tolerance)
    simple, counts = how(mesh, tolerance)
    return simple, {
        "tolerance": tolerance,
        "tolerance_note": note,
        "dense_faces": mesh.n_faces,
        **counts,
    }


def optimize_surface(mesh: Mesh, points, offset, config, progress: bool):
    """Stage "optimize": phase 2 on `mesh` (local frame) with every point (N, 3) of the
    input that the crop keeps, within the config's tolerance of `mesh` if it gives one."""
    if config.crop is not None:
        points = points[crop(points, config.crop[:3], config.crop[3:])]
    result = optimize_mesh(
        mesh,
        points - offset,
        c_rep=config.c_rep,
        kappa=config.kappa,
        tolerance=config.tolerance,
        rng=config.seed,
        progress=progress,
    )
    held = ("tolerance", "tolerance_splits", "tolerance_strays")
    return result, {
        "phase2_points": result.stats["points_used"],
        "phase2_points_ignored": result.stats["points_ignored"],
        **{f"phase2_{key}": result.stats[key] for key in held if key in result.stats},
    }


# ----------------------------------------------------------------------- what was found


def fit_stats(fitted: FittedPlanes) -> dict:
    """The range-noise model and the sensors' disagreement with the tree, where known."""
    stats = {}
    if fitted.density.noise_model is not None:
        intercept, slope = fitted.density.noise_model
        stats["noise_model"] = {"intercept": intercept, "slope": slope}
    if fitted.orientation.disagreement is not None:
        stats["orientation_disagreement"] = fitted.orientation.disagreement
    return stats


def mesh_stats(mesh: Mesh) -> dict:
    """Counts that describe a mesh: vertices, faces, boundary loops, Euler characteristic."""
    return {
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "boundary_loops": len(topology.boundary_loops(mesh.faces)),
        "mesh_components": topology.face_components(mesh.faces, mesh.n_vertices)[0],
        "euler_characteristic": topology.euler_characteristic(mesh),
    }


def surface_changes(stats: dict, config: ReconstructionConfig) -> list[str]:
    """One message per change a run made beyond Hoppe's method, with the option that turns
    it off; `warn_surface_changes` issues them as `SurfaceWarning`. Gap bridges count from
    ``BRIDGES_NOTED`` of the points: an evenly sampled cloud has about 1 % at random gaps."""
    messages = []
    if stats.get("gap_bridge_points", 0) > BRIDGES_NOTED * stats.get("phase1_points", 0):
        messages.append(
            f"{stats['gap_bridge_points']:,} points along chords across gaps in the sampling "
            "count as data; gap_bridges=False (--no-gap-bridges) turns them off"
        )
    if stats.get("small_holes_filled"):
        messages.append(
            f"{stats['small_holes_filled']} small hole(s) closed, the widest "
            f"{stats.get('widest_hole_filled', 0.0):.4g} across; max_hole_edges=0 "
            "(--max-hole-edges 0) keeps every hole open"
        )
    if stats.get("small_components_dropped"):
        messages.append(
            f"{stats['small_components_dropped']} component(s) of fewer than "
            f"{config.min_component_faces} faces dropped; min_component_faces=0 "
            "(--min-component-faces 0) keeps them"
        )
    if stats.get("orientation_components", 1) > 1:
        messages.append(
            f"the orientation graph has {stats['orientation_components']} components, each "
            "oriented on its own (outward at its extreme point); viewpoints, or a larger "
            "rho_delta or orient_k, join them"
        )
    if stats.get("viewpoints_untrusted"):
        where = (
            f"in {stats['viewpoints_untrusted']} of {stats['tiles']} tiles"
            if "tiles" in stats
            else f"on {stats['orientation_disagreement']:.1%} of the points facing a sensor"
        )
        messages.append(
            f"the sensor positions and the spanning tree disagree {where} (over "
            f"{UNTRUSTED:.0%} of them): the tree orients the normals, the sensors only set "
            "each component's sign; check the viewpoints"
        )
    if stats.get("simplify_strays"):
        messages.append(
            f"{stats['simplify_strays']} triangle(s) lie farther than the tolerance "
            f"{stats['tolerance']:.4g} from the dense mesh after every check round; "
            "tolerance=0 (--tolerance 0) keeps the dense mesh"
        )
    return messages


def warn_surface_changes(stats: dict, config: ReconstructionConfig) -> None:
    """Issue every `surface_changes` message as a `SurfaceWarning` to the caller's caller."""
    for message in surface_changes(stats, config):
        warnings.warn(message, SurfaceWarning, stacklevel=3)


def _check_spread(points: np.ndarray) -> None:
    """Reject clouds no surface can come from: coincident or collinear points, or a scale
    whose squared distances float64 cannot hold."""
    largest = float(np.abs(points).max())
    if largest > MAX_COORDINATE:
        raise InputError(
            f"coordinates reach {largest:.3g}; rescale the points so that they stay "
            f"within {MAX_COORDINATE:g} of the origin"
        )
    extent = float(np.ptp(points, axis=0).max())
    if extent == 0.0:
        raise InputError("all points coincide; no surface can be reconstructed")
    if extent < MIN_EXTENT:
        raise InputError(
            f"the points span only {extent:.3g}; rescale them to span at least {MIN_EXTENT:g}"
        )
    sample = points[:: max(1, points.shape[0] // 100_000)]
    singular = np.linalg.svd(sample - sample.mean(axis=0), compute_uv=False)
    # Across a line the points spread less than their spacing along it; for exactly
    # collinear points singular[1] is rounding error, about 1e-16 singular[0].
    if singular[1] * points.shape[0] <= singular[0]:
        raise InputError("the points are collinear; no surface can be reconstructed")
