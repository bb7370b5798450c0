import numpy as np
import pytest

from zeroset import topology
from zeroset._unique import distinct
from zeroset.repair import fill_small_holes, remove_small_components, split_nonmanifold_vertices
from zeroset.types import Mesh


def _grid_mesh(n):
    """An n x n square of quads split into triangles, facing +z."""
    steps = np.arange(n + 1)
    x, y = np.meshgrid(steps, steps, indexing="ij")
    vertices = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)].astype(float)
    idx = lambda i, j: i * (n + 1) + j  # noqa: E731
    faces = []
    for i in range(n):
        for j in range(n):
            faces += [
                (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)),
                (idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)),
            ]
    return Mesh(vertices=vertices, faces=np.array(faces))


def test_tetrahedron_counts(tetra_mesh):
    assert topology.euler_characteristic(tetra_mesh) == 2
    assert topology.boundary_loops(tetra_mesh.faces) == []
    assert topology.is_edge_manifold(tetra_mesh.faces)
    assert topology.is_consistently_oriented(tetra_mesh.faces)
    assert topology.signed_volume(tetra_mesh) == np.float64(1 / 6)


def test_flipped_face_breaks_consistent_orientation(tetra_mesh):
    faces = tetra_mesh.faces.copy()
    faces[0] = faces[0, ::-1]
    assert not topology.is_consistently_oriented(faces)


def test_square_has_one_boundary_loop_in_face_order():
    mesh = _grid_mesh(3)
    (loop,) = topology.boundary_loops(mesh.faces)
    assert len(loop) == 12
    # Counter-clockwise seen from +z, as the faces are.
    x, y = mesh.vertices[loop, 0], mesh.vertices[loop, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0


def test_small_hole_is_filled_and_large_one_kept():
    mesh = _grid_mesh(6)
    centre = mesh.vertices[mesh.faces].mean(axis=1)
    small = (np.abs(centre[:, 0] - 1.5) < 0.5) & (np.abs(centre[:, 1] - 1.5) < 0.5)
    mesh = Mesh(vertices=mesh.vertices, faces=mesh.faces[~small])
    assert len(topology.boundary_loops(mesh.faces)) == 2
    filled, count, widest = fill_small_holes(mesh, max_edges=4)
    assert count == 1
    assert widest == pytest.approx(np.sqrt(2.0))  # the diagonal of the one missing square
    assert len(topology.boundary_loops(filled.faces)) == 1
    assert topology.is_edge_manifold(filled.faces) and topology.is_consistently_oriented(
        filled.faces
    )
    kept, count, widest = fill_small_holes(mesh, max_edges=3)
    assert count == 0 and kept.n_faces == mesh.n_faces and widest == 0.0
    # Four edges, but wider than the data resolve: open.
    kept, count, widest = fill_small_holes(mesh, max_edges=4, max_width=1.4)
    assert count == 0 and kept.n_faces == mesh.n_faces and widest == 0.0


def test_bowtie_vertex_is_split():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    mesh = Mesh(vertices=vertices, faces=np.array([[0, 1, 2], [0, 3, 4]]))
    split, added = split_nonmanifold_vertices(mesh)
    assert added == 1 and split.n_vertices == 6
    assert len(topology.boundary_loops(split.faces)) == 2
    np.testing.assert_array_equal(split.vertices[split.faces], mesh.vertices[mesh.faces])


def test_small_components_are_removed():
    big = _grid_mesh(5)
    speck = Mesh(
        vertices=np.array([[9, 9, 0], [10, 9, 0], [9, 10, 0]], float), faces=np.array([[0, 1, 2]])
    )
    both = Mesh(
        vertices=np.concatenate([big.vertices, speck.vertices]),
        faces=np.concatenate([big.faces, speck.faces + big.n_vertices]),
    )
    cleaned, dropped = remove_small_components(both, min_faces=5)
    assert dropped == 1
    assert cleaned.n_faces == big.n_faces and cleaned.n_vertices == big.n_vertices
    assert topology.face_components(cleaned.faces, cleaned.n_vertices)[0] == 1


def test_boundary_edges_run_as_in_their_faces(tetra_mesh):
    assert topology.boundary_edges(tetra_mesh.faces).shape == (0, 2)
    open_faces = tetra_mesh.faces[:3]  # the tetrahedron without its last face
    edges = topology.boundary_edges(open_faces)
    assert sorted(map(tuple, edges.tolist())) == sorted([(2, 1), (1, 3), (3, 2)])


@pytest.mark.parametrize("shape", [(0,), (1,), (40,), (7, 3)])
def test_distinct_values_are_the_sorted_set(shape):
    values = np.random.default_rng(3).integers(-5, 5, size=shape)
    expected = sorted(set(values.reshape(-1).tolist()))
    assert distinct(values).tolist() == expected
