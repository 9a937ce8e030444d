"""The harness: corpus, confidence intervals, trials, results.json, reports, sweeps."""
import json
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import soundfile as sf
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats
from omegaconf import OmegaConf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.errors import LaughlabError
from laughlab.harness.corpus import build_corpus, folder_items
from laughlab.io.audio import AUDIO_SUFFIXES
from laughlab.harness.experiment import run_experiment
from laughlab.harness.report import _clear_best, write_report
from laughlab.harness.results import SCHEMA, mean_ci, separated

ROOT = Path(__file__).resolve().parents[1]


def test_mean_ci_by_hand():
    r = mean_ci([1.0, 2.0, 3.0, float("nan")])
    assert r["n"] == 3 and r["mean"] == 2.0 and r["std"] == pytest.approx(1.0)
    # a resample's mean is k/3 for k in 3..9: the 2.5th and 97.5th percentiles of 4,999 resamples lie
    # between 1 and 3; the t interval was 2 +- 4.30 / sqrt(3) = [-0.48, 4.48], outside the values
    lo, hi = r["ci95"]
    assert 1.0 <= lo < 2.0 < hi <= 3.0
    assert mean_ci([5.0])["ci95"] == [5.0, 5.0] and mean_ci([4.0, 4.0, 4.0])["ci95"] == [4.0, 4.0]
    assert math.copysign(1.0, mean_ci([-0.0, -0.0])["mean"]) == 1.0     # an entropy of nothing: 0, not "-0"
    assert mean_ci([])["n"] == 0 and math.isnan(mean_ci([])["mean"])
    # seeded: the same values give the same interval, in any run
    assert mean_ci([0.1, 0.7, 0.2, 0.9]) == mean_ci([0.1, 0.7, 0.2, 0.9])


def test_mean_ci_of_a_rare_event_stays_a_fraction():
    """The case a reviewer found in reports/detector_eval: 1 trial in 20 at 0.5, the rest 0, gave a t
    interval of [-0.027, 0.077] for a fraction; the bootstrap's lower end is 0."""
    r = mean_ci([0.5] + [0.0] * 19)
    assert r["mean"] == pytest.approx(0.025)
    assert r["ci95"][0] == 0.0 and 0.025 < r["ci95"][1] <= 0.5


def test_mean_ci_of_many_normal_values_is_near_the_t_interval():
    x = np.random.default_rng(3).normal(10.0, 2.0, 400)
    half = stats.t.ppf(0.975, 399) * x.std(ddof=1) / math.sqrt(400)
    lo, hi = mean_ci(x)["ci95"]
    assert lo == pytest.approx(x.mean() - half, abs=0.1 * half)
    assert hi == pytest.approx(x.mean() + half, abs=0.1 * half)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40))
def test_mean_ci_lies_within_the_values(values):
    r = mean_ci(values)
    lo, hi = r["ci95"]
    assert min(values) <= lo <= hi <= max(values)
    assert lo <= r["mean"] + 1e-12 and r["mean"] - 1e-12 <= hi


def test_mean_ci_is_the_normal_interval_for_a_large_sample():
    """The bounds above hold for any interval clamped to the values (a test audit: they cannot fail); its width
    can.  For 400 values of a normal sample the percentile bootstrap's interval is about mean +- 1.96 sd / sqrt(n)
    (the central limit theorem), and its sd is the sample's."""
    x = np.random.default_rng(7).normal(2.0, 0.5, 400)
    r = mean_ci(x)
    half = 1.959964 * x.std(ddof=1) / np.sqrt(len(x))
    assert r["ci95"] == pytest.approx([x.mean() - half, x.mean() + half], abs=0.1 * half)
    assert r["std"] == pytest.approx(x.std(ddof=1)) and r["n"] == 400
    assert mean_ci([0.3] * 5)["ci95"] == [0.3, 0.3] and mean_ci([float("nan")])["n"] == 0
    # one value's sd is undefined (it was 0: a data user's review); five alike have sd 0
    assert np.isnan(mean_ci([0.3])["std"]) and mean_ci([0.3] * 5)["std"] == 0.0


def test_bold_only_where_the_intervals_are_apart():
    def doc(a, b):
        return {"metrics": {"m": {"higher_is_better": True}},
                "results": {"A": {"m": mean_ci(a)}, "B": {"m": mean_ci(b)}}}
    apart = doc([0.8, 0.9, 0.85, 0.95] * 3, [0.1, 0.2, 0.15, 0.12] * 3)   # a best needs 10 trials a condition
    assert separated(apart["results"]["A"]["m"], apart["results"]["B"]["m"])
    assert _clear_best(apart, "m", ["A", "B"]) == "A"
    near = doc([0.5, 0.9, 0.6, 0.8] * 3, [0.4, 0.85, 0.55, 0.7] * 3)      # A's mean higher, intervals overlap
    assert _clear_best(near, "m", ["A", "B"]) is None
    lower = {**apart, "metrics": {"m": {"higher_is_better": False}}}
    assert _clear_best(lower, "m", ["A", "B"]) == "B"
    assert _clear_best({**apart, "metrics": {"m": {"higher_is_better": None}}}, "m", ["A", "B"]) is None
    # one trial apiece: zero-width "intervals" never overlap, and a best was bolded on 1 trial (a new-user review)
    assert _clear_best(doc([0.9], [0.1]), "m", ["A", "B"]) is None
    assert _clear_best(doc([0.9], [0.1, 0.2, 0.15]), "m", ["A", "B"]) is None
    # two each, all alike: [0.9, 0.9] against [0.1, 0.1] was bolded, and two trials' 0 [0, 0] (a data user's review)
    assert _clear_best(doc([0.9, 0.9], [0.1, 0.1]), "m", ["A", "B"]) is None
    assert _clear_best(doc([0.9] * 9, [0.1] * 10), "m", ["A", "B"]) is None
    assert _clear_best(doc([0.9] * 10, [0.1] * 10), "m", ["A", "B"]) == "A"


def test_no_detector_is_not_the_best_at_its_own_always_open_signal():
    """A new-user review: detector_eval's report bolded detector=none's recall of 1 and latency of a frame, true by
    construction (its laughter signal is always on); the clip metrics still compare it."""
    def doc(metric, better, none, other):
        return {"metrics": {metric: {"higher_is_better": better}},
                "conditions": {"none": ["detector=none"], "yamnet": ["detector=yamnet"]},
                "results": {"none": {metric: mean_ci(none)}, "yamnet": {metric: mean_ci(other)}}}
    assert _clear_best(doc("detector_recall", True, [1.0] * 12, [0.2, 0.3, 0.25, 0.2] * 3), "detector_recall",
                       ["none", "yamnet"]) is None
    assert _clear_best(doc("detection_latency_median_s", False, [0.02] * 12, [0.9, 1.0, 0.8, 0.95] * 3),
                       "detection_latency_median_s", ["none", "yamnet"]) is None
    assert _clear_best(doc("bouts_answered", True, [1.0] * 12, [0.2, 0.3, 0.25, 0.2] * 3), "bouts_answered",
                       ["none", "yamnet"]) == "none"


def test_a_condition_that_played_no_clip_is_not_the_best_at_a_trivial_0():
    """The smoke report bolded scheduler=none's offset tail of 0 s: it never played a clip."""
    def doc(tail_b, cut_b):
        return {"metrics": {"offset_tail_s": {"higher_is_better": False}, "cutoff_rate": {"higher_is_better": False}},
                "results": {"A": {"offset_tail_s": mean_ci([0.5, 0.7, 0.6, 0.8] * 3), "cutoff_rate": mean_ci([0.0] * 12)},
                            "B": {"offset_tail_s": mean_ci(tail_b), "cutoff_rate": mean_ci(cut_b)}}}
    assert _clear_best(doc([0.0] * 12, []), "offset_tail_s", ["A", "B"]) is None        # B played no clip
    assert _clear_best(doc([0.0] * 12, [0.0] * 12), "offset_tail_s", ["A", "B"]) == "B"  # B played clips
    assert _clear_best(doc([0.1, 0.2, 0.1, 0.15] * 3, []), "offset_tail_s", ["A", "B"]) == "B"  # not the trivial 0


def test_a_constant_value_under_every_condition_is_the_same_whatever_the_trials():
    """detector_others drew a panel of zeros (n=3, 9, 5, 253): one value in every trial of every condition says
    nothing about the conditions, whatever their numbers of trials; a mean that only looks alike does."""
    from laughlab.harness.report import _same_table, same_everywhere

    def doc(a, b):
        return {"metrics": {"m": {"higher_is_better": False, "units": "fraction", "description": "d"}},
                "results": {"A": {"m": mean_ci(a)}, "B": {"m": mean_ci(b)}}}
    assert same_everywhere(doc([0.0] * 3, [0.0] * 40), "m")
    assert not same_everywhere(doc([0.0] * 3, [0.5] * 40), "m")                  # two constants
    assert not same_everywhere(doc([0.0, 1.0, 0.5], [0.0, 1.0, 0.5] * 2), "m")   # alike means, not one value
    assert same_everywhere(doc([0.0, 1.0, 0.5], [0.0, 1.0, 0.5]), "m")           # the same trials
    assert not same_everywhere(doc([0.0] * 3, []), "m")                          # B measured nothing
    row = [ln for ln in _same_table(doc([0.0] * 3, [0.0] * 40)) if ln.startswith("| m ")]
    assert row == ["| m ↓ | fraction | 0 [0, 0] (every trial; n=3-40 by condition) |"]


