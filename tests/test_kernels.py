"""Compiled kernels against their NumPy references, on random inputs."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tests import reference
from zeroset._kernels import _jit, linalg
from zeroset._kernels import density as density_kernels
from zeroset._kernels import evaluate as evaluate_kernels
from zeroset._kernels import jets as jet_kernels
from zeroset._kernels import normals as normals_kernels
from zeroset._kernels import orientation as orientation_kernels
from zeroset._kernels import triangles as triangle_kernels
from zeroset.neighbours import knn, spatial_order


def _neighbourhood_inputs(rng):
    points = rng.normal(size=(300, 3))
    nb = knn(points, 10)
    indices = nb.indices.copy()
    indices[rng.random(indices.shape) < 0.1] = -1  # dropped neighbours
    indices[:, 0] = np.arange(300)
    radius = rng.uniform(0.3, 1.5, size=300)
    return points, indices, nb.distances.copy(), radius


def _tree_inputs(rng):
    n = 200
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    order = rng.permutation(n)
    predecessors = np.full(n, -9999)
    for position, v in enumerate(order[1:], start=1):
        predecessors[v] = order[rng.integers(0, position)]
    root_sign = np.zeros(n)
    root_sign[order[0]] = -1.0
    return order.astype(np.int64), predecessors.astype(np.int64), normals, root_sign


def _triangle_soup_inputs(rng):
    # Separate triangles of sizes from 1e-3 to 3, so no two are equally close to a point;
    # the last one repeats a vertex and is flagged degenerate.
    n = 150
    centres = rng.uniform(-2, 2, size=(n, 1, 3))
    sizes = 10.0 ** rng.uniform(-3, 0.5, size=(n, 1, 1))
    corners = centres + sizes * rng.normal(size=(n, 3, 3))
    corners[-1, 2] = corners[-1, 0]
    degenerate = np.zeros(n, dtype=bool)
    degenerate[-1] = True
    points = rng.uniform(-3, 3, size=(300, 3))
    return points, corners.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), degenerate


def _closest_points_on_mesh(points, vertices, faces, degenerate):
    """The hierarchy's closest point, face and distance; it flags degenerate faces itself."""
    face, bary, distance2 = evaluate_kernels.closest_points_on_mesh(points, vertices, faces)
    closest = np.einsum("ni,nij->nj", bary, vertices[faces[face]])
    return closest, face, np.sqrt(distance2)


