"""Every figure laughlab draws can be read: no two texts overprint, every clip is named, every colour
bar says which way is better (issue 26, item 5), and no two named lines differ in hue alone (they would merge
in greyscale and for colour blindness).

Each figure is checked as it is saved (``Figure.savefig`` is watched), with matplotlib's own renderer
(``laughlab.render.labels``): the figures of a default run and of a concatenation run, of an
experiment report (energy against concat) and of a sweep report (2 x 2 and 2 x 1 points), and the
study report's figures.  Inputs are short (10 s runs, 4 s trials) to keep the test fast.
"""
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.core.frame import ClipEvent, clip_blocks
from laughlab.render.labels import (colorbars, colorbars_without_direction, drawn_texts, lines_told_apart_by_hue,
                                     overlapping_texts, texts_cut_off)


def cfg_for(*overrides):
    cfg = compose_config(list(overrides))
    return OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])


class Saved:
    """What one saved figure showed."""

    def __init__(self, name, fig):
        drawn = drawn_texts(fig)
        self.name = re.sub(r"^\.|\.part$", "", Path(name).name)
        self.texts = [t.get_text() for t, _ in drawn]
        self.overlaps = overlapping_texts(fig, drawn)
        self.undirected = colorbars_without_direction(fig)
        self.hue_only = lines_told_apart_by_hue(fig)
        self.cut_off = texts_cut_off(fig, drawn)
        self.n_colorbars = len(colorbars(fig))
        self.figure = fig
        # (label, colour map, values rising upwards) of each colour bar
        self.bars = [(cb.ax.get_ylabel(), cb.cmap.name, not cb.ax.yaxis_inverted()) for cb in colorbars(fig)]
        self.titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
        self.xticks = [[t.get_text() for t in ax.get_xticklabels()] for ax in fig.axes if ax.get_visible()]
        self.ylims = [ax.get_ylim() for ax in fig.axes if ax.get_visible()]
        self.xlims = [ax.get_xlim() for ax in fig.axes if ax.get_visible()]


@pytest.fixture
def saved(monkeypatch):
    """Every figure saved during the test, checked just before it is written.  A PDF written beside its PNG
    (``render.savefig.save_figure``: the same figure, saved again at once with ``format="pdf"``) is not checked a
    second time: its texts and boxes are the PNG's (each check draws the whole figure once more)."""
    seen: list[Saved] = []
    original = Figure.savefig

    def watched(self, fname, *args, **kwargs):
        if kwargs.get("format", "png") == "png":
            seen.append(Saved(fname, self))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", watched)
    return seen


def assert_readable(figures):
    assert figures
    for f in figures:
        assert not f.overlaps, f"{f.name}: overprinted texts {f.overlaps}"
        assert not f.undirected, f"{f.name}: colour bars that do not say which way is better: {f.undirected}"
        assert not f.hue_only, f"{f.name}: lines only their hue tells apart (greyscale, colour-blind): {f.hue_only}"
        assert not f.cut_off, f"{f.name}: texts the figure's edge cuts: {f.cut_off}"


def read_events(run: Path) -> list:
    ev = pd.read_csv(run / "events.csv")
    return [ClipEvent(r.time, r.event, r.clip, r.energy, r.speed) for r in ev.itertuples()]


@pytest.mark.parametrize("scheduler", ["energy", "concat"])
def test_the_figures_of_a_run(tmp_path, saved, monkeypatch, scheduler):
    from laughlab.render import plots

    strips = []
    real = plots.filmstrip
    monkeypatch.setattr(plots, "filmstrip", lambda path, sk, times, *a, **k: strips.append(np.asarray(times))
                        or real(path, sk, times, *a, **k))
    pipeline.execute(pipeline.build(cfg_for("input.duration_s=10", f"scheduler={scheduler}", "~output.bvh")),
                     tmp_path)
    names = {f.name for f in saved}
    wanted = {"fig3_1_calibration.png", "fig3_2_mcs.png", "fig4_2_energy.png", "filmstrip.png"}
    assert names == wanted | ({"fig4_1_energy.png"} if scheduler == "energy" else {"method.png"})   # concat: its cost
    assert_readable(saved)
    # the default filmstrip (8 frames) names its limbs' colours (3 frames: the filmstrip test below)
    (strip,) = [f for f in saved if f.name == "filmstrip.png"]
    assert any("Blue: the left arm and leg; red: the right" in " ".join(t.split()) for t in strip.texts)
    # every clip played is named in Figs. 4.1 and 4.2 (its block's label or the colour key)
    played = {b[0] for b in clip_blocks(read_events(tmp_path), 10.0)}
    assert played
    for f in saved:
        if f.name.startswith("fig4_"):
            for clip in played:
                assert any(t == clip or t.startswith(f"{clip}, e=") for t in f.texts), (f.name, clip)
    # the filmstrip: distinct moments (as printed, 0.1 s), spread over the run, in order
    (times,) = strips
    shown = [f"{t:.1f}" for t in times]
    assert len(set(shown)) == len(shown) == 8
    assert np.all(np.diff(times) > 0) and times[-1] - times[0] > 5.0


def test_fig4_2_of_a_run_without_energy_says_so(tmp_path, saved):
    """A review: with scheduler=none the lower panel was empty, its legend naming a line one could not see."""
    from laughlab.render import plots

    t = np.arange(120) / 60
    plots.figure_4_2(tmp_path / "a.png", t, np.abs(np.sin(t * 9)), np.zeros_like(t), [])
    plots.figure_4_2(tmp_path / "b.png", t, np.abs(np.sin(t * 9)), t * 10, [])      # energy: no such line
    (empty, full) = saved
    assert "no laughing energy and no clip in this run" in empty.texts
    assert "no laughing energy and no clip in this run" not in full.texts
    assert "laughing energy L" not in empty.texts and "laughing energy L" in full.texts   # a line not there: no key
    assert_readable(saved)