def test_corpus_profiles_seeds_and_folder(tmp_path):
    items = build_corpus({"profiles": ["mild", "giggle"], "seeds": 3, "duration_s": 10})
    assert [i.id for i in items] == ["mild-s00", "mild-s01", "mild-s02", "giggle-s00", "giggle-s01", "giggle-s02"]
    assert "input.seed=2" in items[2].overrides and "input.profile=mild" in items[2].overrides
    sf.write(tmp_path / "b.wav", np.zeros(800), 8000)
    sf.write(tmp_path / "a.flac", np.zeros(800), 8000)
    (tmp_path / "a.truth.csv").write_text("kind,bout,onset_s,offset_s,intensity\nbout,0,0.0,0.1,0.5\n")
    (tmp_path / "notes.txt").write_text("x")
    rec = folder_items(tmp_path)
    assert [i.id for i in rec] == ["rec-a", "rec-b"]
    assert rec[0].truth.endswith("a.truth.csv") and rec[1].truth is None
    with pytest.raises(LaughlabError, match="unknown synthetic profile"):
        build_corpus({"profiles": ["loud"], "seeds": 1})
    with pytest.raises(LaughlabError, match="no audio files"):
        folder_items(_empty(tmp_path))


def test_a_corpus_folder_of_session_folders_names_them_and_a_wave_file_is_read(tmp_path):
    """A new-user review: a folder whose recordings sit in subfolders was said to hold no audio, and a ``.wave``
    file (WAV's other suffix) was not a recording.  The line now names the subfolders to give instead."""
    for day in ("day2", "day1", ".hidden"):
        (tmp_path / day).mkdir()
        sf.write(tmp_path / day / "take.wav", np.zeros(800), 8000)
    with pytest.raises(LaughlabError) as e:
        folder_items(tmp_path)
    assert str(e.value) == (f"corpus folder {tmp_path} holds no audio files ({', '.join(AUDIO_SUFFIXES)}) itself; "
                            "its subfolder(s) day1, day2 do: give one of them as harness.corpus.folder (subfolders "
                            "are not searched)")
    sf.write(tmp_path / "day1" / "other.wave", np.zeros(800), 8000, format="WAV")
    assert [i.id for i in folder_items(tmp_path / "day1")] == ["rec-other", "rec-take"]


