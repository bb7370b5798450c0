"""Phase 1 in tiles on Dask: one global lattice, halos, orientation agreed, seams welded.

The cloud's contouring lattice is cut into boxes of whole cubes. Each tile reads its own
points (its box and a halo around it, straight from the file), fits and orients its tangent
planes, and contours only the cubes it owns. Tiles agree on the sign of their normals where
their halos overlap, and the pieces are welded by the global keys of the lattice edges
their vertices lie on: two tiles compute the vertex of a shared edge from the same corner
values, so the welded mesh has no seam. The few-triangle simplification runs a tile at a
time too, then once more across the seams (`_simplify_in_tiles`).
"""

from __future__ import annotations

import logging
import math
import os
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import partial
from operator import itemgetter

import numpy as np

from ._extras import require
from ._lattice import LIMIT
from ._progress import Stages, peak_mib
from ._unique import distinct
from ._validate import as_points
from .config import ReconstructionConfig
from .contour import keyed_marching_cubes
from .errors import InputError, ReconstructionError, SurfaceWarning
from .evaluate import closest_points_on_mesh
from .neighbours import build_tree, query_workers, spatial_order
from .orientation import agree_parts, part_extremes
from .parameters import neighbours_read
from .prepare import CHUNK_POINTS
from .prepare import crop as inside
from .refine import Refined, refine_traced
from .simplify import simplify_mesh
from .stages import (
    DataSupport,
    FittedPlanes,
    LocalCloud,
    choose_parameters,
    data_support,
    distance_field,
    finish,
    fit,
    local_viewpoints,
    mesh_stats,
    simplify,
    warn_surface_changes,
)
from .stats import add_counts, declared
from .surface import Surface, surface_kind
from .thresholds import RADIUS_CAP
from .tile_output import cut, face_tiles, point_tiles, weld
from .topology import boundary_edges, is_consistently_oriented, is_edge_manifold
from .types import Mesh, Parameters

__all__ = [
    "TiledReconstruction",
    "dask_client",
    "parse_tiles",
    "plan_tiles",
    "reconstruct_tiled",
]

#: Halo planned around a tile's box: radii, bridges and the nearest planes of its border
#: cubes lie within this many rho_delta (and HALO_CUBES cubes) of the box, with the LEVELS
#: of neighbourhoods allowed for.
HALO_RADII = 8.0
HALO_CUBES = 2
#: Neighbourhoods of a count of points lie three deep under a cube's value: a plane's
#: SMOOTH_K nearest (its radius, its neighbours), theirs (whether they are outliers), and
#: the WIDE_K nearest of those (their sectors). The halo allows each to reach RADIUS_CAP
#: rho_delta, as far as a radius may; every tile measures them (`Density.extent`) and
#: reads a wider halo, up to GROW_ROUNDS times, where they reach further.
LEVELS = (0, 0, 1)
GROW_ROUNDS = 3
#: Points per tile that ``tiles="auto"`` aims at; and the fewest it cuts a tile to so that
#: every thread of the cluster gets one (below, a tile's halo, a few per cent of its points
#: on each side at these sizes, grows into a share that the extra threads do not repay).
AUTO_TILE_POINTS = 2_000_000
AUTO_LEAST_POINTS = 500_000
#: Clouds of at most this many points (inside the crop) get their parameters from all of
#: them in one task, as `zeroset.reconstruct` chooses them, so that the tiled mesh is the
#: untiled one; a larger cloud from the SAMPLES points it measures them at and every point
#: within reach of those, read in chunks (`_estimate_sampled`).
WHOLE_CLOUD_POINTS = 5_000_000
#: Points of a larger cloud at which the parameters are measured (as `zeroset.reconstruct`
#: measures them at a random 20,000), the share of them whose neighbourhoods must lie
#: wholly within the points read, and the most passes over the file that reach for them.
SAMPLES = 20_000
WHOLE_NEIGHBOURHOODS = 0.995
READ_ROUNDS = 6
#: Fewest points a tile must hold to be reconstructed; emptier tiles hold no surface.
MIN_TILE_POINTS = 32
#: Largest distance, over the cube size, between two tiles' copies of a shared vertex
#: that a run takes for rounding (both come from the same corner values).
SEAM_TOLERANCE = 1e-9
#: Least factor a tile's halo grows by when its neighbourhoods reach beyond it.
GROWTH = 1.5
#: Rings of faces around a tile's own that it refines with them (`_refine_in_tiles`): a
#: vertex's projection is held back by its faces turning over, theirs by their neighbours'.
REFINE_RINGS = 3


@dataclass(frozen=True)
class Tile:
    """One box of the lattice and what a task needs to reconstruct it.

    Attributes
    ----------
    index : (3,) tuple of int
        Position in the grid of tiles.
    owned : ((3,), (3,)) tuple of int64 arrays
        Lattice indices ``[lo, hi)`` of the lower corners of the cubes it contours.
    box : (6,) float64
        ``xmin, ymin, zmin, xmax, ymax, zmax`` of its points, halo included, in input
        coordinates.
    halo : float
        Width of the halo, in data units.
    """

    index: tuple[int, int, int]
    owned: tuple[np.ndarray, np.ndarray]
    box: np.ndarray
    halo: float

    def grown(self, halo: float) -> Tile:
        """The same tile with a halo of `halo`."""
        wider = halo - self.halo
        return replace(self, box=np.r_[self.box[:3] - wider, self.box[3:] + wider], halo=halo)


@dataclass(frozen=True, eq=False)
class TileFit:
    """A tile's points and oriented planes (`_fit_tile`'s result, kept on its worker)."""

    tile: Tile
    cloud: LocalCloud
    fitted: FittedPlanes
    counts: dict


@dataclass(frozen=True, eq=False)
class TileFailure:
    """A tile whose fit failed, and why."""

    tile: Tile
    reason: str


