"""Issue 28: a user's avatar (VRM 0.x, VRM 1.0, humanoid glTF) driven by a run; VRM Animation export."""
import json
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf, open_dict
from scipy.spatial.transform import Rotation

from laughlab.avatar.expressions import ARKIT_TO_VRM, BREATH_DEGREES
from laughlab.avatar.load import MAX_BYTES, AvatarError, load_avatar, local_matrix
from laughlab.avatar.mannequin import mannequin_arkit_glb, mannequin_vrm
from laughlab.avatar.names import JOINT_TO_VRM
from laughlab.avatar.retarget import animated_world, retarget
from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.io.bvh import read_bvh
from laughlab.io.gltf import accessor_array, parse_glb, read_glb
from laughlab.motion.skeleton import HUMANOID, forward_kinematics, global_transforms, rest_pose

ASSETS = Path(__file__).parent / "assets" / "avatars"
GODETTE = ASSETS / "Godette_vrm_v4.vrm"
ROBOT = ASSETS / "debug_robot.vrm"
FRAMES = (0, 61, 137, 239)  # frames of the 4 s run checked (60 fps)


def run(tmp_path, *overrides):
    cfg = compose_config([*overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    with open_dict(cfg):
        cfg.output.pop("plots", None)   # the run's figures: no test here reads them (tests/test_plots_*.py do)
    pipeline.execute(pipeline.build(cfg), tmp_path)
    return tmp_path


@pytest.fixture(scope="module")
def avatars(tmp_path_factory):
    d = tmp_path_factory.mktemp("avatars")
    (d / "mannequin.vrm").write_bytes(mannequin_vrm())
    (d / "mannequin_arkit.glb").write_bytes(mannequin_arkit_glb())
    return d


@pytest.fixture(scope="module")
def vrma_run(tmp_path_factory):
    return run(tmp_path_factory.mktemp("vrma"), "output=vrma", "face=facs", "input.duration_s=4")


def baked(tmp_path_factory, character, name):
    return run(tmp_path_factory.mktemp(name), "output=gltf", "face=facs", "input.duration_s=4",
               f"character={character}")


@pytest.fixture(scope="module")
def godette_run(tmp_path_factory):
    return baked(tmp_path_factory, GODETTE, "godette")


@pytest.fixture(scope="module")
def arkit_run(tmp_path_factory, avatars):
    return baked(tmp_path_factory, avatars / "mannequin_arkit.glb", "arkit")


def file_world(path: Path, frame: int) -> tuple[dict, np.ndarray, dict]:
    """World transforms of every node of a glTF file at ``frame`` of its first animation, composed in Python
    from the file's node hierarchy and animation channels (what a player shows); and the morph weights."""
    doc, binary = read_glb(path)
    local = np.array([local_matrix(n) for n in doc["nodes"]])
    anim = doc["animations"][0]
    weights = {}
    for ch in anim["channels"]:
        s = anim["samplers"][ch["sampler"]]
        v = accessor_array(doc, binary, s["output"])
        node, what = ch["target"]["node"], ch["target"]["path"]
        if what == "rotation":
            scale = np.linalg.norm(local[node, :3, :3], axis=0)
            local[node, :3, :3] = Rotation.from_quat(v[frame].astype(float)).as_matrix() * scale
        elif what == "translation":
            local[node, :3, 3] = v[frame]
        elif what == "weights":
            t = len(accessor_array(doc, binary, s["input"]))
            weights[node] = v.reshape(t, -1)[frame]
    parents = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    world = np.zeros_like(local)
    done = set()

    def solve(i):
        if i in done:
            return world[i]
        world[i] = local[i] if i not in parents else solve(parents[i]) @ local[i]
        done.add(i)
        return world[i]

    for i in range(len(local)):
        solve(i)
    return doc, world, weights


def bvh_world(run_dir: Path):
    sk, motion, _ = read_bvh(run_dir / "motion.bvh")
    return motion, forward_kinematics(HUMANOID, motion) * 0.01


def test_the_test_avatars_load_as_their_kind():
    g, r = load_avatar(GODETTE), load_avatar(ROBOT)
    assert (g.kind, g.facing, len(g.bones)) == ("vrm0", -1, 45)  # VRM 0.x faces -Z
    assert (r.kind, r.facing, len(r.bones)) == ("vrm1", 1, 53)   # VRM 1.0 faces +Z
    # Godette's 0.x presets under 1.0 names, binds with weights 0-1 (the file says 0-100)
    assert {"aa", "ih", "ou", "ee", "oh", "happy", "blink", "blinkLeft", "blinkRight"} <= set(g.expressions)
    face = next(n for n, names in g.morph_names.items() if "ah" in names)
    assert g.expressions["aa"] == [(face, g.morph_names[face].index("ah"), 1.0)]
    assert sorted(g.expressions["happy"]) == [(face, 9, 0.5), (face, 10, 0.25)]


def test_the_mannequin_as_vrm_and_glb_retargets_exactly(avatars, arkit_run, tmp_path):
    """Same proportions, same rest: the avatar's joints are where the BVH's are, to float32 precision."""
    motion, want = bvh_world(arkit_run)
    doc, _, _ = file_world(arkit_run / "character.glb", 0)
    idx = {n["name"]: i for i, n in enumerate(doc["nodes"])}
    for f in FRAMES:
        _, world, _ = file_world(arkit_run / "character.glb", f)
        got = np.array([world[idx[name], :3, 3] for name in HUMANOID.names])
        np.testing.assert_allclose(got, want[f], atol=2e-5)
    # the VRM (bones from its humanoid map, not names) gives the same world positions in memory
    vrm = load_avatar(avatars / "mannequin.vrm")
    world = animated_world(vrm, retarget(vrm, motion[list(FRAMES)]))
    for k, f in enumerate(FRAMES):
        got = np.array([world[k, vrm.bones[JOINT_TO_VRM[n]], :3, 3] for n in HUMANOID.names])
        np.testing.assert_allclose(got, want[f], atol=1e-9)


def _bone_dirs(world, bones, facing, names):
    out = []
    for a, b in names:
        d = world[bones[b], :3, 3] - world[bones[a], :3, 3]
        out.append(d / np.linalg.norm(d) * np.array([facing, 1, facing]))
    return np.array(out)


LIMBS = [("leftUpperArm", "leftLowerArm"), ("leftLowerArm", "leftHand"), ("rightUpperArm", "rightLowerArm"),
         ("rightLowerArm", "rightHand"), ("leftUpperLeg", "leftLowerLeg"), ("leftLowerLeg", "leftFoot"),
         ("rightUpperLeg", "rightLowerLeg"), ("rightLowerLeg", "rightFoot")]
OURS = {v: k for k, v in JOINT_TO_VRM.items()}


@pytest.mark.parametrize("path", [GODETTE, ROBOT], ids=["godette-vrm0", "robot-vrm1"])
def test_other_proportions_follow_the_bvh_limb_by_limb(path, godette_run):
    """Arms and legs point where the BVH's do (the facing undone), within 0.5 degrees; the hips move by the
    BVH's displacement scaled by the leg heights' ratio."""
    motion, want = bvh_world(godette_run)
    av = load_avatar(path)
    moved = retarget(av, motion)
    world = animated_world(av, moved)
    ours = np.array([[want[f, HUMANOID.index(OURS[b])] - want[f, HUMANOID.index(OURS[a])] for a, b in LIMBS]
                     for f in range(len(motion))])
    ours /= np.linalg.norm(ours, axis=-1, keepdims=True)
    for f in FRAMES:
        got = _bone_dirs(world[f], av.bones, av.facing, LIMBS)
        angle = np.degrees(np.arccos(np.clip(np.sum(got * ours[f], axis=1), -1, 1)))
        assert angle.max() < 0.5, (f, angle)
    # the arms really move in this run (else the check above would be empty)
    assert np.degrees(np.arccos(np.clip(np.sum(ours[0] * ours[137], axis=1), -1, 1))).max() > 5
    hips = world[:, av.bones["hips"], :3, 3]
    scale = av.leg_height_m() / 0.93
    step = (want[:, 0] - want[0, 0]) * scale * np.array([av.facing, 1, av.facing])
    np.testing.assert_allclose(hips - hips[0], step, atol=1e-6)


def test_the_trunk_keeps_the_avatars_posture_and_turns_as_the_bvh(godette_run):
    """Godette (no upperChest): her chest turns as laughlab's spine2 (the missing bone falls back to its
    parent), her head as laughlab's head, both from her own rest orientation."""
    motion, _ = bvh_world(godette_run)
    av = load_avatar(GODETTE)
    assert "upperChest" not in av.bones
    world = animated_world(av, retarget(av, motion))
    _, G = global_transforms(HUMANOID, motion)
    F = np.diag([-1.0, 1, -1])
    for bone, joint in (("chest", "spine2"), ("head", "head"), ("spine", "spine")):
        rest = av.rest_world[av.bones[bone], :3, :3]
        for f in FRAMES:
            want = F @ G[f, HUMANOID.index(joint)] @ F.T @ rest
            np.testing.assert_allclose(world[f, av.bones[bone], :3, :3], want, atol=1e-9)


def test_a_missing_neck_and_upper_chest_fall_back_to_the_chest(godette_run, tmp_path):
    """The VRM 1.0 robot without its optional neck and upperChest: its chest takes the deepest missing trunk
    joint's world rotation (laughlab's neck), its head still laughlab's head, from the robot's own rest."""
    motion, _ = bvh_world(godette_run)
    av = load_avatar(_robot_without("neck", tmp_path / "a.vrm"))   # the robot has no upperChest of its own
    assert "neck" not in av.bones and "upperChest" not in av.bones and av.facing == 1
    world = animated_world(av, retarget(av, motion))
    _, G = global_transforms(HUMANOID, motion)
    for bone, joint in (("chest", "neck"), ("head", "head"), ("spine", "spine")):
        rest = av.rest_world[av.bones[bone], :3, :3]
        for f in FRAMES:
            np.testing.assert_allclose(world[f, av.bones[bone], :3, :3], G[f, HUMANOID.index(joint)] @ rest,
                                       atol=1e-9)
    # and the neck really bends in this run (else the chest's check would not tell neck from spine2)
    a, b = G[:, HUMANOID.index("neck")], G[:, HUMANOID.index("spine2")]
    assert np.abs(a[list(FRAMES)] - b[list(FRAMES)]).max() > 1e-3


def test_an_a_pose_avatar_is_turned_into_the_t_pose_first(avatars, godette_run):
    """The mannequin with its arms lowered 40 degrees at rest (an A-pose): the arms still follow the BVH."""
    doc, binary = parse_glb((avatars / "mannequin_arkit.glb").read_bytes())
    for side, s in (("left", -1), ("right", 1)):
        i = next(k for k, n in enumerate(doc["nodes"]) if n["name"] == f"{side}_upper_arm")
        doc["nodes"][i]["rotation"] = [float(x) for x in Rotation.from_euler("z", s * 40, degrees=True).as_quat()]
    from laughlab.io.gltf import Buffer, glb_bytes

    a_pose = avatars / "a_pose.glb"
    a_pose.write_bytes(glb_bytes(doc, Buffer(binary, doc["bufferViews"], doc["accessors"])))
    av = load_avatar(a_pose)
    hand = av.rest_world[av.bones["leftHand"], :3, 3] - av.rest_world[av.bones["leftUpperArm"], :3, 3]
    assert hand[1] < -0.3  # the arm hangs at rest
    motion, want = bvh_world(godette_run)
    world = animated_world(av, retarget(av, motion))
    for f in FRAMES:
        for a, b in LIMBS[:4]:
            d = world[f, av.bones[b], :3, 3] - world[f, av.bones[a], :3, 3]
            o = want[f, HUMANOID.index(OURS[b])] - want[f, HUMANOID.index(OURS[a])]
            np.testing.assert_allclose(d, o, atol=1e-9)  # same bone lengths: same positions


def test_the_baked_laugh_lasts_as_long_as_the_audio(godette_run):
    """A key per frame and one at the audio's end (4.0 s; the last frame is at 239/60 s) holding the last frame, on
    every track of the 'laugh' animation, as in laughlab's own character.glb and the VRMA."""
    doc, binary = read_glb(godette_run / "character.glb")
    anim = doc["animations"][0]
    assert anim["name"] == "laugh" and doc["scenes"][0]["extras"]["laughlab"]["frames"] == 240
    for s in anim["samplers"]:
        t = accessor_array(doc, binary, s["input"])
        v = accessor_array(doc, binary, s["output"]).reshape(len(t), -1)
        assert len(t) == 241 and t[-2] == pytest.approx(239 / 60) and t[-1] == pytest.approx(4.0)
        np.testing.assert_array_equal(v[-1], v[-2])


def test_expressions_follow_the_face_channels(godette_run):
    """Godette has no ARKit morph: her VRM 0.x presets take the documented table, and each morph the sum of
    the expressions bound to it.  Her 'ah' morph is bound by A (weight 1) and Angry (0.25), which is not driven
    (since 2026-11-29: a laugh's lowered brows made VRoid avatars angry)."""
    arkit = np.genfromtxt(godette_run / "face_arkit.csv", delimiter=",", names=True)
    doc, _, _ = file_world(godette_run / "character.glb", 0)
    face = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n and doc["meshes"][n["mesh"]]["name"] == "FaceMesh")
    names = doc["meshes"][doc["nodes"][face]["mesh"]]["primitives"][0]["extras"]["targetNames"]
    for f in FRAMES:
        _, _, w = file_world(godette_run / "character.glb", f)
        ah = np.clip(arkit["jawOpen"][f], 0, 1)
        assert w[face][names.index("ah")] == pytest.approx(ah, abs=1e-6)
        # blink_left: Blink_L (1.0) and Angry (0.25) and Sorrow (0.1); Blink is not driven (split eyes); Blink_L is
        # isBinary in her file: 1 above 0.5, else 0 (review-avatar 8: it took every value between)
        frown = [arkit[k][f] if k in arkit.dtype.names else 0.0 for k in ("mouthFrownLeft", "mouthFrownRight")]
        sad = np.clip(0.5 * frown[0] + 0.5 * frown[1], 0, 1)
        want = np.clip(float(arkit["eyeBlinkLeft"][f] > 0.5) + 0.1 * sad, 0, 1)
        assert w[face][names.index("blink_left")] == pytest.approx(want, abs=1e-6)
    assert arkit["jawOpen"].max() > 0.3 and arkit["eyeBlinkLeft"].max() > 0.5  # the run moves both


def test_arkit_named_morphs_pass_through_by_name(arkit_run):
    arkit = np.genfromtxt(arkit_run / "face_arkit.csv", delimiter=",", names=True)
    channels = np.genfromtxt(arkit_run / "channels.csv", delimiter=",", names=True)
    doc, _, _ = file_world(arkit_run / "character.glb", 0)
    mesh = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)
    names = doc["meshes"][doc["nodes"][mesh]["mesh"]]["extras"]["targetNames"]
    for f in FRAMES:
        _, _, w = file_world(arkit_run / "character.glb", f)
        for name in ("jawOpen", "mouthSmileLeft", "eyeBlinkRight", "cheekSquintLeft"):
            assert w[mesh][names.index(name)] == pytest.approx(np.clip(arkit[name][f], 0, 1), abs=1e-6)
        # the avatar has chest and belly morphs: breathing goes there, not to the bones
        assert w[mesh][names.index("chest")] == pytest.approx(np.clip(channels["chest"][f], 0, 1), abs=1e-6)


