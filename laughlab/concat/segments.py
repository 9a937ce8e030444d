"""Motion segments labelled by pseudo-phoneme class, cut from the clip library.

Ding et al. (2014, section 4.2) synthesise head and eyebrow motion by
concatenating real motion segments, each recorded with (and labelled by) one of
the 14 AVLaughterCycle pseudo-phonemes.  laughlab has no motion capture labelled
by phoneme; its full-body clips (:mod:`laughlab.motion.clips`) are keyframed.  This
module derives a segment database from them instead, with the rules below.
Everything is deterministic and takes about 20 ms for the bundled library.

Cutting
-------
1. Forward kinematics of every clip frame gives the world positions of the 22
   joints and 6 End Sites (cm).  The *whole-body joint speed* of a frame is the
   mean over these 28 points of their speed (cm/s, central differences at the
   clip rate; looping clips wrap around).
2. The speed is smoothed by a 3-frame moving average, so that the cuts follow
   the keyed strokes of the motion rather than every reversal of the 4.5 Hz
   shake layered on top of them.
3. Cuts are placed at local minima of the smoothed speed (the motion is slowest
   between two strokes), the slowest minima first, each at least
   ``min_frames`` (5 frames, 0.21 s at 24 fps) away from the clip's ends and
   from every cut already placed.
4. The segments of a clip are the pieces between consecutive cuts: they tile
   the clip, ``[0, c_1], [c_1, c_2], ..., [c_n, duration_s]`` in clip seconds.

Labelling
---------
Each segment gets five numbers:

* ``mean_speed``, ``peak_speed``: whole-body joint speed over its frames (cm/s);
* ``duration_s``;
* ``shake``: RMS (degrees) over its frames of the torso pitch (the ``x`` angles
  of ``spine1`` plus ``spine2``) band-passed to 3.5-6 Hz (2nd-order Butterworth,
  zero phase, over the whole clip): the rhythmic laughter shake (4-5 Hz);
* ``rise``: how far the neck rises from the segment's first to its last pose
  (cm, > 0 up).

The first rule that holds gives the segment's class *group* (the thresholds are
the fields of :class:`SegmentRules`):

=========== ======================================== =========================
group       rule                                     reading
=========== ======================================== =========================
silence     ``mean_speed < 12 cm/s``                 idle, low-motion pieces
cackle      ``mean_speed >= 45 cm/s``                big, fast pieces
inbreath    ``rise >= 3 cm``                         torso rising as in an in-breath
vowel       ``shake >= 1.2 deg``                     rhythmic 4-5 Hz shaking
sharp       ``duration_s <= 0.25 s``                 short non-rhythmic strokes
grunt       otherwise                                longer non-rhythmic strokes: slow, heavy
=========== ======================================== =========================

Groups with several classes split their segments by mean speed: ranked from
the slowest to the fastest, the ranking is cut into equal parts, one per class
in the order of :data:`GROUPS` (the least to the most energetic sound):
vowel -> ``o, e, vowel, a``; sharp -> ``click, glotstop, plosive``;
inbreath -> ``nasal, ne, fricative, ic``.  The grouping and these orders are our
reading of the AVLaughterCycle classes, not the paper's (it used segments
recorded with each class).

Bundled library (12 clips): 87 segments of 0.21 to 1.42 s; per class silence 9
(7 of them from idle), cackle 16, grunt 10, o/e/vowel/a 9/9/9/9,
click/glotstop/plosive 2/1/1, nasal/ne/fricative/ic 3/3/3/3.

Fallback: a class without a segment of its own is served by the segments of its
group; a group without any segment by the nearest non-empty group on the scale
``silence, inbreath, grunt, vowel, sharp, cackle`` (from still to violent; on
a tie the stiller one).  :meth:`SegmentDB.candidates` applies this, so every one
of the 14 classes always has candidates.

Pose feature (for the continuity cost, Ding Eq. 8)
--------------------------------------------------
``first`` and ``last`` hold the world positions, in **cm**, of the key joints
:data:`KEY_JOINTS` (hips, chest, head, elbows, wrists, knees) at the segment's
first and last pose, flattened to ``(3 * 9,)``.  The full pose vectors (BVH
channels) are kept as ``first_pose`` / ``last_pose``.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from laughlab.motion.skeleton import forward_kinematics

__all__ = [
    "PSEUDO_PHONEMES",
    "GROUPS",
    "GROUP_OF",
    "GROUP_SCALE",
    "KEY_JOINTS",
    "Segment",
    "SegmentRules",
    "SegmentDB",
    "build",
    "cut_points",
    "segment_db",
]

PSEUDO_PHONEMES: tuple[str, ...] = ("silence", "ne", "click", "nasal", "plosive", "fricative", "ic", "e", "o",
                                    "grunt", "cackle", "a", "glotstop", "vowel")
"""The 14 AVLaughterCycle pseudo-phoneme classes (Ding et al. 2014, section 3)."""

GROUPS: dict[str, tuple[str, ...]] = {
    "silence": ("silence",),
    "inbreath": ("nasal", "ne", "fricative", "ic"),
    "grunt": ("grunt",),
    "vowel": ("o", "e", "vowel", "a"),
    "sharp": ("click", "glotstop", "plosive"),
    "cackle": ("cackle",),
}
"""Motion groups and their classes, each from the least to the most energetic."""

GROUP_OF: dict[str, str] = {c: g for g, cs in GROUPS.items() for c in cs}
"""Pseudo-phoneme class -> its motion group."""

HELD = "held"
"""Not a pseudo-phoneme: what the ``concat`` scheduler plays while a detector holds full-body clips back
(``detector=yamnet`` before the model hears laughter).  Its candidates are the ``silence`` segments of clips
with no laughing energy (``idle``): the ``silence`` class also holds pauses cut from laugh clips (``point1``'s
raised arm), which would answer talk with a laugh's gesture."""

