"""Body driver ``follow``: torso and shoulders follow the head pitch by PD controllers (Ding et al. 2014, 4.3).

Ding et al. had no torso or shoulder capture; observing that "torso and head
never go in opposite directions", they drive the torso joints and the shoulder
joints from the synthesised head pitch with two PD controllers, tuned by hand,
and add Perlin noise on the three axes of the torso joints so nothing freezes::

    tau = kp (alpha_target - alpha) - kd alpha_dot                          (PD)

where ``alpha`` is the controlled angle, ``alpha_dot`` its velocity and
``alpha_target`` the desired angle set by the head pitch (the extraction of
the paper reads "alpha_current - alpha" with alpha_current "the current value
of the head pitch"; the desired value is the head pitch times a gain here).

Integration.  With unit inertia, ``alpha'' = tau``: a damped spring towards the
target.  Over each frame the target is held and the linear ODE is integrated
*exactly*: ``[e, alpha_dot](t + dt) = expm(A dt) [e, alpha_dot](t)`` with ``e =
alpha - alpha_target`` and ``A = [[0, 1], [-kp, -kd]]``.  So a target that is
constant over frames gives the same trajectory at any frame rate (to rounding);
only the sampling of a changing target differs.

Joints (offsets added to the clip pose, degrees, BVH order z, x, y):

* torso controller ``alpha_T``, target ``torso_gain * head pitch``, spread over
  ``spine``, ``spine1``, ``spine2`` by ``torso_split`` as forward pitch (x)
  (Ding's vt3, vt6, vt10, vl2; "the other torso joints are extrapolated");
* shoulder controller ``alpha_S``, target ``shoulder_gain * head pitch``:
  ``left_clavicle`` ``z = shoulder_lift alpha_S`` (raises the shoulder),
  ``y = -shoulder_forward alpha_S`` (brings it forward); the right side
  mirrors (``-z``, ``-y``): a forward nod hunches the shoulders up and
  forward, a head thrown back lowers them and pulls them back;
* Perlin noise (:class:`laughlab.motion.noise.NoiseSignal`, seeded from ``ctx.seed``)
  on the three axes of the three torso joints (``noise_deg``) and on the
  clavicles' z and y (``noise_shoulder_deg``).

Head pitch (``head_source``):

* ``face``: ``frame.channels['head_pitch']`` written by the face (``facs``).
  The face steps *after* the body in each frame, so the body reads the value
  the face wrote in the previous frame: the torso follows the head one frame
  late (1/fps, 17 ms at 60 fps; small beside the controllers' own lag).  0
  until the face has written one.
* ``clip``: the head's pitch in the world (degrees, > 0 forward) in the
  playing clip (idle when none), sampled at the mixer's clip time
  (events tracked as the mixer does; its blends are ignored).  The clip's
  torso already leans with its head, so this adds ``torso_gain`` of it again:
  a follow-through exaggeration.
* ``auto`` (default): ``face`` from the first frame after one where the face
  wrote ``head_pitch``, else ``clip``.
* ``none``: 0 (noise only).

Chest and belly: the ``shapes`` body's Eqs. 3.3-3.4 with its parameters
(``shapes``), so ``follow`` can replace ``shapes``.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Body
from laughlab.motion.noise import NoiseSignal
from laughlab.core.plugins import check_range
from laughlab.motion.skeleton import global_transforms, matrix_to_euler
from laughlab_plugins.body_shapes import ShapesBody, ShapesParams

SOURCES = ("auto", "face", "clip", "none")
TORSO_JOINTS = ("spine", "spine1", "spine2")


def pd_torque(target: float, alpha: float, alpha_dot: float, kp: float, kd: float) -> float:
    """Eq. PD: ``tau = kp (target - alpha) - kd alpha_dot`` (deg/s^2 with unit inertia)."""
    return kp * (target - alpha) - kd * alpha_dot


class PDController:
    """One PD-controlled angle, integrated exactly over each frame (target held).

    Parameters
    ----------
    kp : float
        Proportional gain (1/s^2).
    kd : float
        Derivative gain (1/s).

    Attributes
    ----------
    alpha, alpha_dot : float
        Angle (deg) and angular velocity (deg/s).
    """

    def __init__(self, kp: float, kd: float):
        import scipy.linalg  # noqa: F401 - loaded when built, not in the first frame
        self.kp, self.kd = float(kp), float(kd)
        self._dt = None
        self._m = None
        self.reset()

    def reset(self) -> None:
        self.alpha = 0.0
        self.alpha_dot = 0.0

    def transition(self, dt: float) -> np.ndarray:
        """``expm(A dt)`` with ``A = [[0, 1], [-kp, -kd]]`` (cached for the last dt)."""
        if dt != self._dt:
            self._dt = dt
            from scipy.linalg import expm  # imported when used (scipy.linalg ~0.14 s)

            self._m = expm(np.array([[0.0, 1.0], [-self.kp, -self.kd]]) * dt)
            self._mf = tuple(float(v) for v in self._m.ravel())
        return self._m

    def step(self, target: float, dt: float) -> float:
        """Advance ``dt`` seconds towards ``target``; returns the new angle."""
        self.transition(dt)
        m00, m01, m10, m11 = self._mf
        e = self.alpha - target
        v = self.alpha_dot
        self.alpha = target + m00 * e + m01 * v
        self.alpha_dot = m10 * e + m11 * v
        return self.alpha


@dataclass
class FollowParams:
    """Parameters of the ``follow`` body driver (Ding et al. 2014, 4.3).

    The paper tuned its controllers "by trial and error" and gives no values;
    these are ours.

    Attributes
    ----------
    head_source : str
        Where the head pitch comes from: ``auto``, ``face``, ``clip`` or ``none``
        (module docstring).
    torso_gain : float
        Torso target = this x head pitch (deg/deg), spread over the spine joints.
    torso_split : list of float
        Share of the torso angle at ``spine``, ``spine1``, ``spine2`` (sums to 1).
    torso_kp, torso_kd : float
        Torso controller: kp = w^2, kd = 2 zeta w with w = 6 rad/s (about 1 Hz)
        and zeta = 0.8: the heavy torso lags the head by ~0.25 s, barely overshoots.
    shoulder_gain : float
        Shoulder target = this x head pitch (deg/deg).
    shoulder_kp, shoulder_kd : float
        Shoulder controller: w = 10 rad/s, zeta = 0.7 (lighter, quicker).
    shoulder_lift, shoulder_forward : float
        Clavicle z (raise) and y (forward) per degree of the shoulder angle.
    noise_deg : float
        Peak Perlin noise on each axis of each torso joint (deg).
    noise_shoulder_deg : float
        Peak Perlin noise on the clavicles' z and y (deg).
    noise_hz : float
        Lattice rate of the noise's first octave (1/s): it wanders on a ~2.5 s scale.
    noise_octaves : int
        Octaves of the noise (each twice as fast, half as large).
    shapes : ShapesParams
        Chest and belly, as the ``shapes`` body (thesis Eqs. 3.3-3.4, 5.3).
    """

    head_source: str = "auto"
    torso_gain: float = 0.4
    torso_split: list = field(default_factory=lambda: [0.25, 0.35, 0.4])
    torso_kp: float = 36.0
    torso_kd: float = 9.6
    shoulder_gain: float = 0.3
    shoulder_kp: float = 100.0
    shoulder_kd: float = 14.0
    shoulder_lift: float = 1.0
    shoulder_forward: float = 0.5
    noise_deg: float = 1.0
    noise_shoulder_deg: float = 0.5
    noise_hz: float = 0.4
    noise_octaves: int = 2
    shapes: ShapesParams = field(default_factory=ShapesParams)

    def __post_init__(self) -> None:
        if self.head_source not in SOURCES:
            raise ValueError(f"head_source must be one of {', '.join(SOURCES)} (got {self.head_source!r})")
        split = list(self.torso_split)
        if len(split) != 3 or any(not (s >= 0) for s in split) or abs(sum(split) - 1.0) > 1e-6:
            raise ValueError(f"torso_split must be 3 shares >= 0 summing to 1 (got {split})")
        for name in ("torso_kp", "torso_kd", "shoulder_kp", "shoulder_kd"):
            check_range(name, getattr(self, name), 0)
        for name in ("noise_deg", "noise_shoulder_deg"):
            check_range(name, getattr(self, name), 0)
        check_range("noise_hz", self.noise_hz, 0, lo_open=True)
        if not 1 <= self.noise_octaves <= 8:
            raise ValueError(f"noise_octaves must be in 1..8 (got {self.noise_octaves})")


_PITCH_CACHE: "weakref.WeakKeyDictionary[object, dict]" = weakref.WeakKeyDictionary()


def clip_head_pitch(library) -> dict[str, np.ndarray]:
    """Per clip, the head's world pitch at every clip frame (deg, > 0 forward); cached per library."""
    out = _PITCH_CACHE.get(library)
    if out is None:
        sk = library.skeleton
        h = sk.index("head")
        out = {}
        for clip in library:
            _, rot = global_transforms(sk, clip.poses)
            out[clip.name] = matrix_to_euler(rot[:, h])[:, 1].copy()
        _PITCH_CACHE[library] = out
    return out


