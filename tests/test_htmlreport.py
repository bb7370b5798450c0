"""The HTML report: self-contained, its arrays decode to the meshes, and it works in a browser."""

import base64
import gzip
import html
import json
import os
import re
import shutil
from dataclasses import replace
from io import BytesIO

import numpy as np
import pytest

from zeroset import reconstruct
from zeroset.errors import InputError
from zeroset.htmlreport import inspection_summary, write_html_report, write_inspection_report
from zeroset.inspect import Defect, Defects, Joint, Unreliable, inspect_pipe
from zeroset.io import read_mesh, write_mesh
from zeroset.synthetic import sample_cylinder


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    sample = sample_cylinder(8000, radius=0.25, length=1.0, noise=0.002, rng=6)
    points = sample.points + [1000.0, 2000.0, 0.0]  # far from the origin, as scans are
    result = reconstruct(points, optimize=True)
    path = tmp_path_factory.mktemp("report") / "report.html"
    write_html_report(path, result, points=points, source="pipe.ply")
    return path, result, points


def _png(colour) -> bytes:
    """A small PNG file of one colour."""
    from PIL import Image

    buffer = BytesIO()
    Image.new("RGB", (24, 12), colour).save(buffer, format="PNG")
    return buffer.getvalue()


PICTURES = {"deviation map <unrolled>": _png((200, 30, 30)), "ovality": _png((30, 30, 200))}


@pytest.fixture(scope="module")
def inspected(tmp_path_factory):
    """A pipe with a dent 15 mm deep, its inspection, and both kinds of inspection page.

    Near the origin and without phase 2: `inspect_pipe` does not yet fit this pipe's
    centreline far from the origin, nor on phase 2's coarser mesh."""
    sample = sample_cylinder(8000, radius=0.25, length=1.0, noise=0.002, rng=6)
    points = sample.points.copy()
    angle = np.arctan2(points[:, 1], points[:, 0])
    arc = (angle - 1.0) * 0.25  # metres round the wall from the dent's middle
    dent = 0.015 * np.exp(-0.5 * (((points[:, 2] - 0.5) / 0.06) ** 2 + (arc / 0.06) ** 2))
    points[:, :2] *= (1.0 - dent / 0.25)[:, None]
    result = reconstruct(points, progress=False)
    inspection = inspect_pipe(result.dense_mesh, points)  # as the CLI inspects
    folder = tmp_path_factory.mktemp("inspected")
    report = write_html_report(
        folder / "report.html", result, points=points, inspection=inspection, pictures=PICTURES
    )
    mesh = read_mesh(write_mesh(folder / "pipe.ply", result.dense_mesh))
    page = write_inspection_report(
        folder / "inspection.html",
        mesh,
        inspection,
        points=points,
        pictures=PICTURES,
        source="pipe.ply",
    )
    return report, page, mesh, inspection


def _embedded(text, name):
    match = re.search(rf'<script type="application/json" id="{name}">(.*?)</script>', text, re.S)
    return json.loads(match.group(1))


def _unpack(entry):
    data = gzip.decompress(base64.b64decode(entry["gzip"]))
    return np.frombuffer(data, dtype=np.dtype(entry["dtype"]).newbyteorder("<")).reshape(
        entry["shape"]
    )


@pytest.mark.parametrize("page", ["reconstruction", "with inspection", "inspection"])
@pytest.mark.slow
def test_report_is_one_file_that_loads_nothing(report, inspected, page):
    paths = {"reconstruction": report[0], "with inspection": inspected[0]}
    text = paths.get(page, inspected[1]).read_text(encoding="utf-8")
    assert text.startswith("<!doctype html>")
    # Nothing but data URIs (the pictures) in a src or href.
    linked = r"<(script|link|img|iframe)[^>]*\b(src|href)=(?![\"']?data:)"
    assert not re.search(linked, text, re.I)
    assert not re.search(r"\b(fetch|XMLHttpRequest|importScripts)\s*\(", text)
    assert "var THREE=" in text and "zeroset-report" in text  # three.js is inside


