"""A review of laughlab on users' avatars (2026-11-27, /work/exp/review-avatar.md): the face and the morphs.

Each test builds its avatar from laughlab's mannequin (``laughlab.avatar.mannequin``) or the test avatars, bakes
a few frames with known ARKit weights and reads the weights back from the baked file."""
from pathlib import Path

import numpy as np
import pytest

from laughlab.avatar.bake import baked_glb
from laughlab.avatar.load import load_avatar
from laughlab.avatar.mannequin import mannequin_arkit_glb, mannequin_vrm
from laughlab.io.gltf import Buffer, accessor_array, glb_bytes, parse_glb
from laughlab.motion.skeleton import HUMANOID, rest_pose

ASSETS = Path(__file__).parent / "assets" / "avatars"
GODETTE = ASSETS / "Godette_vrm_v4.vrm"


def save(doc: dict, binary: bytes, path: Path) -> Path:
    path.write_bytes(glb_bytes(doc, Buffer(binary, doc["bufferViews"], doc["accessors"])))
    return path


def edited(make, edit, path: Path) -> Path:
    """``make()``'s glb bytes with ``edit(doc)`` applied, written to ``path``."""
    doc, binary = parse_glb(make() if callable(make) else Path(make).read_bytes())
    edit(doc)
    return save(doc, binary, path)


#: three frames of ARKit weights and breathing
ARKIT = {"jawOpen": np.array([0.0, 0.5, 1.0]), "mouthSmileLeft": np.array([0.2, 0.4, 0.9]),
         "mouthSmileRight": np.array([0.1, 0.3, 0.7]), "eyeBlinkLeft": np.array([0.0, 0.6, 0.3]),
         "eyeBlinkRight": np.array([0.0, 0.7, 0.2]), "browDownLeft": np.array([0.3, 0.0, 0.1])}
BREATH = {"chest": np.array([0.1, 0.2, 0.3]), "belly": np.array([0.0, 0.5, 1.0])}


def bake(path: Path, arkit=ARKIT, breath=BREATH) -> tuple[dict, dict]:
    """The avatar at ``path`` baked with 3 frames; its document and node -> weights (frames, targets) as
    written in the file (the last key, held to the audio's end, dropped)."""
    av = load_avatar(path)
    data = baked_glb(av, HUMANOID, np.arange(3) / 60, np.tile(rest_pose(), (3, 1)), arkit, breath,
                     audio_duration_s=3 / 60, fps=60.0)
    doc, binary = parse_glb(data)
    anim = doc["animations"][0]
    out = {}
    for ch in anim["channels"]:
        if ch["target"]["path"] == "weights":
            s = anim["samplers"][ch["sampler"]]
            t = accessor_array(doc, binary, s["input"])
            out[ch["target"]["node"]] = accessor_array(doc, binary, s["output"]).reshape(len(t), -1)[:3]
    return doc, out


def mesh_node(doc: dict) -> int:
    return next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)


# -- 1: morphs the run does not drive keep the avatar's default weights ---------------------------------------

