"""Frozen result objects passed between the pipeline stages.

Every array field is made read-only on construction; take ``.copy()`` to edit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ._validate import as_faces, as_points

__all__ = [
    "DistanceField",
    "Frozen",
    "Mesh",
    "Neighbourhoods",
    "Orientation",
    "Parameters",
    "PointCloud",
    "TangentPlanes",
]


def _rows(values):
    """`values` as they are, or, when empty (``[]``, an empty array), as (0, 3): no rows."""
    empty = values.size == 0 if isinstance(values, np.ndarray) else len(values) == 0
    return np.empty((0, 3)) if empty else values


class Frozen:
    """Mixin: every ndarray field is read-only; a writeable one is copied first, so the
    caller's arrays stay theirs to change."""

    def __post_init__(self) -> None:
        for f in fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                if value.flags.writeable:
                    value = value.copy()
                    object.__setattr__(self, f.name, value)
                value.flags.writeable = False


@dataclass(frozen=True, eq=False)
class PointCloud(Frozen):
    """Points read from a file, with whatever per-point data the file carried.

    Attributes
    ----------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    viewpoints : (N, 3) float64 or None
        Sensor position for every point, when the file carries one.
    intensity : (N,) float64 or None
        Return strength of every point, in the file's units, when it carries one.
    source : str or None
        The file the cloud was read from.
    reduction : dict
        When the file was cropped or sub-sampled while it was read: the points it held
        (``input_points``) and how many each step removed (``cropped``, ``sampled_out``,
        ``voxel_merged``); else empty.
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    viewpoints: np.ndarray | None = None
    intensity: np.ndarray | None = None
    source: str | None = None
    reduction: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Neighbourhoods(Frozen):
    """The k nearest points of every point, itself first.

    Attributes
    ----------
    indices : (N, k) int64
    distances : (N, k) float64, ascending along each row
    """

    indices: np.ndarray
    distances: np.ndarray

    @property
    def k(self) -> int:
        """Number of neighbours per point, the point itself included."""
        return self.indices.shape[1]


@dataclass(frozen=True)
class Parameters:
    """Scale parameters of a reconstruction and how each was chosen.

    Attributes
    ----------
    rho_delta : float
        Neighbourhood radius rho+delta (Hoppe 1992, §3.2), in data units.
    cube_size : float
        Edge length of the contouring grid's cubes, in data units.
    min_neighbours : int
        A point with fewer other points within `rho_delta` is an outlier.
    spacing : float
        Sampling density rho: a quantile of the distance to the k-th neighbour.
    noise : float
        Noise level sigma: median RMS distance of small neighbourhoods from their plane.
    quadric_noise : float
        Noise level measured by quadric fits (jets) of radius `rho_delta`
        (`zeroset.jets.quadric_noise`): it holds no curvature, where `noise` does, and only
        the detail finer than rho+delta. The jets' supports are chosen with it.
    averaging_cell : float
        Size of the cubic cells the points are averaged in before the tangent planes are
        fitted; 0 when the points are used as they are.
    notes : tuple of str
        One line per parameter: its value and where it came from.
    noise_model : (intercept, slope) of float, or None
        The range-noise model ``sigma(r) = intercept + slope r`` to use for every point with
        a known sensor (`zeroset.density.range_noise`); None fits one to the points at hand.
        Live blocks hold one, measured once, so that each block's radii follow one model
        and not its own points' (`zeroset.live`).
    """

    rho_delta: float
    cube_size: float
    min_neighbours: int
    spacing: float
    noise: float
    quadric_noise: float
    averaging_cell: float = 0.0
    notes: tuple[str, ...] = field(default=())
    noise_model: tuple[float, float] | None = None


@dataclass(frozen=True, eq=False)
class TangentPlanes(Frozen):
    """Tangent plane of every point (Hoppe 1992, §3.2).

    Attributes
    ----------
    centroids : (N, 3) float64
        Centroid o_i of each neighbourhood.
    normals : (N, 3) float64
        Unit normal n_i (eigenvector of the smallest covariance eigenvalue), not yet oriented.
    eigenvalues : (N, 3) float64
        Covariance eigenvalues, ascending, in squared data units.
    neighbour_count : (N,) int64
        Points in each neighbourhood, the point itself included.
    """

    centroids: np.ndarray
    normals: np.ndarray
    eigenvalues: np.ndarray
    neighbour_count: np.ndarray


#: `Orientation.method` when viewpoints were given but not trusted.
VIEWPOINTS_UNTRUSTED = "mst, viewpoints untrusted"


@dataclass(frozen=True, eq=False)
class Orientation(Frozen):
    """Consistently oriented normals.

    Attributes
    ----------
    normals : (N, 3) float64
        Oriented unit normals.
    flipped : (N,) bool
        Which input normals were negated.
    component : (N,) int64
        Connected component of the orientation graph each point belongs to.
    roots : (C,) int64
        The point whose orientation seeded each component.
    method : str
        ``"mst"``, ``"mst+viewpoints"``, or ``VIEWPOINTS_UNTRUSTED`` when the sensors
        disagreed with the tree too often, and smoothly, to anchor any point
        (`zeroset.orientation.UNTRUSTED`).
    disagreement : float or None
        With viewpoints: the share of the points that face their sensor clearly whose
        sensor and the spanning tree alone (each component's sign set by its sensors' vote)
        orient them oppositely; None without.
    turned : int
        Components turned whole so as not to point the same way as a neighbouring one
        across the gap between them (without viewpoints, see `zeroset.orientation`).
    """

    normals: np.ndarray
    flipped: np.ndarray
    component: np.ndarray
    roots: np.ndarray
    method: str
    disagreement: float | None = None
    turned: int = 0

    @property
    def viewpoints_untrusted(self) -> bool:
        """Whether viewpoints were given but oriented no point (`method`)."""
        return self.method == VIEWPOINTS_UNTRUSTED

    @property
    def n_components(self) -> int:
        """Number of connected components of the orientation graph."""
        return int(self.roots.size)


@dataclass(frozen=True, eq=False)
class DistanceField(Frozen):
    """Signed distance sampled on a sparse band of one global lattice.

    Grid vertex ``(i, j, k)`` lies at ``origin + cube_size * (i, j, k)``.

    Attributes
    ----------
    vertices_ijk : (V, 3) int64
        Lattice indices of the evaluated grid vertices, sorted by key.
    values : (V,) float64
        Signed distance at each vertex in data units; NaN where undefined.
    origin : (3,) float64
    cube_size : float
    """

    vertices_ijk: np.ndarray
    values: np.ndarray
    origin: np.ndarray
    cube_size: float

    @property
    def positions(self) -> np.ndarray:
        """(V, 3) float64 coordinates of the grid vertices."""
        return self.origin + self.cube_size * self.vertices_ijk


@dataclass(frozen=True, eq=False)
class Mesh(Frozen):
    """Triangle mesh.

    Attributes
    ----------
    vertices : (M, 3) float64
    faces : (F, 3) int64, counter-clockwise seen from outside

    Both are coerced on construction, as trimesh's setters do: any (K, 3) array-like of
    finite numbers (faces of whole numbers, each indexing a vertex; an empty list for
    none) becomes a new C-contiguous array of its dtype, and anything else raises
    `zeroset.errors.InputError` (`TypeError` where it holds no numbers).
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        vertices = as_points(_rows(self.vertices), "Mesh vertices", min_rows=0)
        faces = as_faces(_rows(self.faces), vertices.shape[0], "Mesh faces")
        for name, value in (("vertices", vertices), ("faces", faces)):
            value.flags.writeable = False  # new arrays: no second copy
            object.__setattr__(self, name, value)

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def translated(self, offset) -> Mesh:
        """The same faces on the vertices moved by `offset` (3,)."""
        return Mesh(vertices=self.vertices + offset, faces=self.faces)
