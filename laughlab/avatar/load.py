"""Loading a user's avatar: the glTF document, its humanoid bones, its rest pose, its morphs and expressions.

Accepted: a VRM 0.x file (``VRM`` extension), a VRM 1.0 file (``VRMC_vrm``), or a glTF 2.0
(``.glb``, or ``.gltf`` with embedded or neighbouring buffers) whose node names follow
:data:`laughlab.avatar.names.NODE_NAMES` (Mixamo, Ready Player Me, VRM or Unity names); meshes compressed
with Draco or meshopt are decoded as the file is loaded (:mod:`laughlab.avatar.compressed`).
Anything else raises :class:`AvatarError` (a ``ValueError``) whose one line names the file and
what is missing.  A file over :data:`MAX_BYTES` is refused from its size alone, before it is read.
"""
from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laughlab.avatar.check import check_bones, check_structure
from laughlab.avatar.compressed import DRACO, MESHOPT, decompress, is_fallback
from laughlab.avatar.errors import AvatarError
from laughlab.avatar.images import beside, read_images
from laughlab.avatar.names import REQUIRED, bones_by_name, node_ranks

MAX_BYTES = 100 * 1024 * 1024
"""The largest avatar file laughlab loads (100 MB)."""

#: extensions an avatar may list in ``extensionsRequired`` that laughlab reads (or may ignore without drawing
#: anything wrong): integer vertex attributes, material looks (the video uses the base colour; three.js
#: renders them), and Draco and meshopt mesh compression (decoded at load, :mod:`laughlab.avatar.compressed`);
#: any other required extension is refused: glTF 2.0 (3.12 *Specifying Extensions*) lists in
#: ``extensionsRequired`` the extensions an asset cannot be loaded without
READS_REQUIRED = ("KHR_mesh_quantization", "KHR_texture_transform", "KHR_materials_", DRACO, MESHOPT)

#: required extensions laughlab cannot read -> what to do instead
NOT_READ = {
    "KHR_texture_basisu": "export its textures as PNG or JPEG (not KTX2/Basis)",
}


@dataclass
class Avatar:
    """A humanoid avatar in its rest pose.

    Attributes
    ----------
    path : Path
    kind : str
        ``vrm0``, ``vrm1`` or ``gltf`` (bones recognised by name).
    doc : dict
        The glTF JSON document (as read, its Draco or meshopt compressed meshes decoded; the exporters copy it).
    binary : bytes
        The binary buffer (buffer 0; with the decoded data of a compressed avatar).
    bones : dict
        VRM humanoid bone name -> node index.
    parents : ndarray (N,) int
        Each node's parent, -1 for a scene root.
    rest_local : ndarray (N, 4, 4)
        Each node's local transform in the rest pose.
    rest_world : ndarray (N, 4, 4)
        Each node's world transform in the rest pose.
    facing : int
        +1 if the avatar faces +Z (its left is +X), -1 if it faces -Z (VRM 0.x); for an avatar turned some other
        way about Y, the nearer of the two (``turn`` is exact).
    turn : ndarray (3, 3)
        The rotation about Y that turns laughlab's frame (facing +Z, left +X) into the avatar's: it takes +X to
        the direction from the avatar's right upper arm to its left one, on the ground plane
        (:func:`facing_turn`); identity for +Z, ``diag(-1, 1, -1)`` for -Z.
    expressions : dict
        Expression name (VRM 1.0 preset names, 0.x names translated) -> list of (mesh node, morph index, weight).
    expression_rules : dict
        Expression name -> its VRM rules: ``isBinary`` (bool; VRM 0.x and 1.0) and ``overrideBlink``,
        ``overrideMouth``, ``overrideLookAt`` (``none``, ``block`` or ``blend``; VRM 1.0), for those that set any.
    morph_names : dict
        Mesh node index -> its morph target names ('' where unnamed).
    morph_defaults : dict
        Mesh node index -> its morph targets' default weights: the node's ``weights``, else its mesh's,
        else zeros (glTF 2.0, 3.7.2.2 *Morph Targets*: ``mesh.weights`` holds the default weights, used where the
        node has no ``weights`` of its own; without either, the defaults are 0).
    images : dict
        Image index -> its bytes, for the images outside the buffer (files beside a ``.gltf``, ``data:`` URIs),
        read once at load (:func:`laughlab.avatar.images.read_images`: every image checked by Pillow).
    """

    path: Path
    kind: str
    doc: dict
    binary: bytes
    bones: dict
    parents: np.ndarray
    rest_local: np.ndarray
    rest_world: np.ndarray
    facing: int
    turn: np.ndarray = field(default_factory=lambda: np.eye(3))
    expressions: dict = field(default_factory=dict)
    morph_names: dict = field(default_factory=dict)
    morph_defaults: dict = field(default_factory=dict)
    expression_rules: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)

    @property
    def order(self) -> list[int]:
        """Node indices, every parent before its children."""
        depth = np.zeros(len(self.parents), int)
        for i in range(len(self.parents)):
            p, d = self.parents[i], 0
            while p >= 0:
                p, d = self.parents[p], d + 1
            depth[i] = d
        return [int(i) for i in np.argsort(depth, kind="stable")]

    def leg_height_m(self) -> float:
        """The hips' height above the lowest of the feet and toes in the rest pose (m)."""
        ys = [self.rest_world[self.bones[b], 1, 3] for b in ("leftFoot", "rightFoot", "leftToes", "rightToes")
              if b in self.bones]
        return float(self.rest_world[self.bones["hips"], 1, 3] - min(ys))

    def all_morph_names(self) -> set[str]:
        return {n for names in self.morph_names.values() for n in names if n}


