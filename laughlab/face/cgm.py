"""Contextual Gaussian model of lips and jaw from prosody (Ding et al. 2014, 4.1, Eqs. 1-3).

A contextual Gaussian model (CGM) is a Gaussian over the lip and jaw
articulation ``x`` (dimension d) whose mean depends linearly on a context
``theta`` (dimension c, here the prosody: intensity and F0)::

    mu(theta) = W theta + mu_bar                                            (1)
    p(x | theta) = N(x; mu(theta), Sigma)                                   (2)

With ``Z = [W mu_bar]`` (d x (c + 1)) and ``Omega_t = [theta_t 1]^T`` the mean is
``mu(theta_t) = Z Omega_t``, and the maximum-likelihood estimate from one
training sequence ``(x_t, theta_t)`` is (Eq. 3)::

    Z = [sum_t x_t Omega_t^T] [sum_t Omega_t Omega_t^T]^-1                   (3)

(the least-squares solution; the paper prints no estimate of the covariance).
The covariance's maximum-likelihood estimate is the mean outer product of the
residuals::

    Sigma = (1/T) sum_t (x_t - Z Omega_t)(x_t - Z Omega_t)^T                (3b)

When ``sum Omega Omega^T`` is singular (a context that never varies, e.g. F0 = 0
in every unvoiced frame) its Moore-Penrose pseudo-inverse is used: the
minimum-norm solution, which gives that context a weight of 0.  One CGM per
pseudo-phoneme: :class:`CGMSet`.  Synthesis in real time (Ding's choice) is the
mean ``mu(theta_t)`` of the current pseudo-phoneme's model.

Here ``theta = (intensity dB, F0 Hz)`` (:data:`CONTEXT`) and ``x = (jaw,
lip_open, lip_corner)`` (:data:`OUTPUTS`), all in [0, 1]: jaw opening, lip
aperture, lip-corner pull (spread/smile; 0 = neutral or rounded).

The bundled default model
-------------------------
AVLaughterCycle (the paper's training data) is not available, so the default
model (``laughlab/data/cgm_default.json``) is fitted on data generated from the
synthetic laughter (:mod:`laughlab.synth.laughter`) by the articulatory mapping below;
:func:`fit_default` regenerates it and ``python -m laughlab.face.cgm`` rewrites the
file byte for byte (``--check`` compares).

Contexts (per frame at 60 fps, as the ``phoneme`` extractor sees them):

* intensity: Praat's intensity (dB re 2e-5, samples taken as Pa) of the last
  40 ms of audio before the frame's end, mean removed; a rectangular window
  (the extractor uses Praat's Kaiser window: within about 1 dB on these signals);
* F0: the call's F0 from the ground truth in voiced frames, 0 elsewhere.

Labels from the ground truth at the window's centre: inside a call where the
truth envelope is at least 40 % of the call's intensity (the voiced part: the
breathy onset peaks at 35 %) ``a``; elsewhere inside a call (the breathy 'h'
onset and the decay) ``fricative``; outside calls ``silence`` (the weak breath
between the calls of a bout mostly lies below the ``phoneme`` extractor's
silence threshold, so it labels those frames silence too) -- the three classes
the synthetic laughter holds.  The other eleven classes
borrow the contexts and truth of the nearest of these: the voiced classes (e,
o, ic, vowel, nasal, glotstop, grunt, cackle) those of ``a`` -- grunt with F0
x 0.35 and cackle with F0 x 2.2, which moves the synthetic 200-450 Hz below
130 Hz and above 700 Hz, the ``phoneme`` extractor's grunt and cackle rules --
and the unvoiced ones (ne, click, plosive) those of ``fricative``; each class
then gets its own articulation.

**Articulatory mapping** (ours).  With ``E`` the truth envelope (call intensity
times its amplitude envelope, 0..1), ``B`` the bout's intensity (0 outside
bouts) and per class an openness ``o``, a lip-to-jaw ratio ``r``, a lip offset
``l`` and a corner factor ``s`` (:data:`ARTICULATION`)::

    jaw        = clip(0.3 B + 0.7 o E + n_1)
    lip_open   = clip(r jaw + l B + n_2)
    lip_corner = clip(s (0.6 B + 0.3 E) + n_3)

with ``n_k ~ N(0, 0.02^2)`` (seeded) and clip to [0, 1].  The more intense the
laughter the wider the mouth opens (Ruch & Ekman 2001; van Duijn 2014, 3.3.2);
the bout keeps the jaw partly open and the smile on between its calls
(whatever the class); the classes shape each call's opening and the lips:
``a`` open, ``e``/``ic`` spread, ``o`` rounded (corners drawn in, smaller
aperture), ``nasal`` lips closed, ``plosive`` lips released.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = [
    "CONTEXT",
    "OUTPUTS",
    "ARTICULATION",
    "CGM",
    "CGMSet",
    "omega",
    "fit_cgm",
    "training_data",
    "fit_default",
    "default_path",
    "load_default",
    "main",
]

CONTEXT: tuple[str, ...] = ("intensity_db", "f0_hz")
"""Context variables theta: Praat intensity (dB re 2e-5) and F0 (Hz, 0 = unvoiced)."""

OUTPUTS: tuple[str, ...] = ("jaw", "lip_open", "lip_corner")
"""Articulation x: jaw opening, lip aperture, lip-corner pull, each in [0, 1]."""

ARTICULATION: dict[str, tuple[float, float, float, float]] = {
    # class:      (o openness, r lip/jaw, l lip offset, s corner)
    "silence":   (0.10, 0.8, 0.00, 0.8),
    "fricative": (0.45, 1.0, 0.05, 0.8),
    "a":         (1.00, 1.0, 0.05, 1.0),
    "e":         (0.60, 1.0, 0.05, 1.1),
    "ic":        (0.40, 0.9, 0.05, 1.2),
    "o":         (0.70, 0.7, 0.00, 0.4),
    "vowel":     (0.80, 1.0, 0.05, 1.0),
    "cackle":    (0.90, 1.0, 0.05, 1.1),
    "grunt":     (0.50, 0.8, 0.00, 0.7),
    "nasal":     (0.30, 0.0, 0.00, 0.9),
    "ne":        (0.30, 0.3, 0.00, 0.9),
    "click":     (0.15, 1.0, 0.05, 0.8),
    "plosive":   (0.30, 1.2, 0.10, 0.8),
    "glotstop":  (0.60, 1.0, 0.05, 0.9),
}
"""Articulatory mapping parameters per pseudo-phoneme (see the module docstring)."""

#: class -> (synthetic class whose contexts it borrows, F0 factor)
BORROW: dict[str, tuple[str, float]] = {
    "silence": ("silence", 1.0), "fricative": ("fricative", 1.0), "a": ("a", 1.0),
    "e": ("a", 1.0), "ic": ("a", 1.0), "o": ("a", 1.0), "vowel": ("a", 1.0), "nasal": ("a", 1.0),
    "glotstop": ("a", 1.0), "grunt": ("a", 0.35), "cackle": ("a", 2.2),
    "ne": ("fricative", 1.0), "click": ("fricative", 1.0), "plosive": ("fricative", 1.0),
}

#: the training corpus of the bundled model: synthetic laughter (seed, profile), 60 s each
TRAIN_RUNS: tuple[tuple[int, str], ...] = ((0, "mixed"), (1, "intense"), (2, "mild"), (3, "continuous"),
                                           (4, "mixed"), (5, "intense_fading"))
TRAIN_DURATION_S = 60.0
TRAIN_FPS = 60.0
TRAIN_SAMPLE_RATE = 16000
WINDOW_S = 0.04
NOISE_SD = 0.02
NOISE_SEED = 2014
VOICED_SHARE = 0.4
PRAAT_REF_POWER = 4.0e-10
SIGNIFICANT_DIGITS = 10
"""Digits kept in the saved file, so that it does not change with the last bits of the arithmetic."""


def omega(theta) -> np.ndarray:
    """``Omega_t = [theta_t 1]^T`` (Eq. 1-2); for ``(T, c)`` contexts, rows ``[theta_t, 1]``."""
    theta = np.asarray(theta, dtype=np.float64)
    return np.concatenate([theta, np.ones(theta.shape[:-1] + (1,))], axis=-1)


@dataclass(frozen=True, eq=False)
class CGM:
    """One contextual Gaussian model (Eqs. 1-3).

    Attributes
    ----------
    Z : ndarray (d, c + 1)
        ``[W mu_bar]``.
    sigma : ndarray (d, d)
        Covariance of x given theta (Eq. 2).
    n : int
        Training frames.
    theta_mean : ndarray (c,)
        Mean training context (stands in for a missing context at synthesis).
    """

    Z: np.ndarray
    sigma: np.ndarray
    n: int = 0
    theta_mean: np.ndarray | None = None

    @property
    def W(self) -> np.ndarray:
        """The d x c context weights of Eq. 1."""
        return self.Z[:, :-1]

    @property
    def mu_bar(self) -> np.ndarray:
        """The offset of Eq. 1."""
        return self.Z[:, -1]

    def mean(self, theta) -> np.ndarray:
        """``mu(theta) = Z Omega`` (Eq. 1); ``theta`` (c,) or (T, c)."""
        return omega(theta) @ self.Z.T

    def logpdf(self, x, theta) -> np.ndarray:
        """``log N(x; mu(theta), Sigma)`` (Eq. 2)."""
        r = np.asarray(x, dtype=np.float64) - self.mean(theta)
        d = self.Z.shape[0]
        sign, logdet = np.linalg.slogdet(self.sigma)
        sol = np.linalg.solve(self.sigma, np.atleast_2d(r).T).T.reshape(r.shape)
        return -0.5 * (np.sum(r * sol, axis=-1) + logdet + d * math.log(2.0 * math.pi))

    def sample(self, theta, rng: np.random.Generator) -> np.ndarray:
        """Draws from Eq. 2 at each context."""
        mu = self.mean(theta)
        return mu + rng.multivariate_normal(np.zeros(len(self.sigma)), self.sigma, size=mu.shape[:-1])


def fit_cgm(x, theta) -> CGM:
    """Maximum-likelihood CGM from pairs ``(x_t, theta_t)`` (Eq. 3 and 3b).

    Parameters
    ----------
    x : array (T, d)
    theta : array (T, c)

    Returns
    -------
    CGM
        ``Z = [sum x Omega^T][sum Omega Omega^T]^+`` (pseudo-inverse: the inverse
        when it exists), ``Sigma`` the mean outer product of the residuals.
    """
    x = np.asarray(x, dtype=np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    if x.ndim != 2 or theta.ndim != 2 or len(x) != len(theta) or len(x) == 0:
        raise ValueError(f"x (T, d) and theta (T, c) need the same T > 0 (got {x.shape}, {theta.shape})")
    om = omega(theta)
    a = x.T @ om                      # sum_t x_t Omega_t^T, (d, c+1)
    b = om.T @ om                     # sum_t Omega_t Omega_t^T, (c+1, c+1)
    try:
        z = np.linalg.solve(b.T, a.T).T if np.linalg.cond(b) < 1e12 else a @ np.linalg.pinv(b)
    except np.linalg.LinAlgError:
        z = a @ np.linalg.pinv(b)
    r = x - om @ z.T
    sigma = r.T @ r / len(x)
    return CGM(z, sigma, len(x), theta.mean(axis=0))


class CGMSet:
    """One CGM per pseudo-phoneme class, with fit, save and load.

    Parameters
    ----------
    models : dict[str, CGM]
    context, outputs : sequence of str
        Names of the context variables and of the articulation.
    meta : dict, optional
        Free-form description saved with the models.
    """

    def __init__(self, models: Mapping[str, CGM], context: Sequence[str] = CONTEXT,
                 outputs: Sequence[str] = OUTPUTS, meta: dict | None = None):
        self.models = dict(models)
        self.context, self.outputs = tuple(context), tuple(outputs)
        self.meta = dict(meta or {})
        for label, m in self.models.items():
            if m.Z.shape != (len(self.outputs), len(self.context) + 1):
                raise ValueError(f"model {label!r}: Z has shape {m.Z.shape}, expected "
                                 f"({len(self.outputs)}, {len(self.context) + 1})")

    @classmethod
    def fit(cls, x, theta, labels, **kw) -> "CGMSet":
        """Fit one CGM per distinct label (Eq. 3 on the frames of that label)."""
        x, theta = np.asarray(x, dtype=np.float64), np.asarray(theta, dtype=np.float64)
        labels = np.asarray(labels)
        models = {str(c): fit_cgm(x[labels == c], theta[labels == c]) for c in sorted(set(labels.tolist()))}
        return cls(models, **kw)

    def __contains__(self, label: str) -> bool:
        return label in self.models

    def __getitem__(self, label: str) -> CGM:
        return self.models[label]

    def mean(self, label: str, theta) -> np.ndarray:
        """``mu(theta)`` of the model of ``label`` (Eq. 1)."""
        return self.models[label].mean(theta)

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        def r(a):
            return [float(f"{v:.{SIGNIFICANT_DIGITS}g}") + 0.0 for v in np.asarray(a, float).ravel()]

        return {
            "format": "laughlab-cgm-1",
            "context": list(self.context),
            "outputs": list(self.outputs),
            "meta": self.meta,
            "models": {k: {"Z": [r(row) for row in m.Z], "sigma": [r(row) for row in m.sigma], "n": int(m.n),
                           "theta_mean": r(m.theta_mean if m.theta_mean is not None else np.zeros(len(self.context)))}
                       for k, m in sorted(self.models.items())},
        }

    @classmethod
    def from_dict(cls, d: dict) -> "CGMSet":
        if d.get("format") != "laughlab-cgm-1":
            raise ValueError(f"not a laughlab CGM file (format {d.get('format')!r})")
        models = {k: CGM(np.array(m["Z"], float), np.array(m["sigma"], float), int(m["n"]),
                         np.array(m["theta_mean"], float)) for k, m in d["models"].items()}
        return cls(models, d["context"], d["outputs"], d.get("meta"))

    def dumps(self) -> str:
        """The JSON text of :meth:`save` (deterministic: sorted keys, 10 significant digits)."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=True) + "\n"

    def save(self, path) -> Path:
        """Write to ``path``: JSON (``.json``) or numpy (``.npz``)."""
        path = Path(path)
        if path.suffix == ".npz":
            arrays = {}
            for k, m in self.models.items():
                arrays[f"{k}/Z"], arrays[f"{k}/sigma"] = m.Z, m.sigma
                arrays[f"{k}/n"] = np.array(m.n)
                arrays[f"{k}/theta_mean"] = m.theta_mean if m.theta_mean is not None else np.zeros(len(self.context))
            header = json.dumps({"format": "laughlab-cgm-1", "context": self.context, "outputs": self.outputs,
                                 "meta": self.meta, "labels": sorted(self.models)})
            np.savez(path, __header__=np.array(header), **arrays)
        else:
            path.write_text(self.dumps(), encoding="utf-8")
        return path

    @classmethod
    def load(cls, path) -> "CGMSet":
        """Read a file written by :meth:`save` (``.npz`` or JSON)."""
        path = Path(path)
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as f:
                head = json.loads(str(f["__header__"]))
                models = {k: CGM(f[f"{k}/Z"], f[f"{k}/sigma"], int(f[f"{k}/n"]), f[f"{k}/theta_mean"])
                          for k in head["labels"]}
            return cls(models, head["context"], head["outputs"], head.get("meta"))
        return cls.from_dict(json.loads(path.read_text(encoding="utf-8")))