def test_figs_4_1_and_4_2_say_when_the_detector_kept_every_clip_back(tmp_path, saved):
    """A researcher's review: over a laugh between speech L rose to 19 with no clip block and no word why (the
    detector's clip gate stayed 0).  Said in the panel when the gate never opened; not when it did, nor without
    a detector's gate (detector=none), nor when a clip played."""
    from laughlab.core.frame import ClipEvent
    from laughlab.render import plots

    t = np.arange(240) / 60
    mcs, energy = np.abs(np.sin(t * 9)), 10 * np.abs(np.sin(t))
    shut, opened = np.zeros_like(t), (t > 2).astype(float)
    clip = [ClipEvent(1.0, "start", "giggle", 10.0, blend_s=0.2), ClipEvent(3.0, "stop", "giggle", 10.0)]
    for k, (gate, events) in enumerate([(shut, []), (opened, []), (None, []), (shut, clip)]):
        plots.figure_4_2(tmp_path / f"b{k}.png", t, mcs, energy, events, gate=gate)
        plots.figure_4_1(tmp_path / f"a{k}.png", t, mcs, energy, events, 60.0, gate=gate)
    said = ["no clip: the laughter detector's clip gate stayed closed" in f.texts for f in saved]
    assert said == [True, True, False, False, False, False, False, False]
    assert_readable(saved)


def test_truth_past_the_plotted_stretch_does_not_widen_the_figures(tmp_path, saved):
    """A recording's truth reaches past the first output.plots.max_seconds the figures draw: Fig. 3.1 spread its
    60 s of data over the 90 s of the truth's last bout (seen in reports/detector_eval)."""
    from laughlab.render import plots
    from laughlab.signals.mcs import RmsParams

    t = np.arange(600) / 60                                          # 10 s drawn
    amp = -30 + 10 * np.abs(np.sin(t * 3))
    bouts = [(1.0, 2.0), (30.0, 31.0)]                               # the second one past the stretch
    plots.figure_3_1(tmp_path / "a.png", t, amp, RmsParams(), 60.0, bouts=bouts)
    plots.figure_4_2(tmp_path / "b.png", t, np.abs(np.sin(t)), t, [], bouts)
    for f in saved:
        assert all(hi <= t[-1] + 1e-9 for _, hi in f.xlims), (f.name, f.xlims)


def _tiny_experiment(out: Path, name: str, overrides: list[str], conditions: dict, showcase=None) -> dict:
    from laughlab.harness.experiment import run_experiment

    cfg = compose_config([f"experiment={name}", *overrides])
    h = OmegaConf.to_container(cfg.harness)
    h.update(conditions=conditions, jobs=1, showcase=showcase, plots=False,  # the report draws metrics.png
             corpus={**h["corpus"], "profiles": ["intense"], "seeds": 1, "duration_s": 4.0})
    h["corpus"].pop("real", None)
    if "gap_inputs" in h:
        h["gap_inputs"] = 1
    cfg.harness = OmegaConf.create(h)
    return run_experiment(cfg, out, base_overrides=overrides, progress=False)


def test_the_figures_of_an_experiment_report(tmp_path, saved):
    from laughlab.harness.report import same_everywhere, write_report

    run = tmp_path / "exp"
    doc = _tiny_experiment(run, "smoke", [], {"energy": ["scheduler=energy"], "concat": ["scheduler=concat"]})
    readme = write_report(run, tmp_path / "rep", "cmd").read_text()
    assert_readable(saved)
    same = [m for m in doc["metrics"] if same_everywhere(doc, m)]
    differ = [m for m in doc["metrics"] if m not in same and doc["results"]["energy"][m]["n"]]
    # the detector and the face do not depend on the scheduler: the same under both
    assert {"detector_f1", "jaw_call_r"} <= set(same) and "cutoff_rate" in differ
    (metrics,) = [f for f in saved if f.name == "metrics.png"]             # the report's (the run draws none)
    assert (tmp_path / "rep" / "figures" / "metrics.pdf").read_bytes().startswith(b"%PDF")   # and its PDF
    assert "](figures/metrics.pdf)" in readme
    panels = {t.split(" ")[0] for t in metrics.titles if t}
    compute = {"frame_ms_p50", "frame_ms_p99", "realtime_factor"}
    assert panels == set(differ) - compute   # the compute time in timing.png, apart (it differs run to run)
    (timing,) = [f for f in saved if f.name == "timing.png"]
    assert {t.split(" ")[0] for t in timing.titles if t} == set(differ) & compute
    assert all(m in " ".join(metrics.texts) for m in same)           # named under the panels instead
    assert all(t == ["energy", "concat"] for t, title in zip(metrics.xticks, metrics.titles) if title)
    table = readme.split("![metrics]")[0]
    assert all(f"| {m} " not in table for m in same) and all(f"| {m} " in readme for m in same)
    assert "| metric | units | energy mean [95% CI] | concat mean [95% CI] |" in readme


def _sweep_point(job: Path, overrides: list[str], doc: dict | None = None, scale: float = 1.0) -> dict:
    """One point of a Hydra-like sweep folder: its experiment (run, or ``doc`` with every mean and CI
    times ``scale``) and its ``.hydra/overrides.yaml``."""
    import yaml

    from laughlab.harness.results import write_json

    if doc is None:
        doc = _tiny_experiment(job, "energy_ablation", overrides, {"energy": ["scheduler=energy"]})
    else:
        doc = json.loads(json.dumps(doc))
        for r in doc["results"]["energy"].values():
            if r["mean"] is not None:
                r["mean"] *= scale
                r["ci95"] = [v * scale if v is not None else None for v in r["ci95"]]
        job.mkdir(parents=True)
        write_json(job / "results.json", doc)
    (job / ".hydra").mkdir(parents=True, exist_ok=True)
    (job / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(["experiment=energy_ablation", *overrides]))
    return doc


