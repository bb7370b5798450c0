"""Phase 1 on one machine: `reconstruct` runs the stages of `zeroset.stages` in order."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._progress import Stages
from ._validate import as_points, as_viewpoints
from .config import ReconstructionConfig
from .errors import InputError
from .optimization import OptimizationResult
from .stages import (
    OPTIMIZE_STAGE,
    choose_parameters,
    contour,
    data_support,
    distance_field,
    finish,
    fit,
    fit_stats,
    mesh_stats,
    optimize_surface,
    prepare_points,
    simplify,
    stage_names,
    warn_surface_changes,
)
from .stats import declared
from .surface import Surface
from .types import DistanceField, Mesh, Orientation, Parameters, TangentPlanes

__all__ = ["Reconstruction", "reconstruct"]


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
    surface : Surface
        The oriented local surface whose zero set was contoured (`zeroset.surface`; the
        blended `zeroset.jets.Jets` by default), in the local frame.
    field : DistanceField
    config : ReconstructionConfig
    initial_mesh : Mesh
        Phase 1's mesh, in the input's coordinates (the same as `mesh` without phase 2).
    dense_mesh : Mesh
        Phase 1's mesh before stage "simplify" (`zeroset.simplify`), in the input's
        coordinates: its vertices on the surface, its triangles as small as the surface's
        curvature needs (the same as `initial_mesh` with ``tolerance=0``).
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
    surface: Surface
    field: DistanceField
    config: ReconstructionConfig
    initial_mesh: Mesh
    dense_mesh: Mesh
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
        Run phase 2 (:func:`zeroset.optimize`, Hoppe et al. 1993) on phase 1's dense mesh
        with every point left after cropping, including those that sampling kept from
        phase 1; phase 2 then chooses the triangles, and stage "simplify" does not run.
        A ``tolerance`` in the config keeps phase 2's triangles within it of the dense
        mesh (:func:`zeroset.optimize`'s `tolerance`).
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
    >>> from zeroset.topology import boundary_loops
    >>> result = reconstruct(sample_sphere(3000, rng=0).points)
    >>> len(boundary_loops(result.mesh.faces))
    0
    """
    config = (config or ReconstructionConfig()).with_overrides(**overrides)
    points, viewpoints = _checked(points, viewpoints)
    optimization = None
    with Stages(stage_names(config, optimize), show=progress) as stages:
        cloud = stages.run("prepare", prepare_points, points, viewpoints, config)
        parameters = stages.run("parameters", choose_parameters, cloud.local, config, cloud.tree)
        fitted = fit(cloud, parameters, config, stages)
        normals = fitted.orientation.normals
        field_, bridges, surface = stages.run(
            "signed distance", distance_field, cloud, fitted, normals, parameters, config
        )
        mesh = stages.run("contour", contour, field_, fitted, normals, parameters, config)
        support = data_support(fitted, bridges, parameters)
        dense = finish(mesh, support, surface, parameters, config, stages)
        first = dense
        if surface.smooth and not optimize:
            first = stages.run("simplify", simplify, dense, surface, parameters, config)
        if optimize:
            optimization = stages.run(
                OPTIMIZE_STAGE, optimize_surface, dense, points, cloud.offset, config, progress
            )
    initial_mesh = first.translated(cloud.offset)
    mesh = initial_mesh if optimization is None else optimization.mesh.translated(cloud.offset)
    stats = {"input_points": points.shape[0], **stages.counts}
    stats.update(fit_stats(fitted) | surface.describe() | mesh_stats(mesh))
    warn_surface_changes(stats, config)
    return Reconstruction(
        mesh=mesh,
        initial_mesh=initial_mesh,
        dense_mesh=initial_mesh if first is dense else dense.translated(cloud.offset),
        optimization=optimization,
        offset=cloud.offset,
        points=fitted.points,
        parameters=parameters,
        planes=fitted.planes,
        orientation=fitted.orientation,
        surface=surface,
        field=field_,
        config=config,
        stats=declared(stats),
        timings=dict(stages.timings),
    )


def _checked(points, viewpoints) -> tuple[np.ndarray, np.ndarray | None]:
    """The points (N, 3) and their sensor positions (N, 3) or None, validated."""
    points = as_points(points)
    if viewpoints is not None:
        viewpoints = as_viewpoints(viewpoints, points.shape[0])
        if viewpoints.shape != points.shape:
            raise InputError(f"viewpoints must match points {points.shape}; got {viewpoints.shape}")
    return points, viewpoints
