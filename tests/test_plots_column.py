"""``output.plots.width=column``: the run's figures drawn 3.5 in wide for one column of a two-column paper, every
text at 7 pt or more at that size, as readable as the page layout's (no overprinting, nothing cut, every clip
named); ``page`` (the default) gives the bytes it gave before the setting existed."""
import hashlib

import numpy as np
import pytest
from matplotlib.figure import Figure

from laughlab.core import pipeline
from laughlab.render.labels import drawn_texts, print_sizes
from laughlab.render.layout import COLUMN_MIN_PT, layout_of

from inprocess import laughlab
from test_plots_readable import Saved, assert_readable, cfg_for, read_events


@pytest.fixture
def sized(monkeypatch):
    """Every figure saved during the test: its name, its width (in) and its texts' sizes at 3.5 in."""
    seen = []
    original = Figure.savefig

    def watched(self, fname, *args, **kwargs):
        if kwargs.get("format", "png") == "png":
            drawn = drawn_texts(self)
            seen.append((Saved(fname, self), float(self.get_size_inches()[0]), print_sizes(self, 3.5, drawn)))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", watched)
    return seen


@pytest.mark.parametrize("scheduler", ["energy", "concat"])
def test_every_text_of_the_column_figures_prints_at_7_pt_or_more(tmp_path, sized, scheduler):
    from laughlab.core.frame import clip_blocks

    pipeline.execute(pipeline.build(cfg_for("input.duration_s=6", f"scheduler={scheduler}", "~output.bvh",
                                            "output.plots.width=column")), tmp_path)
    names = {s.name for s, _, _ in sized}
    assert names == {"fig3_1_calibration.png", "fig3_2_mcs.png", "fig4_2_energy.png", "filmstrip.png"} | (
        {"fig4_1_energy.png"} if scheduler == "energy" else {"method.png"})   # concat: its cost in method.png
    for saved, width, sizes in sized:
        assert width == 3.5, saved.name
        assert sizes and sizes[0][1] >= COLUMN_MIN_PT, (saved.name, sizes[:3])
        # the ticks, axis labels and titles at 8 pt (IEEE and ACM ask for 8-9): only legends, the clips' names
        # on their blocks and the filmstrip's captions are smaller, and not below 7
        small = {t for t, pt in sizes if pt < 8}
        assert not any(t.replace(".", "").replace("−", "").isdigit() for t in small), (saved.name, small)
    assert_readable([s for s, _, _ in sized])
    played = {b[0] for b in clip_blocks(read_events(tmp_path), 6.0)}
    for saved, _, _ in sized:
        if saved.name.startswith("fig4_"):      # every clip played named, on its block or in the colour key
            assert all(any(t == c or t.startswith(f"{c}, e=") for t in saved.texts) for c in played), saved.name
    (strip,) = [s for s, _, _ in sized if s.name == "filmstrip.png"]
    assert sum(t.endswith(" s") for t in strip.texts) == 8       # 8 moments, in 2 rows of 4 (their times)
    assert all("\n" in t for t in strip.texts if t.startswith(("smile", "no clip")) or "jaw" in t)


