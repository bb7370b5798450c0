"""Rims where the data stop: the edge test, the cut, and open pipes end to end."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from zeroset import ReconstructionConfig, reconstruct, topology
from zeroset.evaluate import mesh_quality, points_to_mesh_distance
from zeroset.repair import fill_small_holes, split_nonmanifold_vertices
from zeroset.rim import cut_mesh, data_edge, empty_balls
from zeroset.synthetic import sample_cylinder, scan_pipe
from zeroset.thresholds import EDGE_OFFSET, SNAP, WIDTH_EDGES
from zeroset.types import Mesh


def _grid(n: int, step: float = 1.0, jitter: float = 0.0, rng=0):
    """Points (n*n, 3) on a square grid in z = 0, each moved by up to `jitter` steps."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    points = np.stack([i.ravel(), j.ravel(), np.zeros(i.size)], axis=1) * step
    shake = np.random.default_rng(rng).uniform(-jitter, jitter, (points.shape[0], 2)) * step
    points[:, :2] += shake
    return points


def _plane_mesh(n: int) -> Mesh:
    """A triangulated unit square in z = 0, n x n quads, normals +z."""
    vertices = _grid(n + 1, 1.0 / n)
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    quads = np.stack([k, k + n + 1, k + n + 2, k + 1], axis=1)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return Mesh(vertices=vertices, faces=faces)


def _angles(mesh: Mesh) -> np.ndarray:
    """Smallest angle (F,) of each face, degrees."""
    corners = mesh.vertices[mesh.faces]
    smallest = np.full(mesh.n_faces, 180.0)
    for i in range(3):
        u = corners[:, (i + 1) % 3] - corners[:, i]
        v = corners[:, (i + 2) % 3] - corners[:, i]
        cosine = np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
        smallest = np.minimum(smallest, np.degrees(np.arccos(np.clip(cosine, -1, 1))))
    return smallest


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.6, 0.8), (0.28, 0.96)])
def test_cut_follows_the_zero_line_of_a_linear_function(direction):
    mesh = _plane_mesh(24)
    d = np.array([*direction, 0.0])
    value = mesh.vertices @ d - 0.5 * d.sum() - 0.013  # a line across the square
    cut, edges = cut_mesh(mesh, value)
    assert edges > 0
    assert topology.is_edge_manifold(cut.faces) and topology.is_consistently_oriented(cut.faces)
    areas = topology.face_area_vectors(cut.vertices, cut.faces)
    assert np.all(areas[:, 2] > 0.0)  # every face keeps its side up
    # The new boundary lies on the line; the square's own sides stay where they were.
    border = np.unique(topology.boundary_edges(cut.faces))
    on_line = np.abs(cut.vertices[border] @ d - 0.5 * d.sum() - 0.013) <= 1e-12
    on_square = np.any(
        np.isclose(cut.vertices[border, :2], 0.0) | np.isclose(cut.vertices[border, :2], 1.0),
        axis=1,
    )
    assert np.all(on_line | on_square) and on_line.sum() >= 20
    assert np.all(cut.vertices @ d - 0.5 * d.sum() - 0.013 <= 1e-12)
    # Moving vertices onto the line changes the area by less than the moved triangles'.
    kept = 0.5 * np.linalg.norm(areas, axis=1).sum()
    expected = np.mean(
        np.random.default_rng(0).uniform(0, 1, (400_000, 2)) @ d[:2] <= 0.5 * d.sum() + 0.013
    )
    assert kept == pytest.approx(expected, abs=0.01)
    # No sliver: a cut this close to a vertex moves the vertex instead.
    assert _angles(cut).min() > np.degrees(np.arctan(SNAP)) / 2


def test_cut_keeps_everything_inside_and_nothing_outside():
    mesh = _plane_mesh(6)
    kept, edges = cut_mesh(mesh, np.full(mesh.n_vertices, -1.0))
    assert edges == 0 and kept.n_faces == mesh.n_faces
    gone, _ = cut_mesh(mesh, np.full(mesh.n_vertices, 1.0))
    assert gone.n_faces == 0


