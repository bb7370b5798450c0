"""Few triangles within a tolerance of the dense mesh (`zeroset.simplify`)."""

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from zeroset import reconstruct, topology
from zeroset.errors import InputError
from zeroset.evaluate import closest_points_on_mesh, sample_surface
from zeroset.jets import fit_jets
from zeroset.simplify import choose_tolerance, simplify_mesh
from zeroset.synthetic import sample_cylinder
from zeroset.types import Mesh
from zeroset.within import triangle_grid, two_sided_errors


def height_field(seed: int, n: int = 40) -> Mesh:
    """A grid mesh of [0, 1]^2 lifted by a random smooth height (a few waves, 5 cm high),
    faces counter-clockwise seen from above."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    height = np.zeros_like(u)
    for _ in range(3):
        kx, ky = rng.uniform(0.5, 3.0, size=2)
        phase = rng.uniform(0.0, 2.0 * np.pi)
        height += rng.uniform(0.005, 0.02) * np.sin(2 * np.pi * (kx * u + ky * v) + phase)
    vertices = np.column_stack([u.ravel(), v.ravel(), height.ravel()])
    index = np.arange(n * n).reshape(n, n)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return Mesh(vertices=vertices, faces=faces)


def _distances(source: Mesh, target: Mesh, n: int, seed: int) -> np.ndarray:
    """Distances from `n` random points of `source` (and its vertices) to `target`."""
    points = np.concatenate([sample_surface(source, n, rng=seed)[0], source.vertices])
    return closest_points_on_mesh(points, target)[2]


def _boundary(mesh: Mesh) -> tuple[np.ndarray, float]:
    """The boundary vertices' positions (B, 3) and the boundary's length."""
    loops = topology.boundary_loops(mesh.faces)
    length = sum(
        np.linalg.norm(mesh.vertices[loop] - mesh.vertices[np.roll(loop, -1)], axis=1).sum()
        for loop in loops
    )
    return mesh.vertices[np.concatenate(loops)], float(length)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), tolerance=st.floats(5e-4, 1e-2))
@example(seed=2747, tolerance=0.0012461220602781858)  # needed 5 check rounds
def test_random_fields_stay_within_the_tolerance_keep_their_boundary_and_orientation(
    seed, tolerance
):
    dense = height_field(seed)
    simple, counts = simplify_mesh(dense, tolerance)
    assert counts["simplify_strays"] == 0
    assert simple.n_faces <= dense.n_faces
    if tolerance >= 3e-3:  # the dense chords sag up to 1e-3 (waves 2 cm high, 1/40 apart)
        assert simple.n_faces < dense.n_faces / 3
    # Both ways, over whole triangles: random points of each mesh to the other. The check
    # grid of the simplification is coarser than these points; 2 % of slack covers the
    # distance's growth between its points.
    assert _distances(simple, dense, 10_000, seed).max() <= 1.02 * tolerance
    assert _distances(dense, simple, 10_000, seed).max() <= 1.02 * tolerance
    assert topology.is_edge_manifold(simple.faces)
    assert topology.is_consistently_oriented(simple.faces)
    # The boundary: one loop, the dense mesh's own polyline, vertex for vertex (the tiles
    # weld pieces simplified apart on it).
    assert len(topology.boundary_loops(simple.faces)) == 1
    (ends, length), (dense_ends, dense_length) = _boundary(simple), _boundary(dense)
    on_square = np.minimum(np.abs(ends[:, :2]), np.abs(1.0 - ends[:, :2])).min(axis=1)
    assert on_square.max() < 1e-12
    assert length == pytest.approx(dense_length, rel=1e-12)
    np.testing.assert_array_equal(np.unique(ends, axis=0), np.unique(dense_ends, axis=0))
    # Every face faces up, as the dense mesh's do, and none is degenerate.
    corners = simple.vertices[simple.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(normals, axis=1)
    assert (normals[:, 2] > 0.0).all()
    assert area.min() > 1e-9


@pytest.mark.parametrize("seed", [0, 1])
def test_the_check_after_each_split_round_is_the_whole_check(seed):
    # The check rounds re-measure only around the split triangles; what they count at the
    # end is what a check of the whole final mesh finds.
    dense = height_field(seed, 60)
    tolerance = 5e-4
    simple, counts = simplify_mesh(dense, tolerance)
    assert counts["simplify_splits"] > 100
    errors = two_sided_errors(simple, dense)
    assert counts["simplify_strays"] == np.count_nonzero(errors > tolerance)
    assert np.count_nonzero(errors > tolerance) <= 0.001 * simple.n_faces


def test_a_vertex_of_no_face_is_no_sample():
    # A vertex far from every face, used by none: it is left out, not measured against.
    dense = height_field(0)
    lone = Mesh(vertices=np.vstack([dense.vertices, [[5.0, 5.0, 5.0]]]), faces=dense.faces)
    tolerance = 3e-3
    simple, counts = simplify_mesh(lone, tolerance)
    assert counts["simplify_strays"] == 0
    assert np.linalg.norm(simple.vertices - 5.0, axis=1).min() > 1.0
    assert two_sided_errors(simple, dense).max() <= tolerance
    assert simple.n_faces < dense.n_faces / 3


def test_the_error_is_unbiased_on_a_curved_surface():
    # A cylinder of radius 1 as a fine open tube: chords of a half-edge collapse lie inside
    # it; after `unbias` the mean signed distance to it is near zero, while the chords of
    # the same mesh without unbias lie inside by about a third of the sag.
    n_around, n_along = 256, 20
    angle = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    z = np.linspace(0.0, 1.0, n_along)
    a, zz = np.meshgrid(angle, z, indexing="ij")
    vertices = np.column_stack([np.cos(a).ravel(), np.sin(a).ravel(), zz.ravel()])
    index = np.arange(n_around * n_along).reshape(n_around, n_along)
    nxt = np.roll(index, -1, axis=0)
    p, q = index[:, :-1].ravel(), nxt[:, :-1].ravel()
    r, s = nxt[:, 1:].ravel(), index[:, 1:].ravel()
    faces = np.concatenate([np.column_stack([p, q, r]), np.column_stack([p, r, s])])
    dense = Mesh(vertices=vertices, faces=faces)
    tolerance = 2e-3
    simple, _ = simplify_mesh(dense, tolerance)
    assert simple.n_faces < dense.n_faces / 4
    points = sample_surface(simple, 50_000, rng=0)[0]
    signed = np.hypot(points[:, 0], points[:, 1]) - 1.0
    assert abs(signed.mean()) < 0.1 * tolerance
    assert np.abs(signed).max() <= 1.02 * tolerance + 1e-4  # the dense chords sag 1e-4


def test_zero_tolerance_keeps_the_dense_mesh_and_bad_ones_are_refused():
    dense = height_field(0)
    same, counts = simplify_mesh(dense, 0.0)
    assert same is dense and counts["simplify_collapses"] == 0
    for bad in (-1e-3, np.inf, np.nan):
        with pytest.raises(InputError, match="tolerance"):
            simplify_mesh(dense, bad)
    turned = Mesh(
        vertices=dense.vertices, faces=np.concatenate([dense.faces[:1, ::-1], dense.faces[1:]])
    )
    with pytest.raises(InputError, match="oriented"):
        simplify_mesh(turned, 1e-3)


def test_the_uncertainty_of_the_jets_matches_their_error():
    # Points on the plane z = 0 with noise sigma: the jets' heights at the true plane
    # spread about as the uncertainty says (sigma sqrt(6 / points per support)).
    rng = np.random.default_rng(3)
    sigma = 2e-3
    points = np.column_stack([rng.uniform(0, 1, (20_000, 2)), rng.normal(0, sigma, 20_000)])
    jets = fit_jets(points, noise=sigma, rho_delta=0.04)
    truth = np.column_stack([rng.uniform(0.2, 0.8, (5000, 2)), np.zeros(5000)])
    error = np.sqrt(np.mean(jets.evaluate(truth)[0] ** 2))
    assert 0.5 < jets.uncertainty(sigma) / error < 2.0
    tolerance, note = choose_tolerance(jets, sigma, 0.0, None)
    assert tolerance == pytest.approx(2.0 * jets.uncertainty(sigma))
    assert "uncertainty" in note
    # Never finer than the dense mesh's chords; a given tolerance is used as it is.
    chord = 3.0 * tolerance
    assert choose_tolerance(jets, sigma, chord, None)[0] == chord
    assert "chord" in choose_tolerance(jets, sigma, chord, None)[1]
    assert choose_tolerance(jets, sigma, chord, 1e-3) == (1e-3, "tolerance = 0.001: given")


@pytest.fixture(scope="module")
def cylinder():
    sample = sample_cylinder(20_000, radius=0.15, length=0.6, noise=1e-3, rng=0)
    return sample, reconstruct(sample.points)


def test_a_pipe_comes_out_in_few_triangles_as_accurate_as_the_dense_mesh(cylinder):
    sample, result = cylinder
    simple, dense = result.mesh, result.dense_mesh
    assert simple.n_faces * 10 <= dense.n_faces
    assert result.stats["dense_faces"] == dense.n_faces
    assert 0.0 < result.stats["tolerance"] < 1e-3
    assert "tolerance = " in result.stats["tolerance_note"]

    def error(mesh):
        points = sample_surface(mesh, 40_000, rng=1)[0]
        radial = np.hypot(points[:, 0], points[:, 1]) - 0.15
        return np.abs(radial).mean(), radial.mean()

    (mean_simple, bias_simple), (mean_dense, _) = error(simple), error(dense)
    assert mean_simple <= 1.1 * mean_dense
    assert abs(bias_simple) <= 5e-5  # 0.05 mm
    assert len(topology.boundary_loops(simple.faces)) == 2
    assert topology.is_edge_manifold(simple.faces)
    assert topology.is_consistently_oriented(simple.faces)
    # Long along the axis, short around it: the edges' mean |cos| with the axis.
    corners = simple.vertices[simple.faces]
    edges = (corners[:, [1, 2, 0]] - corners).reshape(-1, 3)
    along = np.abs(edges[:, 2]) / np.linalg.norm(edges, axis=1)
    longest = np.linalg.norm(edges, axis=1) > np.median(np.linalg.norm(edges, axis=1))
    assert along[longest].mean() > 0.8


def test_zero_tolerance_gives_the_dense_mesh(cylinder):
    sample, result = cylinder
    dense = reconstruct(sample.points, tolerance=0.0)
    assert dense.mesh.n_faces == result.dense_mesh.n_faces
    assert "simplify_collapses" in dense.stats and dense.stats["simplify_collapses"] == 0


def test_phase_2_holds_a_given_tolerance_of_the_dense_mesh():
    points = sample_cylinder(2000, radius=0.15, length=0.6, rng=0).points
    tolerance = 2e-3
    result = reconstruct(points, optimize=True, tolerance=tolerance)
    assert result.stats["phase2_tolerance"] == tolerance
    # Within the tolerance everywhere but the triangles counted (and warned) as strays.
    strays = np.count_nonzero(two_sided_errors(result.mesh, result.dense_mesh) > tolerance)
    assert strays == result.stats["phase2_tolerance_strays"] <= 0.001 * result.mesh.n_faces
    assert result.mesh.n_faces < result.dense_mesh.n_faces
    with pytest.raises(InputError, match="tolerance"):
        reconstruct(points, tolerance=-1.0)


def test_the_check_grid_covers_a_long_thin_triangle_with_few_points():
    mesh = Mesh(
        vertices=np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.1, 0.02, 0.0]]),
        faces=np.array([[0, 1, 2]]),
    )
    points, face = triangle_grid(mesh, 0.005)
    assert (face == 0).all() and points.shape[0] < 300  # a barycentric grid: 1,891
    u = np.random.default_rng(0).random((20_000, 2))
    u = u[u.sum(axis=1) <= 1.0]
    inside = mesh.vertices[0] + u @ (mesh.vertices[1:] - mesh.vertices[0])
    gap = np.min(np.linalg.norm(inside[:, None] - points[None], axis=2), axis=1)
    assert gap.max() <= 0.005
    corners = mesh.vertices
    assert np.min(np.linalg.norm(points[:, None] - corners[None], axis=2), axis=0).max() < 1e-12
    # Every point lies on the triangle: barycentric coordinates in [0, 1].
    solved = np.linalg.lstsq((corners[1:] - corners[0])[:, :2].T, (points - corners[0])[:, :2].T)
    s, t = solved[0]
    assert (s >= -1e-12).all() and (t >= -1e-12).all() and (s + t <= 1 + 1e-12).all()
