"""laughlab's own mannequin as an avatar file: an ARKit-named GLB and a VRM 1.0.

``python -m laughlab.avatar.mannequin DIR`` writes both (``mannequin_arkit.glb``,
``mannequin.vrm``).  They are the mannequin of :mod:`laughlab.character.body` in its rest pose
(no animation): the GLB with its joints named as in ``motion.bvh`` and its morph targets named
after the ARKit blendshapes (the ARKit route of ``docs/avatars.md``); the VRM with a
``VRMC_vrm`` humanoid map, its morphs renamed ``shapeNN`` (so no ARKit name passes through) and
VRM preset expressions bound to them (:data:`PRESET_BINDS`: the VRM-expression route).  Both are
MIT, like the mannequin.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from laughlab.avatar.names import JOINT_TO_VRM
from laughlab.character.body import build
from laughlab.io.gltf import Buffer, character_glb, glb_bytes, parse_glb
from laughlab.motion.skeleton import HUMANOID, rest_pose

#: VRM preset expression -> the mannequin's ARKit morphs it moves (weight 1 each)
PRESET_BINDS: dict[str, tuple[str, ...]] = {
    "aa": ("jawOpen",), "ih": ("mouthLowerDownLeft", "mouthLowerDownRight"),
    "ee": ("mouthStretchLeft", "mouthStretchRight"), "happy": ("mouthSmileLeft", "mouthSmileRight"),
    "relaxed": ("cheekSquintLeft", "cheekSquintRight"), "sad": ("mouthFrownLeft", "mouthFrownRight"),
    "angry": ("browDownLeft", "browDownRight"), "surprised": ("browInnerUp", "browOuterUpLeft", "browOuterUpRight"),
    "blink": ("eyeBlinkLeft", "eyeBlinkRight"), "blinkLeft": ("eyeBlinkLeft",), "blinkRight": ("eyeBlinkRight",),
}


def mannequin_arkit_glb() -> bytes:
    """The mannequin in its rest pose, joints named as in ``motion.bvh``, ARKit-named morphs (no animation)."""
    c = build(HUMANOID)
    data = character_glb(c, np.zeros(1), rest_pose(HUMANOID)[None], np.zeros((1, len(c.morph_names))),
                         audio_duration_s=0.0, fps=60.0, generator="laughlab mannequin")
    return _without_animation(data)


def _without_animation(data: bytes) -> bytes:
    doc, binary = parse_glb(data)
    samplers = doc["animations"][0]["samplers"]
    used = {s["input"] for s in samplers} | {s["output"] for s in samplers}
    keep = [i for i in range(len(doc["accessors"])) if i not in used]
    assert keep == list(range(len(keep))), "the animation's accessors come last"
    doc.pop("animations")
    doc["scenes"][0].pop("extras", None)
    buf = Buffer()
    for i in keep:  # the accessors the mesh uses, copied in order
        acc, view = doc["accessors"][i], doc["bufferViews"][doc["accessors"][i]["bufferView"]]
        buf.data += b"\0" * (-len(buf.data) % 4)
        buf.views.append({**view, "byteOffset": len(buf.data)})
        buf.data += binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]]
        buf.accessors.append({**acc, "bufferView": len(buf.views) - 1})
    return glb_bytes(doc, buf)


def mannequin_vrm() -> bytes:
    """The mannequin as a VRM 1.0: humanoid map, ``shapeNN`` morphs, preset expressions bound to them."""
    doc, binary = parse_glb(mannequin_arkit_glb())
    names = doc["meshes"][0]["extras"]["targetNames"]
    doc["meshes"][0]["extras"]["targetNames"] = [f"shape{k:02d}" for k in range(len(names))]
    mesh_node = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)
    bones = {JOINT_TO_VRM[n["name"]]: {"node": i} for i, n in enumerate(doc["nodes"]) if n.get("name") in JOINT_TO_VRM}
    presets = {e: {"morphTargetBinds": [{"node": mesh_node, "index": names.index(m), "weight": 1.0} for m in ms],
                   "isBinary": False} for e, ms in PRESET_BINDS.items()}
    doc["extensionsUsed"] = ["VRMC_vrm"]
    doc["extensions"] = {"VRMC_vrm": {
        "specVersion": "1.0",
        "meta": {"name": "laughlab mannequin", "version": "1", "authors": ["laughlab"],
                 "licenseUrl": "https://vrm.dev/licenses/1.0/", "avatarPermission": "everyone",
                 "commercialUsage": "corporation", "creditNotation": "unnecessary", "allowRedistribution": True,
                 "modification": "allowModificationRedistribution",
                 "otherLicenseUrl": "https://opensource.org/licenses/MIT"},
        "humanoid": {"humanBones": bones},
        "expressions": {"preset": presets},
    }}
    buf = Buffer(binary, doc["bufferViews"], doc["accessors"])
    return glb_bytes(doc, buf)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m laughlab.avatar.mannequin",
                                 description="Write laughlab's mannequin as mannequin_arkit.glb and mannequin.vrm.")
    ap.add_argument("out_dir", type=Path)
    args = ap.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    (args.out_dir / "mannequin_arkit.glb").write_bytes(mannequin_arkit_glb())
    (args.out_dir / "mannequin.vrm").write_bytes(mannequin_vrm())
    print(json.dumps({"written": ["mannequin_arkit.glb", "mannequin.vrm"]}))


if __name__ == "__main__":
    main()
