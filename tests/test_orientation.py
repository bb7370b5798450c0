import numpy as np
import pytest

from zeroset.normals import tangent_planes
from zeroset.orientation import agree_parts, orient_normals, part_extremes
from zeroset.synthetic import sample_cylinder, sample_sphere, two_spheres


def _random_signs(normals, rng):
    return normals * rng.choice([-1.0, 1.0], size=(normals.shape[0], 1))


def test_sphere_normals_point_outwards(rng):
    points = sample_sphere(3000, noise=0.01, rng=0).points
    planes = tangent_planes(points, radius=0.2)
    result = orient_normals(planes.centroids, _random_signs(planes.normals, rng))
    assert result.method == "mst" and result.n_components == 1
    assert np.all(np.einsum("ij,ij->i", result.normals, planes.centroids) > 0)


def test_z_axis_cylinder_normals_point_away_from_the_axis(rng):
    points = sample_cylinder(8000, noise=0.002, rng=1).points
    planes = tangent_planes(points, radius=0.03)
    result = orient_normals(planes.centroids, _random_signs(planes.normals, rng))
    radial = np.einsum("ij,ij->i", result.normals[:, :2], planes.centroids[:, :2])
    assert np.mean(radial > 0) > 0.999


def test_each_component_is_seeded_on_its_own(rng):
    sample = two_spheres(4000, rng=2)
    planes = tangent_planes(sample.points, radius=0.2)
    result = orient_normals(planes.centroids, _random_signs(planes.normals, rng), max_edge=0.4)
    assert result.n_components == 2
    centre = np.where(planes.centroids[:, [0]] > 1.5, [3.0, 0.0, 0.0], 0.0)
    assert np.all(np.einsum("ij,ij->i", result.normals, planes.centroids - centre) > 0)


def _arc_sheet(centre, degrees, step=0.02):
    """Points (M, 3) and outward unit normals (M, 3) on an arc of radius 1 about `centre`
    (x, y) over `degrees` (from, to), extruded over z in [0, 1], about `step` apart."""
    theta = np.radians(np.arange(*degrees, np.sign(degrees[1] - degrees[0]) * np.degrees(step)))
    z = np.arange(0.0, 1.0 + step / 2, step)
    theta, z = np.meshgrid(theta, z, indexing="ij")
    out = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(z)], axis=-1).reshape(-1, 3)
    points = out + np.array([*centre, 0.0])
    points[:, 2] = z.ravel()
    return points, out


def test_pieces_of_one_surface_are_joined_whichever_is_largest(rng):
    # An S-shaped sheet in two pieces 0.21 apart (more than the graph's longest edge, 0.15,
    # within the joining reach, 0.3): one arc bulges towards +x, the other towards -x, so
    # each piece's own root turns it outward from its own arc and the two disagree. A plane
    # far away is the largest component; the pieces must still be joined to each other.
    first, first_out = _arc_sheet((0.0, 0.0), (-60.0, -5.0))
    second, second_out = _arc_sheet((2.0, 0.0), (175.0, 120.0))
    far = np.stack(np.meshgrid(np.arange(100) * 0.02, np.arange(100) * 0.02), -1).reshape(-1, 2)
    far = np.c_[far + 10.0, np.zeros(len(far))]
    points = np.concatenate([first, second, far])
    # One consistent side of the S: outward from the first arc, inward to the second.
    truth = np.concatenate([first_out, -second_out, np.tile([0.0, 0.0, 1.0], (len(far), 1))])
    result = orient_normals(points, _random_signs(truth, rng), k=8, max_edge=0.15)
    sheet = slice(0, len(first) + len(second))
    assert result.n_components == 2
    agree = np.einsum("ij,ij->i", result.normals[sheet], truth[sheet]) > 0
    assert agree.all() or not agree.any()


def test_flipped_records_which_normals_changed(rng):
    points = sample_sphere(1000, rng=3).points
    planes = tangent_planes(points, radius=0.3)
    given = _random_signs(planes.normals, rng)
    result = orient_normals(planes.centroids, given)
    np.testing.assert_array_equal(result.normals, np.where(result.flipped[:, None], -given, given))


@pytest.mark.parametrize("per_point", [False, True])
def test_viewpoint_orientation_faces_the_sensor(per_point, rng):
    points = sample_cylinder(3000, rng=4).points
    planes = tangent_planes(points, radius=0.05)
    sensor = np.array([0.05, 0.0, 0.5])
    viewpoints = np.tile(sensor, (3000, 1)) if per_point else sensor
    result = orient_normals(
        planes.centroids, _random_signs(planes.normals, rng), viewpoints=viewpoints
    )
    assert result.method == "mst+viewpoints"
    assert np.all(np.einsum("ij,ij->i", result.normals, sensor - planes.centroids) >= 0)