def test_the_vrma_holds_the_bvh_the_breathing_and_the_expressions(vrma_run):
    doc, binary = read_glb(vrma_run / "animation.vrma")
    ext = doc["extensions"]["VRMC_vrm_animation"]
    assert ext["specVersion"] == "1.0" and doc["extensionsUsed"] == ["VRMC_vrm_animation"]
    assert set(ext["humanoid"]["humanBones"]) == set(JOINT_TO_VRM.values())
    assert doc["scenes"][0]["extras"]["laughlab"]["audio_duration_s"] == pytest.approx(4.0)
    # the clip lasts as long as the audio: one key at 4.0 s after the last frame's (239/60 s), holding it
    ends = [doc["accessors"][s["input"]]["max"][0] for s in doc["animations"][0]["samplers"]]
    assert ends == pytest.approx([4.0] * len(ends))
    sk, motion, _ = read_bvh(vrma_run / "motion.bvh")
    ch = np.genfromtxt(vrma_run / "channels.csv", delimiter=",", names=True)
    arkit = np.genfromtxt(vrma_run / "face_arkit.csv", delimiter=",", names=True)
    # the breathing on the spine bones, by hand: spine x -2 belly, spine1 x -3 chest + 2 belly, neck x +3 chest
    breathing = motion.copy()
    chest, belly = np.clip(ch["chest"], 0, 1), np.clip(ch["belly"], 0, 1)
    assert BREATH_DEGREES == {"chest": {"spine1": -3.0, "neck": 3.0}, "belly": {"spine": -2.0, "spine1": 2.0}}
    breathing[:, HUMANOID.angle_slice("spine").start + 1] += -2 * belly
    breathing[:, HUMANOID.angle_slice("spine1").start + 1] += -3 * chest + 2 * belly
    breathing[:, HUMANOID.angle_slice("neck").start + 1] += 3 * chest
    assert chest.max() > 0.2
    want = forward_kinematics(HUMANOID, breathing) * 0.01
    bones = {b: v["node"] for b, v in ext["humanoid"]["humanBones"].items()}
    for f in FRAMES:
        _, world, _ = file_world(vrma_run / "animation.vrma", f)
        got = np.array([world[bones[JOINT_TO_VRM[n]], :3, 3] for n in HUMANOID.names])
        np.testing.assert_allclose(got, want[f], atol=2e-5)
        # expressions: the X of each expression node's translation
        for name, node in ((k, v["node"]) for k, v in ext["expressions"]["preset"].items()):
            x = world[node, 0, 3]
            w = np.clip(sum(c * arkit[a][f] for a, c in ARKIT_TO_VRM[name].items() if a in arkit.dtype.names), 0, 1)
            assert x == pytest.approx(w, abs=1e-6), name
    assert "blink" not in ext["expressions"]["preset"]  # the eyes go apart: blinkLeft and blinkRight
    # the rest pose is the VRM T-pose: identity rotations, facing +Z, left = +X
    assert all("rotation" not in n for n in doc["nodes"])
    rest = forward_kinematics(HUMANOID, rest_pose())
    assert rest[HUMANOID.index("left_hand"), 0] > 0