def test_data_edge_is_zero_on_the_edge_of_evenly_spaced_points():
    step = 0.01
    points = _grid(60, step, jitter=0.3)
    points = points[points[:, 0] <= 0.3]  # data for x <= 0.3
    radii = np.full(points.shape[0], 1.6 * step)
    x = np.array([0.3 - 2 * step, 0.3 - step, 0.3, 0.3 + step, 0.3 + 2 * step])
    vertices = np.stack([x, np.full(x.size, 0.3), np.zeros(x.size)], axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (x.size, 1))
    value = data_edge(points, radii, vertices, normals)
    assert value[0] < 0.0 and value[-1] > 0.0
    assert np.all(np.diff(value) > 0.0)  # rises across the edge
    assert abs(value[2]) < 0.1  # about zero on it: the half disc's centroid
    assert EDGE_OFFSET == pytest.approx(0.4244, abs=1e-4)


def test_data_edge_counts_a_curve_of_points_as_no_surface():
    t = np.linspace(0.0, 1.0, 400)
    points = np.stack([t, 0.1 * np.sin(3 * t), np.zeros_like(t)], axis=1)
    vertices = points[::40] + [0.0, 0.0, 0.0]
    normals = np.tile([0.0, 0.0, 1.0], (vertices.shape[0], 1))
    value = data_edge(points, np.full(t.size, 0.01), vertices, normals)
    assert np.all(value > 0.0)


@pytest.mark.parametrize("n", [20_000, 80_000])
@pytest.mark.slow
def test_open_pipe_rim_lies_at_the_data_edge_without_steps(n):
    radius, length, noise = 0.25, 1.0, 0.002
    sample = sample_cylinder(n, radius=radius, length=length, noise=noise, rng=1)
    result = reconstruct(sample.points)
    mesh = result.mesh
    spacing = np.sqrt(2 * np.pi * radius * length / n)
    loops = topology.boundary_loops(mesh.faces)
    assert len(loops) == 2 and result.stats["mesh_components"] == 1
    quality = mesh_quality(mesh)
    assert quality["non_manifold_edges"] == 0 and quality["non_manifold_vertices"] == 0
    for loop in loops:
        ring = mesh.vertices[np.r_[loop, loop[:1]]]
        rim_length = np.linalg.norm(np.diff(ring, axis=0), axis=1).sum()
        assert rim_length == pytest.approx(2 * np.pi * radius, rel=0.05)  # no saw-tooth
        # The points were drawn up to z = 0 and z = length, then moved by the noise: the
        # last points lie within 3 sigma of the ends, and the rim within a spacing of them.
        z = ring[:, 2]
        end = 0.0 if z.mean() < length / 2 else length
        assert np.abs(z - end).max() <= spacing + 3 * noise
    # The points at the ends lie on the mesh, give or take their noise: the rim does not
    # stop short of them.
    ends = sample.points[(sample.points[:, 2] < 0.02) | (sample.points[:, 2] > length - 0.02)]
    assert points_to_mesh_distance(ends, mesh).max() <= spacing + 3 * noise


def test_hole_in_a_pipe_wall_stays_round_and_near_its_edge():
    n, radius, hole_radius = 30_000, 0.25, 0.05
    sample = sample_cylinder(n, radius=radius, noise=0.002, hole=(0.0, 0.5, hole_radius), rng=5)
    mesh = reconstruct(sample.points).mesh
    loops = topology.boundary_loops(mesh.faces)
    assert len(loops) == 3
    centre = np.array([radius, 0.0, 0.5])
    rim = mesh.vertices[min(loops, key=len)]
    hole = np.linalg.norm(rim - centre, axis=1)
    spacing = np.sqrt(2 * np.pi * radius / n)
    # A 10 cm hole, 4.3 rho+delta across: wider than any gap bridge, so it opens to its
    # data. Its radius is kept within a spacing (seeds 1-5: 2.3-5.3 mm short, spacing
    # 7.2 mm), it reaches no further than the data do, and every rim vertex lies near a
    # point of the hole's edge.
    assert hole_radius - spacing <= hole.mean() <= hole_radius
    assert hole_radius - 2 * spacing <= hole.min() and hole.max() <= hole_radius + spacing
    gap, _ = cKDTree(sample.points).query(rim)
    assert gap.max() <= 2.5 * spacing


