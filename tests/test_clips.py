"""The bundled clip library: thesis metadata, plausibility of every motion, playback API."""
import json
import shutil

import numpy as np
import pytest

from laughlab.io.bvh import write_bvh
from laughlab.motion.clips import Clip, ClipLibrary
from laughlab.motion.skeleton import HUMANOID, Skeleton, forward_kinematics, global_transforms
from laughlab_plugins.clips import author

SK = HUMANOID
I = SK.index
THESIS = {  # name: (length_frames, energy), thesis section 5.5
    "lean_front1": (22, 5), "lean_front2": (42, 10), "lean_back1": (22, 5), "lean_back2": (36, 10),
    "clap_hands": (46, 15), "hands_on_belly": (73, 15), "point1": (69, 20), "point2": (78, 20),
    "slap_leg": (80, 25), "stop_it": (79, 30), "rofl": (117, 40),
}
FEET = [I(n) for n in ("left_foot", "left_toe", "right_foot", "right_toe")]


@pytest.fixture(scope="module")
def lib():
    return ClipLibrary.load()


@pytest.fixture(scope="module")
def fk(lib):
    return {c.name: forward_kinematics(SK, c.poses) for c in lib}


def episodes(mask):
    """Number of separate runs of True."""
    m = np.concatenate([[False], mask])
    return int(np.sum(m[1:] & ~m[:-1]))


def test_thesis_metadata(lib):
    assert lib.fps == 24 and lib.skeleton is SK
    assert set(lib.names) == set(THESIS) | {"idle"}
    for name, (length, energy) in THESIS.items():
        c = lib[name]
        assert (c.length_frames, c.energy, c.fps, c.loop) == (length, energy, 24, False)
        assert c.duration_s == pytest.approx(length / 24)
    assert lib.idle.loop and lib.idle.energy == 0 and lib.idle.length_frames == 96


def test_clips_start_and_end_neutral_and_move(lib, fk):
    neutral = forward_kinematics(SK, author.NEUTRAL_POSE)
    for c in lib:
        p = fk[c.name]
        assert np.all(np.isfinite(c.poses)), c.name
        assert np.linalg.norm(p[0] - neutral, axis=-1).max() < 1.0, c.name
        assert np.linalg.norm(p[-1] - neutral, axis=-1).max() < 1.0, c.name
        moved = np.linalg.norm(p - neutral, axis=-1).max()
        assert moved > (0.5 if c.name == "idle" else 12.0), (c.name, moved)
    assert np.linalg.norm(fk["idle"] - neutral, axis=-1).max() < 5.0  # idle stays calm


def test_feet_stay_on_floor(lib, fk):
    for c in lib:
        p = fk[c.name]
        assert p[..., 1].min() > -0.5, c.name
        if c.name != "rofl":
            foot_y = p[:, FEET, 1]
            assert foot_y.min() > 0.5 and foot_y.max() < 15.0, c.name  # planted
            slide = np.abs(p[:, FEET][:, :, [0, 2]] - p[0, FEET][:, [0, 2]]).max()
            assert slide < 2.0, (c.name, slide)


def test_leans(fk):
    for name, sign in (("lean_front1", 1), ("lean_front2", 1), ("lean_back1", -1), ("lean_back2", -1)):
        head_z = fk[name][:, I("head"), 2] - fk[name][:, I("hips"), 2]
        assert (sign * head_z).max() > (12 if name[-1] == "1" else 25), name
    big = lambda n: np.abs(fk[n][:, I("head"), 2]).max()
    assert big("lean_front2") > big("lean_front1") and big("lean_back2") > big("lean_back1")


def test_clap_hands_meet_several_times(fk):
    p = fk["clap_hands"]
    gap = np.linalg.norm(p[:, I("left_hand")] - p[:, I("right_hand")], axis=-1)
    assert episodes(gap < 12.0) >= 3
    together = gap < 12.0
    chest = p[:, I("spine2")]
    assert np.all(p[together, I("left_hand"), 1] > chest[together, 1] - 15)  # in front of the chest
    assert np.all(p[together, I("left_hand"), 2] > chest[together, 2] + 20)


