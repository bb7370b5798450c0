"""A pipe's centreline, 12 o'clock frame and nominal radius, fitted to a mesh of its wall.

Every normal of a pipe's wall points at the axis, so the vertices pushed inward along their
normals by the radius gather on the centreline. The radius and the side the normals face
come from the wall's mean curvature; the pushed vertices, ordered along the path of their
spanning tree between its two ends farthest apart, give a first centreline; then the
sections fitted per station move it onto their centres, in rounds until it settles (see
docs/inspection.md).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy import interpolate, sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .._unique import distinct
from .._validate import require_rng
from ..errors import InspectionError
from ..evaluate import sample_surface
from ..neighbours import query_workers
from ..topology import boundary_edges, face_area_vectors, vertex_normals
from ..types import Mesh
from ._frame import UP, clock_angles, transport_frames, unit

__all__ = ["Pipe", "Unreliable", "check_stations", "fit_pipe", "section_fits", "station_fits"]

#: Points sampled on the mesh for its first radius, and the edge of the patches whose
#: curvatures it is the median of, in reaches of the pairs' steps (see `_mean_curvature`).
CURVATURE_SAMPLES = 20_000
PATCH = 4.0
#: Positions used to fit the cross-sections (a seeded subset beyond).
MAX_FIT_VERTICES = 100_000
#: Station length, knot spacing and the centreline's sampling, as shares of the radius.
STATION = 0.1
KNOT = 0.5
SAMPLING = 0.02
#: At most this many rounds of station fits move the centreline onto the sections'
#: centres; they stop once it moves less than `SETTLED` radii.
ROUNDS = 8
SETTLED = 2e-4
#: Residuals beyond this many robust deviations get no weight in a station's fit.
TUKEY = 4.685
#: Sectors of angle around a station, and how many its data must cover to fit a circle;
#: with the radius of the sections around known, `ARC` sectors (90 degrees) place its
#: centre (see `section_fits`).
SECTORS = 16
COVERED = 12
ARC = 4
#: The data's ends are where stretches hold fewer than this share of a typical
#: stretch's points.
THIN = 0.02
#: Fewest points a station needs for its fit.
MIN_STATION_POINTS = 16
#: A stretch is not judged where no section is fitted over more than this many radii
#: running (see `check_stations`).
GUIDED = 2.0
#: Vertices whose curvature is further than this share from the pipe's do not place its
#: first centreline (a branch of another diameter, a flange, the rim), unless fewer than
#: `SMOOTH_ENOUGH` of them are that close (coarse triangles, whose curvature is rough).
BRANCHED = 0.25
SMOOTH_ENOUGH = 0.5


@dataclass(frozen=True)
class Unreliable:
    """A stretch of the centreline, metres from `axial_start` to `axial_end`, whose
    sections the fitted circle or ellipse does not explain to within the noise, and why
    (`reason`, in words). Nothing there is reported as a defect or a branch."""

    axial_start: float
    axial_end: float
    reason: str


@dataclass(frozen=True, eq=False)
class Pipe:
    """A fitted pipe: a centreline sampled densely, its 12 o'clock frame, and its radius.

    Attributes
    ----------
    axial : (M,) float64
        Arc length along the centreline, metres: 0 where the data start, negative over
        the margin of one radius before.
    centres, tangents, ups : (M, 3) float64
        Centreline points, unit tangents, and unit 12 o'clock directions.
    radius : float
        Nominal radius, metres: given, or the median radius of the stations.
    measured_radius : float
        The median radius of the stations, metres.
    length : float
        Length of the centreline with data, metres (``axial[-1]`` less the margin).
    extent : float
        Length of the run the data cover, metres, measured without the fitted
        centreline (along the sensors' path where known, else along the axis points'
        path): `length` should agree with it.
    unreliable : tuple of Unreliable
        Stretches whose sections the fit does not explain.
    """

    axial: np.ndarray
    centres: np.ndarray
    tangents: np.ndarray
    ups: np.ndarray
    radius: float
    measured_radius: float
    length: float
    extent: float = float("nan")
    unreliable: tuple[Unreliable, ...] = ()

    def __post_init__(self) -> None:
        for value in (self.axial, self.centres, self.tangents, self.ups):
            value.flags.writeable = False

    def locate(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Axial position (m), clock angle (degrees) and distance from the centreline (m).

        `x` is (N, 3); each position is projected onto the nearest point of the
        centreline. Positions beyond its ends (the stations with data and a margin of
        one radius) get NaN.
        """
        x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
        _, nearest = cKDTree(self.centres).query(x, workers=query_workers())
        along = self.axial[nearest] + np.einsum(
            "ij,ij->i", x - self.centres[nearest], self.tangents[nearest]
        )
        inside = (along >= self.axial[0]) & (along <= self.axial[-1])
        centre, tangent, up = self._at(along)
        radial = x - centre
        radial -= np.einsum("ij,ij->i", radial, tangent)[:, None] * tangent
        distance = np.linalg.norm(radial, axis=1)
        clock = clock_angles(radial, tangent, up)
        along, clock, distance = (np.where(inside, v, np.nan) for v in (along, clock, distance))
        return along, clock, distance

    def position(self, axial, clock, distance=None) -> np.ndarray:
        """(N, 3) points at `axial` (m) and `clock` (degrees), `distance` (default the
        radius) from the centreline: the inverse of `locate`."""
        axial = np.atleast_1d(np.asarray(axial, dtype=np.float64))
        angle = np.radians(np.broadcast_to(np.asarray(clock, dtype=np.float64), axial.shape))
        distance = self.radius if distance is None else distance
        centre = self._at(axial)[0]
        radial = self.directions(axial, np.degrees(angle))[1]
        return centre + np.asarray(distance, dtype=np.float64).reshape(-1, 1) * radial

    def directions(self, axial, clock) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 3) unit vectors at `axial` (m) and `clock` (degrees): along the centreline,
        away from it, and round it the way the clock runs."""
        axial = np.atleast_1d(np.asarray(axial, dtype=np.float64))
        angle = np.radians(np.broadcast_to(np.asarray(clock, dtype=np.float64), axial.shape))
        _, tangent, up = self._at(axial)
        right = np.cross(tangent, up)
        radial = np.cos(angle)[:, None] * up + np.sin(angle)[:, None] * right
        return tangent, radial, np.cross(tangent, radial)

    def _at(self, along: np.ndarray):
        """Centre, unit tangent and unit up at arc lengths `along`, interpolated linearly."""
        index = np.clip(np.searchsorted(self.axial, along) - 1, 0, self.axial.size - 2)
        w = ((along - self.axial[index]) / (self.axial[index + 1] - self.axial[index]))[:, None]
        centre = (1 - w) * self.centres[index] + w * self.centres[index + 1]
        tangent = unit((1 - w) * self.tangents[index] + w * self.tangents[index + 1])
        up = (1 - w) * self.ups[index] + w * self.ups[index + 1]
        up = unit(up - np.einsum("ij,ij->i", up, tangent)[:, None] * tangent)
        return centre, tangent, up


def beam_steps(pipe: Pipe, samples: np.ndarray, viewpoints, located) -> np.ndarray:
    """(N, 3) components of the unit beam from each sensor in `viewpoints` ((3,) or (N, 3))
    to each of the `samples` (N, 3): along the pipe, round it the way the clock runs and
    away from it, at the samples' `located` axial and clock positions; NaN where the
    sensor or the position is not known."""
    axial, clock, _ = located
    with np.errstate(invalid="ignore", divide="ignore"):
        sensors = np.broadcast_to(np.asarray(viewpoints, dtype=np.float64), samples.shape)
        beams = unit(samples - sensors)
    along, radial, round_ = pipe.directions(np.nan_to_num(axial), np.nan_to_num(clock))
    steps = np.stack([np.einsum("ij,ij->i", beams, e) for e in (along, round_, radial)], 1)
    steps[~(np.isfinite(axial) & np.isfinite(clock))] = np.nan
    return steps


def fit_pipe(
    mesh: Mesh,
    points=None,
    *,
    viewpoints=None,
    nominal_diameter: float | None = None,
    up=UP,
    rng=0,
) -> Pipe:
    """Fit a pipe's centreline, frame and radius to a mesh of its wall.

    Parameters
    ----------
    mesh : Mesh
        The wall of one pipe run: straight, bent, or with branches (the run whose ends lie
        farthest apart is fitted; a branch is what lies far outside it).
    points : (N, 3) array_like, optional
        The scan points: when given, the cross-sections are fitted to them rather than to
        the mesh's vertices (a mesh rounds the seam where a branch joins).
    viewpoints : (N, 3) array_like, optional
        The scanner's position for each of the `points` (NaN rows where not known), in
        the order it scanned them. The robot travels inside the pipe: the run fitted is
        the one through its stations, and it runs the way the robot went.
    nominal_diameter : float, optional
        The pipe's nominal inner diameter in metres; default the measured one.
    up : (3,) array_like
        The world's up: 12 o'clock (see `zeroset.inspect` for the clock convention).
    rng : numpy.random.Generator or int or None
        Chooses the positions fitted when there are more than `MAX_FIT_VERTICES` (as
        evenly over the wall as the data allow, see `_evenly`).

    Returns
    -------
    Pipe
        Its centreline runs the way the robot went when `viewpoints` are given (from the
        station it scanned first); else from the end where the largest component of the
        end-to-end vector is smallest (a pipe along z runs towards +z). Its `extent` is
        the length the data cover along the first centreline, from the axis points alone.

    Raises
    ------
    InspectionError
        If the mesh is not a tube: no consistent curvature, or too short to fit.
    """
    rng = require_rng(rng)
    shift = mesh.vertices.mean(axis=0)  # curvatures far from the origin lose digits
    mesh = mesh.translated(-shift)
    normals = vertex_normals(mesh)
    curvature, defined = _wall_curvature(mesh, normals)
    radius, towards_axis = _radius_and_side(mesh, rng)
    used = np.flatnonzero(defined)
    for _ in range(2):  # the run's own radius, without a branch of another size
        tube = np.flatnonzero(defined & (np.abs(curvature * radius - towards_axis) < BRANCHED))
        if tube.size < SMOOTH_ENOUGH * used.size:
            break  # large triangles: each vertex's curvature is too rough to sort them by
        used, radius = tube, 1.0 / abs(float(np.median(curvature[tube])))
    if used.size > MAX_FIT_VERTICES:
        used = np.sort(rng.choice(used, MAX_FIT_VERTICES, replace=False))
    stations = None
    if viewpoints is not None and points is not None:
        sensors = np.broadcast_to(np.asarray(viewpoints, dtype=np.float64), np.shape(points))
        stations = _stations(sensors - shift, radius)
    axis = mesh.vertices[used] + towards_axis * radius * normals[used]
    path = _straight_run(axis, radius, stations, wall=mesh.vertices)
    run = path[-1] - path[0]
    if stations is None and run[np.argmax(np.abs(run))] < 0:  # the largest component's way
        path = path[::-1]
    pipe = _pipe_along(path, radius, radius, up, margin=radius)
    if points is None:  # the surface, evenly, whatever the size of its triangles
        wall = sample_surface(mesh, MAX_FIT_VERTICES, rng=rng)[0]
    else:
        wall = np.asarray(points, dtype=np.float64) - shift
        if wall.shape[0] > MAX_FIT_VERTICES:
            wall = wall[_evenly(pipe.locate(wall), STATION * radius, rng)]
    first, last = _data_ends(pipe, wall, pipe.locate(wall), STATION * radius)
    extent = last - first
    for _ in range(ROUNDS):
        moved = _refit(pipe, wall, up, path)
        inner = pipe.centres[(pipe.axial > 0) & (pipe.axial < pipe.length)]
        change = max(
            np.nanmax(moved.locate(inner)[2], initial=0.0), abs(moved.length - pipe.length)
        )
        pipe = moved
        if change < SETTLED * pipe.radius:
            break
    radius = pipe.radius if nominal_diameter is None else 0.5 * float(nominal_diameter)
    return replace(pipe, centres=pipe.centres + shift, radius=radius, extent=extent)


def station_fits(
    pipe: Pipe, located, *, step: float | None = None, oval: bool = True, radius=None
) -> dict:
    """Robust circle-plus-ovality fits of points in stations along `pipe`.

    `located` is ``pipe.locate(x)`` of the points x: their axial position, clock angle
    and distance from the centreline.

    Each station of length `step` (default a tenth of the radius) fits the distance from
    the centreline as ``a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t`` of the clock
    angle t, by iteratively reweighted least squares (Tukey's biweight), so dents and
    branches do not pull it; with ``oval=False`` only the circle (the first three terms).
    With `radius`, a function of the axial position (m) giving the radius (m), only the
    centre (``a1``, ``b1``) is fitted, to the distances less that radius, and ``a0`` is
    the radius at the station's centre.
    Returns arrays per station: ``axial`` (K,) centres, ``coef`` (K, 5) or (K, 3),
    ``count`` (K,), ``coverage`` (K,), the sectors its points cover, ``fitted`` (K,) bool,
    ``complete`` (K,) bool and ``spread`` (K,),
    the median over the sectors of angle of the robust spread of the fit's inliers in each
    (a dent in a few sectors leaves it, a section that fits nowhere does not).

    A station is not fitted where its points cover fewer than `COVERED` (with `radius`,
    `ARC`) of `SECTORS` sectors of angle (counting points within a tenth of the median
    distance from the centreline), are fewer than `MIN_STATION_POINTS`, or where the circle's
    centre is more than half the median fitted radius off the centreline or its radius a
    quarter off that median. It is complete when fitted with every sector covered.
    """
    step = STATION * pipe.radius if step is None else step
    along, clock, distance = located
    keep = np.isfinite(along)
    along, angle, distance = along[keep], np.radians(clock[keep]), distance[keep]
    start = pipe.axial[0]
    n_stations = max(1, int(np.ceil((pipe.axial[-1] - start) / step)))
    station = np.minimum(((along - start) / step).astype(np.int64), n_stations - 1)
    terms = [
        np.ones_like(angle),
        np.cos(angle),
        np.sin(angle),
        np.cos(2 * angle),
        np.sin(2 * angle),
    ]
    basis = np.stack(terms if oval else terms[:3], axis=1)
    values = distance
    if radius is not None:
        basis, values = basis[:, 1:3], distance - radius(along)
    sector = np.minimum((angle / (2 * np.pi / SECTORS)).astype(np.int64), SECTORS - 1)
    covered = np.zeros((n_stations, SECTORS), dtype=bool)
    typical = np.median(distance)
    near = np.abs(distance - typical) < 0.1 * typical  # a branch covers nothing
    covered[station[near], sector[near]] = True
    count = np.bincount(station, minlength=n_stations)
    least = COVERED if radius is None else ARC
    fitted = (covered.sum(axis=1) >= least) & (count >= MIN_STATION_POINTS)
    weight = np.where(np.abs(distance - typical) < 0.3 * typical, 1.0, 0.0)
    for _ in range(6):
        coef = _weighted_fits(basis, values, weight, station, n_stations, fitted)
        residual = values - np.einsum("ij,ij->i", basis, coef[station])
        scale = _station_mad(np.abs(residual), station, weight > 0, n_stations)
        u = residual / (TUKEY * np.maximum(scale[station], 1e-9))
        weight = np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)
    by_sector = _station_mad(
        np.abs(residual), station * SECTORS + sector, weight > 0, n_stations * SECTORS
    ).reshape(n_stations, SECTORS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a station without points
        spread = np.nanmedian(np.where(np.isfinite(by_sector), by_sector, np.nan), axis=1)
    centres = start + (np.arange(n_stations) + 0.5) * step
    if radius is not None:
        coef = np.column_stack([radius(centres), coef])
    offset = np.hypot(coef[:, 1], coef[:, 2])
    typical = np.median(coef[fitted, 0]) if fitted.any() else typical
    fitted &= (offset < 0.5 * typical) & (np.abs(coef[:, 0] - typical) < 0.25 * typical)
    return {
        "axial": centres,
        "coef": coef,
        "count": count,
        "coverage": covered.sum(axis=1),
        "fitted": fitted,
        "complete": fitted & covered.all(axis=1),
        "spread": spread,
    }


def section_fits(pipe: Pipe, located, *, step: float | None = None) -> dict:
    """`station_fits` of circle and ovality, with each station's circle: the section's
    where its data go all round; else a circle fitted to the distances less the ovality of
    the complete sections around (`_without_ovality`; beside an opening a second harmonic
    would trade off with the centre) where they cover `COVERED` sectors; else, where they
    cover an arc of `ARC` sectors (the thin tail a scanner sees far ahead, one side of a
    shadow), the centre of a circle with the radius of the sections around, interpolated
    along the pipe. Adds ``circle`` (K, 3), its radius and its centre towards 12 and 3
    o'clock (m), ``centred`` (K,) bool, where it is fitted, and ``arc`` (K,) bool, where
    its radius came from the sections around.

    With the radius known, an arc of half-angle p places the centre along its bisector to
    within the radius' own error times sin(p) / p / (1/2 + sin(2p) / 4p): 1.1 at 90
    degrees, 1.3 at 180; across the bisector, the noise's effect grows as 1 / (1/2 -
    sin(2p) / 4p) ** 0.5, 1.7 times a full circle's at 90 degrees.
    """
    sections = station_fits(pipe, located, step=step)
    flat = _without_ovality(located, sections)
    circles = station_fits(pipe, flat, step=step, oval=False)
    complete = sections["complete"]
    circle = np.where(complete[:, None], sections["coef"][:, :3], circles["coef"])
    centred = complete | circles["fitted"]
    arc = np.zeros_like(centred)
    if centred.any() and not centred.all():
        known = sections["axial"][centred], circle[centred, 0]
        arcs = station_fits(pipe, flat, step=step, radius=lambda x: np.interp(x, *known))
        arc = arcs["fitted"] & ~centred
        circle[arc] = arcs["coef"][arc]
    return {**sections, "circle": circle, "centred": centred | arc, "arc": arc}


def check_stations(pipe: Pipe, located, *, excused=()) -> tuple[Unreliable, ...]:
    """The stretches of `pipe` that the data leave unjudged: `located` is
    ``pipe.locate(x)`` of the points x.

    A stretch is not judged where no section could be fitted to its points for more than
    `GUIDED` radii running because the data do not go round the pipe: they cover fewer
    than `COVERED` of `SECTORS` sectors of angle (a shadow, a water line, the far side of
    a bend), or a station holds fewer than `MIN_STATION_POINTS`. The centreline there is
    placed by arcs of an assumed radius, follows the axis points or runs straight on, and
    no residual there can tell a dent from a section. The reason gives the coverage the
    points show. A station the fitted section does not explain is never excused here: a
    joint, a defect or a deformation explains it (see `inspect_pipe`). Stations within the
    axial stretches `excused` ((start, end) pairs, metres: ring features, whose wall is
    meant to leave the section) are not judged. Consecutive stations with the same reason
    make one stretch.
    """
    circles = station_fits(pipe, located, oval=False)
    sections = station_fits(pipe, located)
    good = circles["fitted"] | sections["complete"]
    axial = circles["axial"]
    step = axial[1] - axial[0] if axial.size > 1 else pipe.length
    inside = (axial > 0.0) & (axial < pipe.length)
    reason = np.full(axial.size, "", dtype=object)
    runs = np.split(np.arange(axial.size), np.flatnonzero(np.diff(good.astype(np.int8))) + 1)
    for run in runs:
        if not good[run[0]] and run.size * step > GUIDED * pipe.radius:
            covered, count = circles["coverage"][run], circles["count"][run]
            few = np.median(count) < MIN_STATION_POINTS
            reason[run] = (
                f"too few points: {int(np.median(count))} a station of {step:.3g} m (median)"
                if few
                else f"the data do not go round the pipe: they cover {int(np.median(covered))} "
                f"of {SECTORS} sectors of {360 / SECTORS:g} degrees (median over the stretch)"
            )
    for start, end in excused:
        reason[(axial > start - step) & (axial < end + step)] = ""
    reason[~inside] = ""
    stretches = []
    for run in np.split(np.arange(axial.size), np.flatnonzero(reason[1:] != reason[:-1]) + 1):
        if reason[run[0]]:
            stretches.append(
                Unreliable(
                    float(max(axial[run[0]] - 0.5 * step, 0.0)),
                    float(min(axial[run[-1]] + 0.5 * step, pipe.length)),
                    str(reason[run[0]]),
                )
            )
    return tuple(stretches)


def _weighted_fits(basis, values, weight, station, n_stations, fitted) -> np.ndarray:
    """(K, P) weighted least-squares coefficients per station (zero where not fitted)."""
    size = basis.shape[1]
    wb = basis * weight[:, None]
    normal = np.zeros((n_stations, size, size))
    for i in range(size):
        for j in range(i, size):
            normal[:, i, j] = normal[:, j, i] = np.bincount(
                station, wb[:, i] * basis[:, j], n_stations
            )
    right = np.stack([np.bincount(station, wb[:, i] * values, n_stations) for i in range(size)], 1)
    coef = np.zeros((n_stations, size))
    solvable = fitted & (np.linalg.cond(normal) < 1e8)
    coef[solvable] = np.linalg.solve(normal[solvable], right[solvable][..., None])[..., 0]
    return coef


def _station_mad(values, station, keep, n_stations) -> np.ndarray:
    """(K,) median of `values` per station over `keep`, times 1.4826 (a robust sigma);
    inf for a station without values."""
    values, station = values[keep], station[keep]
    span = float(values.max() - values.min()) if values.size else 0.0
    order = np.argsort(
        station + 0.5 * (values - values.min()) / (span + 1e-300) if span else station
    )
    count = np.bincount(station, minlength=n_stations)
    start = np.r_[0, np.cumsum(count)[:-1]]
    held = count > 0
    low = order[start[held] + (count[held] - 1) // 2]
    high = order[start[held] + count[held] // 2]
    median = np.full(n_stations, np.inf)
    median[held] = 0.5 * (values[low] + values[high])
    return 1.4826 * median


def _wall_curvature(mesh: Mesh, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(V,) mean curvature normal along the vertex normal (1/m; -1/r on a tube whose
    normals point away from its axis), averaged over two rings; (V,) bool: vertices away
    from the boundary where it is defined."""
    v, f = mesh.vertices, mesh.faces
    laplace = np.zeros_like(v)
    area = np.zeros(v.shape[0])
    double_area = np.linalg.norm(face_area_vectors(v, f), axis=1)
    for corner in range(3):
        i, j, k = f[:, corner], f[:, (corner + 1) % 3], f[:, (corner + 2) % 3]
        cot = np.einsum("ij,ij->i", v[j] - v[i], v[k] - v[i]) / np.maximum(double_area, 1e-300)
        edge = (v[k] - v[j]) * cot[:, None]  # the cotangent at i weighs the opposite edge j-k
        np.add.at(laplace, j, edge)
        np.add.at(laplace, k, -edge)
        area += np.bincount(i, double_area / 6.0, v.shape[0])
    defined = area > 0
    defined[distinct(boundary_edges(f))] = False
    rows, cols = np.repeat(f, 2, axis=1).ravel(), np.roll(f, 1, axis=1).repeat(2, 1).ravel()
    ring = sparse.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(v.shape[0],) * 2).tocsr()
    ring = ring + sparse.identity(v.shape[0], format="csr")
    for _ in range(2):  # a vertex next to the boundary is undefined too
        defined = np.asarray(ring @ ~defined == 0).ravel() & defined
    curvature = np.where(
        defined, np.einsum("ij,ij->i", laplace, normals) / (2.0 * np.maximum(area, 1e-300)), 0.0
    )
    for _ in range(2):
        curvature = (ring @ curvature) / np.maximum(ring @ defined.astype(np.float64), 1.0)
    return curvature, defined


