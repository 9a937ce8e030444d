"""Detector ``yamnet`` (the default: docs/detector.md): Google's YAMNet hears laughter; a fast face, body clips wait for it.

Per frame the detector keeps the last second of audio (``laughlab.detector.yamnet.Window16k``).
Every ``hop_s`` (0.25 s: 15 frames at 60 fps) it runs YAMNet on the 0.975 s window ending
at the current block's last sample (its log-mel rows kept from earlier windows, its network
spread over ``model_frames`` frames, the scores taking effect on the last of them; on a file,
computed ahead in helper threads with the same result) and keeps two scores until the next window: the laughter
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

With ``fuse`` (``detector=yamnet_fused``) the head's probability is replaced by the head fused with the feature
MLP's cues of the window's last frame (``laughlab.detector.fuse``; its opening rule in
``conf/detector/yamnet_fused.yaml``).

Look-ahead: the frame's own audio block.  Live and offline see the same blocks, so the
same bytes.  ``laughter`` holds the head's probability, ``laughter_classes`` the classes'
score, ``laugh_gate`` the clip gain, ``face_gate`` the face gain, ``face_provisional`` 1 while the face answers a
new sound the model has not yet judged, ``face_retract`` 1 on the frame the model takes that answer back (the
faces then undo what their slow states built on it: ``laughlab.face.provisional``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Detector
from laughlab.core.plugins import check_range
from laughlab.detector.model import apply_gate, check_hysteresis, check_non_negative
from laughlab.detector.yamnet import Ahead, LaughterScore, ModelFileError, Window16k, Yamnet, helper
from laughlab.detector.yamnet_model import CUTS, NOISE_VETO, noise_vetoes


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
    model_frames : int
        The model's work on a window is spread over this many frames (1-4; over fewer when windows come
        more often: at most the frames from one window to the next), starting with the frame that takes the
        window, and its scores take effect on the last of them (4, the default: 50 ms later at 60 fps; no
        frame carries more than about a quarter of the network, 0.6-0.9 ms on a 2-core machine; ``CUTS`` in
        ``laughlab.detector.yamnet_model``).  The window's log-mel rows are computed once per
        10 ms frame of audio and kept while windows overlap.
    async_frames : int
        0 (the default): the model runs in the frame thread (``model_frames``).  N > 0: a window's network
        runs in a helper thread and its scores take effect N frames after the frame that took it (2: 33 ms
        later at 60 fps), whatever the thread's timing, so live and offline runs give the same bytes; a live
        frame thread (a game's) then never waits for the model (``model_frames`` is not used).
    prefetch : bool
        On an offline input that can be read twice (``input=file``), a helper thread reads the file ahead,
        converts it and runs the model on the windows to come, several at once; each window's scores take
        effect on the same frame as without it, after the frame thread has checked that the helper read the
        very input samples it did (the same bytes; the frame thread then converts nothing itself; on a
        mismatch it takes the stream up from where the helper last agreed).
    head : str or None
        A head JSON (``python -m laughlab.detector.yamnet_fit --out FILE``); None: the bundled one.
    fuse : bool
        The head's probability fused with the feature MLP's cues of the window's last frame
        (``laughlab.detector.fuse``: a logistic regression on the laughter classes' score, the head's
        probability, the MLP's probability and its 23 features, fitted on the train split): ``laughter``
        is then the fused probability, and ``open_at``/``open_windows``/``close_below`` apply to it.  The cues
        cost a short spectrum and pitch search every frame (``docs/detector.md``).
    fuse_file : str or None
        A fused head JSON (``python -m laughlab.detector.yamnet_fit --fuse --out FILE``); None: the bundled one.
    veto : str
        ``classes`` (the default): a window in which YAMNet scores one of its other non-speech human sounds
        (a cough, sneeze, scream, cry, moan, groan, grunt, breathing, gasp, pant...: ``OTHER_HUMAN_CLASSES``)
        above its laughter classes does not count as laughter for the laughter classes' score: it neither
        opens a gain by that score nor keeps one open.  ``both``: nor for the head's probability.  ``none``:
        no veto.  Untuned (no threshold).  The published scores (``laughter``, ``laughter_classes``) are
        unchanged.  The head needs no veto by default: it was fitted on all 521 scores, these classes' among
        them (``docs/detector.md`` has the figures of the three).
    noise_veto : float
        A window in which YAMNet's steady-noise classes (white and pink noise, static, noise, hiss, environmental
        noise: ``NOISE_CLASSES``) score above this and above its laughter classes: the head's probability does not
        count there (it neither opens the clip gain nor keeps it open; ``laughter`` is published unchanged).  The
        head, fitted on voices, took steady white noise for laughter (0.97): 30 s of it at 44.1 kHz opened the
        gate as often as no detector did.  0.1 chosen on the train split, one window every 0.25 s as live: the
        largest of 0.5, 0.3, 0.2, 0.1 with no opening on 30 s of white noise (3 without the veto; 0.5 and 0.3
        broke one long opening into 9 and 7), bouts found 55.4% -> 54.5% (one bout of 101), openings outside
        laughter and the synthetic profiles unchanged; on the held-out sets no change at the gate
        (``docs/detector.md``).  1 turns it off.
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
    model_frames: int = 4
    async_frames: int = 0
    prefetch: bool = True
    head: str | None = None
    fuse: bool = False
    fuse_file: str | None = None
    veto: str = "classes"
    noise_veto: float = NOISE_VETO

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
        if not (isinstance(self.model_frames, int) and not isinstance(self.model_frames, bool)
                and 1 <= self.model_frames <= max(CUTS)):
            raise ValueError(f"model_frames must be a whole number from 1 to {max(CUTS)} (got {self.model_frames})")
        check_range("noise_veto", self.noise_veto, 0.0, 1.0)
        if self.veto not in VETOES:
            raise ValueError(f"veto must be one of {', '.join(VETOES)} (got {self.veto})")
        for k in ("prefetch", "fuse"):
            if not isinstance(getattr(self, k), bool):
                raise ValueError(f"{k} must be true or false (got {getattr(self, k)})")
        check_hysteresis(self, "class_close", "class_open")
        check_hysteresis(self, "close_below", "open_at")


#: which score opens the clip gain: the head's probability, the laughter classes' score, or either
RULES = ("head", "classes", "either")
#: which scores another human sound louder than laughter vetoes: none, the laughter classes', or both
VETOES = ("none", "classes", "both")
#: between windows, the audio is converted and the complete log-mel rows computed every this many frames,
#: counted back from the next window (``prepare_now``)
PREPARE_EVERY = 16


def prepare_now(pos: int, hop: int) -> bool:
    """Is the frame ``pos`` (1 to ``hop`` - 1) frames after a window one that converts the audio and computes
    the complete log-mel rows (``Window16k.prepare``)?  The frame before the next window and every
    ``PREPARE_EVERY`` frames before that, so the window's own frame (which also runs the network's first part)
    has one block to convert and one or two rows to compute.  At 60 fps and a window every 15 frames that is
    one frame in 15, as before 2026-11-26 (then the 8th after the window: the window's frame converted 7
    blocks and computed about 12 rows)."""
    return (hop - 1 - pos) % PREPARE_EVERY == 0


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
        self.cues = self.fusion = None
        if self.params.fuse:
            from laughlab.detector.fuse import FrameCues, Fusion

            try:
                self.fusion = Fusion.load(self.params.fuse_file)
            except ModelFileError as exc:
                raise ValueError(str(exc)) from None
            self.cues = FrameCues(self.ctx.sample_rate, self.ctx.fps)
        self.window = Window16k(self.ctx.sample_rate)
        self.hop = max(1, int(round(self.params.hop_s * self.ctx.fps)))
        # a window's network is spread over model_frames frames, or over all the frames until the next window
        # when windows come more often (below 14 fps at hop_s = 0.25 s); before 2026-11-26 that was an error,
        # which the default configuration met at 10 fps
        self.frames = min(self.params.model_frames, self.hop)
        if self.params.async_frames == 0:
            self.model.load_parts(self.frames)
        self.ahead = None    # the prefetching helper of an offline input (``prefetch``)
        self.use_head = self.params.rule in ("head", "either")
        self.use_classes = self.params.rule in ("classes", "either")
        self.reset()

    def reset(self) -> None:
        self.window.reset()
        if self.cues is not None:
            self.cues.reset()
        self.k = 0
        self.p = 0.0
        self.q = 0.0        # the laughter classes' score of the newest window
        self.vetoed = False  # the newest window hears another human sound (a cough, a scream...) more than laughter
        self.noise = False   # the newest window hears steady noise (white noise, hiss...) more than laughter
        self.run = 0        # windows in a row at or above open_at
        self.qrun = 0       # windows in a row at or above class_open
        self.open = False
        self.below_s = 0.0
        self.clip_gain = 0.0
        self.face_gain = 0.0
        self.quiet = math.inf
        self.pending = None  # time of the new sound the face follows before the model has heard it
        self.answer = None   # the face's answer to that sound: "provisional", then "confirmed" or taken back (None)
        self.taken_back = False   # this frame a window took the provisional answer back (face_retract)
        self.job = None      # [window end time, next part, network state or ("ahead", samples), cues]: a window in progress
        self.raw = []        # the input's blocks since the last window, while a helper converts them (``prefetch``)
        self._drain()        # self.queue: (frame the scores take effect, window end time, future of its scores, cues)
        self._stop_ahead()

    def _drain(self) -> None:
        """Wait for windows still in the helper thread (a reset or the end of a run)."""
        for _, _, fut, _ in getattr(self, "queue", []):
            fut.result()
        self.queue = []

    def _stop_ahead(self) -> None:
        if getattr(self, "ahead", None) is not None:
            self.ahead.close()
        self.ahead = None

    def close(self) -> None:
        self._drain()
        self._stop_ahead()

    def prefetch(self, blocks) -> None:
        """Offline input: ``blocks()`` gives the run's blocks again, from the start; a helper thread reads
        them ahead and runs the model on the windows to come (``prefetch``; called after ``reset``)."""
        self._stop_ahead()
        if self.params.prefetch and self.params.async_frames == 0:
            self.ahead = Ahead(blocks, self.ctx.sample_rate, self.hop)

    def _run_job(self) -> None:
        """This frame's share of the window in progress (``self.job``: window end time, the frame's number in
        the window's ``model_frames``, network state or ``("ahead", input samples since the window before)``);
        the last frame takes effect."""
        t_end, g, x, cues = self.job
        n = self.frames
        last = g + 1 == n
        if isinstance(x, tuple):      # the helper's scores, checked against the input, on the last frame
            if not last:
                self.job = [t_end, g + 1, x, cues]
                return
            scores = self.ahead.scores(x[1])
            if scores is None:        # the helper read other samples (or stopped): the frame thread takes over
                scores = self._take_over(x[1])
            self.job = None
            self._take(scores, t_end, cues)
            return
        x = self.model.part(g, x, n)
        if last:
            self.job = None
            self._take(x[0].astype(np.float64), t_end, cues)
        else:
            self.job = [t_end, g + 1, x, cues]

    def _take_over(self, raw: np.ndarray) -> np.ndarray:
        """The helper's samples differ from the input's (or it stopped): the stream is taken up from the
        conversion's state where the helper last agreed, the window of ``raw`` (the input's samples since
        then) computed here, and from now on every block converted here, as without a helper."""
        self.window.restore(self.ahead.state)
        self._stop_ahead()
        self.window.push(raw)
        scores = self.model.network(self.window.patch(self.model))[0]
        for b in self.raw:            # the blocks since this window's frame
            self.window.push(b)
        self.raw = []
        return scores

    def _take(self, scores, t_end: float, cues=None) -> None:
        """A window's scores take effect (on its own frame, or ``async_frames`` later); ``cues``: the feature
        MLP's (features, probability) at the window's frame when ``fuse``."""
        p = self.params
        self.p, self.q = self.score.both(scores)
        if cues is not None:
            from laughlab.detector.fuse import inputs

            self.p = float(self.fusion.prob(inputs(self.q, self.p, cues[1], cues[0]))[0])
        self.vetoed = p.veto != "none" and self.score.other_human(scores) > self.q
        # steady noise louder than laughter: the head's probability does not count (noise_veto)
        self.noise = noise_vetoes(self.score.noise(scores), self.q, p.noise_veto)
        self.run = self.run + 1 if self.p >= p.open_at and not self._head_vetoed() else 0
        self.qrun = self.qrun + 1 if self.q >= p.class_open and not self.vetoed else 0
        if (self.pending is not None and t_end - self.pending >= p.decide_s - 1e-9
                and not self._reaches(p.close_below, p.class_close)):
            self.pending = None   # the window keeps no gain open: the face's provisional answer ends
            if self.answer == "provisional":   # ... and what it built is taken back (laughlab.face.provisional)
                self.answer, self.taken_back = None, True

    def _reaches(self, head_at: float, class_at: float) -> bool:
        """Does the newest window's score reach ``head_at`` (the head) or ``class_at`` (the laughter classes),
        counting the scores the rule uses?  A score the ``veto`` covers does not count in a window where another
        human sound outscores laughter."""
        return ((self.use_head and self.p >= head_at and not self._head_vetoed())
                or (self.use_classes and self.q >= class_at and not self.vetoed))

    def _head_vetoed(self) -> bool:
        """The newest window's head probability does not count: another human sound outscores laughter under
        ``veto=both``, or steady noise does (``noise_veto``)."""
        return (self.vetoed and self.params.veto == "both") or self.noise

    def _ramp(self, g: float, up: bool, dt: float) -> float:
        p = self.params
        if up:
            return 1.0 if p.attack_s <= 0 else min(1.0, g + dt / p.attack_s)
        return 0.0 if p.release_s <= 0 else max(0.0, g - dt / p.release_s)

    def step(self, block, frame) -> None:
        p, dt = self.params, frame.dt
        if self.ahead is None:
            self.window.push(block)
        else:                         # the helper converts the input: keep its samples to check the helper's
            self.raw.append(np.array(block, dtype=np.float64).ravel())
        if self.cues is not None:
            self.cues.push(block)
        t_end = (self.k + 1) * dt  # the block's end: the newest sample the window holds
        c = frame.control
        mcs = float(c.get("mcs", 0.0))
        if mcs >= p.onset_mcs:
            if self.quiet >= p.quiet_s and p.decide_s > 0:
                self.pending = t_end
                self.answer = "provisional"
            self.quiet = 0.0
        else:
            self.quiet += dt
        if (self.k + 1) % self.hop == 0:
            cues = self.cues.now() if self.cues is not None else None
            if p.async_frames:
                self.queue.append((self.k + p.async_frames, t_end,
                                   helper().submit(self.model.network, self.window.patch(self.model)), cues))
            elif self.ahead is not None:
                raw = np.concatenate(self.raw) if self.raw else np.zeros(0)
                self.raw = []
                self.job = [t_end, 0, ("ahead", raw), cues]
            else:
                self.job = [t_end, 0, self.window.patch(self.model), cues]
        if self.job is not None:
            self._run_job()
        elif self.ahead is None and prepare_now((self.k + 1) % self.hop, self.hop):
            self.window.prepare(self.model)   # between windows: convert the audio, compute complete rows
        while self.queue and self.queue[0][0] == self.k:
            _, t_win, fut, cues = self.queue.pop(0)
            self._take(fut.result()[0], t_win, cues)
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
        sure = self.open or (sound and self._reaches(p.open_at, p.class_open))
        if sure and self.answer == "provisional":
            self.answer = "confirmed"
        self.face_gain = self._ramp(self.face_gain, sure or self.pending is not None, dt)
        face = max(self.face_gain, self.clip_gain)
        c["laughter"] = self.p
        c["laughter_classes"] = self.q
        c["laugh_gate"] = self.clip_gain
        c["face_gate"] = face
        c["face_provisional"] = 1.0 if self.answer == "provisional" else 0.0
        c["face_retract"] = 1.0 if self.taken_back else 0.0
        self.taken_back = False
        apply_gate(frame, face)
        c["clip_gate"] = self.clip_gain


@hookimpl
def register_detectors(register):
    register(YamnetDetector)
