"""Off-screen pictures: something is drawn, where the object is, in the colours promised."""

import os

import numpy as np
import pytest
from matplotlib import colormaps

from zeroset import InputError, reconstruct
from zeroset.synthetic import sample_cylinder
from zeroset.types import Mesh
from zeroset.viz import (
    RenderError,
    distance_colours,
    intensity_colours,
    preview,
    render,
    vertex_distances,
)


def _no_opengl() -> str | None:
    """Why no picture can be rendered here, or None."""
    try:
        render(Mesh(vertices=np.eye(3), faces=np.array([[0, 1, 2]])), width=16, height=16)
    except RenderError as error:
        return str(error)
    return None


# Without OpenGL these tests skip, except in CI, which installs Mesa's EGL and must run them.
pytestmark = pytest.mark.skipif(
    _no_opengl() is not None and not os.environ.get("CI"), reason="no OpenGL context"
)


@pytest.fixture(scope="module")
def pipe_mesh():
    sample = sample_cylinder(8000, radius=0.25, length=1.0, noise=0.002, rng=5)
    return sample, reconstruct(sample.points).mesh


def _masks(picture):
    r, g, b = (picture[..., i].astype(int) for i in range(3))
    drawn = (r + g + b) < 3 * 250
    blue = (b > r + 40) & drawn
    orange = (r > b + 40) & (g > b) & drawn
    red = (r > 150) & (g < 80) & (b < 80)
    return drawn, blue, orange, red


def test_render_shows_the_pipe_in_each_panel_outside_blue_inside_orange(pipe_mesh):
    _, mesh = pipe_mesh
    picture = render(mesh, width=400, height=200)
    assert picture.shape == (200, 400, 3) and picture.dtype == np.uint8
    for panel in (picture[:, :200], picture[:, 200:]):
        drawn, blue, orange, _ = _masks(panel)
        assert 0.05 < drawn.mean() < 0.8  # not blank, not all object
        rows, cols = np.nonzero(drawn)
        # The camera looks at the mesh's centre: the object is centred in its panel.
        assert abs(rows.mean() - 100) < 25 and abs(cols.mean() - 100) < 25
        assert blue.sum() > 0.2 * drawn.sum()  # the outside faces the viewer
    # Seen from above (second panel), the inside of the open pipe is visible.
    assert _masks(picture[:, 200:])[2].sum() > 0.05 * _masks(picture[:, 200:])[0].sum()


def test_boundaries_points_and_colours_change_the_picture(pipe_mesh):
    sample, mesh = pipe_mesh
    plain = render(mesh, boundaries=False, width=400, height=200)
    assert _masks(plain)[3].sum() == 0
    assert _masks(render(mesh, width=400, height=200))[3].sum() > 20  # red rims
    dotted = render(mesh, points=sample.points, boundaries=False, width=400, height=200)
    assert (dotted.sum(axis=2) < 150).sum() > (plain.sum(axis=2) < 150).sum()  # dark dots
    colours = distance_colours(vertex_distances(mesh, sample.points))
    tinted = render(mesh, colours=colours, boundaries=False, width=400, height=200)

    def greenish(picture):  # viridis' green to yellow: neither the blue nor the orange shading
        r, g, b = (picture[..., i].astype(int) for i in range(3))
        return ((g > r + 20) & (g > b)).mean()

    assert greenish(plain) < 0.001 and greenish(tinted) > 0.05


def test_points_take_their_intensity_colours(pipe_mesh):
    sample, mesh = pipe_mesh
    upper = sample.points[:, 2] > 0.5  # strong returns on the upper half of the pipe
    colours = intensity_colours(np.where(upper, 1000.0, 10.0))
    np.testing.assert_allclose(colours[upper][0], colormaps["plasma"](1.0)[:3])
    np.testing.assert_allclose(colours[~upper][0], colormaps["plasma"](0.0)[:3])
    picture = render(mesh, points=sample.points, point_colours=colours, boundaries=False,
                     width=400, height=200)  # fmt: skip
    r, g, b = (picture[..., i].astype(int) for i in range(3))
    yellow = (r > 180) & (g > 180) & (b < 120)  # plasma's top; the shading has no yellow
    assert yellow.mean() > 0.01
    grey = render(mesh, points=sample.points, boundaries=False, width=400, height=200)
    assert ((grey[..., 0] > 180) & (grey[..., 1] > 180) & (grey[..., 2] < 120)).mean() == 0


def test_far_coordinates_render_like_near_ones(pipe_mesh):
    _, mesh = pipe_mesh
    far = Mesh(vertices=mesh.vertices + [6.0e5, 5.0e6, 300.0], faces=mesh.faces)
    near, moved = render(mesh, width=200, height=100), render(far, width=200, height=100)
    assert np.mean(np.abs(near.astype(int) - moved.astype(int)) > 8) < 0.01


def test_preview_writes_a_png(pipe_mesh, tmp_path):
    from PIL import Image

    _, mesh = pipe_mesh
    path = preview(mesh, tmp_path / "p.png", width=300, height=150)
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size == (300, 150)
    assert [p.name for p in tmp_path.iterdir()] == ["p.png"]  # no temporary file left


def test_vertex_distances_are_the_heights_of_the_points():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [5, 5, 0]], dtype=float)
    mesh = Mesh(vertices=vertices, faces=np.array([[0, 1, 2], [0, 2, 3], [1, 4, 2]]))
    rng = np.random.default_rng(0)
    points = np.c_[rng.uniform(0.05, 0.95, (200, 2)), np.full(200, 0.02)]
    points[:100, 2] = -0.02
    distance = vertex_distances(mesh, points)
    np.testing.assert_allclose(distance[:4], 0.02)
    assert np.isnan(distance[4]) or distance[4] == pytest.approx(0.02)
    colours = distance_colours(np.array([0.0, 1.0, np.nan]), limit=1.0)
    assert colours.shape == (3, 3) and np.all(colours[2] == 0.6)
    assert colours[1, :2].sum() > colours[0, :2].sum()  # far is bright (yellow)


def test_an_empty_mesh_is_an_input_error():
    with pytest.raises(InputError, match="no faces"):
        render(Mesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64)))
