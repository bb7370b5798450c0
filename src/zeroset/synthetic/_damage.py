"""Damaged pipes: dents, bulges and ovality on straight pipes and elbows, sampled or scanned."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .._validate import positive, require_rng
from ..errors import InputError
from ..types import Mesh
from . import _truth
from ._distance import query
from ._pipes import _elbow_axis, _elbow_frame, _elbow_sites
from ._sample import Sample, _count, _fraction, _noise, add_noise, finish
from ._scanner import (
    HOKUYO_FIELD,
    HOKUYO_RANGE,
    HOKUYO_STEP,
    _beam_angles,
    _beam_points,
    _geometry,
    _line_angles,
    _measure,
    _noise_scale,
    _origins,
)
from ._shapes import _wrap

__all__ = ["CLOCK_CONVENTION", "DEFECT_KINDS", "Defect", "damaged_pipe", "scan_damaged_pipe"]

#: The clock convention of `Defect` and the ovality, as written into truth records.
CLOCK_CONVENTION = (
    "Clock angles are degrees clockwise looking along the centreline from its start: "
    "12 o'clock (0) is +y and 3 o'clock (90) is t x y, t the centreline's unit tangent "
    "(-x where the pipe runs along +z, +z on the elbow's second leg along +x)."
)
#: Defect kinds: a dent moves the wall towards the axis, a bulge away from it.
DEFECT_KINDS = ("dent", "bulge")

_Y = np.array([0.0, 1.0, 0.0])
# Scan root finding: radial steps of the march, the share of the narrowest feature an axial
# step may take, the radial gap (m) at which a hit is final, the most refining iterations,
# and how many beam samples a batch holds.
_RADIAL_STEP = 1e-3
_AXIAL_SHARE = 1.0 / 8.0
_TOLERANCE = 1e-12
_ITERATIONS = 200
_BATCH = 1 << 20


@dataclass(frozen=True)
class Defect:
    """A dent or a bulge: a smooth round patch of the wall moved along the radius.

    Clock angles are degrees clockwise looking along the centreline from its start:
    12 o'clock (0) is +y and 3 o'clock (90) is ``t x y``, t the centreline's unit tangent
    (-x where the pipe runs along +z, +z on the elbow's second leg along +x). On the elbow
    (bent in the x-z plane) +y stays 12 o'clock all along.

    At unrolled-wall distance ``d = hypot(R dtheta, ds)`` from the defect's centre (R the
    pipe radius, dtheta the clock difference in radians wrapped to [-pi, pi), ds the
    difference in arc length along the centreline) the wall radius changes by
    ``-+ depth cos(pi d / width)^2`` for ``d < width / 2`` and not at all beyond: minus
    for a dent (the wall moves towards the axis), plus for a bulge. Defects add up where
    they overlap.

    Attributes
    ----------
    kind : {"dent", "bulge"}
    axial : float
        Arc length of the centre along the pipe's centreline from its start, in metres,
        ``>= 0``.
    clock : float
        Clock angle of the centre, in degrees in [0, 360).
    depth : float
        Largest radial change, at the centre, in metres, ``> 0``.
    width : float
        Diameter of the affected patch on the unrolled wall, in metres, ``> 0``.

    Raises
    ------
    InputError
        If a field is out of its range.

    Examples
    --------
    >>> Defect("dent", axial=1.0, clock=90.0, depth=0.01, width=0.2).depth
    0.01
    """

    kind: str
    axial: float
    clock: float
    depth: float
    width: float

    def __post_init__(self) -> None:
        if self.kind not in DEFECT_KINDS:
            raise InputError(f"defect kind must be one of {DEFECT_KINDS}; got {self.kind!r}")
        for name in ("axial", "clock"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise InputError(f"defect {name} must be a number; got {value!r}")
        if not (math.isfinite(self.axial) and self.axial >= 0.0):
            raise InputError(f"defect axial must be a distance >= 0 in metres; got {self.axial!r}")
        if not 0.0 <= self.clock < 360.0:
            raise InputError(f"defect clock must be degrees in [0, 360); got {self.clock!r}")
        object.__setattr__(self, "axial", float(self.axial))
        object.__setattr__(self, "clock", float(self.clock))
        object.__setattr__(self, "depth", positive(self.depth, "defect depth"))
        object.__setattr__(self, "width", positive(self.width, "defect width"))


@dataclass(frozen=True)
class _Wall:
    """A damaged pipe wall ``r(clock, s)`` about a straight (+z) or elbow centreline.

    The methods take clock angles `theta` in radians (see `Defect`) and arc lengths `s`
    along the centreline, `length` long; stored clocks are in degrees. The ovality has full
    value on `span` and fades with a cos^2 taper over one pipe radius beyond each end.
    """

    radius: float
    length: float
    bend_radius: float | None  # None for a straight pipe along +z
    leg: float
    defects: tuple[Defect, ...]
    ovality: float
    ovality_clock: float  # degrees
    span: tuple[float, float]

    @property
    def taper(self) -> float:
        """Length over which the ovality fades beyond its span, in metres."""
        return self.radius

    @property
    def inward(self) -> float:
        """A bound on how far the wall moves towards the axis."""
        dents = sum(d.depth for d in self.defects if d.kind == "dent")
        return dents + 0.5 * self.radius * self.ovality

    @property
    def outward(self) -> float:
        """A bound on how far the wall moves away from the axis."""
        bulges = sum(d.depth for d in self.defects if d.kind == "bulge")
        return bulges + 0.5 * self.radius * self.ovality

    @property
    def feature(self) -> float:
        """The shortest axial scale on which the wall changes: a width or the taper."""
        widths = [d.width for d in self.defects]
        return min(widths + ([self.taper] if self.ovality > 0 else []), default=math.inf)

    @property
    def slope(self) -> float:
        """A bound on the gradient of r on the unrolled wall, per metre of R theta and s."""
        defects = sum(np.pi * d.depth / d.width for d in self.defects)
        amplitude = 0.5 * self.radius * self.ovality
        return defects + amplitude * (2.0 / self.radius + 0.5 * np.pi / self.taper)

    def frame(self, s: np.ndarray):
        """Return centreline points, in-plane normals, unit tangents (M, 3) and curvature (M,)."""
        if self.bend_radius is None:
            zero = np.zeros_like(s)
            centre = np.stack([zero, zero, s], -1)
            e_n = np.broadcast_to([1.0, 0.0, 0.0], centre.shape)
            return centre, e_n, np.broadcast_to([0.0, 0.0, 1.0], centre.shape), zero
        axis = _elbow_axis(self.bend_radius, self.leg)
        centre, e_n = _elbow_frame(axis, self.bend_radius, self.leg, s)
        tangent = np.stack([-e_n[:, 2], np.zeros_like(s), e_n[:, 0]], -1)  # e_n x e_y
        bend = (s > self.leg) & (s < self.leg + 0.5 * np.pi * self.bend_radius)
        return centre, e_n, tangent, np.where(bend, 1.0 / self.bend_radius, 0.0)

    def locate(self, x: np.ndarray):
        """Return tube coordinates of `x` (M, 3): arc length s, clock theta, distance rho from
        the centreline in the cross-section, and the overshoot beyond an open end (all (M,))."""
        if self.bend_radius is None:
            s = np.clip(x[:, 2], 0.0, self.length)
            beyond = np.abs(x[:, 2] - s)
            across = x[:, :2]
        else:
            s, beyond = self._nearest_on_elbow(x)
            centre, e_n, tangent, _ = self.frame(s)
            v = x - centre
            v = v - np.einsum("ij,ij->i", v, tangent)[:, None] * tangent
            across = np.stack([np.einsum("ij,ij->i", v, e_n), v[:, 1]], -1)
        theta = np.mod(np.arctan2(across[:, 1], across[:, 0]) - 0.5 * np.pi, 2.0 * np.pi)
        return s, theta, np.hypot(across[:, 0], across[:, 1]), beyond

    def _nearest_on_elbow(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the arc length (M,) of the centreline point nearest `x` and the overshoot
        (M,) beyond the open ends."""
        rb, leg = self.bend_radius, self.leg
        bend = 0.5 * np.pi * rb
        q0 = np.clip(x[:, 2], 0.0, leg)
        alpha = np.clip(np.arctan2(x[:, 2] - leg, rb - x[:, 0]), 0.0, 0.5 * np.pi)
        q2 = np.clip(x[:, 0] - rb, 0.0, leg)
        zero = np.zeros_like(q0)
        on_bend = np.stack([rb - rb * np.cos(alpha), zero, leg + rb * np.sin(alpha)], -1)
        candidates = [
            (q0, np.stack([zero, zero, q0], -1)),
            (leg + rb * alpha, on_bend),
            (leg + bend + q2, np.stack([rb + q2, zero, np.full_like(q2, leg + rb)], -1)),
        ]
        gaps = np.stack([np.linalg.norm(x - c, axis=1) for _, c in candidates])
        best = np.argmin(gaps, axis=0)
        s = np.choose(best, [q for q, _ in candidates])
        beyond = np.where(best == 0, np.maximum(-x[:, 2], 0.0), 0.0)
        beyond = np.where(best == 2, np.maximum(x[:, 0] - rb - leg, 0.0), beyond)
        return np.minimum(s, self.length), beyond

    def radius_at(self, theta: np.ndarray, s: np.ndarray, *, gradient: bool = False):
        """Return the wall radius r (M,) at clocks `theta` and arc lengths `s` (M,); with
        `gradient`, also its derivatives dr/dtheta (per radian) and dr/ds."""
        r = np.full(theta.shape, self.radius)
        r_theta, r_s = np.zeros(theta.shape), np.zeros(theta.shape)
        for defect in self.defects:
            half = 0.5 * defect.width
            u = self.radius * _wrap(theta - math.radians(defect.clock))
            v = s - defect.axial
            near = np.flatnonzero((np.abs(u) < half) & (np.abs(v) < half))
            d = np.hypot(u[near], v[near])
            near, d = near[d < half], d[d < half]
            sign = -1.0 if defect.kind == "dent" else 1.0
            r[near] += sign * defect.depth * np.cos(np.pi * d / defect.width) ** 2
            if gradient:
                # d/dd of cos^2(pi d / w), divided by d: -(2 pi^2 / w^2) sinc(2 d / w).
                slope = -sign * defect.depth * 2.0 * np.pi**2 / defect.width**2
                slope = slope * np.sinc(2.0 * d / defect.width)
                r_theta[near] += slope * u[near] * self.radius
                r_s[near] += slope * v[near]
        if self.ovality > 0:
            weight, weight_s = self._span_weight(s)
            amplitude = 0.5 * self.radius * self.ovality  # D o / 4
            phase = 2.0 * (theta - math.radians(self.ovality_clock))
            r += amplitude * np.cos(phase) * weight
            r_theta -= 2.0 * amplitude * np.sin(phase) * weight
            r_s += amplitude * np.cos(phase) * weight_s
        return (r, r_theta, r_s) if gradient else r

    def _span_weight(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the ovality's weight (M,), 1 on the span and tapering to 0, and d/ds of it."""
        s0, s1 = self.span
        beyond = np.maximum(s0 - s, s - s1)
        taper = (beyond > 0.0) & (beyond < self.taper)
        k = 0.5 * np.pi / self.taper
        weight = np.where(beyond <= 0.0, 1.0, np.where(taper, np.cos(k * beyond) ** 2, 0.0))
        direction = np.where(s < s0, -1.0, 1.0)
        return weight, np.where(taper, -k * np.sin(2.0 * k * beyond) * direction, 0.0)

    def surface(self, theta: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return wall points and outward unit normals (M, 3) at clocks and arc lengths (M,)."""
        r, r_theta, r_s = self.radius_at(theta, s, gradient=True)
        centre, e_n, tangent, curvature = self.frame(s)
        c, n = np.cos(theta)[:, None], np.sin(theta)[:, None]
        out = c * _Y - n * e_n  # the clock direction; d(out)/dtheta is below
        turn = -n * _Y - c * e_n
        # P(theta, s) = centre + r out: dP/dtheta = r_theta out + r turn and
        # dP/ds = (1 + curvature r sin theta) tangent + r_s out, so this is normal to both.
        stretch = 1.0 + curvature * r * np.sin(theta)
        normal = out - (r_theta / r)[:, None] * turn - (r_s / stretch)[:, None] * tangent
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return centre + r[:, None] * out, normal

    def distance(self, x) -> np.ndarray:
        """Distance (M,) from `x` (M, 3) to the wall, to first order in the wall's slope."""
        x = query(x)
        s, theta, rho, beyond = self.locate(x)
        r, r_theta, r_s = self.radius_at(theta, s, gradient=True)
        curvature = self.frame(s)[3]
        stretch = 1.0 + curvature * r * np.sin(theta)
        slope = np.sqrt(1.0 + (r_theta / r) ** 2 + (r_s / stretch) ** 2)
        return np.where(beyond > 0.0, np.hypot(rho - r, beyond), np.abs(rho - r) / slope)

    def mesh(self, spacing: float | None) -> Mesh:
        """Mesh the damaged wall: the undeformed tube or elbow grid moved along the radius."""
        rb = self.bend_radius
        if rb is None:
            extent = (2.0 * self.radius, 2.0 * self.radius, self.length)
        else:
            extent = (rb + self.leg + self.radius, 2.0 * self.radius, self.leg + rb + self.radius)
        area, diagonal = 2.0 * np.pi * self.radius * self.length, math.hypot(*extent)
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        if spacing is None and self.defects:  # fine enough to show the narrowest defect
            h = _truth.resolve_spacing(min(h, self.feature / 8.0), diagonal=diagonal, area=area)
        if rb is None:
            grid = _truth.tube_mesh(self.radius, self.length, h)[0]
        else:
            grid = _truth.elbow_mesh(self.radius, rb, self.leg, h, _elbow_axis(rb, self.leg))
        s, theta, _, _ = self.locate(grid.vertices)
        return Mesh(vertices=self.surface(theta, s)[0], faces=grid.faces)

    def record(self) -> dict:
        """Return the JSON-able truth of the wall: radius, ovality and defects."""
        s = np.array([d.axial for d in self.defects])
        theta = np.radians([d.clock for d in self.defects])
        centre, e_n, _, _ = self.frame(s)
        out = np.cos(theta)[:, None] * _Y - np.sin(theta)[:, None] * e_n
        centres = np.round(centre + self.radius * out, 12) + 0.0  # no -0.0 or 1e-17 in JSON
        return {
            "radius": self.radius,
            "clock_convention": CLOCK_CONVENTION,
            "ovality": {
                "value": self.ovality,
                "clock": self.ovality_clock,
                "span": list(self.span),
                "taper": self.taper,
            },
            "defects": [
                {
                    "kind": d.kind,
                    "axial": d.axial,
                    "clock": d.clock,
                    "depth": d.depth,
                    "width": d.width,
                    "centre": centres[i].tolist(),
                }
                for i, d in enumerate(self.defects)
            ],
        }


def _wall(radius, length, bend_radius, leg, defects, ovality, ovality_clock, span) -> _Wall:
    """Validate a damaged wall's description (lengths already positive) and build it."""
    defects = tuple(defects)
    for defect in defects:
        if not isinstance(defect, Defect):
            raise TypeError(f"defects must be Defect instances; got {type(defect).__name__}")
        if defect.axial > length:
            raise InputError(
                f"defect at axial={defect.axial!r} lies beyond the centreline's end at "
                f"{length:.6g} m"
            )
    ovality = 0.0 if ovality == 0 else _fraction(ovality, "ovality")
    if (
        isinstance(ovality_clock, bool)
        or not isinstance(ovality_clock, numbers.Real)
        or not 0.0 <= ovality_clock < 360.0
    ):
        raise InputError(f"ovality_clock must be degrees in [0, 360); got {ovality_clock!r}")
    if span is None:
        span = (0.0, length)
    try:
        s0, s1 = (float(v) for v in span)
    except (TypeError, ValueError):
        raise InputError(f"ovality_span must be two numbers (s0, s1); got {span!r}") from None
    if not 0.0 <= s0 < s1 <= length:
        raise InputError(
            f"ovality_span must satisfy 0 <= s0 < s1 <= {length:.6g} (the centreline's "
            f"length); got {span!r}"
        )
    wall = _Wall(radius, length, bend_radius, leg, defects, ovality, float(ovality_clock), (s0, s1))
    if wall.inward >= radius:
        raise InputError(
            f"dents and ovality could move the wall {wall.inward:.6g} m inward, through the "
            f"axis of a pipe of radius {radius!r}; make them shallower"
        )
    if bend_radius is not None and radius + wall.outward >= bend_radius:
        raise InputError(
            f"bulges and ovality could move the wall out to {radius + wall.outward:.6g} m, "
            f"beyond bend_radius={bend_radius!r}; make them smaller"
        )
    return wall


def _shaped_wall(
    shape, radius, length, bend_radius, leg, defects, ovality, ovality_clock, span
) -> tuple[_Wall, dict]:
    """Validate a straight pipe's or an elbow's size (radius already positive) and build its
    damaged wall; return it and the truth record's size: ``length``, or ``leg`` and
    ``bend_radius``."""
    if shape == "straight":
        length = positive(length, "length")
        wall = _wall(radius, length, None, length, defects, ovality, ovality_clock, span)
        return wall, {"length": length}
    if shape != "elbow":
        raise InputError(f"shape must be 'straight' or 'elbow'; got {shape!r}")
    bend_radius, leg = positive(bend_radius, "bend_radius"), positive(leg, "leg")
    if bend_radius <= radius:
        raise InputError(
            f"bend_radius must exceed radius; got bend_radius={bend_radius!r}, radius={radius!r}"
        )
    total = 2.0 * leg + 0.5 * np.pi * bend_radius
    wall = _wall(radius, total, bend_radius, leg, defects, ovality, ovality_clock, span)
    return wall, {"leg": leg, "bend_radius": bend_radius}


def _seed(rng) -> dict:
    """Return ``{"seed": rng}`` when `rng` is an integer seed, else an empty dict."""
    if isinstance(rng, numbers.Integral) and not isinstance(rng, bool):
        return {"seed": int(rng)}
    return {}


def damaged_pipe(
    n: int,
    *,
    shape: str = "straight",
    radius: float = 0.25,
    length: float = 2.0,
    bend_radius: float = 0.6,
    leg: float = 0.5,
    defects=(),
    ovality: float = 0.0,
    ovality_clock: float = 0.0,
    ovality_span: tuple[float, float] | None = None,
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample a pipe with dents, bulges and ovality: a straight pipe or a 90 degree elbow.

    The undeformed pipe is either straight along +z from z = 0 to `length`
    (``shape="straight"``) or the elbow of `sample_elbow` (``shape="elbow"``: a leg along
    +z, a bend in the x-z plane, a leg along +x). Its wall radius becomes
    ``r(clock, s) = radius + sum of the defects + (D o / 4) cos(2 (clock - ovality_clock))``
    with D = 2 radius and o = `ovality` = (D_max - D_min) / D, s the arc length along the
    centreline. Points are drawn uniformly in area on the undeformed wall and moved along
    the radius of their cross-section onto the damaged wall.

    Clock angles are degrees clockwise looking along the centreline from its start:
    12 o'clock (0) is +y and 3 o'clock (90) is ``t x y``, t the centreline's unit tangent
    (-x where the pipe runs along +z, +z on the elbow's second leg along +x). On the elbow
    (bent in the x-z plane) +y stays 12 o'clock all along.

    Parameters
    ----------
    n : int
    shape : {"straight", "elbow"}
    radius : float
        Radius of the undeformed pipe, in metres.
    length : float
        Length of the straight pipe; ignored for the elbow.
    bend_radius, leg : float
        The elbow's bend radius (``> radius`` plus the largest outward change) and the
        length of each of its legs (see `sample_elbow`); ignored for the straight pipe.
    defects : sequence of Defect
        Their `axial` is measured along the centreline, at most its length (`length`, or
        ``2 leg + pi bend_radius / 2`` for the elbow).
    ovality : float in [0, 1)
        (D_max - D_min) / D of the cross-sections on `ovality_span`.
    ovality_clock : float
        Clock angle of the major axis, degrees in [0, 360).
    ovality_span : (float, float), optional
        Arc lengths (s0, s1) along the centreline where the ovality has its full value;
        default the whole pipe. Beyond them it fades to zero over one pipe radius
        (``cos^2`` taper), so the wall stays smooth.
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        ``normals`` are the damaged wall's outward unit normals, from the exact gradient of
        r; ``distance`` is the distance to the damaged wall (see Notes); ``area`` is that
        of the undeformed wall, ``2 pi radius`` times the centreline's length (dents and
        bulges add a fraction about ``(depth / width)^2``, ovality about ``o^2``);
        ``truth_mesh`` is the tube (or elbow) grid of the undeformed wall with every vertex
        moved onto the damaged wall (default spacing also at most the narrowest defect's
        width / 8); ``truth_record`` holds ``kind`` ("damaged pipe" or "damaged elbow"),
        ``radius``, ``length`` (or ``leg`` and ``bend_radius``), ``clock_convention``,
        ``ovality`` (``value``, ``clock``, ``span``, ``taper``), ``defects`` (each with its
        fields and ``centre``, the point [x, y, z] of the undeformed wall it is centred
        on), ``noise``, ``outliers`` and, for an integer `rng`, ``seed``.

    Raises
    ------
    InputError
        If a number is out of range, `shape` is unknown, a defect lies beyond the
        centreline's end, the dents and ovality could reach the axis, or (elbow) the bulges
        and ovality could move the wall out to the bend radius, folding it.
    TypeError
        If a defect is not a `Defect`.

    See Also
    --------
    Defect, scan_damaged_pipe, sample_elbow, write_sample

    Notes
    -----
    ``distance`` is a first-order approximation: ``|rho - r| / sqrt(1 + (r_theta / r)^2 +
    (r_s / J)^2)``, with rho the query's distance from the centreline in its
    cross-section, r_theta and r_s the derivatives of r and J the bend's stretch of the
    wall at the foot point. That is the distance to the wall's tangent plane at the
    point of the same clock and arc length: exact on the wall and where the wall is
    undeformed, and elsewhere off by a term second order in the distance h. Measured
    against a numerical minimisation, on a 10 mm deep dent 0.1 m wide the error is about
    0.5 h^2 per metre (5e-9 m at h = 0.1 mm, 5e-5 m or 0.5 % at 10 mm), on one 0.2 m wide
    0.07 h^2 per metre. Beyond an open end it is ``hypot(rho - r, overshoot)``, r taken at
    the end.

    Examples
    --------
    >>> dent = Defect("dent", axial=1.0, clock=90.0, depth=0.01, width=0.2)
    >>> pipe = damaged_pipe(20_000, defects=[dent], rng=0)
    >>> pipe.points.shape, pipe.truth_record["defects"][0]["centre"]
    ((20000, 3), [-0.25, 0.0, 1.0])
    """
    n, radius = _count(n), positive(radius, "radius")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    wall, size = _shaped_wall(
        shape, radius, length, bend_radius, leg, defects, ovality, ovality_clock, ovality_span
    )
    kind = f"damaged {'pipe' if shape == 'straight' else 'elbow'}"
    record = {"kind": kind, "radius": radius, **size}
    record.update(wall.record(), noise=noise, outliers=outliers, **_seed(rng))
    rng = require_rng(rng)
    if shape == "straight":
        phi = rng.uniform(0.0, 2.0 * np.pi, n)
        s = rng.uniform(0.0, wall.length, n)
    else:
        s, phi = _elbow_sites(n, radius, wall.bend_radius, wall.leg, rng)
    points, normals = wall.surface(np.mod(phi - 0.5 * np.pi, 2.0 * np.pi), s)
    points = add_noise(points, noise, rng=rng)
    area = 2.0 * np.pi * radius * wall.length
    return finish(
        points,
        normals,
        wall.distance,
        area,
        wall.mesh,
        outliers=outliers,
        rng=rng,
        truth_record=record,
    )


def scan_damaged_pipe(
    *,
    shape: str = "straight",
    radius: float = 0.25,
    length: float = 2.0,
    bend_radius: float = 0.6,
    leg: float = 0.5,
    defects=(),
    ovality: float = 0.0,
    ovality_clock: float = 0.0,
    ovality_span: tuple[float, float] | None = None,
    stations=None,
    offset: float = 0.05,
    rotation_step: float = 1.0,
    noise_scale: float = 1.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Simulate an in-pipe robot's scans of a straight pipe or an elbow with dents, bulges
    and ovality.

    The pipe is that of `damaged_pipe`: straight along +z from z = 0 to `length`
    (``shape="straight"``) or the elbow of `sample_elbow` (``shape="elbow"``), its wall
    radius damaged as there. At each of the `stations` the robot stops and takes the scan
    of `scan_pipe`: a Hokuyo URG-04LX-like scanner `offset` from the centreline, its scan
    plane containing the centreline's tangent, turned through a full circle in steps of
    `rotation_step` degrees, with the same beams, range limits and range noise. In the
    elbow the scanner at arc length s0 takes `scan_pipe`'s pose with its x, y and z axes
    along the centreline's in-plane normal (towards the bend's centre), +y and the
    tangent at s0, so its origin circles the centreline in the cross-section at s0. A beam
    returns the first point where it meets the damaged wall, unless that lies beyond an
    open end or outside the range limits: in the elbow, a beam from one leg can see the
    bend and the other leg.

    Clock angles are degrees clockwise looking along the centreline from its start:
    12 o'clock (0) is +y and 3 o'clock (90) is ``t x y``, t the centreline's unit tangent
    (-x where the pipe runs along +z; on the elbow, 90 is the outer side of the bend and
    270 the inner side).

    Parameters
    ----------
    shape : {"straight", "elbow"}
    radius : float
        Radius of the undeformed pipe, in metres.
    length : float
        Length of the straight pipe; ignored for the elbow.
    bend_radius, leg : float
        The elbow's bend radius and leg length, as in `damaged_pipe`; ignored for the
        straight pipe.
    defects : sequence of Defect
        With ``axial`` the arc length of the centre along the centreline (the height z on
        the straight pipe), at most the centreline's length.
    ovality, ovality_clock, ovality_span
        As in `damaged_pipe`; the span is in arc length.
    stations : sequence of float, optional
        Arc lengths s0 of the scanner along the centreline (heights z0 on the straight
        pipe), each in ``[0, length]`` or, for the elbow, ``[0, 2 leg + pi bend_radius /
        2]``; default one at the centreline's middle.
    offset : float
        Distance of the scanner's origin from the centreline, below ``radius`` less the
        largest inward change of the wall.
    rotation_step : float
        Degrees between scan lines, in (0, 360].
    noise_scale : float
        Multiplies the URG-04LX range noise (see `scan_pipe`); 0 gives exact ranges.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`); each
        gets the viewpoint of a random scan point.
    rng : numpy.random.Generator or int or None
        Draws the range noise (station by station) and the outliers.

    Returns
    -------
    Sample
        ``points`` (N, 3): the stations' points concatenated in station order, each
        ordered by scan line then beam angle; ``viewpoints`` (N, 3), the scanner's origin
        of each point; ``normals`` (N, 3), the damaged wall's outward normals at the true
        hits; ``distance``, ``area`` and ``truth_mesh`` as in `damaged_pipe`;
        ``truth_record`` as there, with kind "damaged pipe scan" or "damaged elbow scan",
        ``noise_scale``, ``stations``, ``offset`` and ``rotation_step`` instead of
        ``noise``.

    Raises
    ------
    InputError
        As `damaged_pipe` and `scan_pipe` do, if a station is outside the centreline or
        the scanner's origin could lie outside the damaged wall.
    TypeError
        If a defect is not a `Defect`.

    See Also
    --------
    scan_pipe, damaged_pipe, Defect, hokuyo_accuracy

    Notes
    -----
    In the straight pipe the scan plane contains the axis, so each beam meets the wall at
    a fixed clock (that of its rotation psi, or psi + 180 degrees past the axis) and its
    hit is the first root t of ``|offset + t cos(beta)| = r(clock, z0 + t sin(beta))``.
    Where r does not change along the beam within the band of radii the wall can take,
    the root is closed-form; elsewhere the beam is marched through that band in steps of
    at most 1 mm of radius and 1/8 of the narrowest defect (or the ovality taper) along
    z. In the elbow a beam's clock and arc length change along it, so the gap ``rho -
    r(clock, s)`` (rho the distance from the centreline) is marched from the scanner:
    straight to the band of radii the wall can take, then in steps of the gap over a bound
    on its rate of change along the beam (sphere tracing), but no shorter than the smaller
    of a step that could change the gap by 1 mm and one that could move 1/8 of the
    narrowest feature along the wall. In both the first crossing bracketed is refined (Illinois
    method) until the hit is within 1e-12 m of the wall. Only a sliver of the wall thinner
    than the shortest step along a beam at grazing incidence could be missed. With the
    defaults plus four defects and a partial ovality, 21 stations along a 20 m pipe at
    ``rotation_step=2`` (2.26 million points) take about 4 s. The elbow's march is
    slower: 8 stations 0.25 m apart at ``rotation_step=1`` (1.49 million points) take
    about 11 s on a clean elbow and 33 s with three defects and a partial ovality.

    Examples
    --------
    >>> dent = Defect("dent", axial=1.0, clock=0.0, depth=0.01, width=0.2)
    >>> scan = scan_damaged_pipe(defects=[dent], stations=[0.8, 1.2], rotation_step=30.0)
    >>> scan.points.shape, scan.truth_record["stations"]
    ((12144, 3), [0.8, 1.2])
    >>> elbow = scan_damaged_pipe(shape="elbow", stations=[0.5], rotation_step=30.0)
    >>> elbow.points.shape, elbow.truth_record["kind"]
    ((6276, 3), 'damaged elbow scan')
    """
    radius = positive(radius, "radius")
    wall, size = _shaped_wall(
        shape, radius, length, bend_radius, leg, defects, ovality, ovality_clock, ovality_span
    )
    kind = f"damaged {'pipe' if shape == 'straight' else 'elbow'} scan"
    record = {"kind": kind, "radius": radius, **size}
    length = wall.length
    if shape == "straight":
        what, bound = "heights", f"length={length!r}"
    else:
        what, bound = "arc lengths", f"{length:.6g} (the centreline's length)"
    g = _geometry(
        radius, length, offset, None, rotation_step, HOKUYO_STEP, HOKUYO_FIELD, HOKUYO_RANGE
    )
    noise_scale = _noise_scale(noise_scale)
    outliers = _fraction(outliers, "outliers")
    if g.offset >= radius - wall.inward:
        raise InputError(
            f"offset must be below radius less the wall's inward change, "
            f"{radius - wall.inward:.6g} m; got {offset!r}"
        )
    stations = [0.5 * length] if stations is None else list(np.atleast_1d(stations))
    for z0 in stations:
        if isinstance(z0, bool) or not isinstance(z0, numbers.Real) or not 0 <= z0 <= length:
            raise InputError(f"stations must be {what} in [0, {bound}]; got {z0!r}")
    if not stations:
        raise InputError("stations is empty; give at least one scanner position")
    stations = [float(z0) for z0 in stations]
    record.update(
        wall.record(),
        noise_scale=noise_scale,
        stations=stations,
        offset=g.offset,
        rotation_step=g.rotation_step,
        outliers=outliers,
        **_seed(rng),
    )
    rng = require_rng(rng)
    points, normals, viewpoints = [], [], []
    for z0 in stations:
        if shape == "elbow":  # z0 is an arc length
            for origin, direction, t in _elbow_station_hits(wall, g, z0):
                measured = _measure(t, noise_scale, rng)
                points.append(origin + measured[:, None] * direction)
                hits = origin + t[:, None] * direction
                s, theta, _, _ = wall.locate(hits)
                normals.append(wall.surface(theta, s)[1])
                viewpoints.append(origin)
            continue
        for psi, beta, theta, t in _station_hits(wall, g, z0):
            measured = _measure(t, noise_scale, rng)
            points.append(_beam_points(psi, beta, measured, g.offset, z0))
            normals.append(wall.surface(theta, z0 + t * np.sin(beta))[1])
            viewpoints.append(_origins(psi, g.offset, z0))
    area = 2.0 * np.pi * radius * length
    return finish(
        np.concatenate(points),
        np.concatenate(normals),
        wall.distance,
        area,
        wall.mesh,
        outliers=outliers,
        rng=rng,
        viewpoints=np.concatenate(viewpoints),
        truth_record=record,
    )


@dataclass(frozen=True)
class _Band:
    """Per beam of a station (K,): the stretch of the beam where the wall can be met.

    The beam's radial coordinate on the side of its hit is ``start + t across`` and its
    height ``z0 + t sin_b``; the wall lies between ``t_low`` and ``t_end`` (cut short at
    the range limit and the open ends), heights ``z_lo`` to ``z_hi``; ``live`` beams have
    such a stretch, marched in ``steps`` steps where the wall changes along it.
    """

    beta: np.ndarray
    sin_b: np.ndarray
    start: np.ndarray
    across: np.ndarray
    t_low: np.ndarray
    t_end: np.ndarray
    z_lo: np.ndarray
    z_hi: np.ndarray
    steps: np.ndarray
    live: np.ndarray


def _band(wall: _Wall, g, z0: float) -> _Band:
    """Return the stretch of every beam of the scanner at height `z0` where it can hit."""
    beta = _beam_angles(g)
    cos_b, sin_b = np.cos(beta), np.sin(beta)
    across = np.abs(cos_b)
    start = np.where(cos_b >= 0.0, 1.0, -1.0) * g.offset
    low, high = wall.radius - wall.inward - 1e-9, wall.radius + wall.outward + 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        t_low = (low - start) / across
        t_high = (high - start) / across
        exit_t = np.where(sin_b > 0, (g.length - z0) / sin_b, -z0 / sin_b)
    exit_t = np.where(sin_b == 0, np.inf, exit_t)
    # Past the range limit or an open end a beam returns nothing: march no further.
    t_end = np.minimum.reduce([t_high, np.full(beta.size, g.range_limits[1]), exit_t])
    live = np.isfinite(t_low) & (t_low <= t_end)
    length = np.where(live, t_end - t_low, 0.0)
    steps = np.maximum(
        np.ceil(length * across / _RADIAL_STEP),
        np.ceil(length * np.abs(sin_b) / (_AXIAL_SHARE * wall.feature)),
    )
    steps = 2 ** np.ceil(np.log2(np.maximum(steps, 1.0))).astype(np.int64)  # few sizes
    z_a, z_b = z0 + t_low * sin_b, z0 + t_end * sin_b
    return _Band(
        beta=beta,
        sin_b=sin_b,
        start=start,
        across=across,
        t_low=t_low,
        t_end=t_end,
        z_lo=np.minimum(z_a, z_b),
        z_hi=np.maximum(z_a, z_b),
        steps=steps,
        live=live,
    )


def _station_hits(wall: _Wall, g, z0: float):
    """Yield the returning beams of the scanner at height `z0`, a batch of lines at a time.

    Each batch is (psi, beta, theta, t), all (K,): rotation and beam angle (radians), the
    clock of the hit (radians) and its true range, ordered by scan line then beam angle.
    """
    band = _band(wall, g, z0)
    turn = np.where(band.start >= 0.0, -0.5, 0.5) * np.pi  # clock = psi - 90 deg (or + 90)
    every_psi = _line_angles(g)
    lines = max(1, _BATCH // (4 * band.beta.size))
    for first in range(0, every_psi.size, lines):
        psi = every_psi[first : first + lines, None]
        shape = (psi.size, band.beta.size)
        theta = np.mod(psi + turn, 2.0 * np.pi).ravel()
        beam = np.broadcast_to(np.arange(band.beta.size), shape).ravel()
        t = np.full(theta.size, np.nan)
        alive = np.flatnonzero(band.live[beam])
        varying = _varies(wall, theta[alive], band.z_lo[beam[alive]], band.z_hi[beam[alive]])
        # Where r is constant along the beam's stretch, the root is closed-form.
        fixed, i = alive[~varying], beam[alive[~varying]]
        r = wall.radius_at(theta[fixed], z0 + band.t_low[i] * band.sin_b[i])
        t[fixed] = (r - band.start[i]) / band.across[i]
        moving = alive[varying]
        for steps in np.unique(band.steps[beam[moving]]):
            group = moving[band.steps[beam[moving]] == steps]
            per = max(1, _BATCH // (int(steps) + 1))
            for j in range(0, group.size, per):
                chosen = group[j : j + per]
                t[chosen] = _first_crossing(wall, band, z0, beam[chosen], theta[chosen])
        z = z0 + t * band.sin_b[beam]
        lo, hi = g.range_limits
        with np.errstate(invalid="ignore"):
            hit = np.flatnonzero((t >= lo) & (t <= hi) & (z >= 0.0) & (z <= g.length))
        yield np.broadcast_to(psi, shape).ravel()[hit], band.beta[beam[hit]], theta[hit], t[hit]


def _varies(wall: _Wall, theta, z_lo, z_hi) -> np.ndarray:
    """Return which beams (M,) may see r change along their band [z_lo, z_hi] of heights."""
    varies = np.zeros(theta.shape, dtype=bool)
    for defect in wall.defects:
        half = 0.5 * defect.width
        near = np.abs(wall.radius * _wrap(theta - math.radians(defect.clock))) < half
        varies |= near & (z_hi > defect.axial - half) & (z_lo < defect.axial + half)
    if wall.ovality > 0:
        s0, s1 = wall.span
        for a, b in ((s0 - wall.taper, s0), (s1, s1 + wall.taper)):
            varies |= (z_hi > a) & (z_lo < b)
    return varies


def _first_crossing(wall: _Wall, band: _Band, z0: float, beam, theta) -> np.ndarray:
    """Return the first range t (M,) where the beams `beam` (M,) meet the wall at clocks
    `theta` (M,), all marched in the same number of steps; NaN where they do not.

    The first sign change of the radial gap ``start + t across - r(theta, z0 + t sin_b)``
    along the march is refined by the Illinois method until the gap is below `_TOLERANCE`.
    """
    start, across, sin_b = band.start[beam], band.across[beam], band.sin_b[beam]

    def gap(t, rows):
        return start[rows] + t * across[rows] - wall.radius_at(theta[rows], z0 + t * sin_b[rows])

    count, steps = beam.size, int(band.steps[beam[0]])
    t_low, t_end = band.t_low[beam, None], band.t_end[beam, None]
    t = t_low + (t_end - t_low) * (np.arange(steps + 1) / steps)
    every = np.repeat(np.arange(count), steps + 1)
    outside = gap(t.ravel(), every).reshape(count, steps + 1) >= 0.0
    first = np.argmax(outside, axis=1)
    rows = np.flatnonzero(outside.any(axis=1))
    lo, hi = t[rows, first[rows] - 1], t[rows, first[rows]]
    found = np.full(count, np.nan)
    found[rows] = _refine(gap, rows, lo, hi, gap(lo, rows), gap(hi, rows))
    return found


def _refine(gap, rows, lo, hi, g_lo, g_hi) -> np.ndarray:
    """Return the roots (M,) of ``gap(t, rows)`` bracketed by ``g_lo < 0 <= g_hi`` (M,).

    The Illinois method runs until the gap is below `_TOLERANCE` (or the bracket is).
    """
    rows, index = np.asarray(rows), np.arange(np.size(rows))
    last = np.zeros(index.size, dtype=np.int8)  # which end moved last: -1 lo, +1 hi
    found = np.full(index.size, np.nan)
    for _ in range(_ITERATIONS):
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
        if rows.size == 0:
            return found
    raise AssertionError(f"{rows.size} beams did not converge in {_ITERATIONS} iterations")


def _elbow_station_hits(wall: _Wall, g, s0: float):
    """Yield the returning beams of the scanner at arc length `s0` of the elbow, a batch of
    lines at a time.

    Each batch is (origin, direction, t): the scanner's origins and the beams' unit
    directions (K, 3) and their true ranges (K,), ordered by scan line then beam angle.
    The scanner's local frame is that of `scan_pipe` with e_x, e_y, e_z mapped to the
    in-plane normal, +y and the tangent of the centreline at `s0`.
    """
    centre, e_n, tangent, _ = wall.frame(np.array([s0]))
    axes = np.stack([e_n[0], _Y, tangent[0]])  # rows: local x, y, z in the world
    beta = _beam_angles(g)
    every_psi = _line_angles(g)
    lines = max(1, _BATCH // (4 * beta.size))
    x_end = wall.bend_radius + wall.leg  # the second leg's open end; the first's is z = 0
    lo, hi = g.range_limits
    for first in range(0, every_psi.size, lines):
        psi = every_psi[first : first + lines]
        shape = (psi.size, beta.size)
        origin = np.repeat(_origins(psi, g.offset, 0.0) @ axes + centre, beta.size, axis=0)
        unit = _beam_points(psi[:, None], beta, np.ones(shape), 0.0, 0.0)
        direction = unit.reshape(-1, 3) @ axes
        with np.errstate(divide="ignore", invalid="ignore"):
            down = np.where(direction[:, 2] < 0.0, -origin[:, 2] / direction[:, 2], np.inf)
            out = np.where(direction[:, 0] > 0.0, (x_end - origin[:, 0]) / direction[:, 0], np.inf)
        # Past the range limit or an open end a beam returns nothing: march no further.
        t_end = np.clip(np.minimum(down, out), 0.0, hi)
        t = _elbow_first_crossing(wall, origin, direction, t_end)
        with np.errstate(invalid="ignore"):
            hit = np.flatnonzero(t >= lo)
        yield origin[hit], direction[hit], t[hit]


def _elbow_first_crossing(wall: _Wall, origin, direction, t_end) -> np.ndarray:
    """Return the first range t (M,) in ``[0, t_end]`` where the beams ``origin + t
    direction`` (M, 3) meet the elbow's damaged wall; NaN where they do not.

    The gap ``rho - r(theta, s)`` (negative inside) is marched from the scanner: up to
    the band of radii the wall can take a step keeps rho inside it; within the band a
    step is the gap over a bound on its slope along the beam (sphere tracing), but never
    shorter than the smaller of a step that could change the gap by 1 mm and one that
    could move 1/8 of the narrowest feature along the wall. The first step that ends
    outside is refined by `_refine`.
    """
    low, high = wall.radius - wall.inward, wall.radius + wall.outward
    rb = wall.bend_radius
    reach = min(0.25 * low, 0.5 * (rb - high))  # the longest slope-bounded step
    # A unit step moves a point with rho in [low / 2, high + reach] by at most `speed`
    # on the unrolled wall (R theta, s), so it changes the gap by at most `lipschitz`.
    speed = max(2.0 * wall.radius / low, rb / (rb - high - reach))
    lipschitz = 1.0 + wall.slope * speed
    fine = min(_RADIAL_STEP / lipschitz, _AXIAL_SHARE * wall.feature / speed)

    def gap(t, rows):
        s, theta, rho, _ = wall.locate(origin[rows] + t[:, None] * direction[rows])
        return rho - wall.radius_at(theta, s), rho

    rows = np.arange(t_end.size)
    t = np.zeros(rows.size)
    g_t, rho = gap(t, rows)
    brackets = []
    while rows.size:
        traced = np.where(rho >= 0.75 * low, np.minimum(-g_t / lipschitz, reach), 0.0)
        step = np.maximum(np.maximum(low - rho, traced), fine)
        t_next = np.minimum(t + step, t_end[rows])
        g_next, rho_next = gap(t_next, rows)
        crossed = g_next >= 0.0
        brackets.append((rows[crossed], t[crossed], t_next[crossed], g_t[crossed], g_next[crossed]))
        keep = ~crossed & (t_next < t_end[rows])
        rows, t, g_t, rho = rows[keep], t_next[keep], g_next[keep], rho_next[keep]
    found = np.full(t_end.size, np.nan)
    rows, lo, hi, g_lo, g_hi = (np.concatenate(v) for v in zip(*brackets, strict=True))
    found[rows] = _refine(lambda t, rows: gap(t, rows)[0], rows, lo, hi, g_lo, g_hi)
    return found