@dataclass(frozen=True, eq=False)
class Seam:
    """What a tile tells the others of its orientation (`_seam`).

    Attributes
    ----------
    keys : (S,) void
        Its points within the seam band, by their exact coordinates (`_point_keys`).
    normals : (S, 3) float64
        Their oriented normals.
    component : (S,) int64
        Their orientation components.
    extremes : (C, 6, 2) float64
        `zeroset.orientation.part_extremes` of its components, from the points it owns.
    by_sensors : bool
        Whether the sensors set its signs.
    """

    keys: np.ndarray
    normals: np.ndarray
    component: np.ndarray
    extremes: np.ndarray
    by_sensors: bool


@dataclass(frozen=True, eq=False)
class Piece:
    """A tile's part of the mesh (`_contour_tile`), in the local frame.

    Attributes
    ----------
    edge_keys : (V,) int64
        Global key of the lattice edge each vertex lies on.
    vertices : (V, 3) float64
    faces : (F, 3) int64
    cube_keys : (F,) int64
        Global key of the cube of each face.
    support : DataSupport
        The data support of the points in its cubes.
    surface : Surface or None
        The oriented local fits centred in its cubes; None for a tile with no surface.
    counts : dict
        Its stages' counts.
    peak_mib : float or None
        Its worker's peak resident memory, None where the platform does not say.
    worker : str
        Its worker's address.
    """

    edge_keys: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    cube_keys: np.ndarray
    support: DataSupport
    surface: Surface | None
    counts: dict
    peak_mib: float | None
    worker: str

    @staticmethod
    def empty(peak_mib: float | None, worker: str) -> Piece:
        """The piece of a tile with no surface."""
        return Piece(
            edge_keys=np.zeros(0, dtype=np.int64),
            vertices=np.zeros((0, 3)),
            faces=np.zeros((0, 3), dtype=np.int64),
            cube_keys=np.zeros(0, dtype=np.int64),
            support=DataSupport(
                points=np.zeros((0, 3)),
                radii=np.zeros(0),
                reach=np.zeros(0),
                measured=np.zeros(0, bool),
                planes=np.zeros((0, 3)),
            ),
            surface=None,
            counts={},
            peak_mib=peak_mib,
            worker=worker,
        )


@dataclass(frozen=True, eq=False)
class TiledReconstruction:
    """The welded mesh of a tiled reconstruction, with what was chosen, counted and spent.

    Attributes
    ----------
    mesh : Mesh
        In the input's coordinates.
    offset : (3,) float64
        Origin of the local frame the tiles worked in (the lattice's origin).
    parameters : Parameters
    config : ReconstructionConfig
    tiles : list of Tile
    stats : dict
        Counts summed over the tiles (halo points counted by every tile that reads them);
        ``tiles`` and ``tile_grid`` (tiles per axis); ``tiles_failed`` (left out, with
        `allow_gaps`); ``tiles_grown`` (whose halo was widened for neighbourhoods that
        reach further); ``seam_vertex_gap`` (the largest distance between two tiles'
        copies of a shared vertex); ``orientation_components`` (groups of
        tiles' components joined at seams), ``tile_components_flipped`` and
        ``seam_disagreement`` (the share of seam points held by two tiles whose normals
        still point apart, None without seams); ``worker_peak_mib`` (peak resident memory of each
        worker process, by address); the welded mesh's counts.
    timings : dict
        Wall-clock seconds of each pass ("bounds", "parameters", "fit", "contour", "weld"),
        then of each stage run on the welded mesh: "repair" and "rim" in the client;
        "refine" and "simplify", tasks a tile at a time, the client's cutting and welding,
        and the band across the seams.
    waits : dict
        Of "refine" and "simplify", the seconds spent waiting for their tasks on the
        workers; the rest of each is the client's own work.
    """

    mesh: Mesh
    offset: np.ndarray
    parameters: Parameters
    config: ReconstructionConfig
    tiles: list
    stats: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    waits: dict = field(default_factory=dict)