def test_the_same_run_gives_the_same_bytes(tmp_path, vrma_run, godette_run, tmp_path_factory):
    again = run(tmp_path, "output=vrma", "face=facs", "input.duration_s=4")
    assert (again / "animation.vrma").read_bytes() == (vrma_run / "animation.vrma").read_bytes()
    again = baked(tmp_path_factory, GODETTE, "godette-again")
    assert (again / "character.glb").read_bytes() == (godette_run / "character.glb").read_bytes()


def test_the_khronos_validator_finds_no_error(vrma_run, godette_run, arkit_run, tmp_path_factory, tmp_path):
    from test_gltf import validator_issues

    robot = baked(tmp_path_factory, ROBOT, "robot")
    for path, source in ((vrma_run / "animation.vrma", None), (godette_run / "character.glb", GODETTE),
                         (arkit_run / "character.glb", None), (robot / "character.glb", ROBOT)):
        found = validator_issues(path, tmp_path)
        assert found["numErrors"] == 0, (path, found["messages"])
        # warnings only those the avatar file itself has (Godette: the 'VRM' extension's name, its images)
        codes = {m["code"] for m in found["messages"] if m["severity"] <= 1}
        theirs = set() if source is None else {m["code"] for m in validator_issues(source, tmp_path)["messages"]
                                               if m["severity"] <= 1}
        assert codes <= theirs, (path, codes - theirs)