#: VRM 0.x preset names -> VRM 1.0 preset names
VRM0_PRESETS = {"a": "aa", "i": "ih", "u": "ou", "e": "ee", "o": "oh", "joy": "happy", "angry": "angry",
                "sorrow": "sad", "fun": "relaxed", "blink": "blink", "blink_l": "blinkLeft", "blink_r": "blinkRight",
                "lookup": "lookUp", "lookdown": "lookDown", "lookleft": "lookLeft", "lookright": "lookRight",
                "neutral": "neutral", "surprised": "surprised"}


def load_character(path: str | Path) -> "Avatar":
    """:func:`load_avatar` for ``character=PATH``: a bad file is the run's one-line error (``LaughlabError``)."""
    from laughlab.core.errors import LaughlabError

    try:
        return load_avatar(path)
    except AvatarError as exc:
        raise LaughlabError(str(exc)) from None


def _fail(path: Path, what: str) -> AvatarError:
    """``PATH: what``, or ``PATH is ...``/``PATH has ...`` where ``what`` is a verb's phrase (a review: "fake.vrm: is
    not a glTF file")."""
    return AvatarError(f"{path} {what}" if what.startswith(("is ", "has ")) else f"{path}: {what}")


def read_gltf(path: str | Path) -> tuple[dict, bytes]:
    """The JSON document and buffer 0 of a ``.glb``/``.vrm`` (binary) or ``.gltf`` (JSON) file; a buffer
    shorter than its declared ``byteLength`` (a file cut short) is refused in one line. ``~`` is the home folder
    (a quoted ``character='~/my.vrm'``, or a shell that leaves it, as zsh does after ``=``)."""
    path = Path(path).expanduser()
    doc, binary = _read_gltf(path)
    declared = ((doc.get("buffers") or [{}])[0] or {}).get("byteLength")
    if isinstance(declared, int) and len(binary) < declared:
        raise _fail(path, f"its buffer holds {len(binary):,} bytes where the file declares {declared:,}: "
                          "it is cut short")
    return doc, binary


