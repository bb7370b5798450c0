"""PLY points and meshes in (through plyfile), PLY points and meshes out in float64."""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
import plyfile
from numpy.lib.recfunctions import unstructured_to_structured

from ..errors import InputError
from ._fields import INTENSITY, NORMALS, VIEWPOINTS, XYZ, find_group, stack
from ._sniff import check_content

__all__ = ["iter_chunks", "read_mesh", "read_points", "write_ply", "write_points"]


#: Bytes a header may take; plyfile parses headers a byte at a time (about 2 MB/s).
_HEADER_LIMIT = 1 << 20
_END_HEADER = re.compile(rb"(?:^|[\r\n])end_header[ \t]*(?:\r\n|\r|\n)")
_NEWLINE = re.compile(rb"\r\n|\r|\n")
_TYPE_BYTES = {
    name: size
    for names, size in (
        (("char", "uchar", "int8", "uint8"), 1),
        (("short", "ushort", "int16", "uint16"), 2),
        (("int", "uint", "int32", "uint32", "float", "float32"), 4),
        (("double", "float64"), 8),
    )
    for name in names
}


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read points, normals, viewpoints and intensity from the ``vertex`` element of a PLY file.

    Parameters
    ----------
    path : pathlib.Path
        An ASCII or binary (either byte order) PLY file.

    Returns
    -------
    dict
        ``points`` : (N, 3) float64; ``normals`` : (N, 3) float64 or None, from ``nx, ny, nz``
        (or ``normal_x, ...``); ``viewpoints`` : (N, 3) float64 or None, from
        ``vp_x, vp_y, vp_z`` or ``viewpoint_x, viewpoint_y, viewpoint_z``; ``intensity`` :
        (N,) float64 or None. Other properties (colours) and other elements (faces,
        range_grid) are ignored.

    Raises
    ------
    InputError
        If the file is not valid PLY, is shorter than its header says (checked before
        anything is read, so a header that declares 10**9 rows fails at once), has no
        ``vertex`` element, has lists for x, y or z, or has only some of the properties of
        a group (``nx`` without ``nz``, say). Messages carry no path prefix.
    """
    return next(iter_chunks(path, None))


def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read the ``vertex`` positions and ``face`` polygons of a PLY mesh, in file order.

    Parameters
    ----------
    path : pathlib.Path
        An ASCII or binary PLY file whose ``face`` element has a list property
        ``vertex_indices`` (or ``vertex_index``).

    Returns
    -------
    vertices : (M, 3) float64
    faces : (F, 3) int64
        Polygons of more than three corners are split into fans from their first corner;
        rows of fewer than three are dropped.

    Raises
    ------
    InputError
        If the file is not valid PLY or holds no triangles; messages carry no path prefix.
    """
    header = _header(path)
    if header is None:
        raise InputError("not a valid PLY file (no 'end_header' line)")
    _check_length(path, header)
    face = next((e for e in header.elements if e.name == "face"), None)
    names = [name for name, _, is_list, _ in face.properties if is_list] if face else []
    name = next((n for n in ("vertex_indices", "vertex_index") if n in names), None)
    if name is None:
        raise InputError("contains no triangles (no 'face' element with 'vertex_indices')")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            try:  # triangles only: one read of fixed-length rows, not one per row
                data = plyfile.PlyData.read(os.fspath(path), known_list_len={"face": {name: 3}})
                polygons = [np.asarray(data["face"].data[name], dtype=np.int64)]
            except (plyfile.PlyParseError, ValueError):
                data = plyfile.PlyData.read(os.fspath(path))
                polygons = [np.asarray(row, dtype=np.int64) for row in data["face"].data[name]]
    except (plyfile.PlyParseError, ValueError) as exc:
        raise InputError(f"not a valid PLY file ({exc})") from exc
    if "vertex" not in data:
        raise InputError("has no 'vertex' element")
    vertex = data["vertex"].data
    try:
        vertices = np.column_stack([vertex[axis] for axis in "xyz"]).astype(np.float64)
    except (KeyError, ValueError) as exc:
        raise InputError(f"has no x, y, z vertex properties ({exc})") from exc
    faces = _fans(polygons)
    if faces.shape[0] == 0:
        raise InputError("contains no triangles (empty, or not a valid PLY mesh)")
    return vertices, faces


def _fans(polygons: list[np.ndarray]) -> np.ndarray:
    """Triangles (F, 3): one (T, 3) array of triangles as is, or each polygon (K,) as the
    fan of its first corner."""
    if len(polygons) == 1 and polygons[0].ndim == 2:
        return polygons[0].reshape(-1, 3)
    fans = [
        np.column_stack([np.full(row.size - 2, row[0]), row[1:-1], row[2:]])
        for row in polygons
        if row.size >= 3
    ]
    return np.concatenate(fans) if fans else np.zeros((0, 3), dtype=np.int64)


