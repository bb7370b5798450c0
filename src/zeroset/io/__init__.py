"""Read point clouds and write triangle meshes, choosing the format by file suffix.

Each format lives in one private module; the tables below map a lower-case suffix to the
function that handles it, as ``trimesh/exchange/load.py`` does. Every problem with a file
raises `InputError` with a message that starts with the path. Every writer goes through a
temporary file in the target's directory, so a failed write leaves the target untouched.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .._extras import require
from .._validate import as_faces, as_points, as_poses
from ..errors import InputError
from ..prepare import CHUNK_POINTS, reduce_chunks
from ..prepare import crop as inside
from ..types import Mesh, PointCloud
from . import _e57, _las, _mesh, _numpy, _pcd, _ply, _poses, _text
from ._atomic import atomic_target

__all__ = [
    "MESH_FORMATS",
    "POINT_FORMATS",
    "POSE_FORMATS",
    "atomic_target",
    "check_input",
    "check_output",
    "point_bounds",
    "point_chunks",
    "read_mesh",
    "read_points",
    "read_poses",
    "write_json",
    "write_mesh",
    "write_points",
]

_POINT_READERS = {
    ".3d": _text.read_3dtk_points,
    ".csv": _text.read_points,
    ".e57": _e57.read_points,
    ".las": _las.read_points,
    ".laz": _las.read_points,
    ".npy": _numpy.read_points,
    ".npz": _numpy.read_points,
    ".pcd": _pcd.read_points,
    ".ply": _ply.read_points,
    ".pts": _text.read_points,
    ".txt": _text.read_points,
    ".xyz": _text.read_points,
}
# Readers that yield a file a few million points at a time; the others read it whole.
_POINT_CHUNKS = {".las": _las.iter_chunks, ".laz": _las.iter_chunks, ".ply": _ply.iter_chunks}
_POINT_WRITERS = {
    ".npy": _numpy.write_points,
    ".ply": _ply.write_points,
    ".xyz": _text.write_points,
}
_MESH_READERS = {
    ".obj": _mesh.read_mesh,
    ".off": _mesh.read_mesh,
    ".ply": _ply.read_mesh,
    ".stl": _mesh.read_mesh,
}
_MESH_WRITERS = {
    ".obj": _mesh.write_obj,
    ".off": _mesh.write_off,
    ".ply": _mesh.write_ply,
    ".stl": _mesh.write_stl,
}

# The optional module each format needs (`zeroset._extras.require`), checked with the suffix.
_NEEDS = {
    ".e57": _e57.NEEDS,
    ".las": _las.NEEDS,
    ".laz": _las.NEEDS,
    ".obj": _mesh.NEEDS,
    ".off": _mesh.NEEDS,
    ".pcd": _pcd.NEEDS,
    ".stl": _mesh.NEEDS,
}

_POSE_READERS = {".conf": _poses.read_conf, ".csv": _poses.read_csv, ".json": _poses.read_json}

#: Suffixes `read_points` understands.
POINT_FORMATS: tuple[str, ...] = tuple(sorted(_POINT_READERS))
#: Suffixes `read_mesh` and `write_mesh` understand.
MESH_FORMATS: tuple[str, ...] = tuple(sorted(_MESH_WRITERS))
#: Suffixes `read_poses` understands.
POSE_FORMATS: tuple[str, ...] = tuple(sorted(_POSE_READERS))


def read_points(
    path: str | os.PathLike,
    *,
    crop=None,
    sample: float | None = None,
    voxel_size: float | None = None,
    seed: int | None = 0,
    chunk_points: int = CHUNK_POINTS,
    allow_empty: bool = False,
) -> PointCloud:
    """Read a point cloud with the normals, sensor positions and intensity the file has.

    This is the first stage of the pipeline: everything after it works on the validated
    arrays of the returned cloud. Given `crop`, `sample` or `voxel_size`, the cloud is
    reduced while it is read, exactly as `zeroset.reconstruct` would reduce it
    (`zeroset.prepare.reduce_chunks`); LAS and LAZ files are then read `chunk_points` at a
    time (binary PLY files too, memory-mapped), so a file far larger than memory can be read
    at a reduced density.

    Parameters
    ----------
    path : str or os.PathLike
        A file whose lower-case suffix is in `POINT_FORMATS`:

        - ``.ply``: the ``vertex`` element's ``x, y, z`` (any numeric type), ``nx, ny, nz``
          and ``vp_x, vp_y, vp_z`` (or ``viewpoint_x, ...``); ASCII or binary.
        - ``.las``, ``.laz``: scaled coordinates in float64, ``intensity``, and normals and
          viewpoints from extra dimensions named as in PLY.
        - ``.pcd``: ASCII, binary or binary_compressed; ``normal_x, ...`` (or ``nx, ...``),
          ``intensity``; viewpoints from ``vp_x, ...`` fields or a non-default
          ``VIEWPOINT``. Rows with NaN coordinates (PCL's "no return") are dropped.
        - ``.e57``: every scan in the file's frame, each point's viewpoint the position of
          the scanner that saw it, ``intensity`` when every scan has it.
        - ``.xyz``, ``.txt``, ``.csv``, ``.pts``: rows ``x y z [nx ny nz]`` separated by
          whitespace or commas, with ``#`` comments and an optional header line.
        - ``.npy``: an (N, >=3) table, normals in columns 4-6 when there are exactly six.
        - ``.npz``: arrays ``points`` (else the first), ``normals``, ``viewpoints``.
    crop : sequence of 6 floats, optional
        Keep the points inside the box ``xmin, ymin, zmin, xmax, ymax, zmax``.
    sample : float, optional
        Keep each point with this probability, in (0, 1].
    voxel_size : float, optional
        Keep the point nearest to the centroid of each occupied voxel of this size.
    seed : int or None, default 0
        Seed of `sample`.
    chunk_points : int
        Points per chunk when a LAS or LAZ file is reduced while read.
    allow_empty : bool
        Return an empty cloud, not an error, when the reduction keeps no point (a tile of
        a larger cloud may hold none).

    Returns
    -------
    PointCloud
        ``points`` : (N, 3) float64; ``normals``, ``viewpoints`` : (N, 3) float64 or None;
        ``intensity`` : (N,) float64 or None; ``source`` : `path` as a string;
        ``reduction`` : the counts of the reduction, empty when none ran.

    Raises
    ------
    InputError
        If the suffix is unknown, the file is missing, unreadable or malformed, holds no
        points (or none are left after reduction), or holds non-finite values. The
        message starts with `path`.

    See Also
    --------
    write_points, read_mesh

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = write_points(folder / "scan.xyz", np.eye(3))
    >>> read_points(folder / "scan.xyz").points.shape
    (3, 3)
    """
    target, reader = _existing(path, _POINT_READERS, "point")
    reduce = crop is not None or sample is not None or voxel_size is not None
    options = dict(crop_box=crop, sample=sample, voxel_size=voxel_size, seed=seed)
    counts: dict = {}
    with _about(path, "read"):
        chunks = _POINT_CHUNKS.get(target.suffix.lower())
        if reduce and chunks is not None:
            chunk_points = int(chunk_points)
            reduction = reduce_chunks(lambda: chunks(target, chunk_points), **options)
            columns, counts = reduction.columns, reduction.counts
        else:
            columns = _columns(reader(target))
            if reduce:
                reduction = reduce_chunks(lambda: [columns], **options)
                columns, counts = reduction.columns, reduction.counts
        if reduce and counts["input_points"] == 0:
            raise InputError("contains no points")
        if len(columns["points"]) == 0 and not allow_empty:
            left = f"no points left of {counts['input_points']} after cropping and sampling"
            raise InputError(left)
    return PointCloud(
        points=columns["points"],
        normals=columns.get("normals"),
        viewpoints=columns.get("viewpoints"),
        intensity=columns.get("intensity"),
        source=os.fspath(path),
        reduction=counts,
    )


def point_bounds(
    path: str | os.PathLike, *, crop=None, chunk_points: int = CHUNK_POINTS
) -> tuple[np.ndarray, np.ndarray, int]:
    """Bounding box ``(low (3,), high (3,))`` and number of the points of a file.

    LAS, LAZ and binary PLY files are read `chunk_points` at a time, so only a chunk is in
    memory at once; other formats are read whole. With `crop` (6,), only the points inside
    that box count.

    Raises
    ------
    InputError
        As `read_points`, and when no point lies inside `crop`.
    """
    low, high, count = np.full(3, np.inf), np.full(3, -np.inf), 0
    for points in point_chunks(path, crop=crop, chunk_points=chunk_points):
        if len(points):
            low, high = np.minimum(low, points.min(axis=0)), np.maximum(high, points.max(axis=0))
            count += len(points)
    if count == 0:
        with _about(path, "read"):
            raise InputError("contains no points" + ("" if crop is None else " inside --crop"))
    return low, high, count


def point_chunks(
    path: str | os.PathLike, *, crop=None, chunk_points: int = CHUNK_POINTS
) -> Iterator[np.ndarray]:
    """The points (n, 3) of a file, a chunk at a time: LAS, LAZ and binary PLY files
    `chunk_points` at a time, other formats whole; with `crop` (6,), those inside it."""
    target, reader = _existing(path, _POINT_READERS, "point")
    chunks = _POINT_CHUNKS.get(target.suffix.lower())
    with _about(path, "read"):
        parts = chunks(target, int(chunk_points)) if chunks else [reader(target)]
        for part in parts:
            points = _columns(part)["points"] if len(part["points"]) else np.zeros((0, 3))
            yield points if crop is None else points[inside(points, crop[:3], crop[3:])]


def read_poses(path: str | os.PathLike) -> tuple[list[str] | None, np.ndarray]:
    """Read rigid scan poses.

    Parameters
    ----------
    path : str or os.PathLike
        A file whose lower-case suffix is in `POSE_FORMATS`:

        - ``.conf``: Stanford scanalyze, ``bmesh NAME tx ty tz qx qy qz qw`` a line; a scan
          point ``p`` lies at ``R(q)^T p + t`` (``camera`` lines are skipped).
        - ``.json``: an object mapping scan file names to 4x4 matrices (lists of rows), or a
          list of 4x4 matrices in the order of the scans.
        - ``.csv``: a row per scan, ``[name,] m00, m01, ..., m33``, the matrix row by row.

    Returns
    -------
    names : list of str or None
        The scan each pose belongs to, as the file names it; None when the file gives poses
        in the order of the scans.
    poses : (S, 4, 4) float64
        ``p_world = pose[:3, :3] @ p + pose[:3, 3]``, rotations made exactly orthonormal.

    Raises
    ------
    InputError
        If the file is missing or malformed, holds no pose, or a pose is not rigid. The
        message starts with `path`.
    """
    target, reader = _existing(path, _POSE_READERS, "pose")
    with _about(path, "read"):
        names, matrices = reader(target)
        return names, as_poses(matrices, names)


def _columns(raw: dict) -> dict[str, np.ndarray]:
    """Validate a reader's arrays: finite (N, 3) points and extras, and (N,) intensity."""
    if np.size(raw["points"]) == 0:
        raise InputError("contains no points")
    columns = {"points": _checked(as_points, raw["points"], "points")}
    for name in ("normals", "viewpoints"):
        if raw.get(name) is not None:
            columns[name] = _checked(as_points, raw[name], name)
    if raw.get("intensity") is not None:
        columns["intensity"] = np.asarray(raw["intensity"], dtype=np.float64).reshape(-1)
    for name, values in columns.items():
        if len(values) != len(columns["points"]):
            raise InputError(f"has {len(columns['points'])} points but {len(values)} {name}")
    return columns


def write_points(path: str | os.PathLike, points, *, normals=None, viewpoints=None) -> Path:
    """Write points, and optionally normals and viewpoints, to ``.ply``, ``.xyz`` or ``.npy``.

    Coordinates are stored in full float64 precision: PLY ``double`` properties, 17
    significant digits in XYZ text, or a float64 array.

    Parameters
    ----------
    path : str or os.PathLike
        Destination; its directory must exist. An existing file is replaced atomically.
    points : (N, 3) array_like of float
    normals : (N, 3) array_like of float, optional
    viewpoints : (N, 3) array_like of float, optional
        Sensor position of every point; ``.ply`` only, as ``vp_x, vp_y, vp_z`` (what
        `read_points` reads back).

    Returns
    -------
    pathlib.Path
        `path`.

    Raises
    ------
    InputError
        If the suffix is not writable, the directory is missing, `points`, `normals` or
        `viewpoints` are not finite (N, 3) arrays of the same length, viewpoints are given
        for a format other than ``.ply``, or the file cannot be written. The message starts
        with `path`.

    See Also
    --------
    read_points
    """
    target, writer = _writable(path, _POINT_WRITERS, "point")
    with _about(path, "write"):
        points = as_points(points, "points")
        if normals is not None:
            normals = as_points(normals, "normals")
            if len(normals) != len(points):
                raise InputError(f"{len(points)} points but {len(normals)} normals")
        extra = {}
        if viewpoints is not None:
            if target.suffix.lower() != ".ply":
                raise InputError(
                    f"viewpoints can only be written to .ply; got {target.suffix.lower()!r}"
                )
            extra["viewpoints"] = as_points(viewpoints, "viewpoints")
            if len(extra["viewpoints"]) != len(points):
                raise InputError(f"{len(points)} points but {len(extra['viewpoints'])} viewpoints")
        with atomic_target(target) as temp:
            writer(temp, points, normals, **extra)
    return target


def read_mesh(path: str | os.PathLike) -> Mesh:
    """Read a triangle mesh from ``.ply``, ``.obj``, ``.off`` or ``.stl``.

    Vertex order is kept as stored. STL, which repeats corners per triangle, has identical
    corners merged into shared vertices in order of first appearance.

    Parameters
    ----------
    path : str or os.PathLike
        A file whose lower-case suffix is in `MESH_FORMATS`.

    Returns
    -------
    Mesh
        ``vertices`` : (M, 3) float64; ``faces`` : (F, 3) int64.

    Raises
    ------
    InputError
        If the suffix is unknown, the file is missing or malformed, has no triangles, or
        has non-finite vertices or out-of-range faces. The message starts with `path`.

    See Also
    --------
    write_mesh
    """
    target, reader = _existing(path, _MESH_READERS, "mesh")
    with _about(path, "read"):
        vertices, faces = reader(target)
        vertices = _checked(as_points, vertices, "vertices")
        faces = _checked(as_faces, faces, len(vertices))
    return Mesh(vertices=vertices, faces=faces)


def write_mesh(path: str | os.PathLike, mesh, *, binary: bool = True) -> Path:
    """Write a triangle mesh, choosing the format from the suffix.

    This is the last stage of the pipeline. Vertices and faces are written as given: nothing
    is merged, dropped or reordered.

    Parameters
    ----------
    path : str or os.PathLike
        Destination with a suffix in `MESH_FORMATS`; its directory must exist. An existing
        file is replaced atomically.
    mesh : Mesh
        Or any object with ``vertices`` (M, 3) and ``faces`` (F, 3) attributes, F >= 1.
    binary : bool, default True
        PLY and STL: binary when True, ASCII otherwise. OBJ and OFF are always text.

    Returns
    -------
    pathlib.Path
        `path`.

    Raises
    ------
    TypeError
        If `mesh` has no ``vertices`` and ``faces``.
    InputError
        If the suffix is unknown, the directory is missing, the mesh has no faces or invalid
        arrays, or the file cannot be written. The message starts with `path`.

    See Also
    --------
    read_mesh

    Notes
    -----
    PLY stores ``double`` coordinates, so coordinates near 6e6 keep better than 1e-6
    precision. OBJ and OFF store 12 decimals. Binary STL is float32 by definition (about
    7 significant digits); ASCII STL keeps float64.
    """
    target, writer = _writable(path, _MESH_WRITERS, "mesh")
    if not (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
        raise TypeError(
            f"mesh must have vertices and faces (a zeroset Mesh); got {type(mesh).__name__}"
        )
    with _about(path, "write"):
        vertices = as_points(mesh.vertices, "mesh vertices")
        faces = as_faces(mesh.faces, len(vertices), "mesh faces")
        if len(faces) == 0:
            raise InputError("mesh has no faces; nothing to write")
        with atomic_target(target) as temp:
            writer(temp, vertices, faces, binary=bool(binary))
    return target


def _lookup(path: str | os.PathLike, table: dict, kind: str):
    """Return `path` as a Path and the table entry for its lower-case suffix, once the
    optional module the format needs is known to be installed."""
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in table:
        found = f"unknown {kind} format {suffix!r}" if suffix else "has no suffix"
        raise InputError(f"{os.fspath(path)}: {found}; supported: {', '.join(sorted(table))}")
    if suffix in _NEEDS:
        require(*_NEEDS[suffix])
    return target, table[suffix]


def _existing(path: str | os.PathLike, table: dict, kind: str):
    """Check that `path` has a known suffix and is an existing regular file."""
    target, function = _lookup(path, table, kind)
    if not target.exists():
        raise InputError(f"{os.fspath(path)}: no such file")
    if target.is_dir():
        raise InputError(f"{os.fspath(path)}: is a directory, not a {kind} file")
    if not target.is_file():  # a FIFO would hang, a device would be read forever
        raise InputError(f"{os.fspath(path)}: is not a regular file")
    return target, function


def check_input(path: str | os.PathLike) -> Path:
    """Check that `path` is an existing point file of a known format, before any work.

    Raises
    ------
    InputError
        If its suffix is not in `POINT_FORMATS`, or it is missing, a folder or not a
        regular file. The message starts with `path`.
    """
    return _existing(path, _POINT_READERS, "point")[0]


def check_output(path: str | os.PathLike, *, mesh: bool = False) -> Path:
    """Check that a file can be written at `path`, before any work is done for it.

    Parameters
    ----------
    path : str or os.PathLike
    mesh : bool
        Also check that the suffix is one `write_mesh` writes.

    Returns
    -------
    pathlib.Path
        `path`.

    Raises
    ------
    InputError
        If its folder is missing, is a file or cannot be written in, `path` is a folder, or
        (with `mesh`) its suffix is not in `MESH_FORMATS`. The message starts with `path`.
    """
    if mesh:
        _lookup(path, _MESH_WRITERS, "mesh")
    target = Path(path)
    folder = target.parent
    if folder.is_file():
        raise InputError(f"{target}: {folder} is a file, not a directory")
    if not folder.is_dir():
        raise InputError(f"{target}: directory {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{target}: cannot write in {folder} (permission denied)")
    if target.is_dir():
        raise InputError(f"{target}: is a directory; give a file name")
    return target


def _writable(path: str | os.PathLike, table: dict, kind: str):
    """Check that `path` has a known suffix and can be written (`check_output`)."""
    _, function = _lookup(path, table, kind)
    return check_output(path), function


def _checked(check, values, *args):
    """Run a `_validate` check, turning its TypeError about file content into InputError."""
    try:
        return check(values, *args)
    except TypeError as exc:
        raise InputError(str(exc)) from exc


@contextmanager
def _about(path: str | os.PathLike, verb: str) -> Iterator[None]:
    """Prefix InputError messages with `path` and turn OSError into InputError."""
    try:
        yield
    except InputError as exc:
        raise InputError(f"{os.fspath(path)}: {exc}") from exc
    except OSError as exc:
        raise InputError(f"{os.fspath(path)}: cannot {verb} ({exc.strerror or exc})") from exc


def write_json(path: str | os.PathLike, data: dict) -> Path:
    """Write `data` as indented JSON, atomically; return the path written."""
    target = check_output(path)
    with atomic_target(target) as temp:
        temp.write_text(json.dumps(data, indent=2, default=_json_default) + "\n")
    return target


def _json_default(value):
    """Convert NumPy scalars and arrays for json."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
