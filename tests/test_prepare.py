import numpy as np
import pytest

from zeroset import InputError
from zeroset.neighbours import knn
from zeroset.prepare import (
    cell_labels,
    crop,
    drop_outliers,
    group_means,
    group_viewpoints,
    random_sample,
    reduce_chunks,
    voxel_sample,
)


def test_random_sample_is_seeded_and_sized():
    a, b, c = (random_sample(10_000, 0.3, seed=s) for s in (1, 1, 2))
    assert abs(a.size - 3000) < 4 * np.sqrt(10_000 * 0.3 * 0.7)
    assert np.all(np.diff(a) > 0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    with pytest.raises(InputError, match="sample fraction"):
        random_sample(10, 0.0)


def test_voxel_sample_keeps_the_point_nearest_each_voxel_centroid(rng):
    points = rng.uniform(0, 1, (5000, 3))
    kept = voxel_sample(points, 0.25)
    cells = np.floor(points / 0.25).astype(int)
    assert kept.size == np.unique(cells, axis=0).shape[0] == 64
    for cell in np.unique(cells, axis=0)[:8]:
        members = np.flatnonzero((cells == cell).all(axis=1))
        spread = np.linalg.norm(points[members] - points[members].mean(axis=0), axis=1)
        assert members[np.argmin(spread)] in kept


def _chunked(columns, size):
    """A chunk factory cutting `columns` into pieces of `size` rows."""
    n = len(columns["points"])
    return lambda: ({k: v[i : i + size] for k, v in columns.items()} for i in range(0, n, size))


@pytest.mark.parametrize("size", [1, 97, 1000, 10_000])
def test_reduce_chunks_does_not_depend_on_the_chunk_size(rng, size):
    columns = {
        "points": rng.uniform(-1, 1, (3000, 3)) + [1e6, 2e6, 0],
        "intensity": rng.uniform(0, 100, 3000),
    }
    options = dict(crop_box=(1e6 - 0.8, 2e6 - 1, -1, 1e6 + 1, 2e6 + 0.9, 1), sample=0.6,
                   voxel_size=0.2, seed=5)  # fmt: skip
    whole = reduce_chunks(lambda: [columns], **options)
    parts = reduce_chunks(_chunked(columns, size), **options)
    np.testing.assert_array_equal(parts.rows, whole.rows)
    for name in columns:
        np.testing.assert_array_equal(parts.columns[name], columns[name][whole.rows])
    assert parts.counts == whole.counts
    counts = whole.counts
    assert counts["input_points"] == 3000
    assert counts["input_points"] - counts["cropped"] - counts["sampled_out"] - counts[
        "voxel_merged"
    ] == whole.rows.size


def test_reduce_chunks_steps_compose(rng):
    points = rng.uniform(0, 1, (4000, 3))
    box = (0.1, 0.1, 0.1, 0.9, 0.9, 0.9)
    cropped = reduce_chunks(lambda: [{"points": points}], crop_box=box)
    np.testing.assert_array_equal(cropped.rows, np.flatnonzero(crop(points, box[:3], box[3:])))
    sampled = reduce_chunks(lambda: [{"points": points}], crop_box=box, sample=0.5, seed=1)
    drawn = np.random.default_rng(1).random(4000) < 0.5
    np.testing.assert_array_equal(sampled.rows, np.intersect1d(cropped.rows, np.flatnonzero(drawn)))
    both = reduce_chunks(lambda: [{"points": points}], crop_box=box, sample=0.5, voxel_size=0.3,
                         seed=1)  # fmt: skip
    subset = sampled.rows[voxel_sample(points[sampled.rows], 0.3)]
    np.testing.assert_array_equal(both.rows, subset)


def test_reduce_chunks_errors():
    nan = np.array([[0.0, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(InputError, match="first at row 3"):
        reduce_chunks(_chunked({"points": np.vstack([np.zeros((2, 3)), nan])}, 2))
    with pytest.raises(InputError, match="too small for the cloud's extent"):
        voxel_sample(np.array([[0.0, 0, 0], [1e3, 0, 0]]), 1e-3)
    with pytest.raises(InputError, match="voxel_size"):
        voxel_sample(np.zeros((2, 3)), 0.0)


def test_crop_keeps_the_box(rng):
    points = rng.uniform(-1, 1, (1000, 3))
    mask = crop(points, (0, 0, 0), (1, 1, 1))
    assert np.all(points[mask] >= 0) and np.all(np.any(points[~mask] < 0, axis=1))
    with pytest.raises(InputError, match="lower <= upper"):
        crop(points, (1, 0, 0), (0, 1, 1))


def test_isolated_points_are_outliers(rng):
    cluster = rng.normal(0, 0.05, (500, 3))
    lonely = np.array([[5.0, 5.0, 5.0], [-5.0, 0.0, 0.0]])
    points = np.concatenate([cluster, lonely])
    keep = drop_outliers(knn(points, 8), radius=0.1, min_neighbours=4)
    assert not keep[-2:].any()
    assert keep[:-2].mean() > 0.95


def test_group_means_of_cells_gives_one_mean_and_spread_per_cell(rng):
    points = rng.uniform(0, 1, (5000, 3))
    labels = rng.normal(size=(5000, 3))
    means, counts, spread, label_means = group_means(points, cell_labels(points, 0.5), labels)
    assert means.shape == label_means.shape == (8, 3)
    assert counts.sum() == 5000
    cells = np.floor(means / 0.5)
    assert np.unique(cells, axis=0).shape[0] == 8  # each mean stays in its own cell
    in_first = np.all(np.floor(points / 0.5) == cells[0], axis=1)
    np.testing.assert_allclose(means[0], points[in_first].mean(axis=0))
    np.testing.assert_allclose(label_means[0], labels[in_first].mean(axis=0))
    assert counts[0] == np.count_nonzero(in_first)
    np.testing.assert_allclose(spread[0], np.cov(points[in_first].T, bias=True), atol=1e-12)


def test_a_cell_seen_by_two_sensors_faces_both_at_their_range(rng):
    # A wall in z = 0 seen from (-2, 0, 1) and (2, 0, 1): the mean of the two positions,
    # (0, 0, 1), lies 1 from the wall where the sensors were 2.2 away. The mean direction
    # is straight up, and the sensor stands at the range they measured.
    points = np.c_[rng.uniform(-0.1, 0.1, (200, 2)), np.zeros(200)]
    sensors = np.where(np.arange(200)[:, None] % 2 == 0, [-2.0, 0.0, 1.0], [2.0, 0.0, 1.0])
    sensors[:10] = np.nan  # unknown sensors take no part
    (sensor,) = group_viewpoints(points, sensors, np.zeros(200, dtype=np.int64))
    centre = points[10:].mean(axis=0)
    ranges = np.linalg.norm(sensors[10:] - points[10:], axis=1)
    towards = sensor - centre
    assert np.linalg.norm(towards) == pytest.approx(ranges.mean(), rel=1e-12)
    assert towards[2] / np.linalg.norm(towards) > 0.995  # straight up, within 6 degrees


def test_a_cell_seen_from_both_sides_has_no_sensor(rng):
    # Both faces of a sheet thinner than a cell: one group seen from above and from below,
    # another seen from above only, a third whose sensor is unknown.
    points = rng.uniform(-0.1, 0.1, (300, 3)) * [1.0, 1.0, 0.01]
    labels = np.repeat([0, 1, 2], 100)
    sensors = np.tile([0.0, 0.0, 2.0], (300, 1))
    sensors[50:100, 2] = -2.0
    sensors[200:] = np.nan
    grouped = group_viewpoints(points, sensors, labels)
    assert np.isnan(grouped[[0, 2]]).all()
    assert grouped[1, 2] > 1.9 and np.isfinite(grouped[1]).all()


@pytest.mark.parametrize("scale", [1.0, 1e17])  # 1e17: cells span more than 2**62 keys
def test_cell_labels_order_cells_as_their_indices(rng, scale):
    points = rng.normal(size=(3000, 3)) * scale
    size = 0.3 * scale
    means, *_ = group_means(points, cell_labels(points, size))
    cells, label = np.unique(np.floor(points / size), axis=0, return_inverse=True)
    expected = np.stack([np.bincount(label.reshape(-1), weights=points[:, d]) for d in range(3)], 1)
    expected /= np.bincount(label.reshape(-1))[:, None]
    np.testing.assert_allclose(means, expected, rtol=1e-12)
    assert np.all(np.floor(means / size) == cells)