def iter_chunks(path: Path, chunk_points: int | None) -> Iterator[dict[str, np.ndarray | None]]:
    """Yield what `read_points` returns, `chunk_points` rows at a time (None: all at once).

    A binary vertex element without list properties is memory-mapped, so only the rows of
    the current chunk are ever in memory; other files are parsed whole by plyfile first.
    """
    check_content(path, (".ply",), "PLY file")
    header = _header(path)
    _check_length(path, header)
    table, lists = _ascii_vertices(path, header), set()
    if table is None:
        table, lists = _plyfile_vertices(path)
    groups = {
        "points": _group(table, lists, XYZ),
        "normals": _group(table, lists, NORMALS),
        "viewpoints": _group(table, lists, VIEWPOINTS),
        "intensity": _group(table, lists, INTENSITY),
    }
    if groups["points"] is None:
        raise InputError("'vertex' element has no x, y, z properties")
    total = len(table)
    step = max(1, total if chunk_points is None else chunk_points)
    for start in range(0, max(total, 1), step):
        rows = table[start : start + step]
        yield {name: stack(rows, group, "'vertex' properties") for name, group in groups.items()}


def _plyfile_vertices(path: Path) -> tuple[np.ndarray, set[str]]:
    """The ``vertex`` rows as plyfile reads them (memory-mapped when binary without lists),
    and the names of its list properties."""
    try:
        with warnings.catch_warnings():
            # plyfile warns on empty list rows of elements we do not use (range grids).
            warnings.simplefilter("ignore", UserWarning)
            # Memory-mapped: elements without lists are read in one go, not row by row.
            data = plyfile.PlyData.read(os.fspath(path), mmap="c")
    except (plyfile.PlyParseError, ValueError) as exc:
        raise InputError(f"not a valid PLY file ({exc})") from exc
    names = [element.name for element in data.elements]
    if "vertex" not in names:
        raise InputError(f"has no 'vertex' element (elements: {', '.join(names) or 'none'})")
    vertex = data["vertex"]
    lists = {p.name for p in vertex.properties if isinstance(p, plyfile.PlyListProperty)}
    return vertex.data, lists


class _Element(NamedTuple):
    """An element of a PLY header: its rows (None where the count is not a number) and its
    properties as (name, type, is a list, line well formed)."""

    name: str
    count: int | None
    properties: list[tuple[str, str, bool, bool]]


class _Header(NamedTuple):
    """A PLY header as far as the readers need it: its format, its length in lines and
    bytes, and its elements."""

    binary: bool
    lines: int
    size: int
    elements: list[_Element]


def _header(path: Path) -> _Header | None:
    """Parse the header of a PLY file; None when a short file has no ``end_header`` (plyfile
    then says what is wrong).

    Raises
    ------
    InputError
        If the first ``_HEADER_LIMIT`` bytes hold no ``end_header``, or an element has a
        negative count.
    """
    with open(path, "rb") as stream:
        head = stream.read(_HEADER_LIMIT)
    end = _END_HEADER.search(head)
    if end is None:
        if len(head) == _HEADER_LIMIT:
            raise InputError(
                f"not a valid PLY file (no 'end_header' in its first {len(head)} bytes)"
            )
        return None
    lines = [
        line.decode("ascii", "replace").split() for line in _NEWLINE.split(head[: end.start()])
    ]
    binary = any(words[:1] == ["format"] and words[1:2] != ["ascii"] for words in lines)
    elements: list[_Element] = []
    for words in lines:
        if words[:1] == ["element"] and len(words) == 3:
            count = int(words[2]) if words[2].lstrip("-").isdigit() else None
            if count is not None and count < 0:
                raise InputError(f"not a valid PLY file (element {words[1]!r} has {count} rows)")
            elements.append(_Element(words[1], count, []))
        elif words[:1] == ["property"] and len(words) >= 3 and elements:
            is_list = words[1] == "list"
            kind = words[2] if is_list else words[1]
            well_formed = len(words) == (5 if is_list else 3) and kind in _TYPE_BYTES
            elements[-1].properties.append((words[-1], kind, is_list, well_formed))
    n_lines = len(_NEWLINE.findall(head[: end.end()]))
    return _Header(binary, n_lines, end.end(), elements)