@pytest.mark.slow
def test_embedded_arrays_are_the_meshes_and_numbers_the_report(report):
    path, result, points = report
    text = path.read_text(encoding="utf-8")
    numbers, layers = _embedded(text, "zeroset-report"), _embedded(text, "zeroset-layers")
    assert numbers["stats"]["faces"] == result.mesh.n_faces
    assert numbers["optimization"]["history"][0]["step"] == "start"
    for name, mesh in (("phase 1", result.initial_mesh), ("phase 2", result.mesh)):
        layer = layers[name]
        np.testing.assert_array_equal(_unpack(layer["faces"]), mesh.faces)
        # Relative to the offset, float32 keeps the far-away coordinates to a micrometre.
        vertices = _unpack(layer["vertices"]).astype(np.float64) + result.offset
        np.testing.assert_allclose(vertices, mesh.vertices, atol=1e-6)
        assert _unpack(layer["boundary"]).shape[1] == 2
        assert np.nanmax(_unpack(layer["distance"])) < 0.05
    assert _unpack(layers["points"]).shape == points.shape
    assert "inspection" not in numbers
    assert not any("deviation" in layer for layer in layers.values())


@pytest.mark.slow
def test_report_of_an_inspection_carries_its_deviations_defects_and_pictures(inspected):
    path, _, _, inspection = inspected
    text = path.read_text(encoding="utf-8")
    numbers, layers = _embedded(text, "zeroset-report"), _embedded(text, "zeroset-layers")
    assert "phase 2" not in layers  # phase 1's mesh is the final one
    deviation = _unpack(layers["phase 1"]["deviation"])
    np.testing.assert_array_equal(deviation, inspection.vertex_deviation.astype(np.float32))
    assert deviation.shape == (_unpack(layers["phase 1"]["vertices"]).shape[0],)
    assert "distance" in layers["phase 1"]  # the distance colouring stays
    assert "stats" in numbers and "parameters" in numbers
    found = numbers["inspection"]
    assert found["nominal_diameter"] == pytest.approx(2 * inspection.pipe.radius)
    assert found["nominal_diameter"] == pytest.approx(0.5, abs=0.005)
    assert found["length"] == pytest.approx(inspection.pipe.length)
    assert found["threshold"] == pytest.approx(inspection.defects.threshold)
    defects = inspection.defects.defects
    assert len(found["defects"]) == len(defects) >= 1
    for number, written, defect in zip(
        range(1, len(defects) + 1), found["defects"], defects, strict=True
    ):
        assert written["number"] == number
        assert written["kind"] == defect.kind
        for name in ("axial", "clock", "depth", "axial_start", "axial_end", "width", "area"):
            assert written[name] == pytest.approx(getattr(defect, name))
        assert re.fullmatch(r"(1[0-2]|[1-9]):[0-5]\d", written["clock_time"])
    deepest = found["defects"][0]
    assert deepest["kind"] == "dent" and deepest["depth"] == pytest.approx(-0.012, abs=0.004)
    # 12:00 is +y and 3:00 is -x (see zeroset.inspect), so the dent, at polar angle 1 rad
    # (57 degrees from +x), is at 327 degrees: 10:55.
    assert deepest["clock"] == pytest.approx(327.3, abs=6.0)
    assert deepest["clock_time"].split(":")[0] in ("10", "11")
    for caption, png in PICTURES.items():
        assert f'src="data:image/png;base64,{base64.b64encode(png).decode()}"' in text
        assert f"<figcaption>{html.escape(caption)}</figcaption>" in text
    assert "<unrolled>" not in text  # captions are escaped


