"""An avatar's compressed meshes, decoded when it is loaded: Draco and meshopt.

Ready Player Me hands out Draco-compressed GLBs (``meshCompression=true``), and gltfpack or gltf-transform's
``meshopt`` leave avatars with meshopt-compressed buffer views.  :func:`decompress` turns such a document and
buffer into plain glTF 2.0: every accessor has its data in buffer 0, and neither extension is used any more, so
the checks, the retargeting, the morphs, the video and ``character.glb`` (which must not require the extension:
it carries the decoded data) read it as they read an uncompressed file.

* ``KHR_draco_mesh_compression`` (Khronos, extension README, *glTF Schema Updates* and *Conformance*): a primitive's
  extension names a bufferView of Draco data and, for each attribute it holds, the Draco attribute's unique id.
  The loader decodes it (DracoPy, Google's Draco decoder) and fills the accessors of those attributes and of the
  indices from it, ignoring their own ``bufferView`` and ``byteOffset``; attributes not named in the extension are
  read as usual.  The mode must be ``TRIANGLES`` or ``TRIANGLE_STRIP``; Draco gives triangles, so a strip becomes
  a triangle list.  Morph targets are not compressed: their accessors must have as many vertices as the decoded
  mesh (encoders keep the vertex order of a primitive with targets).  The bufferView of the Draco data is dropped
  when nothing else refers to it.
* ``EXT_meshopt_compression`` (Khronos, extension README, *Specifying compressed views*, *Fallback buffers*): a
  bufferView's extension names the compressed bytes (buffer, byteOffset, byteLength), ``count`` elements of
  ``byteStride`` bytes, the ``mode`` (``ATTRIBUTES``, ``TRIANGLES``, ``INDICES``) and the ``filter`` (``NONE``,
  ``OCTAHEDRAL``, ``QUATERNION``, ``EXPONENTIAL``) applied after decoding; the decoded bytes are the bufferView's
  contents (meshopt, meshoptimizer's own decoder).  A fallback buffer (tagged ``fallback``, or with no data) holds
  nothing laughlab reads and is dropped.

Anything that does not decode, or decodes to other counts than the accessors declare, is one line naming the
mesh or bufferView: the file is damaged.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from laughlab.avatar.check import COMPONENT_BYTES, TYPE_COMPONENTS, _int
from laughlab.avatar.check import COMPONENT_DTYPES as _DTYPES
from laughlab.avatar.errors import AvatarError

DRACO, MESHOPT = "KHR_draco_mesh_compression", "EXT_meshopt_compression"
_MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
_FILTERS = ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL")
#: the most bytes the meshopt views of one avatar may decode to (their byteLengths are declared, not stored)
MAX_DECODED = 1 << 30


def is_fallback(buffer) -> bool:
    """Whether a buffer is an ``EXT_meshopt_compression`` fallback (tagged so), whose data laughlab never reads."""
    ext = (buffer.get("extensions") or {}).get(MESHOPT) if isinstance(buffer, dict) else None
    return isinstance(ext, dict) and ext.get("fallback") is True


def _ext(d, name: str):
    """``d``'s extension object ``name``, or None (also where ``d`` or its ``extensions`` is not an object)."""
    exts = d.get("extensions") if isinstance(d, dict) else None
    return exts.get(name) if isinstance(exts, dict) else None


def _primitives(doc: dict):
    """(mesh index, primitive index, primitive) of every primitive that is an object."""
    for m, mesh in enumerate(doc.get("meshes") or []):
        for p, prim in enumerate(mesh.get("primitives") or [] if isinstance(mesh, dict) else []):
            if isinstance(prim, dict):
                yield m, p, prim


def uses_compression(doc: dict) -> bool:
    """Whether any primitive or bufferView of ``doc`` carries Draco or meshopt compression."""
    return any(_ext(v, MESHOPT) is not None for v in doc.get("bufferViews") or []) or \
        any(_ext(prim, DRACO) is not None for _, _, prim in _primitives(doc))