#: the figures of ``input.duration_s=3`` (seed 0) in the locked environment: the page layout's recorded at 7df9199,
#: before output.plots.width existed (the default run's, a concat run's and btanks laugh01's were compared there too)
#: the PDFs' since 2026-11-28, when a PDF took its PNG's layout instead of a layout pass of its own (the PNGs kept
#: their bytes; the PDFs' axes moved a fraction of a point: render/savefig.py)
PAGE_SHA256 = {
    "fig3_1_calibration.pdf": "92a1e98ac98f143da0a8b4d23ca5f4f7661e73c32ccc96c7bb7713428dadfda5",
    "fig3_1_calibration.png": "60ad58a608e1aa6100a27bffe384084d34fd85c6626f2e9bdb3bac39808fad6e",
    "fig3_2_mcs.pdf": "ab147933c2f49e4e62414b401bbbecec558e9a8a3d81a16bd4d8ba9bbe62aad6",
    "fig3_2_mcs.png": "29b9bc60ad63ff4bcb9fcf66ae2861104ed9af619aedfa29f8333f14361cc2ed",
    "fig4_1_energy.pdf": "cab23021db8b487901cba2e193a0b402a0a0f80936435e3e00d42c7f051eca3d",
    "fig4_1_energy.png": "e0409cef3d978a26332a5d7e58e83990ddd9f8061caefa44ab58b949893f45d3",
    "fig4_2_energy.pdf": "d874c447c8064a4edd89bf9ecf3b9a0c06cabe270f1310bffcb90909386aa37a",
    "fig4_2_energy.png": "a75c17aa5e48e577346469c450752229e45fd81ae2d63e04ad2791c7a5a27edf",
    "filmstrip.pdf": "29b79f1aa43885212edd92369c757284718a9bcccde2c5ae580e9ac2e99ec813",
    "filmstrip.png": "23d10a966fb8e96fb57434770271bef3eb489cbc3032f46ad010435b6153b12a",
}
COLUMN_SHA256 = {
    "fig3_1_calibration.pdf": "c2b64a502f29e7faa4fb605e05565b10732804a01491f72c947431600d7a87d7",
    "fig3_1_calibration.png": "425872206203bd19313f010054ba9f107fbb24d2c8219f9f69cd90835e85bfcc",
    "fig3_2_mcs.pdf": "0fe8460542bcc2b124598582f72baf4eea1e68b4e4464e1ce04aa4edeadad8d1",
    "fig3_2_mcs.png": "c08eb7a1fa56aa2a844f7f30c299ee3ead57e388e6fa0ba741a43a2a0c28aba7",
    "fig4_1_energy.pdf": "1bb36873efe4a72a00c76e118f66b71963b5de4f5af049e5d79405ec5f51fff4",
    "fig4_1_energy.png": "b6b3b491a25163abeafcbb8d8d70d8c3f4549619a3a086abfb5a870550968ebc",
    "fig4_2_energy.pdf": "8cdd46f3f8640e05da1d62b5201073fb82e7577644299987b5a80339c39d2441",
    "fig4_2_energy.png": "ac6b9769ba4f2155dd207c11dcc38865015b0bba16adf110fe8ce618dcf9d392",
    "filmstrip.pdf": "851bbe69b18939bb460549b5bd8776f6f85859e70f767321c1bd64fe00a3daca",
    "filmstrip.png": "971120f2d7913d7818f5c6d4b88cea19d7521a2b0a1c47b8f9e1f21a087a8cdc",
}


@pytest.mark.parametrize("width", ["page", "column"])
def test_the_same_seed_gives_the_same_bytes_and_the_pdfs_keep_truetype(tmp_path, width):
    """In the locked environment each figure is the recorded bytes (the page layout's: those of before the
    setting); anywhere, each PDF has its text in embedded TrueType (Type 42), no Type 3, and no date."""
    import golden

    pipeline.execute(pipeline.build(cfg_for("input.duration_s=3", "~output.csv", "~output.bvh",
                                            f"output.plots.width={width}", "output.plots.pdf=true")), tmp_path)
    files = {p.name: p.read_bytes() for p in sorted((tmp_path / "plots").iterdir())}
    pdfs = [n for n in files if n.endswith(".pdf")]
    assert len(pdfs) == 5 and all(b"/Type3" not in files[n] and b"/FontFile2" in files[n]
                                  and b"CreationDate" not in files[n] for n in pdfs)
    exact, why = golden.exact_environment()
    if not exact:
        pytest.skip(f"the figures' bytes hold in the locked environment only: {why}")
    got = {n: hashlib.sha256(b).hexdigest() for n, b in files.items()}
    assert got == (PAGE_SHA256 if width == "page" else COLUMN_SHA256)


def test_a_width_that_is_neither_page_nor_column_is_one_error_line(tmp_path):
    r = laughlab(f"hydra.run.dir={tmp_path / 'run'}", "input.duration_s=1", "output.plots.width=colum")
    lines = r.stderr.strip().splitlines()
    assert r.returncode != 0 and len(lines) == 1, r.stderr
    assert lines[0].startswith("laughlab: error: ") and "width must be one of page, column (got 'colum')" in lines[0]
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").rglob("*.png"))
    with pytest.raises(ValueError):
        layout_of("a4")


