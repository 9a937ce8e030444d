"""VRM Animation (``.vrma``, glTF 2.0 with ``VRMC_vrm_animation`` 1.0) of a run.

The file holds laughlab's own skeleton in the VRM T-pose (facing +Z, left = +X, identity rest
rotations; metres), its 22 joints mapped to VRM humanoid bones (:data:`JOINT_TO_VRM`), and one
animation, ``laugh``:

* the hips' translation and every joint's rotation per frame (the BVH's ZXY Euler angles as
  quaternions; since the rest rotations are identity, these are the normalised humanoid
  rotations three-vrm-animation and the VRM add-on for Blender apply to any VRM);
* the breathing (``chest``, ``belly``) on the spine bones (:data:`BREATH_DEGREES`), since a VRM
  Animation has no body morphs;
* one node per VRM preset expression of :data:`ARKIT_TO_VRM`, whose translation's X is the
  expression's weight per frame (the extension's convention), from the face's ARKit weights;
* ``scenes[0].extras.laughlab``: fps, frames and the input audio's duration (s); the animation's
  keys run from 0 to the audio's duration (the last frame held to the audio's end, one more key),
  so a player's clip lasts exactly as long as the sound it plays beside.

It does not depend on any avatar: the player retargets it.  Same run, same bytes.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from laughlab.avatar.expressions import breathing_pose, expression_weights
from laughlab.avatar.names import JOINT_TO_VRM
from laughlab.io.gltf import Buffer, glb_bytes, hold_to_end
from laughlab.io.vmc import euler_zxy_to_quat
from laughlab.motion.skeleton import HIPS_HEIGHT_CM, Skeleton


def vrma_bytes(skeleton: Skeleton, times_s: np.ndarray, poses: np.ndarray, arkit: Mapping[str, np.ndarray],
               breath: Mapping[str, np.ndarray], audio_duration_s: float, fps: float,
               generator: str = "laughlab") -> bytes:
    """The ``.vrma`` bytes (see the module's docstring)."""
    times = np.asarray(times_s, dtype=np.float32)
    poses = breathing_pose(np.asarray(poses, dtype=np.float64), breath, skeleton)
    frames, jn = len(times), skeleton.n_joints
    if frames == 0 or poses.shape != (frames, skeleton.n_channels):
        raise ValueError(f"VRM Animation export needs F times and (F, {skeleton.n_channels}) poses; got {frames}, "
                         f"{poses.shape}")
    times, poses, arkit = hold_to_end(times, audio_duration_s, poses, arkit)
    f = len(times)
    buf = Buffer()
    nodes, bones = [], {}
    for j in range(jn):
        p = skeleton.parents[j]
        t = [0.0, HIPS_HEIGHT_CM * 0.01, 0.0] if p < 0 else [float(x) * 0.01 for x in skeleton.offsets[j]]
        node = {"name": skeleton.names[j], "translation": t}
        kids = skeleton.children(j)
        if kids:
            node["children"] = list(kids)
        nodes.append(node)
        if skeleton.names[j] in JOINT_TO_VRM:
            bones[JOINT_TO_VRM[skeleton.names[j]]] = {"node": j}
    t_in = buf.accessor(times, minmax=True)
    samplers, channels = [], []

    def track(node: int, path: str, values: np.ndarray) -> None:
        samplers.append({"input": t_in, "output": buf.accessor(values.astype(np.float32)), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    root = (skeleton.offsets[0] + poses[:, :3]) * 0.01
    track(0, "translation", root)
    q = euler_zxy_to_quat(poses[:, 3:].reshape(f, jn, 3))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    for j in range(jn):
        track(j, "rotation", q[:, j])
    presets = {}
    for name, w in expression_weights(None, arkit, f).items():
        k = len(nodes)
        nodes.append({"name": f"expression.{name}", "translation": [0.0, 0.0, 0.0]})
        presets[name] = {"node": k}
        track(k, "translation", np.stack([w, np.zeros(f), np.zeros(f)], axis=1))
    doc = {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": ["VRMC_vrm_animation"],
        "extensions": {"VRMC_vrm_animation": {"specVersion": "1.0", "humanoid": {"humanBones": bones},
                                              "expressions": {"preset": presets}}},
        "scene": 0,
        "scenes": [{"name": "laugh", "nodes": [0] + [presets[n]["node"] for n in presets], "extras": {"laughlab": {
            "fps": float(fps), "frames": int(frames), "audio_duration_s": float(audio_duration_s)}}}],
        "nodes": nodes,
        "animations": [{"name": "laugh", "samplers": samplers, "channels": channels}],
    }
    return glb_bytes(doc, buf)
