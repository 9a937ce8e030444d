"""Skeleton, forward kinematics and BVH read/write."""

import numpy as np
import pytest
from bvh import Bvh
from scipy.spatial.transform import Rotation

from laughlab.io.bvh import read_bvh, write_bvh
from laughlab.motion.skeleton import (HUMANOID, Skeleton, euler_to_matrix, forward_kinematics, matrix_to_euler,
                               rest_pose)

SK = HUMANOID
I = SK.index


def pose_with(**angles):
    pose = rest_pose(SK)
    for name, a in angles.items():
        pose[SK.angle_slice(name)] = a
    return pose


def test_humanoid_layout():
    assert SK.n_joints == 22 and SK.n_channels == 69
    names = SK.channel_names()
    assert names[:4] == ["hips_Xposition", "hips_Yposition", "hips_Zposition", "hips_Zrotation"]
    assert names[4:6] == ["hips_Xrotation", "hips_Yrotation"] and len(names) == 69
    pos = forward_kinematics(SK, rest_pose(SK), end_sites=True)
    assert pos[I("hips"), 1] == pytest.approx(95.0)
    assert pos[SK.n_joints + SK.leaves().index(I("head")), 1] == pytest.approx(175.0)  # head_end
    assert 0.0 <= pos[:, 1].min() <= 2.0  # feet on the floor
    left = [j for j, n in enumerate(SK.names) if n.startswith("left_")]
    right = [I(SK.names[j].replace("left_", "right_")) for j in left]
    np.testing.assert_allclose(pos[left] * [-1, 1, 1], pos[right])
    assert pos[I("left_hand"), 0] > 0  # character faces +Z, its left is +X
    with pytest.raises(KeyError):
        I("tail")


def test_fk_hand_computed():
    shoulder = np.array([17.0, 142.0, 0.0])
    # Z +90 on the left upper arm: the arm (rest +X) points up
    p = forward_kinematics(SK, pose_with(left_upper_arm=(90, 0, 0)))
    np.testing.assert_allclose(p[I("left_forearm")], shoulder + [0, 28, 0], atol=1e-9)
    np.testing.assert_allclose(p[I("left_hand")], shoulder + [0, 53, 0], atol=1e-9)
    # Y -90 swings it forward (+Z); X +90 on the spine bends forward
    p = forward_kinematics(SK, pose_with(left_upper_arm=(0, 0, -90), spine=(0, 90, 0)))
    np.testing.assert_allclose(p[I("spine1")], [0, 105, 12], atol=1e-9)
    np.testing.assert_allclose(p[I("neck")], [0, 105, 41], atol=1e-9)
    # order Rz @ Rx @ Ry: Y acts first, so (90, 0, 90) sends +X to -Z (not to +Y)
    p = forward_kinematics(SK, pose_with(left_upper_arm=(90, 0, 90)))
    np.testing.assert_allclose(p[I("left_forearm")], shoulder + [0, 0, -28], atol=1e-9)
    # root translation moves everything
    pose = pose_with()
    pose[:3] = [10, 100, -5]
    np.testing.assert_allclose(forward_kinematics(SK, pose)[I("head")], [10, 160, -4], atol=1e-9)


def test_euler_matches_scipy_and_inverts():
    rng = np.random.default_rng(0)
    a = rng.uniform([-180, -89, -180], [180, 89, 180], (200, 3))
    np.testing.assert_allclose(euler_to_matrix(a), Rotation.from_euler("ZXY", a, degrees=True).as_matrix(),
                               atol=1e-12)
    np.testing.assert_allclose(matrix_to_euler(euler_to_matrix(a)), a, atol=1e-9)


def test_fk_vectorised_matches_single():
    rng = np.random.default_rng(1)
    poses = rest_pose(SK) + rng.normal(0, 30, (7, SK.n_channels))
    batch = forward_kinematics(SK, poses, end_sites=True)
    for k in range(7):
        np.testing.assert_allclose(batch[k], forward_kinematics(SK, poses[k], end_sites=True))


def test_bvh_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    motion = rest_pose(SK) + rng.normal(0, 40, (50, SK.n_channels))
    path = write_bvh(tmp_path / "m.bvh", SK, motion, 1 / 24)
    sk, back, ft = read_bvh(path)
    assert sk == SK and sk.names == SK.names
    np.testing.assert_allclose(sk.end_sites[sk.leaves()], SK.end_sites[SK.leaves()])
    np.testing.assert_allclose(back, np.round(motion, 4), atol=1e-9)
    assert ft == pytest.approx(1 / 24, abs=1e-7)
    assert [p.name for p in tmp_path.iterdir()] == ["m.bvh"]  # atomic write left no temp file
    text = path.read_text()
    assert "-0.0000" not in text and text.endswith("\n")
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" in text


def test_bvh_parses_with_pypi_bvh(tmp_path):
    motion = np.tile(rest_pose(SK), (30, 1))
    motion[:, 5] = np.linspace(0, 45, 30)
    path = write_bvh(tmp_path / "m.bvh", SK, motion, 1 / 24)
    mocap = Bvh(path.read_text())
    assert mocap.get_joints_names() == list(SK.names)
    assert mocap.nframes == 30 and mocap.frame_time == pytest.approx(1 / 24, abs=1e-6)
    assert mocap.joint_channels("hips") == ["Xposition", "Yposition", "Zposition",
                                            "Zrotation", "Xrotation", "Yrotation"]
    assert mocap.joint_channels("left_forearm") == ["Zrotation", "Xrotation", "Yrotation"]
    assert mocap.frame_joint_channel(29, "hips", "Yrotation") == pytest.approx(45.0)
    assert mocap.joint_offset("left_forearm") == (28.0, 0.0, 0.0)


