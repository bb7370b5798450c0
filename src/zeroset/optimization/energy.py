"""The energy of a mesh against the data (Hoppe et al. 1993, §3).

``E(K, V) = E_dist + E_rep + E_spring`` with ``E_dist = sum_i d^2(x_i, mesh)``,
``E_rep = c_rep * #vertices`` and ``E_spring = kappa * sum_edges |v_j - v_k|^2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Energy", "distance_energy", "representation_energy", "spring_energy"]


@dataclass(frozen=True)
class Energy:
    """The three terms of the energy and their sum, in squared length units."""

    distance: float
    representation: float
    spring: float

    @property
    def total(self) -> float:
        return self.distance + self.representation + self.spring

    def as_dict(self) -> dict:
        """JSON-ready terms and total."""
        return {
            "distance": self.distance,
            "representation": self.representation,
            "spring": self.spring,
            "total": self.total,
        }


def distance_energy(distance2: np.ndarray) -> float:
    """Return E_dist, the sum of the squared point-to-mesh distances (N,)."""
    return float(np.sum(distance2))


def representation_energy(n_vertices: int, c_rep: float) -> float:
    """Return E_rep = c_rep * #vertices."""
    return float(c_rep) * int(n_vertices)


def spring_energy(vertices: np.ndarray, edges: np.ndarray, kappa: float) -> float:
    """Return E_spring = kappa * sum of squared edge lengths; `edges` (E, 2) int64."""
    if edges.shape[0] == 0:
        return 0.0
    delta = vertices[edges[:, 0]] - vertices[edges[:, 1]]
    return float(kappa) * float(np.einsum("ij,ij->", delta, delta))
