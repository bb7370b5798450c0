"""The local-surface interface: every kind registered works through it alone, and a new
kind is one file and one registry line. Distances are signed against the unit sphere."""

import numpy as np
import pytest

from tests.meshes import assert_same_mesh
from zeroset import InputError, reconstruct, topology
from zeroset.evaluate import sample_surface
from zeroset.normals import NearestPlanes
from zeroset.surface import SURFACES, Surface, surface_kind
from zeroset.synthetic import sample_sphere


@pytest.fixture(scope="module")
def sphere():
    return sample_sphere(6000, noise=0.005, rng=2)


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_every_registered_kind_is_a_surface(name):
    kind = surface_kind(name)
    assert issubclass(kind, Surface) and not kind.__abstractmethods__


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_a_surface_is_the_same_whatever_the_order_of_its_fits(sphere, name):
    result = reconstruct(sphere.points, surface=name)
    surface = result.surface
    n = surface.centres.shape[0]
    halves = np.random.default_rng(0).permutation(n) < n // 2
    shuffled = type(surface).concatenate([surface.select(~halves), surface.select(halves)])
    assert shuffled.centres.shape == (n, 3)
    positions = result.mesh.vertices[::7] - result.offset
    values, gradients = surface.evaluate(positions)
    again, turned = shuffled.evaluate(positions)
    np.testing.assert_allclose(again, values, atol=1e-12)
    np.testing.assert_allclose(turned, gradients, atol=1e-12)
    # its zero set is the sphere's: outward gradients, values within the noise
    outward = np.einsum("ij,ij->i", gradients, positions + result.offset)
    assert np.mean(outward > 0) > 0.99
    assert np.abs(values).mean() < 0.005


def test_the_nearest_plane_gives_the_distance_to_it():
    centres = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    normals = np.array([[0.0, 0, 1], [1.0, 0, 0]])
    planes = NearestPlanes(centres, normals)
    values, gradients = planes.evaluate([[1.0, 2, 0.5], [9.0, 1, 3], [4.0, 0, -2]])
    np.testing.assert_allclose(values, [0.5, -1.0, -2.0])
    np.testing.assert_allclose(gradients, normals[[0, 1, 0]])
    turned = planes.oriented(centres[::-1], -normals[::-1])
    np.testing.assert_allclose(turned.evaluate([[1.0, 2, 0.5]])[0], [-0.5])


def test_a_third_surface_is_one_file_and_one_registry_line(sphere, monkeypatch):
    monkeypatch.setitem(SURFACES, "imls", "tests.toy_surface:PlaneBlend")
    result = reconstruct(sphere.points, surface="imls")
    assert result.stats["surface_function"].startswith("IMLS blend of")
    assert "refine" in result.timings  # the toy is smooth: vertices are moved onto it
    mesh = result.mesh
    assert len(topology.boundary_loops(mesh.faces)) == 0
    assert topology.euler_characteristic(mesh) == 2
    signed = _signed_to_sphere(mesh)
    # The planes pass through their neighbourhoods' centroids, inside a convex surface; a
    # blend of them lies inside too, and no further in than the nearest plane.
    hoppe = _signed_to_sphere(reconstruct(sphere.points, surface="planes").mesh)
    assert hoppe.mean() < signed.mean() < 0.0
    assert np.abs(signed).max() < 0.02
    values, _ = result.surface.evaluate(mesh.vertices - result.offset)
    assert np.abs(values).max() < 1e-3  # refined onto its own zero set


def _signed_to_sphere(mesh):
    x, _ = sample_surface(mesh, 50_000, rng=0)
    return np.linalg.norm(x, axis=1) - 1.0


def test_an_unknown_surface_names_the_known_ones(sphere):
    with pytest.raises(InputError, match=r"surface must be one of \('jets', 'planes'\)"):
        reconstruct(sphere.points, surface="rimls")


@pytest.mark.slow
def test_a_third_surface_runs_in_tiles_as_it_runs_whole(sphere, monkeypatch):
    # The tiles take the surface's kind from the registry and its halo from its reach, as
    # for the jets; workers in this process see the registry line the test adds.
    distributed = pytest.importorskip("distributed")
    from zeroset.tiles import reconstruct_tiled

    monkeypatch.setitem(SURFACES, "imls", "tests.toy_surface:PlaneBlend")
    whole = reconstruct(sphere.points, surface="imls").mesh
    with distributed.Client(
        processes=False, n_workers=2, threads_per_worker=1, dashboard_address=":0"
    ) as client:
        tiled = reconstruct_tiled(sphere.points, tiles=(2, 2, 2), client=client, surface="imls")
    assert tiled.stats["tiles"] == 8
    assert tiled.stats["surface_function"].startswith("IMLS blend of")
    assert_same_mesh(tiled.mesh, whole)
