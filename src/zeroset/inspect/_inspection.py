"""One call from a pipe's mesh (and scan) to its centreline, deviations, ovality and defects."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .._validate import as_points, as_viewpoints, require_rng
from ..errors import InputError
from ..evaluate import sample_surface
from ..topology import face_area_vectors
from ..types import Mesh
from ._centreline import Pipe, beam_steps, check_stations, fit_pipe
from ._defects import Defects, find_defects, smallest_depth
from ._frame import UP
from ._joints import Joint, find_joints, joint_spans
from ._measure import Ovality, deviation, ovality
from ._unrolled import KERNEL, WallMap, unroll

__all__ = ["Inspection", "inspect_pipe"]

#: Most samples drawn on a mesh inspected without its points.
MAX_SURFACE_SAMPLES = 4_000_000


@dataclass(frozen=True, eq=False)
class Inspection:
    """Everything `inspect_pipe` found.

    Attributes
    ----------
    pipe : Pipe
        Centreline, clock frame and nominal radius.
    ovality : Ovality
        Per station.
    wall : WallMap
        The unrolled wall's smoothed deviations, from the points when given.
    defects : Defects
        Defects and branches.
    vertex_deviation : (V,) float64
        Each mesh vertex's signed deviation from the nominal pipe, metres (NaN beyond the
        centreline's ends).
    point_deviation : (N,) float64 or None
        The same for each scan point, when given.
    joints : tuple of Joint
        Ring features (joints, beads), by axial position.
    timings : dict
        Seconds per stage.
    """

    pipe: Pipe
    ovality: Ovality
    wall: WallMap
    defects: Defects
    vertex_deviation: np.ndarray
    point_deviation: np.ndarray | None
    joints: tuple[Joint, ...] = ()
    timings: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.vertex_deviation.flags.writeable = False
        if self.point_deviation is not None:
            self.point_deviation.flags.writeable = False


def inspect_pipe(
    mesh: Mesh,
    points=None,
    *,
    viewpoints=None,
    nominal_diameter: float | None = None,
    threshold: float | None = None,
    up=UP,
    rng=0,
) -> Inspection:
    """Inspect a pipe: fit its centreline, measure deviation and ovality, find joints and
    defects.

    The stages: `fit_pipe` (the centreline), `ovality` and `deviation`, `unroll` (the
    wall map, with the points' noise about the local wall), `find_joints` (ring
    features), `check_stations` (stretches whose data do not go round the pipe,
    reported in ``pipe.unreliable``) and `find_defects`, which judges neither the joints'
    stretches nor the unreliable ones.

    Parameters
    ----------
    mesh : Mesh
        The pipe's wall, e.g. from `zeroset.reconstruct`.
    points : (N, 3) array_like, optional
        The scan the mesh was made from. With it, cross-sections, the wall map and
        defect depths come from the points, whose errors are independent, so a defect is
        judged against each place's own noise; without it, from the mesh's vertices,
        judged against the mesh's overall roughness.
    viewpoints : (3,) or (N, 3) array_like, optional
        The scanner's position for all `points` or for each (a row of NaN where not
        known), in the order it scanned them. With them the centreline follows the run
        the robot travelled, from where it started (see `fit_pipe`), and a defect's depth
        and a gap's width are fitted along the scanner's beams, where its range noise
        lies, which an oblique beam's noise would otherwise blur.
    nominal_diameter : float, optional
        Metres; default the median measured diameter.
    threshold : float, optional
        Smallest depth reported as a defect, metres; default from the measured noise
        (see `find_defects`).
    up : (3,) array_like
        The world's up, which sets 12 o'clock (see `zeroset.inspect`).
    rng : numpy.random.Generator or int or None
        Chooses the positions the cross-sections are fitted to when there are many, and
        the samples drawn on the mesh without points.

    Returns
    -------
    Inspection
    """
    timings: dict[str, float] = {}
    rng = require_rng(rng)
    start = time.perf_counter()
    samples = None if points is None else as_points(points, "points")
    if viewpoints is not None:
        if samples is None:
            raise InputError("viewpoints go with the points they were scanned from")
        viewpoints = as_viewpoints(viewpoints, samples.shape[0])
    pipe = fit_pipe(
        mesh, samples, viewpoints=viewpoints, nominal_diameter=nominal_diameter, up=up, rng=rng
    )
    timings["centreline"] = time.perf_counter() - start
    start = time.perf_counter()
    wall_samples = samples
    if samples is None:  # the surface, evenly, a few samples per cell of the wall map
        area = 0.5 * float(
            np.linalg.norm(face_area_vectors(mesh.vertices, mesh.faces), axis=1).sum()
        )
        count = int(min(max(area / (0.5 * KERNEL * pipe.radius) ** 2, 1), MAX_SURFACE_SAMPLES))
        wall_samples = sample_surface(mesh, count, rng=rng)[0]
    located = pipe.locate(wall_samples)  # once, for every stage below
    beams = None if viewpoints is None else beam_steps(pipe, samples, viewpoints, located)
    found_ovality = ovality(pipe, wall_samples, located=located)
    vertex_deviation = deviation(pipe, mesh.vertices)
    point_deviation = None if samples is None else located[2] - pipe.radius
    timings["deviation and ovality"] = time.perf_counter() - start
    start = time.perf_counter()
    independent = samples is not None
    wall = unroll(
        pipe,
        found_ovality,
        wall_samples,
        independent=independent,
        located=located,
        beams=beams,
    )
    timings["wall map"] = time.perf_counter() - start
    start = time.perf_counter()
    smallest = smallest_depth(wall, pipe) if threshold is None else float(threshold)
    joints = find_joints(pipe, found_ovality, wall, located, beams, smallest=smallest)
    spans = joint_spans(joints, pipe, wall.kernel)
    pipe = replace(pipe, unreliable=check_stations(pipe, located, excused=spans))
    timings["joints and checks"] = time.perf_counter() - start
    start = time.perf_counter()
    defects = find_defects(
        wall,
        pipe,
        found_ovality,
        wall_samples,
        threshold=threshold,
        located=located,
        beams=beams,
        excluded=spans
        + [
            (u.axial_start - 3 * wall.kernel, u.axial_end + 3 * wall.kernel)
            for u in pipe.unreliable
        ],
    )
    timings["defects"] = time.perf_counter() - start
    return Inspection(
        pipe, found_ovality, wall, defects, vertex_deviation, point_deviation, joints, timings
    )
