"""glTF 2.0 binary (``.glb``) of a run: the skinned character, its skeleton's animation, its morph weights.

Layout of the file (Khronos glTF 2.0; metres, Y up, the character faces +Z, as in the skeleton):

* nodes ``0 .. J-1``: the skeleton's joints, named as in ``motion.bvh``, each translated by its
  offset from its parent (the root by its rest position); node ``J``: the mesh, skinned;
* one skin: the joints, inverse bind matrices of the rest (T-) pose;
* one mesh, one primitive: ``POSITION``, ``NORMAL``, ``COLOR_0`` (the material's base colour is
  white, so the vertex colours show), ``JOINTS_0``/``WEIGHTS_0``, and one morph target per
  face or body shape, named in ``mesh.extras.targetNames`` (what Blender and three.js read);
* one animation, ``laugh``, linear: the root's translation and every joint's rotation per
  frame (from the BVH's ZXY Euler angles), and the mesh's morph weights per frame;
* ``scenes[0].extras.laughlab``: frames per second, number of frames, and the duration of the
  input audio (s), so a player can line the animation up with ``input.wav``.

The bytes depend only on the inputs (no time stamps): same run, same file.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Mapping

import numpy as np

from laughlab.io.vmc import euler_zxy_to_quat

_FLOAT, _USHORT, _UINT = 5126, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENT = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint16): _USHORT, np.dtype(np.uint32): _UINT}
_TYPE = {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


class Buffer:
    """The binary chunk with its buffer views and accessors."""

    def __init__(self, data: bytes = b"", views: list | None = None, accessors: list | None = None):
        self.data = bytearray(data)
        self.views: list[dict] = list(views or [])
        self.accessors: list[dict] = list(accessors or [])

    def accessor(self, arr: np.ndarray, target: int | None = None, minmax: bool = False) -> int:
        arr = np.ascontiguousarray(arr)
        width = 1 if arr.ndim == 1 else arr.shape[1]
        self.data += b"\0" * (-len(self.data) % 4)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": arr.nbytes}
        if target is not None:
            view["target"] = target
        self.data += arr.tobytes()
        self.views.append(view)
        acc = {"bufferView": len(self.views) - 1, "componentType": _COMPONENT[arr.dtype], "count": len(arr),
               "type": _TYPE[width]}
        if minmax:
            a2 = arr.reshape(len(arr), width)
            acc["min"] = [float(x) for x in a2.min(axis=0)]
            acc["max"] = [float(x) for x in a2.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def hold_to_end(times: np.ndarray, end_s: float, poses: np.ndarray, *tables: Mapping[str, np.ndarray]):
    """``(times, poses, *tables)``: ``times`` (float32, s), ``poses`` and each table's arrays (a row per frame) with
    one more key at ``end_s`` holding the last frame, when ``end_s`` (the audio's duration) lies after the last
    frame's time; else unchanged.  So an animation lasts as long as its audio: a player that loops or ends the two
    together keeps them in step (the last frame starts up to a frame before the audio ends)."""
    end = np.float32(end_s)
    if not (np.isfinite(end) and end > times[-1]):
        return (times, poses, *tables)
    held = [{k: np.concatenate([np.asarray(v, dtype=np.float64), np.asarray(v, dtype=np.float64)[-1:]])
             for k, v in table.items()} for table in tables]
    return (np.append(times, end), np.concatenate([poses, poses[-1:]]), *held)


def mannequin_tracks(sk, poses: np.ndarray, weights: np.ndarray) -> list[tuple[int, str, np.ndarray]]:
    """The animation of laughlab's character as ``(node, path, values per frame)``: the root's translation (m),
    each joint's rotation (unit quaternion x, y, z, w) from ``poses`` (BVH channel vectors, cm and degrees),
    and the mesh node's morph ``weights`` (F, M); what ``character_glb`` bakes and the live viewer sends."""
    jn = sk.n_joints
    root = (sk.offsets[0] + poses[:, :3]) * 0.01
    quats = euler_zxy_to_quat(poses[:, 3:].reshape(len(poses), jn, 3))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    return [(0, "translation", root), *((j, "rotation", quats[:, j]) for j in range(jn)), (jn, "weights", weights)]


def character_glb(character, times_s: np.ndarray, poses: np.ndarray, morph_weights: np.ndarray,
                  audio_duration_s: float, fps: float, generator: str = "laughlab") -> bytes:
    """The ``.glb`` bytes of ``character`` animated by ``poses`` (BVH channel vectors, cm and degrees).

    Parameters
    ----------
    character : laughlab.character.body.Character
    times_s : ndarray (F,)
        Frame times (s), increasing.
    poses : ndarray (F, 3 + 3J)
        Root position (cm) and ZXY Euler angles (degrees) per joint, as in ``motion.bvh``.
    morph_weights : ndarray (F, M)
        Weights of ``character.morph_names`` per frame, in [0, 1].
    audio_duration_s, fps : float
    """
    sk = character.skeleton
    jn = sk.n_joints
    times = np.asarray(times_s, dtype=np.float32)
    poses = np.asarray(poses, dtype=np.float64)
    weights = np.clip(np.nan_to_num(np.asarray(morph_weights, dtype=np.float64)), 0.0, 1.0).astype(np.float32)
    if len(times) == 0 or poses.shape != (len(times), sk.n_channels) or weights.shape != (len(times),
                                                                                         len(character.morph_names)):
        raise ValueError(f"glTF export needs F times, (F, {sk.n_channels}) poses and (F, "
                         f"{len(character.morph_names)}) morph weights; got {len(times)}, {poses.shape}, "
                         f"{weights.shape}")
    frames = len(times)
    times, poses, held = hold_to_end(times, audio_duration_s, poses, {"weights": weights})
    weights = np.asarray(held["weights"], dtype=np.float32)
    buf = Buffer()
    # the mesh
    attrs = {
        "POSITION": buf.accessor(character.positions, _ARRAY_BUFFER, minmax=True),
        "NORMAL": buf.accessor(character.normals, _ARRAY_BUFFER),
        "COLOR_0": buf.accessor(character.colors, _ARRAY_BUFFER),
        "JOINTS_0": buf.accessor(character.joints, _ARRAY_BUFFER),
        "WEIGHTS_0": buf.accessor(character.weights, _ARRAY_BUFFER),
    }
    targets = [{"POSITION": buf.accessor(m, _ARRAY_BUFFER, minmax=True)} for m in character.morphs]
    indices = buf.accessor(character.indices, _ELEMENT_ARRAY_BUFFER)
    # the skeleton in its rest pose (metres): root at its rest position, joints at their offsets
    rest_global = np.zeros((jn, 3))
    nodes = []
    for j in range(jn):
        p = sk.parents[j]
        t = character.rest_root_m if p < 0 else sk.offsets[j] * 0.01
        rest_global[j] = t if p < 0 else rest_global[p] + t
        node = {"name": sk.names[j], "translation": [float(x) for x in t]}
        kids = sk.children(j)
        if kids:
            node["children"] = list(kids)
        nodes.append(node)
    nodes.append({"name": "character", "mesh": 0, "skin": 0})
    ibm = np.tile(np.eye(4, dtype=np.float32), (jn, 1, 1))
    ibm[:, 3, :3] = -rest_global  # column-major storage of a translation by -rest position
    skin = {"joints": list(range(jn)), "skeleton": 0, "inverseBindMatrices": buf.accessor(ibm.reshape(jn, 16))}
    # the animation
    t_in = buf.accessor(times, minmax=True)
    samplers, channels = [], []
    for node, path, values in mannequin_tracks(sk, poses, weights):
        samplers.append({"input": t_in, "output": buf.accessor(values.astype(np.float32).reshape(
            len(times), -1) if path != "weights" else values.reshape(-1)), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})
    doc = {
        "asset": {"version": "2.0", "generator": generator},
        "scene": 0,
        "scenes": [{"name": "laugh", "nodes": [0, jn], "extras": {"laughlab": {
            "fps": float(fps), "frames": int(frames), "audio_duration_s": float(audio_duration_s)}}}],
        "nodes": nodes,
        "skins": [skin],
        "meshes": [{"name": "character", "weights": [0.0] * len(targets),
                    "extras": {"targetNames": list(character.morph_names)},
                    "primitives": [{"attributes": attrs, "indices": indices, "material": 0, "targets": targets,
                                    "mode": 4}]}],
        "materials": [{"name": "vertex colours", "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}],
        "animations": [{"name": "laugh", "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": 0}],
        "bufferViews": buf.views,
        "accessors": buf.accessors,
    }
    return glb_bytes(doc, buf)


def glb_bytes(doc: dict, buf: Buffer) -> bytes:
    """A ``.glb``: ``doc`` (its buffer 0, buffer views and accessors set from ``buf``) and ``buf``'s bytes."""
    buf.data += b"\0" * (-len(buf.data) % 4)
    doc["buffers"] = [{**(doc.get("buffers") or [{}])[0], "byteLength": len(buf.data)}]
    doc["buffers"][0].pop("uri", None)
    doc["bufferViews"] = buf.views
    doc["accessors"] = buf.accessors
    js = json.dumps(doc, separators=(",", ":"), sort_keys=True).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(buf.data)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(js), b"JSON"), js,
                     struct.pack("<I4s", len(buf.data), b"BIN\0"), bytes(buf.data)])


def read_glb(path: str | Path) -> tuple[dict, bytes]:
    """The JSON document and the binary chunk of a ``.glb`` file."""
    try:
        return parse_glb(Path(path).read_bytes())
    except ValueError:
        raise ValueError(f"{path} is not a glTF 2.0 binary") from None


def parse_glb(data: bytes) -> tuple[dict, bytes]:
    """The JSON document and the binary chunk of ``.glb`` bytes."""
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2 or total != len(data):
        raise ValueError("not a glTF 2.0 binary")
    n, kind = struct.unpack_from("<I4s", data, 12)
    doc = json.loads(data[20:20 + n])
    m, kind2 = struct.unpack_from("<I4s", data, 20 + n)
    return doc, data[28 + n:28 + n + m]


def accessor_array(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """An accessor's data as a numpy array (rows of its type's width)."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = {v: k for k, v in _COMPONENT.items()}[acc["componentType"]]
    width = {v: k for k, v in _TYPE.items()}[acc["type"]]
    arr = np.frombuffer(binary, dtype=dtype, count=acc["count"] * width,
                        offset=view["byteOffset"] + acc.get("byteOffset", 0))
    return arr.reshape(acc["count"], width) if width > 1 else arr
