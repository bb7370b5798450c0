"""End-to-end phase 1 on synthetic clouds with known surfaces."""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from zeroset import (
    InputError,
    ReconstructionConfig,
    ReconstructionError,
    SurfaceWarning,
    evaluate,
    reconstruct,
    topology,
)
from zeroset.evaluate import points_to_mesh_distance
from zeroset.stages import surface_changes
from zeroset.synthetic import sample_cylinder, sample_sphere, sample_torus, scan_pipe


def _face_normals(mesh):
    tri = mesh.vertices[mesh.faces]
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])


def test_open_pipe_has_two_boundary_loops_and_no_caps(pipe):
    _, result = pipe
    mesh = result.mesh
    loops = topology.boundary_loops(mesh.faces)
    assert len(loops) == 2
    # One loop at each end, none across the pipe.
    ends = sorted(float(mesh.vertices[loop, 2].mean()) for loop in loops)
    assert ends[0] < 0.05 and ends[1] > 0.95
    # A cap would put vertices near the axis and faces facing along it.
    assert np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1]).min() > 0.2
    normals = _face_normals(mesh)
    assert np.all(np.abs(normals[:, 2]) < 0.9 * np.linalg.norm(normals, axis=1))


def test_open_pipe_is_close_to_the_true_cylinder(pipe):
    sample, result = pipe
    assert sample.distance(result.mesh.vertices).mean() < 0.002
    truth = sample_cylinder(20_000, rng=99).points  # noise-free samples of the true surface
    covered = points_to_mesh_distance(truth, result.mesh) < 0.01
    assert covered.mean() >= 0.95


def test_open_pipe_mesh_is_manifold_and_consistently_oriented(pipe):
    _, result = pipe
    faces = result.mesh.faces
    assert topology.is_edge_manifold(faces)
    assert topology.is_consistently_oriented(faces)
    assert result.stats["mesh_components"] == 1
    # Outward: face normals point away from the axis.
    centres = result.mesh.vertices[faces].mean(axis=1)
    radial = np.einsum("ij,ij->i", _face_normals(result.mesh)[:, :2], centres[:, :2])
    assert np.mean(radial > 0) > 0.99


@pytest.mark.parametrize("name, euler", [("sphere", 2), ("torus", 0)])
def test_closed_surfaces_are_closed_manifold_outward(name, euler, request):
    sample, result = request.getfixturevalue(name)
    mesh = result.mesh
    assert topology.boundary_loops(mesh.faces) == []
    counts = topology.edge_face_counts(mesh.faces)[1]
    assert np.all(counts == 2)
    assert topology.is_consistently_oriented(mesh.faces)
    assert topology.euler_characteristic(mesh) == euler
    assert topology.signed_volume(mesh) > 0
    assert sample.distance(mesh.vertices).mean() < 0.01


def test_sphere_faces_point_away_from_centre(sphere):
    _, result = sphere
    mesh = result.mesh
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", _face_normals(mesh), centres) > 0)


def test_hole_in_pipe_wall_stays_open():
    sample = sample_cylinder(30_000, noise=0.002, hole=(0.0, 0.5, 0.05), rng=5)
    mesh = reconstruct(sample.points).mesh
    loops = topology.boundary_loops(mesh.faces)
    assert len(loops) == 3
    hole = min(loops, key=len)
    centre = mesh.vertices[hole].mean(axis=0)
    assert abs(centre[2] - 0.5) < 0.03 and centre[0] > 0.2 and abs(centre[1]) < 0.03


def test_two_disjoint_objects_are_both_reconstructed(spheres):
    sample, result = spheres
    mesh = result.mesh
    assert result.orientation.n_components >= 2
    n_components, label = topology.face_components(mesh.faces, mesh.n_vertices)
    assert n_components == 2
    for centre in ([0.0, 0.0, 0.0], [3.0, 0.0, 0.0]):
        part = (
            label
            == label[np.argmin(np.linalg.norm(mesh.vertices[mesh.faces[:, 0]] - centre, axis=1))]
        )
        faces = mesh.faces[part]
        tri_centres = mesh.vertices[faces].mean(axis=1)
        normals = np.cross(
            *(mesh.vertices[faces[:, i]] - mesh.vertices[faces[:, 0]] for i in (1, 2))
        )
        assert np.mean(np.einsum("ij,ij->i", normals, tri_centres - centre) > 0) > 0.99
    assert sample.distance(mesh.vertices).max() < 0.05