def test_morphs_not_driven_keep_the_mesh_and_node_default_weights(tmp_path):
    """Review 1: a weights channel sets every target of its node, and laughlab wrote 0 for those it does not
    drive, so a shape key left at 0.6 in Blender (mesh.weights) went to 0; node.weights wins over mesh.weights."""
    def edit(doc):
        names = doc["meshes"][0]["extras"]["targetNames"]
        names[names.index("mouthFrownLeft")] = "noseSize"
        doc["meshes"][0]["weights"] = [0.0] * len(names)
        doc["meshes"][0]["weights"][names.index("noseSize")] = 0.6
        doc["meshes"][0]["weights"][names.index("jawOpen")] = 0.9   # driven: the run's value, not this

    path = edited(mannequin_arkit_glb, edit, tmp_path / "default.glb")
    doc, w = bake(path)
    node = mesh_node(doc)
    names = doc["meshes"][0]["extras"]["targetNames"]
    np.testing.assert_allclose(w[node][:, names.index("noseSize")], 0.6, atol=1e-7)
    np.testing.assert_allclose(w[node][:, names.index("jawOpen")], ARKIT["jawOpen"], atol=1e-7)
    np.testing.assert_allclose(w[node][:, names.index("chest")], BREATH["chest"], atol=1e-7)
    # an ARKit-named target the face does not give (tongue, pucker...) keeps its default too (here 0)
    assert "mouthPucker" not in ARKIT and w[node][:, names.index("mouthFrownRight")].max() == 0.0

    def on_node(doc):   # the node's own weights win over the mesh's
        edit(doc)
        n = len(doc["meshes"][0]["weights"])
        doc["nodes"][mesh_node(doc)]["weights"] = [0.25] * n

    doc, w = bake(edited(mannequin_arkit_glb, on_node, tmp_path / "node.glb"))
    np.testing.assert_allclose(w[node][:, names.index("noseSize")], 0.25, atol=1e-7)


def test_a_mesh_with_no_driven_morph_gets_no_weights_channel(tmp_path):
    """Review 1: unrelated morph names (Fuse-style 'MouthOpen') got an all-zero weights track; now no track, so a
    player shows the mesh's own weights."""
    def edit(doc):
        doc["meshes"][0]["extras"]["targetNames"] = [f"Shape_{k}" for k in
                                                     range(len(doc["meshes"][0]["extras"]["targetNames"]))]
        doc["meshes"][0]["weights"] = [0.3] * len(doc["meshes"][0]["extras"]["targetNames"])

    doc, w = bake(edited(mannequin_arkit_glb, edit, tmp_path / "fuse.glb"))
    assert w == {}
    # the video draws it with those weights
    from laughlab.avatar.expressions import morph_weights

    av = load_avatar(tmp_path / "fuse.glb")
    got = morph_weights(av, ARKIT, BREATH, 3)
    np.testing.assert_allclose(got[mesh_node(doc)], 0.3)


# -- 4: ARKit's raw names ---------------------------------------------------------------------------------------

def test_arkit_raw_names_are_driven_as_the_swift_names(tmp_path):
    """Review 4: ARKit's BlendShapeLocation raw values (eyeBlink_L, mouthSmile_R, ...) were not recognised: only
    jawOpen, browInnerUp and the breathing moved."""
    import re

    def edit(doc):
        doc["meshes"][0]["extras"]["targetNames"] = [
            re.sub(r"(Left|Right)$", lambda m: "_" + m.group(1)[0], n) for n in doc["meshes"][0]["extras"]["targetNames"]]

    doc, w = bake(edited(mannequin_arkit_glb, edit, tmp_path / "raw.glb"))
    names = doc["meshes"][0]["extras"]["targetNames"]
    node = mesh_node(doc)
    assert "eyeBlink_L" in names and "mouthSmile_R" in names
    for raw, arkit in (("eyeBlink_L", "eyeBlinkLeft"), ("eyeBlink_R", "eyeBlinkRight"), ("mouthSmile_L", "mouthSmileLeft"),
                       ("mouthSmile_R", "mouthSmileRight"), ("browDown_L", "browDownLeft"), ("jawOpen", "jawOpen")):
        np.testing.assert_allclose(w[node][:, names.index(raw)], ARKIT[arkit], atol=1e-7)
    from laughlab.avatar.expressions import arkit_morph

    assert [arkit_morph(n) for n in ("eyeBlink_Left", "blendShape1.cheekSquint_R", "EYEBLINK_l", "chest_L")] == \
        ["eyeBlinkLeft", "cheekSquintRight", "eyeBlinkLeft", None]


# -- 5 and 9: ARKit morphs and VRM expressions decided expression by expression; the line saying which -----------

