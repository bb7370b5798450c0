"""Casting a rotating scanner's beams in a pipe run: where each first meets the wall.

The air in a run is its damaged bore (a `_Wall` about a `PipePath`) joined with the
straight bores of its tees' branches. A beam is marched from the scanner through that
union in steps that cannot pass the wall unseen: balls inside the undamaged tubes, exact
exits from the tube where no feature is near (a cylinder's quadratic, a torus's quartic),
the gap over its Lipschitz bound near features; the first step that ends outside is
refined to the root.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ._scanner import _beam_angles, _beam_points, _line_angles, _measure, _origins
from ._wall import _Feature, _Wall

__all__ = ["Branch", "Bore", "refine"]

# Root finding: the radial change a step may allow near the wall, the share of the
# narrowest feature it may move along the wall, the gap (m) at which a hit is final, the
# most refining iterations, how many beam samples a batch holds, and the slack (m) on a
# window of arc length that holds a point's nearest centreline point.
_RADIAL_STEP = 1e-3
_AXIAL_SHARE = 1.0 / 8.0
_TOLERANCE = 1e-12
_ITERATIONS = 200
_BATCH = 1 << 20
_SLACK = 1e-3
# Steps heed the features nearest in arc length one at a time up to this many, then all.
_NEAREST = 3


class _Probe(NamedTuple):
    """What the steps need at M points: the run's coordinates s, rho and piece (M,), its
    gap (M,), and each branch's gap (M,)."""

    s: np.ndarray
    rho: np.ndarray
    piece: np.ndarray
    run: np.ndarray
    branches: list

    def take(self, rows) -> _Probe:
        """Return the probe at `rows` only."""
        return _Probe(*(v[rows] for v in self[:4]), [v[rows] for v in self.branches])


def refine(gap, rows, lo, hi, g_lo, g_hi) -> np.ndarray:
    """Return the roots (M,) of ``gap(t, rows)`` bracketed by ``g_lo < 0 <= g_hi`` (M,).

    The Illinois method runs until the gap is below `_TOLERANCE` (or the bracket is); a
    root not found in `_ITERATIONS` iterations is NaN.
    """
    rows, index = np.asarray(rows), np.arange(np.size(rows))
    last = np.zeros(index.size, dtype=np.int8)  # which end moved last: -1 lo, +1 hi
    found = np.full(index.size, np.nan)
    for _ in range(_ITERATIONS):
        if rows.size == 0:
            break
        mid = np.clip(hi - g_hi * (hi - lo) / (g_hi - g_lo), lo, hi)
        g_mid = gap(mid, rows)
        done = (np.abs(g_mid) < _TOLERANCE) | (hi - lo < _TOLERANCE)
        found[index[done]] = mid[done]
        below = g_mid < 0.0
        # Illinois: when the same end moves twice running, halve the other end's gap.
        g_hi = np.where(below & (last < 0), 0.5 * g_hi, g_hi)
        g_lo = np.where(~below & (last > 0), 0.5 * g_lo, g_lo)
        lo, g_lo = np.where(below, mid, lo), np.where(below, g_mid, g_lo)
        hi, g_hi = np.where(below, hi, mid), np.where(below, g_hi, g_mid)
        last = np.where(below, -1, 1).astype(np.int8)
        keep = ~done
        state = (rows, index, lo, hi, g_lo, g_hi, last)
        rows, index, lo, hi, g_lo, g_hi, last = (v[keep] for v in state)
    return found