def test_the_figures_of_a_sweep_report(tmp_path, saved):
    """A 2 x 1 sweep run for real (line plots), then made a 2 x 2 one (heatmaps) by two more points whose
    results are the first two's scaled by 1.2 (what the sweep changed is all the report reads)."""
    from laughlab.harness.report import KEY_METRICS, write_report

    docs = [_sweep_point(tmp_path / "line" / str(k), [f"scheduler.overrule_c={c}", "scheduler.decrease_per_s=6"])
            for k, c in enumerate((1.5, 3))]
    write_report(tmp_path / "line", tmp_path / "rep_line", "cmd")
    lines = [f for f in saved if f.name.startswith("line_") and f.name.endswith(".png")]
    assert len(lines) == 1
    assert all("is better" in t for t in lines[0].texts if t.startswith(("fraction", "s (", "Pearson")))
    # what it was measured on (a review: a sweep PNG in a paper could not be traced back), and each point's 95 % CI
    # inside its panel's value axis (a review: bare means, and axes that fitted the means alone)
    text = " ".join(lines[0].texts)
    per = docs[0]["n_trials"] // len(docs[0]["results"])
    assert f"energy_ablation sweep: each point the mean of {per} trial" in text.replace("\n", " ")
    assert "scheduler.decrease_per_s=6" in text.replace("\n", "") and "Error bars: each point's 95% bootstrap CI" in text
    for title, (bottom, top) in zip(lines[0].titles, lines[0].ylims):
        if title:
            cis = [d["results"]["energy"][title.split(" ")[0]]["ci95"] for d in docs]
            assert all(bottom <= lo and hi <= top for lo, hi in cis if lo is not None), (title, cis, bottom, top)
    shutil.copytree(tmp_path / "line", tmp_path / "sweep")
    for k, (c, doc) in enumerate(zip((1.5, 3), docs), start=2):
        _sweep_point(tmp_path / "sweep" / str(k), [f"scheduler.overrule_c={c}", "scheduler.decrease_per_s=20"],
                     doc, 1.2)
    readme = write_report(tmp_path / "sweep", tmp_path / "rep", "cmd").read_text()
    # the table's metric columns carry the better direction and the units, as the experiment report's rows
    units = docs[0]["metrics"]
    header = next(line for line in readme.splitlines() if line.startswith("| scheduler."))
    assert all(f"| {m} {'↑' if units[m]['higher_is_better'] else '↓'} ({units[m]['units']}) |" in header
               for m in KEY_METRICS), header
    (heat,) = [f for f in saved if f.name.startswith("heatmap_") and f.name.endswith(".png")]
    # a vector PDF beside each PNG, named in the README, with no date inside: a second report, the same bytes
    pngs = sorted((tmp_path / "rep" / "figures").glob("*.png"))
    pdfs = {p.with_suffix(".pdf").name: p.with_suffix(".pdf").read_bytes() for p in pngs}
    assert pngs and all(b.startswith(b"%PDF") and b"CreationDate" not in b for b in pdfs.values())
    assert all(f"](figures/{name})" in readme for name in pdfs)
    write_report(tmp_path / "sweep", tmp_path / "rep", "cmd")
    assert pdfs == {n: (tmp_path / "rep" / "figures" / n).read_bytes() for n in pdfs}
    assert "energy_ablation sweep: each point the mean of" in " ".join(heat.texts)
    # a cell's CI under its mean, but not for a point of one trial (its "interval" is its value: it read ±0)
    assert sum(bool(re.fullmatch(CELL, t)) for t in heat.texts) == (0 if per == 1 else 4)
    assert ("none where every point has one trial" in " ".join(heat.texts).replace("\n", " ")) == (per == 1)
    flat = re.findall(r"`(\w+)` \(", readme.split("No figure for")[1].split("\n")[0]) if "No figure for" in readme \
        else []
    # every metric of the table has a heatmap, or the report says why not
    assert sorted(t.split(" ")[0] for t in heat.titles if t) == sorted(m for m in KEY_METRICS if m not in flat)
    assert heat.n_colorbars == len(KEY_METRICS) - len(flat) > 0
    assert all(f"`{m}` (" in readme for m in flat) and ("the sweep did not change it" in readme or not flat)
    # bright (the top of viridis) is better in every heatmap, and every bar's top is its better end; each bar
    # names its units above that
    for (label, cmap, rising), title in zip(heat.bars, [t for t in heat.titles if t]):
        metric_units, way = label.split("\n")
        assert metric_units == units[title.split(" ")[0]]["units"]
        assert (way, cmap, rising) in {("↑ better (higher values)", "viridis", True),
                                       ("↑ better (lower values; scale reversed)", "viridis_r", False)}
    assert {b[0].split("\n")[1] for b in heat.bars} == {"↑ better (higher values)", "↑ better (lower values; scale reversed)"}
    # the axes name the swept parameters with their units where the name says one (a review: raw keys, no units)
    assert {"scheduler.decrease_per_s (1/s)", "scheduler.overrule_c"} <= set(heat.texts)
    assert_readable(saved)


def test_the_study_figures_keep_the_design_order_and_the_fit_says_what_its_warnings_mean(tmp_path, saved):
    from laughlab.study.analyze import analyze

    design_order = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    rng = np.random.default_rng(3)
    rows = []
    for p in range(1, 9):
        rows.append(dict(participant=p, trial=0, stimulus="", condition="", kind="audio_check",
                         question="audio_check", value=1))
        for t, (c, s) in enumerate(((c, s) for c in design_order for s in ("a", "b")), start=1):
            for q in ("naturalness", "body_sound_match"):
                v = 4 + (c == "laugh_energy") + rng.normal(0, 0.7)
                rows.append(dict(participant=p, trial=t, stimulus=f"{c}-{s}", condition=c, kind="rating",
                                 question=q, value=int(np.clip(np.round(v), 1, 7))))
    pd.DataFrame(rows).to_csv(tmp_path / "answers.csv", index=False)
    study = tmp_path / "study"
    study.mkdir()
    (study / "design.json").write_text(json.dumps({
        "conditions": design_order, "scale": "likert", "points": 7, "slider": {"min": 0, "max": 100},
        "questions": [{"id": "naturalness", "prompt": "How natural was it?"},
                      {"id": "body_sound_match", "prompt": "How well did the body match the sound?"}],
        "exclusions": {"audio_check": True, "attention_max_fail": 0, "straightline": True}}))
    out = analyze(tmp_path / "answers.csv", tmp_path / "report", study)
    assert_readable(saved)
    for f in saved:
        assert all([t.replace("\n", "") for t in ticks] == design_order for ticks in f.xticks), f.name
    # people's answers: the titles do not say "simulated"; simulated ones do (below)
    assert not any("simulated" in t for f in saved for t in f.texts)
    from laughlab.study.plots import means_plot

    means_plot(tmp_path / "sim.png", pd.read_csv(out / "means.csv"), pd.read_csv(out / "tidy.csv"), ["naturalness"],
               design_order, simulated=True)
    assert any("simulated participants" in t for t in saved[-1].texts)
    means = pd.read_csv(out / "means.csv")
    assert list(means["condition"][:4]) == design_order and list(means["question"][:4]) == ["naturalness"] * 4
    report = json.loads((out / "report.json").read_text())
    text = (out / "README.md").read_text()
    assert "mle_retvals" not in text and "Retrying" not in text and "boundary of the parameter" not in text
    assert report["model_warnings"]                  # these ratings make statsmodels warn
    for q, warned in report["model_warnings"].items():
        note = report["model_notes"][q]
        said = note.split(" Only ")[0]   # then the few participants' (8 here) and few stimuli's cautions, if any
        assert said.count(". ") == 0 and note.endswith(".") and f"- {q}: {note}" in text   # one sentence
        assert not any(w in text for w in warned)                                            # not pasted raw
        if any(w.startswith("The MLE may be on the boundary") for w in warned):
            assert "variance is at or near zero" in note or "variances are at or near zero" in note


