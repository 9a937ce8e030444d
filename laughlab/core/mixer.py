"""The mixer: plays clips at their speed, blends poses, adds body-driver offsets.

Poses are BVH channel vectors (see :mod:`laughlab.motion.skeleton`): root position in
cm, then Euler angles in degrees per joint.  Blending is linear in these
channels, as Blender's action blend-in is (van Duijn 2014, 5.5).
"""
from __future__ import annotations

import numpy as np

from laughlab.core.frame import Frame


class Mixer:
    """One pose per frame from clip events and joint offsets.

    While no clip plays, the looping idle motion plays (thesis 5.5, last
    paragraph).  A start blends linearly over the event's ``blend_s`` from the
    pose shown at that moment to the new clip; a clip that finishes or is
    stopped hands over to idle with the same blend.

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

    def _switch(self, t: float, blend_s: float) -> None:
        if self.last_pose is not None and blend_s > 0.0:
            self.blend_from = self.last_pose.copy()
            self.blend_start, self.blend_s = t, blend_s
        else:
            self.blend_from = None

    def advance(self, frame: Frame) -> None:
        """Apply the frame's clip events; set ``frame.clip_eyes`` from the playing clip."""
        t = frame.time_s
        for ev in frame.events:
            if ev.kind == "start":
                self._switch(t, ev.blend_s)
                self.clip = self.library[ev.clip]
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
                frame.clip_eyes = 0.0
            else:
                frame.clip_eyes = self.clip.eyes_closed(local)
        else:
            frame.clip_eyes = 0.0

    def pose(self, frame: Frame) -> np.ndarray:
        """The skeleton pose of this frame (BVH channel vector)."""
        t = frame.time_s
        if self.clip is not None:
            pose = self.clip.sample(self.offset + (t - self.clip_start) * self.speed)
        else:
            pose = self.idle.sample(t - self.idle_start)
        if self.blend_from is not None:
            w = (t - self.blend_start) / self.blend_s
            if w >= 1.0:
                self.blend_from = None
            else:
                pose = self.blend_from + w * (pose - self.blend_from)
        if frame.offsets:
            pose = pose.copy()
            col = self._col
            for joint, (z, x, y) in frame.offsets.items():
                c = col[joint]
                pose[c] += z
                pose[c + 1] += x
                pose[c + 2] += y
        self.last_pose = pose
        return pose