def _exit(w: np.ndarray, d: np.ndarray, axis: np.ndarray, radius: float) -> np.ndarray:
    """Return how far (M,) along unit directions `d` (M, 3) points at `w` (M, 3) from a
    point of a cylinder's axis (unit `axis`, (M, 3) or (3,)) reach its wall from inside
    (0 where they are not inside, inf where they never reach it)."""
    w_across = w - np.einsum("ij,ij->i", w, np.broadcast_to(axis, w.shape))[:, None] * axis
    d_across = d - np.einsum("ij,ij->i", d, np.broadcast_to(axis, d.shape))[:, None] * axis
    a = np.einsum("ij,ij->i", d_across, d_across)
    b = np.einsum("ij,ij->i", w_across, d_across)
    c = np.einsum("ij,ij->i", w_across, w_across) - radius**2
    root = np.sqrt(np.maximum(b * b - a * c, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        # The larger root of a t^2 + 2 b t + c, written to avoid cancellation.
        t = np.where(b >= 0.0, -c / (b + root), (root - b) / a)
    return np.where(c < 0.0, np.nan_to_num(t, nan=np.inf), 0.0)


def _slab_exit(along: np.ndarray, rate: np.ndarray, lo, hi) -> np.ndarray:
    """Return how far (M,) points at coordinates `along` (M,), changing at `rate` (M,) per
    unit step, go before leaving [lo, hi]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(rate > 0.0, (hi - along) / rate, (lo - along) / rate)
    return np.where(rate == 0.0, np.inf, np.maximum(t, 0.0))


def _cubic_roots(b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Return the real roots (M, 3) of ``x^3 + b x^2 + c x + d`` (M,), NaN for missing
    ones (trigonometric form with three real roots, Cardano's with one)."""
    p = c - b * b / 3.0
    q = 2.0 * b**3 / 27.0 - b * c / 3.0 + d
    half = 0.5 * q
    disc = half * half + (p / 3.0) ** 3
    r = np.sqrt(np.maximum(-p / 3.0, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        angle = np.arccos(np.clip(-half / r**3, -1.0, 1.0)) / 3.0
    three = 2.0 * r[:, None] * np.cos(angle[:, None] - 2.0 * np.pi / 3.0 * np.arange(3))
    root = np.sqrt(np.maximum(disc, 0.0))
    one = np.cbrt(-half + root) + np.cbrt(-half - root)
    single = np.stack([one, np.full_like(one, np.nan), np.full_like(one, np.nan)], -1)
    return np.where((disc < 0.0)[:, None], three, single) - b[:, None] / 3.0


def _torus_exit(w, d, t0, n0, b0, bend, radius, phi_lo, phi_hi) -> np.ndarray:
    """Return how far (M,) points at `w` (M, 3) from a bend's centre, inside its tube of
    `radius` about the circle of radius `bend` (M,), go along unit directions `d` (M, 3)
    before they meet the tube's wall or leave the wedge of angles [phi_lo, phi_hi] (M,)
    from -n0 towards t0 (axis b0).

    The wall is where the quartic ``(|x|^2 + R_b^2 - r^2)^2 - 4 R_b^2 (|x|^2 - (x.b0)^2)``
    (negative inside) reaches 0; its first root is bracketed between the points where
    its derivative (a cubic, solved in closed form) vanishes and refined.
    """
    # The wedge is where x . tangent(phi_lo) >= 0 >= x . tangent(phi_hi); no chord of the
    # torus's bounding sphere is longer than its diameter.
    limit = np.full(w.shape[0], 2.0 * (np.max(bend) + radius))
    for phi, sign in ((phi_lo, -1.0), (phi_hi, 1.0)):
        normal = np.multiply.outer(np.cos(phi), t0) + np.multiply.outer(np.sin(phi), n0)
        rate = sign * np.einsum("ij,ij->i", d, normal)
        along = sign * np.einsum("ij,ij->i", w, normal)
        with np.errstate(divide="ignore", invalid="ignore"):
            limit = np.where(rate > 0.0, np.minimum(limit, np.maximum(-along / rate, 0.0)), limit)
    p, ww = np.einsum("ij,ij->i", w, d), np.einsum("ij,ij->i", w, w)
    e, de = w @ b0, d @ b0
    q = ww + bend**2 - radius**2
    k = 4.0 * bend**2
    c3 = 4.0 * p
    c2 = 4.0 * p * p + 2.0 * q - k * (1.0 - de * de)
    c1 = 4.0 * p * q - 2.0 * k * (p - e * de)
    c0 = q * q - k * (ww - e * e)

    def quartic(t, rows):
        return (((t + c3[rows]) * t + c2[rows]) * t + c1[rows]) * t + c0[rows]

    every = np.arange(w.shape[0])
    knots = _cubic_roots(0.75 * c3, 0.5 * c2, 0.25 * c1)
    usable = (knots > 0.0) & (knots < limit[:, None])
    knots = np.sort(np.where(usable, knots, limit[:, None]), axis=1)
    knots = np.concatenate([np.zeros((w.shape[0], 1)), knots, limit[:, None]], axis=1)
    finite = np.where(np.isfinite(knots), knots, 0.0)
    values = quartic(finite.T, every).T
    outside = (values >= 0.0) & np.isfinite(knots)
    first = np.argmax(outside, axis=1)
    rows = np.flatnonzero(outside.any(axis=1) & (first > 0))
    reach = np.where(outside[every, 0], 0.0, limit)
    lo, hi = knots[rows, first[rows] - 1], knots[rows, first[rows]]
    g_lo, g_hi = values[rows, first[rows] - 1], values[rows, first[rows]]
    root = refine(quartic, rows, lo, hi, g_lo, g_hi)
    reach[rows] = np.where(np.isnan(root), lo, root)
    return reach


@dataclass(frozen=True)
class Branch:
    """A tee's branch bore: a straight tube of `radius` from `foot`, on the run's
    centreline, along the unit `axis` to its open end `end` metres from the foot."""

    foot: np.ndarray
    axis: np.ndarray
    radius: float
    end: float

    def coordinates(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the distance (M,) of points `x` (M, 3) along the axis from the foot and
        their offsets (M, 3) from the axis."""
        w = x - self.foot
        along = w @ self.axis
        return along, w - along[:, None] * self.axis

    def gap(self, x: np.ndarray) -> np.ndarray:
        """Return the capped tube's gap (M,): negative inside, a lower bound on the distance
        to its wall and ends there, positive outside."""
        along, across = self.coordinates(x)
        rho = np.linalg.norm(across, axis=1)
        return np.maximum.reduce([rho - self.radius, -along, along - self.end])


class Bore:
    """The air of a pipe run: its damaged `wall`'s bore joined with `branches`' bores."""

    def __init__(self, wall: _Wall, branches: tuple[Branch, ...] = (), zones=()):
        """`zones` are extra arc-length stretches (lo, hi) of the run where its wall is not
        the plain tube (a tee's opening)."""
        self.wall, self.branches = wall, tuple(branches)
        path, radius = wall.path, wall.radius
        self.low, self.high = radius - wall.inward, radius + wall.outward
        bend = path._max_curvature
        tight = 1.0 / bend if bend > 0 else math.inf
        # Steps bounded by the gap's rate of change are at most `reach` long.
        self.reach = min(0.25 * self.low, 0.5 * (tight - self.high))
        # A step of length h from a point with rho in [low / 2, high + reach] moves its
        # clock by at most h 2 R / low on the unrolled wall and its arc length by at most
        # h `along`; `speed` bounds both.
        self.along = 1.0 / (1.0 - bend * (self.high + self.reach))
        self.speed = max(2.0 * radius / self.low, self.along)
        features = wall.features() + [_Feature(lo, hi, 0.0, 0.0, 0.0, math.inf) for lo, hi in zones]
        # The sharp features' extents along the centreline and bounds on what they do
        # there; and where the shifts of the pipe beyond offsets start and their bounds,
        # summed over the shifts up to each.
        sharp = [f for f in features if f.sharp]
        self.sharp = {
            name: np.array([getattr(f, name) for f in sharp], dtype=np.float64)
            for name in ("lo", "hi", "inward", "slope", "scale")
        }
        self.axial = np.array([f.axial for f in sharp], dtype=bool)
        shifts = sorted((f for f in features if not f.sharp), key=lambda f: f.lo)
        self.shifts = (
            np.array([f.lo for f in shifts]),
            np.cumsum([0.0] + [f.inward for f in shifts]),
            np.cumsum([0.0] + [f.slope for f in shifts]),
        )

    def ends(self) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Return the open ends: centre (3,), outward normal (3,) and a radius bounding
        the wall there."""
        wall, path = self.wall, self.wall.path
        s = np.array([0.0, path.length])
        f = path._evaluate(s)
        centre, tangent = f.centre + wall.shift(s), f.tangent
        rim = wall.radius + wall.outward + 1e-6
        ends = [(centre[0], -tangent[0], rim), (centre[1], tangent[1], rim)]
        for b in self.branches:
            ends.append((b.foot + b.end * b.axis, b.axis, b.radius + 1e-6))
        return ends

    def _limits(self, origin: np.ndarray, direction: np.ndarray, far: float) -> np.ndarray:
        """Return the range (M,) at which each beam leaves through an open end, or `far`."""
        t_end = np.full(origin.shape[0], far)
        for centre, normal, rim in self.ends():
            rate = direction @ normal
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((centre - origin) @ normal) / rate
            point = origin + np.nan_to_num(t, posinf=0.0, neginf=0.0)[:, None] * direction
            # A scanner on an end's plane may sit a rounding error beyond it.
            through = (rate > 0.0) & (t > -1e-9) & (np.linalg.norm(point - centre, axis=1) <= rim)
            t_end = np.where(through, np.minimum(t_end, t), t_end)
        return np.maximum(t_end, 0.0)

    def gap(self, x: np.ndarray, hint=None, reach=None):
        """Return the union's gap (M,) at points `x` (M, 3), negative inside, and what the
        steps need: the run's coordinates s, rho and piece, its gap, and each branch's
        gap. `hint` and `reach` as in `PipePath._closest`."""
        wall = self.wall
        s, theta, rho, piece = wall.coordinates(x, hint, reach)
        run = rho - wall.radius_at(theta, s)
        branches = [b.gap(x) for b in self.branches]
        gap = np.minimum.reduce([run, *branches]) if branches else run
        return gap, _Probe(s, rho, piece, run, branches)

    def step(self, x: np.ndarray, d: np.ndarray, probe: _Probe) -> np.ndarray:
        """Return steps (M,) along unit directions `d` (M, 3) from points `x` (M, 3) inside
        the union, with the `probe` of `gap` there, that cannot pass the wall unseen.

        A step that moves the arc length by less than the distance to a feature's extent
        need not heed that feature: for each k, a step that reaches only the k features
        nearest in arc length may be a ball inside the undamaged tube narrowed by their
        inward changes, or, near the wall, the gap over the Lipschitz bound their slopes
        give, but is never shorter than the shortest step their scales allow.
        """
        s, rho, piece, run, branches = probe
        limit, inward, slope, scale = self._bounds(s)
        rho_k, run_k = rho[:, None], run[:, None]
        lipschitz = 1.0 + self.speed * slope
        step = self.wall.radius - inward - rho_k
        near = (rho >= 0.75 * self.low)[:, None]
        traced = np.where(near, np.minimum(-run_k / lipschitz, self.reach), 0.0)
        fine = np.minimum(_RADIAL_STEP / lipschitz, _AXIAL_SHARE * scale / self.speed)
        step = np.minimum(np.maximum.reduce([step, traced, fine]), limit).max(axis=1)
        # Where no feature that changes along the centreline is near, the wall is the tube
        # about the (shifted) centreline, made oval on the ovality's span.
        lo, hi, axial = self.sharp["lo"], self.sharp["hi"], self.axial
        after = lo[axial] >= s[:, None]
        before = np.where(hi[axial] <= s[:, None], hi[axial], 0.0).max(axis=1, initial=0.0)
        clear = ~(~after & (hi[axial] > s[:, None])).any(axis=1)
        after = np.where(after, lo[axial], math.inf).min(axis=1, initial=math.inf)
        jump = np.flatnonzero(clear)
        if jump.size:
            on = (lo <= s[jump, None]) & (s[jump, None] <= hi) & ~axial
            oval = np.where(on, self.sharp["inward"], 0.0).sum(axis=1)
            stretch = (before[jump], after[jump])
            reach = self._jump(x[jump], d[jump], s[jump], piece[jump], stretch, oval)
            step[jump] = np.maximum(step[jump], reach)
            bent = np.flatnonzero((oval > 0.0) & self.wall.path._bend[piece[jump]])
            if bent.size:
                rows = jump[bent]
                stretch = (before[rows], after[rows])
                reach = self._across(d[rows], probe.take(rows), stretch, on[bent])
                step[rows] = np.maximum(step[rows], reach)
        for branch, gap in zip(self.branches, branches, strict=True):
            inside = np.flatnonzero(gap < 0.0)
            if inside.size == 0:
                continue
            along, across = branch.coordinates(x[inside])
            rate = d[inside] @ branch.axis
            reach = np.minimum(
                _exit(across, d[inside], branch.axis, branch.radius),
                _slab_exit(along, rate, 0.0, branch.end),
            )
            step[inside] = np.maximum.reduce([step[inside], -gap[inside], reach])
        return step

    def _across(self, d, probe: _Probe, stretch, on) -> np.ndarray:
        """Return steps (M,) along unit directions `d` (M, 3) from points on a bend where
        the wall changes with the clock only (the ovality `on` (M, F) its span, and the
        shifts beyond offsets), that stay in the bend and the `stretch` (M,), (M,) of arc
        lengths and cannot pass the wall unseen.

        The gap changes as a beam moves across the pipe, by at most ``L = 1 + |dr/dclock|
        / rho`` per metre (rho kept above low / 2), and a unit step moves it across by at
        most ``|d x t| + k along h`` after h, t the tangent and k the bend's curvature:
        the step h is where ``L (|d x t| h + k along h^2 / 2)`` reaches the gap.
        """
        s, rho, piece, run, _ = probe
        path = self.wall.path
        start, _, shift_slope = self.shifts
        shifts = shift_slope[np.searchsorted(start, s, side="right")]
        turn = np.where(on, self.sharp["slope"], 0.0).sum(axis=1) + shifts
        lipschitz = 1.0 + self.wall.radius * turn / (0.5 * self.low)
        tangent = path._evaluate(s, piece).tangent
        rate = np.einsum("ij,ij->i", d, tangent)
        across = np.sqrt(np.maximum(1.0 - rate * rate, 0.0))
        bend = self.along / path._radius[piece]
        gap = np.maximum(-run, 0.0) / lipschitz
        reach = 2.0 * gap / (across + np.sqrt(across * across + 2.0 * bend * gap))
        s0, s1 = path._s0[piece], path._s0[piece + 1]
        lo, hi = np.maximum(stretch[0], s0), np.minimum(stretch[1], s1)
        return np.minimum(reach, np.minimum(s - lo, hi - s) / self.along)

    def _bounds(self, s: np.ndarray):
        """Return, for points at arc lengths `s` (M,) and each k = 0 .. K (K the
        `_NEAREST` sharp features nearest in arc length, then all of them), how far (M, K
        + 2) a step heeding the k nearest may go (its arc length may not reach the next),
        and bounds on those features and the shifts before s: the inward change, the
        slope and the shortest scale (M, K + 2)."""
        f, count = self.sharp, s.size
        start, shift_inward, shift_slope = self.shifts
        before = np.searchsorted(start, s, side="right")
        distance = np.maximum(np.maximum(f["lo"] - s[:, None], s[:, None] - f["hi"]), 0.0)
        nearest = min(_NEAREST, f["lo"].size)
        order = np.zeros((count, 0), dtype=np.int64)
        if nearest:
            order = np.argpartition(distance, nearest - 1, axis=1)[:, :nearest]
            ranks = np.argsort(np.take_along_axis(distance, order, 1), 1)
            order = np.take_along_axis(order, ranks, 1)
        gaps = np.take_along_axis(distance, order, axis=1)
        rest = np.full((count, 1), math.inf)
        if nearest < f["lo"].size:  # the nearest beyond those
            others = distance.copy()
            np.put_along_axis(others, order, math.inf, axis=1)
            rest = others.min(axis=1, keepdims=True)
        limit = np.concatenate([gaps, rest, np.full((count, 1), math.inf)], 1) / self.along

        def heed(values, ufunc, first):
            parts = [np.full((count, 1), first), values[order]]
            total = ufunc.reduce(values, initial=first)
            return np.concatenate(
                [ufunc.accumulate(np.concatenate(parts, 1), 1), np.full((count, 1), total)], 1
            )

        inward = heed(f["inward"], np.add, 0.0) + shift_inward[before][:, None]
        slope = heed(f["slope"], np.add, 0.0) + shift_slope[before][:, None]
        return limit, inward, slope, heed(f["scale"], np.minimum, math.inf)

    def _jump(self, x, d, s, piece, stretch, oval) -> np.ndarray:
        """Return how far (M,) beams along `d` (M, 3) from points `x` (M, 3) at arc lengths
        `s` (M,) on `piece` (M,) may jump within the `stretch` (M,), (M,) of arc lengths
        clear of features that change along the centreline, where the wall is the tube
        about the (shifted) centreline made oval by `oval` (M,) (0: round).

        Where the wall is round, to the exit from the tube or the stretch. On a straight
        piece an oval cross-section ``R + a cos(2 clock)`` with ``a < 0.15 R`` (ovality
        below 0.3) is convex, so a beam crosses the wall once before it leaves the tube
        widened by a: to the exit from that. Elsewhere, to the exit from the tube narrowed
        by a.
        """
        path, radius = self.wall.path, self.wall.radius
        offsets = self.wall._offsets(s)
        shift = np.zeros((s.size, 2)) if offsets is None else offsets[0]
        reach = np.zeros(s.size)
        for k in np.unique(piece):
            rows = np.flatnonzero(piece == k)
            s0, s1 = path._s0[k], path._s0[k + 1]
            lo = np.maximum(stretch[0][rows], s0) - s0
            hi = np.minimum(stretch[1][rows], s1) - s0
            t0, (dx, dy) = path._t0[k], shift[rows].T
            if not path._bend[k]:
                axis = path._p0[k] + np.multiply.outer(dx, path._u0[k])
                w = x[rows] - axis - np.multiply.outer(dy, path._r0[k])
                rate = d[rows] @ t0
                convex = oval[rows] < 0.15 * radius
                tube = radius + np.where(convex, oval[rows], -oval[rows])
                reach[rows] = np.minimum(
                    _exit(w, d[rows], t0, tube),
                    _slab_exit(s[rows] - s0, rate, lo, hi),
                )
                continue
            # The shifted centreline is the arc of radius R_b - a about the centre moved b
            # along the bend's axis, a and b the shift's parts towards the centre and along
            # the axis (see `PipePath._evaluate`).
            n0, b0, bend = path._n0[k], path._b0[k], path._radius[k]
            un, ub = path._un[k], path._ub[k]
            towards, along = dx * un - dy * ub, dx * ub + dy * un
            w = x[rows] - (path._p0[k] + bend * n0) - np.multiply.outer(along, b0)
            tube = radius - oval[rows]
            reach[rows] = _torus_exit(
                w, d[rows], t0, n0, b0, bend - towards, tube, lo / bend, hi / bend
            )
        return reach

    def march(self, origin: np.ndarray, direction: np.ndarray, t_end: np.ndarray, start):
        """Return the first range t (M,) in ``[0, t_end]`` where the beams ``origin + t
        direction`` (M, 3) meet the wall, NaN where they do not, and for each hit an arc
        length (M,) and a reach (M,) of arc length around it that holds its nearest
        centreline point. `start` is `gap` at the origins."""
        count = t_end.size
        found, hint, reach = np.full(count, np.nan), np.zeros(count), np.zeros(count)
        if count == 0:
            return found, hint, reach
        rows = np.arange(count)
        t = np.zeros(count)
        gap, probe = start
        brackets = []
        while rows.size:
            step = self.step(origin[rows] + t[:, None] * direction[rows], direction[rows], probe)
            t_next = np.minimum(t + step, t_end[rows])
            x = origin[rows] + t_next[:, None] * direction[rows]
            # A point's nearest arc length is looked for near the previous point's.
            g_next, next_probe = self.gap(x, probe.s, step * self.along + _SLACK)
            # On an open end's plane the capped branch's gap is 0 too: that is no hit.
            exact = (np.abs(g_next) <= _TOLERANCE) & (t_next < t_end[rows])
            found[rows[exact]], hint[rows[exact]] = t_next[exact], next_probe.s[exact]
            crossed = g_next > _TOLERANCE
            brackets.append(
                (rows[crossed], t[crossed], t_next[crossed], gap[crossed], g_next[crossed])
                + (probe.s[crossed], next_probe.s[crossed])
            )
            keep = np.flatnonzero(~exact & ~crossed & (t_next < t_end[rows]))
            rows, t, gap, probe = rows[keep], t_next[keep], g_next[keep], next_probe.take(keep)
        rows, lo, hi, g_lo, g_hi, s_lo, s_hi = (
            np.concatenate(v) for v in zip(*brackets, strict=True)
        )
        # Inside the tube the nearest arc length is monotonic along a beam.
        reach[~np.isnan(found)] = _SLACK
        hint[rows], reach[rows] = 0.5 * (s_lo + s_hi), 0.5 * np.abs(s_hi - s_lo) + _SLACK

        def gap_at(t, rows):
            x = origin[rows] + t[:, None] * direction[rows]
            return self.gap(x, hint[rows], reach[rows])[0]

        found[rows] = refine(gap_at, rows, lo, hi, g_lo, g_hi)
        return found, hint, reach

    def normals(self, points: np.ndarray, hint: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """Return the outward unit normals (M, 3) of the wall at points (M, 3) on it, whose
        nearest arc lengths are within `reach` (M,) of `hint` (M,)."""
        wall = self.wall
        s, theta, rho, _ = wall.coordinates(points, hint, reach)
        normals = wall.surface(theta, s)[1]
        run = rho - wall.radius_at(theta, s)
        for branch in self.branches:
            across = branch.coordinates(points)[1]
            on = branch.gap(points) < run
            normals[on] = across[on] / np.linalg.norm(across[on], axis=1, keepdims=True)
        return normals

    def station(self, g, s0: float):
        """Yield the returning beams of the scanner at arc length `s0`, a batch of lines at
        a time: origins and unit directions (K, 3), true ranges (K,) and a window of arc
        length (K,), (K,) holding the hits' nearest centreline points (see `march`),
        ordered by scan line then beam angle.

        The scanner takes `scan_pipe`'s pose with its x, y and z axes along ``up x
        tangent``, up and the tangent of the centreline at `s0` (on the true centreline,
        moved by any offset joints before it).
        """
        path = self.wall.path
        f = path._evaluate(np.array([s0]))
        centre = f.centre[0] + self.wall.shift(np.array([s0]))[0]
        axes = np.stack([-f.right[0], f.up[0], f.tangent[0]])  # local x, y, z
        beta = _beam_angles(g)
        every_psi = _line_angles(g)
        lines = max(1, _BATCH // (4 * beta.size))
        lo, hi = g.range_limits
        for first in range(0, every_psi.size, lines):
            psi = every_psi[first : first + lines]
            shape = (psi.size, beta.size)
            origins = _origins(psi, g.offset, 0.0) @ axes + centre
            gap, probe = self.gap(origins, np.full(psi.size, s0), np.full(psi.size, g.offset))
            start = (
                np.repeat(gap, beta.size),
                probe.take(np.repeat(np.arange(psi.size), beta.size)),
            )
            origin = np.repeat(origins, beta.size, axis=0)
            unit = _beam_points(psi[:, None], beta, np.ones(shape), 0.0, 0.0)
            direction = unit.reshape(-1, 3) @ axes
            t, hint, reach = self.march(
                origin, direction, self._limits(origin, direction, hi), start
            )
            with np.errstate(invalid="ignore"):
                hit = np.flatnonzero(t >= lo)
            yield origin[hit], direction[hit], t[hit], hint[hit], reach[hit]

    def scan(self, g, stations, noise_scale: float, rng: np.random.Generator):
        """Return the points, normals and viewpoints (N, 3) of the scans at `stations`."""
        points, normals, viewpoints = [], [], []
        for s0 in stations:
            for origin, direction, t, hint, reach in self.station(g, s0):
                measured = _measure(t, noise_scale, rng)
                points.append(origin + measured[:, None] * direction)
                normals.append(self.normals(origin + t[:, None] * direction, hint, reach))
                viewpoints.append(origin)
        return np.concatenate(points), np.concatenate(normals), np.concatenate(viewpoints)
