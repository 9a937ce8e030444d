"""Author the bundled laughter clip library as keyframed motions.

Run ``python -m laughlab_plugins.clips.author`` (or ``python plugins/clips/author.py``)
to regenerate every ``<clip>.bvh`` and ``library.json`` next to this file; the
output is byte-identical from run to run.

Authoring model
---------------
* Keyframes are absolute ZXY Euler angles in degrees, ``dict joint ->
  [(frame, (z, x, y)), ...]`` (see :mod:`laughlab.motion.skeleton` for the signs),
  plus ``"root"`` -> ``(dx, dy, dz)`` cm from the rest root position.  A key
  name ``both_<part>`` keys the left joint and mirrors it to the right one.
* Tracks not keyed at the first / last frame are anchored to the neutral pose
  there, so every clip starts and ends neutral and clips blend cleanly.
* Arms may instead be keyed by a wrist target (two-bone IK, solved against the
  interpolated torso at that frame), which yields ordinary angle keys.
* Keys are interpolated with monotone cubic Hermite splines (PCHIP: smooth, no
  overshoot); a 4.5 Hz laughter shake is layered on the torso and shoulders;
  finally the root height is corrected so the feet stay on the floor (rofl:
  nothing may sink below the floor).
"""
from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from laughlab.io.bvh import write_bvh
from laughlab.motion.skeleton import (HUMANOID, euler_to_matrix, forward_kinematics, global_transforms, matrix_to_euler,
                               rest_pose)

FPS = 24
SHAKE_HZ = 4.5
OUT = Path(__file__).resolve().parent
SK = HUMANOID
SIDES = ("left", "right")

NEUTRAL = {"left_upper_arm": (-78.0, 0.0, 0.0), "left_forearm": (0.0, 0.0, -12.0)}
"""Neutral standing pose: arms hanging relaxed, elbows slightly bent (left side; right mirrors)."""


def mirror(a):
    """Mirror ``(z, x, y)`` angles of a left joint onto the right one: ``(-z, x, -y)``."""
    z, x, y = a
    return (-z, x, -y)


def neutral_pose() -> np.ndarray:
    """Pose vector of the neutral standing pose."""
    pose = rest_pose(SK)
    for name, a in NEUTRAL.items():
        pose[SK.angle_slice(name)] = a
        pose[SK.angle_slice(name.replace("left_", "right_"))] = mirror(a)
    return pose


NEUTRAL_POSE = neutral_pose()


# ----------------------------------------------------------------------------- pose helpers
def torso(pitch=0.0, twist=0.0, side=0.0, head=(0.0, 0.0, 0.0)) -> dict:
    """Spread a torso bend over spine, spine1, spine2 (degrees: pitch > 0 forward,
    twist > 0 turns to the character's left, side > 0 bends to its right);
    ``head`` is ``(z, x, y)`` for the head, the neck taking 30 % of its pitch."""
    share = {"spine": 0.3, "spine1": 0.35, "spine2": 0.35}
    keys = {j: (side * w, pitch * w, twist * w) for j, w in share.items()}
    keys["neck"] = (0.0, 0.3 * head[1], 0.0)
    keys["head"] = (head[0], 0.7 * head[1], head[2])
    return keys


def crouch(alpha=0.0, pelvis=0.0) -> dict:
    """Bend the knees by ``2 * alpha`` with the feet flat under the hips while the
    pelvis pitches forward by ``pelvis`` degrees (negative: hips pushed forward)."""
    a, p = np.radians(alpha), np.radians(pelvis)
    return {"hips": (0.0, pelvis, 0.0), "both_thigh": (0.0, -alpha - pelvis, 0.0),
            "both_shin": (0.0, 2 * alpha, 0.0), "both_foot": (0.0, -alpha, 0.0),
            "root": (0.0, 8 + 83 * np.cos(a) + 4 * np.cos(p) - 95, 4 * np.sin(p))}


