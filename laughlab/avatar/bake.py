"""A user's avatar with a run baked in: the avatar's own glTF plus one animation, ``laugh``.

Everything of the avatar file is kept (meshes, skins, materials, textures, its VRM extension); the
images of a ``.gltf`` (files beside it, ``data:`` URIs) are put into the file's buffer, so it is whole;
the animation is appended: the humanoid bones' local rotations and the hips' translation per
frame (:func:`laughlab.avatar.retarget.retarget`), and the morph weights per frame of every mesh node
with a target the run drives (:func:`laughlab.avatar.expressions.morph_weights`; its other targets
keep the avatar's default weights; a node with none driven gets no ``weights`` channel).
``scenes[0].extras.laughlab`` carries fps, frames and the input audio's duration as in laughlab's own
``character.glb``, and ``face``: the number of morph targets, how many the face drove, and the VRM
expressions it used (:func:`laughlab.avatar.expressions.face_route`).
"""
from __future__ import annotations

import copy
from typing import Mapping

import numpy as np

from laughlab.avatar.expressions import breath_on_bones, breathing_pose, driven_morphs, face_route, morph_weights
from laughlab.avatar.images import embed_images
from laughlab.avatar.load import Avatar
from laughlab.avatar.retarget import retarget
from laughlab.io.gltf import Buffer, glb_bytes, hold_to_end
from laughlab.motion.skeleton import Skeleton


def avatar_tracks(avatar: Avatar, skeleton: Skeleton, poses: np.ndarray, arkit: Mapping[str, np.ndarray],
                  breath: Mapping[str, np.ndarray]) -> list[tuple[int, str, np.ndarray]]:
    """The run on the avatar as ``(node, path, values per frame)``: the hips' translation (m), the humanoid bones'
    local rotations (quaternions x, y, z, w) and the weights of every mesh node with a target the run drives
    (its others keep the avatar's defaults; a node with none driven gets no track); what :func:`baked_glb`
    bakes and the live viewer sends."""
    poses = breathing_pose(poses, breath_on_bones(avatar, breath), skeleton)
    moved = retarget(avatar, poses, skeleton)
    out = [(avatar.bones["hips"], "translation", moved.hips_translation)]
    out += [(node, "rotation", moved.rotations[:, k]) for k, node in enumerate(moved.nodes)]
    driven = driven_morphs(avatar, arkit, breath)
    out += [(node, "weights", w) for node, w in sorted(morph_weights(avatar, arkit, breath, len(poses)).items())
            if driven.get(node)]   # a node none of whose targets the run drives keeps its own weights
    return out


def baked_glb(avatar: Avatar, skeleton: Skeleton, times_s: np.ndarray, poses: np.ndarray,
              arkit: Mapping[str, np.ndarray], breath: Mapping[str, np.ndarray], audio_duration_s: float,
              fps: float) -> bytes:
    """The avatar's ``.glb`` bytes with the run's animation appended."""
    times = np.asarray(times_s, dtype=np.float32)
    f = len(times)
    poses = np.asarray(poses, dtype=np.float64)
    if f == 0 or poses.shape != (f, skeleton.n_channels):
        raise ValueError(f"the baked avatar needs F times and (F, {skeleton.n_channels}) poses; got {f}, "
                         f"{poses.shape}")
    times, poses, arkit, breath = hold_to_end(times, audio_duration_s, poses, arkit, breath)
    doc = copy.deepcopy(avatar.doc)
    buf = Buffer(avatar.binary, doc.get("bufferViews"), doc.get("accessors"))
    embed_images(doc, avatar.images, buf)   # a .gltf's texture files: into the file, which goes elsewhere
    t_in = buf.accessor(times, minmax=True)
    samplers, channels = [], []

    def track(node: int, path: str, values: np.ndarray) -> None:
        samplers.append({"input": t_in, "output": buf.accessor(np.ascontiguousarray(values, dtype=np.float32)),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": int(node), "path": path}})

    for node, path, values in avatar_tracks(avatar, skeleton, poses, arkit, breath):
        track(node, path, values if path != "weights" else values.reshape(-1))
    doc.setdefault("animations", []).insert(0, {"name": "laugh", "samplers": samplers, "channels": channels})
    scene = doc.get("scene", 0)
    if doc.get("scenes"):
        extras = doc["scenes"][scene].setdefault("extras", {})
        route = face_route(avatar, set(arkit))
        extras["laughlab"] = {"fps": float(fps), "frames": int(f), "audio_duration_s": float(audio_duration_s),
                              "face": {k: route[k] for k in ("morphs", "morphs_driven", "expressions")}}
    doc["asset"] = {**doc.get("asset", {}), "generator": f"laughlab (avatar: {doc.get('asset', {}).get('generator', '?')})"}
    return glb_bytes(doc, buf)