def decompress(path: Path, doc: dict, binary: bytes) -> tuple[dict, bytes]:
    """``doc`` and ``binary`` as they are if nothing is compressed; else a decoded copy (see the module)."""
    listed = [e for k in ("extensionsUsed", "extensionsRequired") for e in doc.get(k) or [] if e in (DRACO, MESHOPT)]
    if not listed and not uses_compression(doc):
        return doc, binary
    doc = copy.deepcopy(doc)
    views = [v for v in doc.get("bufferViews") or [] if _ext(v, MESHOPT) is not None]
    declared = sum(v.get("byteLength") for v in views if isinstance(v.get("byteLength"), int))
    if declared > MAX_DECODED:
        raise AvatarError(f"{path}: its meshopt-compressed data would decode to {declared / 1e9:.1f} GB; laughlab "
                          f"decodes avatars up to {MAX_DECODED / 1e9:.1f} GB")
    contents = {i: _meshopt_view(path, i, v, binary) for i, v in enumerate(doc.get("bufferViews") or [])
                if _ext(v, MESHOPT) is not None}
    new_views: list[tuple[bytes, int | None, int | None]] = []   # decoded Draco data: bytes, stride, target
    draco_views = set()
    for m, p, prim in _primitives(doc):
        ext = _ext(prim, DRACO)
        if ext is not None:
            draco_views.add(_draco_primitive(path, doc, f"mesh {m}'s primitive {p}", prim, ext, binary, contents,
                                             new_views))
    return doc, _rebuild(path, doc, binary, contents, new_views, draco_views)


def _damaged(path: Path, what: str, why: str) -> AvatarError:
    return AvatarError(f"{path}: {what} {why}; the file is damaged (export it again)")


def _meshopt_view(path: Path, i: int, view: dict, binary: bytes) -> bytes:
    """The decoded contents of bufferView ``i`` (EXT_meshopt_compression, *JSON schema updates*: the rules the
    extension object must keep are checked before the decoder runs)."""
    import meshopt

    what = f"bufferView {i}'s {MESHOPT}"
    ext = view["extensions"].pop(MESHOPT)
    if not view["extensions"]:
        del view["extensions"]
    if not isinstance(ext, dict):
        raise _damaged(path, what, "is not an object")
    if _int(path, ext, "buffer", what) != 0:
        raise _damaged(path, what, f"refers to buffer {ext['buffer']}, not the file's data (buffer 0)")
    off, length = _int(path, ext, "byteOffset", what, 0), _int(path, ext, "byteLength", what, least=1)
    stride, count = _int(path, ext, "byteStride", what, least=1), _int(path, ext, "count", what, least=1)
    mode, filt = ext.get("mode"), ext.get("filter", "NONE")
    if mode not in _MODES or filt not in _FILTERS:
        raise _damaged(path, what, f"has mode {mode!r} and filter {filt!r}")
    if off + length > len(binary):
        raise _damaged(path, what, f"ends at byte {off + length:,}, past its buffer's {len(binary):,}")
    if view.get("byteLength") != stride * count or view.get("byteStride", stride) != stride:
        raise _damaged(path, what, f"holds {count} x {stride} bytes, and the bufferView {view.get('byteLength')!r}")
    try:
        out = meshopt.decode_gltf_buffer(binary[off:off + length], count, stride, mode, filt)
    except (ValueError, RuntimeError) as exc:   # the binding's checks, and the decoder's error codes
        raise _damaged(path, what, f"data does not decode ({exc})") from None
    return np.ascontiguousarray(out).tobytes()


