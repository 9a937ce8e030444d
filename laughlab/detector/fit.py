"""Fit the laughter detector's model on the *train* split and write ``laughlab/data/detector.json``.

``python -m laughlab.detector.fit`` (after ``python -m laughlab corpus fetch``)
regenerates the bundled model byte for byte: the scenes are seeded, the fit
(scikit-learn's ``MLPClassifier``, L-BFGS, fixed ``random_state``) is
deterministic, and the weights are written with 7 significant digits.
``--check`` refits and compares with the bundled file instead of writing.

Training data (all from the train split, see ``laughlab.corpora.sources``):
scenes of real laughs spliced between speech turns, coughs, music and noise
over room noise at SNRs of inf/20/10/5 dB (``laughlab.corpora.mixed``), each
coloured by a random microphone/room response (``channel``: tilt and low-pass), plus
the synthetic laughter generator's seven profiles, so the default pipeline's
own input still counts as laughter.  Frames below ``SILENCE_DBFS`` are not used
(the detector gives them 0).  A frame is laughter when its centre lies inside
an annotated bout.

Why scikit-learn: a tested L-BFGS MLP with reproducible seeding; only the fit
needs it (``pip install -e '.[fit]'``), the detector itself evaluates the
exported weights with numpy.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from laughlab.detector.model import FEATURES, SILENCE_DBFS, Gate, GateParams, Model, probabilities
from laughlab.core.errors import LaughlabError

FPS = 60.0
SEED = 20261123
N_SCENES = 48
SCENE_S = 40.0
SNRS = (None, 20.0, 10.0, 5.0)
HIDDEN = (32,)
#: L2 penalty of the MLP: chosen by 2-fold cross-validation over the train scenes (1, 3, 10; hidden 8, 16, 32)
ALPHA = 10.0
#: colour each training scene with a random microphone/room response (``channel``)
AUGMENT = True
OUT = Path(__file__).resolve().parents[1] / "data" / "detector.json"


def frame_labels(rows: list[dict], n: int, fps: float = FPS) -> np.ndarray:
    """1 where a frame's centre lies inside a bout of ``rows`` (truth rows), else 0."""
    y = np.zeros(n)
    mid = (np.arange(n) + 0.5) / fps
    for r in rows:
        if r["kind"] == "bout":
            y[(mid >= r["onset_s"]) & (mid < r["offset_s"])] = 1.0
    return y


def synthetic_scenes(seed: int) -> list[tuple[np.ndarray, int, list[dict]]]:
    """The generator's profiles at 16 kHz (its default rate), 30 s each, with truth rows."""
    from laughlab.synth.laughter import PROFILES, SyntheticLaughter

    out = []
    for i, prof in enumerate(PROFILES):
        s = SyntheticLaughter(seed=seed + i, duration_s=30.0, sample_rate=16000, profile=prof)
        rows = s.truth_table().to_dict("records")
        out.append((s.audio().astype(np.float64), 16000, rows))
    return out


