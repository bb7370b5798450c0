"""A damaged pipe wall about any centreline: dents, bulges, ovality and joints."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .._validate import positive
from ..errors import InputError
from ..types import Mesh
from . import _truth
from ._distance import query
from ._path import PipePath
from ._sample import _fraction
from ._shapes import _wrap

__all__ = ["CLOCK_CONVENTION", "DEFECT_KINDS", "JOINT_KINDS", "Defect", "Joint"]

#: The clock convention of `Defect` and the ovality, as written into truth records.
CLOCK_CONVENTION = (
    "Clock angles are degrees clockwise looking along the centreline from its start: "
    "12 o'clock (0) is +y and 3 o'clock (90) is t x y, t the centreline's unit tangent "
    "(-x where the pipe runs along +z, +z on the elbow's second leg along +x)."
)
#: Defect kinds: a dent moves the wall towards the axis, a bulge away from it.
DEFECT_KINDS = ("dent", "bulge")
#: Joint kinds: a gap recesses a ring of the wall, an offset steps the pipe beyond it
#: sideways, a bead stands into the bore.
JOINT_KINDS = ("gap", "offset", "bead")

# Joint profiles (m): the axial ramp of a gap's edges and of an offset's step, and the
# axial extent of a bead.
GAP_RAMP = 1e-3
OFFSET_RAMP = 2e-3
BEAD_WIDTH = 0.02


def _settle(feature, what: str, kinds, lengths: tuple[str, ...]) -> None:
    """Validate a frozen feature in place: its kind among `kinds` (None: it has none), its
    position (an arc length >= 0 and a clock angle in [0, 360)) and its `lengths` (> 0),
    all as floats."""
    if kinds is not None and feature.kind not in kinds:
        raise InputError(f"{what} kind must be one of {kinds}; got {feature.kind!r}")
    axial, clock = feature.axial, feature.clock
    for name, value in (("axial", axial), ("clock", clock)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise InputError(f"{what} {name} must be a number; got {value!r}")
    if not (math.isfinite(axial) and axial >= 0.0):
        raise InputError(f"{what} axial must be a distance >= 0 in metres; got {axial!r}")
    if not 0.0 <= clock < 360.0:
        raise InputError(f"{what} clock must be degrees in [0, 360); got {clock!r}")
    object.__setattr__(feature, "axial", float(axial))
    object.__setattr__(feature, "clock", float(clock))
    for name in lengths:
        object.__setattr__(feature, name, positive(getattr(feature, name), f"{what} {name}"))


@dataclass(frozen=True)
class Defect:
    """A dent or a bulge: a smooth round patch of the wall moved along the radius.

    Clock angles are degrees clockwise looking along the centreline from its start:
    12 o'clock (0) is +y and 3 o'clock (90) is ``t x y``, t the centreline's unit tangent
    (-x where the pipe runs along +z, +z on the elbow's second leg along +x). On the elbow
    (bent in the x-z plane) +y stays 12 o'clock all along. On a pipe run 12 o'clock is
    the run's up (see `PipePath`).

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
        _settle(self, "defect", DEFECT_KINDS, ("depth", "width"))

    def record(self, centre) -> dict:
        """The JSON-able truth of the defect, with its `centre` (3,), a point of the wall."""
        return {
            "kind": self.kind,
            "axial": self.axial,
            "clock": self.clock,
            "depth": self.depth,
            "width": self.width,
            "centre": np.asarray(centre, dtype=np.float64).tolist(),
        }


@dataclass(frozen=True)
class Joint:
    """A ring feature of a synthetic pipe's wall: a gap, an offset or a weld bead.

    At arc-length distance ``v = s - axial`` from the joint the wall radius changes by:

    - gap: ``+depth`` over an axial width `size` (a recess all round, the wall moved
      outward), its edges ramped smoothly (``sin``) over 1 mm centred on ``|v| = size /
      2``, so the wall stays continuous;
    - offset: beyond the joint the pipe's cross-sections are circles of the pipe's radius
      about the centreline moved `size` towards `clock`, reached over a smooth 2 mm ramp
      centred on the joint; the wall radius about the original centreline becomes
      ``p + sqrt(R^2 - q^2)`` for the offset's components p along and q across the clock
      direction (about ``R + size cos(clock_angle - clock)``);
    - bead: ``-size cos(pi v / 0.02)^2`` for ``|v| < 0.01``: a ring 20 mm wide standing
      `size` into the bore.

    This is `zeroset.synthetic`'s joint, which shapes a wall; the inspection's
    `zeroset.inspect.Joint` is a measured one.

    Attributes
    ----------
    kind : {"gap", "offset", "bead"}
    axial : float
        Arc length of the joint along the centreline, in metres, ``>= 0``.
    size : float
        A gap's axial width (5-20 mm is typical), an offset's sideways step (2-15 mm), a
        bead's height into the bore (2-5 mm), in metres, ``> 0``.
    clock : float
        An offset's direction, degrees in [0, 360); unused by the other kinds.
    depth : float
        A gap's radial recess, in metres, ``> 0``; unused by the other kinds.

    Raises
    ------
    InputError
        If a field is out of its range.

    Examples
    --------
    >>> Joint("offset", axial=2.0, size=0.005, clock=90.0).size
    0.005
    """

    kind: str
    axial: float
    size: float
    clock: float = 0.0
    depth: float = 0.01

    def __post_init__(self) -> None:
        _settle(self, "joint", JOINT_KINDS, ("size", "depth"))

    def record(self, centre) -> dict:
        """The JSON-able truth of the joint, with its `centre` (3,) on the centreline."""
        return {
            "kind": self.kind,
            "axial": self.axial,
            "size": self.size,
            "clock": self.clock,
            "depth": self.depth,
            "centre": np.asarray(centre, dtype=np.float64).tolist(),
        }


def _step(x: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Return a smooth step (M,) from 0 (x <= -width/2) to 1 (x >= width/2), and d/dx."""
    inside = np.abs(x) < 0.5 * width
    k = np.pi / width
    value = np.where(inside, 0.5 + 0.5 * np.sin(k * np.clip(x, -0.5 * width, 0.5 * width)), 0.0)
    value = np.where(x >= 0.5 * width, 1.0, value)
    return value, np.where(inside, 0.5 * k * np.cos(k * x), 0.0)


@dataclass(frozen=True)
class _Feature:
    """Where a wall feature changes the radius, and bounds on how: its arc-length extent
    [lo, hi], how far it moves the wall in and out, a bound on its slope on the unrolled
    wall, its shortest axial scale, whether it is `sharp` (a shift of the whole pipe,
    beyond an offset, is not: the wall stays a circle there), and whether it changes
    along the centreline, `axial` (the ovality on its span does not: there it depends on
    the clock only)."""

    lo: float
    hi: float
    inward: float
    outward: float
    slope: float
    scale: float
    sharp: bool = True
    axial: bool = True


def _joint_features(j: Joint, radius: float) -> list[_Feature]:
    """Return where a joint changes the radius of a wall of `radius`, and bounds on how."""
    if j.kind == "gap":
        half, slope = 0.5 * (j.size + GAP_RAMP), 0.5 * np.pi * j.depth / GAP_RAMP
        return [_Feature(j.axial - half, j.axial + half, 0.0, j.depth, slope, GAP_RAMP)]
    if j.kind == "bead":
        half, slope = 0.5 * BEAD_WIDTH, np.pi * j.size / BEAD_WIDTH
        return [_Feature(j.axial - half, j.axial + half, j.size, 0.0, slope, BEAD_WIDTH)]
    # An offset: the step, then the shifted pipe, whose radius about the original
    # centreline turns by at most about 2 size / radius per metre of the unrolled wall.
    half, size, turn = 0.5 * OFFSET_RAMP, j.size, 2.0 * j.size / radius
    slope = 0.5 * np.pi * size / OFFSET_RAMP + turn
    return [
        _Feature(j.axial - half, j.axial + half, size, size, slope, OFFSET_RAMP),
        _Feature(j.axial + half, math.inf, size, size, turn, math.inf, False, False),
    ]


def _peak(features: list[_Feature], name: str) -> float:
    """Return the largest sum of the features' `name` over any arc length: where their
    extents overlap."""
    edges = sorted({f.lo for f in features} | {f.hi for f in features} - {math.inf})
    probes = [0.5 * (a + b) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    probes += [edges[-1] + 1.0] if edges else []
    return max(
        (sum(getattr(f, name) for f in features if f.lo < x < f.hi) for x in probes), default=0.0
    )


@dataclass(frozen=True)
class _Wall:
    """A damaged pipe wall ``r(clock, s)`` about the centreline of `path`.

    The methods take clock angles `theta` in radians (see `Defect`) and arc lengths `s`
    along the centreline; stored clocks are in degrees. The ovality has full value on
    `span` and fades with a cos^2 taper over one pipe radius beyond each end.
    """

    radius: float
    path: PipePath
    defects: tuple[Defect, ...]
    ovality: float
    ovality_clock: float  # degrees
    span: tuple[float, float]
    joints: tuple[Joint, ...] = ()

    @property
    def length(self) -> float:
        """The centreline's length."""
        return self.path.length

    @property
    def taper(self) -> float:
        """Length over which the ovality fades beyond its span, in metres."""
        return self.radius

    def features(self) -> list[_Feature]:
        """Return every feature's extent along the centreline and its bounds."""
        out = []
        for d in self.defects:
            dent = d.kind == "dent"
            half = 0.5 * d.width
            move = (d.depth, 0.0) if dent else (0.0, d.depth)
            slope = np.pi * d.depth / d.width
            out.append(_Feature(d.axial - half, d.axial + half, *move, slope, d.width))
        if self.ovality > 0:
            a, s0, s1, taper = 0.5 * self.radius * self.ovality, *self.span, self.taper
            turn = 2.0 * a / self.radius
            slope = turn + a * 0.5 * np.pi / taper
            out.append(_Feature(s0 - taper, s0, a, a, slope, taper))
            out.append(_Feature(s0, s1, a, a, turn, math.inf, axial=False))
            out.append(_Feature(s1, s1 + taper, a, a, slope, taper))
        for j in self.joints:
            out += _joint_features(j, self.radius)
        return out

    @property
    def inward(self) -> float:
        """A bound on how far the wall moves towards the axis."""
        return _peak(self.features(), "inward")

    @property
    def outward(self) -> float:
        """A bound on how far the wall moves away from the axis."""
        return _peak(self.features(), "outward")

    @property
    def feature(self) -> float:
        """The shortest axial scale on which the wall changes: a width, a ramp or the taper."""
        return min((f.scale for f in self.features()), default=math.inf)

    def coordinates(self, x: np.ndarray, hint=None, reach=None):
        """Return tube coordinates of `x` (M, 3): arc length s, clock theta, distance rho from
        the centreline in the cross-section, and the piece of the path holding s (all
        (M,)); `hint` and `reach` as in `PipePath._closest`."""
        foot = self.path._closest(x, hint, reach)
        theta = np.mod(np.arctan2(foot.right, foot.up), 2.0 * np.pi)
        return foot.s, theta, np.hypot(foot.up, foot.right), foot.piece

    def locate(self, x: np.ndarray):
        """Return tube coordinates of `x` (M, 3): arc length s, clock theta, distance rho from
        the centreline in the cross-section, and the overshoot beyond an open end (M,)."""
        s, theta, rho, _ = self.coordinates(x)
        return s, theta, rho, self.path._overshoot(x, s)

    def _offsets(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Return the centreline's shift by the offset joints at arc lengths `s` (M,) as
        (M, 2) components along up and ``tangent x up``, and d/ds of it; None without
        offsets."""
        offsets = [j for j in self.joints if j.kind == "offset"]
        if not offsets:
            return None
        shift, rate = np.zeros((s.size, 2)), np.zeros((s.size, 2))
        for j in offsets:
            w, dw = _step(s - j.axial, OFFSET_RAMP)
            towards = j.size * np.array(_clock_vector(j.clock))
            shift += w[:, None] * towards
            rate += dw[:, None] * towards
        return shift, rate

    def shift(self, s: np.ndarray) -> np.ndarray:
        """Return how far (M, 3) the offset joints move the centreline at arc lengths `s`."""
        offsets = self._offsets(s)
        if offsets is None:
            return np.zeros((s.size, 3))
        f = self.path._evaluate(s)
        return offsets[0][:, :1] * f.up + offsets[0][:, 1:] * f.right

    def radius_at(self, theta: np.ndarray, s: np.ndarray, *, gradient: bool = False):
        """Return the wall radius r (M,) at clocks `theta` and arc lengths `s` (M,); with
        `gradient`, also its derivatives dr/dtheta (per radian) and dr/ds."""
        r = np.full(theta.shape, self.radius)
        r_theta, r_s = np.zeros(theta.shape), np.zeros(theta.shape)
        for defect in self.defects:
            half = 0.5 * defect.width
            near = np.flatnonzero(np.abs(s - defect.axial) < half)
            u = self.radius * _wrap(theta[near] - math.radians(defect.clock))
            v = s[near] - defect.axial
            d = np.hypot(u, v)
            inside = d < half
            near, u, v, d = near[inside], u[inside], v[inside], d[inside]
            sign = -1.0 if defect.kind == "dent" else 1.0
            r[near] += sign * defect.depth * np.cos(np.pi * d / defect.width) ** 2
            if gradient:
                # d/dd of cos^2(pi d / w), divided by d: -(2 pi^2 / w^2) sinc(2 d / w).
                slope = -sign * defect.depth * 2.0 * np.pi**2 / defect.width**2
                slope = slope * np.sinc(2.0 * d / defect.width)
                r_theta[near] += slope * u * self.radius
                r_s[near] += slope * v
        if self.ovality > 0:
            weight, weight_s = self._span_weight(s)
            amplitude = 0.5 * self.radius * self.ovality  # D o / 4
            phase = 2.0 * (theta - math.radians(self.ovality_clock))
            r += amplitude * np.cos(phase) * weight
            r_theta -= 2.0 * amplitude * np.sin(phase) * weight
            r_s += amplitude * np.cos(phase) * weight_s
        for joint in self.joints:
            if joint.kind == "gap":
                near = np.flatnonzero(np.abs(s - joint.axial) < 0.5 * (joint.size + GAP_RAMP))
                v = s[near] - joint.axial
                w, dw = _step(0.5 * joint.size - np.abs(v), GAP_RAMP)
                r[near] += joint.depth * w
                r_s[near] -= joint.depth * dw * np.sign(v)
            elif joint.kind == "bead":
                near = np.flatnonzero(np.abs(s - joint.axial) < 0.5 * BEAD_WIDTH)
                v, k = s[near] - joint.axial, np.pi / BEAD_WIDTH
                r[near] -= joint.size * np.cos(k * v) ** 2
                r_s[near] += joint.size * k * np.sin(2.0 * k * v)
        offsets = self._offsets(s)
        if offsets is not None:
            (dx, dy), (ex, ey) = offsets[0].T, offsets[1].T
            c, n = np.cos(theta), np.sin(theta)
            along, across = dx * c + dy * n, dx * n - dy * c
            root = np.sqrt(self.radius**2 - across**2)
            r += along + root - self.radius
            r_theta -= across + across * along / root
            r_s += ex * c + ey * n - across * (ex * n - ey * c) / root
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
        f = self.path._evaluate(s)
        c, n = np.cos(theta)[:, None], np.sin(theta)[:, None]
        out = c * f.up + n * f.right  # the clock direction; d(out)/dtheta is `turn`
        turn = c * f.right - n * f.up
        # P(theta, s) = centre + r out: dP/dtheta = r_theta out + r turn and, as up and
        # right are parallel transported, dP/ds = (1 - r bend . out) tangent + r_s out, so
        # this is normal to both.
        stretch = 1.0 - r * np.einsum("ij,ij->i", f.bend, out)
        normal = out - (r_theta / r)[:, None] * turn - (r_s / stretch)[:, None] * f.tangent
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return f.centre + r[:, None] * out, normal

    def distance(self, x) -> np.ndarray:
        """Distance (M,) from `x` (M, 3) to the wall, to first order in the wall's slope."""
        x = query(x)
        s, theta, rho, beyond = self.locate(x)
        r, r_theta, r_s = self.radius_at(theta, s, gradient=True)
        f = self.path._evaluate(s)
        out = np.cos(theta)[:, None] * f.up + np.sin(theta)[:, None] * f.right
        stretch = 1.0 - r * np.einsum("ij,ij->i", f.bend, out)
        slope = np.sqrt(1.0 + (r_theta / r) ** 2 + (r_s / stretch) ** 2)
        return np.where(beyond > 0.0, np.hypot(rho - r, beyond), np.abs(rho - r) / slope)

    def spacing(self, spacing: float | None) -> float:
        """Return the truth mesh's edge length: `spacing`, or the default, no coarser than
        an eighth of the narrowest defect."""
        # The bounding box of the undamaged tube, from rings R / 4 apart of 64 points.
        s = np.repeat(self.path.sample(self.radius / 4.0)[0], 64)
        f = self.path._evaluate(s)
        clock = np.tile(np.radians(np.arange(64) * 5.625), s.size // 64)[:, None]
        ring = f.centre + self.radius * (np.cos(clock) * f.up + np.sin(clock) * f.right)
        diagonal = float(np.linalg.norm(ring.max(axis=0) - ring.min(axis=0)))
        area = 2.0 * np.pi * self.radius * self.length
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        if spacing is None and self.defects:  # fine enough to show the narrowest defect
            narrowest = min(d.width for d in self.defects)
            h = _truth.resolve_spacing(min(h, narrowest / 8.0), diagonal=diagonal, area=area)
        return h

    def grid(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return a grid on the wall with edges of about `h`, and rows a quarter of a
        joint's shortest scale apart across it: arc lengths (R,), clocks (C,) and the
        points (R, C, 3) and outward normals (R, C, 3) there."""
        rows = [np.zeros(1)]
        for k, (lo, hi) in enumerate(zip(self.path._s0[:-1], self.path._s0[1:], strict=True)):
            count = max(2 if self.path._bend[k] else 1, math.ceil((hi - lo) / h))
            rows.append(np.linspace(lo, hi, count + 1)[1:])
        for j in self.joints:
            for f in _joint_features(j, self.radius):
                if f.sharp:
                    lo, hi = max(f.lo, 0.0), min(f.hi, self.length)
                    rows.append(np.linspace(lo, hi, max(2, math.ceil(4.0 * (hi - lo) / f.scale))))
        s = np.sort(np.concatenate(rows))
        s = s[np.concatenate([[True], np.diff(s) > 1e-9 * max(h, self.length)])]
        count = max(32, math.ceil(2.0 * math.pi * self.radius / h))
        clocks = np.mod(2.0 * math.pi * np.arange(count) / count - 0.5 * np.pi, 2.0 * np.pi)
        points, normals = self.surface(np.tile(clocks, s.size), np.repeat(s, count))
        return s, points.reshape(s.size, count, 3), normals.reshape(s.size, count, 3)

    def mesh(self, spacing: float | None) -> Mesh:
        """Mesh the damaged wall: a tube grid along the centreline moved onto the wall."""
        _, points, normals = self.grid(self.spacing(spacing))
        return _truth.grid_mesh(points, normals)

    def record(self) -> dict:
        """Return the JSON-able truth of the wall: radius, ovality and defects.

        A defect's ``centre`` is the point at its clock on the circle of the pipe's radius
        about the true centreline (moved by any offsets).
        """
        s = np.array([d.axial for d in self.defects])
        theta = np.radians([d.clock for d in self.defects])
        f = self.path._evaluate(s)
        out = np.cos(theta)[:, None] * f.up + np.sin(theta)[:, None] * f.right
        centres = _rounded(f.centre + self.shift(s) + self.radius * out)
        return {
            "radius": self.radius,
            "clock_convention": CLOCK_CONVENTION,
            "ovality": {
                "value": self.ovality,
                "clock": self.ovality_clock,
                "span": list(self.span),
                "taper": self.taper,
            },
            "defects": [d.record(centres[i]) for i, d in enumerate(self.defects)],
        }


def _rounded(points: np.ndarray) -> np.ndarray:
    """Round points (M, 3) for JSON: 12 decimals, no -0.0."""
    return np.round(points, 12) + 0.0


def _clock_vector(clock: float) -> tuple[float, float]:
    """Return the components along up and ``tangent x up`` of the clock direction (degrees)."""
    return math.cos(math.radians(clock)), math.sin(math.radians(clock))


def _wall(radius, path, defects, ovality, ovality_clock, span, joints=()) -> _Wall:
    """Validate a damaged wall's description (radius already positive) and build it."""
    length = path.length
    defects, joints = tuple(defects), tuple(joints)
    for defect in defects:
        if not isinstance(defect, Defect):
            raise TypeError(f"defects must be Defect instances; got {type(defect).__name__}")
    for joint in joints:
        if not isinstance(joint, Joint):
            raise TypeError(
                f"joints must be zeroset.synthetic.Joint instances; got {type(joint).__name__}"
            )
    for what, feature in [("defect", d) for d in defects] + [("joint", j) for j in joints]:
        if feature.axial > length:
            raise InputError(
                f"{what} at axial={feature.axial!r} lies beyond the centreline's end at "
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
    wall = _Wall(radius, path, defects, ovality, float(ovality_clock), (s0, s1), joints)
    if wall.inward >= radius:
        raise InputError(
            f"dents, beads, offsets and ovality could move the wall {wall.inward:.6g} m "
            f"inward, through the axis of a pipe of radius {radius!r}; make them shallower"
        )
    bends = path._radius[path._bend]
    if bends.size and radius + wall.outward >= bends.min():
        raise InputError(
            f"bulges, gaps, offsets and ovality could move the wall out to "
            f"{radius + wall.outward:.6g} m, beyond bend_radius={float(bends.min())!r} (the "
            f"smallest bend's); make them smaller"
        )
    return wall
