"""ASTM E57 scans in, through pye57 (libE57Format): every scan, in the file's frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._extras import require
from ..errors import InputError
from ._sniff import check_content

__all__ = ["read_points"]

#: The optional module this format needs, and what for (`zeroset._extras.require`).
NEEDS = ("pye57", "reading .e57 files")


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read every scan of an E57 file, moved into the file's frame by its pose.

    Each scan's points are stored in the scanner's own frame, and its pose moves them into
    the file's frame, so the pose's translation is where the scanner stood: it becomes the
    viewpoint of each of the scan's points. Points flagged invalid are dropped.

    Parameters
    ----------
    path : pathlib.Path
        An E57 file with Cartesian or spherical coordinates.

    Returns
    -------
    dict
        ``points`` : (N, 3) float64; ``viewpoints`` : (N, 3) float64; ``intensity`` : (N,)
        float64 when every scan has it, else None; ``normals`` : None.

    Raises
    ------
    InputError
        If libE57Format cannot read the file or it holds no scans. Messages carry no path
        prefix.
    """
    pye57 = require(*NEEDS)

    check_content(path, (".e57",), "E57 file")
    try:
        with pye57.E57(str(path), mode="r") as e57:
            scans = [_scan(e57, index) for index in range(e57.scan_count)]
    except InputError:
        raise
    except Exception as exc:  # libE57Format raises its own exception types
        raise InputError(f"not a valid E57 file ({exc})") from exc
    if not scans:
        raise InputError("holds no scans")
    intensity = None
    if all(scan["intensity"] is not None for scan in scans):
        intensity = np.concatenate([scan["intensity"] for scan in scans])
    return {
        "points": np.concatenate([scan["points"] for scan in scans]),
        "viewpoints": np.concatenate([scan["viewpoints"] for scan in scans]),
        "intensity": intensity,
        "normals": None,
    }


def _scan(e57, index: int) -> dict[str, np.ndarray | None]:
    """Points, viewpoints and intensity of scan `index`, in the file's frame."""
    data = e57.read_scan(index, intensity=True, transform=True, ignore_missing_fields=True)
    header = e57.get_header(index)
    points = np.column_stack(
        [data["cartesianX"], data["cartesianY"], data["cartesianZ"]]
    ).astype(np.float64)
    origin = np.asarray(header.translation, dtype=np.float64) if header.has_pose() else np.zeros(3)
    intensity = data.get("intensity")
    return {
        "points": points,
        "viewpoints": np.tile(origin, (len(points), 1)),
        "intensity": None if intensity is None else np.asarray(intensity, dtype=np.float64),
    }