def test_a_corpus_folder_with_one_name_in_two_formats_is_one_line_before_any_trial(tmp_path):
    """A review: ``take.flac`` beside ``take.mp3`` (one recording exported twice) ran both as the trial
    ``rec-take``, into the same folder, and the experiment stopped part way on ``cannot write ...``."""
    from inprocess import laughlab

    sf.write(tmp_path / "take.wav", np.zeros(8000), 8000)
    sf.write(tmp_path / "take.flac", np.zeros(8000), 8000)
    with pytest.raises(LaughlabError, match=r"two recordings share the name 'take' \(take.flac, take.wav\)"):
        folder_items(tmp_path)
    r = laughlab("experiment=smoke", f"harness.corpus.folder={tmp_path}", "harness.corpus.seeds=1",
                 "harness.corpus.profiles=[mild]", "harness.showcase=null", "harness.plots=false", "progress=off",
                 f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and not (tmp_path / "run").exists()
    assert r.stderr.startswith("laughlab: error: corpus folder ") and r.stderr.count("\n") == 1, r.stderr


def _empty(tmp_path):
    d = tmp_path / "empty"
    d.mkdir()
    return d


def tiny_cfg(**harness):
    from laughlab.core.config import compose_config

    cfg = compose_config(["experiment=smoke"])
    # about the harness, not the detector: the papers' pipeline (detector=none), as before issue 27
    h = {"name": "tiny", "conditions": {"energy": ["scheduler=energy", "detector=none"],
                                       "none": ["scheduler=none", "detector=none"]},
         "corpus": {"profiles": ["intense"], "seeds": 2, "duration_s": 4.0}, "showcase": "intense-s00", "jobs": 1}
    h.update(harness)
    cfg.harness = OmegaConf.create(h)
    return cfg


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp")
    doc = run_experiment(tiny_cfg(), out, base_overrides=[], progress=False)
    return out, doc


@pytest.fixture(scope="module")
def small_run(tiny_run, tmp_path_factory):
    """tiny_run's folder with its results cut to 3 metrics (one differing between the conditions, one the same,
    one of compute time): for the tests of where a report goes and which files it replaces or keeps, not of what
    its figures show.  metrics.png of all 38 metrics, drawn again as PNG and PDF, was most of each report's 5-7 s."""
    out = tmp_path_factory.mktemp("small") / "exp"
    shutil.copytree(tiny_run[0], out)
    doc = json.loads((out / "results.json").read_text())
    keep = ("miss_rate", "cutoff_rate", "frame_ms_p50")
    doc["metrics"] = {m: doc["metrics"][m] for m in keep}
    doc["results"] = {c: {m: r[m] for m in keep} for c, r in doc["results"].items()}
    (out / "results.json").write_text(json.dumps(doc))
    return out


def test_experiment_records_and_results_schema(tiny_run):
    out, doc = tiny_run
    lines = (out / "metrics.jsonl").read_text().splitlines()
    records = [json.loads(x) for x in lines]
    assert len(records) == 4 == doc["n_trials"]
    assert [(r["condition"], r["input"]) for r in records] == [
        ("energy", "intense-s00"), ("energy", "intense-s01"), ("none", "intense-s00"), ("none", "intense-s01")]
    saved = json.loads((out / "results.json").read_text())
    for key in ("schema", "experiment", "date", "git_hash", "versions", "plugins", "config", "corpus",
                "conditions", "n_trials", "metrics", "results", "by_profile", "extra"):
        assert key in saved
    assert saved["schema"] == SCHEMA and saved["versions"]["laughlab"]
    r = saved["results"]["energy"]["miss_rate"]
    assert set(r) == {"mean", "ci95", "std", "n"} and r["n"] == 2
    assert saved["results"]["none"]["miss_rate"]["mean"] == 1.0       # no clip ever starts
    assert (out / "plots" / "energy_fig4_2_energy.png").exists() and (out / "plots" / "metrics.png").exists()
    assert not (out / "trials").exists()                               # trial outputs not kept


def test_experiment_is_reproducible(tiny_run, tmp_path):
    out, doc = tiny_run
    doc2 = run_experiment(tiny_cfg(showcase=None, plots=False), tmp_path, base_overrides=[], progress=False)
    assert not (tmp_path / "plots").exists()  # harness.plots=false: results.json only (a report draws the figure)
    for cond in ("energy", "none"):
        for m in ("intensity_r_clip", "miss_rate", "clip_entropy", "onset_latency_median_s"):
            a, b = doc["results"][cond][m]["mean"], doc2["results"][cond][m]["mean"]
            assert (a == b) or (math.isnan(a) and math.isnan(b)), (cond, m)


def test_the_same_seed_draws_the_same_metrics_png(tiny_run, tmp_path):
    """A sweeps review: metrics.png drew the compute-time panels, so two runs of one seed never gave its bytes;
    they are in timing.png now, the one figure that differs run to run."""
    out, doc = tiny_run
    doc2 = run_experiment(tiny_cfg(showcase=None), tmp_path, base_overrides=[], progress=False)
    assert doc2["results"]["energy"]["frame_ms_p50"]["mean"] != doc["results"]["energy"]["frame_ms_p50"]["mean"]
    assert (tmp_path / "plots" / "metrics.png").read_bytes() == (out / "plots" / "metrics.png").read_bytes()
    assert (tmp_path / "plots" / "timing.png").exists() and (out / "plots" / "timing.png").exists()


def test_report_tables_and_figures(tiny_run, tmp_path):
    out, _ = tiny_run
    readme = write_report(out, tmp_path / "rep", "python -m laughlab report X")
    text = readme.read_text()
    assert text.startswith("# tiny")
    # the trials behind the tables, a row each: their means are the table's (a data user's review: JSON only)
    trials, doc = pd.read_csv(tmp_path / "rep" / "trials.csv"), json.loads((out / "results.json").read_text())
    assert list(trials.columns[:5]) == ["condition", "input", "profile", "seed", "duration_s"]
    assert len(trials) == doc["n_trials"] and "[trials.csv](trials.csv)" in text
    for cond, rows in trials.groupby("condition"):
        assert rows["miss_rate"].mean() == pytest.approx(doc["results"][cond]["miss_rate"]["mean"])
    assert "| metric | units | energy mean [95% CI] | none mean [95% CI] |" in text
    # synthetic laughter holds no cough: no row of n/a, one line naming it
    results = text.split("## Metrics")[0]
    assert "| false_starts_cough_per_min" not in results and "n/a | n/a" not in results
    assert "No value under any condition" in text and "`false_starts_cough_per_min`" in text
    # tiny: 2 seeds a condition, too few for a bold (it was bold until a data user's review)
    assert "| miss_rate ↓ | fraction | 0 [0, 0] (n=2) | 1 [1, 1] (n=2) |" in text
    assert "(n=K): a mean of fewer than 10 trials" in text
    assert (tmp_path / "rep" / "figures" / "metrics.png").exists()
    assert (tmp_path / "rep" / "figures" / "energy_fig4_2_energy.png").exists()
    # the showcase's run figures come with their PDFs, for print (PNG only before), and the README says so
    for png in (tmp_path / "rep" / "figures").glob("*_*.png"):
        assert png.with_suffix(".pdf").read_bytes().startswith(b"%PDF-"), png.name
    assert "vector PDF of the same name beside it in `figures/`" in text
    # every figure in figures/ is shown or linked (a review found Fig. 3.2 and the filmstrips there unmentioned)
    for png in (tmp_path / "rep" / "figures").glob("*.png"):
        assert f"(figures/{png.name})" in text, png.name
    assert "[energy_filmstrip.png](figures/energy_filmstrip.png)" in text
    # Fig. 3.1, the same bytes under both (one extractor, one input): shown once, the other copy linked
    figs = tmp_path / "rep" / "figures"
    assert (figs / "energy_fig3_1_calibration.png").read_bytes() == (figs / "none_fig3_1_calibration.png").read_bytes()
    assert text.count("![energy_fig3_1_calibration.png]") == 1 and "![none_fig3_1_calibration.png]" not in text
    assert ("**every condition**, Fig. 3.1 (the same bytes under each: "
            "[none_fig3_1_calibration.png](figures/none_fig3_1_calibration.png))") in text


def test_report_panels_draws_the_metrics_a_paper_discusses_in_a_column_and_says_when_a_figure_is_too_tall(
        tiny_run, tmp_path):
    """A column's metrics.png of every metric was 13.9 in tall, taller than a column, with no way to draw fewer
    panels. ``report --panels A,B`` draws only those, in that order (a compute one in timing.png), and the table
    keeps every metric; without it, a column report says which figure is too tall. A name the run did not measure:
    one line, and the earlier report stays."""
    from PIL import Image

    out, doc = tiny_run
    # every metric measured under both conditions (scheduler=none's clip metrics, n/a there, given energy's halved),
    # so that each has its panel: a metric measured under one condition only has none (a researcher's review)
    full = tmp_path / "full"
    shutil.copytree(out, full)
    d = json.loads((full / "results.json").read_text())
    for m, e in d["results"]["energy"].items():
        if e["n"] and not d["results"]["none"][m]["n"]:
            d["results"]["none"][m] = {**e, "mean": e["mean"] / 2, "ci95": [v / 2 for v in e["ci95"]]}
    (full / "results.json").write_text(json.dumps(d))
    r = laughlab("report", full, "--out", tmp_path / "all", "--width", "column")
    assert r.returncode == 0, r.stderr
    assert re.search(r"^laughlab: metrics\.png \(1\d\.\d in tall\) is taller than a column \(about 9\.5 in\): "
                     r"--panels NAME,NAME draws only the metrics you discuss", r.stdout, re.M), r.stdout
    panels = ["onset_latency_median_s", "miss_rate", "intensity_r_clip", "frame_ms_p50"]
    shown = []
    with pytest.MonkeyPatch.context() as mp:
        from matplotlib.figure import Figure

        real = Figure.savefig
        mp.setattr(Figure, "savefig", lambda fig, name, *a, **k: (
            k.get("format", "png") == "png" and shown.append((Path(name).stem, [ax.get_title() for ax in fig.axes
                                                                                if ax.get_visible()])),
            real(fig, name, *a, **k))[1])
        r = laughlab("report", out, "--out", tmp_path / "some", "--width", "column", "--panels", ",".join(panels))
        assert r.returncode == 0 and "taller than a column" not in r.stdout, r.stdout + r.stderr
        titles = dict(shown)
        shown.clear()
        r = laughlab("report", out, "--out", tmp_path / "timing", "--panels", "frame_ms_p50,frame_ms_p50")
        assert r.returncode == 0, r.stderr
        assert [(n, [t.split(" ")[0] for t in ts if t]) for n, ts in shown] == [("timing", ["frame_ms_p50"])]
    assert [t.split(" ")[0] for t in titles["metrics"] if t] == panels[:3]
    assert [t.split(" ")[0] for t in titles["timing"]] == panels[3:]
    figs = tmp_path / "some" / "figures"
    for name, tall in (("metrics.png", 2), ("timing.png", 1)):
        with Image.open(figs / name) as im:   # the column's width, one panel spanning it alone
            assert im.size[0] == 455 and im.size[1] < (tall * 1.75 + 1.2) * 130, (name, im.size)
    text = (tmp_path / "some" / "README.md").read_text()
    assert all(f"| {m} " in text for m in doc["metrics"] if any(doc["results"][c][m]["n"] for c in doc["results"]))
    before = (figs / "metrics.png").read_bytes()
    r = laughlab("report", out, "--out", tmp_path / "some", "--panels", "miss_rate,jaw_mean")
    assert r.returncode == 2 and r.stderr.startswith("laughlab: error: --panels: tiny measured no jaw_mean; its "
                                                     "metrics: ") and len(r.stderr.splitlines()) == 1, r.stderr
    assert (figs / "metrics.png").read_bytes() == before
    # compute metrics only (a name given twice: once): timing.png alone, and the report links no metrics.png
    text = (tmp_path / "timing" / "README.md").read_text()
    assert "figures/metrics.png" not in text and "![timing](figures/timing.png)" in text
    assert not (tmp_path / "timing" / "figures" / "metrics.png").exists()


def test_report_goes_next_to_the_run_unless_out_is_given(small_run, tmp_path):
    """Issue 26: ``report RUN`` used to overwrite the committed reports/<experiment>/ of the working folder."""
    run = tmp_path / "run"
    shutil.copytree(small_run, run)
    work = tmp_path / "work"  # the folder the command runs in: nothing may appear here
    work.mkdir()
    r = laughlab("report", run, cwd=work)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"laughlab: report written: {run / 'report' / 'README.md'}"
    assert (run / "report" / "figures" / "metrics.png").exists() and list(work.iterdir()) == []
    assert (run / "report" / "README.md").read_text().startswith("# tiny")
    r = laughlab("report", run, "--out", "reports/tiny", cwd=work)
    assert r.returncode == 0, r.stderr
    text = (work / "reports" / "tiny" / "README.md").read_text()
    assert f"Generated by `python -m laughlab report {run} --out reports/tiny`" in text  # the command that remakes it
    assert "- the run" not in text                 # a results.json without Hydra's record of its command
    # with it, the experiment's own command too (a review: a report named only its report step)
    (run / ".hydra").mkdir()
    # (overwrite=true and progress=off are how it was run, not what it computes: left out)
    (run / ".hydra" / "overrides.yaml").write_text("- experiment=smoke\n- overwrite=true\n"
                                                   "- harness.corpus.profiles=[intense]\n- progress=off\n")
    r = laughlab("report", run, "--out", "reports/tiny", cwd=work)
    text = (work / "reports" / "tiny" / "README.md").read_text()
    assert (f"- the run: `python -m laughlab experiment=smoke 'harness.corpus.profiles=[intense]' "
            f"hydra.run.dir={run}`\n") in text


def test_a_new_report_keeps_the_users_files_in_figures(small_run, tmp_path):
    """A sweeps review: regenerating a report deleted a caption and an edited copy of a figure the user had put in
    report/figures/.  Only the files the earlier report wrote (its manifest) are replaced or removed."""
    rep = tmp_path / "rep"
    assert laughlab("report", small_run, "--out", rep).returncode == 0
    figs = rep / "figures"
    (figs / "caption.txt").write_text("Figure 2 caption\n")
    shutil.copyfile(figs / "metrics.png", figs / "metrics_edited_by_me.png")
    (figs / "stale.png").write_bytes(b"x")   # as if the earlier report had written it and this one does not
    files = json.loads((rep / ".laughlab-report.json").read_text())["files"]
    (rep / ".laughlab-report.json").write_text(json.dumps({"files": files + ["figures/stale.png"]}))
    assert laughlab("report", small_run, "--out", rep).returncode == 0
    assert (figs / "caption.txt").read_text() == "Figure 2 caption\n" and (figs / "metrics_edited_by_me.png").exists()
    assert not (figs / "stale.png").exists() and (figs / "metrics.png").exists()
    # a file of the user's where the report would write one (no earlier report wrote it) is refused, and kept
    (rep / ".laughlab-report.json").write_text(json.dumps({"files": [f for f in files if f != "figures/metrics.png"]}))
    (figs / "metrics.png").write_bytes(b"mine")
    r = laughlab("report", small_run, "--out", rep)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "figures/metrics.png" in r.stderr
    assert (figs / "metrics.png").read_bytes() == b"mine"


def test_a_report_edited_in_place_is_not_replaced_without_asking(small_run, tmp_path):
    """A diff review: notes added to a report's README, or one of its figures retouched in place, were replaced
    by the next report without a word (only other names were kept).  The manifest holds each file's sha256: an
    edited one is refused in one line and kept; --overwrite replaces it."""
    rep = tmp_path / "rep"
    assert laughlab("report", small_run, "--out", rep).returncode == 0
    assert laughlab("report", small_run, "--out", rep).returncode == 0   # unchanged: replaced as before
    readme = rep / "README.md"
    mine = readme.read_text() + "\nMy notes on this run.\n"
    readme.write_text(mine)
    r = laughlab("report", small_run, "--out", rep)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {rep}: README.md changed since the report wrote "
                                              "it; choose another --out, or add --overwrite to replace it\n")
    assert readme.read_text() == mine
    r = laughlab("report", small_run, "--out", rep, "--overwrite")
    assert r.returncode == 0 and "My notes" not in readme.read_text()