def _draco_primitive(path: Path, doc: dict, what: str, prim: dict, ext, binary: bytes, contents: dict,
                     new_views: list) -> int:
    """Decode one primitive's Draco data into its accessors (KHR_draco_mesh_compression, *Conformance*); the index
    of the bufferView that held the data."""
    import DracoPy

    prim["extensions"].pop(DRACO)
    if not prim["extensions"]:
        del prim["extensions"]
    what = f"{what}'s {DRACO}"
    views, accessors = doc.get("bufferViews") or [], doc.get("accessors") or []
    if not isinstance(ext, dict) or not isinstance(ext.get("attributes"), dict):
        raise _damaged(path, what, "is not an object with attributes")
    vi = _int(path, ext, "bufferView", what)
    if vi >= len(views):
        raise _damaged(path, what, f"refers to bufferView {vi}, and the file has {len(views)}")
    data = _view_bytes(path, vi, views[vi], binary, contents)
    if prim.get("mode", 4) not in (4, 5):
        raise _damaged(path, what, f"is on a primitive of mode {prim.get('mode')}; Draco holds triangles")
    try:
        mesh = DracoPy.decode(bytes(data))
        faces = getattr(mesh, "faces", None)
    except Exception as exc:   # DracoPy raises its own FileTypeException (an Exception) on any bad data
        raise _damaged(path, what, f"data does not decode ({exc})") from None
    if faces is None or len(faces) == 0:
        raise _damaged(path, what, "data holds no triangles")
    n, decoded = None, {}
    attributes = prim.get("attributes") or {}
    for semantic, uid in ext["attributes"].items():
        attr = mesh.get_attribute_by_unique_id(uid) if isinstance(uid, int) else None
        if attr is None or semantic not in attributes:
            raise _damaged(path, what, f"names the attribute {semantic} as Draco attribute {uid!r}, which "
                                       f"{'the primitive lacks' if attr is not None else 'the data lacks'}")
        values = np.asarray(attr["data"])
        decoded[semantic] = values.reshape(len(values), -1)
        n = len(values) if n is None else n
    _unit_sums(accessors, attributes, decoded)
    for semantic, values in decoded.items():
        _fill(path, doc, f"{what}'s {semantic}", attributes[semantic], values, n, new_views, 34962)
    indices = np.asarray(faces).reshape(-1)
    if n is not None and indices.size and int(indices.max()) >= n:
        raise _damaged(path, what, f"data has a triangle on vertex {int(indices.max())} of {n}")
    if "indices" not in prim:
        accessors.append({"componentType": 5125, "type": "SCALAR", "count": len(indices)})
        prim["indices"] = len(accessors) - 1
    idx = _int(path, prim, "indices", what)
    if idx < len(accessors) and isinstance(accessors[idx], dict):
        accessors[idx]["count"] = len(indices)   # a strip's count was the strip's
    _fill(path, doc, f"{what}'s indices", idx, indices[:, None], len(indices), new_views, 34963)
    prim["mode"] = 4
    for k, target in enumerate(prim.get("targets") or []):
        for semantic, a in (target.items() if isinstance(target, dict) else ()):
            count = accessors[a].get("count") if isinstance(a, int) and 0 <= a < len(accessors) else None
            if n is not None and count != n:
                raise _damaged(path, what, f"data has {n} vertices and morph target {k}'s {semantic} {count!r}")
    return vi


def _unit_sums(accessors: list, attributes: dict, decoded: dict) -> None:
    """The decoded ``WEIGHTS_n`` of each vertex scaled to sum to 1 together, as glTF 2.0 (3.7.3.3 *Skinned Mesh
    Attributes*) requires: Draco quantises them as generic attributes (gltf-transform: 12 bits), which leaves sums
    1e-4 off, and the Khronos validator rejects the exported file.  Normalised integers are rounded and the rounding
    put on each vertex's largest weight, so their sums are exact too."""
    names = sorted(s for s in decoded if s.startswith("WEIGHTS_") and isinstance(attributes[s], int)
                   and 0 <= attributes[s] < len(accessors) and isinstance(accessors[attributes[s]], dict))
    if not names or len({decoded[s].shape for s in names}) != 1:
        return
    top = [float(np.iinfo(_DTYPES[t]).max) if (t := accessors[attributes[s]].get("componentType")) in (5121, 5123)
           else 1.0 for s in names]
    w = np.stack([decoded[s] / m for s, m in zip(names, top)]).astype(np.float64)   # (sets, V, 4)
    total = w.sum(axis=(0, 2), keepdims=True)
    w = np.where(total > 0, w / np.where(total > 0, total, 1.0), w)
    for k, (s, m) in enumerate(zip(names, top)):
        decoded[s] = w[k] if m == 1.0 else np.rint(w[k] * m)
    ints = [k for k, m in enumerate(top) if m != 1.0]
    if len(ints) == len(names) == 1:   # one set of integers: the rounding onto the largest weight
        k, m = ints[0], top[ints[0]]
        rows = decoded[names[k]]
        big = np.argmax(rows, axis=1)
        rows[np.arange(len(rows)), big] += np.where(rows.sum(axis=1) > 0, m - rows.sum(axis=1), 0)


