"""Edge collapse, split and swap on a mesh with its data points (Hoppe et al. 1993, §4).

:class:`MeshState` holds a mesh in the flat arrays of the compiled moves, together with the
projection of every data point onto it. Its ``try_*`` methods evaluate one move locally and
make it when it is legal and lowers the energy; :func:`run_pass` tries them on every edge.
"""

from __future__ import annotations

import enum

import numpy as np

from .._kernels import optimize as _kernels
from ..types import Mesh
from .fit import Projection

__all__ = ["MeshState", "MoveOutcome", "MOVES"]

#: Move kinds, in the order of the rows of a tally.
MOVES = ("collapse", "split", "swap")


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
    ) -> None:
        degree = np.bincount(faces.reshape(-1), minlength=vertices.shape[0])
        width = max(32, int(degree.max(initial=0)) + 8)
        spare_v = int(spare * vertices.shape[0]) + 16
        self._state = _kernels.build_state(
            np.ascontiguousarray(vertices, dtype=np.float64),
            np.ascontiguousarray(faces, dtype=np.int64),
            np.ascontiguousarray(points, dtype=np.float64),
            np.ascontiguousarray(projection.face, dtype=np.int64),
            np.ascontiguousarray(projection.bary, dtype=np.float64),
            np.ascontiguousarray(projection.distance2, dtype=np.float64),
            width,
            spare_v,
            2 * spare_v,
        )
        self.kappa = float(kappa)
        self.c_rep = float(c_rep)
        self.min_cos = float(np.cos(np.radians(max_fold_degrees)))
        self.last_delta = 0.0

    def _try(self, kernel, i: int, j: int, force: bool) -> MoveOutcome:
        result = np.zeros(2)
        outcome = kernel(
            self._state, int(i), int(j), self.kappa, self.c_rep, self.min_cos, bool(force), result
        )
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
        of :class:`MoveOutcome`.
        """
        if edges is None:
            edges = np.unique(_kernels.edges_of(self._state), axis=0)
        edges = np.ascontiguousarray(edges[rng.permutation(edges.shape[0])], dtype=np.int64)
        tally = np.zeros((3, 4), dtype=np.int64)
        seed = int(rng.integers(0, 2**31 - 1))
        delta = _kernels.run_pass(
            self._state, edges, self.kappa, self.c_rep, self.min_cos, seed, max_attempts, tally
        )
        return float(delta), tally

    @property
    def distance2(self) -> np.ndarray:
        """(N,) squared distance of every point to the face it is assigned to."""
        return self._state.pd.copy()

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
