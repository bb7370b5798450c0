"""The HTML report: self-contained, its arrays decode to the meshes, and it works in a browser."""

import base64
import gzip
import json
import os
import re
import shutil

import numpy as np
import pytest

from zeroset import reconstruct
from zeroset.htmlreport import write_html_report
from zeroset.synthetic import sample_cylinder


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    sample = sample_cylinder(8000, radius=0.25, length=1.0, noise=0.002, rng=6)
    points = sample.points + [1000.0, 2000.0, 0.0]  # far from the origin, as scans are
    result = reconstruct(points, optimize=True)
    path = tmp_path_factory.mktemp("report") / "report.html"
    write_html_report(path, result, points=points, source="pipe.ply")
    return path, result, points


def _embedded(text, name):
    match = re.search(rf'<script type="application/json" id="{name}">(.*?)</script>', text, re.S)
    return json.loads(match.group(1))


def _unpack(entry):
    data = gzip.decompress(base64.b64decode(entry["gzip"]))
    return np.frombuffer(data, dtype=np.dtype(entry["dtype"]).newbyteorder("<")).reshape(
        entry["shape"]
    )


def test_report_is_one_file_that_loads_nothing(report):
    path, _, _ = report
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!doctype html>")
    assert not re.search(r"<(script|link|img|iframe)[^>]*\b(src|href)=", text, re.I)
    assert not re.search(r"\b(fetch|XMLHttpRequest|importScripts)\s*\(", text)
    assert "var THREE=" in text and "zeroset-report" in text  # three.js is inside


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


def test_viewer_draws_and_toggles_offline_without_console_errors(report):
    from selenium.webdriver.support.ui import WebDriverWait

    path, _, _ = report
    browser = _browser()
    try:
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
