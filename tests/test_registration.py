"""Registration of overlapping scans: recovered poses against a known synthetic truth."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from zeroset.errors import InputError
from zeroset.registration import Registration, register_scans

#: Noise of the synthetic scans (m) and the perturbation of the given poses.
NOISE = 0.0015
PERTURB_DEGREES = 2.0
PERTURB_METRES = 0.02


def bumpy_ellipsoid(n: int, rng: np.random.Generator) -> np.ndarray:
    """Points (n, 3) on a closed 1.0 x 0.7 x 0.5 m ellipsoid with 40 bumps and dents, noisy.

    The bumps break every symmetry, so overlapping patches fix all six degrees of freedom.
    """
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radius = 1.0 / np.sqrt(((directions / [0.5, 0.35, 0.25]) ** 2).sum(axis=1))
    shape = np.random.default_rng(99)
    centres = shape.normal(size=(40, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    heights = shape.uniform(0.03, 0.08, 40) * shape.choice([-1.0, 1.0], 40)
    radius *= 1.0 + (np.exp(-(1.0 - directions @ centres.T) / 0.02) * heights).sum(axis=1)
    return radius[:, None] * directions + rng.normal(scale=NOISE, size=(n, 3))


def rigid(rotation: np.ndarray, translation) -> np.ndarray:
    """4x4 pose from a rotation matrix and a translation."""
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = translation
    return pose


def split_into_scans(points, centre, rng):
    """Three 160-degree sectors about z (40-degree overlaps), each in its own random frame.

    Returns the scans and their true poses (scan frame to world).
    """
    azimuth = np.degrees(np.arctan2(points[:, 1] - centre[1], points[:, 0] - centre[0]))
    scans, truth = [], []
    for middle in (0.0, 120.0, 240.0):
        inside = np.abs((azimuth - middle + 180.0) % 360.0 - 180.0) < 80.0
        pose = rigid(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-2, 2, 3))
        scans.append((points[inside] - pose[:3, 3]) @ pose[:3, :3])
        truth.append(pose)
    return scans, np.array(truth)


def perturbed(pose, centre, rng) -> np.ndarray:
    """`pose` moved by PERTURB_DEGREES about a random axis through `centre` and by
    PERTURB_METRES in a random direction."""
    axis, direction = rng.normal(size=(2, 3))
    rotation = Rotation.from_rotvec(
        np.radians(PERTURB_DEGREES) * axis / np.linalg.norm(axis)
    ).as_matrix()
    move = rigid(rotation, centre - rotation @ centre)
    move[:3, 3] += PERTURB_METRES * direction / np.linalg.norm(direction)
    return move @ pose


def pose_errors(poses, truth, centre) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (degrees) and displacement at `centre` (m) of each scan's error.

    The error compares each scan's pose relative to scan 0 with the true relative pose,
    expressed in the world: the motion taking the true place of the scan's points to the
    estimated one, with scan 0 held where it truly is.
    """
    angles, shifts = [], []
    for pose, true in zip(poses, truth, strict=True):
        error = truth[0] @ np.linalg.inv(poses[0]) @ pose @ np.linalg.inv(true)
        cosine = np.clip((np.trace(error[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
        angles.append(np.degrees(np.arccos(cosine)))
        shifts.append(np.linalg.norm(error[:3, :3] @ centre + error[:3, 3] - centre))
    return np.array(angles), np.array(shifts)


def make_scene(seed: int, centre=(0.0, 0.0, 0.0)):
    """Scans, true poses, perturbed poses (scans 1 and 2) and the object's centre."""
    rng = np.random.default_rng(seed)
    centre = np.asarray(centre, dtype=float)
    scans, truth = split_into_scans(bumpy_ellipsoid(30_000, rng) + centre, centre, rng)
    given = truth.copy()
    for i in (1, 2):
        given[i] = perturbed(truth[i], centre, rng)
    return scans, truth, given, centre


@pytest.fixture(scope="module")
def scene():
    return make_scene(11)


def test_recovers_perturbed_poses(scene):
    scans, truth, given, centre = scene
    angles, shifts = pose_errors(given, truth, centre)
    assert np.allclose(angles[1:], PERTURB_DEGREES) and np.all(shifts[1:] > 0.01)

    result = register_scans(scans, given)

    angles, shifts = pose_errors(result.poses, truth, centre)
    assert np.all(angles < 0.2), angles
    assert np.all(shifts < 0.002), shifts
    assert np.all(result.residual_after < result.residual_before)
    assert np.all(result.overlap_after > result.overlap_before)
    # The residual after is the noise of one scan against the other's fitted planes.
    assert np.all(result.residual_after < 2 * NOISE)
    np.testing.assert_allclose(result.poses[0], given[0], atol=1e-12)  # the fixed scan
    rotations = result.poses[:, :3, :3]
    assert np.allclose(rotations @ rotations.transpose(0, 2, 1), np.eye(3), atol=1e-9)
    assert np.allclose(result.poses[:, 3], [0, 0, 0, 1])


def test_correct_poses_stay(scene):
    scans, truth, _, centre = scene
    result = register_scans(scans, truth)
    angles, shifts = pose_errors(result.poses, truth, centre)
    assert np.all(angles < 0.05), angles
    assert np.all(shifts < 0.0005), shifts
    assert np.allclose(result.residual_after, result.residual_before, rtol=0.1)


def test_same_input_gives_same_poses(scene):
    scans, _, given, _ = scene
    first = register_scans(scans, given, rounds=2)
    second = register_scans([scan.copy() for scan in scans], given.copy(), rounds=2)
    assert np.array_equal(first.poses, second.poses)
    assert np.array_equal(first.residual_after, second.residual_after, equal_nan=True)


def test_result_is_frozen_and_does_not_alias(scene):
    scans, _, given, _ = scene
    result = register_scans(scans, given, rounds=1)
    assert isinstance(result, Registration) and result.rounds == 1
    assert result.max_distance > 0
    with pytest.raises(ValueError, match="read-only"):
        result.poses[0, 0, 3] = 1.0
    assert not np.shares_memory(result.poses, given)


def test_far_from_origin():
    # 20 km out, 1 cm voxels would overflow small_gicp's 21-bit voxel keys.
    scans, truth, given, centre = make_scene(12, centre=(20_000.0, -5_000.0, 300.0))
    result = register_scans(scans, given)
    angles, shifts = pose_errors(result.poses, truth, centre)
    assert np.all(angles < 0.2), angles
    assert np.all(shifts < 0.002), shifts


def test_scan_that_does_not_overlap_is_refused(scene):
    scans, truth, _, _ = scene
    away = truth.copy()
    away[2, :3, 3] += [0.0, 0.0, 3.0]
    names = ["left.ply", "right.ply", "bun180.ply"]
    with pytest.raises(InputError, match=r"bun180\.ply does not overlap the other scans: 0\.0 %"):
        register_scans(scans, away, names=names)


def test_scans_that_overlap_only_each_other_are_refused(scene):
    # Two pairs of overlapping scans, far apart: each scan overlaps another, but scans 2
    # and 3 cannot be placed relative to scan 0.
    scans, truth, _, _ = scene
    shift = rigid(np.eye(3), [0.0, 0.0, 3.0])
    poses = np.array([truth[0], truth[1], shift @ truth[1], shift @ truth[2]])
    with pytest.raises(InputError, match="scan 2, scan 3 do not overlap scan 0 or the scans"):
        register_scans([scans[0], scans[1], scans[1], scans[2]], poses)


def _bad_poses(truth, kind):
    poses = truth.copy()
    if kind == "scaled":
        poses[1, :3, :3] *= 1.01
    elif kind == "reflected":
        poses[1, :3, 0] *= -1.0
    elif kind == "last row":
        poses[1, 3, 0] = 0.5
    elif kind == "nan":
        poses[1, 0, 3] = np.nan
    return poses


@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("scaled", r"scan 1: the pose's upper-left 3x3 block is not a rotation"),
        ("reflected", r"scan 1: .* not a rotation .* det -1"),
        ("last row", r"scan 1: the pose's last row must be 0 0 0 1"),
        ("nan", r"scan 1: the pose holds non-finite values"),
    ],
)
def test_bad_pose_is_refused(scene, kind, message):
    scans, truth, _, _ = scene
    with pytest.raises(InputError, match=message):
        register_scans(scans, _bad_poses(truth, kind))


@pytest.mark.parametrize(
    ("shape", "message"),
    [((3, 3, 4), "shape \\(S, 4, 4\\)"), ((2, 4, 4), "2 poses for 3 scans"), ((4, 4), "shape")],
)
def test_poses_of_wrong_shape_are_refused(scene, shape, message):
    scans, _, _, _ = scene
    with pytest.raises(InputError, match=message):
        register_scans(scans, np.zeros(shape))


def test_bad_scans_are_refused(scene):
    scans, truth, _, _ = scene
    with pytest.raises(InputError, match="at least 2 scans; got 1"):
        register_scans(scans[:1], truth[:1])
    with pytest.raises(InputError, match="scan 1 has 5 rows; at least 10"):
        register_scans([scans[0], scans[1][:5], scans[2]], truth)
    broken = scans[2].copy()
    broken[7, 1] = np.inf
    with pytest.raises(InputError, match="b.ply contain 1 non-finite values .* row 7"):
        register_scans([scans[0], scans[1], broken], truth, names=["a.ply", "c.ply", "b.ply"])


def test_bad_options_are_refused(scene):
    scans, truth, _, _ = scene
    with pytest.raises(InputError, match="fixed must be a scan index in"):
        register_scans(scans, truth, fixed=3)
    with pytest.raises(InputError, match="min_overlap must be a share"):
        register_scans(scans, truth, min_overlap=5)
    with pytest.raises(InputError, match="max_distance must be a positive number"):
        register_scans(scans, truth, max_distance=-1.0)
    with pytest.raises(InputError, match="names must name each of the 3 scans"):
        register_scans(scans, truth, names=["a", "b"])
