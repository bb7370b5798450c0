"""Phase 1 as the robot scans: blocks of the lattice meshed and finished as the scans pass.

Scans come one at a time, each with its sensor's position. The lattice is cut into blocks
of ``block_cubes`` cubes a side, the tiles of `zeroset.tiles` without an end, and a block
goes through three states:

- **sealed** once no later scan can put a point into it: it lies farther than ``reach``
  (the longest range seen so far, or given) from the newest sensor. A later point that
  falls into a sealed block all the same is counted and left out, with a warning.
- **contoured** once every block its box reads (its own cubes and their halo) is sealed:
  its fits, orientation and signed distance are those of a tile (`zeroset.tiles.fit_tile`,
  `zeroset.tiles.contour_fit`), from the same points in the same order, so its dense
  piece is the one a run over all the points makes.
- **finished** once its 26 neighbours are contoured: stages "repair" and "rim" run on the
  welded pieces of the block and its neighbours, stage "refine" on the block's faces and
  ``REFINE_RINGS`` rings around them (on the block's own fits), and the few-triangle
  simplification on the block's faces with their boundary kept. The block's mesh is then
  final; it is written (one PLY file a block and the manifest of `zeroset.tile_output`,
  each atomically) and its points and pieces are dropped once its neighbours no longer
  need them, so memory follows a window along the robot's path.

With ``background``, `LiveReconstruction.add` only checks its scan and queues it: a worker
thread takes the scans in order and does for each what `add` does without it, and while no
scan waits goes on with the work their budgets left; the blocks are the ones made without
it, and the robot's loop does not wait for them (the kernels release the GIL). Once
``QUEUE`` scans wait, `add` waits for the worker to take one: the scans held, and so the
memory, stay bounded where the work falls behind the scans.

Blocks that no scan has sealed yet are previewed: those the newest scan put points into
within ``preview`` of its sensor are fitted and contoured from the points so far.

With an ``inspection`` (`zeroset.inspect.LiveInspection`) each finished block's mesh and
points go to it, and it inspects the pipe in windows as the finished front moves on.
"""

from __future__ import annotations

import queue
import threading
import time
import warnings
from dataclasses import dataclass, field, replace
from itertools import product
from pathlib import Path

import numpy as np

from . import io
from ._progress import Stages, peak_mib
from ._validate import as_points
from .config import ReconstructionConfig
from .density import range_noise
from .errors import InputError, ReconstructionError, SurfaceWarning
from .neighbours import build_tree
from .refine import refine_traced
from .simplify import choose_tolerance, simplify_mesh
from .stages import (
    DataSupport,
    average_in_cells,
    choose_parameters,
    find_neighbours,
    repair,
    trim_rim,
    warn_surface_changes,
)
from .stats import add_counts, declared
from .surface import surface_kind
from .thresholds import CHORD_NOISE
from .tile_output import (
    FORMAT,
    MANIFEST,
    check_folder,
    cut,
    read_tile_meshes,
    weld,
    weld_coincident,
)
from .tiles import (
    HALO_CUBES,
    HALO_RADII,
    REFINE_RINGS,
    SAMPLES,
    SEAM_TOLERANCE,
    Tile,
    TileFit,
    contour_fit,
    face_rings,
    fit_tile,
    weld_pieces,
)
from .topology import boundary_edges
from .types import Mesh, Parameters

__all__ = ["BLOCK_CUBES", "BUDGET", "QUEUE", "LiveReconstruction", "ScanUpdate"]

#: Cubes along each edge of a block. A block's box reads a halo of about 13 cubes on
#: every side (the jets' reach, 16 rho+delta, at cubes of 1.5 rho+delta, and
#: ``HALO_CUBES``): at 40 the points it reads are about 1.6 times its own along a pipe.
BLOCK_CUBES = 40
#: Largest distance, over the cube size, at which two finished blocks' copies of a seam
#: vertex are taken for one, the later moved onto the earlier. Both come from the same
#: dense vertex refined on two blocks' fits, which agree to rounding when the blocks hold
#: one range-noise model (`Parameters.noise_model`). Given parameters without one, each
#: block fits its own, and the copies differ (an 8-degree scan: fits 5.5e-6 m apart at a
#: seam; the 20 m benchmark run's bends: copies up to 0.18 mm, 0.007 cubes, apart, about
#: the surface's own uncertainty there). Past ``SEAM_TOLERANCE`` a warning gives the gap.
SEAM_MATCH = 1e-2
#: Seconds of block work an `add` does by default (``budget``): a scan's blocks then
#: spread over the scans that follow, as long as the scans leave the time.
BUDGET = 1.0
#: Scans a ``background`` run holds for its worker before `add` waits: one scan's work
#: may then run past the time between scans (a block's contour takes up to about 7 s on
#: the benchmark run) without holding the robot, while the memory of scans held stays a
#: few scans'.
QUEUE = 2
#: Relative change of rho+delta or of the noise at which a finished block's own points
#: would have chosen differently from the held parameters; the report says so.
PARAMETER_DRIFT = 0.25


@dataclass(frozen=True, eq=False)
class ScanUpdate:
    """What one scan changed (`LiveReconstruction.add`, and `close`).

    Attributes
    ----------
    scan : int
        The scan's number, from 0, in the order given; -1 for `close`.
    points : int
        Its points that were used.
    skipped : str or None
        Why the scan was left out whole (no usable points, a sensor far from the others).
    late_points : int
        Its points that fell into blocks already sealed, left out.
    finished : dict
        Block index (3,) tuple -> its final `Mesh` (input coordinates), for the blocks
        this scan finished.
    previewed : dict
        Block index -> its provisional dense `Mesh`, for the blocks it previewed.
    seconds : float
        Wall-clock seconds the call took.
    waiting : int
        Blocks sealed but not yet finished after it (`LiveReconstruction.budget`).
    inspected : tuple of zeroset.inspect.Stretch
        The stretches of the pipe its live inspection reported.
    done : tuple of (int, float)
        ``(scan, seconds)`` for each scan whose work ended since the previous call: the
        seconds from its `add` being called to then. Without ``background``, this scan.

    With ``background``, `late_points`, `finished`, `previewed`, `inspected` and `waiting`
    are what the worker did since the previous call, for this scan or earlier ones, and
    `points` counts the scan's usable points before any late ones are known.
    """

    scan: int
    points: int
    skipped: str | None
    late_points: int
    finished: dict
    previewed: dict
    seconds: float
    waiting: int = 0
    inspected: tuple = ()
    done: tuple = ()


