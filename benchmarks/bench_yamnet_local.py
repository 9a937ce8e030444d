"""Does YAMNet hear a laugh sooner in the last part of its window?  Local laughter scores from the network's
map before its average pool, on the held-out (test) split.

YAMNet's last layer (ops 56-57 of the bundled file) is a 3 x 2 x 1024 map (time x frequency x channels) that
the file averages (``MEAN``) and then classifies with one dense layer (``FULLY_CONNECTED`` + ``LOGISTIC``).
The dense layer is linear, so applying it to one time column of the map instead of the average gives that
column's own class scores (a class activation map, Zhou et al., "Learning Deep Features for Discriminative
Localization", CVPR 2016); the average of the columns' logits is the file's logit.  Per window, the largest of
the six laughter classes (``laughter_classes``) is scored three ways: ``global`` (the file's own score, the
map averaged), ``last2`` (the last two time columns), ``last`` (the last column, about the window's last
third; its receptive field reaches further back).

Windows of 0.975 s end every 0.1 s (causal: a window ending at ``t`` holds audio up to ``t``), on the sets
``real`` (the annotated laughs alone), ``between`` (laughs spliced between real speech) and ``speech`` of
``benchmarks/bench_detector.py``'s held-out sets.  Printed per score and threshold: bouts whose score reaches
the threshold between their start and 1 s after their end, the median time from a bout's start to that
window's end, the share within 0.3 s, and openings (the score rising through the threshold) outside bouts
per 10 minutes.  Then, for each score, the threshold is chosen on the train split (the head's 48 scenes,
``laughlab.detector.yamnet_fit.train_scenes``, a window every 0.25 s as live): the lowest of 0.05-0.4 with no
more openings outside laughter than the file's own score at the live gate's ``class_open`` (0.1); the test
sets are scored again at those thresholds, a window every 0.25 s.  Writes
``benchmarks/results/yamnet_local.json``.

Run: ``python benchmarks/bench_yamnet_local.py [--scenes 48]`` (about 7 minutes on one core).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import soundfile as sf

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import bench_detector as B  # noqa: E402
from laughlab.detector.stream16k import to_16k  # noqa: E402
from laughlab.detector.yamnet_model import (WINDOW, Yamnet, _Layout, _Runner, class_names, data_dir,  # noqa: E402
                                            frames, laugh_indices)

HOP_S = 0.1
THRESHOLDS = (0.05, 0.1, 0.15, 0.2, 0.3)
#: the live gate's hop and its class_open (conf/detector/yamnet.yaml), and the thresholds tried on the train split
LIVE_HOP_S, CLASS_OPEN = 0.25, 0.1
CHOICES = tuple(np.round(np.arange(0.05, 0.401, 0.025), 3))
#: the bundled file's pre-pool map (tensor 120, (1, 3, 2, 1024)), the dense layer's weights and bias
MAP_OPS, MAP_IN, MAP_OUT, DENSE_W, DENSE_B = (19, 57), 93, 120, 12, 1


def _tensor(layout: _Layout, t: int) -> np.ndarray:
    """A constant tensor of the file as float32 (int8 weights times their per-channel scale)."""
    g = layout.model.subgraphs[0]
    tt = g.tensors[t]
    dtype = {0: np.float32, 2: np.int32, 9: np.int8}[tt.type]
    a = np.frombuffer(bytes(layout.model.buffers[tt.buffer].data), dtype).reshape(tt.shape).astype(np.float32)
    if dtype == np.int8:
        scale = np.asarray(tt.quantization.scale, np.float32)
        a *= scale[:, None] if scale.size > 1 else scale
    return a


class LocalScores:
    """Per window: the laughter classes' largest score from the whole map, its last two and its last column."""

    def __init__(self):
        layout = _Layout((data_dir() / "yamnet.tflite").read_bytes())
        self.map = _Runner(layout.piece(*MAP_OPS, MAP_IN, MAP_OUT))
        self.w, self.b = _tensor(layout, DENSE_W), _tensor(layout, DENSE_B)
        self.model = Yamnet()
        self.idx = laugh_indices(class_names())

    def _classes(self, features: np.ndarray) -> np.ndarray:
        z = np.clip(features @ self.w.T + self.b, -60, 60)[:, self.idx]
        return (1.0 / (1.0 + np.exp(-z))).max(axis=1)

    def __call__(self, y16: np.ndarray, ends: np.ndarray) -> dict[str, np.ndarray]:
        m = np.array([self.map(self.model.logmel(frames(_window(y16, e))).reshape(1, 96, 64, 1))[0]
                      for e in ends])  # (windows, 3, 2, 1024)
        return {"global": self._classes(m.mean(axis=(1, 2))), "last2": self._classes(m[:, 1:].mean(axis=(1, 2))),
                "last": self._classes(m[:, 2].mean(axis=1))}

    def check(self, y16: np.ndarray, ends: np.ndarray) -> float:
        """Largest difference between ``global`` and the whole file's laughter classes on these windows."""
        ours = self(y16, ends)["global"]
        theirs = [self.model.scores(_window(y16, e))[self.idx].max() for e in ends]
        return float(np.max(np.abs(ours - np.array(theirs))))


def _window(y16: np.ndarray, end: int) -> np.ndarray:
    """The window of 16 kHz samples ending at ``end``, silence before the start."""
    w = y16[max(0, end - WINDOW):end]
    return np.concatenate([np.zeros(WINDOW - len(w), np.float32), w])


