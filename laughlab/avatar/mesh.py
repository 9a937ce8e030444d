"""An avatar's triangles for the software renderer: positions, normals, skins, morphs, colours per vertex.

Every triangle primitive of every mesh node in the avatar's scene, in the node's space: its vertex
positions and normals, its morph targets' position offsets, its skin (up to four joints and weights
a vertex, the joints' inverse bind matrices) or, unskinned, the node it hangs from.  The colour of a
vertex is its material's base colour factor times the base colour texture sampled at the vertex's
UV (nearest texel, repeat) times its ``COLOR_0`` if it has one (glTF 2.0, 3.9.2: the three are
multiplied; vertex-coloured avatars drew white before), in sRGB 0-255: right for the palette
textures of low-poly avatars, blurred for detailed ones (the renderer interpolates colours between
vertices).
"""
from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from laughlab.avatar.check import COMPONENT_DTYPES as _DTYPES
from laughlab.avatar.load import Avatar

_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}


def accessor(avatar: Avatar, index: int) -> np.ndarray:
    """An accessor's values as float64 (normalised integers scaled to [0, 1]), rows of its type's width;
    byte strides and sparse substitutions applied."""
    doc, acc = avatar.doc, avatar.doc["accessors"][index]
    dtype, width, count = np.dtype(_DTYPES[acc["componentType"]]), _WIDTH[acc["type"]], acc["count"]
    out = np.zeros((count, width))
    if "bufferView" in acc:
        view = doc["bufferViews"][acc["bufferView"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        stride = view.get("byteStride") or dtype.itemsize * width
        raw = np.frombuffer(avatar.binary, dtype=np.uint8, count=stride * (count - 1) + dtype.itemsize * width,
                            offset=start)
        rows = np.lib.stride_tricks.as_strided(raw, (count, dtype.itemsize * width), (stride, 1))
        out = np.ascontiguousarray(rows).view(dtype).reshape(count, width).astype(np.float64)
    sparse = acc.get("sparse")
    if sparse:
        iv, vv = sparse["indices"], sparse["values"]
        idx_view, val_view = doc["bufferViews"][iv["bufferView"]], doc["bufferViews"][vv["bufferView"]]
        idx = np.frombuffer(avatar.binary, dtype=_DTYPES[iv["componentType"]], count=sparse["count"],
                            offset=idx_view.get("byteOffset", 0) + iv.get("byteOffset", 0)).astype(np.int64)
        val = np.frombuffer(avatar.binary, dtype=dtype, count=sparse["count"] * width,
                            offset=val_view.get("byteOffset", 0) + vv.get("byteOffset", 0))
        out[idx] = val.reshape(-1, width)
    if acc.get("normalized") and acc["componentType"] in _NORM:
        out = np.maximum(out / _NORM[acc["componentType"]], -1.0)
    return out


@dataclass
class Part:
    """The triangles of one primitive of one mesh node."""

    node: int
    positions: np.ndarray           # (V, 3) the node's (or the skin's bind) space, avatar units
    normals: np.ndarray             # (V, 3)
    colours: np.ndarray             # (V, 3) sRGB 0-255
    triangles: np.ndarray           # (T, 3) int64
    morphs: np.ndarray              # (M, V, 3) position offsets
    joints: np.ndarray | None       # (J,) the skin's joints (node indices), or None (rigid on ``node``)
    weights: np.ndarray | None      # (V, 4)
    inverse_bind: np.ndarray | None  # (J, 4, 4) the skin's inverse bind matrices, by skin joint
    skin_slots: np.ndarray | None   # (V, 4) each vertex's skin joints (indices into ``inverse_bind``)


def _texture(avatar: Avatar, tex_index: int, cache: dict) -> np.ndarray | None:
    if tex_index in cache:
        return cache[tex_index]
    from PIL import Image

    doc = avatar.doc
    img = None
    src = (doc.get("textures") or [{}])[tex_index].get("source")
    if src is not None:
        image = doc["images"][src]
        if src in avatar.images:    # read from its file (or data: URI) when the avatar was loaded
            data = avatar.images[src]
        else:
            view = doc["bufferViews"][image["bufferView"]]
            data = avatar.binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
        try:
            img = np.asarray(Image.open(io.BytesIO(data)).convert("RGBA").convert("RGB"), dtype=np.float64)
        except Exception as exc:   # identified at load (laughlab.avatar.images), but its pixels do not decode
            from laughlab.avatar.errors import AvatarError
            from laughlab.avatar.images import image_name

            raise AvatarError(f"{avatar.path}: its texture {image_name(doc, src)!r} cannot be decoded "
                              f"({type(exc).__name__}); save it again as PNG or JPEG") from None
    cache[tex_index] = img
    return img


def _colours(avatar: Avatar, prim: dict, uv: np.ndarray | None, n: int, cache: dict) -> np.ndarray:
    mats = avatar.doc.get("materials") or []
    mat = mats[prim["material"]] if "material" in prim and prim["material"] < len(mats) else {}
    pbr = mat.get("pbrMetallicRoughness") or {}
    factor = np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])[:3], dtype=np.float64)
    srgb_factor = 255.0 * np.clip(factor, 0, 1) ** (1 / 2.2)  # the factor is linear
    tex = pbr.get("baseColorTexture")
    img = _texture(avatar, tex["index"], cache) if tex is not None and uv is not None else None
    if img is None:
        out = np.broadcast_to(srgb_factor, (n, 3)).copy()
    else:
        h, w = img.shape[:2]
        x = np.floor(np.mod(uv[:, 0], 1.0) * w).astype(np.int64).clip(0, w - 1)
        y = np.floor(np.mod(uv[:, 1], 1.0) * h).astype(np.int64).clip(0, h - 1)
        out = img[y, x] * (srgb_factor / 255.0)
    if "COLOR_0" in prim.get("attributes", {}):   # glTF multiplies the vertex colour in too (linear, RGB or RGBA)
        vc = accessor(avatar, prim["attributes"]["COLOR_0"])[:n, :3]
        out = out * np.clip(vc, 0.0, 1.0) ** (1 / 2.2)
    return out


