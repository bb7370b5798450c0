"""The inner problem: vertex positions for fixed connectivity (Hoppe et al. 1993, §3.2).

Alternate (a) the exact projection of every data point onto the mesh, and (b) the linear
least-squares problem for the vertex positions given those projections,

    min_V  sum_i |x_i - sum_c b_ic v_c|^2 + kappa sum_edges |v_j - v_k|^2,

solved with one sparse factorisation for all three coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from .._kernels import evaluate as _kernels
from ..topology import edge_face_pairs, fold_cosines
from .energy import distance_energy, spring_energy

__all__ = ["Projection", "fit_vertices", "on_itself", "project"]

# Weight of the proximal term mu |v - v_old|^2 that makes the system definite where a
# vertex has neither points nor springs, relative to the largest diagonal entry. It
# cannot raise the energy: the minimiser of f + mu |v - v_old|^2 has f(v) <= f(v_old).
_PROXIMAL = 1e-9


@dataclass(frozen=True, eq=False)
class Projection:
    """The closest point of the mesh to every data point.

    Attributes
    ----------
    face : (N,) int64
        Face holding the closest point.
    bary : (N, 3) float64
        Its barycentric coordinates in that face, in the face's corner order.
    distance2 : (N,) float64
        Squared distance from the point to it.
    """

    face: np.ndarray
    bary: np.ndarray
    distance2: np.ndarray

    def take(self, rows) -> Projection:
        """The projection of the points `rows` (indices or a mask) only, in that order."""
        return Projection(
            face=self.face[rows], bary=self.bary[rows], distance2=self.distance2[rows]
        )


def project(
    points: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    guess: np.ndarray | None = None,
    in_order: bool = False,
) -> Projection:
    """Project each point (N, 3) exactly onto the mesh (vertices (M, 3), faces (F, 3)).

    One search of the bounding-volume hierarchy of :mod:`zeroset.evaluate` gives the
    nearest face, exact over all faces (so no point is lost because its foot falls outside
    a triangle or above a peak), the barycentric coordinates of the closest point in it and
    the squared distance. `guess` (N,), a face per point from an earlier projection,
    makes the search faster; `in_order` says that the points are in
    :func:`~zeroset.neighbours.spatial_order` already.
    """
    face, bary, distance2 = _kernels.closest_points_on_mesh(
        points, vertices, faces, guess, in_order
    )
    return Projection(face=face, bary=bary, distance2=distance2)


def on_itself(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, Projection]:
    """The vertices of a mesh (each of some face) and then its face centroids, (V + F, 3),
    and their projection onto it: each vertex at a corner of one of its faces, each
    centroid at the middle of its face."""
    n_v, n_f = vertices.shape[0], faces.shape[0]
    face_of_vertex = np.empty(n_v, dtype=np.int64)
    face_of_vertex[faces.ravel()] = np.repeat(np.arange(n_f), 3)
    corner = np.argmax(faces[face_of_vertex] == np.arange(n_v)[:, None], axis=1)
    bary = np.zeros((n_v, 3))
    bary[np.arange(n_v), corner] = 1.0
    projection = Projection(
        face=np.concatenate([face_of_vertex, np.arange(n_f)]),
        bary=np.concatenate([bary, np.full((n_f, 3), 1.0 / 3.0)]),
        distance2=np.zeros(n_v + n_f),
    )
    return np.concatenate([vertices, vertices[faces].mean(axis=1)]), projection


def fit_vertices(
    points: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    edges: np.ndarray,
    *,
    kappa: float,
    projection: Projection | None = None,
    min_cos: float = -1.0,
    max_iterations: int = 10,
    tolerance: float = 1e-4,
    in_order: bool = False,
    limits: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
    settled: float = 0.0,
) -> tuple[np.ndarray, Projection, int]:
    """Optimise the vertex positions for fixed connectivity; never raises the energy.

    Nor does it fold the mesh: a solve is kept only if it leaves no more pairs of
    neighbouring faces folded beyond `min_cos` than before, none sharper than the sharpest
    before, and no degenerate face. With `limits`, the corners of every face that a solve
    takes a point farther from than its limit keep their places, until no point is.

    Parameters
    ----------
    points : (N, 3) float64
    vertices : (M, 3) float64
    faces : (F, 3) int64
    edges : (E, 2) int64
        The mesh's undirected edges, each once (the springs).
    kappa : float
        Spring constant.
    projection : Projection, optional
        The points' projection onto the mesh as given, if already known.
    min_cos : float
        Cosine of the largest fold between neighbouring face normals that a solve may add.
    max_iterations : int
        Most alternations of projection and solve.
    tolerance : float
        Stop when an alternation lowers E_dist + E_spring by less than this share.
    in_order : bool
        The points are in :func:`~zeroset.neighbours.spatial_order` (faster projections).
    limits : (N,) float64, optional
        Distance from the mesh that each point may not pass (inf: none); every point lies
        within it on the given mesh. Default: none.
    fixed : (M,) bool, optional
        Vertices that keep their places. Default: none.
    settled : float
        Stop also when a solve moves no vertex farther than this (data units).

    Returns
    -------
    vertices : (M, 3) float64
    projection : Projection
        Of the points onto the returned mesh.
    iterations : int
        Solves that were kept.
    """
    if projection is None:
        projection = project(points, vertices, faces, in_order=in_order)
    energy = distance_energy(projection.distance2) + spring_energy(vertices, edges, kappa)
    spring = _spring_matrix(edges, vertices.shape[0], kappa)
    pairs = edge_face_pairs(faces)
    folds = _folds(vertices, faces, pairs, min_cos)
    kept = 0
    for _ in range(max_iterations):
        trial = _solve(points, vertices, faces, projection, spring)
        if fixed is not None:
            trial[fixed] = vertices[fixed]
        trial_projection = project(points, trial, faces, guess=projection.face, in_order=in_order)
        if limits is not None:
            trial, trial_projection = _hold_back(
                points, vertices, faces, projection, trial, trial_projection, limits, in_order
            )
        trial_folds = _folds(trial, faces, pairs, min_cos)
        if trial_folds[0] > folds[0] or (trial_folds[0] > 0 and trial_folds[1] < folds[1]):
            break
        trial_energy = distance_energy(trial_projection.distance2) + spring_energy(
            trial, edges, kappa
        )
        if not trial_energy < energy:
            break
        improvement = (energy - trial_energy) / max(energy, 1e-300)
        step = float(np.max(np.linalg.norm(trial - vertices, axis=1), initial=0.0))
        vertices, projection, energy, folds = trial, trial_projection, trial_energy, trial_folds
        kept += 1
        if improvement < tolerance or step <= settled:
            break
    return vertices, projection, kept


def _hold_back(points, vertices, faces, before, trial, projection, limits, in_order):
    """The `trial` positions (M, 3) with the corners of the faces that hold a point farther
    than its limit (N,) back at `vertices`, both its face on `trial` and its face `before`
    (its projection onto `vertices`, within the limit), repeated until no point is
    farther; and the points' projection onto the result. Ends, since a point whose face
    before is all back lies within its limit."""
    while True:
        over = projection.distance2 > limits**2
        if not over.any():
            return trial, projection
        corners = faces[np.concatenate([projection.face[over], before.face[over]])].reshape(-1)
        trial = trial.copy()
        trial[corners] = vertices[corners]
        projection = project(points, trial, faces, guess=projection.face, in_order=in_order)


def _folds(vertices, faces, pairs, min_cos) -> tuple[int, float]:
    """How many face pairs fold beyond min_cos (degenerate faces count), and the worst cosine."""
    cosines = np.nan_to_num(fold_cosines(vertices, faces, pairs), nan=-2.0)
    return int(np.count_nonzero(cosines < min_cos)), float(cosines.min(initial=1.0))


def _spring_matrix(edges: np.ndarray, n_vertices: int, kappa: float) -> sparse.csr_matrix:
    """kappa times the graph Laplacian of the edges, (M, M)."""
    a, b = edges[:, 0], edges[:, 1]
    ones = np.full(a.size, kappa)
    adjacency = sparse.coo_matrix(
        (np.concatenate([ones, ones]), (np.concatenate([a, b]), np.concatenate([b, a]))),
        shape=(n_vertices, n_vertices),
    ).tocsr()
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sparse.diags(degree) - adjacency).tocsr()


def _solve(points, vertices, faces, projection: Projection, spring) -> np.ndarray:
    """The least-squares vertex positions for the given projections (normal equations)."""
    n, m = points.shape[0], vertices.shape[0]
    rows = np.repeat(np.arange(n), 3)
    cols = faces[projection.face].reshape(-1)
    basis = sparse.coo_matrix((projection.bary.reshape(-1), (rows, cols)), shape=(n, m)).tocsr()
    system = (basis.T @ basis + spring).tocsc()
    mu = _PROXIMAL * max(float(system.diagonal().max(initial=0.0)), 1e-300)
    system = system + mu * sparse.identity(m, format="csc")
    rhs = basis.T @ points + mu * vertices
    return splu(system).solve(np.asarray(rhs))
