"""The live inspection: windows of finished blocks, stitched along the run, find the defects
where they are as the blocks finish, on one axial scale and clock frame."""

import csv
import warnings

import numpy as np
import pytest

from tests.test_live import BLOCK_CUBES, RADIUS, RANGE, _scans
from zeroset.errors import InputError, SurfaceWarning
from zeroset.inspect import LIVE_FILES, LiveInspection, Stretch, inspect_pipe
from zeroset.inspect._live import MARGIN, _no_stations
from zeroset.live import LiveReconstruction
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
