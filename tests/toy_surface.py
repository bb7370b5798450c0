"""A third local surface, for the tests only: the implicit moving least squares (IMLS) blend
of the oriented tangent planes (Kolluri 2008), smooth where the nearest plane jumps.

It is one file; the tests register it with one line (``SURFACES["imls"] = ...``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from zeroset.surface import Surface

#: Planes blended at a position.
K = 8


@dataclass(frozen=True, eq=False)
class PlaneBlend(Surface):
    """``f(x) = sum_i w_i (x - o_i) . n_i / sum_i w_i`` over the K nearest planes, with
    Gaussian weights ``w_i = exp(-|x - o_i|^2 / h^2)``."""

    reach = 2.0
    smooth = True

    centres: np.ndarray
    normals: np.ndarray
    width: float

    @classmethod
    def fit(cls, points, owner, planes, parameters, config) -> PlaneBlend:
        return cls(planes.centroids, planes.normals, parameters.rho_delta)

    def oriented(self, centroids, normals, *, tree=None) -> PlaneBlend:
        tree = cKDTree(centroids) if tree is None else tree
        return PlaneBlend(self.centres, normals[tree.query(self.centres)[1]], self.width)

    def evaluate(self, positions):
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        k = min(K, self.centres.shape[0])
        distances, nearest = self.tree.query(positions, k=k)
        offsets = distances - distances[:, :1]  # weights relative to the nearest: no underflow
        weights = np.exp(-(offsets * (distances + distances[:, :1])) / self.width**2)
        weights /= weights.sum(axis=1, keepdims=True)
        normals = self.normals[nearest]
        heights = np.einsum("mkd,mkd->mk", positions[:, None, :] - self.centres[nearest], normals)
        gradients = np.einsum("mk,mkd->md", weights, normals)
        gradients /= np.linalg.norm(gradients, axis=1, keepdims=True)
        return np.einsum("mk,mk->m", weights, heights), gradients

    def curvature_at(self, positions):
        return np.zeros(len(positions))

    def select(self, rows) -> PlaneBlend:
        return PlaneBlend(self.centres[rows], self.normals[rows], self.width)

    @classmethod
    def concatenate(cls, parts) -> PlaneBlend:
        return cls(
            np.concatenate([p.centres for p in parts]),
            np.concatenate([p.normals for p in parts]),
            parts[0].width,
        )

    def describe(self) -> dict:
        return {"surface_function": f"IMLS blend of {self.centres.shape[0]:,} planes"}
