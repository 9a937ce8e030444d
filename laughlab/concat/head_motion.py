"""Head and eyebrow motion by segment concatenation (Ding et al. 2014, 4.2), in real time.

Ding et al. synthesise head and eyebrow motion by choosing, for each
pseudo-phoneme, a recorded head-and-eyebrow motion segment of that class with
the lowest cost ``gamma C_dur(d(s), d(p)) + (1 - gamma) C_cont(s', s)``
(Eqs. 4-8; the greedy real-time variant), stretching it linearly to the
pseudo-phoneme's duration and smoothing the joins by linear interpolation.
This module does the same with the costs of :mod:`laughlab.concat.costs`.

The database
------------
AVLaughterCycle's head and eyebrow tracks are not available, so the segments
come from the clip library: the segments of :func:`laughlab.concat.segments.segment_db`
(the library cut at the slowest moments of the motion and labelled by
pseudo-phoneme class with its documented rules) give the cut points and the
labels; each segment's *head curve* is sampled from the clip at its frames:

* ``pitch``, ``yaw``, ``roll`` (degrees): the rotation of the head relative to
  the chest, ``R = R_neck R_head`` (the local rotations of ``neck`` and
  ``head``), as BVH Euler angles ``(z, x, y) = (roll, pitch, yaw)``.  Signs as in
  :mod:`laughlab.motion.skeleton`: pitch > 0 nods forward (down), < 0 tilts the head
  back; yaw > 0 turns it to its left; roll > 0 tilts it towards its right
  shoulder.  The keyed clips move the head mainly in pitch (it tilts back up to
  27 degrees, in rofl); yaw and roll are near zero except in ``stop_it`` (a
  28-degree turn, 6 degrees of roll) and a few degrees in ``point1`` and ``idle``.
* ``brow`` (0..1, AU1+2): **brow rule** (ours): the brows rise as the head
  tilts back, ``brow = clip(max(0, -pitch) / brow_full_deg, 0, 1)``.  Eyebrow
  raises accompany upward head movements in speech (Graf, Cosatto, Strom &
  Huang 2002, "Visual prosody"); laughter's head is thrown back (Ruch & Ekman
  2001).  Without eyebrow capture this is a stand-in, and it ties the brows to
  the head as the recorded segments of Ding et al. are.

The continuity cost (Eq. 8) compares the last sample of a segment with the first
of the next in the feature ``(pitch, yaw, roll, brow * brow_full_deg)``
(degrees), measured in units of ``cont_unit_deg``: ``C_cont = sum(((last -
first) / cont_unit_deg)^2)``, so a 10-degree jump costs 1, as much as a duration
mismatch of 0.69 s (``C_dur = e^0.69 - 1``).  (Implemented by scaling the
features by ``100 / cont_unit_deg`` into :func:`laughlab.concat.costs.c_cont`'s cm.)

Synthesis (greedy, real time)
-----------------------------
As the ``concat`` scheduler: at the first frame of a pseudo-phoneme its
duration is predicted by the running mean duration of its class (initialised
with the mean duration of its candidates); the segment with the lowest local
cost starts, stretched by ``speed = d(s) / d(p)`` clipped to ``[speed_min,
speed_max]``; a segment that ends before its pseudo-phoneme is followed by
another of the same class (target: the larger of the prediction and the time
the pseudo-phoneme has lasted).  At each join the jump from the value shown to
the new segment's first value is faded out linearly over ``blend_s`` (the
paper's linear smoothing).  Labels come from ``frame.label``; without one,
``silence`` if ``control['mcs'] < mcs_silence``, else ``vowel`` (as the
``concat`` scheduler).  Deterministic: no random numbers.

Outputs are scaled by ``gain``: the head's rotation offsets (added to the head
joint of the clip pose) and ``brow_raise`` (clipped to [0, 1]).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from laughlab.concat.costs import CONT_UNIT_CM, choose, stretch
from laughlab.core.errors import LaughlabError
from laughlab.core.plugins import check_range
from laughlab.concat.segments import PSEUDO_PHONEMES, Segment, SegmentDB, segment_db
from laughlab.motion.skeleton import euler_to_matrix, matrix_to_euler

__all__ = ["HEAD_CHANNELS", "HeadMotionParams", "HeadSegments", "head_curves", "build_head_db", "HeadMotion"]

HEAD_CHANNELS: tuple[str, ...] = ("head_pitch", "head_yaw", "head_roll", "brow_raise")
"""Channels of the head motion: three angles (degrees) and the brow raise (0..1)."""


@dataclass
class HeadMotionParams:
    """Parameters of the head and eyebrow motion (Ding et al. 2014, 4.2).

    Attributes
    ----------
    enabled : bool
        Synthesise head and eyebrow motion (else the channels stay 0 and the head gets no offset).
    gamma : float
        Weight of the duration cost against the continuity cost (Eq. 4), in
        [0, 1].  The paper tuned it by hand and gives no value; 0.5 as the
        ``concat`` scheduler.
    blend_s : float
        Linear smoothing at each join: the jump is faded out over this time (s).
    speed_min, speed_max : float
        Bounds of the stretch ``d(s) / d(p)`` (the paper: only small factors are tolerable).
    gain : float
        Scale of the synthesised head angles and brow raise (1 = as in the clips).
    brow_full_deg : float
        Brow rule: the brows are fully raised when the head tilts back this far (degrees).
    cont_unit_deg : float
        Unit of the continuity cost (degrees): a jump of this size costs 1.
    mcs_silence : float
        Without a label, MCS below this is ``silence``, else ``vowel``.
    """

    enabled: bool = True
    gamma: float = 0.5
    blend_s: float = 0.15
    speed_min: float = 0.5
    speed_max: float = 2.0
    gain: float = 1.0
    brow_full_deg: float = 15.0
    cont_unit_deg: float = 10.0
    mcs_silence: float = 0.1

    def __post_init__(self) -> None:
        check_range("gamma", self.gamma, 0, 1)
        check_range("blend_s", self.blend_s, 0)
        check_range("speed_min", self.speed_min, 0, lo_open=True)
        if self.speed_max < self.speed_min:
            raise ValueError(f"speed_max must be >= speed_min (got {self.speed_max} < {self.speed_min})")
        check_range("gain", self.gain, 0)
        check_range("brow_full_deg", self.brow_full_deg, 0, lo_open=True)
        check_range("cont_unit_deg", self.cont_unit_deg, 0, lo_open=True)
        check_range("mcs_silence", self.mcs_silence, 0, 1)


def head_curves(library, brow_full_deg: float = 15.0) -> dict[str, np.ndarray]:
    """Per clip, the head curve at every clip frame: ``(F, 4)`` = pitch, yaw, roll (deg), brow (0..1).

    See the module docstring for the angles and the brow rule.
    """
    sk = library.skeleton
    neck, head = sk.angle_slice("neck"), sk.angle_slice("head")
    out = {}
    for clip in library:
        r = euler_to_matrix(clip.poses[:, neck]) @ euler_to_matrix(clip.poses[:, head])
        zxy = matrix_to_euler(r)
        pitch, yaw, roll = zxy[:, 1], zxy[:, 2], zxy[:, 0]
        brow = np.clip(np.maximum(0.0, -pitch) / brow_full_deg, 0.0, 1.0)
        out[clip.name] = np.column_stack([pitch, yaw, roll, brow]) + 0.0
    return out


@dataclass(frozen=True, eq=False)
class HeadSegments:
    """Head-and-eyebrow motion segments by pseudo-phoneme class.

    Attributes
    ----------
    db : SegmentDB
        The segments (same clips, times and labels as the clip segment
        database), with features ``(pitch, yaw, roll, brow * brow_full_deg)``
        scaled by ``100 / cont_unit_deg`` for :func:`laughlab.concat.costs.c_cont`.
    curves : tuple of ndarray (n_i, 4)
        Each segment's head curve sampled at ``times[i]``.
    times : tuple of ndarray (n_i,)
        Segment-relative times of the samples (s of clip time, from 0 to the duration).
    """

    db: SegmentDB
    curves: tuple
    times: tuple

    def sample(self, i: int, u: float) -> np.ndarray:
        """Segment ``i``'s head curve at segment time ``u`` (s; clamped to the segment)."""
        tt, cc = self.times[i], self.curves[i]
        u = min(max(u, 0.0), float(tt[-1]))
        k = min(int(np.searchsorted(tt, u, side="right")) - 1, len(tt) - 2)
        if k < 0:
            return cc[0].copy()
        w = (u - tt[k]) / (tt[k + 1] - tt[k])
        return cc[k] + w * (cc[k + 1] - cc[k])


