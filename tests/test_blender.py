"""A run's motion.bvh and character.glb imported by Blender itself, headless, with the options docs/pipeline.md
gives ("In Blender"): frame rate and range, the skeleton upright, every joint's rotation and every ARKit shape key
equal to laughlab's own files.  Slow (Blender starts twice); skipped where ``blender`` is not on PATH or its Python
has no numpy (Debian: ``apt-get install blender python3-numpy``)."""
import json
import os
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.io.bvh import read_bvh
from laughlab.motion.skeleton import global_transforms

pytestmark = pytest.mark.slow

#: what ``import laughlab`` sets for numpy and OpenBLAS (laughlab/_kernels.py): not for Blender's numpy
KERNEL_VARS = ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")
#: laughlab's frame k is the BVH import's frame k + 1 and the glTF import's frame k (seconds x scene rate)
FRAMES = (0, 45, 90, 150, 200)
#: laughlab's world (Y up, facing +Z) in Blender's (Z up, facing -Y): x -> x, y -> z, z -> -y
C = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)

INSIDE = r'''
import json, sys
import bpy
import numpy
numpy.bool = bool  # Debian's Blender 3.4.1: its glTF importer uses numpy.bool (removed in numpy 1.24)
if bpy.app.version < (3, 5, 0) and sys.version_info >= (3, 11):
    import builtins  # Debian's Blender 3.4.1 on Python 3.11: its BVH importer opens files with mode 'rU'
    _open = builtins.open
    builtins.open = lambda f, mode="r", *a, **k: _open(f, mode.replace("U", ""), *a, **k)
args = json.loads(sys.argv[sys.argv.index("--") + 1])
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
print("LAUGHLAB-IMPORT", flush=True)
if args["kind"] == "bvh":
    res = bpy.ops.import_anim.bvh(filepath=args["path"], global_scale=0.01, update_scene_fps=True,
                                  update_scene_duration=True)
else:
    scene.render.fps, scene.render.fps_base = args["fps"], 1.0  # the docs: the run's rate before importing
    res = bpy.ops.import_scene.gltf(filepath=args["path"])
print("LAUGHLAB-IMPORTED", flush=True)
arm = [o for o in scene.objects if o.type == "ARMATURE"][0]
out = {"result": sorted(res), "fps": scene.render.fps, "fps_base": scene.render.fps_base,
       "frame_end": scene.frame_end, "action_range": list(arm.animation_data.action.frame_range),
       "rest": {b.name: {"parent": b.parent.name if b.parent else None, "length": b.length,
                         "head": list(arm.matrix_world @ b.head_local),
                         "matrix": [list(r) for r in (arm.matrix_world @ b.matrix_local).to_3x3()]}
                for b in arm.data.bones},
       "pose": {}, "keys": {}}
meshes = [o for o in scene.objects if o.type == "MESH" and o.data.shape_keys]
for f in args["frames"]:
    scene.frame_set(f)
    out["pose"][f] = {p.name: [list(r) for r in arm.matrix_world @ p.matrix] for p in arm.pose.bones}
    if meshes:
        out["keys"][f] = {k.name: k.value for k in meshes[0].data.shape_keys.key_blocks}
print("LAUGHLAB-RESULT " + json.dumps(out))
'''


def blender_with_numpy() -> str | None:
    exe = shutil.which("blender")
    if exe is None:
        return None
    r = subprocess.run([exe, "-b", "-noaudio", "--factory-startup", "--python-expr", "import numpy"],
                       capture_output=True, text=True, timeout=120)
    return exe if "ModuleNotFoundError" not in r.stdout + r.stderr else None


@pytest.fixture(scope="module")
def blender():
    exe = blender_with_numpy()
    if exe is None:
        pytest.skip("needs blender with numpy in its Python (Debian: apt-get install blender python3-numpy)")
    return exe


@pytest.fixture(scope="module")
def facs_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("blender")
    cfg = compose_config(["output=gltf", "face=facs", "input.duration_s=4"])
    pipeline.execute(pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])),
                     out)
    return out