def _radius_and_side(mesh: Mesh, rng: np.random.Generator) -> tuple[float, float]:
    """The wall's radius and the sign of the step along the normals towards the axis (-1
    when they point away from it): a first guess, which the circles fitted per station
    correct.

    Over pairs of points sampled on the surface a few triangles apart, the change of the
    face normal along the step between them, ``sum(dn . dp) / sum(|dp|^2)``, is the mean
    curvature H (on a tube ``+-1 / 2r``); unlike a curvature per vertex it does not depend
    on the triangles being small or even. It takes the pairs' steps to lie evenly in the
    tangent plane, which holds while they are short against the radius: where three
    triangles reach farther than half the radius found (the few long triangles of phase
    2), the reach is cut to that half, judged on a tenth of the samples, until it holds.
    """
    points, normals = sample_surface(mesh, CURVATURE_SAMPLES, rng=rng)
    v, f = mesh.vertices, mesh.faces
    reach = 3.0 * float(np.mean(np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1)))
    few = CURVATURE_SAMPLES // 10  # the samples are random: the first are a random tenth
    while (first := _mean_curvature(points[:few], normals[:few], reach)) is not None:
        if 0.5 / abs(first) >= 2.0 * reach:
            break
        reach = 0.25 / abs(first)
    curvature = _mean_curvature(points, normals, reach)
    if curvature is None:
        raise InspectionError("the mesh is too small to fit a pipe to")
    return 0.5 / abs(curvature), (1.0 if curvature < 0 else -1.0)


