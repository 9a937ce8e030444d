"""Fit the YAMNet laughter head on the *train* split and write ``laughlab/data/yamnet/head.json``.

``python -m laughlab.detector.yamnet_fit`` (after ``python -m laughlab corpus fetch``; ``make
yamnet-head``) regenerates the bundled head byte for byte: the scenes are those of
``laughlab.detector.fit`` (seeded, train split, 20/10/5 dB and clean, coloured by a random
microphone/room response) plus the synthetic generator's seven profiles, the windows are
YAMNet's on the live 16 kHz conversion, the fit (scikit-learn's L2 logistic regression,
L-BFGS) is deterministic and the weights are written with 7 significant digits.
``--check`` refits and compares with the bundled file instead of writing; ``--gate`` and ``--rules``
print the live gate's rules on the train scenes (the thresholds of ``conf/detector/yamnet.yaml``
were chosen there, never on the test split).

A window (0.975 s, one every 0.25 s) counts as laughter when at least half of its last
0.5 s lies inside an annotated bout: the head says "laughing now", not "a laugh is
somewhere in the last second", so the gate closes soon after a laugh ends.  The
features are the logarithms of the 521 scores (plus 1e-4).  The synthetic profiles
are in the training data so the default run's own input counts as laughter (YAMNet
alone hears it as speech or animal sounds: ``docs/detector.md``).
"""
from __future__ import annotations

import argparse
import json
import sys
import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.detector.yamnet import N_CLASSES, WINDOW, Head, Yamnet, data_dir, window_scores

SEED = 20261125
N_SCENES = 48
SCENE_S = 40.0
STEP_S = 0.25
#: the part of the window a label is about (s)
LABEL_S = 0.5
EPS = 1e-4
#: inverse L2 strength of the logistic regression
C = 0.1
OUT = data_dir() / "head.json"


def window_labels(rows: list[dict], ends_s: np.ndarray) -> np.ndarray:
    """1 where at least half of ``[end - LABEL_S, end]`` lies inside the bouts of ``rows``."""
    cover = np.zeros(len(ends_s))
    for r in rows:
        if r["kind"] == "bout":
            lo = np.maximum(ends_s - LABEL_S, r["onset_s"])
            hi = np.minimum(ends_s, r["offset_s"])
            cover += np.clip(hi - lo, 0.0, None)
    return (cover >= 0.5 * LABEL_S).astype(float)