def build_head_db(library, brow_full_deg: float = 15.0, cont_unit_deg: float = 10.0) -> HeadSegments:
    """Cut the head curves of ``library`` at the clip segments' boundaries (see the module docstring)."""
    curves = head_curves(library, brow_full_deg)
    scale = np.array([1.0, 1.0, 1.0, brow_full_deg]) * (CONT_UNIT_CM / cont_unit_deg)
    segs, cs, ts = [], [], []
    for s in segment_db(library):
        clip = library[s.clip]
        f0, f1 = s.start_s * clip.fps, s.end_s * clip.fps
        frames = np.arange(math.ceil(f0 - 1e-9), math.floor(f1 + 1e-9) + 1, dtype=float)
        frames = np.unique(np.concatenate([[f0], frames, [f1]]))
        frames = frames[(frames >= f0 - 1e-9) & (frames <= f1 + 1e-9)]
        c = curves[s.clip]
        idx = np.clip(frames, 0, len(c) - 1)
        lo = np.floor(idx).astype(int)
        hi = np.minimum(lo + 1, len(c) - 1)
        w = (idx - lo)[:, None]
        curve = c[lo] + w * (c[hi] - c[lo])
        segs.append(Segment(s.clip, s.start_s, s.end_s, s.label, curve[0] * scale, curve[-1] * scale, s.energy))
        cs.append(curve)
        ts.append((frames - f0) / clip.fps)
    return HeadSegments(SegmentDB(segs), tuple(cs), tuple(ts))


