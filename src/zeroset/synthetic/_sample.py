"""The `Sample` result, noise, outliers and writing a sample with its truth mesh."""

from __future__ import annotations

import numbers
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validate import as_points, positive, require_rng
from ..errors import InputError
from ..types import Mesh

__all__ = ["Sample", "add_noise", "add_outliers", "write_sample"]


@dataclass(frozen=True, eq=False)
class Sample:
    """Points on a known surface, with the surface's exact distance and a truth mesh.

    Arrays are read-only; take ``.copy()`` to edit.

    Attributes
    ----------
    points : (N, 3) float64
        Samples, noise and outliers included.
    normals : (N, 3) float64
        Unit normals of the true surface at the noise-free samples: outward for closed
        surfaces, away from the pipe axis for pipes (so a sensor inside a pipe sees their
        backs). Rows of outliers are (0, 0, 0).
    distance : callable
        ``distance(x)`` maps (M, 3) positions to the (M,) exact unsigned distances to the
        true surface (see each generator's Notes for how exact).
    area : float
        Area of the true surface.
    truth_mesh : callable or None
        ``truth_mesh(spacing=None) -> Mesh``: a dense mesh of the true surface built from its
        parametrisation, every vertex on the surface, consistently oriented like `normals`,
        with open boundaries where the surface has them. `spacing` is the target edge length;
        the default is 1/300 of the bounding-box diagonal, coarsened when that would take
        more than `MAX_FACES` faces. The mesh is built on the first call and the default one
        is kept, so `truth` costs nothing the second time.
    viewpoints : (N, 3) float64 or None
        Sensor position of every point for simulated scans; None for surface samples.
    is_outlier : (N,) bool or None
        Which points are outliers (see `add_outliers`); None only for hand-made samples.
    truth_record : dict or None
        A JSON-able description of the truth beyond the mesh, for generators whose truth
        has named parts (the defects of `damaged_pipe` and `scan_damaged_pipe`; the path,
        centreline, defects, joints and tees of `pipe_run` and `scan_pipe_run`); None
        otherwise. `write_sample` writes it beside the points as ``<stem>-truth.json``.
    """

    points: np.ndarray
    normals: np.ndarray
    distance: Callable[[np.ndarray], np.ndarray]
    area: float
    truth_mesh: Callable[..., Mesh] | None = None
    viewpoints: np.ndarray | None = None
    is_outlier: np.ndarray | None = None
    truth_record: dict | None = None

    def __post_init__(self) -> None:
        for name in ("points", "normals", "viewpoints", "is_outlier"):
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    @property
    def truth(self) -> Mesh:
        """The default truth mesh, ``truth_mesh()``; built once, on first use."""
        if self.truth_mesh is None:
            raise AttributeError("this Sample was built without a truth mesh")
        return self.truth_mesh()


def lazy_mesh(build: Callable[[float | None], Mesh]) -> Callable[..., Mesh]:
    """Wrap a truth-mesh builder so the default-spacing mesh is built once, on demand."""
    cache: dict[str, Mesh] = {}

    def truth_mesh(spacing: float | None = None) -> Mesh:
        """Return a mesh of the true surface with edges of about `spacing` (default: 1/300 of
        the bounding-box diagonal, capped at `MAX_FACES` faces)."""
        if spacing is not None:
            return build(spacing)
        if "default" not in cache:
            cache["default"] = build(None)
        return cache["default"]

    return truth_mesh


def add_noise(points: np.ndarray, sigma: float, *, rng=None) -> np.ndarray:
    """Return `points` (N, 3) plus Gaussian noise of standard deviation `sigma` on each axis."""
    if sigma == 0:
        return points.copy()
    return points + require_rng(rng).normal(0.0, positive(sigma, "sigma"), size=points.shape)


def _count(n) -> int:
    """Return `n` as a positive int."""
    return positive(n, "n", integer=True)


def _noise(noise) -> float:
    """Return a noise level: 0 or a positive float."""
    if noise == 0:
        return 0.0
    return positive(noise, "noise")