def _read_gltf(path: Path) -> tuple[dict, bytes]:
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise _fail(path, f"cannot read the avatar ({exc.strerror or exc})") from None
    if not path.is_file():
        raise _fail(path, "is not a file")
    if size > MAX_BYTES:
        raise _fail(path, f"the avatar is {size / 1e6:.0f} MB; laughlab loads avatars up to "
                          f"{MAX_BYTES // (1024 * 1024)} MB")
    with open(path, "rb") as fh:
        head = fh.read(12)
        if len(head) == 12 and head[:4] == b"glTF":
            version, total = struct.unpack_from("<II", head, 4)
            if version != 2:
                raise _fail(path, f"is glTF version {version}; laughlab reads glTF 2.0")
            data = head + fh.read()
            if total != len(data) or len(data) < 20:
                raise _fail(path, "is a truncated glTF binary (its header's length is not the file's)")
            n, kind = struct.unpack_from("<I4s", data, 12)
            if kind != b"JSON" or 20 + n > len(data):
                raise _fail(path, "is not a glTF binary (no JSON chunk)")
            doc = _json(path, data[20:20 + n])
            binary = b""
            if 20 + n + 8 <= len(data):
                m, kind2 = struct.unpack_from("<I4s", data, 20 + n)
                if kind2 == b"BIN\0":
                    binary = data[28 + n:28 + n + m]
            return doc, binary
        fh.seek(0)
        doc = _json(path, fh.read())
    if "asset" not in doc:
        raise _fail(path, "is JSON but not glTF (no 'asset')")
    buffers = doc.get("buffers") or []
    binary = b""
    if len([b for b in buffers if not is_fallback(b)]) > 1:   # a meshopt fallback holds nothing to read
        raise _fail(path, f"has {len(buffers)} buffers; laughlab reads avatars with one (a .glb, or a .gltf "
                          "with one .bin)")
    if buffers:
        uri = buffers[0].get("uri", "")
        if uri.startswith("data:"):
            binary = base64.b64decode(uri.split(",", 1)[1])
        elif uri:
            bin_path = beside(path, uri)
            try:
                bin_size = bin_path.stat().st_size
                if size + bin_size > MAX_BYTES:
                    raise _fail(path, f"the avatar with its buffer {uri} is {(size + bin_size) / 1e6:.0f} MB; "
                                      f"laughlab loads avatars up to {MAX_BYTES // (1024 * 1024)} MB")
                binary = bin_path.read_bytes()
            except OSError:
                raise _fail(path, f"its buffer {uri} cannot be read") from None
    return doc, binary


#: other formats an avatar comes in, named in the line that refuses them (an avatar developer's review: Mixamo
#: gives FBX, and "is not a glTF file" sent its user searching)
OTHER_FORMATS = {".fbx": "FBX", ".obj": "OBJ", ".blend": "a Blender file", ".dae": "COLLADA", ".usdz": "USDZ",
                 ".usd": "USD", ".pmx": "a MikuMikuDance model", ".vroid": "a VRoid Studio project"}


def _json(path: Path, raw: bytes) -> dict:
    try:
        doc = json.loads(raw)
    except (UnicodeDecodeError, json.JSONDecodeError):
        other = OTHER_FORMATS.get(path.suffix.lower())
        if other:
            raise _fail(path, f"is {other}, which laughlab does not read: export the avatar as glTF binary (.glb) "
                              "or VRM (.vrm), e.g. Blender's File > Export > glTF 2.0, VRoid Studio's Export VRM "
                              "(docs/avatars.md)") from None
        raise _fail(path, "is not a glTF file (neither a glTF binary nor glTF JSON)") from None
    if not isinstance(doc, dict):
        raise _fail(path, "is not a glTF file")
    return doc


def _quat_matrix(q) -> np.ndarray:
    x, y, z, w = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def local_matrix(node: dict) -> np.ndarray:
    """A node's local transform (4x4) from its ``matrix`` or its TRS."""
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    m = np.eye(4)
    m[:3, :3] = _quat_matrix(node.get("rotation", (0, 0, 0, 1))) * np.asarray(node.get("scale", (1, 1, 1)), float)
    m[:3, 3] = node.get("translation", (0, 0, 0))
    return m


