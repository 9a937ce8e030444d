"""A review of laughlab on users' avatars (2026-11-27, /work/exp/review-avatar.md): the face and the morphs.

Each test builds its avatar from laughlab's mannequin (``laughlab.avatar.mannequin``) or the test avatars, bakes
a few frames with known ARKit weights and reads the weights back from the baked file."""
from pathlib import Path

import numpy as np

from laughlab.avatar.bake import baked_glb
from laughlab.avatar.load import load_avatar
from laughlab.avatar.mannequin import mannequin_arkit_glb
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