def channel(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random microphone and room colour: a first-order tilt (pre-emphasis a in [-0.7, 0.7]:
    brighter or duller by up to ~10 dB across the band) and, half the time, a 4th-order
    Butterworth low-pass at 3.5-8 kHz, so the model learns the laugh rather than the recording."""
    from scipy.signal import butter, lfilter, sosfilt

    from laughlab.corpora.mixed import SAMPLE_RATE

    a = rng.uniform(-0.7, 0.7)
    y = lfilter([1.0, -a], [1.0], x)
    if rng.random() < 0.5:
        y = sosfilt(butter(4, rng.uniform(3500.0, 8000.0), fs=SAMPLE_RATE, output="sos"), y)
    return y * (np.sqrt(np.mean(x * x)) / (np.sqrt(np.mean(y * y)) + 1e-12))


def dataset(split: str, n_scenes: int, seed: int, with_synthetic: bool = True, augment: bool = AUGMENT):
    """Features, labels and scene index of every non-silent frame of the scenes of ``split``."""
    from laughlab.corpora.mixed import SAMPLE_RATE, Pool, build_scene

    pool = Pool.of_split(split)
    scenes = []
    for i in range(n_scenes):
        rng = np.random.default_rng([seed, i])
        x, rows = build_scene(rng, pool, SCENE_S, SNRS[i % len(SNRS)])
        if augment:
            x = channel(x, rng)
        scenes.append((x, SAMPLE_RATE, rows))
    if with_synthetic:
        scenes += synthetic_scenes(seed)
    X, Y, G, P = [], [], [], []
    for i, (x, sr, rows) in enumerate(scenes):
        f, _, level = probabilities(x, sr, FPS)
        y = frame_labels(rows, len(f))
        keep = level >= SILENCE_DBFS
        X.append(f[keep])
        Y.append(y[keep])
        G.append(np.full(int(keep.sum()), i))
        P.append((f, y, level))
    return np.concatenate(X), np.concatenate(Y), np.concatenate(G), P


def fit(X: np.ndarray, y: np.ndarray, seed: int = 0) -> dict:
    """Standardise, fit the MLP, return the model as a JSON-able dict (weights rounded to 7 digits)."""
    try:
        from sklearn.neural_network import MLPClassifier
    except ImportError:
        raise LaughlabError("fitting the detector needs scikit-learn: pip install -e '.[fit]'") from None
    mean = X.mean(axis=0)
    scale = X.std(axis=0)
    scale[scale < 1e-9] = 1.0
    Z = (X - mean) / scale
    clf = MLPClassifier(hidden_layer_sizes=HIDDEN, activation="tanh", solver="lbfgs", alpha=ALPHA,
                        max_iter=600, random_state=seed)
    clf.fit(Z, y.astype(int))
    r = lambda a: [float(f"{v:.7g}") for v in np.ravel(a)]  # noqa: E731
    weights = [np.asarray(w).round(12) for w in clf.coefs_]
    return {
        "features": list(FEATURES),
        "mean": r(mean), "scale": r(scale),
        "weights": [[r(row) for row in w] for w in weights],
        "biases": [r(b) for b in clf.intercepts_],
    }


def gate_f1(models_prob: list[tuple[np.ndarray, np.ndarray]], gp: GateParams, fps: float = FPS) -> float:
    """Frame F1 of the gate (gain >= 0.5) against the labels, over several streams."""
    tp = fp = fn = 0
    for prob, y in models_prob:
        g = Gate(gp, 1.0 / fps)
        on = np.array([g.step(float(p)) for p in prob]) >= 0.5
        tp += int((on & (y > 0)).sum())
        fp += int((on & (y == 0)).sum())
        fn += int((~on & (y > 0)).sum())
    return 2 * tp / max(2 * tp + fp + fn, 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m laughlab.detector.fit", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(OUT), help="where to write the model (default: the bundled file)")
    ap.add_argument("--check", action="store_true", help="refit and compare with the bundled model; write nothing")
    ns = ap.parse_args(argv)
    try:
        X, y, _, streams = dataset("train", N_SCENES, SEED)
        model = fit(X, y)
        m = Model(np.array(model["mean"]), np.array(model["scale"]), [np.array(w) for w in model["weights"]],
                  [np.array(b) for b in model["biases"]], model)
        probs = []
        for f, yy, level in streams:
            probs.append((m.prob_at(f, level), yy))
        frame_f1 = gate_f1(probs, GateParams())
        model["fit"] = {"command": "python -m laughlab.detector.fit", "split": "train", "scenes": N_SCENES,
                        "scene_s": SCENE_S, "snr_db": [s if s is not None else "inf" for s in SNRS],
                        "synthetic_profiles": 7, "frames": int(len(y)), "laughter_share": round(float(y.mean()), 4),
                        "hidden": list(HIDDEN), "alpha": ALPHA, "seed": SEED, "train_gate_f1": round(frame_f1, 4)}
        text = json.dumps(model, indent=None, separators=(",", ":")) + "\n"
    except LaughlabError as exc:
        print(f"laughlab: error: {exc}", file=sys.stderr)
        return 2
    return write_or_check(text, ns.out, OUT, ns.check, "model",
                          f"{len(y)} frames, {100 * y.mean():.1f}% laughter, train gate F1 {frame_f1:.3f}")


def write_or_check(text: str, out, bundled: Path, check: bool, what: str, summary: str,
                   tolerance: float | None = None) -> int:
    """Write a refitted file (exit 0), or with ``check`` compare it with the bundled one: 0 the same bytes,
    1 not.  ``tolerance``: a refit whose every number (weights, bias, ...) is within it of the bundled file's
    exits 3 instead of 1 (the YAMNet heads: fitted on YAMNet's scores, which XNNPACK rounds by CPU family,
    so their bytes hold on the CPU family they were fitted on only)."""
    if check:
        old = bundled.read_text(encoding="utf-8")
        if old == text:
            print(f"the bundled {what} is reproduced byte for byte")
            return 0
        if tolerance is not None:
            d = _largest_difference(json.loads(old), json.loads(text))
            if d <= tolerance:
                print(f"the refit agrees with the bundled {what} to {d:.3g} in every number, not byte for byte: "
                      "it is fitted on YAMNet's scores, which its XNNPACK kernels round by CPU family")
                return 3
        print(f"the refit differs from the bundled {what}")
        return 1
    from laughlab.core.install import clone_dir

    if clone_dir() is None and Path(out).resolve() == bundled.resolve():   # an installed wheel's own file (a
        print(f"laughlab: error: not written: {out} is the installed package's {what}; give --out PATH for the "
              "refit (a clone's make regenerates the bundled file)", file=sys.stderr)   # packaging review)
        return 2
    Path(out).write_text(text, encoding="utf-8")
    print(f"wrote {out}: {summary}")
    return 0


def _largest_difference(a, b) -> float:
    """The largest absolute difference between the numbers of two JSON documents of the same shape (inf if
    their shapes or words differ)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return max((_largest_difference(a[k], b[k]) for k in a), default=0.0) if a.keys() == b.keys() else math.inf
    if isinstance(a, list) and isinstance(b, list):
        return max((_largest_difference(x, y) for x, y in zip(a, b)), default=0.0) if len(a) == len(b) else math.inf
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return abs(float(a) - float(b))
    return 0.0 if a == b else math.inf


if __name__ == "__main__":
    raise SystemExit(main())
