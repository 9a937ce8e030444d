"""The mixer: plays clips at their speed, blends poses, adds body-driver offsets.

Poses are BVH channel vectors (see :mod:`laughlab.motion.skeleton`): root position in
cm, then Euler angles in degrees per joint.  Blending is linear in these
channels, as Blender's action blend-in is (van Duijn 2014, 5.5).
"""
from __future__ import annotations

import math

import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.core.frame import Frame


class Mixer:
    """One pose per frame from clip events and joint offsets.

    While no clip plays, the looping idle motion plays (thesis 5.5, last
    paragraph).  A start blends linearly over the event's ``blend_s`` from the
    pose shown at that moment to the new clip; a clip that finishes or is
    stopped hands over to idle with the same blend.  The body driver's joint
    offsets go on top of the clips' (blended) pose, so a blend starts from that
    pose without them: they are added once, never carried into the blend.  The clip's eye key
    (``frame.clip_eyes``, thesis 3.3.3) blends over the same time from the
    value shown at the switch, so the eyes do not snap when a clip starts, is
    overruled or ends (Blender's blend-in mixes shape keys of the action too).

    Parameters
    ----------
    library : ClipLibrary
        The clips.
    idle_blend_s : float
        Blend time back to idle when a clip ends (s).
    """

    def __init__(self, library, idle_blend_s: float = 10.0 / 24.0):
        self.library = library
        self.skeleton = library.skeleton
        self.idle = library.idle
        self.idle_blend_s = idle_blend_s
        self._col = {name: 3 + 3 * i for i, name in enumerate(self.skeleton.names)}
        self.offsets_by = "the body"   # the run names it: "body 'sway' (its file)"
        self.reset()

    def reset(self) -> None:
        self.clip = None          # the playing clip, or None for idle
        self.clip_start = 0.0     # time the clip started (s)
        self.speed = 1.0
        self.offset = 0.0         # clip time at the start (s)
        self.end = 0.0            # clip time where playback ends (s)
        self.idle_start = 0.0     # time idle (re)started (s)
        self.blend_from: np.ndarray | None = None
        self.blend_start = 0.0
        self.blend_s = 0.0
        self.last_pose = None
        self.last_eyes = 0.0      # the clip eye key shown last
        self.eyes_from: float | None = None  # eye key at the last switch while its blend runs
        self.eyes_start = 0.0
        self.eyes_blend_s = 0.0
        self._pending: list = []  # what each noted frame shows, not yet rendered
        self._rendered: list = []  # poses rendered early (a blend needed the last one)

    def _switch(self, t: float, blend_s: float) -> None:
        if self._pending:  # the blend starts from the pose shown last: render it now
            self._rendered.append(self._render(self._pending))
            self._pending = []
        if blend_s > 0.0:   # from the pose shown last; before any, the idle pose this frame would show (a clip
            # started on the first frame snapped to its pose: every concat run began mid-gesture, a study's review)
            self.blend_from = (self.last_pose.copy() if self.last_pose is not None
                               else self.idle.sample_rows(np.array([t - self.idle_start]))[0])
            self.blend_start, self.blend_s = t, blend_s
        else:
            self.blend_from = None
        self.eyes_from = self.last_eyes if blend_s > 0.0 else None
        self.eyes_start, self.eyes_blend_s = t, blend_s

    def advance(self, frame: Frame) -> None:
        """Apply the frame's clip events; set ``frame.clip_eyes`` from the playing clip."""
        t = frame.time_s
        for ev in frame.events:
            if ev.kind == "start":
                self._switch(t, ev.blend_s)
                try:
                    self.clip = self.library[ev.clip]
                except KeyError as exc:   # a scheduler's bug: one line, not a traceback through the pipeline
                    raise LaughlabError(f"the scheduler started clip {ev.clip!r} at {t:.2f} s (frame {frame.index}), "
                                        f"which the clip library does not hold ({exc.args[0]})") from None
                self.clip_start, self.speed, self.offset = t, ev.speed, ev.offset_s
                self.end = self.clip.duration_s if ev.end_s is None else ev.end_s
            elif ev.kind == "stop" and self.clip is not None and ev.clip == self.clip.name:
                self._switch(t, self.idle_blend_s)
                self.clip, self.idle_start = None, t
        if self.clip is not None:
            local = self.offset + (t - self.clip_start) * self.speed
            if local >= self.end:  # the clip (or segment) played to its end
                self._switch(t, self.idle_blend_s)
                self.clip, self.idle_start = None, t
                eyes = 0.0
            else:
                eyes = self.clip.eyes_closed(local)
        else:
            eyes = 0.0
        if self.eyes_from is not None:
            w = (t - self.eyes_start) / self.eyes_blend_s
            if w >= 1.0:
                self.eyes_from = None
            else:
                eyes = self.eyes_from + w * (eyes - self.eyes_from)
        frame.clip_eyes = self.last_eyes = eyes

    def note(self, frame: Frame) -> None:
        """Record what this frame shows (clip and clip time, blend, joint offsets); :meth:`take` renders it.

        Rendering a chunk of frames at once (:meth:`Clip.sample_rows`) gives the poses
        :meth:`pose` gives frame by frame, at a fraction of the cost.
        """
        t = frame.time_s
        if self.clip is not None:
            src, local = self.clip, self.offset + (t - self.clip_start) * self.speed
        else:
            src, local = self.idle, t - self.idle_start
        bf, w = None, 0.0
        if self.blend_from is not None:
            w = (t - self.blend_start) / self.blend_s
            if w >= 1.0:
                self.blend_from = None
            else:
                bf = self.blend_from
        self._pending.append((src, local, bf, w, frame.offsets or None, frame.index))

    def take(self) -> np.ndarray:
        """The poses of the frames noted since the last call, one row per frame (BVH channel vectors)."""
        parts = self._rendered
        if self._pending:
            parts.append(self._render(self._pending))
        self._pending, self._rendered = [], []
        if not parts:
            return np.empty((0, self.skeleton.n_channels))
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def pose(self, frame: Frame) -> np.ndarray:
        """The skeleton pose of this frame (BVH channel vector): :meth:`note` and :meth:`take` for one frame."""
        self.note(frame)
        return self.take()[0]

    def _render(self, recipes: list) -> np.ndarray:
        """Poses of noted frames: clip samples, then blends, then joint offsets (the order of 0.1's mixer)."""
        out = np.empty((len(recipes), self.skeleton.n_channels))
        groups: dict = {}
        for i, r in enumerate(recipes):
            groups.setdefault(id(r[0]), (r[0], []))[1].append(i)
        for src, rows in groups.values():
            out[rows] = src.sample_rows([recipes[i][1] for i in rows])
        blend = [i for i, r in enumerate(recipes) if r[2] is not None]
        if blend:
            bf = np.array([recipes[i][2] for i in blend])
            w = np.array([recipes[i][3] for i in blend])[:, None]
            out[blend] = bf + w * (out[blend] - bf)
        self.last_pose = out[-1].copy()  # a blend starts from the clips' pose: the offsets go on top once, below
        col = self._col
        for i, r in enumerate(recipes):
            if r[4]:
                row = out[i]
                for joint, rot in r[4].items():
                    c = col.get(joint)
                    if c is None:   # a body's bug: one line naming the joint, not a KeyError through the pipeline
                        raise LaughlabError(f"{self.offsets_by} wrote an offset for joint {joint!r}, which the "
                                            f"skeleton does not have (its joints: {', '.join(col)})")
                    try:
                        z, x, y = rot
                        ok = math.isfinite(z + x + y)
                    except (TypeError, ValueError):
                        ok = False
                    if not ok:   # a plugin author's review: a 2-tuple ended in a traceback, a NaN named no joint
                        raise bad_offset(self.offsets_by, joint, rot, r[5])
                    row[c] += z
                    row[c + 1] += x
                    row[c + 2] += y
        return out


