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
#: below this level (dB re full scale, RMS of the window) a frame is silence
SILENCE_DBFS = -65.0
N_MEL, N_CEP = 20, 8
#: pitch candidates lose this much normalised autocorrelation per octave of lag (Boersma 1993)
OCTAVE_COST = 0.03

FEATURES = (
    "rel_db", "voicing", "hf_ratio", "flatness", "c1", "c2", "c3",
    "e_std_s", "voi_mean_s", "hf_mean_s", "dcep_s",
    "e_std_l", "mod_3_8", "env_periodicity", "voi_mean_l", "voiced_frac_l", "active_frac_l",
    "f0_mean_l", "f0_std_l", "cep_std_l", "dcep_l", "hf_mean_l", "hf_std_l", "flat_mean_l",
)


def _sd(v: np.ndarray) -> float:
    """Standard deviation (population) without ``np.std``'s per-call overhead."""
    n = len(v)
    m = float(v.sum()) / n
    return math.sqrt(max(float(np.dot(v, v)) / n - m * m, 0.0))


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
      of lag), and the pitch at that peak;
    - ``hf_ratio``: energy 2-5 kHz over 0.1-5 kHz (breathiness);
    - ``flatness``: geometric over arithmetic mean of the power spectrum;
    - ``c1..c3``: mel cepstra (20 bands, 80 Hz-5 kHz, DCT-II) of the spectral shape.

    Over the short (0.3 s) and long (1 s) history: the level's spread
    (``e_std``), mean voicing, mean breathiness, mean cepstral change between
    frames (``dcep``, speech changes formants, laughter repeats a vowel), the
    share of the level trajectory's modulation energy at 3-8 Hz (``mod_3_8``),
    its autocorrelation peak at lags 0.12-0.33 s (``env_periodicity``, regular
    calls), voiced and active shares, pitch mean (log2 Hz) and spread
    (semitones), cepstral spread and the spread of breathiness.
    """

    def __init__(self, sample_rate: int, fps: float):
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
        wac = np.fft.irfft(np.abs(np.fft.rfft(self.window, self.nfft)) ** 2, self.nfft)
        self.wac_inv = wac[0] / wac[self.lmin:self.lmax]
        # Boersma (1993) octave cost: a longer lag must be clearly better to win (no halved pitch)
        self.octave_cost = OCTAVE_COST * np.log2(np.arange(self.lmin, self.lmax) / self.lmin)
        self.fps = float(fps)
        self.nl = max(8, int(round(LONG_S * fps)))
        self.ns = max(3, int(round(SHORT_S * fps)))
        self.lag_lo, self.lag_hi = max(1, int(round(0.12 * fps))), min(self.nl - 2, int(round(0.33 * fps)))
        # the level trajectory, zero-padded to twice its length: its spectrum gives the
        # modulation band energies and (inverse) its non-circular autocorrelation
        self.nfft_mod = 2 * self.nl
        mod_f = np.fft.rfftfreq(self.nfft_mod, 1.0 / fps)
        self.mod_band = (mod_f >= 3.0) & (mod_f <= 8.0)
        self.mod_all = (mod_f >= 0.5) & (mod_f <= 15.0)
        self.reset()

    def reset(self) -> None:
        self.buf = np.zeros(self.win)
        # one row per frame of the last second: e, voi, f0 (log2 Hz), hf, flat, dcep, then the cepstra
        self.hist = np.zeros((self.nl, 6 + N_CEP))
        self.hist[:, 0] = -120.0
        self.hist[:, 2] = 7.0
        self.level_dbfs = -120.0

    def step(self, block: np.ndarray) -> np.ndarray:
        """Take one frame's samples; return the feature vector (``FEATURES`` order)."""
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
        spec = np.fft.rfft(x * self.window, self.nfft)
        p = spec.real ** 2 + spec.imag ** 2
        pb = p[self.k100: self.kmax] + 1e-12
        tot = float(pb.sum())
        e = 10.0 * math.log10(tot)
        hf = float(pb[self.k2k - self.k100:].sum()) / tot
        flat = math.exp(float(np.log(pb).sum()) / len(pb)) * len(pb) / tot
        cep = self.dct @ np.log(self.mel @ pb + 1e-10)
        p[self.kmax:] = 0.0
        ac = np.fft.irfft(p, self.nfft)
        r = ac[self.lmin:self.lmax] * (self.wac_inv / (ac[0] + 1e-12))
        i = int(np.argmax(r - self.octave_cost))
        voi = min(1.0, max(0.0, float(r[i])))
        H = self.hist
        H[:-1] = H[1:]
        row = H[-1]
        row[0], row[1], row[2], row[3], row[4] = e, voi, math.log2(self.sr / (self.lmin + i)), hf, flat
        row[5] = float(np.abs(cep - H[-2, 6:]).sum()) / N_CEP
        row[6:] = cep
        return self._features(e, voi, hf, flat, cep)

    def _features(self, e, voi, hf, flat, cep) -> np.ndarray:
        H, ns, nl = self.hist, self.ns, self.nl
        E = H[:, 0]
        top = float(E.max())
        active = (E > top - ACTIVE_DB).astype(np.float64)
        voiced = active * (H[:, 1] > 0.5)
        na, nv = float(active.sum()), float(voiced.sum())
        # masked first and second moments of every column at once
        s1 = active @ H / max(na, 1.0)
        s2 = active @ (H * H) / max(na, 1.0)
        sd = np.sqrt(np.maximum(s2 - s1 * s1, 0.0))
        a_s = active[-ns:]
        ns_a = float(a_s.sum())
        t1 = a_s @ H[-ns:, :6] / max(ns_a, 1.0)
        if nv >= 2:
            v1 = voiced @ H[:, 2] / nv
            f0_std = 12.0 * math.sqrt(max(float(voiced @ (H[:, 2] ** 2)) / nv - v1 * v1, 0.0))
        else:
            v1, f0_std = 7.0, 0.0
        traj = np.maximum(E, top - 40.0)
        traj = traj - float(traj.sum()) / nl
        ms = np.fft.rfft(traj, self.nfft_mod)
        ms = ms.real ** 2 + ms.imag ** 2
        ac = np.fft.irfft(ms, self.nfft_mod)
        mod = float(ms[self.mod_band].sum() / (ms[self.mod_all].sum() + 1e-12))
        per = float(ac[self.lag_lo:self.lag_hi + 1].max() / (ac[0] + 1e-12))
        return np.array([
            e - top, voi, hf, flat, cep[0], cep[1], cep[2],
            _sd(E[-ns:]), t1[1], t1[3], t1[5],
            _sd(E), mod, per, s1[1], nv / max(na, 1.0), na / nl,
            v1, f0_std, float(sd[6:6 + N_CEP].sum()) / N_CEP if na >= 2 else 0.0, s1[5], s1[3], sd[3], s1[4],
        ])


