"""The detector on the real corpus' held-out (test) split: guards of what the benchmark measures.

Runs on the fetched corpus (``make test`` fetches it first).  The bounds are
below the figures measured by ``benchmarks/bench_detector.py`` (README), so a
change that makes the detector worse on held-out people fails here.
"""
import numpy as np
import pandas as pd
import pytest

from laughlab.corpora.fetch import corpus_dir
from laughlab.corpora.mixed import SAMPLE_RATE, Pool, speech_only, write_set
from laughlab.detector.model import Gate, GateParams, Model, probabilities

FPS = 60.0


@pytest.fixture(scope="module")
def model():
    return Model.load()


def gate_of(x, sr, model):
    _, p, _ = probabilities(x, sr, FPS, model)
    g = Gate(GateParams(), 1 / FPS)
    return np.array([g.step(float(v)) for v in p]) >= 0.5


def test_held_out_speech_rarely_opens_the_gate(model):
    pool = Pool.of_split("test")
    x = speech_only(pool, 120.0, seed=11)                    # 2 minutes, voices of the test split
    open_ = gate_of(x, SAMPLE_RATE, model)
    assert open_.mean() < 0.03                              # measured 0.006
    openings = int((np.diff(open_.astype(int)) == 1).sum())
    assert openings <= 6                                     # per 2 minutes; measured 2


def test_held_out_laughs_open_the_gate(model):
    import soundfile as sf

    wavs = write_set(corpus_dir() / "sets" / "real-test", "real", "test", 6, 100.0, [20.0, 10.0, 5.0], 0)
    found = []
    for w in wavs:
        x, sr = sf.read(w)
        open_ = gate_of(x, sr, model)
        t = np.arange(len(open_)) / FPS
        tr = pd.read_csv(w.with_name(w.stem + ".truth.csv"))
        for b in tr[tr.kind == "bout"].itertuples():
            found.append(bool(open_[(t >= b.onset_s) & (t <= b.offset_s + 0.25)].any()))
    assert len(found) >= 30
    print(f"held-out bouts found by the gate: {np.mean(found):.3f} of {len(found)}")
    assert np.mean(found) >= 0.35                           # measured 0.41 (34 bouts)


def test_the_others_set_is_every_other_human_sound_of_the_split_alone():
    import soundfile as sf

    from laughlab.corpora.fetch import load_lock
    from laughlab.corpora.mixed import HUMAN_KINDS

    lock = load_lock()["files"]
    want = sorted(f"{e['kind']}__{iid.replace('/', '__')}" for iid, e in lock.items()
                  if e["kind"] in HUMAN_KINDS and e["split"] == "test")
    from laughlab.harness.corpus import set_folder

    wavs = write_set(corpus_dir() / "sets" / set_folder("others", "test", 6, 100.0), "others", "test", 6, 100.0, [], 0)
    assert sorted(w.stem for w in wavs) == want and len(want) >= 40
    for w in wavs[:: max(1, len(wavs) // 12)]:
        iid = w.stem.split("__", 1)[1].replace("__", "/")
        x, sr = sf.read(w)
        tr = pd.read_csv(w.with_name(w.stem + ".truth.csv"))
        assert sr == SAMPLE_RATE and len(tr) == 1 and tr.kind[0] == lock[iid]["kind"] == w.stem.split("__")[0]
        assert tr.onset_s[0] == 0.5 and abs(len(x) / sr - 1.0 - lock[iid]["duration_s"]) < 0.05  # the whole recording
        assert abs(tr.offset_s[0] - (len(x) / sr - 0.5)) < 1e-3
        assert not x[: int(0.5 * sr)].any() and not x[-int(0.5 * sr):].any() and np.abs(x).max() > 0.01


@pytest.mark.slow
def test_the_bundled_model_is_regenerated_byte_for_byte():
    """``python -m laughlab.detector.fit --check`` refits on the train split and compares the bytes (~3 min)."""
    from laughlab.detector.fit import main

    assert main(["--check"]) == 0