GROUP_SCALE: tuple[str, ...] = ("silence", "inbreath", "grunt", "vowel", "sharp", "cackle")
"""Groups from still to violent: an empty group falls back to its nearest non-empty neighbour here."""

KEY_JOINTS: tuple[str, ...] = ("hips", "spine2", "head", "left_forearm", "right_forearm", "left_hand",
                               "right_hand", "left_shin", "right_shin")
"""Joints whose world positions (cm) form the pose feature of the continuity cost."""

SHAKE_BAND_HZ = (3.5, 6.0)
"""Pass band of the shake measure (Hz): around the 4-5 Hz laughter shake."""


@dataclass(frozen=True)
class SegmentRules:
    """Cutting and labelling thresholds (see the module docstring).

    Attributes
    ----------
    min_frames : int
        Shortest segment, clip frames (5 frames = 0.21 s at 24 fps).
    smooth_frames : int
        Width of the moving average applied to the joint speed before cutting.
    silence_speed : float
        Mean joint speed below which a segment is silence (cm/s).
    cackle_speed : float
        Mean joint speed from which a segment is a cackle (cm/s).
    inbreath_rise : float
        Neck rise from which a segment is in-breath-like (cm).
    vowel_shake : float
        Band-passed torso pitch RMS from which a segment is vowel-like (degrees).
    sharp_max_s : float
        Longest non-rhythmic segment counted as sharp (s).
    """

    min_frames: int = 5
    smooth_frames: int = 3
    silence_speed: float = 12.0
    cackle_speed: float = 45.0
    inbreath_rise: float = 3.0
    vowel_shake: float = 1.2
    sharp_max_s: float = 0.25

    def __post_init__(self) -> None:
        if self.min_frames < 1 or self.smooth_frames < 1:
            raise ValueError("min_frames and smooth_frames must be >= 1")
        if not self.silence_speed <= self.cackle_speed:
            raise ValueError("silence_speed must be <= cackle_speed")

    def group(self, mean_speed: float, duration_s: float, shake: float, rise: float) -> str:
        """The motion group of a segment: the first rule that holds."""
        if mean_speed < self.silence_speed:
            return "silence"
        if mean_speed >= self.cackle_speed:
            return "cackle"
        if rise >= self.inbreath_rise:
            return "inbreath"
        if shake >= self.vowel_shake:
            return "vowel"
        if duration_s <= self.sharp_max_s:
            return "sharp"
        return "grunt"