def _mean_curvature(points: np.ndarray, normals: np.ndarray, reach: float) -> float | None:
    """The median over patches of the wall (cubes of `PATCH` reaches) of ``sum(dn . dp) /
    sum(|dp|^2)`` over the pairs of `points` (N, 3) with unit `normals` (N, 3) closer than
    `reach` (see `_radius_and_side`): a joint's groove, a ring or a deposit, which bend the
    wall their own way, do not pull it, and a facet's flat middle does not set it. None
    where fewer than 32 pairs are."""
    pairs = cKDTree(points).query_pairs(reach, output_type="ndarray")
    if pairs.shape[0] < 32:
        return None
    step = points[pairs[:, 1]] - points[pairs[:, 0]]
    turn = normals[pairs[:, 1]] - normals[pairs[:, 0]]
    key = np.floor(points[pairs[:, 0]] / (PATCH * reach)).astype(np.int64)
    patch = np.unique(key, axis=0, return_inverse=True)[1].ravel()
    count = np.bincount(patch)
    ratios = np.bincount(patch, np.einsum("ij,ij->i", turn, step)) / np.maximum(
        np.bincount(patch, np.einsum("ij,ij->i", step, step)), 1e-300
    )
    full = count >= 0.25 * np.median(count)  # not the patches a boundary cuts short
    curvature = float(np.median(ratios[full]))
    if not np.isfinite(curvature) or curvature == 0.0:
        raise InspectionError("the mesh is flat: no pipe wall to fit")
    return curvature


