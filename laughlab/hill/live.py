"""Real-time audio-driven control of the Hill torso: per-call fitting, each call played from an earlier call's fit.

The paper fits a whole recording offline, call by call (DiLorenzo, Zordan &
Sanders 2008, 6.2; :func:`laughlab.hill.fit.fit`).  Live, a call's sound is
only known once it has been heard, so :class:`LiveFitter` plays each call
from the fit of an earlier call:

1. :class:`CallTracker` cuts the streaming target pressure (cm H2O, one value
   a frame) into calls causally: a call begins on the first frame above
   ``onset_cmh2o``; it ends on the first frame at or below ``end_fraction`` of
   its peak (that frame included), or at a valley (a local minimum below
   ``valley_fraction`` of the peak, confirmed by the next frame's rise, which
   begins the next call), or after ``max_call_s``.
2. At a call's onset the driver starts the *template*, the seven parameters
   (:data:`laughlab.hill.fit.PARAMS`) fitted to an earlier call (step 3), timed from
   the onset (starts are relative to the call, never before it), its three
   amplitudes scaled by ``sqrt(peak so far / template's peak)``, updated every
   frame until the call ends (pressure goes as the square of the flow, ``P = k
   Q^2``, the flow as the activation).  Before the first fit the template is
   :data:`FIRST_TEMPLATE`.  The abdomen's step (its hold, ``x[0]``, which each
   call adds to) is played only while the torso's own pressure in the last call
   stayed at or below that call's target peak (our feedback, since
   2026-11-29: the template's step, added call after call whatever the state,
   ratcheted the abdomen up to saturation and the pressure to 5-8 times the
   target's; the offline fit chooses each step knowing the state).
3. A call whose peak is under ``fit.quiet_frac`` (5%) of the highest call peak so
   far is counted (``quiet``) and not fitted, as the offline fit leaves quiet
   calls undriven (the causal counterpart of its 99th percentile of the whole
   target: a three-frame ripple of 0.007 cm H2O fitted with activations of 0.6
   became the template and drove the next calls at twice the template's scale).
   When any other call ends, its frames are fitted (:class:`laughlab.hill.fit.CallProblem`,
   the offline fit's cost, optimiser and primitives) from the torso's state at
   the call's onset, on top of what the earlier calls play; the result becomes
   the template of the first call that starts at least ``adopt_after_s`` (0.25 s)
   after the call ended, unless its error is 1 or more (no better than holding
   still).  Within a bout the next call usually starts a few frames after the
   last ends, so a call plays the fit of the call before the last (our
   departure from "the previous call": it leaves the fit 0.25 s to finish
   in a thread, and fixes which fit plays by frame numbers alone).
   The held abdominal activations are let go as in
   the offline fit (:func:`laughlab.hill.fit.release`): from the first frame
   that starts ``release_after_s`` after the last call's end with no call begun.
   The first call of a bout plays :data:`FIRST_TEMPLATE` again (the torso is
   relaxed; a fit from deep in the last bout, where the muscles fought the
   chest wall's recoil, asked for far too much: the abdomen saturated and
   ruined the next bout).

Look-behind: the activations of call ``n`` come from the fit of a call that
ended at least ``adopt_after_s`` before call ``n`` began, and call ``n``'s own
onset and peak so far; nothing later is used.  Fitting runs either in the frame
where the call ends (``threaded: no``, the default for files) or in a
background thread (``threaded: yes``, the default for live input and in a ``Session``: frames keep
coming at their rate).  Which fit a call plays is fixed by frame numbers, not
by when the thread finishes (a fit not finished when due holds that frame
until it is), so both give the same bytes and a microphone session replays
offline exactly.  A fit takes about 0.05 s of one core per 0.2 s call with the
compiled torso step (``benchmarks/bench_hill.py``).  ``adopt_after_s: 0`` is
the behaviour before 2026-11-28 (each call from the previous call's fit: error
mean 0.57 against 0.62, median 0.44 against 0.45, on bench_hill's
synthetic corpus), right for files, but
live it holds each call's first frame for the whole fit.
"""
from __future__ import annotations

import collections
import math
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from laughlab.hill.fit import CallProblem, FitParams, call_span, optimise, play, with_secondary
from laughlab.core.plugins import check_range

