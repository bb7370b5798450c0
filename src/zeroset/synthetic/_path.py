"""A pipe run's centreline: straight legs and circular bends, with a parallel-transported frame."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .._validate import as_vector3, positive
from ..errors import InputError
from ._distance import query

__all__ = ["PipePath"]

#: Kinds of piece of a `PipePath`: ``("straight", length)`` and
#: ``("bend", bend_radius, angle_deg, roll_deg)``.
PIECE_KINDS = ("straight", "bend")


def _cos_sin(degrees: float) -> tuple[float, float]:
    """Return cos and sin of an angle in degrees, exact at multiples of 90 degrees."""
    quarter, rest = divmod(float(degrees) % 360.0, 90.0)
    if rest == 0.0:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarter)]
    return math.cos(math.radians(degrees)), math.sin(math.radians(degrees))


class _Frame(NamedTuple):
    """The centreline's frame at M arc lengths, each (M, 3): centre, unit tangent, unit up
    (12 o'clock), unit right (``tangent x up``, 3 o'clock) and the curvature vector
    (towards a bend's centre, 1 / bend radius long; zero on straights)."""

    centre: np.ndarray
    tangent: np.ndarray
    up: np.ndarray
    right: np.ndarray
    bend: np.ndarray


class _Foot(NamedTuple):
    """Where M points stand to the centreline: the arc length s (M,) of the nearest
    centreline point and its piece (M,), the squared distance to it (M,), and the
    components along up and right there (M,) of the point's offset from the centreline
    in the cross-section."""

    s: np.ndarray
    piece: np.ndarray
    distance2: np.ndarray
    up: np.ndarray
    right: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    """`v` (..., 3) scaled to unit length along its last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _piece(piece) -> tuple:
    """Validate one piece and return it with float fields."""
    if not isinstance(piece, tuple | list) or not piece or piece[0] not in PIECE_KINDS:
        raise InputError(
            "each piece must be ('straight', length) or ('bend', bend_radius, angle_deg, "
            f"roll_deg); got {piece!r}"
        )
    kind, values = piece[0], tuple(piece[1:])
    if kind == "straight":
        if len(values) != 1:
            raise InputError(f"a straight piece is ('straight', length); got {piece!r}")
        return ("straight", positive(values[0], "a straight piece's length"))
    if len(values) != 3:
        raise InputError(f"a bend is ('bend', bend_radius, angle_deg, roll_deg); got {piece!r}")
    bend_radius = positive(values[0], "a bend's radius")
    angle, roll = values[1], values[2]
    if isinstance(angle, bool) or not isinstance(angle, numbers.Real) or not 0 < angle <= 180:
        raise InputError(f"a bend's angle must be degrees in (0, 180]; got {angle!r}")
    if isinstance(roll, bool) or not isinstance(roll, numbers.Real) or not math.isfinite(roll):
        raise InputError(f"a bend's roll must be a number of degrees; got {roll!r}")
    return ("bend", bend_radius, float(angle), float(roll))


@dataclass(frozen=True)
class PipePath:
    """A pipe run's centreline: straight legs and circular bends joined with a common tangent.

    The centreline starts at `start` heading along `direction`. Each piece continues it:
    ``("straight", length)`` runs straight on; ``("bend", bend_radius, angle_deg,
    roll_deg)`` turns it through `angle_deg` on a circle of radius `bend_radius`, towards
    the clock direction `roll_deg` of the frame at the bend's start: roll 0 turns towards
    12 o'clock (up), 90 towards 3 o'clock (``tangent x up``), 180 down and 270 towards 9
    o'clock. Starting level with up vertical, rolls 0 and 180 bend in the vertical plane,
    90 and 270 in the horizontal plane, and any other roll leaves both.

    The 12 o'clock direction ("up") starts as `up` projected onto the first cross-section
    and is carried along by parallel transport, so it does not twist: on a straight it is
    constant, and on a bend it turns about the bend's axis by the angle turned (a roll 90
    bend of a level pipe keeps up vertical). Clock angles are clockwise looking along the
    tangent: the radial direction at clock c is ``cos(c) up + sin(c) (tangent x up)``, as
    in `zeroset.inspect`.

    Build one with `build`. Lengths are metres, angles degrees. A pipe about a path needs
    the path to keep clear of itself by more than the pipe's diameter, so that every point
    of its wall has one nearest centreline point.

    Attributes
    ----------
    pieces : tuple of tuple
        The pieces, with float fields.
    start, direction, up : tuple of float
        The start point, the unit start tangent and the unit start up (perpendicular to
        the tangent).

    Examples
    --------
    >>> path = PipePath.build([("straight", 2.0), ("bend", 1.0, 90.0, 90.0)])
    >>> round(path.length, 6)
    3.570796
    >>> centre, tangent, up, curvature = path.frame(np.array([path.length]))
    >>> np.round(centre, 6).tolist(), np.round(tangent, 6).tolist(), (up + 0.0).tolist()
    ([[3.0, -1.0, 0.0]], [[0.0, -1.0, 0.0]], [[0.0, 0.0, 1.0]])
    """

    pieces: tuple[tuple, ...]
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    # Per piece: where it starts along the centreline (P + 1,), whether it bends, its start
    # point, tangent, up and right (P, 3), the direction towards a bend's centre and its
    # axis (P, 3; zero on straights), up's weights on those two (P,), its bend radius (0 on
    # straights), length and angle; for `_closest`, each piece's origin (a straight's start,
    # a bend's centre) and axes (P, 3, 3: t0, up and right, or t0, n0 and b0); and the end
    # point and tangent (3,).
    _s0: np.ndarray = field(init=False, repr=False, compare=False)
    _bend: np.ndarray = field(init=False, repr=False, compare=False)
    _p0: np.ndarray = field(init=False, repr=False, compare=False)
    _t0: np.ndarray = field(init=False, repr=False, compare=False)
    _u0: np.ndarray = field(init=False, repr=False, compare=False)
    _r0: np.ndarray = field(init=False, repr=False, compare=False)
    _n0: np.ndarray = field(init=False, repr=False, compare=False)
    _b0: np.ndarray = field(init=False, repr=False, compare=False)
    _un: np.ndarray = field(init=False, repr=False, compare=False)
    _ub: np.ndarray = field(init=False, repr=False, compare=False)
    _radius: np.ndarray = field(init=False, repr=False, compare=False)
    _size: np.ndarray = field(init=False, repr=False, compare=False)
    _angle: np.ndarray = field(init=False, repr=False, compare=False)
    _origin: np.ndarray = field(init=False, repr=False, compare=False)
    _basis: np.ndarray = field(init=False, repr=False, compare=False)
    _end: np.ndarray = field(init=False, repr=False, compare=False)
    _end_tangent: np.ndarray = field(init=False, repr=False, compare=False)

    @classmethod
    def build(
        cls, pieces, *, start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), up=(0.0, 0.0, 1.0)
    ) -> PipePath:
        """Return the path of `pieces` from `start` along `direction`, 12 o'clock towards `up`.

        Parameters
        ----------
        pieces : sequence of tuple
            ``("straight", length)`` or ``("bend", bend_radius, angle_deg, roll_deg)``,
            angle in (0, 180].
        start : (3,) array_like of float
        direction : (3,) array_like of float
            The start tangent; normalised.
        up : (3,) array_like of float
            Projected onto the plane normal to `direction` and normalised; must not be
            parallel to it.

        Raises
        ------
        InputError
            If there are no pieces, a piece is malformed or out of range, or `up` is
            parallel to `direction`.

        Examples
        --------
        >>> PipePath.build([("straight", 1.0), ("bend", 0.5, 90.0, 0.0)]).pieces
        (('straight', 1.0), ('bend', 0.5, 90.0, 0.0))
        """
        return cls(tuple(pieces), start, direction, up)

    def __post_init__(self) -> None:
        if not isinstance(self.pieces, tuple | list) or not self.pieces:
            raise InputError(f"a path needs at least one piece; got {self.pieces!r}")
        pieces = tuple(_piece(p) for p in self.pieces)
        point = as_vector3(self.start, "start")
        tangent = as_vector3(self.direction, "direction")
        if not np.linalg.norm(tangent) > 0.0:
            raise InputError(f"direction must not be zero; got {self.direction!r}")
        tangent = _unit(tangent)
        up = as_vector3(self.up, "up")
        up = up - (up @ tangent) * tangent
        if not np.linalg.norm(up) > 1e-9 * np.linalg.norm(as_vector3(self.up, "up")):
            raise InputError(
                f"up must not be parallel to direction; got up={self.up!r}, "
                f"direction={self.direction!r}"
            )
        up = _unit(up)
        object.__setattr__(self, "pieces", pieces)
        object.__setattr__(self, "start", tuple(point.tolist()))
        object.__setattr__(self, "direction", tuple(tangent.tolist()))
        object.__setattr__(self, "up", tuple(up.tolist()))
        names = ("p0", "t0", "u0", "r0", "n0", "b0", "un", "ub", "radius", "size", "angle")
        rows = {name: [] for name in names}
        for piece in pieces:
            rows["p0"].append(point)
            rows["t0"].append(tangent)
            rows["u0"].append(up)
            rows["r0"].append(np.cross(tangent, up))
            if piece[0] == "straight":
                length = piece[1]
                point = point + length * tangent
                for name, value in (("n0", np.zeros(3)), ("b0", np.zeros(3))):
                    rows[name].append(value)
                rows["un"].append(0.0)
                rows["ub"].append(0.0)
                rows["radius"].append(0.0)
                rows["size"].append(length)
                rows["angle"].append(0.0)
                continue
            _, bend_radius, angle, roll = piece
            c, s = _cos_sin(roll)
            towards = c * up + s * np.cross(tangent, up)  # the bend's centre lies this way
            axis = np.cross(tangent, towards)
            c, s = _cos_sin(angle)
            point = point + bend_radius * s * tangent + bend_radius * (1.0 - c) * towards
            # Parallel transport on a circle: up's parts along `towards` and the axis keep
            # their weights while `towards` turns with the tangent.
            rows["un"].append(up @ towards)
            rows["ub"].append(up @ axis)
            up = (up @ towards) * (c * towards - s * tangent) + (up @ axis) * axis
            tangent = c * tangent + s * towards
            up = _unit(up - (up @ tangent) * tangent)
            rows["n0"].append(towards)
            rows["b0"].append(axis)
            rows["radius"].append(bend_radius)
            rows["size"].append(bend_radius * math.radians(angle))
            rows["angle"].append(math.radians(angle))
        rows["end"], rows["end_tangent"] = point, tangent
        for name, value in rows.items():
            array = np.array(value, dtype=np.float64)
            array.flags.writeable = False
            object.__setattr__(self, f"_{name}", array)
        bend = np.array([p[0] == "bend" for p in pieces])
        origin = self._p0 + self._radius[:, None] * self._n0
        basis = np.where(
            bend[:, None, None],
            np.stack([self._t0, self._n0, self._b0], 1),
            np.stack([self._t0, self._u0, self._r0], 1),
        )
        for name, value in (("origin", origin), ("basis", basis)):
            value.flags.writeable = False
            object.__setattr__(self, f"_{name}", value)
        s0 = np.concatenate([[0.0], np.cumsum(self._size)])
        s0.flags.writeable = False
        bend.flags.writeable = False
        object.__setattr__(self, "_s0", s0)
        object.__setattr__(self, "_bend", bend)

    @property
    def length(self) -> float:
        """The centreline's length, in metres."""
        return float(self._s0[-1])

    @property
    def _max_curvature(self) -> float:
        """The largest curvature, 1 / the smallest bend radius (0 without bends), per metre."""
        return max(
            (1.0 / r for r, b in zip(self._radius, self._bend, strict=True) if b), default=0.0
        )

    def _arc(self, s) -> np.ndarray:
        """Validate arc lengths: a (M,) float64 array within [0, length]."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        if s.ndim != 1 or not np.isfinite(s).all():
            raise InputError("s must be a 1-D array of finite arc lengths")
        slack = 1e-12 * max(1.0, self.length)
        if s.size and (s.min() < -slack or s.max() > self.length + slack):
            raise InputError(
                f"s must be arc lengths in [0, {self.length:.6g}] (the path's length); got "
                f"values from {s.min():.6g} to {s.max():.6g}"
            )
        return s

    def _index(self, s: np.ndarray) -> np.ndarray:
        """Return the piece (M,) that holds each arc length (M,); a junction goes to the
        piece it starts."""
        return np.searchsorted(self._s0[1:-1], s, side="right")

    def _evaluate(self, s: np.ndarray, piece: np.ndarray | None = None) -> _Frame:
        """Return the frame at arc lengths `s` (M,) on pieces `piece` (M,) (default: the
        pieces holding them). Arc lengths beyond a piece continue it (a bend's circle, a
        straight's line)."""
        piece = self._index(s) if piece is None else piece
        frame = _Frame(*(np.zeros((s.size, 3)) for _ in _Frame._fields))
        for k in range(self._size.size):
            rows = np.flatnonzero(piece == k) if self._size.size > 1 else slice(None)
            q = s[rows] - self._s0[k]
            p0, t0 = self._p0[k], self._t0[k]
            if not self._bend[k]:
                frame.centre[rows] = p0 + np.multiply.outer(q, t0)
                frame.tangent[rows], frame.up[rows], frame.right[rows] = (
                    t0,
                    self._u0[k],
                    self._r0[k],
                )
                continue
            radius, n0, b0 = self._radius[k], self._n0[k], self._b0[k]
            phi = q / radius
            c, sn = np.cos(phi), np.sin(phi)
            frame.centre[rows] = (
                p0 + np.multiply.outer(radius * sn, t0) + np.multiply.outer(radius * (1.0 - c), n0)
            )
            frame.tangent[rows] = np.multiply.outer(c, t0) + np.multiply.outer(sn, n0)
            towards = np.multiply.outer(c, n0) - np.multiply.outer(sn, t0)
            # up = un towards + ub axis, so right = tangent x up = un axis - ub towards.
            un, ub = self._un[k], self._ub[k]
            frame.up[rows] = un * towards + ub * b0
            frame.right[rows] = un * b0 - ub * towards
            frame.bend[rows] = towards / radius
        return frame

    def frame(self, s):
        """Return the centreline's frame at arc lengths `s`.

        Parameters
        ----------
        s : (M,) array_like of float
            Arc lengths in ``[0, length]``, in metres.

        Returns
        -------
        centre, tangent, up : (M, 3) float64
            Centreline points, unit tangents and unit 12 o'clock directions.
        curvature : (M,) float64
            1 / bend radius on bends, 0 on straights, per metre.

        Raises
        ------
        InputError
            If an arc length is outside ``[0, length]``.

        Examples
        --------
        >>> path = PipePath.build([("bend", 1.0, 90.0, 0.0)])
        >>> centre, tangent, up, curvature = path.frame([0.0, path.length])
        >>> np.round(up, 12).tolist(), curvature.tolist()
        ([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]], [1.0, 1.0])
        """
        f = self._evaluate(self._arc(s))
        return f.centre, f.tangent, f.up, np.linalg.norm(f.bend, axis=1)

    def _closest(self, x: np.ndarray, hint=None, reach=None) -> _Foot:
        """Return where points `x` (M, 3) stand to the centreline.

        Each piece is solved in closed form: the clamped projection on a straight, the
        clamped angle about a bend's centre. With a `hint` (M,), only the pieces within
        `reach` (M,) of arc length of it are tried: exact where the nearest point is that
        close, as it is for a point that moved a distance ``reach / along`` from one whose
        nearest arc length was `hint`, both within a bend radius of the centreline.
        """
        count, pieces = x.shape[0], self._size.size
        foot = _Foot(
            np.zeros(count),
            np.zeros(count, dtype=np.int64),
            np.full(count, np.inf),
            np.zeros(count),
            np.zeros(count),
        )
        if hint is not None and pieces > 1:
            first, last = self._index(hint - reach), self._index(hint + reach)
        for k in range(pieces):
            if hint is None or pieces == 1:
                rows = np.arange(count)
            else:
                rows = np.flatnonzero((first <= k) & (k <= last))
            w = x[rows] - self._origin[k]
            a, b, c = (w @ self._basis[k].T).T
            if self._bend[k]:
                # From the bend's centre, a along t0, b along n0 and c along its axis b0; the
                # arc lies at angles 0 to 2 half from -n0 towards t0: clamp the point's.
                radius, half = self._radius[k], 0.5 * self._angle[k]
                ch, sh = math.cos(half), math.sin(half)
                phi = half + np.clip(np.arctan2(a * ch + b * sh, a * sh - b * ch), -half, half)
                radial = a * np.sin(phi) - b * np.cos(phi)  # along sin(phi) t0 - cos(phi) n0
                d2 = np.einsum("ij,ij->i", w, w) + radius * (radius - 2.0 * radial)
                # up = -un f + ub b0 and right = ub f + un b0, f the radial direction.
                un, ub, across = self._un[k], self._ub[k], radial - radius
                up, right = ub * c - un * across, ub * across + un * c
                along = radius * phi
            else:
                # From the piece's start, a along t0, b along up and c along right.
                along = np.clip(a, 0.0, self._size[k])
                d2 = np.einsum("ij,ij->i", w, w) + along * (along - 2.0 * a)
                up, right = b, c
            better = d2 < foot.distance2[rows]
            chosen = rows[better]
            foot.s[chosen] = self._s0[k] + along[better]
            foot.piece[chosen] = k
            foot.distance2[chosen] = d2[better]
            foot.up[chosen], foot.right[chosen] = up[better], right[better]
        np.maximum(foot.distance2, 0.0, out=foot.distance2)
        return foot

    def _overshoot(self, x: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Return how far points `x` (M, 3) with nearest arc lengths `s` (M,) lie beyond the
        planes of the open ends (0 where the nearest point is not an end)."""
        before = np.maximum((self._p0[0] - x) @ self._t0[0], 0.0)
        after = np.maximum((x - self._end) @ self._end_tangent, 0.0)
        return np.where(s <= 0.0, before, np.where(s >= self.length, after, 0.0))

    def nearest(self, x):
        """Return the arc length of the nearest centreline point and the overshoot.

        Parameters
        ----------
        x : (M, 3) array_like of float

        Returns
        -------
        s : (M,) float64
            Arc length of the centreline point nearest each point, in ``[0, length]``
            (exact: closed form per piece).
        overshoot : (M,) float64
            How far the point lies beyond the plane of an open end, where its nearest
            centreline point is that end; 0 elsewhere.

        Examples
        --------
        >>> path = PipePath.build([("straight", 1.0), ("bend", 1.0, 90.0, 90.0)])
        >>> s, overshoot = path.nearest([[0.5, 0.3, 0.0], [-0.2, 0.0, 0.1]])
        >>> s.tolist(), np.round(overshoot, 12).tolist()
        ([0.5, 0.0], [0.0, 0.2])
        """
        x = query(x)
        s = self._closest(x).s
        return s, self._overshoot(x, s)

    def sample(self, spacing: float) -> tuple[np.ndarray, np.ndarray]:
        """Return arc lengths 0, spacing, 2 spacing, ... and the end (K,), and centres (K, 3).

        Examples
        --------
        >>> s, centres = PipePath.build([("straight", 0.25)]).sample(0.1)
        >>> s.tolist(), centres[-1].tolist()
        ([0.0, 0.1, 0.2, 0.25], [0.25, 0.0, 0.0])
        """
        spacing = positive(spacing, "spacing")
        count = math.floor(self.length / spacing * (1.0 + 1e-12))
        s = spacing * np.arange(count + 1)
        if self.length - s[-1] > 1e-9 * spacing:
            s = np.append(s, self.length)
        s[-1] = min(s[-1], self.length)
        return s, self._evaluate(s).centre


def _tube_sites(path: PipePath, radius: float, n: int, rng: np.random.Generator):
    """Draw `n` sites uniform in area on the tube of `radius` about `path`: arc lengths s
    (n,) and angles phi (n,) about the centreline, phi = clock + 90 degrees (radians).

    Candidates uniform in (s, phi) are kept with probability proportional to the area
    element ``1 - radius k . out``, k the curvature vector and out the radial direction.
    """
    ratio = radius * path._max_curvature
    s, phi = np.zeros(0), np.zeros(0)
    while s.size < n:
        batch = int(1.1 * (1.0 + ratio) * (n - s.size)) + 64
        ss = rng.uniform(0.0, path.length, batch)
        pp = rng.uniform(0.0, 2.0 * np.pi, batch)
        f = path._evaluate(ss)
        clock = pp - 0.5 * np.pi
        out = np.cos(clock)[:, None] * f.up + np.sin(clock)[:, None] * f.right
        weight = (1.0 - radius * np.einsum("ij,ij->i", f.bend, out)) / (1.0 + ratio)
        accept = rng.uniform(0.0, 1.0, batch) < weight
        s, phi = np.concatenate([s, ss[accept]]), np.concatenate([phi, pp[accept]])
    return s[:n], phi[:n]