def _sector_inputs(rng):
    points, indices, distances, _ = _neighbourhood_inputs(rng)
    distances[indices < 0] = np.inf
    u = rng.normal(size=(300, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(u, rng.normal(size=(300, 3)))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return points, indices, distances, u, v, 8


def _surface_patch(rng, n=400):
    """Noisy samples of a curved patch, random weights and spreads, and 24 neighbours each."""
    uv = rng.uniform(-1, 1, size=(n, 2))
    points = np.column_stack([uv, 0.3 * uv[:, 0] ** 2 - 0.2 * uv[:, 1] ** 2 + 0.1 * uv[:, 0]])
    points += 0.01 * rng.normal(size=points.shape)
    weights = rng.integers(1, 5, n).astype(float)
    root = 0.01 * rng.normal(size=(n, 3, 3))
    spreads = root @ root.transpose(0, 2, 1)
    nb = knn(points, 24)
    return points, weights, spreads, nb.indices, nb.distances


def _fit_inputs(rng):
    points, weights, spreads, indices, distances = _surface_patch(rng)
    radius = rng.uniform(0.1, 0.6, size=indices.shape[0])
    return points, weights, spreads, indices, distances, radius, 8


def _blend_inputs(rng):
    jets = jet_kernels.fit_rows(*_fit_inputs(rng))
    positions = rng.uniform(-1, 1, size=(200, 3)) * [1, 1, 0.2]
    distances, indices = cKDTree(jets[0]).query(positions, k=9)
    return positions, indices, distances, jets[0], jets[1], jets[2]


COMPARISONS = [
    (jet_kernels.blend_rows, reference.blend_jet_rows, _blend_inputs),
    (density_kernels.sector_nearest, reference.sector_nearest, _sector_inputs),
    (normals_kernels.centroid_covariance, reference.centroid_covariance, _neighbourhood_inputs),
    (orientation_kernels.propagate_signs, reference.propagate_signs, _tree_inputs),
    (_closest_points_on_mesh, reference.closest_points_on_mesh, _triangle_soup_inputs),
]


@pytest.mark.parametrize(
    "kernel, ref, build", COMPARISONS, ids=lambda f: getattr(f, "__name__", "")
)
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.slow
def test_kernel_matches_reference(kernel, ref, build, seed):
    inputs = build(np.random.default_rng(seed))
    got, expected = kernel(*inputs), ref(*inputs)
    for g, e in zip(
        np.atleast_1d(got) if not isinstance(got, tuple) else got,
        np.atleast_1d(expected) if not isinstance(expected, tuple) else expected,
        strict=True,
    ):
        np.testing.assert_allclose(g, e, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize(
    "kernel, build",
    [
        (jet_kernels.fit_rows, _fit_inputs),
        (jet_kernels.blend_rows, _blend_inputs),
        (density_kernels.sector_nearest, _sector_inputs),
        (normals_kernels.centroid_covariance, _neighbourhood_inputs),
        (_closest_points_on_mesh, _triangle_soup_inputs),
    ],
    ids=lambda f: getattr(f, "__name__", ""),
)
def test_rows_shared_among_threads_give_what_one_thread_gives(kernel, build, monkeypatch):
    inputs = build(np.random.default_rng(5))
    whole = kernel(*inputs)
    monkeypatch.setattr(_jit, "CHUNK_ROWS", 7)
    monkeypatch.setattr(_jit, "threads", lambda: 4)  # many chunks, even on one core
    shared = kernel(*inputs)
    for w, s in zip(whole, shared, strict=True):
        np.testing.assert_array_equal(s, w)


@pytest.mark.skipif(
    not hasattr(normals_kernels._centroid_covariance_rows, "signatures"),
    reason="Numba's JIT is off (NUMBA_DISABLE_JIT=1): nothing is compiled",
)
def test_a_kernel_compiles_once_for_frozen_and_writeable_inputs():
    points, indices, distances, radius = _neighbourhood_inputs(np.random.default_rng(6))
    frozen = [a.copy() for a in (points, indices, distances, radius)]
    for a in frozen:
        a.flags.writeable = False
    strided = [np.repeat(a, 2, axis=0)[::2] for a in (points, indices, distances, radius)]
    for arrays in ((points, indices, distances, radius), frozen, strided):
        normals_kernels.centroid_covariance(*arrays)
    assert len(normals_kernels._centroid_covariance_rows.signatures) == 1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jet_fit_matches_reference(seed):
    inputs = _fit_inputs(np.random.default_rng(seed))
    got, expected = jet_kernels.fit_rows(*inputs), reference.fit_jet_rows(*inputs)
    for g, e in zip(got[:1] + got[3:], expected[:1] + expected[3:], strict=True):
        np.testing.assert_allclose(g, e, rtol=1e-8, atol=1e-12)
    # Frames are eigenvectors, each row up to its sign; the coefficients follow the signs.
    signs = np.sign(np.einsum("nij,nij->ni", got[1], expected[1]))
    np.testing.assert_allclose(got[1] * signs[..., None], expected[1], atol=1e-8)
    s1, s2, sn = signs.T
    flips = np.stack([sn, sn * s1, sn * s2, sn, sn * s1 * s2, sn], axis=1)
    np.testing.assert_allclose(got[2][:, :6] * flips, expected[2][:, :6], rtol=1e-7, atol=1e-9)
    # Turning the normal over negates the principal curvatures, so they swap places.
    curvatures = np.sort(got[2][:, 6:8] * sn[:, None], axis=1)
    np.testing.assert_allclose(
        curvatures, np.sort(expected[2][:, 6:8], axis=1), rtol=1e-7, atol=1e-9
    )


def test_component_extremes_finds_the_farthest_point_per_direction():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(500, 3))
    component = rng.integers(0, 4, size=500)
    extremes = orientation_kernels.component_extremes(points, component, 4)
    for c in range(4):
        members = np.flatnonzero(component == c)
        for axis in range(3):
            assert extremes[c, 2 * axis] == members[np.argmax(points[members, axis])]
            assert extremes[c, 2 * axis + 1] == members[np.argmin(points[members, axis])]


def _barycentric_closest_points(rng):
    corners = rng.normal(size=(500, 3, 3)) * 10.0 ** rng.uniform(-2, 1, size=(500, 1, 1))
    corners[-1, 2] = corners[-1, 0] + 1e-14  # nearly degenerate
    points = rng.normal(size=(500, 3)) * 2
    a, b, c = (np.ascontiguousarray(corners[:, k]) for k in range(3))
    distance2, bary = np.zeros(500), np.zeros((500, 3))
    triangle_kernels.closest_point_rows(points, a, b, c, distance2, bary)
    return points, a, b, c, distance2, bary


def test_barycentrics_reproduce_the_closest_point():
    points, a, b, c, distance2, bary = _barycentric_closest_points(np.random.default_rng(4))
    assert np.all(bary >= 0.0)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    foot = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    np.testing.assert_allclose(distance2, np.sum((points - foot) ** 2, axis=1), atol=1e-12)
    # Against the plain NumPy reference (normal equations, not dual vectors).
    expected = reference.closest_points_on_triangles(points, a, b, c)
    np.testing.assert_allclose(foot, expected, atol=1e-9)
    np.testing.assert_allclose(distance2, np.sum((points - expected) ** 2, axis=1), atol=1e-9)
    # Against an independent search: the triangle densely sampled, and its three edges.
    u, v = np.meshgrid(np.linspace(0, 1, 101), np.linspace(0, 1, 101))
    u, v = u[u + v <= 1], v[u + v <= 1]
    s = np.linspace(0, 1, 1001)[:, None]
    for i in range(0, 500, 5):
        samples = np.concatenate(
            [a[i] + u[:, None] * (b[i] - a[i]) + v[:, None] * (c[i] - a[i])]
            + [x + s * (y - x) for x, y in ((a[i], b[i]), (b[i], c[i]), (c[i], a[i]))]
        )
        brute = np.sum((samples - points[i]) ** 2, axis=1).min()
        assert distance2[i] <= brute + 1e-12


def _ordered_soup(seed, in_order):
    """The generator, and a triangle soup's points (in spatial order if `in_order`),
    vertices and faces."""
    rng = np.random.default_rng(seed)
    points, vertices, faces, _ = _triangle_soup_inputs(rng)
    if in_order:
        points = np.ascontiguousarray(points[spatial_order(points)])
    return rng, points, vertices, faces


@pytest.mark.parametrize("in_order", [False, True])
def test_a_guessed_face_changes_no_closest_point(in_order):
    # A guess only bounds the search: any face, right or wrong, gives the same answer
    # (the soup's triangles are never equally close to a point).
    rng, points, vertices, faces = _ordered_soup(8, in_order)
    plain = evaluate_kernels.closest_points_on_mesh(points, vertices, faces)
    for guess in (plain[0], rng.integers(0, faces.shape[0], size=points.shape[0])):
        guessed = evaluate_kernels.closest_points_on_mesh(points, vertices, faces, guess, in_order)
        for got, expected in zip(guessed, plain, strict=True):
            np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("in_order", [False, True])
def test_a_bound_finds_the_closest_face_only_where_it_is_nearer(in_order):
    # Against the unbounded search: where the closest face lies nearer than the bound it
    # is found as before; elsewhere the point gets face -1 and the squared bound.
    rng, points, vertices, faces = _ordered_soup(9, in_order)
    face, bary, distance2 = evaluate_kernels.closest_points_on_mesh(points, vertices, faces)
    within = np.sqrt(distance2) * rng.choice([0.5, 2.0], size=distance2.size)
    got = evaluate_kernels.closest_points_on_mesh(
        points, vertices, faces, in_order=in_order, within=within
    )
    nearer = within**2 > distance2
    assert 0 < np.count_nonzero(nearer) < nearer.size
    np.testing.assert_array_equal(got[0], np.where(nearer, face, -1))
    np.testing.assert_array_equal(got[1][nearer], bary[nearer])
    np.testing.assert_array_equal(got[2], np.where(nearer, distance2, within**2))


@pytest.mark.parametrize(
    "b",
    [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.5, 0.0, 0.0], [4.0, 0.0, 0.0]],
    ids=["b=a", "b=c", "collinear", "collinear outside"],
)
def test_barycentrics_on_degenerate_triangles_find_the_nearest_segment_point(b):
    # a = 0 and c = (2, 0, 0); b repeats a corner or lies on their line, inside or beyond.
    p = np.array([[0.5, 1.0, 0.0], [3.0, 0.0, 0.0], [-1.0, 0.5, 0.0], [1.5, -2.0, 1.0]])
    a, c = np.zeros((4, 3)), np.tile([2.0, 0.0, 0.0], (4, 1))
    b = np.tile(b, (4, 1))
    hull = np.array([min(b[0, 0], 0.0), max(b[0, 0], 2.0)])
    expected = np.c_[np.clip(p[:, 0], *hull), np.zeros((4, 2))]
    distance2, bary = np.zeros(4), np.zeros((4, 3))
    triangle_kernels.closest_point_rows(p, a, b, c, distance2, bary)
    assert np.all(np.isfinite(bary)) and np.all(bary >= 0.0)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c, expected)
    np.testing.assert_allclose(distance2, np.sum((p - expected) ** 2, axis=1))


