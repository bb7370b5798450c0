"""PLY points in (through plyfile), PLY points and meshes out in float64."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import plyfile

from ..errors import InputError

__all__ = ["read_points", "write_ply", "write_points"]

_XYZ = ("x", "y", "z")
_NORMALS = ("nx", "ny", "nz")
_VIEWPOINTS = (("vp_x", "vp_y", "vp_z"), ("viewpoint_x", "viewpoint_y", "viewpoint_z"))


def read_points(path: Path) -> dict[str, np.ndarray | None]:
    """Read points, normals and viewpoints from the ``vertex`` element of a PLY file.

    Parameters
    ----------
    path : pathlib.Path
        An ASCII or binary (either byte order) PLY file.

    Returns
    -------
    dict
        ``points`` : (N, 3) float64; ``normals`` : (N, 3) float64 or None, from ``nx, ny, nz``;
        ``viewpoints`` : (N, 3) float64 or None, from ``vp_x, vp_y, vp_z`` or
        ``viewpoint_x, viewpoint_y, viewpoint_z``. Other properties (colours, intensity) and
        other elements (faces, range_grid) are ignored.

    Raises
    ------
    InputError
        If the file is not valid PLY, has no ``vertex`` element, or has only some of the
        properties of a group (``nx`` without ``nz``, say). Messages carry no path prefix.
    """
    try:
        with warnings.catch_warnings():
            # plyfile warns on empty list rows of elements we do not use (range grids).
            warnings.simplefilter("ignore", UserWarning)
            data = plyfile.PlyData.read(os.fspath(path), mmap=False)
    except (plyfile.PlyParseError, ValueError) as exc:
        raise InputError(f"not a valid PLY file ({exc})") from exc
    names = [element.name for element in data.elements]
    if "vertex" not in names:
        raise InputError(f"has no 'vertex' element (elements: {', '.join(names) or 'none'})")
    vertex = data["vertex"]
    viewpoints = None
    for group in _VIEWPOINTS:
        viewpoints = _columns(vertex, group)
        if viewpoints is not None:
            break
    points = _columns(vertex, _XYZ)
    if points is None:
        raise InputError("'vertex' element has no x, y, z properties")
    return {"points": points, "normals": _columns(vertex, _NORMALS), "viewpoints": viewpoints}


def _columns(vertex: plyfile.PlyElement, group: tuple[str, str, str]) -> np.ndarray | None:
    """Stack three vertex properties as an (N, 3) float64 array; None if all are absent."""
    present = [name for name in group if name in vertex.data.dtype.names]
    if not present:
        return None
    if len(present) < 3:
        missing = ", ".join(name for name in group if name not in present)
        raise InputError(f"'vertex' element has {', '.join(present)} but not {missing}")
    try:
        return np.column_stack([np.asarray(vertex[name], dtype=np.float64) for name in group])
    except (TypeError, ValueError) as exc:
        raise InputError(f"'vertex' properties {', '.join(group)} are not numbers") from exc


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
    groups = [(_XYZ, vertices), (_NORMALS, normals), (_VIEWPOINTS[0], viewpoints)]
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
