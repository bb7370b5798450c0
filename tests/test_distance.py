import numpy as np

from zeroset.distance import signed_distance
from zeroset.thresholds import ZERO_NUDGE


def _plane_patch(rng, n=3000):
    points = np.c_[rng.uniform(0, 1, (n, 2)), np.zeros(n)]
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    return points, normals


def test_values_are_heights_above_the_plane(rng):
    points, normals = _plane_patch(rng)
    field = signed_distance(points, points, normals, cube_size=0.05, radius=0.04)
    z = field.positions[:, 2]
    defined = ~np.isnan(field.values)
    expected = np.where(np.abs(z) < ZERO_NUDGE * 0.05, ZERO_NUDGE * 0.05, z)
    np.testing.assert_allclose(field.values[defined], expected[defined], atol=1e-12)
    assert np.all(field.values[defined] != 0.0)


def test_values_are_undefined_beyond_the_data(rng):
    points, normals = _plane_patch(rng)
    field = signed_distance(points, points, normals, cube_size=0.05, radius=0.04)
    x, y = field.positions[:, 0], field.positions[:, 1]
    outside = (x < -0.045) | (x > 1.045) | (y < -0.045) | (y > 1.045)
    inside = (x > 0.05) & (x < 0.95) & (y > 0.05) & (y < 0.95)
    assert outside.any() and np.all(np.isnan(field.values[outside]))
    assert not np.isnan(field.values[inside]).any()


def test_band_is_thin_and_on_the_global_lattice(rng):
    points, normals = _plane_patch(rng)
    field = signed_distance(points + 0.3, points + 0.3, normals, cube_size=0.05, radius=0.04)
    assert np.abs(field.positions[:, 2] - 0.3).max() <= 2 * 0.05 + 1e-12
    # About 22 x 22 x 4 vertices around the patch, not the bounding box of anything larger.
    assert field.values.size < 4000
    np.testing.assert_allclose(field.positions / 0.05, np.round(field.positions / 0.05), atol=1e-9)
    keys = field.vertices_ijk
    assert np.unique(keys, axis=0).shape[0] == keys.shape[0]


def test_one_bad_plane_does_not_open_a_hole(rng):
    points, normals = _plane_patch(rng)
    normals = normals.copy()
    centre = np.argmin(np.linalg.norm(points - [0.5, 0.5, 0.0], axis=1))
    normals[centre] = [1.0, 0.0, 0.0]  # a wildly wrong tangent plane in the middle
    field = signed_distance(points, points, normals, cube_size=0.05, radius=0.04)
    x, y = field.positions[:, 0], field.positions[:, 1]
    inside = (x > 0.05) & (x < 0.95) & (y > 0.05) & (y < 0.95)
    assert not np.isnan(field.values[inside]).any()