@dataclass(frozen=True, eq=False)
class _Scan:
    """One scan as `add` checked it: points (N, 3), sensors (N, 3), ranges (N,), input
    frame, and the `time.perf_counter` at which `add` was called."""

    number: int
    points: np.ndarray
    viewpoints: np.ndarray
    ranges: np.ndarray
    given: float


def _merged(updates: list, waiting: int = 0) -> ScanUpdate:
    """One `ScanUpdate` of what `updates` changed, in order (later meshes replace earlier
    ones; `waiting` is the last's, or the one given where there is none)."""
    merged = ScanUpdate(-1, 0, None, 0, {}, {}, 0.0, waiting)
    for u in updates:
        merged = replace(
            merged, late_points=merged.late_points + u.late_points,
            finished=merged.finished | u.finished, previewed=merged.previewed | u.previewed,
            waiting=u.waiting, inspected=merged.inspected + u.inspected,
            done=merged.done + u.done,
        )  # fmt: skip
    return merged


@dataclass(eq=False)
class _Block:
    """One block's points and what has been made of them."""

    points: list = field(default_factory=list)
    viewpoints: list = field(default_factory=list)
    sealed: bool = False
    piece: object = None  # its dense `zeroset.tiles.Piece`, once contoured
    surface: object = None  # its whole oriented surface (halo included), once contoured
    contoured: bool = False
    stuck: bool = False  # its halo grew into a block that may still get points
    finished: bool = False
    order: int = -1  # its place among the blocks in the order they were sealed
    boundary: np.ndarray | None = None  # its final mesh's boundary vertices (B, 3), local

    def cloud(self) -> tuple[np.ndarray, np.ndarray]:
        """Its points (N, 3) and their sensor positions (N, 3), local frame."""
        if not self.points:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return np.concatenate(self.points), np.concatenate(self.viewpoints)