def _straight_run(centres: np.ndarray, radius: float, stations=None, wall=None) -> np.ndarray:
    """(K, 3) cell means of `centres` along their spanning tree, between two of its ends.

    With the `wall` (W, 3), the positions the centres were pushed from, a cell whose mean
    lies within 1 - `BRANCHED` radii of it is none of the axis's: a rim's normals curl
    along the pipe and a groove's tilt, and their pushed points land beside the wall.

    Without `stations` the two ends lie farthest apart: a tee's straight run rather than
    a turn into its branch. With the scanner's `stations` (S, 3), in the order the robot
    visited them, the run is the one the robot travelled: from the end beyond its first
    station to the end beyond its last, passing by both.
    """
    cell = 0.5 * radius
    key = np.floor(centres / cell).astype(np.int64)
    _, label = np.unique(key, axis=0, return_inverse=True)
    label = label.ravel()
    count = np.bincount(label)
    means = np.stack([np.bincount(label, centres[:, i]) for i in range(3)], 1) / count[:, None]
    means = means[count >= max(3, 0.05 * np.median(count))]
    if wall is not None and means.shape[0]:  # a few hundred cells: the wall's tree is quick
        clear = cKDTree(wall).query(means, workers=query_workers())[0]
        means = means[clear > (1.0 - BRANCHED) * radius]
    if means.shape[0] < 3:
        raise InspectionError("the mesh does not span a pipe: its normals do not meet on an axis")
    pairs = cKDTree(means).query_pairs(2.0 * cell, output_type="ndarray")
    lengths = np.linalg.norm(means[pairs[:, 0]] - means[pairs[:, 1]], axis=1)
    graph = sparse.coo_matrix(
        (lengths + 1e-12, (pairs[:, 0], pairs[:, 1])), shape=(len(means),) * 2
    )
    tree = csgraph.minimum_spanning_tree(graph)
    _, component = csgraph.connected_components(tree, directed=False)
    degree = np.diff((tree + tree.T).tocsr().indptr)
    main = component == np.argmax(np.bincount(component))
    ends = np.flatnonzero(main & (degree <= 1))
    if stations is not None and len(stations) >= 2:
        near = cKDTree(means[main]).query(np.asarray(stations)[[0, -1]])[1]
        first, last = np.flatnonzero(main)[near]
        start = _beyond(tree, means, ends, first, last, 2.0 * cell)
        node = _beyond(tree, means, ends, last, first, 2.0 * cell)
    else:
        # The two ends farthest apart: the one farthest from the ends' mean, then the one
        # farthest from it (no all-pairs table: a long pipe's tree has many short twigs).
        middle = means[ends].mean(axis=0)
        start = int(ends[np.argmax(np.linalg.norm(means[ends] - middle, axis=1))])
        node = int(ends[np.argmax(np.linalg.norm(means[ends] - means[start], axis=1))])
    _, before = csgraph.dijkstra(tree, directed=False, indices=start, return_predecessors=True)
    path = [node]
    while before[node] >= 0:
        node = int(before[node])
        path.append(node)
    if len(path) < 3:
        raise InspectionError(
            "the mesh is too short along its axis to fit a pipe to: it must be longer than a radius"
        )
    return means[path[::-1]]


