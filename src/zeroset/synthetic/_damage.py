"""Damaged pipes: dents, bulges and ovality on straight pipes and elbows, sampled or scanned."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .._validate import positive, require_rng
from ..errors import InputError
from ._cast import Bore, refine
from ._path import PipePath, _tube_sites
from ._pipes import _elbow_path
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
from ._wall import CLOCK_CONVENTION, DEFECT_KINDS, Defect, _Wall, _wall

__all__ = ["CLOCK_CONVENTION", "DEFECT_KINDS", "Defect", "damaged_pipe", "scan_damaged_pipe"]

# Scan root finding on the straight pipe: radial steps of the march, the share of the
# narrowest feature an axial step may take, and how many beam samples a batch holds.
_RADIAL_STEP = 1e-3
_AXIAL_SHARE = 1.0 / 8.0
_BATCH = 1 << 20


def _shaped_wall(
    shape, radius, length, bend_radius, leg, defects, ovality, ovality_clock, span
) -> tuple[_Wall, dict]:
    """Validate a straight pipe's or an elbow's size (radius already positive) and build its
    damaged wall; return it and the truth record's size: ``length``, or ``leg`` and
    ``bend_radius``."""
    if shape == "straight":
        length = positive(length, "length")
        path = PipePath.build([("straight", length)], direction=(0, 0, 1), up=(0, 1, 0))
        return _wall(radius, path, defects, ovality, ovality_clock, span), {"length": length}
    if shape != "elbow":
        raise InputError(f"shape must be 'straight' or 'elbow'; got {shape!r}")
    bend_radius, leg = positive(bend_radius, "bend_radius"), positive(leg, "leg")
    if bend_radius <= radius:
        raise InputError(
            f"bend_radius must exceed radius; got bend_radius={bend_radius!r}, radius={radius!r}"
        )
    wall = _wall(radius, _elbow_path(bend_radius, leg), defects, ovality, ovality_clock, span)
    return wall, {"leg": leg, "bend_radius": bend_radius}


def _scan_setup(wall: _Wall, offset, rotation_step, noise_scale, outliers, stations, *, heights):
    """Validate an in-pipe scan of `wall`: the scanner's set-up and its stations (default
    the centreline's middle; `heights` names them so in messages). Return the set-up, the
    noise scale, the outlier share and the stations as floats."""
    radius, length = wall.radius, wall.length
    g = _geometry(
        radius, length, offset, None, rotation_step, HOKUYO_STEP, HOKUYO_FIELD, HOKUYO_RANGE
    )
    if g.offset >= radius - wall.inward:
        raise InputError(
            f"offset must be below radius less the wall's inward change, "
            f"{radius - wall.inward:.6g} m; got {offset!r}"
        )
    if heights:
        what, bound = "heights", f"length={length!r}"
    else:
        what, bound = "arc lengths", f"{length:.6g} (the centreline's length)"
    stations = [0.5 * length] if stations is None else list(np.atleast_1d(stations))
    for z0 in stations:
        if isinstance(z0, bool) or not isinstance(z0, numbers.Real) or not 0 <= z0 <= length:
            raise InputError(f"stations must be {what} in [0, {bound}]; got {z0!r}")
    if not stations:
        raise InputError("stations is empty; give at least one scanner position")
    return (
        g,
        _noise_scale(noise_scale),
        _fraction(outliers, "outliers"),
        [float(z0) for z0 in stations],
    )


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
        s, phi = _tube_sites(wall.path, radius, n, rng)
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
    z. In the elbow a beam's clock and arc length change along it: it is cast as in
    `scan_pipe_run` (an elbow is a pipe run of a leg, a 90 degree bend and a leg), marched
    in steps that cannot pass the wall unseen, with exact exits from the undamaged tube
    where no feature is near. In both the first crossing bracketed is refined (Illinois
    method) until the hit is within 1e-12 m of the wall. Only a sliver of the wall thinner
    than the shortest step along a beam at grazing incidence could be missed. With the
    defaults plus four defects and a partial ovality, 21 stations along a 20 m pipe at
    ``rotation_step=2`` (2.26 million points) take about 4 s. The elbow's cast is
    slower: 8 stations 0.25 m apart at ``rotation_step=1`` (1.49 million points) take
    about 6 s on a clean elbow and 24 s with three defects and a partial ovality.

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
    g, noise_scale, outliers, stations = _scan_setup(
        wall, offset, rotation_step, noise_scale, outliers, stations, heights=shape == "straight"
    )
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
    if shape == "elbow":  # stations are arc lengths
        points, normals, viewpoints = Bore(wall).scan(g, stations, noise_scale, rng)
    else:
        points, normals, viewpoints = [], [], []
        for z0 in stations:
            for psi, beta, theta, t in _station_hits(wall, g, z0):
                measured = _measure(t, noise_scale, rng)
                points.append(_beam_points(psi, beta, measured, g.offset, z0))
                normals.append(wall.surface(theta, z0 + t * np.sin(beta))[1])
                viewpoints.append(_origins(psi, g.offset, z0))
        points, normals = np.concatenate(points), np.concatenate(normals)
        viewpoints = np.concatenate(viewpoints)
    area = 2.0 * np.pi * radius * length
    return finish(
        points,
        normals,
        wall.distance,
        area,
        wall.mesh,
        outliers=outliers,
        rng=rng,
        viewpoints=viewpoints,
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
    found[rows] = refine(gap, rows, lo, hi, gap(lo, rows), gap(hi, rows))
    return found