def plan_tiles(
    low, high, offset, parameters: Parameters, counts, *, halo_radii: float = HALO_RADII
) -> list[Tile]:
    """Cut the lattice over the box ``[low, high]`` into ``counts`` (3,) tiles per axis.

    The lattice is the reconstruction's: cubes of ``parameters.cube_size`` from `offset`.
    Every cube belongs to exactly one tile; the outermost tiles own everything beyond.
    Each tile reads `halo_radii` rho_delta and ``HALO_CUBES`` cubes around its cubes.
    """
    cube = parameters.cube_size
    first = np.floor((np.asarray(low) - offset) / cube).astype(np.int64)
    last = np.floor((np.asarray(high) - offset) / cube).astype(np.int64) + 1
    halo = halo_radii * parameters.rho_delta + HALO_CUBES * cube
    cuts = [
        np.linspace(first[a], last[a], int(counts[a]) + 1).round().astype(np.int64)
        for a in range(3)
    ]
    tiles = []
    for index in np.ndindex(*(int(c) for c in counts)):
        lo = np.array([cuts[a][index[a]] for a in range(3)])
        hi = np.array([cuts[a][index[a] + 1] for a in range(3)])
        lo = np.where(np.array(index) == 0, -LIMIT, lo)
        hi = np.where(np.array(index) == np.asarray(counts) - 1, LIMIT, hi)
        box_lo = offset + cube * np.maximum(lo, first) - halo
        box_hi = offset + cube * np.minimum(hi, last) + halo
        tiles.append(
            Tile(
                index=tuple(int(i) for i in index),
                owned=(lo, hi),
                box=np.r_[box_lo, box_hi],
                halo=halo,
            )
        )
    return tiles


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None):
    """A Dask client of the scheduler at address `scheduler`, or of a local cluster of
    `workers` single-threaded processes (one per core by default), closed on exit.

    Each local worker's compiled kernels and k-d tree queries share its part of the cores
    (``NUMBA_NUM_THREADS``, `zeroset.neighbours.query_workers`): the cores over the workers,
    at least one, so that the workers' threads add up to the cores rather than each asking
    for all of them. Workers of another scheduler take ``NUMBA_NUM_THREADS`` from their own
    environment."""
    distributed = require("distributed", "tiled reconstruction (--tiles)")
    import dask

    if scheduler is not None:
        with distributed.Client(scheduler) as client:
            yield client
        return
    cores = os.cpu_count() or 1
    share = max(1, cores // (workers or cores))
    # Set before each worker process starts: Numba reads it once, on import.
    spawn = {"distributed.nanny.pre-spawn-environ.NUMBA_NUM_THREADS": str(share)}
    with (
        dask.config.set(spawn),
        distributed.LocalCluster(
            n_workers=workers,
            processes=True,
            threads_per_worker=1,
            dashboard_address=":0",
            silence_logs=logging.CRITICAL,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


def reconstruct_tiled(
    source,
    config: ReconstructionConfig | None = None,
    *,
    tiles="auto",
    client=None,
    parameters: Parameters | None = None,
    progress: bool = False,
    allow_gaps: bool = False,
    **overrides,
) -> TiledReconstruction:
    """Phase 1 (`zeroset.reconstruct`) in tiles run as Dask tasks, welded into one mesh.

    Parameters
    ----------
    source : str or os.PathLike or (N, 3) array_like of float
        A point file (each task reads its own tile from it, LAS, LAZ and binary PLY a chunk
        at a time) or the points themselves.
    config : ReconstructionConfig, optional
        As for `zeroset.reconstruct`; ``sample`` and ``voxel_size`` are not supported here,
        and only marching cubes contours tiles.
    tiles : "auto", "NxMxK" or (3,) ints
        Tiles per axis; "auto" aims at ``AUTO_TILE_POINTS`` per tile, and at a tile for
        every thread of the cluster where each still holds ``AUTO_LEAST_POINTS``, cutting
        the longest axes first.
    client : distributed.Client, optional
        Where the tasks run; a local cluster of one worker process per core by default.
    parameters : Parameters, optional
        Use these instead of estimating them. By default a cloud of at most
        ``WHOLE_CLOUD_POINTS`` gets those `zeroset.reconstruct` chooses, from all its
        points, and the tiled mesh is the untiled one (same vertices and faces); a larger
        one gets them measured the same way at points drawn in one pass over its chunks
        (`_estimate_sampled`).
    progress : bool
        Show a progress bar over the tiles when stderr is a terminal.
    allow_gaps : bool
        When a tile's fit fails, leave its part of the mesh out with a `SurfaceWarning`
        naming it, instead of raising.

    Returns
    -------
    TiledReconstruction

    Raises
    ------
    ReconstructionError
        If a tile's fit fails (the message names the tile) and not `allow_gaps`, or the
        welded mesh is not edge-manifold and consistently oriented.
    """
    config = (config or ReconstructionConfig()).with_overrides(**overrides)
    if config.sample is not None or config.voxel_size is not None:
        raise InputError("--sample and --voxel are not supported with tiles; use --crop")
    if config.contour != "marching":
        raise InputError("tiles are contoured by marching cubes only; drop --contour cubes")
    if client is None:
        with dask_client() as local:
            return reconstruct_tiled(
                source,
                config,
                tiles=tiles,
                client=local,
                parameters=parameters,
                progress=progress,
                allow_gaps=allow_gaps,
            )
    if not isinstance(source, (str, bytes)) and not hasattr(source, "__fspath__"):
        source = as_points(source)
    timings: dict = {}
    start = time.perf_counter()
    low, high, n_points = client.submit(_bounds, source, config.crop, pure=False).result()
    if n_points < config.k_max:
        raise InputError(
            f"only {n_points} points; a neighbourhood needs at least k_max={config.k_max}"
        )
    offset = (low + high) / 2.0
    threads = sum(w["nthreads"] for w in client.scheduler_info()["workers"].values())
    counts = _counts(tiles, low, high, n_points, threads)
    timings["bounds"] = time.perf_counter() - start
    drawn = np.zeros((0, 3))
    if parameters is None:
        start = time.perf_counter()
        estimate = _estimate_whole if n_points <= WHOLE_CLOUD_POINTS else _estimate_sampled
        task = client.submit(estimate, source, n_points, offset, config, pure=False)
        parameters, drawn = task.result()
        timings["parameters"] = time.perf_counter() - start
    # A local surface may reach further than the planes (zeroset.surface.Surface.reach).
    reach = max(HALO_RADII, surface_kind(config.surface).reach)
    plan = plan_tiles(low, high, offset, parameters, counts, halo_radii=reach)

    start = time.perf_counter()
    # The tiles' work grows with their points, told by the points drawn: each to a worker
    # by the LPT rule, each worker's largest first (a tile's contouring and refinement
    # follow on its worker). Another worker may take one whose worker is gone.
    drawn_in = np.bincount(
        point_tiles(drawn, plan, np.zeros(3), parameters.cube_size), None, len(plan)
    )
    where = _balanced(client, drawn_in.tolist())
    fits = [
        client.submit(_fit_tile, source, tile, offset, parameters, config,
                      workers=[worker], allow_other_workers=True, priority=int(most),
                      pure=False)
        for tile, most, worker in zip(plan, drawn_in, where, strict=True)
    ]  # fmt: skip
    seams = _gather(
        client,
        [client.submit(_seam, fit, parameters, pure=False) for fit in fits],
        "orienting",
        progress,
    )
    failed = [
        f"tile {seam.tile.index} of {'x'.join(map(str, counts))}: {seam.reason}"
        for seam in seams
        if isinstance(seam, TileFailure)
    ]
    if failed and not allow_gaps:
        raise ReconstructionError(
            f"{'; '.join(failed)}; allow_gaps=True (--allow-gaps) keeps the other tiles"
        )
    for message in failed:
        warnings.warn(f"left out, a gap in the mesh: {message}", SurfaceWarning, stacklevel=2)
    flips, disagreement, groups = _agree(seams)
    timings["fit"] = time.perf_counter() - start

    start = time.perf_counter()
    contoured = [
        client.submit(_contour_tile, fit, flip, parameters, config, pure=False)
        for fit, flip in zip(fits, flips, strict=True)
    ]
    # The pieces come to the client; each tile's surface stays on its worker, to refine on.
    pieces = [client.submit(itemgetter(0), tile, pure=False) for tile in contoured]
    pieces = _gather(client, pieces, "contouring", progress)
    del fits
    timings["contour"] = time.perf_counter() - start

    start = time.perf_counter()
    stats = {"input_points": n_points, "tiles": len(plan), "tiles_failed": len(failed)}
    for piece in pieces:
        add_counts(stats, piece.counts)
    stats["orientation_components"] = groups
    stats["seam_disagreement"] = disagreement
    stats["tile_grid"] = [int(c) for c in counts]
    stats["tile_components_flipped"] = sum(len(flip) for flip in flips)
    mesh, stats["seam_vertex_gap"] = weld_pieces(pieces)
    _warn_gap(stats["seam_vertex_gap"], parameters, "a neighbourhood reached beyond their halos")
    if not (is_edge_manifold(mesh.faces) and is_consistently_oriented(mesh.faces)):
        raise ReconstructionError(
            "the tiles' meshes welded into a mesh that is not edge-manifold and consistently "
            "oriented: their seams disagree; run without tiles, or with fewer"
        )
    timings["weld"] = time.perf_counter() - start
    surface = _owned_surface(pieces)
    stages = Stages((), show=False)
    support = DataSupport.concatenate([piece.support for piece in pieces])
    cube = parameters.cube_size
    waits: dict = {}
    in_tiles = partial(_refine_in_tiles, client, plan, contoured, cube, progress, waits)
    mesh = finish(mesh, support, surface, parameters, config, stages, refine_how=in_tiles)
    del contoured
    gap = stages.counts.pop("seam_vertex_gap", 0.0)
    _warn_gap(
        gap,
        parameters,
        f"the {REFINE_RINGS} rings of faces refined around a tile's own held too few",
    )
    stats["seam_vertex_gap"] = max(stats["seam_vertex_gap"], gap)
    if surface.smooth:
        in_tiles = partial(_simplify_in_tiles, client, plan, cube, progress, waits)
        mesh = stages.run("simplify", simplify, mesh, surface, parameters, config, how=in_tiles)
    timings.update(stages.timings)
    add_counts(stats, stages.counts)
    mesh = mesh.translated(offset)
    stats.update(surface.describe() | mesh_stats(mesh))
    warn_surface_changes(stats, config)
    peaks: dict = {}
    for piece in pieces:
        if piece.peak_mib is not None:  # None where the platform does not say
            peaks[piece.worker] = max(peaks.get(piece.worker, 0.0), piece.peak_mib)
    stats["worker_peak_mib"] = peaks
    return TiledReconstruction(
        mesh=mesh,
        offset=offset,
        parameters=parameters,
        config=config,
        tiles=plan,
        stats=declared(stats),
        timings=timings,
        waits=waits,
    )


def _warn_gap(gap: float, parameters: Parameters, why: str) -> None:
    """A `SurfaceWarning` where two tiles put a shared vertex `gap` apart, more than
    rounding (``SEAM_TOLERANCE`` cubes) explains; `why` says what held too little."""
    if gap > SEAM_TOLERANCE * parameters.cube_size:
        warnings.warn(
            f"two tiles put a shared vertex {gap:.3g} apart, the first one's kept: {why}, "
            "and the mesh differs from the untiled one there; use fewer tiles",
            SurfaceWarning,
            stacklevel=3,
        )


def _refine_in_tiles(
    client, plan, contoured, cube_size: float, progress: bool, waits: dict, mesh: Mesh,
    surface, *, noise: float, levels: int | None,
) -> tuple[Mesh, dict]:  # fmt: skip
    """`zeroset.refine.refine_mesh` of `mesh` (local frame) a tile at a time: each tile's
    faces (`zeroset.tile_output.face_tiles`) with ``REFINE_RINGS`` rings of faces around
    them, refined by a task on the tile's own surface (`contoured`, its futures), which
    keeps the faces within its own (`_refine_part`). The pieces weld by the keys of their
    vertices (`zeroset.refine.refine_traced`: the index in `mesh`, a midpoint's from its
    edge's ends). `surface` (the tiles' own fits, gathered) is not needed.

    Returns the mesh and the counts, with ``seam_vertex_gap``: the largest distance between
    two tiles' copies of one vertex (0 where the rings held all that moved it); the wait
    for the tasks goes into `waits` as "refine"."""
    owner = face_tiles(mesh, plan, np.zeros(3), cube_size)
    futures, faces = [], []
    for k, part in enumerate(_with_rings(mesh.faces, owner, len(plan), REFINE_RINGS)):
        if part is None:
            continue
        faces.append(np.flatnonzero(part))  # of `mesh`, in the part's order
        ((piece, used),) = cut(mesh, np.where(part, 0, -1), 1)
        # On the worker that holds the tile's surface, which is larger than its part.
        workers = list(client.who_has([contoured[k]])[contoured[k].key])
        [scattered] = client.scatter([(piece, used, owner[part] == k)], workers=workers)
        futures.append(
            client.submit(_refine_part, scattered, contoured[k], noise, levels, pure=False)
        )
    start = time.perf_counter()
    done = _gather(client, futures, "refining", progress)
    waits["refine"] = time.perf_counter() - start
    welded, index = weld([part.mesh for part in done], [part.keys for part in done])
    keys = np.empty(welded.n_vertices, dtype=np.int64)
    keys[index] = np.concatenate([part.keys for part in done])
    held = np.empty(welded.n_vertices, dtype=np.int64)
    held[index] = np.concatenate([part.held for part in done])
    parent = np.concatenate([ids[part.parent] for ids, part in zip(faces, done, strict=True)])
    rounds = max(part.rounds for part in done)
    refined = Refined(mesh=welded, keys=keys, parent=parent, held=held, rounds=rounds)
    copies = np.concatenate([part.mesh.vertices for part in done])
    gap = np.linalg.norm(copies - welded.vertices[index], axis=1).max(initial=0.0)
    return welded, refined.counts | {"seam_vertex_gap": float(gap)}


def _refine_part(part, contoured, noise: float, levels: int | None):
    """A tile's faces and the rings around them refined on its surface (a Dask task):
    `part` is (Mesh, the index (V,) in the whole mesh of each vertex, (F,) bool the tile's
    own faces), `contoured` `_contour_tile`'s result. Returns the `zeroset.refine.Refined`
    of its own faces only."""
    piece, used, own = part
    refined = refine_traced(piece, contoured[1], noise=noise, levels=levels, keys=used)
    mine = own[refined.parent]
    ((mesh, kept),) = cut(refined.mesh, np.where(mine, 0, -1), 1)
    return replace(
        refined,
        mesh=mesh,
        keys=refined.keys[kept],
        parent=refined.parent[mine],
        held=refined.held[kept],
    )


def _with_rings(faces: np.ndarray, owner: np.ndarray, n_tiles: int, rings: int) -> list:
    """For each tile k < `n_tiles`, (F,) bool its faces (`owner` (F,) == k) and the faces
    within `rings` rings of them, or None where it owns none. The faces of other tiles
    within reach lie within `rings` rings of a seam vertex (one of two tiles' faces), so
    the rings grow within that band only."""
    n_vertices = int(faces.max(initial=-1)) + 1
    low = np.full(n_vertices, n_tiles)
    high = np.full(n_vertices, -1)
    np.minimum.at(low, faces.ravel(), np.repeat(owner, 3))
    np.maximum.at(high, faces.ravel(), np.repeat(owner, 3))
    band = np.flatnonzero(face_rings(faces, low != high, rings))
    parts = []
    for k in range(n_tiles):
        own = owner == k
        if not own.any():
            parts.append(None)
            continue
        reached = np.zeros(n_vertices, dtype=bool)
        reached[faces[own]] = True
        near = np.zeros(band.size, dtype=bool)
        for _ in range(rings):
            near = reached[faces[band]].any(axis=1)
            reached[faces[band[near]]] = True
        own[band[near]] = True
        parts.append(own)
    return parts


def _simplify_in_tiles(
    client,
    plan: list[Tile],
    cube_size: float,
    progress: bool,
    waits: dict,
    dense: Mesh,
    tolerance: float,
) -> tuple[Mesh, dict]:
    """`zeroset.simplify.simplify_mesh` of the welded `dense` mesh (local frame) a tile at
    a time, then across the seams.

    Each tile's faces (`zeroset.tile_output.face_tiles`) are simplified by a task of their
    own, their boundary kept vertex for vertex, so the pieces weld where they met
    (`_simplify_piece`). Along the seams the pieces then hold the dense mesh's vertices;
    the band of the welded mesh around them (the faces within two rings of a seam vertex)
    is simplified again, against the dense faces beneath it (those whose centroids lie
    closest to one of its faces), its own boundary kept. Returns the mesh and the counts;
    the wait for the tasks goes into `waits` as "simplify".
    """
    if tolerance == 0.0:  # the dense mesh as it is, in its order
        return simplify_mesh(dense, tolerance)
    owner = face_tiles(dense, plan, np.zeros(3), cube_size)
    pieces = cut(dense, owner, len(plan))
    kept = [k for k, (piece, _) in enumerate(pieces) if piece is not None]
    # Its work grows with a piece's faces: the largest first, each to the least loaded.
    where = _balanced(client, [pieces[k][0].n_faces for k in kept])
    futures = [
        client.submit(_simplify_piece, client.scatter(pieces[k][0], workers=[worker]),
                      pieces[k][1], tolerance, workers=[worker], pure=False)
        for k, worker in zip(kept, where, strict=True)
    ]  # fmt: skip
    start = time.perf_counter()
    done = _gather(client, futures, "simplifying", progress)
    waits["simplify"] = time.perf_counter() - start
    counts: dict = {}
    for _, _, _, piece_counts in done:
        add_counts(counts, piece_counts)
    welded, index = weld([simple for simple, *_ in done], [keys for _, keys, *_ in done])
    # The welded face under each dense face: its piece's faces follow the earlier pieces'.
    starts = np.cumsum([0] + [simple.n_faces for simple, *_ in done])
    under = np.empty(dense.n_faces, dtype=np.int64)
    for k, (_, _, below, _), start in zip(kept, done, starts[:-1], strict=True):
        under[owner == k] = start + below
    # Seam vertices: those of two pieces or more.
    seam = np.bincount(index, minlength=welded.n_vertices) > 1
    if not seam.any():
        return welded, counts
    band = face_rings(welded.faces, seam, 2)
    reach = face_rings(welded.faces, seam, 3)  # one ring more: the reference goes on past it
    beneath = reach[under]
    ((reference, _),) = cut(dense, np.where(beneath, 0, -1), 1)
    (strip, strip_vertices), (rest, rest_vertices) = cut(welded, np.where(band, 0, 1), 2)
    simple, strip_counts = simplify_mesh(
        strip, tolerance, reference=reference, under=band[under[beneath]]
    )
    add_counts(counts, strip_counts)
    parts = [(simple, _boundary_keys(strip, strip_vertices, simple))]
    if rest is not None:
        parts.insert(0, (rest, rest_vertices))
    mesh, _ = weld(*zip(*parts, strict=True))
    if not (is_edge_manifold(mesh.faces) and is_consistently_oriented(mesh.faces)):
        raise ReconstructionError(
            "the tiles' simplified meshes welded into a mesh that is not edge-manifold and "
            "consistently oriented; run with --tolerance 0, or without tiles"
        )
    return mesh, counts


def _balanced(client, work: list) -> list[str]:
    """The address of the worker for each task of `work` (its cost, any unit): the
    costliest first, each to the worker with the least work so far (the LPT rule)."""
    workers = sorted(client.scheduler_info()["workers"])
    load = {worker: [0, 0] for worker in workers}  # work, then tasks, so ties alternate
    where = [""] * len(work)
    for task in np.argsort(work, kind="stable")[::-1]:
        where[task] = min(workers, key=load.__getitem__)
        load[where[task]][0] += work[task]
        load[where[task]][1] += 1
    return where


def _simplify_piece(piece: Mesh, used: np.ndarray, tolerance: float):
    """A tile's piece of the dense mesh simplified (a Dask task; `simplify_mesh` keeps its
    boundary vertices where they are): the mesh; the dense mesh's index (`used` (V,) of
    each vertex of `piece`) of each of its boundary vertices, -1 for every other vertex;
    the face of the mesh closest to each face's centroid of `piece`; and the counts."""
    simple, counts = simplify_mesh(piece, tolerance)
    below = closest_points_on_mesh(piece.vertices[piece.faces].mean(axis=1), simple)[1]
    return simple, _boundary_keys(piece, used, simple), below, counts


def _boundary_keys(mesh: Mesh, keys: np.ndarray, simple: Mesh) -> np.ndarray:
    """(V',) for each vertex of `simple`, the key (`keys` (V,)) of the boundary vertex of
    `mesh` at the same place, -1 where none is."""
    where = {mesh.vertices[v].tobytes(): keys[v] for v in distinct(boundary_edges(mesh.faces))}
    return np.array([where.get(v.tobytes(), -1) for v in simple.vertices], dtype=np.int64)


def face_rings(faces: np.ndarray, marked: np.ndarray, rings: int) -> np.ndarray:
    """(F,) bool the faces within `rings` rings of the `marked` (V,) bool vertices: the
    faces with a marked vertex, then those with a vertex of those, and so on."""
    vertices = marked.copy()
    near = np.zeros(faces.shape[0], dtype=bool)
    for _ in range(rings):
        near = vertices[faces].any(axis=1)
        vertices[faces[near]] = True
    return near


def parse_tiles(tiles) -> str | np.ndarray:
    """``"auto"``, or the tiles per axis (3,) int64 of ``"NxMxK"`` or three counts."""
    if isinstance(tiles, str) and tiles == "auto":
        return tiles
    if isinstance(tiles, str):
        tiles = tiles.lower().split("x")
    try:
        counts = np.array([int(count) for count in tiles], dtype=np.int64)
    except (TypeError, ValueError):
        counts = np.zeros(0, dtype=np.int64)
    if counts.shape != (3,) or (counts < 1).any():
        raise InputError(f"tiles must be auto or three positive counts NxMxK; got {tiles!r}")
    return counts


def _counts(tiles, low, high, n_points: int, threads: int = 1) -> np.ndarray:
    """Tiles per axis (3,): as given, or for "auto" enough for ``AUTO_TILE_POINTS`` each,
    and one for each of the cluster's `threads` where each still holds
    ``AUTO_LEAST_POINTS``; the longest axes cut first."""
    tiles = parse_tiles(tiles)
    if not isinstance(tiles, str):
        return tiles
    wanted = max(
        1, math.ceil(n_points / AUTO_TILE_POINTS), min(threads, n_points // AUTO_LEAST_POINTS)
    )
    counts = np.ones(3, dtype=np.int64)
    extent = np.maximum(np.asarray(high) - np.asarray(low), 1e-300)
    while counts.prod() < wanted:
        counts[np.argmax(extent / counts)] += 1
    return counts


def _read(source, box, crop=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (N, 3) inside `box` (6,) and `crop` (6,), and their sensor positions, from a
    file or an array."""
    if crop is not None:
        box = np.r_[np.maximum(box[:3], crop[:3]), np.minimum(box[3:], crop[3:])]
        if np.any(box[:3] > box[3:]):
            return np.zeros((0, 3)), None
    if isinstance(source, np.ndarray):
        return source[inside(source, box[:3], box[3:])], None
    from . import io

    cloud = io.read_points(source, crop=box, allow_empty=True)
    return cloud.points, cloud.viewpoints


def _bounds(source, crop) -> tuple[np.ndarray, np.ndarray, int]:
    """Bounding box (3,), (3,) and count of the points (inside `crop`), read in chunks."""
    crop = None if crop is None else np.asarray(crop, dtype=np.float64)
    if isinstance(source, np.ndarray):
        points = source if crop is None else source[inside(source, crop[:3], crop[3:])]
        if len(points) == 0:
            raise InputError("no points inside --crop")
        return points.min(axis=0), points.max(axis=0), len(points)
    from . import io

    return io.point_bounds(source, crop=crop)


def _estimate_whole(source, n_points, offset, config) -> tuple[Parameters, np.ndarray]:
    """Parameters of every point (a Dask task): those `zeroset.reconstruct` chooses; and
    ``SAMPLES`` of the points (local frame) drawn at random, which tell where they lie."""
    local = np.concatenate(list(_chunks(source, config.crop))) - offset
    drawn = np.random.default_rng(config.seed).permutation(len(local))[:SAMPLES]
    return choose_parameters(local[spatial_order(local)], config)[0], local[drawn]


def _estimate_sampled(
    source, n_points, offset, config, chunk_points=CHUNK_POINTS
) -> tuple[Parameters, np.ndarray]:
    """Parameters of a cloud too large to hold (a Dask task), measured as `zeroset.reconstruct`
    measures them: at ``SAMPLES`` points drawn at random in one pass over its chunks, on
    every point within reach of them read in another. The reach starts at twice the
    distance their neighbourhoods would span at the mean density, and doubles until those
    of ``WHOLE_NEIGHBOURHOODS`` of them lie wholly within it; the others are not used.
    Returns the parameters and the points drawn (local frame)."""
    rng = np.random.default_rng(config.seed)
    share = min(1.0, 2.0 * SAMPLES / n_points)
    drawn = [c[rng.random(len(c)) < share] for c in _chunks(source, config.crop, chunk_points)]
    samples = np.concatenate(drawn)
    samples = samples[rng.permutation(len(samples))[:SAMPLES]] - offset
    wanted = neighbours_read(config.radius_k)
    tree = build_tree(samples)
    spacing = float(np.median(tree.query(samples, k=2, workers=query_workers())[0][:, 1]))
    reach = 2.0 * spacing * np.sqrt(wanted * len(samples) / n_points)
    for _ in range(READ_ROUNDS):
        near = []
        for chunk in _chunks(source, config.crop, chunk_points):
            chunk = chunk - offset
            gap = tree.query(chunk, distance_upper_bound=reach, workers=query_workers())[0]
            near.append(chunk[np.isfinite(gap)])
        local = np.concatenate(near)
        read = build_tree(local)
        distances, rows = read.query(samples, k=min(wanted, len(local)), workers=query_workers())
        whole = distances[:, -1] <= reach
        if whole.mean() >= WHOLE_NEIGHBOURHOODS:
            return choose_parameters(local, config, tree=read, rows=rows[whole, 0])[0], samples
        reach *= 2.0
    raise ReconstructionError(
        f"the neighbourhoods of only {whole.mean():.1%} of {len(samples)} sample points lie "
        f"within {reach / 2.0:.4g} of them; pass parameters, or rho_delta and cube_size"
    )


def _chunks(source, crop, chunk_points=CHUNK_POINTS):
    """The points (n, 3) of `source`, a file or an array, inside `crop` (6,) when given, a
    chunk of the file at a time."""
    if isinstance(source, np.ndarray):
        yield source if crop is None else source[inside(source, crop[:3], crop[3:])]
        return
    from . import io

    yield from io.point_chunks(source, crop=crop, chunk_points=chunk_points)


def _fit_tile(source, tile: Tile, offset, parameters, config) -> TileFit | TileFailure | None:
    """Read a tile from `source` (a file or an array) and fit it (a Dask task; the result
    stays on the worker): `fit_tile`."""
    return fit_tile(partial(_read, source, crop=config.crop), tile, offset, parameters, config)


def fit_tile(read, tile: Tile, offset, parameters, config) -> TileFit | TileFailure | None:
    """Fit and orient the planes of a tile's points, ``read(box)`` (those (N, 3) inside
    `box` (6,), input coordinates, and their sensor positions (N, 3) or None), with a wider
    halo where its neighbourhoods reach further than the halo allows. None for a tile of
    too few points to hold a surface."""
    base = tile.halo - len(LEVELS) * RADIUS_CAP * parameters.rho_delta
    for grown in range(GROW_ROUNDS + 1):
        points, viewpoints = read(tile.box)
        if len(points) < max(MIN_TILE_POINTS, config.k_max):
            return None
        order = spatial_order(points)
        cloud = LocalCloud(
            points[order] - offset, offset, local_viewpoints(viewpoints, order, offset, config)
        )
        stages = Stages((), show=False)
        try:
            fitted = fit(cloud, parameters, config, stages)
        except ReconstructionError as error:
            return TileFailure(tile, str(error))
        needed = _halo_needed(fitted, tile, base, parameters.cube_size)
        if needed <= tile.halo:
            stages.counts["tiles_grown"] = int(grown > 0)
            return TileFit(tile, cloud, fitted, stages.counts)
        tile = tile.grown(max(needed, GROWTH * tile.halo))
    return TileFailure(
        tile,
        f"its neighbourhoods reach {needed:.4g} from its cubes, beyond the halo of "
        f"{tile.halo:.4g} read around them after {GROW_ROUNDS} widenings; the points are "
        "too sparse for tiles this small: use fewer tiles",
    )


def _halo_needed(fitted, tile: Tile, base: float, cube: float) -> float:
    """The halo `tile` needs for the neighbourhoods `fitted` measured: `base`, the reach of
    what a cube's value reads by distance, plus the ``LEVELS`` of neighbourhoods reached in
    turn from its cubes."""
    lo, hi = _owned_box(tile, cube)
    points = fitted.points
    away = np.linalg.norm(np.maximum(np.maximum(lo - points, points - hi), 0.0), axis=1)
    needed = base
    for column in LEVELS:
        needed += fitted.density.extent[away <= needed, column].max(initial=0.0)
    return float(needed)


def _seam(fit: TileFit | TileFailure | None, parameters: Parameters) -> Seam | TileFailure | None:
    """A tile's oriented normals at its seams, keyed by the points, and its extremes.

    The seam is the band within half the halo of the faces the tile shares with others:
    there both tiles hold the points with their whole neighbourhoods.
    """
    if not isinstance(fit, TileFit):
        return fit
    fitted = fit.fitted
    points, normals = fitted.points, fitted.orientation.normals
    component = fitted.orientation.component
    cube = parameters.cube_size
    lo, hi = _owned_box(fit.tile, cube)
    width = 0.5 * (HALO_RADII * parameters.rho_delta + HALO_CUBES * cube)
    near = np.all((points >= lo - width) & (points <= hi + width), axis=1) & np.any(
        (np.abs(points - lo) < width) | (np.abs(points - hi) < width), axis=1
    )
    owned = np.all((points >= lo) & (points < hi), axis=1)
    return Seam(
        keys=_point_keys(points[near]),
        normals=normals[near],
        component=component[near],
        extremes=part_extremes(
            fitted.planes.centroids[owned],
            normals[owned],
            component[owned],
            fitted.orientation.n_components,
        ),
        by_sensors=fitted.orientation.disagreement is not None,
    )


def _owned_box(tile: Tile, cube: float) -> tuple[np.ndarray, np.ndarray]:
    """Corners (3,), (3,) of the cubes a tile owns, in the local frame (+-inf outside)."""
    lo = np.where(tile.owned[0] <= -LIMIT, -np.inf, cube * tile.owned[0].astype(np.float64))
    hi = np.where(tile.owned[1] >= LIMIT, np.inf, cube * tile.owned[1].astype(np.float64))
    return lo, hi


def _point_keys(points: np.ndarray) -> np.ndarray:
    """(N,) keys identifying points by their exact coordinates."""
    return np.ascontiguousarray(points).view(np.dtype((np.void, 24))).ravel()


def _agree(seams) -> tuple[list[dict], float | None, int]:
    """Flips that make the tiles' orientations agree, as `zeroset.reconstruct` would orient
    (`zeroset.orientation.agree_parts`, each tile's component a part). Tiles oriented by
    sensors keep their signs.

    Returns
    -------
    flips : list of dict
        Per tile, {component: -1.0} for the components to negate.
    disagreement : float or None
        Share of the seam points held by two tiles whose normals still point apart.
    groups : int
        Number of groups of parts joined by seams that hold points a tile owns.
    """
    live = [i for i, seam in enumerate(seams) if isinstance(seam, Seam)]
    flips: list[dict] = [{} for _ in seams]
    if not live:
        return flips, None, 0
    first = np.cumsum([0] + [seams[i].extremes.shape[0] for i in live])
    extremes = np.concatenate([seams[i].extremes for i in live])
    sign, group, disagreement = agree_parts(
        np.concatenate([seams[i].keys for i in live]),
        np.concatenate([first[k] + seams[i].component for k, i in enumerate(live)]),
        np.concatenate([seams[i].normals for i in live]),
        extremes,
        by_sensors=all(seams[i].by_sensors for i in live),
    )
    for k, tile in enumerate(live):
        flips[tile] = {int(c): -1.0 for c in np.flatnonzero(sign[first[k] : first[k + 1]] < 0)}
    owning = np.isfinite(extremes[:, :, 0]).any(axis=1)  # parts with points of their own
    return flips, disagreement, int(distinct(group[owning]).size)


def _contour_tile(
    fit: TileFit | TileFailure | None,
    flips: dict,
    parameters: Parameters,
    config: ReconstructionConfig,
) -> tuple[Piece, Surface | None]:
    """`contour_fit` as a Dask task, its piece naming the worker."""
    import socket

    worker = socket.gethostname()
    try:
        worker = require("distributed", "tiled reconstruction (--tiles)").get_worker().address
    except ValueError:
        pass
    return contour_fit(fit, flips, parameters, config, worker=worker)


def contour_fit(
    fit: TileFit | TileFailure | None,
    flips: dict,
    parameters: Parameters,
    config: ReconstructionConfig,
    *,
    worker: str = "",
) -> tuple[Piece, Surface | None]:
    """Contour the cubes a tile owns: its `Piece`, and its whole oriented surface (None
    for a tile with no surface), which its border is refined on; `flips` negates the
    normals of its orientation components ({component: -1.0}, `_agree`)."""
    if not isinstance(fit, TileFit):
        return Piece.empty(peak_mib(), worker), None
    fitted = fit.fitted
    sign = np.ones(fitted.orientation.n_components)
    for component, flip in flips.items():
        sign[component] = flip
    normals = fitted.orientation.normals * sign[fitted.orientation.component][:, None]
    stages = Stages((), show=False)
    field_, bridges, surface = stages.run(
        "signed distance", distance_field, fit.cloud, fitted, normals, parameters, config
    )
    edge_keys, vertices, faces, cube_keys = keyed_marching_cubes(field_, owned=fit.tile.owned)
    support = data_support(fitted, bridges, parameters)
    lo, hi = fit.tile.owned
    piece = Piece(
        edge_keys=edge_keys,
        vertices=vertices,
        faces=faces,
        cube_keys=cube_keys,
        support=support.select(_in_cubes(support.points, lo, hi, parameters.cube_size)),
        surface=surface.select(_in_cubes(surface.centres, lo, hi, parameters.cube_size)),
        counts=add_counts(dict(fit.counts), stages.counts),
        peak_mib=peak_mib(),
        worker=worker,
    )
    return piece, surface


def _in_cubes(positions: np.ndarray, lo, hi, cube: float) -> np.ndarray:
    """(N,) whether each position lies in a cube of index lo..hi - 1 on every axis."""
    index = np.floor(positions / cube)
    return np.all((index >= lo) & (index < hi), axis=1)


def _owned_surface(pieces) -> Surface:
    """The union of the local fits each tile owns (those centred in its cubes)."""
    owned = [p.surface for p in pieces if p.surface is not None]
    if not owned:
        raise ReconstructionError("no surface: every tile failed")
    return type(owned[0]).concatenate(owned)


def weld_pieces(pieces) -> tuple[Mesh, float]:
    """One mesh of the tiles' pieces: vertices shared by global edge key, faces in cube
    order; and how far apart two tiles put one vertex (0 when their halos held all that
    its corners' values depend on)."""
    keys = np.concatenate([p.edge_keys for p in pieces])
    vertices = np.concatenate([p.vertices for p in pieces])
    starts = np.cumsum([0] + [len(p.edge_keys) for p in pieces[:-1]])
    faces = np.concatenate([p.faces + s for p, s in zip(pieces, starts, strict=True)])
    cube_keys = np.concatenate([p.cube_keys for p in pieces])
    unique, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(cube_keys, kind="stable")
    gap = np.linalg.norm(vertices - vertices[first][inverse.ravel()], axis=1).max(initial=0.0)
    return Mesh(vertices=vertices[first], faces=inverse[faces[order]].astype(np.int64)), float(gap)


def _gather(client, futures, what: str, progress: bool) -> list:
    """Results of `futures` in order, with a bar over those done."""
    import sys

    from tqdm.auto import tqdm

    as_completed = require("distributed", "tiled reconstruction (--tiles)").as_completed

    bar = tqdm(
        total=len(futures),
        desc=what,
        unit="tile",
        disable=not (progress and sys.stderr.isatty()),
        leave=False,
    )
    for _ in as_completed(futures):
        bar.update()
    bar.close()
    return client.gather(futures)