def _blender_scene_rate(frame_time: float) -> tuple[int, float]:
    """What Blender's BVH importer sets with Update Scene FPS (io_anim_bvh ``_update_scene_fps``): the scene's
    ``fps`` (an int) and ``fps_base`` (a 32-bit float), from ``1 / Frame Time``."""
    new_fps = 1.0 / frame_time
    fps = int(round(new_fps))
    return fps, float(np.float32(fps / new_fps))


@pytest.mark.parametrize("fps", [24, 25, 30, 50, 60, 120, 240])
def test_the_frame_time_gives_blender_the_runs_frame_rate_exactly(tmp_path, fps):
    """Blender's BVH importer takes the scene rate from ``1 / Frame Time``: 7 decimals (0.0166667) gave a
    60 fps run ``fps_base`` 1.000002, a scene at 59.99988 fps.  Both writers (``write_bvh``, the run's
    streaming ``bvh`` sink) write the same line, read here by laughlab's reader and PyPI's ``bvh``."""
    from types import SimpleNamespace

    from laughlab_plugins.sink_bvh import BvhSink

    write_bvh(tmp_path / "w.bvh", SK, np.tile(rest_pose(SK), (2, 1)), 1 / fps)
    sink = BvhSink()
    sink.open(SimpleNamespace(out_dir=tmp_path / "run", fps=float(fps), skeleton=SK, n_frames=None))
    sink.write(SimpleNamespace(poses=np.tile(rest_pose(SK), (2, 1))))
    sink.close()
    for path in (tmp_path / "w.bvh", tmp_path / "run" / "motion.bvh"):
        frame_time = read_bvh(path)[2]
        assert Bvh(path.read_text()).frame_time == frame_time
        assert _blender_scene_rate(frame_time) == (fps, 1.0), path.name


def test_non_dfs_order_round_trips_by_name(tmp_path):
    sk = Skeleton(("root", "a", "b", "a_tip"), (-1, 0, 0, 1), [[0, 0, 0], [10, 0, 0], [-10, 0, 0], [0, 5, 0]])
    motion = np.array([[1, 2, 3, 0, 0, 0, 90, 0, 0, 0, 30, 0, 0, 0, 45]], float)
    sk2, m2, _ = read_bvh(write_bvh(tmp_path / "x.bvh", sk, motion, 0.1))
    assert sk2.names == ("root", "a", "a_tip", "b")
    p1, p2 = forward_kinematics(sk, motion)[0], forward_kinematics(sk2, m2)[0]
    for j, n in enumerate(sk.names):
        np.testing.assert_allclose(p1[j], p2[sk2.index(n)], atol=1e-4)


def test_read_other_rotation_order(tmp_path):
    text = """HIERARCHY
ROOT r
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
  JOINT j
  {
    OFFSET 0 10 0
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
1 2 3 30 40 50 10 20 -30
0 0 0 0 0 0 0 0 0
"""
    (tmp_path / "o.bvh").write_text(text)
    sk, m, ft = read_bvh(tmp_path / "o.bvh")
    np.testing.assert_allclose(m[0, :3], [1, 2, 3])
    np.testing.assert_allclose(euler_to_matrix(m[0, 3:6]), Rotation.from_euler("XYZ", [30, 40, 50], degrees=True).as_matrix(), atol=1e-9)
    np.testing.assert_allclose(euler_to_matrix(m[0, 6:9]), Rotation.from_euler("YXZ", [10, 20, -30], degrees=True).as_matrix(), atol=1e-9)
    np.testing.assert_allclose(sk.end_sites[1], [0, 5, 0])
    assert ft == pytest.approx(1 / 30, abs=1e-6)


@pytest.mark.parametrize("old,new,line", [
    ("OFFSET 0.0000 10.0000 0.0000", "OFFSET 0.0000 ten 0.0000", 8),
    ("JOINT spine\n", "JIONT spine\n", 6),
    ("Frames: 3", "Frames: 4", None),
])
def test_read_malformed_raises_with_line(tmp_path, old, new, line):
    path = write_bvh(tmp_path / "m.bvh", SK, np.tile(rest_pose(SK), (3, 1)), 1 / 24)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ValueError, match=r"line \d+") as err:
        read_bvh(path)
    assert "\n" not in str(err.value)
    if line is not None:
        assert f"line {line}:" in str(err.value)


def test_bad_motion_value_names_line(tmp_path):
    path = write_bvh(tmp_path / "m.bvh", SK, np.tile(rest_pose(SK), (3, 1)), 1 / 24)
    lines = path.read_text().splitlines()
    lines[-2] = lines[-2].replace("95.0000", "nope", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=f"line {len(lines) - 1}: non-numeric"):
        read_bvh(path)


def test_write_rejects_wrong_width(tmp_path):
    with pytest.raises(ValueError, match="channels"):
        write_bvh(tmp_path / "m.bvh", SK, np.zeros((2, 10)), 1 / 24)


@pytest.mark.slow
def test_write_36000_frames(tmp_path):
    """A 25-minute take at 24 fps is written whole (its speed: benchmarks/bench_pipeline.py)."""
    motion = np.random.default_rng(3).normal(0, 50, (36000, SK.n_channels))
    write_bvh(tmp_path / "big.bvh", SK, motion, 1 / 24)
    lines = (tmp_path / "big.bvh").read_text().splitlines()
    k = lines.index("MOTION")
    assert lines[k + 1].split() == ["Frames:", "36000"] and len(lines) - k - 3 == 36000
    np.testing.assert_allclose(np.array(lines[-1].split(), float), motion[-1], atol=1e-3)
