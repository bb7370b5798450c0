"""Meshes compared in tests: the same vertices and faces, in any order."""

import numpy as np
from scipy.spatial import cKDTree


def face_rows(faces):
    """(F, 3) each face from its least vertex, orientation kept, the rows sorted: the same
    for two lists of the same faces in any order."""
    turn = np.argmin(faces, axis=1)
    faces = np.take_along_axis(faces, (turn[:, None] + np.arange(3)) % 3, axis=1)
    return faces[np.lexsort(faces.T[::-1])]


def assert_same_mesh(mesh, expected, atol=1e-9):
    """The same vertices (to `atol`, one to one) and the same faces, oriented alike, in any
    order: the tiles refine apart and list their parts' vertices and faces tile by tile."""
    assert mesh.n_vertices == expected.n_vertices and mesh.n_faces == expected.n_faces
    distance, match = cKDTree(expected.vertices).query(mesh.vertices)
    assert distance.max(initial=0.0) <= atol
    assert np.unique(match).size == mesh.n_vertices  # one to one
    np.testing.assert_array_equal(face_rows(match[mesh.faces]), face_rows(expected.faces))