def _post_and_wall(seed: int, width: float = 0.12, spacing: float = 0.03, noise: float = 0.003):
    """Points on a wall (x = 0, 2 m square) and on a post `width` wide 0.4 m in front of it
    (x = -0.4, |y| <= width / 2, 2 m tall), about `spacing` apart with `noise` across, the
    post's shadow (|y| < width) cut out of the wall."""
    rng = np.random.default_rng(seed)

    def sheet(x, half, z_top):
        n = int(2 * half * z_top / spacing**2)
        points = np.stack([np.full(n, x), rng.uniform(-half, half, n), rng.uniform(0, z_top, n)], 1)
        points[:, 0] += rng.normal(0.0, noise, n)
        return points

    wall = sheet(0.0, 1.0, 2.0)
    return np.concatenate([wall[np.abs(wall[:, 1]) > width], sheet(-0.4, width / 2, 2.0)])


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("sensor", [False, True])
def test_narrow_post_in_front_of_a_wall_stays_whole(seed, sensor):
    # The post is 0.12 m wide, 1.4 rho+delta and under a cube (0.13 m): one column of
    # vertices tests inside, and balls between post and wall (4.6 rho+delta apart) see the
    # post's points and the wall's around them. It comes out one piece, its whole height,
    # within a spacing of its edges, on its plane, and joined to nothing.
    spacing, noise = 0.03, 0.003
    points = _post_and_wall(seed, spacing=spacing, noise=noise)
    viewpoints = np.tile([-3.0, 0.0, 1.0], (len(points), 1)) if sensor else None
    mesh = reconstruct(points, viewpoints=viewpoints).mesh
    _, label = topology.face_components(mesh.faces, mesh.n_vertices)
    centre = mesh.vertices[mesh.faces].mean(axis=1)
    assert not np.any((centre[:, 0] > -0.3) & (centre[:, 0] < -0.1))  # nothing between
    on_post = centre[:, 0] < -0.2
    assert np.unique(label[on_post]).size == 1
    post = mesh.vertices[np.unique(mesh.faces[on_post])]
    assert post[:, 2].min() <= 2.5 * spacing and post[:, 2].max() >= 2.0 - 2.5 * spacing
    assert np.abs(post[:, 1]).max() <= 0.06 + spacing
    off = post[:, 0] + 0.4
    assert abs(off.mean()) <= noise and np.abs(off).mean() <= 2 * noise
    assert np.abs(off).max() <= 0.02


def test_cut_keeps_a_strip_one_edge_wide():
    # Only the column of vertices at x = 0.5 is inside, 0.015 from the cut on either side:
    # each end of its edges lies within SNAP of a crossing, and moving them all onto the
    # cut would leave the strip no area. It stays whole, from y = 0 to 1, 0.03 wide.
    mesh = _plane_mesh(10)
    cut, _ = cut_mesh(mesh, np.abs(mesh.vertices[:, 0] - 0.5) - 0.015)
    assert topology.face_components(cut.faces, cut.n_vertices)[0] == 1
    assert cut.vertices[:, 1].min() == 0.0 and cut.vertices[:, 1].max() == 1.0
    np.testing.assert_allclose(np.abs(cut.vertices[:, 0] - 0.5).max(), 0.015)
    area = 0.5 * np.linalg.norm(topology.face_area_vectors(cut.vertices, cut.faces), axis=1)
    assert area.sum() == pytest.approx(0.03, rel=1e-9)
    assert topology.is_edge_manifold(cut.faces)


