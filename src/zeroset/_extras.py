"""Optional dependencies: each feature beyond the core names the extra that installs it.

The core (`pip install zeroset`) reads and writes PLY, XYZ-like text and NumPy files and
runs phases 1 and 2. Every other feature imports its library through `require`, which
fails with one line naming the extra to install.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import MissingExtraError

__all__ = ["EXTRAS", "require"]

#: Extra of each optional module, as declared in pyproject.toml.
EXTRAS = {
    "distributed": "tiles",
    "laspy": "las",
    "matplotlib": "render",
    "moderngl": "render",
    "PIL": "render",
    "pye57": "e57",
    "pypcd4": "pcd",
    "small_gicp": "register",
    "trimesh": "mesh",
}


def require(module: str, feature: str) -> ModuleType:
    """Import `module` (a key of ``EXTRAS``, or one of its submodules) for `feature`.

    Raises
    ------
    MissingExtraError
        If it is not installed: "FEATURE needs the 'EXTRA' extra: pip install
        'zeroset[EXTRA]'".
    """
    extra = EXTRAS[module.partition(".")[0]]
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise MissingExtraError(
            f"{feature} needs the '{extra}' extra: pip install 'zeroset[{extra}]'"
        ) from error