def bouts(wav: Path) -> list[tuple[float, float]]:
    return [(r["onset_s"], r["offset_s"]) for r in B.truth_rows(wav) if r["kind"] == "bout"]


def _openings(t: np.ndarray, s: np.ndarray, thr: float, truth) -> int:
    on = s >= thr
    rises = t[on & ~np.r_[False, on[:-1]]]
    return sum(not any(a <= x <= b + 1.0 for a, b in truth) for x in rises)


def summarise(rows: list[dict], key: str, thr: float) -> dict:
    lat, found, n, opened, dur = [], 0, 0, 0, 0.0
    for r in rows:
        t, s = np.asarray(r["t"]), np.asarray(r[key])
        for a, b in r["bouts"]:
            n += 1
            hit = (t >= a) & (t <= b + 1.0) & (s >= thr)
            if hit.any():
                found += 1
                lat.append(float(t[hit][0] - a))
        opened += _openings(t, s, thr, r["bouts"])
        dur += float(t[-1]) if len(t) else 0.0
    return {"found": found, "bouts": n, "latency_median_s": float(np.median(lat)) if lat else None,
            "within_0_3_s": float(np.mean(np.asarray(lat) <= 0.3)) if lat else 0.0,
            "openings_per_10_min": opened / dur * 600 if dur else 0.0}


def score_rows(local: LocalScores, items, hop_s: float) -> list[dict]:
    """``items``: (name, audio, sample rate, bouts); per item the window ends (s) and the three scores."""
    rows = []
    for name, x, sr, truth in items:
        y16 = to_16k(x, sr).astype(np.float32)
        ends = np.arange(int(0.25 * 16000), len(y16) + 1, int(round(hop_s * 16000)))
        rows.append({"file": name, "t": (ends / 16000).tolist(), "bouts": truth,
                     **{k: v.tolist() for k, v in local(y16, ends).items()}})
    return rows


def _wavs(paths):
    for wav in sorted(paths):
        x, sr = sf.read(wav, dtype="float64", always_2d=True)
        yield wav.name, x.mean(axis=1), sr, bouts(wav)


def _train(n_scenes: int):
    from laughlab.detector.yamnet_fit import train_scenes

    for i, (x, sr, rows) in enumerate(train_scenes(n_scenes)):
        yield f"train-{i:02d}", x, sr, [(r["onset_s"], r["offset_s"]) for r in rows if r["kind"] == "bout"]


def _print(table: dict) -> None:
    for key, by_thr in table.items():
        for thr, r in by_thr.items():
            cells = [f"{n}: {v['found']}/{v['bouts']}, {v['latency_median_s'] or float('nan'):.2f} s, "
                     f"{v['within_0_3_s']:.0%} in 0.3 s, {v['openings_per_10_min']:.1f}/10 min"
                     if v["bouts"] else f"{n}: {v['openings_per_10_min']:.1f}/10 min" for n, v in r.items()]
            print(f"{key:6s} {float(thr):.3f} | " + " | ".join(cells))


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=48, help="train scenes for the choice of thresholds (48: the head's)")
    ns = ap.parse_args()
    sets = B.held_out_sets()
    local = LocalScores()
    test = {name: score_rows(local, _wavs(sets[name]), HOP_S) for name in ("real", "between", "speech")}
    y16 = to_16k(sf.read(sorted(sets["real"])[0], dtype="float64", always_2d=True)[0].mean(axis=1), 44100)
    worst = local.check(y16.astype(np.float32), np.arange(16000, len(y16) + 1, 4000)[:8])
    table = {key: {str(thr): {name: summarise(test[name], key, thr) for name in test} for thr in THRESHOLDS}
             for key in ("global", "last2", "last")}
    print(f"global against the whole file's score: largest difference {worst:.2g}")
    print(f"test split, a window every {HOP_S} s:")
    _print(table)
    # thresholds chosen on the train split (a window every 0.25 s, as live): for each score the lowest with no more
    # openings outside laughter than the file's own score at the live gate's class_open (0.1); then the test split
    train = score_rows(local, _train(ns.scenes), LIVE_HOP_S)
    limit = summarise(train, "global", CLASS_OPEN)["openings_per_10_min"]
    chosen = {}
    for key in ("global", "last2", "last"):
        ok = [thr for thr in CHOICES if summarise(train, key, thr)["openings_per_10_min"] <= limit + 1e-9]
        chosen[key] = float(min(ok)) if ok else float(max(CHOICES))
    live = {name: score_rows(local, _wavs(sets[name]), LIVE_HOP_S) for name in ("real", "between", "speech")}
    at_live = {key: {f"{thr:g}": {"train": summarise(train, key, thr),
                                  **{name: summarise(live[name], key, thr) for name in live}}}
               for key, thr in chosen.items()}
    print(f"thresholds chosen on {ns.scenes} train scenes ({limit:.1f} openings per 10 min, the file's score at "
          f"{CLASS_OPEN}); a window every {LIVE_HOP_S} s:")
    _print(at_live)
    out = HERE / "results" / "yamnet_local.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"hop_s": HOP_S, "check_max_abs_diff": worst, "table": table,
                               "chosen_on_train": chosen, "live_hop_s": LIVE_HOP_S, "at_live_hop": at_live},
                              indent=1) + "\n")


if __name__ == "__main__":
    main()
