"""The laughter detector: features checked by hand on known signals, the gate step by step, the model's
arithmetic, the plugin's gating rule, no look-ahead, and what the pipeline writes."""
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.detector.model import (FEATURES, SILENCE_DBFS, FeatureStream, Gate, GateParams, Model, apply_gate,
                               probabilities)
from laughlab.core.frame import Frame

FPS = 60.0
IX = {n: i for i, n in enumerate(FEATURES)}


def run(x, sr, fps=FPS):
    f, _, level = probabilities(x, sr, fps)
    return f, level


def harmonic(f0, sr, seconds, n_harm=8):
    t = np.arange(int(sr * seconds)) / sr
    return sum(np.sin(2 * np.pi * f0 * k * t) / k for k in range(1, n_harm + 1)) * 0.1


def test_a_harmonic_tone_is_voiced_at_its_pitch():
    for sr in (16000, 44100, 48000):
        f, _ = run(harmonic(200.0, sr, 1.5), sr)
        last = f[-1]
        assert last[IX["voicing"]] > 0.9
        assert last[IX["f0_mean_l"]] == pytest.approx(math.log2(200.0), abs=0.03)   # log2 Hz
        assert last[IX["f0_std_l"]] < 0.5                                           # semitones
        assert last[IX["voiced_frac_l"]] == pytest.approx(1.0)


def test_white_noise_is_unvoiced_flat_and_breathy():
    sr = 44100
    x = np.random.default_rng(1).standard_normal(sr * 2) * 0.05
    f, _ = run(x, sr)
    last = f[-30:].mean(axis=0)
    assert last[IX["voicing"]] < 0.4
    # energy 2-5 kHz over 0.1-5 kHz of a flat spectrum: 3000 / 4900
    assert last[IX["hf_ratio"]] == pytest.approx(3000 / 4900, abs=0.03)
    # spectral flatness of a chi-square(2) periodogram: exp(E ln) / E = exp(-Euler's gamma) = 0.561
    assert last[IX["flatness"]] == pytest.approx(math.exp(-0.5772), abs=0.05)


def test_calls_at_5_per_second_modulate_and_repeat():
    sr = 44100
    t = np.arange(sr * 3) / sr
    calls = harmonic(300.0, sr, 3) * (np.sin(2 * np.pi * 5.0 * t) > 0)
    steady = harmonic(300.0, sr, 3)
    fc, _ = run(calls, sr)
    fs, _ = run(steady, sr)
    assert fc[-1][IX["mod_3_8"]] > 0.6 and fc[-1][IX["env_periodicity"]] > 0.5
    assert fs[-1][IX["env_periodicity"]] < fc[-1][IX["env_periodicity"]]
    assert fs[-1][IX["e_std_l"]] < 1.0 < fc[-1][IX["e_std_l"]]


