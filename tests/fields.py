"""Distance fields on full grids, for the contouring tests."""

import numpy as np

from zeroset import _lattice
from zeroset.types import DistanceField


def grid_field(values, cube=1.0):
    """A field on the full (a, b, c) grid of `values`, in key order."""
    ijk = np.argwhere(np.ones(values.shape, bool))
    order = np.argsort(_lattice.encode(ijk))
    return DistanceField(
        vertices_ijk=ijk[order],
        values=values.reshape(-1)[order],
        origin=np.zeros(3),
        cube_size=cube,
    )


def tilted_plane(shape, height, *, lift=0.0, n=4000, seed=0):
    """The field of the plane z = height + 0.1 x on a grid of `shape` (a, b, c), and `n`
    (n, 3) data points on z = height + lift + 0.1 x with the plane's unit normals (n, 3)."""
    x, _, z = np.meshgrid(*(np.arange(float(k)) for k in shape), indexing="ij")
    field = grid_field(z - height - 0.1 * x)
    rng = np.random.default_rng(seed)
    points = np.c_[rng.uniform(0, shape[0] - 1, (n, 2)), np.zeros(n)]
    points[:, 2] = height + lift + 0.1 * points[:, 0]
    normal = np.array([-0.1, 0.0, 1.0]) / np.hypot(0.1, 1.0)
    return field, points, np.tile(normal, (n, 1))