def _obj(path: Path, value, what: str) -> dict:
    """``value`` if it is a JSON object, ``{}`` if absent (None is damage too, where the key is there)."""
    if not isinstance(value, dict):
        raise _fail(path, f"its {what} is {json.dumps(value)[:40]}, not an object; the file is damaged")
    return value


def _items(path: Path, parent: dict, key: str, what: str, kind: type = dict):
    """``parent[key]`` (a JSON object or list, as ``kind``; empty if absent), or one line saying it is damaged."""
    value = parent.get(key, kind())
    if not isinstance(value, kind):
        raise _fail(path, f"its {what}.{key} is {json.dumps(value)[:40]}, not "
                          f"{'an object' if kind is dict else 'a list'}; the file is damaged")
    return value


def _whole(path: Path, d: dict, key: str, what: str, default=None) -> int:
    v = d.get(key, default)
    if v is None:
        raise _fail(path, f"its {what} has no {key}; the file is damaged")
    if isinstance(v, bool) or not isinstance(v, int):
        raise _fail(path, f"its {what} has {key} {json.dumps(v)[:40]}, not a whole number; the file is damaged")
    return v


def _number(path: Path, d: dict, key: str, what: str, default: float) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(path, f"its {what} has {key} {json.dumps(v)[:40]}, not a number; the file is damaged")
    return float(v)


def _extension(path: Path, doc: dict, name: str) -> dict:
    return _obj(path, _obj(path, doc.get("extensions", {}), "extensions")[name], f"{name} extension")


def _humanoid(path: Path, doc: dict) -> tuple[str, dict]:
    """The kind of avatar and its humanoid bones; the VRM extension's JSON checked as it is read (a damaged one
    ended in a traceback, a review found), each failure one line naming the field."""
    ext = _obj(path, doc.get("extensions", {}), "extensions")
    n_nodes = len(doc.get("nodes") or [])
    if "VRMC_vrm" in ext:
        human = _obj(path, _extension(path, doc, "VRMC_vrm").get("humanoid", {}), "VRMC_vrm.humanoid")
        bones = {k: _obj(path, v, f"VRMC_vrm.humanoid.humanBones.{k}").get("node")
                 for k, v in _items(path, human, "humanBones", "VRMC_vrm.humanoid").items()}
        kind = "vrm1"
    elif "VRM" in ext:
        human = _obj(path, _extension(path, doc, "VRM").get("humanoid", {}), "VRM.humanoid")
        bones = {}
        for k, b in enumerate(_items(path, human, "humanBones", "VRM.humanoid", list)):
            b = _obj(path, b, f"VRM.humanoid.humanBones[{k}]")
            bones[b.get("bone")] = b.get("node")
        kind = "vrm0"
    else:
        names = [n.get("name", "") if isinstance(n.get("name", ""), str) else "" for n in doc.get("nodes") or []]
        bones = bones_by_name(names, node_ranks(doc))
        if not bones:
            raise _fail(path, "has no humanoid: no VRM humanoid bone map and no node named as a Mixamo, Ready "
                              "Player Me or VRM bone (docs/avatars.md lists the names)")
        kind = "gltf"
    for b in REQUIRED:   # present with a node that is not there: damage, not a missing bone (a new-user review)
        v = bones.get(b)
        if v is not None and not (isinstance(v, int) and not isinstance(v, bool) and 0 <= v < n_nodes):
            raise _fail(path, f"its humanoid bone {b} refers to node {json.dumps(v)[:40]}, which is not there (the "
                              f"file has {n_nodes} node{'s' if n_nodes != 1 else ''}); the file is damaged")
    bones = {k: int(v) for k, v in bones.items() if isinstance(v, int) and 0 <= v < n_nodes}
    missing = [b for b in REQUIRED if b not in bones]
    if missing:
        what = "VRM humanoid" if kind != "gltf" else "humanoid (bones recognised by name)"
        raise _fail(path, f"the {what} lacks the required bone{'s' if len(missing) > 1 else ''} "
                          f"{', '.join(missing)}")
    return kind, bones