def test_a_report_replaces_only_a_report_and_goes_with_its_run(small_run, tmp_path):
    """``report --out`` into a folder of the user's is refused (their README kept); into an earlier report it
    replaces it; the report beside a finished run counts among the run's files, so overwriting the run
    removes it (it was left, stale, beside the new run's results)."""
    from laughlab.core import rundir

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "README.md").write_text("# my notes\n")
    r = laughlab("report", small_run, "--out", mine)
    assert r.returncode == 2 and "holds files that are not a laughlab report (README.md)" in r.stderr
    assert [p.name for p in mine.iterdir()] == ["README.md"] and (mine / "README.md").read_text() == "# my notes\n"
    rep = tmp_path / "rep"
    assert laughlab("report", small_run, "--out", rep).returncode == 0
    assert laughlab("report", small_run, "--out", rep).returncode == 0        # an earlier report: replaced
    # another experiment's report is not replaced without --overwrite (a review: a sweep's report was silently
    # replaced by another run's)
    other = tmp_path / "other"
    shutil.copytree(small_run, other)
    doc = json.loads((other / "results.json").read_text())
    (other / "results.json").write_text(json.dumps({**doc, "experiment": "other"}))
    before = (rep / "README.md").read_text()
    r = laughlab("report", other, "--out", rep)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {rep} holds the report of another experiment "
                                              f"('{doc['experiment']}', not 'other'); choose another --out, or add "
                                              "--overwrite to replace it\n")
    assert (rep / "README.md").read_text() == before
    r = laughlab("report", other, "--out", rep, "--overwrite")
    assert r.returncode == 0 and (rep / "README.md").read_text().startswith("# other\n")
    run = tmp_path / "run"
    claim = rundir.claim(run)                                  # a finished run, as the command line leaves one
    for item in small_run.iterdir():
        (shutil.copytree if item.is_dir() else shutil.copyfile)(item, run / item.name)
    claim.finish("hash")
    os.close(claim.fd)
    assert laughlab("report", run).returncode == 0 and (run / "report" / "README.md").exists()
    again = rundir.claim(run, overwrite=True)                 # overwrite=true: the earlier run's files go
    os.close(again.fd)
    assert not (run / "report").exists() and not (run / "results.json").exists()


REAL = {"sets": ["real", "mixed"], "split": "test", "scenes": 1, "duration_s": 10.0, "snr_db": [10], "seed": 0}


def test_without_the_real_corpus_an_experiment_runs_the_synthetic_half_and_says_so(tmp_path, monkeypatch, capsys):
    """Issue 26: the headline experiment on a fresh machine (an empty data folder)."""
    from laughlab.corpora.fetch import CorpusNotFetched

    monkeypatch.setenv("LAUGHLAB_DATA", str(tmp_path / "fresh"))
    spec = {"profiles": ["intense"], "seeds": 1, "duration_s": 3.0}
    left_out = []
    items = build_corpus({**spec, "real": {**REAL, "if_missing": "skip"}}, [], left_out)
    assert [i.id for i in items] == ["intense-s00"] and left_out == ["real", "mixed"]
    with pytest.raises(CorpusNotFetched, match=r"not fetched .*; run: python -m laughlab corpus fetch$"):
        build_corpus({**spec, "real": REAL})                                   # stop: the default
    with pytest.raises(CorpusNotFetched, match="run: python -m laughlab corpus fetch"):   # nothing would be left
        build_corpus({"profiles": [], "real": {**REAL, "if_missing": "skip"}})
    with pytest.raises(LaughlabError, match="if_missing must be skip or stop"):
        build_corpus({**spec, "real": {**REAL, "if_missing": "fetch"}})

    out = tmp_path / "exp"
    doc = run_experiment(tiny_cfg(corpus={**spec, "real": {**REAL, "if_missing": "skip"}}, showcase=None,
                                  plots=False), out, base_overrides=[], progress=False)
    err = capsys.readouterr().err.splitlines()
    assert err == [f"tiny: the real corpus is not fetched (in {tmp_path / 'fresh'}), so its sets (real, mixed) are "
                   "left out: running the other 1 inputs. To add them: python -m laughlab corpus fetch (once), then "
                   "run this command again into a new hydra.run.dir"]
    assert doc["n_trials"] == 2 and doc["corpus"]["not_fetched"] == ["real", "mixed"]
    assert not (tmp_path / "fresh").exists()                                   # nothing written for the real sets
    text = write_report(out).read_text()
    assert "**without the real recordings**: the real corpus was not fetched, so its sets (real, mixed)" in text


def test_a_best_lag_at_the_edge_of_its_search_is_marked_and_definitions_are_whole(tiny_run):
    """A review: a lag of 2.0 [2.0, 2.0] s (the end of the [0, 2] s search) went unflagged, so its correlation read
    as a finding; and the Metrics table cut each definition at its docstring's first line."""
    import copy

    from laughlab.harness.report import _results_table

    _, doc = tiny_run
    info = doc["metrics"]["intensity_lag_clip_s"]
    assert info["search"] == [0.0, 2.0] and "search" not in doc["metrics"]["miss_rate"]
    d = copy.deepcopy(doc)
    conds = list(d["results"])
    for c, mean in zip(conds, (2.0, 0.4)):
        d["results"][c]["intensity_lag_clip_s"].update(mean=mean, n=2, ci95=[mean, mean])
    text = "\n".join(_results_table(d))
    row = next(line for line in text.splitlines() if line.startswith("| intensity_lag_clip_s"))
    assert row.count("‡") == 1 and "2 [2, 2] (n=2) ‡" in row
    assert text.endswith("‡ every trial's best was found at the edge of the search (`intensity_lag_clip_s` [0, 2] "
                         "s): the value that goes with it (the correlation at that lag) was measured at the edge, and "
                         "the best may lie beyond it.")
    d["results"][conds[0]]["intensity_lag_clip_s"].update(mean=1.999, ci95=[1.99, 2.0])
    assert "‡" not in "\n".join(_results_table(d))
    # the definition is the docstring's whole first paragraph, on one line
    assert doc["metrics"]["human_sounds_starting_a_clip"]["description"].endswith("(issue 27: at most 1 in 10).")


def test_report_of_nothing_is_one_line(tmp_path):
    r = laughlab("report", tmp_path)
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no results.json" in r.stderr
    (tmp_path / "laugh.wav").write_bytes(b"x")   # a review: a file was said to hold no results.json
    r = laughlab("report", tmp_path / "laugh.wav")
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {tmp_path / 'laugh.wav'} is a file; report takes an "
                                              "experiment's run folder (its hydra.run.dir)\n")


@pytest.mark.parametrize("text, why", [
    ('{"experiment": "smoke", "results": {', "not JSON: Expecting property name enclosed in double quotes "
                                            "at line 1"),
    ("", "empty"),
    ("{}", "no experiment and results in it"),
    ("[1, 2]", "no experiment and results in it"),
    ('{"experiment": "smoke"}', "no experiment and results in it"),
])
def test_a_damaged_results_file_is_one_line_and_writes_nothing(tmp_path, text, why):
    """A review: a truncated, empty or foreign results.json gave a traceback (JSONDecodeError, KeyError)."""
    (tmp_path / "results.json").write_text(text)
    r = laughlab("report", tmp_path)
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0
    assert f"results.json is not a laughlab results file ({why}); run the experiment again" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
    assert r.stderr.endswith("; run the experiment again (its command with overwrite=true)\n")   # (a review: the
    # same command alone is refused, the run being finished)
    sweep = tmp_path / "sweep"   # a sweep's job with a damaged one: the same line
    (sweep / "0").mkdir(parents=True)
    (sweep / "0" / "results.json").write_text(text)
    r = laughlab("report", sweep)
    assert r.returncode == 2 and "is not a laughlab results file" in r.stderr and not (sweep / "report").exists()


