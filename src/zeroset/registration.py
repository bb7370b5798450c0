"""Rigid registration of overlapping scans: refine their poses by ICP before merging them.

Several scans of one object, each in its own frame, are placed in a common world frame by
rough poses (from a turntable, a tracker or a manual pick). Before the scans are merged and
reconstructed, `register_scans` refines those poses: each scan but the reference is aligned
to the union of the others by small_gicp's plane-to-plane ICP (GICP), in a few rounds with
a shrinking correspondence distance, using only the points that face the other scans.
How well the scans fit together before and after is measured here, on the full-resolution
points, as the RMS distance of each scan's points from the tangent planes of the others.
"""

from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import numpy as np

from ._extras import require
from ._kernels.normals import centroid_covariance
from ._progress import Stages
from ._rigid import transform
from ._validate import as_points, as_poses, positive
from .errors import InputError
from .neighbours import build_tree
from .types import Frozen

__all__ = ["Registration", "register_scans"]

#: The final correspondence distance, over the median nearest-neighbour spacing.
FINE_SPACINGS = 4.0
#: The first correspondence distance, over the diagonal of the scans' bounding box.
COARSE_DIAGONAL = 0.05
#: Refinement rounds; in each, every scan but the fixed one is aligned once.
ROUNDS = 4
#: Voxel size of the clouds given to small_gicp, over the median spacing.
VOXEL_SPACINGS = 2.0
#: Neighbours (the point included) whose covariance gives a point's normal.
NORMAL_K = 10
#: Points per scan sampled to measure the spacing, the residuals and the overlap.
SAMPLE = 20_000
#: Fewest points a scan may have.
MIN_POINTS = 10
#: Farthest a point may lie across the normal of its nearest target point and still
#: take part in an alignment, over the voxel size.
EDGE_VOXELS = 2.0
#: small_gicp's registration: GICP with plane-like covariances (see `register_scans`).
METHOD = "GICP"
#: ICP iterations per alignment, and its stopping steps: radians, and data units over the
#: final correspondence distance.
MAX_ITERATIONS = 50
ROTATION_EPSILON = 1e-5
TRANSLATION_EPSILON = 1e-4
#: small_gicp keys voxels by 21-bit integers per axis; coordinates stay within half that.
_VOXEL_RANGE = 2.0**19
_SEED = 0


@dataclass(frozen=True, eq=False)
class Registration(Frozen):
    """Refined poses of S scans and how well the scans fit together before and after.

    A pose maps a scan's own coordinates to the world: ``p_world = R @ p + t`` with
    ``R = poses[s, :3, :3]`` and ``t = poses[s, :3, 3]``.

    Attributes
    ----------
    poses : (S, 4, 4) float64
        Refined poses; the fixed scan keeps the one it was given.
    residual_before : (S,) float64
        RMS distance, in data units, of each scan's overlapping points from the tangent
        planes of the other scans, at the given poses; NaN where no point overlaps.
    residual_after : (S,) float64
        The same at the refined poses.
    overlap_before : (S,) float64
        Share of each scan's (sampled) points within `max_distance` of another scan, at the
        given poses.
    overlap_after : (S,) float64
        The same at the refined poses.
    max_distance : float
        The final correspondence distance, in data units; points farther than this from
        every other scan do not overlap.
    rounds : int
        Rounds of alignment run.
    """

    poses: np.ndarray
    residual_before: np.ndarray
    residual_after: np.ndarray
    overlap_before: np.ndarray
    overlap_after: np.ndarray
    max_distance: float
    rounds: int


