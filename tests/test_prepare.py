import numpy as np
import pytest

from zeroset import InputError
from zeroset.neighbours import knn
from zeroset.prepare import average_in_cells, crop, drop_outliers, random_sample, voxel_sample


def test_random_sample_is_seeded_and_sized():
    a, b, c = (random_sample(1000, 0.3, rng=s) for s in (1, 1, 2))
    assert a.size == 300 and np.unique(a).size == 300
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    with pytest.raises(InputError, match="sample fraction"):
        random_sample(10, 0.0)


def test_voxel_sample_keeps_one_point_per_voxel(rng):
    points = rng.uniform(0, 1, (5000, 3))
    kept = voxel_sample(points, 0.25)
    cells = np.floor((points[kept] - points.min(axis=0)) / 0.25).astype(int)
    assert kept.size == np.unique(cells, axis=0).shape[0] == 64


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


def test_average_in_cells_gives_one_mean_per_cell(rng):
    points = rng.uniform(0, 1, (5000, 3))
    labels = rng.normal(size=(5000, 3))
    means, label_means = average_in_cells(points, 0.5, labels)
    assert means.shape == label_means.shape == (8, 3)
    cells = np.floor(means / 0.5)
    assert np.unique(cells, axis=0).shape[0] == 8  # each mean stays in its own cell
    in_first = np.all(np.floor(points / 0.5) == cells[0], axis=1)
    np.testing.assert_allclose(means[0], points[in_first].mean(axis=0))
    np.testing.assert_allclose(label_means[0], labels[in_first].mean(axis=0))