def test_a_fit_note_says_what_the_warnings_mean():
    from laughlab.study.analyze import fit_model, fit_note

    conds = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    rng = np.random.default_rng(1)
    d = pd.DataFrame([dict(participant=p, stimulus=f"{c}-{s}", condition=c,
                           value=float(np.clip(np.round(4 + (c == "laugh_energy") + rng.normal(0, 0.7)), 1, 7)))
                      for p in range(1, 9) for c in conds for s in ("a", "b")])
    fit, ref, warned = fit_model(d, conds)
    assert ref == "smile_only" and fit.converged
    assert any(w.startswith("The MLE may be on the boundary") for w in warned)
    assert fit.vcomp[0] < 1e-6 < fit.vcomp[1]       # participants: no spread beyond the noise
    assert fit_note(fit, warned) == (
        "The fit converged; the participant variance is at or near zero (participants differ no more than the "
        "rating noise, so the model is in effect one without that random intercept), which by itself leaves the "
        "condition estimates and tests below as they are.")
    # the same maximum whichever condition is the reference level (both optimisers are tried)
    other, ref2, _ = fit_model(d, conds[::-1])
    assert ref2 == "laugh_concat" and other.llf == pytest.approx(fit.llf, abs=1e-6)
    assert np.allclose(other.vcomp, fit.vcomp, atol=1e-5) and other.scale == pytest.approx(fit.scale, rel=1e-5)
    assert fit_note(fit, []) == ""
    assert fit_note(fit, ["Something new"]).endswith("statsmodels also warned of something else (see report.json), "
                                                     "so check these estimates.")


def test_filmstrip_moments_by_hand():
    from laughlab.render.plots import filmstrip_moments

    times = np.arange(10.0)
    pos = np.zeros((10, 2, 3))
    pos[3, :, 0] = 10.0            # the pose farthest from the usual one (all zeros), in the clap block
    pos[8, :, 0] = 5.0
    blocks = [("clap", 2.0, 5.0, 15.0), ("idle", 5.0, 10.0, 0.0)]
    # 3 (clap's most pronounced); then parts [0, 3) and [6, 9]: 0 (the first pose unlike 3), then
    # 8 (the one unlike both 3 and 0)
    assert filmstrip_moments(times, pos, 3, blocks) == [0, 3, 8]
    assert filmstrip_moments(times, pos, 1, blocks) == [3]
    assert filmstrip_moments(times[:3], pos[:3], 20, []) == [0, 1, 2]
    assert filmstrip_moments(times[:0], pos[:0], 8, blocks) == []


def test_the_checks_see_overprinting_and_a_colour_bar_that_does_not_say_which_way_is_better():
    fig = Figure()
    ax = fig.subplots()
    ax.text(0.5, 0.5, "lean_front2")
    ax.text(0.52, 0.5, "lean_back2")
    im = ax.imshow(np.arange(4.0).reshape(2, 2))
    fig.colorbar(im, ax=ax, label="miss_rate")
    assert overlapping_texts(fig) == [("lean_front2", "lean_back2")]
    assert colorbars_without_direction(fig) == ["miss_rate"]


@pytest.mark.parametrize("frames", [3])
def test_the_filmstrip_keeps_its_title_inside_and_names_its_colours(tmp_path, saved, frames):
    """A strip of 3 figures is 3.75 in wide: its one-line title was cut at both edges; it wraps now. The red and
    blue limbs were named nowhere.  (The default 8 frames: test_the_figures_of_a_run checks the same of its
    filmstrip, a run of each scheduler.)"""
    pipeline.execute(pipeline.build(cfg_for("input.duration_s=6", f"output.plots.filmstrip_frames={frames}",
                                            "~output.bvh")), tmp_path)
    strip = [f for f in saved if f.name == "filmstrip.png"]
    assert_readable(strip)
    assert any("Blue: the left arm and leg; red: the right" in " ".join(t.split()) for t in strip[0].texts)


def test_the_check_sees_lines_only_their_hue_tells_apart():
    """Solid red against solid blue (or green) merge in greyscale and for red-green colour blindness; a dash or a
    clearly lighter colour tells them apart."""
    fig = Figure()
    ax = fig.subplots()
    ax.plot([0, 1], color="tab:red", label="a")
    ax.plot([1, 0], color="tab:blue", label="b")
    ax.plot([0, 0], color="tab:green", ls="--", label="c")
    ax.plot([1, 1], color="0.8", label="d")          # light grey: far lighter than red and blue
    ax.plot([0.5, 0.5], color="tab:orange")            # unnamed: not in a legend
    assert lines_told_apart_by_hue(fig) == [("a", "b")]

    # a panel a sub-figure (Fig. 7 in a column): the same spot of two sub-figures is two panels, not twins, and
    # within one sub-figure the check still looks
    fig = Figure()
    top, bottom = fig.subfigures(2, 1)
    top.subplots().plot([0, 1], color="tab:red", label="top")
    ax = bottom.subplots()
    ax.plot([0, 1], color="tab:blue", label="bottom")
    ax.twinx().plot([1, 0], color="tab:red", label="twin")
    assert lines_told_apart_by_hue(fig) == [("bottom", "twin")]


