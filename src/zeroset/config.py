"""Every knob of a reconstruction, with its default and one line of help."""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from .errors import InputError
from .surface import SURFACES

__all__ = ["CONTOURS", "RIMS", "ReconstructionConfig"]

#: The contouring methods of phase 1.
CONTOURS = ("marching", "cubes")
#: Where open boundaries lie: cut at the edge of the data, or at whole lattice cubes.
RIMS = ("data", "cubes")


def _opt(default, help: str, **extra):
    """A dataclass field carrying its help text (read by the CLI)."""
    return field(default=default, metadata={"help": help, **extra})


@dataclass(frozen=True)
class ReconstructionConfig:
    """Parameters of :func:`zeroset.reconstruct`; None means "choose automatically"."""

    rho_delta: float | None = _opt(
        None, "neighbourhood radius rho+delta in data units (default: estimated)"
    )
    cube_size: float | None = _opt(
        None, "marching-cubes cube size (default: cube_factor x rho_delta)"
    )
    quantile: float = _opt(0.9, "quantile of neighbour distances that sets rho_delta")
    radius_k: int = _opt(12, "rank of the neighbour whose distance measures the point spacing")
    noise_factor: float = _opt(3.0, "rho_delta = spacing + noise_factor x estimated noise")
    cube_factor: float = _opt(1.5, "cube size over rho_delta when cube_size is not given")
    k_min: int = _opt(
        10, "smallest neighbourhood for a tangent plane (wider than rho_delta if needed)"
    )
    k_max: int = _opt(16, "largest neighbourhood for a tangent plane, the point included")
    min_neighbours: int = _opt(4, "points with fewer others within their radius are outliers")
    orient_k: int = _opt(8, "neighbours per point in the orientation graph")
    averaging_cell: float | None = _opt(
        None, "average the points in cubic cells of this size before fitting planes (0: never)"
    )
    sample: float | None = _opt(None, "keep each point with this probability, in (0, 1]")
    voxel_size: float | None = _opt(
        None, "keep the point nearest each voxel's centroid, voxels of this size", flag="voxel"
    )
    crop: tuple[float, float, float, float, float, float] | None = _opt(
        None, "keep points inside the box xmin,ymin,zmin,xmax,ymax,zmax"
    )
    viewpoint: tuple[float, float, float] | None = _opt(
        None, "sensor position x,y,z (in each scan's own frame): normals face it"
    )
    contour: str = _opt(
        "marching",
        "contouring: marching (marching cubes) or cubes (Method of Cubes, a vertex per cell)",
        choices=CONTOURS,
    )
    surface: str = _opt(
        "jets",
        "surface function: jets (blended quadric fits, unbiased on curved surfaces) or planes "
        "(Hoppe's signed distance to the nearest tangent plane)",
        choices=SURFACES,
    )
    fit_support: float | None = _opt(
        None, "support radius of the jets in data units (default: bias-variance rule per region)"
    )
    refine_levels: int | None = _opt(
        None,
        "split every triangle edge this many times (default: split where a chord sags, jets only)",
    )
    tolerance: float | None = _opt(
        None,
        "largest distance of the output's triangles from the dense mesh, data units (default: "
        "twice the surface's own uncertainty; 0: the dense mesh; with phase 2, none unless "
        "given)",
    )
    rim: str = _opt(
        "data",
        "open boundaries: data (cut where the data stop, within a fraction of the spacing) or "
        "cubes (whole cubes whose corners lie within reach of the data, as in Hoppe's method)",
        choices=RIMS,
    )
    gap_bridges: bool = _opt(
        True,
        "cross gaps in the sampling up to 3.5 rho_delta wide (scan bands far down a pipe) with "
        "chords that leave a point on its open side",
    )
    min_component_faces: int = _opt(20, "drop mesh components with fewer faces")
    max_hole_edges: int = _opt(
        6,
        "close boundary loops of at most this many edges that are at most 2 rho_delta "
        "across, and holes the rim cut opened that have room for no empty ball (0: none)",
    )
    c_rep: float | None = _opt(
        None, "phase 2: cost of a vertex, normalised to a unit diagonal (default: from the noise)"
    )
    kappa: float | None = _opt(
        None, "phase 2: first spring constant of the decreasing schedule (default: from the data)"
    )
    seed: int = _opt(0, "seed of every random choice")

    def __post_init__(self) -> None:
        if self.contour not in CONTOURS:
            raise InputError(f"contour must be one of {CONTOURS}; got {self.contour!r}")
        if self.surface not in SURFACES:
            raise InputError(f"surface must be one of {tuple(SURFACES)}; got {self.surface!r}")
        if not isinstance(self.gap_bridges, bool):
            raise InputError(f"gap_bridges must be True or False; got {self.gap_bridges!r}")
        if self.rim not in RIMS:
            raise InputError(f"rim must be one of {RIMS}; got {self.rim!r}")
        if self.fit_support is not None and not self.fit_support > 0:
            raise InputError(f"fit_support must be positive; got {self.fit_support!r}")
        if self.refine_levels is not None and not 0 <= self.refine_levels <= 4:
            raise InputError(f"refine_levels must lie in 0..4; got {self.refine_levels!r}")
        if self.tolerance is not None and not 0.0 <= self.tolerance < float("inf"):
            raise InputError(f"tolerance must be a distance >= 0; got {self.tolerance!r}")
        if self.k_max <= self.min_neighbours or self.k_max < self.k_min:
            raise InputError(
                f"k_max must exceed min_neighbours and be at least k_min; got k_max={self.k_max}, "
                f"k_min={self.k_min}, min_neighbours={self.min_neighbours}"
            )

    def with_overrides(self, **overrides) -> ReconstructionConfig:
        """Return a copy with the given fields replaced; unknown names raise TypeError."""
        names = {f.name for f in fields(self)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(
                f"unknown reconstruction parameter(s) {unknown}; known: {sorted(names)}"
            )
        return replace(self, **overrides)