@dataclass(frozen=True, eq=False)
class Segment:
    """A piece of a clip, labelled with a pseudo-phoneme class.

    Attributes
    ----------
    clip : str
        Name of the source clip in the library.
    start_s, end_s : float
        Clip time where the segment starts and ends (s); play it with
        ``ClipEvent(offset_s=start_s, end_s=end_s)``.
    label : str
        Pseudo-phoneme class (one of :data:`PSEUDO_PHONEMES`).
    first, last : ndarray, shape (D,)
        Pose feature at the first and last pose: world positions of
        :data:`KEY_JOINTS`, cm, flattened (any fixed D for hand-made DBs).
    energy : float
        Laughing energy of the source clip (thesis units; idle: 0).
    first_pose, last_pose : ndarray, shape (3 + 3J,) or None
        The full pose vectors (BVH channels) at ``start_s`` and ``end_s``.
    mean_speed, peak_speed : float
        Whole-body joint speed over the segment (cm/s).
    shake : float
        RMS of the 3.5-6 Hz band-passed torso pitch (degrees).
    rise : float
        Rise of the neck from the first to the last pose (cm).
    """

    clip: str
    start_s: float
    end_s: float
    label: str
    first: np.ndarray
    last: np.ndarray
    energy: float = 0.0
    first_pose: np.ndarray | None = None
    last_pose: np.ndarray | None = None
    mean_speed: float = math.nan
    peak_speed: float = math.nan
    shake: float = math.nan
    rise: float = math.nan

    @property
    def duration_s(self) -> float:
        """Segment duration ``end_s - start_s`` (s of clip time)."""
        return self.end_s - self.start_s

    def __repr__(self) -> str:
        return (f"Segment({self.clip!r}, {self.start_s:.3f}-{self.end_s:.3f} s, {self.label!r}, "
                f"energy={self.energy:g})")