def test_one_arkit_named_morph_does_not_switch_off_the_vrm_expressions(tmp_path):
    """Review 5: Godette with her unused HideBlush morph renamed tongueOut lost every expression (the choice was
    all-or-nothing): no mouth, blink or smile.  Now she laughs as before; and an ARKit morph that is an input of an
    expression takes its weight itself, the expression being left out (no double drive)."""
    def tongue(doc):
        prim = next(p for m in doc["meshes"] for p in m["primitives"] if (p.get("extras") or {}).get("targetNames"))
        prim["extras"]["targetNames"][2] = "tongueOut"

    plain_doc, plain = bake(GODETTE)
    doc, w = bake(edited(GODETTE, tongue, tmp_path / "tongue.vrm"))
    assert plain and set(w) == set(plain)
    for node in w:
        np.testing.assert_array_equal(w[node], plain[node])   # tongueOut is not driven by laughlab's faces
    assert max(v.max() for v in w.values()) > 0.5

    def blink_morph(doc):   # her left-eye blink morph renamed as ARKit's: it takes eyeBlinkLeft, blinkLeft is out
        prim = next(p for m in doc["meshes"] for p in m["primitives"] if (p.get("extras") or {}).get("targetNames"))
        names = prim["extras"]["targetNames"]
        names[names.index("blink_left")] = "eyeBlinkLeft"

    from laughlab.avatar.expressions import face_route, used_expressions

    path = edited(GODETTE, blink_morph, tmp_path / "blink.vrm")
    av = load_avatar(path)
    assert "blinkLeft" not in used_expressions(av, ARKIT) and "happy" in used_expressions(av, ARKIT)
    doc, w = bake(path)
    node = next(n for n, names in av.morph_names.items() if "eyeBlinkLeft" in names)
    k = av.morph_names[node].index("eyeBlinkLeft")
    np.testing.assert_allclose(w[node][:, k], ARKIT["eyeBlinkLeft"], atol=1e-7)
    assert face_route(av)["line"].startswith("face: ") and "1 ARKit-named morph and the VRM expressions aa" in \
        face_route(av)["line"]


@pytest.mark.parametrize("edit, says", [
    # said before the run's face gives anything: laughlab's faces together (a review read it as the run's own count)
    (None, "face: up to 10 of 15 morphs of {name} driven by laughlab's faces together (this run's face: counted in "
           "metrics.json for a video, in character.glb's scenes[0].extras.laughlab.face for output=gltf), through the "
           "VRM expressions aa, ih, ee, happy, relaxed, sad, "
           "blinkLeft, blinkRight"),
    (lambda d: d["extensions"]["VRM"]["blendShapeMaster"].update(blendShapeGroups=[]),
     "face: 0 of 15 morphs of {name} driven: no ARKit-named morph and no VRM expression laughlab maps"),
])
def test_the_run_says_in_one_line_how_the_face_drives_the_avatar(tmp_path, edit, says):
    """Review 9: a face laughlab cannot drive was silent.  Now one line at start-up says the route and how many
    morphs move, and character.glb's extras hold the counts.  (    Godette without her blend shape groups has no expression: 0 morphs.)"""
    from inprocess import laughlab

    path = tmp_path / "face.glb"
    edited(GODETTE, edit, path) if edit else path.write_bytes(GODETTE.read_bytes())
    out = laughlab("output=gltf", "face=facs", "input.duration_s=1", f"character={path}", "~output.plots",
                   f"hydra.run.dir={tmp_path / 'run'}")
    assert out.returncode == 0, out.stderr
    said = [ln for ln in out.stderr.splitlines() if ln.startswith("laughlab: face: ")]
    assert len(said) == 1 and said[0].startswith(f"laughlab: {says.format(name=path.name)}"), out.stderr
    doc, _ = parse_glb((tmp_path / "run" / "character.glb").read_bytes())
    face = doc["scenes"][0]["extras"]["laughlab"]["face"]
    weights = [w for ch, w in _weights(doc, tmp_path / "run" / "character.glb")]
    moving = sum(int((w.max(axis=0) > w.min(axis=0)).sum()) for w in weights)
    assert face["morphs"] == 15 and (face["morphs_driven"] == moving == 0 if edit else 0 < moving <= face[
        "morphs_driven"] == 8), (face, moving)   # face=facs: aa, ih, ee, happy, relaxed and the blinks (angry: no more)


