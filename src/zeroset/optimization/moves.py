"""Edge collapse, split and swap on a mesh with its data points (Hoppe et al. 1993, §4).

:class:`MeshState` holds a mesh in the flat arrays of the compiled moves, together with the
projection of every data point onto it. Its ``try_*`` methods evaluate one move locally and
make it when it is legal and lowers the energy; :meth:`MeshState.run_pass` tries them on
every edge.

A pass cuts the mesh into slabs of about equal work, labelled alternately, and runs the
moves of each label on a thread of its own, then the moves near the cuts. A move of one
label touches nothing of another's (see ``_kernels.optimize.run_pass``), so the result is
the same however many cores run them, and the same from run to run.
"""

from __future__ import annotations

import enum
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .._kernels import optimize as _kernels
from .._kernels._jit import inputs
from .._unique import distinct
from ..topology import edge_keys
from ..types import Mesh
from .fit import Projection

__all__ = ["MeshState", "MoveOutcome", "MOVES"]

#: Move kinds, in the order of the rows of a tally.
MOVES = ("collapse", "split", "swap")
#: Labels of the slabs a pass cuts the mesh into: the moves of each run on a thread of
#: their own. Fixed, like the cuts, so that the result does not depend on the machine.
LABELS = 2
#: The cuts of each round, as quantiles of the work along the mesh's longest axis. Each
#: label gets half the work, and the second round's slabs hold the first round's cuts,
#: one each; a last round runs what is left on one thread.
ROUND_CUTS = ((0.25, 0.75), (0.5,))
#: A mesh of fewer faces is not cut: most of its moves would lie near a cut.
MIN_SLAB_FACES = 256