def test_hands_on_belly(lib, fk):
    pos, rot = global_transforms(SK, lib["hands_on_belly"].poses)
    belly = pos[:, I("spine")] + np.einsum("fij,j->fi", rot[:, I("spine")], [0, 2, 13])
    for hand in ("left_hand", "right_hand"):
        d = np.linalg.norm(fk["hands_on_belly"][12:60, I(hand)] - belly[12:60], axis=-1)
        assert d.max() < 16.0, hand


def test_pointing(fk):
    for name, side in (("point1", "right"), ("point2", "left")):
        p = fk[name]
        hand, shoulder = p[:, I(f"{side}_hand")], p[:, I(f"{side}_upper_arm")]
        ext = np.linalg.norm(hand - shoulder, axis=-1)
        forward = hand[:, 2] - shoulder[:, 2]
        pointing = (ext > 50) & (forward > 40)
        assert pointing.sum() > 20, name
    p1 = fk["point1"]
    assert np.any((p1[:, I("right_hand"), 1] > p1[:, I("right_upper_arm"), 1]) & (p1[:, I("right_hand"), 2] > 45))


def test_slap_leg_reaches_thigh(lib, fk):
    pos, rot = global_transforms(SK, lib["slap_leg"].poses)
    thigh = pos[:, I("right_thigh")] + np.einsum("fij,j->fi", rot[:, I("right_thigh")], [0, -22, 8])
    d = np.linalg.norm(fk["slap_leg"][:, I("right_hand")] - thigh, axis=-1)
    assert episodes(d < 10.0) >= 3


def test_stop_it_raised_hand(fk):
    p = fk["stop_it"]
    up = p[:, I("right_hand"), 1] > p[:, I("right_upper_arm"), 1]
    assert up.sum() > 30
    head = p[:, I("head"), 2] - p[:, I("hips"), 2]
    assert head.min() < -8  # leans away


def test_rofl_goes_down_and_up(lib, fk):
    c, p = lib["rofl"], fk["rofl"]
    assert c.poses[:, 1].min() < 60
    knees = p[:, [I("left_shin"), I("right_shin")], 1]
    assert knees.min() < 10  # on the knees
    assert c.poses[-1, 1] > 94


def test_laughter_shake_4_to_5_hz(lib):
    for name in ("hands_on_belly", "slap_leg", "rofl"):
        s = lib[name].poses[:, SK.angle_slice("spine2").start + 1]
        hp = (s - np.convolve(s, np.ones(5) / 5, mode="same"))[5:-5]
        spec = np.abs(np.fft.rfft(hp * np.hanning(len(hp))))
        peak = np.fft.rfftfreq(len(hp), 1 / 24)[spec.argmax()]
        assert 4.0 <= peak <= 5.0, (name, peak)


def test_eyes(lib):
    closed = {c.name: c.eyes_closed_many(np.arange(c.length_frames) / c.fps).mean() for c in lib}
    intense = np.mean([closed[n] for n, (_, e) in THESIS.items() if e >= 25])
    mild = np.mean([closed[n] for n, (_, e) in THESIS.items() if e <= 10])
    assert intense > mild
    for name, side in (("point1", "right"), ("point2", "left")):  # open while pointing
        c = lib[name]
        p = forward_kinematics(SK, c.poses)
        pointing = (p[:, I(f"{side}_hand"), 2] - p[:, I(f"{side}_upper_arm"), 2]) > 40
        assert np.all(c.eyes_closed_many(np.flatnonzero(pointing) / c.fps) == 0.0)
    assert all(c.eyes_closed(c.duration_s) == 0.0 for c in lib)  # clips end with open eyes