class LiveReconstruction:
    """Phase 1 of `zeroset.reconstruct`, grown scan by scan (module docstring).

    Parameters
    ----------
    config : ReconstructionConfig, optional
        As for `zeroset.reconstruct`, fields also as keywords; ``sample``, ``voxel_size``
        and ``contour="cubes"`` are not supported, as with tiles.
    parameters : Parameters, optional
        Use these; without a ``noise_model`` each block fits its own range-noise model,
        and blocks either side of a seam agree only to within what those differ by. By
        default they are measured once the first ``SAMPLES`` points are sealed (no later
        scan can add to their neighbourhoods), from every point so far at those points,
        with the range-noise model of those points, and then held.
    origin : (3,) array_like of float, optional
        Origin of the lattice (input coordinates); by default the corner of the block that
        has the first scan's sensor in its middle.
    block_cubes : int
        Cubes along each edge of a block (``BLOCK_CUBES``).
    reach : float, optional
        Farthest a scan's point lies from its sensor (data units): a block farther than
        that from the newest sensor is sealed. The longest range seen so far by default;
        give the scanner's range limit where later scans may see further.
    max_jump : float, optional
        Farthest a scan's sensor may lie from the previous scan's before the scan is
        skipped as not belonging to the run; ``reach`` by default.
    folder : str or os.PathLike, optional
        Write each finished block there (``block-I-J-K.ply``, input coordinates) and the
        manifest `zeroset.tile_output.MANIFEST` after it, both atomically, and drop the
        finished meshes from memory; `zeroset.tile_output.read_tile_meshes` reads it back.
    preview : float
        Preview the unsealed blocks that the newest scan reached within this distance of
        its sensor (data units); 0 previews none.
    budget : float
        Seconds of block work (contouring, finishing, inspecting) one `add` does once it
        has taken its scan: it stops at the first block or window done past them, and what
        is left waits for the next scans (`close` does it all; `waiting` counts the
        blocks). ``inf`` does all that can be done at once.
    background : bool
        Do each scan's work on a worker thread (module docstring), which goes on with the
        work the budgets left while no scan waits: `add` returns once the scan is checked
        and queued, and what the worker did comes with the next calls
        (`ScanUpdate`); `close` waits for it. An error of the worker is raised by the next
        `add` or `close`. The mesh is the one made without it.
    inspection : zeroset.inspect.LiveInspection, optional
        Inspect the pipe as its blocks finish: each finished block's mesh and points go
        to it, and it is told how far along the sensors' path every block is finished.
    """

    def __init__(
        self,
        config: ReconstructionConfig | None = None,
        *,
        parameters: Parameters | None = None,
        origin=None,
        block_cubes: int = BLOCK_CUBES,
        reach: float | None = None,
        max_jump: float | None = None,
        folder=None,
        preview: float = 0.0,
        budget: float = BUDGET,
        inspection=None,
        background: bool = False,
        **overrides,
    ) -> None:
        config = (config or ReconstructionConfig()).with_overrides(**overrides)
        if config.sample is not None or config.voxel_size is not None:
            raise InputError("sample and voxel_size are not supported live; use crop")
        if config.contour != "marching":
            raise InputError("live blocks are contoured by marching cubes only")
        if not (isinstance(block_cubes, int | np.integer) and block_cubes >= 4):
            raise InputError(f"block_cubes must be an integer >= 4; got {block_cubes!r}")
        for name, value in (("reach", reach), ("max_jump", max_jump)):
            if value is not None and not 0.0 < value < np.inf:
                raise InputError(f"{name} must be a positive distance; got {value!r}")
        if not 0.0 <= preview < np.inf:
            raise InputError(f"preview must be a distance >= 0; got {preview!r}")
        if not 0.0 <= budget <= np.inf:
            raise InputError(f"budget must be seconds >= 0; got {budget!r}")
        self.config = config
        self.parameters = parameters
        self.block_cubes = int(block_cubes)
        self.folder = None if folder is None else check_folder(folder)
        self.preview = float(preview)
        self.budget = float(budget)
        self.inspection = inspection
        self.background = bool(background)
        self._origin = None if origin is None else as_points(np.reshape(origin, (1, 3)))[0]
        self._origin_given = origin is not None
        self._given_reach, self._max_jump = reach, max_jump
        self._range = 0.0  # the longest range of the scans taken so far
        self._sensor: np.ndarray | None = None  # the newest scan's taken, local frame
        self._given: tuple = (None, 0.0)  # the newest scan's sensor given, and longest range
        self._queue: queue.Queue | None = None  # scans for the worker, with `background`
        self._worker: threading.Thread | None = None
        self._outbox: list = []  # what the worker did since the last call: `ScanUpdate`s
        self._outbox_lock = threading.Lock()
        self._failure: BaseException | None = None  # the worker's error
        self._waited = 0  # blocks waiting after the last scan the worker took
        self._steps = 0  # blocks contoured or finished so far
        self._raw: list = []  # scans held until the parameters are measured
        self._blocks: dict = {}
        self._tolerance: float | None = None
        self._meshes: dict = {}  # finished block -> final mesh (local), without a folder
        self._entries: list = []  # the manifest's tiles, in the order they finished
        self._position: dict = {}  # finished block -> its place in `_entries`
        self._seams: dict = {}  # (position, position) -> shared vertices
        self._welded_vertices = 0
        self._faces = 0
        self._drift: list = []  # (block, rho_delta, noise) its own points would choose
        self.stats: dict = {
            "scans": 0,
            "scans_skipped": 0,
            "late_points": 0,
            "nonfinite_points": 0,
            "cropped": 0,
            "blocks_moved_at_seams": 0,
            "blocks_failed": 0,
            "small_holes_filled": 0,
            "small_components_dropped": 0,
        }
        self.timings: dict = {}
        self.skipped: list = []  # (scan, reason)
        self._scans = 0
        self._closed = False
        self._final = False  # every block sealed: no more scans come
        self._sealings = 0
        if self.folder is not None:
            self.folder.mkdir(exist_ok=True)

    # ---------------------------------------------------------------------- the interface

    @property
    def offset(self) -> np.ndarray | None:
        """Origin (3,) of the lattice and of the local frame, once the first scan set it."""
        return self._origin

    def add(self, points, viewpoint) -> ScanUpdate:
        """Take one scan: its points (N, 3) and its sensor's position, (3,) or one per point
        (N, 3), in the cloud's frame. Returns what it changed (`ScanUpdate`).

        A scan with no usable points, or whose sensor lies more than ``max_jump`` from the
        previous scan's, is left out whole with a `SurfaceWarning` saying why."""
        if self._closed:
            raise InputError("this live reconstruction is closed; start a new one")
        self._raise_failure()
        start = time.perf_counter()
        number = self._scans
        self._scans += 1
        self.stats["scans"] += 1
        points, viewpoints, problem = self._checked(points, viewpoint)
        if problem is None:
            problem = self._jump(viewpoints.mean(axis=0))
        if problem is not None:
            self.stats["scans_skipped"] += 1
            self.skipped.append((number, problem))
            warnings.warn(f"scan {number} skipped: {problem}", SurfaceWarning, stacklevel=2)
            return ScanUpdate(number, 0, problem, 0, {}, {}, time.perf_counter() - start)
        ranges = np.linalg.norm(points - viewpoints, axis=1)
        self._given = (viewpoints.mean(axis=0), max(self._given[1], float(ranges.max())))
        scan = _Scan(number, points, viewpoints, ranges, start)
        if self.background:
            self._put(scan)
            taken = self._collect()
        else:
            taken = [self._take(scan, deadline=start + self.budget)]
        seconds = time.perf_counter() - start
        self.timings.setdefault("scans", []).append(seconds)
        update = _merged(taken, self._waited)
        self._waited = update.waiting
        used = points.shape[0] - (0 if self.background else update.late_points)
        return replace(update, scan=number, points=used, seconds=seconds)

    def _take(self, scan: _Scan, deadline: float) -> ScanUpdate:
        """Bin scan `scan` (once the parameters are known) and do the block work it allows
        until `deadline`; what that changed, with the scan's own seconds in ``done``."""
        if self._origin is None:
            self._origin = scan.viewpoints.mean(axis=0)
            if self.parameters is not None:
                self._sensor = np.zeros(3)
                self._place_lattice()
        local, local_viewpoints = scan.points - self._origin, scan.viewpoints - self._origin
        self._sensor = local_viewpoints.mean(axis=0)
        self._range = max(self._range, float(scan.ranges.max()))
        if self.inspection is not None:
            self.inspection.scan(self._sensor + self._origin, scan.ranges)
        late = 0
        if self.parameters is None:
            self._raw.append((scan.points, scan.viewpoints))
            self._measure_parameters()
        else:
            late = self._bin(local, local_viewpoints)
        finished, inspected = self._advance(final=False, deadline=deadline)
        previewed = self._previews(local) if self.preview > 0.0 else {}
        if late:
            self.stats["late_points"] += late
            warnings.warn(
                f"scan {scan.number}: {late} point(s) fell into blocks already sealed and "
                f"are left out; give a reach of at least {self._range:.4g}",
                SurfaceWarning,
                stacklevel=3,
            )
        done = ((scan.number, time.perf_counter() - scan.given),)
        return ScanUpdate(scan.number, 0, None, late, finished, previewed, 0.0,
                          self.waiting(), tuple(inspected), done)  # fmt: skip

    # ------------------------------------------------------------- the background worker

    def _put(self, scan: _Scan | None) -> None:
        """Queue `scan` for the worker (started by the first), waiting while ``QUEUE``
        scans wait; the worker's error, if it stopped with one."""
        if self._worker is None:
            self._queue = queue.Queue(maxsize=QUEUE)
            self._worker = threading.Thread(target=self._work, name="zeroset-live", daemon=True)
            self._worker.start()
        while True:
            self._raise_failure()
            try:
                self._queue.put(scan, timeout=0.1)
                return
            except queue.Full:
                continue

    def _work(self) -> None:
        """The worker: take the queued scans in order until `close` queues None, and while
        none waits, go on with the block work and windows their budgets left."""
        try:
            while (scan := self._queue.get()) is not None:
                self._post(self._take(scan, deadline=time.perf_counter() + self.budget))
                while self._queue.empty():
                    steps = self._steps
                    finished, inspected = self._advance(
                        final=False, deadline=time.perf_counter() + self.budget
                    )
                    if self._steps == steps and not inspected:
                        break  # nothing left that the scans so far allow
                    self._post(ScanUpdate(-1, 0, None, 0, finished, {}, 0.0, self.waiting(),
                                          tuple(inspected)))  # fmt: skip
        except BaseException as error:  # raised in the caller's thread by `add` or `close`
            self._failure = error

    def _post(self, update: ScanUpdate) -> None:
        """Hand `update` to the caller's next `add` or `close`."""
        with self._outbox_lock:
            self._outbox.append(update)

    def _collect(self) -> list:
        """What the worker did since the last call (`ScanUpdate`s), emptied."""
        with self._outbox_lock:
            taken, self._outbox = self._outbox, []
        return taken

    def _raise_failure(self) -> None:
        """Raise the worker's error, if it stopped with one, and close the run."""
        if self._failure is not None:
            self._closed = True
            raise self._failure

    def _join(self) -> None:
        """Wait for the worker to take every scan queued, and stop it."""
        if self._worker is None:
            return
        self._put(None)
        self._worker.join()
        self._worker = None
        self._raise_failure()

    def close(self) -> ScanUpdate:
        """Finish every block left (no more scans come) and return what that changed."""
        start = time.perf_counter()
        if not self._closed:
            self._join()
            self._closed = True
            taken = self._collect()
            if self.parameters is None and self._raw:
                self._measure_parameters(final=True)
            finished, inspected = self._advance(final=True)
            taken.append(ScanUpdate(-1, 0, None, 0, finished, {}, 0.0, 0, tuple(inspected)))
            if self.inspection is not None:
                self.inspection.close()
            stats = self.summary()
            warn_surface_changes(stats, self.config)
            self._warn_drift()
            if stats["blocks_moved_at_seams"]:
                warnings.warn(
                    f"{stats['blocks_moved_at_seams']} block(s) had seam vertices up to "
                    f"{stats['seam_vertex_gap']:.3g} from their neighbours' copies, more "
                    "than rounding explains (the blocks' fits differ there: give parameters "
                    "with a noise_model); they "
                    "were moved onto them",
                    SurfaceWarning,
                    stacklevel=2,
                )
            if stats["nonfinite_points"]:
                warnings.warn(
                    f"{stats['nonfinite_points']} point(s) of the scans were not finite "
                    "(a beam with no return) and were left out",
                    SurfaceWarning,
                    stacklevel=2,
                )
            if stats["small_holes_filled"] or stats["small_components_dropped"]:
                warnings.warn(
                    "the counts of holes closed and components dropped are summed over "
                    "the blocks' regions (a block and its neighbours): one near a seam "
                    "counts once in each region that holds it",
                    SurfaceWarning,
                    stacklevel=2,
                )
        else:
            taken = []
        seconds = time.perf_counter() - start
        return replace(_merged(taken), scan=-1, points=0, seconds=seconds, waiting=0)

    def mesh(self) -> Mesh:
        """The whole current mesh, input coordinates: the finished blocks welded (read back
        from the folder where one is written), and the contoured blocks' dense pieces."""
        parts = []
        if self.folder is not None and self._entries:
            parts.append(read_tile_meshes(self.folder))
        elif self._meshes:
            meshes = dict(self._meshes)
            parts.append(weld_coincident([meshes[b] for b in sorted(meshes)])[0])
            parts[0] = parts[0].translated(self._origin)
        blocks = list(self._blocks.values())  # a worker may be adding to them
        pieces = [b.piece for b in blocks if b.contoured and not b.finished]
        pieces = [p for p in pieces if p is not None and p.faces.shape[0]]
        if pieces:
            parts.append(weld_pieces(pieces)[0].translated(self._origin))
        if not parts:
            return Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
        return weld(parts, [np.full(m.n_vertices, -1) for m in parts])[0]

    def summary(self) -> dict:
        """The counts so far (``zeroset.stats.SCHEMA``) with the finished mesh's."""
        stats = dict(self.stats)
        stats["blocks_finished"] = len(self._position)
        stats["vertices"] = self._welded_vertices
        stats["faces"] = self._faces
        if self._tolerance is not None:
            stats["tolerance"] = self._tolerance
        peak = peak_mib()
        if peak is not None:
            stats["peak_mib"] = peak
        return declared(stats)

    # ---------------------------------------------------------------------- the machinery

    def _checked(self, points, viewpoint):
        """Points (N, 3), sensor positions (N, 3), and a problem that skips the scan."""
        try:
            points = np.asarray(points, dtype=np.float64)
            if points.ndim != 2 or points.shape[1] != 3:
                raise InputError(f"points must have shape (N, 3); got {points.shape}")
            viewpoints = np.asarray(viewpoint, dtype=np.float64)
            if viewpoints.shape == (3,):
                viewpoints = np.broadcast_to(viewpoints, points.shape)
            if viewpoints.shape != points.shape:
                raise InputError(
                    f"viewpoint must be (3,) or match the points {points.shape}; got "
                    f"{viewpoints.shape}"
                )
        except (TypeError, ValueError) as error:
            raise InputError(str(error)) from error
        if not np.isfinite(viewpoints).all():
            return points, viewpoints, "its sensor position is not finite"
        finite = np.isfinite(points).all(axis=1)
        usable = finite.copy()
        if self.config.crop is not None:
            crop = np.asarray(self.config.crop)
            usable &= np.all((points >= crop[:3]) & (points <= crop[3:]), axis=1)
        if not usable.any():
            return points, viewpoints, "no usable points (none finite and inside the crop)"
        self.stats["nonfinite_points"] += int(finite.size - np.count_nonzero(finite))
        self.stats["cropped"] += int(np.count_nonzero(finite & ~usable))
        return points[usable], np.ascontiguousarray(viewpoints[usable]), None

    def _jump(self, sensor: np.ndarray) -> str | None:
        """Why a scan whose sensor is at `sensor` (3,) does not belong, or None."""
        previous, longest = self._given
        if previous is None:
            return None
        limit = self._max_jump or self._given_reach or longest
        away = float(np.linalg.norm(sensor - previous))
        if limit > 0.0 and away > limit:
            return (
                f"its sensor lies {away:.4g} from the previous scan's, farther than "
                f"max_jump {limit:.4g}"
            )
        return None

    def _reach(self) -> float:
        """How far from its sensor a scan's point may lie."""
        return self._given_reach if self._given_reach is not None else self._range

    def _measure_parameters(self, final: bool = False) -> None:
        """Measure the parameters from the scans held, at ``SAMPLES`` points that no later
        scan comes near and that lie beyond reach of the first sensor, once there are that
        many (with `final`, at any points where there are fewer); then bin them."""
        points = np.concatenate([s[0] for s in self._raw])
        viewpoints = np.concatenate([s[1] for s in self._raw])
        local = points - self._origin
        # Sealed, and scanned from both sides: as dense as they will be, unlike the run's
        # end behind the first sensor.
        first = self._raw[0][1].mean(axis=0) - self._origin
        far = (
            np.minimum(
                np.linalg.norm(local - self._sensor, axis=1), np.linalg.norm(local - first, axis=1)
            )
            > self._reach()
        )
        if final and np.count_nonzero(far) < SAMPLES:
            far[:] = True
        if np.count_nonzero(far) < (1 if final else SAMPLES):
            return
        if local.shape[0] < self.config.k_max:
            raise InputError(
                f"only {local.shape[0]} points; a neighbourhood needs at least "
                f"k_max={self.config.k_max}"
            )
        rows = np.flatnonzero(far)
        rows = rows[np.random.default_rng(self.config.seed).permutation(rows.size)]
        start = time.perf_counter()
        parameters = choose_parameters(local, self.config, rows=rows)[0]
        if parameters.noise_model is None:
            local_viewpoints = viewpoints - self._origin
            parameters = self._with_noise_model(parameters, local[far], local_viewpoints[far])
        self.parameters = parameters
        self.timings["parameters"] = time.perf_counter() - start
        self._raw = []
        self._place_lattice()
        self._bin(points - self._origin, viewpoints - self._origin)

    def _with_noise_model(self, parameters: Parameters, local, viewpoints) -> Parameters:
        """`parameters` with the range-noise model of the points (N, 3) and their sensors
        (N, 3), local frame, fitted once as stage "radii" fits it, to be held: a model fitted
        to each block's own points would give the blocks either side of a seam other radii
        (on the tests' sparse pipe, fits 5.5e-6 m apart there; held, 1e-16)."""
        cells = average_in_cells(local, viewpoints, parameters, self.config)[0]
        neighbours = find_neighbours(cells.points, self.config)[0]
        model = range_noise(cells.points, neighbours, cells.viewpoints, noise=parameters.noise)[1]
        note = (
            f"noise_model = {model[0]:.4g} + {model[1]:.4g} x range: fitted once, to the "
            f"{cells.points.shape[0]:,} cells of the first sealed points, and held"
        )
        return replace(parameters, noise_model=model, notes=(*parameters.notes, note))

    def _place_lattice(self) -> None:
        """Once the parameters are known, move the lattice's origin from the first sensor
        to the corner of the block it stands in the middle of, unless an origin was given
        (a pipe along an axis then runs through the middle of its blocks, not along their
        edges, where every block beside it would read it too)."""
        if self._origin_given:
            return
        shift = np.full(3, 0.5 * self._block_size())
        self._origin = self._origin - shift
        self._sensor = self._sensor + shift

    def _bin(self, local: np.ndarray, views: np.ndarray) -> int:
        """Put points (N, 3) and their sensors (N, 3), local frame, into their blocks;
        returns how many fell into sealed blocks and were left out."""
        blocks = np.floor(local / self._block_size()).astype(np.int64)
        unique, inverse = np.unique(blocks, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        order = np.argsort(inverse, kind="stable")
        starts = np.searchsorted(inverse[order], np.arange(unique.shape[0] + 1))
        late = 0
        for k, index in enumerate(map(tuple, unique.tolist())):
            rows = order[starts[k] : starts[k + 1]]
            block = self._blocks.setdefault(index, _Block())
            if block.sealed:
                late += rows.size
                continue
            block.points.append(local[rows])
            block.viewpoints.append(views[rows])
        return late

    def _block_size(self) -> float:
        return self.block_cubes * self.parameters.cube_size

    def _halo(self) -> float:
        """The halo a block's box reads around its cubes (as `zeroset.tiles.plan_tiles`)."""
        reach = max(HALO_RADII, surface_kind(self.config.surface).reach)
        return reach * self.parameters.rho_delta + HALO_CUBES * self.parameters.cube_size

    def _tile(self, index) -> Tile:
        """Block `index` as a tile of the lattice (its box in input coordinates)."""
        lo = np.asarray(index, dtype=np.int64) * self.block_cubes
        hi = lo + self.block_cubes
        cube, halo = self.parameters.cube_size, self._halo()
        box = np.r_[self._origin + cube * lo - halo, self._origin + cube * hi + halo]
        return Tile(index=tuple(index), owned=(lo, hi), box=box, halo=halo)

    def _advance(self, final: bool, deadline: float = np.inf) -> tuple[dict, list]:
        """Seal the blocks out of reach; contour and finish those that can be, oldest
        sealed first, finishing before contouring, then inspect, until `deadline`
        (`time.perf_counter`) has passed after one of them; the finished meshes and the
        stretches inspected."""
        if self.parameters is None:
            return {}, []
        self._final = final
        for index, block in self._blocks.items():
            block.stuck = False
            if not block.sealed and self._out_of_reach(index):
                block.sealed, block.order = True, self._sealings
                self._sealings += 1
        reach = int(np.ceil(self._halo() / self._block_size()))
        finished = {}
        while True:
            step = self._next_step(reach)
            if step is None:
                break
            kind, index = step
            self._steps += 1
            if kind == "contour":
                self._contour(index)
            else:
                mesh = self._finish(index)
                if mesh is not None:
                    finished[index] = mesh.translated(self._origin)
            if time.perf_counter() > deadline:
                break
        inspected = []
        if self.inspection is not None:
            front = self._front()
            # Past the budget too once the reports lag: the blocks it holds stay a window's.
            if time.perf_counter() <= deadline or self.inspection.behind(front):
                start = time.perf_counter()
                inspected = self.inspection.advance(front, deadline)
                _time(self.timings, "inspect", start)
        self._drop(reach)
        return finished, inspected

    def _front(self) -> float:
        """How far along the sensors' path every block is finished (``inf`` when all
        are): half a block's diagonal short of the path's position nearest the middle of
        the first block not finished, or of the first sensor within reach of the newest
        (and so of blocks that may still get points)."""
        pending = [i for i, b in self._blocks.items() if not b.finished]
        if self._final and not pending:
            return np.inf
        nodes = self.inspection.path - self._origin
        near = np.linalg.norm(nodes - self._sensor, axis=1) <= self._reach()
        along = self.inspection.position(np.r_[self._centres(pending), nodes[near]] + self._origin)
        return float(min(along, default=np.inf)) - 0.5 * np.sqrt(3.0) * self._block_size()

    def _centres(self, indices) -> np.ndarray:
        """(K, 3) the middles of blocks `indices` (K index tuples), local frame."""
        blocks = np.asarray(indices, dtype=np.float64).reshape(-1, 3)
        return (blocks + 0.5) * self._block_size()

    def _next_step(self, reach: int):
        """("finish" or "contour", block index) of the oldest sealed block that can be
        finished (its neighbours contoured), else of the oldest that can be contoured; None
        where none can."""
        ready = sorted(
            (b.order, index) for index, b in self._blocks.items() if b.sealed and not b.finished
        )
        for _, index in ready:
            block = self._blocks[index]
            if block.contoured and self._all_contoured(index):
                return "finish", index
        for _, index in ready:
            block = self._blocks[index]
            if not block.contoured and not block.stuck and self._all_sealed(index, reach):
                return "contour", index
        return None

    def waiting(self) -> int:
        """Blocks sealed but not yet finished: the work the scans' budgets left."""
        return sum(b.sealed and not b.finished for b in list(self._blocks.values()))

    def _neighbours(self, index, reach: int = 1):
        """Indices of the blocks within `reach` blocks of `index` on every axis."""
        steps = range(-reach, reach + 1)
        return [tuple(int(i) + d for i, d in zip(index, delta, strict=True))
                for delta in product(steps, steps, steps)]  # fmt: skip

    def _out_of_reach(self, index) -> bool:
        """Whether no later scan can put a point into block `index`."""
        size = self._block_size()
        gap = _box_distance(self._sensor, np.asarray(index) * size, size)
        return self._final or gap > self._reach()

    def _state(self, index, state: str) -> bool:
        """Whether block `index` is "sealed", "contoured" or "finished"; one that holds no
        point is, once no later scan can reach it."""
        block = self._blocks.get(index)
        return getattr(block, state) if block is not None else self._out_of_reach(index)

    def _all_sealed(self, index, reach: int) -> bool:
        """Whether every block the box of `index` reads is sealed."""
        return all(self._state(n, "sealed") for n in self._neighbours(index, reach))

    def _all_contoured(self, index) -> bool:
        """Whether `index` and its 26 neighbours are contoured, or hold no point and never
        will."""
        return all(self._state(n, "contoured") for n in self._neighbours(index))

    def _read(self, index, box: np.ndarray, sealed: bool):
        """The points inside `box` (6,), input coordinates, of the blocks around `index`,
        in an order that does not depend on the scans': ``read`` of `fit_tile`. With
        `sealed`, `_NotYet` where one of those blocks may still get points."""
        size = self._block_size()
        lo = np.floor((box[:3] - self._origin) / size).astype(np.int64)
        hi = np.floor((box[3:] - self._origin) / size).astype(np.int64)
        parts = []
        for n in product(*(range(a, b + 1) for a, b in zip(lo, hi, strict=True))):
            if sealed and not self._state(n, "sealed"):
                raise _NotYet
            if n in self._blocks:
                if self._blocks[n].points is None:
                    raise ReconstructionError(
                        f"block {index}: its neighbourhoods reach beyond the blocks next to "
                        f"it; give a larger block_cubes than {self.block_cubes}"
                    )
                parts.append(self._blocks[n].cloud())
        if not parts:
            return np.zeros((0, 3)), np.zeros((0, 3))
        local = np.concatenate([p[0] for p in parts])
        views = np.concatenate([p[1] for p in parts])
        inside = np.all((local >= box[:3] - self._origin) & (local <= box[3:] - self._origin), 1)
        local, views = local[inside], views[inside]
        order = np.lexsort((views[:, 2], views[:, 1], views[:, 0], *local.T[::-1]))
        return local[order] + self._origin, views[order] + self._origin

    def _fit(self, index, sealed: bool = True):
        """`fit_tile` and `contour_fit` of block `index`: its fit, and its piece and surface
        (`_NotYet` with `sealed` where a block it reads is not sealed)."""
        tile = self._tile(index)
        fit = fit_tile(
            lambda box: self._read(index, box, sealed),
            tile,
            self._origin,
            self.parameters,
            self.config,
        )
        if fit is not None and not isinstance(fit, TileFit):
            raise ReconstructionError(f"block {index}: {fit.reason}")
        return fit, contour_fit(fit, {}, self.parameters, self.config)

    def _contour(self, index) -> None:
        """Contour block `index` from its sealed points."""
        start = time.perf_counter()
        block = self._blocks[index]
        try:
            fit, (piece, surface) = self._fit(index)
        except _NotYet:
            block.stuck = True  # until the next scan seals more
            return
        except ReconstructionError as error:
            block.contoured = True  # with no piece: a gap in the mesh
            self._left_out(index, str(error))
            return
        block.piece, block.surface, block.contoured = piece, surface, True
        add_counts(self.stats, {k: v for k, v in piece.counts.items() if k in _BLOCK_COUNTS})
        if fit is not None:
            self._note_drift(index, fit)
        if self._tolerance is None and surface is not None and surface.smooth:
            chord = CHORD_NOISE * self.parameters.noise
            self._tolerance, note = choose_tolerance(
                surface, self.parameters.quadric_noise, chord, self.config.tolerance
            )
            self.stats["tolerance_note"] = note
        _time(self.timings, "contour", start)

    def _note_drift(self, index, fit: TileFit) -> None:
        """What the block's own points would choose, from its points in its cubes."""
        lo, hi = (self.parameters.cube_size * np.asarray(e, float) for e in fit.tile.owned)
        local = fit.cloud.local
        own = np.flatnonzero(np.all((local >= lo) & (local < hi), axis=1))
        if own.size < SAMPLES // 4:
            return
        rows = own[np.random.default_rng(self.config.seed).permutation(own.size)]
        rows = rows[: SAMPLES // 4]  # a quarter of a run's: enough to tell a drift
        would = choose_parameters(local, self.config, tree=fit.cloud.tree, rows=rows)[0]
        self._drift.append((index, would.rho_delta, would.noise))

    def _previews(self, local: np.ndarray) -> dict:
        """Fit and contour, from the points so far, the unsealed blocks the scan's points
        `local` reached within ``preview`` of its sensor; their dense meshes."""
        if self.parameters is None:
            return {}
        start = time.perf_counter()
        near = local[np.linalg.norm(local - self._sensor, axis=1) <= self.preview]
        indices = np.unique(np.floor(near / self._block_size()).astype(np.int64), axis=0)
        meshes = {}
        for index in map(tuple, indices.tolist()):
            block = self._blocks.get(index)
            if block is None or block.sealed:
                continue
            try:
                _, (piece, _) = self._fit(index, sealed=False)
            except ReconstructionError:
                continue  # too little yet to preview
            if piece.faces.shape[0]:
                mesh = Mesh(vertices=piece.vertices, faces=piece.faces)
                meshes[index] = mesh.translated(self._origin)
        _time(self.timings, "preview", start)
        return meshes

    def _finish(self, index) -> Mesh | None:
        """Finish block `index` (`_final_mesh`) and hand it and its points to the
        inspection; its final mesh (local frame), None where it has no face."""
        mesh = self._final_mesh(index)
        if self.inspection is not None:
            block = self._blocks[index]
            local, views = block.cloud()
            centre = self._centres([index])[0] + self._origin
            placed = None if mesh is None else mesh.translated(self._origin)
            self.inspection.block(index, placed, local + self._origin, views + self._origin,
                                  centre, self._block_size())  # fmt: skip
        return mesh

    def _final_mesh(self, index) -> Mesh | None:
        """Repair, rim, refine and simplify block `index` among its neighbours; record,
        write and return its final mesh (local frame), None where it has no face."""
        start = time.perf_counter()
        block = self._blocks[index]
        block.finished = True
        if block.piece is None or block.piece.faces.shape[0] == 0:
            return None
        region = [
            self._blocks[n].piece
            for n in self._neighbours(index)
            if n in self._blocks and self._blocks[n].piece is not None
        ]
        mesh, _ = weld_pieces([p for p in region if p.faces.shape[0]])
        support = DataSupport.concatenate([p.support for p in region])
        stages = Stages((), show=False)
        try:
            mesh = stages.run("repair", repair, mesh, self.parameters, self.config)
            if self.config.rim == "data":
                mesh = stages.run("rim", trim_rim, mesh, support, self.parameters, self.config)
        except ReconstructionError as error:
            self._left_out(index, str(error))
            return None
        owner = self._face_blocks(mesh) == np.asarray(index)
        own = owner.all(axis=1)
        if not own.any():
            return None
        if block.surface.smooth:
            mesh, own = self._refine_own(mesh, own, block.surface, stages)
        ((piece, _),) = cut(mesh, np.where(own, 0, -1), 1)
        dense_faces = piece.n_faces
        if block.surface.smooth and self._tolerance:
            with stages.stage("simplify"):
                piece, counts = simplify_mesh(piece, self._tolerance)
            add_counts(stages.counts, counts)
        counts = {k: v for k, v in stages.counts.items() if k in _BLOCK_COUNTS}
        add_counts(self.stats, counts | {"block_dense_faces": dense_faces})
        piece = self._seal_seams(index, piece)
        self._record(index, piece)
        for name, seconds in stages.timings.items():
            self.timings[name] = self.timings.get(name, 0.0) + seconds
        _time(self.timings, "finish", start)
        return piece

    def _left_out(self, index, reason: str) -> None:
        """Count and warn of block `index` left out of the mesh, a gap, for `reason`."""
        self.stats["blocks_failed"] += 1
        warnings.warn(
            f"block {index} left out, a gap in the mesh: {reason}", SurfaceWarning, stacklevel=4
        )

    def _face_blocks(self, mesh: Mesh) -> np.ndarray:
        """(F, 3) the block index of the cube holding each face's centroid."""
        centroids = mesh.vertices[mesh.faces].mean(axis=1)
        cubes = np.floor(centroids / self.parameters.cube_size).astype(np.int64)
        return np.floor_divide(cubes, self.block_cubes)

    def _refine_own(self, mesh: Mesh, own: np.ndarray, surface, stages: Stages):
        """Stage "refine" of the faces `own` (F,) bool of `mesh` and ``REFINE_RINGS`` rings
        around them, on the block's `surface`: the refined mesh, and (F',) bool its faces
        that lie in one of `own`."""
        marked = np.zeros(mesh.n_vertices, dtype=bool)
        marked[mesh.faces[own]] = True
        part = own | face_rings(mesh.faces, marked, REFINE_RINGS)
        ((piece, _),) = cut(mesh, np.where(part, 0, -1), 1)
        with stages.stage("refine"):
            refined = refine_traced(
                piece, surface, noise=self.parameters.noise, levels=self.config.refine_levels
            )
        add_counts(stages.counts, refined.counts)
        return refined.mesh, own[part][refined.parent]

    def _seal_seams(self, index, piece: Mesh) -> Mesh:
        """`piece` with its boundary vertices that a finished neighbour's mesh holds moved
        onto that neighbour's copies (they agree to rounding), the seams counted."""
        ends = _boundary_vertices(piece)
        vertices = piece.vertices.copy()
        matched = np.zeros(piece.n_vertices, dtype=bool)
        gap = 0.0
        position = len(self._entries)
        for n in self._neighbours(index):
            other = self._blocks.get(n)
            if n == tuple(index) or other is None or other.boundary is None or not ends.size:
                continue
            distance, row = build_tree(other.boundary).query(vertices[ends])
            close = distance <= SEAM_MATCH * self.parameters.cube_size
            # One to one: a copy two of this block's vertices are near is neither's.
            taken = np.bincount(row[close], minlength=other.boundary.shape[0])
            close &= taken[row] == 1
            if close.any():
                vertices[ends[close]] = other.boundary[row[close]]
                matched[ends[close]] = True
                gap = max(gap, float(distance[close].max()))
                pair = (self._position[n], position)
                self._seams[pair] = self._seams.get(pair, 0) + int(np.count_nonzero(close))
        if gap > SEAM_TOLERANCE * self.parameters.cube_size:
            self.stats["blocks_moved_at_seams"] += 1
        self.stats["seam_vertex_gap"] = max(self.stats.get("seam_vertex_gap", 0.0), gap)
        self._welded_vertices += piece.n_vertices - int(np.count_nonzero(matched))
        return Mesh(vertices=vertices, faces=piece.faces)

    def _record(self, index, piece: Mesh) -> None:
        """Keep block `index`'s final mesh (local frame): its boundary for the neighbours
        still to finish, the mesh itself, or its file and the manifest."""
        block = self._blocks[index]
        block.boundary = piece.vertices[_boundary_vertices(piece)]
        self._position[index] = len(self._entries)
        self._faces += piece.n_faces
        tile = self._tile(index)
        entry = {"index": list(index), "owned": _owned(tile, self._origin, self.parameters)}
        if self.folder is None:
            self._meshes[index] = piece
            self._entries.append(entry)
            return
        name = "block-{}-{}-{}.ply".format(*index)
        placed = piece.translated(self._origin)
        io.write_mesh(self.folder / name, placed)
        bounds = np.r_[placed.vertices.min(axis=0), placed.vertices.max(axis=0)]
        self._entries.append(
            entry | {"file": name, "vertices": placed.n_vertices, "faces": placed.n_faces,
                     "bounds": bounds.tolist()}
        )  # fmt: skip
        self._write_manifest()

    def _write_manifest(self) -> Path:
        """The manifest of the blocks finished so far (`zeroset.tile_output`), atomically."""
        manifest = {
            "format": FORMAT,
            "grid": None,
            "vertices": self._welded_vertices,
            "faces": self._faces,
            "tiles": self._entries,
            "seams": [
                {"tiles": [a, b], "vertices": n} for (a, b), n in sorted(self._seams.items())
            ],
        }
        return io.write_json(self.folder / MANIFEST, manifest)

    def _drop(self, reach: int) -> None:
        """Forget the points no block still to contour reads, the pieces no block still to
        finish welds, and the boundaries no block still to finish matches."""
        for index, block in self._blocks.items():
            near = self._neighbours(index, reach)
            held = self.inspection is not None and not block.finished  # for the inspection
            if block.points is not None and not held and all(
                self._state(n, "contoured") for n in near
            ):
                block.points = block.viewpoints = None
            if all(self._state(n, "finished") for n in self._neighbours(index)):
                block.piece = block.surface = None
                block.boundary = None

    def _warn_drift(self) -> None:
        """A `SurfaceWarning` where finished blocks' own points would have chosen other
        parameters than the ones held."""
        held = self.parameters
        if held is None or not self._drift:
            return
        rho = np.array([d[1] for d in self._drift])
        noise = np.array([d[2] for d in self._drift])
        off = (np.abs(rho / held.rho_delta - 1.0) > PARAMETER_DRIFT) | (
            np.abs(noise / held.noise - 1.0) > PARAMETER_DRIFT
        )
        self.stats["blocks_drifted"] = int(np.count_nonzero(off))
        if off.any():
            warnings.warn(
                f"{int(off.sum())} of {off.size} blocks would have chosen other parameters "
                f"from their own points (rho_delta {rho.min():.4g}-{rho.max():.4g}, noise "
                f"{noise.min():.4g}-{noise.max():.4g}; held {held.rho_delta:.4g} and "
                f"{held.noise:.4g}): give parameters measured on such a stretch",
                SurfaceWarning,
                stacklevel=3,
            )


class _NotYet(Exception):
    """A block reads points of a block that may still get some."""


#: Counts a block's stages add to the run's.
_BLOCK_COUNTS = frozenset(
    {
        "phase1_points",
        "outliers",
        "gap_bridge_points",
        "bowtie_vertices_split",
        "small_holes_filled",
        "widest_hole_filled",
        "small_components_dropped",
        "rim_faces_removed",
        "edges_split",
        "projection_held",
        "simplify_collapses",
        "simplify_splits",
        "simplify_strays",
        "tiles_grown",
    }
)


def _boundary_vertices(mesh: Mesh) -> np.ndarray:
    """(B,) the vertices of `mesh` on its boundary, in increasing order."""
    return np.unique(boundary_edges(mesh.faces))


def _box_distance(point: np.ndarray, low: np.ndarray, size: float) -> float:
    """Distance from `point` (3,) to the cube ``[low, low + size]``."""
    return float(np.linalg.norm(np.maximum(np.maximum(low - point, point - low - size), 0.0)))


def _owned(tile: Tile, origin: np.ndarray, parameters: Parameters) -> list:
    """``[[x, y, z], [x, y, z]]`` corners of a block's cubes, input coordinates."""
    return [(origin + parameters.cube_size * np.asarray(e, float)).tolist() for e in tile.owned]


def _time(timings: dict, name: str, start: float) -> None:
    """Add the seconds since `start` to ``timings[name]``."""
    timings[name] = timings.get(name, 0.0) + time.perf_counter() - start