def bad_offset(who: str, joint: str, rot, index: int) -> LaughlabError:
    """The line for a joint offset that is not three finite angles (a body's bug)."""
    from laughlab.core.blame import WHOSE, PluginBug

    return PluginBug(f"{who} offsets joint {joint!r} by {str(rot)[:60]} at frame {index}: an offset is three finite "
                     f"angles (z, x, y) in degrees; {WHOSE}; nothing was written")


def mid_clip(mixer) -> bool:
    """A clip other than a looping idle plays, or the blend back to idle runs (``run_out`` goes on while it does): a
    review found ``scheduler=concat``'s idle segments, a looping clip, kept ``run_out`` going to its 20 s cap."""
    return (mixer.clip is not None and not mixer.clip.loop) or mixer.blend_from is not None


#: a face whose ``smile`` and ``jaw`` are at most this (weights) and moved at most this in the last frame is at rest:
#: ``run_out`` ends
FACE_STILL = 1e-3


def settling(mixer, before, frame) -> bool:
    """``run_out`` goes on: :func:`mid_clip`, or the face is not yet at rest: its ``smile`` or ``jaw`` above
    :data:`FACE_STILL`, or moving by more than it from the frame ``before`` to ``frame`` (since 2026-11-29; a review
    of baked assets in Blender: the body stood at rest and the face still smiled at 0.29, face=facs' smile falling
    0.2 a second). The level counts since 2026-11-29's eighteenth session: the default face's smile is clipped at 1
    while its state falls (thesis Eq. 3.3's output range), so it did not move, and a facial animator's review saw
    run_out end on a full smile."""
    if mid_clip(mixer):
        return True
    if before is None or frame is None:
        return False
    a, b = before.channels, frame.channels
    return any(b.get(c, 0.0) > FACE_STILL or abs(b.get(c, 0.0) - a.get(c, 0.0)) > FACE_STILL for c in ("smile", "jaw"))
