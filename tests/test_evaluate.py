import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tests import reference
from zeroset import topology
from zeroset.evaluate import (
    closest_points_on_mesh,
    closest_points_on_triangles,
    compare_to_points,
    compare_to_reference,
    evaluate,
    format_report,
    mesh_quality,
    points_to_mesh_distance,
    sample_surface,
    smallest_angles,
)
from zeroset.types import Mesh

MM = 0.001


# --------------------------------------------------------------------------- test meshes


def _icosphere(radius, level):
    """Icosahedron subdivided `level` times and projected onto the sphere; faces outward."""
    t = (1 + 5**0.5) / 2
    vertices = np.array(
        [
            [-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
            [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1],
        ],
        dtype=float,
    )  # fmt: skip
    faces = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
            [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
            [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ]
    )  # fmt: skip
    for _ in range(level):
        edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        ab, bc, ca = (vertices.shape[0] + inverse.reshape(-1, 3)).T
        vertices = np.vstack([vertices, vertices[unique].mean(axis=1)])
        a, b, c = faces.T
        faces = np.concatenate(
            [np.c_[a, ab, ca], np.c_[b, bc, ab], np.c_[c, ca, bc], np.c_[ab, bc, ca]]
        )
    vertices = radius * vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    return Mesh(vertices=vertices, faces=faces)


def _cylinder(radius, height, n_around, n_along):
    """Open cylinder around z of equal quads, each split in two triangles; faces outward."""
    theta = 2 * np.pi * np.arange(n_around) / n_around
    z = np.linspace(0.0, height, n_along + 1)
    zz, tt = np.meshgrid(z, theta, indexing="ij")
    vertices = np.c_[radius * np.cos(tt.ravel()), radius * np.sin(tt.ravel()), zz.ravel()]
    i, j = np.meshgrid(np.arange(n_along), np.arange(n_around), indexing="ij")
    a, b = i * n_around + j, i * n_around + (j + 1) % n_around
    c, d = b + n_around, a + n_around
    faces = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    return Mesh(vertices=vertices, faces=faces)


def _regular_tetrahedron():
    vertices = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    return Mesh(vertices=vertices, faces=faces)


def _uneven_soup(rng):
    """Big triangles under a cloud of tiny ones, plus slivers and a repeated-vertex face.

    Near the big triangle's middle the 16 nearest centroids all belong to tiny triangles
    0.5 above it, so a nearest-centroid shortlist misses the closest triangle.
    """
    big = np.array([[[-5, -5, 0], [5, -5, 0], [0, 6, 0]], [[-6, 4, -3], [6, 5, -2], [0, 0, 4]]])
    tiny = rng.uniform(-1, 1, size=(300, 1, 3)) * [1, 1, 0.1] + [0, 0, 0.5]
    tiny = tiny + 0.01 * rng.normal(size=(300, 3, 3))
    sliver_a, sliver_b = rng.uniform(-3, 3, size=(2, 20, 3))
    sliver_c = sliver_a + rng.uniform(0, 1, size=(20, 1)) * (sliver_b - sliver_a)
    slivers = np.stack([sliver_a, sliver_b, sliver_c + 1e-9 * rng.normal(size=(20, 3))], axis=1)
    repeated = np.array([[[2.0, 2, 1], [2, 2, 1], [3, 2, 2]]])
    corners = np.concatenate([big, tiny, slivers, repeated]).astype(float)
    order = rng.permutation(corners.shape[0])
    corners = corners[order]
    return Mesh(vertices=corners.reshape(-1, 3), faces=np.arange(corners.size // 3).reshape(-1, 3))


def _graded_grid(rng):
    """A connected height field whose cells grow geometrically from 1e-3 to 1 wide."""
    x = np.concatenate([[0.0], np.geomspace(1e-3, 3.0, 30)])
    y = np.linspace(0.0, 1.0, 8)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    zz = 0.05 * rng.normal(size=xx.shape)
    vertices = np.c_[xx.ravel(), yy.ravel(), zz.ravel()]
    n = y.size
    i, j = np.meshgrid(np.arange(x.size - 1), np.arange(n - 1), indexing="ij")
    a, b = (i * n + j).ravel(), ((i + 1) * n + j).ravel()
    faces = np.r_[np.c_[a, b, b + 1], np.c_[a, b + 1, a + 1]]
    return Mesh(vertices=vertices, faces=faces)


def _brute_force(points, mesh):
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))
    double_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest2 = np.max([((b - a) ** 2).sum(1), ((c - b) ** 2).sum(1), ((a - c) ** 2).sum(1)], 0)
    flagged = double_area <= 1e-12 * longest2
    return reference.closest_points_on_mesh(points, mesh.vertices, mesh.faces, flagged)


def _on_face(closest, mesh, face):
    """Distance from each closest point to the face it is reported on."""
    a, b, c = (mesh.vertices[mesh.faces[face, i]] for i in range(3))
    return np.linalg.norm(closest_points_on_triangles(closest, a, b, c) - closest, axis=1)


# --------------------------------------------------------------------------- closest points


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


def test_closest_points_on_degenerate_triangles_lie_on_their_segment():
    p = np.array([[0.5, 1.0, 0.0], [3.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [1.5, -2.0, 0.0]])
    a = np.zeros((4, 3))
    c = np.tile([2.0, 0.0, 0.0], (4, 1))
    expected = np.array([[0.5, 0, 0], [2, 0, 0], [0, 0, 0], [1.5, 0, 0]])
    for b in (a, c, 0.5 * c):  # a repeated vertex, either way, or three collinear ones
        np.testing.assert_allclose(closest_points_on_triangles(p, a, b, c), expected, atol=1e-15)


def test_points_to_mesh_distance_on_a_tetrahedron(tetra_mesh):
    points = np.array([[0.2, 0.2, -0.5], [2.0, 0.0, 0.0], [0.1, 0.1, 0.1]])
    d = points_to_mesh_distance(points, tetra_mesh)
    np.testing.assert_allclose(d, [0.5, 1.0, 0.1], atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closest_points_are_exact_on_uneven_triangle_soup(seed):
    rng = np.random.default_rng(seed)
    mesh = _uneven_soup(rng)
    near = mesh.vertices[rng.integers(0, mesh.n_vertices, 400)] + rng.normal(
        scale=10.0 ** rng.uniform(-4, 0, size=(400, 1)), size=(400, 3)
    )
    middle = rng.uniform(-0.5, 0.5, size=(100, 3)) * [1, 1, 0] + [0, 0, 0.1]
    far = rng.uniform(-30, 30, size=(100, 3))
    points = np.concatenate([near, middle, far])
    closest, face, distance = closest_points_on_mesh(points, mesh)
    _, _, brute = _brute_force(points, mesh)
    assert np.all(np.abs(distance - brute) <= 1e-12 * (1 + brute))
    np.testing.assert_allclose(np.linalg.norm(points - closest, axis=1), distance, atol=1e-12)
    assert _on_face(closest, mesh, face).max() < 1e-9
    # The points above the big triangle defeat a shortlist of the 16 nearest centroids.
    centroids = mesh.vertices[mesh.faces].mean(axis=1)
    shortlist = np.argsort(np.linalg.norm(middle[:, None] - centroids, axis=2), axis=1)[:, :16]
    a, b, c = (mesh.vertices[mesh.faces[shortlist, i]].reshape(-1, 3) for i in range(3))
    foot = closest_points_on_triangles(np.repeat(middle, 16, axis=0), a, b, c)
    naive = np.linalg.norm(np.repeat(middle, 16, axis=0) - foot, axis=1).reshape(-1, 16).min(1)
    assert np.mean(naive > distance[400:500] + 0.01) > 0.8


def test_closest_points_are_exact_on_a_graded_connected_mesh(rng):
    mesh = _graded_grid(rng)
    points = np.c_[rng.uniform(-0.5, 3.5, 600), rng.uniform(-0.5, 1.5, 600), rng.normal(size=600)]
    closest, face, distance = closest_points_on_mesh(points, mesh)
    _, _, brute = _brute_force(points, mesh)
    np.testing.assert_allclose(distance, brute, rtol=0, atol=1e-12)
    # Shared edges make ties; any face as close as the best is a right answer.
    assert _on_face(closest, mesh, face).max() < 1e-12


@given(
    corners=arrays(
        np.float64, st.tuples(st.integers(1, 12), st.just(9)), elements=st.floats(-4, 4)
    ),
    repeat=st.integers(0, 3),
    points=arrays(np.float64, st.tuples(st.integers(1, 8), st.just(3)), elements=st.floats(-6, 6)),
)
def test_closest_points_match_brute_force_on_any_triangles(corners, repeat, points):
    corners = corners.reshape(-1, 3, 3)
    corners[:repeat, 1] = corners[:repeat, 0]  # some faces repeat a vertex
    mesh = Mesh(vertices=corners.reshape(-1, 3), faces=np.arange(corners.size // 3).reshape(-1, 3))
    closest, face, distance = closest_points_on_mesh(points, mesh)
    _, _, brute = _brute_force(points, mesh)
    np.testing.assert_allclose(distance, brute, rtol=0, atol=1e-9)
    assert _on_face(closest, mesh, face).max() < 1e-9


def test_closest_points_do_not_depend_on_query_order(rng):
    mesh = _uneven_soup(rng)
    points = rng.uniform(-3, 3, size=(500, 3))
    order = rng.permutation(500)
    first = closest_points_on_mesh(points, mesh)
    second = closest_points_on_mesh(points[order], mesh)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a[order], b)


def test_closest_point_errors(tetra_mesh):
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        points_to_mesh_distance(np.zeros((4, 2)), tetra_mesh)
    with pytest.raises(TypeError, match="Mesh"):
        points_to_mesh_distance(np.zeros((4, 3)), tetra_mesh.vertices)
    with pytest.raises(ValueError, match="no faces"):
        points_to_mesh_distance(np.zeros((4, 3)), Mesh(np.eye(3), np.zeros((0, 3), dtype=int)))
    with pytest.raises(ValueError, match=r"outside \[0, 4\)"):
        points_to_mesh_distance(np.zeros((4, 3)), Mesh(tetra_mesh.vertices, np.array([[0, 1, 7]])))


# --------------------------------------------------------------------------- sampling


def test_samples_lie_on_their_faces_with_the_face_normals():
    mesh = _icosphere(1.0, 2)
    points, normals = sample_surface(mesh, 2000, rng=0)
    closest, face, distance = closest_points_on_mesh(points, mesh)
    assert distance.max() < 1e-12
    a, b, c = (mesh.vertices[mesh.faces[face, i]] for i in range(3))
    expected = np.cross(b - a, c - a)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(normals, expected, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", normals, points) > 0)  # outward, like the faces


def test_samples_are_spread_by_area():
    # Two triangles, areas 1 and 3.
    vertices = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 1], [6, 0, 1], [0, 1, 1]])
    mesh = Mesh(vertices=vertices.astype(float), faces=np.array([[0, 1, 2], [3, 4, 5]]))
    points, _ = sample_surface(mesh, 20_000, rng=1)
    share = np.mean(points[:, 2] > 0.5)
    assert abs(share - 0.75) < 4 * np.sqrt(0.75 * 0.25 / 20_000)
    # Uniform inside a triangle: the mean is the centroid.
    np.testing.assert_allclose(points[points[:, 2] > 0.5].mean(axis=0), [2, 1 / 3, 1], atol=0.03)


def test_sampling_is_seeded():
    mesh = _icosphere(1.0, 1)
    first, second = sample_surface(mesh, 100, rng=5), sample_surface(mesh, 100, rng=5)
    np.testing.assert_array_equal(first[0], second[0])
    assert not np.array_equal(first[0], sample_surface(mesh, 100, rng=6)[0])


def test_sampling_errors(tetra_mesh):
    with pytest.raises(ValueError, match="positive integer"):
        sample_surface(tetra_mesh, 0)
    flat = Mesh(vertices=np.zeros((3, 3)), faces=np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="zero area"):
        sample_surface(flat, 10)


# --------------------------------------------------------------------------- against a reference


def test_a_mesh_matches_itself():
    mesh = _icosphere(1.0, 3)
    report = compare_to_reference(mesh, mesh, n_samples=5000)
    assert report["accuracy"]["max"] < 1e-12 and report["completeness"]["max"] < 1e-12
    assert report["chamfer_l1"] < 1e-12 and report["hausdorff"] < 1e-12
    assert all(item["f_score"] == 1.0 for item in report["thresholds"])
    assert report["normal_consistency"] == pytest.approx(1.0, abs=1e-12)
    json.dumps(report, allow_nan=False)


def test_spheres_one_millimetre_apart():
    inner, outer = _icosphere(50 * MM, 5), _icosphere(51 * MM, 5)
    report = compare_to_reference(
        inner, outer, n_samples=10_000, taus=(0.5 * MM, 2 * MM), tau_unit="absolute"
    )
    # Matching faces lie in parallel planes 1 mm * cos(angle) apart; cos > 0.9998 here.
    for side in ("accuracy", "completeness"):
        assert report[side]["mean"] == pytest.approx(MM, rel=0.03)
        assert report[side]["max"] == pytest.approx(MM, rel=0.03)
    assert report["hausdorff"] == pytest.approx(MM, rel=0.03)
    assert report["chamfer_l1"] == pytest.approx(MM, rel=0.03)
    assert report["chamfer_l2"] == pytest.approx(MM**2, rel=0.06)
    below, above = report["thresholds"]
    assert below["tau"] == 0.5 * MM and below["f_score"] == 0.0
    assert above["tau"] == 2 * MM and above["f_score"] == 1.0
    assert above["tau_fraction"] == pytest.approx(2 * MM / report["diagonal"])
    assert report["diagonal"] == pytest.approx(np.sqrt(3) * 102 * MM, rel=1e-3)
    assert report["normal_consistency"] > 0.999


def test_a_missing_patch_lowers_recall_by_its_share():
    full = _cylinder(1.0, 2.0, n_around=120, n_along=40)
    angle = np.arctan2(*full.vertices[full.faces].mean(axis=1)[:, 1::-1].T) % (2 * np.pi)
    patch = angle < 2 * np.pi * 0.1  # 12 of the 120 columns of equal faces: 10 % of the area
    assert patch.mean() == pytest.approx(0.1)
    holed = Mesh(vertices=full.vertices, faces=full.faces[~patch])
    whole = compare_to_reference(full, full, n_samples=2000, taus=(0.001,))
    report = compare_to_reference(holed, full, n_samples=20_000, taus=(0.001,))
    (item,) = report["thresholds"]
    assert item["recall"] == pytest.approx(0.9, abs=0.01)
    assert item["precision"] == 1.0
    assert report["accuracy"]["max"] < 1e-12 and whole["accuracy"]["max"] < 1e-12
    # The hole is 0.63 wide, so the farthest reference samples are about 0.31 from the mesh.
    assert 0.25 < report["completeness"]["max"] < 0.32


def test_reference_option_errors(tetra_mesh):
    with pytest.raises(ValueError, match="tau_unit"):
        compare_to_reference(tetra_mesh, tetra_mesh, tau_unit="metres")
    with pytest.raises(ValueError, match="positive number"):
        compare_to_reference(tetra_mesh, tetra_mesh, taus=(0.01, -1))
    with pytest.raises(ValueError, match="empty"):
        compare_to_reference(tetra_mesh, tetra_mesh, taus=())
    with pytest.raises(ValueError, match="n_samples"):
        compare_to_reference(tetra_mesh, tetra_mesh, n_samples=0)
    with pytest.raises(TypeError, match="reference must be a zeroset Mesh"):
        compare_to_reference(tetra_mesh, None)


# --------------------------------------------------------------------------- against points


def test_points_on_the_mesh_are_covered():
    mesh = _icosphere(1.0, 3)
    points, _ = sample_surface(mesh, 3000, rng=2)
    report = compare_to_points(mesh, points)
    assert report["coverage"] == 1.0
    assert report["distance"]["max"] < 1e-12
    assert report["tau_fraction"] == pytest.approx(0.01)
    assert report["tau"] == pytest.approx(0.01 * np.linalg.norm(np.ptp(points, axis=0)))


def test_points_offset_outwards_are_their_offset_away():
    # Outside a convex polyhedron, a point moved along its face normal is that far away.
    mesh = _icosphere(1.0, 3)
    points, normals = sample_surface(mesh, 3000, rng=3)
    report = compare_to_points(mesh, points + 0.02 * normals, tau=0.01)
    for stat in ("mean", "median", "p95", "max"):
        assert report["distance"][stat] == pytest.approx(0.02, rel=1e-9)
    assert report["tau"] == 0.01 and report["coverage"] == 0.0


def test_points_errors(tetra_mesh):
    with pytest.raises(ValueError, match="tau"):
        compare_to_points(tetra_mesh, np.zeros((3, 3)), tau=-1.0)
    with pytest.raises(ValueError, match="coincide"):
        compare_to_points(tetra_mesh, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        compare_to_points(tetra_mesh, [[0.0, np.nan, 0.0]])


# --------------------------------------------------------------------------- mesh quality


def test_regular_tetrahedron_quality():
    quality = mesh_quality(_regular_tetrahedron())
    assert quality["euler_characteristic"] == 2
    assert quality["vertices"] == 4 and quality["faces"] == 4 and quality["edges"] == 6
    assert quality["boundary_edges"] == 0 and quality["boundary_loops"] == 0
    assert quality["non_manifold_edges"] == 0 and quality["non_manifold_vertices"] == 0
    assert quality["components"] == 1 and quality["degenerate_faces"] == 0
    for value in quality["aspect_ratio"].values():
        assert value == pytest.approx(1.0, abs=1e-12)
    assert quality["min_angle_degrees"]["min"] == pytest.approx(60.0, abs=1e-9)
    assert quality["area"] == pytest.approx(8 * np.sqrt(3))  # four triangles of side 2 sqrt 2
    json.dumps(quality, allow_nan=False)


def test_smallest_angles_per_face():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [0.5, 3**0.5 / 2, 0]])
    faces = np.array([[0, 1, 2], [0, 1, 4], [0, 1, 3], [2, 1, 0]])
    angles = smallest_angles(Mesh(vertices=vertices, faces=faces))
    np.testing.assert_allclose(angles, [45.0, 60.0, 0.0, 45.0], atol=1e-9)


def test_right_isosceles_aspect_ratio():
    # R = hypotenuse / 2 = sqrt(2) / 2, r = (2 - sqrt(2)) / 2 for legs of 1.
    mesh = Mesh(vertices=np.eye(3)[[0, 1]].tolist() + [[0.0, 0, 0]], faces=np.array([[2, 0, 1]]))
    quality = mesh_quality(mesh)
    assert quality["aspect_ratio"]["max"] == pytest.approx(np.sqrt(2) / (2 * (2 - np.sqrt(2))))
    assert quality["min_angle_degrees"]["min"] == pytest.approx(45.0)


def test_non_manifold_edge_and_bowtie_are_counted():
    vertices = np.array(
        [
            [0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1],  # three wings on 0-1
            [3, 0, 0], [4, 1, 0], [4, -1, 0], [2, 1, 0], [2, -1, 0],  # two triangles at 5
        ],
        dtype=float,
    )  # fmt: skip
    faces = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [5, 7, 6], [5, 8, 9]])
    quality = mesh_quality(Mesh(vertices=vertices, faces=faces))
    assert quality["non_manifold_edges"] == 1
    assert quality["non_manifold_vertices"] == 1
    assert quality["edges"] == 13 and quality["boundary_edges"] == 12
    # Wings: one connected set of boundary edges; the bow-tie splits into two triangles.
    assert quality["boundary_loops"] == 3
    assert quality["components"] == 2
    assert quality["euler_characteristic"] == 10 - 13 + 5