# -- bad input ---------------------------------------------------------------------------------------------------

def _cli(tmp_path, *args):
    from inprocess import laughlab

    return laughlab(*args, f"hydra.run.dir={tmp_path / 'run'}")


def _robot_without(bone: str, path: Path) -> Path:
    doc, binary = parse_glb(ROBOT.read_bytes())
    del doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"][bone]
    from laughlab.io.gltf import Buffer, glb_bytes

    path.write_bytes(glb_bytes(doc, Buffer(binary, doc["bufferViews"], doc["accessors"])))
    return path


def _no_humanoid(path: Path) -> Path:
    doc, binary = parse_glb(ROBOT.read_bytes())
    del doc["extensions"], doc["extensionsUsed"]
    for k, n in enumerate(doc["nodes"]):
        n["name"] = f"part{k}"
    from laughlab.io.gltf import Buffer, glb_bytes

    path.write_bytes(glb_bytes(doc, Buffer(binary, doc["bufferViews"], doc["accessors"])))
    return path


def _robot_edited(edit, path: Path) -> Path:
    """The debug robot (VRM 1.0) with ``edit(doc)`` applied to its document, its buffer as it is."""
    doc, binary = parse_glb(ROBOT.read_bytes())
    edit(doc)
    path.write_bytes(_glb(doc, binary))
    return path


