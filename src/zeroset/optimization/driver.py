"""Mesh optimisation, phase 2 (Hoppe et al. 1993): fewer triangles, closer to the data."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .. import topology
from .._progress import Stages
from .._unique import distinct
from .._validate import as_points, positive, require_rng
from ..errors import InputError, SurfaceWarning
from ..neighbours import spatial_order
from ..thresholds import SAMPLE_MARGIN
from ..types import Mesh
from ..within import hold_within
from . import schedule
from .energy import Energy, distance_energy, representation_energy, spring_energy
from .fit import Projection, fit_vertices, on_itself, project
from .moves import MOVES, MeshState, MoveOutcome

__all__ = ["OptimizationResult", "optimize_mesh"]


@dataclass(frozen=True, eq=False)
class OptimizationResult:
    """What a mesh optimisation produced.

    Energies are in the normalised frame where the data's bounding-box diagonal is 1, the
    frame in which `c_rep` and `kappa` are given.

    Attributes
    ----------
    mesh : Mesh
        The optimised mesh, in the input's coordinates.
    energy_before, energy : Energy
        The energy of the starting mesh (with the first kappa) and of the result (with the
        last kappa).
    history : list of dict
        One entry per step (``"start"``, ``"fit"`` or ``"moves"``) with its kappa, energy
        terms, vertex and face counts. The total never increases.
    moves : dict
        For each of collapse, split and swap: how many attempts ended in each
        :class:`MoveOutcome`.
    parameters : dict
        ``c_rep``, the ``kappa`` schedule, ``scale`` (the diagonal), the estimated noise
        ``sigma`` and ``max_distance`` (data units), and how each was chosen (``notes``).
    stats : dict
        Points used and left out (farther than `max_distance` from the starting mesh).
    timings : dict
        Seconds per kappa level.
    """

    mesh: Mesh
    energy_before: Energy
    energy: Energy
    history: list = field(default_factory=list)
    moves: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


def optimize_mesh(
    mesh: Mesh,
    points,
    *,
    c_rep: float | None = None,
    kappa: float | None = None,
    max_distance: float | None = None,
    max_fold_degrees: float = schedule.MAX_FOLD_DEGREES,
    tolerance: float | None = None,
    rng=0,
    progress: bool = False,
) -> OptimizationResult:
    """Optimise a mesh against the data: fewer vertices, closer to the points.

    Minimises ``E = sum_i d^2(x_i, mesh) + c_rep #vertices + kappa sum_edges |v_j - v_k|^2``
    over the vertex positions and the connectivity (Hoppe et al. 1993). For each kappa of a
    decreasing schedule: fit the vertex positions (exact projection and a sparse
    least-squares solve, alternated), then try edge collapse, swap and split on every edge
    in random order, each evaluated locally and made when it is legal and lowers E; repeat
    until a pass accepts nothing.

    Parameters
    ----------
    mesh : Mesh
        Starting mesh, edge-manifold (phase 1's output, for instance).
    points : (N, 3) array_like of float
        The data, in the mesh's coordinates; phase 2 may use more points than phase 1.
    c_rep : float, optional
        Cost of a vertex, in the normalised frame (bounding-box diagonal 1). Default: the
        squared noise level times the logarithm of the number of points, whatever the
        starting mesh (see :mod:`zeroset.optimization.schedule`).
    kappa : float, optional
        First spring constant of the schedule, in the same frame; later ones are smaller
        by the factors in ``schedule.KAPPA_STEPS``. Default: 1e-2 times the points per
        starting vertex.
    max_distance : float, optional
        Points farther than this from the starting mesh (data units) are left out as
        outliers. Default: five times the estimated noise level.
    max_fold_degrees : float
        No move may leave two neighbouring faces folded further than this, unless they
        were before it.
    tolerance : float, optional
        Keep the result within this distance (data units) of the starting mesh over each
        triangle's whole area, so that phase 2 keeps phase 1's accuracy in few triangles.
        Phase 1 has averaged the points' noise out, so the mesh is then fitted to the
        starting mesh's own vertices and face centroids instead of the points (which still
        set sigma and c_rep): no move and no fit may take one farther than
        ``SAMPLE_MARGIN`` times the tolerance, the boundary stays where it is, and every
        triangle is checked against the starting mesh as stage "simplify" checks its own
        (:func:`zeroset.within.hold_within`). Default: none, the points are fitted.
    rng : numpy.random.Generator or int or None
        Seed of the random order of the candidate edges.
    progress : bool
        Show a progress bar when stderr is a terminal.

    Returns
    -------
    OptimizationResult

    Raises
    ------
    InputError
        If the mesh has no faces, is not edge-manifold, the points are not (N, 3) and
        finite, or a parameter is not a positive number.

    See Also
    --------
    zeroset.reconstruct : phase 1, and phase 2 with ``optimize=True``.

    Notes
    -----
    Legal moves keep the mesh a manifold with the same boundary: the link condition for a
    collapse, boundary vertices stay on the boundary, boundary edges are never swapped, a
    swap never creates an edge that exists, and no move leaves a degenerate or folded
    face (Hoppe et al. 1993, §4.1; thesis §3.3.7). A move is evaluated with the points on
    the faces it changes, projected onto the new faces, and its new vertex is optimised
    from the edge's midpoint and end points.

    References
    ----------
    H. Hoppe, T. DeRose, T. Duchamp, J. McDonald, W. Stuetzle, "Mesh optimization",
    SIGGRAPH 1993, doi:10.1145/166117.166119.

    Examples
    --------
    >>> from zeroset import reconstruct
    >>> from zeroset.synthetic import sample_sphere
    >>> points = sample_sphere(4000, noise=0.01, rng=0).points
    >>> start = reconstruct(points).mesh
    >>> result = optimize_mesh(start, points)
    >>> result.mesh.n_faces < start.n_faces / 2, result.energy.total < result.energy_before.total
    (True, True)
    """
    vertices, faces = _check_mesh(mesh)
    start_mesh = Mesh(vertices=vertices, faces=faces)
    points = as_points(points, min_rows=4)
    for name, value in (
        ("c_rep", c_rep), ("kappa", kappa), ("max_distance", max_distance),
        ("tolerance", tolerance),
    ):  # fmt: skip
        positive(value, name, allow_none=True)
    if not 0.0 < float(max_fold_degrees) <= 180.0:
        raise InputError(f"max_fold_degrees must lie in (0, 180]; got {max_fold_degrees!r}")
    rng = require_rng(rng)

    # Normalise: centre of the bounding box at the origin, its diagonal 1.
    both = np.concatenate([points, vertices])
    low, high = both.min(axis=0), both.max(axis=0)
    centre, scale = 0.5 * (low + high), float(np.linalg.norm(high - low)) or 1.0
    # Points in spatial order: the moves walk the points of neighbouring faces, which
    # then lie close together in memory.
    x = (points[spatial_order(points)] - centre) / scale
    v = (vertices - centre) / scale

    start = project(x, v, faces, in_order=True)
    distance = np.sqrt(start.distance2)
    edge_length = np.median(np.linalg.norm(v[faces[:, 0]] - v[faces[:, 1]], axis=1))
    sigma = max(1.4826 * float(np.median(distance)), 1e-3 * float(edge_length))
    notes = [f"sigma = {sigma * scale:.6g}: 1.4826 x median distance of the points to the start"]
    if max_distance is None:
        cutoff = schedule.MAX_DISTANCE_SIGMAS * sigma
        notes.append(
            f"max_distance = {cutoff * scale:.6g}: {schedule.MAX_DISTANCE_SIGMAS:g} x sigma"
        )
    else:
        cutoff = max_distance / scale
    keep = distance <= cutoff
    x = np.ascontiguousarray(x[keep])
    if x.shape[0] < 4:
        raise InputError(
            f"only {x.shape[0]} points lie within max_distance={cutoff * scale:.4g} of the mesh"
        )
    projection = start.take(keep)
    n_data, limits = x.shape[0], None
    if tolerance is not None:
        # Phase 1 has averaged the points' noise out: fit its surface, the starting mesh's
        # vertices and face centroids, each held within the margin of the tolerance.
        x, projection = _samples(v, faces)
        limits = np.full(x.shape[0], SAMPLE_MARGIN * tolerance / scale)
        notes.append(
            f"tolerance = {tolerance:.6g}: fitted to {x.shape[0]} samples of the starting mesh "
            f"(its vertices and face centroids), each held within {SAMPLE_MARGIN:g} x it"
        )
    per_vertex = x.shape[0] / vertices.shape[0]
    if c_rep is None:
        c_rep = schedule.C_REP_FACTOR * sigma**2 * np.log(n_data)
        notes.append(
            f"c_rep = {c_rep:.6g}: {schedule.C_REP_FACTOR:g} x sigma^2 x ln {n_data} points "
            "(normalised)"
        )
    if kappa is None:
        kappa = schedule.KAPPA_START * per_vertex
        notes.append(
            f"kappa = {kappa:.6g}: {schedule.KAPPA_START:g} x {per_vertex:.3g} points per "
            "starting vertex (normalised)"
        )
    kappas = tuple(float(kappa) * step for step in schedule.KAPPA_STEPS)

    history: list[dict] = []
    tally = np.zeros((3, 4), dtype=np.int64)
    energy_before = _energy(v, faces, projection, kappas[0], c_rep)
    history.append(_entry("start", kappas[0], energy_before, v, faces))
    names = tuple(f"kappa {k:.3g}" for k in kappas)
    stages = Stages(names, show=progress)
    try:
        for name, level in zip(names, kappas, strict=True):
            with stages.stage(name):
                v, faces, projection = _optimise_level(
                    x,
                    limits,
                    v,
                    faces,
                    projection,
                    level,
                    c_rep,
                    max_fold_degrees,
                    sigma,
                    rng,
                    tally,
                    history,
                )
    finally:
        stages.close()

    result_mesh = Mesh(vertices=v * scale + centre, faces=faces)
    held = {}
    if tolerance is not None:
        result_mesh, splits, strays = hold_within(result_mesh, start_mesh, tolerance)
        held = {
            "tolerance": float(tolerance),
            "tolerance_splits": splits,
            "tolerance_strays": strays,
        }
        if strays:
            warnings.warn(
                f"{strays} triangle(s) of phase 2 lie farther than the tolerance "
                f"{tolerance:.4g} from the starting mesh after every check round",
                SurfaceWarning,
                stacklevel=2,
            )
    moves = {
        kind: {outcome.name.lower(): int(tally[row, outcome]) for outcome in MoveOutcome}
        for row, kind in enumerate(MOVES)
    }
    return OptimizationResult(
        mesh=result_mesh,
        energy_before=energy_before,
        energy=_energy(v, faces, projection, kappas[-1], c_rep),
        history=history,
        moves=moves,
        parameters={
            "c_rep": float(c_rep),
            "kappa": list(kappas),
            "scale": scale,
            "sigma": sigma * scale,
            "max_distance": cutoff * scale,
            "notes": notes,
        },
        stats={
            "points_used": n_data,
            "points_ignored": int(np.count_nonzero(~keep)),
            "vertices_before": int(vertices.shape[0]),
            "faces_before": int(mesh.n_faces),
            "vertices": result_mesh.n_vertices,
            "faces": result_mesh.n_faces,
            **held,
        },
        timings=dict(stages.timings),
    )


def _optimise_level(
    x, limits, v, faces, projection, kappa, c_rep, max_fold, sigma, rng, tally, history
):  # fmt: skip
    """Fit, then passes of moves each followed by a fit, until a pass accepts nothing.
    `limits` (N,) or None as for `fit_vertices`; with limits, the boundary stays.

    The first pass tries every edge; a later one the edges of the vertices that the fit
    before it moved by more than ``schedule.MOVED_SIGMAS`` x sigma (the others would be
    evaluated as they were).
    """
    min_cos = float(np.cos(np.radians(max_fold)))
    still = schedule.MOVED_SIGMAS * sigma  # a smaller step is no change to the passes
    hold = limits is not None  # with a tolerance, the boundary stays the starting mesh's
    v, projection, _ = fit_vertices(
        x, v, faces, _edges(faces), kappa=kappa, projection=projection, min_cos=min_cos,
        in_order=True, limits=limits, fixed=_boundary_vertices(faces, v) if hold else None,
        settled=still,
    )  # fmt: skip
    history.append(_entry("fit", kappa, _energy(v, faces, projection, kappa, c_rep), v, faces))
    candidates = None
    for _ in range(schedule.MAX_PASSES):
        state = MeshState(
            v, faces, x, projection, kappa=kappa, c_rep=c_rep, max_fold_degrees=max_fold,
            limits=limits, hold_boundary=hold,
        )  # fmt: skip
        _, counts = state.run_pass(rng, 20 * 3 * faces.shape[0] + 1000, candidates)
        tally += counts
        moved = state.to_mesh()
        v, faces = moved.vertices, moved.faces
        projection = project(x, v, faces, guess=state.point_faces, in_order=True)
        history.append(
            _entry("moves", kappa, _energy(v, faces, projection, kappa, c_rep), v, faces)
        )
        edges = _edges(faces)
        fitted, projection, _ = fit_vertices(
            x, v, faces, edges, kappa=kappa, projection=projection, min_cos=min_cos,
            in_order=True, limits=limits, fixed=_boundary_vertices(faces, v) if hold else None,
            settled=still,
        )  # fmt: skip
        moved = np.linalg.norm(fitted - v, axis=1) > still
        v = fitted
        history.append(_entry("fit", kappa, _energy(v, faces, projection, kappa, c_rep), v, faces))
        candidates = edges[moved[edges].any(axis=1)]
        if counts[:, MoveOutcome.ACCEPTED].sum() == 0 or candidates.shape[0] == 0:
            break
    return v, faces, projection


def _boundary_vertices(faces: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(M,) bool: the boundary vertices of the mesh (v, faces)."""
    fixed = np.zeros(v.shape[0], dtype=bool)
    fixed[topology.boundary_edges(faces).reshape(-1)] = True
    return fixed