def test_bowtie_of_two_squares_has_two_loops():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    vertices = np.concatenate([square, square[1:] + [1, 1, 0]])  # shares vertex 2
    faces = np.array([[0, 1, 2], [0, 2, 3], [2, 4, 5], [2, 5, 6]])
    quality = mesh_quality(Mesh(vertices=vertices, faces=faces))
    assert quality["non_manifold_vertices"] == 1 and quality["boundary_loops"] == 2


def test_degenerate_faces_are_counted_and_left_out_of_shapes():
    tetra = _regular_tetrahedron()
    vertices = np.vstack([tetra.vertices, [0.5 * (tetra.vertices[0] + tetra.vertices[1])]])
    faces = np.vstack([tetra.faces, [[0, 1, 4], [2, 2, 3]]])  # collinear, repeated vertex
    quality = mesh_quality(Mesh(vertices=vertices, faces=faces))
    assert quality["degenerate_faces"] == 2
    assert quality["aspect_ratio"]["max"] == pytest.approx(1.0)
    assert quality["min_angle_degrees"]["min"] == pytest.approx(60.0)
    assert quality["area"] == pytest.approx(8 * np.sqrt(3))
    json.dumps(quality, allow_nan=False)


@pytest.mark.parametrize("holed, loops, euler", [(False, 2, 0), (True, 1, 1)])
def test_boundary_loops_agree_with_topology_on_manifold_meshes(holed, loops, euler):
    mesh = _cylinder(1.0, 1.0, n_around=24, n_along=5)
    if holed:  # cut a strip of columns: the tube becomes a rectangle
        angle = np.arctan2(*mesh.vertices[mesh.faces].mean(axis=1)[:, 1::-1].T) % (2 * np.pi)
        mesh = Mesh(vertices=mesh.vertices, faces=mesh.faces[angle > 1.0])
    quality = mesh_quality(mesh)
    assert quality["boundary_loops"] == loops == len(topology.boundary_loops(mesh.faces))
    assert quality["euler_characteristic"] == euler == topology.euler_characteristic(mesh)
    assert (quality["unreferenced_vertices"] > 0) == holed


