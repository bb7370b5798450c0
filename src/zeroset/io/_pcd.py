"""Point Cloud Library PCD files in (ASCII, binary and binary_compressed), through pypcd4."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .._extras import require
from ..errors import InputError
from ._fields import INTENSITY, NORMALS, VIEWPOINTS, XYZ, find_group, stack
from ._sniff import check_content

__all__ = ["read_points"]

#: The optional module this format needs, and what for (`zeroset._extras.require`).
NEEDS = ("pypcd4", "reading .pcd files")

_DEFAULT_VIEWPOINT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
_MAX_HEADER_LINES = 64  # a PCD header has 11 lines, and a few comments
_MAX_LINE = 1 << 16
_LZF_RATIO = 100  # LZF expands its input at most ~88 times


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read points, normals, intensity and the viewpoint from a PCD file.

    Rows whose x, y or z is NaN are PCL's mark of "no return" in organised clouds; they are
    dropped, as PCL's ``removeNaNFromPointCloud`` does.

    Parameters
    ----------
    path : pathlib.Path
        A PCD v0.5-0.7 file with fields ``x y z`` and optionally ``normal_x normal_y
        normal_z`` (or ``nx ny nz``), ``intensity``, ``vp_x vp_y vp_z``.

    Returns
    -------
    dict
        ``points`` : (N, 3) float64; ``normals`` : (N, 3) float64 or None; ``intensity`` :
        (N,) float64 or None; ``viewpoints`` : (N, 3) float64 or None, from per-point
        ``vp_*`` fields, else from the header's ``VIEWPOINT`` translation when it is not the
        default ``0 0 0 1 0 0 0`` (PCL writes that default whether or not the sensor was at
        the origin, so it says nothing).

    Raises
    ------
    InputError
        If the file is not valid PCD, its data is shorter than its header says, or it has
        no ``x y z`` fields. Messages carry no path prefix.
    """
    pypcd4 = require(*NEEDS)

    count = _check_layout(path)
    try:
        cloud = pypcd4.PointCloud.from_path(path)
        data = cloud.pc_data
    except Exception as exc:  # pypcd4 raises many kinds (pydantic, numpy, lzf) on bad input
        raise InputError(f"not a valid PCD file ({_first_line(exc)})") from exc
    if len(data) != count:
        raise InputError(f"is truncated: the header says {count} points, it holds {len(data)}")
    names = data.dtype.names or ()
    xyz = find_group(names, XYZ, "fields")
    if xyz is None:
        raise InputError(f"has no x, y, z fields (fields: {', '.join(names) or 'none'})")
    points = stack(data, xyz, "fields")
    valid = ~np.isnan(points).any(axis=1)
    normals = find_group(names, NORMALS, "fields")
    viewpoints = stack(data, find_group(names, VIEWPOINTS, "fields"), "fields")
    pose = tuple(float(v) for v in cloud.metadata.viewpoint)
    if viewpoints is None and pose != _DEFAULT_VIEWPOINT:
        viewpoints = np.tile(pose[:3], (len(points), 1))
    intensity = stack(data, find_group(names, INTENSITY, "fields"), "fields")
    return {
        "points": points[valid],
        "normals": None if normals is None else stack(data, normals, "fields")[valid],
        "viewpoints": None if viewpoints is None else viewpoints[valid],
        "intensity": None if intensity is None else intensity[valid],
    }


def _check_layout(path: Path) -> int:
    """Return the header's point count after checking that the file can hold that many.

    pypcd4 trusts the header: it silently returns fewer points from a truncated binary
    file, and sizes its buffers for binary_compressed data by the header alone.
    """
    check_content(path, (".pcd", "text", "binary"), "PCD file")
    fields: dict[str, list[str]] = {}
    with open(path, "rb") as stream:
        for _ in range(_MAX_HEADER_LINES):
            words = stream.readline(_MAX_LINE).decode("ascii", "replace").split()
            if words and not words[0].startswith("#"):
                fields[words[0].upper()] = words[1:]
            if words[:1] == ["DATA"] or not words and stream.peek(1) == b"":
                break
        try:
            count = int(fields["POINTS"][0])
            encoding = fields["DATA"][0].lower()
            row = sum(int(a) * int(b) for a, b in zip(fields["SIZE"], fields["COUNT"], strict=True))
        except (KeyError, IndexError, ValueError):
            raise InputError("not a valid PCD file (no POINTS, DATA, SIZE, COUNT lines)") from None
        start = stream.tell()
        size = stream.seek(0, 2) - start
        stream.seek(start)
        if encoding == "binary" and size < count * row:
            raise InputError(
                f"is truncated: the header says {count} points, it holds {size // max(row, 1)}"
            )
        if encoding == "binary_compressed":
            sizes = stream.read(8)
            packed, unpacked = struct.unpack("<II", sizes) if len(sizes) == 8 else (0, -1)
            if unpacked != count * row or packed > size - 8 or unpacked > _LZF_RATIO * packed:
                raise InputError(
                    f"is truncated or corrupt: the header says {count} points of {row} bytes, "
                    f"the compressed block is {packed} bytes of {size - 8} present"
                )
    return count


def _first_line(exc: Exception) -> str:
    """The first line of an exception's message (pydantic's run over several)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