def test_the_detector_pr_figure_tells_its_curves_apart_without_colour(tmp_path, saved):
    """detector_eval's precision-recall curves: four scores and chance, each with a style of its own."""
    from laughlab_experiments.detector_eval import SCORES, pr_figure

    rng = np.random.default_rng(0)
    y = rng.random(2000) < 0.2
    fig, out = pr_figure({name: y * rng.random(2000) + rng.random(2000) for name in SCORES}, y)
    assert set(out["scores"]) == set(SCORES)
    fig.savefig(tmp_path / "detector_pr.png")
    assert_readable(saved)
    # the sets it was measured on, as given (a new-user review: "real, mixed and between" of a run of mixed alone)
    assert "(sets real, mixed and between)" in out["what"]
    assert "(sets mixed)" in pr_figure({"yamnet (head)": y * 1.0}, y, sets=["mixed"])[1]["what"]
    # a folder of one's own is not "held-out" (a new-user review published that title on their own recordings)
    from laughlab_experiments.detector_eval import data_words

    assert data_words(["between", "mixed-10dB", "real"]) == (
        "the held-out recordings with a truth (sets between, mixed-10dB and real)", "held-out recordings")
    assert data_words(["recording"]) == ("the recordings of harness.corpus.folder with a truth", "your recordings")
    assert data_words(["real", "recording"], "train") == (
        "the train-split recordings with a truth (sets real) and the recordings of harness.corpus.folder with a "
        "truth", "train-split recordings and your recordings")
    fig, out = pr_figure({"yamnet (head)": y * 1.0}, y, sets=["recording"])
    assert fig.axes[0].get_title() == "Laughter scores per frame, your recordings (dots: the gates' thresholds)"


@pytest.mark.parametrize("names", [["yamnet", "yamnet_fused", "laugh", "none"],
                                   ["energy_fast_decay", "energy_slow_decay", "concat_segments"]])
def test_the_comparison_figure_keeps_long_condition_names_apart(tmp_path, saved, names):
    """reports/detector_eval drew 'yamnet', 'yamnet_fused' and 'laugh' on top of each other under every panel."""
    from laughlab.harness.report import comparison_figure

    metrics = {"bouts_answered": {"higher_is_better": True, "units": "fraction"},
               "frame_ms_p99": {"higher_is_better": False, "units": "ms"}}
    results = {c: {m: {"n": 3, "mean": 0.2 + 0.1 * i + j, "ci95": [0.1 + 0.1 * i + j, 0.3 + 0.1 * i + j]}
                   for j, m in enumerate(metrics)} for i, c in enumerate(names)}
    doc = {"experiment": "detector_eval", "n_trials": 3 * len(names), "conditions": {c: [] for c in names},
           "results": results, "metrics": metrics}
    comparison_figure(doc, tmp_path / "metrics.png")
    assert_readable(saved)
    assert saved[-1].xticks[0] == names


def test_an_all_zero_metric_starts_at_0_and_a_metric_that_does_not_apply_says_n_a(tmp_path, saved):
    """A new-user review: cutoff_rate (0 under energy, no clip under none) got an empty panel running
    -0.04..0.04, and the missing bar of none read as a 0.  A researcher's review: a panel of one condition's
    "0 (n=2)" beside an "n/a" compares nothing: a metric measured under one condition only has no panel and
    is named, with its value, under the panels."""
    from laughlab.harness.report import comparison_figure

    metrics = {"cutoff_rate": {"higher_is_better": False, "units": "fraction"},
               "repetition_rate": {"higher_is_better": False, "units": "fraction"},
               "clip_entropy": {"higher_is_better": True, "units": "bits"},
               "miss_rate": {"higher_is_better": False, "units": "fraction"}}
    nothing = {"n": 0, "mean": None, "ci95": [None, None]}
    results = {"energy": {"cutoff_rate": {"n": 4, "mean": 0.0, "ci95": [0.0, 0.0]},
                          "repetition_rate": {"n": 4, "mean": 0.0, "ci95": [0.0, 0.0]},
                          "clip_entropy": {"n": 4, "mean": 1.5, "ci95": [1.0, 2.0]},
                          "miss_rate": {"n": 4, "mean": 0.25, "ci95": [0.0, 0.5]}},
               "concat": {"cutoff_rate": {"n": 4, "mean": 0.5, "ci95": [0.25, 0.75]},
                          "repetition_rate": nothing, "clip_entropy": nothing,
                          "miss_rate": {"n": 4, "mean": 0.5, "ci95": [0.25, 0.75]}},
               "none": {"cutoff_rate": nothing, "repetition_rate": nothing, "clip_entropy": nothing,
                        "miss_rate": {"n": 4, "mean": 1.0, "ci95": [1.0, 1.0]}}}
    doc = {"experiment": "smoke", "n_trials": 12, "conditions": {"energy": [], "concat": [], "none": []},
           "results": results, "metrics": metrics}
    comparison_figure(doc, tmp_path / "metrics.png")
    assert_readable(saved)
    (fig,) = saved
    assert sorted(t for t in fig.titles if t) == ["cutoff_rate ↓", "miss_rate ↓"]
    note = " ".join(" ".join(fig.texts).split())
    assert ("Not shown, measured under one condition only: repetition_rate (energy: 0), clip_entropy (energy: "
            "1.5) (values in the report's table).") in note
    cutoff = fig.titles.index("cutoff_rate ↓")
    lo, hi = fig.ylims[cutoff]
    assert lo == 0 and hi >= 0.75                   # an axis from 0, not matplotlib's -0.04..0.04
    assert fig.texts.count("n/a") == 1                 # none's missing bar
    # means of fewer than 10 trials say so over their bars, as the table's "(n=4)" (a review: the figure did not),
    # a bar at 0 too (a review: its n was lost under the "0")
    assert fig.texts.count("0 (n=4)") == 1 and fig.texts.count("n=4") == 4
    assert fig.ylims[fig.titles.index("miss_rate ↓")][0] == 0


