"""Scheduler ``concat``: full-body motion by segment concatenation (Ding et al. 2014, 4.2).

Ding et al. synthesise head and eyebrow motion by concatenating recorded motion
segments, one per pseudo-phoneme, chosen to minimise a duration cost plus a
continuity cost (Eqs. 4-8), stretched linearly to the phoneme's duration and
smoothed linearly at the joins.  Here the same method drives the whole body:
the segments are pieces of the clip library, cut and labelled by pseudo-phoneme
class in :mod:`laughlab.concat.segments`; the costs and the two selection algorithms
are in :mod:`laughlab.concat.costs`.

Labels.  Each frame reads ``frame.label`` (a pseudo-phoneme from the
extractor).  When it is None the scheduler derives a coarse label from the
motion control signal: ``silence`` if ``control['mcs'] < mcs_silence``, else
``vowel`` (0 when there is no ``mcs``).  While a detector holds full-body clips
back (``clip_gate`` below 0.5, ``detector=yamnet`` before the model hears
laughter) every frame is ``held``, whatever the extractor says: the idle pieces
of the ``silence`` class play (``laughlab.concat.segments.HELD``), so talk is
not concatenated into laughter, nor answered by a laugh clip's pause.  A new pseudo-phoneme starts whenever
the label differs from the previous frame's.

Silence is a pseudo-phoneme too.  Ding et al.'s input is the whole pseudo-phoneme
sequence, pauses included (e.g. ``[a, silence, nasal]``; silence is the most frequent of
the 14 classes in their corpus, 729 occurrences), and a segment is concatenated for every
pseudo-phoneme in it.  So the scheduler plays segments from the first frame on, before the
first laugh and between bouts: the ``silence`` class's segments, the library's slowest
pieces (most of them cut from ``idle``).  A run's ``events.csv`` and Fig. 4.2 therefore show
segments from t = 0 on, and many short ones (each call and pause is its own
pseudo-phoneme); this is the method, not a fault.

``mode: greedy`` (default, real time; the paper's "simplified version").  At the
first frame of a pseudo-phoneme its duration is not known yet, so the target
duration d(p) is *predicted*: the running mean duration of the class so far,
initialised with the mean duration of the class's segments in the database (as
one observation).  The segment with the lowest local cost
``gamma C_dur(d(s), d(p)) + (1 - gamma) C_cont(previous segment, s)`` starts,
with speed ``d(s) / d(p)`` clipped to ``[speed_min, speed_max]``.

``mode: optimal`` (offline only: its look-ahead is the whole input).  Call
:meth:`ConcatScheduler.plan` with the labels of every frame before the first
``step``: it computes the exact minimum of Eq. 4 over the pseudo-phonemes with
their true durations (dynamic programming), and ``step`` then plays that plan
(stepping without a plan is an error).  A live run cannot use it.

In both modes:

* at a pseudo-phoneme change the playing segment stops (``reason='next'``) and
  the chosen one starts in the same frame, ``ClipEvent(offset_s=start of the
  segment, end_s=its end, speed, blend_s)``; the mixer blends linearly from the
  pose shown to the new segment over ``blend_s`` (the paper's linear smoothing
  at the joins);
* a segment stretched no slower than ``speed_min`` may end before its
  pseudo-phoneme; then it stops (``reason='finished'``) and another segment of
  the same class is chained by the local cost, with target the time left of
  the pseudo-phoneme (optimal) or, in greedy mode, the larger of the predicted
  duration and the time the pseudo-phoneme has lasted so far (a pause that has
  lasted 2 s is likely a long one: without this a long silence would loop one
  short segment); a segment played no faster than ``speed_max`` is cut at the
  next change.

Channels written every frame:

* ``clip_energy``: the energy of the source clip of the playing segment (0 if none);
* ``energy``: a running intensity kept for compatibility with ``energy``
  (plots, metrics): ``ENERGY_SCALE * mcs`` smoothed by a one-pole low-pass
  with time constant ``ENERGY_TAU_S`` (0.5 s); ENERGY_SCALE = 40 is the largest
  clip energy (rofl), so sustained MCS 1 reads as the most intense clip;
* ``concat_cost``: Eq. 4 of the segments played so far.  Each played segment is
  a unit u, its d(p_u) being the time it has covered in the output (up to the
  end of this frame): ``gamma sum C_dur(d(s_u), covered_u) + (1 - gamma) sum
  C_cont(s_{u-1}, s_u)``.  Without chaining and speed clipping this is Eq. 4 of
  the pseudo-phonemes so far; at the last frame of an ``optimal`` run it is the
  planned minimum.

The scheduler is deterministic (no random numbers; ties go to the lowest segment index).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Scheduler
from laughlab.concat.costs import Concatenation, c_cont, c_dur, choose, label_runs, optimal, stretch
from laughlab.core.errors import LaughlabError
from laughlab.core.frame import ClipEvent
from laughlab.core.plugins import check_range
from laughlab.detector.model import clip_allowed, clip_drive
from laughlab.concat.segments import HELD, PSEUDO_PHONEMES, pose_features, segment_db

ENERGY_SCALE = 40.0
"""Scale of the ``energy`` channel: MCS 1 reads as the energy of rofl, the largest clip energy."""

ENERGY_TAU_S = 0.5
"""Time constant of the one-pole low-pass smoothing the ``energy`` channel (s)."""

MODES = ("greedy", "optimal")

LABELS = (*PSEUDO_PHONEMES, HELD)
"""What a frame may be: a pseudo-phoneme, or ``held`` while a detector holds clips back."""


def _drive(frame) -> float:
    """The mcs that drives clips (0 without one; see ``clip_drive``)."""
    return clip_drive(frame.control) if "mcs" in frame.control else 0.0


@dataclass
class ConcatParams:
    """Parameters of the ``concat`` scheduler (Ding et al. 2014, Eqs. 4-8).

    Attributes
    ----------
    gamma : float
        Weight of the duration cost against the continuity cost, in [0, 1]
        (Eq. 4).  The paper tuned it manually and gives no value; 0.5 weighs
        both alike.
    mode : str
        ``greedy``: real time, segment by segment with predicted durations (the
        paper's real-time variant).  ``optimal``: offline only, the exact
        minimum of Eq. 4 over the whole label sequence given in advance with
        :meth:`ConcatScheduler.plan`.
    blend_s : float
        Linear smoothing at each join: blend from the pose shown to the next
        segment over this time (s).  The paper gives no value.  On 30 s of the
        synthetic laughter (labels from MCS, greedy) the 99th percentile of the
        fastest joint's speed is 590 cm/s with 0.1 s, faster than anything in
        the clips (583 cm/s): the joins snap; 310 cm/s with 0.2 s; 260 cm/s
        with 0.3 s, which blurs the 0.1 s calls.
    speed_min, speed_max : float
        Bounds of the playback speed ``d(s) / d(p)`` (clip seconds per second).
        The paper bounds nothing but notes that stretching is tolerable only for
        small factors; a factor of 2 either way.
    mcs_silence : float
        Without a label, MCS below this is ``silence``, else ``vowel``.
    """

    gamma: float = 0.5
    mode: str = "greedy"
    blend_s: float = 0.2
    speed_min: float = 0.5
    speed_max: float = 2.0
    mcs_silence: float = 0.1

    def __post_init__(self) -> None:
        check_range("gamma", self.gamma, 0, 1)
        if self.mode not in MODES:
            raise ValueError(f"mode must be greedy or optimal (got {self.mode!r})")
        check_range("blend_s", self.blend_s, 0)
        check_range("speed_min", self.speed_min, 0, lo_open=True)
        check_range("mcs_silence", self.mcs_silence, 0, 1)
        if self.speed_max < self.speed_min:
            raise ValueError(f"speed_max must be >= speed_min (got {self.speed_max} < {self.speed_min})")


class ConcatScheduler(Scheduler):
    """Segment concatenation by pseudo-phoneme (Ding et al. 2014, 4.2), greedy or optimal.

    See the module docstring.  Attributes: ``db`` (the
    :class:`~laughlab.concat.segments.SegmentDB` of the context's clip library);
    after each ``step`` ``segment`` (index in ``db`` of the playing segment, or
    None), ``speed`` and ``label``; after :meth:`plan`, ``planned`` (the
    :class:`~laughlab.concat.costs.Concatenation` it computed).
    """

    name = "concat"
    Params = ConcatParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        self.db = segment_db(self.ctx.clips)
        # the pose the first segment joins: the idle clip's, which the character shows before any segment
        # (Ding et al.'s Eq. 8 joins two segments; with no segment before, the first was chosen by its duration
        # alone and a run began mid-gesture, an arm out: a study researcher's review)
        lib = self.ctx.clips
        self._idle = lambda t: pose_features(lib.skeleton, lib.idle.sample_many(np.array([t])))[0]
        self._plan: list | None = None        # [(first frame, n frames, label, segment index)]
        self.planned: Concatenation | None = None
        self.reset()

    def reset(self) -> None:
        db = self.db
        self._mean = {c: db.mean_duration(c) for c in LABELS}   # running mean duration per class
        self._count = dict.fromkeys(LABELS, 1)                     # the DB mean counts as one
        self.label: str | None = None
        self._run_start = 0          # first frame of the current pseudo-phoneme
        self.segment: int | None = None
        self.speed = 1.0
        self._seg_start_t = 0.0      # time the playing segment started (s)
        self._unit_start = 0         # its first frame
        self._cost_closed = 0.0      # Eq. 4 terms fixed so far (all but the playing unit's C_dur)
        self._energy = 0.0
        self._alpha_dt = None
        self._alpha = 0.0
        self._unit = -1              # planned unit playing (optimal mode)

    # ------------------------------------------------------------------ labels and plan
    @property
    def offline_plan(self) -> bool:
        """True in ``mode: optimal``: the pipeline first runs the extractor over the whole
        input, hands every frame's label to :meth:`plan`, then runs as usual."""
        return self.params.mode == "optimal"

    def label_of(self, frame) -> str:
        """The frame's pseudo-phoneme: ``held`` while a detector holds full-body clips back (``clip_allowed``
        false: ``detector=yamnet`` has not yet heard laughter; the idle pieces of the ``silence`` class,
        ``laughlab.concat.segments.HELD``; departure from Ding et al., whose input is always laughter), else
        ``frame.label``, else derived from MCS."""
        if not clip_allowed(frame.control):
            return HELD
        if frame.label is not None:
            return frame.label
        return "silence" if _drive(frame) < self.params.mcs_silence else "vowel"

    def plan(self, labels: Sequence[str]) -> Concatenation:
        """Plan an offline run (``mode: optimal``): the minimum of Eq. 4 over the whole input.

        Parameters
        ----------
        labels : sequence of str
            The pseudo-phoneme of every frame of the run, in order.

        Returns
        -------
        Concatenation
            One segment per pseudo-phoneme (true durations: frames x dt) and the
            minimum cost.
        """
        labels = list(labels)
        bad = [x for x in labels if x not in LABELS]
        if bad:
            raise LaughlabError(f"cannot plan label {bad[0]!r}; choose from: {', '.join(PSEUDO_PHONEMES)}")
        dt = self.ctx.dt
        runs = label_runs(labels)
        self.planned = optimal([(lab, n * dt) for lab, _, n in runs], self.db, self.params.gamma, self._idle(0.0))
        self._plan = [(start, n, lab, i) for (lab, start, n), i in zip(runs, self.planned.indices)]
        self._plan_frames = len(labels)
        self._unit = -1
        return self.planned

    # ------------------------------------------------------------------ per frame
    def step(self, frame) -> None:
        p, db = self.params, self.db
        k, t, dt = frame.index, frame.time_s, frame.dt
        if p.mode == "optimal":
            label, target = self._planned(frame)
        else:
            label = self.label_of(frame)
            if label not in self._mean:
                raise LaughlabError(f"unknown pseudo-phoneme {label!r}; choose from: {', '.join(PSEUDO_PHONEMES)}")
            target = None
        if label != self.label:
            if self.label is not None and p.mode == "greedy":
                self._observe(self.label, (k - self._run_start) * dt)
            self.label, self._run_start = label, k
            if p.mode == "optimal":
                choice = self._plan[self._unit][3]
            else:
                target = self._mean[label]
                joins = self.segment if self.segment is not None else self._idle(t)
                choice = choose(db, label, target, p.gamma, joins)
            self._start(frame, choice, target, "next")
        elif self.segment is not None:
            seg = db[self.segment]
            if seg.start_s + (t - self._seg_start_t) * self.speed >= seg.end_s:  # the mixer's end test
                if p.mode == "optimal":
                    start, n = self._plan[self._unit][:2]
                    target = (start + n - k) * dt
                else:  # it has lasted (k - run start) frames already: expect at least as long again
                    target = max(self._mean[label], (k - self._run_start) * dt)
                self._start(frame, choose(db, label, target, p.gamma, self.segment), target, "finished")
        # channels
        if dt != self._alpha_dt:
            self._alpha_dt, self._alpha = dt, -math.expm1(-dt / ENERGY_TAU_S)
        self._energy += self._alpha * (ENERGY_SCALE * _drive(frame) - self._energy)
        frame.channels["energy"] = self._energy
        frame.channels["clip_energy"] = db[self.segment].energy if self.segment is not None else 0.0
        covered = (k - self._unit_start + 1) * dt
        frame.channels["concat_cost"] = self._cost_closed + p.gamma * c_dur(db[self.segment].duration_s, covered)

    def _planned(self, frame) -> tuple[str, float]:
        """The planned label of this frame and the true duration of its pseudo-phoneme (s)."""
        if self._plan is None:
            raise LaughlabError("scheduler.mode=optimal is offline-only: call plan(labels) with the labels of "
                                "the whole input before the first step, or use mode=greedy")
        k = frame.index
        if k >= self._plan_frames:
            raise LaughlabError(f"frame {k} is beyond the plan ({self._plan_frames} frames)")
        while self._unit + 1 < len(self._plan) and self._plan[self._unit + 1][0] <= k:
            self._unit += 1
        start, n, label, _ = self._plan[self._unit]
        if frame.label is not None and self.label_of(frame) != label:
            raise LaughlabError(f"frame {k} has label {self.label_of(frame)!r} but the plan has {label!r}")
        return label, n * frame.dt

    def _observe(self, label: str, duration_s: float) -> None:
        """Update the running mean duration of ``label`` with a finished pseudo-phoneme."""
        self._count[label] += 1
        self._mean[label] += (duration_s - self._mean[label]) / self._count[label]

    def _start(self, frame, choice: int, target: float, reason: str) -> None:
        """Stop the playing segment (if any) and start segment ``choice`` stretched to ``target`` s."""
        p, db, k, t = self.params, self.db, frame.index, frame.time_s
        seg = db[choice]
        if self.segment is not None:
            old = db[self.segment]
            self._cost_closed += p.gamma * c_dur(old.duration_s, (k - self._unit_start) * frame.dt)
            self._cost_closed += (1.0 - p.gamma) * c_cont(db.last[self.segment], db.first[choice])
            frame.events.append(ClipEvent(t, "stop", old.clip, old.energy, self.speed, reason=reason,
                                          offset_s=old.start_s, end_s=old.end_s))
        else:   # the first segment joins the idle pose shown (as plan's optimal total counts it)
            self._cost_closed += (1.0 - p.gamma) * c_cont(self._idle(t), db.first[choice])
        self.speed = stretch(seg.duration_s, target, p.speed_min, p.speed_max)
        self.segment, self._seg_start_t, self._unit_start = choice, t, k
        frame.events.append(ClipEvent(t, "start", seg.clip, seg.energy, self.speed, blend_s=p.blend_s,
                                      offset_s=seg.start_s, end_s=seg.end_s))


@hookimpl
def register_schedulers(register):
    register(ConcatScheduler)