def kneel(pelvis=0.0, thigh=0.0, knee_z=25.0, toes=150.0, shin=90.0, knee_y=5.0) -> dict:
    """Kneel with the knees at height ``knee_y`` and depth ``knee_z`` cm: thighs pitched
    ``thigh`` degrees forward of vertical, shins ``shin`` degrees back from vertical
    (90: flat on the floor), feet ``toes`` degrees, pelvis pitched ``pelvis``."""
    b, p = np.radians(thigh), np.radians(pelvis)
    hip_y, hip_z = knee_y + 42 * np.cos(b), knee_z - 42 * np.sin(b)
    return {"hips": (0.0, pelvis, 0.0), "both_thigh": (0.0, -thigh - pelvis, 0.0),
            "both_shin": (0.0, shin + thigh, 0.0), "both_foot": (0.0, toes - shin, 0.0),
            "root": (0.0, hip_y + 4 * np.cos(p) - 95, hip_z + 4 * np.sin(p))}


def _rodrigues(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation matrix taking unit vector ``a`` to unit vector ``b``."""
    v, c = np.cross(a, b), float(a @ b)
    s = np.linalg.norm(v)
    if s < 1e-9:
        return np.eye(3)
    k = v / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    ang = np.arctan2(s, c)
    return np.eye(3) + np.sin(ang) * kx + (1 - np.cos(ang)) * kx @ kx


def solve_arm(pose, side, joint, local, pole, fingers=None) -> dict:
    """Two-bone IK for one arm.

    Parameters
    ----------
    pose : ndarray, shape (C,)
        Pose whose torso (and clavicles) the arm hangs from.
    side : {'left', 'right'}
    joint : str
        Frame of ``local``: a joint name, or ``'ground'`` for world axes from the
        floor point under the root.
    local : (3,) cm
        Wrist target in that frame.
    pole, fingers : (3,)
        Direction the elbow points to / the fingers point along, in the chest
        (``spine2``) frame; ``fingers=None`` leaves the hand unkeyed.

    All vectors are given for the left side; x is mirrored for the right side.

    Returns
    -------
    dict
        ``(z, x, y)`` degrees for the upper arm, forearm (and hand).
    """
    s = 1.0 if side == "left" else -1.0
    m = np.array([s, 1.0, 1.0])
    pos, rot = global_transforms(SK, pose)
    chest = rot[SK.index("spine2")]
    if joint == "ground":
        target = pos[0] * (1, 0, 1) + m * np.asarray(local, float)
    else:
        j = SK.index(joint)
        target = pos[j] + rot[j] @ (m * np.asarray(local, float))
    ua, fa, hd = (SK.index(f"{side}_{p}") for p in ("upper_arm", "forearm", "hand"))
    a, b = np.linalg.norm(SK.offsets[fa]), np.linalg.norm(SK.offsets[hd])
    d = target - pos[ua]
    u = d / np.linalg.norm(d)
    dist = np.clip(np.linalg.norm(d), abs(a - b) + 1.0, a + b - 0.05)
    pw = chest @ (m * np.asarray(pole, float))
    v = pw - (pw @ u) * u
    v /= np.linalg.norm(v)
    ca = (a * a + dist * dist - b * b) / (2 * a * dist)
    du = ca * u + np.sqrt(max(0.0, 1 - ca * ca)) * v
    df = (dist * u - a * du) / b
    theta = np.degrees(np.arccos(np.clip(du @ df, -1, 1)))
    zd = df - (df @ du) * du
    zd = zd / np.linalg.norm(zd) if np.linalg.norm(zd) > 1e-6 else -v
    world = np.column_stack([s * du, np.cross(zd, s * du), zd])
    keys = {f"{side}_upper_arm": matrix_to_euler(rot[SK.parents[ua]].T @ world),
            f"{side}_forearm": np.array([0.0, 0.0, -s * theta])}
    if fingers is not None:
        fore = world @ euler_to_matrix(keys[f"{side}_forearm"])
        want = fore.T @ chest @ (m * np.asarray(fingers, float))
        keys[f"{side}_hand"] = matrix_to_euler(_rodrigues(np.array([s, 0, 0]), want / np.linalg.norm(want)))
    return keys


# ----------------------------------------------------------------------------- motion builder
class Motion:
    """Keyframe container for one clip; :meth:`build` returns dense poses ``(F, C)``."""

    ARM_JOINTS = {f"{s}_{p}" for s in SIDES for p in ("upper_arm", "forearm", "hand")}

    def __init__(self, length: int, ground: str = "feet") -> None:
        self.length, self.ground = length, ground
        self.keys: dict[str, list] = defaultdict(list)
        self.reaches: list = []
        self.shakes: list = []

    def at(self, frame: float, *dicts: dict, **joints) -> "Motion":
        """Key joints at ``frame`` (values ``(z, x, y)`` deg; ``root`` is ``(dx, dy, dz)`` cm)."""
        for d in dicts + (joints,):
            for name, val in d.items():
                if name.startswith("both_"):
                    self.keys[f"left_{name[5:]}"].append((frame, tuple(val)))
                    self.keys[f"right_{name[5:]}"].append((frame, mirror(val)))
                else:
                    self.keys[name].append((frame, tuple(val)))
        return self

    def reach(self, frame: float, side: str, joint: str, local, pole=(1.0, -0.3, -1.0), fingers=None) -> "Motion":
        """Key an arm by its wrist target (see :func:`solve_arm`); ``side='both'`` mirrors."""
        for sd in SIDES if side == "both" else (side,):
            self.reaches.append((frame, sd, joint, local, pole, fingers))
        return self

    def shake(self, start: float, end: float, amp: float) -> "Motion":
        """Layer a 4.5 Hz laughter shake (amplitude ``amp`` deg) between two frames."""
        self.shakes.append((start, end, amp))
        return self

    def _fill(self, dense: np.ndarray, keys: dict) -> None:
        frames = np.arange(self.length)
        for name, ks in keys.items():
            root = name == "root"
            sl = slice(0, 3) if root else SK.angle_slice(name)
            neutral = np.zeros(3) if root else NEUTRAL_POSE[sl]  # root keys are offsets from rest
            table = {0.0: neutral, float(self.length - 1): neutral}
            table.update({float(f): np.asarray(v, float) for f, v in ks})
            fr = np.array(sorted(table))
            vals = np.array([table[f] for f in fr])
            if not root:
                vals = np.unwrap(vals, period=360.0, axis=0)
            dense[:, sl] = PchipInterpolator(fr, vals, axis=0)(frames) + (NEUTRAL_POSE[:3] if root else 0.0)

    def build(self) -> np.ndarray:
        """Dense poses ``(length, 3 + 3J)`` at 24 fps."""
        dense = np.tile(NEUTRAL_POSE, (self.length, 1))
        self._fill(dense, {k: v for k, v in self.keys.items() if k not in self.ARM_JOINTS})
        arm_keys = {k: list(v) for k, v in self.keys.items() if k in self.ARM_JOINTS}
        for frame, side, joint, local, pole, fingers in self.reaches:
            pose = dense[int(round(frame))]
            for name, val in solve_arm(pose, side, joint, local, pole, fingers).items():
                arm_keys.setdefault(name, []).append((frame, tuple(val)))
        self._fill(dense, arm_keys)
        add_shake(dense, self.shakes)
        return ground(dense, self.ground)


def add_shake(dense: np.ndarray, shakes) -> None:
    """Add rhythmic 4.5 Hz torso pitch / shoulder bobbing between ``(start, end, amp)`` frames."""
    f = np.arange(len(dense), dtype=float)
    for start, end, amp in shakes:
        env = np.clip(np.minimum(f - start, end - f) / 5.0, 0.0, 1.0)
        w = amp * env * env * (3 - 2 * env) * np.sin(2 * np.pi * SHAKE_HZ * (f - start) / FPS)
        for name, axis, gain in (("spine1", 1, 0.5), ("spine2", 1, 0.7), ("head", 1, -0.6),
                                 ("left_clavicle", 0, 1.6), ("right_clavicle", 0, -1.6)):
            dense[:, SK.angle_slice(name).start + axis] += gain * w


_FEET = [SK.index(n) for n in ("left_foot", "left_toe", "right_foot", "right_toe")] + [
    SK.n_joints + k for k, j in enumerate(SK.leaves()) if SK.names[j].endswith("_toe")]
_REST_FOOT_Y = forward_kinematics(SK, NEUTRAL_POSE, end_sites=True)[_FEET, 1].min()
_RADIUS = np.full(SK.n_joints + len(SK.leaves()), 6.0)  # body-part thickness above the floor, cm
_RADIUS[_FEET] = _REST_FOOT_Y
_RADIUS[[SK.index("left_shin"), SK.index("right_shin")]] = 5.0
_RADIUS[[SK.index("left_hand"), SK.index("right_hand")]] = 3.0
_RADIUS[[SK.n_joints + k for k, j in enumerate(SK.leaves()) if SK.names[j].endswith("_hand")]] = 1.0


def ground(dense: np.ndarray, mode: str) -> np.ndarray:
    """Shift the root height: ``'feet'`` keeps the lowest foot point at its rest
    height, ``'clamp'`` only lifts the body so no part sinks below the floor."""
    pos = forward_kinematics(SK, dense, end_sites=True)
    if mode == "feet":
        dense[:, 1] += _REST_FOOT_Y - pos[:, _FEET, 1].min(axis=1)
    else:
        dense[:, 1] += np.maximum(0.0, -(pos[..., 1] - _RADIUS).min(axis=1))
    return dense


# ----------------------------------------------------------------------------- the clips
BELLY = ("spine", (12.0, 2.0, 13.0))
BELLY_POLE = (1.0, -0.2, -0.6)
BELLY_FINGERS = (-0.8, -0.3, 0.3)


def lean_front1() -> Motion:
    m = Motion(22)
    for f in (9, 13):
        m.at(f, torso(18, head=(0, 4, 0)), crouch(6, 4), both_upper_arm=(-79, 0, -10))
    return m.shake(3, 19, 1.5)


def lean_front2() -> Motion:
    m = Motion(42)
    for f, p in ((12, 26), (20, 20), (28, 30), (32, 28)):
        m.at(f, torso(p, head=(0, -6, 0)), crouch(12, 10), both_upper_arm=(-80, 0, -18),
             both_forearm=(0, 0, -25))
    return m.shake(4, 37, 2.5)


def lean_back1() -> Motion:
    m = Motion(22)
    for f in (9, 13):
        m.at(f, torso(-12, head=(0, -10, 0)), crouch(5, -5), both_upper_arm=(-76, 0, 6))
    return m.shake(3, 19, 1.5)


def lean_back2() -> Motion:
    m = Motion(36)
    for f, p in ((10, -22), (17, -16), (24, -24), (27, -23)):
        m.at(f, torso(p, head=(0, -16, 0)), crouch(9, -9), both_upper_arm=(-70, 0, 10),
             both_forearm=(0, 0, -20))
    return m.shake(3, 32, 2.5)


def clap_hands() -> Motion:
    m = Motion(46)
    for f in (7, 38):
        m.at(f, torso(8), crouch(5, 3))
    apart, together, pole, fingers = (20.0, -2.0, 28.0), (4.5, -4.0, 32.0), (0.6, -1.0, -0.3), (-0.2, 0.6, 0.8)
    m.reach(7, "both", "spine2", apart, pole, fingers)
    for k in range(4):
        m.reach(11 + 7 * k, "both", "spine2", together, pole, fingers)
        m.reach(14.5 + 7 * k, "both", "spine2", apart, pole, fingers)
        m.at(11 + 7 * k, torso(12), crouch(7, 4))
    return m.shake(5, 40, 2.0)


def hands_on_belly() -> Motion:
    m = Motion(73)
    rock = ((10, 10, 4), (22, 24, 12), (34, -12, 2), (46, 24, 12), (58, 6, 3))
    for f, p, knees in rock:
        m.at(f, torso(p, head=(0, -0.4 * p, 0)), crouch(knees, 0.4 * p))
        m.reach(f, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.reach(62, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    return m.shake(8, 64, 2.5)


def point1() -> Motion:
    m = Motion(69)
    aim, pole = (12.0, 25.0, 52.0), (1.0, -1.0, -0.2)
    for f, p in ((9, -6), (15, 2), (21, -8), (27, 2), (33, -8), (42, -4)):
        m.at(f, torso(p, twist=-6, head=(0, -4, -4)))
        m.reach(f, "right", "spine2", aim, pole)
    m.reach(10, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.reach(42, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(52, torso(22, head=(0, 4, 0)), crouch(10, 8))
    m.reach(52, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(59, torso(16), crouch(8, 6))
    return m.shake(5, 63, 2.0)


def point2() -> Motion:
    m = Motion(78)
    aim, pole = (14.0, 40.0, 46.0), (1.0, -1.0, -0.2)
    knee = ("right_shin", (-2.0, -6.0, 9.0))
    for f, p in ((12, 24), (19, 32), (26, 24), (33, 32), (40, 24), (48, 28)):
        m.at(f, torso(p, twist=8, head=(0, -22, 0)), crouch(14, 14))
        m.reach(f, "left", "spine2", aim, pole)
        m.reach(f, "right", *knee, pole=(1.0, 0.0, -1.0))
    m.at(58, torso(10, head=(0, -4, 0)), crouch(6, 4))
    m.reach(58, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(66, torso(4), crouch(3, 2))
    return m.shake(6, 70, 2.0)


def slap_leg() -> Motion:
    m = Motion(80)
    up, hit = ("spine2", (24.0, -2.0, 30.0)), ("right_thigh", (-3.0, -22.0, 10.0))
    m.at(6, torso(12), crouch(8, 8))
    for k in range(5):
        f = 10 + 9 * k
        m.at(f, torso(20, side=3, head=(0, -10, 0)), crouch(12, 16))
        m.at(f + 4.5, torso(30, side=6, head=(0, -4, 0)), crouch(16, 20))
        m.reach(f, "right", *up, pole=(1.0, 0.3, -1.0))
        m.reach(f + 4.5, "right", *hit, pole=(1.0, 0.3, -1.0))
    m.reach(10, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.reach(55, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(64, torso(10), crouch(6, 6))
    return m.shake(6, 70, 3.0)


def stop_it() -> Motion:
    m = Motion(79)
    pole, fingers = (1.0, -1.0, -0.3), (0.0, 1.0, 0.1)
    for k, f in enumerate(range(10, 59, 6)):
        x = 2.0 if k % 2 else 20.0
        m.reach(f, "right", "spine2", (x, 16.0, 42.0), pole, fingers)
        m.at(f, torso(-14 + 4 * (k % 2), twist=22, side=-5, head=(6, -10, 28)), crouch(6, -6))
    m.reach(12, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.reach(58, "left", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(68, torso(18, head=(0, 6, 0)), crouch(8, 8))
    m.reach(68, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    return m.shake(5, 72, 3.0)


def rofl() -> Motion:
    m = Motion(117, ground="clamp")
    on_thighs, pole = ("spine", (16.0, -10.0, 24.0)), (1.0, 0.0, -1.0)
    floor, lifted = ("ground", (18.0, 4.0, 62.0)), ("ground", (22.0, 32.0, 56.0))
    half_kneel = kneel(pelvis=25, thigh=30, shin=70, knee_y=16, knee_z=27, toes=110)
    m.at(10, torso(24, head=(0, 6, 0)), crouch(18, 18))
    m.reach(10, "both", *BELLY, BELLY_POLE, BELLY_FINGERS)
    m.at(22, torso(20), crouch(50, 30))
    m.reach(22, "both", "spine", (14.0, -20.0, 30.0), pole)
    m.at(28, torso(16), half_kneel)
    m.at(34, torso(10, head=(0, -10, 0)), kneel(pelvis=10, thigh=5, knee_z=28))
    m.reach(34, "both", *on_thighs, pole)
    for f in (44, 76):
        m.at(f, torso(28, head=(0, -20, 0)), kneel(pelvis=45, knee_z=28))
        m.reach(f, "both", *floor, pole=(1.0, 0.5, -0.5))
    for k, f in enumerate((50, 58, 66)):  # pound the floor with the right hand, rocking
        m.at(f, torso(24, side=8, head=(0, -26, 0)), kneel(pelvis=40, knee_z=28))
        m.at(f + 4, torso(32, side=-6, head=(0, -14, 0)), kneel(pelvis=48, knee_z=28))
        m.reach(f, "right", *lifted, pole=(1.0, 0.5, -0.5))
        m.reach(f + 4, "right", *floor, pole=(1.0, 0.5, -0.5))
    m.reach(50, "left", *floor, pole=(1.0, 0.5, -0.5))
    m.at(84, torso(6, head=(0, -14, 0)), kneel(pelvis=8, thigh=5, knee_z=28))
    m.reach(84, "both", *on_thighs, pole)
    m.at(89, torso(16), half_kneel)
    m.at(95, torso(24), crouch(52, 30))
    m.reach(95, "both", "spine", (14.0, -20.0, 30.0), pole)
    m.at(106, torso(12), crouch(14, 10))
    return m.shake(8, 100, 3.5)


def idle(length: int = 96) -> np.ndarray:
    """Loopable calm breathing and weight-shift sway (periods 4 s and 2 s)."""
    ph = 2 * np.pi * np.arange(length) / length
    sway, breath = np.sin(ph), np.sin(2 * ph)
    dense = np.tile(NEUTRAL_POSE, (length, 1))
    dense[:, 0] += 1.5 * sway
    add = {("hips", 0): -1.5 * sway, ("spine", 0): 0.8 * sway, ("spine2", 0): 0.6 * sway,
           ("spine1", 1): -0.6 * breath, ("spine2", 1): -0.8 * breath, ("head", 1): 1.2 * breath,
           ("head", 2): 3.0 * sway, ("left_clavicle", 0): 1.2 * breath, ("right_clavicle", 0): -1.2 * breath,
           ("left_upper_arm", 2): -2.0 * sway, ("right_upper_arm", 2): -2.0 * sway,
           # legs lean against the 1.5 cm root sway (world thigh angle -1.035 deg) so the feet stay put
           ("left_thigh", 0): 0.465 * sway, ("right_thigh", 0): 0.465 * sway,
           ("left_foot", 0): 1.035 * sway, ("right_foot", 0): 1.035 * sway}
    for (name, axis), v in add.items():
        dense[:, SK.angle_slice(name).start + axis] += v
    return ground(dense, "feet")


# ----------------------------------------------------------------------------- library
# name: (builder, length_frames, energy, eye keys [(frame, closed)])
CLIPS = {
    "lean_front1": (lean_front1, 22, 5, [(0, 0), (5, 1), (15, 0)]),
    "lean_front2": (lean_front2, 42, 10, [(0, 0), (6, 1), (34, 0)]),
    "lean_back1": (lean_back1, 22, 5, [(0, 0), (6, 1), (16, 0)]),
    "lean_back2": (lean_back2, 36, 10, [(0, 0), (5, 1), (29, 0)]),
    "clap_hands": (clap_hands, 46, 15, [(0, 0), (9, 1), (38, 0)]),
    "hands_on_belly": (hands_on_belly, 73, 15, [(0, 0), (8, 1), (40, 0), (44, 1), (64, 0)]),
    "point1": (point1, 69, 20, [(0, 0), (46, 1), (62, 0)]),
    "point2": (point2, 78, 20, [(0, 0), (52, 1), (68, 0)]),
    "slap_leg": (slap_leg, 80, 25, [(0, 0), (6, 1), (36, 0), (40, 1), (70, 0)]),
    "stop_it": (stop_it, 79, 30, [(0, 0), (6, 1), (70, 0)]),
    "rofl": (rofl, 117, 40, [(0, 0), (8, 1), (100, 0)]),
}


def build_all() -> dict[str, tuple[np.ndarray, dict]]:
    """Dense poses and ``library.json`` entries of every clip (thesis clips, then ``idle``)."""
    out = {}
    for name, (fn, length, energy, eyes) in CLIPS.items():
        poses = fn().build()
        assert len(poses) == length
        out[name] = poses, {"energy": energy, "loop": False, "eyes": eyes}
    out["idle"] = idle(), {"energy": 0, "loop": True, "eyes": [(0, 0)]}
    return out


def main(out: Path = OUT) -> None:
    """Write ``<clip>.bvh`` files and ``library.json`` into ``out``."""
    entries = []
    for name, (poses, meta) in build_all().items():
        write_bvh(out / f"{name}.bvh", SK, poses, 1.0 / FPS)
        entries.append({"name": name, "file": f"{name}.bvh", "length_frames": len(poses),
                        "energy": meta["energy"], "loop": meta["loop"],
                        "eyes": [[int(f), int(v)] for f, v in meta["eyes"]]})
    head = json.dumps({"fps": FPS, "skeleton": "humanoid"})[:-1]
    text = head + ',\n "clips": [\n' + ",\n".join(f"  {json.dumps(e)}" for e in entries) + "\n ]\n}\n"
    (out / "library.json").write_text(text, encoding="ascii")  # one clip per line
    print(f"wrote {len(entries)} clips to {out}")


if __name__ == "__main__":
    main()
