"""Synthetic pipe runs: legs, bends, joints and tees with dents and bulges, sampled or scanned."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace

import numpy as np

from .._validate import positive, require_rng
from ..errors import InputError
from ..types import Mesh
from . import _truth
from ._cast import Bore, Branch
from ._damage import _scan_setup, _seed
from ._distance import query
from ._path import PipePath, _tube_sites
from ._pipes import _branch_area
from ._sample import Sample, _count, _fraction, _noise, add_noise, finish
from ._wall import DEFECT_KINDS, Defect, Joint, _clock_vector, _rounded, _settle, _wall

__all__ = [
    "RUN_CLOCK_CONVENTION",
    "RunSpec",
    "Tee",
    "pipe_run",
    "random_pipe_run",
    "scan_pipe_run",
]

#: The clock convention of pipe runs, as written into their truth records.
RUN_CLOCK_CONVENTION = (
    "Clock angles are degrees clockwise looking along the centreline from its start: "
    "12 o'clock (0) is the run's up, carried along the centreline by parallel transport "
    "(it does not twist in bends), and 3 o'clock (90) is t x up, t the centreline's unit "
    "tangent."
)
# The truth record samples the true centreline this often (m).
_CENTRELINE_STEP = 0.01


@dataclass(frozen=True)
class Tee:
    """A branch leaving a straight leg of a pipe run at right angles.

    The branch's axis leaves the run's centreline at arc length `axial` towards the clock
    direction `clock` (see `PipePath`); its bore has radius `radius`, below the run's, and
    its open end lies `length` beyond the run's (undamaged) wall, ``run radius + length``
    from the run's centreline. The run's wall is open where the branch enters it.

    Attributes
    ----------
    axial : float
        Arc length along the run's centreline, in metres, ``>= 0``.
    clock : float
        Direction of the branch, degrees in [0, 360).
    radius : float
        The branch's radius, in metres, ``> 0``.
    length : float
        How far the branch reaches beyond the run's wall, in metres, ``> 0``.

    Raises
    ------
    InputError
        If a field is out of its range.

    Examples
    --------
    >>> Tee(axial=1.5, clock=90.0, radius=0.1, length=0.5).radius
    0.1
    """

    axial: float
    clock: float
    radius: float
    length: float

    def __post_init__(self) -> None:
        _settle(self, "tee", None, ("radius", "length"))


def _towards(path: PipePath, axial: float, clock: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the centreline's point (3,) at arc length `axial` and the unit radial
    direction (3,) at `clock` (degrees) there."""
    f = path._evaluate(np.array([axial]))
    c, n = _clock_vector(clock)
    return f.centre[0], c * f.up[0] + n * f.right[0]


def _run(path, radius, defects, joints, tees, ovality, ovality_clock, span):
    """Validate a run's description (radius already positive); return its `Bore` and its
    tees."""
    if not isinstance(path, PipePath):
        raise TypeError(f"path must be a zeroset.synthetic.PipePath; got {type(path).__name__}")
    wall = _wall(radius, path, defects, ovality, ovality_clock, span, joints)
    tees = tuple(tees)
    branches, zones = [], []
    for tee in tees:
        if not isinstance(tee, Tee):
            raise TypeError(f"tees must be Tee instances; got {type(tee).__name__}")
        if tee.radius >= radius - wall.inward:
            raise InputError(
                f"a tee's radius must be below the run's less the wall's inward change, "
                f"{radius - wall.inward:.6g} m; got {tee.radius!r}"
            )
        k = int(path._index(np.array([tee.axial]))[0])
        lo, hi = path._s0[k], path._s0[k + 1]
        if path._bend[k] or not lo + tee.radius <= tee.axial <= hi - tee.radius:
            raise InputError(
                f"a tee at axial={tee.axial!r} must leave a straight piece with its radius "
                f"{tee.radius!r} to spare on each side"
            )
        foot, axis = _towards(path, tee.axial, tee.clock)
        foot = foot + wall.shift(np.array([tee.axial]))[0]
        branches.append(Branch(foot, axis, tee.radius, radius + tee.length))
        zones.append((tee.axial - tee.radius, tee.axial + tee.radius))
    return Bore(wall, tuple(branches), tuple(zones)), tees