def test_huge_coordinates_give_the_same_mesh_translated():
    points = sample_cylinder(8_000, noise=0.002, rng=6).points
    shift = np.array([6e5, 5e6, 300.0])
    near = reconstruct(points)
    far = reconstruct(points + shift)
    assert far.dense_mesh.faces.shape == near.dense_mesh.faces.shape
    np.testing.assert_array_equal(far.dense_mesh.faces, near.dense_mesh.faces)
    np.testing.assert_allclose(
        far.dense_mesh.vertices - shift, near.dense_mesh.vertices, rtol=0, atol=1e-6
    )
    # The simplification decides at the tolerance, where the rounding of the far frame
    # (1e-9) may tip a collapse: the same surface, not the same triangles.
    assert far.mesh.n_faces == pytest.approx(near.mesh.n_faces, rel=0.05)
    tolerance = near.stats["tolerance"]
    away = points_to_mesh_distance(far.mesh.vertices - shift, near.dense_mesh)
    assert away.max() <= tolerance


def test_same_seed_same_mesh_and_sampling_follows_the_seed():
    points = sample_sphere(4_000, noise=0.01, rng=7).points
    a = reconstruct(points, sample=0.5, seed=1).mesh
    b = reconstruct(points, sample=0.5, seed=1).mesh
    c = reconstruct(points, sample=0.5, seed=2).mesh
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)
    assert a.vertices.shape != c.vertices.shape or not np.array_equal(a.vertices, c.vertices)


def test_given_parameters_are_used_and_reported():
    points = sample_sphere(3_000, rng=8).points
    result = reconstruct(points, rho_delta=0.2, cube_size=0.15)
    assert result.parameters.rho_delta == 0.2
    assert result.parameters.cube_size == 0.15
    assert any("given" in note for note in result.parameters.notes)
    assert result.field.cube_size == 0.15


def test_preparation_counts_what_it_removed():
    points = sample_sphere(5_000, rng=9).points
    result = reconstruct(points, sample=0.5, crop=(-2, -2, -0.5, 2, 2, 2))
    assert result.stats["sampled_out"] + result.stats["cropped"] + result.points.shape[0] <= 5_000
    assert result.stats["cropped"] > 0 and result.stats["sampled_out"] > 0
    assert result.points[:, 2].min() + result.offset[2] >= -0.5 - 1e-12


def test_outliers_are_dropped_and_counted():
    sample = sample_sphere(5_000, noise=0.005, rng=10)
    far = np.random.default_rng(0).uniform(-3, 3, size=(40, 3))
    far = far[np.linalg.norm(far, axis=1) > 1.5]
    result = reconstruct(np.concatenate([sample.points, far]))
    assert result.stats["outliers"] >= far.shape[0]
    assert sample.distance(result.mesh.vertices).max() < 0.1


def test_every_stage_is_timed(pipe):
    sample, result = pipe
    assert set(result.timings) == {
        "prepare",
        "parameters",
        "cell means",
        "neighbours",
        "radii",
        "outliers",
        "tangent planes",
        "orientation",
        "local fits",
        "signed distance",
        "contour",
        "repair",
        "rim",
        "refine",
        "simplify",
    }
    assert all(seconds >= 0 for seconds in result.timings.values())
    planes = reconstruct(sample.points[:5000], surface="planes")
    # Hoppe's planes are their own local fits, with no curvature to refine onto.
    assert "refine" not in planes.timings
    assert planes.stats["surface_function"] == "nearest tangent plane (Hoppe 1992)"


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((0, 3)), r"points is empty"),
        (np.ones((100, 2)), r"shape \(N, 3\)"),
        (np.array([[0.0, 0.0, np.nan]] + [[1.0, 2.0, 3.0]] * 50), r"non-finite values .*row 0"),
        (np.random.default_rng(0).normal(size=(8, 3)), r"neighbourhood needs at least"),
        (np.c_[np.linspace(0, 1, 200), 2 * np.linspace(0, 1, 200), np.zeros(200)], r"collinear"),
        (np.ones((200, 3)), r"coincide"),
    ],
)
def test_bad_input_is_rejected_with_a_clear_message(points, message):
    with pytest.raises(InputError, match=message):
        reconstruct(points)


def test_radius_far_below_the_spacing_finds_no_surface():
    points = sample_sphere(2_000, rng=11).points
    with pytest.raises(ReconstructionError, match="rho_delta"):
        reconstruct(points, rho_delta=1e-4)


def test_unknown_option_is_a_type_error():
    with pytest.raises(TypeError, match="unknown reconstruction parameter"):
        reconstruct(np.zeros((10, 3)), not_an_option=1)


def test_unknown_contouring_is_a_value_error():
    with pytest.raises(ValueError, match=r"contour must be one of \('marching', 'cubes'\)"):
        reconstruct(np.zeros((10, 3)), contour="dual")


def test_scan_lines_far_apart_reconstruct_in_one_piece():
    # Lines along the pipe 1 mm apart within a line, 4 degrees (17 mm) between lines: the
    # nearest neighbours of a point all lie on its own line.
    rng = np.random.default_rng(12)
    theta, z = np.meshgrid(np.radians(np.arange(0, 360, 4.0)), np.arange(0, 1, 0.001))
    points = np.c_[0.25 * np.cos(theta.ravel()), 0.25 * np.sin(theta.ravel()), z.ravel()]
    result = reconstruct(points + rng.normal(0, 0.001, points.shape))
    assert result.stats["mesh_components"] == 1
    assert result.stats["boundary_loops"] == 2
    radius = np.hypot(result.mesh.vertices[:, 0], result.mesh.vertices[:, 1])
    assert np.abs(radius - 0.25).mean() < 0.002


