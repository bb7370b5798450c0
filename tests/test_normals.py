import numpy as np
import pytest

from zeroset.normals import tangent_planes
from zeroset.synthetic import sample_sphere


def test_plane_normals_are_perpendicular_to_the_plane(rng):
    points = np.c_[rng.uniform(-1, 1, (2000, 2)), 0.001 * rng.normal(size=2000)]
    planes = tangent_planes(points, radius=0.15)
    assert np.all(np.abs(planes.normals[:, 2]) > 0.95)
    np.testing.assert_allclose(np.linalg.norm(planes.normals, axis=1), 1.0)
    assert np.all(planes.eigenvalues[:, 0] <= planes.eigenvalues[:, 1])


def test_sphere_normals_are_radial_and_centroids_near_the_surface():
    sample = sample_sphere(5000, rng=0)
    planes = tangent_planes(sample.points, radius=0.15)
    cosine = np.abs(np.einsum("ij,ij->i", planes.normals, sample.normals))
    assert np.percentile(cosine, 1) > 0.99
    assert np.abs(np.linalg.norm(planes.centroids, axis=1) - 1).max() < 0.02


def test_neighbourhood_is_widened_to_k_min_where_the_radius_holds_too_few(rng):
    points = rng.normal(size=(500, 3))
    planes = tangent_planes(points, radius=1e-9, k_min=6, k_max=10)
    assert np.all(planes.neighbour_count == 6)


def test_normals_rotate_with_the_points(rng):
    points = sample_sphere(1500, noise=0.01, rng=1).points
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    a = tangent_planes(points, radius=0.25)
    b = tangent_planes(points @ q.T + 5.0, radius=0.25)
    np.testing.assert_allclose(
        np.abs(np.einsum("ij,ij->i", a.normals @ q.T, b.normals)), 1.0, atol=1e-6
    )
    np.testing.assert_allclose(a.centroids @ q.T + 5.0, b.centroids, atol=1e-9)


def test_result_arrays_are_read_only(rng):
    planes = tangent_planes(rng.normal(size=(100, 3)), radius=1.0)
    with pytest.raises(ValueError):
        planes.normals[0, 0] = 1.0


def test_bad_radius_is_rejected(rng):
    with pytest.raises(ValueError, match="radius must be a positive number"):
        tangent_planes(rng.normal(size=(100, 3)), radius=-1.0)