# ---------------------------------------------------------------------- training data
def _intensity(audio: np.ndarray, ends: np.ndarray, n_win: int) -> np.ndarray:
    """Praat intensity (dB re 2e-5, mean removed, rectangular window) of the ``n_win`` samples before each end."""
    x = np.concatenate([np.zeros(n_win), np.asarray(audio, dtype=np.float64)])
    c1 = np.concatenate([[0.0], np.cumsum(x)])
    c2 = np.concatenate([[0.0], np.cumsum(x * x)])
    e = ends + n_win
    s1, s2 = c1[e] - c1[e - n_win], c2[e] - c2[e - n_win]
    var = np.maximum(s2 / n_win - (s1 / n_win) ** 2, 0.0)
    return 10.0 * np.log10(np.maximum(var, PRAAT_REF_POWER) / PRAAT_REF_POWER)


def articulate(label: str, env: np.ndarray, bout: np.ndarray, rng: np.random.Generator,
               noise_sd: float = NOISE_SD) -> np.ndarray:
    """The articulatory mapping (module docstring): ``(T, 3)`` = jaw, lip_open, lip_corner."""
    o, r, l, s = ARTICULATION[label]
    n = rng.normal(0.0, noise_sd, (len(env), 3)) if noise_sd > 0 else np.zeros((len(env), 3))
    jaw = np.clip(0.3 * bout + 0.7 * o * env + n[:, 0], 0.0, 1.0)
    lip = np.clip(r * jaw + l * bout + n[:, 1], 0.0, 1.0)
    corner = np.clip(s * (0.6 * bout + 0.3 * env) + n[:, 2], 0.0, 1.0)
    return np.column_stack([jaw, lip, corner])


