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
    assert b.phase1_fraction == pytest.approx(a.phase1_fraction)


def test_denser_clouds_get_smaller_spacing_and_phase1_sampling(rng):
    sparse = estimate_parameters(_noisy_plane(2_000, 0.0, rng), rng=0)
    dense = estimate_parameters(_noisy_plane(200_000, 0.002, rng), rng=0)
    assert dense.spacing < sparse.spacing / 5
    assert sparse.phase1_fraction == 1.0 and dense.phase1_fraction < 0.5


def test_given_values_win_and_are_noted(rng):
    params = estimate_parameters(
        _noisy_plane(1_000, 0.0, rng), rho_delta=0.5, cube_size=0.25, phase1_fraction=0.7
    )
    assert (params.rho_delta, params.cube_size, params.phase1_fraction) == (0.5, 0.25, 0.7)
    assert sum("given" in note for note in params.notes) == 3


@pytest.mark.parametrize(
    "option, value, message",
    [
        ("quantile", 1.5, "quantile must lie in"),
        ("rho_delta", -1.0, "rho_delta must be a positive number"),
        ("cube_size", 0.0, "cube_size must be a positive number"),
        ("phase1_fraction", 2.0, "phase1_fraction must lie in"),
        ("k", 0, "k must be a positive integer"),
    ],
)
def test_bad_options_are_rejected(option, value, message, rng):
    with pytest.raises(InputError, match=message):
        estimate_parameters(_noisy_plane(100, 0.0, rng), **{option: value})
