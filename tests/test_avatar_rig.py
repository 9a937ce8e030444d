"""A review of laughlab on users' avatars (2026-11-27, /work/exp/review-avatar.md): the rig. Which nodes are the
bones, which way the avatar faces, which names are recognised; each checked by the joints' world positions
against laughlab's own skeleton (motion.bvh's forward kinematics)."""
import copy
from pathlib import Path

import numpy as np
import pytest

from laughlab.avatar.errors import AvatarError
from laughlab.avatar.load import load_avatar
from laughlab.avatar.mannequin import mannequin_arkit_glb
from laughlab.avatar.names import JOINT_TO_VRM
from laughlab.avatar.retarget import animated_world, retarget
from laughlab.io.gltf import Buffer, glb_bytes, parse_glb
from laughlab.motion.skeleton import HUMANOID, forward_kinematics

#: a few frames of laughlab's skeleton in motion: every joint turned by up to 40 degrees, the hips moved
POSES = np.concatenate([np.random.default_rng(7).uniform(-5, 5, (4, 3)),
                        np.random.default_rng(8).uniform(-40, 40, (4, 3 * HUMANOID.n_joints))], axis=1)


def want_world(poses=POSES) -> np.ndarray:
    """laughlab's joints' world positions (m) for ``poses``."""
    return forward_kinematics(HUMANOID, poses) * 0.01


def got_world(path: Path, turn: np.ndarray = np.eye(3)) -> np.ndarray:
    """The avatar's humanoid joints' world positions (m) after retargeting ``POSES``, turned back by ``turn``."""
    av = load_avatar(path)
    world = animated_world(av, retarget(av, POSES))
    pos = np.stack([world[:, av.bones[JOINT_TO_VRM[n]], :3, 3] for n in HUMANOID.names], axis=1)
    return pos @ turn   # (turn^T p) for each row: the avatar's frame back to laughlab's


def save(doc: dict, binary: bytes, path: Path) -> Path:
    path.write_bytes(glb_bytes(doc, Buffer(binary, doc["bufferViews"], doc["accessors"])))
    return path


def prepend_node(doc: dict, node: dict) -> dict:
    """``doc`` with ``node`` as node 0 (every node reference shifted), a root of the scene."""
    d = copy.deepcopy(doc)
    for n in d["nodes"]:
        if "children" in n:
            n["children"] = [c + 1 for c in n["children"]]
    for s in d.get("skins", []):
        s["joints"] = [j + 1 for j in s["joints"]]
        if "skeleton" in s:
            s["skeleton"] += 1
    for sc in d["scenes"]:
        sc["nodes"] = [c + 1 for c in sc["nodes"]] + [0]
    d["nodes"].insert(0, node)
    return d


# -- 6: bones are joints, not meshes named like them ---------------------------------------------------------------

def test_a_mesh_named_head_is_not_taken_for_the_head_bone(tmp_path):
    """Review 6: a skinned mesh 'Head' listed before the bones took the head bone's place (the first node of the
    name won); the animation then targeted the mesh, which a player ignores, and the head never turned."""
    doc, binary = parse_glb(mannequin_arkit_glb())
    doc = prepend_node(doc, {"name": "Head", "mesh": 0, "skin": 0})
    path = save(doc, binary, tmp_path / "headmesh.glb")
    av = load_avatar(path)
    assert av.bones["head"] != 0 and doc["nodes"][av.bones["head"]]["name"] == "head"
    np.testing.assert_allclose(got_world(path), want_world(), atol=1e-9)


def test_a_skinned_mesh_mapped_as_a_bone_is_one_line(tmp_path):
    """A VRM map (or a name) that puts a driven bone on a skinned mesh node is refused: its animation would move
    nothing."""
    from laughlab.avatar.mannequin import mannequin_vrm

    doc, binary = parse_glb(mannequin_vrm())
    mesh = next(i for i, n in enumerate(doc["nodes"]) if "skin" in n)
    doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["head"] = {"node": mesh}
    path = save(doc, binary, tmp_path / "m.vrm")
    with pytest.raises(AvatarError, match=rf"m.vrm: the head bone is node {mesh}, a skinned mesh .*whose own "
                                          r"transform glTF ignores; map the bone to its joint"):
        load_avatar(path)


# -- 7: an avatar exported facing another way ----------------------------------------------------------------------

def turned(tmp_path: Path, degrees: float) -> tuple[Path, np.ndarray]:
    """The mannequin under a root node turned ``degrees`` about Y (an export with the wrong forward axis), and that
    turn as a matrix."""
    from scipy.spatial.transform import Rotation

    doc, binary = parse_glb(mannequin_arkit_glb())
    rot = Rotation.from_euler("y", degrees, degrees=True)
    scene = doc["scenes"][0]
    doc["nodes"].append({"name": "Root", "rotation": [float(x) for x in rot.as_quat()], "children": scene["nodes"]})
    scene["nodes"] = [len(doc["nodes"]) - 1]
    return save(doc, binary, tmp_path / f"turned{degrees:g}.glb"), rot.as_matrix()