def synthetic_frames(seed: int, profile: str, duration_s: float = TRAIN_DURATION_S, fps: float = TRAIN_FPS,
                     sample_rate: int = TRAIN_SAMPLE_RATE) -> dict:
    """Per-frame contexts and truth of one synthetic laughter (see the module docstring).

    Returns
    -------
    dict
        ``theta`` (T, 2), ``label`` (T,) in {silence, fricative, a}, ``env`` and ``bout`` (T,).
    """
    from laughlab.synth.laughter import SyntheticLaughter

    s = SyntheticLaughter(seed=seed, duration_s=duration_s, sample_rate=sample_rate, profile=profile)
    audio = s.audio()
    n_frames = int(round(duration_s * fps))
    ends = np.round(np.arange(1, n_frames + 1) * (sample_rate / fps)).astype(np.int64)
    ends = np.minimum(ends, len(audio))
    n_win = int(round(WINDOW_S * sample_rate))
    intensity = _intensity(audio, ends, n_win)
    t = ends / sample_rate - WINDOW_S / 2.0
    env = s.intensity_envelope(t)
    bout = np.zeros(n_frames)
    for b in s.bouts:
        bout[(t >= b.onset_s) & (t < b.offset_s)] = b.intensity
    voiced = np.zeros(n_frames, bool)
    in_call = np.zeros(n_frames, bool)
    f0 = np.zeros(n_frames)
    for c in s.calls:
        inside = (t >= c.onset_s) & (t < c.offset_s)
        in_call |= inside
        v = inside & (env >= VOICED_SHARE * c.intensity)
        voiced |= v
        f0[v] = c.f0_hz
    label = np.where(voiced, "a", np.where(in_call, "fricative", "silence"))
    return {"theta": np.column_stack([intensity, f0]), "label": label, "env": env, "bout": bout}


