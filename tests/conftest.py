"""Shared fixtures: seeded synthetic clouds and their reconstructions (built once per session)."""

import os
from contextlib import ExitStack

import numpy as np
import pytest
from hypothesis import settings

from zeroset import reconstruct
from zeroset._kernels._ahead import late_kernels_ahead
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_torus, two_spheres
from zeroset.types import Mesh

PIPE_NOISE = 0.002

# The same examples on every run, here and in CI: a failure reproduces, and a fresh
# install's test run cannot fail by the draw. HYPOTHESIS_PROFILE=explore draws new ones.
settings.register_profile("default", derandomize=True, max_examples=40, deadline=None)
settings.register_profile("explore", max_examples=200, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

_SESSION = ExitStack()


def pytest_sessionstart(session):
    # On a fresh Numba cache, the simplification's, the later stages' and phase 2's kernels
    # compile in a second process while the first tests compile the first stages' (as a
    # first run does).
    _SESSION.enter_context(late_kernels_ahead(optimize=True, simplify=True))


def pytest_sessionfinish(session, exitstatus):
    _SESSION.close()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def pipe():
    """Noisy open pipe (radius 0.25 m, length 1 m, sigma 2 mm) and its reconstruction."""
    sample = sample_cylinder(30_000, noise=PIPE_NOISE, rng=1)
    return sample, reconstruct(sample.points)


@pytest.fixture(scope="session")
def sphere():
    sample = sample_sphere(6_000, noise=0.005, rng=2)
    return sample, reconstruct(sample.points)


@pytest.fixture(scope="session")
def torus():
    sample = sample_torus(12_000, noise=0.005, rng=3)
    return sample, reconstruct(sample.points)


@pytest.fixture(scope="session")
def spheres():
    sample = two_spheres(9_000, noise=0.005, rng=4)
    return sample, reconstruct(sample.points)


@pytest.fixture
def tetra_mesh():
    """A closed, outward-facing tetrahedron."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return Mesh(vertices=vertices, faces=faces)