def test_a_point_triangle_is_its_corner():
    p = np.array([[1.0, 2.0, 3.0]])
    a = np.array([[0.5, 0.5, 0.5]])
    distance2, bary = np.zeros(1), np.zeros((1, 3))
    triangle_kernels.closest_point_rows(p, a, a.copy(), a.copy(), distance2, bary)
    assert np.all(np.isfinite(bary)) and bary.sum() == 1.0
    np.testing.assert_allclose(distance2, [0.25 + 2.25 + 6.25])


def test_barycentrics_stay_exact_on_slivers():
    # Triangles whose height is 1e-7.5 to 1e-6 of their length (the differences of dot
    # products of Ericson's §5.1.5 miss by up to 1e-4 there) and points straight above a
    # point inside: the distance is the height above the plane.
    rng = np.random.default_rng(6)
    n = 300
    height = 10.0 ** rng.uniform(-7.5, -6, n)
    a = np.zeros((n, 3))
    b = np.tile([2.0, 0.0, 0.0], (n, 1))
    c = np.c_[rng.uniform(0.2, 1.8, n), 2.0 * height, np.zeros(n)]
    x = rng.uniform(0.3, 1.7, n)
    room = np.minimum(x / c[:, 0], (2 - x) / (2 - c[:, 0]))  # share of the height at x
    offset = rng.normal(size=n) * 0.1
    points = np.c_[x, height * rng.uniform(0.1, 1.9, n) * room, offset]
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    points, a, b, c = (np.ascontiguousarray(x @ rotation.T) for x in (points, a, b, c))
    distance2, bary = np.zeros(n), np.zeros((n, 3))
    triangle_kernels.closest_point_rows(points, a, b, c, distance2, bary)
    np.testing.assert_allclose(np.sqrt(distance2), np.abs(offset), rtol=0, atol=1e-14)