def register_scans(
    scans,
    poses,
    *,
    names=None,
    fixed: int = 0,
    max_distance: float | None = None,
    min_overlap: float = 0.05,
    rounds: int = ROUNDS,
    threads: int = 1,
    progress: bool = False,
) -> Registration:
    """Refine the rigid poses of overlapping scans by ICP.

    Scan `fixed` keeps its pose and defines the world frame. In the first round the other
    scans join it one at a time, each aligned to the scans placed before it, the one that
    overlaps them most first; in each later round every other scan in turn is aligned to
    the union of all the others at their current poses. The correspondence distance
    shrinks geometrically from round to round, from a coarse one that catches the error of
    the given poses to `max_distance`.

    Parameters
    ----------
    scans : sequence of S >= 2 (N_s, 3) array_like of float
        The points of each scan in its own frame; at least 10 per scan.
    poses : (S, 4, 4) array_like of float
        Initial pose of each scan: a rotation and a translation mapping its frame to the
        world (the last row is ``0 0 0 1``).
    names : sequence of S str, optional
        Names of the scans (such as their files) used in messages; default
        ``"scan 0"``, ``"scan 1"``, ...
    fixed : int
        The scan whose pose is kept.
    max_distance : float, optional
        Final correspondence distance in data units: points farther than this from the
        other scans are left out of the last round, the residuals and the overlap.
        Default: ``FINE_SPACINGS`` (4) times the median distance from a point to its
        nearest neighbour in its own scan, over up to ``SAMPLE`` seeded points per scan.
    min_overlap : float
        Least share of each scan's points that must lie within the coarse correspondence
        distance of the other scans at the given poses.
    rounds : int
        Rounds of alignment; with one round only `max_distance` is used.
    threads : int
        Threads small_gicp uses. With more than one, its sums run in a varying order, and
        the poses vary from run to run in the last digits (about 1e-11 of the size of the
        data); with one, the same input gives the same poses bit for bit.
    progress : bool
        Show a progress bar over the alignments when stderr is a terminal.

    Returns
    -------
    Registration
        ``poses`` (S, 4, 4), ``residual_before`` / ``residual_after`` (S,),
        ``overlap_before`` / ``overlap_after`` (S,), ``max_distance`` and ``rounds``.

    Raises
    ------
    InputError
        Fewer than two scans, a scan with fewer than 10 points or non-finite values, poses
        of the wrong shape or not rigid, bad options, a scan that does not overlap the
        others at its given pose, or scans that overlap only each other and not the fixed
        one.

    See Also
    --------
    zeroset.prepare.crop : cut the scans to the object before registering them.
    zeroset.reconstruct : reconstruct the merged, registered points.

    Notes
    -----
    The coarse correspondence distance is ``COARSE_DIAGONAL`` (5 %) of the diagonal of the
    bounding box of all scans at the given poses, never less than `max_distance`: on a
    1 m object it is about 7 cm, enough for poses off by 2 degrees and 2 cm. Round ``r``
    (from 0) of ``R`` uses ``coarse * (max_distance / coarse) ** (r / (R - 1))``.

    small_gicp receives each scan voxel-averaged (voxels of ``VOXEL_SPACINGS`` times the
    median spacing, larger where needed to keep the coordinates within its 21-bit voxel
    keys), in a frame centred on the data, and averaged on one thread (its parallel
    averaging is not deterministic). Before each alignment the scan is cut to the points
    that face the target: the nearest target point lies within the round's distance and
    the offset to it runs along that point's normal, less than ``EDGE_VOXELS`` voxels
    across it. A point beyond the edge of the target's surface is offset across the
    normal, and such pairs pull the scan towards the edge (Turk and Levoy 1994 drop them
    for the same reason); without the cut, a 7 cm distance turned a 2 degree error into
    5 to 8 degrees.

    The alignment is small_gicp's GICP (Segal et al. 2009): a plane-to-plane ICP whose
    covariances, from the ``NORMAL_K`` nearest points, are flattened to eigenvalues
    (1e-3, 1, 1), so offsets along the normals weigh about a thousand times more than
    offsets along the surface. small_gicp's ``PLANE_ICP`` is not used: it multiplies
    normal and offset component by component (``n * (q - T p)``, a 3-vector) rather than
    taking their dot product, so offsets along the surface count too, and it pulled
    correctly placed scans 0.3 degrees off at a 3 cm distance.

    The residuals are measured on up to ``SAMPLE`` seeded points of each scan at full
    resolution: a point's nearest point among the other scans gives the tangent plane
    (the centroid and least-variance axis of that point's ``NORMAL_K`` nearest neighbours
    in its own scan, Hoppe et al. 1992, §3.2); only points within `max_distance` count.

    References
    ----------
    Y. Chen and G. Medioni, "Object modelling by registration of multiple range images",
    Image and Vision Computing 10(3), 1992.
    G. Turk and M. Levoy, "Zippered polygon meshes from range images", SIGGRAPH 1994.
    A. Segal, D. Haehnel and S. Thrun, "Generalized-ICP", Robotics: Science and Systems
    2009.
    K. Koide, "small_gicp: Efficient and parallel algorithms for point cloud registration",
    Journal of Open Source Software 9(100), 2024.

    Examples
    --------
    >>> import numpy as np
    >>> from zeroset.synthetic import sample_torus
    >>> points = sample_torus(4000, rng=0).points
    >>> halves = [points[points[:, 0] < 0.1], points[points[:, 0] > -0.1]]
    >>> result = register_scans(halves, np.stack([np.eye(4)] * 2))
    >>> result.poses.shape
    (2, 4, 4)
    """
    scans, names = _check_scans(scans, names)
    n_scans = len(scans)
    if np.ndim(poses) == 3 and len(poses) != n_scans:
        raise InputError(f"{len(poses)} poses for {n_scans} scans; give one per scan")
    poses = as_poses(poses, names)
    fixed = _check_index(fixed, n_scans)
    max_distance = positive(max_distance, "max_distance", allow_none=True)
    min_overlap = _check_share(min_overlap)
    rounds = positive(rounds, "rounds", integer=True)
    threads = positive(threads, "threads", integer=True)

    rng = np.random.default_rng(_SEED)
    samples = [_sample_rows(scan.shape[0], rng) for scan in scans]
    trees = [build_tree(scan) for scan in scans]
    spacing = _median_spacing(scans, trees, samples)
    fine = FINE_SPACINGS * spacing if max_distance is None else max_distance
    world = [transform(pose, scan) for pose, scan in zip(poses, scans, strict=True)]
    low = np.min([w.min(axis=0) for w in world], axis=0)
    high = np.max([w.max(axis=0) for w in world], axis=0)
    coarse = max(fine, COARSE_DIAGONAL * float(np.linalg.norm(high - low)))
    schedule = _schedule(coarse, fine, rounds)

    fit = [_nearest_other(scans, trees, samples, poses, i, coarse) for i in range(n_scans)]
    for i, (distance, _, _, _, _) in enumerate(fit):
        share = float(np.mean(distance <= coarse))
        if share < min_overlap:
            raise InputError(
                f"{names[i]} does not overlap the other scans: {100 * share:.1f} % of its "
                f"points lie within {coarse:.3g} of them (need {100 * min_overlap:g} %); "
                "check its pose"
            )
    order = _chain_order(np.array([f[4] for f in fit]), fixed, names, min_overlap, coarse)
    residual_before, overlap_before = _fit_quality(scans, trees, fit, fine)

    centre = 0.5 * (low + high)
    voxel = max(VOXEL_SPACINGS * spacing, float(np.max(high - low)) / _VOXEL_RANGE)
    corrections = _align_rounds(
        [w - centre for w in world],
        names,
        fixed,
        order,
        schedule,
        voxel=voxel,
        threads=threads,
        progress=progress,
    )
    refined = poses.copy()
    for i, correction in enumerate(corrections):
        if i != fixed:
            refined[i] = _compose_about(correction, poses[i], centre)

    fit = [_nearest_other(scans, trees, samples, refined, i, fine) for i in range(n_scans)]
    residual_after, overlap_after = _fit_quality(scans, trees, fit, fine)
    return Registration(
        poses=refined,
        residual_before=residual_before,
        residual_after=residual_after,
        overlap_before=overlap_before,
        overlap_after=overlap_after,
        max_distance=float(fine),
        rounds=rounds,
    )


