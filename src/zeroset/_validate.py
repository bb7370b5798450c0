"""Conversion and checks at the public boundary; every stage calls these and nothing else."""

from __future__ import annotations

import numbers
import warnings

import numpy as np

from .errors import InputError

__all__ = [
    "as_faces",
    "as_points",
    "as_poses",
    "as_vector3",
    "as_viewpoints",
    "positive",
    "require_rng",
]


def as_points(values, name: str = "points", *, min_rows: int = 1) -> np.ndarray:
    """Return `values` as a new C-contiguous (N, 3) float64 array of finite rows."""
    try:
        with warnings.catch_warnings():
            # Complex values would lose their imaginary parts with only a warning.
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            array = np.array(values, dtype=np.float64, order="C", copy=True)
    except (TypeError, ValueError, np.exceptions.ComplexWarning) as exc:
        dtype = f" of {values.dtype}" if isinstance(values, np.ndarray) else ""
        raise TypeError(
            f"{name} must be an array of real numbers; got {type(values).__name__}{dtype}"
        ) from exc
    if array.ndim != 2 or array.shape[1] != 3:
        raise InputError(f"{name} must have shape (N, 3); got {array.shape}")
    if array.shape[0] < min_rows:
        what = "is empty" if array.shape[0] == 0 else f"has {array.shape[0]} rows"
        raise InputError(f"{name} {what}; at least {min_rows} are needed")
    finite = np.isfinite(array)
    if not finite.all():
        bad_rows = np.flatnonzero(~finite.all(axis=1))
        raise InputError(
            f"{name} contain {int((~finite).sum())} non-finite values in {bad_rows.size} rows "
            f"(first at row {int(bad_rows[0])}); drop or impute them first"
        )
    return array


def as_viewpoints(values, rows: int) -> np.ndarray:
    """Return sensor positions as a new (3,) or (rows, 3) float64 array.

    One position for all points must be finite; per point, a row is either finite or all
    NaN (that point's sensor is not known).
    """
    array = np.array(values, dtype=np.float64, copy=True)
    if array.shape not in ((3,), (rows, 3)):
        raise InputError(
            f"viewpoints must be three numbers or one row per point ({rows}, 3); "
            f"got shape {array.shape}"
        )
    finite = np.isfinite(array)
    known = finite.all(axis=-1) | np.isnan(array).all(axis=-1)
    if not (finite.all() if array.ndim == 1 else known.all()):
        bad = np.flatnonzero(~np.atleast_1d(known)) if array.ndim == 2 else [0]
        raise InputError(
            "viewpoints must be finite, or a whole row of NaN where a point's sensor is not "
            f"known; row {int(bad[0]) if len(bad) else 0} is neither"
        )
    return array


def as_faces(values, n_vertices: int, name: str = "faces") -> np.ndarray:
    """Return `values` as a new C-contiguous (F, 3) int64 array indexing `n_vertices`
    vertices: whole numbers, not truncated ones."""
    try:
        given = np.asarray(values)
    except ValueError as exc:  # ragged rows
        raise InputError(f"{name} must have shape (F, 3); {exc}") from None
    if not (np.issubdtype(given.dtype, np.integer) or np.issubdtype(given.dtype, np.floating)):
        raise TypeError(f"{name} must be an array of whole numbers; got {given.dtype}")
    if np.issubdtype(given.dtype, np.floating) and not np.array_equal(given, np.round(given)):
        raise InputError(f"{name} must hold whole numbers (vertex indices)")
    array = np.array(given, dtype=np.int64, order="C", copy=True)
    if array.ndim != 2 or array.shape[1] != 3:
        raise InputError(f"{name} must have shape (F, 3); got {array.shape}")
    if array.size and (array.min() < 0 or array.max() >= n_vertices):
        raise InputError(
            f"{name} index vertices outside [0, {n_vertices}); got range "
            f"[{array.min()}, {array.max()}]"
        )
    return array


#: Largest departure of a pose's rotation part from orthonormal (|R^T R - I|) accepted;
#: poses printed with six digits (Stanford .conf files) stay well within it.
POSE_TOLERANCE = 1e-4


def as_poses(values, names=None) -> np.ndarray:
    """Return rigid poses as a new (S, 4, 4) float64 array, rotations made exactly orthonormal.

    Each pose maps a scan's points into the world, ``p_world = R p + t`` with
    ``R = pose[:3, :3]`` and ``t = pose[:3, 3]``; its last row must be ``0 0 0 1`` and `R`
    a rotation (orthonormal within ``POSE_TOLERANCE``, determinant +1). `names` (S,) label
    the poses in messages.
    """
    array = np.array(values, dtype=np.float64, copy=True)
    if array.ndim != 3 or array.shape[1:] != (4, 4):
        raise InputError(f"poses must have shape (S, 4, 4); got {array.shape}")
    labels = list(names) if names is not None else [f"pose {i}" for i in range(len(array))]
    for label, pose in zip(labels, array, strict=True):
        rotation = pose[:3, :3]
        if not np.isfinite(pose).all():
            raise InputError(f"{label}: the pose holds non-finite values")
        if not np.allclose(pose[3], [0.0, 0.0, 0.0, 1.0]):
            raise InputError(f"{label}: the pose's last row must be 0 0 0 1; got {pose[3]}")
        error = np.abs(rotation.T @ rotation - np.eye(3)).max()
        if error > POSE_TOLERANCE or np.linalg.det(rotation) < 0.0:
            raise InputError(
                f"{label}: the pose's upper-left 3x3 block is not a rotation "
                f"(|R^T R - I| = {error:.2g}, det {np.linalg.det(rotation):.3g})"
            )
        u, _, vt = np.linalg.svd(rotation)
        pose[:3, :3] = u @ vt
    return array


def as_vector3(value, name: str) -> np.ndarray:
    """Return one finite 3-vector as a (3,) float64 array."""
    array = np.asarray(value, dtype=np.float64).reshape(-1)
    if array.shape != (3,) or not np.isfinite(array).all():
        raise InputError(f"{name} must be three finite numbers x, y, z; got {value!r}")
    return array


def positive(value, name: str, *, allow_none: bool = False, integer: bool = False):
    """Return `value` if it is a finite number > 0 (or None when allowed)."""
    if value is None and allow_none:
        return None
    kind = numbers.Integral if integer else numbers.Real
    if (
        isinstance(value, bool)
        or not isinstance(value, kind)
        or not np.isfinite(value)
        or value <= 0
    ):
        expected = "a positive integer" if integer else "a positive number"
        raise InputError(f"{name} must be {expected}; got {value!r}")
    return int(value) if integer else float(value)


def positive_per_row(value, name: str, rows: int) -> np.ndarray:
    """Return `value`, one positive number or one per row, as a (rows,) float64 array."""
    if np.ndim(value) == 0:
        return np.full(rows, positive(value, name))
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (rows,) or not (np.all(np.isfinite(array)) and np.all(array > 0.0)):
        raise InputError(
            f"{name} must be a positive number or {rows} of them; got shape {array.shape}"
        )
    return array


def require_rng(rng) -> np.random.Generator:
    """Return a Generator from a Generator, an integer seed or None."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, numbers.Integral) and not isinstance(rng, bool)):
        return np.random.default_rng(rng)
    raise TypeError(
        f"rng must be a numpy Generator, an integer seed or None; got {type(rng).__name__}"
    )
