"""Real-time laughter detection: causal acoustic features, a small model, and the gate.

Laughter differs from speech in ways a listener hears within a call or two
(van Duijn 2014, ch. 6 "laughter detection"; Gillick et al. 2021; Bachorowski
et al. 2001): calls repeat at 3-8 per second with the *same* vowel, so the
spectrum barely changes from call to call while speech changes its formants
every syllable; calls alternate voiced bursts with breathy 'h' (high-frequency
noise); the pitch is high and varies a lot.  :class:`FeatureStream` measures
those cues from the audio of each frame and the second before it (no look-ahead:
frame ``k`` uses samples up to the end of its own block), :class:`Model` maps
them to a laughter probability, and :class:`Gate` turns the probability into a
gain in [0, 1] with hysteresis, which the ``laugh`` detector multiplies into the
signals that drive the body and face.

Only the band below ``BAND_HZ`` (5 kHz) is used, so every sample rate from
11.025 kHz up gives the same features (recordings at 11.025, 16, 22.05, 44.1
and 48 kHz are all in the corpus) and a recording's bandwidth cannot stand in
for its class.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources

import numpy as np

#: highest frequency used (Hz)
BAND_HZ = 5000.0
#: analysis window (s): 32 ms, two pitch periods at 70 Hz
WINDOW_S = 0.032
#: long and short history (s)
LONG_S = 1.0
SHORT_S = 0.3
#: pitch search range (Hz): men's speech to women's laughter (Bachorowski 2001: up to ~1 kHz)
F0_MIN_HZ, F0_MAX_HZ = 75.0, 1000.0
#: a frame is active when within this many dB of the loudest frame of the last second
ACTIVE_DB = 25.0
#: the running peak level falls this fast (dB/s): loud sound minutes ago no longer sets the scale
PEAK_FALL_DB_S = 1.0
#: below this level (dB re full scale, RMS of the window) a frame is silence
SILENCE_DBFS = -65.0
N_MEL, N_CEP = 20, 8
#: pitch candidates lose this much normalised autocorrelation per octave of lag (Boersma 1993)
OCTAVE_COST = 0.03
#: a shorter lag within this much of the best correlation is taken as the period
NEAR_MAX = 0.1

FEATURES = (
    "rel_db", "voicing", "hf_ratio", "flatness",
    "e_std_s", "voi_mean_s", "hf_mean_s", "dcep_s",
    "e_std_l", "mod_3_8", "env_periodicity", "voi_mean_l", "voiced_frac_l",
    "f0_mean_l", "f0_std_l", "cep_std_l", "dcep_l", "hf_mean_l", "hf_std_l", "flat_mean_l", "cep_periodicity",
    "rel_peak_db", "act_rel_peak_db",
)


def _mel_bank(freqs: np.ndarray, n: int, lo: float, hi: float) -> np.ndarray:
    mel = lambda f: 2595.0 * np.log10(1.0 + f / 700.0)  # noqa: E731
    edges = 700.0 * (10 ** (np.linspace(mel(lo), mel(hi), n + 2) / 2595.0) - 1.0)
    bank = np.zeros((n, len(freqs)))
    for i in range(n):
        a, c, b = edges[i], edges[i + 1], edges[i + 2]
        up = (freqs - a) / (c - a)
        down = (b - freqs) / (b - c)
        bank[i] = np.clip(np.minimum(up, down), 0.0, None)
    return bank


class FeatureStream:
    """Per-frame laughter features from consecutive audio blocks (no look-ahead).

    Per frame (32 ms Hann window ending at the block's last sample; band 0-5 kHz):

    - ``rel_db``: window level minus the loudest level of the last second (dB);
    - ``voicing``: peak of the normalised autocorrelation r(tau)/r_w(tau) for
      pitch 75-1000 Hz (Boersma 1993, Eq. 9: divided by the window's own
      autocorrelation; the peak chosen with an octave cost of 0.03 per octave
      of lag, then the shortest lag within 0.1 of it), and the pitch at that peak;
    - ``hf_ratio``: energy 2-5 kHz over 0.1-5 kHz (breathiness);
    - ``flatness``: geometric over arithmetic mean of the power spectrum;
    - mel cepstra c1..c8 (20 bands, 80 Hz-5 kHz, DCT-II, floor 30 dB under the mean band)
      of the spectral shape, used only for how they change and repeat: the
      cepstra themselves depend on the microphone and the room, and would let a
      model learn the recording rather than the laugh.

    Over the short (0.3 s) and long (1 s) history: the level's spread
    (``e_std``, at most 40 dB under the top, so digital silence does not dominate), mean voicing, mean breathiness, mean cepstral change between
    frames (``dcep``, speech changes formants, laughter repeats a vowel), the
    share of the level trajectory's modulation energy at 3-8 Hz (``mod_3_8``),
    its autocorrelation peak at lags 0.12-0.33 s (``env_periodicity``, regular
    calls), the voiced share of active frames, pitch mean (log2 Hz) and spread
    (semitones), cepstral spread and the spread of breathiness, and the
    periodicity of the spectral shape (``cep_periodicity``: the cepstra's
    autocorrelation at 0.12-0.33 s over active frames; laughter's h-a-h-a
    repeats one vowel, speech moves on).

    Against a running peak level that falls 1 dB/s (the scale of the room's
    loudest sound, as the thesis' min/max calibration of the MCS): the frame's
    level (``rel_peak_db``) and the mean level of the last second's active
    frames (``act_rel_peak_db``), so a quiet bed of music or noise does not
    count as foreground.
    """

    def __init__(self, sample_rate: int, fps: float):
        import scipy.fft  # noqa: F401 - loaded when the stream is built, not in its first (live) frame
        self.sr = int(sample_rate)
        self.win = max(64, int(round(WINDOW_S * self.sr)))
        self.lmin = max(2, int(self.sr / F0_MAX_HZ))
        self.lmax = min(self.win // 2, int(self.sr / F0_MIN_HZ))
        # zero padding to win + lmax: the autocorrelation up to lmax is not circular
        self.nfft = 1 << int(math.ceil(math.log2(self.win + self.lmax)))
        self.window = np.hanning(self.win)
        freqs = np.fft.rfftfreq(self.nfft, 1.0 / self.sr)
        self.kmax = int(np.searchsorted(freqs, min(BAND_HZ, self.sr / 2.0)))
        f = freqs[: self.kmax]
        self.k100 = int(np.searchsorted(f, 100.0))
        self.k2k = int(np.searchsorted(f, 2000.0))
        self.mel = _mel_bank(f, N_MEL, 80.0, min(BAND_HZ, self.sr / 2.0))[:, self.k100:]
        n = np.arange(N_MEL)
        self.dct = np.cos(np.pi / N_MEL * (n + 0.5)[None, :] * np.arange(1, N_CEP + 1)[:, None])
        # The autocorrelation of the band below 5 kHz, from the same spectrum: the inverse
        # transform of its first kmax bins is the autocorrelation sampled at 2 (kmax - 1) / nfft
        # of the sample rate (about 10 kHz whatever the input rate): a short inverse FFT.
        self.nac = 2 * (self.kmax - 1)
        self.sr_ac = self.sr * self.nac / self.nfft
        self.jmin = max(2, int(math.floor(self.lmin * self.nac / self.nfft)))
        self.jmax = min(self.nac // 2, int(math.ceil(self.lmax * self.nac / self.nfft)) + 1)
        wp = np.abs(np.fft.rfft(self.window, self.nfft))[: self.kmax] ** 2
        wac = np.fft.irfft(wp, self.nac)
        self.wac_inv = wac[0] / wac[self.jmin:self.jmax]
        # Boersma (1993) octave cost: a longer lag must be clearly better to win (no halved pitch)
        self.octave_cost = OCTAVE_COST * np.log2(np.arange(self.jmin, self.jmax) / self.jmin)
        self.fps = float(fps)
        self.dt = 1.0 / self.fps
        self.nl = max(8, int(round(LONG_S * fps)))
        self.ns = max(3, int(round(SHORT_S * fps)))
        self.lag_lo, self.lag_hi = max(1, int(round(0.12 * fps))), min(self.nl - 2, int(round(0.33 * fps)))
        # the level trajectory's spectrum (zero-padded to twice its length) at 0.5-15 Hz, as a
        # cos/sin matrix: the modulation energy at 3-8 Hz over that at 0.5-15 Hz
        mod_f = np.fft.rfftfreq(2 * self.nl, 1.0 / fps)
        mod_f = mod_f[(mod_f >= 0.5) & (mod_f <= 15.0)]
        t = np.arange(self.nl) / fps
        self.n_mod = len(mod_f)
        self.mod_dft = np.vstack([np.cos(2 * np.pi * mod_f[:, None] * t), np.sin(2 * np.pi * mod_f[:, None] * t)])
        self.mod_band = ((mod_f >= 3.0) & (mod_f <= 8.0)).astype(np.float64)
        # frame weights of the history sums: active, voiced active, active in the short window
        self.short_mask = np.zeros(self.nl)
        self.short_mask[-self.ns:] = 1.0
        self.weights = np.zeros((3, self.nl))
        self.reset()

    def reset(self) -> None:
        self.buf = np.zeros(self.win)
        # one row per frame of the last second: e, voi, f0 (log2 Hz), hf, flat, dcep, the cepstra, 1
        self.hist = np.zeros((self.nl, 7 + N_CEP))
        self.hist[:, -1] = 1.0
        self.hist[:, 0] = -120.0
        self.hist[:, 2] = 7.0
        self.level_dbfs = -120.0
        self.peak_db = -120.0
        self._last = (-120.0, 0.0, 0.0, 0.0)

    def step(self, block: np.ndarray) -> np.ndarray:
        """Take one frame's samples; return the feature vector (``FEATURES`` order)."""
        self.push(block)
        return self.features()

    def push(self, block: np.ndarray) -> None:
        """Take one frame's samples: the frame's own measures (level, spectrum, pitch) go into the history.
        :meth:`features` then gives what :meth:`step` would have (a user that needs the features only now and
        then pushes every frame and asks on those frames)."""
        b = np.asarray(block, dtype=np.float64)
        n = len(b)
        if n >= self.win:
            self.buf = b[-self.win:].copy()
        elif n:
            self.buf[:-n] = self.buf[n:]
            self.buf[-n:] = b
        x = self.buf
        pw = float(np.dot(x, x))
        if not math.isfinite(pw):  # NaN/Inf samples count as silence, as in the extractors
            self.buf = x = np.where(np.isfinite(x), x, 0.0)
            pw = float(np.dot(x, x))
        self.level_dbfs = 10.0 * math.log10(pw / self.win + 1e-14)
        from scipy import fft as _fft  # imported on first use (scipy.fft ~0.15 s at start-up)

        spec = _fft.rfft(x * self.window, self.nfft)
        p = spec.real ** 2 + spec.imag ** 2
        pb = p[self.k100: self.kmax] + 1e-12
        tot = float(pb.sum())
        e = 10.0 * math.log10(tot)
        self.peak_db = max(e, self.peak_db - PEAK_FALL_DB_S * self.dt)
        hf = float(pb[self.k2k - self.k100:].sum()) / tot
        flat = math.exp(float(np.log(pb).sum()) / len(pb)) * len(pb) / tot
        mel = self.mel @ pb
        # floor 30 dB under the mean band energy: silence and faint bands do not swing the cepstra
        cep = self.dct @ np.log(mel + 1e-3 * float(mel.sum()) / N_MEL + 1e-10)
        ac = _fft.irfft(p[: self.kmax], self.nac)
        r = ac[self.jmin:self.jmax] * (self.wac_inv / (ac[0] + 1e-12))
        # the shortest lag whose correlation comes within NEAR_MAX of the best (a periodic sound
        # correlates as well at 2T, 3T, ... as at T; the grid of ~0.1 ms can favour a multiple),
        # then up to its local peak
        i = int(np.argmax(r - self.octave_cost))
        i = int(np.argmax(r >= r[i] - NEAR_MAX))
        while i + 1 < len(r) and r[i + 1] > r[i]:
            i += 1
        voi = min(1.0, max(0.0, float(r[i])))
        lag = float(self.jmin + i)
        if 0 < i < len(r) - 1:  # parabolic interpolation of the peak's lag
            a, b, c = float(r[i - 1]), float(r[i]), float(r[i + 1])
            den = a - 2.0 * b + c
            if den < 0.0:
                lag += 0.5 * (a - c) / den
        H = self.hist
        H[:-1] = H[1:]
        row = H[-1]
        row[0], row[1], row[2], row[3], row[4] = e, voi, math.log2(self.sr_ac / lag), hf, flat
        row[5] = float(np.abs(cep - H[-2, 6:-1]).sum()) / N_CEP
        row[6:-1] = cep
        self._last = (e, voi, hf, flat)

    def features(self) -> np.ndarray:
        """The feature vector (``FEATURES`` order) after the last :meth:`push`."""
        e, voi, hf, flat = self._last
        H, ns, nl, W = self.hist, self.ns, self.nl, self.weights
        E = H[:, 0]
        top = float(E.max())
        act = E > top - ACTIVE_DB
        W[0] = act
        W[1] = act & (H[:, 1] > 0.5)
        W[2] = W[0] * self.short_mask
        # sums of every column (and of its square) over: the active frames, the voiced active
        # frames, the active frames of the short window (the last column of H is 1: the counts)
        S1 = (W @ H).tolist()
        S2 = (W @ (H * H)).tolist()
        na, nv = S1[0][-1], S1[1][-1]

        def mean(w, c):
            return S1[w][c] / S1[w][-1] if S1[w][-1] > 0 else 0.0

        def sd(w, c):
            n = S1[w][-1]
            if n < 2:
                return 0.0
            m = S1[w][c] / n
            return math.sqrt(max(S2[w][c] / n - m * m, 0.0))

        cep_std = sum(sd(0, c) for c in range(6, 6 + N_CEP)) / N_CEP
        traj = np.maximum(E, top - 40.0)
        traj -= float(traj.sum()) / nl
        # the level's spread over the last second and the short window (dB), at most 40 dB under its top
        e_std_l = math.sqrt(float(np.dot(traj, traj)) / nl)
        ts = traj[-ns:]
        e_std_s = math.sqrt(max(float(np.dot(ts, ts)) / ns - (float(ts.sum()) / ns) ** 2, 0.0))
        v = self.mod_dft @ traj
        v *= v
        ms = v[: self.n_mod] + v[self.n_mod:]
        mod = float(ms @ self.mod_band) / (float(ms.sum()) + 1e-12)
        ac = np.correlate(traj, traj, "full")
        per = float(ac[nl - 1 + self.lag_lo: nl + self.lag_hi].max()) / (float(ac[nl - 1]) + 1e-12)
        # the spectral shape's periodicity: the autocorrelation of the (centred) cepstra of the
        # active frames, summed over coefficients, at the call-period lags (0.12-0.33 s)
        C = H[:, 6:-1] * act[:, None]
        C = C - (C.sum(axis=0) / max(na, 1.0)) * act[:, None]
        from scipy import fft as _fft  # imported on first use (scipy.fft ~0.15 s at start-up)

        R = _fft.irfft(np.abs(_fft.rfft(C, 2 * nl, axis=0)) ** 2, 2 * nl, axis=0).sum(axis=1)
        cper = float(R[self.lag_lo:self.lag_hi + 1].max()) / (float(R[0]) + 1e-12)
        return np.array([
            e - top, voi, hf, flat,
            e_std_s, mean(2, 1), mean(2, 3), mean(2, 5),
            e_std_l, mod, per, mean(0, 1), nv / max(na, 1.0),
            mean(1, 2) if nv >= 2 else 7.0, 12.0 * sd(1, 2), cep_std, mean(0, 5), mean(0, 3), sd(0, 3),
            mean(0, 4), cper, e - self.peak_db, mean(0, 0) - self.peak_db,
        ])


@dataclass
class Model:
    """A small multi-layer perceptron: standardised features -> laughter probability.

    ``p = sigmoid(W_L tanh(... tanh(W_1 z + b_1) ...) + b_L)`` with
    ``z = (x - mean) / scale``.  Loaded from a JSON file written by
    ``python -m laughlab.detector.fit`` (``laughlab/data/detector.json``).
    """

    mean: np.ndarray
    scale: np.ndarray
    weights: list
    biases: list
    meta: dict

    @classmethod
    def load(cls, path=None) -> "Model":
        if path is None:
            text = resources.files("laughlab").joinpath("data", "detector.json").read_text(encoding="utf-8")
        else:
            with open(path, encoding="utf-8") as fh:
                text = fh.read()
        d = json.loads(text)
        if tuple(d["features"]) != FEATURES:
            raise ValueError("the detector model was fitted on other features; refit: python -m laughlab.detector.fit")
        return cls(np.array(d["mean"]), np.array(d["scale"]), [np.array(w) for w in d["weights"]],
                   [np.array(b) for b in d["biases"]], d)

    def logit(self, x: np.ndarray) -> np.ndarray:
        """Logit of the laughter probability; ``x`` is (D,) or (N, D)."""
        h = (np.asarray(x) - self.mean) / self.scale
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = h @ w + b
            if i < last:
                h = np.tanh(h)
        return h[..., 0]

    def prob(self, x: np.ndarray) -> np.ndarray:
        z = np.clip(self.logit(x), -30.0, 30.0)
        return 1.0 / (1.0 + np.exp(-z))

    def prob_at(self, x: np.ndarray, level_dbfs) -> np.ndarray:
        """The laughter probability, 0 where the window's level is below ``SILENCE_DBFS`` (silence)."""
        return np.where(np.asarray(level_dbfs) < SILENCE_DBFS, 0.0, self.prob(x))


@dataclass
class GateParams:
    """The gate's rule (hysteresis on the laughter probability).

    The defaults maximise the gate's frame F1 in 2-fold cross-validation over the
    train split's scenes (open_at 0.5-0.7, open_s 0.05-0.15 s, hold_s 0.1-0.25 s);
    the test split was not used to choose them.

    Attributes
    ----------
    open_at : float
        The gate opens when the probability has stayed at or above ``open_at`` ...
    open_s : float
        ... for ``open_s`` (s; 0: at once): a lone frame of laughter-like sound does not open it ...
    close_below : float
        ... and closes once it has stayed below ``close_below`` for ``hold_s``.
    hold_s : float
        Time below ``close_below`` before the gate closes (s): bridges the gaps between calls.
    attack_s, release_s : float
        Time for the gain to go from 0 to 1 once open, and from 1 to 0 once closed (s).
    """

    open_at: float = 0.7
    open_s: float = 0.1
    close_below: float = 0.3
    hold_s: float = 0.1
    attack_s: float = 0.05
    release_s: float = 0.25

    def __post_init__(self) -> None:
        for k in ("open_at", "close_below"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f"{k} must be a number in [0, 1] (got {v})")
        check_hysteresis(self, "close_below", "open_at")
        check_non_negative(self, ("open_s", "hold_s", "attack_s", "release_s"))


def check_hysteresis(params, low: str, high: str) -> None:
    """A gate's two thresholds in order: 0 <= ``low`` <= ``high`` <= 1 (ValueError naming both)."""
    lo, hi = getattr(params, low), getattr(params, high)
    if not (0.0 <= lo <= hi <= 1.0):
        raise ValueError(f"need 0 <= {low} <= {high} <= 1 (got {high}={hi}, {low}={lo})")


def check_non_negative(params, names) -> None:
    """Each of ``names`` (times, levels) a finite number >= 0 (ValueError naming the first that is not)."""
    for k in names:
        v = getattr(params, k)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{k} must be a number >= 0 (got {v})")


class Gate:
    """Hysteresis gate: ``open`` state from the probability, ``gain`` ramps toward it.

    Per frame of length dt: if closed, ``p >= open_at`` for ``open_s`` in a row opens it (the frame
    that completes ``open_s``, counting itself).  If open: ``p < close_below``
    for ``hold_s`` in a row closes it.  The gain moves toward 1 (open) by
    ``dt / attack_s`` and toward 0 (closed) by ``dt / release_s`` per frame.
    """

    def __init__(self, params: GateParams, dt: float):
        self.p = params
        self.dt = dt
        self.reset()

    def reset(self) -> None:
        self.open = False
        self.above_s = 0.0
        self.below_s = 0.0
        self.gain = 0.0

    def step(self, prob: float) -> float:
        p = self.p
        if not self.open:
            self.above_s = self.above_s + self.dt if prob >= p.open_at else 0.0
            if prob >= p.open_at and self.above_s >= p.open_s - 1e-9:
                self.open, self.below_s = True, 0.0
        else:
            self.below_s = self.below_s + self.dt if prob < p.close_below else 0.0
            if self.below_s >= p.hold_s:
                self.open = False
        if self.open:
            self.gain = 1.0 if p.attack_s <= 0 else min(1.0, self.gain + self.dt / p.attack_s)
        else:
            self.gain = 0.0 if p.release_s <= 0 else max(0.0, self.gain - self.dt / p.release_s)
        return self.gain


def probabilities(audio: np.ndarray, sample_rate: int, fps: float, model: Model | None = None) -> tuple:
    """Per-frame features and laughter probability of a whole signal (the streaming code, frame by frame).

    Returns ``(features (N, D), prob (N,), level_dbfs (N,))``; frame ``k`` holds samples
    ``[round(k sr/fps), round((k+1) sr/fps))`` as every source cuts them.
    """
    fs = FeatureStream(sample_rate, fps)
    n = int(math.ceil(len(audio) * fps / sample_rate))
    feats = np.empty((n, len(FEATURES)))
    level = np.empty(n)
    for k in range(n):
        a, b = int(round(k * sample_rate / fps)), int(round((k + 1) * sample_rate / fps))
        feats[k] = fs.step(audio[a:b])
        level[k] = fs.level_dbfs
    return feats, model.prob_at(feats, level) if model is not None else None, level


#: control signals multiplied by the gate's gain (what drives bodies, faces and schedulers)
GATED_GAIN = ("mcs", "pressure")
#: control events dropped while the gain is below one half
GATED_EVENTS = ("call_onset",)
#: the pseudo-phoneme label given to frames while the gain is below one half
SILENT_LABEL = "silence"


def apply_gate(frame, gain: float) -> None:
    """Gate a frame's driving signals (the rule the ``laugh`` detector documents).

    ``mcs`` and ``pressure`` are multiplied by ``gain`` (their ungated values stay in
    ``mcs_ungated``/``pressure_ungated``); below a gain of 0.5, ``call_onset`` is 0 and
    the pseudo-phoneme label is ``silence``.  Other controls (``rms``, ``intensity``,
    ``f0``) are measurements of the sound and pass unchanged.
    """
    if not 0.0 <= gain <= 1.0:   # a gain above 1 drove mcs past 1, blamed on the extractor (a plugin author's review)
        raise ValueError(f"apply_gate: the gain is 0-1 (got {gain!r})")
    c = frame.control
    for k in GATED_GAIN:
        if k in c:
            c[k + "_ungated"] = c[k]
            c[k] = c[k] * gain
    if gain < 0.5:
        for k in GATED_EVENTS:
            if k in c:
                c[k] = 0.0
        if frame.label is not None:
            frame.label = SILENT_LABEL


def clip_allowed(control) -> bool:
    """May a full-body clip start on this frame?  Yes unless a detector set ``clip_gate`` below 0.5
    (``detector=yamnet``: clips wait for the model to agree)."""
    g = control.get("clip_gate")
    return g is None or g >= 0.5


def energy_drive(control) -> float:
    """The ``mcs`` that feeds the energy scheduler's laughing energy (van Duijn 2014, Eq. 4.1): ``mcs`` as the
    detector left it, i.e. under ``detector=yamnet`` scaled by the face gain, which opens at once on a new
    sound: a laugh builds its energy while the model listens, and its clip starts as soon as
    ``clip_allowed``."""
    return control["mcs"]


def clip_drive(control) -> float:
    """The ``mcs`` the concat scheduler reads (it plays segments all the time, so it has no start to hold
    back): ``mcs``, or ``mcs_ungated * clip_gate`` when a detector set ``clip_gate`` (``detector=yamnet``:
    full-body laughter waits for the model while the face answers)."""
    g = control.get("clip_gate")
    if g is None:
        return control["mcs"]
    return control["mcs_ungated"] * g if "mcs_ungated" in control else control["mcs"] * g