#: how many of the latest fits a live fitter keeps (``LiveFitter.fits``): about 25 minutes of laughter's calls
FITS_KEPT = 4096

#: the template before any call has been fitted (physical, ``PARAMS``) and the call peak it was made for (cm H2O):
#: a typical fit of a call of average height (0.1 cm H2O) at the start of a bout of the synthetic corpus
FIRST_TEMPLATE = (np.array([0.03, 0.03, 0.0, 0.0, 7.0, 0.0, 7.0]), 0.1)


def _fit_defaults() -> FitParams:
    return FitParams(max_evals=400, polish_evals=100, sigma0=0.2)


@dataclass
class LiveParams:
    """Live per-call fitting (``control=fit`` of the ``hill`` body).

    Attributes
    ----------
    onset_cmh2o : float
        A call begins on the first frame whose target pressure exceeds this (cm H2O).
    end_fraction : float
        A call ends on the first frame at or below this share of its peak.
    valley_fraction : float
        ... or at a local minimum below this share of its peak (the next call then begins).
    max_call_s : float
        ... or after this long (s).
    min_scale, max_scale : float
        Bounds of the template's amplitude scale.
    max_step : float
        Largest abdominal hold a call may add when played from a template (activation; the
        offline fits of the synthetic corpus add 0.01-0.06 a call): one poor fit cannot lock the abdomen.
    threaded : str
        ``auto`` (a background thread for live input and in a ``laughlab.Session``, in the frame otherwise), ``yes``
        or ``no``.
    adopt_after_s : float
        A call's fit becomes the template of the first call starting at least this long after it ended (s).
    hold_feedback : bool
        Add the template's abdominal step to the hold only after a call whose played pressure stayed at or below
        its target's peak (module notes, step 2); ``False``: every call, the rule before 2026-11-29.
    fit : FitParams
        The per-call fit (:class:`laughlab.hill.fit.FitParams`); by default 400 + 100 evaluations.
    """

    onset_cmh2o: float = 0.005
    end_fraction: float = 0.15
    valley_fraction: float = 0.6
    max_call_s: float = 0.6
    min_scale: float = 0.25
    max_scale: float = 2.0
    max_step: float = 0.1
    threaded: str = "auto"
    adopt_after_s: float = 0.25
    hold_feedback: bool = True
    fit: FitParams = field(default_factory=_fit_defaults)

    def __post_init__(self) -> None:
        check_range("onset_cmh2o", self.onset_cmh2o, 0, lo_open=True)
        check_range("end_fraction", self.end_fraction, 0, 1)
        check_range("valley_fraction", self.valley_fraction, 0, 1)
        check_range("max_call_s", self.max_call_s, 0, lo_open=True)
        check_range("min_scale", self.min_scale, 0, lo_open=True)
        check_range("adopt_after_s", self.adopt_after_s, 0)
        if not self.max_scale >= self.min_scale:
            raise ValueError(f"max_scale must be >= min_scale (got {self.max_scale} < {self.min_scale})")
        if self.threaded not in ("auto", "yes", "no"):
            raise ValueError(f"threaded must be auto, yes or no (got {self.threaded!r})")
        if isinstance(self.fit, dict):
            self.fit = FitParams(**self.fit)


class CallTracker:
    """Causal call segmentation of a pressure stream (module notes, step 1).

    :meth:`update` takes frame ``k``'s value and returns the events it
    completes, in order: ``("end", start, end, peak)`` (frames ``[start, end)``)
    and ``("start", k)``.
    """

    def __init__(self, params: LiveParams, fps: float):
        self.p = params
        self.max_frames = max(1, int(round(params.max_call_s * fps)))
        self.active = False
        self.start = self.peak_k = 0
        self.peak = 0.0
        self.prev = 0.0

    def update(self, k: int, v: float) -> list:
        p, ev = self.p, []
        v = float(v) if np.isfinite(v) else 0.0
        if self.active:
            if v > self.peak:
                self.peak, self.peak_k = v, k
            if v <= p.end_fraction * self.peak:
                ev.append(("end", self.start, k + 1, self.peak))
                self.active = False
            elif (v > self.prev and self.prev <= p.valley_fraction * self.peak and self.peak_k < k - 1):
                ev.append(("end", self.start, k, self.peak))       # the valley was frame k - 1
                self.active = False
            elif k + 1 - self.start >= self.max_frames:
                ev.append(("end", self.start, k + 1, self.peak))
                self.active = False
        if not self.active and v > p.onset_cmh2o and not (ev and ev[-1][2] == k + 1):
            self.active, self.start, self.peak, self.peak_k = True, k, v, k
            ev.append(("start", k))
        self.prev = v
        return ev


