"""The precision-recall curves of experiment=detector_eval (experiments/detector_eval.py)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.metrics import average_precision_score, precision_recall_curve

from laughlab_experiments.detector_eval import pr_curve, truth_frames


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 400), st.integers(1, 20))
def test_pr_curve_agrees_with_scikit_learn(seed, n, levels):
    """Ties (a score held between two model windows), any share of laughter: scikit-learn's curve and AP."""
    rng = np.random.default_rng(seed)
    y = rng.random(n) < rng.uniform(0.05, 0.95)
    if not y.any():
        y[0] = True
    s = np.round(rng.random(n) * levels) / levels + 0.2 * y * rng.random()
    p, r, thr, ap = pr_curve(s, y)
    assert np.isclose(ap, average_precision_score(y, s))
    sp, sr, sthr = precision_recall_curve(y, s)
    for t, pi, ri in zip(thr, p, r):
        k = int(np.flatnonzero(np.isclose(sthr, t))[0])
        assert np.isclose(pi, sp[k]) and np.isclose(ri, sr[k])


def test_pr_curve_by_hand():
    # scores 0.9 (laugh), 0.8 (not), 0.4 (laugh), 0.4 (not): thresholds 0.9, 0.8, 0.4
    p, r, thr, ap = pr_curve(np.array([0.9, 0.8, 0.4, 0.4]), np.array([True, False, True, False]))
    assert np.allclose(thr, [0.9, 0.8, 0.4])
    assert np.allclose(p, [1.0, 0.5, 0.5]) and np.allclose(r, [0.5, 0.5, 1.0])
    assert np.isclose(ap, 0.5 * 1.0 + 0.0 * 0.5 + 0.5 * 0.5)


def test_truth_frames_mark_the_frames_inside_bouts(tmp_path):
    t = tmp_path / "x.truth.csv"
    t.write_text("kind,bout,onset_s,offset_s,intensity\nbout,0,0.1000,0.2000,1.0\n")
    y = truth_frames(str(t), 20, 1 / 60)   # frame centres (k + 0.5) / 60
    assert np.flatnonzero(y).tolist() == [6, 7, 8, 9, 10, 11]


def test_every_detector_a_run_compares_has_a_curve_a_plugins_and_an_overridden_one_too():
    """A plugin author's review: a detector of their own was in the table but not among the curves, and a
    condition's detector.* overrides were dropped from them."""
    from laughlab_experiments.detector_eval import OWN_THRESHOLD, SCORES, curves

    conds = {"none": ["detector=none"], "yamnet": ["detector=yamnet"], "mine": ["detector=modlaugh"],
             "low": ["detector=yamnet", "detector.threshold=0.3"], "again": ["detector=modlaugh", "seed=2"]}
    got = curves(conds)
    assert [(n, d, own, key, at) for n, d, own, key, at in got] == [
        ("yamnet (head)", "yamnet", (), "laughter", SCORES["yamnet (head)"][2]),
        ("yamnet classes", "yamnet", (), "laughter_classes", SCORES["yamnet classes"][2]),
        ("modlaugh", "modlaugh", (), "laughter", OWN_THRESHOLD),
        ("yamnet (head) (threshold=0.3)", "yamnet", ("detector.threshold=0.3",), "laughter",
         SCORES["yamnet (head)"][2]),
        ("yamnet classes (threshold=0.3)", "yamnet", ("detector.threshold=0.3",), "laughter_classes",
         SCORES["yamnet classes"][2])]
    assert curves({"none": ["detector=none"]}) == []
    # a threshold the condition sets is its curve's operating point (a diff review: marked at the default)
    strict = curves({"strict": ["detector=yamnet", "detector.open_at=0.8", "detector.class_open=0.3"]})
    assert [(n, at) for n, _, _, _, at in strict] == [("yamnet (head) (class_open=0.3, open_at=0.8)", 0.8),
                                                       ("yamnet classes (class_open=0.3, open_at=0.8)", 0.3)]


def test_a_detector_of_ones_own_is_drawn_with_its_threshold(tmp_path):
    from laughlab_experiments.detector_eval import pr_figure

    y = np.array([True, True, False, False] * 50)
    fig, out = pr_figure({"modlaugh": y * 0.9 + 0.05}, y, thresholds={"modlaugh": 0.5})
    assert out["scores"]["modlaugh"]["at_gate_threshold"] == {"threshold": 0.5, "precision": 1.0, "recall": 1.0}
    assert out["scores"]["modlaugh"]["average_precision"] == 1.0


def test_each_detector_is_stepped_over_each_recording_once_and_a_plugin_that_cannot_be_is_said(tmp_path, monkeypatch,
                                                                                                capsys):
    """The last session's note: a plugin's detector was stepped over the first recording twice (a probe, then the
    curve); a plugin that raises stepped alone is one warning and no curve, the others drawn."""
    from types import SimpleNamespace

    from omegaconf import OmegaConf

    import laughlab_experiments.detector_eval as de

    calls = []

    def scores(det, path, fps=60.0, overrides=()):
        calls.append((det, path, overrides))
        if det == "broken":
            raise KeyError("mcs_raw")
        return {"laughter": np.linspace(0, 1, 40), "laughter_classes": np.linspace(1, 0, 40)}, 1 / 60

    monkeypatch.setattr(de, "frame_scores", scores)
    monkeypatch.setattr(de, "truth_frames", lambda truth, n, dt: np.arange(n) >= n // 2)
    from laughlab.harness.corpus import Item

    items = [Item(f"real-{k}", ("input=file", f"input.path=r{k}.wav"), "real", None, f"t{k}.json") for k in range(3)]
    run = SimpleNamespace(items=items, out_dir=tmp_path, cfg=OmegaConf.create({}),
                          conditions={"y": ["detector=yamnet"], "mine": ["detector=modlaugh"],
                                      "b": ["detector=broken"]})
    out = de.extra(run)["detector_pr"]
    assert sorted(calls) == sorted([(d, f"r{k}.wav", ()) for d in ("yamnet", "modlaugh") for k in range(3)] +
                                   [("broken", "r0.wav", ())])
    assert sorted(out["scores"]) == ["modlaugh", "yamnet (head)", "yamnet classes"]
    assert out["scores"]["modlaugh"]["average_precision"] == 1.0   # the rising score on the second half's truth
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no PR curve of detector=broken" in err and "KeyError" in err
    assert (tmp_path / "plots" / "detector_pr.png").is_file()