def _check_scans(scans, names) -> tuple[list[np.ndarray], list[str]]:
    """Return the scans as (N_s, 3) float64 arrays and their names."""
    if isinstance(scans, np.ndarray) and scans.ndim == 2:
        raise InputError("scans must be a sequence of (N, 3) arrays, one per scan; got one array")
    try:
        n_scans = len(scans)
    except TypeError as exc:
        raise TypeError(
            f"scans must be a sequence of (N, 3) arrays; got {type(scans).__name__}"
        ) from exc
    if n_scans < 2:
        raise InputError(f"registration needs at least 2 scans; got {n_scans}")
    if names is None:
        names = [f"scan {i}" for i in range(n_scans)]
    else:
        names = [str(name) for name in names]
        if len(names) != n_scans:
            raise InputError(f"names must name each of the {n_scans} scans; got {len(names)}")
    arrays = [
        as_points(scan, name, min_rows=MIN_POINTS) for scan, name in zip(scans, names, strict=True)
    ]
    return arrays, names


def _check_index(fixed, n_scans: int) -> int:
    """Return `fixed` if it indexes one of `n_scans` scans."""
    if (
        isinstance(fixed, bool)
        or not isinstance(fixed, numbers.Integral)
        or not 0 <= fixed < n_scans
    ):
        raise InputError(f"fixed must be a scan index in [0, {n_scans}); got {fixed!r}")
    return int(fixed)


def _check_share(value) -> float:
    """Return `value` if it is a share in [0, 1]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not 0 <= value <= 1:
        raise InputError(f"min_overlap must be a share in [0, 1]; got {value!r}")
    return float(value)


def _sample_rows(n_rows: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted rows (M,) of at most SAMPLE points out of `n_rows`."""
    if n_rows <= SAMPLE:
        return np.arange(n_rows)
    return np.sort(rng.choice(n_rows, SAMPLE, replace=False))


