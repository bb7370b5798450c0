import numpy as np
import pytest

from zeroset import InputError
from zeroset.parameters import estimate_parameters


def _noisy_plane(n, sigma, rng, scale=1.0):
    return scale * np.c_[rng.uniform(0, 1, (n, 2)), sigma * rng.normal(size=n)]


def test_noise_estimate_recovers_sigma(rng):
    params = estimate_parameters(_noisy_plane(40_000, 0.002, rng), rng=0)
    assert params.noise == pytest.approx(0.002, rel=0.2)
    assert params.rho_delta == pytest.approx(params.spacing + 3 * params.noise)
    assert params.cube_size == pytest.approx(1.5 * params.rho_delta)


def test_parameters_scale_with_the_data(rng):
    points = _noisy_plane(5_000, 0.003, rng)
    a = estimate_parameters(points, rng=0)
    b = estimate_parameters(points * 1000.0, rng=0)
    assert b.rho_delta == pytest.approx(1000 * a.rho_delta, rel=1e-9)
    assert b.averaging_cell == pytest.approx(1000 * a.averaging_cell, rel=1e-9)


def test_denser_clouds_get_smaller_spacing(rng):
    sparse = estimate_parameters(_noisy_plane(2_000, 0.0, rng), rng=0)
    dense = estimate_parameters(_noisy_plane(200_000, 0.002, rng), rng=0)
    assert dense.spacing < sparse.spacing / 5
    assert dense.averaging_cell < sparse.averaging_cell


def test_scan_lines_set_the_spacing_from_the_sparse_direction():
    # Lines 1 mm apart along x, 20 mm apart along y: the k nearest lie on one line.
    x, y = np.meshgrid(np.arange(0, 1, 0.001), np.arange(0, 1, 0.02))
    points = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    params = estimate_parameters(points, rng=0)
    assert params.spacing >= 0.02
    assert params.rho_delta < 0.05


def test_given_values_win_and_are_noted(rng):
    params = estimate_parameters(
        _noisy_plane(1_000, 0.0, rng), rho_delta=0.5, cube_size=0.25, averaging_cell=0.1
    )
    assert (params.rho_delta, params.cube_size, params.averaging_cell) == (0.5, 0.25, 0.1)
    assert sum("given" in note for note in params.notes) == 3


@pytest.mark.parametrize(
    "option, value, message",
    [
        ("quantile", 1.5, "quantile must lie in"),
        ("rho_delta", -1.0, "rho_delta must be a positive number"),
        ("cube_size", 0.0, "cube_size must be a positive number"),
        ("averaging_cell", -1.0, "averaging_cell must be >= 0"),
        ("k", 0, "k must be a positive integer"),
    ],
)
def test_bad_options_are_rejected(option, value, message, rng):
    with pytest.raises(InputError, match=message):
        estimate_parameters(_noisy_plane(100, 0.0, rng), **{option: value})


def _rippled_plane(n, sigma, rng, wavelength=0.05, amplitude=0.002):
    xy = rng.uniform(0, 1, (n, 2))
    k = 2 * np.pi / wavelength
    height = amplitude * np.sin(k * xy[:, 0]) * np.sin(k * xy[:, 1])
    return np.column_stack([xy, height]) + sigma * rng.normal(size=(n, 3))


def test_quadric_noise_holds_neither_curvature_nor_resolved_detail(rng):
    # Ripples 2 mm high, 5 cm long, under 0.5 mm of noise: a plane's residuals take them
    # for noise, a quadric's do not.
    params = estimate_parameters(_rippled_plane(40_000, 0.0005, rng), rng=0)
    assert params.noise > 1.3 * 0.0005
    assert params.quadric_noise == pytest.approx(0.0005, rel=0.1)
    sphere = np.random.default_rng(1).normal(size=(20_000, 3))
    sphere = 0.1 * sphere / np.linalg.norm(sphere, axis=1, keepdims=True)
    sphere += 0.001 * rng.normal(size=sphere.shape)
    assert estimate_parameters(sphere, rng=0).quadric_noise == pytest.approx(0.001, rel=0.06)
