"""The phase-1 pipeline: prepare, estimate parameters, tangent planes, orient, distance, contour."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from . import topology
from ._progress import Stages
from ._validate import as_points, as_viewpoints
from .config import ReconstructionConfig
from .contour import marching_cubes, method_of_cubes
from .density import (
    BRIDGE_LENGTH,
    BRIDGE_REACH,
    BRIDGE_STEP,
    gap_bridges,
    point_radii,
    range_noise,
    sector_distances,
)
from .distance import signed_distance
from .errors import InputError, ReconstructionError, SurfaceWarning
from .jets import evaluate_jets, fit_jets, orient_jets
from .neighbours import knn, restrict, spatial_order
from .normals import tangent_planes
from .optimization import OptimizationResult, optimize_mesh
from .orientation import UNTRUSTED, orient_normals
from .parameters import estimate_parameters
from .prepare import (
    cell_labels,
    crop,
    drop_outliers,
    group_means,
    group_viewpoints,
    reduce_chunks,
)
from .refine import refine_mesh
from .repair import (
    WIDTH_EDGES,
    fill_small_holes,
    remove_small_components,
    split_nonmanifold_vertices,
)
from .rim import no_empty_ball, trim_to_data
from .types import DistanceField, Jets, Mesh, Orientation, Parameters, TangentPlanes

__all__ = ["Reconstruction", "reconstruct"]

STAGES = (
    "prepare",
    "parameters",
    "neighbours",
    "outliers",
    "tangent planes",
    "orientation",
    "local fits",
    "signed distance",
    "contour",
    "rim",
    "refine",
)
#: Stages that run only for the blended-jets surface, and only for rims at the data.
JET_STAGES = ("local fits", "refine")
RIM_STAGES = ("rim",)
OPTIMIZE_STAGE = "optimize"
#: Gap-bridge points, as a share of the fitted points, from which a run warns of them (an
#: evenly sampled sphere, pipe or torus makes 0.8-1 %, a scan with gaps between its lines
#: tens of percent).
BRIDGES_NOTED = 0.02
#: Nearest neighbours found per point: enough to reach across the gap between scan lines.
WIDE_K = 32
#: Widest hole closed, over rho+delta, after contouring and after the rim cut: the signed
#: distance is defined within rho+delta of the data on either side, so the data cannot
#: resolve a narrower one.
HOLE_WIDTH = 2.0
#: Radius of the empty balls that open a hole to its measured points, over the radius of
#: the point each reaches to (rho+delta where the sampling is even): half the longest gap
#: bridge, so no gap the bridges may cross is opened, and no hole wider than a bridge may
#: cross is closed by chords off its centre.
HOLE_BALL = BRIDGE_LENGTH / 2.0
#: Largest coordinate magnitude and smallest extent accepted: squared distances between
#: points then stay far from float64's overflow (1.8e308) and underflow (2.2e-308).
MAX_COORDINATE = 1e100
MIN_EXTENT = 1e-100


@dataclass(frozen=True, eq=False)
class Reconstruction:
    """Everything a reconstruction produced.

    Intermediate arrays (`points`, `planes`, `orientation`, `field`) are in the local frame
    ``original = local + offset``; `mesh` is in the original frame.

    Attributes
    ----------
    mesh : Mesh
        The reconstructed surface, in the input's coordinates.
    offset : (3,) float64
        Origin of the local frame in input coordinates.
    points : (N, 3) float64
        The points the tangent planes were fitted to (after preparation, averaging in
        cells and outlier removal), in the local frame.
    parameters : Parameters
    planes : TangentPlanes
    orientation : Orientation
    jets : Jets or None
        The oriented local fits whose blend is the surface; None for ``surface="planes"``.
    field : DistanceField
    config : ReconstructionConfig
    initial_mesh : Mesh
        Phase 1's mesh, in the input's coordinates (the same as `mesh` without phase 2).
    optimization : OptimizationResult or None
        Phase 2's energies, moves and parameters, when it ran.
    stats : dict
        Counts: points in and removed by each step, components, grid, mesh.
    timings : dict
        Wall-clock seconds per stage.
    """

    mesh: Mesh
    offset: np.ndarray
    points: np.ndarray
    parameters: Parameters
    planes: TangentPlanes
    orientation: Orientation
    jets: Jets | None
    field: DistanceField
    config: ReconstructionConfig
    initial_mesh: Mesh
    optimization: OptimizationResult | None = None
    stats: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    @property
    def normals(self) -> np.ndarray:
        """(N, 3) oriented unit normals of `points`."""
        return self.orientation.normals


def reconstruct(
    points,
    config: ReconstructionConfig | None = None,
    *,
    viewpoints=None,
    optimize: bool = False,
    progress: bool = False,
    **overrides,
) -> Reconstruction:
    """Reconstruct a triangle mesh from a point cloud (Hoppe et al. 1992).

    Parameters
    ----------
    points : (N, 3) array_like of float
    config : ReconstructionConfig, optional
        All parameters; fields may also be given as keywords (``rho_delta=0.02``).
    viewpoints : (N, 3) array_like of float, optional
        Sensor position of every point, a row of NaN where not known; normals are oriented
        towards it (:func:`zeroset.orientation.orient_normals`).
    optimize : bool
        Run phase 2 (:func:`zeroset.optimize`, Hoppe et al. 1993) on phase 1's mesh with
        every point left after cropping, including those that sampling kept from phase 1.
    progress : bool
        Show a progress bar when stderr is a terminal.

    Returns
    -------
    Reconstruction
        The mesh, every intermediate, the parameters chosen, counts and timings.

    Raises
    ------
    InputError
        Bad points or options: non-finite values, too few points, collinear points.
    ReconstructionError
        When the data cannot support a surface with these parameters.

    Examples
    --------
    >>> from zeroset.synthetic import sample_sphere
    >>> result = reconstruct(sample_sphere(3000, rng=0).points)
    >>> len(topology.boundary_loops(result.mesh.faces))
    0
    """
    config = (config or ReconstructionConfig()).with_overrides(**overrides)
    points = as_points(points)
    if viewpoints is not None:
        viewpoints = as_viewpoints(viewpoints, points.shape[0])
        if viewpoints.shape != points.shape:
            raise InputError(f"viewpoints must match points {points.shape}; got {viewpoints.shape}")
    stats: dict = {"input_points": points.shape[0]}
    names = tuple(
        s
        for s in STAGES
        if (config.surface == "jets" or s not in JET_STAGES)
        and (config.rim == "data" or s not in RIM_STAGES)
    )
    stages = Stages(names + ((OPTIMIZE_STAGE,) if optimize else ()), show=progress)
    try:
        with stages.stage("prepare"):
            rows = _prepare(points, config, stats)
            kept = points[rows]
            _check_spread(kept)
            offset = (kept.min(axis=0) + kept.max(axis=0)) / 2.0
            local = kept - offset
            if viewpoints is not None:
                viewpoints = viewpoints[rows] - offset
            elif config.viewpoint is not None:
                viewpoints = np.asarray(config.viewpoint, dtype=np.float64) - offset
        with stages.stage("parameters"):
            parameters = choose_parameters(local, config)
        fitted = fit_planes(local, viewpoints, parameters, config, stats, stages)
        jets = oriented_jets(fitted, fitted.orientation.normals)
        field_, bridges = distance_field(
            local,
            fitted,
            fitted.orientation.normals,
            parameters,
            stats,
            stages,
            config=config,
            jets=jets,
        )
        with stages.stage("contour"):
            if config.contour == "cubes":
                mesh = method_of_cubes(
                    field_, fitted.points, fitted.planes.centroids, fitted.orientation.normals
                )
            else:
                mesh = marching_cubes(field_)
            mesh = repair(mesh, parameters, config, stats)
        if config.rim == "data":
            with stages.stage("rim"):
                mesh = trim_rim(
                    mesh, *data_support(fitted, bridges, parameters), parameters, config, stats
                )
        if jets is not None:
            with stages.stage("refine"):
                mesh, counts = refine_mesh(
                    mesh, jets, noise=parameters.noise, levels=config.refine_levels
                )
                stats.update(counts)
        initial_mesh = Mesh(vertices=mesh.vertices + offset, faces=mesh.faces)
        optimization = None
        if optimize:
            with stages.stage(OPTIMIZE_STAGE):
                if config.crop is not None:  # phase 2 takes every point the crop keeps
                    points = points[crop(points, config.crop[:3], config.crop[3:])]
                optimization = optimize_mesh(
                    mesh,
                    points - offset,
                    c_rep=config.c_rep,
                    kappa=config.kappa,
                    rng=config.seed,
                    progress=progress,
                )
                mesh = optimization.mesh
                stats["phase2_points"] = optimization.stats["points_used"]
                stats["phase2_points_ignored"] = optimization.stats["points_ignored"]
    finally:
        stages.close()
    mesh = Mesh(vertices=mesh.vertices + offset, faces=mesh.faces)
    stats.update(mesh_stats(mesh))
    warn_surface_changes(stats, config)
    return Reconstruction(
        mesh=mesh,
        initial_mesh=initial_mesh,
        optimization=optimization,
        offset=offset,
        points=fitted.points,
        parameters=parameters,
        planes=fitted.planes,
        orientation=fitted.orientation,
        jets=jets,
        field=field_,
        config=config,
        stats=stats,
        timings=dict(stages.timings),
    )


def choose_parameters(local: np.ndarray, config: ReconstructionConfig) -> Parameters:
    """Stage "parameters": `zeroset.parameters.estimate_parameters` with `config`'s knobs."""
    return estimate_parameters(
        local,
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


@dataclass(frozen=True, eq=False)
class FittedPlanes:
    """What phase 1 knows of the points once their tangent planes are oriented.

    Attributes
    ----------
    points : (N, 3) float64
        The points the planes were fitted to (averaged in cells, outliers dropped).
    radii : (N,) float64
        Per-point radius (`zeroset.density.point_radii`).
    sectors : (N, 8) float64
        Nearest distance per direction (`zeroset.density.sector_distances`).
    planes : TangentPlanes
    orientation : Orientation
    jets : Jets or None
        The local fits, not yet oriented; None for ``surface="planes"``.
    """

    points: np.ndarray
    radii: np.ndarray
    sectors: np.ndarray
    planes: TangentPlanes
    orientation: Orientation
    jets: Jets | None = None


def fit_planes(local, viewpoints, parameters, config, stats, stages) -> FittedPlanes:
    """Stages "neighbours" to "local fits" on points in the local frame; counts to `stats`."""
    with stages.stage("neighbours"):
        phase1, cell = local, np.arange(local.shape[0])
        if parameters.averaging_cell > 0.0:
            cell = cell_labels(local, parameters.averaging_cell)
            phase1 = group_means(local, cell)[0]
            if viewpoints is not None and viewpoints.ndim == 2:
                viewpoints = group_viewpoints(local, viewpoints, cell)
        neighbours = knn(phase1, max(config.k_max, WIDE_K))
        noise = parameters.noise
        if viewpoints is not None:
            noise, model = range_noise(phase1, neighbours, viewpoints, noise=noise)
            stats["noise_model"] = {"intercept": model[0], "slope": model[1]}
        sectors, _ = sector_distances(phase1, neighbours.indices, neighbours.distances)
        radii = point_radii(
            sectors,
            neighbours,
            rho_delta=parameters.rho_delta,
            margin=config.noise_factor * noise,
        )
    with stages.stage("outliers"):
        keep = drop_outliers(neighbours, radii, parameters.min_neighbours)
        stats["outliers"] = int(np.count_nonzero(~keep))
        phase1, neighbours = phase1[keep], restrict(neighbours, keep)
        radii, sectors = radii[keep], sectors[keep]
        if viewpoints is not None and viewpoints.ndim == 2:
            viewpoints = viewpoints[keep]
        stats["phase1_points"] = phase1.shape[0]
        stats["widened_radii"] = int(np.count_nonzero(radii > parameters.rho_delta))
        if phase1.shape[0] < config.k_max:
            raise ReconstructionError(
                f"only {phase1.shape[0]} points are left after removing {stats['outliers']} "
                f"outliers (fewer than {parameters.min_neighbours} neighbours within "
                f"rho_delta={parameters.rho_delta:.4g}); increase rho_delta"
            )
    with stages.stage("tangent planes"):
        planes = tangent_planes(
            phase1, radius=radii, k_min=config.k_min, k_max=config.k_max, neighbours=neighbours
        )
    with stages.stage("orientation"):
        orientation = orient_normals(
            planes.centroids,
            planes.normals,
            k=config.orient_k,
            max_edge=2.0 * radii,
            neighbours=neighbours,
            viewpoints=viewpoints,
        )
        stats["orientation_components"] = orientation.n_components
        stats["orientation_turned"] = orientation.turned
        if orientation.disagreement is not None:
            stats["orientation_disagreement"] = orientation.disagreement
            stats["viewpoints_untrusted"] = int(orientation.viewpoints_untrusted)
    jets = None
    if config.surface == "jets":
        with stages.stage("local fits"):
            rows = keep[cell]  # every point of the cells kept, with its cell's plane
            jets = fit_jets(
                local[rows],
                (np.cumsum(keep) - 1)[cell[rows]],
                planes.centroids,
                planes.normals,
                noise=parameters.quadric_noise,
                rho_delta=parameters.rho_delta,
                support=config.fit_support,
                density=(config.radius_k + 1) / (np.pi * parameters.spacing**2),
            )
            stats["jets"] = jets.centres.shape[0]
            stats["fit_support"] = jets.support
            stats["fit_notes"] = "; ".join(jets.notes)
    return FittedPlanes(phase1, radii, sectors, planes, orientation, jets)


def oriented_jets(fitted: FittedPlanes, normals: np.ndarray) -> Jets | None:
    """The jets of `fitted`, each turned like the nearest of the planes turned by `normals`."""
    if fitted.jets is None:
        return None
    return orient_jets(fitted.jets, fitted.planes.centroids, normals)


def distance_field(
    local,
    fitted,
    normals,
    parameters,
    stats,
    stages,
    *,
    config: ReconstructionConfig,
    jets: Jets | None = None,
) -> tuple[DistanceField, np.ndarray]:
    """Stage "signed distance": the field of the planes of `fitted` turned by `normals`,
    valued by the oriented `jets` where they are given, and the gap bridges (B, 3).

    Without ``config.gap_bridges`` there are none. For ``config.rim == "data"`` the field
    reaches one cube further than the points' radii, so that
    the cubes cover the edge of the data wherever the lattice lies; the rim is then cut
    back to that edge (`trim_rim`)."""
    with stages.stage("signed distance"):
        bridges = (
            gap_bridges(
                fitted.points, fitted.sectors, rho_delta=parameters.rho_delta, normals=normals
            )
            if config.gap_bridges
            else np.zeros((0, 3))
        )
        stats["gap_bridge_points"] = bridges.shape[0]
        field_ = signed_distance(
            local,
            fitted.planes.centroids,
            normals,
            cube_size=parameters.cube_size,
            radius=fitted.radii + (parameters.cube_size if config.rim == "data" else 0.0),
            bridges=bridges,
            bridge_reach=BRIDGE_REACH * parameters.rho_delta,
            surface=None if jets is None else (lambda x: evaluate_jets(jets, x)[0]),
        )
        stats["grid_vertices"] = int(field_.values.size)
        stats["undefined_grid_vertices"] = int(np.count_nonzero(np.isnan(field_.values)))
    return field_, bridges


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
    return messages


def warn_surface_changes(stats: dict, config: ReconstructionConfig) -> None:
    """Issue every `surface_changes` message as a `SurfaceWarning` to the caller's caller."""
    for message in surface_changes(stats, config):
        warnings.warn(message, SurfaceWarning, stacklevel=3)


def data_support(fitted: FittedPlanes, bridges: np.ndarray, parameters: Parameters):
    """Where the data are: the points (N + B, 3) of `fitted` and the gap `bridges`, each
    one's radius (N + B,), how far (N + B,) the surface reaches from it, and whether it was
    measured (N + B,), not bridged. The reach is a point's radius, and for a bridge point
    the step between bridge points, so that a chord covers a strip along itself and not
    the middle of a round hole off its end."""
    n_bridges = bridges.shape[0]
    radii = np.r_[fitted.radii, np.full(n_bridges, BRIDGE_REACH * parameters.rho_delta)]
    reach = np.r_[fitted.radii, np.full(n_bridges, BRIDGE_STEP * parameters.rho_delta)]
    measured = np.r_[np.ones(fitted.points.shape[0], bool), np.zeros(n_bridges, bool)]
    return np.concatenate([fitted.points, bridges]), radii, reach, measured


def repair(mesh: Mesh, parameters, config, stats) -> Mesh:
    """Split bow-tie vertices, close small holes, drop tiny components; counts to `stats`."""
    mesh, stats["bowtie_vertices_split"] = split_nonmanifold_vertices(mesh)
    mesh, stats["small_holes_filled"], stats["widest_hole_filled"] = fill_small_holes(
        mesh, config.max_hole_edges, max_width=HOLE_WIDTH * parameters.rho_delta
    )
    mesh, stats["small_components_dropped"] = remove_small_components(
        mesh, config.min_component_faces
    )
    if mesh.n_faces == 0:
        raise ReconstructionError(
            f"no surface: no cube of size {parameters.cube_size:.4g} has eight defined "
            f"corners with a sign change; rho_delta={parameters.rho_delta:.4g} may be "
            "too small for the point spacing"
        )
    return mesh


def trim_rim(mesh: Mesh, points, radii, reach, measured, parameters, config, stats) -> Mesh:
    """Stage "rim": cut the boundaries back to the edge of the data (`data_support`), and
    open every hole wider than the longest gap bridge to its measured points
    (``HOLE_BALL``); a hole the cut opened with room for no such ball is closed again;
    counts to `stats`."""
    mesh, counts = trim_to_data(
        mesh,
        points,
        radii,
        cube_size=parameters.cube_size,
        reach=reach,
        measured=measured,
        hole=HOLE_BALL,
    )
    stats.update(counts)
    # Where the cut's own line pinches two stretches of rim into one vertex, split it.
    mesh, split = split_nonmanifold_vertices(mesh)
    stats["bowtie_vertices_split"] += split
    if config.max_hole_edges > 0:  # gaps with room for no empty ball are no holes
        closable = no_empty_ball(points[measured], HOLE_BALL * radii[measured])
        mesh, filled, widest = fill_small_holes(mesh, WIDTH_EDGES, closable=closable)
        stats["small_holes_filled"] += filled
        stats["widest_hole_filled"] = max(stats["widest_hole_filled"], widest)
    mesh, dropped = remove_small_components(mesh, config.min_component_faces)
    stats["small_components_dropped"] += dropped
    if mesh.n_faces == 0:
        raise ReconstructionError(
            "no surface: the points within reach of every vertex sample a curve or too "
            f"few directions (rho_delta={parameters.rho_delta:.4g})"
        )
    return mesh


def _prepare(points: np.ndarray, config: ReconstructionConfig, stats: dict) -> np.ndarray:
    """Row indices of `points` kept by crop, random and voxel sampling, in spatial order."""
    reduction = reduce_chunks(
        lambda: [{"points": points}],
        crop_box=config.crop,
        sample=config.sample,
        voxel_size=config.voxel_size,
        seed=config.seed,
    )
    stats.update({k: v for k, v in reduction.counts.items() if k != "input_points"})
    rows = reduction.rows
    needed = config.k_max
    if rows.size < needed:
        left = (
            f" of {points.shape[0]} left after cropping and sampling"
            if rows.size < points.shape[0]
            else ""
        )
        raise InputError(
            f"only {rows.size} point{'' if rows.size == 1 else 's'}{left}; "
            f"a neighbourhood needs at least k_max={needed}"
        )
    return rows[spatial_order(points[rows])]


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


def mesh_stats(mesh: Mesh) -> dict:
    """Counts that describe a mesh: vertices, faces, boundary loops, Euler characteristic."""
    return {
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "boundary_loops": len(topology.boundary_loops(mesh.faces)),
        "mesh_components": topology.face_components(mesh.faces, mesh.n_vertices)[0],
        "euler_characteristic": topology.euler_characteristic(mesh),
    }