@pytest.mark.slow
def test_inspection_summary_reads_the_clock_and_has_no_nan(inspected):
    *_, inspection = inspected
    defect = Defect("bulge", 0.5, 0.0, 0.003, float("nan"), 0.4, 0.6, 350.0, 10.0, 0.09, 0.01)
    clocks = (0.0, 90.0, 15.0, 359.9, 187.5)
    defects = Defects(
        tuple(replace(defect, clock=c) for c in clocks), (), 0.002, 5.0, inspection.defects.labels
    )
    unfitted = np.full_like(inspection.ovality.ovality, np.nan)
    no_station = replace(inspection.ovality, ovality=unfitted)
    summary = inspection_summary(replace(inspection, defects=defects, ovality=no_station))
    times = [d["clock_time"] for d in summary["defects"]]
    assert times == ["12:00", "3:00", "12:30", "12:00", "6:15"]
    assert summary["defects"][0]["uncertainty"] is None
    assert summary["stations"] == {
        "count": 0, "d_min_mm": None, "d_mean_mm": None, "d_max_mm": None, "ovality_percent": None
    }  # fmt: skip
    json.dumps(summary, allow_nan=False)  # ready for JSON as it is


@pytest.mark.slow
def test_deviation_goes_on_the_final_mesh_and_must_match_it(report, inspected, tmp_path):
    _, result, _ = report
    *_, inspection = inspected
    deviation = np.linspace(-0.01, 0.02, result.mesh.n_vertices)
    deviation[::7] = np.nan  # beyond the centreline's ends
    path = write_html_report(
        tmp_path / "phase2.html",
        result,
        report={"stats": {}},
        inspection=replace(inspection, vertex_deviation=deviation),
    )
    layers = _embedded(path.read_text(encoding="utf-8"), "zeroset-layers")
    written = _unpack(layers["phase 2"]["deviation"])
    np.testing.assert_array_equal(written, deviation.astype(np.float32))  # NaN too
    assert "deviation" not in layers["phase 1"]
    with pytest.raises(InputError, match=r"deviations of \d+ vertices; the mesh shown has \d+"):
        write_html_report(tmp_path / "not.html", result, report={}, inspection=inspection)
    with pytest.raises(TypeError, match="PNG bytes"):
        write_html_report(tmp_path / "not.html", result, report={}, pictures={"x": b"GIF89a"})
    assert not (tmp_path / "not.html").exists()


@pytest.mark.slow
def test_inspection_report_of_a_mesh_read_from_a_file(inspected):
    _, path, mesh, inspection = inspected
    text = path.read_text(encoding="utf-8")
    numbers, layers = _embedded(text, "zeroset-report"), _embedded(text, "zeroset-layers")
    assert set(layers) == {"inspected", "points"}  # no reconstruction: no normals, no phases
    assert set(numbers) == {"source", "inspection"}
    assert numbers["inspection"] == json.loads(json.dumps(inspection_summary(inspection)))
    layer = layers["inspected"]
    np.testing.assert_array_equal(_unpack(layer["faces"]), mesh.faces)
    vertices = _unpack(layer["vertices"]).astype(np.float64)
    shift = mesh.vertices.mean(axis=0) - vertices.mean(axis=0)  # shown about their middle
    np.testing.assert_allclose(vertices + shift, mesh.vertices, atol=1e-6)
    deviation = _unpack(layer["deviation"])
    np.testing.assert_array_equal(deviation, inspection.vertex_deviation.astype(np.float32))
    assert _unpack(layer["boundary"]).shape[0] > 0  # an open pipe: two rims
    assert "<title>zeroset inspection: pipe.ply</title>" in text
    assert text.count("<figure>") == len(PICTURES)


def _browser():
    """A headless Chromium driven by Selenium, or a skip (a failure in CI) if there is none."""
    webdriver = pytest.importorskip("selenium.webdriver")
    binary, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if binary is None or driver is None:
        if os.environ.get("CI"):
            pytest.fail("CI needs the Debian packages chromium and chromium-driver (.ci/run)")
        pytest.skip("no chromium and chromedriver (Debian: apt-get install chromium-driver)")
    options = webdriver.ChromeOptions()
    for argument in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=1200,800",
    ):
        options.add_argument(argument)
    options.binary_location = binary
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    from selenium.webdriver.chrome.service import Service

    return webdriver.Chrome(service=Service(driver), options=options)