def import_in_blender(blender, tmp_path, kind: str, path, frames) -> tuple[dict, str]:
    """What Blender made of the file, and what it printed while importing it."""
    script = tmp_path / "inside.py"
    script.write_text(INSIDE)
    args = json.dumps({"kind": kind, "path": str(path), "fps": 60, "frames": list(frames)})
    env = {k: v for k, v in os.environ.items() if k not in KERNEL_VARS}  # Blender's own numpy picks its kernels
    r = subprocess.run([blender, "-b", "-noaudio", "--factory-startup", "--python", str(script), "--", args],
                       capture_output=True, text=True, timeout=600, env=env)
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("LAUGHLAB-RESULT ")), None)
    assert line is not None, r.stdout[-3000:] + r.stderr[-3000:]
    said = r.stdout.split("LAUGHLAB-IMPORT\n", 1)[-1].split("LAUGHLAB-IMPORTED", 1)[0]
    return json.loads(line.split(" ", 1)[1]), said


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two rotation matrices (chordal: exact for small angles, unlike an arccos of the trace)."""
    return float(np.degrees(2 * np.arcsin(min(1.0, np.linalg.norm(a - b) / (2 * np.sqrt(2))))))


def check_skeleton(res: dict, run_dir, offset: int) -> None:
    """Every joint's world rotation away from its rest, and its world position, equal laughlab's forward
    kinematics of motion.bvh at each frame; the skeleton upright (Z up) and facing Blender's front (-Y)."""
    sk, motion, _ = read_bvh(run_dir / "motion.bvh")
    pos, rot = global_transforms(sk, motion)
    rest = res["rest"]
    assert set(sk.names) <= set(rest)
    assert all(rest[n]["parent"] == (sk.names[p] if p >= 0 else None) for n, p in zip(sk.names, sk.parents))
    assert min(rest[n]["length"] for n in sk.names) > 0.005  # metres: no zero-length bone
    assert rest["head"]["head"][2] - rest["hips"]["head"][2] == pytest.approx(0.60, abs=1e-4)  # upright: 60 cm up
    assert rest["head"]["head"][1] == pytest.approx(-0.01, abs=1e-4)  # the head's 1 cm forward is Blender's -Y
    for f, pose in res["pose"].items():
        k = int(f) - offset
        for j, n in enumerate(sk.names):
            p = np.array(pose[n])
            g = C.T @ (p[:3, :3] @ np.linalg.inv(np.array(rest[n]["matrix"]))) @ C
            assert rotation_error_deg(g, rot[k, j]) < 0.01, (f, n)
            assert np.linalg.norm(p[:3, 3] - 0.01 * C @ pos[k, j]) < 1e-4, (f, n)  # 0.1 mm


def test_blender_imports_the_bvh_at_the_runs_rate_and_pose(blender, facs_run, tmp_path):
    res, log = import_in_blender(blender, tmp_path, "bvh", facs_run / "motion.bvh", [k + 1 for k in FRAMES])
    metrics = json.loads((facs_run / "metrics.json").read_text())
    assert res["result"] == ["FINISHED"] and not any(w in log for w in ("Error", "Warning", "Traceback")), log
    assert (res["fps"], res["fps_base"]) == (metrics["fps"], 1.0)
    assert res["action_range"] == [1.0, float(metrics["n_frames"])]
    assert res["frame_end"] >= metrics["n_frames"]
    check_skeleton(res, facs_run, offset=1)


def test_blender_imports_the_glb_with_its_pose_and_arkit_shape_keys(blender, facs_run, tmp_path):
    res, log = import_in_blender(blender, tmp_path, "gltf", facs_run / "character.glb", FRAMES)
    metrics = json.loads((facs_run / "metrics.json").read_text())
    assert res["result"] == ["FINISHED"] and not any(w in log for w in ("Error", "Warning", "Traceback")), log
    duration = metrics["duration_s"]
    assert res["action_range"] == pytest.approx([0.0, duration * 60], abs=1e-3)  # the key at the audio's end
    check_skeleton(res, facs_run, offset=0)
    face = pd.read_csv(facs_run / "face_arkit.csv")
    channels = pd.read_csv(facs_run / "channels.csv")
    for f, keys in res["keys"].items():
        for name in [c for c in face.columns if c != "time"]:
            assert keys[name] == pytest.approx(face[name].iloc[int(f)], abs=1e-5), (f, name)
        for name in ("chest", "belly"):
            assert keys[name] == pytest.approx(channels[name].iloc[int(f)], abs=1e-5), (f, name)