def _expressions(path: Path, doc: dict, kind: str, mesh_nodes: dict[int, list[int]]) -> tuple[dict, dict]:
    """Expression -> [(mesh node, morph index, weight 0-1)], and expression -> its rules (``isBinary``,
    ``override*``: VRMC_vrm-1.0 expressions.md, *expression object*; VRM 0.x has ``isBinary`` only).  The
    extension's JSON is checked as it is read (one line naming the field, as :func:`_humanoid`)."""
    out: dict[str, list] = {}
    rules: dict[str, dict] = {}
    if kind == "vrm1":
        groups = _obj(path, _extension(path, doc, "VRMC_vrm").get("expressions", {}), "VRMC_vrm.expressions")
        for section in ("preset", "custom"):
            for name, e in _items(path, groups, section, "VRMC_vrm.expressions").items():
                what = f"VRMC_vrm.expressions.{section}.{name}"
                e = _obj(path, e, what)
                binds = []
                for k, b in enumerate(_items(path, e, "morphTargetBinds", what, list)):
                    b = _obj(path, b, f"{what}.morphTargetBinds[{k}]")
                    at = f"{what}.morphTargetBinds[{k}]"
                    binds.append((_whole(path, b, "node", at), _whole(path, b, "index", at),
                                  _number(path, b, "weight", at, 1.0)))
                out[name] = binds
                rule = {k: e[k] for k in ("overrideBlink", "overrideMouth", "overrideLookAt")
                        if e.get(k) in ("block", "blend")}
                if e.get("isBinary") is True:
                    rule["isBinary"] = True
                if rule:
                    rules[name] = rule
    elif kind == "vrm0":
        master = _obj(path, _extension(path, doc, "VRM").get("blendShapeMaster", {}), "VRM.blendShapeMaster")
        for j, g in enumerate(_items(path, master, "blendShapeGroups", "VRM.blendShapeMaster", list)):
            what = f"VRM.blendShapeMaster.blendShapeGroups[{j}]"
            g = _obj(path, g, what)
            preset = str(g.get("presetName", "unknown")).lower()
            name = VRM0_PRESETS.get(preset, str(g.get("name", preset))) if preset != "unknown" \
                else str(g.get("name", ""))
            binds = []
            for k, b in enumerate(_items(path, g, "binds", what, list)):
                at = f"{what}.binds[{k}]"
                b = _obj(path, b, at)
                mesh, index = _whole(path, b, "mesh", at), _whole(path, b, "index", at)
                weight = _number(path, b, "weight", at, 100.0) / 100.0
                binds += [(node, index, weight) for node in mesh_nodes.get(mesh, [])]
            out[name] = binds
            if g.get("isBinary") is True:
                rules[name] = {"isBinary": True}
    return out, rules


def _check_required(path: Path, doc: dict) -> None:
    """Refuse an avatar that requires an extension laughlab cannot read (a Draco-compressed mesh read as zeros
    drew nothing and the viewer failed, a review found, both with exit 0)."""
    required = doc.get("extensionsRequired") or []
    if not isinstance(required, list):
        raise _fail(path, "its extensionsRequired is not a list; the file is damaged")
    for name in required:
        if not isinstance(name, str) or not name.startswith(READS_REQUIRED):
            hint = NOT_READ.get(name, "export it without that extension")
            raise _fail(path, f"the avatar requires the glTF extension {name}, which laughlab cannot read; "
                              f"{hint}")


#: an avatar whose shoulders lie within this angle (degrees) of the X axis faces exactly +Z or -Z (exporters'
#: rounding: Godette's are 1e-5 degrees off), so its retargeting is the exact half turn or none
AXIS_SNAP_DEG = 0.01