def _edges(faces: np.ndarray) -> np.ndarray:
    """The (E, 2) undirected edges of `faces`, each once."""
    return topology.edge_face_counts(faces)[0]


def _energy(v, faces, projection, kappa, c_rep) -> Energy:
    return Energy(
        distance=distance_energy(projection.distance2),
        representation=representation_energy(distinct(faces).size, c_rep),
        spring=spring_energy(v, _edges(faces), kappa),
    )


def _entry(step: str, kappa: float, energy: Energy, v, faces) -> dict:
    return {
        "step": step,
        "kappa": kappa,
        **energy.as_dict(),
        "vertices": int(distinct(faces).size),
        "faces": int(faces.shape[0]),
    }


def _samples(v: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, Projection]:
    """The vertices and face centroids of the mesh (v, faces) (`on_itself`) in spatial
    order, and their projection onto it."""
    samples, itself = on_itself(v, faces)
    order = spatial_order(samples)
    return np.ascontiguousarray(samples[order]), itself.take(order)


def _check_mesh(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's used vertices and reindexed faces; refuse what the moves cannot handle."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be a zeroset.Mesh; got {type(mesh).__name__}")
    if mesh.n_faces == 0:
        raise InputError("mesh has no faces; phase 2 needs a starting mesh")
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if not topology.is_edge_manifold(faces):
        raise InputError("mesh is not edge-manifold (an edge has more than two faces)")
    if not topology.is_consistently_oriented(faces):
        raise InputError("mesh faces are not consistently oriented")
    used, faces = np.unique(faces, return_inverse=True)
    return np.ascontiguousarray(mesh.vertices[used], dtype=np.float64), faces.reshape(-1, 3)
