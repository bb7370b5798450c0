"""Names under which point files store normals and sensor positions, shared by the readers."""

from __future__ import annotations

from collections.abc import Iterable

from ..errors import InputError

__all__ = ["INTENSITY", "NORMALS", "VIEWPOINTS", "XYZ", "find_group"]

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