def test_viewpoints_of_the_wrong_shape_are_rejected(rng):
    c = rng.normal(size=(10, 3))
    with pytest.raises(ValueError, match="viewpoints must be"):
        orient_normals(c, c, viewpoints=np.zeros((4, 3)))


def _plate(rng, n=4000, gap=0.02):
    """A thin plate: its top seen from above, its bottom from below, `gap` apart."""
    xy = rng.uniform(-0.5, 0.5, size=(n, 2))
    top = np.column_stack([xy[: n // 2], np.full(n // 2, gap / 2)])
    bottom = np.column_stack([xy[n // 2 :], np.full(n - n // 2, -gap / 2)])
    sensors = np.array([[0.0, 0.0, 2.0]] * (n // 2) + [[0.0, 0.0, -2.0]] * (n - n // 2))
    return np.vstack([top, bottom]), sensors


def test_each_normal_faces_the_sensor_that_saw_it(rng):
    # Both sides of a thin plate share one spanning tree, which orients them alike; each
    # side must face its own sensor instead.
    points, sensors = _plate(rng)
    normals = _random_signs(np.tile([0.0, 0.0, 1.0], (points.shape[0], 1)), rng)
    tree_only = orient_normals(points, normals, k=12)
    assert abs(np.mean(tree_only.normals[:, 2] > 0) - 0.5) > 0.4  # one side is wrong
    result = orient_normals(points, normals, k=12, viewpoints=sensors)
    assert np.all(np.einsum("ij,ij->i", result.normals, sensors - points) > 0)
    assert 0.4 < result.disagreement < 0.6
    # High disagreement, but abrupt: the tree joined the two sides; the sensors are trusted.
    assert result.method == "mst+viewpoints" and not result.viewpoints_untrusted


def test_points_with_no_known_sensor_follow_their_neighbours(rng):
    points = sample_cylinder(6000, rng=5).points
    planes = tangent_planes(points, radius=0.05)
    sensors = np.tile([0.0, 0.0, 0.5], (points.shape[0], 1))
    unknown = rng.random(points.shape[0]) < 0.7
    sensors[unknown] = np.nan
    result = orient_normals(
        planes.centroids, _random_signs(planes.normals, rng), viewpoints=sensors
    )
    inward = np.einsum("ij,ij->i", result.normals[:, :2], -planes.centroids[:, :2]) > 0
    assert np.mean(inward[unknown]) > 0.999
    assert result.disagreement == 0.0


def test_sensors_decide_the_side_of_a_closed_surface(rng):
    # Sensors inside a closed sphere turn it inside out: they, not the outward convention
    # of the spanning tree, decide, and the tree agrees with them up to that one sign.
    points = sample_sphere(3000, noise=0.005, rng=6).points
    planes = tangent_planes(points, radius=0.2)
    given = _random_signs(planes.normals, rng)
    outside = orient_normals(planes.centroids, given, viewpoints=3.0 * planes.centroids)
    inside = orient_normals(planes.centroids, given, viewpoints=np.zeros(3))
    assert np.all(np.einsum("ij,ij->i", outside.normals, planes.centroids) > 0)
    assert np.all(np.einsum("ij,ij->i", inside.normals, planes.centroids) < 0)
    assert outside.disagreement < 0.01 and inside.disagreement < 0.01


def test_viewpoint_rows_must_be_finite_or_all_nan(rng):
    c = rng.normal(size=(10, 3))
    sensors = np.zeros((10, 3))
    sensors[3, 1] = np.nan
    with pytest.raises(ValueError, match="row 3"):
        orient_normals(c, c, viewpoints=sensors)


@pytest.mark.parametrize("tilt, joined", [(20.0, True), (40.0, False)])
def test_a_part_is_joined_by_a_step_within_30_degrees_of_both_tangent_planes(tilt, joined):
    # Two patches of the plane z = 0, 3 cm apart along x; normals tilted towards x by
    # `tilt` make the step between their closest points leave both tangent planes by
    # `tilt` degrees: one surface up to `ON_ONE_SURFACE`, two sheets beyond.
    from zeroset.orientation import _bridges

    x, y = np.meshgrid(np.arange(0.0, 0.2, 0.01), np.arange(0.0, 0.2, 0.01))
    big = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    small = big[big[:, 0] < 0.05] + [0.22, 0.0, 0.0]
    centroids = np.concatenate([big, small])
    component = np.repeat([0, 1], [big.shape[0], small.shape[0]])
    angle = np.radians(tilt)
    normals = np.tile([np.sin(angle), 0.0, np.cos(angle)], (centroids.shape[0], 1))
    edges = _bridges(centroids, normals, component, np.full(centroids.shape[0], 0.1))
    assert (edges.nnz == 1) == joined


def _overlaps(*parts):
    """The arguments of `agree_parts` for parts given as (points, normals, extremes (6, 2))
    of one component each."""
    keys = np.concatenate([np.array(p, dtype=np.float64) for p, _, _ in parts])
    return (
        np.ascontiguousarray(keys).view(np.dtype((np.void, 24))).ravel(),
        np.concatenate([np.full(len(p), i) for i, (p, _, _) in enumerate(parts)]),
        np.concatenate([np.array(n, dtype=np.float64) for _, n, _ in parts]),
        np.stack([np.array(e, dtype=np.float64) for _, _, e in parts]),
    )


def test_parts_that_orient_oppositely_are_turned_to_agree():
    # Two parts share three points; the second oriented them the other way. The first
    # holds the point farthest along +x, whose normal points along -x: so it turns.
    shared = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0]]
    up, down = [[1.0, 0.0, 0.0]] * 3, [[-1.0, 0.0, 0.0]] * 3
    far = np.full((6, 2), -np.inf)
    far[0] = [5.0, -1.0]  # +x: coordinate 5, normal against +x
    near = np.full((6, 2), -np.inf)
    near[0] = [1.0, 1.0]
    sign, group, disagreement = agree_parts(*_overlaps((shared, up, far), (shared, down, near)))
    assert sign.tolist() == [-1.0, 1.0] and group[0] == group[1] and disagreement == 0.0
    # Three parts whose pairs cannot all agree (0 and 1 disagree, 1 and 2 agree, 2 and 0
    # agree): one pair is left disagreeing, and reported, not hidden.
    b, c = [[7.0, 0.0, 0.0]], [[8.0, 0.0, 0.0]]
    x = [[1.0, 0.0, 0.0]]
    parts = [(shared + c, up + x, far), (shared + b, down + x, near), (b + c, x * 2, near)]
    _, group, disagreement = agree_parts(*_overlaps(*parts))
    assert disagreement == pytest.approx(1 / 5) and np.unique(group).size == 1
    # Sensors that set every sign keep them.
    sign, _, disagreement = agree_parts(*_overlaps(*parts), by_sensors=True)
    assert sign.tolist() == [1.0, 1.0, 1.0] and disagreement == pytest.approx(3 / 5)


def test_halves_of_a_sphere_oriented_apart_agree_outward(rng):
    # Each half, with an overlap, oriented on its own after one half is turned inward:
    # agreeing on the overlap and rooting at the extreme point turns every normal outward.
    points = sample_sphere(4000, noise=0.005, rng=3).points
    planes = tangent_planes(points, radius=0.2)
    keys, part, normals, extremes = [], [], [], []
    for i, side in enumerate((planes.centroids[:, 0] < 0.2, planes.centroids[:, 0] > -0.2)):
        own = orient_normals(planes.centroids[side], _random_signs(planes.normals[side], rng))
        turned = own.normals * (-1.0 if i else 1.0)
        keys.append(np.ascontiguousarray(planes.centroids[side]).view(np.dtype((np.void, 24))))
        part.append(np.full(np.count_nonzero(side), i))
        normals.append(turned)
        owned = planes.centroids[side, 0] < 0 if i == 0 else planes.centroids[side, 0] >= 0
        extremes.append(
            part_extremes(planes.centroids[side][owned], turned[owned], own.component[owned], 1)
        )
    sign, group, disagreement = agree_parts(
        np.concatenate(keys).ravel(),
        np.concatenate(part),
        np.concatenate(normals),
        np.concatenate(extremes),
    )
    assert sign.tolist() == [1.0, -1.0] and group[0] == group[1] and disagreement < 0.01
    for i, side in enumerate((planes.centroids[:, 0] < 0.2, planes.centroids[:, 0] > -0.2)):
        outward = np.einsum("ij,ij->i", normals[i] * sign[i], planes.centroids[side])
        assert np.mean(outward > 0) > 0.999