@pytest.mark.parametrize("degrees", [90, -90, 37, 180, 0.5])
def test_an_avatar_turned_any_way_about_y_is_retargeted_exactly(tmp_path, degrees):
    """Review 7: facing was only +Z or -Z, so an avatar facing +X was retargeted as if it faced -Z: its hands 0.77 m
    from where they belong.  Now any yaw: the joints are laughlab's, turned as the avatar is."""
    path, R = turned(tmp_path, degrees)
    np.testing.assert_allclose(got_world(path, R), want_world(), atol=1e-9)


def test_the_video_and_the_viewer_turn_it_to_the_camera_alike(tmp_path):
    """The video's vertices of the turned avatar are the unturned one's; the viewer turns its root by the same
    angle (run.json's avatar.turn, radians about Y)."""
    from laughlab.render.avatar_view import AvatarRenderer
    from laughlab.viewer.server import view_of

    plain = tmp_path / "plain.glb"
    plain.write_bytes(mannequin_arkit_glb())
    path, _ = turned(tmp_path, 90)
    pose = POSES[:1]
    a, b = (AvatarRenderer(load_avatar(p), HUMANOID, 64, 48) for p in (plain, path))
    va, _ = a.vertices(a.worlds(pose)[0], {})
    vb, _ = b.vertices(b.worlds(pose)[0], {})
    np.testing.assert_allclose(vb, va, atol=1e-6)
    assert view_of(load_avatar(path))["turn"] == pytest.approx(-np.pi / 2)
    assert view_of(load_avatar(plain))["turn"] == 0.0


def test_arms_one_above_the_other_are_one_line(tmp_path):
    from laughlab.avatar.load import facing_turn

    with pytest.raises(AvatarError, match=r"a.glb: its upper arms are one above the other in the rest pose"):
        facing_turn(Path("a.glb"), np.array([0.001, 0.3, 0.0]))
    np.testing.assert_array_equal(facing_turn(Path("a.glb"), np.array([-0.24, 0.0, 3e-8])), np.diag([-1.0, 1, -1]))


# -- 17: Unreal, Blender metarig/Rigify and VRoid names ------------------------------------------------------------

TRUNK = ("hips", "spine", "spine1", "spine2", "neck", "head")
RIGS = {
    "unreal": dict(zip(TRUNK, ("pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head")), **{
        f"{s}_{j}": f"{u}_{s[0]}" for s in ("left", "right") for j, u in (
            ("clavicle", "clavicle"), ("upper_arm", "upperarm"), ("forearm", "lowerarm"), ("hand", "hand"),
            ("thigh", "thigh"), ("shin", "calf"), ("foot", "foot"), ("toe", "ball"))}),
    "metarig": dict(zip(TRUNK, ("spine", "spine.001", "spine.002", "spine.003", "spine.004", "spine.006")), **{
        f"{s}_{j}": f"{b}.{s[0].upper()}" for s in ("left", "right") for j, b in (
            ("clavicle", "shoulder"), ("upper_arm", "upper_arm"), ("forearm", "forearm"), ("hand", "hand"),
            ("thigh", "thigh"), ("shin", "shin"), ("foot", "foot"), ("toe", "toe"))}),
    "vroid": dict(zip(TRUNK, ("J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_UpperChest",
                              "J_Bip_C_Neck", "J_Bip_C_Head")), **{
        f"{s}_{j}": f"J_Bip_{s[0].upper()}_{b}" for s in ("left", "right") for j, b in (
            ("clavicle", "Shoulder"), ("upper_arm", "UpperArm"), ("forearm", "LowerArm"), ("hand", "Hand"),
            ("thigh", "UpperLeg"), ("shin", "LowerLeg"), ("foot", "Foot"), ("toe", "ToeBase"))}),
}


@pytest.mark.parametrize("rig", ["unreal", "metarig", "vroid", "rigify-def"])
def test_unreal_metarig_rigify_and_vroid_names_are_recognised(tmp_path, rig):
    """Review 17: metarig.glb lacked 'hips, head, leftUpperArm...' (its root bone 'spine' was taken as VRM spine),
    unreal.glb 'spine, leftUpperLeg...' (spine_01, thigh_l, calf_l unknown).  Every joint is now found, and the
    joints are where laughlab's are.  Rigify's deform bones are the metarig's names with DEF-, beside ORG- copies
    that no skin uses (the skin's joints win)."""
    doc, binary = parse_glb(mannequin_arkit_glb())
    names = RIGS["metarig" if rig == "rigify-def" else rig]
    for n in doc["nodes"]:
        if n.get("name") in names:
            n["name"] = ("DEF-" if rig == "rigify-def" else "") + names[n["name"]]
    if rig == "rigify-def":   # ORG- copies of every bone, not in the skin, listed first
        for name in [doc["nodes"][j]["name"] for j in doc["skins"][0]["joints"]]:
            doc = prepend_node(doc, {"name": name.replace("DEF-", "ORG-")})
        assert sum(n["name"].startswith("ORG-") for n in doc["nodes"]) == 22
    path = save(doc, binary, tmp_path / f"{rig}.glb")
    av = load_avatar(path)
    assert len(av.bones) == 22 and not any(doc["nodes"][i]["name"].startswith("ORG-") for i in av.bones.values())
    np.testing.assert_allclose(got_world(path), want_world(), atol=1e-9)