def test_sampling():
    poses = np.arange(4 * 3, dtype=float).reshape(4, 3)
    c = Clip("t", 1, 4, 2.0, poses, [(0, 0), (1, 1), (3, 0)])
    np.testing.assert_allclose(c.sample(0.0), poses[0])
    np.testing.assert_allclose(c.sample(0.25), 0.5 * (poses[0] + poses[1]))
    np.testing.assert_allclose(c.sample(10.0), poses[-1])  # clamped
    np.testing.assert_allclose(c.sample_many([0.0, 0.25, 10.0]), [c.sample(0.0), c.sample(0.25), c.sample(10.0)])
    loop = Clip("l", 0, 4, 2.0, poses, loop=True)
    np.testing.assert_allclose(loop.sample(1.75), 0.5 * (poses[3] + poses[0]))  # wraps
    np.testing.assert_allclose(loop.sample(2.25), loop.sample(0.25))
    # eyes: a key starts a ramp that ends ramp frames later (clamped to half the gap to the next key)
    assert c.eyes_closed(0.5 / 2) == 0.0
    assert c.eyes_closed(1.5 / 2) == pytest.approx(0.5)
    assert c.eyes_closed(2.0 / 2) == 1.0 and c.eyes_closed(4.5 / 2) == pytest.approx(0.5)
    assert c.eyes_closed(6.0 / 2) == 0.0
    e = Clip("e", 1, 30, 24.0, np.zeros((30, 3)), [(0, 0), (10, 1), (20, 0)])
    np.testing.assert_allclose(e.eyes_closed_many(np.array([10, 11.5, 13, 19, 21.5, 23]) / 24),
                               [0, 0.5, 1, 1, 0.5, 0])


def test_library_sampling_and_iteration(lib):
    assert list(c.name for c in lib) == list(lib.names) and len(lib) == 12 and "rofl" in lib
    idle = lib.idle
    np.testing.assert_allclose(idle.sample(idle.duration_s + 0.3), idle.sample(0.3))
    with pytest.raises(KeyError, match="no clip"):
        lib["dance"]


def test_library_validation(tmp_path):
    dst = tmp_path / "clips"
    shutil.copytree(author.OUT, dst, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    (dst / "rofl.bvh").unlink()
    with pytest.raises(ValueError, match=r"clip 'rofl'.*not found"):
        ClipLibrary.load(dst)
    small = Skeleton(("hips", "spine"), (-1, 0), [[0, 0, 0], [0, 10, 0]])
    write_bvh(dst / "rofl.bvh", small, np.zeros((117, 9)), 1 / 24)
    with pytest.raises(ValueError, match="channels"):
        ClipLibrary.load(dst)
    meta = json.loads((dst / "library.json").read_text())
    meta["clips"] = [c for c in meta["clips"] if c["name"] != "rofl"]
    (dst / "library.json").write_text(json.dumps(meta))
    assert "rofl" not in ClipLibrary.load(dst)


def test_author_is_byte_identical(tmp_path):
    author.main(tmp_path)
    for f in sorted(author.OUT.glob("*.bvh")) + [author.OUT / "library.json"]:
        assert (tmp_path / f.name).read_bytes() == f.read_bytes(), f.name


def test_contact_sheet(tmp_path, lib):
    from laughlab.render.figure import contact_sheet

    small = ClipLibrary([lib["clap_hands"], lib["rofl"]], lib.skeleton, lib.fps)
    out = contact_sheet(tmp_path / "sheet.png", small, n_frames=3)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_scalar_sample_equals_vectorised():
    from laughlab.motion.clips import ClipLibrary

    lib = ClipLibrary.load()
    rng = np.random.default_rng(0)
    for clip in lib:
        ts = np.r_[-0.5, 0.0, rng.uniform(-0.1, clip.duration_s * 1.5, 50), clip.duration_s]
        many = clip.sample_many(ts)
        eyes = clip.eyes_closed_many(ts)
        for t, row, e in zip(ts, many, eyes):
            assert np.array_equal(clip.sample(float(t)), row)
            assert clip.eyes_closed(float(t)) == e