@dataclass
class _Entry:
    """A call as played: physical parameters, start (s), release time (s; None: held)."""

    x: np.ndarray
    t_call: float
    t_release: float | None = None


class LiveFitter:
    """Per-frame activations of the torso from a pressure stream (module notes)."""

    def __init__(self, params: LiveParams, fps: float, torso_params, live: bool = False):
        self.p = params
        self.fps = float(fps)
        self.torso_params = torso_params
        self.threaded = params.threaded == "yes" or (params.threaded == "auto" and live)
        self._pool = ThreadPoolExecutor(max_workers=1) if self.threaded else None
        self.delay = int(math.ceil(params.adopt_after_s * self.fps - 1e-9))
        self.reset()

    def reset(self) -> None:
        self.tracker = CallTracker(self.p, self.fps)
        self.entries: list[_Entry] = []
        self.template = (FIRST_TEMPLATE[0].copy(), FIRST_TEMPLATE[1])
        self.current = None          # (entry, torso state at the call's start)
        self.buffer: list[float] = []
        self.last_end_s = None
        self.bout_start_s = 0.0      # fits of calls before the current bout's let-go are not templates
        self.pending: list = []     # (frame due, fit: a future or its record), oldest first
        # one record per fitted call (frames, x, error, evals, seconds), the latest FITS_KEPT: a soak review found the
        # list of every one grew 6 MB an hour of laughter for ever; ``fitted`` counts them all
        self.fits: collections.deque = collections.deque(maxlen=FITS_KEPT)
        self.fitted = 0
        # frames held for a fit due and unfinished (threaded): how long (s), the latest FITS_KEPT; all counted
        self.waits: collections.deque = collections.deque(maxlen=FITS_KEPT)
        self.held, self.held_max_s = 0, 0.0
        self.loudest = 0.0           # the highest call peak so far (cm H2O): quiet calls are below quiet_frac of it
        self.quiet = 0               # quiet calls, not fitted
        self.played_peak = 0.0       # the torso's highest pressure in the current call (cm H2O)
        self.overshoot = False       # the last call's played pressure rose above its target's peak

    # -- fitting
    def _scaled(self, peak: float) -> np.ndarray:
        x, peak_t = self.template
        s = math.sqrt(max(peak, 0.0) / peak_t) if peak_t > 0 else 1.0
        s = min(self.p.max_scale, max(self.p.min_scale, s))
        out = x.copy()
        out[:3] *= s
        out[0] = min(out[0], self.p.max_step)
        if self.overshoot and self.p.hold_feedback:   # the last call played above its target: no more hold (step 2)
            out[0] = 0.0
        return out

    def _fit(self, target, start: int, state, entries: list, u_start) -> dict:
        fp = self.p.fit

        def base(times):
            return play(times, ((e.x, e.t_call, e.t_release) for e in entries), fp.release_s)

        t0 = time.perf_counter()
        problem = CallProblem(np.asarray(target, dtype=float), start / self.fps, self.fps, base, state,
                              self.torso_params, fp)
        if problem.norm > 0:
            u, _ = optimise(problem, problem.to_unit(u_start), fp)
            x = problem.to_physical(u)
            err = float(problem.history_error[-1]) if problem.history_error else float("nan")
        else:
            x, err = np.zeros(7), float("nan")
        return {"start": start, "end": start + len(target), "x": x, "peak": float(np.max(target)) if len(target) else 0.0,
                "error": err, "evals": problem.evals, "seconds": time.perf_counter() - t0}

    def _submit(self, args) -> Future:
        """The fit in the thread; in this one, the same fit, once the thread has stopped at the interpreter's exit
        (an unclosed ``Session`` finishing its run there: Python's exit stops the thread first)."""
        try:
            return self._pool.submit(self._fit, *args)
        except RuntimeError:   # "cannot schedule new futures after (interpreter) shutdown"
            done = Future()
            done.set_result(self._fit(*args))
            return done

    def _adopt(self, rec: dict) -> None:
        self.fits.append(rec)
        self.fitted += 1
        if (rec["peak"] > 0 and rec["x"][:3].sum() > 0 and rec["end"] / self.fps >= self.bout_start_s
                and rec["error"] < 1.0):       # a fit no better than holding still teaches nothing
            self.template = (rec["x"], rec["peak"])

    def _collect(self, k: int | None = None) -> None:
        """Adopt the fits due by frame ``k`` (all with ``None``), waiting for any still running (each wait counted
        in ``waits``, s: the machine fits more slowly than ``adopt_after_s``)."""
        while self.pending and (k is None or self.pending[0][0] <= k):
            _, fit = self.pending.pop(0)
            if self._pool is not None and k is not None and not fit.done():
                t0 = time.perf_counter()
                fit.result()
                w = time.perf_counter() - t0
                self.waits.append(w)
                self.held, self.held_max_s = self.held + 1, max(self.held_max_s, w)
            self._adopt(fit.result() if self._pool is not None else fit)

    def close(self) -> None:
        """Wait for a fit in progress and stop the thread (also when the fit failed: its error is raised after; a
        diff review found the thread left running)."""
        try:
            self._collect()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)

    # -- per frame
    def update(self, k: int, pressure: float, torso) -> None:
        """Take frame ``k``'s target pressure (cm H2O); ``torso`` (:class:`laughlab.hill.torso.Torso`) is at the
        frame's start, and its state is kept when a call begins."""
        v = float(pressure) if np.isfinite(pressure) else 0.0
        if self.current is not None:
            self.buffer.append(v)
            self.played_peak = max(self.played_peak, float(torso.lung.gauge_cmh2o[0]))
        for ev in self.tracker.update(k, v):
            if ev[0] == "end":
                entry, state = self.current
                _, s, e, peak = ev
                entry.x = self._scaled(peak)
                self.loudest = max(self.loudest, peak)
                self.overshoot = self.played_peak > peak
                self.played_peak = 0.0
                if peak >= self.p.fit.quiet_frac * self.loudest:
                    earlier = [x for x in self.entries if x is not entry]
                    args = (self.buffer[:e - s], s, state, [_Entry(x.x.copy(), x.t_call, x.t_release) for x in earlier],
                            self.template[0])
                    self.pending.append((k + self.delay, self._submit(args) if self.threaded else self._fit(*args)))
                else:   # a quiet call: counted, not fitted (module notes, step 3)
                    self.quiet += 1
                self.current, self.buffer = None, []
                self.last_end_s = e / self.fps
            else:
                self._collect(k)
                entry = _Entry(self._scaled(v), k / self.fps)
                self.entries.append(entry)
                self.current = (entry, torso.get_state(0))
                self.buffer = [v]
        if self.current is not None:
            self.current[0].x = self._scaled(self.tracker.peak)
        elif self.last_end_s is not None:
            t_rel = self.last_end_s + self.p.fit.release_after_s
            if k / self.fps >= t_rel - 1e-9:
                for e in self.entries:
                    if e.t_release is None:
                        e.t_release = k / self.fps
                self.last_end_s = None
                self.bout_start_s = k / self.fps       # later fits of this bout's calls are not adopted
                self.template = (FIRST_TEMPLATE[0].copy(), FIRST_TEMPLATE[1])   # a new bout starts relaxed
        # forget calls that play no more
        rel, now = self.p.fit.release_s, k / self.fps
        self.entries = [e for e in self.entries if call_span(e.x, e.t_call, e.t_release, rel)[1] >= now]

    def schedule(self, times):
        """``(activations (n, 6) in [0, 1] with the clavicle elevators, spine target rad (n,))``, as the offline fit's."""
        fp = self.p.fit
        return with_secondary(play(times, ((e.x, e.t_call, e.t_release) for e in self.entries), fp.release_s), fp)