def test_figure_10_error_labels_stay_apart_and_clear_of_the_legend(tmp_path, saved):
    """A new-user review: per-call errors of short neighbouring calls ran together ("0.340.09") and the
    legend covered some."""
    from types import SimpleNamespace

    from laughlab_experiments.hill_fit import figure_10

    fps, n = 60, 25
    calls = [SimpleNamespace(call=SimpleNamespace(start=30 + 10 * k, end=37 + 10 * k), error=0.3 - 0.01 * k)
             for k in range(n)]
    t = np.arange(30 + 10 * n + 60)
    target = np.maximum(np.sin(2 * np.pi * t / 10), 0) * 0.1
    res = SimpleNamespace(calls=calls, fps=fps, target=target, simulated=target * 1.1)
    figure_10(tmp_path / "fig10_pressure.png", res)
    assert_readable(saved)
    assert sum(t.startswith("0.") for t in saved[-1].texts) >= n


def test_fig3_2_zooms_on_laughter_and_fig4_2_names_its_energy(tmp_path, saved):
    """A review: on a scene of talk and laughter Fig. 3.2's zoom showed the busiest talk before the first bout, and
    the concat run's Fig. 4.2 called its energy channel (40 MCS, low-passed) the thesis' laughing energy L."""
    from laughlab.render import plots

    t = np.arange(0, 20, 1 / 60)
    raw = np.where(t < 5, 0.9, 0.0) + np.where((t > 12) & (t < 15), 0.5 * np.abs(np.sin(t * 30)), 0.0)
    plots.figure_3_2(tmp_path / "z.png", t, raw, 1 / 60, bouts=[(12.0, 15.0)])
    plots.figure_3_2(tmp_path / "n.png", t, raw, 1 / 60)
    with_bouts, without = saved
    assert "zoom: 11.5-15.5 s" in with_bouts.titles and "zoom: 0.5-4.5 s" in without.titles   # the middle of equal windows
    plots.figure_4_2(tmp_path / "c.png", t, raw, 40 * raw, [], energy_label="energy (40 MCS, 0.5 s low-pass)")
    assert "energy (40 MCS, 0.5 s low-pass)" in saved[-1].texts and "laughing energy L" not in saved[-1].texts


def test_the_baseline_condition_is_grey_in_every_report():
    """A review: colours went by position, so `none` was red in one report and purple in the next."""
    from matplotlib.colors import to_hex

    from laughlab.harness.report import condition_colors

    a = condition_colors(["yamnet", "yamnet_fused", "laugh", "none"])
    b = condition_colors(["none", "energy"])
    assert to_hex(a["none"]) == to_hex(b["none"]) == "#999999"
    assert [to_hex(a[c]) for c in ("yamnet", "yamnet_fused", "laugh")] == ["#1f77b4", "#ff7f0e", "#2ca02c"]
    assert to_hex(b["energy"]) == "#1f77b4"


def test_heatmap_cells_of_different_values_read_differently(tmp_path, saved):
    """A review: cells labelled with 2 significant figures showed 0.78 on cells of clearly different colour."""
    from laughlab.harness.sweep_figures import distinct_labels, heatmaps

    assert distinct_labels([0.7812, 0.7849, 0.2]) == ["0.781", "0.785", "0.2"]        # 3 figures by default
    assert distinct_labels([0.78121, 0.78149, float("nan")]) == ["0.7812", "0.7815", "n/a"]   # more where needed
    info = {"intensity_r_clip": {"higher_is_better": True, "units": "Pearson r"}}
    points = [{"params": {"a": a, "b": b}, "r": {"mean": v, "ci95": [v - 0.01, v + 0.01], "n": 4}}
              for (a, b), v in zip([("1", "1"), ("2", "1"), ("1", "2"), ("2", "2")], (0.7812, 0.7849, 0.79, 0.80))]
    heatmaps(points, "a", "b", ["intensity_r_clip"], lambda p, m: p["r"], tmp_path / "h.png", info, "t")
    cells = [t.split("\n")[0] for t in saved[-1].texts if re.fullmatch(CELL, t)]
    assert sorted(cells) == ["0.781", "0.785", "0.79", "0.8"]


#: a heatmap cell: its mean over its 95% interval
CELL = r"[\d.]+\n\[[\d.]+, [\d.]+\]"


def test_a_heatmap_cell_gives_its_interval_not_a_plus_minus_past_a_fractions_range(tmp_path, saved):
    """A sweep researcher's review: a miss rate of 0.0833 with its interval [0, 0.25] was written '0.0833 ±0.12',
    which reads as reaching below 0; the cell now gives the interval itself, within the values' range."""
    from laughlab.harness.sweep_figures import heatmaps

    info = {"miss_rate": {"higher_is_better": False, "units": "fraction"}}
    points = [{"params": {"a": a, "b": b}, "r": {"mean": v, "ci95": ci, "n": 12}}
              for (a, b), v, ci in zip([("1", "1"), ("2", "1"), ("1", "2"), ("2", "2")], (0.0833, 0.0, 0.25, 0.5),
                                       ([0.0, 0.25], [0.0, 0.0], [0.0833, 0.4167], [0.3333, 0.6667]))]
    heatmaps(points, "a", "b", ["miss_rate"], lambda p, m: p["r"], tmp_path / "h.png", info, "t")
    cells = sorted(t for t in saved[-1].texts if re.fullmatch(CELL, t))
    assert cells == ["0\n[0, 0]", "0.0833\n[0, 0.25]", "0.25\n[0.083, 0.42]", "0.5\n[0.33, 0.67]"], cells
    assert not any("±" in t for t in saved[-1].texts)


