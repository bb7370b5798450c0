"""Phase 2: mesh optimisation against the data (Hoppe et al. 1993)."""

from .driver import OptimizationResult, optimize_mesh
from .energy import Energy, distance_energy, representation_energy, spring_energy
from .fit import Projection, fit_vertices, on_itself, project
from .moves import MOVES, MeshState, MoveOutcome

__all__ = [
    "MOVES",
    "Energy",
    "MeshState",
    "MoveOutcome",
    "OptimizationResult",
    "Projection",
    "distance_energy",
    "fit_vertices",
    "on_itself",
    "optimize_mesh",
    "project",
    "representation_energy",
    "spring_energy",
]
