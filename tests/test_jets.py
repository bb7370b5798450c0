"""The blended-jets surface: no curvature bias, vertices on the surface, error that falls
with density. Distances are signed against the analytic surfaces, positive outside."""

import numpy as np
import pytest

from zeroset import reconstruct, topology
from zeroset.config import ReconstructionConfig
from zeroset.evaluate import sample_surface
from zeroset.jets import evaluate_jets, fit_jets, orient_jets
from zeroset.refine import project_to_surface, sagging_edges, split_edges
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_torus
from zeroset.thresholds import MAX_LEVELS
from zeroset.types import Mesh

#: Largest |signed mean distance| allowed, as a fraction of the radius.
BIAS = 5e-4


def _signed(shape, radius, x):
    if shape == "sphere":
        return np.linalg.norm(x, axis=1) - radius
    if shape == "pipe":
        return np.hypot(x[:, 0], x[:, 1]) - radius
    tube = np.hypot(np.hypot(x[:, 0], x[:, 1]) - 2.5 * radius, x[:, 2])
    return tube - radius


def _sample(shape, radius, n, noise):
    if shape == "sphere":
        return sample_sphere(n, radius=radius, noise=noise, rng=4)
    if shape == "pipe":
        return sample_cylinder(n, radius=radius, length=4 * radius, noise=noise, rng=4)
    return sample_torus(n, major=2.5 * radius, minor=radius, noise=noise, rng=4)


def _surface_errors(shape, radius, mesh):
    """Area-weighted signed mean and mean absolute distance of `mesh` to the true surface
    (for the open pipe, away from its ends)."""
    x, _ = sample_surface(mesh, 100_000, rng=0)
    if shape == "pipe":
        x = x[np.abs(x[:, 2] - 2.0 * radius) < 1.5 * radius]  # the pipe spans z in [0, 4 r]
    d = _signed(shape, radius, x)
    return d.mean(), np.abs(d).mean()


CASES = [
    # shape, radius (m), points, noise (m)
    ("sphere", 1.0, 4_000, 0.0),
    ("sphere", 0.37, 20_000, 0.001),
    ("pipe", 0.25, 20_000, 0.002),
    ("pipe", 0.1, 10_000, 0.0),
    ("torus", 0.13, 20_000, 0.002),
]


@pytest.mark.parametrize("shape, radius, n, noise", CASES)
@pytest.mark.slow
def test_surface_has_no_curvature_bias(shape, radius, n, noise):
    result = reconstruct(_sample(shape, radius, n, noise).points)
    bias, _ = _surface_errors(shape, radius, result.mesh)
    assert abs(bias) <= BIAS * radius, f"{shape}: bias {bias:.3g} m"
    assert topology.is_edge_manifold(result.mesh.faces)
    assert topology.is_consistently_oriented(result.mesh.faces)


@pytest.mark.sweep
@pytest.mark.parametrize("shape", ["sphere", "pipe", "torus"])
@pytest.mark.parametrize("radius", [0.1, 0.25, 0.6])
@pytest.mark.parametrize("n, noise", [(5_000, 0.0), (20_000, 0.001), (80_000, 0.002)])
def test_surface_has_no_curvature_bias_sweep(shape, radius, n, noise):
    result = reconstruct(_sample(shape, radius, n, noise).points)
    bias, _ = _surface_errors(shape, radius, result.mesh)
    assert abs(bias) <= BIAS * radius, f"{shape}: bias {bias:.3g} m"


def test_planes_shrink_and_jets_do_not():
    points = sample_sphere(4_000, radius=1.0, rng=4).points
    planes, _ = _surface_errors("sphere", 1.0, reconstruct(points, surface="planes").mesh)
    jets, _ = _surface_errors("sphere", 1.0, reconstruct(points).mesh)
    assert planes < -2e-3  # Hoppe's centroid planes: about r^2 / 4R inside
    assert abs(jets) < abs(planes) / 10


@pytest.mark.slow
def test_error_falls_as_points_are_added():
    errors, supports = [], []
    for n in (5_000, 20_000, 80_000):
        result = reconstruct(_sample("pipe", 0.25, n, 0.002).points)
        errors.append(_surface_errors("pipe", 0.25, result.mesh)[1])
        supports.append(result.surface.support / result.parameters.rho_delta)
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.001  # half the noise of one point
    assert supports[0] <= supports[1] <= supports[2]  # more points per support


def _ripple(x, y):
    """Ripples 2 mm high and 5 cm long."""
    k = 2 * np.pi / 0.05
    return 0.002 * np.sin(k * x) * np.sin(k * y)