def test_a_heatmap_cell_of_single_trials_has_no_plus_minus_and_no_clip_is_no_value(tmp_path, saved):
    """A new-user review: a sweep of one trial a point printed "±0" under every cell (one trial's interval is its
    value), and scheduler=none's offset tail of 0 s (no clip played, so no tail) was the brightest, "best", cell."""
    from laughlab.harness.report_format import NO_VALUE, vacuous
    from laughlab.harness.sweep_figures import heatmaps

    info = {"intensity_r_clip": {"higher_is_better": True, "units": "Pearson r"}}
    one = [{"params": {"a": a, "b": b}, "r": {"mean": v, "ci95": [v, v], "n": 1}}
           for (a, b), v in zip([("1", "1"), ("2", "1"), ("1", "2"), ("2", "2")], (0.5, 0.6, 0.7, 0.8))]
    heatmaps(one, "a", "b", ["intensity_r_clip"], lambda p, m: p["r"], tmp_path / "h.png", info, "t")
    texts = saved[-1].texts
    assert {"0.5", "0.6", "0.7", "0.8"} <= set(texts)   # the cells, each its value alone
    assert not any("\n" in t for t in texts if t[:1].isdigit()) and any("those of one trial" in t for t in texts)
    # a cell with a point of 3 trials and one of 1: its interval is the 3-trial point's alone
    mixed = one[:3] + [{"params": {"a": "2", "b": "2"}, "r": {"mean": 0.8, "ci95": [0.7, 0.9], "n": 3}}]
    heatmaps(mixed, "a", "b", ["intensity_r_clip"], lambda p, m: p["r"], tmp_path / "h2.png", info, "t")
    assert [t for t in saved[-1].texts if re.fullmatch(CELL, t)] == ["0.8\n[0.7, 0.9]"]
    # scheduler=none: no clip played (cutoff_rate has no value), so its offset tail's 0 is no value
    doc = {"metrics": {"offset_tail_s": {"higher_is_better": False}, "cutoff_rate": {"higher_is_better": False}},
           "results": {"none": {"offset_tail_s": {"mean": 0.0, "ci95": [0.0, 0.0], "n": 4},
                                "cutoff_rate": {"mean": None, "ci95": [None, None], "n": 0}},
                       "energy": {"offset_tail_s": {"mean": 0.0, "ci95": [0.0, 0.0], "n": 4},
                                  "cutoff_rate": {"mean": 0.1, "ci95": [0.0, 0.2], "n": 4}}}}
    assert vacuous(doc, "offset_tail_s", "none") and not vacuous(doc, "offset_tail_s", "energy")
    info = {"offset_tail_s": {"higher_is_better": False, "units": "s"}}
    pts = [{"params": {"a": a, "b": "1"}, "cond": c, "r": doc["results"][c]["offset_tail_s"]}
           for a, c in (("energy", "energy"), ("none", "none"))] + [
          {"params": {"a": a, "b": "2"}, "cond": "energy", "r": {"mean": 0.4, "ci95": [0.3, 0.5], "n": 4}}
          for a in ("energy", "none")]

    def shown(p, m):   # as sweep_report shows a point
        return NO_VALUE if vacuous(doc, m, p["cond"]) else p["r"]

    heatmaps(pts, "a", "b", ["offset_tail_s"], shown, tmp_path / "h3.png", info, "t")
    cells = sorted(t for t in saved[-1].texts if re.fullmatch(CELL, t) or t == "n/a")
    assert cells == ["0\n[0, 0]", "0.4\n[0.3, 0.5]", "0.4\n[0.3, 0.5]", "n/a"], cells   # energy's 0 stays: it played clips


class _ClipCount:
    """A researcher's own metric, registered in code as a plugin would be (not laughlab's)."""

    @staticmethod
    def metric():
        from laughlab.harness.metrics import metric

        @metric("clip_events_n", True, "count")
        def clip_events_n(trial):
            """How many clip events the trial had."""
            return float(len(trial.events))

        return clip_events_n

    def __init__(self):
        self.m = self.metric()

    from laughlab import hookimpl

    @hookimpl
    def register_metrics(self, register):
        register(self.m)


def test_a_sweep_report_shows_a_plugins_metric_and_those_asked_for(tmp_path, saved):
    """A plugin authors' review: a sweep's table and figures showed only the fixed key metrics, so a metric a
    plugin registered never appeared; ``report --metrics`` adds any the sweep measured, and refuses others."""
    from laughlab.core import plugins
    from laughlab.core.errors import LaughlabError
    from laughlab.harness.report import write_report

    mine = _ClipCount()
    plugins.pm.register(mine, name="test-clip-count")
    try:
        for k, c in enumerate((6, 20)):
            _sweep_point(tmp_path / "sweep" / str(k), ["scheduler.overrule_c=2", f"scheduler.decrease_per_s={c}"])
    finally:
        plugins.pm.unregister(mine)
    readme = write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", metrics=["detector_f1"]).read_text()
    header = next(line for line in readme.splitlines() if line.startswith("| scheduler."))
    assert "| clip_events_n ↑ (count) |" in header and "| detector_f1 ↑ (F1) |" in header, header
    assert "and `clip_events_n`, `detector_f1` (a plugin's own, or asked for with `report --metrics`)" in readme
    (line,) = [f for f in saved if f.name.startswith("line_") and f.name.endswith(".png")]
    assert "clip_events_n ↑" in line.titles or "`clip_events_n` (" in readme   # a panel, or said to be flat
    with pytest.raises(LaughlabError, match=r"^--metrics: the sweep measured no jaw_mean; its metrics: "):
        write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", metrics=["jaw_mean"])
    with pytest.raises(LaughlabError, match=r"^--metrics: the sweep measured no missrate \(did you mean miss_rate\?\), "
                                            r"jaw_mean; its metrics: "):   # a typo: the nearest metric
        write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", metrics=["missrate", "jaw_mean"])
    # report --panels: the figures show only those metrics, in that order; the table keeps the key ones too
    saved.clear()
    panels = ["intensity_r_kinetic", "clip_events_n", "intensity_r_clip"]   # the two that vary, the other way round
    readme = write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", panels=panels).read_text()
    (line,) = [f for f in saved if f.name.startswith("line_") and f.name.endswith(".png")]
    drawn = [t.split(" ")[0] for t in line.titles if t]
    assert drawn == ["intensity_r_kinetic", "intensity_r_clip"], line.titles
    assert all(f"`{m}` (" in readme for m in panels if m not in drawn)   # not drawn: said to be flat
    assert "| clip_events_n ↑ (count) |" in readme and "| cutoff_rate" in readme
    with pytest.raises(LaughlabError, match=r"^--panels: \S+ measured no jaw_mean; its metrics: "):
        write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", panels=["jaw_mean"])
    with pytest.raises(LaughlabError, match=r"^--panels: \S+ measured no cutoff \(did you mean cutoff_rate\?\); its "):
        write_report(tmp_path / "sweep", tmp_path / "rep", "cmd", panels=["cutoff"])


