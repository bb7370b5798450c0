"""Names under which point files store normals and sensor positions, shared by the readers."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..errors import InputError

__all__ = ["INTENSITY", "NORMALS", "VIEWPOINTS", "XYZ", "find_group", "stack"]

XYZ = (("x", "y", "z"),)
NORMALS = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))
VIEWPOINTS = (("vp_x", "vp_y", "vp_z"), ("viewpoint_x", "viewpoint_y", "viewpoint_z"))
INTENSITY = (("intensity",), ("scalar_intensity",))


def find_group(
    names: Iterable[str], groups: tuple[tuple[str, ...], ...], what: str
) -> tuple[str, ...] | None:
    """Return the stored names of the first of `groups` present in `names`, or None.

    Matching ignores case (``NX`` is ``nx``); the returned names are spelled as stored.

    Raises
    ------
    InputError
        If only some of a group are present (``nx`` without ``nz``, say).
    """
    stored = {name.lower(): name for name in names}
    for group in groups:
        present = [name for name in group if name in stored]
        if len(present) == len(group):
            return tuple(stored[name] for name in group)
        if present:
            missing = ", ".join(name for name in group if name not in stored)
            raise InputError(f"has {what} {', '.join(present)} but not {missing}")
    return None


def stack(rows, names: tuple[str, ...] | None, what: str) -> np.ndarray | None:
    """Columns `names` of a record table as (n, 3) float64, (n,) for one name; None for None.

    `rows` is anything indexed by column name: a structured array, a laspy point record.

    Raises
    ------
    InputError
        If a column does not convert to numbers (``"{what} x, y, z are not numbers"``).
    """
    if names is None:
        return None
    try:
        columns = [np.asarray(rows[name], dtype=np.float64) for name in names]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} {', '.join(names)} are not numbers") from exc
    return columns[0] if len(columns) == 1 else np.column_stack(columns)