def test_a_folder_of_separate_runs_is_not_reported_as_a_sweep(small_run, tmp_path):
    """A review: two runs copied into one folder gave a "sweep" report (exit 0) of duplicated, unnamed rows."""
    both = tmp_path / "my runs"
    for name in ("a", "b"):
        shutil.copytree(small_run, both / name)
    r = laughlab("report", both)
    assert r.returncode == 2 and r.stderr == (
        f"laughlab: error: {both} is not a sweep (no multirun.yaml) and two of its runs have the same settings (a, b); "
        f"report each run on its own: python -m laughlab report '{both / 'a'}'\n")
    assert sorted(p.name for p in both.iterdir()) == ["a", "b"]


def test_sweep_through_hydra_multirun_and_its_report(tmp_path):
    sweep = tmp_path / "sweep"
    r = laughlab("-m", "experiment=energy_ablation", "extractor.rise_per_s=24", "scheduler.min_inactive_s=2",
                 "scheduler.overrule_c=1.5,3", "scheduler.decrease_per_s=6,20", "harness.corpus.seeds=1",
                 "harness.corpus.profiles=[intense]", "harness.corpus.duration_s=5", f"hydra.sweep.dir={sweep}")
    assert r.returncode == 0, r.stderr
    docs = sorted(sweep.glob("*/results.json"))
    assert len(docs) == 4
    c = {json.loads(d.read_text())["config"]["scheduler"]["overrule_c"] for d in docs}
    assert c == {1.5, 3.0}                       # each point's trials used its own parameters
    fall = {json.loads(d.read_text())["config"]["extractor"]["fall_per_s"] for d in docs}
    assert fall == {12.0}                        # fall tied to rise / 2
    readme = write_report(sweep, tmp_path / "rep", "cmd")
    # every trial a row with its point and swept settings (a data user's review: the records did not say their point)
    trials = pd.read_csv(tmp_path / "rep" / "trials.csv")
    assert list(trials.columns[:3]) == ["point", "scheduler.decrease_per_s", "scheduler.overrule_c"]
    assert len(trials) == 4 and sorted(set(zip(trials["scheduler.decrease_per_s"], trials["scheduler.overrule_c"]))) \
        == [(6, 1.5), (6, 3.0), (20, 1.5), (20, 3.0)]
    import yaml

    for _, row in trials.iterrows():   # each row its own point's: its settings, its trial, its metric
        point = sweep / str(row["point"])
        given = dict(o.split("=", 1) for o in yaml.safe_load((point / ".hydra" / "overrides.yaml").read_text()))
        assert float(given["scheduler.decrease_per_s"]) == row["scheduler.decrease_per_s"]
        assert float(given["scheduler.overrule_c"]) == row["scheduler.overrule_c"]
        (record,) = [json.loads(line) for line in (point / "metrics.jsonl").read_text().splitlines()]
        assert record["trial_hash"] == row["trial_hash"]
        assert row["clip_entropy"] == pytest.approx(record["metrics"]["clip_entropy"])
    text = readme.read_text()
    assert "swept: scheduler.decrease_per_s, scheduler.overrule_c" in text
    assert len(list((tmp_path / "rep" / "figures").glob("heatmap_*.png"))) == 1
    # what a reader needs to run it again (a review: only the swept keys were named; the fixed ones, the seeds and
    # the command were only in multirun.yaml)
    assert ("- the sweep: `python -m laughlab -m experiment=energy_ablation extractor.rise_per_s=24 "
            "scheduler.min_inactive_s=2 scheduler.overrule_c=1.5,3 scheduler.decrease_per_s=6,20 "
            "harness.corpus.seeds=1 'harness.corpus.profiles=[intense]' harness.corpus.duration_s=5 "
            f"hydra.sweep.dir={tmp_path / 'sweep'}`\n") in text   # the folder the report was made from
    assert "swept by the experiment's" not in text          # every swept key was given on the command line
    assert ("- fixed at every point: extractor.rise_per_s=24, harness.corpus.duration_s=5, harness.corpus.profiles="
            "[intense], harness.corpus.seeds=1, scheduler.min_inactive_s=2\n") in text
    assert "- each point: 1 trial of condition **energy** (profiles intense; seeds 0)\n" in text
    # a best lag at the end of its [0, 2] s search in every trial is said (a review)
    assert "- ‡ `intensity_lag_kinetic_s` sat at the edge of its search, [0, 2] s, in every trial of " in text
    n = len(json.loads(docs[0].read_text())["metrics"])
    assert f"Each cell is the mean of a point's 1 trial of that condition; the table shows 9 key metrics of the {n} each" in text
    # a half-finished sweep (a review): the points without results.json are named in the report and on stderr, and a
    # swept parameter of which only one value finished is still swept, not "fixed at every point"
    half = tmp_path / "half"
    shutil.copytree(sweep, half, ignore=shutil.ignore_patterns("report"))
    gone = sorted(p.parent.name for p in half.glob("*/results.json")
                  if "scheduler.overrule_c=3" in (p.parent / ".hydra" / "overrides.yaml").read_text())
    for name in gone:
        unfinish(half / name)
    r = laughlab("report", half)
    assert r.returncode == 0 and r.stderr.count("\n") == 1, r.stderr
    # each named by its folder and its values (a sweep researcher's review: '2' alone beside the others' values)
    named = [f"{g} (scheduler.overrule_c=3 scheduler.decrease_per_s={d})" for g, d in zip(gone, ("6", "20"))]
    assert r.stderr.startswith(f"laughlab: warning: {half}: 2 of 4 sweep points unfinished ({', '.join(named)}): run "
                               "the sweep's command again to finish it: python -m laughlab -m experiment=energy_ablation ")
    text = (half / "report" / "README.md").read_text()
    assert (f"**PARTIAL: 2 of the sweep's 4 points have no results** (unfinished: "
            f"{', '.join(f'`{g}`' for g in named)})") in text.splitlines()[4]
    assert "- sweep points: 2 of 4 planned; swept: scheduler.decrease_per_s, scheduler.overrule_c\n" in text
    assert "scheduler.overrule_c=1.5" not in text.split("fixed at every point")[1].splitlines()[0]
    # no point finished (a review: "run an experiment first" for a started sweep)
    for p in half.glob("*/results.json"):
        unfinish(p.parent)
    shutil.rmtree(half / "report")
    r = laughlab("report", half)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {half}: a sweep with no finished point (0 of 4): run the "
                                              "sweep's command again to finish it: python -m laughlab -m "
                                              + text.split("python -m laughlab -m ")[1].split("`")[0]
                                              .replace(f"hydra.sweep.dir={sweep}", f"hydra.sweep.dir={half}") + "\n")


def unfinish(job):
    """A sweep point as a stopped experiment leaves it: no results.json, its run marker not complete."""
    (job / "results.json").unlink()
    marker = json.loads((job / ".laughlab-run.json").read_text())
    (job / ".laughlab-run.json").write_text(json.dumps({**marker, "complete": False}))


def test_a_sweeps_command_names_its_launcher(tmp_path):
    """A sweep's report and its 'run the sweep's command again' line gave only the task's overrides: a Slurm sweep
    (hydra/launcher=submitit_slurm and its partition) read as one to run in a single process. Hydra's own overrides
    come after the task's, but for its mode, and the folder is the one the sweep is in."""
    import yaml

    from laughlab.harness.sweep_plan import sweep_command

    (tmp_path / "multirun.yaml").write_text(yaml.safe_dump({"hydra": {"overrides": {
        "hydra": ["hydra/launcher=submitit_slurm", "hydra.launcher.partition=gpu", "hydra.sweep.dir=elsewhere",
                  "hydra.mode=MULTIRUN"],
        "task": ["experiment=energy_ablation", "scheduler.overrule_c=1.5,3", "harness.corpus.profiles=[intense]"]}}}))
    assert sweep_command(tmp_path) == (
        "python -m laughlab -m experiment=energy_ablation scheduler.overrule_c=1.5,3 'harness.corpus.profiles=[intense]' "
        f"hydra/launcher=submitit_slurm hydra.launcher.partition=gpu hydra.sweep.dir={tmp_path}")