def test_print_sizes_by_hand():
    fig = Figure(figsize=(7.0, 2.0))
    fig.text(0.1, 0.5, "small", fontsize=6)
    fig.text(0.5, 0.5, "big", fontsize=10)
    assert print_sizes(fig, 3.5) == [("small", 3.0), ("big", 5.0)]      # half the width: half the size
    assert print_sizes(fig, 7.0)[0] == ("small", 6.0)
    np.testing.assert_allclose([pt for _, pt in print_sizes(fig, 14.0)], [12.0, 20.0])


def test_a_reports_metrics_figure_in_a_column_prints_every_text_at_7_pt_or_more(tmp_path, sized):
    """``report --width column``: metrics.png 3.5 in wide, 2 panels a row, long metric and condition names, a mean
    of few trials (its n=k), a 0 and an n/a (the page figure's 5.5-6 pt marks and tick labels)."""
    from laughlab.harness.report import comparison_figure

    names = ["yamnet", "yamnet_fused", "laugh", "none"]
    metrics = {"onset_latency_median_s": {"higher_is_better": False, "units": "s"},
               "false_starts_per_min_speech": {"higher_is_better": False, "units": "per min"},
               "bouts_answered": {"higher_is_better": True, "units": "fraction"}}
    results = {c: {m: {"n": 4 if i else 12, "mean": (0.2 + 0.1 * i + j) if i < 3 else (0.0 if j else None),
                       "ci95": [0.1 + 0.1 * i + j, 0.3 + 0.1 * i + j] if i < 3 else ([0.0, 0.0] if j else [None, None])}
                   for j, m in enumerate(metrics)} for i, c in enumerate(names)}
    doc = {"experiment": "detector_eval", "n_trials": 40, "conditions": {c: [] for c in names},
           "results": results, "metrics": metrics}
    comparison_figure(doc, tmp_path / "metrics.png", width="column")
    (saved, width, sizes) = sized[-1]
    assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, sizes[:3]
    assert_readable([saved])
    assert {"n/a", "0 (n=4)", "n=4"} <= set(saved.texts) and saved.xticks[0] == names
    comparison_figure(doc, tmp_path / "page.png")                       # the page's: 3 panels a row, 5.5 pt marks
    assert sized[-1][1] == 2.3 * 3 and min(pt for _, pt in print_sizes_at_own(sized[-1])) == 5.5


def print_sizes_at_own(entry):
    """A saved figure's text sizes at its own width (``sized`` holds them at 3.5 in)."""
    _, width, sizes = entry
    return [(t, pt * width / 3.5) for t, pt in sizes]


def test_report_width_that_is_neither_page_nor_column_is_one_error_line(tmp_path):
    (tmp_path / "sweep" / "0").mkdir(parents=True)
    (tmp_path / "sweep" / "0" / "results.json").write_text("{}")
    r = laughlab("report", tmp_path / "sweep", "--width", "a4")
    assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1 and "invalid choice: 'a4'" in r.stderr
    assert r.stderr.startswith("laughlab: error: ") and not (tmp_path / "sweep" / "report").exists()


def test_a_sweeps_heatmaps_and_line_plots_in_a_column_print_every_text_at_7_pt_or_more(tmp_path, sized):
    """``report --width column`` on a sweep: the heatmaps one a row, the line plots two, 3.5 in wide, long metric
    names broken after an underscore, the line plots' value labels on two lines."""
    from laughlab.harness.sweep_figures import heatmaps, lines

    info = {"intensity_r_clip": {"higher_is_better": True, "units": "Pearson r"},
            "onset_latency_median_s": {"higher_is_better": False, "units": "s"},
            "false_starts_per_min_speech": {"higher_is_better": False, "units": "per min"}}
    points = [{"params": {"scheduler.overrule_c": a, "scheduler.decrease_per_s": b},
               "r": {m: {"mean": 0.3 + 0.1 * i + 0.05 * j + 0.2 * k, "n": 4,
                         "ci95": [0.25 + 0.1 * i + 0.05 * j + 0.2 * k, 0.35 + 0.1 * i + 0.05 * j + 0.2 * k]}
                     for k, m in enumerate(info)}}
              for i, a in enumerate(("1.5", "3", "6")) for j, b in enumerate(("6", "20"))]
    title = "energy_ablation sweep: each point the mean of 8 trials (profiles intense, mild; seeds 0, 1)"
    heatmaps(points, "scheduler.overrule_c", "scheduler.decrease_per_s", list(info), lambda p, m: p["r"][m],
             tmp_path / "heatmap.png", info, title, "column")
    lines([p for p in points if p["params"]["scheduler.decrease_per_s"] == "6"], "scheduler.overrule_c", list(info),
          lambda p, m: p["r"][m], tmp_path / "line.png", info, title, "column")
    assert len(sized) == 2
    for saved, width, sizes in sized:
        assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, (saved.name, sizes[:3])
    assert_readable([s for s, _, _ in sized])
    heat, line = (s for s, _, _ in sized)
    assert heat.n_colorbars == 3 and "onset_latency_\nmedian_s ↓" in line.titles
    assert "Pearson r\n(higher is better)" in line.texts


