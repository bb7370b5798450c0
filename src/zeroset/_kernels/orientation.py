"""Sign propagation over the orientation tree (Hoppe et al. 1992, §3.3)."""

import numpy as np

from ._jit import inputs, jit


@jit
def _component_extremes(centroids, component, n_components):
    # For each component and each direction +x, -x, +y, -y, +z, -z: the point farthest along it.
    best = np.empty((n_components, 6), dtype=np.int64)
    value = np.empty((n_components, 6))
    for c in range(n_components):  # a loop, not np.full: less to compile
        for d in range(6):
            best[c, d] = -1
            value[c, d] = -np.inf
    for i in range(centroids.shape[0]):
        c = component[i]
        for axis in range(3):
            for side in range(2):
                t = centroids[i, axis] if side == 0 else -centroids[i, axis]
                d = 2 * axis + side
                if t > value[c, d]:
                    value[c, d] = t
                    best[c, d] = i
    return best


@jit
def _propagate_signs(order, predecessors, normals, root_sign, signs):
    # Visit the tree breadth first; a child takes its parent's sign, negated when the
    # two unit normals point apart (n_parent . n_child < 0).
    n = normals.shape[0]
    for v in order:
        if v >= n:
            continue
        p = predecessors[v]
        if p < 0 or p >= n:
            signs[v] = root_sign[v]
            continue
        dot = (
            normals[p, 0] * normals[v, 0]
            + normals[p, 1] * normals[v, 1]
            + normals[p, 2] * normals[v, 2]
        )
        signs[v] = signs[p] if dot >= 0.0 else -signs[p]


def component_extremes(centroids, component, n_components):
    """Return (C, 6) int64: per component (`component` (N,) int64), the point of
    `centroids` (N, 3) farthest along +x, -x, +y, -y, +z, -z."""
    return _component_extremes(*inputs(centroids, component), int(n_components))


def propagate_signs(order, predecessors, normals, root_sign):
    """Return (N,) float64 signs +-1 spreading `root_sign` (N,) down a breadth-first tree
    (`order` and `predecessors` int64, a node's predecessor negative at a root)."""
    signs = np.ones(normals.shape[0])
    _propagate_signs(*inputs(order, predecessors, normals, root_sign), signs)
    return signs