def _weights(doc, path):
    _, binary = parse_glb(path.read_bytes())
    anim = doc["animations"][0]
    for ch in anim["channels"]:
        if ch["target"]["path"] == "weights":
            s = anim["samplers"][ch["sampler"]]
            t = accessor_array(doc, binary, s["input"])
            yield ch, accessor_array(doc, binary, s["output"]).reshape(len(t), -1)


# -- 8: the VRM rules overrideBlink/overrideMouth and isBinary -----------------------------------------------------

def _mannequin_vrm_with(tmp_path, rules: dict) -> tuple[Path, list]:
    """The mannequin as a VRM 1.0 with ``rules`` merged into its preset expressions; and its ARKit names by morph
    index (the VRM's morphs are named shapeNN)."""
    names = parse_glb(mannequin_arkit_glb())[0]["meshes"][0]["extras"]["targetNames"]

    def edit(doc):
        for name, rule in rules.items():
            doc["extensions"]["VRMC_vrm"]["expressions"]["preset"][name].update(rule)

    return edited(mannequin_vrm, edit, tmp_path / "rules.vrm"), names


def test_vrm_override_and_is_binary_rules_are_applied(tmp_path):
    """Review 8: happy with overrideBlink block and overrideMouth blend still let the eyes close and the jaw open
    through it, and an isBinary blink took every value between 0 and 1; three-vrm, playing the run's
    animation.vrma, applies the rules, so the run's two files disagreed."""
    path, names = _mannequin_vrm_with(tmp_path, {"happy": {"overrideBlink": "block", "overrideMouth": "blend"},
                                                 "blinkRight": {"isBinary": True}})
    doc, w = bake(path)
    m = w[mesh_node(doc)]
    happy = np.clip(0.5 * ARKIT["mouthSmileLeft"] + 0.5 * ARKIT["mouthSmileRight"], 0, 1)
    assert (happy > 0).all()
    np.testing.assert_allclose(m[:, names.index("eyeBlinkLeft")], 0.0)          # blocked while happy > 0
    np.testing.assert_allclose(m[:, names.index("eyeBlinkRight")], 0.0)         # binary and overridden: 0
    np.testing.assert_allclose(m[:, names.index("jawOpen")], ARKIT["jawOpen"] * (1 - happy), atol=1e-7)  # blend
    np.testing.assert_allclose(m[:, names.index("mouthSmileLeft")], happy, atol=1e-7)   # happy itself as it was

    doc, w = bake(_mannequin_vrm_with(tmp_path, {"blinkLeft": {"isBinary": True}})[0])
    m = w[mesh_node(doc)]
    np.testing.assert_array_equal(m[:, names.index("eyeBlinkLeft")], [0.0, 1.0, 0.0])   # 0, 0.6, 0.3 -> 1 above 0.5
    np.testing.assert_allclose(m[:, names.index("eyeBlinkRight")], ARKIT["eyeBlinkRight"], atol=1e-7)
    np.testing.assert_allclose(m[:, names.index("jawOpen")], ARKIT["jawOpen"], atol=1e-7)   # no override: as is


def test_a_binary_overrider_acts_through_its_binary_value(tmp_path):
    """VRMC_vrm-1.0 expressions.md, 'Interaction between override and isBinary': a binary happy (0.15, 0.35, 0.8:
    0, 0, 1) blending the blink suppresses it only where it is 1."""
    path, names = _mannequin_vrm_with(tmp_path, {"happy": {"overrideBlink": "blend", "isBinary": True}})
    doc, w = bake(path)
    m = w[mesh_node(doc)]
    np.testing.assert_allclose(m[:, names.index("eyeBlinkLeft")], ARKIT["eyeBlinkLeft"] * [1, 1, 0], atol=1e-7)
    np.testing.assert_allclose(m[:, names.index("mouthSmileLeft")], [0, 0, 1], atol=1e-7)


