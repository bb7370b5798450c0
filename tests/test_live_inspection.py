"""The live inspection: windows of finished blocks, stitched along the run, find the defects
where they are as the blocks finish, on one axial scale and clock frame."""

import csv
import warnings

import numpy as np
import pytest

from tests.test_live import BLOCK_CUBES, RADIUS, RANGE, _scans
from zeroset.errors import InputError, SurfaceWarning
from zeroset.inspect import LIVE_FILES, LiveInspection, Stretch, inspect_pipe
from zeroset.inspect._defects import Defect as Found
from zeroset.inspect._live import MARGIN, _no_stations, _same_region
from zeroset.live import LiveReconstruction
from zeroset.repair import keep_faces
from zeroset.synthetic import Defect, PipePath, scan_pipe_run

LENGTH = 6.0
#: Two dents, reported by different windows, on different sides of the pipe.
DENTS = (Defect("dent", 2.0, 90.0, 0.015, 0.1), Defect("dent", 4.5, 210.0, 0.010, 0.1))
STEP = 0.6


@pytest.fixture(scope="module")
def grown(tmp_path_factory):
    """A 6 m pipe with two dents given scan by scan, inspected as its blocks finish: the
    live inspection, the stretches each scan reported, the live mesh and the scans."""
    folder = tmp_path_factory.mktemp("inspection")
    scans = _scans(rotation_step=4.0, defects=DENTS, length=LENGTH)
    inspection = LiveInspection(step=STEP, folder=folder)
    live = LiveReconstruction(
        reach=RANGE, block_cubes=BLOCK_CUBES, budget=np.inf, inspection=inspection
    )
    during = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for points, viewpoints in scans:
            during.append(live.add(points, viewpoints).inspected)
        last = live.close().inspected
    return inspection, during, last, live.mesh(), scans, folder


@pytest.mark.slow
def test_stretches_are_reported_while_the_scans_come_and_join_end_to_end(grown):
    inspection, during, last, *_ = grown
    early = [s for update in during for s in update]
    assert len(early) >= 2 and len(last) == 1
    assert inspection.stretches == [*early, *last]
    ends = [(s.axial_start, s.axial_end) for s in inspection.stretches]
    assert ends[0][0] == 0.0
    assert all(b[0] == a[1] and a[1] > a[0] for a, b in zip(ends, ends[1:], strict=False))
    # The run's length along the stitched windows is the pipe's.
    assert abs(inspection.inspected_to - LENGTH) < 0.05


@pytest.mark.slow
def test_the_stations_run_on_one_scale_and_measure_the_diameter(grown):
    inspection, *_ = grown
    stations = inspection.ovality()
    steps = np.diff(stations.axial)
    station = 0.1 * RADIUS  # the stations of `zeroset.inspect.ovality`
    assert steps.min() > 0.5 * station and steps.max() < 1.5 * station  # no overlap, no gap
    fitted = np.isfinite(stations.d_mean)
    assert np.count_nonzero(fitted) > 0.9 * LENGTH / station
    assert np.abs(stations.d_mean[fitted] - 2 * RADIUS).max() < 1e-3
    assert abs(inspection.nominal_diameter - 2 * RADIUS) < 2e-4