@settings(max_examples=12, deadline=None)
@given(f0=st.floats(120.0, 600.0), sr=st.sampled_from([22050, 32000, 44100, 48000]))
def test_features_do_not_depend_on_the_sample_rate(f0, sr):
    """Only the band below 5 kHz is used: the same band-limited sound at any rate gives the same cues."""
    n_harm = int(4000 // f0)
    a, _ = run(harmonic(f0, 16000, 1.2, n_harm), 16000)
    b, _ = run(harmonic(f0, sr, 1.2, n_harm), sr)
    for name, tol in (("voicing", 0.05), ("f0_mean_l", 0.03), ("hf_ratio", 0.02), ("voiced_frac_l", 0.05)):
        assert b[-1][IX[name]] == pytest.approx(a[-1][IX[name]], abs=tol), name


def test_no_look_ahead():
    """Features and probabilities up to frame K do not change when the audio after frame K does."""
    sr, k = 44100, 50
    rng = np.random.default_rng(3)
    x = rng.standard_normal(sr * 2) * 0.1
    y = x.copy()
    y[int((k + 1) * sr / FPS):] = rng.standard_normal(len(y) - int((k + 1) * sr / FPS))
    m = Model.load()
    fx, px, _ = probabilities(x, sr, FPS, m)
    fy, py, _ = probabilities(y, sr, FPS, m)
    assert np.array_equal(fx[: k + 1], fy[: k + 1]) and np.array_equal(px[: k + 1], py[: k + 1])
    assert not np.array_equal(fx[k + 1:], fy[k + 1:])


def test_nonfinite_samples_count_as_silence():
    fs = FeatureStream(16000, FPS)
    f = fs.step(np.full(267, np.nan))
    assert np.all(np.isfinite(f)) and fs.level_dbfs < SILENCE_DBFS


def test_gate_step_by_step():
    """dt 0.1 s, open at 0.5, close below 0.3 after 0.2 s, attack 0.2 s, release 0.4 s: worked out by hand."""
    g = Gate(GateParams(open_at=0.5, open_s=0.0, close_below=0.3, hold_s=0.2, attack_s=0.2, release_s=0.4), 0.1)
    probs = [0.4, 0.6, 0.2, 0.4, 0.1, 0.1, 0.1, 0.1, 0.1]
    want = [0.0, 0.5, 1.0, 1.0, 1.0, 0.75, 0.5, 0.25, 0.0]
    # 0.4: closed.  0.6: open, +0.5.  0.2: below for 0.1 s, still open, 1.0.  0.4: not below 0.3, the
    # count restarts.  0.1: 0.1 s.  0.1: 0.2 s -> closed, -0.25 per frame from here.
    got = [g.step(p) for p in probs]
    assert got == pytest.approx(want)


def test_the_gate_opens_only_after_open_s_above_open_at():
    """open_s 0.2 s at dt 0.1 s: two frames in a row at or above open_at; a lone frame does not open it."""
    g = Gate(GateParams(open_at=0.5, open_s=0.2, close_below=0.3, hold_s=0.1, attack_s=0.0, release_s=0.0), 0.1)
    got = [g.step(p) for p in (0.9, 0.2, 0.6, 0.5, 0.9, 0.1, 0.1)]
    assert got == [0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]


def test_gate_parameters_are_checked():
    with pytest.raises(ValueError, match="close_below <= open_at"):
        GateParams(open_at=0.3, close_below=0.6)
    with pytest.raises(ValueError, match="hold_s"):
        GateParams(hold_s=-1.0)


def test_apply_gate_scales_drive_and_silences_events():
    f = Frame(control={"mcs": 0.8, "pressure": 2.0, "call_onset": 1.0, "rms": 0.1}, label="a")
    apply_gate(f, 0.25)
    assert f.control == {"mcs": 0.2, "mcs_ungated": 0.8, "pressure": 0.5, "pressure_ungated": 2.0,
                         "call_onset": 0.0, "rms": 0.1}
    assert f.label == "silence"
    g = Frame(control={"mcs": 0.8, "call_onset": 1.0}, label="a")
    apply_gate(g, 0.75)
    assert g.control["mcs"] == pytest.approx(0.6) and g.control["call_onset"] == 1.0 and g.label == "a"


def test_model_arithmetic_by_hand(tmp_path):
    d = len(FEATURES)
    w1 = np.zeros((d, 2))
    w1[0, 0], w1[1, 1] = 1.0, -2.0
    spec = {"features": list(FEATURES), "mean": [1.0] * d, "scale": [2.0] * d,
            "weights": [w1.tolist(), [[3.0], [1.0]]], "biases": [[0.0, 0.5], [-1.0]]}
    p = tmp_path / "m.json"
    p.write_text(json.dumps(spec))
    m = Model.load(p)
    x = np.full(d, 1.0)
    x[0], x[1] = 3.0, 2.0          # z0 = 1, z1 = 0.5
    h = [math.tanh(1.0), math.tanh(-2.0 * 0.5 + 0.5)]
    logit = 3.0 * h[0] + h[1] - 1.0
    assert m.logit(x) == pytest.approx(logit)
    assert m.prob(x) == pytest.approx(1 / (1 + math.exp(-logit)))


def test_a_model_of_other_features_is_refused(tmp_path):
    p = tmp_path / "m.json"
    p.write_text(json.dumps({"features": ["x"], "mean": [0], "scale": [1], "weights": [[[1]]], "biases": [[0]]}))
    with pytest.raises(ValueError, match="other features"):
        Model.load(p)


def test_bundled_model_says_how_it_was_fitted():
    m = Model.load()
    assert m.meta["fit"]["command"] == "python -m laughlab.detector.fit"
    assert m.meta["fit"]["split"] == "train"
    assert len(m.weights) == len(m.biases) == 2


# ------------------------------------------------------------------ in the pipeline
@pytest.fixture(scope="module")
def gated_and_plain(tmp_path_factory):
    import pandas as pd

    d = tmp_path_factory.mktemp("det")
    out = {}
    for det in ("laugh", "none"):
        r = laughlab(f"hydra.run.dir={d / det}", "input.duration_s=10", "input.profile=intense",
                     f"detector={det}", "output=trial")
        assert r.returncode == 0, r.stderr
        out[det] = pd.read_csv(d / det / "channels.csv")
    return out


def test_the_gate_scales_the_drive_and_none_passes_it(gated_and_plain):
    g, n = gated_and_plain["laugh"], gated_and_plain["none"]
    assert np.allclose(g.mcs, g.mcs_ungated * g.laugh_gate, atol=2e-6)      # csv keeps 6 decimals
    assert np.array_equal(g.mcs_ungated, n.mcs)                              # the same extractor, ungated
    assert (n.laugh_gate == 1.0).all() and (n.laughter == 1.0).all()
    assert g.laughter.between(0, 1).all() and g.laugh_gate.between(0, 1).all()
    assert g.laugh_gate.max() == 1.0                                         # synthetic laughter opens it


@pytest.mark.parametrize("args,msg", [
    (["detector=laugh", "detector.open_at=2"], "bad parameter in detector=laugh: need 0 <= close_below <= open_at <= 1"),
    (["detector=laugh", "detector.model=/no/such.json"],
     "bad parameter in detector=laugh: model file not found: /no/such.json"),
    (["detector=nope"], "unknown detector 'nope'"),
    (["detector=none", "detector.open_at=0.5"], "detector.open_at is a parameter of detector=laugh, "
                                                "detector=yamnet and detector=yamnet_fused, not of detector=none: "
                                                "use one of them instead"),
    (["detector.model=/x.json"], "detector.model is a parameter of detector=laugh, not of detector=yamnet: "
                                 "add detector=laugh"),
])
def test_detector_errors_are_one_line(tmp_path, args, msg):
    r = laughlab(f"hydra.run.dir={tmp_path / 'x'}", "input.duration_s=1", *args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and msg in lines[0], r.stderr
    assert not (tmp_path / "x" / "channels.csv").exists()