def test_a_finished_sweep_of_runs_counts_as_finished(tmp_path):
    """A diff review: a point counted as finished only with results.json, which a plain run never writes, so a
    finished sweep of runs was "a sweep with no finished point (0 of 2): run the sweep's command again", and a
    Ctrl-C line said 0 of N.  Points count by their run marker."""
    from laughlab.harness.sweep_plan import interrupted_line, unfinished

    sweep = tmp_path / "runs"
    r = laughlab("-m", "input.duration_s=1", "seed=1,2", "detector=none", "output=[files]", "~output.plots",
                 f"hydra.sweep.dir={sweep}")
    assert r.returncode == 0, r.stderr
    assert unfinished(sweep) == (2, [])
    assert interrupted_line([f"hydra.sweep.dir={sweep}"]).startswith("interrupted: 2 of 2 points finished")
    r = laughlab("report", sweep)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {sweep} holds no results.json (run an experiment "
                                              f"first); report is for experiments: to watch a run, python -m laughlab "
                                              f"view {sweep / '0'}\n"), r.stderr
    marker = json.loads((sweep / "1" / ".laughlab-run.json").read_text())
    (sweep / "1" / ".laughlab-run.json").write_text(json.dumps({**marker, "complete": False}))
    assert unfinished(sweep) == (2, ["1 (seed=2)"])   # its folder and its values


def _bad_corpus(folder):
    """Two good laughs, a truncated OGG, a text file named .wav, and an annotation with overlapping calls."""
    import soundfile as sf

    from laughlab.synth.laughter import SyntheticLaughter

    folder.mkdir()
    x = SyntheticLaughter(seed=1, duration_s=3.0).render(0, 48000)
    for name in ("good1", "good2", "overlap"):
        sf.write(str(folder / f"{name}.wav"), x, 16000)
    sf.write(str(folder / "cut.ogg"), x, 16000)
    data = (folder / "cut.ogg").read_bytes()
    (folder / "cut.ogg").write_bytes(data[: len(data) // 3])
    (folder / "notes.wav").write_text("not audio at all\n")
    (folder / "overlap.txt").write_text("0.1\t0.9\tlaugh\n0.5\t1.2\tlaugh\n")


def test_a_bad_corpus_is_reported_in_one_message_before_any_trial(tmp_path):
    corpus = tmp_path / "corpus"
    _bad_corpus(corpus)
    out = tmp_path / "run"
    r = laughlab("experiment=smoke", f"hydra.run.dir={out}", f"harness.corpus.folder={corpus}",
                 "harness.corpus.profiles=[]")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    for name in ("cut.ogg", "notes.wav", "overlap.wav"):
        assert name in r.stderr
    assert "good1" not in r.stderr and "3 of 5 files are bad" in r.stderr
    assert not out.exists()  # nothing ran, nothing was written


@pytest.mark.parametrize("setting, message", [
    ("harness.corpus.folder={file}", "harness.corpus.folder {file} is a file, not a folder of recordings"),
    ("harness.corpus.seeds=0", "the corpus is empty: harness.corpus.seeds gives no seed for its profiles"),
])
def test_a_corpus_error_names_its_cause(tmp_path, setting, message):
    """A review: a file given as the folder was "not found", and seeds=0 asked for the profiles that were given."""
    f = tmp_path / "laugh.wav"
    f.write_bytes(b"RIFF")
    out = tmp_path / "run"
    r = laughlab("experiment=smoke", f"hydra.run.dir={out}", setting.format(file=f))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and message.format(file=f) in r.stderr
    assert not out.exists()


def test_report_of_a_single_run_says_what_to_do_with_it(tmp_path):
    run = tmp_path / "laugh"
    assert laughlab("input.duration_s=1", f"hydra.run.dir={run}", "~output.plots").returncode == 0
    r = laughlab("report", run)
    assert r.returncode == 2 and r.stderr.strip().endswith(
        f"holds no results.json (run an experiment first); report is for experiments: to watch this run, "
        f"python -m laughlab view {run}")


def test_on_bad_skip_runs_the_rest_and_records_what_it_skipped(tmp_path):
    corpus = tmp_path / "corpus"
    _bad_corpus(corpus)
    out = tmp_path / "run"
    r = laughlab("experiment=smoke", f"hydra.run.dir={out}", f"harness.corpus.folder={corpus}",
                 "harness.corpus.profiles=[]", "harness.corpus.on_bad=skip", "harness.showcase=null",
                 "harness.plots=false", "progress=off")
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "results.json").read_text())
    assert doc["corpus"]["inputs"] == ["rec-good1", "rec-good2"]
    assert sorted(s["file"] for s in doc["corpus"]["skipped"]) == ["cut.ogg", "notes.wav", "overlap.wav"]
    assert all(s["reason"] for s in doc["corpus"]["skipped"])
    # and on screen as it starts (only results.json had them, a new-user review)
    said = [ln for ln in r.stderr.splitlines() if "left out" in ln]
    assert len(said) == 1 and said[0].startswith("smoke: left out 3 bad corpus files (harness.corpus.on_bad=skip): "
                                                 "cut.ogg: "), r.stderr
    assert all(f in said[0] for f in ("notes.wav: ", "overlap.wav: ")) and said[0].endswith("(all of them in results.json)")


def test_an_inputs_hash_is_of_its_overrides_or_its_bytes_not_of_its_id(tmp_path):
    """A sweep runs its experiments in one process, where one id can name two inputs (the hash was cached by id:
    the second experiment journaled the first one's hash, and an interrupted one resumed fewer trials)."""
    import hashlib
    import os

    from laughlab.harness.corpus import Item
    from laughlab.harness.runner import input_hash

    short = Item("mild-s00", ("input.profile=mild", "input.seed=0", "input.duration_s=4"), "mild", 0, None)
    long = Item("mild-s00", ("input.profile=mild", "input.seed=0", "input.duration_s=7"), "mild", 0, None)
    assert input_hash(short) == hashlib.sha256(json.dumps(list(short.overrides)).encode()).hexdigest()
    assert input_hash(long) != input_hash(short)
    wav = tmp_path / "a.wav"
    wav.write_bytes(b"first")
    rec = Item("rec-a", ("input=file", f"input.path={wav}"), "recording", None, None)
    assert input_hash(rec) == hashlib.sha256(b"first").hexdigest()
    wav.write_bytes(b"second, longer")                       # the same file name, other bytes
    os.utime(wav, ns=(1, 1))
    assert input_hash(rec) == hashlib.sha256(b"second, longer").hexdigest()


def test_an_experiment_says_what_it_does_after_its_trials(tmp_path):
    """The summary after the last trial (intervals, extras, metrics.png) took ~30 s in silence on 2 cores."""
    r = laughlab("experiment=smoke", f"hydra.run.dir={tmp_path / 'run'}", "harness.corpus.seeds=1",
                 "harness.corpus.profiles=[intense]", "harness.corpus.duration_s=3", "harness.showcase=null",
                 "harness.plots=false")
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stderr.splitlines() if "summarising" in ln)
    assert line.startswith("smoke: summarising ") and "means and bootstrap intervals" in line
    assert "metrics.png" not in line                                      # harness.plots=false: none drawn
    r = laughlab("experiment=smoke", f"hydra.run.dir={tmp_path / 'quiet'}", "harness.corpus.seeds=1",
                 "harness.corpus.profiles=[intense]", "harness.corpus.duration_s=3", "harness.showcase=null",
                 "harness.plots=false", "progress=off")
    assert r.returncode == 0 and "summarising" not in r.stderr


def test_a_folder_of_two_experiments_sweeps_is_one_line_not_a_traceback(tmp_path):
    """Found by a new-user review: energy_ablation and concat_ablation sweeps in one folder ended in
    "TypeError: '<' not supported between instances of 'float' and 'str'"."""
    from laughlab.harness.sweep_report import _order, sweep_report

    for name, job in (("energy_ablation", "a/0"), ("concat_ablation", "b/0")):
        (tmp_path / job).mkdir(parents=True)
        (tmp_path / job / "results.json").write_text(json.dumps({"experiment": name, "results": {}}))
    with pytest.raises(LaughlabError, match=r"holds the results of 2 experiments \(concat_ablation, "
                                            r"energy_ablation\); report each point's folder on its own"):
        sweep_report(tmp_path, tmp_path / "rep", "cmd")
    assert sorted(["12", "", "3", "fast"], key=_order) == ["3", "12", "", "fast"]   # numbers, then words


def test_the_commit_stamp_is_dirty_only_when_code_differs(tmp_path):
    """A review: regenerating the committed reports one after another stamped every report but the first
    '+dirty' (the reports written before it were changes); reports, docs and Markdown do not change a run."""
    import subprocess

    from laughlab.harness.results import git_diff_sha256, git_hash

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    for f in ("reports/x/README.md", "docs/a.md", "README.md", "laughlab/m.py"):
        (tmp_path / f).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / f).write_text("1\n")
    git("add", ".")
    git("-c", "user.email=a@b", "-c", "user.name=a", "commit", "-qm", "x")
    clean = git_hash(tmp_path)
    assert clean and not clean.endswith("+dirty")
    for f in ("reports/x/README.md", "docs/a.md", "README.md"):
        (tmp_path / f).write_text("2\n")
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "new.txt").write_text("untracked\n")
    assert git_hash(tmp_path) == clean
    assert git_diff_sha256(tmp_path) is None
    (tmp_path / "laughlab" / "m.py").write_text("2\n")
    assert git_hash(tmp_path) == clean + "+dirty"
    # a reproducibility review: two edits of one commit said the same; the diff's digest tells them apart
    first = git_diff_sha256(tmp_path)
    (tmp_path / "laughlab" / "m.py").write_text("3\n")
    assert git_hash(tmp_path) == clean + "+dirty" and first and git_diff_sha256(tmp_path) not in (None, first)
    (tmp_path / "laughlab" / "m.py").write_text("2\n")
    assert git_diff_sha256(tmp_path) == first