@pytest.mark.slow
def test_each_dent_is_found_once_where_it_is_as_deep_as_the_batch_inspection_finds_it(grown):
    inspection, during, _, mesh, scans, folder = grown
    found = inspection.defects()
    assert [d.kind for d in found] == ["dent", "dent"]
    for dent, d in zip(DENTS, found, strict=True):
        assert abs(d.axial - dent.axial) < 0.03
        assert abs(d.clock - dent.clock) < 5.0  # 12 o'clock carried from window to window
        assert abs(-d.depth - dent.depth) < 1e-3
    # The first dent is reported before the run ends, as its blocks finish.
    early = [d for update in during for s in update for d in s.defects]
    assert early and abs(early[0].axial - DENTS[0].axial) < 0.03
    points = np.concatenate([s[0] for s in scans])
    viewpoints = np.concatenate([s[1] for s in scans])
    batch = inspect_pipe(mesh, points, viewpoints=viewpoints).defects.defects
    batch = sorted(batch, key=lambda d: d.axial)
    assert len(batch) == 2
    for d, b in zip(found, batch, strict=True):  # as deep (their axial origins differ)
        assert abs(d.depth - b.depth) < 5e-4 and abs(d.clock - b.clock) < 2.0
    with open(folder / LIVE_FILES[1], encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [float(r["axial_m"]) for r in rows] == [round(d.axial, 4) for d in found]


def test_the_path_position_is_the_arc_length_to_the_nearest_point():
    inspection = LiveInspection()
    for sensor in ([0.0, 0, 0], [1.0, 0, 0], [1.0, 2.0, 0]):
        inspection.scan(np.array(sensor), np.array([0.2]))
    x = np.array([[0.5, 0.3, 0.0], [1.4, 1.0, 0.0], [-1.0, 0.0, 0.0], [2.0, 5.0, 0.0]])
    assert np.allclose(inspection.position(x), [0.5, 2.0, 0.0, 3.0])


def _stretch(start, end, diameter, threshold):
    return Stretch(start, end, _no_stations(), (), (), (), (), diameter, threshold, 0.0)


def test_later_windows_that_would_choose_otherwise_are_reported():
    inspection = LiveInspection(nominal_diameter=0.4, threshold=0.002)
    inspection.stretches += [_stretch(0.0, 2.0, 0.4, 0.002), _stretch(2.0, 4.0, 0.41, 0.0021)]
    assert inspection.drift() == []
    inspection.stretches.append(_stretch(4.0, 6.0, 0.52, 0.003))
    lines = inspection.drift()
    assert len(lines) == 2 and "520.0 mm" in lines[0] and "3.00 mm" in lines[1]
    with pytest.warns(SurfaceWarning, match="later stretches would have chosen otherwise"):
        inspection.close()


@pytest.mark.parametrize("option", ["nominal_diameter", "threshold", "step"])
def test_bad_options_are_refused(option):
    with pytest.raises(InputError, match=option):
        LiveInspection(**{option: -1.0})


def test_a_window_that_fits_no_pipe_is_reported_as_not_inspected():
    inspection = LiveInspection()
    for x in (0.0, 1.0, 2.0):
        inspection.scan(np.array([x, 0.0, 0.0]), np.full(10, 0.2))
    points = np.random.default_rng(0).normal(size=(100, 3))
    inspection.block((0, 0, 0), None, points, np.zeros((100, 3)), np.array([1.0, 0, 0]), 1.0)
    with pytest.warns(SurfaceWarning, match="not inspected: no surface"):
        (stretch,) = inspection.advance(np.inf)
    (gap,) = stretch.unreliable
    assert gap.reason == "not inspected: no surface" and stretch.axial_end > 0.0
    assert inspection.inspected_to == stretch.axial_end


@pytest.mark.slow
def test_12_oclock_is_carried_up_a_bend_into_a_vertical_leg():
    """A window that starts on a vertical leg gets no 12 o'clock from the world's up (the
    convention falls back to +y there, a quarter turn off); the last window's carried up
    keeps the clock of the batch inspection, which carries it through the bend."""
    path = PipePath.build([("straight", 2.0), ("bend", 0.6, 90.0, 0.0), ("straight", 5.5)])
    dent = Defect("dent", 7.0, 90.0, 0.012, 0.1)  # on the vertical leg
    scans = []
    for k, station in enumerate(np.arange(0.25, path.length, 0.5)):
        scan = scan_pipe_run(path, radius=RADIUS, stations=[station], rotation_step=4.0,
                             defects=(dent,), rng=k)  # fmt: skip
        near = np.linalg.norm(scan.points - scan.viewpoints, axis=1) <= RANGE
        scans.append((scan.points[near], scan.viewpoints[near]))
    inspection = LiveInspection(step=0.5)
    live = LiveReconstruction(
        reach=RANGE, block_cubes=BLOCK_CUBES, budget=np.inf, inspection=inspection
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for points, viewpoints in scans:
            live.add(points, viewpoints)
        live.close()
    bend_end = 2.0 + 0.6 * np.pi / 2
    (found,) = inspection.defects()
    (window,) = [s for s in inspection.stretches if s.axial_start <= found.axial < s.axial_end]
    assert window.axial_start - MARGIN * RADIUS > bend_end  # its window starts on the leg
    points = np.concatenate([s[0] for s in scans])
    viewpoints = np.concatenate([s[1] for s in scans])
    (batch,) = inspect_pipe(live.mesh(), points, viewpoints=viewpoints).defects.defects
    assert abs(found.clock - batch.clock) < 5.0 and abs(found.clock - dent.clock) < 5.0
    assert abs(found.axial - dent.axial) < 0.03


def _arc_to_nearest(x, nodes):
    """(M,) arc length along the polyline `nodes` (S, 3) of its nearest point to each of
    `x` (M, 3), over every segment (the reference for `LiveInspection.position`)."""
    a, b = nodes[:-1], nodes[1:]
    length = np.linalg.norm(b - a, axis=1)
    t = np.clip(np.einsum("msk,sk->ms", x[:, None] - a, b - a) / length**2, 0.0, 1.0)
    gap = np.linalg.norm(x[:, None] - a - t[..., None] * (b - a), axis=2)
    j = np.argmin(gap, axis=1)
    return np.r_[0.0, np.cumsum(length)][j] + t[np.arange(j.size), j] * length[j]


@pytest.mark.slow
def test_a_window_is_cut_square_at_the_front(monkeypatch):
    """Blocks are boxes: across a bend a window of whole blocks ends obliquely, past the
    front on one side of the pipe and short of it on the other, and there the centreline
    and the wall map go wrong. The points and faces a window inspects end at the front
    (by the path position of their nearest path point), and reach it."""
    path = PipePath.build([("straight", 1.5), ("bend", 0.6, 90.0, 0.0), ("straight", 1.5)])
    inspection = LiveInspection(nominal_diameter=2 * RADIUS, step=0.5)  # windows in RADIUS
    scans = []
    for k, station in enumerate(np.arange(0.25, path.length, 0.5)):
        scan = scan_pipe_run(path, radius=RADIUS, stations=[station], rotation_step=8.0,
                             rng=k)  # fmt: skip
        near = np.linalg.norm(scan.points - scan.viewpoints, axis=1) <= RANGE
        points, sensors = scan.points[near], scan.viewpoints[near]
        scans.append((points, sensors))
        inspection.scan(scan.viewpoints.mean(axis=0), np.linalg.norm(points - sensors, axis=1))
    nodes = inspection.path
    points, viewpoints = (np.concatenate(part) for part in zip(*scans, strict=True))
    truth = scan.truth_mesh()
    size = 0.5
    block = np.floor(points / size).astype(np.int64)
    face_block = np.floor(truth.vertices[truth.faces].mean(axis=1) / size).astype(np.int64)
    for index in np.unique(block, axis=0):
        here = (block == index).all(axis=1)
        faces = (face_block == index).all(axis=1)
        mesh = keep_faces(truth, faces) if faces.any() else None
        inspection.block(tuple(index), mesh, points[here], viewpoints[here],
                         (index + 0.5) * size, size)  # fmt: skip
    seen = []

    def spy(mesh, points, **options):
        seen.append((mesh, points))
        return inspect_pipe(mesh, points, **options)

    monkeypatch.setattr("zeroset.inspect._live.inspect_pipe", spy)
    arc = _arc_to_nearest(nodes, nodes)
    bend = 1.5 + 0.5 * np.pi * 0.6 - 0.25  # the bend's end, on the path from its first station
    fronts = (bend - 0.3, arc[-1] - 0.3)  # in the bend, and on the last leg
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SurfaceWarning)
        for front in fronts:
            (stretch,) = inspection.advance(front)
            assert stretch.defects == ()  # the wall is clean
    for (mesh, window), front in zip(seen, fronts, strict=True):
        for x in (window, mesh.vertices):
            along = _arc_to_nearest(x, nodes)
            assert along.max() <= front + 0.01  # within a sample's spacing of the front
            assert along.max() > front - 0.05  # and the data reach it


def _found(kind, axial, clock, extent=(0.05, 20.0)):
    """A found defect at `axial` (m) and `clock` (degrees), `extent` long and wide."""
    (length, width) = extent
    return Found(kind, axial, clock, -0.005, 0.0005, axial - length / 2, axial + length / 2,
                 (clock - width / 2) % 360, (clock + width / 2) % 360, 0.01, 1e-4)  # fmt: skip


@pytest.mark.parametrize(
    "other, same",
    [
        (_found("dent", 6.63, 270.0), True),  # the same dent placed 3 cm on by the next window
        (_found("dent", 6.70, 270.0), False),  # its own region, just past
        (_found("dent", 6.60, 90.0), False),  # across the pipe
        (_found("bulge", 6.60, 270.0), False),
        (_found("dent", 6.62, 262.0, (0.02, 2.0)), True),  # inside it
    ],
)
def test_a_region_two_windows_see_is_one_defect(other, same):
    dent = _found("dent", 6.60, 270.0)
    assert _same_region(dent, other) is same and _same_region(other, dent) is same


def test_regions_overlap_across_12_oclock():
    assert _same_region(_found("dent", 1.0, 355.0), _found("dent", 1.0, 8.0))
    assert not _same_region(_found("dent", 1.0, 340.0), _found("dent", 1.0, 20.0))


def test_path_positions_near_a_bent_path_are_those_of_the_nearest_path_point():
    rng = np.random.default_rng(3)
    turn = np.linspace(0.0, 0.5 * np.pi, 8)  # a bend of 0.6 m radius between two legs
    nodes = np.r_[[[x, 0.0, 0.0] for x in np.arange(-2.0, 0.0, 0.5)],
                  np.c_[0.6 * np.sin(turn), 0.6 - 0.6 * np.cos(turn), 0 * turn],
                  [[0.6, 0.6 + y, 0.0] for y in np.arange(0.5, 2.0, 0.5)]]  # fmt: skip
    inspection = LiveInspection(nominal_diameter=2 * RADIUS)
    for node in nodes:
        inspection.scan(node, np.array([RADIUS]))
    near = nodes[rng.integers(0, len(nodes), 5000)] + rng.normal(0.0, RADIUS, (5000, 3))
    error = np.abs(inspection.position(near) - _arc_to_nearest(near, nodes))
    assert np.mean(error < 1e-9) > 0.97  # exact where the nearest sample's segment is
    assert error.max() < 0.05 * RADIUS  # and off by less than a sample's spacing round corners
