import numpy as np

from zeroset.evaluate import closest_points_on_triangles, points_to_mesh_distance


def test_closest_points_beat_a_dense_sampling_of_each_triangle(rng):
    p, a, b, c = (rng.normal(size=(100, 3)) for _ in range(4))
    foot = closest_points_on_triangles(p, a, b, c)
    u, v = np.meshgrid(np.linspace(0, 1, 101), np.linspace(0, 1, 101))
    inside = u + v <= 1
    u, v = u[inside], v[inside]
    for i in range(100):
        samples = a[i] + u[:, None] * (b[i] - a[i]) + v[:, None] * (c[i] - a[i])
        brute = np.linalg.norm(samples - p[i], axis=1).min()
        mine = np.linalg.norm(foot[i] - p[i])
        assert mine <= brute + 1e-12
        assert mine >= brute - 0.02 * np.linalg.norm(b[i] - a[i]) - 0.02 * np.linalg.norm(
            c[i] - a[i]
        )


def test_points_to_mesh_distance_on_a_tetrahedron(tetra_mesh):
    points = np.array([[0.2, 0.2, -0.5], [2.0, 0.0, 0.0], [0.1, 0.1, 0.1]])
    d = points_to_mesh_distance(points, tetra_mesh)
    np.testing.assert_allclose(d, [0.5, 1.0, 0.1], atol=1e-12)
