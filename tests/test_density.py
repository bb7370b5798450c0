"""Per-point radii, gap bridges and the range noise model on planes with known sampling."""

import numpy as np
import pytest

from zeroset.density import (
    gap_bridges,
    local_spacing,
    point_radii,
    range_noise,
    sector_distances,
)
from zeroset.distance import signed_distance
from zeroset.neighbours import knn
from zeroset.thresholds import BRIDGE_REACH, RADIUS_CAP


def _grid(xs, ys, rng, noise=0.0):
    x, y = np.meshgrid(xs, ys)
    points = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    return points + rng.normal(0.0, noise, points.shape) if noise else points


def _sectors(points):
    neighbours = knn(points, 32)
    return sector_distances(points, neighbours.indices, neighbours.distances)[0]


def _banded(rng):
    """A plane sampled every 5 mm in bands 10 mm wide, with 40 mm gaps between the bands."""
    band = np.arange(0.0, 0.015, 0.005)
    ys = np.concatenate([start + band for start in np.arange(0.0, 0.5, 0.05)])
    return _grid(np.arange(0.0, 0.5, 0.005), ys, rng, noise=0.0005)


def _two_densities(rng):
    """A plane sampled every 10 mm where x < 0.3 and every 25 mm beyond: the points, their
    neighbours and sector distances, and which lie away from the edges and the seam."""
    dense = _grid(np.arange(0.0, 0.3, 0.01), np.arange(0.0, 0.6, 0.01), rng)
    sparse = _grid(np.arange(0.3, 0.6, 0.025), np.arange(0.0, 0.6, 0.025), rng)
    points = np.concatenate([dense, sparse])
    neighbours = knn(points, 32)
    sectors, _ = sector_distances(points, neighbours.indices, neighbours.distances)
    inner = (np.abs(points[:, 1] - 0.3) < 0.2) & (np.abs(points[:, 0] - 0.3) > 0.1)
    return points, neighbours, sectors, inner


def test_radius_grows_where_the_sampling_is_sparse(rng):
    points, neighbours, sectors, inner = _two_densities(rng)
    radii = point_radii(local_spacing(sectors, neighbours), rho_delta=0.02, margin=0.001)
    assert np.all(radii[inner & (points[:, 0] < 0.3)] == 0.02)
    sparse_radii = radii[inner & (points[:, 0] > 0.3)]
    # Six of eight directions reach a neighbour at the diagonal, 25 sqrt(2) mm.
    np.testing.assert_allclose(np.median(sparse_radii), 0.025 * np.sqrt(2) + 0.001, rtol=0.05)
    assert radii.max() <= RADIUS_CAP * 0.02


def test_local_spacing_is_not_held_to_the_clouds_radius(rng):
    # The dense half's spacing is its own (10 mm to the diagonal neighbour), below the
    # cloud's rho+delta that floors its radius; the sparse half's is 25 mm's.
    points, neighbours, sectors, inner = _two_densities(rng)
    spacing = local_spacing(sectors, neighbours)
    np.testing.assert_allclose(spacing[inner & (points[:, 0] < 0.3)], 0.01 * np.sqrt(2))
    np.testing.assert_allclose(spacing[inner & (points[:, 0] > 0.3)], 0.025 * np.sqrt(2))
    radii = point_radii(spacing, rho_delta=0.02, margin=0.001)
    np.testing.assert_array_equal(radii[inner], np.maximum(spacing[inner] + 0.001, 0.02))


def test_gaps_between_bands_are_bridged_and_the_field_is_defined_across_them(rng):
    points = _banded(rng)
    rho_delta = 0.015
    bridges = gap_bridges(points, _sectors(points), rho_delta=rho_delta)
    up = np.tile([0.0, 0.0, 1.0], (points.shape[0], 1))
    along = gap_bridges(points, _sectors(points), rho_delta=rho_delta, normals=up)
    np.testing.assert_array_equal(along, bridges)  # every chord lies in the plane
    assert not np.any((points[:, 1] + 0.005) % 0.05 > 0.018)  # no data point in a gap
    middle = np.abs(bridges[:, 1] % 0.05 - 0.03) < 0.005
    inside = (bridges[:, 0] > 0.05) & (bridges[:, 0] < 0.45) & (bridges[:, 1] < 0.45)
    # Every gap, all along its length, holds bridge points near its middle line.
    for start in np.arange(0.0, 0.45, 0.05):
        row = bridges[middle & inside & (np.abs(bridges[:, 1] - start - 0.03) < 0.005)]
        assert np.all(np.diff(np.sort(np.r_[0.05, row[:, 0], 0.45])) < 0.02)
    normals = np.tile([0.0, 0.0, 1.0], (points.shape[0], 1))
    without = signed_distance(points, points, normals, cube_size=0.01, radius=rho_delta)
    with_bridges = signed_distance(
        points,
        points,
        normals,
        cube_size=0.01,
        radius=rho_delta,
        bridges=bridges,
        bridge_reach=BRIDGE_REACH * rho_delta,
    )
    for field, expect_defined in ((without, False), (with_bridges, True)):
        x, y, z = field.positions.T
        # 20 mm from the data on either side, farther than rho_delta.
        inside = (x > 0.1) & (x < 0.4) & (y > 0.0) & (y < 0.45)
        gap_middle = inside & (np.abs(y % 0.05 - 0.03) < 0.001)
        on_plane = gap_middle & (np.abs(z) < 0.011)
        assert on_plane.sum() > 50
        assert np.all(np.isfinite(field.values[on_plane]) == expect_defined)


