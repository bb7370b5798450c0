"""Joints and other ring features: where the wall changes all round the pipe at once."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, special

from ._centreline import SECTORS, Pipe, station_fits
from ._defects import BRANCH
from ._frame import clock_angles
from ._measure import Ovality
from ._unrolled import OFF_WALL, WallMap

__all__ = ["JOINT_KINDS", "Joint", "find_joints", "joint_spans"]

#: Kinds of ring feature: a gap (missing or recessed wall), an offset (the pipe beyond
#: steps sideways), a bead (a ring standing into the bore).
JOINT_KINDS = ("gap", "offset", "bead")
#: Rings' length, and the reach each side of the running median they are judged against,
#: as shares of the radius.
RING = 0.01
BASELINE = 0.25
#: Rings whose excess noise alone would reach, over the run, on average (and the same for
#: the station boundaries judged for an offset).
FALSE_ALARMS = 0.05
#: Share of the covered sectors the excess must leave the wall in, the same way.
ALL_ROUND = 0.75
#: A bead's width, as a share of the radius, for the stretch of wall it takes.
BEAD_WIDTH = 0.1
#: Offsets: the reach of the quadratics each side, the gap left next to the boundary,
#: and the smallest step reported, as shares of the radius.
OFFSET_REACH = 1.0
OFFSET_GAP = 0.5
MIN_OFFSET = 0.005


@dataclass(frozen=True)
class Joint:
    """A ring feature of the wall: a joint between two pipe lengths, or a weld's bead.

    Lengths are metres, angles degrees on the clock.

    Attributes
    ----------
    kind : {"gap", "offset", "bead"}
    axial : float
        Position along the centreline.
    size : float
        A gap's axial width, an offset's step, a bead's height into the bore.
    uncertainty : float
        One standard deviation of `size`.
    clock : float
        An offset's direction: the clock angle towards which the pipe beyond the joint
        moved; NaN for the other kinds.
    depth : float
        A gap's recess, outward from the wall (NaN where the wall is missing, or for the
        other kinds).
    """

    kind: str
    axial: float
    size: float
    uncertainty: float
    clock: float = float("nan")
    depth: float = float("nan")


def find_joints(pipe: Pipe, ovality: Ovality, wall: WallMap, located) -> tuple[Joint, ...]:
    """Find the ring features of a pipe's wall: gaps, beads and offsets, by axial position.

    `located` is ``pipe.locate(x)`` of the scan's points (or samples of the mesh), and
    `wall` their map, which gives their noise about the local wall and where the wall is
    whole: only rings whose map rows, and `BASELINE` radii round them, are defined all
    round and hold no branch are judged.

    **Gaps and beads** change the wall all round at once. The points' residuals from
    their station's section (`Ovality.section_at`) are averaged in rings `RING` radii
    long; a ring whose mean leaves the running median of the rings around it (`BASELINE`
    radii each side) by more than z of its standard errors (``noise / sqrt(n)``, z so
    that noise alone makes `FALSE_ALARMS` such rings over the run) starts a feature, and
    the neighbouring rings beyond half of it join it. A feature counts only where the
    residuals leave the wall the same way in at least `ALL_ROUND` of the sectors its
    points cover, which a dent, a deposit or a branch (one side of the pipe) does not.
    Outward it is a gap: its depth is the deepest ring's excess, its width the share of
    the recess the points there see (each point's excess over the depth, clipped to [0,
    1]) over the points per metre of wall around it. Inward it is a bead: its size is
    the largest excess of three rings running.

    **Offsets** move the pipe beyond the joint sideways, for good. The centres of the
    sections (`station_fits`), in the world, are fitted with quadratics on both sides of
    each station boundary over `OFFSET_REACH` radii, leaving out `OFFSET_GAP` radii next
    to it (there a dent pulls the sections' centres, and the centreline smooths the
    step); where the two meet the boundary apart by more than z of their standard errors,
    and more than `MIN_OFFSET` radii, the largest such step is an offset towards the clock
    of the difference. It lies at the station boundary within the gap that puts the
    fewest section centres on the wrong side's quadratic. Quadratics follow a bend's arc
    on either side, so the boundary between a straight leg and a bend shows no step.
    """
    axial, clock, distance = located
    keep = np.isfinite(axial)
    axial, clock = axial[keep], clock[keep]
    residual = distance[keep] - ovality.section_at(axial, clock, pipe.radius)
    on_wall = np.abs(residual) < OFF_WALL * pipe.radius
    axial, clock, residual = axial[on_wall], clock[on_wall], residual[on_wall]
    noise = float(np.nanmedian(wall.noise)) if np.isfinite(wall.noise).any() else 0.0
    whole = np.isfinite(wall.residual).all(axis=1) & (wall.off_wall < BRANCH).all(axis=1)
    reach = int(np.ceil(BASELINE * pipe.radius / (wall.axial_edges[1] - wall.axial_edges[0])))
    whole = ~ndimage.binary_dilation(~whole, iterations=reach, border_value=1)
    found = list(_rings(pipe, axial, clock, residual, noise, wall, whole))
    found += _offsets(pipe, located, noise)
    return tuple(sorted(found, key=lambda j: j.axial))


def joint_spans(joints, pipe: Pipe, kernel: float) -> list[tuple[float, float]]:
    """Axial stretches (start, end), metres, whose wall the `joints` change: not judged
    for defects. A ring's own width and `kernel`-smoothing reach each side; an offset's
    reach of the centreline's smoothing (the knots' spacing twice) besides."""
    spans = []
    for joint in joints:
        half = 0.5 * (joint.size if joint.kind == "gap" else BEAD_WIDTH * pipe.radius)
        if joint.kind == "offset":
            half = OFFSET_REACH * pipe.radius
        spans.append((joint.axial - half - 3 * kernel, joint.axial + half + 3 * kernel))
    return spans


def _rings(pipe: Pipe, axial, clock, residual, noise: float, wall: WallMap, whole):
    """Yield the gaps and beads among the rings of the wall (see `find_joints`): those
    whose map rows are `whole` (A,) bool."""
    step = RING * pipe.radius
    start = float(np.min(axial))
    index = ((axial - start) / step).astype(np.int64)
    n_rings = int(index.max()) + 1
    count = np.bincount(index, minlength=n_rings)
    total = np.bincount(index, residual, n_rings)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
    half = max(1, int(round(BASELINE / RING)))
    baseline = _running_median(mean, half)
    excess = mean - baseline
    error = noise / np.sqrt(np.maximum(count, 1))
    error *= _dispersion(excess / error)
    z = float(special.ndtri(1.0 - FALSE_ALARMS / (2.0 * n_rings)))
    rows, _ = wall.cells(start + step * (np.arange(n_rings) + 0.5), np.zeros(n_rings))
    strong = (np.abs(np.nan_to_num(excess)) > z * error) & (rows >= 0) & whole[rows]
    density = count.sum() / (n_rings * step)  # points per metre of wall
    sector = np.minimum((clock / (360.0 / SECTORS)).astype(np.int64), SECTORS - 1)
    for seed in np.flatnonzero(strong):
        if not strong[seed]:
            continue  # already part of a feature
        sign = np.sign(excess[seed])
        lo, hi = seed, seed
        while lo > 0 and sign * np.nan_to_num(excess[lo - 1]) > 0.5 * sign * excess[seed]:
            lo -= 1
        while hi < n_rings - 1 and sign * np.nan_to_num(excess[hi + 1]) > 0.5 * sign * excess[seed]:
            hi += 1
        strong[lo : hi + 1] = False
        members = (index >= lo) & (index <= hi)
        if not _all_round(sector[members], sign * (residual[members] - baseline[index[members]])):
            continue
        peak = lo + int(np.nanargmax(sign * excess[lo : hi + 1]))
        centre = start + step * (0.5 + np.average(np.arange(lo, hi + 1), weights=np.clip(
            np.nan_to_num(sign * excess[lo : hi + 1]), 1e-12, None)))  # fmt: skip
        if sign > 0:
            depth = float(excess[peak])
            seen = np.clip((residual[members] - baseline[index[members]]) / depth, 0.0, 1.0)
            width = float(seen.sum() / density)
            uncertainty = float(error[peak] / depth * width + step / np.sqrt(12))
            yield Joint("gap", float(centre), width, uncertainty, depth=depth)
            continue
        three = np.convolve(np.nan_to_num(-excess), np.ones(3) / 3.0, mode="same")
        best = lo + int(np.argmax(three[lo : hi + 1]))
        uncertainty = float(np.sqrt(np.sum(error[max(best - 1, 0) : best + 2] ** 2)) / 3.0)
        if three[best] > z * uncertainty:
            yield Joint("bead", float(centre), float(three[best]), uncertainty)


def _all_round(sector: np.ndarray, excess: np.ndarray) -> bool:
    """Whether the points' `excess` (positive the feature's way) is positive on average in
    at least `ALL_ROUND` of the `SECTORS` their `sector` numbers cover."""
    count = np.bincount(sector, minlength=SECTORS)
    mean = np.bincount(sector, excess, SECTORS) / np.maximum(count, 1)
    covered = count > 0
    return bool(covered.any() and np.mean(mean[covered] > 0) >= ALL_ROUND)


def _offsets(pipe: Pipe, located, noise: float) -> list[Joint]:
    """The offsets among the station boundaries of the pipe (see `find_joints`)."""
    fits = station_fits(pipe, located, oval=False)
    good = fits["fitted"] & (fits["axial"] > 0.0) & (fits["axial"] < pipe.length)
    along = fits["axial"][good]
    if along.size < 8:
        return []
    centre, tangent, up = pipe._at(along)
    right = np.cross(tangent, up)
    coef = fits["coef"][good]
    centres = centre + coef[:, 1:2] * up + coef[:, 2:3] * right
    sigma = noise * np.sqrt(2.0 / np.maximum(fits["count"][good], 1))  # a circle's centre
    reach, gap = OFFSET_REACH * pipe.radius, OFFSET_GAP * pipe.radius
    bounds = 0.5 * (along[:-1] + along[1:])
    sides = [_side_fits(along, centres, sigma, at, gap, reach) for at in bounds]
    judged = np.array([side is not None for side in sides])
    if not judged.any():
        return []
    jumps, errors = np.zeros((bounds.size, 3)), np.full(bounds.size, np.inf)
    for k in np.flatnonzero(judged):
        (before, var_b), (after, var_a) = ((q[0], inverse[0, 0]) for q, inverse in sides[k])
        jumps[k] = after - before - ((after - before) @ tangent[k]) * tangent[k]
        errors[k] = np.sqrt(var_b + var_a)
    scores = np.linalg.norm(jumps, axis=1) / errors
    # a step's size over its error is Rayleigh under noise alone: its median is 1.18
    scale = max(float(np.median(scores[judged])) / np.sqrt(2.0 * np.log(2.0)), 1.0)
    scores, errors = scores / scale, errors * scale
    z = float(special.ndtri(1.0 - FALSE_ALARMS / (2.0 * bounds.size)))
    strong = (scores > z) & (np.linalg.norm(jumps, axis=1) > MIN_OFFSET * pipe.radius)
    found = []
    while strong.any():
        k = int(np.argmax(np.where(strong, scores, -np.inf)))
        strong &= np.abs(bounds - bounds[k]) > reach + gap
        at = _split(along, centres, bounds[k], gap, sides[k])
        size = float(np.linalg.norm(jumps[k]))
        direction = jumps[k] / size
        clock = float(clock_angles(direction[None], tangent[k][None], up[k][None])[0])
        found.append(Joint("offset", at, size, float(errors[k]), clock=clock))
    return found


def _side_fits(along, centres, sigma, at: float, gap: float, reach: float):
    """Weighted quadratic fits of the section `centres` (K, 3) at positions `along` (K,)
    before and after `at`, over `reach` metres beyond a `gap` each side: for each side
    the (3, 3) coefficients in powers of (along - at), and the inverse normal matrix;
    None where a side holds fewer than four stations."""
    fits = []
    for side in (along < at - gap, along > at + gap):
        chosen = side & (np.abs(along - at) <= reach + gap)
        if np.count_nonzero(chosen) < 4:
            return None
        x = along[chosen] - at
        basis = np.stack([np.ones_like(x), x, x * x], 1)
        weight = 1.0 / sigma[chosen] ** 2
        inverse = np.linalg.pinv(basis.T @ (basis * weight[:, None]))
        fits.append((inverse @ (basis * weight[:, None]).T @ centres[chosen], inverse))
    return fits


def _split(along, centres, at: float, gap: float, sides) -> float:
    """Where, within `gap` metres of `at`, the section centres (K, 3) at `along` (K,)
    leave the quadratic of the side before for that of the side after (`sides`, from
    `_side_fits`): the station boundary that puts the fewest of them on the wrong side."""
    near = np.flatnonzero(np.abs(along - at) <= gap)
    if near.size == 0:
        return float(at)
    x = along[near] - at
    powers = np.stack([np.ones_like(x), x, x * x], 1)
    misfit = [np.linalg.norm(centres[near] - powers @ q, axis=1) for q, _ in sides]
    # cost of each split: stations before it judged by the first side, after by the second
    cost = np.r_[0.0, np.cumsum(misfit[0])] + np.r_[np.cumsum(misfit[1][::-1])[::-1], 0.0]
    split = int(np.argmin(cost))
    edges = np.r_[along[near[0]] - 0.5 * (along[near[1]] - along[near[0]]) if near.size > 1
                  else along[near[0]], 0.5 * (along[near[:-1]] + along[near[1:]]),
                  along[near[-1]]]  # fmt: skip
    return float(edges[min(split, edges.size - 1)])


def _dispersion(standardized: np.ndarray) -> float:
    """The robust spread of `standardized` values (residuals over their standard errors),
    at least 1: how much the errors understate what the rings or sections really scatter
    by (the centreline's and the sections' own errors, the scan's pattern). Ring features
    are sparse along a run (a joint every metre or more), so this median ignores them."""
    finite = np.abs(standardized[np.isfinite(standardized)])
    return max(1.4826 * float(np.median(finite)), 1.0) if finite.size else 1.0


def _running_median(values: np.ndarray, half: int) -> np.ndarray:
    """(K,) median of the finite `values` over the `half` neighbours each side."""
    padded = np.pad(values, half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(windows, axis=1)
