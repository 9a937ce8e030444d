"""Taking back what a face built on a sound the detector then judged not laughter.

``detector=yamnet`` opens the face gain at once on a new sound, provisionally, and closes it when a window
that has heard ``decide_s`` of it hears no laughter (docs/detector.md, *Face gain*).  The fast channels (the
jaw's calls, the chest) let go with the gain; a slow state does not: van Duijn 2014's smile rises to full in
0.17 s and falls over 5 s (thesis 5.3: rise 0.03, fall 0.001 per tick, maxE 0.3), so the half second of every
phrase of talk kept the smile above 0.5 through 99% of a minute of speech (a review, 2026-11-27).

:class:`Retraction` snapshots a face's slow states when a provisional answer starts
(``control['face_provisional']`` rising to 1) and, on the frame the detector takes it back
(``control['face_retract']`` = 1), holds each state under a ceiling that comes down linearly from its value
then to its snapshot over ``retract_s`` (a state already lower stays as the face leaves it).  An answer the
model confirms is kept whole; without these channels (``detector=none``, the papers) nothing changes.
"""
from __future__ import annotations

import math


class Retraction:
    """The slow states ``(object, attribute)`` of a face, taken back after a rejected provisional answer.

    A face calls :meth:`begin` before its own step on a frame and :meth:`clamp` after it, before it writes its
    channels.  ``retract_s`` (s): how long the states take to come down to their snapshot; it should be at
    least the detector's ``release_s`` (0.25 s), while the face gain still lets some of the sound through.
    """

    def __init__(self, states: list[tuple[object, str]], retract_s: float, dt: float):
        self.states = states
        self.frames = max(1, math.ceil(retract_s / dt - 1e-9))
        self.reset()

    def reset(self) -> None:
        self.was = False
        self.base: list[float] = []    # the states when the provisional answer began
        self.top: list[float] = []     # the states when it was taken back
        self.k = self.frames           # frames of taking back done (= frames: not taking back)

    def begin(self, control: dict) -> None:
        """Before the face's step: snapshot the states as a provisional answer starts; start taking back."""
        provisional = control.get("face_provisional", 0.0) >= 0.5
        if provisional and not self.was:
            self.base = [getattr(o, a) for o, a in self.states]
            self.k = self.frames        # a new answer: an earlier taking back ends
        self.was = provisional
        if control.get("face_retract", 0.0) >= 0.5 and self.base:
            self.top = [getattr(o, a) for o, a in self.states]
            self.k = 0

    def clamp(self) -> bool:
        """After the face's step: while taking back, each state is held under a ceiling going linearly from its
        value when the answer was taken back to its snapshot, over ``retract_s`` (the face's own dynamics, still
        fed a fading sound, cannot build it up again meanwhile).  True while taking back: the face then writes
        its channels from the states as clamped."""
        if self.k >= self.frames:
            return False
        self.k += 1
        f = self.k / self.frames
        for (o, a), b, t in zip(self.states, self.base, self.top):
            ceiling = max(b, t - (t - b) * f)
            if getattr(o, a) > ceiling:
                setattr(o, a, ceiling)
        return True