def _glb(doc: dict, binary: bytes) -> bytes:
    import json
    import struct

    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _hips(doc: dict) -> dict:
    return doc["nodes"][doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["hips"]["node"]]


def _root_of(doc: dict, node: int) -> int:
    """The scene root above ``node``."""
    parent = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    while node in parent:
        node = parent[node]
    return node


def test_bones_laughlab_does_not_drive_are_not_checked_and_a_tiny_scale_is_fine(tmp_path):
    """The checks are for the bones laughlab poses: an eye bone on the head's node (some exporters do that) and
    an avatar scaled by 1e-5 overall still load (review: the absolute test refused the second)."""
    def eye_on_head(d):
        d["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["leftEye"] = {"node": _bone_node(d, "head")}

    assert load_avatar(_robot_edited(eye_on_head, tmp_path / "eye.vrm")).bones["leftEye"] == \
        load_avatar(ROBOT).bones["head"]

    def tiny(d):
        d["nodes"][_root_of(d, _bone_node(d, "hips"))]["scale"] = [1e-5] * 3

    load_avatar(_robot_edited(tiny, tmp_path / "tiny.vrm"))


def test_a_tilde_in_the_character_path_is_the_home_folder(tmp_path, monkeypatch):
    """An avatar developer's review: the hint for character=~/x.vrm (zsh leaves the ~) said to quote it, and the
    quoted path was then not found ("~/x.vrm: cannot read the avatar")."""
    home = tmp_path / "home"
    home.mkdir()
    (home / "my robot.vrm").write_bytes(ROBOT.read_bytes())
    monkeypatch.setenv("HOME", str(home))
    out = _cli(tmp_path, "output=gltf", "input.duration_s=1", "detector=none", "character='~/my robot.vrm'")
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "run" / "character.glb").stat().st_size > 0
    assert load_avatar("~/my robot.vrm").bones == load_avatar(ROBOT).bones


