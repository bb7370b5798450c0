import numpy as np
import pytest

from zeroset.errors import InputError
from zeroset.types import Mesh


def test_a_mesh_coerces_lists_as_trimesh_does():
    mesh = Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2.0]])
    assert mesh.n_vertices == 3 and mesh.n_faces == 1
    assert mesh.vertices.dtype == np.float64 and mesh.faces.dtype == np.int64
    assert mesh.vertices.flags.c_contiguous and not mesh.faces.flags.writeable
    assert Mesh(vertices=[], faces=[]).faces.shape == (0, 3)


def test_a_mesh_keeps_the_callers_arrays_theirs():
    vertices = np.eye(3)
    mesh = Mesh(vertices=vertices, faces=np.array([[0, 1, 2]], dtype=np.uint32))
    vertices[0, 0] = 5.0
    assert mesh.vertices[0, 0] == 1.0 and vertices.flags.writeable


@pytest.mark.parametrize(
    "vertices, faces, error, message",
    [
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], InputError, r"shape \(N, 3\); got \(3, 2\)"),
        ([[0, 0, 0], [1, 0, 0, 1]], [], TypeError, "real numbers"),
        ([[0, 0, np.nan]], [], InputError, "non-finite"),
        (np.eye(3), [[0, 1], [2]], InputError, r"faces must have shape \(F, 3\)"),
        (np.eye(3), [[0, 1, 3]], InputError, r"outside \[0, 3\); got range \[0, 3\]"),
        (np.eye(3), [[0, -1, 2]], InputError, r"outside \[0, 3\)"),
        (np.eye(3), [[0, 1.5, 2]], InputError, "whole numbers"),
    ],
)
def test_a_mesh_rejects_what_is_no_mesh_at_once(vertices, faces, error, message):
    with pytest.raises(error, match=message):
        Mesh(vertices=vertices, faces=faces)