def _canvas(browser):
    """(H, W, 4) uint8 pixels of the viewer's canvas."""
    from io import BytesIO

    from PIL import Image

    url = browser.execute_script("return document.getElementById('canvas').toDataURL('image/png')")
    with Image.open(BytesIO(base64.b64decode(url.split(",", 1)[1]))) as image:
        return np.asarray(image.convert("RGBA"))


def _open(browser, path):
    """Open a report offline and wait until the viewer is ready (or failed)."""
    from selenium.webdriver.support.ui import WebDriverWait

    browser.set_network_conditions(
        offline=True, latency=0, download_throughput=0, upload_throughput=0
    )
    browser.get(path.as_uri())
    WebDriverWait(browser, 60).until(
        lambda b: b.execute_script(
            "return (window.zerosetViewer && window.zerosetViewer.ready) "
            "|| document.body.dataset.error"
        )
    )
    assert browser.execute_script("return document.body.dataset.error || null") is None


@pytest.mark.slow
def test_viewer_draws_and_toggles_offline_without_console_errors(report):
    path, _, _ = report
    browser = _browser()
    try:
        _open(browser, path)
        layers = browser.execute_script("return window.zerosetViewer.layers")
        assert {"phase 1 mesh", "phase 2 mesh", "points", "normals", "boundaries"} <= set(layers)
        shown = _canvas(browser)
        drawn = shown[..., :3].sum(axis=2) < 3 * 250
        assert 0.02 < drawn.mean() < 0.9  # the mesh is drawn on a white background
        browser.execute_script("window.zerosetViewer.setLayer('phase 2 mesh', false)")
        hidden = _canvas(browser)
        assert (hidden[..., :3].sum(axis=2) < 3 * 250).mean() < 0.5 * drawn.mean()
        browser.execute_script("window.zerosetViewer.setLayer('colour by distance', true)")
        browser.execute_script("window.zerosetViewer.setLayer('phase 1 mesh', true)")
        assert np.abs(_canvas(browser).astype(int) - hidden).sum() > 0
        assert "Parameters" in browser.find_element("id", "numbers").text
        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == []
    finally:
        browser.quit()


@pytest.mark.slow
def test_viewer_colours_by_deviation_first_and_shows_the_inspection(inspected):
    report, page, _, inspection = inspected
    checked = "return document.querySelector(`input[data-layer='${arguments[0]}']`).checked"
    browser = _browser()
    try:
        _open(browser, page)
        layers = browser.execute_script("return window.zerosetViewer.layers")
        assert layers == [
            "inspected mesh", "points", "boundaries", "colour by distance", "colour by deviation"
        ]
        assert browser.execute_script(checked, "colour by deviation")
        legend = browser.find_element("id", "legend").text
        limits = r"deviation: blue \u2212([\d.]+) mm \(inward\) \u2026 red \+([\d.]+) mm"
        magnitude = np.abs(inspection.vertex_deviation.astype(np.float32))
        magnitude = np.sort(magnitude[np.isfinite(magnitude)])
        p99 = 1000 * magnitude[int(0.99 * magnitude.size)]  # the viewer's 99th percentile
        shown = re.search(limits, legend).groups()
        assert shown[0] == shown[1] and float(shown[0]) == pytest.approx(p99, rel=0.06)
        pixels = _canvas(browser)[..., :3].astype(int)
        drawn = pixels.sum(axis=2) < 3 * 250
        # Mostly near the nominal wall: near white, not the plain material's blue (B - R = 127).
        assert np.median(np.abs(pixels[..., 2] - pixels[..., 0])[drawn]) < 40
        numbers = browser.find_element("id", "numbers").text
        assert "Defects" in numbers and "Parameters" not in numbers
        assert f"{1000 * inspection.defects.defects[0].depth:.1f} \u00b1" in numbers
        browser.execute_script("window.zerosetViewer.setLayer('colour by distance', true)")
        assert not browser.execute_script(checked, "colour by deviation")  # one at a time
        assert "distance" in browser.find_element("id", "legend").text
        assert np.abs(_canvas(browser)[..., :3].astype(int) - pixels).sum() > 0
        browser.execute_script("window.zerosetViewer.setLayer('colour by distance', false)")
        assert not browser.find_element("id", "legend").is_displayed()

        _open(browser, report)
        assert browser.execute_script(checked, "colour by deviation")
        numbers = browser.find_element("id", "numbers").text
        assert "Inspection" in numbers and "Parameters" in numbers
        pictures = browser.execute_script(
            "return Array.from(document.querySelectorAll('#pictures img'), (i) => i.naturalWidth)"
        )
        assert pictures == [24, 24]  # the PNGs decode
        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == []
    finally:
        browser.quit()