def _fraction(value, name: str = "fraction") -> float:
    """Return `value` as a float in [0, 1)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not np.isfinite(value)
        or not 0.0 <= value < 1.0
    ):
        raise InputError(f"{name} must be a number in [0, 1); got {value!r}")
    return float(value)


def add_outliers(points, fraction: float, *, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """Append uniform outliers so that they make up `fraction` of the returned points.

    Outliers are drawn uniformly in the axis-aligned bounding box of `points` enlarged by
    10 % (5 % of its extent added on each side of each axis), the way stray returns
    (reflections, dust, mixed pixels) scatter through a scan's volume.

    Parameters
    ----------
    points : (N, 3) array_like of float
    fraction : float in [0, 1)
        Share of outliers among the returned points: ``round(fraction * N / (1 - fraction))``
        are appended.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    points : (N + K, 3) float64
        The input points followed by the K outliers.
    is_outlier : (N + K,) bool
        False for the first N rows, True for the outliers.

    Raises
    ------
    InputError
        If `points` is not a non-empty finite (N, 3) array or `fraction` is not in [0, 1).

    Examples
    --------
    >>> points, is_outlier = add_outliers(np.zeros((90, 3)) + [0, 1, 2], 0.1, rng=0)
    >>> points.shape, int(is_outlier.sum())
    ((100, 3), 10)
    """
    points = as_points(points)
    fraction = _fraction(fraction)
    rng = require_rng(rng)
    count = round(fraction * points.shape[0] / (1.0 - fraction))
    lo, hi = points.min(axis=0), points.max(axis=0)
    margin = 0.05 * (hi - lo)
    outliers = rng.uniform(lo - margin, hi + margin, size=(count, 3))
    is_outlier = np.zeros(points.shape[0] + count, dtype=bool)
    is_outlier[points.shape[0] :] = True
    return np.concatenate([points, outliers]), is_outlier


def finish(
    points: np.ndarray,
    normals: np.ndarray,
    distance: Callable[[np.ndarray], np.ndarray],
    area: float,
    build: Callable[[float | None], Mesh],
    *,
    outliers: float,
    rng: np.random.Generator,
    viewpoints: np.ndarray | None = None,
    truth_record: dict | None = None,
) -> Sample:
    """Add outliers (drawn last from `rng`, nothing drawn when 0) and assemble the Sample.

    Outliers get zero normals and, in scans, the viewpoint of a randomly chosen scan point.
    """
    is_outlier = np.zeros(points.shape[0], dtype=bool)
    if outliers > 0:
        points, is_outlier = add_outliers(points, outliers, rng=rng)
        count = points.shape[0] - normals.shape[0]
        normals = np.concatenate([normals, np.zeros((count, 3))])
        if viewpoints is not None:
            source = rng.integers(0, viewpoints.shape[0], size=count)
            viewpoints = np.concatenate([viewpoints, viewpoints[source]])
    return Sample(
        points=np.ascontiguousarray(points, dtype=np.float64),
        normals=np.ascontiguousarray(normals, dtype=np.float64),
        distance=distance,
        area=float(area),
        truth_mesh=lazy_mesh(build),
        viewpoints=viewpoints,
        is_outlier=is_outlier,
        truth_record=truth_record,
    )


def write_sample(
    sample: Sample, path: str | os.PathLike, *, spacing: float | None = None
) -> tuple[Path, Path | None]:
    """Write a sample's points as PLY and its truth mesh beside them as ``<stem>-truth.ply``.

    The points file holds ``x, y, z``, ``nx, ny, nz`` and, for scans, ``vp_x, vp_y, vp_z``
    as doubles, which `zeroset.io.read_points` reads back. A sample with a ``truth_record``
    (the damaged pipes: radius, ovality, each defect with its centre; the pipe runs also
    their path, centreline, joints and tees) also gets it as indented JSON in
    ``<stem>-truth.json``. Each file is replaced atomically (through
    `zeroset.io`), so a failed write leaves an existing file untouched.

    Parameters
    ----------
    sample : Sample
    path : str or os.PathLike
        Destination of the points, ending in ``.ply``; its directory must exist.
    spacing : float, optional
        Edge length of the truth mesh written; default that of ``sample.truth``.

    Returns
    -------
    points_path : pathlib.Path
    truth_path : pathlib.Path or None
        ``<stem>-truth.ply`` beside `path`; None when the sample has no truth mesh. The
        truth record, when there is one, goes to ``<stem>-truth.json`` beside it.

    Raises
    ------
    TypeError
        If `sample` is not a Sample.
    InputError
        If `path` does not end in ``.ply`` or a file cannot be written.

    See Also
    --------
    zeroset.io.write_points, zeroset.io.write_mesh, zeroset.io.write_json
    """
    from .. import io

    if not isinstance(sample, Sample):
        raise TypeError(f"sample must be a zeroset.synthetic.Sample; got {type(sample).__name__}")
    target = Path(path)
    if target.suffix.lower() != ".ply":
        raise InputError(f"{os.fspath(path)}: samples are written as .ply; got {target.suffix!r}")
    points_path = io.write_points(
        target, sample.points, normals=sample.normals, viewpoints=sample.viewpoints
    )
    if sample.truth_record is not None:
        io.write_json(target.with_name(f"{target.stem}-truth.json"), sample.truth_record)
    if sample.truth_mesh is None:
        return points_path, None
    truth_path = io.write_mesh(
        target.with_name(f"{target.stem}-truth.ply"), sample.truth_mesh(spacing)
    )
    return points_path, truth_path