def _distance(bore: Bore):
    """Return ``distance(x)``: the run wall's first-order distance (`_Wall.distance`),
    joined with the branches' walls."""
    wall = bore.wall
    if not bore.branches:
        return wall.distance

    def distance(x) -> np.ndarray:
        x = query(x)
        best = wall.distance(x)
        s, theta = wall.locate(x)[:2]
        on_run = wall.surface(theta, s)[0]
        for branch in bore.branches:
            # Where the run's wall is cut away, its nearest point is the opening's rim.
            cut = np.maximum(-branch.gap(on_run), 0.0)
            best = np.hypot(best, cut)
            along, offset = branch.coordinates(x)
            rho_b = np.linalg.norm(offset, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                on_branch = x + ((branch.radius - rho_b) / rho_b)[:, None] * offset
            # Inside the run, or beyond the open end, the branch's wall is not there.
            hidden = np.maximum(-bore.gap(on_branch)[1].run, along - branch.end)
            best = np.minimum(best, np.hypot(rho_b - branch.radius, np.maximum(hidden, 0.0)))
        return best

    return distance


def _branch_frame(bore: Bore, branch: Branch) -> tuple[np.ndarray, np.ndarray]:
    """Return two unit vectors (3,) across a branch's axis."""
    s = bore.wall.path._closest(branch.foot[None]).s
    first = bore.wall.path._evaluate(s).tangent[0]
    return first, np.cross(branch.axis, first)


def _branch_start(bore: Bore, branch: Branch) -> float:
    """Return where along a branch its wall can first leave the run's (undamaged) bore."""
    return math.sqrt(max(bore.low**2 - branch.radius**2, 0.0))


def _cells(kept: np.ndarray) -> np.ndarray:
    """Return which cells (R - 1, C) of a grid with columns periodic have all four corners
    `kept` (R, C)."""
    rows = kept[:-1] & kept[1:]
    return rows & np.roll(rows, -1, axis=1)


def _mesh(bore: Bore):
    """Return ``build(spacing)``: the run's wall grid moved onto the damaged wall, less its
    cells reaching into a branch, and each branch's tube grid outside the run."""
    wall = bore.wall

    def build(spacing: float | None) -> Mesh:
        h = wall.spacing(spacing)
        _, points, normals = wall.grid(h)
        outside = np.ones(points.shape[:2], dtype=bool)
        for branch in bore.branches:
            outside &= branch.gap(points.reshape(-1, 3)).reshape(outside.shape) >= 0.0
        meshes = [_truth.grid_mesh(points, normals, _cells(outside))]
        for branch in bore.branches:
            first, second = _branch_frame(bore, branch)
            start = max(_branch_start(bore, branch) - 2.0 * h, 0.0)
            along = np.linspace(start, branch.end, max(2, math.ceil((branch.end - start) / h)) + 1)
            count = max(32, math.ceil(2.0 * math.pi * branch.radius / h))
            angle = 2.0 * math.pi * np.arange(count) / count
            radial = np.multiply.outer(np.cos(angle), first) + np.multiply.outer(
                np.sin(angle), second
            )
            grid = branch.foot + np.multiply.outer(along, branch.axis)[:, None]
            grid = grid + branch.radius * radial
            outside = bore.gap(grid.reshape(-1, 3))[1].run.reshape(grid.shape[:2]) >= 0.0
            normals = np.broadcast_to(radial, grid.shape)
            meshes.append(_truth.grid_mesh(grid, normals, _cells(outside)))
        return _truth.join(*meshes)

    return build


def _area(bore: Bore) -> float:
    """Return the undamaged run's wall area (Pappus) plus what its branches add."""
    wall = bore.wall
    area = 2.0 * np.pi * wall.radius * wall.length
    return area + sum(_branch_area(wall.radius, b.radius, b.end) for b in bore.branches)


def _record(kind: str, bore: Bore, tees: tuple[Tee, ...]) -> dict:
    """Return the truth record of a run: path, wall, joints, tees and true centreline."""
    wall, path = bore.wall, bore.wall.path
    s, centres = path.sample(_CENTRELINE_STEP)
    centres = _rounded(centres + wall.shift(s))
    tee_centres = _rounded(np.array([b.foot + wall.radius * b.axis for b in bore.branches]))
    record = {
        "kind": kind,
        "radius": wall.radius,
        "path": {
            "pieces": [list(p) for p in path.pieces],
            "start": list(path.start),
            "direction": list(path.direction),
            "up": list(path.up),
        },
        "length": path.length,
        **wall.record(),
        "clock_convention": RUN_CLOCK_CONVENTION,
    }
    at = np.array([j.axial for j in wall.joints])
    joints = _rounded(path._evaluate(at).centre + wall.shift(at))
    record["joints"] = [j.record(joints[i]) for i, j in enumerate(wall.joints)]
    record["tees"] = [
        {
            "axial": t.axial,
            "clock": t.clock,
            "radius": t.radius,
            "length": t.length,
            "centre": tee_centres[i].tolist(),
        }
        for i, t in enumerate(tees)
    ]
    record["centreline"] = np.column_stack([np.round(s, 12), centres]).tolist()
    return record


def pipe_run(
    path: PipePath,
    n: int,
    *,
    radius: float = 0.2,
    defects=(),
    joints=(),
    tees=(),
    ovality: float = 0.0,
    ovality_clock: float = 0.0,
    ovality_span: tuple[float, float] | None = None,
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample the wall of a pipe run: any centreline, with dents, bulges, joints and tees.

    The run's undamaged wall is the tube of `radius` about the centreline of `path`
    (straight legs and circular bends). Its radius becomes ``r(clock, s) = radius + the
    defects + the joints + (D o / 4) cos(2 (clock - ovality_clock))``, as in
    `damaged_pipe`, with s the arc length along the centreline and clocks those of `path`
    (12 o'clock its up, carried along without twist). Each tee adds a straight branch and
    opens the run's wall where it enters; inside, the air is the union of the bores.
    Points are drawn uniformly in area on the undamaged walls, and on the run moved along
    the radius onto the damaged wall; those falling into another bore are dropped.

    Parameters
    ----------
    path : PipePath
    n : int
        Number of points.
    radius : float
        Radius of the undamaged run, in metres, below every bend's radius less the wall's
        outward change.
    defects : sequence of Defect
        With ``axial`` the arc length along the centreline, at most its length.
    joints : sequence of Joint
        Ring features: gaps, offsets (the run beyond steps sideways) and beads.
    tees : sequence of Tee
        Branches, each leaving a straight piece with its radius to spare on each side.
    ovality, ovality_clock, ovality_span
        As in `damaged_pipe`; the span is in arc length.
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        ``normals`` the walls' outward unit normals; ``distance`` the distance to the
        walls (see Notes); ``area`` that of the undamaged walls, ``2 pi radius length``
        plus what each branch adds (exact, as `sample_tee`'s); ``truth_mesh`` the run's
        tube grid moved onto the damaged wall less its cells reaching into a branch, and
        each branch's tube grid less its cells reaching into the run (every vertex is on
        the true wall, but the seam is left open, a gap about one edge wide: the mesh is
        not watertight there), with rows a quarter of a joint's ramp apart across the
        joints; ``truth_record`` as `scan_pipe_run`'s, with kind "pipe run", ``noise`` and
        ``outliers``.

    Raises
    ------
    InputError
        As `damaged_pipe` does, if a tee does not fit on a straight piece or is as wide
        as the run.
    TypeError
        If `path` is not a `PipePath` or a feature is not a `Defect`, `Joint` or `Tee`.

    See Also
    --------
    scan_pipe_run, random_pipe_run, PipePath, damaged_pipe

    Notes
    -----
    ``distance`` is that of `damaged_pipe` on the run's wall (first order in the wall's
    slope), joined with the exact distance to each branch's wall; where the foot point
    on one wall lies inside the other bore (the opening, the branch inside the run) the
    distance to the rim is taken to first order. It is exact on the walls.

    Examples
    --------
    >>> path = PipePath.build([("straight", 1.0), ("bend", 0.6, 90.0, 90.0), ("straight", 1.0)])
    >>> run = pipe_run(path, 5000, tees=[Tee(0.5, 0.0, 0.1, 0.3)], rng=0)
    >>> run.points.shape, float(run.distance(run.points).max()) < 1e-9
    ((5000, 3), True)
    """
    n, radius = _count(n), positive(radius, "radius")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    bore, tees = _run(path, radius, defects, joints, tees, ovality, ovality_clock, ovality_span)
    record = _record("pipe run", bore, tees)
    record.update(noise=noise, outliers=outliers, **_seed(rng))
    rng = require_rng(rng)
    wall = bore.wall
    areas = [2.0 * np.pi * radius * wall.length] + [
        2.0 * np.pi * b.radius * (b.end - _branch_start(bore, b)) for b in bore.branches
    ]
    points, normals = np.zeros((0, 3)), np.zeros((0, 3))
    while points.shape[0] < n:
        counts = rng.multinomial(
            int(1.1 * (n - points.shape[0])) + 64, np.array(areas) / sum(areas)
        )
        s, phi = _tube_sites(wall.path, radius, int(counts[0]), rng)
        candidates, directions = wall.surface(np.mod(phi - 0.5 * np.pi, 2.0 * np.pi), s)
        keep = np.ones(candidates.shape[0], dtype=bool)
        for branch in bore.branches:
            keep &= branch.gap(candidates) >= 0.0
        parts = [(candidates[keep], directions[keep])]
        for branch, count in zip(bore.branches, counts[1:], strict=True):
            first, second = _branch_frame(bore, branch)
            along = rng.uniform(_branch_start(bore, branch), branch.end, count)
            angle = rng.uniform(0.0, 2.0 * np.pi, count)
            radial = np.multiply.outer(np.cos(angle), first) + np.multiply.outer(
                np.sin(angle), second
            )
            candidates = (
                branch.foot + np.multiply.outer(along, branch.axis) + branch.radius * radial
            )
            outside = bore.gap(candidates)[1].run >= 0.0
            parts.append((candidates[outside], radial[outside]))
        order = rng.permutation(sum(p.shape[0] for p, _ in parts))  # mix the walls
        points = np.concatenate([points, np.concatenate([p for p, _ in parts])[order]])
        normals = np.concatenate([normals, np.concatenate([d for _, d in parts])[order]])
    points = add_noise(points[:n], noise, rng=rng)
    area = _area(bore)
    return finish(
        points,
        normals[:n],
        _distance(bore),
        area,
        _mesh(bore),
        outliers=outliers,
        rng=rng,
        truth_record=record,
    )


def scan_pipe_run(
    path: PipePath,
    *,
    radius: float = 0.2,
    defects=(),
    joints=(),
    tees=(),
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
    """Simulate an in-pipe robot's scans of a pipe run with bends, joints, tees and damage.

    The run is that of `pipe_run`. At each of the `stations` the robot stops and takes
    the scan of `scan_pipe`: a Hokuyo URG-04LX-like scanner `offset` from the
    centreline, its scan plane containing the centreline's tangent, turned through a full
    circle in steps of `rotation_step` degrees, with the same beams, range limits and
    range noise. At arc length s0 the scanner takes `scan_pipe`'s pose with its x, y and
    z axes along ``up x tangent``, up and the tangent at s0, its origin circling the true
    centreline (moved by any offset joints before s0). A beam returns the first point
    where it meets a wall, unless it first leaves through an open end of the run or of a
    branch, or runs past the range limit: a beam in one leg can see the bends and legs
    beyond, and into a branch.

    Parameters
    ----------
    path : PipePath
    radius, defects, joints, tees, ovality, ovality_clock, ovality_span
        As in `pipe_run`.
    stations : sequence of float, optional
        Arc lengths of the scanner along the centreline, each in ``[0, path.length]``;
        default one at the middle.
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
        ordered by scan line then beam angle; ``viewpoints`` (N, 3), each point's scanner
        origin; ``normals`` (N, 3), the walls' outward normals at the true hits;
        ``distance``, ``area`` and ``truth_mesh`` as in `pipe_run`; ``truth_record``
        holds ``kind`` ("pipe run scan"), ``radius``, ``path`` (``pieces``, ``start``,
        ``direction``, ``up``), ``length``, ``clock_convention``, ``ovality``,
        ``defects`` (as `damaged_pipe`'s; ``centre`` on the circle of the pipe's radius
        about the true centreline), ``joints`` (their fields and ``centre``, the true
        centreline's point at the joint), ``tees`` (their fields and ``centre``, where the
        branch's axis meets the run's undamaged wall), ``centreline`` (rows [s, x, y, z]
        every 1 cm and at the end: the true centreline, moved by the offset joints),
        ``noise_scale``, ``stations``, ``offset``, ``rotation_step``, ``outliers`` and,
        for an integer `rng`, ``seed``.

    Raises
    ------
    InputError
        As `pipe_run` and `scan_damaged_pipe` do.
    TypeError
        As `pipe_run` does.

    See Also
    --------
    pipe_run, random_pipe_run, scan_damaged_pipe, scan_pipe, hokuyo_accuracy

    Notes
    -----
    A beam is marched from the scanner through the union of the bores, in steps that
    cannot pass a wall unseen. Where no sharp feature (a defect, the ovality, a joint's
    ring or step, a tee's opening) lies on the stretch of arc length ahead, the wall is the
    tube about the (shifted) centreline, and the step goes to the exact exit from it or
    from the stretch: a quadratic's root on a straight piece, on a bend the first root of
    the torus's quartic, bracketed by the roots of its derivative (a cubic). Elsewhere a
    step is a ball inside the undamaged tube narrowed by the inward changes of the
    features it can reach (the distance to a centreline less a radius is 1-Lipschitz, and
    the union's gap is the least of the tubes'), or, near the wall, the gap over a bound
    on its rate of change along the beam from their slopes. A step heeds only the
    features whose extent its arc length can reach, and is never shorter than the smaller
    of one that could change the gap by 1 mm and one that could move 1/8 of the narrowest
    of them along the wall. The first step that ends outside is refined (Illinois method)
    until the hit is within 1e-12 m of the wall; a beam whose root does not converge
    returns nothing, like a dropout at a sharp edge, and a sliver of wall thinner than a
    step at grazing incidence can be missed. In a run few beams leave through the ends,
    so a station at ``rotation_step=1`` returns about 230,000 points: the 10.4 m run of
    ``random_pipe_run(11, defects=3, joints=(1.0, 3.0), tee=True)`` scanned at 10 stations
    1 m apart (2.33 million points) takes about 14 s on 2 cores (21 s of CPU). An
    ovality over the whole run leaves no round stretch to jump along: with
    ``ovality=0.03`` instead of the tee the same scan takes about 28 s.

    Examples
    --------
    >>> path = PipePath.build([("straight", 1.0), ("bend", 0.6, 90.0, 90.0), ("straight", 1.0)])
    >>> scan = scan_pipe_run(path, stations=[0.5, 1.5], rotation_step=30.0, noise_scale=0.0)
    >>> scan.points.shape[1], float(scan.distance(scan.points).max()) < 1e-9
    (3, True)
    """
    radius = positive(radius, "radius")
    bore, tees = _run(path, radius, defects, joints, tees, ovality, ovality_clock, ovality_span)
    g, noise_scale, outliers, stations = _scan_setup(
        bore.wall, offset, rotation_step, noise_scale, outliers, stations, heights=False
    )
    record = _record("pipe run scan", bore, tees)
    record.update(
        noise_scale=noise_scale,
        stations=stations,
        offset=g.offset,
        rotation_step=g.rotation_step,
        outliers=outliers,
        **_seed(rng),
    )
    rng = require_rng(rng)
    points, normals, viewpoints = bore.scan(g, stations, noise_scale, rng)
    return finish(
        points,
        normals,
        _distance(bore),
        _area(bore),
        _mesh(bore),
        outliers=outliers,
        rng=rng,
        viewpoints=viewpoints,
        truth_record=record,
    )


@dataclass(frozen=True)
class RunSpec:
    """A pipe run drawn by `random_pipe_run`: what `pipe_run` and `scan_pipe_run` take.

    Attributes
    ----------
    path : PipePath
    radius : float
    stations : tuple of float
        Scanner positions, arc lengths along the centreline.
    defects : tuple of Defect
    joints : tuple of Joint
    tees : tuple of Tee
    ovality : float
    seed : int or None
        The integer seed the run was drawn with, if any; `scan` and `sample` draw their
        noise with it unless given another `rng`.

    Examples
    --------
    >>> spec = random_pipe_run(3, defects=2)
    >>> plain = spec.without_damage()
    >>> len(spec.defects), len(plain.defects), plain.path == spec.path
    (2, 0, True)
    """

    path: PipePath
    radius: float
    stations: tuple[float, ...]
    defects: tuple[Defect, ...] = ()
    joints: tuple[Joint, ...] = ()
    tees: tuple[Tee, ...] = ()
    ovality: float = 0.0
    seed: int | None = None

    def without_damage(self) -> RunSpec:
        """Return the same run, tees and stations with no defects, joints or ovality.

        Examples
        --------
        >>> random_pipe_run(3, defects=1, ovality=0.02).without_damage().ovality
        0.0
        """
        return replace(self, defects=(), joints=(), ovality=0.0)

    def _features(self) -> dict:
        """Return the keywords describing the run's wall."""
        return {
            "radius": self.radius,
            "defects": self.defects,
            "joints": self.joints,
            "tees": self.tees,
            "ovality": self.ovality,
        }

    def scan(self, **options) -> Sample:
        """Return `scan_pipe_run` of this run at its stations; `options` are its other
        keywords (``rng`` defaults to `seed`).

        Examples
        --------
        >>> random_pipe_run(3).scan(rotation_step=90.0).truth_record["seed"]
        3
        """
        options.setdefault("rng", self.seed)
        return scan_pipe_run(self.path, stations=self.stations, **self._features(), **options)

    def sample(self, n: int, **options) -> Sample:
        """Return `pipe_run` of this run with `n` points; `options` are its other keywords
        (``rng`` defaults to `seed`).

        Examples
        --------
        >>> random_pipe_run(3).sample(1000).points.shape
        (1000, 3)
        """
        options.setdefault("rng", self.seed)
        return pipe_run(self.path, n, **self._features(), **options)


def _interval(value, name: str, *, integer: bool = False) -> tuple:
    """Validate a (low, high) range with ``low <= high``: integers ``>= 0``, or positive
    numbers."""
    kind = numbers.Integral if integer else numbers.Real
    try:
        low, high = value
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a pair (low, high); got {value!r}") from None
    valid = all(isinstance(v, kind) and not isinstance(v, bool) for v in (low, high))
    valid = valid and math.isfinite(low) and math.isfinite(high) and 0 <= low <= high
    if not valid or (not integer and low <= 0):
        what = "integers >= 0" if integer else "positive numbers"
        raise InputError(f"{name} must be {what} (low, high) with low <= high; got {value!r}")
    return (int(low), int(high)) if integer else (float(low), float(high))


def _draw_path(rng, count, bend_radius, legs, diameter, out_of_plane) -> PipePath:
    """Draw a path: `count` bends of 30-90 degrees between straight legs."""
    bends = int(rng.integers(count[0], count[1] + 1))
    pieces = [("straight", diameter * rng.uniform(*legs))]
    rolls = rng.choice([90.0, 270.0], bends) if not out_of_plane else rng.uniform(0, 360, bends)
    if out_of_plane and bends and np.all(np.abs(np.mod(rolls, 180.0) - 90.0) < 15.0):
        rolls[rng.integers(bends)] = rng.choice([0.0, 180.0])  # one bend leaves the plane
    for roll in rolls:
        angle = rng.uniform(30.0, 90.0)
        pieces.append(("bend", diameter * rng.uniform(*bend_radius), angle, float(roll)))
        pieces.append(("straight", diameter * rng.uniform(*legs)))
    return PipePath.build(pieces)


def _clear(path: PipePath, diameter: float, extra=()) -> bool:
    """Whether the path keeps 1.5 diameters from itself beyond 2 diameters of arc, and
    the `extra` points (K, 3) 1.5 diameters from it (a branch's axis)."""
    s, centres = path.sample(0.25 * diameter)
    gap = np.linalg.norm(centres[:, None] - centres[None], axis=-1)
    far = np.abs(s[:, None] - s[None]) > 2.0 * diameter
    if np.any(gap[far] < 1.5 * diameter):
        return False
    for points in extra:
        gap = np.linalg.norm(points[:, None] - centres[None], axis=-1)
        if np.any(gap < 0.75 * diameter):
            return False
    return True


def _draw_tee(rng, path: PipePath, diameter: float) -> Tee | None:
    """Draw a tee on a straight leg with room for it, clear of the rest of the run."""
    radius = 0.5 * diameter
    for _ in range(20):
        branch = radius * rng.uniform(0.3, 0.7)
        room = branch + 0.5 * diameter
        legs = [
            (lo + room, hi - room)
            for lo, hi, bend in zip(path._s0[:-1], path._s0[1:], path._bend, strict=True)
            if not bend and hi - lo > 2.0 * room
        ]
        legs = [(max(lo, diameter), min(hi, path.length - diameter)) for lo, hi in legs]
        legs = [(lo, hi) for lo, hi in legs if lo < hi]
        if not legs:
            return None
        lo, hi = legs[int(rng.integers(len(legs)))]
        tee = Tee(
            rng.uniform(lo, hi), rng.uniform(0.0, 360.0), branch, diameter * rng.uniform(1.0, 3.0)
        )
        foot, axis = _towards(path, tee.axial, tee.clock)
        along = np.linspace(radius + diameter, radius + tee.length, 16)
        if _clear(path, diameter, [foot + np.multiply.outer(along, axis)]):
            return tee
    return None


def _draw_joints(rng, path: PipePath, diameter: float, spacing, tees) -> tuple[Joint, ...]:
    """Draw joints every `spacing` (m) along the straight legs, 0.5 D from bends, ends and
    tees."""
    margin = 0.5 * diameter
    joints = []
    s = rng.uniform(*spacing)
    while s < path.length:
        k = int(path._index(np.array([s]))[0])
        lo, hi = path._s0[k] + margin, path._s0[k + 1] - margin
        free = all(abs(s - t.axial) >= t.radius + margin for t in tees)
        if not path._bend[k] and lo <= s <= hi and free:
            kind = str(rng.choice(["gap", "offset", "bead"]))
            if kind == "gap":
                joint = Joint("gap", s, rng.uniform(0.005, 0.02), depth=rng.uniform(0.003, 0.01))
            elif kind == "offset":
                joint = Joint("offset", s, rng.uniform(0.002, 0.015), clock=rng.uniform(0, 360))
            else:
                joint = Joint("bead", s, rng.uniform(0.002, 0.005))
            joints.append(joint)
        s += rng.uniform(*spacing)
    return tuple(joints)


def _draw_defects(rng, path, diameter, count, joints, tees) -> tuple[Defect, ...]:
    """Draw `count` dents and bulges, 2 widths from each other, joints and tees and 1 D
    from the ends."""
    radius = 0.5 * diameter
    if count and path.length <= 2.0 * diameter:
        raise InputError(
            f"a {path.length:.3g} m run has no room for defects a diameter from its ends; "
            "allow longer legs or ask for none"
        )
    defects: list[Defect] = []
    for _ in range(1000 * count):
        if len(defects) == count:
            break
        width = rng.uniform(0.04, 0.10)
        kind = str(rng.choice(DEFECT_KINDS))
        axial, clock = rng.uniform(diameter, path.length - diameter), rng.uniform(0.0, 360.0)
        near = any(abs(axial - j.axial) < 2.0 * width for j in joints) or any(
            abs(axial - t.axial) < 2.0 * width + t.radius for t in tees
        )
        for d in defects:
            turn = math.radians((clock - d.clock + 180.0) % 360.0 - 180.0)
            near |= math.hypot(radius * turn, axial - d.axial) < 2.0 * max(width, d.width)
        if not near:
            defects.append(Defect(kind, axial, clock, rng.uniform(0.005, 0.015), width))
    if len(defects) < count:
        raise InputError(
            f"could not place {count} defects 2 widths apart on a {path.length:.3g} m run; "
            "ask for fewer"
        )
    return tuple(defects)


def random_pipe_run(
    rng=None,
    *,
    diameter: float = 0.4,
    bends=(2, 4),
    bend_radius=(1.0, 3.0),
    legs=(1.0, 5.0),
    out_of_plane: bool = False,
    tee: bool = False,
    defects: int = 0,
    joints=None,
    ovality: float = 0.0,
    station_spacing=(0.5, 1.5),
) -> RunSpec:
    """Draw a random pipe run: legs, bends, optionally a tee, joints, dents and bulges.

    The run starts at the origin along +x with up +z. It has a number of bends drawn in
    `bends`, each turning 30-90 degrees on a radius drawn in `bend_radius` diameters,
    between straight legs drawn in `legs` diameters; the bends stay in the horizontal
    plane (roll 90 or 270) unless `out_of_plane`, where each roll is uniform and at least
    one leaves the plane. Paths that come within 1.5 diameters of themselves are drawn
    again. A tee gets a radius of 0.3-0.7 of the run's and reaches 1-3 diameters beyond
    the wall, on a straight leg with half a diameter to spare (and a diameter from the
    ends), clear of the rest of the run. Joints (kinds mixed: gaps 5-20 mm wide and 3-10
    mm deep, offsets 2-15 mm, beads 2-5 mm) come every `joints` metres along the straight
    legs, at least half a diameter from bends, ends and tees. Defects (dents or bulges
    5-15 mm deep, 4-10 cm wide) are placed anywhere on the wall at least 2 widths from
    each other (on the unrolled wall), from joints and tees, and a diameter from the
    ends. Stations are spaced by draws in `station_spacing` metres, the first half a draw
    from the start.

    Each part is drawn from its own generator spawned from `rng` (the path, the tee, the
    stations, the joints, the defects), so switching the damage on or off leaves the
    path, tee and stations as they were. With `tee`, a path on which no tee fits is drawn
    again, so the path can differ from the one drawn without.

    Parameters
    ----------
    rng : numpy.random.Generator or int or None
    diameter : float
        The run's diameter, in metres.
    bends : (int, int)
        Fewest and most bends.
    bend_radius, legs : (float, float)
        Ranges of the bend radius and the leg lengths, in diameters; the bend radius at
        least one diameter.
    out_of_plane : bool
    tee : bool
    defects : int
        Number of defects.
    joints : (float, float), optional
        Range of the spacing between joints, in metres; None for no joints.
    ovality : float in [0, 1)
        Ovality of the whole run (major axis at 12 o'clock).
    station_spacing : (float, float)
        Range of the spacing between stations, in metres.

    Returns
    -------
    RunSpec
        The run: give it to `scan_pipe_run` and `pipe_run` through `RunSpec.scan` and
        `RunSpec.sample`.

    Raises
    ------
    InputError
        If a range is malformed, the bend radius is below one diameter, no clear path
        (with a tee, if asked) is found in 100 draws, or the defects do not fit.

    See Also
    --------
    RunSpec, scan_pipe_run, pipe_run, PipePath

    Examples
    --------
    >>> spec = random_pipe_run(7, defects=2, joints=(1.0, 3.0), tee=True)
    >>> spec == random_pipe_run(7, defects=2, joints=(1.0, 3.0), tee=True)
    True
    >>> spec.path == random_pipe_run(7, tee=True).path, len(spec.tees)
    (True, 1)
    """
    diameter = positive(diameter, "diameter")
    count = _interval(bends, "bends", integer=True)
    bend_radius = _interval(bend_radius, "bend_radius")
    legs = _interval(legs, "legs")
    station_spacing = _interval(station_spacing, "station_spacing")
    joints = None if joints is None else _interval(joints, "joints")
    if bend_radius[0] < 1.0:
        raise InputError(f"bend_radius must be at least 1 diameter; got {bend_radius!r}")
    defects = positive(defects, "defects", integer=True) if defects != 0 else 0
    ovality = 0.0 if ovality == 0 else _fraction(ovality, "ovality")
    seed = _seed(rng).get("seed")
    draw_path, draw_tee, draw_stations, draw_joints, draw_defects = require_rng(rng).spawn(5)
    for _ in range(100):
        path = _draw_path(draw_path, count, bend_radius, legs, diameter, out_of_plane)
        if not _clear(path, diameter):
            continue
        tees = () if not tee else (_draw_tee(draw_tee, path, diameter),)
        if None not in tees:
            break
    else:
        raise InputError(
            "no clear path found in 100 draws; allow shorter legs, fewer bends or no tee"
        )
    stations = [0.5 * draw_stations.uniform(*station_spacing)]
    while stations[-1] + station_spacing[1] <= path.length:
        stations.append(stations[-1] + draw_stations.uniform(*station_spacing))
    joints = () if joints is None else _draw_joints(draw_joints, path, diameter, joints, tees)
    defects = _draw_defects(draw_defects, path, diameter, defects, joints, tees)
    return RunSpec(
        path=path,
        radius=0.5 * diameter,
        stations=tuple(float(s) for s in stations),
        defects=defects,
        joints=joints,
        tees=tees,
        ovality=ovality,
        seed=seed,
    )
