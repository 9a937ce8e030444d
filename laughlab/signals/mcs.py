"""Extractor ``rms``: the motion control signal (MCS) of van Duijn 2014 (ch. 3.1, listing 5.2).

Per frame, in the order of the thesis listing (restored: reading notes in docs/papers.md):
amplitude (RMS, Eq. 3.1), running min/max update, mapping to [0, 1], falloff of
min/max, rise/fall limit (Eq. 3.2), store previous, raise to the power 2.

Calibration (3.1.1): "this way of mapping the signal requires a calibration
(short burst of sound in the microphone) at the start of the simulation to set
an initial minimum and maximum amplitude".  The first ``calibration_s`` seconds
of the input are that burst: they set minAmp and maxAmp (the lowest and highest
amplitude heard, no falloff) while the MCS stays 0, then the listing runs from
there and both drift by the falloff (Fig. 3.1).  ``input=mic`` asks for 3 s
(with a level meter on the terminal); files start without one unless
``extractor.calibration_s`` is set.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from laughlab.core.bases import Extractor
from laughlab.core.plugins import check_range
from laughlab.signals.smoothing import THESIS_TICK_HZ, refill, rise_budget


#: the floor of SoundAnalyse's loudness: RMS below 1e-7 counts as 1e-7
LOUDNESS_FLOOR_RMS = 1e-7
#: default maxAmp floor per scale (loudness: RMS 0.003, about -50 dBFS)
DEFAULT_MAX_FLOOR = {"loudness": -25.0, "linear": 0.003}


@dataclass
class RmsParams:
    """Parameters of the ``rms`` extractor (thesis values converted at 60 ticks/s).

    Attributes
    ----------
    scale : str
        Amplitude measure.  ``loudness`` (default): ``10 log10(RMS)`` of
        full-scale samples, floored at RMS 1e-7, which is what SoundAnalyse's
        ``loudness()`` returns, the module the thesis used for ``getAmplitude``
        (5.2); the per-tick falloff of 0.001 is then slow, as Fig. 3.1 asks.
        ``linear``: the RMS itself (Eq. 3.1), full-scale units.
    rise_per_s : float
        Largest rise of the MCS per second (thesis ``ampRise`` 0.4 per tick = 24 /s).  Above 60 fps the
        MCS may rise one tick's step (``rise_per_s / 60``) at once, the budget refilling at ``rise_per_s``
        (``laughlab.signals.smoothing.rise_budget``), so that it answers a call no later than at 60 fps.
    fall_per_s : float
        Largest fall per second (thesis ``ampFall`` 0.2 per tick = 12 /s).
    falloff_per_s : float
        Amount by which maxAmp falls and minAmp rises per second, in amplitude
        units of ``scale`` (thesis ``fallof`` 0.001 per tick = 0.06 /s).
    power : float
        Exponent of the final mapping (thesis: 2).
    min_amp, max_amp : float or None
        Calibrated minimum and maximum amplitude at the start (units of
        ``scale``), as the thesis' calibration burst sets them; None lets the
        first frame set them.
    max_floor : float or None
        maxAmp never falls below this (units of ``scale``; None: -25 for
        loudness, 0.003 for linear).  Departure from the thesis: without it a
        long silence lets the falloff shrink the range to the noise floor,
        which then maps to full-scale MCS.  Likewise minAmp is kept at or below
        maxAmp (ours: the listing lets them cross, and the mapping then inverts).
    calibration_s : float or None
        Length of the calibration phase at the start of the input (3.1.1), in
        seconds; 0 = none; None = what the input asks for (``input=mic``: its
        ``calibration_s``, 3 s; files and the generator: 0).
    """

    scale: str = "loudness"
    rise_per_s: float = 0.4 * THESIS_TICK_HZ
    fall_per_s: float = 0.2 * THESIS_TICK_HZ
    falloff_per_s: float = 0.001 * THESIS_TICK_HZ
    power: float = 2.0
    min_amp: float | None = None
    max_amp: float | None = None
    max_floor: float | None = None
    calibration_s: float | None = None

    def __post_init__(self) -> None:
        if self.scale not in DEFAULT_MAX_FLOOR:
            raise ValueError(f"scale must be loudness or linear (got {self.scale!r})")
        check_range("rise_per_s", self.rise_per_s, 0, lo_open=True)
        check_range("fall_per_s", self.fall_per_s, 0, lo_open=True)
        check_range("falloff_per_s", self.falloff_per_s, 0)
        check_range("power", self.power, 0, lo_open=True)
        if self.calibration_s is not None:
            check_range("calibration_s", self.calibration_s, 0, 600)
        if self.min_amp is not None and self.max_amp is not None and not self.max_amp >= self.min_amp:
            raise ValueError(f"max_amp must be >= min_amp (got {self.max_amp} < {self.min_amp})")

    @property
    def floor(self) -> float:
        return DEFAULT_MAX_FLOOR[self.scale] if self.max_floor is None else self.max_floor


def frame_rms(block: np.ndarray) -> tuple[float, int]:
    """RMS amplitude of one frame of samples (van Duijn 2014, Eq. 3.1), full-scale units.

    ``x_rms = sqrt((x_1^2 + ... + x_n^2) / n)``.  Non-finite samples (NaN, +/-Inf)
    are treated as silence (0) and counted; an empty block has RMS 0.

    Returns
    -------
    rms : float
    n_bad : int
        Number of non-finite samples that were replaced.
    """
    n = block.shape[0]
    if n == 0:
        return 0.0, 0
    x = np.asarray(block, dtype=np.float64)  # float32 squares overflow above 1.8e19; blocks come as float64
    ms = float(np.dot(x, x)) / n
    if math.isfinite(ms):
        return math.sqrt(ms), 0
    bad = ~np.isfinite(x)
    x = np.where(bad, 0.0, x)
    return math.sqrt(float(np.dot(x, x)) / n), int(bad.sum())


class RmsExtractor(Extractor):
    """Motion control signal from RMS amplitude (van Duijn 2014, 3.1 and listing 5.2).

    Writes ``control['rms']`` (full-scale RMS), ``control['amp']`` (the
    amplitude in units of ``scale``), ``control['mcs_raw']`` (the min/max
    mapping in [0, 1], before rise/fall) and ``control['mcs']`` (final MCS in [0, 1]);
    with a calibration phase also ``control['calibrating']`` (1 during it, else 0).
    """

    name = "rms"
    Params = RmsParams
    calibrates = True  # has a calibration phase (thesis 3.1.1): input=mic runs its meter

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p, dt = self.params, self.ctx.dt
        self._rise = p.rise_per_s * dt
        self._cap = rise_budget(p.rise_per_s, dt)   # above 60 fps: one tick's rise at once (smoothing.py)
        self._fall = p.fall_per_s * dt
        self._falloff = p.falloff_per_s * dt
        self._floor = p.floor
        self._loudness = p.scale == "loudness"
        self._power = p.power
        cal_s = self.ctx.calibration_s if p.calibration_s is None else p.calibration_s
        self.ctx.calibration_s = cal_s  # the run's calibration phase: input=mic shows its meter this long
        self._cal_frames = int(round(cal_s * self.ctx.fps))
        self.nonfinite_samples = 0
        self.reset()

    def reset(self) -> None:
        p = self.params
        self.min_amp = math.inf if p.min_amp is None else float(p.min_amp)
        self.max_amp = -math.inf if p.max_amp is None else float(max(p.max_amp, self._floor))
        self.prev = 0.0
        self._left = self._rise if self._cap is None else self._cap
        self.nonfinite_samples = 0
        self._cal_left = self._cal_frames
        self._cal_lo, self._cal_hi = math.inf, -math.inf

    def amplitude(self, rms: float) -> float:
        """The amplitude of ``scale``: ``10 log10(max(rms, 1e-7))`` (SoundAnalyse loudness) or ``rms``."""
        if self._loudness:
            return 10.0 * math.log10(rms if rms > LOUDNESS_FLOOR_RMS else LOUDNESS_FLOOR_RMS)
        return rms

    def calibrate(self, audio: np.ndarray) -> None:
        """Set min/max amplitude from a calibration recording (thesis 3.1.1), as the calibration phase does."""
        n = max(1, int(round(self.ctx.sample_rate / self.ctx.fps)))
        levels = [self.amplitude(frame_rms(audio[i:i + n])[0]) for i in range(0, max(1, len(audio) - n + 1), n)]
        self._cal_lo, self._cal_hi = min(levels), max(levels)
        self._end_calibration()

    def _end_calibration(self) -> None:
        self.min_amp = self._cal_lo
        self.max_amp = max(self._cal_hi, self._floor)
        self._cal_left = 0

    def step(self, block, frame) -> None:
        rms, bad = frame_rms(block)
        if bad:
            self.nonfinite_samples += bad
        if self._loudness:  # self.amplitude(rms), inlined: this runs every frame
            amp = 10.0 * math.log10(rms if rms > LOUDNESS_FLOOR_RMS else LOUDNESS_FLOOR_RMS)
        else:
            amp = rms
        c = frame.control
        c["rms"] = rms
        c["amp"] = amp
        self.step_amplitude(amp, c)

    def step_amplitude(self, amp: float, c: dict) -> None:
        """The frame from its amplitude on, into ``c``: the calibration phase, else one tick of listing 5.2.

        Lines 6-8 (min/max update, mapping), 11-13 (falloff, ours: maxAmp >=
        ``max_floor``, minAmp <= maxAmp), 16-20 (rise/fall, Eq. 3.2), 22 (store
        previous), 25 (``pow(motionSignal, 2)``).
        """
        if self._cal_frames:
            c["calibrating"] = 1.0 if self._cal_left else 0.0
            if self._cal_left:  # the calibration burst (3.1.1): min/max only, the character waits
                self._cal_lo = min(self._cal_lo, amp)
                self._cal_hi = max(self._cal_hi, amp)
                self._cal_left -= 1
                if not self._cal_left:
                    self._end_calibration()
                c["mcs_raw"] = 0.0
                c["mcs"] = 0.0
                return
        hi, lo = self.max_amp, self.min_amp
        if amp > hi:
            hi = amp
        if amp < lo:
            lo = amp
        span = hi - lo
        mapped = (amp - lo) / span if span > 0.0 else 0.0  # max == min is silence
        hi = hi - self._falloff
        if hi < self._floor:
            hi = self._floor
        lo = lo + self._falloff
        if lo > hi:
            lo = hi
        self.max_amp, self.min_amp = hi, lo
        prev = self.prev
        if mapped > prev:
            mcs = min(mapped, prev + self._left)
        else:
            mcs = max(mapped, prev - self._fall)
        if self._cap is not None:   # above 60 fps: the rise budget (laughlab.signals.smoothing.rise_budget)
            self._left = refill(self._left, mcs - prev if mcs > prev else 0.0, self._rise, self._cap)
        self.prev = mcs
        c["mcs_raw"] = mapped
        c["mcs"] = mcs ** self._power

def replay(amps: np.ndarray, params: RmsParams, fps: float) -> dict[str, np.ndarray]:
    """Run the rms extractor from a run's amplitudes (``amp`` channel) again, recording minAmp and maxAmp.

    Returns arrays ``min_amp``, ``max_amp`` (after each frame's update and
    falloff; during a calibration phase the quietest and loudest level so far),
    ``mcs_raw`` and ``mcs``: the same numbers the run computed when ``params``
    are the run's (a test checks), or what other parameters would have given,
    e.g. ``falloff_per_s=0`` for Fig. 3.1's left panel.
    """
    from laughlab.core.bases import Context

    ext = RmsExtractor(params, Context(fps=fps))
    n = len(amps)
    out = {k: np.empty(n) for k in ("min_amp", "max_amp", "mcs_raw", "mcs")}
    c: dict = {}
    for i, a in enumerate(np.asarray(amps, dtype=np.float64).tolist()):
        ext.step_amplitude(a, c)
        calibrating = ext._cal_left > 0
        out["min_amp"][i] = ext._cal_lo if calibrating else ext.min_amp
        out["max_amp"][i] = ext._cal_hi if calibrating else ext.max_amp
        out["mcs_raw"][i], out["mcs"][i] = c["mcs_raw"], c["mcs"]
    return out


def params_of_run(config: dict) -> RmsParams | None:
    """The rms extractor's parameters in a run's composed configuration (``extractor`` or ``extractor.rms``)."""
    ext = (config or {}).get("extractor") or {}
    values = ext if ext.get("name") == "rms" else ext.get("rms")
    if not isinstance(values, dict):
        return None
    return RmsParams(**{k: v for k, v in values.items() if k != "name"})