def test_no_bridge_joins_a_floor_to_a_wall_across_a_gap(rng):
    # A floor (z = 0) that stops 40 mm short of a wall (x = 0.34): the chords from the
    # floor's edge to the wall are shorter than a bridge's limit, but run across the wall.
    floor = _grid(np.arange(0.0, 0.3, 0.005), np.arange(0.0, 0.5, 0.005), rng, noise=0.0005)
    z, y = np.meshgrid(np.arange(-0.1, 0.2, 0.005), np.arange(0.0, 0.5, 0.005))
    wall = np.c_[np.full(z.size, 0.34), y.ravel(), z.ravel()]
    points = np.concatenate([floor, wall])
    normals = np.concatenate(
        [
            np.tile([0.0, 0.0, 1.0], (floor.shape[0], 1)),
            np.tile([1.0, 0.0, 0.0], (wall.shape[0], 1)),
        ]
    )
    corner = (points[:, 0] > 0.3) & (points[:, 0] < 0.335)  # between the floor and the wall
    blind = gap_bridges(points, _sectors(points), rho_delta=0.015)
    assert np.count_nonzero((blind[:, 0] > 0.3) & (blind[:, 0] < 0.335)) > 50
    assert not corner.any()
    bridges = gap_bridges(points, _sectors(points), rho_delta=0.015, normals=normals)
    assert not np.any((bridges[:, 0] > 0.3) & (bridges[:, 0] < 0.335))


def test_round_holes_and_open_ends_get_no_bridge_across(rng):
    points = _grid(np.arange(0.0, 1.0, 0.01), np.arange(0.0, 1.0, 0.01), rng, noise=0.001)
    centre = np.array([0.5, 0.5, 0.0])
    points = points[np.linalg.norm(points - centre, axis=1) > 0.05]
    rho_delta = 0.025  # the hole is 4 rho_delta wide
    bridges = gap_bridges(points, _sectors(points), rho_delta=rho_delta)
    assert np.all(np.linalg.norm(bridges - centre, axis=1) > 0.02)
    # Beyond the sampled square there is nothing to bridge to.
    assert np.all((bridges[:, :2] > -0.005) & (bridges[:, :2] < 0.995))


def test_range_noise_recovers_noise_growing_with_range(rng):
    points = _grid(np.arange(-2.0, 2.0, 0.01), np.arange(-2.0, 2.0, 0.01), rng)
    viewpoint = np.array([0.0, 0.0, 0.5])
    ranges = np.linalg.norm(points - viewpoint, axis=1)
    truth = 0.001 + 0.002 * ranges
    noisy = points + np.c_[np.zeros((points.shape[0], 2)), rng.normal(0.0, truth)]
    sigma, (intercept, slope) = range_noise(noisy, knn(noisy, 16), viewpoint, noise=0.003)
    # Plane fits over 16 points absorb a little of the noise.
    np.testing.assert_allclose(slope, 0.002, rtol=0.25)
    np.testing.assert_allclose(np.median(sigma / truth), 1.0, atol=0.2)
    assert sigma[ranges > 1.8].mean() > 2.0 * sigma[ranges < 0.8].mean()


def test_range_noise_has_no_negative_slope(rng):
    points = _grid(np.arange(-1.0, 1.0, 0.01), np.arange(-1.0, 1.0, 0.01), rng, noise=0.002)
    sigma, (_, slope) = range_noise(points, knn(points, 16), np.array([0.0, 0.0, 0.3]), noise=0.002)
    assert slope >= 0.0
    assert np.all(sigma >= 0.001)


@pytest.mark.parametrize("tilt, bridged", [(45.0, True), (70.0, False)])
def test_a_chord_is_bridged_within_60_degrees_of_both_tangent_planes(tilt, bridged, rng):
    # The bands lie in z = 0 and their gaps run along x; normals tilted towards y by `tilt`
    # make a chord square across a gap leave both tangent planes by `tilt` degrees: noisy
    # normals of one surface up to `ALONG`, beyond it no longer one surface. (Chords up to
    # `CROSSING`'s 32 degrees off square lean less into the planes: at 70 a tenth stay.)
    points = _banded(rng)
    blind = gap_bridges(points, _sectors(points), rho_delta=0.015)
    angle = np.radians(tilt)
    normals = np.tile([0.0, np.sin(angle), np.cos(angle)], (points.shape[0], 1))
    seen = gap_bridges(points, _sectors(points), rho_delta=0.015, normals=normals)
    assert blind.shape[0] > 10_000
    if bridged:
        np.testing.assert_array_equal(seen, blind)
    else:
        assert seen.shape[0] < 0.2 * blind.shape[0]