def _sample(curve: np.ndarray, fps: float, loop: bool, t: float) -> float:
    """Linear interpolation of a per-frame curve at clip time ``t`` (s), as :class:`~laughlab.motion.clips.Clip` samples."""
    n = len(curve)
    f = t * fps
    if loop:
        f = f % n
        i = int(f)
        w = f - i
        return float(curve[i] + w * (curve[(i + 1) % n] - curve[i]))
    f = min(max(f, 0.0), n - 1.0)
    i = min(int(f), n - 2) if n > 1 else 0
    w = f - i
    return float(curve[i] + w * (curve[min(i + 1, n - 1)] - curve[i]))


class FollowBody(Body):
    """Torso and shoulders following the head pitch by two PD controllers, plus Perlin noise.

    See the module docstring.  Writes ``frame.offsets`` for ``spine``,
    ``spine1``, ``spine2``, ``left_clavicle``, ``right_clavicle`` and the
    channels ``chest``, ``belly`` (as ``shapes``), ``follow_head_pitch`` (the
    head pitch used, deg), ``torso_pitch`` and ``shoulder_angle`` (the two
    controlled angles, deg).
    """

    name = "follow"
    Params = FollowParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p = self.params
        self.shapes = ShapesBody(p.shapes, self.ctx)
        self.torso = PDController(p.torso_kp, p.torso_kd)
        self.shoulders = PDController(p.shoulder_kp, p.shoulder_kd)
        for pd in (self.torso, self.shoulders):  # expm once, before the first frame
            pd.transition(self.ctx.dt)
        seed = int(self.ctx.seed)

        def noise(stream, amp):
            return NoiseSignal(seed, stream, p.noise_hz, amp, p.noise_octaves)

        self.torso_noise = [[noise(3 * j + a, p.noise_deg) for a in range(3)] for j in range(3)]
        self.shoulder_noise = [[noise(9 + 2 * s + a, p.noise_shoulder_deg) for a in range(2)] for s in range(2)]
        self._split = [float(s) for s in p.torso_split]
        self._pitch = None
        if p.head_source in ("auto", "clip"):
            self.library = self.ctx.clips
            self._pitch = clip_head_pitch(self.library)
        self.reset()

    def reset(self) -> None:
        self.shapes.reset()
        self.torso.reset()
        self.shoulders.reset()
        self._prev = None
        self._face_seen = False
        self._clip = None
        self._clip_start = self._offset = self._idle_start = 0.0
        self._speed = 1.0
        self._end = 0.0

    # ---------------------------------------------------------------- head pitch
    def _clip_pitch(self, frame) -> float:
        """The playing clip's head pitch, tracking the frame's clip events as the mixer does."""
        t = frame.time_s
        lib = self.library
        for ev in frame.events:
            if ev.kind == "start":
                self._clip = lib[ev.clip]
                self._clip_start, self._speed, self._offset = t, ev.speed, ev.offset_s
                self._end = self._clip.duration_s if ev.end_s is None else ev.end_s
            elif ev.kind == "stop" and self._clip is not None and ev.clip == self._clip.name:
                self._clip, self._idle_start = None, t
        if self._clip is not None:
            local = self._offset + (t - self._clip_start) * self._speed
            if local >= self._end:
                self._clip, self._idle_start = None, t
            else:
                c = self._clip
                return _sample(self._pitch[c.name], c.fps, c.loop, local)
        idle = lib.idle
        return _sample(self._pitch[idle.name], idle.fps, idle.loop, t - self._idle_start)

    def head_pitch(self, frame) -> float:
        """The head pitch driving the controllers this frame (deg), by ``head_source``."""
        src = self.params.head_source
        prev = self._prev
        face = prev.channels.get("head_pitch") if prev is not None else None
        if face is not None:
            self._face_seen = True
        clip = self._clip_pitch(frame) if self._pitch is not None else 0.0  # keeps the clip tracking in step
        if src == "none":
            return 0.0
        if src == "face" or (src == "auto" and (self._face_seen or frame.index == 0)):
            return 0.0 if face is None else float(face)
        return clip

    # ---------------------------------------------------------------- per frame
    def step(self, frame) -> None:
        p, dt, t = self.params, frame.dt, frame.time_s
        self.shapes.step(frame)
        pitch = self.head_pitch(frame)
        self._prev = frame
        a_t = self.torso.step(p.torso_gain * pitch, dt)
        a_s = self.shoulders.step(p.shoulder_gain * pitch, dt)
        off = frame.offsets
        for name, share, (nz, nx, ny) in zip(TORSO_JOINTS, self._split, self.torso_noise):
            off[name] = (nz(t), share * a_t + nx(t), ny(t))
        (lz, ly), (rz, ry) = self.shoulder_noise
        lift, fwd = p.shoulder_lift * a_s, p.shoulder_forward * a_s
        off["left_clavicle"] = (lift + lz(t), 0.0, -fwd + ly(t))
        off["right_clavicle"] = (-(lift + rz(t)), 0.0, fwd + ry(t))
        ch = frame.channels
        ch["follow_head_pitch"] = pitch
        ch["torso_pitch"] = a_t
        ch["shoulder_angle"] = a_s


@hookimpl
def register_bodies(register):
    register(FollowBody)
