"""Could YAMNet's own "Speech synthesizer" class keep the head from taking a synthetic voice for laughter?

The bundled head (``laughlab/data/yamnet/head.json``) says laughter on espeak-ng speech (``docs/detector.md``,
*Synthetic voices*), where YAMNet's laughter classes stay near 0.  YAMNet has a class for such voices, ``Speech
synthesizer`` (index 5 of ``yamnet_class_map.csv``).  A veto would not count a window towards the head's run of
windows (the clip gain's ``open_windows``) when that class reaches ``t`` while the six laughter classes stay under
``c``.  This measures, a window every 0.25 s as live, the share of the windows where the head says laughter
(probability >= 0.5) that such a veto would take away, and the default clip gate (``either``: the classes at 0.1
or the head at 0.5 x3, ``laughlab.detector.yamnet_fit.gate_windows``, without the quiet close) with the veto:
bouts found and openings, as ``python -m laughlab.detector.yamnet_fit --rules`` counts them, on

- on the train split (where a rule is chosen): the laughter windows of the head's 48 scenes
  (``laughlab.detector.yamnet_fit.train_scenes``), of the seven synthetic profiles, and the non-laughter windows
  of the 12 monotone resyntheses of the train split's speech;
- held out, never in a fit: the synthetic voices of ``benchmarks/bench_detector.py`` (``tts_espeak``, 10 voices,
  2.7 min; ``tts_flite``, 5 voices, 1.9 min; ``espeak_sentence``), for the engines installed.

Run: ``python benchmarks/bench_synth_veto.py`` (about 1 minute on 2 cores; needs the corpus, and espeak-ng and
flite for the held-out rows).  Writes ``benchmarks/results/synth_veto.json``.
"""
from __future__ import annotations

import argparse
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
from laughlab.detector.yamnet import (OTHER_HUMAN_CLASSES, Head, class_names, class_score,  # noqa: E402
                                      laugh_indices, window_scores)
from laughlab.detector.yamnet_model import Yamnet  # noqa: E402

#: YAMNet's "Speech synthesizer" class and its six laughter classes (yamnet_class_map.csv)
SYNTH = 5
LAUGHTER = [13, 14, 15, 16, 17, 18]
VETOES = [(t, c) for t in (0.01, 0.02, 0.05) for c in (0.001, 0.01)]
HOP_S = 0.25


def scene(model: Yamnet, head: Head, x: np.ndarray, sr: int, rows: list[dict]) -> dict:
    """A scene's windows, one every :data:`HOP_S`: scores, the head's probability, the laughter classes' and the
    other human sounds' scores, laughter labels, and its bouts."""
    names = class_names()
    ends = np.arange(int(round(HOP_S * sr)), len(x) + 1, int(round(HOP_S * sr)))
    S = window_scores(x, sr, ends, model)
    return {"S": S, "p": head.prob(S), "q": class_score(S, laugh_indices(names)),
            "o": class_score(S, laugh_indices(names, OTHER_HUMAN_CLASSES)), "t": ends / sr, "dur": len(x) / sr,
            "y": F.window_labels(rows, ends / sr),
            "bouts": [(r["onset_s"], r["offset_s"]) for r in rows if r["kind"] == "bout"]}


def veto_of(sc: dict, t: float, c: float) -> np.ndarray:
    return (sc["S"][:, SYNTH] >= t) & (sc["S"][:, LAUGHTER].max(axis=1) < c)


def vetoed(scenes: list[dict], laughter: bool) -> dict:
    """The head's laughter windows (``laughter``: those labelled laughter; else those labelled not) and the share
    each veto of :data:`VETOES` takes away; then the gate with each veto: bouts found, openings."""
    pick = np.concatenate([(sc["p"] >= 0.5) & ((sc["y"] > 0.5) if laughter else (sc["y"] <= 0.5)) for sc in scenes])
    out = {"windows": int(pick.sum())}
    for t, c in VETOES:
        veto = np.concatenate([veto_of(sc, t, c) for sc in scenes])
        out[f"windows vetoed, t={t} c={c}"] = round(float(veto[pick].mean()), 3) if pick.any() else None
    for t, c in [(None, None), *VETOES]:
        def opened(sc, t=t, c=c):
            p = sc["p"] if t is None else np.where(veto_of(sc, t, c), 0.0, sc["p"])
            return F.gate_windows(p, sc["q"], rule="either", class_open=0.1, class_windows=1, class_close=0.05,
                                  open_windows=3, other=sc["o"], veto="classes")
        found, _ = F._found_false(scenes, opened)
        onsets = sum(int((g & ~np.concatenate([[False], g[:-1]])).sum()) for g in map(opened, scenes))
        out[f"gate, veto t={t} c={c}"] = {"bouts_found": round(found, 3), "openings": onsets}
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
            res["rows"][name] = vetoed([scene(model, head, *a) for a in scenes], laughter)
            print(name, res["rows"][name], flush=True)
    out = HERE / "results" / "synth_veto.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":   # --help prints what it measures; it took no arguments and ran (a review)
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