def test_quality_survives_inconsistent_orientation(tetra_mesh):
    faces = tetra_mesh.faces[1:].copy()  # open, and one face flipped
    faces[0] = faces[0, ::-1]
    quality = mesh_quality(Mesh(vertices=tetra_mesh.vertices, faces=faces))
    assert quality["boundary_edges"] == 3 and quality["boundary_loops"] == 1


# --------------------------------------------------------------------------- reports


def test_evaluate_combines_the_sections_and_prints_them():
    mesh, truth = _icosphere(1.0, 2), _icosphere(1.0, 3)
    points, _ = sample_surface(truth, 500, rng=4)
    report = evaluate(mesh, reference=truth, points=points, n_samples=2000)
    assert set(report) == {"quality", "reference", "points"}
    assert report["reference"] == compare_to_reference(mesh, truth, n_samples=2000)
    json.loads(json.dumps(report, allow_nan=False))
    text = format_report(report)
    assert text.splitlines()[0].startswith("reference: 2,000 samples per surface")
    assert "\npoints: 500 scan points" in text and "\nquality\n" in text
    # Columns line up: in the quality block every count ends in the same column.
    block = text.split("\nquality\n")[1].splitlines()[:11]
    assert len({len(line) for line in block}) == 1
    assert set(evaluate(mesh)) == {"quality"}
    assert format_report(mesh_quality(mesh)) == format_report({"quality": mesh_quality(mesh)})


def test_report_errors(tetra_mesh):
    with pytest.raises(ValueError, match="none of the sections"):
        format_report({"something": 1})
    with pytest.raises(TypeError, match="dict"):
        format_report("quality")
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        evaluate(tetra_mesh, points=np.zeros(3))
