"""Detector ``yamnet`` (the default: docs/detector.md): Google's YAMNet hears laughter; a fast face, body clips wait for it.

Per frame the detector keeps the last second of audio (``laughlab.detector.yamnet.Window16k``).
Every ``hop_s`` (0.25 s: 15 frames at 60 fps) it runs YAMNet on the 0.975 s window ending
at the current block's last sample and keeps two scores until the next window: the laughter
probability of the ``Head`` (a logistic regression fitted on the corpus' train split) and
the laughter classes' own score (the largest of YAMNet's six laughter classes).  Two gains
follow (the rule of ``docs/detector.md``):

- the **clip gain** (``laugh_gate``) is the model's.  ``rule=either`` (the default): it opens
  when the head's probability of ``open_windows`` (3) windows in a row reaches ``open_at`` or
  the classes' score of ``class_windows`` (1) reaches ``class_open`` (0.1), and closes once both
  are under their lower thresholds (``close_below``, ``class_close``) for ``hold_s``, or at once
  after ``close_quiet_s`` (0.3 s) of quiet (ungated ``mcs`` under ``onset_mcs``).  ``rule=head``
  and ``rule=classes`` use one score only.  A full-body clip may start only while this gain
  is at least 0.5 (``control['clip_gate']``, ``laughlab.detector.model.clip_allowed``);
- the **face gain** (``face_gate``) is the clip gain, except that a new sound (the
  extractor's ungated ``mcs`` rising above ``onset_mcs`` after ``quiet_s`` below it) opens
  it at once, provisionally, until a window that has heard at least ``decide_s`` of it has
  neither score keeping a gain open (head under ``close_below``, classes under
  ``class_close``): the face (and the small chest/belly shapes) answer a laugh's first calls
  while the model listens, and let go of talk after half a second.  ``mcs`` and ``pressure``
  are scaled by it, call onsets and labels are dropped below 0.5 (``apply_gate``); the
  energy scheduler's energy is fed by that ``mcs``, so a laugh's clip is ready when the
  model agrees.

Look-ahead: the frame's own audio block.  Live and offline see the same blocks, so the
same bytes.  ``laughter`` holds the head's probability, ``laughter_classes`` the classes'
score, ``laugh_gate`` the clip gain, ``face_gate`` the face gain.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from laughlab import hookimpl
from laughlab.core.bases import Detector
from laughlab.detector.model import apply_gate, check_hysteresis, check_non_negative
from laughlab.detector.yamnet import LaughterScore, ModelFileError, Window16k, Yamnet, helper


@dataclass
class YamnetParams:
    """The gate's rule.

    Attributes
    ----------
    rule : str
        What opens the clip gain: ``head`` (the head's probability), ``classes`` (YAMNet's own
        laughter classes, untuned: the largest of their six scores) or ``either`` (the default:
        whichever opens first; the gain stays open while either keeps it).
    hop_s : float
        Time between two model windows (s), rounded to whole frames (0.25 s: 15 frames at 60 fps).
    open_at, close_below : float
        Rule head/either: the clip gain opens when the head's probability of ``open_windows``
        windows in a row reaches ``open_at`` ...
    open_windows : int
        Windows in a row at or above ``open_at`` that open the clip gain (3 at 0.25 s; chosen on the
        train scenes, ``yamnet_fit --rules``).
    hold_s : float
        ... and closes once it has stayed below ``close_below`` for this long (s).
    class_open, class_windows, class_close : float, int, float
        Rule classes/either: the gain opens when the laughter classes' score of ``class_windows``
        windows in a row reaches ``class_open`` and stays open while the newest window's is at or above
        ``class_close`` (the head's ``close_below`` also keeps it open under ``either``).
    close_quiet_s : float
        Whatever the scores, the clip gain closes once the ungated ``mcs`` has stayed below
        ``onset_mcs`` this long (s), and cannot open until it is back (0: never): the clip stops soon
        after the laugh while the one-second window still holds it.
    onset_mcs, quiet_s : float
        A new sound: the ungated ``mcs`` reaches ``onset_mcs`` after ``quiet_s`` (s) below it.
    decide_s : float
        The face follows a new sound until a window has heard this much of it (s); 0: never provisional.
    attack_s, release_s : float
        Time for a gain to go 0 -> 1 once open and 1 -> 0 once closed (s).
    async_frames : int
        0 (the default): a model window runs on the frame that takes it (that frame carries its 3-6 ms).
        N > 0: it runs in a helper thread and its scores take effect N frames after the frame that took it
        (2: 33 ms later at 60 fps), whatever the thread's timing, so live and offline runs give the same
        bytes; a live frame thread (a game's) then never waits for the model.  Offline it is not faster: the
        model's time dominates, and the frame thread waits for it N frames later.
    head : str or None
        A head JSON (``python -m laughlab.detector.yamnet_fit --out FILE``); None: the bundled one.
    """

    rule: str = "either"
    hop_s: float = 0.25
    open_at: float = 0.5
    open_windows: int = 3
    close_below: float = 0.3
    hold_s: float = 0.0
    onset_mcs: float = 0.15
    quiet_s: float = 0.3
    decide_s: float = 0.3
    attack_s: float = 0.05
    release_s: float = 0.25
    class_open: float = 0.1
    class_close: float = 0.05
    class_windows: int = 1
    close_quiet_s: float = 0.3
    async_frames: int = 0
    head: str | None = None

    def __post_init__(self) -> None:
        check_non_negative(self, ("hop_s", "hold_s", "quiet_s", "decide_s", "attack_s", "release_s", "onset_mcs",
                                  "close_quiet_s"))
        if self.rule not in RULES:
            raise ValueError(f"rule must be one of {', '.join(RULES)} (got {self.rule})")
        for k in ("open_windows", "class_windows"):
            v = getattr(self, k)
            if not (isinstance(v, int) and v >= 1):
                raise ValueError(f"{k} must be a whole number >= 1 (got {v})")
        if not (isinstance(self.async_frames, int) and not isinstance(self.async_frames, bool)
                and 0 <= self.async_frames <= 60):
            raise ValueError(f"async_frames must be a whole number from 0 to 60 (got {self.async_frames})")
        check_hysteresis(self, "class_close", "class_open")
        check_hysteresis(self, "close_below", "open_at")


#: which score opens the clip gain: the head's probability, the laughter classes' score, or either
RULES = ("head", "classes", "either")


class YamnetDetector(Detector):
    name = "yamnet"
    Params = YamnetParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        try:
            self.model = Yamnet()
            self.score = LaughterScore(self.params.head)
        except ModelFileError as exc:
            raise ValueError(str(exc)) from None
        self.window = Window16k(self.ctx.sample_rate)
        self.hop = max(1, int(round(self.params.hop_s * self.ctx.fps)))
        self.use_head = self.params.rule in ("head", "either")
        self.use_classes = self.params.rule in ("classes", "either")
        self.reset()

    def reset(self) -> None:
        self.window.reset()
        self.k = 0
        self.p = 0.0
        self.q = 0.0        # the laughter classes' score of the newest window
        self.run = 0        # windows in a row at or above open_at
        self.qrun = 0       # windows in a row at or above class_open
        self.open = False
        self.below_s = 0.0
        self.clip_gain = 0.0
        self.face_gain = 0.0
        self.quiet = math.inf
        self.pending = None  # time of the new sound the face follows before the model has heard it
        self._drain()        # self.queue: (frame the scores take effect, future of the window's scores)

    def _drain(self) -> None:
        """Wait for windows still in the helper thread (a reset or the end of a run)."""
        for _, fut in getattr(self, "queue", []):
            fut.result()
        self.queue = []

    def close(self) -> None:
        self._drain()

    def _take(self, scores, t_end: float) -> None:
        """A window's scores take effect (on its own frame, or ``async_frames`` later)."""
        p = self.params
        self.p, self.q = self.score.both(scores)
        self.run = self.run + 1 if self.p >= p.open_at else 0
        self.qrun = self.qrun + 1 if self.q >= p.class_open else 0
        if (self.pending is not None and t_end - self.pending >= p.decide_s - 1e-9
                and not self._reaches(p.close_below, p.class_close)):
            self.pending = None   # the window keeps no gain open: the face's provisional answer ends

    def _reaches(self, head_at: float, class_at: float) -> bool:
        """Does the newest window's score reach ``head_at`` (the head) or ``class_at`` (the laughter classes),
        counting the scores the rule uses?"""
        return (self.use_head and self.p >= head_at) or (self.use_classes and self.q >= class_at)

    def _ramp(self, g: float, up: bool, dt: float) -> float:
        p = self.params
        if up:
            return 1.0 if p.attack_s <= 0 else min(1.0, g + dt / p.attack_s)
        return 0.0 if p.release_s <= 0 else max(0.0, g - dt / p.release_s)

    def step(self, block, frame) -> None:
        p, dt = self.params, frame.dt
        self.window.push(block)
        t_end = (self.k + 1) * dt  # the block's end: the newest sample the window holds
        c = frame.control
        mcs = float(c.get("mcs", 0.0))
        if mcs >= p.onset_mcs:
            if self.quiet >= p.quiet_s and p.decide_s > 0:
                self.pending = t_end
            self.quiet = 0.0
        else:
            self.quiet += dt
        if (self.k + 1) % self.hop == 0:
            if p.async_frames == 0:
                self._take(self.model.scores(self.window.window()), t_end)
            else:
                self.queue.append((self.k + p.async_frames, helper().submit(self.model.scores, self.window.window())))
        while self.queue and self.queue[0][0] == self.k:
            self._take(self.queue.pop(0)[1].result(), t_end)
        self.k += 1
        sound = p.close_quiet_s <= 0 or self.quiet < p.close_quiet_s - 1e-9
        if sound and ((self.use_head and self.run >= p.open_windows)
                      or (self.use_classes and self.qrun >= p.class_windows)):
            self.open, self.below_s = True, 0.0
        elif self.open:
            if not sound:
                self.open = False
            elif not self._reaches(p.close_below, p.class_close):
                self.below_s += dt
                if self.below_s >= p.hold_s - 1e-9:
                    self.open = False
            else:
                self.below_s = 0.0
        self.clip_gain = self._ramp(self.clip_gain, self.open, dt)
        face_open = self.open or self.pending is not None or (sound and self._reaches(p.open_at, p.class_open))
        self.face_gain = self._ramp(self.face_gain, face_open, dt)
        face = max(self.face_gain, self.clip_gain)
        c["laughter"] = self.p
        c["laughter_classes"] = self.q
        c["laugh_gate"] = self.clip_gain
        c["face_gate"] = face
        apply_gate(frame, face)
        c["clip_gate"] = self.clip_gain


@hookimpl
def register_detectors(register):
    register(YamnetDetector)