def test_cut_does_not_pinch_two_pieces_into_one_vertex():
    # A saddle, turned: the data lie in two opposite quadrants that meet at the centre.
    # Moving the vertex next to the centre onto both cuts would join the two at it.
    mesh = _plane_mesh(10)
    x, y = (mesh.vertices[:, :2] - 0.5).T
    u, v = np.cos(0.3) * x + np.sin(0.3) * y, np.cos(0.3) * y - np.sin(0.3) * x
    cut, _ = cut_mesh(mesh, 0.0005 - u * v)
    assert split_nonmanifold_vertices(cut)[1] == 0
    assert topology.is_edge_manifold(cut.faces)
    assert topology.is_consistently_oriented(cut.faces)


@pytest.mark.parametrize("gap", ["hole", "edge", "strip"])
def test_empty_balls_fill_a_round_hole_and_nothing_else(gap):
    # Points every 0.01 on the unit square, less a hole of radius 0.2 in its middle, or
    # less everything past x = 0.5 (an open edge), or less a strip 0.3 wide: each leaves
    # room for balls of radius 0.1, and only the hole is surrounded by its points.
    mesh = _plane_mesh(20)
    points = _grid(101, 0.01)
    off = {
        "hole": np.linalg.norm(points[:, :2] - 0.5, axis=1) < 0.2,
        "edge": points[:, 0] > 0.5,
        "strip": np.abs(points[:, 0] - 0.5) < 0.15,
    }[gap]
    normals = np.tile([0.0, 0.0, 1.0], (mesh.n_vertices, 1))
    least = np.full(np.count_nonzero(~off), 0.1)
    centres, radii = empty_balls(mesh, normals, cKDTree(points[~off]), least)
    if gap != "hole":
        assert centres.shape[0] == 0
        return
    assert radii.max() == pytest.approx(0.2, abs=0.005)
    assert np.linalg.norm(centres[np.argmax(radii), :2] - 0.5) < 0.01
    nearest, _ = cKDTree(points[~off]).query(centres)
    np.testing.assert_allclose(nearest, radii)  # each reaches to its nearest point


def test_empty_balls_beside_a_narrow_strip_are_no_holes():
    # The mesh (z = 0) lies 0.2 in front of a wall (z = -0.2), and a strip 0.1 wide (a post
    # in the plane y = 0.62) stands across it. The wall's points surround every ball in the
    # mesh's plane; the post's points surround a ball in the post's plane only when the
    # ball lies in front of the post, not beside it.
    mesh = _plane_mesh(20)
    wall = _grid(101, 0.01) + [0.0, 0.0, -0.2]
    x, z = np.meshgrid(np.arange(64, 75) * 0.01, np.arange(-50, 51) * 0.01)
    post = np.stack([x.ravel(), np.full(x.size, 0.62), z.ravel()], axis=1)
    points = np.concatenate([wall, post])
    planes = np.concatenate(
        [np.tile([0.0, 0.0, 1.0], (len(wall), 1)), np.tile([0.0, 1.0, 0.0], (len(post), 1))]
    )
    normals = np.tile([0.0, 0.0, 1.0], (mesh.n_vertices, 1))
    tree, least = cKDTree(points), np.full(len(points), 0.15)
    beside = {}
    for name, kept in (("mesh plane", None), ("both planes", planes)):
        centres, _ = empty_balls(mesh, normals, tree, least, planes=kept)
        on_post = tree.query(centres)[1] >= len(wall)
        assert np.count_nonzero(~on_post) > 0  # the mesh off the wall is no data either way
        x = centres[on_post, 0]
        beside[name] = np.count_nonzero((x < 0.64 - 0.01) | (x > 0.74 + 0.01))
    assert beside["mesh plane"] > 0
    assert beside["both planes"] == 0


def test_rim_of_whole_cubes_is_hoppes_and_is_not_cut():
    n, noise = 20_000, 0.002
    sample = sample_cylinder(n, radius=0.25, length=1.0, noise=noise, rng=1)
    cubes = reconstruct(sample.points, rim="cubes")
    assert "rim" not in cubes.timings and "rim_edges_cut" not in cubes.stats
    data = reconstruct(sample.points)
    assert data.stats["rim_edges_cut"] > 0
    # The cubes' rim reaches well past the end of the pipe, the cut one does not.
    reach = np.sqrt(2 * np.pi * 0.25 / n) + 3 * noise
    assert cubes.mesh.vertices[:, 2].max() > 1.0 + reach >= data.mesh.vertices[:, 2].max()