_CACHE: "weakref.WeakKeyDictionary[object, dict]" = weakref.WeakKeyDictionary()


def _cached_db(library, brow_full_deg: float, cont_unit_deg: float) -> HeadSegments:
    per_lib = _CACHE.setdefault(library, {})
    key = (float(brow_full_deg), float(cont_unit_deg))
    if key not in per_lib:
        per_lib[key] = build_head_db(library, *key)
    return per_lib[key]


class HeadMotion:
    """Greedy real-time head and eyebrow synthesis (see the module docstring).

    Parameters
    ----------
    params : HeadMotionParams
    library : ClipLibrary
        Source of the segments (built once per library and cached).

    Attributes
    ----------
    heads : HeadSegments
    segment : int or None
        Index of the playing segment.
    speed : float
        Its stretch factor.
    """

    def __init__(self, params: HeadMotionParams, library):
        self.params = params
        self.heads = _cached_db(library, params.brow_full_deg, params.cont_unit_deg)
        self.db = self.heads.db
        self.reset()

    def reset(self) -> None:
        db = self.db
        self._mean = {c: db.mean_duration(c) for c in PSEUDO_PHONEMES}
        self._count = dict.fromkeys(PSEUDO_PHONEMES, 1)
        self.label: str | None = None
        self._run_start = 0.0
        self.segment: int | None = None
        self.speed = 1.0
        self._seg_start = 0.0
        self._jump = np.zeros(4)
        self._jump_t = 0.0
        self._shown = np.zeros(4)

    def label_of(self, frame) -> str:
        """The frame's pseudo-phoneme: ``frame.label``, else derived from MCS."""
        if frame.label is not None:
            return frame.label
        return "silence" if frame.control.get("mcs", 0.0) < self.params.mcs_silence else "vowel"

    def _start(self, t: float, choice: int, target: float) -> None:
        p = self.params
        self.speed = stretch(self.db.durations[choice], target, p.speed_min, p.speed_max)
        self.segment, self._seg_start = choice, t
        self._jump = self._shown - self.heads.curves[choice][0]
        self._jump_t = t

    def step(self, t: float, label: str) -> tuple[float, float, float, float]:
        """Advance to time ``t`` (s) with this frame's label; returns pitch, yaw, roll (deg) and brow (0..1)."""
        p, db = self.params, self.db
        if label not in self._mean:
            raise LaughlabError(f"unknown pseudo-phoneme {label!r}; choose from: {', '.join(PSEUDO_PHONEMES)}")
        if label != self.label:
            if self.label is not None:
                self._count[self.label] += 1
                n = self._count[self.label]
                self._mean[self.label] += ((t - self._run_start) - self._mean[self.label]) / n
            self.label, self._run_start = label, t
            target = self._mean[label]
            self._start(t, choose(db, label, target, p.gamma, self.segment), target)
        else:
            i = self.segment
            if self._seg_start + db.durations[i] / self.speed <= t + 1e-9:  # played to its end
                target = max(self._mean[label], t - self._run_start)
                self._start(t, choose(db, label, target, p.gamma, i), target)
        u = (t - self._seg_start) * self.speed
        v = self.heads.sample(self.segment, u)
        if p.blend_s > 0.0:
            w = 1.0 - (t - self._jump_t) / p.blend_s
            if w > 0.0:
                v = v + w * self._jump
        self._shown = v
        g = p.gain
        brow = g * float(v[3])
        return g * float(v[0]), g * float(v[1]), g * float(v[2]), 0.0 if brow < 0.0 else (1.0 if brow > 1.0 else brow)
