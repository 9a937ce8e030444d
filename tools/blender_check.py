"""Load laughlab's exports in Blender, as a user would: the VRM add-on for Blender and Blender's glTF importer.

    python tools/blender_check.py --addon DIR --vrm AVATAR.vrm --vrma RUN/animation.vrma [--glb RUN/character.glb]

``DIR`` holds the add-on's ``io_scene_vrm`` folder (from saturday06/VRM-Addon-for-Blender, MIT or GPL-3.0;
not part of laughlab).  Blender runs headless (``blender -b``) with a scripts folder made for it in a temporary
directory, so the user's own Blender set-up is untouched.  Checks:

* the add-on imports ``AVATAR.vrm`` (a VRM 1.0 avatar: the add-on imports VRM Animation only onto VRM 1.0
  armatures) and then ``animation.vrma`` onto it: a humanoid action whose bone rotations change over time, and
  expression curves (``vrm1.expressions.preset.*.preview``) that are not all zero;
* Blender's own glTF importer imports ``character.glb`` (``output=gltf character=...``): an armature action and,
  when the avatar has morph targets, a shape-key action.

Prints what Blender found and exits 1 when a check fails.  Needs ``blender`` on PATH (Debian: ``apt-get install
blender python3-numpy``).  Debian's Blender 3.4.1 ships a glTF importer that still uses ``numpy.bool``, which
numpy 1.24 removed: the script restores the alias inside Blender before importing.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

INSIDE = r'''
import json, sys, traceback
import bpy, numpy
numpy.bool = bool  # Debian's Blender 3.4.1: its glTF importer uses numpy.bool (removed in numpy 1.24)
import addon_utils
args = json.loads(sys.argv[sys.argv.index("--") + 1])
out = {}
for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
if args.get("vrma"):
    out["addon"] = addon_utils.enable("io_scene_vrm", default_set=True) is not None
    out["import_vrm"] = sorted(bpy.ops.import_scene.vrm(filepath=args["vrm"]))
    arm = [o for o in bpy.data.objects if o.type == "ARMATURE"][0]
    bpy.context.view_layer.objects.active = arm
    out["import_vrma"] = sorted(bpy.ops.import_scene.vrma(filepath=args["vrma"], armature_object_name=arm.name))
    ad = arm.animation_data
    if ad and ad.action:
        lo, hi = (int(v) for v in ad.action.frame_range)
        out["vrma_frames"] = [lo, hi]
        out["vrma_bone_curves"] = len(ad.action.fcurves)
        moved = {}
        for name in ("spine", "chest", "head"):
            b = arm.pose.bones.get(name)
            if b is None:
                continue
            qs = []
            for f in range(lo, hi + 1, max(1, (hi - lo) // 12)):
                bpy.context.scene.frame_set(f)
                qs.append([round(v, 4) for v in b.rotation_quaternion])
            moved[name] = max(abs(q[i] - qs[0][i]) for q in qs for i in range(4))
        out["vrma_bone_change"] = moved
    dd = arm.data.animation_data
    if dd and dd.action:
        out["vrma_expressions"] = {fc.data_path.split(".")[-2]: round(max(k.co[1] for k in fc.keyframe_points), 3)
                                   for fc in dd.action.fcurves if "expressions" in fc.data_path}
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
if args.get("glb"):
    out["import_glb"] = sorted(bpy.ops.import_scene.gltf(filepath=args["glb"]))
    out["glb_actions"] = {a.name: len(a.fcurves) for a in bpy.data.actions}
    out["glb_shape_key_actions"] = [o.name for o in bpy.data.objects if o.type == "MESH" and o.data.shape_keys
                                    and o.data.shape_keys.animation_data and o.data.shape_keys.animation_data.action]
print("LAUGHLAB-RESULT " + json.dumps(out))
'''


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--addon", required=True, help="folder holding io_scene_vrm (the VRM add-on for Blender)")
    ap.add_argument("--vrm", required=True, help="a VRM 1.0 avatar to import the VRM Animation onto")
    ap.add_argument("--vrma", required=True, help="animation.vrma (output=vrma)")
    ap.add_argument("--glb", help="character.glb (output=gltf character=...)")
    ns = ap.parse_args(argv)
    blender = shutil.which("blender")
    if blender is None:
        print("blender_check: blender is not on PATH (Debian: apt-get install blender python3-numpy)", file=sys.stderr)
        return 2
    addon = Path(ns.addon) / "io_scene_vrm"
    if not (addon / "__init__.py").is_file():
        print(f"blender_check: {addon} is not the VRM add-on's io_scene_vrm folder", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        scripts = Path(tmp) / "scripts"
        shutil.copytree(addon, scripts / "addons" / "io_scene_vrm")
        (Path(tmp) / "inside.py").write_text(INSIDE)
        args = json.dumps({"vrm": str(Path(ns.vrm).resolve()), "vrma": str(Path(ns.vrma).resolve()),
                           "glb": str(Path(ns.glb).resolve()) if ns.glb else None})
        r = subprocess.run([blender, "-b", "-noaudio", "--python", str(Path(tmp) / "inside.py"), "--", args],
                           capture_output=True, text=True, env={**__import__("os").environ,
                                                                "BLENDER_USER_SCRIPTS": str(scripts)})
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("LAUGHLAB-RESULT ")), None)
    if line is None:
        print(r.stdout[-2000:], r.stderr[-2000:], sep="\n", file=sys.stderr)
        print("blender_check: Blender did not finish the checks", file=sys.stderr)
        return 1
    res = json.loads(line.split(" ", 1)[1])
    print(json.dumps(res, indent=1))
    ok = (res.get("import_vrma") == ["FINISHED"] and res.get("vrma_bone_curves", 0) > 0
          and any(v > 1e-3 for v in res.get("vrma_bone_change", {}).values())
          and any(v > 0 for v in res.get("vrma_expressions", {}).values()))
    if ns.glb:
        ok = ok and res.get("import_glb") == ["FINISHED"] and bool(res.get("glb_actions"))
    print("blender_check: " + ("every check passed" if ok else "a check FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
