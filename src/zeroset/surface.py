"""The local surface whose zero set phase 1 contours: what every kind provides, and the
registry of kinds.

Phase 1 fits tangent planes to the points and orients them (Hoppe et al. 1992); a local
surface, fitted with them, then gives the signed distance wherever the planes say the
data reach. Hoppe's own choice is the nearest plane (`zeroset.normals.NearestPlanes`);
zeroset's default blends quadric jets (`zeroset.jets.Jets`). Every stage works through the
methods below, so a new kind is one module and one line of ``SURFACES``::

    from zeroset.surface import SURFACES
    SURFACES["mine"] = "mypackage.mine:MySurface"  # a subclass of Surface
    zeroset.reconstruct(points, surface="mine")
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from functools import cached_property
from importlib import import_module
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    import numpy as np

    from .config import ReconstructionConfig
    from .types import Parameters, TangentPlanes

__all__ = ["SURFACES", "Surface", "surface_kind"]

#: The kinds of local surface, by the name ``ReconstructionConfig.surface`` gives, each as
#: ``"module:class"`` (loaded on first use).
SURFACES = {
    "jets": "zeroset.jets:Jets",
    "planes": "zeroset.normals:NearestPlanes",
}


def surface_kind(name: str) -> type[Surface]:
    """The `Surface` subclass registered under `name` in ``SURFACES``."""
    module, _, attribute = SURFACES[name].partition(":")
    return getattr(import_module(module), attribute)


class Surface(ABC):
    """A signed distance near the data, made of local fits centred at ``centres`` (J, 3).

    Values are positive on the side the oriented normals point to, in data units.
    """

    #: Every value depends only on fits and points within this many rho+delta of it (the
    #: halo that tiles give each other, `zeroset.tiles`).
    reach: ClassVar[float]
    #: Whether the surface is smooth and knows its curvature: stage "refine" then moves the
    #: vertices onto it and splits the edges whose chords sag.
    smooth: ClassVar[bool]

    centres: np.ndarray

    @cached_property
    def tree(self):
        """The k-d tree of `centres`, built once."""
        from .neighbours import build_tree  # SciPy loads with the first tree, not the config

        return build_tree(self.centres)

    @classmethod
    @abstractmethod
    def fit(
        cls,
        points: np.ndarray,
        owner: np.ndarray,
        planes: TangentPlanes,
        parameters: Parameters,
        config: ReconstructionConfig,
    ) -> Surface:
        """Fit to `points` (N, 3), each in the cell of the tangent plane `owner` (N,) gives
        (-1 where its cell was dropped); the planes are not yet oriented."""

    @abstractmethod
    def oriented(self, centroids: np.ndarray, normals: np.ndarray, *, tree=None) -> Surface:
        """The same fits turned to agree with the oriented planes (`centroids`, `normals`
        (M, 3); `tree` over the centroids where built)."""

    @abstractmethod
    def evaluate(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (M,) and its gradient (M, 3) at `positions` (M, 3)."""

    def uncertainty(self, noise: float) -> float | None:
        """Typical standard error of the surface's position where points of noise level
        `noise` (data units) were fitted, in data units; None where this kind does not
        know it (then no tolerance is chosen from it)."""
        return None

    @abstractmethod
    def curvature_at(self, positions: np.ndarray) -> np.ndarray:
        """(M,) largest absolute principal curvature near each of `positions`, in 1 / data
        units."""

    @abstractmethod
    def select(self, rows) -> Surface:
        """The fits of `rows` (a mask or indices of ``centres``)."""

    @classmethod
    @abstractmethod
    def concatenate(cls, parts: list) -> Surface:
        """One surface of the fits of every one of `parts`, in order."""

    @abstractmethod
    def describe(self) -> dict:
        """What a run reports of it: ``surface_function`` (one line), and its counts (each
        declared in `zeroset.stats.SCHEMA`)."""