def _beyond(tree, means: np.ndarray, ends: np.ndarray, near: int, far: int, reach: float) -> int:
    """The end of `tree` (of the nodes `ends`, at `means` (K, 3)) farthest along it from
    node `far` among those whose path to `far` passes within `reach` of node `near`;
    `near` if none does. The node nearest a station may sit on a twig of the tree, which
    no end's path passes through."""
    length, before = csgraph.dijkstra(tree, directed=False, indices=far, return_predecessors=True)
    best, farthest = int(near), -1.0
    for end in ends:
        node = int(end)
        while node >= 0 and np.linalg.norm(means[node] - means[near]) > reach:
            node = int(before[node])
        if node >= 0 and length[end] > farthest:
            best, farthest = int(end), float(length[end])
    return best


def _stations(viewpoints: np.ndarray, radius: float) -> np.ndarray | None:
    """(S, 3) the scanner's stations in the order the robot visited them (the order their
    first points have in the scan): the means of its positions that lie within a radius
    of each other; None without any known position."""
    known = np.isfinite(viewpoints).all(axis=1)
    if not known.any():
        return None
    unique, first, counts = np.unique(
        viewpoints[known], axis=0, return_index=True, return_counts=True
    )
    pairs = cKDTree(unique).query_pairs(radius, output_type="ndarray")
    graph = sparse.coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(unique),) * 2
    )
    n_groups, group = csgraph.connected_components(graph, directed=False)
    weight = counts.astype(np.float64)
    centres = (
        np.stack([np.bincount(group, weight * unique[:, i], n_groups) for i in range(3)], 1)
        / np.bincount(group, weight, n_groups)[:, None]
    )
    order = np.full(n_groups, np.iinfo(np.int64).max)
    np.minimum.at(order, group, first)
    return centres[np.argsort(order)]


