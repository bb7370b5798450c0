"""zeroset: triangle meshes from noisy point clouds (Hoppe's zero-set reconstruction).

The names below load their modules on first use, so ``import zeroset`` stays quick and
imports neither NumPy, SciPy nor Numba.
"""

from importlib import import_module

from .errors import (
    InputError,
    InspectionError,
    MissingExtraError,
    ReconstructionError,
    SurfaceWarning,
    ZerosetError,
)

#: Module and attribute of each name loaded on first use.
_LAZY = {
    "DistanceField": ("types", "DistanceField"),
    "Mesh": ("types", "Mesh"),
    "OptimizationResult": ("optimization", "OptimizationResult"),
    "Orientation": ("types", "Orientation"),
    "Parameters": ("types", "Parameters"),
    "PointCloud": ("types", "PointCloud"),
    "Reconstruction": ("pipeline", "Reconstruction"),
    "ReconstructionConfig": ("config", "ReconstructionConfig"),
    "TangentPlanes": ("types", "TangentPlanes"),
    "optimize": ("optimization", "optimize_mesh"),
    "reconstruct": ("pipeline", "reconstruct"),
}

__all__ = [
    "DistanceField",
    "InputError",
    "InspectionError",
    "Mesh",
    "MissingExtraError",
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


def __getattr__(name: str):
    """Load a name of ``_LAZY`` from its module on first use."""
    if name not in _LAZY:
        raise AttributeError(f"module 'zeroset' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = getattr(import_module(f".{module}", __name__), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names, the lazy ones included."""
    return sorted({*globals(), *_LAZY})
