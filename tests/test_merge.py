"""Several scans into one cloud: pose files, matching poses to scans, merging, one sheet."""

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from zeroset import PointCloud, io, reconstruct
from zeroset._rigid import transform
from zeroset.cli import main
from zeroset.errors import InputError
from zeroset.evaluate import compare_to_reference
from zeroset.merge import match_poses, merge_scans
from zeroset.synthetic import sample_sphere


def _pose(rotvec, translation):
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    pose[:3, 3] = translation
    return pose


POSES = [_pose([0.1, -0.2, 0.3], [1.0, 2.0, 3.0]), _pose([0.0, 0.0, 1.2], [-0.5, 0.0, 0.25])]


def test_stanford_conf_puts_scan_points_at_the_conjugate_rotation_plus_translation(tmp_path):
    quaternion = Rotation.from_rotvec([0.2, 0.5, -0.1]).as_quat()  # x, y, z, w
    t = [0.01, -0.02, 0.03]
    path = tmp_path / "scans.conf"
    path.write_text(
        "camera 0 0 -0.7 0 1 0 0\n"
        f"bmesh a.ply {' '.join(map(str, t))} {' '.join(map(str, quaternion))}\n"
        "bmesh b 0 0 0 0 0 0 1\n"
    )
    names, poses = io.read_poses(path)
    assert names == ["a.ply", "b"]
    p = np.array([[0.1, 0.2, 0.3]])
    expected = Rotation.from_quat(quaternion).inv().apply(p) + t
    np.testing.assert_allclose(transform(poses[0], p), expected, atol=1e-12)
    np.testing.assert_array_equal(poses[1], np.eye(4))


def test_json_and_csv_poses_named_or_in_order(tmp_path):
    named = tmp_path / "named.json"
    named.write_text(json.dumps({"s1.ply": POSES[0].tolist(), "s2.ply": POSES[1].tolist()}))
    ordered = tmp_path / "ordered.json"
    ordered.write_text(json.dumps([pose.tolist() for pose in POSES]))
    table = tmp_path / "poses.csv"
    rows = [",".join(["name"] + [f"m{i}{j}" for i in range(4) for j in range(4)])]
    rows += [
        ",".join([name, *map(str, pose.ravel().tolist())])
        for name, pose in zip("ab", POSES, strict=True)
    ]
    table.write_text("\n".join(rows) + "\n")
    for path, names in [(named, ["s1.ply", "s2.ply"]), (ordered, None), (table, ["a", "b"])]:
        read_names, poses = io.read_poses(path)
        assert read_names == names
        np.testing.assert_allclose(poses, POSES, atol=1e-12)


def test_poses_match_scans_by_file_name_then_by_stem():
    scans = ["dir/b.ply", "a.ply"]
    matched = match_poses(scans, ["a.ply", "b"], np.array(POSES), source="p.conf")
    np.testing.assert_array_equal(matched, [POSES[1], POSES[0]])
    with pytest.raises(InputError, match=r"p.conf: has no pose for c.ply"):
        match_poses(["c.ply"], ["a.ply"], np.array(POSES[:1]), source="p.conf")
    with pytest.raises(InputError, match="2 unnamed poses for 3 scans"):
        match_poses(["a", "b", "c"], None, np.array(POSES), source="p.json")


@pytest.mark.parametrize(
    "suffix, text, message",
    [
        (".conf", "bmesh a.ply 0 0 0 0 0 0\n", "line 1: expected 'bmesh NAME"),
        (".conf", "bmesh a.ply 0 0 0 0 0 0 zero\n", "line 1: could not convert"),
        (".conf", "bmesh a.ply 0 0 0 0 0 0 0\n", "quaternion is zero"),
        (".conf", "camera 0 0 0 0 0 0 1\n", "holds no 'bmesh' pose"),
        (".json", "{", "not valid JSON"),
        (".json", '{"a": [[1, 0], [0, 1]]}', "a: expected a 4x4 matrix"),
        (".json", json.dumps([np.diag([2.0, 2.0, 2.0, 1.0]).tolist()]), "is not a rotation"),
        (
            ".json",
            json.dumps([[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]]]),
            "0 0 0 1",
        ),
        (".csv", "1,2,3\n", "16 numbers"),
    ],
)
def test_malformed_pose_files_are_named_in_one_line(tmp_path, suffix, text, message):
    path = tmp_path / f"poses{suffix}"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as error:
        io.read_poses(path)
    assert str(error.value).startswith(str(path))


