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
    "vertices, faces, message",
    [
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], "must be a (K, 3) array; got shape (3, 2)"),
        ([[0, 0, 0], [1, 0, 0, 1]], [], "vertices must be a (K, 3) array"),
        ([["a", "b", "c"]], [], "vertices must hold numbers"),
        (np.eye(3), [[0, 1, 3]], "faces must index its 3 vertices; got indices 0 to 3"),
        (np.eye(3), [[0, -1, 2]], "faces must index its 3 vertices"),
        (np.eye(3), [[0, 1.5, 2]], "faces must hold whole numbers"),
    ],
)
def test_a_mesh_rejects_what_is_no_mesh_at_once(vertices, faces, message):
    with pytest.raises(InputError) as error:
        Mesh(vertices=vertices, faces=faces)
    assert message in str(error.value)