def test_the_commit_stamp_is_not_the_commit_of_a_repository_laughlab_is_installed_inside(tmp_path):
    """laughlab installed from PyPI into a project's own .venv: its folder is inside the project's repository, and
    git_hash stamped the project's commit as laughlab's in metrics.json,
    results.json and every report (repro review).  Only a checkout of laughlab itself is stamped."""
    import subprocess

    from laughlab.harness.results import git_hash

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "analysis.py").write_text("1\n")
    site = tmp_path / ".venv" / "lib" / "python3.11" / "site-packages"
    site.mkdir(parents=True)
    git("add", "analysis.py")
    git("-c", "user.email=a@b", "-c", "user.name=a", "commit", "-qm", "x")
    assert git_hash(tmp_path) and git_hash(site) is None


@pytest.mark.parametrize("text, message", [
    ("garbage\n", "tank.truth.csv: no column kind, onset_s, offset_s"),
    ("kind,bout,onset_s,offset_s,intensity\nbout,0,0.5,99,1\n", "tank.truth.csv, line 2: offset_s 99 is past the "
                                                                 "recording's end (3.000 s)"),
    ("kind,bout,onset_s,offset_s,intensity\nbout,0,0.5,2,1\nbout,1,1.5,2.5,1\n",
     "tank.truth.csv, line 3: the bout at 1.5-2.5 s overlaps the one at 0.5-2 s"),
    ("kind,bout,onset_s,offset_s,intensity\ncall,0,1,0.5,1\n", "tank.truth.csv, line 2: need 0 <= onset_s < offset_s"),
    ("kind,bout,onset_s,offset_s,intensity\ncall,0,x,0.5,1\n", "tank.truth.csv, line 2: onset_s and offset_s must be"),
    ("kind,bout,onset_s,offset_s\nbout,0,0.5,2\n", "tank.truth.csv: no column intensity (0..1) for its bouts"),
])
def test_a_corpus_folders_truth_csv_is_checked_before_any_trial(tmp_path, text, message):
    """A review: a malformed NAME.truth.csv failed in the trial workers after the trials had run; one whose bout
    ended past the recording or overlapped another was taken silently. Checked now as the annotations are."""
    import soundfile as sf

    from laughlab.harness.corpus import folder_items

    sf.write(tmp_path / "tank.wav", np.zeros(48000), 16000)
    (tmp_path / "tank.truth.csv").write_text(text)
    with pytest.raises(LaughlabError, match="^corpus folder .*1 of 1 file is bad") as err:
        folder_items(tmp_path)
    assert message in str(err.value)
    (tmp_path / "tank.truth.csv").write_text("kind,bout,onset_s,offset_s,intensity\nbout,0,0.5,2,1\ncall,0,0.5,0.7,1\n"
                                             "bout,1,2,3.0005,0.5\n")   # touching bouts, an end within rounding
    assert folder_items(tmp_path)[0].truth == str(tmp_path / "tank.truth.csv")


def test_report_extras_compute_rows_and_the_shared_plugins():
    """A figure review: a mapping of mappings (detector_eval's PR scores) was printed as a Python dict with 17
    digits; the compute rows were bolded though a rerun reversed them; the plugins every condition shares (set by
    the experiment's defaults, as energy_vs_concat's extractor=phoneme) were said nowhere."""
    from laughlab.harness.report import _base_line, _clear_best, _extra_lines

    lines = _extra_lines("scores", {"n": 2, "pr": {"head": {"ap": 0.32200027, "at": {"threshold": 0.5}},
                                                    "mlp": {"ap": 0.3130371, "at": {"threshold": 0.7}}}})
    assert lines == ["### scores", "", "- n: 2", "", "pr:", "", "|  | ap | at.threshold |", "|---|---|---|",
                     "| head | 0.322 | 0.5 |", "| mlp | 0.313 | 0.7 |", ""]
    r = lambda m: {"n": 20, "mean": m, "ci95": [m - 0.01, m + 0.01]}   # noqa: E731 - apart intervals
    doc = {"metrics": {"frame_ms_p99": {"higher_is_better": False}, "miss_rate": {"higher_is_better": False}},
           "results": {"a": {"frame_ms_p99": r(0.2), "miss_rate": r(0.1)},
                       "b": {"frame_ms_p99": r(1.4), "miss_rate": r(0.5)}}}
    assert _clear_best(doc, "miss_rate", ["a", "b"]) == "a" and _clear_best(doc, "frame_ms_p99", ["a", "b"]) is None
    assert _base_line({"config": {"extractor": {"name": "phoneme"}, "face": {"name": "smile", "x": 1}}}) == [
        "- every condition starts from `extractor=phoneme face=smile` (its overrides replace these)"]
    from laughlab.harness.report import _trials_line

    # 1 synthetic input and 3 recordings run with seeds 0 and 1: 7 runs a condition (a review: "4 inputs x 2")
    two = {"n_trials": 14, "conditions": {"a": [], "b": []}, "config": {"harness": {"run_seeds": [0, 1]}},
           "corpus": {"inputs": ["mild-s00", "rec-a", "rec-b", "rec-c"], "profiles": ["mild", "recording"],
                      "seeds": [0, 1]}}
    assert _trials_line(two) == ("- trials: 14 (7 runs of 4 inputs, the recordings once per run seed (0, 1) x 2 "
                                 "conditions; profiles mild, recording; seeds 0..1)")
    one = {**two, "n_trials": 8, "corpus": {**two["corpus"], "seeds": [0]}}
    assert _trials_line(one) == "- trials: 8 (4 inputs x 2 conditions; profiles mild, recording; seed 0)"
    single = {**one, "n_trials": 1, "conditions": {"a": []}, "corpus": {**one["corpus"], "inputs": ["mild-s00"]}}
    assert _trials_line(single) == "- trials: 1 (1 input x 1 condition; profiles mild, recording; seed 0)"  # "1 inputs"


def test_a_sweep_of_a_two_condition_experiment_reports_both(tmp_path):
    """A review: a sweep's report showed only the first condition (smoke's energy; none was dropped without a word)
    and gave the first point's whole trial count as every point's."""
    from laughlab.harness.report import write_report

    sweep = tmp_path / "sweep"
    r = laughlab("-m", "experiment=smoke", "harness.corpus.seeds=1,2", "harness.corpus.duration_s=2",
                 "harness.corpus.profiles=[mild]", "harness.showcase=null", "harness.plots=false",
                 f"hydra.sweep.dir={sweep}")
    assert r.returncode == 0, r.stderr
    text = write_report(sweep, tmp_path / "rep", "cmd").read_text()
    assert "- sweep points: 2 x 2 conditions; swept: condition, harness.corpus.seeds\n" in text
    assert "- each point: 1-2 trials of each condition (**energy**, **none**; profiles mild; seeds 0 at the first " \
           "point)\n" in text
    rows = [ln for ln in text.splitlines() if ln.startswith(("| energy |", "| none |"))]
    assert [ln.split(" | ")[:2] for ln in rows] == [["| energy", "1"], ["| energy", "2"], ["| none", "1"], ["| none", "2"]]
    assert "| none | 1 | n/a |" in text                      # none plays no clip: its clip metrics do not apply


def test_trial_processes_ignore_ctrl_c(monkeypatch):
    """The terminal's Ctrl-C reaches every process of the command: a trial process' own KeyboardInterrupt printed its
    traceback after the one line (a sweeps review); the parent alone stops them."""
    import signal

    from laughlab.harness import runner

    monkeypatch.setattr(runner, "run_trial", lambda t: {"condition": t.condition, "input": t.item.id, "seed": t.seed,
                                                        "ignored": signal.getsignal(signal.SIGINT) == signal.SIG_IGN})
    items = build_corpus({"profiles": ["mild"], "seeds": 2, "duration_s": 3})
    trials = runner.make_trials(items, {"a": []}, lambda item: [0], [], Path("/nonexistent"))
    records = runner.run_trials(trials, jobs=2, progress=False)
    assert len(records) == 2 and all(r["ignored"] for r in records)


