"""NumPy ``.npy`` tables and ``.npz`` archives of points."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ._sniff import check_content

__all__ = ["read_points", "write_points"]

_HEADER_READERS = {
    (1, 0): np.lib.format.read_array_header_1_0,
    (2, 0): np.lib.format.read_array_header_2_0,
}


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read points from a ``.npy`` table or a ``.npz`` archive.

    A table's first three columns are the points; a table with exactly six columns also
    carries normals in columns 4-6. An archive's points are its ``points`` array (else its
    first array), read as a table; its ``normals`` and ``viewpoints`` arrays, when present,
    override or add to that. A single (3,) viewpoint is repeated for every point.

    Parameters
    ----------
    path : pathlib.Path
        A ``.npy`` or ``.npz`` file; the content decides which, not the suffix.

    Returns
    -------
    dict
        ``points`` : array, (N, 3) when well formed; ``normals`` and ``viewpoints`` : array or
        None. Shapes, dtypes and values are checked by the caller.

    Raises
    ------
    InputError
        If the file is neither format, is shorter than an array's header says (checked
        before the array is allocated), holds pickled objects or is an empty archive.
        Messages carry no path prefix.
    """
    kind = check_content(path, (".npy", ".npz"), "NPY or NPZ file")
    try:
        if kind == ".npy":
            with open(path, "rb") as stream:
                _check_array_header(stream, path.stat().st_size)
        else:
            with zipfile.ZipFile(path) as archive:
                for member in archive.infolist():
                    with archive.open(member) as stream:
                        _check_array_header(stream, member.file_size, member.filename)
        loaded = np.load(path, allow_pickle=False)
        if isinstance(loaded, np.ndarray):
            return _from_table(loaded)
        with loaded as archive:
            return _from_archive(archive)
    except InputError:
        raise
    except (ValueError, EOFError, OSError, zipfile.BadZipFile) as exc:
        raise InputError(f"not a valid NPY or NPZ file ({exc})") from exc


def _check_array_header(stream, size: int, member: str = "") -> None:
    """Refuse an NPY array holding Python objects, or longer than the `size` bytes stored.

    Raises ValueError for a malformed header.
    """
    header = _HEADER_READERS.get(np.lib.format.read_magic(stream))
    if header is None:
        return  # version 3 (UTF-8 field names): left to np.load
    shape, _, dtype = header(stream)
    where = f"array {member!r} " if member else ""
    if dtype.hasobject:
        raise InputError(
            f"{where}holds pickled Python objects, which are never loaded; save numbers"
        )
    needed = math.prod(shape) * dtype.itemsize
    available = size - stream.tell()
    if needed > available:
        raise InputError(
            f"{where}header declares {' x '.join(map(str, shape))} values, {needed} bytes, but "
            f"only {available} bytes follow it; the file is truncated or the header is wrong"
        )


def _from_table(table: np.ndarray) -> dict[str, np.ndarray | None]:
    """Split an (N, >=3) table into points and, for six columns, normals."""
    if table.ndim != 2 or table.shape[1] < 3:
        return {"points": table, "normals": None}  # the caller reports the shape
    return {"points": table[:, :3], "normals": table[:, 3:6] if table.shape[1] == 6 else None}


def _from_archive(archive) -> dict[str, np.ndarray | None]:
    """Pick points, normals and viewpoints out of an open NpzFile."""
    if not archive.files:
        raise InputError("contains no arrays")
    key = "points" if "points" in archive.files else archive.files[0]
    cloud = _from_table(archive[key])
    if "normals" in archive.files:
        cloud["normals"] = archive["normals"]
    if "viewpoints" in archive.files:
        viewpoints = archive["viewpoints"]
        if viewpoints.shape == (3,):
            viewpoints = np.tile(viewpoints, (len(cloud["points"]), 1))
        cloud["viewpoints"] = viewpoints
    return cloud


def write_points(path: Path, points: np.ndarray, normals: np.ndarray | None) -> None:
    """Write an (N, 3) table, or (N, 6) with normals, as ``.npy``.

    Parameters
    ----------
    path : pathlib.Path
        Destination, overwritten.
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    table = points if normals is None else np.hstack([points, normals])
    with open(path, "wb") as stream:
        np.save(stream, table, allow_pickle=False)