def facing_turn(path: Path, left: np.ndarray) -> np.ndarray:
    """The avatar's ``turn`` (see :class:`Avatar`) from ``left``, the vector from its right upper arm to its left
    one in the rest pose: any yaw (an export with the wrong forward axis faces +-X; retargeted as +-Z it twisted
    the arms back, a review found), or one line if the arms are one above the other."""
    x, z = float(left[0]), float(left[2])
    flat = np.hypot(x, z)
    if not flat > 0.05 * np.linalg.norm(left):
        raise _fail(path, "its upper arms are one above the other in the rest pose, so which way it faces cannot be "
                          "told; export it standing, in a T-pose or an A-pose")
    x, z = x / flat, z / flat
    if abs(z) < np.sin(np.radians(AXIS_SNAP_DEG)):
        x, z = (1.0 if x > 0 else -1.0), 0.0
    return np.array([[x, 0.0, -z], [0.0, 1.0, 0.0], [z, 0.0, x]])


def _target_names(d: dict) -> list[str]:
    """``extras.targetNames`` (the exporters' convention for morph names), if it is a list; names as strings."""
    names = (d.get("extras") if isinstance(d.get("extras"), dict) else {}).get("targetNames")
    return [n if isinstance(n, str) else "" for n in names] if isinstance(names, list) else []


def _default_weights(node: dict, mesh: dict, n: int) -> np.ndarray:
    """A mesh node's default morph weights: ``node.weights``, else ``mesh.weights``, else zeros (glTF 2.0,
    3.7.2.2 *Morph Targets* and 5.25 ``node.weights``); a list of the wrong length or not numbers is ignored."""
    for w in (node.get("weights"), mesh.get("weights")):
        if isinstance(w, list) and len(w) == n and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in w):
            return np.nan_to_num(np.asarray(w, dtype=np.float64))
    return np.zeros(n)


def load_avatar(path: str | Path) -> Avatar:
    """Read and check an avatar file (see the module's docstring); ``~`` is the home folder."""
    path = Path(path).expanduser()
    doc, binary = read_gltf(path)
    nodes = doc.get("nodes") or []
    if not nodes:
        raise _fail(path, "has no nodes, so no skeleton")
    _check_required(path, doc)
    doc, binary = decompress(path, doc, binary)
    check_structure(path, doc, binary)
    kind, bones = _humanoid(path, doc)
    n = len(nodes)
    parents = np.full(n, -1, int)
    for i, node in enumerate(nodes):
        for c in node.get("children") or []:
            if 0 <= c < n:
                parents[c] = i
    rest_local = np.array([local_matrix(nd) for nd in nodes])
    av = Avatar(path, kind, doc, binary, bones, parents, rest_local, np.zeros_like(rest_local), 1)
    av.images = read_images(path, doc, binary)
    order = av.order
    for i in order:
        av.rest_world[i] = rest_local[i] if parents[i] < 0 else av.rest_world[parents[i]] @ rest_local[i]
    check_bones(path, bones, av.rest_world, order, nodes)
    av.turn = facing_turn(path, av.rest_world[bones["leftUpperArm"], :3, 3] - av.rest_world[bones["rightUpperArm"], :3, 3])
    av.facing = 1 if av.turn[0, 0] > 0 else -1
    if kind == "gltf" and not doc.get("skins") and not any("mesh" in nd for nd in nodes):
        raise _fail(path, "has bones but nothing to show: no skin and no mesh")
    mesh_nodes: dict[int, list[int]] = {}
    for i, nd in enumerate(nodes):
        if "mesh" in nd:
            mesh_nodes.setdefault(int(nd["mesh"]), []).append(i)
            mesh = doc["meshes"][nd["mesh"]]
            names = _target_names(mesh)
            prims = mesh.get("primitives") or [{}]
            n_t = len(prims[0].get("targets") or [])
            if not names:
                names = _target_names(prims[0])
            av.morph_names[i] = (names + [""] * n_t)[:n_t]
            av.morph_defaults[i] = _default_weights(nd, mesh, n_t)
    av.expressions, av.expression_rules = _expressions(path, doc, kind, mesh_nodes)
    return av
