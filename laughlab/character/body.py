"""A skinned human character built from the humanoid skeleton by this code (no third-party assets).

Where it comes from and its licence: every vertex is computed here from the joint offsets of
:data:`laughlab.motion.skeleton.HUMANOID`, deterministically, so the character is part of
laughlab's source and under its licence (MIT).  It is a mannequin, not a likeness: limbs and
trunk are tapered tubes with rounded ends along the bones, the head a sphere with a nose,
eyes, brows and lips.

Skinning (linear blend, at most two bones a vertex): a tube follows the joint whose rotation
moves it (a bone from joint ``j`` to its child rotates with ``j``); within a quarter of its
length from either end it blends towards the neighbouring bone, half and half at the joint,
so elbows, knees and the spine bend smoothly.  Head, face and neck-top follow ``head``.

Morph targets (position offsets in the rest pose, metres):

* the face, ARKit names (Apple's ``ARFaceAnchor.BlendShapeLocation``) for every shape the
  face plugins write: ``jawOpen``, ``mouthClose``, ``mouthSmile*``, ``mouthFrown*``, ``mouthStretch*``,
  ``mouthUpperUp*``, ``mouthLowerDown*``, ``cheekSquint*``, ``eyeBlink*``, ``eyeSquint*``,
  ``browInnerUp``, ``browDown*``, ``browOuterUp*`` (``*`` = ``Left``/``Right``, the
  character's own sides: left is +X);
* the body: ``chest`` (the rib cage widens and lifts) and ``belly`` (the abdomen bulges
  forward), driven by the ``chest`` and ``belly`` channels of ``body=shapes`` and
  ``body=hill``.

Units: the skeleton is in centimetres; :func:`build` returns metres (glTF's unit).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from laughlab.motion.skeleton import HUMANOID, Skeleton, forward_kinematics, rest_pose

#: the morph targets, face first (ARKit names), then the body
FACE_MORPHS = (
    "jawOpen", "mouthClose", "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight",
    "mouthStretchLeft", "mouthStretchRight", "mouthUpperUpLeft", "mouthUpperUpRight",
    "mouthLowerDownLeft", "mouthLowerDownRight", "cheekSquintLeft", "cheekSquintRight",
    "eyeBlinkLeft", "eyeBlinkRight", "eyeSquintLeft", "eyeSquintRight", "browInnerUp",
    "browDownLeft", "browDownRight", "browOuterUpLeft", "browOuterUpRight",
)
BODY_MORPHS = ("chest", "belly")
MORPHS = FACE_MORPHS + BODY_MORPHS

SKIN = (0.87, 0.70, 0.58)
SHIRT = (0.32, 0.42, 0.60)
TROUSERS = (0.22, 0.24, 0.30)
SHOES = (0.12, 0.10, 0.09)
WHITE = (0.95, 0.95, 0.95)
IRIS = (0.20, 0.28, 0.36)
BROW = (0.25, 0.17, 0.12)
LIP = (0.70, 0.35, 0.35)
MOUTH = (0.25, 0.06, 0.09)

#: (joint, child or None for its end site, radius at the joint cm, radius at the far end cm,
#:  depth/width ratio of the cross-section, colour)
LIMBS = (
    ("hips", "spine", 15.0, 14.0, 0.70, TROUSERS),
    ("spine", "spine1", 14.0, 14.0, 0.72, SHIRT),
    ("spine1", "spine2", 14.5, 15.5, 0.72, SHIRT),
    ("spine2", "neck", 15.5, 6.0, 0.66, SHIRT),
    ("neck", "head", 5.0, 5.0, 1.0, SKIN),
    ("left_clavicle", "left_upper_arm", 5.0, 5.5, 1.0, SHIRT),
    ("left_upper_arm", "left_forearm", 5.0, 4.0, 1.0, SHIRT),
    ("left_forearm", "left_hand", 4.0, 3.0, 1.0, SKIN),
    ("left_hand", None, 3.2, 2.6, 0.55, SKIN),
    ("right_clavicle", "right_upper_arm", 5.0, 5.5, 1.0, SHIRT),
    ("right_upper_arm", "right_forearm", 5.0, 4.0, 1.0, SHIRT),
    ("right_forearm", "right_hand", 4.0, 3.0, 1.0, SKIN),
    ("right_hand", None, 3.2, 2.6, 0.55, SKIN),
    ("left_thigh", "left_shin", 8.0, 6.0, 1.0, TROUSERS),
    ("left_shin", "left_foot", 5.5, 4.2, 1.0, TROUSERS),
    ("left_foot", "left_toe", 4.2, 4.0, 0.8, SHOES),
    ("left_toe", None, 4.0, 3.2, 0.8, SHOES),
    ("right_thigh", "right_shin", 8.0, 6.0, 1.0, TROUSERS),
    ("right_shin", "right_foot", 5.5, 4.2, 1.0, TROUSERS),
    ("right_foot", "right_toe", 4.2, 4.0, 0.8, SHOES),
    ("right_toe", None, 4.0, 3.2, 0.8, SHOES),
)
#: the head sphere: radius (cm) and centre above the head joint (cm)
HEAD_RADIUS_CM = 10.0
HEAD_CENTRE_CM = (0.0, 10.0, 0.0)


@dataclass
class Character:
    """A skinned mesh in its rest pose (the skeleton's T-pose), metres.

    Attributes
    ----------
    positions, normals : ndarray (V, 3) float32
    colors : ndarray (V, 3) float32, linear RGB in [0, 1]
    indices : ndarray (T * 3,) uint32, counter-clockwise seen from outside
    joints : ndarray (V, 4) uint16, indices into ``skeleton`` joints
    weights : ndarray (V, 4) float32, each row sums to 1
    morph_names : tuple[str, ...]
    morphs : ndarray (M, V, 3) float32, position offsets
    skeleton : Skeleton
    rest_root_m : ndarray (3,), the root (hips) position in the rest pose
    """

    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    morph_names: tuple
    morphs: np.ndarray
    skeleton: Skeleton
    rest_root_m: np.ndarray = field(default_factory=lambda: np.zeros(3))


class _Builder:
    """Accumulates parts: vertices (cm), faces, two bones and a weight per vertex, colours, tags."""

    def __init__(self):
        self.v, self.f, self.bones, self.w, self.col, self.tag = [], [], [], [], [], []
        self.n = 0

    def add(self, verts, faces, bones, w, colour, tag: str) -> None:
        verts = np.asarray(verts, float)
        self.v.append(verts)
        self.f.append(np.asarray(faces, np.int64) + self.n)
        self.bones.append(np.broadcast_to(np.asarray(bones, np.int64), (len(verts), 2)))
        self.w.append(np.broadcast_to(np.asarray(w, float), (len(verts),)))
        self.col.append(np.broadcast_to(np.asarray(colour, float), (len(verts), 3)))
        self.tag += [tag] * len(verts)
        self.n += len(verts)


def _frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit axis ``d``: 'width' (towards X, or Z for limbs
    along X) and 'depth'."""
    ref = np.array([0.0, 0.0, 1.0]) if abs(d[0]) > 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = ref - (ref @ d) * d
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def _capsule(a, b, r0, r1, depth: float, sides: int = 16, rings: int = 8, cap: int = 3):
    """A tapered tube from ``a`` to ``b`` with rounded ends: vertices, faces, and each vertex's
    position along the bone (0 at ``a``, 1 at ``b``; caps beyond)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    length = float(np.linalg.norm(b - a))
    d = (b - a) / length
    e1, e2 = _frame(d)
    profile = []  # (axial position cm, radius factor, radius cm)
    for k in range(cap, 0, -1):
        th = 0.5 * np.pi * k / (cap + 1)
        profile.append((-r0 * np.sin(th), np.cos(th), r0))
    for k in range(rings + 1):
        u = k / rings
        profile.append((u * length, 1.0, r0 + (r1 - r0) * u))
    for k in range(1, cap + 1):
        th = 0.5 * np.pi * k / (cap + 1)
        profile.append((length + r1 * np.sin(th), np.cos(th), r1))
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(ang)[:, None] * e1 + depth * np.sin(ang)[:, None] * e2
    verts, along = [], []
    for t, f, r in profile:
        verts.append(a + t * d + f * r * ring)
        along.append(np.full(sides, t / length))
    verts.append(a - r0 * d)
    verts.append(b + r1 * d)
    along += [np.array([-r0 / length]), np.array([1 + r1 / length])]
    verts = np.vstack(verts)
    n_rings = len(profile)
    faces = []
    for i in range(n_rings - 1):
        for s in range(sides):
            p, q = i * sides + s, i * sides + (s + 1) % sides
            faces += [(p, q, q + sides), (p, q + sides, p + sides)]
    apex0, apex1 = n_rings * sides, n_rings * sides + 1
    last = (n_rings - 1) * sides
    for s in range(sides):
        faces.append((apex0, (s + 1) % sides, s))
        faces.append((apex1, last + s, last + (s + 1) % sides))
    faces = np.array(faces)
    # winding: outward normals for a right-handed frame (d, e1, e2); flip if the frame is left-handed
    if np.dot(np.cross(e1, depth * e2), d) < 0:
        faces = faces[:, ::-1]
    return verts, faces, np.concatenate(along)


def _sphere(centre, radii, rows: int = 14, cols: int = 24):
    """A UV sphere (ellipsoid with radii ``(rx, ry, rz)``), poles on the Y axis."""
    c, r = np.asarray(centre, float), np.asarray(radii, float)
    verts = [c + (0.0, r[1], 0.0)]
    for i in range(1, rows):
        th = np.pi * i / rows
        ph = 2 * np.pi * np.arange(cols) / cols
        verts += list(c + np.stack([np.sin(th) * np.sin(ph) * r[0], np.full(cols, np.cos(th) * r[1]),
                                    np.sin(th) * np.cos(ph) * r[2]], axis=1))
    verts.append(c - (0.0, r[1], 0.0))
    faces = []
    for j in range(cols):
        faces.append((0, 1 + j, 1 + (j + 1) % cols))
    for i in range(rows - 2):
        for j in range(cols):
            p, q = 1 + i * cols + j, 1 + i * cols + (j + 1) % cols
            faces += [(p, p + cols, q + cols), (p, q + cols, q)]
    bottom = len(verts) - 1
    base = 1 + (rows - 2) * cols
    for j in range(cols):
        faces.append((bottom, base + (j + 1) % cols, base + j))
    return np.array(verts), np.array(faces)


def _normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def build(skeleton: Skeleton = HUMANOID) -> Character:
    """The character on ``skeleton`` (joint names of :data:`HUMANOID`), rest pose, metres."""
    rest = rest_pose(skeleton)
    pos = forward_kinematics(skeleton, rest[None], end_sites=True)[0]  # joints then end sites, cm
    jn = skeleton.n_joints
    end_of = {j: jn + i for i, j in enumerate(skeleton.leaves())}
    B = _Builder()
    ix = skeleton.index
    for name, child, r0, r1, depth, colour in LIMBS:
        j = ix(name)
        a = pos[j]
        b = pos[ix(child)] if child else pos[end_of[j]]
        verts, faces, u = _capsule(a, b, r0, r1, depth)
        parent = skeleton.parents[j]
        # the second bone and its weight: the parent near this joint, the child near the far end
        near = np.clip(0.5 - 2.0 * u, 0.0, 0.5) if parent >= 0 else np.zeros_like(u)
        far = np.clip(2.0 * u - 1.5, 0.0, 0.5) if child else np.zeros_like(u)
        other = np.where(near > 0, parent, ix(child) if child else j)
        B.add(verts, faces, np.stack([np.full(len(verts), j), other], axis=1), np.where(near > 0, near, far),
              colour, name)
    head = ix("head")
    hc = pos[head] + np.array(HEAD_CENTRE_CM)
    R = HEAD_RADIUS_CM
    hv, hf = _sphere(hc, (R, R * 1.12, R * 1.02), rows=26, cols=40)
    B.add(hv, hf, (head, head), 0.0, SKIN, "head")
    # nose, eyes, brows, lips and the mouth's inside, all on the head (cm from the head centre)
    nv, nf, _ = _capsule(hc + (0, 1.5, 9.6), hc + (0, -1.2, 11.0), 1.2, 1.0, 1.0, sides=10, rings=3, cap=2)
    B.add(nv, nf, (head, head), 0.0, SKIN, "nose")
    for side, sx in (("L", 1.0), ("R", -1.0)):
        ec = hc + (3.4 * sx, 2.4, 8.3)
        ev, ef = _sphere(ec, (1.6, 1.6, 1.6), rows=8, cols=12)
        cols = np.where(((ev - ec) @ (0, 0, 1) > 1.2)[:, None], IRIS, WHITE)
        B.add(ev, ef, (head, head), 0.0, cols, f"eye{side}")
        bv, bf, _ = _capsule(hc + (1.3 * sx, 5.2, 9.2), hc + (5.6 * sx, 5.0, 7.8), 0.55, 0.45, 0.6,
                             sides=8, rings=3, cap=1)
        B.add(bv, bf, (head, head), 0.0, BROW, f"brow{side}")
    for lip, y, z, r in (("lipU", -3.3, 9.4, 0.7), ("lipL", -4.7, 9.2, 0.75)):
        for sx in (1.0, -1.0):
            lv, lf, _ = _capsule(hc + (0.0, y, z + 0.4), hc + (3.2 * sx, y + (0.4 if lip == "lipL" else -0.1),
                                                              z - 1.2), r, 0.45, 0.8, sides=8, rings=3, cap=1)
            B.add(lv, lf, (head, head), 0.0, LIP, lip)
    mv, mf = _sphere(hc + (0, -4.0, 8.9), (2.9, 0.55, 0.6), rows=6, cols=12)
    B.add(mv, mf, (head, head), 0.0, MOUTH, "mouth")

    v = np.vstack(B.v)
    f = np.vstack(B.f)
    bones = np.vstack(B.bones)
    w2 = np.concatenate(B.w)
    tags = np.array(B.tag)
    joints = np.zeros((len(v), 4), np.uint16)
    weights = np.zeros((len(v), 4), np.float32)
    same = (bones[:, 1] == bones[:, 0]) | (w2 <= 0.0)  # one bone: unused slots are joint 0, weight 0 (glTF)
    joints[:, 0] = bones[:, 0]
    joints[:, 1] = np.where(same, 0, bones[:, 1])
    weights[:, 0] = np.where(same, 1.0, 1.0 - w2)
    weights[:, 1] = np.where(same, 0.0, w2)
    morphs = _morphs(v, tags, hc, pos, skeleton)
    return Character(
        positions=(v * 0.01).astype(np.float32), normals=_normals(v, f).astype(np.float32),
        colors=np.vstack(B.col).astype(np.float32), indices=f.reshape(-1).astype(np.uint32),
        joints=joints, weights=weights, morph_names=MORPHS, morphs=(morphs * 0.01).astype(np.float32),
        skeleton=skeleton, rest_root_m=pos[0] * 0.01)


def _bump(p: np.ndarray, centre, radius: float) -> np.ndarray:
    """Smooth falloff 1 at ``centre`` to 0 at ``radius`` (cm)."""
    d = np.linalg.norm(p - np.asarray(centre, float), axis=1) / radius
    return np.clip(1.0 - d * d, 0.0, 1.0) ** 2


def _morphs(v: np.ndarray, tags: np.ndarray, hc: np.ndarray, pos: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Position offsets (cm) of every morph target, :data:`MORPHS` order."""
    m = {name: np.zeros_like(v) for name in MORPHS}
    p = v - hc  # face coordinates: cm from the head centre
    face = np.isin(tags, ["head", "nose", "lipU", "lipL", "mouth"]) & (p[:, 2] > 2.0)
    lip_u, lip_l, mouth = tags == "lipU", tags == "lipL", tags == "mouth"
    # jaw: the chin, the lower lip and the mouth's lower half drop, a little back
    # the skin from the upper lip down follows the jaw in a smooth ramp (no tearing at the lips)
    chin = face & (p[:, 1] < -3.3) & (tags == "head")
    sideways = np.clip(1.0 - (np.abs(p[:, 0]) - 3.0) / 5.0, 0.0, 1.0)
    drop = np.where(chin, np.clip((-3.3 - p[:, 1]) / 1.6, 0.0, 1.0) * sideways, 0.0)
    drop = np.where(lip_l, 1.0, drop)
    drop = np.where(mouth, np.clip((-4.0 - p[:, 1]) / 0.55 + 0.5, 0.0, 1.0), drop)
    m["jawOpen"][:, 1] = -3.2 * drop
    m["jawOpen"][:, 2] = -0.6 * drop
    # mouthClose (ARKit: the lips closed while the jaw is open, used with jawOpen): the lower lip and the mouth's
    # lower half go back up by the jaw's drop, the chin stays down (face=cgm writes it: a review found it dropped)
    m["mouthClose"] = -np.where((lip_l | mouth)[:, None], m["jawOpen"], 0.0)
    for side, sx in (("Left", 1.0), ("Right", -1.0)):
        corner = (3.2 * sx, -4.0, 8.4)
        near = _bump(p, corner, 3.2) * (face | lip_u | lip_l | mouth)
        m[f"mouthSmile{side}"] += near[:, None] * (0.9 * sx, 1.3, -0.2)
        m[f"mouthFrown{side}"] += near[:, None] * (0.2 * sx, -1.2, 0.0)
        m[f"mouthStretch{side}"] += near[:, None] * (1.3 * sx, -0.3, -0.3)
        half = (p[:, 0] * sx > -0.5)
        m[f"mouthUpperUp{side}"][:, 1] = 0.9 * (lip_u & half) * np.clip(1 - np.abs(p[:, 0]) / 4, 0.3, 1)
        m[f"mouthLowerDown{side}"][:, 1] = -0.9 * (lip_l & half) * np.clip(1 - np.abs(p[:, 0]) / 4, 0.3, 1)
        cheek = _bump(p, (4.6 * sx, -0.8, 7.8), 3.4) * (tags == "head")
        m[f"cheekSquint{side}"] += cheek[:, None] * (0.0, 0.9, 0.5)
        eye = tags == ("eyeL" if sx > 0 else "eyeR")
        ec = np.array([3.4 * sx, 2.4, 8.3])
        m[f"eyeBlink{side}"][:, 1] = np.where(eye, -(p[:, 1] - ec[1]) * 0.92, 0.0)
        m[f"eyeSquint{side}"][:, 1] = np.where(eye, -(p[:, 1] - ec[1]) * 0.45, 0.0)
        m[f"eyeSquint{side}"] += 0.5 * cheek[:, None] * (0.0, 0.9, 0.5)
        brow = tags == ("browL" if sx > 0 else "browR")
        inner = np.clip(1.0 - (np.abs(p[:, 0]) - 1.3) / 4.3, 0.0, 1.0)
        m["browInnerUp"][:, 1] += np.where(brow, 1.0 * inner, 0.0)
        m[f"browDown{side}"][:, 1] = np.where(brow, -0.8, 0.0)
        m[f"browDown{side}"][:, 0] = np.where(brow, -0.3 * sx * inner, 0.0)
        m[f"browOuterUp{side}"][:, 1] = np.where(brow, 1.0 * (1.0 - inner), 0.0)
    # body: the chest widens and lifts, the belly bulges forward (rest-pose offsets, cm)
    ix = skeleton.index
    trunk = np.isin(tags, ["spine", "spine1", "spine2"])
    y_chest, y_belly = pos[ix("spine2")][1], pos[ix("spine")][1] + 6.0
    axis = np.stack([v[:, 0] - pos[ix("spine1")][0], np.zeros(len(v)), v[:, 2] - pos[ix("spine1")][2]], axis=1)
    wc = trunk * np.clip(1.0 - np.abs(v[:, 1] - y_chest) / 14.0, 0.0, 1.0)
    m["chest"] = wc[:, None] * (0.10 * axis + (0.0, 1.0, 0.0))
    wb = trunk * np.clip(1.0 - np.abs(v[:, 1] - y_belly) / 11.0, 0.0, 1.0) * np.clip(axis[:, 2] / 8.0, 0.0, 1.0)
    m["belly"] = wb[:, None] * (0.04 * axis + (0.0, 0.0, 3.0))
    return np.stack([m[name] for name in MORPHS])


def morph_weights(channels, n: int) -> np.ndarray:
    """Weights ``(n, len(MORPHS))`` of the morph targets from a run's channels (name -> array).

    The face's ARKit weights (``arkit.*`` channels, or the ``smile`` face's smile/jaw/eyes mapped
    as for VMC, :func:`laughlab.io.vmc.arkit_weights`) and the body's ``chest`` and ``belly``,
    each clipped to [0, 1]; a shape the run does not drive stays 0.
    """
    from laughlab.io.vmc import arkit_weights

    face = arkit_weights(channels)
    srcs = [face[name] if name in face else channels.get(name) for name in MORPHS]
    have = [i for i, src in enumerate(srcs) if src is not None]
    out = np.zeros((n, len(MORPHS)))
    if have:   # clipped together: one call, not one per shape (a live frame's cost was numpy's call overhead)
        out[:, have] = np.clip(np.nan_to_num(np.stack([np.asarray(srcs[i], float) for i in have], axis=1)), 0.0, 1.0)
    return out.astype(np.float32)