class SegmentDB:
    """Segments with their class index and stacked arrays for the costs.

    Parameters
    ----------
    segments : sequence of Segment
        Every label must be one of :data:`PSEUDO_PHONEMES`; all ``first`` /
        ``last`` features must have the same length.

    Attributes
    ----------
    segments : tuple of Segment
    durations : ndarray (N,)
        Segment durations (s).
    first, last : ndarray (N, D)
        Pose features (cm).
    energies : ndarray (N,)
    """

    def __init__(self, segments: Sequence[Segment]):
        self.segments = tuple(segments)
        if not self.segments:
            raise ValueError("a segment database needs at least one segment")
        bad = [s.label for s in self.segments if s.label not in GROUP_OF]
        if bad:
            raise ValueError(f"unknown pseudo-phoneme {bad[0]!r}; choose from: {', '.join(PSEUDO_PHONEMES)}")
        self.durations = np.array([s.duration_s for s in self.segments], dtype=np.float64)
        if not (self.durations > 0).all():
            raise ValueError("segment durations must be > 0")
        self.first = np.array([np.asarray(s.first, dtype=np.float64) for s in self.segments])
        self.last = np.array([np.asarray(s.last, dtype=np.float64) for s in self.segments])
        self.energies = np.array([s.energy for s in self.segments], dtype=np.float64)
        labels = np.array([s.label for s in self.segments])
        self._members = {c: np.flatnonzero(labels == c) for c in PSEUDO_PHONEMES}
        self._candidates = {c: self._fallback(c) for c in PSEUDO_PHONEMES}
        still = self._candidates["silence"][self.energies[self._candidates["silence"]] == 0]
        self._candidates[HELD] = still if still.size else self._candidates["silence"]
        self._mean = {c: float(self.durations[self._candidates[c]].mean()) for c in (*PSEUDO_PHONEMES, HELD)}

    def _fallback(self, label: str) -> np.ndarray:
        own = self._members[label]
        if own.size:
            return own
        def group(g):
            return np.sort(np.concatenate([self._members[c] for c in GROUPS[g]]))
        k = GROUP_SCALE.index(GROUP_OF[label])
        for dist in range(len(GROUP_SCALE)):
            for j in (k - dist, k + dist):  # the stiller neighbour first
                if 0 <= j < len(GROUP_SCALE):
                    idx = group(GROUP_SCALE[j])
                    if idx.size:
                        return idx
        raise AssertionError("unreachable: the database is not empty")  # pragma: no cover

    def members(self, label: str) -> np.ndarray:
        """Indices of the segments labelled ``label`` (possibly empty)."""
        return self._members[self._check(label)]

    def candidates(self, label: str) -> np.ndarray:
        """Indices of the segments that may play ``label``: its own, else the fallback (never empty)."""
        return self._candidates[self._check(label)]

    def mean_duration(self, label: str) -> float:
        """Mean duration of the candidates of ``label`` (s)."""
        return self._mean[self._check(label)]

    def counts(self) -> dict[str, int]:
        """Number of segments labelled with each class (before any fallback)."""
        return {c: int(self._members[c].size) for c in PSEUDO_PHONEMES}

    @staticmethod
    def _check(label: str) -> str:
        if label not in GROUP_OF and label != HELD:
            raise KeyError(f"unknown pseudo-phoneme {label!r}; choose from: {', '.join(PSEUDO_PHONEMES)}")
        return label

    def __len__(self) -> int:
        return len(self.segments)

    def __getitem__(self, i: int) -> Segment:
        return self.segments[i]

    def __iter__(self) -> Iterator[Segment]:
        return iter(self.segments)


def _joint_speed(points: np.ndarray, fps: float, loop: bool) -> np.ndarray:
    """Mean speed over the points of each frame (cm/s), central differences."""
    if loop:
        vel = (np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)) * (0.5 * fps)
    elif len(points) > 1:
        vel = np.gradient(points, axis=0) * fps
    else:
        vel = np.zeros_like(points)
    return np.linalg.norm(vel, axis=-1).mean(axis=-1)


def cut_points(speed: np.ndarray, rules: SegmentRules = SegmentRules(), loop: bool = False) -> list[int]:
    """Frame indices where a clip is cut: slowest local minima of the smoothed speed first.

    Parameters
    ----------
    speed : ndarray (F,)
        Whole-body joint speed per frame (cm/s).
    rules : SegmentRules
    loop : bool
        Pad the smoothing by wrapping around (looping clips).

    Returns
    -------
    list of int
        Sorted interior cut frames, each ``>= min_frames`` from the ends and from each other.
    """
    n, w, m = len(speed), rules.smooth_frames, rules.min_frames
    half = w // 2
    padded = np.pad(speed, (half, w - 1 - half), mode="wrap" if loop else "edge")
    smooth = np.convolve(padded, np.ones(w) / w, mode="valid")
    minima = [i for i in range(1, n - 1) if smooth[i] < smooth[i - 1] and smooth[i] <= smooth[i + 1]]
    minima.sort(key=lambda i: (smooth[i], i))
    cuts: list[int] = []
    for i in minima:
        if i >= m and n - i >= m and all(abs(i - j) >= m for j in cuts):
            cuts.append(i)
    return sorted(cuts)


