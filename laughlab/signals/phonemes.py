"""Extractor ``phoneme``: online laughter pseudo-phonemes, prosody and call onsets (Ding et al. 2014, 3-4).

Ding et al. (2014) drive lips, jaw, head and eyebrows from the segmentation of
laughter into the 14 pseudo-phonemes of the AVLaughterCycle database (section
3: silence, ne, click, nasal, plosive, fricative, ic, e, o, grunt, cackle, a,
glotstop, vowel) and from its prosody, energy and pitch, extracted with PRAAT
(section 3; the contextual Gaussian model of Eqs. 1-3 takes them as its context
theta).  Their pseudo-phonemes were annotated by hand; this extractor finds
them online, frame by frame, with a transparent rule-based classifier on
acoustic features (table below), or reads them from a Praat TextGrid.

Per frame it writes ``control['intensity']`` (dB, Praat's intensity),
``control['f0']`` (Hz, 0 when unvoiced), ``control['voicing']`` (0..1: Praat's
normalised autocorrelation at the chosen period, also given in unvoiced frames),
``control['call_onset']`` (1.0 on the frame where a laughter call 'ha' starts),
the motion control signal of the ``rms`` extractor (``rms``, ``amp``,
``mcs_raw``, ``mcs``; van Duijn 2014, 3.1, by composition with
:class:`~laughlab.signals.mcs.RmsExtractor`), and ``frame.label``.

Look-ahead and latency
----------------------
**No look-ahead**: frame ``k`` uses only the samples up to the end of its own
block.  Prosody and spectrum come from the last ``window_s`` (40 ms) of audio,
so they describe the window centred ``window_s / 2`` before the block's end
(at 60 fps: 3.3 ms before the frame's start ``time_s``; 20 ms of latency
behind the newest sample).  Call onsets come from 15 ms energies every 5 ms and
fire on the frame whose block holds the rise.  A label change needs
``confirm_frames`` (2) frames that agree, so labels lag by one more frame
(16.7 ms), except at a call onset and for the transient classes (click,
plosive, glotstop), which switch at once.

Features (all over the last ``window_s`` of audio unless said)
--------------------------------------------------------------
* intensity I (dB re 2e-5, samples as Pa): Praat's ``To Intensity`` (Kaiser
  window of Praat's shape, mean subtracted) with minimum pitch ``6.4 / window_s``;
* F0 and voicing strength r: Boersma's (1993) normalised autocorrelation
  (Hann window, divided by the window's autocorrelation, parabolic peak
  interpolation), Praat's octave cost and its voiced/unvoiced decision with the
  silence threshold relative to a running peak instead of the whole file.
  Praat's Viterbi path needs the future; online, the period is chosen on the
  generalised autocorrelation (spectrum compressed to |X|^(2/3), Tolonen &
  Karjalainen 2000, so formants pull less), Praat's octave cost on heights
  relative to the best, as the shortest candidate at least ``period_ratio`` as
  strong as the best, the best its subharmonic (YIN's guard, de Cheveigne &
  Kawahara 2002; both since 2026-11-29), and voicing has hysteresis
  (``voiced_unvoiced_cost``, Praat's V/UV cost taken greedily);
* spectral centroid C (Hz) and the share of power above ``nasal_split_hz``;
* zero-crossing rate Z (Hz: crossings per second / 2, a sine's frequency);
* F1, F2 (Hz, voiced frames only): peaks of an order-10 LPC envelope of the
  spectrum below 5.5 kHz (Praat's formant range), pre-emphasised from 50 Hz;
* per 5 ms hop: the level of the last 15 ms (dB), a noise floor (follows dips
  at once, rises ``floor_rise_db_per_s``) and a running peak; per block: the
  crest factor (peak / RMS) and the level change from the previous block.

Class rules (first match wins: click, plosive, silence, glotstop, then the rest)
--------------------------------------------------------------------------------
==========  ===============================================================  ==========
class       rule                                                             synthetic
==========  ===============================================================  ==========
silence     I < ``abs_silence_db``, or I < peak I - ``silence_range_db``,     yes
            or I < floor + ``silence_margin_db`` once the running peak has
            once risen ``floor_contrast_db`` above the floor
click       (checked first, on the newest block) unvoiced, audible block,    no
            crest factor >= ``click_crest`` and the block's level rose >=
            ``click_rise_db``: an impulse much shorter than a frame
plosive     (on the newest block) unvoiced, audible, after >= ``closure_s``  no
            of silence, level rose >= ``plosive_rise_db`` in one frame and
            C >= ``plosive_min_centroid_hz`` (a broadband burst after a closure)
glotstop    silent, voiced less than a window before a 5-ms level fell by    no
            >= ``glotstop_drop_db`` from within 6 dB of the call's peak
            (voicing cut off, not faded out), within a window + a frame
grunt       voiced, F0 < ``grunt_max_f0_hz``                                  no
cackle      voiced, F0 > ``cackle_min_f0_hz``                                 no
nasal       voiced, power above ``nasal_split_hz`` <= ``nasal_max_high_db``    no
            and F1 < ``nasal_max_f1_hz`` (a low murmur, no formant above)
a, e, ic, o voiced: nearest of :data:`VOWEL_FORMANTS_HZ` in (log2 F1,         a only
            log2 F2), within ``vowel_max_oct`` octaves
vowel       voiced, no vowel prototype within ``vowel_max_oct``               no
ne          unvoiced, C < ``ne_max_centroid_hz`` (nareal friction: low,       no
            muffled noise)
fricative   unvoiced otherwise (h-like breath noise, high Z)                 yes
==========  ===============================================================  ==========

The synthetic corpus (``laughlab.synth.laughter``) holds only silence (its -60 dBFS
floor), breath noise (the 'h' aspirations, the gaps, the in-breaths) and one
/a/-like vowel, so it exercises ``silence``, ``fricative`` and ``a`` only; the
other eleven rules are checked on hand-made signals in the tests, and their
thresholds are phonetic rules of thumb, not fitted to real laughter.  The
AVLaughterCycle counts (Ding et al., section 3: fricative 514, a 144, ic 162,
nasal 126, ne 105, ...) say which classes matter most on real recordings.

Call onsets
-----------
A call ('ha') starts where the 15-ms level rises ``onset_rise_db`` above the
lowest level since the last call ended and ``onset_margin_db`` above the noise
floor; the detector re-arms when the level falls ``rearm_drop_db`` below the
call's peak, and calls are at least ``min_ioi_s`` apart (laughter calls come at
4-7 per second).  It fires on the breathy 'h' onset, not the vowel.  Its known
false alarm on the synthetic corpus: the in-breath closing some bouts.

TextGrid input
--------------
With ``textgrid`` set, labels come from that file's interval tier (the one
named ``tier``, else the first interval tier) at each frame's mid-time, and
``call_onset`` fires on the frame holding the start of each vowel-like
interval (a, e, ic, o, vowel, cackle) that follows silence or a fricative (or
starts the file); intensity, F0, voicing and the MCS still come from the audio.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from laughlab.core.bases import Extractor
from laughlab.core.plugins import check_range
from laughlab.signals.prosody import PRAAT_REF_POWER
from laughlab.io.textgrid import read_textgrid
from laughlab.signals.mcs import RmsExtractor, RmsParams

#: vowel-like pseudo-phonemes: a call starts where one follows silence or a fricative
VOWEL_LIKE = frozenset({"a", "e", "ic", "o", "vowel", "cackle"})
#: short events that switch the label at once (no confirmation frames)
TRANSIENT = frozenset({"click", "plosive", "glotstop"})
#: F1, F2 prototypes (Hz) of the vowel classes, from the averages of men and women in
#: Peterson & Barney (1952) and the schwa of a uniform 17.5 cm tube: ``a`` open /ɑ ʌ/,
#: ``e`` mid central /ə/ (laughter vowels are mainly central), ``ic`` /ɪ/, ``o`` /ɔ o/
VOWEL_FORMANTS_HZ: dict[str, tuple[float, float]] = {
    "a": (750.0, 1250.0),
    "e": (500.0, 1500.0),
    "ic": (410.0, 2200.0),
    "o": (560.0, 880.0),
}
#: the autocorrelation's lag grid is at least this fine (Hz): twice the samples at 8 kHz
OVERSAMPLE_RATE_HZ = 16000.0
_LPC_TOP_HZ = 5500.0  # Praat's default maximum formant
_PREEMPH_FROM_HZ = 50.0  # Praat's pre-emphasis


#: the best period counts as a subharmonic of a shorter one within this of 2, 3 or 4 of its periods
SUBHARMONIC_TOL = 0.1

@dataclass
class PhonemeParams:
    """Parameters of the ``phoneme`` extractor (see the module docstring for the rules).

    Attributes
    ----------
    window_s : float
        Analysis window for intensity, F0 and spectrum (s); at least 3 periods
        of ``pitch_floor_hz`` (Praat's autocorrelation method).
    pitch_floor_hz, pitch_ceiling_hz : float
        F0 search range (Hz).  Laughter F0 is high: means ~280 Hz (men) and
        ~420 Hz (women) with peaks past 1 kHz (Bachorowski et al. 2001).
    voicing_threshold : float
        Praat's voicing threshold: least normalised autocorrelation of a voiced frame.
    silence_threshold : float
        Praat's silence threshold: window peak amplitude relative to the running
        peak below which a frame is unvoiced (Praat: relative to the whole file).
    octave_cost : float
        Praat's octave cost per octave favouring higher F0 candidates.
    voiced_unvoiced_cost : float
        Praat's voiced/unvoiced path cost, taken greedily: voicing starts only
        if the best candidate beats Praat's unvoiced candidate by this much.
    period_ratio : float
        Of the candidate periods at least this fraction as strong as the best
        and of which the best is a subharmonic (2, 3 or 4 periods), the shortest
        is taken (subharmonics are as periodic as the period).
    peak_decay_db_per_s : float
        How fast the running peaks (amplitude, intensity, level) forget (dB/s).
    abs_silence_db : float
        Intensity below which a frame is silence whatever came before (dB).
    silence_range_db : float
        Frames this far below the running peak intensity are silence (dB).
    silence_margin_db : float
        Frames less than this above the noise floor are silence (dB) ...
    floor_contrast_db : float
        ... once the running peak has risen this far above the noise floor
        (dB); until then a steady sound is not its own silence.
    floor_rise_db_per_s : float
        Rise of the noise floor while the level stays above it (dB/s).
    hop_s : float
        Hop of the call-onset detector's levels (s); each level covers 3 hops.
    onset_rise_db : float
        A call starts where the level rises this far above the lowest level
        since the previous call ended (dB) ...
    onset_margin_db : float
        ... and this far above the noise floor (dB).
    rearm_drop_db : float
        The level must fall this far below the call's peak before the next
        call can start (dB).
    min_ioi_s : float
        Least time between two call onsets (s).
    grunt_max_f0_hz, cackle_min_f0_hz : float
        Voiced frames below / above these F0 are grunt / cackle (Hz).
    nasal_split_hz, nasal_max_high_db : float
        Voiced frames whose power above ``nasal_split_hz`` is at most
        ``nasal_max_high_db`` relative to their total power are nasal (a murmur
        with no formants above the first) ...
    nasal_max_f1_hz : float
        ... and whose first LPC peak (or none) lies below this (Hz): the nasal
        murmur's low resonance, 250-300 Hz.
    vowel_max_oct : float
        Largest distance (octaves, in log2 F1 / log2 F2) to a vowel prototype;
        farther voiced frames are ``vowel``.
    ne_max_centroid_hz : float
        Unvoiced frames with a spectral centroid below this are ``ne``.
    click_crest, click_rise_db : float
        Crest factor and level rise (dB) of a click.
    plosive_rise_db, plosive_min_centroid_hz, closure_s : float
        Level rise (dB), least centroid (Hz) and preceding silence (s) of a plosive.
    glotstop_drop_db : float
        Fall of the 5-ms level (dB) that makes a voiced frame end in a glottal stop.
    min_segment_s : float
        A label is kept at least this long (s), so labels do not flicker.
    confirm_frames : int
        Frames a new label must win in a row before it replaces the current one.
    textgrid : str or None
        A Praat TextGrid whose labels replace the detector's (see module docstring).
    tier : str or None
        Its interval tier; None: the first interval tier.
    rms : RmsParams
        Parameters of the motion control signal (the ``rms`` extractor).
    """

    window_s: float = 0.04
    pitch_floor_hz: float = 75.0
    pitch_ceiling_hz: float = 1000.0
    voicing_threshold: float = 0.45
    silence_threshold: float = 0.03
    octave_cost: float = 0.01
    period_ratio: float = 0.9
    voiced_unvoiced_cost: float = 0.14
    peak_decay_db_per_s: float = 1.0
    abs_silence_db: float = 30.0
    silence_range_db: float = 40.0
    silence_margin_db: float = 8.0
    floor_contrast_db: float = 20.0
    floor_rise_db_per_s: float = 2.0
    hop_s: float = 0.005
    onset_rise_db: float = 10.0
    onset_margin_db: float = 10.0
    rearm_drop_db: float = 8.0
    min_ioi_s: float = 0.08
    grunt_max_f0_hz: float = 130.0
    cackle_min_f0_hz: float = 700.0
    nasal_split_hz: float = 1000.0
    nasal_max_high_db: float = -25.0
    nasal_max_f1_hz: float = 350.0
    vowel_max_oct: float = 0.6
    ne_max_centroid_hz: float = 700.0
    click_crest: float = 8.0
    click_rise_db: float = 10.0
    plosive_rise_db: float = 20.0
    plosive_min_centroid_hz: float = 2500.0
    closure_s: float = 0.03
    glotstop_drop_db: float = 20.0
    min_segment_s: float = 0.03
    confirm_frames: int = 2
    textgrid: str | None = None
    tier: str | None = None
    rms: RmsParams = field(default_factory=RmsParams)

    def __post_init__(self) -> None:
        check_range("window_s", self.window_s, 0.005, 0.2)
        check_range("pitch_floor_hz", self.pitch_floor_hz, 20.0, 1000.0)
        check_range("pitch_ceiling_hz", self.pitch_ceiling_hz, 0, 5000.0, lo_open=True)
        if not self.pitch_ceiling_hz > self.pitch_floor_hz:
            raise ValueError(f"pitch_ceiling_hz must be > pitch_floor_hz "
                             f"(got {self.pitch_ceiling_hz} <= {self.pitch_floor_hz})")
        if self.window_s < 3.0 / self.pitch_floor_hz - 1e-9:
            raise ValueError(f"window_s must hold 3 periods of pitch_floor_hz: >= {3.0 / self.pitch_floor_hz:.4g} s "
                             f"(got {self.window_s})")
        check_range("nasal_max_high_db", self.nasal_max_high_db, -120.0, 0.0)
        for name in ("voicing_threshold", "silence_threshold", "period_ratio"):
            check_range(name, getattr(self, name), 0.0, 1.0)
        for name in ("octave_cost", "voiced_unvoiced_cost", "peak_decay_db_per_s", "silence_range_db", "silence_margin_db",
                     "floor_contrast_db", "floor_rise_db_per_s", "onset_rise_db", "onset_margin_db",
                     "rearm_drop_db", "min_ioi_s", "grunt_max_f0_hz", "cackle_min_f0_hz", "nasal_split_hz", "nasal_max_f1_hz",
                     "vowel_max_oct", "ne_max_centroid_hz", "click_crest", "click_rise_db", "plosive_rise_db",
                     "plosive_min_centroid_hz", "closure_s", "glotstop_drop_db", "min_segment_s"):
            check_range(name, getattr(self, name), 0.0)
        if not self.grunt_max_f0_hz < self.cackle_min_f0_hz:   # (a phonetician's review: accepted before)
            raise ValueError(f"grunt_max_f0_hz must be < cackle_min_f0_hz (got {self.grunt_max_f0_hz} >= "
                             f"{self.cackle_min_f0_hz})")
        check_range("abs_silence_db", self.abs_silence_db, -50.0, 200.0)
        check_range("hop_s", self.hop_s, 0.001, 0.05)
        if not (isinstance(self.confirm_frames, int) and self.confirm_frames >= 1):
            raise ValueError(f"confirm_frames must be a whole number >= 1 (got {self.confirm_frames!r})")
        if self.textgrid is not None and not str(self.textgrid).strip():
            raise ValueError("textgrid must be a file path or null")
        if isinstance(self.rms, dict):  # built in code with a plain dict
            self.rms = RmsParams(**self.rms)


def _praat_kaiser(n: int) -> np.ndarray:
    """Praat's intensity window over ``n`` samples: I0((2 pi^2 + 0.5) sqrt(1 - x^2)), x in [-1, 1]."""
    x = np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1)
    return np.i0((2.0 * math.pi ** 2 + 0.5) * np.sqrt(np.clip(1.0 - x * x, 0.0, None)))