def _by_slab(owner: np.ndarray, edges: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The `edges` (E, 2) whose ends share a label of `owner`, one array per label, in
    their order, and those whose ends do not."""
    label = owner[edges]
    same = label[:, 0] == label[:, 1]
    inside = [np.ascontiguousarray(edges[same & (label[:, 0] == k)]) for k in range(LABELS)]
    return inside, edges[~same]


def _unique_edges(state) -> np.ndarray:
    """The (E, 2) edges of the state's live faces, each once, in lexicographic order."""
    n = np.int64(state.V.shape[0])
    keys = distinct(edge_keys(_kernels.edges_of(state), n))
    return np.ascontiguousarray(np.column_stack([keys // n, keys % n]))


def _by_length(state, edges: np.ndarray) -> np.ndarray:
    """`edges` (E, 2) int64 of a state, shortest first."""
    length = np.linalg.norm(state.V[edges[:, 0]] - state.V[edges[:, 1]], axis=1)
    return np.ascontiguousarray(edges[np.argsort(length, kind="stable")], dtype=np.int64)


class MoveOutcome(enum.IntEnum):
    """What became of one attempted move."""

    ACCEPTED = _kernels.ACCEPTED
    ENERGY_INCREASE = _kernels.ENERGY_INCREASE
    ILLEGAL_TOPOLOGY = _kernels.ILLEGAL_TOPOLOGY
    BAD_DIHEDRAL = _kernels.BAD_DIHEDRAL


class MeshState:
    """A mutable mesh with its data points, for the local moves.

    Parameters
    ----------
    vertices : (M, 3) float64
    faces : (F, 3) int64
        An edge-manifold, consistently oriented mesh.
    points : (N, 3) float64
    projection : Projection
        Of `points` onto the mesh.
    kappa, c_rep : float
        Spring constant and cost of a vertex.
    max_fold_degrees : float
        A move may not leave two neighbouring faces whose normals differ by more than this,
        unless they did so before the move.
    spare : float
        Room for new vertices and faces from splits, as a share of the current counts.
    limits : (N,) float64, optional
        Distance from the mesh that no move may take each point beyond (inf: none);
        default none.
    hold_boundary : bool
        No move moves the boundary: no boundary edge collapses or splits, and an edge with
        one end on the boundary collapses onto that end.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        points: np.ndarray,
        projection: Projection,
        *,
        kappa: float,
        c_rep: float,
        max_fold_degrees: float = 90.0,
        spare: float = 1.0,
        limits: np.ndarray | None = None,
        hold_boundary: bool = False,
    ) -> None:
        degree = np.bincount(faces.reshape(-1), minlength=vertices.shape[0])
        width = max(32, int(degree.max(initial=0)) + 8)
        spare_v = int(spare * vertices.shape[0]) + 16 * (LABELS + 1)
        limits = np.full(len(points), np.inf) if limits is None else limits
        self._state = _kernels.build_state(
            *inputs(
                np.asarray(vertices, dtype=np.float64),
                np.asarray(faces, dtype=np.int64),
                np.asarray(points, dtype=np.float64),
                np.square(limits, dtype=np.float64),
                np.asarray(projection.face, dtype=np.int64),
                np.asarray(projection.bary, dtype=np.float64),
                np.asarray(projection.distance2, dtype=np.float64),
            ),
            width,
            spare_v,
            2 * spare_v,
        )
        self._width = width
        self._scratch = []  # one per thread that has run moves
        self.kappa = float(kappa)
        self.c_rep = float(c_rep)
        self.min_cos = float(np.cos(np.radians(max_fold_degrees)))
        self.hold_boundary = bool(hold_boundary)
        self.last_delta = 0.0

    def _scratches(self, n: int) -> list:
        """`n` Scratch buffers for the moves, made on first use."""
        while len(self._scratch) < n:
            points = self._state.X.shape[0]
            self._scratch.append(_kernels.make_scratch(points, self._width))
        return self._scratch[:n]

    def _try(self, kernel, i: int, j: int, force: bool) -> MoveOutcome:
        result = np.zeros(2)
        (scratch,) = self._scratches(1)
        outcome = kernel(
            self._state, scratch, int(i), int(j), self.kappa, self.c_rep, self.min_cos,
            bool(force), self.hold_boundary, result,
        )  # fmt: skip
        self.last_delta = float(result[0])
        return MoveOutcome(outcome)

    def try_collapse(self, i: int, j: int, *, force: bool = False) -> MoveOutcome:
        """Collapse edge (i, j) into vertex i if legal and lowering E (if legal, with `force`)."""
        return self._try(_kernels.try_collapse, i, j, force)

    def try_split(self, i: int, j: int, *, force: bool = False) -> MoveOutcome:
        """Split edge (i, j) at a new vertex if that lowers E (always legal)."""
        return self._try(_kernels.try_split, i, j, force)

    def try_swap(self, i: int, j: int, *, force: bool = False) -> MoveOutcome:
        """Replace interior edge (i, j) by the other diagonal of its two faces."""
        return self._try(_kernels.try_swap, i, j, force)

    def run_pass(
        self, rng: np.random.Generator, max_attempts: int, edges: np.ndarray | None = None
    ) -> tuple[float, np.ndarray]:
        """Try collapse, swap and split on the edges in random order until none is left.

        `edges` (E, 2) are the candidates to start from (default: every edge); the edges
        around each accepted move join them. Returns the energy change of the accepted moves
        and the (3, 4) tally of outcomes, rows in the order of ``MOVES``, columns the values
        of :class:`MoveOutcome`. `max_attempts` bounds the moves tried in each run of the
        compiled pass (see below).

        The moves run in rounds. In each of the first two, the mesh is cut across its
        longest axis at ``ROUND_CUTS`` into slabs labelled 0, 1, 0, ...; the moves of each
        label run on a thread of their own, and a move that would touch a face of the
        other label waits for the next round. The last round runs what is left on one
        thread.
        """
        state = self._state
        if edges is None:
            edges = _unique_edges(state)
        edges = np.ascontiguousarray(edges[rng.permutation(edges.shape[0])], dtype=np.int64)
        seeds = rng.integers(0, 2**31 - 1, size=len(ROUND_CUTS) * LABELS + 1)
        # Each label fills its own share of the free slots, the last round the last share.
        slots_v = np.linspace(state.sizes[0], state.sizes[3], LABELS + 2).astype(np.int64)
        slots_f = np.linspace(state.sizes[1], state.sizes[4], LABELS + 2).astype(np.int64)
        sizes = [
            np.array([slots_v[k], slots_f[k], 0, slots_v[k + 1], slots_f[k + 1]], dtype=np.int64)
            for k in range(LABELS + 1)
        ]
        tally = np.zeros((3, 4), dtype=np.int64)
        delta = 0.0
        lanes = min(LABELS, numba.get_num_threads())
        scratches = self._scratches(lanes)
        for round_, cuts in enumerate(ROUND_CUTS):
            owner = self._slabs(cuts)
            if owner is None or edges.shape[0] == 0:
                break
            inside, crossing = _by_slab(owner, edges)
            live = np.count_nonzero(state.alive_v)
            jobs = []
            for k in range(LABELS):
                sizes[k][2] = live
                jobs.append(
                    (state._replace(sizes=sizes[k]), k, inside[k], int(seeds[round_ * LABELS + k]))
                )
            waiting = [crossing]
            for job_delta, job_tally, job_deferred in self._run_jobs(
                jobs, owner, scratches, max_attempts
            ):
                delta += job_delta
                tally += job_tally
                waiting.append(job_deferred)
            edges = np.concatenate(waiting)
            edges = np.ascontiguousarray(edges[rng.permutation(edges.shape[0])])
        sizes[-1][2] = np.count_nonzero(state.alive_v)
        state.sizes[:] = sizes[-1]
        last_delta, last_tally, _ = self._pass(
            state, -1, edges, int(seeds[-1]), scratches[0], np.zeros(1, np.int64), max_attempts
        )
        return delta + last_delta, tally + last_tally

    def collapse_within(self, normals: np.ndarray) -> int:
        """Collapse edges, shortest first, while every point stays within its limit of
        the face it lies on, and that face within ``max_fold_degrees`` of the point's unit
        normal (`normals` (N, 3); `_kernels.optimize.try_collapse_within`); the edges
        around each collapse join the end of the queue. Returns the number of collapses.

        The collapses run in the rounds of :meth:`run_pass`, the slabs of each label on a
        thread of their own.
        """
        state = self._state
        normals = np.ascontiguousarray(normals, dtype=np.float64)
        edges = _by_length(state, _unique_edges(state))
        lanes = min(LABELS, numba.get_num_threads())
        scratches = self._scratches(lanes)

        def collapse(job_state, label, job_edges, scratch, owner):
            tally = np.zeros((3, 4), dtype=np.int64)
            deferred = np.zeros((max(4 * job_edges.shape[0], 1024), 2), dtype=np.int64)
            done, n_deferred = _kernels.run_within_pass(
                job_state, scratch, normals, owner, label, job_edges, self.min_cos, tally,
                deferred,
            )  # fmt: skip
            return done, deferred[:n_deferred]

        total = 0
        for cuts in ROUND_CUTS:
            owner = self._slabs(cuts)
            if owner is None or edges.shape[0] == 0:
                break
            inside, crossing = _by_slab(owner, edges)
            live = np.count_nonzero(state.alive_v)
            # Each job counts the live vertices in a copy of its own (`sizes`).
            jobs = [(state._replace(sizes=state.sizes.copy()), k, inside[k]) for k in range(LABELS)]
            waiting = [crossing]
            arguments = [(*job, scratches[k % lanes], owner) for k, job in enumerate(jobs)]
            with ThreadPoolExecutor(lanes) as pool:  # one lane: one job after the other
                results = list(pool.map(collapse, *zip(*arguments, strict=True)))
            for done, deferred in results:
                total += done
                waiting.append(deferred)
            state.sizes[2] = live - sum(done for done, _ in results)
            edges = _by_length(state, np.concatenate(waiting))
        done, _ = collapse(state, -1, edges, scratches[0], np.zeros(1, np.int64))
        return total + done

    def _run_jobs(self, jobs, owner, scratches, max_attempts) -> list:
        """`_pass` for each (state, label, edges, seed) job, one thread per scratch."""
        lanes = len(scratches)

        def lane_jobs(lane: int) -> list:
            return [
                self._pass(*job, scratches[lane], owner, max_attempts) for job in jobs[lane::lanes]
            ]

        with ThreadPoolExecutor(lanes) as pool:
            return [result for done in pool.map(lane_jobs, range(lanes)) for result in done]

    def _pass(self, state, label, edges, seed, scratch, owner, max_attempts):
        """One compiled pass over `edges` within `label` (-1: all)."""
        tally = np.zeros((3, 4), dtype=np.int64)
        deferred = np.zeros((max(8 * edges.shape[0], 1024), 2), dtype=np.int64)
        delta, n_deferred = _kernels.run_pass(
            state, scratch, owner, label, edges, self.kappa, self.c_rep, self.min_cos,
            self.hold_boundary, seed, max_attempts, tally, deferred,
        )  # fmt: skip
        return float(delta), tally, deferred[:n_deferred]

    def _slabs(self, cuts: tuple[float, ...]) -> np.ndarray | None:
        """(Vc,) int64 label of each vertex slot (-1: none), or None for a small mesh.

        The `cuts` lie across the longest axis of the vertices' bounding box at those
        quantiles of the work, a vertex's work being the points on its faces; the slabs
        between them are labelled 0, 1, 0, ...
        """
        state = self._state
        live_f = np.flatnonzero(state.alive_f)
        if live_f.size < MIN_SLAB_FACES:
            return None
        used = np.flatnonzero(state.alive_v)
        position = state.V[used]
        axis = int(np.argmax(np.ptp(position, axis=0)))
        work = np.zeros(state.alive_v.shape[0])
        np.add.at(work, state.F[live_f].reshape(-1), np.repeat(state.count[live_f] + 1.0, 3))
        order = np.argsort(position[:, axis], kind="stable")
        cumulative = np.cumsum(work[used][order])
        at = np.searchsorted(cumulative, cumulative[-1] * np.asarray(cuts))
        owner = np.full(state.alive_v.shape[0], -1, dtype=np.int64)
        owner[used[order]] = np.searchsorted(at, np.arange(used.size), side="right") % LABELS
        return owner

    @property
    def distance2(self) -> np.ndarray:
        """(N,) squared distance of every point to the face it is assigned to."""
        return self._state.pd.copy()

    @property
    def point_faces(self) -> np.ndarray:
        """(N,) int64: the face of :meth:`to_mesh` each point is assigned to (not always
        its nearest: a move projects its points onto its own faces only)."""
        alive_f = self._state.alive_f
        return (np.cumsum(alive_f) - 1)[self._state.pf]

    @property
    def vertex_slots(self) -> np.ndarray:
        """(M,) int64: the index in the state (as the ``try_*`` methods take it) of each
        vertex of :meth:`to_mesh`."""
        return np.flatnonzero(self._state.alive_v)

    def to_mesh(self) -> Mesh:
        """The live vertices and faces as a compact Mesh."""
        state = self._state
        used = self.vertex_slots
        index = np.full(state.alive_v.shape[0], -1, dtype=np.int64)
        index[used] = np.arange(used.size)
        return Mesh(vertices=state.V[used].copy(), faces=index[state.F[state.alive_f]])