def test_the_clean_up_after_ctrl_c_is_not_cut_by_another(tmp_path):
    """After the first stop signal the command ignores more of it, and so do the processes its clean-up starts
    (loky's pgrep, run to end the trial processes, died of the terminal's second SIGINT with tracebacks: a review)."""
    import signal
    import subprocess

    from laughlab.core import interrupts

    old = signal.signal(signal.SIGINT, interrupts._handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            interrupts._handler(signal.SIGINT, None)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
        child = subprocess.run(["sh", "-c", "kill -INT $$; echo alive"], capture_output=True, text=True)
        assert child.returncode == 0 and child.stdout == "alive\n"
        interrupts.reset()
        assert signal.getsignal(signal.SIGINT) is interrupts._handler   # the next command handles it again
    finally:
        interrupts.received = None
        signal.signal(signal.SIGINT, old)


def test_a_showcase_figure_the_same_under_every_condition_is_shown_once(tmp_path):
    """A plugin author's review: a face comparison's report showed the same Fig. 4.2 under each face's name."""
    from laughlab.harness.report import SAME_FIGURE, _one_figure

    for name, data in (("a_fig4_2_energy.png", b"png"), ("b_fig4_2_energy.png", b"png"), ("c_fig4_2_energy.png",
                                                                                           b"other")):
        (tmp_path / name).write_bytes(data)
    assert _one_figure(tmp_path, ["a_fig4_2_energy.png", "b_fig4_2_energy.png"])
    assert not _one_figure(tmp_path, ["a_fig4_2_energy.png", "b_fig4_2_energy.png", "c_fig4_2_energy.png"])
    assert not _one_figure(tmp_path, ["a_fig4_2_energy.png"])   # one condition: nothing to compare
    assert SAME_FIGURE.startswith("**Every condition**: this figure is byte for byte the same under each")



def test_the_showcase_figures_follow_the_experiments_order_of_conditions(tiny_run, tmp_path):
    """A plugin author's review: the tables went in the experiment's order of conditions, the figures by name."""
    out = tmp_path / "exp"
    shutil.copytree(tiny_run[0], out)
    doc = json.loads((out / "results.json").read_text())
    doc["conditions"] = dict(reversed(list(doc["conditions"].items())))   # none first, then energy
    (out / "results.json").write_text(json.dumps(doc))
    text = write_report(out, tmp_path / "rep", "cmd").read_text()
    assert text.index("| none mean") < text.index("| energy mean")
    links = [text.index(f"[{c}_filmstrip.png]") for c in ("none", "energy")]
    assert links[0] < links[1]
    assert text.index("(figures/none_fig3_2_mcs.png)") < text.index("(figures/energy_fig3_2_mcs.png)")


def test_an_empty_annotation_or_one_without_calls_is_warned_once(tmp_path, capsys):
    """A new-user review: an empty Audacity export and an ELAN file of bouts alone were taken without a word (the
    report's intensity n one short, the empty one counted as a recording without laughter)."""
    from laughlab.harness import corpus

    for name in ("empty", "bouts", "full"):
        sf.write(tmp_path / f"{name}.wav", np.zeros(16000 * 3), 16000)
    (tmp_path / "empty.txt").write_text("")
    (tmp_path / "bouts.txt").write_text("0.5\t1.5\tlaugh\n")
    (tmp_path / "full.txt").write_text("0.5\t1.5\tlaugh\n0.6\t0.8\tcall\n")
    monkey = corpus._WARNED.copy()
    try:
        items = folder_items(tmp_path)
        folder_items(tmp_path)                                   # read again (the showcase's check): said once
    finally:
        corpus._WARNED.clear()
        corpus._WARNED.update(monkey)
    assert [i.id for i in items] == ["rec-bouts", "rec-empty", "rec-full"]
    err = capsys.readouterr().err.splitlines()
    assert err == [f"laughlab: warning: {tmp_path / 'bouts.txt'} marks bouts but no calls: rec-bouts's metrics of "
                   "laughter intensity (intensity_r_*, intensity_rho_*, jaw_call_r) are left blank "
                   "(docs/experiments.md: annotate the calls)",
                   f"laughlab: warning: {tmp_path / 'empty.txt'} holds no laughter bout: rec-empty counts as a "
                   "recording without laughter (its false starts count, its detector scores are blank)"]


def test_each_of_your_recordings_gets_a_row_under_each_condition(tmp_path):
    """A new-user review: the report pooled four recordings of one's own, hiding that one condition missed both
    bouts of one of them. A row per folder recording and condition, the mean over run seeds; corpus sets and
    synthetic inputs stay pooled."""
    from laughlab.harness.report_recordings import recordings_table

    def rec(inp, cond, seed, **m):
        return json.dumps({"input": inp, "condition": cond, "seed": seed, "metrics": m})

    (tmp_path / "metrics.jsonl").write_text("\n".join([
        rec("rec-a", "x", 0, bouts_answered=1.0, detector_f1=0.5), rec("rec-a", "x", 1, bouts_answered=0.0,
                                                                        detector_f1=None),
        rec("rec-a", "y", 0, bouts_answered=0.5, detector_f1=0.25), rec("rec-b", "y", 0, bouts_answered=None),
        rec("intense-s00", "x", 0, bouts_answered=0.0, detector_f1=0.9), rec("real-z", "x", 0, bouts_answered=0.0)]))
    doc = {"conditions": {"x": [], "y": []},
           "metrics": {"bouts_answered": {"higher_is_better": True}, "detector_f1": {"higher_is_better": True},
                       "miss_rate": {"higher_is_better": False}}}
    lines = recordings_table(tmp_path, doc)
    assert lines[1] == "## Each of your recordings"
    assert lines[-5:] == ["| recording | condition | bouts_answered ↑ | detector_f1 ↑ |", "|---|---|---|---|",
                          "| a | x | 0.5 | 0.5 |", "| a | y | 0.5 | 0.25 |", "| b | y | n/a | n/a |"]
    (tmp_path / "metrics.jsonl").write_text(rec("intense-s00", "x", 0, bouts_answered=1.0))
    assert recordings_table(tmp_path, doc) == []               # no folder recording: no section


def test_a_sweep_run_over_with_overwrite_reports_its_own_points_and_a_parent_folder_is_refused(tmp_path):
    """A sweep researcher's review: a sweep of 4 points, then one of 2 other points into the same folder with
    overwrite=true; the report took the old points 2 and 3 in beside the new ones, drew heatmaps over
    'overwrite', and its 'run the sweep's command again' carried overwrite=true (which redoes, not resumes). And
    `report` on the folder above two sweeps said to report each point's folder, not each sweep's."""
    common = ["-m", "experiment=energy_ablation", "extractor.rise_per_s=24", "scheduler.min_inactive_s=2",
              "harness.corpus.seeds=1", "harness.corpus.profiles=[intense]", "harness.corpus.duration_s=3"]
    sweep = tmp_path / "sweeps" / "s"
    r = laughlab(*common, "scheduler.overrule_c=1.5,3", "scheduler.decrease_per_s=6,20", f"hydra.sweep.dir={sweep}")
    assert r.returncode == 0, r.stderr
    r = laughlab(*common, "scheduler.overrule_c=2", "scheduler.decrease_per_s=6,30", f"hydra.sweep.dir={sweep}",
                 "overwrite=true")
    assert r.returncode == 0, r.stderr
    assert sorted(p.parent.name for p in sweep.glob("*/results.json")) == ["0", "1", "2", "3"]   # 2, 3: the old
    r = laughlab("report", sweep, "--out", tmp_path / "rep")
    assert r.returncode == 0 and r.stderr == (f"laughlab: warning: {sweep}: 2 folders with results here (2, 3) are no "
                                              "point of this sweep (an earlier sweep's, run over with overwrite=true): "
                                              "left out of the report\n"), r.stderr
    text = (tmp_path / "rep" / "README.md").read_text()
    assert "- sweep points: 2; swept: scheduler.decrease_per_s\n" in text and "overwrite" not in text.split(
        "- the sweep:")[1].split("\n")[0]
    rows = [ln for ln in text.splitlines() if ln.startswith(("| 6 |", "| 30 |", "| 20 |"))]
    assert [ln.split(" | ")[0] for ln in rows] == ["| 6", "| 30"]
    assert "- fixed at every point: " in text and "scheduler.overrule_c=2" in text.split("- fixed at every point:")[1]
    assert not list((tmp_path / "rep" / "figures").glob("heatmap_*"))   # one swept key: a line plot, no heatmap
    # the folder above the sweep (and another one): each sweep named, nothing written
    shutil.copytree(sweep, tmp_path / "sweeps" / "t")
    r = laughlab("report", tmp_path / "sweeps")
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {tmp_path / 'sweeps'} is no run or sweep folder; it "
                                              "holds 2 sweeps (s, t): report each on its own, python -m laughlab "
                                              f"report {sweep}\n"), r.stderr
    assert not (tmp_path / "sweeps" / "report").exists()


def test_a_report_says_the_version_where_there_was_no_checkout():
    """A packaging review: run from an installed wheel, a report said ``laughlab commit: `None```."""
    from laughlab.harness.results import made_by

    assert made_by({"git_hash": "abc123+dirty", "versions": {"laughlab": "0.2.0"}}) == "- laughlab commit: `abc123+dirty`"
    assert made_by({"git_hash": None, "versions": {"laughlab": "0.2.0"}}) == \
        "- laughlab 0.2.0: an installed package, no git checkout"