def _bone_node(doc: dict, bone: str) -> int:
    return doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"][bone]["node"]


@pytest.mark.parametrize("make, says", [
    (lambda p: p.write_bytes(b"RIFF\0\0\0\0WAVEfmt ") and p, "is not a glTF file"),
    (lambda p: _no_humanoid(p), "has no humanoid: no VRM humanoid bone map and no node named as a Mixamo"),
    (lambda p: _robot_without("leftHand", p), "the VRM humanoid lacks the required bone leftHand"),
    # damaged files (new-user review, 2026-11-27): each wrote a broken character.glb or ended in a traceback
    (lambda p: _robot_edited(lambda d: _hips(d).update(scale=[0, 0, 0]), p),
     "the hips bone (node"),
    (lambda p: _robot_edited(lambda d: d["bufferViews"][0].update(byteOffset=10 ** 9), p),
     "bufferView 0 ends at byte 1,000,"),
    (lambda p: _robot_edited(lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=9999), p),
     "mesh 0 refers to 9999"),
    (lambda p: _robot_edited(lambda d: d["nodes"][_bone_node(d, "head")].setdefault("children", []).append(
        _bone_node(d, "hips")), p), "has two parents"),
    (lambda p: _robot_edited(lambda d: d["nodes"][_bone_node(d, "head")].setdefault("children", []).append(
        _root_of(d, _bone_node(d, "head"))), p), "is its own ancestor (a cycle of children)"),
    (lambda p: _robot_edited(lambda d: d["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["leftHand"].update(
        node=_bone_node(d, "hips")), p), "maps hips and leftHand to the same node"),
    # a bone whose node is not there was "lacks the required bone head", and the bone is there (a review)
    (lambda p: _robot_edited(lambda d: d["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["head"].update(
        node=9999), p), "its humanoid bone head refers to node 9999, which is not there (the file has "),
    # Mixamo's download (an avatar developer's review: "is not a glTF file" sent its user searching)
    (lambda p: (p.with_suffix(".fbx").write_bytes(b"Kaydara FBX Binary  \0\x1a\0") and p.with_suffix(".fbx")),
     "is FBX, which laughlab does not read: export the avatar as glTF binary (.glb) or VRM (.vrm)"),
], ids=["not-gltf", "fbx", "no-humanoid", "vrm-missing-bone", "zero-scale", "view-past-buffer", "accessor-out-of-range",
        "two-parents", "node-cycle", "two-bones-one-node", "bone-node-not-there"])
