"""Could YAMNet's own "Speech synthesizer" class keep the head from taking a synthetic voice for laughter?

The bundled head (``laughlab/data/yamnet/head.json``) says laughter on espeak-ng speech (``docs/detector.md``,
*Synthetic voices*), where YAMNet's laughter classes stay near 0.  YAMNet has a class for such voices, ``Speech
synthesizer`` (index 5 of ``yamnet_class_map.csv``).  A veto would not count a window towards the head's run of
windows (the clip gain's ``open_windows``) when that class reaches ``t`` while the six laughter classes stay under
``c``.  This measures, per window (one every 0.25 s, as live), the share of the windows where the head says
laughter (probability >= 0.5) that such a veto would take away:

- on the train split (where a rule is chosen): the laughter windows of the head's 48 scenes
  (``laughlab.detector.yamnet_fit.train_scenes``), of the seven synthetic profiles, and the non-laughter windows
  of the 12 monotone resyntheses of the train split's speech;
- held out, never in a fit: the synthetic voices of ``benchmarks/bench_detector.py`` (``tts_espeak``, 10 voices,
  2.7 min; ``tts_flite``, 5 voices, 1.9 min; ``espeak_sentence``), for the engines installed.

Run: ``python benchmarks/bench_synth_veto.py`` (about 1 minute on 2 cores; needs the corpus, and espeak-ng and
flite for the held-out rows).  Writes ``benchmarks/results/synth_veto.json``.
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import soundfile as sf

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import bench_detector as B  # noqa: E402
from laughlab.detector import yamnet_fit as F  # noqa: E402
from laughlab.detector.fit import synthetic_scenes  # noqa: E402
from laughlab.detector.yamnet import Head  # noqa: E402
from laughlab.detector.yamnet_model import Yamnet  # noqa: E402

#: YAMNet's "Speech synthesizer" class and its six laughter classes (yamnet_class_map.csv)
SYNTH = 5
LAUGHTER = [13, 14, 15, 16, 17, 18]
VETOES = [(t, c) for t in (0.01, 0.02, 0.05) for c in (0.001, 0.01)]


def scored(model: Yamnet, scenes) -> tuple[np.ndarray, np.ndarray]:
    """Scores (N, 521) and laughter labels (N,) of the windows of ``scenes``, one every 0.25 s."""
    S, Y = [], []
    for x, sr, rows in scenes:
        s, y = F.scene_windows(model, x, sr, rows)
        S.append(s)
        Y.append(y)
    return np.concatenate(S), np.concatenate(Y)


def vetoed(S: np.ndarray, Y: np.ndarray, head: Head, laughter: bool) -> dict:
    """The head's laughter windows (``laughter``: those labelled laughter; else those labelled not) and the share
    each veto of :data:`VETOES` takes away."""
    pick = (head.prob(S) >= 0.5) & ((Y > 0.5) if laughter else (Y <= 0.5))
    out = {"windows": int(pick.sum())}
    for t, c in VETOES:
        veto = (S[:, SYNTH] >= t) & (S[:, LAUGHTER].max(axis=1) < c)
        out[f"t={t} c={c}"] = round(float(veto[pick].mean()), 3) if pick.any() else None
    return out


def main() -> None:
    model, head = Yamnet(), Head.load()
    res = {"data": "train split (choose) and synthetic voices (held out)", "rows": {}}
    sets = {"train laughs": (F.train_scenes(), True), "synthetic laughter": (synthetic_scenes(F.SEED), True),
            "monotone speech (train)": (F.monotone_speech(), False)}
    with tempfile.TemporaryDirectory() as tmp:
        for name, wav in B.tts_sets(Path(tmp)).items():
            x, sr = sf.read(wav, dtype="float32")
            sets[f"{name} (held out)"] = ([(x, sr, [])], False)
        for name, (scenes, laughter) in sets.items():
            res["rows"][name] = vetoed(*scored(model, scenes), head, laughter)
            print(name, res["rows"][name], flush=True)
    out = HERE / "results" / "synth_veto.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
