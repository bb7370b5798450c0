"""A pipe inspected while it is reconstructed: windows of finished blocks, stitched along the
robot's path.

`zeroset.live.LiveReconstruction` hands each finished block (its final mesh, its points and
their sensors) to a `LiveInspection`, and tells it how far along the path every block is
finished (the *front*). Each time the front has moved ``step`` past what was reported, the
blocks from `MARGIN` radii before the report's end to the front are inspected as one pipe
(`inspect_pipe`), and what lies between the report's end and `TAIL` radii short of the
front is reported: its stations, defects, joints, branches and unreliable stretches. The
window's points and faces are cut square at the front (each by the path position of its
nearest path point): blocks are boxes, and a window of whole blocks ends raggedly and
obliquely across a bend, where the centreline and the wall map see a wall that is not
there. The window's own ends are ends of the data to the inspection (a one-sided
smoothing kernel, the centreline's end), so each is reported by the window where it lies
inside. A defect is the first window's whose report its region reaches (its deepest point
before the report's end, its extent past the report's start), unless its region overlaps
one already reported: a region at a junction is seen by both windows, on axial scales that
differ by the junction's error, and is reported once.

Axial positions run along the whole run: the first window's are the run's (0 where the data
start, as in `inspect_pipe`); each later window's are shifted so that its report begins where
the last one ended. 12 o'clock is carried from one window to the next: a window's ``up`` is
the last window's 12 o'clock at its start. Stations lie on each window's own grid: a
window's first station is the first at least half a station past the last one reported, so
two stations at a junction lie half to one and a half stations apart. The nominal diameter
and the threshold are held: given, or the first window's, as the reconstruction holds its
parameters; what each later window would have chosen is kept, and `LiveInspection.drift`
says where it differs.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .. import io
from .._validate import as_points
from ..errors import InputError, SurfaceWarning
from ..live import PARAMETER_DRIFT
from ..neighbours import query_workers
from ..repair import keep_faces
from ..tile_output import weld_coincident
from ..types import Mesh
from ._centreline import STATION, Unreliable
from ._defects import Branch, Defect, smallest_depth
from ._files import (
    DEFECT_COLUMNS,
    JOINT_COLUMNS,
    OVALITY_COLUMNS,
    branch_table,
    defect_table,
    joint_table,
    ovality_table,
    station_summary,
    write_csv,
)
from ._frame import UP
from ._inspection import inspect_pipe
from ._joints import Joint
from ._measure import Ovality

__all__ = ["LIVE_FILES", "STEP", "LiveInspection", "Stretch"]

#: Radii the finished front must move past the last report before the next window: each
#: window inspects ``MARGIN + STEP + TAIL`` radii to report `STEP`, 1.6 times the run's length
#: over the run.
STEP = 10.0
#: Radii before a report's start that its window inspects again: two diameters, past the
#: end effects of the data's ends (the centreline's margin of one radius and its knots of
#: half a radius, the defects' two kernels of 0.04 radii, the thin stretch where the data
#: start).
MARGIN = 4.0
#: Radii short of the front that a window leaves to the next one: the front is an end of
#: the data to it.
TAIL = 2.0
#: Steps the finished front may run ahead of the reports before a window is inspected
#: past the scan's budget (`LiveInspection.behind`): the blocks held stay a window's.
BEHIND = 2.0
#: Radii between the samples of the sensors' path that `LiveInspection.position` finds the
#: nearest of (a k-d tree) before it projects onto that sample's segment: a point's
#: position is off by at most about this where its nearest path point lies on another
#: segment than its nearest sample's (round a corner of the path).
SAMPLE = 0.05
#: The files `LiveInspection.write` writes, rewritten as each window is reported.
LIVE_FILES = ("live-inspection.json", "live-defects.csv", "live-joints.csv", "live-ovality.csv")


@dataclass(frozen=True, eq=False)
class Stretch:
    """What one window reported: the stretch from `axial_start` to `axial_end` of the run
    (metres along the centreline), with its findings in the run's axial positions.

    Attributes
    ----------
    axial_start, axial_end : float
        The stretch reported, metres.
    ovality : Ovality
        Its stations.
    defects : tuple of Defect
        By axial position.
    joints : tuple of Joint
    branches : tuple of Branch
    unreliable : tuple of Unreliable
        Its unreliable stretches, cut to it; a window not inspected is one, with the reason.
    measured_diameter : float
        The window's median station diameter, metres (NaN where not inspected).
    would_threshold : float
        The threshold the window would have chosen from its own noise, metres.
    seconds : float
        The window's inspection time.
    """

    axial_start: float
    axial_end: float
    ovality: Ovality
    defects: tuple[Defect, ...]
    joints: tuple[Joint, ...]
    branches: tuple[Branch, ...]
    unreliable: tuple[Unreliable, ...]
    measured_diameter: float
    would_threshold: float
    seconds: float


class LiveInspection:
    """A pipe's inspection grown as its blocks finish (module docstring).

    Parameters
    ----------
    nominal_diameter : float, optional
        Metres; default the first window's measured diameter, held.
    threshold : float, optional
        Smallest depth reported as a defect, metres; default the first window's, held.
    up : (3,) array_like
        The world's up, which sets 12 o'clock at the run's start (see `zeroset.inspect`).
    step : float, optional
        Metres the finished front moves between windows; default `STEP` radii (the radius
        guessed from the first scan's nearest ranges until the first window measures it).
    folder : str or os.PathLike, optional
        Rewrite `LIVE_FILES` there, atomically, as each window is reported.
    rng : int
        Seed of each window's `inspect_pipe`.
    """

    def __init__(
        self,
        *,
        nominal_diameter: float | None = None,
        threshold: float | None = None,
        up=UP,
        step: float | None = None,
        folder=None,
        rng: int = 0,
    ) -> None:
        for name, value in (("nominal_diameter", nominal_diameter), ("threshold", threshold),
                            ("step", step)):  # fmt: skip
            if value is not None and not 0.0 < value < math.inf:
                raise InputError(f"{name} must be a positive length; got {value!r}")
        self.nominal_diameter = nominal_diameter
        self.threshold = threshold
        self.step = step
        self.folder = None if folder is None else Path(folder)
        self.rng = rng
        self.stretches: list[Stretch] = []
        self._up = as_points(np.reshape(up, (1, 3)), "up")[0]
        self._nodes: list = []  # the sensor path, input coordinates
        self._samples = None  # (node count, spacing, tree, segment of each sample): `_sampled`
        self._radius: float | None = None  # guessed, then the held nominal radius
        self._blocks: dict = {}  # block -> (path position, mesh, points, viewpoints)
        self._done = -math.inf  # path position the reports reach
        self._failed = -math.inf  # the front at which the first window last fitted no pipe
        self._axial_done = 0.0  # ... and its axial position along the run
        if self.folder is not None:
            self.folder.mkdir(parents=True, exist_ok=True)

    # --------------------------------------------------------------- fed by the reconstruction

    def scan(self, sensor, ranges: np.ndarray) -> None:
        """Take a scan's sensor position (3,) and its points' ranges (N,): the path, and the
        radius guessed from the first scan (its nearest 5 % of ranges)."""
        self._nodes.append(np.asarray(sensor, dtype=np.float64))
        if self._radius is None and ranges.size:
            self._radius = float(np.percentile(ranges, 5.0))

    def block(self, index, mesh: Mesh | None, points: np.ndarray, viewpoints: np.ndarray,
              centre: np.ndarray, size: float) -> None:  # fmt: skip
        """Take a finished block: its final mesh (None where it has none), its points (N, 3)
        and their sensors (N, 3), and its centre (3,), all input coordinates, and its edge's
        length: it spans the path from half its diagonal before its centre's position to
        half after."""
        position = float(self.position(centre[None])[0])
        half = 0.5 * np.sqrt(3.0) * size
        self._blocks[tuple(index)] = (position - half, position + half, mesh, points, viewpoints)

    @property
    def path(self) -> np.ndarray:
        """(S, 3) the sensor's positions, scan by scan, input coordinates."""
        return np.asarray(self._nodes, dtype=np.float64).reshape(-1, 3)

    def position(self, x: np.ndarray) -> np.ndarray:
        """(M,) path position (metres along the sensors' path) of the nearest path point to
        each of `x` (M, 3): the nearest of the path's samples every `SAMPLE` radii, then the
        nearest point of that sample's segment."""
        nodes = self.path
        if nodes.shape[0] < 2:
            return np.zeros(x.shape[0])
        tree, segment = self._sampled(nodes)
        a, b = nodes[:-1], nodes[1:]
        length = np.linalg.norm(b - a, axis=1)
        arc = np.r_[0.0, np.cumsum(length)]
        j = segment[tree.query(x, workers=query_workers())[1]]
        t = np.einsum("mk,mk->m", x - a[j], b[j] - a[j]) / np.maximum(length[j] ** 2, 1e-300)
        return arc[j] + np.clip(t, 0.0, 1.0) * length[j]

    def advance(self, front: float, deadline: float = math.inf) -> list[Stretch]:
        """Inspect the windows the finished `front` (path position; ``inf`` once every block
        is finished) allows, until `deadline` (`time.perf_counter`) has passed after one;
        the stretches reported."""
        reported = []
        while self._blocks:
            final = math.isinf(front)
            if not final and self._ahead(front) < 1.0:
                break  # the front has not moved a step past the last report or failure
            stretch = self._window(front)
            if stretch is None:
                break
            reported.append(stretch)
            if final or time.perf_counter() > deadline:
                break
        if reported and self.folder is not None:
            self.write(self.folder)
        return reported

    def behind(self, front: float) -> bool:
        """Whether the finished `front` has run `BEHIND` steps or more past the reports."""
        return self._ahead(front) >= BEHIND

    # ------------------------------------------------------------------------ the results

    @property
    def inspected_to(self) -> float:
        """Axial position (m) up to which the run is reported."""
        return self._axial_done

    def ovality(self) -> Ovality:
        """Every station reported so far, by axial position."""
        parts = [s.ovality for s in self.stretches]
        if not parts:
            return _no_stations()
        return Ovality(*(np.concatenate([getattr(p, n) for p in parts]) for n in _OVALITY))

    def defects(self) -> tuple[Defect, ...]:
        """Every defect reported so far, by axial position."""
        return tuple(d for s in self.stretches for d in s.defects)

    def joints(self) -> tuple[Joint, ...]:
        """Every joint reported so far, by axial position."""
        return tuple(j for s in self.stretches for j in s.joints)

    def unreliable(self) -> tuple[Unreliable, ...]:
        """Every unreliable stretch reported so far (those not inspected too)."""
        return tuple(u for s in self.stretches for u in s.unreliable)

    def drift(self) -> list[str]:
        """Where later windows would have chosen another diameter or threshold than the
        held ones (by more than `zeroset.live.PARAMETER_DRIFT`, as the reconstruction's
        parameters), in words; empty where none would."""
        lines = []
        for s in self.stretches[1:]:
            held_d, held_t = self.nominal_diameter, self.threshold
            drift = PARAMETER_DRIFT
            if math.isfinite(s.measured_diameter) and abs(s.measured_diameter / held_d - 1) > drift:
                lines.append(
                    f"{s.axial_start:.2f}-{s.axial_end:.2f} m measured a diameter of "
                    f"{1e3 * s.measured_diameter:.1f} mm; held {1e3 * held_d:.1f} mm"
                )
            if math.isfinite(s.would_threshold) and abs(s.would_threshold / held_t - 1) > drift:
                lines.append(
                    f"{s.axial_start:.2f}-{s.axial_end:.2f} m would have judged defects from "
                    f"{1e3 * s.would_threshold:.2f} mm; held {1e3 * held_t:.2f} mm"
                )
        return lines

    def summary(self) -> dict:
        """The inspection so far, ready for JSON: the held ``nominal_diameter`` and
        ``threshold`` (metres), ``inspected_to`` (m), ``stations`` (`station_summary`),
        one dict per stretch (its ends, measured diameter, would-be threshold and
        seconds), ``defects`` (`defect_table`, numbered by axial position), ``joints``,
        ``branches``, ``unreliable`` and ``drift`` (`drift`)."""
        return {
            "nominal_diameter": self.nominal_diameter,
            "threshold": self.threshold,
            "inspected_to": self._axial_done,
            "stations": station_summary(self.ovality()),
            "stretches": [
                {
                    "axial_start": s.axial_start,
                    "axial_end": s.axial_end,
                    "measured_diameter": _finite(s.measured_diameter),
                    "would_threshold": _finite(s.would_threshold),
                    "seconds": s.seconds,
                }
                for s in self.stretches
            ],
            "defects": defect_table(self.defects()),
            "joints": joint_table(self.joints()),
            "branches": branch_table(b for s in self.stretches for b in s.branches),
            "unreliable": [asdict(u) for u in self.unreliable()],
            "drift": self.drift(),
        }

    def write(self, folder) -> None:
        """Write `LIVE_FILES` to `folder`, each atomically: the summary and the tables of
        defects, joints and stations so far."""
        folder = Path(folder)
        json_name, defects_name, joints_name, ovality_name = LIVE_FILES
        write_csv(folder / defects_name, DEFECT_COLUMNS, defect_table(self.defects()))
        write_csv(folder / joints_name, JOINT_COLUMNS, joint_table(self.joints()))
        write_csv(
            folder / ovality_name, OVALITY_COLUMNS, ovality_table(self.ovality(), self.unreliable())
        )
        io.write_json(folder / json_name, self.summary())

    def close(self) -> None:
        """Warn where later windows would have chosen otherwise (`drift`)."""
        lines = self.drift()
        if lines:
            warnings.warn(
                "the live inspection held its first window's diameter and threshold, which "
                "later stretches would have chosen otherwise: " + "; ".join(lines)
                + "; give --nominal-diameter and --threshold-mm",
                SurfaceWarning,
                stacklevel=3,
            )

    # ---------------------------------------------------------------------- the machinery

    def _unit(self) -> float:
        """The radius windows are measured in, metres."""
        if self.nominal_diameter is not None:
            return 0.5 * self.nominal_diameter
        return self._radius if self._radius else 1.0

    def _step(self) -> float:
        return self.step if self.step is not None else STEP * self._unit()

    def _ahead(self, front: float) -> float:
        """Steps the `front` (less the tail) lies past the last report, or past the front
        at which the first window last fitted no pipe."""
        since = max(self._done, self._failed - TAIL * self._unit(), 0.0)
        return (front - TAIL * self._unit() - since) / self._step()

    def _window(self, front: float) -> Stretch | None:
        """Inspect the blocks from `MARGIN` radii before the reports' end up to `front`,
        report the stretch up to `TAIL` radii short of it (all, at the end); None where the
        first window fits no pipe yet."""
        start = time.perf_counter()
        final = math.isinf(front)
        unit = self._unit()
        low = self._done - MARGIN * unit
        end = math.inf if final else front - TAIL * unit
        chosen = sorted(k for k, b in self._blocks.items() if b[1] >= low and b[0] <= front)
        meshes = [self._blocks[k][2] for k in chosen if self._blocks[k][2] is not None]
        points = np.concatenate([self._blocks[k][3] for k in chosen])
        viewpoints = np.concatenate([self._blocks[k][4] for k in chosen])
        before = self._before(points, front)
        points, viewpoints = points[before], viewpoints[before]
        sensors, inverse = np.unique(viewpoints, axis=0, return_inverse=True)
        along = self.position(sensors)[inverse.ravel()]
        order = np.argsort(along, kind="stable")  # as the robot went
        try:
            mesh = weld_coincident(meshes)[0] if meshes else None
            if mesh is not None:
                mesh = keep_faces(mesh, self._before(mesh.vertices, front)[mesh.faces].all(axis=1))
            if mesh is None or mesh.n_faces == 0:
                raise InputError("no surface")
            found = inspect_pipe(
                mesh,
                points[order],
                viewpoints=viewpoints[order],
                nominal_diameter=self.nominal_diameter,
                threshold=self.threshold,
                up=self._up,
                rng=self.rng,
            )
        except InputError as error:
            if not self.stretches and not final:
                self._failed = front  # too little yet: the first window waits a step
                return None
            return self._not_inspected(end, str(error), time.perf_counter() - start)
        pipe = found.pipe
        first = not self.stretches
        if first:
            self.nominal_diameter = self.nominal_diameter or 2.0 * pipe.radius
            self.threshold = self.threshold or found.defects.threshold
        # The report, in the window's axial positions: from where the last one ended (the
        # run's start for the first) to the tail's start (the pipe's end for the last).
        # (Where the last report's end lies before this window's data, its data's start.)
        a_low = -math.inf if first else self._axial_at(pipe, self._done, 0.0)
        a_high = math.inf if final else self._axial_at(pipe, end, math.nan)
        if math.isnan(a_high):  # the path's point lies past the data: end at the data's end
            a_high = pipe.length
            data_end = pipe.position(pipe.length, 0.0, distance=0.0)  # its centre there
            end = max(float(self.position(data_end)[0]), self._done)
        offset = 0.0 if first else self._axial_done - a_low
        a_start, a_end = (0.0 if first else a_low), min(a_high, pipe.length)

        def inside(axial: float) -> bool:
            return a_low <= axial < a_high

        def shifted(record, *names):
            return replace(record, **{n: getattr(record, n) + offset for n in names})

        last = () if first else self.stretches[-1].ovality.axial[-1:]
        lowest = last[0] + 0.5 * STATION * pipe.radius if len(last) else a_low + offset
        kept = (found.ovality.axial + offset >= lowest) & (found.ovality.axial < a_high)
        ovality = _stations(found.ovality, kept, offset)
        seen = self.defects()  # each region reported once (module docstring)
        defects = sorted(
            (d for d in (shifted(d, "axial", "axial_start", "axial_end")
                         for d in found.defects.defects
                         if d.axial < a_high and d.axial_end >= a_low)
             if not any(_same_region(d, e) for e in seen)),
            key=lambda d: d.axial,
        )  # fmt: skip
        unreliable = tuple(
            Unreliable(max(u.axial_start, a_start) + offset, min(u.axial_end, a_end) + offset,
                       u.reason)
            for u in pipe.unreliable
            if u.axial_end >= a_low and u.axial_start < a_high
        )  # fmt: skip
        stretch = Stretch(
            axial_start=a_start + offset,
            axial_end=a_end + offset,
            ovality=ovality,
            defects=tuple(defects),
            joints=tuple(shifted(j, "axial") for j in found.joints if inside(j.axial)),
            branches=tuple(shifted(b, "axial") for b in found.defects.branches if inside(b.axial)),
            unreliable=unreliable,
            measured_diameter=2.0 * pipe.measured_radius,
            would_threshold=smallest_depth(found.wall, pipe),
            seconds=time.perf_counter() - start,
        )
        # The next window's 12 o'clock: this one's at the next window's start.
        a_next = self._axial_at(pipe, end - MARGIN * unit, 0.0) if not final else a_end
        self._up = pipe.directions(a_next, 0.0)[1][0]  # 12 o'clock there
        return self._reported(stretch, end)

    def _not_inspected(self, end: float, reason: str, seconds: float) -> Stretch:
        """A stretch no pipe was fitted to, with a warning: one unreliable stretch, as long
        as its stretch of the path."""
        warnings.warn(f"a stretch of the run was not inspected: {reason}", SurfaceWarning,
                      stacklevel=4)  # fmt: skip
        if math.isinf(end):
            end = max(b[1] for b in self._blocks.values())
        a0 = self._axial_done
        a1 = a0 + max(end - max(self._done, 0.0), 0.0)
        none = _no_stations()
        stretch = Stretch(a0, a1, none, (), (), (), (Unreliable(a0, a1, f"not inspected: "
                          f"{reason}"),), math.nan, math.nan, seconds)  # fmt: skip
        return self._reported(stretch, end)

    def _reported(self, stretch: Stretch, end: float) -> Stretch:
        """Record `stretch`, move the reports' end to `end`, and forget the blocks no later
        window reads."""
        self.stretches.append(stretch)
        self._done, self._axial_done = end, stretch.axial_end
        keep = self._done - MARGIN * self._unit()
        self._blocks = {k: b for k, b in self._blocks.items() if b[1] >= keep and
                        not math.isinf(end)}  # fmt: skip
        return stretch

    def _axial_at(self, pipe, position: float, otherwise: float) -> float:
        """The axial position on `pipe` of the path's point at `position` (m along it)."""
        point = self._path_point(position)
        axial = float(pipe.locate(point[None])[0][0])
        return axial if math.isfinite(axial) else otherwise

    def _before(self, x: np.ndarray, front: float) -> np.ndarray:
        """(M,) bool: whether the path position of each of `x` (M, 3) lies at or before
        `front` (m; ``inf`` for the last window)."""
        if math.isinf(front):
            return np.ones(x.shape[0], dtype=bool)
        return self.position(x) <= front

    def _sampled(self, nodes: np.ndarray):
        """A k-d tree of the path `nodes` (S, 3) sampled every `SAMPLE` radii, nodes
        included, and the segment of each sample; built again when the path or the radius
        changes."""
        spacing = SAMPLE * self._unit()
        if self._samples is None or self._samples[:2] != (nodes.shape[0], spacing):
            a, b = nodes[:-1], nodes[1:]
            pieces = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / spacing), 1).astype(int)
            segment = np.repeat(np.arange(a.shape[0]), pieces)
            t = np.arange(segment.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)
            t = t / pieces[segment]
            samples = np.r_[a[segment] + t[:, None] * (b - a)[segment], nodes[-1:]]
            segment = np.r_[segment, a.shape[0] - 1]
            self._samples = (nodes.shape[0], spacing, cKDTree(samples), segment)
        return self._samples[2:]

    def _path_point(self, position: float) -> np.ndarray:
        """(3,) the point of the sensors' path at `position` metres along it."""
        nodes = self.path
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(nodes, axis=0), axis=1))]
        return np.array([np.interp(position, arc, nodes[:, i]) for i in range(3)])


#: The fields of an `Ovality`, in order.
_OVALITY = ("axial", "ovality", "d_max", "d_mean", "d_min", "major_clock", "offset", "scatter")


def _no_stations() -> Ovality:
    shapes = {"offset": (0, 2), "scatter": (0, 5)}
    return Ovality(*(np.zeros(shapes.get(n, (0,))) for n in _OVALITY))


def _stations(found: Ovality, kept: np.ndarray, offset: float) -> Ovality:
    """The stations `kept` (K,) bool of `found`, `offset` metres along."""
    values = [getattr(found, n)[kept] for n in _OVALITY]
    return Ovality(values[0] + offset, *values[1:])


def _same_region(d: Defect, e: Defect) -> bool:
    """Whether defects `d` and `e` (one axial scale) are of one kind and their regions
    overlap along the pipe and round it: one region seen by two windows."""

    def on_arc(clock, start, end):
        return (clock - start) % 360.0 <= (end - start) % 360.0

    return (
        d.kind == e.kind
        and d.axial_start <= e.axial_end
        and e.axial_start <= d.axial_end
        and (on_arc(d.clock_start, e.clock_start, e.clock_end)
             or on_arc(e.clock_start, d.clock_start, d.clock_end))
    )  # fmt: skip


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