def test_a_bad_avatar_is_one_line_exit_2_and_nothing_written(tmp_path, make, says):
    path = make(tmp_path / "avatar.glb") or tmp_path / "avatar.glb"
    out = _cli(tmp_path, "output=gltf", "input.duration_s=1", f"character={path}")
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().count("\n") == 0 and "Traceback" not in out.stderr
    # "PATH is not ...", "PATH has no ...", or "PATH: what is wrong in it" (not "PATH: is not", a review)
    assert out.stderr.startswith(f"laughlab: error: {path}") and says in out.stderr, out.stderr
    assert f"{path}: is " not in out.stderr and f"{path}: has " not in out.stderr
    assert not (tmp_path / "run").exists()


def test_stimuli_on_a_bad_avatar_are_one_line_and_nothing_written(tmp_path):
    path = _robot_without("head", tmp_path / "avatar.vrm")
    out = _cli(tmp_path, "experiment=stimuli", f"character={path}")
    assert out.returncode == 2 and out.stderr.strip().count("\n") == 0, out.stderr
    assert "the VRM humanoid lacks the required bone head" in out.stderr and not (tmp_path / "run").exists()


def test_a_very_large_avatar_is_refused_from_its_size(tmp_path):
    big = tmp_path / "big.vrm"
    with open(big, "wb") as fh:  # sparse: 101 MB on paper, nothing on disk
        fh.write(b"glTF")
        fh.truncate(MAX_BYTES + 1024 * 1024)
    with pytest.raises(AvatarError, match=r"big.vrm: the avatar is 106 MB; laughlab loads avatars up to 100 MB"):
        load_avatar(big)
    out = _cli(tmp_path, "output=gltf", "input.duration_s=1", f"character={big}")
    assert out.returncode == 2 and "up to 100 MB" in out.stderr and not (tmp_path / "run").exists()


def test_a_gltf_whose_buffer_file_is_very_large_is_refused_before_it_is_read(tmp_path):
    gltf = tmp_path / "big.gltf"
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "big.bin", "byteLength": 1}]}))
    with open(tmp_path / "big.bin", "wb") as fh:  # sparse, as above
        fh.truncate(MAX_BYTES)
    with pytest.raises(AvatarError, match=r"big.gltf: the avatar with its buffer big.bin is 105 MB; laughlab loads "
                                          r"avatars up to 100 MB"):
        load_avatar(gltf)


def test_breathing_goes_to_the_bones_channel_by_channel():
    """An avatar with a chest morph but no belly one: the chest breathes on the morph, the belly on the spine bones
    (BREATH_DEGREES), not nowhere."""
    from types import SimpleNamespace

    from laughlab.avatar.expressions import breath_on_bones, breathing_pose

    breath = {"chest": np.array([0.5]), "belly": np.array([1.0])}
    ours = {"asset": {"generator": "laughlab mannequin"}}
    # laughlab_chest/laughlab_belly on any avatar; plain chest/belly only on laughlab's own files: elsewhere a
    # 'Chest' morph is a body-shape slider (review-avatar 18: breathing drove it from 0 to 1)
    for morphs, doc, bones in ((["laughlab_Chest", "jawOpen"], {}, {"belly"}),
                               (["laughlab_chest", "LAUGHLAB_BELLY"], {}, set()), ([], {}, {"chest", "belly"}),
                               (["Chest", "belly"], {}, {"chest", "belly"}), (["Chest", "jawOpen"], ours, {"belly"}),
                               (["chest", "BELLY"], ours, set())):
        av = SimpleNamespace(all_morph_names=lambda m=morphs: m, doc=doc)
        assert set(breath_on_bones(av, breath)) == bones, (morphs, doc)
    posed = breathing_pose(np.zeros((1, HUMANOID.n_channels)), breath_on_bones(
        SimpleNamespace(all_morph_names=lambda: ["laughlab_chest"], doc={}), breath), HUMANOID)
    x = {j: posed[0, HUMANOID.angle_slice(j).start + 1] for j in ("spine", "spine1", "neck")}
    assert x == pytest.approx({"spine": -2.0, "spine1": 2.0, "neck": 0.0})   # belly 1.0 only, by hand


def test_a_character_no_output_uses_is_said(tmp_path):
    out = _cli(tmp_path, "input.duration_s=1", f"character={GODETTE}")
    assert out.returncode == 2 and "do not use it" in out.stderr and not (tmp_path / "run").exists()
    # the fix, in the options a user types (a game developer's review: the line named sinks and no fix)
    assert out.stderr.strip().endswith("do not use it: add one, e.g. 'output=[files,gltf]', or leave out character=")
    out = _cli(tmp_path, "input.duration_s=1", "output=vrma", f"character={GODETTE}")
    assert out.returncode == 2 and out.stderr.strip().endswith("animation.vrma (output=vrma) fits any VRM without it")


