"""laughlab's skeleton onto an avatar's humanoid bones, rest-pose-relatively.

Each of laughlab's joints drives the avatar bone :data:`laughlab.avatar.names.JOINT_TO_VRM` names.
The avatar bone takes the joint's *world* rotation away from the rest pose, turned into the
avatar's frame::

    W_b = F  G_j  D_j  F^T  A_b

* ``A_b``: the bone's world rotation in the avatar's rest pose; ``G_j``: the joint's world
  rotation in the frame (identity in laughlab's T-pose rest);
* ``F``: the avatar's facing: identity if it faces +Z like laughlab (VRM 1.0, most glTF), a half
  turn about Y if it faces -Z (VRM 0.x), any other turn about Y for an avatar exported facing
  another way (e.g. +X); it is read from the file (the direction from the right upper arm to the
  left one, on the ground plane), not assumed from the version;
* ``D_j``: the rest correction of the limbs (shoulders, arms, hands, legs, feet, toes): the
  shortest rotation that turns the avatar's rest bone (from the bone to its child bone) onto
  laughlab's T-pose bone; identity for a T-pose avatar, about 30-45 degrees about Z at the
  shoulders of an A-pose one.  The hands and toes take their parent's correction.  The trunk,
  neck and head keep the avatar's own rest posture (no correction).

A bone's local rotation is then ``R_parent^T W_b`` with the parent's world rotation as animated
(bones that no joint drives, e.g. fingers and hair, keep their rest local rotation).  The hips
move by the joint's translation scaled by the ratio of the avatar's leg height (hips above the
feet) to laughlab's.

Missing optional bones.  A trunk bone that the avatar lacks (``upperChest``, ``chest``, ``neck``)
falls back to its parent: the nearest avatar bone above it takes the world rotation of the
deepest missing joint of the trunk below it (e.g. without ``upperChest``, ``chest`` turns as
laughlab's ``spine2`` does, so the neck and shoulders sit where they should).  A missing
``leftShoulder``/``rightShoulder`` or toe bone is simply not driven (the arms and feet still
take their own world rotations).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from laughlab.avatar.load import Avatar
from laughlab.avatar.names import JOINT_TO_VRM
from laughlab.motion.skeleton import HUMANOID, Skeleton, forward_kinematics, global_transforms, rest_pose

#: trunk joints whose missing avatar bone folds into the nearest avatar bone above
TRUNK = ("spine", "spine1", "spine2", "neck")
#: limb joint -> the child joint its rest direction points to (None: take the parent's correction)
LIMB_CHILD = {
    **{f"{s}_{a}": (f"{s}_{b}" if b else None) for s in ("left", "right")
       for a, b in (("clavicle", "upper_arm"), ("upper_arm", "forearm"), ("forearm", "hand"), ("hand", None),
                    ("thigh", "shin"), ("shin", "foot"), ("foot", "toe"), ("toe", None))},
}


@dataclass
class Retargeted:
    """The avatar's animated nodes.

    Attributes
    ----------
    nodes : list[int]
        The avatar nodes driven (humanoid bones), parents first.
    bones : list[str]
        Their VRM bone names.
    rotations : ndarray (F, B, 4)
        Their local rotations per frame, quaternions (x, y, z, w), unit, w >= 0 on the first frame
        and sign-continuous after it.
    hips_translation : ndarray (F, 3)
        The hips node's local translation per frame (the avatar's units).
    """

    nodes: list
    bones: list
    rotations: np.ndarray
    hips_translation: np.ndarray


def _rot(m: np.ndarray) -> np.ndarray:
    """The rotation part of affine matrices ``(..., 4, 4)`` (columns normalised: positive uniform scale)."""
    r = np.asarray(m)[..., :3, :3]
    return r / np.linalg.norm(r, axis=-2, keepdims=True)


def _arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The shortest rotation (3x3) turning unit vector ``a`` onto unit vector ``b``."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    s = np.linalg.norm(v)
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return Rotation.from_rotvec(np.pi * axis / np.linalg.norm(axis)).as_matrix()
    return Rotation.from_rotvec(v / s * np.arctan2(s, c)).as_matrix()


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else None


def drivers(avatar: Avatar, skeleton: Skeleton = HUMANOID) -> dict[str, int]:
    """VRM bone -> the laughlab joint whose world rotation it takes (missing trunk bones folded)."""
    out: dict[str, int] = {}
    for j, name in enumerate(skeleton.names):
        bone = JOINT_TO_VRM.get(name)
        if bone in avatar.bones:
            out[bone] = j
    for j, name in enumerate(skeleton.names):
        if name not in TRUNK or JOINT_TO_VRM.get(name) in avatar.bones:
            continue
        a = skeleton.parents[j]
        while a >= 0 and JOINT_TO_VRM.get(skeleton.names[a]) not in avatar.bones:
            a = skeleton.parents[a]
        if a >= 0:
            out[JOINT_TO_VRM[skeleton.names[a]]] = j  # the deeper joint wins (joints come parents first)
    return out


def facing_matrix(avatar: Avatar) -> np.ndarray:
    """``F``: the avatar's turn about Y (:attr:`Avatar.turn`): identity for an avatar facing +Z, a half turn
    for one facing -Z, any other yaw for one turned otherwise."""
    return np.asarray(avatar.turn, dtype=np.float64)


def corrections(avatar: Avatar, skeleton: Skeleton = HUMANOID) -> dict[int, np.ndarray]:
    """Joint -> ``D_j`` (3x3) for the limbs the avatar has (see the module's docstring)."""
    F = facing_matrix(avatar)
    rest = forward_kinematics(skeleton, rest_pose(skeleton)[None])[0]
    pos = avatar.rest_world[:, :3, 3]
    out: dict[int, np.ndarray] = {}
    for j, name in enumerate(skeleton.names):  # parents first, so a hand finds its forearm's correction
        if name not in LIMB_CHILD or JOINT_TO_VRM[name] not in avatar.bones:
            continue
        child = LIMB_CHILD[name]
        d = None
        if child is not None and JOINT_TO_VRM[child] in avatar.bones:
            c = skeleton.index(child)
            ours = _unit(rest[c] - rest[j])
            theirs = _unit(F.T @ (pos[avatar.bones[JOINT_TO_VRM[child]]] - pos[avatar.bones[JOINT_TO_VRM[name]]]))
            if ours is not None and theirs is not None:
                d = _arc(theirs, ours)
        if d is None:
            d = out.get(skeleton.parents[j], np.eye(3))
        out[j] = d
    return out


def leg_height_cm(skeleton: Skeleton = HUMANOID) -> float:
    """laughlab's hips above the lowest of its feet and toes in the rest pose (cm)."""
    rest = forward_kinematics(skeleton, rest_pose(skeleton)[None])[0]
    feet = [skeleton.index(n) for n in ("left_foot", "right_foot", "left_toe", "right_toe") if n in skeleton.names]
    return float(rest[0, 1] - rest[feet, 1].min())


def _constants(avatar: Avatar, skeleton: Skeleton) -> tuple:
    """What :func:`retarget` needs of the avatar and the skeleton alone, computed once per pair and kept on the
    avatar (the live viewer retargets one frame at a time: recomputed, they were half of a frame's 3 ms)."""
    cache = avatar.__dict__.setdefault("_retarget_constants", {})
    if id(skeleton) not in cache:
        drive = drivers(avatar, skeleton)
        rest_root = forward_kinematics(skeleton, rest_pose(skeleton)[None])[0, 0]
        scale = avatar.leg_height_m() / (leg_height_cm(skeleton) * 0.01)
        cache[id(skeleton)] = (skeleton, facing_matrix(avatar), drive, corrections(avatar, skeleton),
                               {avatar.bones[b]: b for b in drive}, _rot(avatar.rest_world), _rot(avatar.rest_local),
                               rest_root, scale)   # the skeleton kept: its id stays its own
    return cache[id(skeleton)][1:]


def retarget(avatar: Avatar, poses: np.ndarray, skeleton: Skeleton = HUMANOID) -> Retargeted:
    """The avatar's humanoid bones' local rotations and the hips' translation for ``poses`` (F, 3 + 3J)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=np.float64))
    f = len(poses)
    _, G = global_transforms(skeleton, poses)  # (F, J, 3, 3)
    F, drive, D, node_bone, A, L_rest, rest_root, scale = _constants(avatar, skeleton)
    world: dict[int, np.ndarray] = {}
    local: dict[int, np.ndarray] = {}
    for i in avatar.order:
        p = int(avatar.parents[i])
        parent = world[p] if p >= 0 and p in world else (np.broadcast_to(A[p], (f, 3, 3)) if p >= 0 else None)
        if i in node_bone:
            j = drive[node_bone[i]]
            W = F @ G[:, j] @ D.get(j, np.eye(3)) @ F.T @ A[i]
            world[i] = W
            local[i] = W if parent is None else np.swapaxes(parent, -1, -2) @ W
        elif parent is not None and p in world:
            world[i] = parent @ L_rest[i]
    nodes = [i for i in avatar.order if i in local]
    q = Rotation.from_matrix(np.stack([local[i] for i in nodes], axis=1).reshape(-1, 3, 3)).as_quat()
    q = q.reshape(f, len(nodes), 4)
    q *= np.where(q[:1, :, 3:] < 0, -1.0, 1.0)  # w >= 0 on the first frame
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=-1, keepdims=True) < 0, -1.0, 1.0), axis=0)
    q[1:] *= flip  # no sign jumps between frames (LINEAR interpolation takes the short way)
    # the hips: world position, then in the hips' parent's frame
    hips = avatar.bones["hips"]
    root = skeleton.offsets[0] + poses[:, :3]
    P = avatar.rest_world[hips, :3, 3] + ((root - rest_root) * 0.01 * scale) @ F.T
    inv = hips_parent_inverse(avatar)
    if inv is not None:
        P = P @ inv[:3, :3].T + inv[:3, 3]
    return Retargeted(nodes, [node_bone[i] for i in nodes], q + 0.0, P)


def animated_world(avatar: Avatar, result: Retargeted) -> np.ndarray:
    """World transforms ``(F, N, 4, 4)`` of every avatar node, composed from the node hierarchy with the
    retargeted rotations and hips translation (what a glTF player shows)."""
    f = len(result.rotations)
    n = len(avatar.parents)
    local = np.broadcast_to(avatar.rest_local, (f, n, 4, 4)).copy()
    rot = Rotation.from_quat(result.rotations.reshape(-1, 4)).as_matrix().reshape(f, -1, 3, 3)
    for k, i in enumerate(result.nodes):
        scale = np.linalg.norm(avatar.rest_local[i, :3, :3], axis=0)
        local[:, i, :3, :3] = rot[:, k] * scale
    local[:, avatar.bones["hips"], :3, 3] = result.hips_translation
    world = np.empty_like(local)
    for i in avatar.order:
        p = int(avatar.parents[i])
        world[:, i] = local[:, i] if p < 0 else world[:, p] @ local[:, i]
    return world


def vmc_rest(avatar: Avatar, skeleton: Skeleton, joints: list[int], offsets_cm: np.ndarray) -> tuple:
    """What ``output=vmc`` sends of ``avatar`` at rest, in laughlab's frame (cm): each sent joint's offset from
    the nearest sent ancestor, such that chained from the hips every joint the avatar has lands on its own (a joint
    it lacks at laughlab's ``offsets_cm`` from its parent, scaled by leg height), the hips' rest position,
    laughlab's rest root and the scale by which root motion is carried over (as :func:`retarget` carries it: the
    avatar's leg height over laughlab's), and ``(A, b)``, which take the hips' world position into its parent
    node's frame, ``A @ p + b`` (laughlab's axes, cm): a receiver sets it as the Hips' ``localPosition`` (EVMC4U), so
    an avatar whose Hips hang under a joint off the origin (Godette's root, 5 cm up) floated by that much.  Returns
    ``(offsets (J, 3), hips (3,), rest_root (3,), scale, (A, b))``."""
    F, drive, *_, rest_root, scale = _constants(avatar, skeleton)
    pos = avatar.rest_world[:, :3, 3] @ F * 100.0   # F.T p, per row: laughlab's frame, cm
    node = {j: avatar.bones.get(JOINT_TO_VRM.get(n)) for j, n in enumerate(skeleton.names)}
    world: dict[int, np.ndarray] = {}   # each sent joint at rest: the avatar's where it has the bone (an
    out = []                            # UpperChest it lacks: laughlab's offset, scaled, so its child still lands)
    for j in joints:
        a = skeleton.parents[j]
        while a >= 0 and a not in world:
            a = skeleton.parents[a]
        base = world[a] if a >= 0 else np.zeros(3)
        world[j] = pos[node[j]] if node[j] is not None else base + np.asarray(offsets_cm[j], float) * scale
        out.append(world[j] - base)
    hips = avatar.bones["hips"]
    inv = hips_parent_inverse(avatar)
    A, b = np.eye(3), np.zeros(3)
    if inv is not None:   # world (laughlab's axes, cm) -> the parent's frame: F.T M^-1 (F x / 100) * 100
        A = F.T @ inv[:3, :3] @ F
        b = F.T @ inv[:3, 3] * 100.0
    return np.array(out).reshape(len(joints), 3), pos[hips], np.asarray(rest_root, float), scale, (A, b)


def hips_parent_inverse(avatar: Avatar) -> np.ndarray | None:
    """The inverse of the rest world transform (4x4, glTF's axes, m) of the node the hips hang from, which takes a
    world position into the frame the hips' own translation is in; None when the hips are a root."""
    p = int(avatar.parents[avatar.bones["hips"]])
    return np.linalg.inv(avatar.rest_world[p]) if p >= 0 else None