@dataclass
class Model:
    """A small multi-layer perceptron: standardised features -> laughter probability.

    ``p = sigmoid(W_L tanh(... tanh(W_1 z + b_1) ...) + b_L)`` with
    ``z = (x - mean) / scale``.  Loaded from a JSON file written by
    ``python -m laughlab.detector_fit`` (``laughlab/data/detector.json``).
    """

    mean: np.ndarray
    scale: np.ndarray
    weights: list
    biases: list
    meta: dict

    @classmethod
    def load(cls, path=None) -> "Model":
        if path is None:
            text = resources.files("laughlab").joinpath("data", "detector.json").read_text()
        else:
            with open(path, encoding="utf-8") as fh:
                text = fh.read()
        d = json.loads(text)
        if tuple(d["features"]) != FEATURES:
            raise ValueError("the detector model was fitted on other features; refit: python -m laughlab.detector_fit")
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


@dataclass
class GateParams:
    """The gate's rule (hysteresis on the laughter probability).

    Attributes
    ----------
    open_at : float
        The gate opens when the probability reaches ``open_at`` ...
    close_below : float
        ... and closes once it has stayed below ``close_below`` for ``hold_s``.
    hold_s : float
        Time below ``close_below`` before the gate closes (s): bridges the gaps between calls.
    attack_s, release_s : float
        Time for the gain to go from 0 to 1 once open, and from 1 to 0 once closed (s).
    """

    open_at: float = 0.5
    close_below: float = 0.3
    hold_s: float = 0.35
    attack_s: float = 0.05
    release_s: float = 0.25

    def __post_init__(self) -> None:
        for k in ("open_at", "close_below"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f"{k} must be a number in [0, 1] (got {v})")
        if not (0.0 <= self.close_below <= self.open_at <= 1.0):
            raise ValueError(f"need 0 <= close_below <= open_at <= 1 (got open_at={self.open_at}, "
                             f"close_below={self.close_below})")
        for k in ("hold_s", "attack_s", "release_s"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{k} must be a number >= 0 (got {v})")


class Gate:
    """Hysteresis gate: ``open`` state from the probability, ``gain`` ramps toward it.

    Per frame of length dt: if closed and ``p >= open_at``: open.  If open: ``p < close_below``
    for ``hold_s`` in a row closes it.  The gain moves toward 1 (open) by
    ``dt / attack_s`` and toward 0 (closed) by ``dt / release_s`` per frame.
    """

    def __init__(self, params: GateParams, dt: float):
        self.p = params
        self.dt = dt
        self.reset()

    def reset(self) -> None:
        self.open = False
        self.below_s = 0.0
        self.gain = 0.0

    def step(self, prob: float) -> float:
        p = self.p
        if not self.open:
            if prob >= p.open_at:
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
    prob = model.prob(feats) if model is not None else None
    if prob is not None:
        prob = np.where(level < SILENCE_DBFS, 0.0, prob)
    return feats, prob, level


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