def _median_spacing(scans, trees, samples) -> float:
    """Median distance from a sampled point to its nearest neighbour in its own scan."""
    gaps = [
        tree.query(scan[rows], k=2)[0][:, 1]
        for scan, tree, rows in zip(scans, trees, samples, strict=True)
    ]
    spacing = float(np.median(np.concatenate(gaps)))
    if not spacing > 0.0:
        raise InputError("the scans' points coincide: the median nearest-neighbour spacing is 0")
    return spacing


def _schedule(coarse: float, fine: float, rounds: int) -> np.ndarray:
    """Correspondence distance (rounds,) of each round, geometric from `coarse` to `fine`."""
    if rounds == 1:
        return np.array([fine])
    return coarse * (fine / coarse) ** (np.arange(rounds) / (rounds - 1))


def _compose_about(correction: np.ndarray, pose: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Pose (4, 4) of a scan moved by `correction`, a rigid motion of the frame at `centre`."""
    shift = np.eye(4)
    shift[:3, 3] = -centre
    composed = correction @ shift @ pose
    composed[:3, 3] += centre
    composed[3] = [0.0, 0.0, 0.0, 1.0]
    return composed


def _nearest_other(scans, trees, samples, poses, i: int, bound: float):
    """Nearest point among the other scans of each sampled point of scan `i`.

    Returns
    -------
    distance : (M,) float64
        Distance to it; inf where none lies within `bound`.
    scan : (M,) int64
        The scan it belongs to (-1 for none).
    row : (M,) int64
        Its row in that scan.
    query : (M, 3) float64
        The sampled point in that scan's frame.
    share : (S,) float64
        Share of the sampled points within `bound` of each scan (0 for scan `i`).
    """
    world = transform(poses[i], scans[i][samples[i]])
    distance = np.full(world.shape[0], np.inf)
    scan = np.full(world.shape[0], -1, dtype=np.int64)
    row = np.full(world.shape[0], -1, dtype=np.int64)
    query = np.zeros_like(world)
    share = np.zeros(len(scans))
    for j, tree in enumerate(trees):
        if j == i:
            continue
        rotation, translation = poses[j][:3, :3], poses[j][:3, 3]
        local = (world - translation) @ rotation
        d, k = tree.query(local, k=1, distance_upper_bound=bound)
        share[j] = np.mean(d <= bound)
        closer = d < distance
        distance[closer] = d[closer]
        scan[closer] = j
        row[closer] = k[closer]
        query[closer] = local[closer]
    return distance, scan, row, query, share


def _chain_order(share: np.ndarray, fixed: int, names, min_overlap: float, distance: float):
    """Scans (S - 1,) in the order they join the fixed one, each overlapping one before it.

    `share[i, j]` is the share of scan i's points near scan j. The next scan is the one
    with the largest share, either way, with a scan already placed.
    """
    mutual = np.maximum(share, share.T)
    placed = [fixed]
    left = [i for i in range(share.shape[0]) if i != fixed]
    while left:
        best = mutual[np.ix_(left, placed)].max(axis=1)
        if best.max() < min_overlap:
            missing = ", ".join(names[i] for i in left)
            raise InputError(
                f"{missing} do not overlap {names[fixed]} or the scans that overlap it: at "
                f"most {100 * best.max():.1f} % of points lie within {distance:.3g} of them "
                f"(need {100 * min_overlap:g} %); check their poses"
            )
        placed.append(left.pop(int(np.argmax(best))))
    return placed[1:]


def _fit_quality(scans, trees, fit, bound: float) -> tuple[np.ndarray, np.ndarray]:
    """RMS tangent-plane distance (S,) and overlap share (S,) of each scan within `bound`."""
    residual = np.full(len(scans), np.nan)
    overlap = np.zeros(len(scans))
    for i, (distance, scan, row, query, _) in enumerate(fit):
        near = distance <= bound
        overlap[i] = np.mean(near)
        if not near.any():
            continue
        squares = np.zeros(int(near.sum()))
        for j in np.unique(scan[near]):
            pick = scan[near] == j
            rows = row[near][pick]
            centroid, normal = _tangent_planes(scans[j], trees[j], rows)
            offset = np.einsum("ij,ij->i", query[near][pick] - centroid, normal)
            squares[pick] = offset**2
        residual[i] = np.sqrt(np.mean(squares))
    return residual, overlap


def _tangent_planes(points, tree, rows) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (M, 3) and unit normal (M, 3) of the NORMAL_K nearest points of each row."""
    distances, neighbours = tree.query(points[rows], k=min(NORMAL_K, points.shape[0]))
    centroid, covariance, _ = centroid_covariance(
        points, neighbours.astype(np.int64), distances, np.full(len(rows), np.inf)
    )
    return centroid, np.linalg.eigh(covariance)[1][:, :, 0]


def _align_rounds(
    clouds, names, fixed: int, order, schedule, *, voxel: float, threads: int, progress: bool
) -> list[np.ndarray]:
    """Corrections (4, 4) of every cloud, aligning each in turn to the others (small_gicp).

    `clouds` are the scans at their given poses in a frame centred on the data; cloud `i`
    at its refined place is ``corrections[i]`` applied to ``clouds[i]``. In the first
    round each scan in `order` is aligned to the fixed scan and those before it; in the
    later rounds, to all the others.
    """
    small_gicp = require("small_gicp", "registering scans")

    points = [
        small_gicp.voxelgrid_sampling(cloud, voxel, num_threads=1).points()[:, :3]
        for cloud in clouds
    ]
    corrections = [np.eye(4) for _ in clouds]
    steps = [(r, position) for r in range(len(schedule)) for position in range(len(order))]
    labels = tuple(f"register {r + 1}/{len(schedule)}" for r, _ in steps)
    with Stages(labels, show=progress) as stages:
        for round_, position in steps:
            i = order[position]
            if round_ == 0:
                others = [fixed, *order[:position]]
            else:
                others = [j for j in range(len(clouds)) if j != i]
            with stages.stage(f"register {round_ + 1}/{len(schedule)}"):
                corrections[i] = _align_one(
                    points[i],
                    np.concatenate([transform(corrections[j], points[j]) for j in others]),
                    corrections[i],
                    float(schedule[round_]),
                    name=f"{names[i]} in round {round_ + 1}",
                    reach=EDGE_VOXELS * voxel,
                    tolerance=TRANSLATION_EPSILON * float(schedule[-1]),
                    threads=threads,
                )
    return corrections


def _align_one(source_points, target_points, start, distance, *, name, reach, tolerance, threads):
    """Correction (4, 4) aligning `source_points` (N, 3) to `target_points` (M, 3) by GICP.

    `start` is the current correction; the one returned replaces it (and is `start` itself
    when too few points face the target, with a warning naming the scan as `name`).
    """
    small_gicp = require("small_gicp", "registering scans")

    target = small_gicp.PointCloud(target_points)
    target_tree = small_gicp.KdTree(target, num_threads=threads)
    small_gicp.estimate_normals_covariances(
        target, target_tree, num_neighbors=NORMAL_K, num_threads=threads
    )
    rows = _overlapping(
        transform(start, source_points),
        target,
        target_tree,
        distance=distance,
        reach=reach,
        threads=threads,
    )
    if min(rows.size, target.size()) <= MIN_POINTS:
        # small_gicp needs more than 10 points on either side.
        warnings.warn(
            f"{name} was not moved: only {rows.size} of its points face the "
            f"{target.size()} points of the other scans within {distance:.3g}",
            stacklevel=4,
        )
        return start
    source = small_gicp.PointCloud(source_points[rows])
    small_gicp.estimate_covariances(
        source,
        small_gicp.KdTree(source, num_threads=threads),
        num_neighbors=NORMAL_K,
        num_threads=threads,
    )
    result = small_gicp.align(
        target,
        source,
        target_tree,
        init_T_target_source=start,
        registration_type=METHOD,
        max_correspondence_distance=distance,
        num_threads=threads,
        max_iterations=MAX_ITERATIONS,
        rotation_epsilon=ROTATION_EPSILON,
        translation_epsilon=tolerance,
    )
    moved = np.asarray(result.T_target_source, dtype=np.float64)
    return moved if np.isfinite(moved).all() else start


def _overlapping(points, target, tree, *, distance: float, reach: float, threads: int):
    """Rows (M,) of `points` that face the small_gicp cloud `target` within `distance`.

    A point faces the target where its nearest target point lies within `distance` and
    the offset to it runs along that point's normal, not more than `reach` across it: a
    point beyond the edge of the target's surface is offset across the normal, and would
    pull the scan towards the edge (Turk and Levoy 1994 drop such pairs).
    """
    nearest, squared = tree.batch_nearest_neighbor_search(points, num_threads=threads)
    nearest = np.asarray(nearest, dtype=np.int64)
    near = np.flatnonzero((nearest >= 0) & (np.asarray(squared) <= distance**2))
    offset = points[near] - target.points()[nearest[near], :3]
    normal = target.normals()[nearest[near], :3]
    across = offset - np.einsum("ij,ij->i", offset, normal)[:, None] * normal
    return near[np.einsum("ij,ij->i", across, across) <= reach**2]