@pytest.mark.parametrize("name, loops, euler", [("pipe", 2, 0), ("sphere", 0, 2), ("torus", 0, 0)])
@pytest.mark.slow
def test_method_of_cubes_keeps_topology_and_accuracy_with_better_triangles(
    name, loops, euler, request
):
    # Both contoured meshes as they are, vertices projected but no edge split: refinement
    # splits wherever the chords sag, whichever contouring made them.
    sample, _ = request.getfixturevalue(name)
    marching = reconstruct(sample.points, refine_levels=0, tolerance=0.0)
    result = reconstruct(sample.points, contour="cubes", refine_levels=0, tolerance=0.0)
    mesh = result.mesh
    assert result.parameters.cube_size == marching.parameters.cube_size
    assert len(topology.boundary_loops(mesh.faces)) == loops
    assert topology.euler_characteristic(mesh) == euler
    assert topology.is_edge_manifold(mesh.faces) and topology.is_consistently_oriented(mesh.faces)
    assert result.stats["mesh_components"] == 1
    if not loops:
        assert topology.signed_volume(mesh) > 0
    # Mean distance of the mesh's surface to the true surface: no worse than marching cubes.
    points, _ = evaluate.sample_surface(mesh, 50_000, rng=0)
    reference, _ = evaluate.sample_surface(marching.mesh, 50_000, rng=0)
    assert np.abs(sample.distance(points)).mean() <= np.abs(sample.distance(reference)).mean()
    # No slivers: the smallest angles are far above marching cubes' (which reach 0).
    ours, theirs = evaluate.smallest_angles(mesh), evaluate.smallest_angles(marching.mesh)
    assert np.percentile(ours, 5) > 20.0 > np.percentile(theirs, 5)
    assert mesh.n_faces <= marching.mesh.n_faces + 2 * euler


@pytest.mark.slow
def test_wrong_sensor_positions_are_not_trusted():
    # Every "sensor" at the centre of a torus, in its hole: the outer half of the tube faces
    # away from it. The sensors are not trusted, a warning says so, and the mesh is the one
    # the spanning tree alone gives: closed, of genus one.
    points = sample_torus(20_000, major=0.42, minor=0.13, noise=0.002, rng=0).points
    plain = reconstruct(points)
    with pytest.warns(SurfaceWarning, match="sensor positions and the spanning tree disagree"):
        wrong = reconstruct(points, viewpoints=np.zeros_like(points))
    assert wrong.orientation.method == "mst, viewpoints untrusted"
    assert wrong.orientation.disagreement > 0.05
    for key in ("mesh_components", "boundary_loops", "euler_characteristic"):
        assert wrong.stats[key] == plain.stats[key]
    assert topology.is_consistently_oriented(wrong.mesh.faces)
    # The dense meshes: the simplified ones differ where rounding tipped a collapse.
    gap, _ = cKDTree(plain.dense_mesh.vertices).query(wrong.dense_mesh.vertices)
    assert gap.max() < 0.5 * plain.parameters.rho_delta
    # The same surface, however each was split: every vertex of either lies on the other.
    for one, other in ((wrong, plain), (plain, wrong)):
        gap = points_to_mesh_distance(one.dense_mesh.vertices, other.dense_mesh)
        assert gap.max() < 0.02 * plain.parameters.rho_delta


def test_right_sensor_positions_are_trusted():
    scan = scan_pipe(rotation_step=2.0, rng=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SurfaceWarning)
        result = reconstruct(scan.points, viewpoints=scan.viewpoints, gap_bridges=False)
    assert result.orientation.method == "mst+viewpoints"
    assert result.orientation.disagreement < 0.01


def test_every_change_to_the_surface_names_its_off_switch():
    config = ReconstructionConfig()
    quiet = {"gap_bridge_points": 10, "phase1_points": 1_000, "orientation_components": 1}
    assert surface_changes(quiet, config) == []  # 1 % bridges: random gaps, no warning
    loud = {
        "gap_bridge_points": 50,
        "phase1_points": 1_000,
        "small_holes_filled": 3,
        "widest_hole_filled": 0.05,
        "small_components_dropped": 2,
        "orientation_components": 4,
        "viewpoints_untrusted": 1,
        "orientation_disagreement": 0.23,
    }
    messages = surface_changes(loud, config)
    switches = ["--no-gap-bridges", "--max-hole-edges 0", "--min-component-faces 0", "orient_k"]
    for message, switch in zip(messages, switches + ["viewpoints"], strict=True):
        assert switch in message
    assert "the widest 0.05 across" in messages[1]
    assert "23.0%" in messages[-1]
