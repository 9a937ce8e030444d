"""Seeded synthetic laughter: the built-in default input and ground truth.

Laughter is modelled as *bouts* of voiced 'ha' *calls* separated by silences.
Numbers come from the literature:

* Filippelli et al. (2001), "Respiratory dynamics during laughter",
  J. Appl. Physiol. 90: bout duration 3.7 +/- 2.2 s, call ('ha') rate
  4.6 +/- 1.1 Hz, laughter ending with an inspiration.
* Bachorowski, Smoski & Owren (2001), "The acoustic features of human
  laughter", J. Acoust. Soc. Am. 110: voiced calls of ~0.1 s, high and
  strongly modulated F0 (means ~280 Hz male, ~420 Hz female), breathy 'h'
  onsets, central/open vowel quality (an /a/-like vowel is used here,
  F1 ~ 800 Hz, F2 ~ 1200 Hz, F3 ~ 2500 Hz).

Each call is an aspiration noise onset ('h', 20-50 ms), a voiced part
(60-150 ms; Rosenberg glottal pulses at F0 with a rise-fall contour, shaped by
a cascade of formant resonators) and a decay; weak breath noise fills the gap
to the next call, and some bouts end with a long noisy in-breath.  Between
bouts there is only a -60 dBFS noise floor.

The schedule (bouts and calls) is planned cheaply in the constructor; audio is
synthesised lazily by :meth:`SyntheticLaughter.render`, which only renders the
events overlapping the requested block.  Every event draws its noise from its
own generator seeded from ``(seed, event index)`` and the floor from
``(seed, chunk index)``, so any block partition concatenates to exactly
:meth:`SyntheticLaughter.audio`.

Examples
--------
>>> s = SyntheticLaughter(seed=1, duration_s=20.0)
>>> x = s.audio()                      # float32, mono, [-1, 1]
>>> block = s.render(16000, 1024)      # identical to x[16000:17024]
>>> s.truth_table().head()             # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from numbers import Integral, Real
from os import PathLike
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas and scipy.signal are imported where used (~0.7 s at start-up otherwise)
    import pandas as pd

#: the columns of :meth:`SyntheticLaughter.truth_table` and ``truth.csv``
TRUTH_COLUMNS = ("kind", "bout", "onset_s", "offset_s", "intensity", "f0_hz")

__all__ = ["PROFILES", "Bout", "Call", "SyntheticLaughter"]

PROFILES: tuple[str, ...] = (
    "mixed",
    "mild",
    "intense",
    "intense_fading",
    "continuous",
    "long_silences",
    "giggle",
)

# --- literature constants ----------------------------------------------------
BOUT_DURATION_S = (3.7, 2.2)  # mean, sd (Filippelli 2001)
BOUT_DURATION_RANGE_S = (0.6, 9.0)  # clip range (ours)
CALL_RATE_HZ = (4.6, 1.1)  # mean, sd (Filippelli 2001)
CALL_RATE_RANGE_HZ = (4.0, 7.0)  # truncation range (truncated mean ~5.0 Hz)
VOICED_RANGE_S = (0.06, 0.15)  # voiced part of a call (Bachorowski 2001)
ASPIRATION_RANGE_S = (0.02, 0.05)  # breathy 'h' onset
DECAY_RANGE_S = (0.02, 0.04)
F0_RANGE_HZ = (200.0, 450.0)  # Bachorowski 2001 (male..female laughter F0)
# /a/-like formants (centre, bandwidth) in Hz.
FORMANTS_HZ = ((800.0, 80.0), (1200.0, 90.0), (2500.0, 150.0))
# In-breath: broad noise resonances (centre, bandwidth) in Hz.
INHALE_RESONANCES_HZ = ((1100.0, 500.0), (2700.0, 900.0))
NOISE_FLOOR_DBFS = -60.0  # RMS of the floor
FLOOR_CHUNK = 4096  # samples per independently seeded floor chunk

_ASP_REL = 0.35  # aspiration envelope peak relative to the voiced envelope
_ASP_NOISE_GAIN = 2.0  # aspiration noise level relative to the glottal pulses
_GAP_TRUTH = 0.05  # ground-truth intensity between calls, times bout intensity
_GAP_NOISE_GAIN = 0.015  # breath noise between calls, relative to the pulses
_INHALE_REL = 0.15  # in-breath peak, relative to the bout's peak call
_LOUDNESS_EXP = 0.7  # call peak ~ intensity**0.7 (mildly compressive)
_CACHE_EVENTS = 16  # rendered events kept for blocks that split an event


@dataclass(frozen=True)
class Call:
    """One 'ha' call: times in s, intensity in [0, 1], mean voiced F0 in Hz."""

    onset_s: float
    offset_s: float
    intensity: float
    f0_hz: float
    bout: int


@dataclass(frozen=True)
class Bout:
    """One laughter bout: times in s, peak intensity in [0, 1]."""

    onset_s: float
    offset_s: float
    intensity: float


@dataclass(frozen=True)
class _Profile:
    bout_s: tuple[float, float] = BOUT_DURATION_S
    bout_range_s: tuple[float, float] = BOUT_DURATION_RANGE_S
    pause_range_s: tuple[float, float] = (0.5, 4.0)
    intensity: str = "alternate"  # alternate | mild | intense | fading | any


_PROFILE_SPECS = {
    "mixed": _Profile(),
    "mild": _Profile(intensity="mild"),
    "intense": _Profile(intensity="intense"),
    "intense_fading": _Profile(intensity="fading"),
    "continuous": _Profile(bout_s=(6.5, 1.5), bout_range_s=(3.0, 9.0),
                           pause_range_s=(0.5, 1.0), intensity="any"),
    "long_silences": _Profile(pause_range_s=(4.0, 10.0)),
    "giggle": _Profile(intensity="mild"),  # planned separately
}


def _call_shapes(tau, asp, voiced, decay):
    """Aspiration and voicing amplitude envelopes of a call.

    Parameters
    ----------
    tau : ndarray
        Time since call onset in s.
    asp, voiced, decay : float or ndarray
        Durations in s of the aspiration, voiced and decay parts.

    Returns
    -------
    asp_env, voice_env : ndarray
        Envelopes (voiced peak 1, aspiration peak ``_ASP_REL``), zero outside
        ``[0, asp + voiced + decay)``.
    """
    tau = np.asarray(tau, dtype=float)
    inside = (tau >= 0.0) & (tau < asp + voiced + decay)
    asp_env = _ASP_REL * np.where(tau < asp, tau / asp, np.exp(-(tau - asp) / 0.015))
    tv = tau - asp
    attack = 0.5 - 0.5 * np.cos(np.pi * np.clip(tv / 0.012, 0.0, 1.0))
    sustain = 1.0 - 0.15 * np.clip(tv / voiced, 0.0, 1.0)
    release = (1.0 - np.clip((tv - voiced) / decay, 0.0, 1.0)) ** 2
    voice_env = np.where(tv >= 0.0, attack * sustain * release, 0.0)
    return np.where(inside, asp_env, 0.0), np.where(inside, voice_env, 0.0)


def _resonators(specs, fs):
    """Cascade of Klatt two-pole resonators (unity DC gain) as one (b, a).

    Resonators whose band does not fit below Nyquist are dropped.
    """
    b, a = np.ones(1), np.ones(1)
    for f, bw in specs:
        if f + 2.0 * bw >= fs / 2.0:
            continue
        r = math.exp(-math.pi * bw / fs)
        a_k = np.array([1.0, -2.0 * r * math.cos(2.0 * math.pi * f / fs), r * r])
        b = b * a_k.sum()
        a = np.convolve(a, a_k)
    return b, a


def _rosenberg_derivative(phase, t_open, t_close):
    """Rosenberg glottal flow derivative, peak-normalised to 1.

    Parameters
    ----------
    phase : ndarray
        Cycle phase in [0, 1).
    t_open, t_close : float
        Opening and closing phase durations as fractions of a period.
    """
    opening = np.sin(np.pi * phase / t_open) * (math.pi / (2.0 * t_open))
    pc = (phase - t_open) / t_close
    closing = -np.sin(0.5 * np.pi * pc) * (math.pi / (2.0 * t_close))
    g = np.where(phase < t_open, opening, np.where(pc < 1.0, closing, 0.0))
    return g * (2.0 * t_close / math.pi)


def _truncnorm(rng, mean, sd, lo, hi):
    """One draw of N(mean, sd) truncated to [lo, hi] (rejection)."""
    for _ in range(1000):
        x = rng.normal(mean, sd)
        if lo <= x <= hi:
            return float(x)
    return float(np.clip(mean, lo, hi))


class SyntheticLaughter:
    """Seeded synthetic laughter signal with ground truth.

    Parameters
    ----------
    seed : int
        Non-negative seed; same seed gives byte-identical audio.
    duration_s : float
        Signal duration in s (> 0).
    sample_rate : int
        Sampling rate in Hz (> 0; 8-192 kHz intended).
    profile : str
        One of :data:`PROFILES`.
    level_dbfs : float
        Peak level in dBFS of a call of intensity 1; a call of intensity
        ``i`` peaks at ``level_dbfs + 14 * log10(i)`` dBFS.

    Attributes
    ----------
    bouts : list of Bout
    calls : list of Call
        Sorted by onset; ``Call.bout`` indexes ``bouts``.
    sample_rate : int
        Hz.
    n_samples : int
        ``round(duration_s * sample_rate)``.
    duration_s : float
        s.
    """

    def __init__(self, seed: int = 0, duration_s: float = 30.0, sample_rate: int = 16000,
                 profile: str = "mixed", level_dbfs: float = -12.0):
        import scipy.signal  # noqa: F401 - loaded at construction, not while rendering the first frame
        if profile not in _PROFILE_SPECS:
            raise ValueError(f"unknown profile {profile!r}; valid choices: {', '.join(PROFILES)}")
        if not (isinstance(duration_s, Real) and math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration_s must be a positive finite number of seconds, "
                             f"got {duration_s!r}")
        if not (isinstance(sample_rate, Real) and sample_rate > 0
                and float(sample_rate).is_integer()):
            raise ValueError("sample_rate must be a positive integer in Hz (e.g. 8000-192000), "
                             f"got {sample_rate!r}")
        if not (isinstance(seed, Integral) and seed >= 0):
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        if not (isinstance(level_dbfs, Real) and math.isfinite(level_dbfs)):
            raise ValueError(f"level_dbfs must be finite (dBFS, e.g. -12.0), got {level_dbfs!r}")
        self.seed = int(seed)
        self.duration_s = float(duration_s)
        self.sample_rate = int(sample_rate)
        self.profile = profile
        self.level_dbfs = float(level_dbfs)
        self.n_samples = max(1, int(round(self.duration_s * self.sample_rate)))
        self.bouts: list[Bout] = []
        self.calls: list[Call] = []
        self._plan(np.random.default_rng(self.seed))
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._floor_cache: tuple[int, np.ndarray] | None = None

    # ------------------------------------------------------------------ plan
    def _q(self, t: float) -> float:
        """Quantise a time in s to the sample grid."""
        return round(t * self.sample_rate) / self.sample_rate

    def _plan(self, rng: np.random.Generator) -> None:
        spec = _PROFILE_SPECS[self.profile]
        dur = self.duration_s
        # Speaker: base F0 (Bachorowski 2001: ~280 Hz male .. ~420 Hz female
        # laughter means, reached here at high intensity) and vocal tract scale.
        self._speaker_f0 = rng.uniform(200.0, 300.0)
        vt = rng.uniform(0.95, 1.05)
        fs = self.sample_rate
        b, a = _resonators([(f * vt, bw) for f, bw in FORMANTS_HZ], fs)
        # Mild pre-emphasis (+6 dB/oct above ~1 kHz) stands in for the higher
        # formants omitted from the cascade.
        self._vowel = (np.convolve(b, [1.0, -math.exp(-2.0 * math.pi * 1000.0 / fs)]), a)
        self._breath = _resonators(INHALE_RESONANCES_HZ, fs)

        t = min(rng.uniform(0.3, 1.0), 0.1 * dur)
        end = dur - min(0.2, 0.05 * dur)
        spans: list[tuple[float, float]] = []
        if self.profile == "giggle":
            spans.append((t, end - t))
        else:
            lo, hi = spec.bout_range_s
            while True:
                d = float(np.clip(rng.normal(*spec.bout_s), lo, hi))
                if t + d > end:
                    d = end - t
                    if d < BOUT_DURATION_RANGE_S[0]:
                        break
                spans.append((t, d))
                t += d + rng.uniform(*spec.pause_range_s)

        levels = self._bout_levels(len(spans), spec.intensity, rng)
        # Per-call hidden parameters (s): aspiration, voiced, decay.
        self._asp, self._voiced, self._decay = [], [], []
        self._inhales: list[tuple[float, float, int]] = []  # onset, offset, bout
        for b, ((t0, d), level) in enumerate(zip(spans, levels)):
            self._plan_bout(rng, b, t0, d, float(level))

        self._asp = np.array(self._asp)
        self._voiced = np.array(self._voiced)
        self._decay = np.array(self._decay)
        self._call_on = np.array([c.onset_s for c in self.calls])
        self._call_off = np.array([c.offset_s for c in self.calls])
        self._call_int = np.array([c.intensity for c in self.calls])
        self._bout_on = np.array([b.onset_s for b in self.bouts])
        self._bout_off = np.array([b.offset_s for b in self.bouts])
        self._bout_int = np.array([b.intensity for b in self.bouts])
        self._build_events()

    def _bout_levels(self, n: int, mode: str, rng: np.random.Generator) -> np.ndarray:
        """Bout intensities in [0, 1]: mild ~0.2-0.45, intense ~0.7-1."""
        mild = rng.uniform(0.2, 0.45, n)
        intense = rng.uniform(0.7, 1.0, n)
        if mode == "mild":
            return mild
        if mode == "intense":
            return intense
        if mode == "any":
            return rng.uniform(0.3, 1.0, n)
        if mode == "fading":
            ramp = np.linspace(1.0, 0.2, n) if n > 1 else np.array([0.95])
            return np.sort(np.clip(ramp + rng.uniform(-0.03, 0.03, n), 0.05, 1.0))[::-1]
        first = rng.integers(2)  # alternate: mild/intense/mild... or reverse
        return np.where((np.arange(n) + first) % 2 == 0, mild, intense)

    def _plan_bout(self, rng, b, t0, d, level):
        """Plan the calls (and optional final in-breath) of one bout."""
        giggle = self.profile == "giggle"
        if giggle:
            rate, max_calls = rng.uniform(6.0, 7.0), int(rng.integers(3, 7))
        else:
            rate, max_calls = _truncnorm(rng, *CALL_RATE_HZ, *CALL_RATE_RANGE_HZ), 10**6
        period = 1.0 / rate
        # Laughter ends with an inspiration (Filippelli 2001); audible here in
        # some bouts, more often in intense ones.
        inhale = None
        if not giggle and d >= 1.5 and rng.random() < 0.2 + 0.4 * level:
            gap, length = rng.uniform(0.05, 0.15), rng.uniform(0.3, 0.7)
            inhale = (gap, length)
            limit = t0 + d - gap - length
        else:
            limit = t0 + d
        # Call parts scale with the period so a call fills at most 85 % of it.
        (a_lo, a_hi), (d_lo, d_hi) = ASPIRATION_RANGE_S, DECAY_RANGE_S
        a_hi, d_hi = max(a_lo, min(a_hi, 0.2 * period)), max(d_lo, min(d_hi, 0.15 * period))
        tau, plan = t0, []
        while len(plan) < max_calls:
            asp, dec = rng.uniform(a_lo, a_hi), rng.uniform(d_lo, d_hi)
            voi = float(np.clip(rng.uniform(0.35, 0.5) * period, *VOICED_RANGE_S))
            if giggle:
                voi = min(voi, 0.08)
            length = asp + voi + dec
            if tau + length > limit:
                break
            plan.append((self._q(tau), asp, voi, dec))
            x = (tau - t0) / max(limit - t0, 1e-9)
            # Slight ritardando across the bout, timing jitter.
            step = period * (0.95 + 0.1 * x) * (1.0 + rng.normal(0.0, 0.04))
            tau += max(step, length + 0.015)
        n = len(plan)
        if n == 0:  # only possible for a giggle in a very short clip
            return
        x = np.arange(n) / max(n - 1, 1)
        # Crescendo then decrescendo across the calls of a bout.
        shape = 0.5 + 0.5 * np.sin(np.pi * x ** 0.6)
        ints = np.clip(level * shape * rng.lognormal(0.0, 0.08, n), 0.02, 1.0)
        f0s = self._speaker_f0 * (0.95 + 0.55 * ints) * (1.2 if giggle else 1.0)
        f0s = np.clip(f0s * (1.0 - 0.05 * x) * rng.lognormal(0.0, 0.03, n), *F0_RANGE_HZ)
        for (on, asp, voi, dec), inten, f0 in zip(plan, ints, f0s):
            off = self._q(on + asp + voi + dec)
            self.calls.append(Call(on, off, float(inten), float(f0), b))
            self._asp.append(asp)
            self._voiced.append(voi)
            self._decay.append(off - on - asp - voi)
        end = self.calls[-1].offset_s
        if inhale is not None:
            on = self._q(end + inhale[0])
            end = self._q(on + inhale[1])
            self._inhales.append((on, end, b))
        self.bouts.append(Bout(plan[0][0], end, level))

    def _build_events(self) -> None:
        """Sample extents of the render events: calls (with gap) and in-breaths."""
        fs = self.sample_rate
        ev = []  # (start, stop, kind, ref)
        for i, c in enumerate(self.calls):
            stop = c.offset_s
            if i + 1 < len(self.calls) and self.calls[i + 1].bout == c.bout:
                stop = self.calls[i + 1].onset_s
            ev.append((round(c.onset_s * fs), round(stop * fs), 0, i))
        for k, (on, off, b) in enumerate(self._inhales):
            ev.append((round(on * fs), round(off * fs), 1, k))
        ev.sort()
        arr = np.array(ev, dtype=np.int64).reshape(-1, 4)
        arr[:, 1] = np.minimum(arr[:, 1], self.n_samples)
        self._ev = arr
        self._ev_stop_max = np.maximum.accumulate(arr[:, 1]) if len(arr) else arr[:, 1]

    # ---------------------------------------------------------------- render
    def render(self, start: int, n: int) -> np.ndarray:
        """Render samples ``[start, start + n)``.

        Parameters
        ----------
        start : int
            First sample index (>= 0).
        n : int
            Number of samples (>= 0).

        Returns
        -------
        ndarray of float32, shape (n,)
            Mono samples in [-1, 1]; samples past ``n_samples`` are 0.

        Notes
        -----
        Keeps a small cache of rendered events; not thread-safe.
        """
        start, n = int(start), int(n)
        if start < 0 or n < 0:
            raise ValueError(f"start and n must be >= 0, got start={start}, n={n}")
        out = np.zeros(n, dtype=np.float32)
        stop = min(start + n, self.n_samples)
        if stop <= start:
            return out
        self._floor(out[: stop - start], start)
        lo = int(np.searchsorted(self._ev_stop_max, start, side="right"))
        hi = int(np.searchsorted(self._ev[:, 0], stop, side="left"))
        for j in range(lo, hi):
            e0, e1 = int(self._ev[j, 0]), int(self._ev[j, 1])
            a, b = max(e0, start), min(e1, stop)
            if a < b:
                out[a - start: b - start] += self._event(j)[a - e0: b - e0]
        np.clip(out, -1.0, 1.0, out=out)
        return out

    def audio(self) -> np.ndarray:
        """Whole signal, float32, identical to ``render(0, n_samples)``."""
        return self.render(0, self.n_samples)

    def _floor(self, out: np.ndarray, start: int) -> None:
        """Write the noise floor (-60 dBFS RMS) into ``out`` from sample ``start``.

        Each chunk of ``FLOOR_CHUNK`` samples has its own generator seeded from
        ``(seed, chunk index)``, so the floor does not depend on the blocking.
        """
        amp = np.float32(10.0 ** (NOISE_FLOOR_DBFS / 20.0))
        stop = start + len(out)
        for c in range(start // FLOOR_CHUNK, (stop - 1) // FLOOR_CHUNK + 1):
            if self._floor_cache is not None and self._floor_cache[0] == c:
                chunk = self._floor_cache[1]
            else:
                rng = np.random.default_rng([self.seed, 1, c])
                chunk = rng.standard_normal(FLOOR_CHUNK, dtype=np.float32) * amp
                self._floor_cache = (c, chunk)
            c0 = c * FLOOR_CHUNK
            a, b = max(c0, start), min(c0 + FLOOR_CHUNK, stop)
            out[a - start: b - start] = chunk[a - c0: b - c0]

    def _event(self, j: int) -> np.ndarray:
        """Rendered samples of event ``j`` (cached; never mutate)."""
        if j in self._cache:
            self._cache.move_to_end(j)
            return self._cache[j]
        start, stop, kind, ref = (int(v) for v in self._ev[j])
        rng = np.random.default_rng([self.seed, 0, j])
        if kind == 0:
            y = self._render_call(ref, stop - start, rng)
        else:
            y = self._render_inhale(ref, stop - start, rng)
        self._cache[j] = y
        if len(self._cache) > _CACHE_EVENTS:
            self._cache.popitem(last=False)
        return y

    def _render_call(self, i: int, n: int, rng: np.random.Generator) -> np.ndarray:
        """One call plus the breath-noise gap up to the next call, ``n`` samples."""
        fs = self.sample_rate
        c = self.calls[i]
        asp, voi, dec = self._asp[i], self._voiced[i], self._decay[i]
        n_call = min(n, int(round((c.offset_s - c.onset_s) * fs)))
        tau = np.arange(n_call) / fs
        asp_env, voice_env = _call_shapes(tau, asp, voi, dec)
        noise = rng.standard_normal(n)
        src = np.empty(n)
        src[:n_call] = _ASP_NOISE_GAIN * asp_env * noise[:n_call]
        # Voiced part: rise-fall F0 contour whose mean over the voiced part is
        # c.f0_hz; Rosenberg pulses plus some breathiness.
        v0 = min(n_call, int(asp * fs))
        tv = tau[v0:]
        depth = rng.uniform(0.1, 0.25)
        u = np.clip((tv - asp) / voi, 0.0, 1.0)
        f0 = c.f0_hz * (1.0 + depth * (np.sin(np.pi * u) - 2.0 / np.pi))
        phase = np.cumsum(f0 / fs) + rng.uniform(0.0, 0.1)
        # Intense calls: faster glottal closure -> flatter spectral tilt.
        glottal = _rosenberg_derivative(phase % 1.0, 0.4, 0.28 - 0.14 * c.intensity)
        breathy = rng.uniform(0.05, 0.15)
        src[v0:n_call] += voice_env[v0:] * (glottal + breathy * noise[v0:n_call])
        # Weak breath noise in the gap up to the next call of the bout.
        g = n - n_call
        src[n_call:] = _GAP_NOISE_GAIN * np.sin(np.pi * np.arange(g) / g) * noise[n_call:]
        from scipy.signal import lfilter

        y = lfilter(self._vowel[0], self._vowel[1], src)
        peak = np.max(np.abs(y[:max(n_call, 1)]))
        gain = 10.0 ** (self.level_dbfs / 20.0) * c.intensity ** _LOUDNESS_EXP
        y *= gain / max(peak, 1e-12)
        fade = min(n, max(1, int(0.002 * fs)))
        y[n - fade:] *= np.linspace(1.0, 0.0, fade)
        return y

    def _render_inhale(self, k: int, n: int, rng: np.random.Generator) -> np.ndarray:
        """A noisy in-breath of ``n`` samples at the end of a bout."""
        b = self._inhales[k][2]
        u = np.arange(n) / max(n - 1, 1)
        env = np.sin(np.pi * u ** 0.7) ** 1.5  # quick rise, slow release
        from scipy.signal import lfilter

        y = lfilter(self._breath[0], self._breath[1], rng.standard_normal(n) * env)
        level = self.bouts[b].intensity
        peak = np.max(np.abs(y)) if n else 1.0
        y *= 10.0 ** (self.level_dbfs / 20.0) * level * _INHALE_REL / max(peak, 1e-12)
        return y

    # ----------------------------------------------------------------- truth
    def intensity_envelope(self, times_s) -> np.ndarray:
        """Ground-truth laughter intensity at the given times.

        Parameters
        ----------
        times_s : array_like
            Times in s.

        Returns
        -------
        ndarray of float
            Same shape as ``times_s``, in [0, 1]: 0 outside bouts; inside a
            call the call intensity times its amplitude envelope; between
            calls of a bout (and during a final in-breath) a low value,
            ``0.05 * bout intensity``.
        """
        t = np.asarray(times_s, dtype=float)
        flat = t.ravel()
        out = np.zeros(flat.shape)
        if not self.bouts:
            return out.reshape(t.shape)
        bi = np.searchsorted(self._bout_on, flat, side="right") - 1
        bc = np.clip(bi, 0, None)
        inb = (bi >= 0) & (flat < self._bout_off[bc])
        out[inb] = _GAP_TRUTH * self._bout_int[bc[inb]]
        ci = np.searchsorted(self._call_on, flat, side="right") - 1
        cc = np.clip(ci, 0, None)
        inc = (ci >= 0) & (flat < self._call_off[cc])
        k = cc[inc]
        asp_env, voice_env = _call_shapes(flat[inc] - self._call_on[k], self._asp[k],
                                          self._voiced[k], self._decay[k])
        val = self._call_int[k] * np.maximum(asp_env, voice_env)
        out[inc] = np.maximum(out[inc], val)
        return np.clip(out, 0.0, 1.0).reshape(t.shape)

    def truth_table(self) -> pd.DataFrame:
        """Ground truth, one row per bout (``kind='bout'``) followed by its calls.

        Columns: ``kind``, ``bout``, ``onset_s``, ``offset_s``, ``intensity``,
        ``f0_hz`` (NaN for bouts).  Times in s.
        """
        import pandas as pd

        return pd.DataFrame(self._truth_rows(), columns=list(TRUTH_COLUMNS))

    def _truth_rows(self) -> list[tuple]:
        rows, i = [], 0
        for b, bout in enumerate(self.bouts):
            rows.append(("bout", b, bout.onset_s, bout.offset_s, bout.intensity, np.nan))
            while i < len(self.calls) and self.calls[i].bout == b:
                c = self.calls[i]
                rows.append(("call", b, c.onset_s, c.offset_s, c.intensity, c.f0_hz))
                i += 1
        return rows

    def write_truth(self, path: str | PathLike) -> None:
        """Write :meth:`truth_table` as CSV to ``path``: the bytes of ``truth_table().to_csv(path,
        index=False)`` (floats as their shortest repr, NaN empty), without importing pandas (~0.7 s)."""
        def cell(v):
            if isinstance(v, str):
                return v
            if isinstance(v, (int, np.integer)):
                return str(int(v))
            v = float(v)
            return "" if math.isnan(v) else repr(v)

        lines = [",".join(TRUTH_COLUMNS)] + [",".join(cell(v) for v in row) for row in self._truth_rows()]
        with open(path, "w", newline="", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n")
