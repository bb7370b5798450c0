"""Several scans in one frame: poses matched to scan files, points moved, sensors kept."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import PurePath

import numpy as np

from ._rigid import transform
from ._validate import as_poses, as_vector3
from .errors import InputError
from .types import PointCloud

__all__ = ["match_poses", "merge_scans"]


def match_poses(scans: Sequence[str | os.PathLike], names, poses, *, source: str) -> np.ndarray:
    """The pose of every scan file, (S, 4, 4), from poses read with `zeroset.io.read_poses`.

    Named poses are matched by file name (``bun000.ply``), else by name without suffix
    (``bun000``); unnamed ones must be as many as the scans and are taken in order.

    Raises
    ------
    InputError
        If a scan has no pose or the counts differ; the message starts with `source`.
    """
    if names is None:
        if len(poses) != len(scans):
            raise InputError(
                f"{source}: holds {len(poses)} unnamed poses for {len(scans)} scans; "
                "give one per scan, in the order of the scans, or name them"
            )
        return np.asarray(poses)
    by_name = {name: pose for name, pose in zip(names, poses, strict=True)}
    by_stem = {PurePath(name).stem: pose for name, pose in by_name.items()}
    matched = []
    for scan in scans:
        path = PurePath(scan)
        pose = by_name.get(path.name, by_stem.get(path.stem))
        if pose is None:
            raise InputError(f"{source}: has no pose for {os.fspath(scan)} (names: {names})")
        matched.append(pose)
    return np.array(matched)


def merge_scans(clouds: Sequence[PointCloud], poses=None, *, viewpoint=None) -> PointCloud:
    """One cloud from several scans, moved into one frame, each point keeping its sensor.

    Parameters
    ----------
    clouds : sequence of PointCloud
        The scans, each in its own frame.
    poses : (S, 4, 4) array_like of float, optional
        Rigid pose of each scan, ``p_world = R p + t``; None when the scans share a frame.
    viewpoint : (3,) array_like of float, optional
        The sensor's position in each scan's own frame, for scans whose file carries no
        per-point sensor positions. With `poses` it defaults to the scan frame's origin,
        where a laser scanner's own frame puts it.

    Returns
    -------
    PointCloud
        ``points`` (N, 3) in the common frame; ``normals`` rotated when every scan has them;
        ``viewpoints`` (N, 3) in the common frame, a row of NaN for a point whose sensor is
        not known, None when no point's is; ``intensity`` when every scan has it.
    """
    if not clouds:
        raise InputError("no scans to merge")
    if poses is not None:
        poses = as_poses(poses, [cloud.source or f"scan {i}" for i, cloud in enumerate(clouds)])
        if len(poses) != len(clouds):
            raise InputError(f"{len(poses)} poses for {len(clouds)} scans")
        if viewpoint is None:
            viewpoint = np.zeros(3)
    if viewpoint is not None:
        viewpoint = as_vector3(viewpoint, "viewpoint")
    identity = np.eye(4)
    points, normals, sensors = [], [], []
    for index, cloud in enumerate(clouds):
        pose = identity if poses is None else poses[index]
        points.append(transform(pose, cloud.points))
        if cloud.normals is not None:
            normals.append(transform(pose, cloud.normals, rotate_only=True))
        if cloud.viewpoints is not None:
            sensors.append(transform(pose, cloud.viewpoints))
        elif viewpoint is not None:
            sensors.append(np.broadcast_to(transform(pose, viewpoint[None]), cloud.points.shape))
        else:
            sensors.append(np.full(cloud.points.shape, np.nan))
    viewpoints = np.concatenate(sensors)
    intensities = [cloud.intensity for cloud in clouds]
    return PointCloud(
        points=np.concatenate(points),
        normals=np.concatenate(normals) if len(normals) == len(clouds) else None,
        viewpoints=None if np.isnan(viewpoints).all() else viewpoints,
        intensity=None if any(i is None for i in intensities) else np.concatenate(intensities),
        source=", ".join(str(cloud.source) for cloud in clouds),
        reduction={},
    )
