"""pytest-benchmark suite: the whole pipeline and its four main stages.

``addopts`` carries ``--benchmark-disable``, so a plain ``pytest benchmarks`` runs every
benchmark once as a test. Time them with::

    pytest benchmarks --benchmark-enable

Each benchmark runs one warm-up round first, so Numba JIT compilation is excluded. The
stage inputs come from one `reconstruct()` of the same cloud, so each stage sees the data
it sees inside the pipeline. For the whole-pipeline wall time per stage at 1e6 points, see
``benchmarks/bench_phase1.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import zeroset
from zeroset import topology
from zeroset.contour import marching_cubes
from zeroset.distance import signed_distance
from zeroset.neighbours import knn
from zeroset.normals import tangent_planes
from zeroset.orientation import orient_normals
from zeroset.synthetic import sample_cylinder

SIZES = [
    pytest.param(1_000, id="1000"),
    pytest.param(10_000, id="10000"),
    pytest.param(100_000, id="100000", marks=pytest.mark.slow),
]
ROUNDS = 5


def _cloud(n: int) -> np.ndarray:
    return sample_cylinder(n, radius=0.25, length=1.0, noise=0.002, rng=0).points


@pytest.fixture(scope="module", params=SIZES)
def case(request):
    """A reconstruction of an n-point noisy open pipe and the inputs of each stage."""
    points = _cloud(request.param)
    result = zeroset.reconstruct(points)
    return {
        "n": request.param,
        "cloud": points,
        "result": result,
        # The pipeline hands its k_max-neighbourhoods to both stages; do the same.
        "neighbours": knn(result.points, result.config.k_max),
    }


def _run(benchmark, target, *args, rounds: int = ROUNDS, **kwargs):
    return benchmark.pedantic(
        target, args=args, kwargs=kwargs, rounds=rounds, iterations=1, warmup_rounds=1
    )


def test_pipeline(benchmark, case):
    result = _run(benchmark, zeroset.reconstruct, case["cloud"], rounds=3)
    assert result.mesh.n_faces > 0
    # An open pipe: one surface, two rims.
    assert result.stats["boundary_loops"] == 2
    assert result.stats["mesh_components"] == 1
    assert result.stats["phase1_points"] <= case["n"]


def test_tangent_planes(benchmark, case):
    result = case["result"]
    config = result.config
    planes = _run(
        benchmark,
        tangent_planes,
        result.points,
        radius=result.parameters.rho_delta,
        k_min=config.k_min,
        k_max=config.k_max,
        neighbours=case["neighbours"],
    )
    assert planes.normals.shape == result.points.shape
    np.testing.assert_allclose(np.linalg.norm(planes.normals, axis=1), 1.0, atol=1e-9)
    # On a pipe of radius 0.25 along z, the normals are nearly horizontal.
    assert np.median(np.abs(planes.normals[:, 2])) < 0.1


def test_orient_normals(benchmark, case):
    result = case["result"]
    planes = result.planes
    orientation = _run(
        benchmark,
        orient_normals,
        planes.centroids,
        planes.normals,
        k=result.config.orient_k,
        max_edge=2.0 * result.parameters.rho_delta,
        neighbours=case["neighbours"],
    )
    np.testing.assert_allclose(np.abs(orientation.normals), np.abs(planes.normals))
    assert orientation.n_components == 1
    # Consistent orientation on a pipe: all outward or all inward.
    axial = (planes.centroids + result.offset)[:, :2]
    radial = axial / np.linalg.norm(axial, axis=1)[:, None]
    agree = np.einsum("ij,ij->i", orientation.normals[:, :2], radial) > 0.0
    assert max(agree.mean(), 1.0 - agree.mean()) > 0.98


def test_signed_distance(benchmark, case):
    result = case["result"]
    parameters = result.parameters
    field = _run(
        benchmark,
        signed_distance,
        result.points,
        result.planes.centroids,
        result.orientation.normals,
        cube_size=parameters.cube_size,
        radius=parameters.rho_delta,
    )
    defined = ~np.isnan(field.values)
    assert defined.sum() > 0
    # Away from the wall, the sign of f tells inside from outside of the pipe (radius 0.25),
    # with one sign convention for the whole field.
    positions = field.positions[defined] + result.offset
    truth = np.linalg.norm(positions[:, :2], axis=1) - 0.25
    clear = np.abs(truth) > 0.5 * parameters.cube_size
    assert clear.sum() > 0
    agree = np.mean(np.sign(field.values[defined][clear]) == np.sign(truth[clear]))
    assert max(agree, 1.0 - agree) > 0.95


def test_marching_cubes(benchmark, case):
    result = case["result"]
    mesh = _run(benchmark, marching_cubes, result.field)
    assert mesh.n_faces > 0
    assert mesh.faces.min() >= 0 and mesh.faces.max() < mesh.n_vertices
    # The vertices lie on the pipe's wall, within a cube of radius 0.25 from the z axis.
    radius = np.linalg.norm((mesh.vertices + result.offset)[:, :2], axis=1)
    assert np.abs(radius - 0.25).max() < result.parameters.cube_size
    assert len(topology.boundary_loops(mesh.faces)) >= 2