def test_the_hill_fits_fig10_in_a_column_names_every_calls_error_at_7_pt_or_more(tmp_path, sized):
    """experiment=hill_fit draws fig10_pressure.png at the run's output.plots.width: 25 short calls' errors (0.17 s
    apart, 0.1 in in a column) in 3 staggered rows, none overprinted, and its PDF keeps TrueType."""
    from types import SimpleNamespace

    from laughlab_experiments.hill_fit import figure_10

    n = 25
    calls = [SimpleNamespace(call=SimpleNamespace(start=30 + 10 * k, end=37 + 10 * k), error=0.3 - 0.01 * k)
             for k in range(n)]
    t = np.arange(30 + 10 * n + 60)
    target = np.maximum(np.sin(2 * np.pi * t / 10), 0) * 0.1
    res = SimpleNamespace(calls=calls, fps=60, target=target, simulated=target * 1.1)
    figure_10(tmp_path / "fig10_pressure.png", res, width="column", pdf=True)
    (saved, width, sizes) = sized[-1]
    assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, sizes[:3]
    assert_readable([saved])
    errors = [f"{c.error:.2f}" for c in calls]
    assert all(saved.texts.count(e) >= errors.count(e) for e in errors)    # every call's error is written
    pdf = (tmp_path / "fig10_pressure.pdf").read_bytes()
    assert b"/Type3" not in pdf and b"/FontFile2" in pdf


def test_the_hill_fits_fig7_in_a_column_stacks_its_calls_at_7_pt_or_more(tmp_path, sized):
    """experiment=hill_fit's fig7_optimisers.png had no column layout (5.2 in a call side by side: 10.4 in for two,
    its legends 7 pt there, 2.4 pt at 3.5 in) and no PDF. In a column: 3.5 in, a call a row, each call's legend under
    its panel naming every optimiser's error and time, every text at 7 pt or more, and its PDF with TrueType."""
    from laughlab_experiments.hill_fit import figure_7

    rng = np.random.default_rng(3)
    methods = {"nelder-mead": 400, "annealing": 1900, "pds": 900, "cma": 1200}
    comparison = {}
    for call in range(2):
        runs = {}
        for j, (m, n) in enumerate(methods.items()):
            h = np.minimum.accumulate(np.exp(-5 * np.arange(n) / n) + 0.2 * rng.random(n))
            runs[m] = {"history": list(h), "error": float(h[-1]), "seconds": 0.1 + 0.01 * j + call}
        comparison[f"call {call} ({call}.10-{call}.30 s)"] = {"methods": runs}
    figure_7(tmp_path / "page" / "fig7_optimisers.png", comparison)
    figure_7(tmp_path / "column" / "fig7_optimisers.png", comparison, width="column", pdf=True)
    (_, page_w, page_sizes), (saved, width, sizes) = sized[-2:]
    assert page_w == 10.4 and page_sizes[0][1] < COLUMN_MIN_PT          # the page one shrunk: under 7 pt
    assert not (tmp_path / "page" / "fig7_optimisers.pdf").exists()     # output.plots.pdf false: none
    assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, sizes[:3]
    assert_readable([saved])
    for label, runs in comparison.items():
        assert label in saved.titles
        for r in runs["methods"].values():
            assert any(t.endswith(f": {r['error']:.2f} in {r['seconds']:.2f} s") for t in saved.texts)
    pdf = (tmp_path / "column" / "fig7_optimisers.pdf").read_bytes()
    assert b"/Type3" not in pdf and b"/FontFile2" in pdf


