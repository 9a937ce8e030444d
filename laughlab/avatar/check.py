"""The structure of an avatar's glTF, checked before anything reads or copies it.

The exporters copy the avatar's document and buffer into ``character.glb`` and the video draws its meshes,
so a reference out of range or a buffer view past the buffer's end would become a broken file of ours or a
traceback half-way through a run.  These are the glTF 2.0 rules (Khronos, *glTF 2.0 Specification*, 2021,
sections 3.6 *Buffers*, 3.7 *Accessors*, 3.5 *Nodes*) that laughlab relies on; the Khronos validator checks
many more.  Each failure is one line naming the element.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from laughlab.avatar.errors import AvatarError

#: bytes of one component (glTF 2.0, 3.6.2.2) and components of one element (3.6.2.3)
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
#: each component type's numpy type (3.6.2.2)
COMPONENT_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _index(path: Path, value, n: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n:
        raise AvatarError(f"{path}: {what} refers to {value!r}, and the file has {n}; the file is damaged")
    return value


def _int(path: Path, d: dict, key: str, what: str, default=None, least: int = 0) -> int:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int) or v < least:
        raise AvatarError(f"{path}: {what} has {key} {v!r}; the file is damaged")
    return v


def check_structure(path: Path, doc: dict, binary: bytes) -> None:
    """Refuse a document whose buffer views, accessors, meshes, skins, nodes, images or animations refer to
    what is not there, or whose nodes are not a forest (a node with two parents, a cycle)."""
    views, accessors = doc.get("bufferViews") or [], doc.get("accessors") or []
    for i, v in enumerate(views):
        what = f"bufferView {i}"
        _int(path, v, "buffer", what)
        if v["buffer"] != 0:
            raise AvatarError(f"{path}: {what} refers to buffer {v['buffer']}; laughlab reads avatars with one buffer")
        off, length = _int(path, v, "byteOffset", what, 0), _int(path, v, "byteLength", what, least=1)
        if off + length > len(binary):
            raise AvatarError(f"{path}: {what} ends at byte {off + length:,}, past its buffer's {len(binary):,}; "
                              "the file is damaged")
    for i, a in enumerate(accessors):
        what = f"accessor {i}"
        if a.get("componentType") not in COMPONENT_BYTES or a.get("type") not in TYPE_COMPONENTS:
            raise AvatarError(f"{path}: {what} has componentType {a.get('componentType')!r} and type "
                              f"{a.get('type')!r}; the file is damaged")
        count = _int(path, a, "count", what, least=1)
        size = COMPONENT_BYTES[a["componentType"]] * TYPE_COMPONENTS[a["type"]]
        if "bufferView" in a:
            view = views[_index(path, a["bufferView"], len(views), what)]
            stride = view.get("byteStride") or size
            end = _int(path, a, "byteOffset", what, 0) + (count - 1) * stride + size
            if end > view["byteLength"]:
                raise AvatarError(f"{path}: {what} needs {end:,} bytes of bufferView {a['bufferView']}, which holds "
                                  f"{view['byteLength']:,}; the file is damaged")
        sparse = a.get("sparse")
        if sparse:
            for part in ("indices", "values"):
                _index(path, (sparse.get(part) or {}).get("bufferView"), len(views), f"{what}'s sparse {part}")
    meshes = doc.get("meshes") or []
    for i, m in enumerate(meshes):
        for prim in m.get("primitives") or []:
            refs = list((prim.get("attributes") or {}).values()) + [
                v for t in prim.get("targets") or [] for v in t.values()]
            refs += [prim["indices"]] if "indices" in prim else []
            for r in refs:
                _index(path, r, len(accessors), f"mesh {i}")
    nodes = doc.get("nodes") or []
    skins = doc.get("skins") or []
    for i, s in enumerate(skins):
        for j in s.get("joints") or []:
            _index(path, j, len(nodes), f"skin {i}'s joint")
        if "inverseBindMatrices" in s:
            _index(path, s["inverseBindMatrices"], len(accessors), f"skin {i}")
    for i, img in enumerate(doc.get("images") or []):
        if not isinstance(img, dict):
            raise AvatarError(f"{path}: image {i} is not an object; the file is damaged")
        if "bufferView" in img:
            _index(path, img["bufferView"], len(views), f"image {i}")
    for i, anim in enumerate(doc.get("animations") or []):
        samplers = anim.get("samplers") or []
        for s in samplers:
            _index(path, s.get("input"), len(accessors), f"animation {i}'s sampler")
            _index(path, s.get("output"), len(accessors), f"animation {i}'s sampler")
        for c in anim.get("channels") or []:
            _index(path, c.get("sampler"), len(samplers), f"animation {i}'s channel")
            _index(path, (c.get("target") or {}).get("node", 0), len(nodes), f"animation {i}'s channel")
    _check_nodes(path, nodes, len(meshes), len(skins))


def _check_nodes(path: Path, nodes: list, n_meshes: int, n_skins: int) -> None:
    parent = [-1] * len(nodes)
    for i, nd in enumerate(nodes):
        if not isinstance(nd, dict):
            raise AvatarError(f"{path}: node {i} is not an object; the file is damaged")
        if "mesh" in nd:
            _index(path, nd["mesh"], n_meshes, f"node {i}'s mesh")
        if "skin" in nd:
            _index(path, nd["skin"], n_skins, f"node {i}'s skin")
        for c in nd.get("children") or []:
            _index(path, c, len(nodes), f"node {i}'s child")
            if c == i:
                raise AvatarError(f"{path}: node {i} is its own child; glTF nodes form trees, and the file is damaged")
            if parent[c] >= 0:
                raise AvatarError(f"{path}: node {c} has two parents (nodes {parent[c]} and {i}); glTF nodes form "
                                  "trees, and the file is damaged")
            parent[c] = i
        numbers = [nd[k] for k in ("matrix", "rotation", "scale", "translation") if k in nd]
        try:
            finite = all(np.isfinite(np.asarray(v, dtype=np.float64)).all() for v in numbers)
        except (TypeError, ValueError):
            finite = False
        if not finite:
            raise AvatarError(f"{path}: node {i} has a transform that is not finite numbers; the file is damaged")
    for i in range(len(nodes)):   # a cycle: walking up the parents never reaches a root
        p, steps = i, 0
        while p >= 0 and steps <= len(nodes):
            p, steps = parent[p], steps + 1
        if p >= 0:   # after more steps than there are nodes, the walk is going round the cycle: p is on it
            raise AvatarError(f"{path}: node {p} is its own ancestor (a cycle of children); glTF nodes form "
                              "trees, and the file is damaged")


def check_bones(path: Path, bones: dict, rest_world: np.ndarray, order: list[int], nodes: list | None = None) -> None:
    """Refuse two of the bones laughlab drives (:data:`laughlab.avatar.names.JOINT_TO_VRM`) on one node, and such
    a bone whose rest transform cannot be inverted (a zero scale on it or an ancestor; tested relative to its
    largest scale, so an avatar in centimetres or scaled by 0.01 is fine): the body's rotations are solved in
    each bone's own frame.  Bones laughlab does not drive (eyes, jaw, fingers) are not checked.  Bones are taken
    parent first (``order``), so the line names the highest bone a zero scale reaches.  A driven bone on a skinned
    mesh node (``nodes``) is refused too: glTF ignores that node's own transform (2.0 spec, 3.7.3 *Skins*), so
    its animation would move nothing."""
    from laughlab.avatar.names import JOINT_TO_VRM

    driven = set(JOINT_TO_VRM.values())
    rank = {node: k for k, node in enumerate(order)}
    seen: dict[int, str] = {}
    for bone, node in sorted(((b, n) for b, n in bones.items() if b in driven),
                             key=lambda b: (rank.get(b[1], 0), b[0])):
        if node in seen:
            raise AvatarError(f"{path}: the humanoid maps {seen[node]} and {bone} to the same node {node}; "
                              "each bone needs its own node")
        seen[node] = bone
        if nodes is not None and "skin" in nodes[node]:
            raise AvatarError(f"{path}: the {bone} bone is node {node}, a skinned mesh "
                              f"({nodes[node].get('name', 'unnamed')!r}), whose own transform glTF ignores; map "
                              "the bone to its joint")
        scales = np.linalg.svd(rest_world[node][:3, :3], compute_uv=False)
        if not np.isfinite(scales).all() or scales[-1] <= 1e-9 * scales[0]:
            raise AvatarError(f"{path}: the {bone} bone (node {node}) has a zero scale in its rest pose (or an "
                              "ancestor has), so it cannot be posed; give it a non-zero scale")
