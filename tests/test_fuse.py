"""``detector.fuse``: YAMNet's scores fused with the feature MLP's cues (``laughlab.detector.fuse``)."""
import json
import math

import numpy as np
import pytest
import soundfile as sf
from hypothesis import given, settings, strategies as st

from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab.detector import fuse as F
from laughlab.detector.model import FEATURES, FeatureStream
from test_yamnet import corpus_audio   # real speech, a real laugh, the speech again (44.1 kHz, test split)

FPS = 60.0


@settings(max_examples=10, deadline=None)
@given(sr=st.sampled_from([16000, 44100, 48000]), every=st.integers(1, 20), seed=st.integers(0, 2**31))
def test_features_asked_now_and_then_are_the_every_frame_features(sr, every, seed):
    """The detector pushes every frame and asks for the features on window frames only: the same numbers as
    ``step`` every frame."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(sr * 3) * np.repeat(rng.uniform(0, 0.5, 30), sr // 10)
    a, b = FeatureStream(sr, FPS), FeatureStream(sr, FPS)
    for k in range(int(3 * FPS)):
        blk = x[int(round(k * sr / FPS)):int(round((k + 1) * sr / FPS))]
        want = a.step(blk)
        b.push(blk)
        if k % every == every - 1:
            assert np.array_equal(b.features(), want)


def test_the_fused_probability_by_hand():
    """p = sigmoid(w . (x - mean) / scale + b) on log(q + 1e-4), logit(head), logit(mlp) and the 23 features."""
    n = len(F.INPUTS)
    w = np.zeros(n)
    w[0], w[2], w[3] = 1.0, 1.0, 0.5
    mean, scale = np.zeros(n), np.ones(n)
    scale[3] = 2.0
    fus = F.Fusion(mean, scale, w, -0.25, {})
    feats = np.zeros(len(FEATURES))
    feats[0] = -6.0                                  # rel_db
    x = F.inputs(0.1, 0.5, 0.9, feats)
    assert x.shape == (1, n)
    z = math.log(0.1 + 1e-4) + math.log(0.9 / 0.1) + 0.5 * (-6.0 / 2.0) - 0.25
    assert fus.prob(x)[0] == pytest.approx(1.0 / (1.0 + math.exp(-z)), rel=1e-12)
    # probabilities of 0 and 1 enter clipped to 1e-4: finite
    assert np.isfinite(F.inputs(0.0, 0.0, 1.0, feats)).all()
    assert F.inputs(0.0, 0.0, 1.0, feats)[0, 1] == pytest.approx(math.log(1e-4 / (1 - 1e-4)))


def test_the_bundled_fused_head_is_complete_and_a_foreign_one_is_refused(tmp_path):
    fus = F.Fusion.load()
    assert fus.meta["inputs"] == list(F.INPUTS) and fus.weights.shape == (len(F.INPUTS),)
    assert fus.meta["fit"]["split"] == "train" and np.all(fus.scale > 0)
    d = dict(fus.meta, inputs=list(F.INPUTS[:-1]))
    (tmp_path / "f.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match=r"f\.json was fitted on other inputs; refit: python -m laughlab\.detector\.yamnet_fit --fuse"):
        F.Fusion.load(tmp_path / "f.json")
    (tmp_path / "g.json").write_text("{not json")
    with pytest.raises(ValueError, match=r"cannot read the fused head .*g\.json .*git checkout laughlab/data/yamnet"):
        F.Fusion.load(tmp_path / "g.json")


def test_a_missing_fuse_file_is_one_line_and_no_run_folder(tmp_path):
    from inprocess import laughlab

    out = tmp_path / "run"
    r = laughlab("input.duration_s=1", "detector.fuse=true", f"detector.fuse_file={tmp_path / 'nope.json'}",
                 f"hydra.run.dir={out}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "cannot read the fused head" in r.stderr and "nope.json" in r.stderr and not out.exists()


def test_the_live_fused_probability_is_the_fits_offline_one():
    """The detector's ``laughter`` on each window's frame (fuse=true, scores on the window's own frame) is the
    fused head on ``yamnet_fit.fuse_scene``'s inputs, the offline path the head was fitted on."""
    from laughlab.detector.yamnet import Head, Yamnet
    from laughlab.detector.yamnet_fit import fuse_scene
    from laughlab_plugins.detector_yamnet import YamnetDetector, YamnetParams

    sr = 44100
    x = corpus_audio()
    det = YamnetDetector(YamnetParams(fuse=True, model_frames=1), Context(fps=FPS, sample_rate=sr))
    live = []
    n = int(len(x) * FPS / sr)
    for k in range(n):
        f = Frame(k, k / FPS, 1 / FPS, {"mcs": 0.5}, None, {}, {}, [], 0.0)
        det.step(x[int(round(k * sr / FPS)):int(round((k + 1) * sr / FPS))], f)
        if (k + 1) % 15 == 0:
            live.append(f.control["laughter"])
    off = fuse_scene(Yamnet(), Head.load(), x[:int(round(n * sr / FPS))], sr, [])
    want = det.fusion.prob(off["X"])
    assert len(live) == len(want) > 15
    np.testing.assert_allclose(live, want, rtol=1e-9, atol=1e-12)
    assert 0.0 < min(live) < max(live) < 1.0


def test_a_fused_run_gives_the_same_bytes_with_and_without_the_look_ahead(tmp_path):
    """input=file, fuse=true: the helper thread's windows (prefetch) and the frame thread's give the same bytes,
    and they differ from the unfused run's."""
    from laughlab.core import pipeline
    from laughlab.harness.runner import _compose

    wav = tmp_path / "in.wav"
    sf.write(wav, corpus_audio(), 44100, subtype="PCM_16")

    def run(name, *extra):
        cfg = _compose(["input=file", f"input.path={wav}", "output=trial", "progress=off", *extra])
        pipeline.execute(pipeline.build(cfg), tmp_path / name, {})
        return (tmp_path / name / "channels.csv").read_bytes()

    a = run("on", "detector.fuse=true")
    assert run("off", "detector.fuse=true", "detector.prefetch=false") == a
    assert run("plain") != a


def test_a_bad_fuse_value_is_refused():
    from laughlab_plugins.detector_yamnet import YamnetParams

    with pytest.raises(ValueError, match=r"fuse must be true or false \(got maybe\)"):
        YamnetParams(fuse="maybe")


def test_the_fused_heads_c_reads_a_cpu_familys_rounding_as_a_tie():
    """The cross-validated APs of the bundled fit (AVX-512, 2026-11-27, at 4 decimals) and of its refit on AVX2
    (2026-11-28), where the best-AP rule picked C = 0.3: both give the bundled C = 1."""
    from laughlab.detector.yamnet_fit import FUSE_C_TIE, chosen_c

    avx512 = {0.003: 0.9261, 0.01: 0.9288, 0.03: 0.9304, 0.1: 0.9307, 0.3: 0.9308, 1.0: 0.9308}
    avx2 = {**avx512, 0.3: 0.9307, 1.0: 0.9306}
    assert chosen_c(avx512) == chosen_c(avx2) == 1.0
    # a real difference is not a tie: the better C wins
    assert chosen_c({**avx2, 1.0: 0.9307 - 2 * FUSE_C_TIE}) == 0.3
    assert chosen_c({0.1: 0.95, 0.3: 0.90, 1.0: 0.90}) == 0.1


@given(st.dictionaries(st.sampled_from((0.003, 0.01, 0.03, 0.1, 0.3, 1.0)), st.floats(0, 1), min_size=1))
@settings(max_examples=200, deadline=None)
def test_the_fused_heads_c_is_within_the_tie_of_the_best_and_the_weakest_there(cv):
    from laughlab.detector.yamnet_fit import FUSE_C_TIE, chosen_c

    c, top = chosen_c(cv), max(cv.values())
    assert cv[c] >= top - FUSE_C_TIE and not [k for k, v in cv.items() if v >= top - FUSE_C_TIE and k > c]
    if cv[c] < top:   # a C that lost by less than the tie: it is larger than the best one
        assert c > max(k for k, v in cv.items() if v == top)


@pytest.mark.slow
def test_the_fused_head_is_refitted_byte_for_byte():
    """``python -m laughlab.detector.yamnet_fit --fuse --check`` refits on the train split and compares (~3-5 min)."""
    from laughlab.detector.yamnet_fit import main

    # byte for byte on the CPU family the bundled heads were fitted on; elsewhere within yamnet_fit.CPU_TOLERANCE
    # (exit 3): the refit is fitted on YAMNet's scores, which XNNPACK rounds by CPU family
    from golden import HEADS_FITTED_ON, cpu_family

    # (another family may round alike: this AMD EPYC with AVX-VNNI besides refits the bytes of the one without)
    assert main(["--fuse", "--check"]) in ((0,) if cpu_family() == HEADS_FITTED_ON else (0, 3))


def test_detector_yamnet_fused_is_yamnet_with_the_rule_chosen_for_the_fused_head():
    from laughlab.harness.runner import _compose

    d = _compose(["detector=yamnet_fused"]).detector
    plain = _compose(["detector=yamnet"]).detector
    assert (d.name, d.fuse, d.open_at, d.open_windows) == ("yamnet", True, 0.6, 2)
    assert {k: v for k, v in d.items() if k not in ("fuse", "open_at", "open_windows")} == \
        {k: v for k, v in plain.items() if k not in ("fuse", "open_at", "open_windows")}


def test_the_detector_comparison_steps_the_fused_preset_as_a_run_would(tmp_path):
    """experiments/detector_eval.py composes a ``detector=`` option as a run does: the fused preset's
    ``laughter`` is the fused probability (it differs from the plain head's), per frame, live."""
    from laughlab_experiments.detector_eval import frame_scores

    wav = tmp_path / "in.wav"
    sf.write(wav, corpus_audio()[: 44100 * 4], 44100, subtype="PCM_16")
    fused, dt = frame_scores("yamnet_fused", str(wav))
    plain, _ = frame_scores("yamnet", str(wav))
    assert dt == pytest.approx(1 / 60) and len(fused["laughter"]) == len(plain["laughter"]) == 240
    assert np.array_equal(fused["laughter_classes"], plain["laughter_classes"])
    assert not np.array_equal(fused["laughter"], plain["laughter"])


def test_the_fused_scores_in_a_helper_thread_are_the_frame_threads_shifted_by_async_frames():
    """async_frames=2 carries each window's cues with it: the fused probability is the in-thread one, 2 frames later."""
    from laughlab.corpora import fetch
    from laughlab.corpora.mixed import load
    from laughlab_plugins.detector_yamnet import YamnetDetector, YamnetParams

    sr = 44100
    x = load(str(fetch.require()["hedgewars/Classic-Laugh"]), sr)

    def run(**kw):
        det = YamnetDetector(YamnetParams(fuse=True, **kw), Context(fps=FPS, sample_rate=sr))
        out = []
        for k in range(int(len(x) * FPS / sr)):
            f = Frame(k, k / FPS, 1 / FPS, {"mcs": 0.5}, None, {}, {}, [], 0.0)
            det.step(x[int(round(k * sr / FPS)):int(round((k + 1) * sr / FPS))], f)
            out.append(f.control["laughter"])
        det.close()
        return np.array(out)

    a, b = run(model_frames=1), run(async_frames=2)
    assert len(a) > 60 and a.max() > 0.5 and np.array_equal(a[:-2], b[2:])


def test_a_refit_check_tells_bytes_a_cpu_familys_rounding_and_a_real_change_apart(tmp_path):
    from laughlab.detector.fit import write_or_check

    bundled = tmp_path / "head.json"
    bundled.write_text('{"bias":-0.0139,"fit":{"C":0.1},"weights":[0.7,-0.2]}\n')
    same = bundled.read_text()
    near = '{"bias":-0.0145,"fit":{"C":0.1},"weights":[0.7134,-0.2]}\n'     # what another CPU family gave
    far = '{"bias":-0.0145,"fit":{"C":0.1},"weights":[0.8,-0.2]}\n'
    other = '{"bias":-0.0139,"fit":{"C":1.0},"weights":[0.7,-0.2]}\n'
    assert write_or_check(same, None, bundled, True, "head", "", tolerance=0.05) == 0
    assert write_or_check(near, None, bundled, True, "head", "", tolerance=0.05) == 3
    assert write_or_check(near, None, bundled, True, "head", "") == 1                  # no tolerance: bytes only
    assert write_or_check(far, None, bundled, True, "head", "", tolerance=0.05) == 1
    assert write_or_check(other, None, bundled, True, "head", "", tolerance=0.05) == 1       # a setting changed
    assert write_or_check('{"weights":[0.7]}\n', None, bundled, True, "head", "", tolerance=0.05) == 1  # shape


def test_a_refit_does_not_write_over_an_installed_packages_bundled_file(tmp_path, monkeypatch, capsys):
    """A packaging review: from an installed wheel, ``--out``'s default is the file inside site-packages."""
    from laughlab.core import install
    from laughlab.detector.fit import write_or_check

    bundled = tmp_path / "detector.json"
    bundled.write_text("{}\n")
    monkeypatch.setattr(install, "clone_dir", lambda: None)
    assert write_or_check('{"a":1}\n', str(bundled), bundled, False, "model", "") == 2
    assert bundled.read_text() == "{}\n" and "give --out PATH" in capsys.readouterr().err
    assert write_or_check('{"a":1}\n', str(tmp_path / "mine.json"), bundled, False, "model", "") == 0
    monkeypatch.setattr(install, "clone_dir", lambda: tmp_path)    # a clone: the bundled file is the make target
    assert write_or_check('{"a":2}\n', str(bundled), bundled, False, "model", "") == 0 and '"a":2' in bundled.read_text()
