"""laughlab's own mannequin as an avatar file: an ARKit-named GLB and a VRM 1.0.

``python -m laughlab.avatar.mannequin DIR [--overwrite]`` writes both (``mannequin_arkit.glb``,
``mannequin.vrm``; files of those names already there are replaced only with ``--overwrite``).  They are the mannequin of :mod:`laughlab.character.body` in its rest pose
(no animation): the GLB with its joints named as in ``motion.bvh`` and its morph targets named
after the ARKit blendshapes (the ARKit route of ``docs/avatars.md``); the VRM with a
``VRMC_vrm`` humanoid map, its morphs renamed ``shapeNN`` (so no ARKit name passes through) and
VRM preset expressions bound to them (:data:`PRESET_BINDS`: the VRM-expression route).  Both are
MIT, like the mannequin.
"""
from __future__ import annotations

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


FILES = ("mannequin_arkit.glb", "mannequin.vrm")


def write(out_dir: Path, overwrite: bool = False) -> list[str]:
    """Write :data:`FILES` into ``out_dir`` (made if missing); an existing file is refused unless ``overwrite``
    (it replaced a user's file of that name silently, a review found), and nothing is written then.  Each file
    goes to a ``.part`` first and is renamed, so a failure leaves no half-written one."""
    from laughlab.core.errors import LaughlabError

    out_dir = Path(out_dir)
    there = [f for f in FILES if (out_dir / f).exists()]
    if there and not overwrite:
        raise LaughlabError(f"{out_dir / there[0]} exists; pass --overwrite to replace "
                            f"{'it' if len(there) == 1 else ' and '.join(there)}, or give another folder")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        for name, data in zip(FILES, (mannequin_arkit_glb(), mannequin_vrm())):
            part = out_dir / f".{name}.part"
            part.write_bytes(data)
            part.replace(out_dir / name)
    except OSError as exc:
        raise LaughlabError(f"cannot write the mannequin into {out_dir} ({exc.strerror or exc})") from None
    return list(FILES)


def main(argv: list[str] | None = None) -> None:
    import sys

    from laughlab.core.errors import LaughlabError, one_line_parser

    ap = one_line_parser(prog="python -m laughlab.avatar.mannequin",
                         description="Write laughlab's mannequin as mannequin_arkit.glb and mannequin.vrm.")
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--overwrite", action="store_true", help="replace those two files if the folder has them")
    try:
        args = ap.parse_args(argv)
        written = write(args.out_dir, args.overwrite)
    except LaughlabError as exc:
        print(f"laughlab: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    print(json.dumps({"written": written}))


if __name__ == "__main__":
    main()