def test_the_docs_tables_are_the_codes():
    """docs/avatars.md lists every accepted node name and the ARKit -> VRM table exactly as the code has them."""
    from laughlab.avatar.names import NODE_NAMES

    doc = (Path(__file__).parent.parent / "docs" / "avatars.md").read_text()
    for bone, names in NODE_NAMES.items():
        assert f"| `{bone}` | " + ", ".join(f"`{n}`" for n in names) + " |" in doc, bone
    for expr, terms in ARKIT_TO_VRM.items():
        assert f"| `{expr}` | " in doc and " + ".join(f"{w:g} `{k}`" for k, w in terms.items()) + " |" in doc, expr


MIXAMO = {"hips": "Hips", "spine": "Spine", "spine1": "Spine1", "spine2": "Spine2", "neck": "Neck", "head": "Head",
          **{f"{s}_{j}": f"{S}{m}" for s, S in (("left", "Left"), ("right", "Right"))
             for j, m in (("clavicle", "Shoulder"), ("upper_arm", "Arm"), ("forearm", "ForeArm"), ("hand", "Hand"),
                          ("thigh", "UpLeg"), ("shin", "Leg"), ("foot", "Foot"), ("toe", "ToeBase"))}}


def test_a_mixamo_named_gltf_json_is_recognised_and_retargets_exactly(tmp_path, godette_run):
    """The mannequin with Mixamo's node names (``mixamorig:LeftArm``...), as a .gltf JSON with its buffer in a
    data URI: every joint found by name, and its joints where the BVH's are."""
    import base64

    doc, binary = parse_glb(mannequin_arkit_glb())
    for n in doc["nodes"]:
        if n.get("name") in MIXAMO:
            n["name"] = "mixamorig:" + MIXAMO[n["name"]]
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
    path = tmp_path / "mixamo.gltf"
    path.write_text(json.dumps(doc))
    av = load_avatar(path)
    assert av.kind == "gltf" and len(av.bones) == 22 and av.facing == 1
    motion, want = bvh_world(godette_run)
    world = animated_world(av, retarget(av, motion[list(FRAMES)]))
    for k, f in enumerate(FRAMES):
        got = np.array([world[k, av.bones[JOINT_TO_VRM[n]], :3, 3] for n in HUMANOID.names])
        np.testing.assert_allclose(got, want[f], atol=1e-9)


def _robot_as_gltf(folder: Path, uri: str = "robot.bin", cut: int | None = None) -> Path:
    """The robot VRM as a .gltf with its buffer in a file named by ``uri`` (relative to the .gltf), cut to
    ``cut`` bytes if given."""
    doc, binary = parse_glb(ROBOT.read_bytes())
    folder.mkdir(parents=True, exist_ok=True)
    target = (folder / uri)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(binary[:cut] if cut is not None else binary)
    doc["buffers"] = [{"uri": uri, "byteLength": len(binary)}]
    path = folder / "robot.gltf"
    path.write_text(json.dumps(doc))
    return path


def test_a_gltf_reads_only_files_beside_it_and_whole(tmp_path):
    """Found by a new-user review: a buffer URI '../../etc/passwd' copied that file into character.glb and the
    viewer page, and a .bin cut to 1,500 bytes passed output=gltf (and crashed output=video)."""
    assert load_avatar(_robot_as_gltf(tmp_path / "ok")).path.name == "robot.gltf"      # beside it: fine
    outside = _robot_as_gltf(tmp_path / "a" / "b", uri="../../secret.bin")
    with pytest.raises(AvatarError, match=r"robot.gltf: its file '../../secret.bin' lies outside the avatar's folder"):
        load_avatar(outside)
    cut = _robot_as_gltf(tmp_path / "cut", cut=1500)
    with pytest.raises(AvatarError, match=r"robot.gltf: its buffer holds 1,500 bytes where the file declares "):
        load_avatar(cut)
    for path in (outside, cut):
        for output in ("output=gltf", "output=video"):
            out = _cli(tmp_path, output, "input.duration_s=1", f"character={path}")
            assert out.returncode == 2 and out.stderr.strip().count("\n") == 0, out.stderr
            assert not (tmp_path / "run").exists()