def _ascii_vertices(path: Path, header: _Header | None) -> np.ndarray | None:
    """The ``vertex`` rows of an ASCII PLY file parsed by NumPy, a structured float64 array.

    plyfile parses ASCII rows one at a time (4 s for a 40,000-point Stanford range image,
    most of it in the range grid after the vertices); NumPy reads only the vertex lines,
    a hundred times faster. None, leaving the file to plyfile, when it is binary, its
    vertex element has list properties, or a row does not hold one number per property.
    """
    if header is None or header.binary:
        return None
    skip = header.lines
    for element in header.elements:
        if element.count is None:
            return None
        if element.name == "vertex":
            break
        skip += element.count  # an ASCII row is one line
    else:
        return None
    names = [name for name, _, is_list, well_formed in element.properties if well_formed]
    scalar = all(well_formed and not is_list for _, _, is_list, well_formed in element.properties)
    if not (scalar and names) or len(set(names)) != len(names):
        return None  # lists, or errors for plyfile to report
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # no rows: plyfile says what is wrong
            table = np.loadtxt(
                path,
                skiprows=skip,
                max_rows=element.count,
                ndmin=2,
                comments=None,
                encoding="latin-1",
            )
    except ValueError:
        return None
    if table.shape != (element.count, len(names)):
        return None
    return unstructured_to_structured(table, names=names)


def _group(table: np.ndarray, lists: set[str], groups) -> tuple[str, ...] | None:
    """The stored names of the first of `groups` the vertex rows have; lists refused."""
    names = find_group(table.dtype.names, groups, "'vertex' properties")
    if names is None:
        return None
    listed = [n for n in names if n in lists]
    if listed:
        raise InputError(f"'vertex' properties {', '.join(listed)} are lists, not numbers")
    return names


def _check_length(path: Path, header: _Header | None) -> None:
    """Refuse a file shorter than the fewest bytes the rows its header declares can take.

    This runs before plyfile allocates the rows. A binary row takes at least the bytes of
    its scalar properties and list lengths; an ASCII row, two bytes per property (one
    character and a separator). Malformed lines count for nothing, and a header that
    cannot be parsed is left for plyfile to report.
    """
    if header is None:
        return
    # The last value of an ASCII file may lack its newline.
    available = path.stat().st_size - header.size + (0 if header.binary else 1)
    needed = 0
    for element in header.elements:
        row_bytes = sum(
            _TYPE_BYTES.get(kind, 1) if header.binary else 2 for _, kind, _, _ in element.properties
        )
        needed += (element.count or 0) * row_bytes
        if needed > available:
            raise InputError(
                f"header declares {element.count} {element.name} rows, at least {needed} "
                f"bytes, but only {available} bytes follow it; the file is truncated or the "
                "header is wrong"
            )


def write_points(
    path: Path,
    points: np.ndarray,
    normals: np.ndarray | None,
    *,
    viewpoints: np.ndarray | None = None,
) -> None:
    """Write points, normals and viewpoints when given, as a binary PLY ``vertex`` element.

    Parameters
    ----------
    path : pathlib.Path
        Destination, overwritten.
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    viewpoints : (N, 3) float64, optional
        Sensor position of every point, written as ``double vp_x, vp_y, vp_z``.
    """
    write_ply(path, points, normals=normals, viewpoints=viewpoints)


def write_ply(
    path: Path,
    vertices: np.ndarray,
    *,
    normals: np.ndarray | None = None,
    viewpoints: np.ndarray | None = None,
    faces: np.ndarray | None = None,
    binary: bool = True,
) -> None:
    """Write vertices as ``double`` properties, with optional normals and triangles.

    Parameters
    ----------
    path : pathlib.Path
        Destination, overwritten.
    vertices : (N, 3) float64
    normals : (N, 3) float64, optional
        Written as ``double nx, ny, nz``.
    viewpoints : (N, 3) float64, optional
        Written as ``double vp_x, vp_y, vp_z``, the names `read_points` looks for first.
    faces : (F, 3) int64, optional
        Written as a ``face`` element with ``list uchar int vertex_indices``.
    binary : bool
        Binary little-endian when True, ASCII otherwise.

    Raises
    ------
    InputError
        If a face index does not fit the PLY ``int`` type (2**31 vertices or more).
    """
    groups = [(XYZ[0], vertices), (NORMALS[0], normals), (VIEWPOINTS[0], viewpoints)]
    groups = [(names, values) for names, values in groups if values is not None]
    columns = [name for names, _ in groups for name in names]
    table = np.hstack([values for _, values in groups])
    vertex = np.zeros(len(table), dtype=[(name, "f8") for name in columns])
    for index, name in enumerate(columns):
        vertex[name] = table[:, index]
    elements = [plyfile.PlyElement.describe(vertex, "vertex")]
    if faces is not None:
        if len(vertices) > np.iinfo(np.int32).max:
            raise InputError(f"PLY face indices are 32-bit; {len(vertices)} vertices is too many")
        face = np.zeros(len(faces), dtype=[("vertex_indices", "i4", (3,))])
        face["vertex_indices"] = faces
        elements.append(plyfile.PlyElement.describe(face, "face"))
    ply = plyfile.PlyData(elements, text=not binary, byte_order="<", comments=["zeroset"])
    ply.write(os.fspath(path))