class PhonemeExtractor(Extractor):
    """Online laughter pseudo-phonemes, Praat-like prosody and call onsets (Ding et al. 2014, 3-4).

    See the module docstring for the features, the class rules, the call
    detector and the latency (no look-ahead).

    Attributes
    ----------
    features : dict[str, float]
        The last frame's features (intensity, f0, centroid_hz, high_share,
        zcr_hz, f1_hz, f2_hz, crest, level_db, floor_db), for
        inspection and tests.
    nonfinite_samples : int
        Non-finite input samples seen (treated as silence).
    """

    name = "phoneme"
    calibrates = True  # its MCS is the rms extractor's, with the calibration phase (thesis 3.1.1)
    Params = PhonemeParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p, sr = self.params, int(self.ctx.sample_rate)
        self._rms = RmsExtractor(p.rms, self.ctx)
        self._sr = sr
        n = max(16, int(round(p.window_s * sr)))
        self._n = n
        self._hann = np.hanning(n + 2)[1:-1]  # no zero end points
        kaiser = _praat_kaiser(n)
        self._kaiser = kaiser / kaiser.sum()
        lag_max = max(4, min(int(math.ceil(sr / p.pitch_floor_hz)), n // 2))
        nfft = 1
        while nfft < n + lag_max + 2:
            nfft *= 2
        self._nfft = nfft
        # the autocorrelation is read on a lag grid ``ov`` times finer than the samples (band-limited
        # interpolation by zero-padding the spectrum), so peak heights and the octave choice are
        # exact enough; Praat interpolates with sincs for the same reason
        ov = self._ov = max(1, min(8, int(round(OVERSAMPLE_RATE_HZ / sr))))
        self._lag_min = max(2, int(math.floor(ov * sr / p.pitch_ceiling_hz)))
        self._lag_max = max(self._lag_min + 2, ov * lag_max)
        rw = np.fft.irfft(np.abs(np.fft.rfft(self._hann, nfft)) ** 2, nfft * ov)[: self._lag_max + 2]
        self._rw = rw / rw[0]
        self._freqs = np.fft.rfftfreq(nfft, 1.0 / sr)
        self._nasal_bin = int(np.searchsorted(self._freqs, p.nasal_split_hz))
        self._nasal_max_high = 10.0 ** (p.nasal_max_high_db / 10.0)
        # LPC of the spectrum below 5.5 kHz: an autocorrelation at rate 2 * top from the low bins
        top = min(_LPC_TOP_HZ, sr / 2.0)
        self._kc = max(8, int(round(top * nfft / sr)))
        self._kc = min(self._kc, nfft // 2)
        self._lpc_rate = 2.0 * self._kc * sr / nfft
        self._lpc_order = max(4, 2 * int(round(self._lpc_rate / 2.0 / 1100.0)))
        mu = math.exp(-2.0 * math.pi * _PREEMPH_FROM_HZ / self._lpc_rate)
        w = 2.0 * math.pi * self._freqs[: self._kc + 1] / self._lpc_rate
        self._preemph = 1.0 + mu * mu - 2.0 * mu * np.cos(w)
        kk = np.arange(self._kc + 1)
        weight = np.where((kk == 0) | (kk == self._kc), 1.0, 2.0) * self._preemph
        lags = np.arange(self._lpc_order + 1)
        self._lpc_cos = np.cos(np.pi * np.outer(lags, kk) / self._kc) * weight
        self._env_freqs = np.linspace(0.0, self._lpc_rate / 2.0, 129)
        om = 2.0 * np.pi * np.outer(self._env_freqs / self._lpc_rate, lags)
        self._env_cos, self._env_sin = np.cos(om), np.sin(om)
        self._hop = max(1, int(round(p.hop_s * sr)))
        hop_s = self._hop / sr
        self._hop_s = hop_s
        self._floor_rise = p.floor_rise_db_per_s * hop_s
        self._peak_decay_hop = p.peak_decay_db_per_s * hop_s
        self._peak_decay_frame = p.peak_decay_db_per_s * self.ctx.dt
        self._amp_decay_frame = 10.0 ** (-self._peak_decay_frame / 20.0)
        self._proto = {k: (math.log2(f1), math.log2(f2)) for k, (f1, f2) in VOWEL_FORMANTS_HZ.items()}
        self._grid = None
        if p.textgrid is not None:
            self._load_textgrid(p.textgrid, p.tier)
        self.features: dict[str, float] = {}
        self.reset()

    # ------------------------------------------------------------------ setup
    def _load_textgrid(self, path: str, tier: str | None) -> None:
        ivs = read_textgrid(path, tier)
        self._grid_starts = [a for a, _, _ in ivs]
        self._grid = ivs
        onsets, prev = [], None
        for a, _, lab in ivs:
            if lab in VOWEL_LIKE and (prev is None or prev in ("silence", "fricative")):
                onsets.append(a)
            prev = lab
        self._grid_onsets = onsets

    def reset(self) -> None:
        self._rms.reset()
        self._buf = np.zeros(self._n)
        self._rem = np.zeros(0)
        self._lv_prev = np.zeros(2)  # mean squares of the last two hops
        self._hop_t = 0.0  # time (s) of the end of the last hop
        self._floor = math.nan
        self._lpeak = -math.inf  # running peak of the hop level (dB)
        self._floor_ok = False  # has the level ever risen floor_contrast_db above the floor?
        self._armed = True
        self._valley = math.inf
        self._call_peak = -math.inf
        self._last_onset = -math.inf
        self._prev_raw_lv = -math.inf
        self._gs_t = -math.inf  # time of the last abrupt fall of the level
        self._voiced_t = -math.inf  # time of the last voiced frame
        self._frame_t = 0.0
        self._amp_peak = 0.0
        self._ipeak = -math.inf
        self._prev_block_db = 0.0
        self._silent_for = math.inf
        self._prev_f0 = 0.0
        self._label = "silence"
        self._label_since = -math.inf
        self._cand = None
        self._cand_n = 0

    @property
    def nonfinite_samples(self) -> int:
        return self._rms.nonfinite_samples

    # -------------------------------------------------------------- per frame
    def step(self, block, frame) -> None:
        self._rms.step(block, frame)  # rms, amp, mcs_raw, mcs (and counts non-finite samples)
        x = np.asarray(block, dtype=np.float64).ravel()
        if x.size and not np.isfinite(np.dot(x, x)):
            x = np.where(np.isfinite(x), x, 0.0)
        m = x.shape[0]
        if m >= self._n:
            self._buf = x[-self._n:].copy()
        elif m:
            self._buf = np.concatenate((self._buf[m:], x))
        self._frame_t = frame.time_s + frame.dt
        onset = self._onsets(x)
        intensity, f0, voicing, voiced, silent = self._prosody()
        if self._grid is not None:
            label, onset = self._from_grid(frame)
        else:
            raw = self._classify(x, intensity, f0, voiced, silent)
            label = self._smooth(raw, onset, frame.time_s)
        c = frame.control
        c["intensity"] = intensity
        c["f0"] = f0
        c["voicing"] = voicing
        c["call_onset"] = 1.0 if onset else 0.0
        frame.label = label

    # --------------------------------------------------------- call onsets
    def _onsets(self, x: np.ndarray) -> bool:
        """Advance the 5-ms level detector over the new samples; True if a call started."""
        seg = np.concatenate((self._rem, x)) if self._rem.size else x
        hop = self._hop
        k = seg.shape[0] // hop
        self._rem = seg[k * hop:].copy()
        if k == 0:
            return False
        sub = seg[: k * hop].reshape(k, hop)
        ms = np.einsum("ij,ij->i", sub, sub) / hop
        full = np.concatenate((self._lv_prev, ms))
        self._lv_prev = full[-2:]
        ref = PRAAT_REF_POWER
        raw = 10.0 * np.log10(np.maximum(ms, ref) * (1.0 / ref))
        lvl = 10.0 * np.log10(np.maximum((full[:-2] + full[1:-1] + full[2:]) * (1.0 / 3.0), ref) * (1.0 / ref))
        p = self.params
        fired = False
        for raw_db, level in zip(raw.tolist(), lvl.tolist()):
            self._hop_t += self._hop_s
            # noise floor: follows dips at once, rises slowly; running peak decays slowly
            if self._floor != self._floor or level < self._floor:  # NaN: the first hop
                self._floor = level
            else:
                self._floor += self._floor_rise
            self._lpeak = max(level, self._lpeak - self._peak_decay_hop)
            # glottal stop: the raw 5-ms level falls abruptly from near the call's peak
            if (self._prev_raw_lv - raw_db >= p.glotstop_drop_db
                    and self._prev_raw_lv >= self._call_peak - 6.0):
                self._gs_t = self._hop_t
            self._prev_raw_lv = raw_db
            if self._armed:
                if level < self._valley:
                    self._valley = level
                if (level >= self._valley + p.onset_rise_db and level >= self._floor + p.onset_margin_db
                        and self._hop_t - self._last_onset >= p.min_ioi_s):
                    fired = True
                    self._armed = False
                    self._call_peak = level
                    self._last_onset = self._hop_t
            else:
                if level > self._call_peak:
                    self._call_peak = level
                elif level <= self._call_peak - p.rearm_drop_db:
                    self._armed = True
                    self._valley = level
        return fired

    # ------------------------------------------------------------- prosody
    def _prosody(self):
        """Intensity, F0, voicing strength, voiced and silent of the last ``window_s``."""
        p = self.params
        buf = self._buf
        x = buf - float(buf.sum()) / buf.shape[0]
        self._x = x
        ms = float(np.dot(x * x, self._kaiser))
        intensity = 10.0 * math.log10(max(ms, PRAAT_REF_POWER) / PRAAT_REF_POWER)
        if not math.isfinite(intensity):  # overflow of absurd input: clip
            intensity = 1000.0
        self._ipeak = max(intensity, self._ipeak - self._peak_decay_frame)
        amp = max(float(x.max()), -float(x.min()))
        self._amp_peak = max(amp, self._amp_peak * self._amp_decay_frame)
        floor = self._floor if self._floor == self._floor else intensity
        if not self._floor_ok and self._lpeak - floor >= p.floor_contrast_db:
            self._floor_ok = True  # something clearly louder than the floor was heard: it is a floor
        silent = (intensity < p.abs_silence_db or intensity < self._ipeak - p.silence_range_db
                  or (self._floor_ok and intensity < floor + p.silence_margin_db))
        # normalised autocorrelation (Boersma 1993)
        X = np.fft.rfft(x * self._hann, self._nfft)
        P = X.real * X.real + X.imag * X.imag
        self._P = P
        f0 = 0.0
        r_best = 0.0
        ra = np.fft.irfft(P, self._nfft * self._ov)[: self._lag_max + 2]
        r0 = ra[0]
        if r0 > 0.0 and math.isfinite(r0):
            lo, hi = self._lag_min - 1, self._lag_max + 1
            rx = ra[lo: hi + 1] / (r0 * self._rw[lo: hi + 1])
            # the period is chosen on the generalised autocorrelation (|X|^(2/3), Tolonen &
            # Karjalainen 2000), whose compressed spectrum lets the formants pull less
            rg = np.fft.irfft(np.cbrt(P), self._nfft * self._ov)[: self._lag_max + 2]
            cand = self._peaks(rg[lo: hi + 1] / (rg[0] * self._rw[lo: hi + 1]), lo, 0.0) if rg[0] > 0.0 else None
            if cand is not None:
                lag_s, r_s = cand
                # Praat's octave cost on heights relative to the best (here 0.10-0.18 on a breathy laugh: 0.01 an
                # octave weighed like 0.06 and pulled the choice up to 1 kHz; a phonetician's review)
                strength = r_s / max(float(r_s.max()), 1e-12) - p.octave_cost * np.log2(p.pitch_floor_hz * lag_s /
                                                                                         self._sr)
                i = int(np.argmax(strength))
                # subharmonics (2, 3, 4 periods) are as periodic as the period: the shortest lag nearly as strong
                # as the best (YIN's rule), the best its subharmonic (any shorter lag took 932 Hz over 128 Hz)
                m = lag_s[i] / lag_s
                near = (strength >= p.period_ratio * strength[i]) & (np.abs(m - np.round(m)) <= SUBHARMONIC_TOL) & \
                    (np.round(m) <= 4)
                i = int(np.flatnonzero(near)[0])
                # F0 and strength from Praat's normalised autocorrelation at that peak
                c0 = int(round(lag_s[i] * self._ov)) - lo
                w = max(2, int(0.03 * c0))
                a0, b0 = max(1, c0 - w), min(len(rx) - 1, c0 + w + 1)
                j = min(max(a0 + int(np.argmax(rx[a0:b0])), 1), len(rx) - 2)
                a, b, c = rx[j - 1], rx[j], rx[j + 1]
                den = a - 2.0 * b + c
                delta = min(max(0.5 * (a - c) / den, -0.5), 0.5) if den < 0.0 else 0.0
                r_best = min(float(b - 0.25 * (a - c) * delta), 1.0)
                lag = (lo + j + delta) / self._ov
                s_best = r_best - p.octave_cost * math.log2(p.pitch_floor_hz * lag / self._sr)
                # Praat's unvoiced candidate, strong when the window is quiet relative to the peak;
                # starting to voice costs voiced_unvoiced_cost (Praat's path cost, taken greedily)
                rel = amp / self._amp_peak if self._amp_peak > 0.0 else 0.0
                # (silence_threshold 0, allowed by Praat: no window is quiet enough, the term is 0)
                unvoiced = p.voicing_threshold + (max(0.0, 2.0 - rel / (p.silence_threshold /
                                                                        (1.0 + p.voicing_threshold)))
                                                  if p.silence_threshold > 0.0 else 0.0)
                switch = -p.voiced_unvoiced_cost if self._prev_f0 > 0.0 else p.voiced_unvoiced_cost
                if s_best - switch > unvoiced and not silent and lag > 0.0:
                    f0 = self._sr / lag
                    if not p.pitch_floor_hz <= f0 <= p.pitch_ceiling_hz:  # a peak at the edge of the range
                        f0 = 0.0
        self._prev_f0 = f0
        voicing = min(max(r_best, 0.0), 1.0)
        voiced = f0 > 0.0
        return intensity, f0, voicing, voiced, silent

    def _peaks(self, rx: np.ndarray, lo: int, least: float):
        """Local maxima of a normalised autocorrelation above ``least``: (lags in samples, heights), parabolic."""
        mid = rx[1:-1]
        pk = np.flatnonzero((mid > rx[:-2]) & (mid >= rx[2:]) & (mid > least)) + 1
        if not pk.size:
            return None
        a, b, c = rx[pk - 1], rx[pk], rx[pk + 1]
        den = a - 2.0 * b + c
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.where(den < 0.0, 0.5 * (a - c) / den, 0.0)
        delta = np.clip(delta, -0.5, 0.5)
        r = np.minimum(b - 0.25 * (a - c) * delta, 1.0)
        return (lo + pk + delta) / self._ov, r

    # -------------------------------------------------------- classification
    def _formants(self) -> tuple[float, float]:
        """F1, F2 (Hz) from an order-10 LPC envelope of the spectrum below 5.5 kHz (0 if none).

        The autocorrelation of the pre-emphasised signal band-limited to 5.5 kHz (at
        11 kHz) is a cosine transform of the low spectrum bins (one matrix product);
        Levinson-Durbin gives the predictor; the envelope's peaks below 5.5 kHz are
        the formant candidates, and the first two above 200 Hz are F1 and F2.
        """
        r = (self._lpc_cos @ self._P[: self._kc + 1]).tolist()
        r0 = r[0]
        if not (r0 > 0.0 and math.isfinite(r0)):
            return 0.0, 0.0
        err = r0 * (1.0 + 1e-6)  # white-noise correction keeps the recursion stable
        a: list[float] = []
        for i in range(1, self._lpc_order + 1):  # Levinson-Durbin
            acc = r[i]
            for j, aj in enumerate(a):
                acc -= aj * r[i - 1 - j]
            k = acc / err
            a = [aj - k * a[i - 2 - j] for j, aj in enumerate(a)] + [k]
            err *= 1.0 - k * k
            if not err > 0.0:
                return 0.0, 0.0
        c = np.array([1.0] + [-v for v in a])
        re, im = self._env_cos @ c, self._env_sin @ c
        inv = re * re + im * im  # 1 / envelope: formants at its minima
        mid = inv[1:-1]
        pk = np.flatnonzero((mid < inv[:-2]) & (mid <= inv[2:])) + 1
        fr = self._env_freqs[pk]
        fr = fr[fr > 200.0]
        if fr.size == 0:
            return 0.0, 0.0
        return float(fr[0]), (float(fr[1]) if fr.size > 1 else 0.0)

    def _classify(self, x: np.ndarray, intensity: float, f0: float, voiced: bool, silent: bool) -> str:
        """The raw pseudo-phoneme of this frame (rules in the module docstring)."""
        p = self.params
        P = self._P
        total = float(P[1:].sum())
        centroid = float(np.dot(P, self._freqs)) / total if total > 0.0 else 0.0
        high = float(P[self._nasal_bin:].sum()) / total if total > 0.0 else 0.0
        sb = np.signbit(self._x)
        zcr = 0.5 * int(np.count_nonzero(sb[1:] != sb[:-1])) * self._sr / (sb.shape[0] - 1)
        m = x.shape[0]
        if m:
            xm = x - float(x.sum()) / m
            e = float(np.dot(xm, xm)) / m
            crest = max(float(xm.max()), -float(xm.min())) / math.sqrt(e) if e > 0.0 else 0.0
            block_db = 10.0 * math.log10(max(e, PRAAT_REF_POWER) / PRAAT_REF_POWER)
        else:
            crest, block_db = 0.0, self._prev_block_db
        rise = block_db - self._prev_block_db
        self._prev_block_db = block_db
        f1 = f2 = 0.0
        t = self._frame_t
        # transients are judged on the newest block: the window's taper hides its last milliseconds
        audible = block_db >= p.abs_silence_db and block_db >= self._floor + p.silence_margin_db
        if not voiced and audible and crest >= p.click_crest and rise >= p.click_rise_db:
            label = "click"
        elif (not voiced and audible and self._silent_for >= p.closure_s and rise >= p.plosive_rise_db
              and centroid >= p.plosive_min_centroid_hz):
            label = "plosive"
        elif silent:
            # a glottal stop: voicing cut off (not faded) less than a window ago
            recent = t - self._gs_t <= p.window_s + self.ctx.dt and self._gs_t - self._voiced_t <= p.window_s
            label = "glotstop" if recent else "silence"
        elif voiced:
            if f0 < p.grunt_max_f0_hz:
                label = "grunt"
            elif f0 > p.cackle_min_f0_hz:
                label = "cackle"
            else:
                f1, f2 = self._formants()
                if high <= self._nasal_max_high and f1 < p.nasal_max_f1_hz:
                    label = "nasal"
                else:
                    label = self._vowel(f1, f2)
        elif centroid < p.ne_max_centroid_hz:
            label = "ne"
        else:
            label = "fricative"
        dt = self.ctx.dt
        self._silent_for = self._silent_for + dt if silent else 0.0
        if voiced:
            self._voiced_t = t
        self.features = {"intensity": intensity, "f0": f0, "centroid_hz": centroid, "high_share": high,
                         "zcr_hz": zcr, "f1_hz": f1, "f2_hz": f2, "crest": crest, "level_db": block_db,
                         "floor_db": self._floor}
        return label

    def _vowel(self, f1: float, f2: float) -> str:
        if f1 <= 0.0 or f2 <= 0.0:
            return "vowel"
        l1, l2 = math.log2(f1), math.log2(f2)
        best, dist = "vowel", math.inf
        for name, (p1, p2) in self._proto.items():
            d = math.hypot(l1 - p1, l2 - p2)
            if d < dist:
                best, dist = name, d
        return best if dist <= self.params.vowel_max_oct else "vowel"

    def _smooth(self, raw: str, onset: bool, t: float) -> str:
        """Hysteresis: confirm a new label over ``confirm_frames``, keep each at least ``min_segment_s``."""
        p = self.params
        if raw == self._label:
            self._cand, self._cand_n = None, 0
            return raw
        if raw == self._cand:
            self._cand_n += 1
        else:
            self._cand, self._cand_n = raw, 1
        urgent = raw in TRANSIENT or (onset and raw != "silence")
        held = t - self._label_since >= p.min_segment_s - 1e-9
        if (urgent or self._cand_n >= p.confirm_frames) and (held or raw in TRANSIENT):
            self._label, self._label_since = raw, t
            self._cand, self._cand_n = None, 0
        return self._label

    # -------------------------------------------------------------- TextGrid
    def _from_grid(self, frame) -> tuple[str, bool]:
        t0, dt = frame.time_s, frame.dt
        mid = t0 + 0.5 * dt
        i = bisect.bisect_right(self._grid_starts, mid) - 1
        label = "silence"
        if i >= 0:
            a, b, lab = self._grid[i]
            if mid < b:
                label = lab
        j = bisect.bisect_left(self._grid_onsets, t0 - 1e-12)
        onset = j < len(self._grid_onsets) and self._grid_onsets[j] < t0 + dt - 1e-12
        return label, onset