def test_merging_moves_points_normals_and_sensors_into_one_frame(rng):
    a = PointCloud(points=rng.normal(size=(5, 3)), normals=np.tile([0.0, 0.0, 1.0], (5, 1)))
    b = PointCloud(
        points=rng.normal(size=(4, 3)),
        normals=np.tile([1.0, 0.0, 0.0], (4, 1)),
        viewpoints=np.tile([0.0, 0.0, 9.0], (4, 1)),
    )
    merged = merge_scans([a, b], POSES)
    np.testing.assert_allclose(merged.points[:5], transform(POSES[0], a.points))
    np.testing.assert_allclose(merged.normals[5:], np.tile(POSES[1][:3, 0], (4, 1)))
    # A scan without sensor positions was seen from its frame's origin; a file's own move.
    np.testing.assert_allclose(merged.viewpoints[:5], np.tile(POSES[0][:3, 3], (5, 1)))
    np.testing.assert_allclose(merged.viewpoints[5:], transform(POSES[1], b.viewpoints))
    # Without poses, a sensor nobody gave is unknown: NaN rows.
    unposed = merge_scans([a, b])
    assert np.isnan(unposed.viewpoints[:5]).all() and np.isfinite(unposed.viewpoints[5:]).all()
    assert merge_scans([a, a]).viewpoints is None


def _seen(n, sensor, radius, noise, rng):
    """Points of a sphere that a sensor sees within 75 degrees, with noise along the beam."""
    p = sample_sphere(n, radius=radius, rng=rng).points
    beam = p - sensor
    distance = np.linalg.norm(beam, axis=1)
    p = p[np.einsum("ij,ij->i", p / radius, -beam) > 0.25 * distance]
    beam = (p - sensor) / np.linalg.norm(p - sensor, axis=1)[:, None]
    return p + beam * rng.normal(0.0, noise, size=(p.shape[0], 1)), np.broadcast_to(sensor, p.shape)


def _facet_area(mesh, keep):
    v, f = mesh.vertices, mesh.faces
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    return area[keep(v[f].mean(axis=1))].sum()


@pytest.mark.parametrize("offset", [0.003, 0.006])
def test_overlapping_scans_of_different_density_make_one_sheet(offset):
    # Two scans of a sphere (radius 0.5 m, range noise 1 mm), the second a quarter as dense
    # and displaced by `offset` (3 and 6 times the noise): where they overlap, one surface.
    rng = np.random.default_rng(7)
    radius, noise = 0.5, 0.001
    a, va = _seen(60_000, np.array([2.0, 0.0, 0.0]), radius, noise, rng)
    b, vb = _seen(15_000, np.array([0.0, 2.0, 0.0]), radius, noise, rng)
    b = b + offset * np.array([0.6, 0.0, 0.8])
    result = reconstruct(np.vstack([a, b]), viewpoints=np.vstack([va, vb]))
    mesh = result.mesh
    assert result.stats["mesh_components"] == 1 and result.stats["boundary_loops"] == 1

    def overlap(c):
        unit = c / np.linalg.norm(c, axis=1)[:, None]
        return (unit[:, 0] > 0.5) & (unit[:, 1] > 0.5)

    truth = sample_sphere(200_000, radius=radius, rng=8).points
    true_area = 4 * np.pi * radius**2 * np.mean(overlap(truth))
    # A second sheet would double the area; the surface lies between the two scans.
    assert abs(_facet_area(mesh, overlap) / true_area - 1.0) < 0.05
    inside = overlap(mesh.vertices)
    off_surface = np.abs(np.linalg.norm(mesh.vertices[inside], axis=1) - radius)
    assert np.percentile(off_surface, 99) < offset + 3 * noise
    assert result.orientation.disagreement < 0.01


BUNNY = Path(__file__).resolve().parents[2] / "shared" / "data" / "stanford_bunny"


@pytest.mark.skipif(not BUNNY.is_dir(), reason="the shared Stanford bunny scans are not here")
@pytest.mark.slow
def test_stanford_bunny_scans_with_their_poses_match_the_reference(tmp_path):
    # Ten Cyberware range scans with bun.conf; the scanner looks along -z of each scan
    # frame, so its position there is given as 0,0,1 (a metre up the z axis).
    scans = sorted(BUNNY.glob("data/*.ply"))
    out, report = tmp_path / "bunny.ply", tmp_path / "report.json"
    poses = ["--poses", str(BUNNY / "data" / "bun.conf"), "--viewpoint", "0,0,1"]
    code = main(["reconstruct", *map(str, scans), *poses, "-o", str(out), "--report", str(report)])
    assert code == 0 and len(scans) == 10
    mesh = io.read_mesh(out)
    reference = io.read_mesh(BUNNY / "reconstruction" / "bun_zipper.ply")
    scores = compare_to_reference(mesh, reference, n_samples=50_000)
    # The scans' noise is 50-60 micrometres and their poses agree to about 0.3 mm.
    assert scores["accuracy"]["mean"] < 1.5e-4 and scores["completeness"]["mean"] < 1.5e-4
    assert scores["thresholds"][1]["f_score"] > 0.99  # within 0.5 % of the diagonal (1.25 mm)
    assert scores["normal_consistency"] > 0.97
    stats = json.loads(report.read_text())["stats"]
    assert stats["mesh_components"] == 1 and stats["orientation_disagreement"] < 0.01