@pytest.mark.slow
def test_viewer_tables_the_stations_defects_joints_and_centreline_check(inspected, tmp_path):
    *_, mesh, inspection = inspected
    dent = Defect("dent", 0.5, 330.0, -0.032, 5e-4, 0.45, 0.55, 320.0, 340.0, 0.09, 0.01, 6.4, True)
    joints = (Joint("gap", 0.3, 0.012, 0.001, depth=0.003), Joint("offset", 0.6, 0.004, 5e-4, 90.0))
    shown = replace(
        inspection,
        defects=replace(inspection.defects, defects=(dent,), basis="4.9 standard errors"),
        joints=joints,
        pipe=replace(
            inspection.pipe,
            extent=inspection.pipe.length + 0.2,
            unreliable=(Unreliable(0.8, 0.9, "the sections are not ellipses"),),
        ),
    )
    page = write_inspection_report(tmp_path / "shown.html", mesh, shown)
    browser = _browser()
    try:
        _open(browser, page)
        text = browser.find_element("id", "numbers").text
        rows = browser.execute_script(
            "return Array.from(document.querySelectorAll('#numbers tr.warn'), (r) => r.innerText)"
        )
        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        browser.quit()
    assert errors == []
    assert "threshold: 4.9 standard errors" in text
    assert "Stations: min / median / max over" in text and "D_mean" in text
    assert "the sections are not ellipses" in text
    assert "Joints" in text and "3:00" in text
    # the centreline's length 0.2 m from the data's extent, and the dent to assess, are marked
    assert len(rows) == 2
    assert "the data extend" in rows[0] and "differ by more than 2 % or one diameter" in rows[0]
    assert "6.4" in rows[1] and "> 6 % D, assess" in rows[1]


@pytest.mark.slow
def test_the_cli_reports_an_inspection_of_the_dense_mesh(tmp_path):
    # The CLI inspects the dense mesh and shows it, coloured by deviation, in the report
    # of a run whose final mesh is the simplified one (it stopped with an InputError).
    from zeroset.cli import main
    from zeroset.io import write_points

    sample = sample_cylinder(8000, radius=0.25, length=1.0, noise=0.002, rng=6)
    cloud = write_points(tmp_path / "pipe.ply", sample.points)
    mesh_path, report = tmp_path / "m.ply", tmp_path / "r.html"
    argv = ["reconstruct", str(cloud), "-o", str(mesh_path), "--quiet"]
    assert main([*argv, "--inspect", str(tmp_path / "pipe"), "--report", str(report)]) == 0
    layers = _embedded(report.read_text(encoding="utf-8"), "zeroset-layers")
    vertices = _unpack(layers["phase 1"]["vertices"]).reshape(-1, 3)
    deviation = _unpack(layers["phase 1"]["deviation"])
    written = read_mesh(mesh_path)
    assert deviation.shape == (vertices.shape[0],)
    assert vertices.shape[0] > 3 * written.n_vertices  # the dense mesh, not the simplified
    radius = np.hypot(vertices[:, 0], vertices[:, 1])
    middle = np.abs(vertices[:, 2] - 0.5) < 0.4
    assert np.abs(radius[middle] - 0.25).mean() < 0.001
