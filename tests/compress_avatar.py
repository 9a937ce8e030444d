"""Compressed copies of the test avatars, made with real encoders in Python (tests/test_avatar_compressed.py):
Draco (DracoPy, Google's Draco encoder) on every primitive, meshopt (meshoptimizer's encoder) on every bufferView
its accessors use.  The copies keep everything else of the file; their old uncompressed data stays in the buffer,
no longer referred to."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from laughlab.avatar.check import COMPONENT_DTYPES
from laughlab.avatar.load import load_avatar
from laughlab.avatar.mesh import accessor
from laughlab.io.gltf import parse_glb

DRACO, MESHOPT = "KHR_draco_mesh_compression", "EXT_meshopt_compression"
#: Draco's attribute types (draco/attributes/geometry_attribute.h) -> the glTF semantic DracoPy's encoder gives them
_DRACO_TYPES = {0: "POSITION", 1: "NORMAL", 3: "TEXCOORD_0"}


def glb(doc: dict, binary: bytes) -> bytes:
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary = bytes(binary) + b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _require(doc: dict, name: str) -> None:
    for key in ("extensionsUsed", "extensionsRequired"):
        doc[key] = [*doc.get(key, []), name]


def draco(src: Path, dst: Path, preserve_order: bool = True, bits: int = 14, normal_bits: int = 10,
          uv_bits: int = 12, weights_off: float = 0.0) -> Path:
    """``src`` with every triangle primitive Draco-compressed as KHR_draco_mesh_compression stores it: new accessors
    without a bufferView (a primitive's own, also where the source shares them), their counts the decoded mesh's
    (the extension's implementation note); JOINTS_0 and WEIGHTS_0 as generic attributes.  ``preserve_order``:
    Draco's sequential coder (what encoders use for a primitive with morph targets), else edgebreaker.
    ``weights_off``: the weights scaled by 1 + it, their sums off as a quantising encoder leaves them (gltf-transform
    quantises them to 12 bits; DracoPy keeps generic floats as they are)."""
    import DracoPy

    doc, binary = parse_glb(src.read_bytes())
    av = load_avatar(src)
    out = bytearray(binary)
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            a = prim["attributes"]
            generic = {10 + k: (accessor(av, a[s]) * (1 + weights_off * (s == "WEIGHTS_0"))).astype(
                np.uint16 if s == "JOINTS_0" else np.float32)
                for k, s in enumerate(("JOINTS_0", "WEIGHTS_0")) if s in a}
            data = DracoPy.encode(
                accessor(av, a["POSITION"]), accessor(av, prim["indices"]).astype(np.uint32).reshape(-1, 3),
                quantization_bits=bits, compression_level=7, preserve_order=preserve_order,
                normals=accessor(av, a["NORMAL"]) if "NORMAL" in a else None,
                tex_coord=accessor(av, a["TEXCOORD_0"]) if "TEXCOORD_0" in a else None,
                normal_quantization_bits=normal_bits, tex_coord_quantization_bits=uv_bits,
                generic_attributes=generic or None)
            decoded = DracoPy.decode(data)
            ids = {_DRACO_TYPES[at["attribute_type"]]: at["unique_id"] for at in decoded.attributes
                   if at["attribute_type"] in _DRACO_TYPES}
            ids.update({s: 10 + k for k, s in enumerate(("JOINTS_0", "WEIGHTS_0")) if s in a})
            for semantic in ids:
                acc = {k: v for k, v in doc["accessors"][a[semantic]].items() if k not in ("bufferView", "byteOffset")}
                doc["accessors"].append({**acc, "count": len(decoded.points)})
                a[semantic] = len(doc["accessors"]) - 1
            acc = {k: v for k, v in doc["accessors"][prim["indices"]].items() if k not in ("bufferView", "byteOffset")}
            doc["accessors"].append({**acc, "count": decoded.faces.size})
            prim["indices"] = len(doc["accessors"]) - 1
            out += b"\0" * (-len(out) % 4)
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(out), "byteLength": len(data)})
            out += data
            prim.setdefault("extensions", {})[DRACO] = {"bufferView": len(doc["bufferViews"]) - 1, "attributes": ids}
    _require(doc, DRACO)
    doc["buffers"][0]["byteLength"] = len(out) + (-len(out) % 4)
    dst.write_bytes(glb(doc, out))
    return dst


def meshopt(src: Path, dst: Path) -> Path:
    """``src`` with every bufferView an accessor uses meshopt-compressed (EXT_meshopt_compression): ``TRIANGLES``
    for a triangle list's indices, ``ATTRIBUTES`` for the rest (elements of 4-byte multiples; others kept plain),
    the plain data moved to a fallback buffer without data (buffer 1), as gltfpack writes it."""
    import meshopt

    doc, binary = parse_glb(src.read_bytes())
    out, fallback = bytearray(binary), 0
    index_views = {doc["accessors"][p["indices"]]["bufferView"] for m in doc["meshes"] for p in m["primitives"]
                   if "indices" in p and p.get("mode", 4) == 4}
    users = {}
    for acc in doc["accessors"]:
        users.setdefault(acc.get("bufferView"), []).append(acc)
    for i, view in enumerate(doc["bufferViews"]):
        accs = users.get(i, [])
        if len(accs) != 1 or accs[0].get("byteOffset", 0):
            continue
        acc = accs[0]
        dtype = np.dtype(COMPONENT_DTYPES[acc["componentType"]])
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
        stride = view.get("byteStride", dtype.itemsize * width)
        rows = np.frombuffer(binary, np.uint8, acc["count"] * stride, view.get("byteOffset", 0))
        if i in index_views:
            mode, data = "TRIANGLES", rows.view(dtype)
        elif stride % 4 == 0:
            mode, data = "ATTRIBUTES", rows.reshape(acc["count"], stride).view(np.uint32)
        else:
            continue
        enc = meshopt.encode_gltf_buffer(data, mode)
        out += b"\0" * (-len(out) % 4)
        ext = {"buffer": 0, "byteOffset": len(out), "byteLength": len(enc), "byteStride": stride,
               "count": len(rows) // stride, "mode": mode}
        out += enc
        fallback += -fallback % 4
        view.update(buffer=1, byteOffset=fallback, byteLength=len(rows), extensions={MESHOPT: ext})
        fallback += len(rows)
    doc["buffers"] = [{"byteLength": len(out) + (-len(out) % 4)},
                      {"byteLength": fallback, "extensions": {MESHOPT: {"fallback": True}}}]
    _require(doc, MESHOPT)
    dst.write_bytes(glb(doc, out))
    return dst