def _rippled_points():
    """40,000 points on a metre square of `_ripple`, noise 0.5 mm per axis."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 1, (40_000, 2))
    return np.column_stack([xy, _ripple(*xy.T)]) + 0.0005 * rng.normal(size=(40_000, 3))


@pytest.mark.slow
def test_supports_shrink_to_follow_detail(monkeypatch):
    # The ripples are about 3.6 rho+delta long: the curvature rule alone picks a support
    # that flattens them. Detail measured at two pilot supports shrinks it, and the
    # surface follows the ripples to a third of the error.
    points = _rippled_points()

    def error(result):
        x, _ = sample_surface(result.mesh, 100_000, rng=0)
        x = x[np.all((x[:, :2] > 0.1) & (x[:, :2] < 0.9), axis=1)]
        return np.abs(x[:, 2] - _ripple(x[:, 0], x[:, 1])).mean()

    followed = reconstruct(points)
    monkeypatch.setattr("zeroset.jets.DETAIL_MARGIN", np.inf)
    flattened = reconstruct(points)
    assert followed.surface.support < 0.6 * flattened.surface.support
    assert error(followed) < 0.4 * error(flattened)
    assert error(followed) < 0.0003  # below the noise of one point
    assert "shrunk to follow detail" in followed.surface.notes[0]


def test_vertices_lie_on_the_blended_surface():
    result = reconstruct(_sample("torus", 0.13, 20_000, 0.002).points)
    values, _ = evaluate_jets(result.surface, result.dense_mesh.vertices - result.offset)
    assert np.abs(values).max() < 1e-3 * 0.13
    assert result.stats["refine_levels"] >= 1


def test_projection_turns_no_triangle_over():
    # A coarse mesh around a sphere whose vertices the projection pulls a long way in.
    sample = sample_sphere(3_000, radius=1.0, rng=0)
    result = reconstruct(sample.points, refine_levels=0)
    jets = result.surface
    vertices = result.mesh.vertices - result.offset
    before = Mesh(vertices=vertices * 1.08, faces=result.mesh.faces)  # all outside
    after, held = project_to_surface(before, jets)
    normals = topology.face_area_vectors(after.vertices, after.faces)
    reference = topology.face_area_vectors(before.vertices, before.faces)
    assert np.all(np.einsum("ij,ij->i", normals, reference) > 0.0)
    moved = np.linalg.norm(after.vertices - before.vertices, axis=1)
    assert np.median(moved) > 0.05 and held < before.n_vertices // 100


def test_split_edges_keeps_boundaries_orientation_and_euler_characteristic(rng):
    result = reconstruct(_sample("pipe", 0.25, 5_000, 0.002).points, refine_levels=0)
    mesh = result.mesh
    edges = topology.undirected_edges(mesh.faces)[0]
    for marked in (np.ones(edges.shape[0], bool), rng.random(edges.shape[0]) < 0.3):
        split = split_edges(mesh, marked)
        assert split.n_vertices == mesh.n_vertices + marked.sum()
        assert topology.is_edge_manifold(split.faces)
        assert topology.is_consistently_oriented(split.faces)
        assert topology.euler_characteristic(split) == topology.euler_characteristic(mesh)
        assert len(topology.boundary_loops(split.faces)) == 2
        area = np.linalg.norm(topology.face_area_vectors(split.vertices, split.faces), axis=1)
        whole = np.linalg.norm(topology.face_area_vectors(mesh.vertices, mesh.faces), axis=1)
        assert area.sum() == pytest.approx(whole.sum(), rel=1e-12)  # same flat pieces
        assert area.min() > 0.0


def test_refined_edges_sag_no_further_than_the_tolerance():
    # An exact pipe (r = 0.25): the contoured edges sag L^2 / 8r, more than refine allows,
    # and after refine none does.
    sample = _sample("pipe", 0.25, 5_000, 0.0)
    coarse = reconstruct(sample.points, refine_levels=0)
    noise = coarse.parameters.noise
    unrefined = Mesh(
        vertices=coarse.dense_mesh.vertices - coarse.offset, faces=coarse.dense_mesh.faces
    )
    assert sagging_edges(unrefined, coarse.surface, noise=noise).mean() > 0.5
    refined = reconstruct(sample.points)
    assert 1 <= refined.stats["refine_levels"] <= MAX_LEVELS
    final = Mesh(
        vertices=refined.dense_mesh.vertices - refined.offset, faces=refined.dense_mesh.faces
    )
    assert not sagging_edges(final, refined.surface, noise=noise).any()


def test_given_support_is_used_and_reported():
    points = sample_sphere(4_000, radius=1.0, noise=0.01, rng=1).points
    result = reconstruct(points, fit_support=0.3)
    assert np.all(result.surface.radii <= 0.3 + 1e-12)
    assert "given" in result.surface.notes[0]
    assert result.stats["fit_support"] == pytest.approx(np.median(result.surface.radii))


def test_fit_jets_recovers_a_known_quadric(rng):
    # z = 0.5 (x^2 - y^2) sampled densely: the jet at the origin has curvatures +-1.
    xy = rng.uniform(-0.3, 0.3, size=(20_000, 2))
    points = np.column_stack([xy, 0.5 * (xy[:, 0] ** 2 - xy[:, 1] ** 2)])
    jets = fit_jets(points, noise=1e-4, rho_delta=0.02, support=0.06)
    up = np.tile([0.0, 0.0, 1.0], (jets.centres.shape[0], 1))
    jets = orient_jets(jets, jets.centres, up)
    assert np.all(jets.frames[:, 2, 2] > 0.9)
    centre = np.argmin(np.linalg.norm(jets.centres, axis=1))
    assert jets.curvature[centre] == pytest.approx(1.0, rel=0.05)
    probe = np.array([[0.05, 0.05, 0.01], [0.0, 0.0, -0.01]])
    values, _ = evaluate_jets(jets, probe)
    truth = probe[:, 2] - 0.5 * (probe[:, 0] ** 2 - probe[:, 1] ** 2)
    np.testing.assert_allclose(values, truth, atol=2e-4)


@pytest.mark.parametrize(
    "option, message",
    [
        ({"surface": "spheres"}, "surface must be one of"),
        ({"fit_support": 0.0}, "fit_support must be positive"),
        ({"refine_levels": -1}, "refine_levels must lie in 0..4"),
    ],
)
def test_bad_surface_options_are_refused(option, message):
    with pytest.raises(ValueError, match=message):
        ReconstructionConfig(**option)