def training_data(runs: Sequence[tuple[int, str]] = TRAIN_RUNS, noise_sd: float = NOISE_SD,
                  noise_seed: int = NOISE_SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bundled model's training set: ``x`` (N, 3), ``theta`` (N, 2), ``labels`` (N,).

    Every class of :data:`ARTICULATION` gets the frames of the synthetic class it
    borrows (:data:`BORROW`, F0 scaled), articulated by :func:`articulate` with
    noise from one generator seeded by ``noise_seed`` (classes in sorted order).
    """
    frames = [synthetic_frames(seed, profile) for seed, profile in runs]
    theta = np.concatenate([f["theta"] for f in frames])
    label = np.concatenate([f["label"] for f in frames])
    env = np.concatenate([f["env"] for f in frames])
    bout = np.concatenate([f["bout"] for f in frames])
    rng = np.random.default_rng(noise_seed)
    xs, ts, ls = [], [], []
    for cls in sorted(ARTICULATION):
        src, f0_factor = BORROW[cls]
        m = label == src
        th = theta[m].copy()
        th[:, 1] *= f0_factor
        xs.append(articulate(cls, env[m], bout[m], rng, noise_sd))
        ts.append(th)
        ls.append(np.full(int(m.sum()), cls))
    return np.concatenate(xs), np.concatenate(ts), np.concatenate(ls)


def fit_default() -> CGMSet:
    """Fit the bundled default model (14 classes) on :func:`training_data`."""
    x, theta, labels = training_data()
    meta = {
        "source": "laughlab.face.cgm.fit_default: synthetic laughter, articulatory mapping (see laughlab/face/cgm.py)",
        "runs": [f"seed {s} {p}" for s, p in TRAIN_RUNS],
        "duration_s": TRAIN_DURATION_S, "fps": TRAIN_FPS, "window_s": WINDOW_S, "noise_sd": NOISE_SD,
        "noise_seed": NOISE_SEED,
    }
    return CGMSet.fit(x, theta, labels, meta=meta)


def default_path() -> Path:
    """The bundled model file."""
    return Path(__file__).resolve().parents[1] / "data" / "cgm_default.json"


_DEFAULT: CGMSet | None = None


def load_default() -> CGMSet:
    """The bundled model (loaded once)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = CGMSet.load(default_path())
    return _DEFAULT


def main(argv: list[str] | None = None) -> int:
    """``python -m laughlab.face.cgm [--check] [--out PATH]``: regenerate (or check) the bundled model."""
    ap = argparse.ArgumentParser(prog="python -m laughlab.face.cgm", description=main.__doc__)
    ap.add_argument("--out", default=str(default_path()), help="file to write (default: the bundled model)")
    ap.add_argument("--check", action="store_true", help="only compare with the file; exit 1 if it differs")
    args = ap.parse_args(argv)
    text = fit_default().dumps()
    out = Path(args.out)
    if args.check:
        same = out.exists() and out.read_text(encoding="utf-8") == text
        print(f"{out}: {'up to date' if same else 'DIFFERS from a fresh fit'}")
        return 0 if same else 1
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