def parts(avatar: Avatar) -> list[Part]:
    """Every triangle primitive of the avatar's mesh nodes (see the module's docstring)."""
    doc, out, cache = avatar.doc, [], {}
    for node, nd in enumerate(doc["nodes"]):
        if "mesh" not in nd:
            continue
        skin = doc["skins"][nd["skin"]] if "skin" in nd and doc.get("skins") else None
        ibm = None
        if skin is not None:
            n_j = len(skin["joints"])
            ibm = (accessor(avatar, skin["inverseBindMatrices"]).reshape(n_j, 4, 4).transpose(0, 2, 1)
                   if "inverseBindMatrices" in skin else np.tile(np.eye(4), (n_j, 1, 1)))
        for prim in doc["meshes"][nd["mesh"]]["primitives"]:
            if prim.get("mode", 4) != 4 or "POSITION" not in prim["attributes"]:
                continue
            a = prim["attributes"]
            pos = accessor(avatar, a["POSITION"])
            n = len(pos)
            nrm = accessor(avatar, a["NORMAL"]) if "NORMAL" in a else np.tile([0.0, 0.0, 1.0], (n, 1))
            uv = accessor(avatar, a["TEXCOORD_0"]) if "TEXCOORD_0" in a else None
            tris = (accessor(avatar, prim["indices"]).astype(np.int64).reshape(-1, 3) if "indices" in prim
                    else np.arange(n - n % 3).reshape(-1, 3))
            morphs = np.array([accessor(avatar, t["POSITION"]) if "POSITION" in t else np.zeros((n, 3))
                               for t in prim.get("targets") or []]).reshape(-1, n, 3)
            joints = weights = slots = None
            if skin is not None and "JOINTS_0" in a and "WEIGHTS_0" in a:
                slots = np.rint(accessor(avatar, a["JOINTS_0"])).astype(np.int64)
                weights = accessor(avatar, a["WEIGHTS_0"])
                weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1e-12)
                joints = np.asarray(skin["joints"], dtype=np.int64)
            out.append(Part(node, pos, nrm, _colours(avatar, prim, uv, n, cache), tris, morphs, joints, weights,
                            ibm if joints is not None else None, slots))
    return out