def _pipe_along(path: np.ndarray, radius: float, measured: float, up, margin: float) -> Pipe:
    """A Pipe through the ordered points `path` (K, 3), smoothed by a least-squares cubic
    spline with knots `KNOT` radii apart, sampled every `SAMPLING` radii, extended by
    `margin` at both ends."""
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(_moving_average(path), axis=0), axis=1))]
    keep = np.r_[True, np.diff(chord) > 1e-12]
    path, chord = path[keep], chord[keep]
    spline = _smooth(chord, path, KNOT * radius)
    fine = np.linspace(
        chord[0], chord[-1], max(8, int(np.ceil(chord[-1] / (SAMPLING * radius))) + 1)
    )
    centres = spline(fine)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(centres, axis=0), axis=1))]
    tangents = unit(spline(fine, 1))
    length = float(arc[-1])
    if margin > 0:  # straight on, in the direction of the last radius
        back = np.searchsorted(arc, [radius, length - radius])
        tangents[: back[0]] = unit(centres[back[0]] - centres[0])
        tangents[back[1] :] = unit(centres[-1] - centres[back[1]])
        ahead = np.arange(1, int(np.ceil(margin / (SAMPLING * radius))) + 1) * SAMPLING * radius
        centres = np.concatenate(
            [
                centres[0] - ahead[::-1, None] * tangents[0],
                centres,
                centres[-1] + ahead[:, None] * tangents[-1],
            ]
        )
        tangents = np.concatenate(
            [
                np.repeat(tangents[:1], ahead.size, 0),
                tangents,
                np.repeat(tangents[-1:], ahead.size, 0),
            ]
        )
        arc = np.concatenate([-ahead[::-1], arc, length + ahead])
    return Pipe(arc, centres, tangents, transport_frames(tangents, up), radius, measured, length)


