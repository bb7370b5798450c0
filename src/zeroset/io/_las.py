"""ASPRS LAS and LAZ point clouds in, through laspy (LAZ decompressed by lazrs).

laspy is imported inside the functions, as trimesh is, so that importing zeroset stays light.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .._extras import require
from ..errors import InputError
from ..prepare import CHUNK_POINTS
from ._fields import NORMALS, VIEWPOINTS, find_group, stack
from ._sniff import check_content

__all__ = ["iter_chunks", "read_points"]

#: The optional module this format needs, and what for (`zeroset._extras.require`).
NEEDS = ("laspy", "reading .las and .laz files")

# The public header block up to the VLR count: signature, then at byte 94 the header size,
# the offset to the point data and the number of VLRs (LAS 1.0-1.4).
_HEADER = struct.Struct("<4s90xHII")
_VLR_HEADER = 54  # bytes of a variable-length record's header


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read a whole LAS or LAZ file, `CHUNK_POINTS` at a time (never sized by the header).

    Returns
    -------
    dict
        As `iter_chunks` yields, for every point of the file.
    """
    chunks = list(iter_chunks(path, CHUNK_POINTS))
    return {
        name: None if chunks[0][name] is None else np.concatenate([c[name] for c in chunks])
        for name in chunks[0]
    }


def iter_chunks(path: Path, chunk_points: int) -> Iterator[dict[str, np.ndarray | None]]:
    """Yield the points of a LAS or LAZ file in file order, `chunk_points` at a time.

    Coordinates are the stored integers times the header's scale plus its offset, in float64,
    so large georeferenced offsets are kept exactly as the file defines them.

    Parameters
    ----------
    path : pathlib.Path
        LAS 1.0-1.4 or LAZ; the content decides, not the suffix.
    chunk_points : int
        Points per chunk.

    Yields
    ------
    dict
        ``points`` : (n, 3) float64; ``intensity`` : (n,) float64; ``normals`` and
        ``viewpoints`` : (n, 3) float64 from extra dimensions ``nx, ny, nz`` (or
        ``normal_x, ...``) and ``vp_x, vp_y, vp_z``, else None. At least one chunk, which
        is empty for a file without points.

    Raises
    ------
    InputError
        If the file is not LAS/LAZ, is truncated, or cannot be decompressed. Messages carry
        no path prefix.
    """
    laspy = require(*NEEDS)
    import lazrs

    _check_header(path)
    try:
        with laspy.open(path) as reader:
            header = reader.header
            _check_size(path, header)
            names = list(header.point_format.dimension_names)
            normals = find_group(names, NORMALS, "extra dimensions")
            viewpoints = find_group(names, VIEWPOINTS, "extra dimensions")
            total, read = header.point_count, 0
            for record in reader.chunk_iterator(chunk_points):
                read += len(record)
                yield {
                    "points": np.column_stack([record.x, record.y, record.z]).astype(np.float64),
                    "normals": stack(record, normals, "extra dimensions"),
                    "viewpoints": stack(record, viewpoints, "extra dimensions"),
                    "intensity": np.asarray(record.intensity, dtype=np.float64),
                }
            if read == 0:
                yield _empty(normals, viewpoints)
            elif read < total:
                raise InputError(f"is truncated: the header says {total} points, it holds {read}")
    except InputError:
        raise
    except (laspy.errors.LaspyException, lazrs.LazrsError) as exc:
        raise InputError(f"not a valid LAS/LAZ file ({exc})") from exc
    except (ValueError, EOFError) as exc:
        raise InputError(f"not a valid LAS/LAZ file or truncated ({exc})") from exc


def _check_header(path: Path) -> None:
    """Reject a file whose public header block is inconsistent, before laspy parses it.

    laspy trusts the header's counts: a corrupt VLR count makes it loop for minutes.
    """
    check_content(path, (".las",), "LAS/LAZ file")
    with open(path, "rb") as stream:
        block = stream.read(_HEADER.size)
        size = stream.seek(0, 2)
    if len(block) < _HEADER.size:
        raise InputError(f"not a valid LAS/LAZ file: {size} bytes, too short for its header")
    header_size, data_offset, n_vlrs = _HEADER.unpack(block)[1:]
    if not header_size <= data_offset <= size or n_vlrs * _VLR_HEADER > data_offset - header_size:
        raise InputError(
            f"not a valid LAS/LAZ file: the header's sizes ({header_size}-byte header, "
            f"{n_vlrs} VLRs, points at byte {data_offset}) do not fit its {size} bytes"
        )


def _check_size(path: Path, header) -> None:
    """Reject an uncompressed file shorter than its header's point count needs."""
    if header.are_points_compressed:
        return
    needed = header.offset_to_point_data + header.point_count * header.point_format.size
    size = path.stat().st_size
    if size < needed:
        held = max(0, size - header.offset_to_point_data) // header.point_format.size
        raise InputError(
            f"is truncated: the header says {header.point_count} points, it holds {held}"
        )


def _empty(normals, viewpoints) -> dict[str, np.ndarray | None]:
    """The single chunk of a file without points."""
    none3 = np.zeros((0, 3))
    return {
        "points": none3,
        "normals": None if normals is None else none3,
        "viewpoints": None if viewpoints is None else none3,
        "intensity": np.zeros(0),
    }