def pose_features(skeleton, poses) -> np.ndarray:
    """The continuity feature (Ding et al. 2014, Eq. 8) of each pose of ``poses`` (BVH channel vectors, (N, C)):
    the world positions of :data:`KEY_JOINTS` in cm, (N, 3 * 9), as a segment's ``first`` and ``last``."""
    key = [skeleton.index(n) for n in KEY_JOINTS]
    return forward_kinematics(skeleton, np.atleast_2d(poses))[:, key].reshape(len(np.atleast_2d(poses)), -1)


def build(library, rules: SegmentRules = SegmentRules()) -> SegmentDB:
    """Cut and label every clip of ``library`` (see the module docstring).

    Parameters
    ----------
    library : ClipLibrary
    rules : SegmentRules

    Returns
    -------
    SegmentDB
        Segments in library order, each clip's segments in time order.
    """
    sk = library.skeleton
    key = [sk.index(n) for n in KEY_JOINTS]
    neck = sk.index("neck")
    pitch_cols = [sk.angle_slice(n).start + 1 for n in ("spine1", "spine2")]
    segments: list[Segment] = []
    for clip in library:
        n, fps = clip.length_frames, clip.fps
        points = forward_kinematics(sk, clip.poses, end_sites=True)
        speed = _joint_speed(points, fps, clip.loop)
        bounds = [0, *cut_points(speed, rules, clip.loop), n]
        pitch = clip.poses[:, pitch_cols].sum(axis=1)
        lo, hi = SHAKE_BAND_HZ
        if n > 12 and hi < 0.5 * fps:
            from scipy.signal import butter, sosfiltfilt  # imported when used (~0.6 s)

            sos = butter(2, [lo, hi], btype="band", fs=fps, output="sos")
            band = sosfiltfilt(sos, pitch, padlen=min(n - 1, 3 * (2 * len(sos) + 1)))
        else:  # too short or too coarse to see a 4-5 Hz shake
            band = np.zeros(n)
        times = [b / fps for b in bounds]
        times[-1] = clip.duration_s
        poses = clip.sample_many(np.array(times))
        fk = forward_kinematics(sk, poses)
        feats = fk[:, key].reshape(len(times), -1)
        for k, (a, b) in enumerate(zip(bounds, bounds[1:])):
            mean_speed = float(speed[a:b].mean())
            shake = float(np.sqrt(np.mean(band[a:b] ** 2)))
            rise = float(fk[k + 1, neck, 1] - fk[k, neck, 1])
            group = rules.group(mean_speed, times[k + 1] - times[k], shake, rise)
            segments.append(Segment(clip.name, times[k], times[k + 1], group, feats[k], feats[k + 1],
                                    float(clip.energy), poses[k], poses[k + 1], mean_speed,
                                    float(speed[a:b].max()), shake, rise))
    return SegmentDB(_split_groups(segments))


def _split_groups(segments: list[Segment]) -> list[Segment]:
    """Replace group labels by classes: rank each group by mean speed, cut into equal parts."""
    from dataclasses import replace

    out = list(segments)
    for group, classes in GROUPS.items():
        idx = [i for i, s in enumerate(segments) if s.label == group]
        idx.sort(key=lambda i: (segments[i].mean_speed, i))
        for rank, i in enumerate(idx):
            out[i] = replace(segments[i], label=classes[rank * len(classes) // len(idx)])
    return out


_CACHE: "weakref.WeakKeyDictionary[object, SegmentDB]" = weakref.WeakKeyDictionary()


def segment_db(library=None) -> SegmentDB:
    """The segment database of ``library``, built once per library object and cached.

    Parameters
    ----------
    library : ClipLibrary, optional
        Defaults to the bundled library (loaded once).
    """
    if library is None:
        global _DEFAULT_LIBRARY
        if _DEFAULT_LIBRARY is None:
            from laughlab.motion.clips import ClipLibrary

            _DEFAULT_LIBRARY = ClipLibrary.load()
        library = _DEFAULT_LIBRARY
    db = _CACHE.get(library)
    if db is None:
        db = _CACHE[library] = build(library)
    return db


_DEFAULT_LIBRARY = None
