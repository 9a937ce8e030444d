"""Issue 11 on the real corpus' held-out laughs: the faces' jaws follow the calls, the Hill fit finds them.

Runs on the fetched corpus (``make test`` fetches it first): the test split's
laughs with annotated calls, at their own rates (44.1/48 kHz).  The bounds sit
below the figures ``benchmarks/bench_real.py`` measures (README, "Faces and the
Hill torso on real laughter"), so a change that makes a face or the Hill fit
worse on real people fails here.  Timings are left to the benchmark.
"""
import csv

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.corpora import annotations, fetch

EXAMPLE = "hedgewars/Default_ru-Laugh"   # the laugh of issue 11: 1.3 s, 8 calls at 6.5 a second, 44.1 kHz


def held_out_laughs() -> list[tuple[str, str, int]]:
    """``(id, path, annotated calls)`` of the test split's laughs with annotated calls."""
    manifest = {r["id"]: r for r in csv.DictReader(open(fetch.corpus_dir() / "manifest.csv"))}
    out = []
    for iid, path in sorted(fetch.require(["laugh"], "test").items()):
        ann = annotations.bundled(iid)
        if ann is not None and ann.calls and manifest[iid]["split"] == "test":
            out.append((iid, str(path), len(ann.calls)))
    return out


@pytest.fixture(scope="module")
def laughs():
    items = held_out_laughs()
    assert len(items) >= 20 and EXAMPLE in {i for i, _, _ in items}
    return items


def jaw_r(path: str, face: str, extractor: str, tmp_path, detector: str = "none") -> float:
    from laughlab.core import pipeline
    from laughlab.harness.metrics import compute
    from laughlab.harness.runner import _compose
    from laughlab.harness.trialdata import TrialData

    cfg = _compose(["input=file", f"input.path={path}", f"face={face}", f"extractor={extractor}", "body=shapes",
                    "scheduler=none", "output=trial", f"detector={detector}"])
    out = tmp_path / "run"
    out.mkdir(exist_ok=True)
    pipeline.execute(pipeline.build(cfg), out, OmegaConf.to_container(cfg, resolve=True))
    return compute(TrialData.load(out))["jaw_envelope_r"]


@pytest.mark.parametrize("face, extractor, detector, bound, example_bound", [
    # slow: the default suite checks facs-rms under the default detector below (make test-all runs this too)
    pytest.param("facs", "rms", "none", 0.65, 0.7, marks=pytest.mark.slow),  # measured: median 0.77, the example 0.82
    ("cgm", "phoneme", "none", 0.7, 0.65),   # measured: median 0.77, the example 0.73
    # the default detector gates the face: it follows a new sound at once, lets go when YAMNet's window
    # says "not laughter" and comes back when it says "laughter" (docs/detector.md): measured median 0.66 on 2026-11-27,
    # the same with face.retract_s=null (the mouth's units are not taken back: with them, 0.60)
    ("facs", "rms", "yamnet", 0.6, 0.6),
])
def test_the_jaw_follows_the_calls_of_held_out_laughs(laughs, face, extractor, detector, bound, example_bound,
                                                       tmp_path):
    rs = {iid: jaw_r(path, face, extractor, tmp_path, detector) for iid, path, _ in laughs}
    print(f"{face} ({detector}): jaw_envelope_r median {np.median(list(rs.values())):.3f} over {len(rs)} "
          f"held-out laughs, the example {rs[EXAMPLE]:.3f}")
    assert np.median(list(rs.values())) >= bound
    assert rs[EXAMPLE] >= example_bound


def hill_input(path: str):
    from laughlab.harness.runner import _compose
    from laughlab_experiments.hill_fit import extract_target

    target, fps, _, level = extract_target(_compose(["input=file", f"input.path={path}", "extractor=pressure",
                                                     "body=hill"]))
    return target, fps, level


def test_hill_finds_the_calls_of_held_out_laughs(laughs):
    from laughlab.hill.fit import FitParams, find_calls, segment_calls

    level_ok, pressure_ok = [], []
    for iid, path, n in laughs:
        target, fps, level = hill_input(path)
        level_ok.append(abs(len(find_calls(target, fps, FitParams(), level)) - n) <= 1)
        pressure_ok.append(abs(len(segment_calls(target, fps)) - n) <= 1)
    print(f"calls within +/-1: level {np.mean(level_ok):.2f}, pressure {np.mean(pressure_ok):.2f}")
    assert np.mean(level_ok) >= 0.6                      # measured 0.69
    # the paper's way: 0.50 (0.23 before the pressure extractor's noise floor, 2026-11-29, deepened its valleys)
    assert np.mean(level_ok) > np.mean(pressure_ok) + 0.1


def test_hill_fits_the_example_laugh(laughs):
    from laughlab.hill.fit import FitParams, fit

    path, n = next((p, n) for i, p, n in laughs if i == EXAMPLE)
    target, fps, level = hill_input(path)
    res = fit(target, fps, FitParams(), level=level)
    assert abs(len(res.calls) - n) <= 1                 # measured 7 of 8
    s = res.summary()
    assert s["error_median"] <= 0.18                     # measured 0.134 (the level-free pressure: 0.141)
    assert s["evals_mean"] <= 1000 + 200 + 49            # the budget: max_evals + polish (+ one batch)


@pytest.mark.parametrize("laugh, before, measured", [
    ("ovos/female-132252__robinhood76__02940-insane-women-laughter.wav", 6.18, 1.06),
    ("hedgewars/Classic-Laugh.ogg", 5.72, 2.05),
])
def test_the_live_hill_torso_does_not_blow_up_on_real_laughs(laugh, before, measured, tmp_path):
    """The seventeenth session's note: live control (``body=hill``'s default) played these two laughs at 5-8 times
    their target pressure (whole-file error, the paper's 6.2 measure over channels.csv: 6.18 and 5.72): a quiet
    ripple fitted as a call became the template, and the abdomen's hold ratcheted call after call. With quiet calls
    left unfitted and the hold fed back, 1.06 and 2.05 (the default pipeline, 2026-11-29)."""
    import pandas as pd

    from inprocess import laughlab

    path = fetch.corpus_dir() / "files" / laugh
    r = laughlab("input=file", f"input.path={path}", "extractor=pressure", "body=hill", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 0, r.stderr
    d = pd.read_csv(tmp_path / "r" / "channels.csv")
    target, played = d["pressure"].to_numpy(), d["lung_pressure"].to_numpy()
    err = float(np.sqrt(np.mean((played - target) ** 2)) / np.sqrt(np.mean(target ** 2)))
    assert err < min(2.5, before / 2), err
    assert played.max() < 2 * target.max()
    import json

    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["hill_calls_fitted"] > 5 and m["hill_calls_quiet"] >= 1   # robinhood76: 15 and 4; Classic: 8 and 1