def _moving_average(path: np.ndarray, window: int = 5) -> np.ndarray:
    """(K, 3) `path` averaged twice over `window` consecutive points (ends padded)."""
    if path.shape[0] <= window:
        return path
    kernel = np.ones(window) / window
    for _ in range(2):
        padded = np.pad(path, ((window // 2, window // 2), (0, 0)), mode="edge")
        path = np.stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(3)], 1)
    return path


def _smooth(x: np.ndarray, y: np.ndarray, knot: float):
    """A least-squares cubic spline y(x) (vector valued) with interior knots about `knot`
    apart (fewer when there are not four points a span), at quantiles of `x` so that
    every span holds data."""
    n_spans = max(1, min(int(round((x[-1] - x[0]) / knot)), x.size // 4))
    inner = np.quantile(x, np.linspace(0.0, 1.0, n_spans + 1)[1:-1])
    inner = np.unique(inner[(inner > x[0]) & (inner < x[-1])])
    knots = np.r_[[x[0]] * 4, inner, [x[-1]] * 4]
    return interpolate.make_lsq_spline(x, y, knots, k=3)


def _without_ovality(located, sections: dict):
    """`located` (axial, clock, distance) with each distance less the second harmonic
    (the ovality) of the complete sections among `sections` (`station_fits`),
    interpolated along the pipe: what a circle fits where the data do not go round, and
    the ovality would otherwise pull its centre towards the side seen."""
    complete = sections["complete"]
    if not complete.any():
        return located
    axial, clock, distance = located
    a2, b2 = (np.interp(axial, sections["axial"][complete], sections["coef"][complete, i])
              for i in (3, 4))  # fmt: skip
    twice = np.radians(2.0 * clock)
    return axial, clock, distance - a2 * np.cos(twice) - b2 * np.sin(twice)


def _evenly(located, step: float, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of at most `MAX_FIT_VERTICES` of the positions `located` (axial,
    clock, distance; NaN beyond the centreline), as evenly over the wall as they allow: a
    random choice of at most the same number in every cell of `step` metres by one of
    `SECTORS` sectors of angle, all of them where a cell holds fewer. A scan's thin tail
    far from the scanner, and the side of a bend its scan lines leave sparse, keep every
    point their sections need. Positions beyond the centreline make one more cell."""
    axial, clock, _ = located
    cell = np.floor(axial / step) * SECTORS + np.floor(clock / (360.0 / SECTORS))
    _, label = np.unique(cell, return_inverse=True)  # NaN: one more
    label = label.ravel()
    counts = np.bincount(label)
    low, high = 0, int(counts.max())  # the most per stretch that keeps within the budget
    while low < high:
        middle = (low + high + 1) // 2
        if np.minimum(counts, middle).sum() <= MAX_FIT_VERTICES:
            low = middle
        else:
            high = middle - 1
    order = np.lexsort((rng.random(axial.size), label))
    rank = np.arange(axial.size) - np.r_[0, np.cumsum(counts)[:-1]][label[order]]
    return np.sort(order[rank < low])


def _data_ends(pipe: Pipe, wall: np.ndarray, located, step: float) -> tuple[float, float]:
    """Axial positions (m) where the data start and stop: the ends of the stretches of
    `step` metres holding two points or more of the `wall` (N, 3) near it, and `THIN` of
    a typical stretch's (the range noise scatters a few beyond an open end), joined where
    they lie less than a radius apart, around the middle of the data; thin tails count,
    stray points beyond a gap do not. Points beyond the centreline's ends (NaN in
    `located`) count along the straight lines its ends run on."""
    along, _, distance = located
    beyond = ~np.isfinite(along)
    if beyond.any():
        ends = [(pipe.centres[i], pipe.tangents[i], pipe.axial[i]) for i in (0, -1)]
        past = [a + (wall[beyond] - c) @ t for c, t, a in ends]
        gaps = [np.linalg.norm(wall[beyond] - c, axis=1) for c, _, _ in ends]
        along = along.copy()
        along[beyond] = np.where(gaps[0] < gaps[1], past[0], past[1])
    typical = np.nanmedian(distance)
    on_wall = np.isfinite(along) & ~(np.abs(distance - typical) >= 0.3 * typical)
    bins = np.floor(along[on_wall] / step).astype(np.int64)
    counts = np.bincount(bins - bins.min())
    held = np.flatnonzero(counts >= max(2.0, THIN * np.median(counts[counts > 0]))) + bins.min()
    # the stretch without a gap of a radius that holds the middle of the data
    pieces = np.split(held, np.flatnonzero(np.diff(held) * step > pipe.radius) + 1)
    middle = np.median(bins)
    main = min(pieces, key=lambda p: 0 if p[0] <= middle <= p[-1] else abs(p - middle).min())
    inside = along[on_wall][(bins >= main[0]) & (bins <= main[-1])]
    return float(inside.min()), float(inside.max())


def _refit(pipe: Pipe, wall: np.ndarray, up, guide: np.ndarray) -> Pipe:
    """Move the centreline onto the centres of the sections fitted to `wall` per station
    (`section_fits`).

    Where no station is fitted for two stations' length (data on less than a quarter of
    the circle), the centreline follows the `guide` (K, 3), the axis points it
    started from, rather than running straight on from the last fitted station: after a
    bend, that would leave the pipe.
    """
    located = pipe.locate(wall)
    fits = section_fits(pipe, located)
    good = fits["centred"]
    if np.count_nonzero(good) < 4:
        raise InspectionError(
            "too few cross-sections of the pipe are covered by the mesh to fit it: four "
            "stations or more need data on a quarter of the circle"
        )
    along, coef = fits["axial"][good], fits["circle"][good]
    centre, tangent, up_dir = pipe._at(along)
    right = np.cross(tangent, up_dir)
    moved = centre + coef[:, 1:2] * up_dir + coef[:, 2:3] * right
    guided = pipe.locate(guide)[0]
    step = fits["axial"][1] - fits["axial"][0] if fits["axial"].size > 1 else 0.0
    gap = np.abs(guided[:, None] - along[None, :]).min(axis=1) if along.size else guided
    alone = np.isfinite(guided) & (gap > 2.0 * step)
    if alone.any():
        order = np.argsort(np.r_[along, guided[alone]], kind="stable")
        along = np.r_[along, guided[alone]][order]
        moved = np.concatenate([moved, guide[alone]])[order]
        tangent = np.concatenate([tangent, pipe._at(guided[alone])[1]])[order]
    measured = float(np.median(coef[:, 0]))
    first, last = _data_ends(pipe, wall, located, step)
    head = _end_direction(moved[::-1], along[0] - along[::-1], measured)
    tail = _end_direction(moved, along - along[0], measured)
    moved = np.concatenate(
        [
            moved[:1] + (along[0] - first) * head,
            moved,
            moved[-1:] + (last - along[-1]) * tail,
        ]
    )
    return _pipe_along(moved, measured, measured, up, margin=measured)


def _end_direction(centres: np.ndarray, along: np.ndarray, reach: float) -> np.ndarray:
    """(1, 3) unit direction in which the ordered `centres` (K, 3) at increasing `along`
    (m) leave their last one: the line fitted to those within `reach` metres of it (the
    last two at least), whose noise a single tangent would carry far beyond the data."""
    last = centres[along >= along[-1] - reach]
    if last.shape[0] < 2:
        last = centres[-2:]
    mean = last.mean(axis=0)
    direction = np.linalg.svd(last - mean, full_matrices=False)[2][0]
    if direction @ (last[-1] - last[0]) < 0:
        direction = -direction
    return direction[None, :]
