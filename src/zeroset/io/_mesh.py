"""Triangle meshes in and out: PLY through plyfile, OBJ, OFF and STL through trimesh.

trimesh (the ``mesh`` extra) takes about a second to import, so it is imported inside the
functions that use it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._extras import require
from ..errors import InputError
from ._ply import write_ply as _write_ply_file

__all__ = ["read_mesh", "write_obj", "write_off", "write_ply", "write_stl"]

#: The optional module this format needs, and what for (`zeroset._extras.require`).
NEEDS = ("trimesh", "reading and writing OBJ, OFF and STL meshes")

# Decimals in OBJ and OFF text. trimesh writes fixed-point, so 12 decimals round-trip a
# float64 exactly from about 1e4 upwards and to 5e-13 absolute below that.
_DIGITS = 12


def _trimesh(vertices: np.ndarray, faces: np.ndarray):
    """Wrap arrays in a trimesh.Trimesh that merges, drops and reorders nothing."""
    trimesh = require(*NEEDS)

    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray, *, binary: bool) -> None:
    """Write a PLY mesh with ``double`` vertex coordinates.

    trimesh's PLY exporter stores ``float`` (float32) coordinates, whose spacing near 6e6 m
    is 0.5 m, so PLY is written with plyfile instead.

    Parameters
    ----------
    path : pathlib.Path
        Destination, overwritten.
    vertices : (M, 3) float64
    faces : (F, 3) int64
    binary : bool
        Binary little-endian when True, ASCII otherwise.
    """
    _write_ply_file(path, vertices, faces=faces, binary=binary)


def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray, *, binary: bool) -> None:
    """Write a Wavefront OBJ mesh with `_DIGITS` decimals; OBJ is text, `binary` is ignored.

    Parameters
    ----------
    path : pathlib.Path
    vertices : (M, 3) float64
    faces : (F, 3) int64
    binary : bool
        Ignored.
    """
    trimesh = require(*NEEDS)

    text = trimesh.exchange.obj.export_obj(
        _trimesh(vertices, faces),
        include_normals=False,
        include_color=False,
        include_texture=False,
        digits=_DIGITS,
        header=None,
    )
    path.write_text(text, encoding="utf-8")


def write_off(path: Path, vertices: np.ndarray, faces: np.ndarray, *, binary: bool) -> None:
    """Write an OFF mesh with `_DIGITS` decimals; OFF is text here, `binary` is ignored.

    Parameters
    ----------
    path : pathlib.Path
    vertices : (M, 3) float64
    faces : (F, 3) int64
    binary : bool
        Ignored.
    """
    trimesh = require(*NEEDS)

    text = trimesh.exchange.off.export_off(_trimesh(vertices, faces), digits=_DIGITS)
    path.write_text(text, encoding="utf-8")


def write_stl(path: Path, vertices: np.ndarray, faces: np.ndarray, *, binary: bool) -> None:
    """Write an STL mesh: binary (float32 by the format) or ASCII (float64 repr).

    Parameters
    ----------
    path : pathlib.Path
    vertices : (M, 3) float64
    faces : (F, 3) int64
    binary : bool
        Binary STL when True, ASCII STL otherwise.
    """
    trimesh = require(*NEEDS)

    mesh = _trimesh(vertices, faces)
    if binary:
        path.write_bytes(trimesh.exchange.stl.export_stl(mesh))
    else:
        path.write_text(trimesh.exchange.stl.export_stl_ascii(mesh), encoding="utf-8")


def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read an OBJ, OFF or STL triangle mesh with trimesh, keeping vertex order.

    STL stores three corners per triangle, so identical corners are merged back into shared
    vertices, numbered in order of first appearance.

    Parameters
    ----------
    path : pathlib.Path
        A ``.obj``, ``.off`` or ``.stl`` file; the suffix names the format.

    Returns
    -------
    vertices : (M, 3) float64
    faces : (F, 3) int64
        Polygons are triangulated by trimesh.

    Raises
    ------
    InputError
        If trimesh cannot parse the file or finds no triangles in it. Messages carry no path
        prefix.
    """
    trimesh = require(*NEEDS)

    file_type = path.suffix.lower().lstrip(".")
    try:
        loaded = trimesh.load_mesh(path, file_type=file_type, process=False, maintain_order=True)
    except OSError:
        raise
    except Exception as exc:  # trimesh's parsers raise many kinds on malformed input
        raise InputError(f"not a valid {file_type.upper()} file ({exc})") from exc
    if len(loaded.faces) == 0:
        raise InputError(f"contains no triangles (empty, or not a valid {file_type.upper()} mesh)")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if file_type == "stl":
        vertices, faces = _merge_identical(vertices, faces)
    return vertices, faces


def _merge_identical(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical vertices, keeping the first occurrence's position in the order."""
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.argsort(order)
    return vertices[first[order]], rank[inverse.reshape(-1)][faces]