def test_jet_freedom_predicts_the_residual_of_pure_noise():
    # Rows standing for `weights` points each, with noise of variance sigma^2 / weight along
    # the normal of a tilted plane: the misfit over 1 - freedom averages to sigma^2, whatever
    # the support holds.
    rng = np.random.default_rng(5)
    n, sigma = 6_000, 0.001
    uv = rng.uniform(-1, 1, size=(n, 2))
    weights = rng.integers(1, 8, n).astype(float)
    normal = np.array([-0.3, 0.2, 1.0]) / np.sqrt(1.13)
    points = np.column_stack([uv, 0.3 * uv[:, 0] - 0.2 * uv[:, 1]])
    points += (sigma / np.sqrt(weights) * rng.normal(size=n))[:, None] * normal
    nb = knn(points, 48)
    rows = rng.choice(n, 2_000, replace=False)
    for radius in (0.06, 0.1, 0.16):
        fit = jet_kernels.fit_rows(
            points,
            weights,
            np.zeros((n, 3, 3)),
            nb.indices[rows],
            nb.distances[rows],
            np.full(rows.size, radius),
            8,
        )
        misfit, freedom = fit[5], fit[6]
        assert np.all((freedom > 0.0) & (freedom < 1.0))
        assert np.mean(misfit) < 0.95 * sigma**2  # the fit absorbs part of the noise ...
        assert np.mean(misfit / (1.0 - freedom)) == pytest.approx(sigma**2, rel=0.04)  # ... this


@pytest.mark.parametrize("seed", [0, 1])
def test_small_eigen_decompositions_match_lapack(seed):
    rng = np.random.default_rng(seed)
    roots = rng.normal(size=(500, 3, 3))
    matrices = roots @ roots.transpose(0, 2, 1)
    # Nearly flat and nearly linear neighbourhoods: two eigenvalues almost equal.
    matrices[:100] = np.diag([1e-9, 1.0, 1.0]) + 1e-12 * matrices[:100]
    matrices[100:200] = np.diag([1e-9, 2e-9, 1.0]) + 1e-13 * matrices[100:200]
    values, vectors = linalg.eigh_rows(matrices)
    expected = np.linalg.eigvalsh(matrices)
    scale = expected[:, -1:]
    np.testing.assert_allclose(values / scale, expected / scale, atol=1e-12)
    gram = vectors.transpose(0, 2, 1) @ vectors
    np.testing.assert_allclose(gram, np.tile(np.eye(3), (500, 1, 1)), atol=1e-12)
    residual = matrices @ vectors - vectors * values[:, None, :]
    assert np.abs(residual).max() < 1e-12 * scale.max()


def test_cholesky_solve_matches_numpy():
    rng = np.random.default_rng(2)
    root = rng.normal(size=(6, 6))
    a = root @ root.T + 1e-3 * np.eye(6)
    b = rng.normal(size=(6, 7))
    x = b.copy()
    assert linalg.cholesky_solve(a.copy(), x)
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
    assert not linalg.cholesky_solve(-a, b.copy())  # not positive definite