def _fill(path: Path, doc: dict, what: str, index, values: np.ndarray, n: int, new_views: list, target: int) -> None:
    """Accessor ``index`` given ``values`` (rows), stored in a new bufferView: its own component type, its elements
    4-byte aligned for a vertex attribute (glTF 2.0, 3.6.2.4), min and max recomputed where it has them (the
    decoded values are the quantised ones)."""
    accessors = doc.get("accessors") or []
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(accessors):
        raise _damaged(path, what, f"refers to accessor {index!r}, and the file has {len(accessors)}")
    acc = accessors[index]
    width = TYPE_COMPONENTS.get(acc.get("type"))
    if acc.get("componentType") not in _DTYPES or width is None or values.shape[1] != width or len(values) != n:
        raise _damaged(path, what, f"decodes to {len(values)} x {values.shape[1]} values, and its accessor "
                                   f"{index} is {acc.get('type')!r} of {acc.get('componentType')!r}")
    dtype = np.dtype(_DTYPES[acc["componentType"]])
    rows = np.rint(values) if dtype.kind != "f" and values.dtype.kind == "f" else values
    rows = np.ascontiguousarray(rows.astype(dtype))
    size = COMPONENT_BYTES[acc["componentType"]] * width
    stride = -size % 4 + size if target == 34962 else size
    padded = np.zeros((n, stride), np.uint8)
    padded[:, :size] = rows.view(np.uint8).reshape(n, size)
    new_views.append((padded.tobytes(), stride if stride != size else None, target))
    for key in ("bufferView", "byteOffset", "sparse"):
        acc.pop(key, None)
    acc["bufferView"] = -len(new_views)   # placed by _rebuild
    acc["count"] = n
    if "min" in acc or "max" in acc or what.endswith("POSITION"):   # glTF 2.0, 5.1.7: POSITION needs them
        acc["min"] = [v.item() for v in rows.min(axis=0)]
        acc["max"] = [v.item() for v in rows.max(axis=0)]


def _refs(node, out: list) -> None:
    """Every dict that has a ``bufferView`` index, anywhere in the document (accessors, sparse, images, extensions)."""
    if isinstance(node, dict):
        if isinstance(node.get("bufferView"), int) and not isinstance(node.get("bufferView"), bool):
            out.append(node)
        for v in node.values():
            _refs(v, out)
    elif isinstance(node, list):
        for v in node:
            _refs(v, out)


def _view_bytes(path: Path, i: int, view, binary: bytes, contents: dict) -> bytes:
    """bufferView ``i``'s bytes: decoded (meshopt), or its range of buffer 0 (a fallback buffer holds nothing)."""
    if i in contents:
        return contents[i]
    if not isinstance(view, dict):
        raise _damaged(path, f"bufferView {i}", "is not an object")
    what = f"bufferView {i}"
    off, length = _int(path, view, "byteOffset", what, 0), _int(path, view, "byteLength", what)
    if view.get("buffer") != 0 or off + length > len(binary):
        raise _damaged(path, what, "is neither compressed nor inside the file's buffer")
    return binary[off:off + length]


def _rebuild(path: Path, doc: dict, binary: bytes, contents: dict, new_views: list, draco_views: set) -> bytes:
    """One buffer holding every bufferView's bytes (meshopt views decoded, each at its old offset modulo 4 so its
    accessors stay aligned) and the decoded Draco data; the Draco data's own views dropped when nothing else refers
    to them; the fallback buffers and both extensions gone from the document."""
    refs: list[dict] = []
    _refs({k: v for k, v in doc.items() if k != "bufferViews"}, refs)
    used = {r["bufferView"] for r in refs if r["bufferView"] >= 0}
    out, views, renumber = bytearray(), [], {}
    for i, view in enumerate(doc.get("bufferViews") or []):
        if i in draco_views and i not in used:
            continue
        data = _view_bytes(path, i, view, binary, contents)
        out += b"\0" * ((view.get("byteOffset", 0) - len(out)) % 4)
        renumber[i] = len(views)
        views.append({**view, "buffer": 0, "byteOffset": len(out), "byteLength": len(data)})
        out += data
    for k, (data, stride, target) in enumerate(new_views):
        out += b"\0" * (-len(out) % 4)
        renumber[-k - 1] = len(views)
        view = {"buffer": 0, "byteOffset": len(out), "byteLength": len(data), "target": target}
        views.append({**view, "byteStride": stride} if stride else view)
        out += data
    for r in refs:
        r["bufferView"] = renumber.get(r["bufferView"], r["bufferView"])
    out += b"\0" * (-len(out) % 4)
    doc["bufferViews"] = views
    buffer = {k: v for k, v in (doc.get("buffers") or [{}])[0].items() if k != "uri"}
    doc["buffers"] = [{**buffer, "byteLength": len(out)}]
    for key in ("extensionsUsed", "extensionsRequired"):
        if key in doc:
            doc[key] = [e for e in doc[key] if e not in (DRACO, MESHOPT)]
            if not doc[key]:
                del doc[key]
    return bytes(out)