def test_an_experiment_with_output_plots_width_column_runs_its_trials_and_draws_metrics_for_a_column(tmp_path):
    """output.plots.width on an experiment's command line reached its trials, whose output=trial has no plots:
    'unknown parameter output.plots.width' before any trial ran. Now the trials leave it out and metrics.png is
    drawn 3.5 in wide (455 px at 130 dpi)."""
    from PIL import Image
    from omegaconf import OmegaConf

    from laughlab.core.config import compose_config
    from laughlab.harness.experiment import run_experiment

    overrides = ["experiment=smoke", "output.plots.width=column"]
    cfg = compose_config(overrides)
    h = OmegaConf.to_container(cfg.harness)
    h.update(jobs=1, showcase=None, plots=True, corpus={**h["corpus"], "profiles": ["intense"], "seeds": 1,
                                                        "duration_s": 3.0})
    h["corpus"].pop("real", None)
    cfg.harness = OmegaConf.create(h)
    doc = run_experiment(cfg, tmp_path, base_overrides=overrides[1:], progress=False)
    assert doc["n_trials"] == 2
    assert Image.open(tmp_path / "plots" / "metrics.png").size[0] == 455


def test_detector_pr_in_a_column_prints_every_text_at_7_pt_or_more(tmp_path, sized):
    """detector_eval's detector_pr.png at the run's output.plots.width: 3.5 in, the legend in one column."""
    from laughlab_experiments.detector_eval import SCORES, pr_figure

    rng = np.random.default_rng(0)
    y = rng.random(2000) < 0.2
    fig, out = pr_figure({name: y * rng.random(2000) + rng.random(2000) for name in SCORES}, y, width="column")
    fig.savefig(tmp_path / "detector_pr.png")
    (saved, width, sizes) = sized[-1]
    assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, sizes[:3]
    assert_readable([saved])
    assert all(any(t.startswith(f"{name}: AP ") for t in saved.texts) for name in SCORES)


def test_the_study_figures_in_a_column_print_every_text_at_7_pt_or_more(tmp_path, sized):
    """``study analyze --width column``: one panel a row, 3.5 in, long condition names broken after an underscore,
    a CI past the axis' end marked and its bound written (7 pt)."""
    import pandas as pd

    from laughlab.study.plots import means_plot, participant_lines

    conditions = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    rng = np.random.default_rng(0)
    tidy = pd.DataFrame([dict(participant=p, condition=c, question=q, value=int(rng.integers(1, 8)))
                         for p in range(6) for c in conditions for q in ("naturalness", "body_sound_match")])
    means = tidy.groupby(["question", "condition"], as_index=False)["value"].mean().rename(columns={"value": "mean"})
    means["ci_low"], means["ci_high"] = means["mean"] - 0.8, means["mean"] + 0.8
    means.loc[0, "ci_high"] = 9.0                                       # past the 7-point scale's end
    design = {"scale": "likert", "points": 7, "questions": [
        {"id": "naturalness", "prompt": "How natural was it?"},
        {"id": "body_sound_match", "prompt": "How well did the body match the sound?"}]}
    questions = ["naturalness", "body_sound_match"]
    means_plot(tmp_path / "fig_means.png", means, tidy, questions, conditions, design, width="column")
    participant_lines(tmp_path / "fig_participants.png", tidy, means, questions, conditions, design, width="column")
    pngs = [entry for entry in sized if entry[0].name.endswith(".png")]
    assert len(pngs) == 2
    for saved, width, sizes in pngs:
        assert width == 3.5 and sizes[0][1] >= COLUMN_MIN_PT, (saved.name, sizes[:3])
        assert ["smile_\nonly", "face_\nbreathing", "laugh_\nenergy", "laugh_\nconcat"] in saved.xticks
    assert_readable([s for s, _, _ in pngs])
    assert "9.00" in pngs[0][0].texts