@pytest.mark.slow
def test_without_gap_bridges_the_far_ends_of_a_scan_tear():
    # Far down a 0.1 m pipe the scan rings are 2-2.5 rho+delta apart: bridges join them.
    scan = scan_pipe(radius=0.1, rotation_step=1.0, offset=0.0, rng=3)
    bridged = reconstruct(scan.points)
    torn = reconstruct(scan.points, gap_bridges=False)
    assert bridged.stats["gap_bridge_points"] > 0 and torn.stats["gap_bridge_points"] == 0
    assert bridged.stats["boundary_loops"] == 2 < torn.stats["boundary_loops"]


def test_unknown_rim_is_refused():
    with pytest.raises(ValueError, match="rim must be one of"):
        ReconstructionConfig(rim="edges")


@pytest.mark.parametrize("width, filled", [(0.5, 1), (0.1, 0)])
def test_holes_narrower_than_the_limit_are_closed(width, filled):
    mesh = _plane_mesh(12)
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    keep = np.linalg.norm(centres[:, :2] - 0.5, axis=1) > 0.13  # a hole 0.3 across
    holed = Mesh(vertices=mesh.vertices, faces=mesh.faces[keep])
    loops = topology.boundary_loops(holed.faces)
    assert len(loops) == 2 and max(len(loop) for loop in loops) > 6
    closed, count, widest = fill_small_holes(holed, WIDTH_EDGES, max_width=width)
    assert count == filled
    assert (0.25 < widest < 0.4) if filled else widest == 0.0  # the hole is 0.3 across
    assert len(topology.boundary_loops(closed.faces)) == 2 - filled
    assert topology.is_edge_manifold(closed.faces)
    assert topology.is_consistently_oriented(closed.faces)


def test_the_outer_edge_of_a_patch_is_never_filled():
    # A loop is filled only from the side its mesh faces: a patch's outer edge runs the
    # other way round from a hole's, and a fan over it would fold back over the patch.
    patch = _plane_mesh(3)
    kept, count, widest = fill_small_holes(patch, WIDTH_EDGES, closable=lambda ring: True)
    assert count == 0 and kept.n_faces == patch.n_faces and widest == 0.0


@pytest.mark.parametrize("half_width, closed", [(1.3, True), (2.0, False)])
def test_a_gap_with_room_for_no_empty_ball_is_closed(half_width, closed):
    # A slot 6 rho+delta long in the sampling of a plane, without gap bridges: the edge test
    # opens it (its middle lies beyond the reach of the data), but a slot 2.6 rho+delta wide
    # has room for no empty ball of 1.75 radii, the rule that opens a hole, and is closed
    # again; one 4 rho+delta wide has, and stays open.
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-0.5, 0.5, (12_000, 2)), 0.001 * rng.normal(size=12_000)])
    rho_delta = 0.0245
    slot = (np.abs(points[:, 0]) < half_width * rho_delta) & (np.abs(points[:, 1]) < 3 * rho_delta)
    result = reconstruct(points[~slot], rho_delta=rho_delta, gap_bridges=False)
    mesh = result.mesh
    gap = points_to_mesh_distance(np.zeros((1, 3)), mesh)[0]
    assert result.stats["boundary_loops"] == (1 if closed else 2)
    if closed:
        assert result.stats["small_holes_filled"] >= 1
        assert gap < 0.1 * rho_delta  # the slot's middle is covered, on the plane
        assert np.abs(mesh.vertices[:, 2]).max() < 0.005
    else:
        assert gap > half_width * rho_delta - 0.5 * rho_delta
    assert topology.is_edge_manifold(mesh.faces) and topology.is_consistently_oriented(mesh.faces)
