"""Scans for `zeroset.live`: a cloud cut into the scans it was made of, and a folder watched
for new scan files, as a robot writes them."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["follow", "read_column", "split_scans"]


def split_scans(viewpoints, *, column=None, every: float | None = None) -> list[np.ndarray]:
    """The rows of each scan of a cloud whose points lie in the order they were measured.

    By a per-point `column` (N,) (a scan index or a time): each run of equal values is a
    scan, or with `every`, each run of equal ``floor(column / every)``. Else by the sensor
    positions `viewpoints` (N, 3): a scan ends where the sensor has moved more than
    `every` (data units) from where the scan began.

    Returns
    -------
    list of (n,) int64
        The rows of each scan, in order.

    Raises
    ------
    InputError
        Without a column, if `every` is missing or not positive.
    """
    if column is not None:
        column = np.asarray(column, dtype=np.float64)
        if not np.isfinite(column).all():
            raise InputError("the column to split the scans by holds non-finite values")
        label = column if every is None else np.floor(column / _positive(every))
        starts = np.flatnonzero(np.r_[True, label[1:] != label[:-1]])
    else:
        if every is None:
            raise InputError(
                "splitting a cloud by its sensor positions needs --split-every, the "
                "distance the sensor moves between two scans"
            )
        every = _positive(every)
        viewpoints = np.asarray(viewpoints, dtype=np.float64)
        starts, first = [0], viewpoints[0]
        # Steps of a robot are few: walk the jumps, not the points.
        away = np.flatnonzero(np.linalg.norm(np.diff(viewpoints, axis=0), axis=1) > 0) + 1
        for row in away:
            if np.linalg.norm(viewpoints[row] - first) > every:
                starts.append(int(row))
                first = viewpoints[row]
        starts = np.asarray(starts)
    n = len(column) if column is not None else len(viewpoints)
    return [np.arange(a, b) for a, b in zip(starts, np.r_[starts[1:], n], strict=True)]


def read_column(path, name: str) -> np.ndarray:
    """The per-point property `name` (N,) of a PLY file, or array of an NPZ file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        from plyfile import PlyData

        vertex = PlyData.read(str(path))["vertex"]
        names = [p.name for p in vertex.properties]
        if name not in names:
            raise InputError(f"{path}: has no point property {name!r} (it has {names})")
        return np.asarray(vertex[name], dtype=np.float64)
    if suffix == ".npz":
        with np.load(path) as arrays:
            if name not in arrays:
                raise InputError(f"{path}: has no array {name!r} (it has {list(arrays)})")
            return np.asarray(arrays[name], dtype=np.float64).reshape(-1)
    raise InputError(f"{path}: a column to split by is read from PLY or NPZ files only")


def follow(folder, suffixes, *, idle: float, poll: float = 1.0, seen=()) -> Iterator[Path]:
    """Yield each new file of `folder` whose suffix is one of `suffixes`, in name order,
    once its size and time have held still for one `poll` (seconds); stop after `idle`
    seconds without one. Hidden files (a writer's temporary ones) are never taken."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: is not a folder to follow")
    taken = {Path(p).resolve() for p in seen}
    sizes: dict = {}
    last = time.monotonic()
    while time.monotonic() - last <= idle:
        ready = []
        for path in sorted(folder.iterdir()):
            if path.name.startswith(".") or path.suffix.lower() not in suffixes:
                continue
            if path.resolve() in taken or not path.is_file():
                continue
            stat = path.stat()
            now = (stat.st_size, stat.st_mtime_ns)
            if sizes.get(path) == now:
                ready.append(path)
            sizes[path] = now
        for path in ready:
            taken.add(path.resolve())
            yield path
            last = time.monotonic()
        if not ready:
            time.sleep(poll)


def _positive(value: float) -> float:
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"--split-every must be a positive number; got {value!r}")
    return float(value)