# -- 18: a body-shape slider named Chest is not a breathing morph --------------------------------------------------

def test_a_chest_slider_is_left_alone_and_the_spine_breathes(tmp_path):
    """Review 18: breathing drove any morph named chest or belly from 0 to 1 over its value (a character creator's
    'Chest' slider), and the spine did not breathe.  Only laughlab's own files keep plain chest/belly (the
    mannequin below, as test_avatar's ARKit run shows); other avatars name them laughlab_chest/laughlab_belly."""
    from laughlab.avatar.expressions import breath_on_bones

    def slider(doc):
        doc["asset"]["generator"] = "Blender glTF exporter"
        names = doc["meshes"][0]["extras"]["targetNames"]
        doc["meshes"][0]["weights"] = [0.0] * len(names)
        doc["meshes"][0]["weights"][names.index("chest")] = 0.4

    path = edited(mannequin_arkit_glb, slider, tmp_path / "slider.glb")
    doc, w = bake(path)
    names = doc["meshes"][0]["extras"]["targetNames"]
    node = mesh_node(doc)
    np.testing.assert_allclose(w[node][:, names.index("chest")], 0.4, atol=1e-7)   # the avatar's own value
    assert set(breath_on_bones(load_avatar(path), BREATH)) == {"chest", "belly"}   # both breathe on the spine

    def renamed(doc):
        slider(doc)
        names = doc["meshes"][0]["extras"]["targetNames"]
        names[names.index("chest")] = "laughlab_chest"

    doc, w = bake(edited(mannequin_arkit_glb, renamed, tmp_path / "renamed.glb"))
    np.testing.assert_allclose(w[node][:, names.index("chest")], BREATH["chest"], atol=1e-7)
    # laughlab's own mannequin file keeps its chest and belly morphs breathing
    doc, w = bake(edited(mannequin_arkit_glb, lambda d: None, tmp_path / "ours.glb"))
    np.testing.assert_allclose(w[node][:, names.index("belly")], BREATH["belly"], atol=1e-7)
    # a review: a user's avatar once baked is stamped "laughlab (avatar: ...)"; loaded again (character= a run's
    # character.glb, view --character), its slider must stay the user's, and a baked mannequin keeps breathing
    for made, kept in ((path, True), (tmp_path / "ours.glb", False)):
        again = tmp_path / f"again-{made.stem}.glb"
        again.write_bytes(baked_glb(load_avatar(made), HUMANOID, np.arange(3) / 60, np.tile(rest_pose(), (3, 1)),
                                    ARKIT, BREATH, audio_duration_s=3 / 60, fps=60.0))
        assert parse_glb(again.read_bytes())[0]["asset"]["generator"].startswith("laughlab (avatar: ")
        doc, w = bake(again)
        want = 0.4 if kept else BREATH["chest"]
        np.testing.assert_allclose(w[node][:, names.index("chest")], want, atol=1e-7)


def test_a_laughs_lowered_brows_do_not_make_a_vrm_avatar_angry():
    """A facial animator's review: face=facs lowers the brows in the laugh's squint (AU4 with AU6), and the table
    turned that into VRM 'angry' at 0.40-0.57 on VRoid avatars laughing (a whole angry face). 'angry' is not driven,
    in a VRM Animation or on an avatar; ARKit-named brow morphs still take browDown."""
    from laughlab.avatar.expressions import ARKIT_TO_VRM, expression_weights

    n = 5
    arkit = {"browDownLeft": np.ones(n), "browDownRight": np.ones(n), "mouthSmileLeft": np.ones(n),
             "mouthSmileRight": np.ones(n)}
    assert "angry" not in ARKIT_TO_VRM
    w = expression_weights(None, arkit, n)
    assert "angry" not in w and np.all(w["happy"] == 1.0)
    w = expression_weights(load_avatar(GODETTE), arkit, n)
    assert "angry" not in w and np.all(w["happy"] == 1.0)
