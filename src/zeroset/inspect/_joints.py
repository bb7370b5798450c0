"""Joints and other ring features: where the wall changes all round the pipe at once."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, special

from ._bump import FIT_EVALUATIONS, REACH, along_beams, at_most, bump, covariance, range_deviation
from ._centreline import SECTORS, Pipe, station_fits
from ._defects import BRANCH, MAX_BUMP_POINTS, dispersion
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
#: Offsets: the reach each side of a boundary over which the sections' centres are
#: fitted, the gap next to it left out (the sections there, square to a centreline that
#: turns to follow the step, see both sides), and the smallest step reported, as shares
#: of the radius; the fewest stations each side.
OFFSET_REACH = 0.75
OFFSET_GAP = 0.25
MIN_OFFSET = 0.005
OFFSET_STATIONS = 4
#: The step a cubic and a step fitted across a boundary read from a change of curvature
#: there, per unit of that change times the reach squared: derived, the least-squares fit
#: of ``max(x, 0)^2 / 2`` on stations from `OFFSET_GAP` to `OFFSET_REACH` each side.
KINK_STEP = 0.06


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


def find_joints(
    pipe: Pipe, ovality: Ovality, wall: WallMap, located, beams=None, *, smallest: float = 0.0
) -> tuple[Joint, ...]:
    """Find the ring features of a pipe's wall: gaps, beads and offsets, by axial position.

    `located` is ``pipe.locate(x)`` of the scan's points (or samples of the mesh), and
    `wall` their map, which gives their noise about the local wall and where the wall is
    whole: only rings whose map rows, and `BASELINE` radii round them, are defined over
    `ALL_ROUND` of the circle at least and hold no branch are judged.

    **Gaps and beads** change the wall all round at once. The points' residuals from
    their station's section (`Ovality.section_at`) are averaged in rings `RING` radii
    long; a ring whose mean leaves the running median of the rings around it (`BASELINE`
    radii each side) by more than z of its standard errors (the noise there over
    ``sqrt(n)``, z so
    that noise alone makes `FALSE_ALARMS` such rings over the run) starts a feature, and
    the neighbouring rings beyond half of it join it. A feature counts only where the
    residuals leave the wall the same way in at least `ALL_ROUND` of the sectors its
    points cover, which a dent, a deposit or a branch (one side of the pipe) does not.
    Outward it is a gap: a recess, a box in the axial position blurred by the points'
    axial scatter around it (`_gap`), is fitted to the rings' excess for its position,
    width and depth. With the scanner's `beams` (`beam_steps` of the points) the scatter is the
    range noise along the beams' axial component, which smears a narrow gap over
    centimetres; without, the noise is taken as isotropic (as for a defect's depth).
    Inward it is a bead: its size is the largest excess of three rings running; with the
    beams, a raised cosine in the axial position fitted along them (`_bead`). Rings
    within an offset's reach are part of the offset (its step leaves the rings' means as
    it crosses them).

    **Offsets** move the pipe beyond the joint sideways: the centreline steps. At each
    boundary between stations, the centres of the sections (`station_fits`), in the
    world, from `OFFSET_GAP` to `OFFSET_REACH` radii of it are fitted by a cubic in the
    axial position and a step at the boundary; where the step exceeds z of its standard
    error (scaled by the centres' scatter about
    the fit where that exceeds their own errors: the sections of a bend seen obliquely
    from afar), and `MIN_OFFSET` radii, the largest is an offset towards the clock of
    the step, at the axial position where the centres cross half of it, if the outer
    halves of both sides show at least half of it too (`_lasting`). Only stretches that
    bend little are judged: where a bend meets a leg, the curvature changes by about
    twice the centreline's mean curvature over the fit, and the cubic and step read
    `KINK_STEP` times that change times the reach squared as a step; that must stay below
    half the smallest step reported. Offsets in tight bends are not judged; a real pipe
    whose lengths are laid in slight turns is.

    Features that change the wall's radius by less than `smallest` (metres: a bead's
    height, a gap's depth, an offset's step) are not reported: `inspect_pipe` passes the
    smallest defect it reports (`smallest_depth`). The rings' means hold thousands of
    points and tell a fraction of a millimetre from the noise, but not from the
    section's own errors, which are of that size on a scan's far, oblique views.
    """
    axial, clock, distance = located
    keep = np.isfinite(axial)
    axial, clock = axial[keep], clock[keep]
    residual = distance[keep] - ovality.section_at(axial, clock, pipe.radius)
    on_wall = np.abs(residual) < OFF_WALL * pipe.radius
    axial, clock, residual = axial[on_wall], clock[on_wall], residual[on_wall]
    blur = wall.noise_along(axial)  # isotropic noise moves points along the axis as much
    steps = None
    if beams is not None:  # range noise moves them along the beams
        steps = beams[keep][on_wall]
        s_a, _, s_r = steps.T
        known = np.isfinite(s_a)
        blur[known] *= np.abs(s_a[known]) / np.maximum(np.abs(s_r[known]), 0.2)
    # a ring is judged over the sectors its points cover, as `_all_round` judges it: a
    # shadow or a water line takes a few, a branch's opening is no wall
    whole = (np.isfinite(wall.residual).mean(axis=1) >= ALL_ROUND) & (wall.off_wall < BRANCH).all(
        axis=1
    )
    reach = int(np.ceil(BASELINE * pipe.radius / (wall.axial_edges[1] - wall.axial_edges[0])))
    whole = ~ndimage.binary_dilation(~whole, iterations=reach, border_value=1)
    offsets = _offsets(pipe, located, wall.noise_along)
    spans = joint_spans(offsets, pipe, wall.kernel)
    rings = [
        ring
        for ring in _rings(pipe, axial, clock, residual, blur, steps, wall, whole)
        if not any(start <= ring.axial <= end for start, end in spans)
    ]
    found = [j for j in offsets + rings if (j.depth if j.kind == "gap" else j.size) >= smallest]
    return tuple(sorted(found, key=lambda j: j.axial))


def joint_spans(joints, pipe: Pipe, kernel: float) -> list[tuple[float, float]]:
    """Axial stretches (start, end), metres, whose wall the `joints` change: not judged
    for defects. A gap's width, a bead's `BEAD_WIDTH` or an offset's fit (`OFFSET_REACH`
    each side, where the centreline turns to follow its step), and three `kernel`s (the
    map's smoothing, m) each side."""
    spans = []
    for joint in joints:
        if joint.kind == "offset":
            half = OFFSET_REACH * pipe.radius
        elif joint.kind == "gap":
            half = 0.5 * joint.size
        else:
            half = 0.5 * BEAD_WIDTH * pipe.radius
        spans.append((joint.axial - half - 3 * kernel, joint.axial + half + 3 * kernel))
    return spans


def _rings(pipe: Pipe, axial, clock, residual, blur, steps, wall: WallMap, whole):
    """Yield the gaps and beads among the rings of the wall (see `find_joints`): those
    whose map rows are `whole` (A,) bool; `steps` are the points' beams (`beam_steps`),
    or None."""
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
    error = wall.noise_along(start + step * (np.arange(n_rings) + 0.5)) / np.sqrt(
        np.maximum(count, 1)
    )
    error *= dispersion(excess / error)  # ring features are sparse along a run
    z = float(special.ndtri(1.0 - FALSE_ALARMS / (2.0 * n_rings)))
    rows, _ = wall.cells(start + step * (np.arange(n_rings) + 0.5), np.zeros(n_rings))
    strong = (np.abs(np.nan_to_num(excess)) > z * error) & (rows >= 0) & whole[rows]
    sector = np.minimum((clock / (360.0 / SECTORS)).astype(np.int64), SECTORS - 1)
    beads: list[float] = []  # where beads were fitted (a bead's two flanks may each start one)
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
            window = np.abs(np.arange(n_rings) - peak) <= half
            window &= np.isfinite(excess)
            # the points' scatter about the wall around (the noise measured on the gap itself
            # holds the recess the smoothed wall does not follow)
            spread = float(np.median(blur[np.abs(index - peak) <= half]))
            middle = start + step * (np.arange(n_rings)[window] + 0.5)
            gap = _gap(middle, excess[window], error[window], centre, spread, step)
            if steps is not None:  # fitted along the beams: the far edge hides the floor
                near = np.flatnonzero(np.abs(index - peak) <= half)
                values = residual[near] - baseline[index[near]]
                peak_excess = float(excess[peak])  # as wide as the rings' excess' area
                area = float(np.clip(np.nan_to_num(excess[window]), 0.0, None).sum() * step)
                guess = (centre, peak_excess, area / peak_excess) if gap is None else gap
                fitted = _recess(axial[near], values, steps[near], guess, step, pipe)
                gap = gap if fitted is None else fitted
            if gap is not None:
                yield gap
            continue
        three = np.convolve(np.nan_to_num(-excess), np.ones(3) / 3.0, mode="same")
        best = lo + int(np.argmax(three[lo : hi + 1]))
        uncertainty = float(np.sqrt(np.sum(error[max(best - 1, 0) : best + 2] ** 2)) / 3.0)
        if three[best] <= z * uncertainty:
            continue
        near = np.flatnonzero(np.abs(index - peak) <= half)
        bead = Joint("bead", float(centre), float(three[best]), uncertainty)
        if steps is not None:  # fitted along the beams, which an oblique view's noise blurs
            values = residual[near] - baseline[index[near]]
            fitted = _bead(axial[near], values, steps[near], centre, float(three[best]), pipe)
            bead = bead if fitted is None else fitted
        if all(abs(bead.axial - other) > 0.5 * BEAD_WIDTH * pipe.radius for other in beads):
            beads.append(bead.axial)
            yield bead


def _bead(axial, values, steps, centre: float, height: float, pipe: Pipe) -> Joint | None:
    """A bead fitted to the points at `axial` (m) with their residuals `values` (m, less
    the rings' running median) and `steps`, their beams (`beam_steps`): a raised cosine
    in the axial position standing into the bore, ``c - h cos^2(pi (s - a) / w)`` for
    ``|s - a| < w / 2``, whose misfit is taken along each point's beam (as a defect's
    bump, `along_beams`): range noise along an oblique beam smears a bead over
    centimetres and three rings' mean reads it low. `centre` (m) and `height` (m, the
    rings' estimate) start it; None where it does not converge to a bead near there, at
    least a ring wide and no higher than the points on the wall reach (`OFF_WALL`)."""
    known = np.flatnonzero(np.isfinite(steps).all(axis=1))
    known = at_most(known, MAX_BUMP_POINTS)
    a, values, steps = axial[known] - centre, values[known], steps[known].T
    if values.size < 20:
        return None
    b, around = np.zeros_like(a), np.log(1e3)  # all round: no change with the clock

    def ring(q):  # (c, d, a0, log half-width) as a defect's bump, constant round the pipe
        return bump(np.array([q[0], q[1], q[2], 0.0, q[3], around]))

    reach = REACH * range_deviation(values, steps)
    found = optimize.least_squares(
        lambda q: along_beams(ring(q), a, b, values, steps, reach),
        np.array([0.0, -height, 0.0, np.log(0.5 * BEAD_WIDTH * pipe.radius)]),
        loss="soft_l1",
        f_scale=0.5 * reach,
        max_nfev=FIT_EVALUATIONS,
    )
    _, d, shift, half_width = found.x
    resolved = 2.0 * np.exp(half_width) >= RING * pipe.radius  # a spike on no point is none
    on_wall = -OFF_WALL * pipe.radius < d < 0  # standing into the bore, as the points do
    if not (found.success and on_wall and resolved and abs(shift) <= BASELINE * pipe.radius):
        return None
    return Joint("bead", float(centre + shift), float(-d), float(np.sqrt(covariance(found)[1, 1])))


def _gap(axial, excess, error, centre: float, blur: float, step: float) -> Joint | None:
    """A gap fitted to the rings' `excess` (m) at `axial` (m), with standard `error`: a
    recess of depth d and width w centred at a, ``d (Phi((s - a + w/2) / b) - Phi((s - a
    - w/2) / b))``, the box blurred by the axial scatter b of the points (`blur`, from
    the range noise along oblique beams, and the rings' length); None where it does not
    converge to a recess at least a ring (`step`) wide."""
    b = float(np.hypot(blur, step / np.sqrt(12.0)))

    def profile(q):
        a, w, d = q
        return d * (
            special.ndtr((axial - a + 0.5 * w) / b) - special.ndtr((axial - a - 0.5 * w) / b)
        )

    peak = float(excess.max())
    area = float(np.clip(excess, 0.0, None).sum() * step)
    start = np.array([centre, max(area / max(peak, 1e-9), step), peak])
    found = optimize.least_squares(lambda q: (profile(q) - excess) / error, start)
    a, w, d = found.x
    inside = abs(a - centre) < 0.5 * (axial[-1] - axial[0])
    if not (found.success and w >= step and d > 0 and inside):
        return None  # no recess, or one narrower than a ring: not resolved
    spread = np.linalg.pinv(found.jac.T @ found.jac) * max(
        float(found.fun @ found.fun) / max(excess.size - 3, 1), 1.0
    )
    return Joint("gap", float(a), float(w), float(np.sqrt(spread[1, 1])), depth=float(d))


def _recess(axial, values, steps, guess, step: float, pipe: Pipe) -> Joint | None:
    """A gap fitted to the points at `axial` (m) with their residuals `values` (m, less
    the rings' running median) along their beams `steps` (`beam_steps`, as a bead's, see
    `_bead`): a recess ``c + d (Phi((s - a + w/2) / e) - Phi((s - a - w/2) / e))``, its
    edges as sharp as a ring resolves (e, a ring's `step` over sqrt(12)). Seen from
    afar, a recess' far edge hides its floor, and the rings' means read it wide and
    shallow. `guess` is the rings' gap (a Joint) or (centre, depth, width); None where
    it does not converge to a recess near there, a ring wide or more, narrower than the
    points' stretch and no deeper than off-wall points reach (`OFF_WALL`)."""
    known = np.flatnonzero(np.isfinite(steps).all(axis=1))
    known = at_most(known, MAX_BUMP_POINTS)
    a, values, steps = axial[known], values[known], steps[known].T
    if values.size < 20:
        return None
    centre, depth, width = (
        (guess.axial, guess.depth, guess.size) if isinstance(guess, Joint) else guess
    )
    edge = step / np.sqrt(12.0)

    def wall(q):  # (c, d, a, log w), the same all round
        half = 0.5 * np.exp(q[3])
        return lambda s, _: (
            q[0]
            + q[1]
            * (special.ndtr((s - q[2] + half) / edge) - special.ndtr((s - q[2] - half) / edge))
        )

    reach = REACH * range_deviation(values, steps)
    b = np.zeros_like(a)
    found = optimize.least_squares(
        lambda q: along_beams(wall(q), a, b, values, steps, reach),
        np.array([0.0, depth, centre, np.log(max(width, step))]),
        loss="soft_l1",
        f_scale=0.5 * reach,
        max_nfev=FIT_EVALUATIONS,
    )
    _, d, middle, log_width = found.x
    w, span = float(np.exp(log_width)), float(a.max() - a.min())
    inside = abs(middle - centre) <= 0.5 * span and step <= w < span
    if not (found.success and inside and 0 < d < OFF_WALL * pipe.radius):
        return None
    spread = covariance(found)
    return Joint("gap", float(middle), w, float(w * np.sqrt(spread[3, 3])), depth=float(d))


def _all_round(sector: np.ndarray, excess: np.ndarray) -> bool:
    """Whether the points' `excess` (positive the feature's way) is positive on average in
    at least `ALL_ROUND` of the `SECTORS` their `sector` numbers cover."""
    count = np.bincount(sector, minlength=SECTORS)
    mean = np.bincount(sector, excess, SECTORS) / np.maximum(count, 1)
    covered = count > 0
    return bool(covered.any() and np.mean(mean[covered] > 0) >= ALL_ROUND)


def _offsets(pipe: Pipe, located, noise) -> list[Joint]:
    """The offsets among the station boundaries of the pipe (see `find_joints`); `noise`
    gives the points' noise (m) at axial positions (m)."""
    fits = station_fits(pipe, located, oval=False)
    good = fits["fitted"] & (fits["axial"] > 0.0) & (fits["axial"] < pipe.length)
    along = fits["axial"][good]
    if along.size < 8:
        return []
    centre, tangent, up = pipe._at(along)
    right = np.cross(tangent, up)
    coef = fits["coef"][good]
    centres = centre + coef[:, 1:2] * up + coef[:, 2:3] * right
    sigma = noise(along) * np.sqrt(2.0 / np.maximum(fits["count"][good], 1))  # a centre's
    reach = OFFSET_REACH * pipe.radius
    bounds = 0.5 * (along[:-1] + along[1:])
    jumps, errors = np.zeros((bounds.size, 3)), np.full(bounds.size, np.inf)
    models = [None] * bounds.size
    # where a bend meets a leg, the curvature changes by about twice the mean over the
    # fit, and a cubic and a step across it read a step of about 0.06 times that change
    # times reach^2 (`KINK_STEP`): judge only where that stays below half the smallest
    # step reported
    turn = _mean_curvature(pipe, bounds, reach)
    for k, at in enumerate(bounds):
        gap = np.abs(along - at)
        near = (gap <= reach) & (gap >= OFFSET_GAP * pipe.radius)
        if KINK_STEP * 2.0 * turn[k] * reach**2 > 0.5 * MIN_OFFSET * pipe.radius:
            continue
        before, after = np.count_nonzero(near & (along < at)), np.count_nonzero(near & (along > at))
        if min(before, after) < OFFSET_STATIONS:
            continue
        x = (along[near] - at) / reach
        basis = np.stack([np.ones_like(x), x, x * x, x**3, (x > 0).astype(np.float64)], 1)
        weight = 1.0 / sigma[near] ** 2
        inverse = np.linalg.pinv(basis.T @ (basis * weight[:, None]))
        q = inverse @ (basis * weight[:, None]).T @ centres[near]
        # the centres' scatter about the fit, where it exceeds their errors, is error too
        misfit = np.sum(weight[:, None] * (centres[near] - basis @ q) ** 2)
        scatter = misfit / (3 * (x.size - basis.shape[1]))
        jumps[k] = q[-1] - (q[-1] @ tangent[k]) * tangent[k]
        errors[k] = np.sqrt(inverse[-1, -1] * max(scatter, 1.0))
        models[k] = q
    judged = np.isfinite(errors)
    if not judged.any():
        return []
    scores = np.linalg.norm(jumps, axis=1) / errors
    # a step's size over its error is Rayleigh under noise alone: its median is 1.18
    scale = max(float(np.median(scores[judged])) / np.sqrt(2.0 * np.log(2.0)), 1.0)
    scores, errors = scores / scale, errors * scale
    z = float(special.ndtri(1.0 - FALSE_ALARMS / (2.0 * bounds.size)))
    strong = (scores > z) & (np.linalg.norm(jumps, axis=1) > MIN_OFFSET * pipe.radius)
    found = []
    while strong.any():
        k = int(np.argmax(np.where(strong, scores, -np.inf)))
        strong &= np.abs(bounds - bounds[k]) > reach
        if not _lasting(along, centres, sigma, bounds[k], reach, jumps[k]):
            continue
        size = float(np.linalg.norm(jumps[k]))
        direction = jumps[k] / size
        clock = float(clock_angles(direction[None], tangent[k][None], up[k][None])[0])
        at = _halfway(along, centres, bounds[k], reach, models[k], direction)
        found.append(Joint("offset", at, size, float(errors[k]), clock=clock))
    return found


def _lasting(along, centres, sigma, at: float, reach: float, jump) -> bool:
    """Whether the step `jump` (3,) at `at` (m) is there in the outer halves of both sides
    too, a line each side and a step (at least half of it, the same way): an offset
    moves the pipe for good, a dent's flank in one window only pulls a few centres."""
    gap = np.abs(along - at)
    outer = (gap >= 0.5 * (reach + OFFSET_GAP * reach / OFFSET_REACH)) & (gap <= reach)
    if min(np.count_nonzero(outer & (along < at)), np.count_nonzero(outer & (along > at))) < 2:
        return False
    x = (along[outer] - at) / reach
    basis = np.stack([np.ones_like(x), x, (x > 0).astype(np.float64)], 1)
    weight = 1.0 / sigma[outer] ** 2
    q = np.linalg.pinv(basis.T @ (basis * weight[:, None])) @ (basis * weight[:, None]).T
    step = (q @ centres[outer])[-1]
    return bool(step @ jump >= 0.5 * (jump @ jump))


def _mean_curvature(pipe: Pipe, at: np.ndarray, reach: float) -> np.ndarray:
    """(K,) the centreline's mean curvature (1/m) over `reach` metres each side of the
    axial positions `at` (K,): the angle between its tangents there over the length. A
    step's S-turn, and the noise of the fit, cancel out in it; a bend does not."""
    before, after = pipe._at(at - reach)[1], pipe._at(at + reach)[1]
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", before, after), -1.0, 1.0))
    return angle / (2.0 * reach)


def _halfway(along, centres, at: float, reach: float, q, direction) -> float:
    """Where, within `reach` of the boundary `at` (m), the section `centres` (K, 3) at
    `along` (K,) cross half of the step of the fitted model `q` (cubic, then step) along
    its `direction`: the joint's position, though the stations astride it see both sides."""
    near = np.abs(along - at) <= reach
    x = (along[near] - at) / reach
    cubic = np.stack([np.ones_like(x), x, x * x, x**3], 1) @ q[:4]
    share = (centres[near] - cubic) @ direction / (q[-1] @ direction)
    crossing = np.flatnonzero((share[:-1] < 0.5) & (share[1:] >= 0.5))
    if crossing.size == 0:
        return float(at)
    i = crossing[np.argmin(np.abs(along[near][crossing] - at))]
    t = (0.5 - share[i]) / (share[i + 1] - share[i])
    return float(along[near][i] + t * (along[near][i + 1] - along[near][i]))


def _running_median(values: np.ndarray, half: int) -> np.ndarray:
    """(K,) median of the finite `values` over the `half` neighbours each side."""
    padded = np.pad(values, half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(windows, axis=1)
