"""zeroset: triangle meshes from noisy point clouds (Hoppe's zero-set reconstruction)."""

from .config import ReconstructionConfig
from .errors import InputError, ReconstructionError, SurfaceWarning, ZerosetError
from .optimization import OptimizationResult
from .optimization import optimize_mesh as optimize
from .pipeline import Reconstruction, reconstruct
from .types import DistanceField, Mesh, Orientation, Parameters, PointCloud, TangentPlanes

__all__ = [
    "DistanceField",
    "InputError",
    "Mesh",
    "OptimizationResult",
    "Orientation",
    "Parameters",
    "PointCloud",
    "Reconstruction",
    "ReconstructionConfig",
    "ReconstructionError",
    "SurfaceWarning",
    "TangentPlanes",
    "ZerosetError",
    "optimize",
    "reconstruct",
]

__version__ = "0.1.0"
