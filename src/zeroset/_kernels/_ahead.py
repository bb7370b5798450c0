"""Kernels compiled ahead, in a second process, while the first run works.

A fresh install has no compiled kernels, and a run compiles each when it first calls it,
one after another; most of a first run is that. The kernels a run calls after its first
stages (the orientation's, the jets' blend, the closest points on the mesh behind a report's
distances, the simplification's collapses, and phase 2's moves) need none of their results,
so a second process started with the command compiles them into Numba's cache on another
core while the first stages compile theirs; the run then loads them (docs/benchmarks.md,
"First run"). Once they are cached, no process is started.

The simplification's kernels are the largest (about half a minute on one core); the
process compiles them first, and a run that reaches stage simplify before they are cached
waits for them (`await_simplify_kernels`) instead of compiling them a second time.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numba
import numpy as np

__all__ = [
    "await_simplify_kernels",
    "compile_late_kernels",
    "compile_phase2_kernels",
    "compile_simplify_kernels",
    "late_kernels_ahead",
    "late_kernels_cached",
]

#: The process `late_kernels_ahead` started, while its block runs.
_process: subprocess.Popen | None = None


def _late_kernels(optimize: bool = False, simplify: bool = False) -> list:
    """The dispatchers `compile_late_kernels` compiles, with `optimize` the pass of
    phase 2's moves (the largest that `compile_phase2_kernels` compiles), with `simplify`
    those of `_simplify_kernels`."""
    from .evaluate import _closest_face_rows
    from .jets import _blend_rows
    from .optimize import run_pass
    from .orientation import _component_extremes, _propagate_signs

    late = [_component_extremes, _propagate_signs, _blend_rows, _closest_face_rows]
    late += [run_pass] if optimize else []
    return late + _simplify_kernels() if simplify else late


def _simplify_kernels() -> list:
    """The dispatchers stage simplify calls first (`compile_simplify_kernels`)."""
    from .evaluate import _closest_face_rows, _median_split
    from .optimize import build_state, edges_of, make_scratch, run_within_pass
    from .triangles import triangle_rows

    return [
        build_state, make_scratch, edges_of, run_within_pass,
        _closest_face_rows, _median_split, triangle_rows,
    ]  # fmt: skip


def late_kernels_cached(optimize: bool = False, simplify: bool = False) -> bool:
    """Whether Numba's cache holds every late kernel already, with `optimize` phase 2's
    too, with `simplify` the simplification's (or nothing is compiled: Numba's JIT is
    off)."""
    if numba.config.DISABLE_JIT:
        return True
    return all(_cached(kernel) for kernel in _late_kernels(optimize, simplify))


def await_simplify_kernels() -> None:
    """Wait while the process of `late_kernels_ahead` runs and the simplification's
    kernels are not cached yet: it compiles them first, and compiling them here too
    would only double the work."""
    process = _process
    if process is None or numba.config.DISABLE_JIT:
        return
    kernels = _simplify_kernels()
    while process.poll() is None and not all(_cached(kernel) for kernel in kernels):
        time.sleep(0.05)


def _cached(kernel) -> bool:
    """Whether Numba's cache holds `kernel` compiled from its source as it is now: an index
    of a source edited or upgraded since is stale, as Numba's own test finds it."""
    try:
        fresh_index = kernel._cache._cache_file._load_index
    except AttributeError:  # another Numba's internals: any index will do
        return any(Path(kernel.stats.cache_path).glob(f"*.{kernel.__name__}-*.nbi"))
    return bool(fresh_index())


def compile_late_kernels() -> None:
    """Compile the late kernels for the signatures a run calls them with (each wrapper
    passes `_jit.inputs`), on the smallest inputs: a tetrahedron and two points near it."""
    from .evaluate import closest_points_on_mesh
    from .jets import COEFFICIENTS, blend_rows
    from .orientation import component_extremes, propagate_signs

    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    near = np.array([[0.2, 0.2, 0.9], [2.0, 0.1, 0.1]])
    closest_points_on_mesh(near, vertices, faces)
    one = np.zeros(4, dtype=np.int64)
    component_extremes(vertices, one, 1)
    propagate_signs(np.arange(4), np.array([-9999, 0, 0, 0]), vertices, np.ones(4))
    frames = np.broadcast_to(np.eye(3), (4, 3, 3))
    indices, distances = np.tile(np.arange(4), (2, 1)), np.ones((2, 4))
    blend_rows(near, indices, distances, vertices, frames, np.zeros((4, COEFFICIENTS)))


def compile_simplify_kernels() -> None:
    """Compile the simplification's kernels for the signatures `zeroset.simplify` calls
    them with, on a grid of 6 x 6 points over a saddle, where it collapses, swaps and
    splits."""
    from ..simplify import simplify_mesh
    from ..types import Mesh

    u, v = np.meshgrid(np.linspace(-1.0, 1.0, 6), np.linspace(-1.0, 1.0, 6), indexing="ij")
    vertices = np.column_stack([u.ravel(), v.ravel(), 0.2 * (u * v).ravel()])
    index = np.arange(36).reshape(6, 6)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    simplify_mesh(Mesh(vertices=vertices, faces=faces), 0.02)


def compile_phase2_kernels() -> None:
    """Compile phase 2's kernels for the signatures `zeroset.optimize` calls them with, by
    optimising the convex hull of 60 points on a unit sphere against 400 noisy ones."""
    from scipy.spatial import ConvexHull

    from ..optimization import optimize_mesh
    from ..types import Mesh

    rng = np.random.default_rng(0)
    points = rng.normal(size=(400, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    faces = ConvexHull(points[:60]).simplices
    a, b, c = (points[faces[:, corner]] for corner in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0.0
    faces[inward] = faces[inward][:, ::-1]
    used, faces = np.unique(faces, return_inverse=True)
    mesh = Mesh(vertices=points[used], faces=faces.reshape(-1, 3))
    optimize_mesh(mesh, points + rng.normal(scale=0.01, size=points.shape))


@contextmanager
def late_kernels_ahead(
    *, optimize: bool = False, simplify: bool = False
) -> Iterator[subprocess.Popen | None]:
    """Within the block, a quiet process compiles the late kernels into Numba's cache
    (with `simplify` `compile_simplify_kernels` first, then `compile_late_kernels`, then
    with `optimize` `compile_phase2_kernels`), unless they are cached already; it yields
    that process or None. A run that reaches a kernel first compiles it itself, as without
    it, but for the simplification's (`await_simplify_kernels`); a process still at work
    when the block ends is stopped (Numba renames each cache file into place once written,
    so none is left half written)."""
    global _process
    process = None
    if not late_kernels_cached(optimize, simplify):
        steps = ["compile_simplify_kernels()"] if simplify else []
        steps += ["compile_late_kernels()"]
        steps += ["compile_phase2_kernels()"] if optimize else []
        code = f"import {__name__} as ahead; " + "; ".join(f"ahead.{step}" for step in steps)
        process = subprocess.Popen(
            [sys.executable, "-c", code],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env={**os.environ, "NUMBA_NUM_THREADS": "1"},
        )
    outer = _process  # a block within another's: the outer process is still at work
    _process = outer if process is None else process
    try:
        yield process
    finally:
        _process = outer
        if process is not None:
            if process.poll() is None:
                process.kill()
            process.wait()