@pytest.mark.parametrize("frames", [1, 2])
def test_a_filmstrip_of_one_or_two_figures_keeps_a_readable_title(tmp_path, saved, frames):
    """A new-user review: a 0.2 s run's filmstrip of one figure was 1.25 in wide, its title 7 lines of 2 words.  The
    strip is now at least 5 in wide, its figures keeping 1.25 in each, in the middle; the title on 3 lines or fewer."""
    from laughlab.motion.skeleton import HUMANOID as sk, rest_pose
    from laughlab.render import plots

    plots.filmstrip(tmp_path / "s.png", sk, np.arange(frames) * 0.2, np.stack([rest_pose(sk)] * frames),
                    ["no clip\nsmile 0.00, jaw 0.00"] * frames)
    (strip,) = saved
    fig = strip.figure
    assert fig.get_figwidth() == 5.0
    title = fig._suptitle.get_text()
    assert title.count("\n") + 1 <= 3, title
    for ax in fig.axes:   # each figure's panel as wide as in a strip of n (1.25 in less the margins), centred
        assert 1.15 <= ax.get_position().width * 5.0 <= 1.23
    boxes = [ax.get_position() for ax in fig.axes]
    assert min(b.x0 for b in boxes) == pytest.approx(1 - max(b.x1 for b in boxes), abs=1e-6)
    assert_readable(saved)


@pytest.mark.parametrize("width", ["page", "column"])
def test_fig_3_1_of_another_extractor_does_not_call_the_rms_mapping_the_runs_mcs(saved, tmp_path, width):
    """A researcher's review: under extractor=pressure, Fig. 3.1's panels labelled "MCS" reached 1 where the run's
    MCS (the pressure extractor's) was 0: they are what the rms extractor would make of the sound."""
    from inprocess import laughlab

    r = laughlab("input.duration_s=2", "extractor=pressure", "detector=none", f"output.plots.width={width}",
                 f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 0, r.stderr
    assert_readable(saved)
    (fig,) = [f for f in saved if f.name == "fig3_1_calibration.png"]
    assert "rms's MCS" in fig.texts and "MCS" not in fig.texts
    assert any("not the MCS of this run" in t.replace("\n", " ") for t in fig.texts)


@pytest.mark.parametrize("args, titles", [
    (["extractor=pressure", "body=hill", "output.plots.width=column", "run_out=true"], [
        "Lung pressure (DiLorenzo et al. 2008, Eqs. 1-4) and its target from the audio (Sec. 6)",
        "Muscle activations (Hill model, Sec. 5.1)", "Airflow (out positive)"]),
    (["extractor=pressure"], [
        "Pressure target from the audio (DiLorenzo et al. 2008, Sec. 6: |audio| low-passed, fitted)"]),
    (["extractor=phoneme", "scheduler=concat", "face=cgm", "body=follow", "output.plots.width=column"],
     ["Torso following the head (Ding et al. 2014)", "Prosody (Ding et al. 2014: Praat's pitch)",
      "Lips and jaw (Ding et al. 2014, contextual Gaussian model, Eq. 1)",
      "Concatenation cost of the segments so far (Ding et al. 2014, Eq. 4)"]),
    (["body=fourier"], ["Fourier blend s, calm 0 to intense 1, past 1 extrapolated (Unuma et al. 1995, Eq. 3)"]),
    ([], None),
])
def test_a_runs_method_figure_shows_the_methods_own_signals(tmp_path, saved, args, titles):
    """A paper-reproducing researcher's review: body=hill, body=fourier and Ding et al.'s pipeline drew only van
    Duijn's figures; their own channels were in channels.csv alone. plots/method.png: a panel each, with units;
    none for van Duijn's pipeline alone."""
    from inprocess import laughlab

    r = laughlab("input.duration_s=2", "detector=none", *args, f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 0, r.stderr
    assert_readable(saved)
    shown = [f for f in saved if f.name == "method.png"]
    assert (tmp_path / "r" / "plots" / "method.png").exists() == bool(titles) == bool(shown)
    if titles:
        got = [ax.get_title(loc="left").replace("\n", " ") for ax in shown[0].figure.axes]
        assert got == titles
        assert all(ax.get_ylabel() for ax in shown[0].figure.axes)   # every panel has its unit


def test_drawing_leaves_the_users_backend_and_pyplot_alone(tmp_path):
    """A Python user's review: importing laughlab's plotting modules called ``matplotlib.use("Agg")``, which switched
    a notebook's inline backend away (later ``plt.show()`` showed nothing).  Every figure is now a bare ``Figure``
    on its own Agg canvas: the report and sweep modules imported and a run's plots and filmstrip drawn with the
    user's backend set to svg leave it svg, and pyplot is never imported."""
    import subprocess
    import sys

    code = f"""
import sys, matplotlib
matplotlib.use("svg")
from laughlab.core import pipeline
from laughlab.core.config import compose_config
from omegaconf import OmegaConf
import laughlab.harness.report, laughlab.harness.sweep_figures, laughlab.render.method_plots
cfg = compose_config(["input.duration_s=3", "scheduler=concat"])
cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
pipeline.execute(pipeline.build(cfg), __import__("pathlib").Path({str(tmp_path)!r}), {{}})
print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-2:] == ["svg", "False"], r.stdout
    assert {"fig3_2_mcs.png", "fig4_2_energy.png", "filmstrip.png"} <= {p.name for p in (tmp_path / "plots").iterdir()}