def scene_windows(model: Yamnet, x: np.ndarray, sr: int, rows: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    step = int(round(STEP_S * sr))
    ends = np.arange(int(WINDOW * sr / 16000), len(x) + 1, step)
    return window_scores(x, sr, ends, model), window_labels(rows, ends / sr)


def dataset(split: str = "train", n_scenes: int = N_SCENES, seed: int = SEED):
    """Scores (N, 521) and labels (N,) of the windows of ``split``'s scenes and the synthetic profiles."""
    from laughlab.corpora.mixed import SAMPLE_RATE, Pool, build_scene
    from laughlab.detector.fit import SNRS, channel, synthetic_scenes

    model = Yamnet()
    pool = Pool.of_split(split)
    S, Y = [], []
    for i in range(n_scenes):
        rng = np.random.default_rng([seed, i])
        x, rows = build_scene(rng, pool, SCENE_S, SNRS[i % len(SNRS)])
        x = channel(x, rng)
        s, y = scene_windows(model, x, SAMPLE_RATE, rows)
        S.append(s)
        Y.append(y)
    for x, sr, rows in synthetic_scenes(seed):
        s, y = scene_windows(model, x, sr, rows)
        S.append(s)
        Y.append(y)
    return np.concatenate(S), np.concatenate(Y)


def fit(S: np.ndarray, y: np.ndarray) -> dict:
    try:
        from sklearn.linear_model import LogisticRegression
    except ImportError:
        raise LaughlabError("fitting the head needs scikit-learn: pip install -e '.[fit]'") from None
    X = np.log(S + EPS)
    clf = LogisticRegression(C=C, max_iter=5000, solver="lbfgs")
    clf.fit(X, y.astype(int))
    r = lambda a: [float(f"{v:.7g}") for v in np.ravel(a)]  # noqa: E731
    return {"eps": EPS, "weights": r(clf.coef_[0]), "bias": r(clf.intercept_)[0]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m laughlab.detector.yamnet_fit", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(OUT), help="where to write the head (default: the bundled file)")
    ap.add_argument("--check", action="store_true", help="refit and compare with the bundled head; write nothing")
    ap.add_argument("--gate", action="store_true", help="print the live gate's opening rules on the train scenes")
    ap.add_argument("--rules", action="store_true", help="print the rules head / classes / either on the train "
                    "scenes (windows every 0.25 s)")
    ns = ap.parse_args(argv)
    if ns.rules:
        for r in rule_sweep():
            print(f"{r['rule']}: bouts found {r['bouts_found']:.3f}, openings outside laughter "
                  f"{r['false_per_10min']:.1f} per 10 min; synthetic bouts found {r['synthetic_found']:.3f}")
        return 0
    if ns.gate:
        for r in gate_sweep():
            print(f"open_at {r['open_at']:.1f}, {r['windows']} window(s) in a row: bouts found "
                  f"{r['bouts_found']:.3f}, openings outside laughter {r['false_per_10min']:.1f} per 10 min")
        return 0
    try:
        S, y = dataset()
        head = fit(S, y)
        h = Head(np.array(head["weights"]), head["bias"], head["eps"], head)
        p = h.prob(S)
        acc = float(((p >= 0.5) == (y > 0)).mean())
        head["fit"] = {"command": "python -m laughlab.detector.yamnet_fit", "split": "train", "scenes": N_SCENES,
                       "scene_s": SCENE_S, "synthetic_profiles": 7, "step_s": STEP_S, "label_s": LABEL_S,
                       "windows": int(len(y)), "laughter_share": round(float(y.mean()), 4), "C": C, "seed": SEED,
                       "train_accuracy": round(acc, 4), "classes": N_CLASSES}
        text = json.dumps(head, separators=(",", ":")) + "\n"
    except LaughlabError as exc:
        print(f"laughlab: error: {exc}", file=sys.stderr)
        return 2
    from laughlab.detector.fit import write_or_check

    return write_or_check(text, ns.out, OUT, ns.check, "head",
                          f"{len(y)} windows, {100 * y.mean():.1f}% laughter, train accuracy {acc:.3f}")



def gate_sweep(n_scenes: int = N_SCENES, seed: int = SEED) -> list[dict]:
    """The live gate's opening rule on the train scenes (``--gate``): for ``open_at`` and the number of
    windows in a row at or above it (every 0.5 s, as live), the share of bouts during which the gate opens
    (inside the bout or up to 1 s after) and the openings outside every bout per minute of non-laughter."""
    from laughlab.corpora.mixed import SAMPLE_RATE, Pool, build_scene
    from laughlab.detector.fit import SNRS, channel

    model, head = Yamnet(), Head.load()
    pool = Pool.of_split("train")
    scenes = []
    for i in range(n_scenes):
        rng = np.random.default_rng([seed, i])
        x, rows = build_scene(rng, pool, SCENE_S, SNRS[i % len(SNRS)])
        x = channel(x, rng)
        step = SAMPLE_RATE // 2
        ends = np.arange(step, len(x) + 1, step)
        scenes.append({"p": head.prob(window_scores(x, SAMPLE_RATE, ends, model)), "t": ends / SAMPLE_RATE,
                       "bouts": [(r["onset_s"], r["offset_s"]) for r in rows if r["kind"] == "bout"],
                       "dur": len(x) / SAMPLE_RATE})
    out = []
    for open_at in (0.3, 0.4, 0.5, 0.6, 0.7, 0.8):
        for run in (1, 2):
            def opened_of(sc, open_at=open_at, run=run):
                ok = sc["p"] >= open_at
                opened = ok.copy()
                for k in range(1, run):
                    opened[k:] &= ok[:-k]
                    opened[:k] = False
                return opened

            found, false = _found_false(scenes, opened_of)
            out.append({"open_at": open_at, "windows": run, "bouts_found": found, "false_per_10min": false})
    return out


def gate_windows(p: np.ndarray, q: np.ndarray, rule: str, open_at: float = 0.5, open_windows: int = 2,
                 close_below: float = 0.3, class_open: float = 0.1, class_windows: int = 1,
                 class_close: float = 0.05) -> np.ndarray:
    """The live clip gate's state after each window (``plugins/detector_yamnet.py`` without the quiet close):
    ``p`` the head's probabilities, ``q`` the laughter classes' scores, one per window."""
    head, classes = rule in ("head", "either"), rule in ("classes", "either")
    out = np.zeros(len(p), bool)
    is_open, run, qrun = False, 0, 0
    for i in range(len(p)):
        run = run + 1 if p[i] >= open_at else 0
        qrun = qrun + 1 if q[i] >= class_open else 0
        if (head and run >= open_windows) or (classes and qrun >= class_windows):
            is_open = True
        elif is_open and not ((head and p[i] >= close_below) or (classes and q[i] >= class_close)):
            is_open = False
        out[i] = is_open
    return out


def _found_false(scenes: list, opened_of) -> tuple[float, float]:
    """Share of bouts during which the gate is open (inside the bout or up to 1 s after) and openings outside
    every bout (and its 1 s tail) per 10 minutes of non-laughter."""
    found = n_bouts = false = 0
    non_laugh_min = 0.0
    for sc in scenes:
        t, bouts = sc["t"], sc["bouts"]
        opened = opened_of(sc)
        onsets = t[opened & ~np.concatenate([[False], opened[:-1]])]
        n_bouts += len(bouts)
        found += sum(bool(((t >= a) & (t <= b + 1.0) & opened).any()) for a, b in bouts)
        heard = np.zeros(len(onsets), bool)
        for a, b in bouts:
            heard |= (onsets >= a) & (onsets <= b + 1.0)
        false += int((~heard).sum())
        non_laugh_min += max(sc["dur"] - sum(b + 1.0 - a for a, b in bouts), 0.0) / 60.0
    return found / max(n_bouts, 1), 10 * false / max(non_laugh_min, 1e-9)


def rule_sweep(n_scenes: int = N_SCENES, seed: int = SEED, hop_s: float = 0.25) -> list[dict]:
    """The rules ``head``, ``classes`` and ``either`` on the train scenes and the synthetic profiles (``--rules``),
    one window every ``hop_s`` as live: bouts found and openings outside laughter (as :func:`gate_sweep`)."""
    from laughlab.corpora.mixed import SAMPLE_RATE, Pool, build_scene
    from laughlab.detector.fit import SNRS, channel, synthetic_scenes
    from laughlab.detector.yamnet import class_names, class_score, laugh_indices

    model, head = Yamnet(), Head.load()
    idx = laugh_indices(class_names())

    def scene(x, sr, rows):
        step = int(round(hop_s * sr))
        ends = np.arange(step, len(x) + 1, step)
        S = window_scores(x, sr, ends, model)
        return {"p": head.prob(S), "q": class_score(S, idx), "t": ends / sr, "dur": len(x) / sr,
                "bouts": [(r["onset_s"], r["offset_s"]) for r in rows if r["kind"] == "bout"]}

    pool = Pool.of_split("train")
    train = []
    for i in range(n_scenes):
        rng = np.random.default_rng([seed, i])
        x, rows = build_scene(rng, pool, SCENE_S, SNRS[i % len(SNRS)])
        train.append(scene(channel(x, rng), SAMPLE_RATE, rows))
    synth = [scene(x, sr, rows) for x, sr, rows in synthetic_scenes(seed)]
    rules = [(f"head, open_at 0.5 x{n}", {"rule": "head", "open_windows": n}) for n in (2, 3, 4)]
    rules += [(f"classes, class_open {c} x{n}, class_close {c / 2:g}",
               {"rule": "classes", "class_open": c, "class_windows": n, "class_close": c / 2})
              for c in (0.05, 0.1, 0.15, 0.2, 0.3) for n in (1, 2)]
    rules += [(f"either, class_open {c} x{n} or head 0.5 x{h}",
               {"rule": "either", "class_open": c, "class_windows": n, "class_close": c / 2, "open_windows": h})
              for c in (0.1, 0.2) for n in (1, 2) for h in (2, 3, 4)]
    out = []
    for name, kw in rules:
        def opened(sc, kw=kw):
            return gate_windows(sc["p"], sc["q"], **kw)
        found, false = _found_false(train, opened)
        out.append({"rule": name, **kw, "bouts_found": found, "false_per_10min": false,
                    "synthetic_found": _found_false(synth, opened)[0]})
    return out


if __name__ == "__main__":
    raise SystemExit(main())
