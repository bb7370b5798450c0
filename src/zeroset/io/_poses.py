"""Rigid scan poses: Stanford ``.conf`` files, JSON and CSV tables of 4x4 matrices.

Every reader returns ``(names, matrices)``: the scan names the file gives (None when it
gives none, so poses follow the scans' order) and an (S, 4, 4) float64 array of poses
``p_world = R p + t`` with ``R = matrix[:3, :3]`` and ``t = matrix[:3, 3]``.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ..errors import InputError


def read_conf(path: Path) -> tuple[list[str], np.ndarray]:
    """Stanford scanalyze ``.conf``: ``bmesh NAME tx ty tz qx qy qz qw`` lines.

    The quaternion rotates the world into the scan, so a scan point ``p`` lies at
    ``R(q)^T p + t`` in the world (the Stanford 3D Scanning Repository's convention).
    ``camera`` lines (the viewer's position) and blank lines are skipped.
    """
    from scipy.spatial.transform import Rotation

    names, matrices = [], []
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        fields = line.split()
        if not fields or fields[0] == "camera" or fields[0].startswith("#"):
            continue
        if fields[0] != "bmesh" or len(fields) != 9:
            raise InputError(
                f"line {number}: expected 'bmesh NAME tx ty tz qx qy qz qw'; got {line.strip()!r}"
            )
        values = _numbers(fields[2:], f"line {number}")
        quaternion = values[3:]
        if not np.linalg.norm(quaternion) > 0.0:
            raise InputError(f"line {number}: the quaternion is zero")
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.from_quat(quaternion).as_matrix().T
        matrix[:3, 3] = values[:3]
        names.append(fields[1])
        matrices.append(matrix)
    if not matrices:
        raise InputError("holds no 'bmesh' pose")
    return names, np.array(matrices)


def read_json(path: Path) -> tuple[list[str] | None, np.ndarray]:
    """JSON: an object mapping scan names to 4x4 matrices, or a list of 4x4 matrices."""
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"is not valid JSON ({exc})") from exc
    if isinstance(data, dict):
        names, values = list(data), list(data.values())
    elif isinstance(data, list):
        names, values = None, data
    else:
        raise InputError("must hold an object of scan names to 4x4 matrices, or a list of them")
    if not values:
        raise InputError("holds no pose")
    matrices = []
    for index, value in enumerate(values):
        label = names[index] if names else f"pose {index}"
        try:
            matrix = np.array(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{label}: not a 4x4 matrix of numbers") from exc
        if matrix.shape != (4, 4):
            raise InputError(f"{label}: expected a 4x4 matrix; got shape {matrix.shape}")
        matrices.append(matrix)
    return names, np.array(matrices)


def read_csv(path: Path) -> tuple[list[str] | None, np.ndarray]:
    """CSV: one pose a row, ``[name,] m00, m01, ..., m33`` (the 4x4 matrix row by row).

    A first row that is not numbers is a header; ``#`` starts a comment line.
    """
    text = path.read_text()
    rows = [
        [field.strip() for field in row]
        for row in csv.reader(line for line in text.splitlines() if not line.startswith("#"))
        if any(field.strip() for field in row)
    ]
    if rows and not _is_number(rows[0][-1]):
        rows = rows[1:]
    if not rows:
        raise InputError("holds no pose")
    widths = {len(row) for row in rows}
    if widths not in ({16}, {17}):
        raise InputError(
            "every row must hold 16 numbers (a 4x4 matrix row by row), optionally after a "
            f"scan name; got rows of {sorted(widths)} fields"
        )
    named = widths == {17}
    names = [row[0] for row in rows] if named else None
    matrices = [
        _numbers(row[1:] if named else row, f"row {number}").reshape(4, 4)
        for number, row in enumerate(rows, start=1)
    ]
    return names, np.array(matrices)


def _numbers(fields: list[str], where: str) -> np.ndarray:
    """The fields as float64 numbers; InputError naming `where` if one is not a number."""
    try:
        return np.array([float(field) for field in fields])
    except ValueError as exc:
        raise InputError(f"{where}: {exc}") from exc


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
