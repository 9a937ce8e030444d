"""Experiment ``hill_fit``: audio-driven optimisation of the Hill-muscle torso (DiLorenzo et al. 2008, 6.2).

``python -m laughlab experiment=hill_fit`` (``conf/experiment/hill_fit.yaml``).
:func:`run` replaces the trial harness (the CLI calls it when the module of
``harness.module`` defines it):

1. The run's input (``input=...``, synthetic by default, or ``input=file
   input.path=...``) goes through the ``pressure`` extractor: the target lung
   pressure, one value per frame.
2. :func:`laughlab.hill.fit.fit` cuts it into calls (found in the frame RMS,
   ``harness.fit.segment``) and fits each call's seven parameters in turn
   (``harness.fit``); the printed line and ``hill_fit.json`` give the calls
   found against the annotated ones (the synthetic truth, ``NAME.txt`` or
   ``NAME.TextGrid`` beside a file, or the real corpus' bundled annotation),
   the median error and the seconds and evaluations per fitted call.
3. The fitted activations drive the ``hill`` body (:meth:`HillBody.play`) in an
   ordinary run of the pipeline: ``channels.csv``, ``events.csv``,
   ``motion.bvh``, ``metrics.json`` and ``plots/`` as any run writes.
4. ``plots/fig10_pressure.png``: target and simulated pressure over the bout
   with the most calls (the paper's Fig. 10).
5. ``plots/fig7_optimisers.png``: running best error against evaluations of the
   optimisers of ``harness.compare`` on the same calls (the paper's Fig. 7).
   Both figures are drawn at the run's ``output.plots.width`` (``page`` or
   ``column``), with a PDF beside them when ``output.plots.pdf=true``.
6. With synthetic input, the inputs of ``harness.corpus`` are fitted too.
   ``calls.csv`` (one row per call: input, times, error, evaluations, seconds,
   parameters) and ``hill_fit.json`` (summaries per input and overall, the
   comparison, the configuration, versions, git hash) hold the numbers.
"""
from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

PAPER = {"simplex": {"error": 0.18, "evals": 400}, "annealing": {"error": 0.16, "evals": 1800},
         "seconds_per_call": 3600.0, "call_s": 0.2}


def extract_target(cfg) -> tuple[np.ndarray, float, object, np.ndarray]:
    """Run the configured source and extractor; return the ``pressure`` per frame, the fps, the source's truth
    and the frame RMS (``rms``, full scale: where the calls are cut)."""
    from laughlab.core import pipeline
    from laughlab.core.errors import LaughlabError
    from laughlab.core.frame import Frame

    pipe = pipeline.build(cfg)
    dt = pipe.ctx.dt
    out, level = [], []
    try:
        pipe.extractor.reset()
        for k, block in enumerate(pipe.source.blocks()):
            frame = Frame(k, k * dt, dt, {}, None, {}, {}, [], 0.0)
            pipe.extractor.step(block, frame)
            if "pressure" not in frame.control:
                raise LaughlabError(f"experiment hill_fit needs extractor=pressure (got {pipe.extractor.name})")
            out.append(frame.control["pressure"])
            level.append(frame.control.get("rms", 0.0))
    finally:
        pipe.source.close()
    return np.array(out), float(pipe.ctx.fps), pipe.source.truth, np.array(level)


def annotated_calls(cfg, truth) -> int | None:
    """How many calls the input holds by its annotation: the synthetic truth's calls; for a file, the
    labels beside it (``NAME.txt`` or ``NAME.TextGrid``) or, for a file of the real corpus, its bundled
    annotation; None when there is none."""
    calls = getattr(truth, "calls", None)
    if calls is not None:
        return int(len(calls))
    if cfg.input.name != "file":
        return None
    from laughlab.corpora import annotations, fetch

    path = Path(str(cfg.input.path)).resolve()
    for side in (path.with_suffix(".txt"), path.with_suffix(".TextGrid")):
        if side.exists():
            return len(annotations.read(side).calls)
    try:
        iid = path.relative_to((fetch.corpus_dir() / "files").resolve()).with_suffix("").as_posix()
    except ValueError:
        return None
    ann = annotations.bundled(iid)
    return None if ann is None else len(ann.calls)


def fit_params(cfg):
    """FitParams from ``harness.fit`` with the secondary motion of ``body.track``."""
    from laughlab.hill.fit import FitParams

    values = dict(OmegaConf.to_container(cfg.harness.get("fit") or {}, resolve=True))
    track = cfg.body.get("track") or {}
    values.setdefault("clavicle_ratio", float(track.get("clavicle_ratio", 1.0)))
    values.setdefault("spine_deg", float(track.get("spine_deg", 30.0)))
    values.setdefault("substep_hz", float(cfg.body.get("substep_hz", 240.0)))
    return FitParams(**values)


def torso_params(cfg):
    """The body's TorsoParams (validated by the plugin's Params)."""
    from laughlab.core import plugins

    info = plugins.get("body", cfg.body.name)
    return plugins.make_params(info.obj, cfg.body, "body.hill").torso


def _rows(name: str, res) -> list[dict]:
    from laughlab.hill.fit import PARAMS

    rows = []
    for i, cf in enumerate(res.calls):
        row = {"input": name, "call": i, "start_s": cf.call.start / res.fps, "end_s": cf.call.end / res.fps,
               "duration_s": (cf.call.end - cf.call.start) / res.fps, "driven": int(cf.driven),
               "error": cf.error, "evals": cf.evals,
               "seconds": cf.seconds}
        row.update({p: float(v) for p, v in zip(PARAMS, cf.x)})
        rows.append(row)
    return rows


def _bouts(res, gap_frames: int) -> list[list[int]]:
    """Runs of consecutive calls (a call starting where the previous ended, or within ``gap_frames``)."""
    runs: list[list[int]] = []
    for i, cf in enumerate(res.calls):
        if runs and cf.call.start - res.calls[runs[-1][-1]].call.end <= gap_frames:
            runs[-1].append(i)
        else:
            runs.append([i])
    return runs


def _bout_span(res, bout) -> tuple[int, int, np.ndarray, float]:
    """Fig. 10's frames (from 0.2 s before the bout to 0.3 s after), their times (s) and the highest pressure."""
    f0 = max(0, res.calls[bout[0]].call.start - int(0.2 * res.fps))
    f1 = min(len(res.target), res.calls[bout[-1]].call.end + int(0.3 * res.fps))
    top = max(float(res.target[f0:f1].max()), float(res.simulated[f0:f1].max()), 1e-6)
    return f0, f1, (np.arange(f0, f1) + 1) / res.fps, top


def figure_10(path: Path, res, truth=None, width: str = "page", pdf: bool = False) -> dict:
    """Target (blue) and simulated (red) pressure over the bout with the most calls, as the paper's Fig. 10.

    ``width``: ``page`` (10 in) or ``column`` (3.5 in, every text at 7 pt or more: :func:`_figure_10_column`), as
    the run's ``output.plots.width``; ``pdf``: a vector PDF beside the PNG, as ``output.plots.pdf``."""
    from laughlab.render.layout import drawing, layout_of
    from laughlab.render.savefig import new_figure, save_figure

    runs = _bouts(res, int(0.05 * res.fps))
    bout = max(runs, key=len) if runs else []
    path.parent.mkdir(parents=True, exist_ok=True)
    if layout_of(width).column:
        with drawing(layout_of(width)):
            _figure_10_column(path, res, bout, pdf)
        return {"calls": bout, "start_s": res.calls[bout[0]].call.start / res.fps if bout else None}
    fig, ax = new_figure(figsize=(10, 4))
    if bout:
        f0, f1, t, top = _bout_span(res, bout)
        ax.plot(t, res.target[f0:f1], color="tab:blue", lw=1.8, label="target (from audio)")
        ax.plot(t, res.simulated[f0:f1], color="tab:red", lw=1.8, ls="--",   # dashed: red is as light as blue
                label="simulated (fitted activations)")
        for k, i in enumerate(bout):
            cf = res.calls[i]
            ax.axvline(cf.call.start / res.fps, color="0.75", lw=0.8, zorder=0)
            # every other label a row higher: neighbouring short calls' labels would run into each other
            ax.text((cf.call.start + cf.call.end) / 2 / res.fps, (1.04 + 0.07 * (k % 2)) * top, f"{cf.error:.2f}",
                    ha="center", fontsize=6.5, color="0.3")
        ax.axvline(res.calls[bout[-1]].call.end / res.fps, color="0.75", lw=0.8, zorder=0)
        errs = [res.calls[i].error for i in bout]
        ax.set_title(f"Fig. 10 style: a {len(bout)}-call bout; per-call normalised RMS error above "
                     f"(mean {np.nanmean(errs):.2f})", fontsize=10)
        ax.set_ylim(min(float(res.simulated[f0:f1].min()), 0.0) * 1.1, 1.2 * top)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("lung pressure (cm H$_2$O, gauge)")
    # below the axes, not over the error labels along the top
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    save_figure(fig, path, pdf, dpi=120)
    return {"calls": bout, "start_s": res.calls[bout[0]].call.start / res.fps if bout else None}


#: rows of the per-call errors over a column's Fig. 10 (3.5 in: a call of 0.17 s is 0.1 in, a label 0.25 in)
COLUMN_ERROR_ROWS = 3


def _figure_10_column(path: Path, res, bout: list, pdf: bool) -> None:
    """Fig. 10 3.5 in wide: text 7-8 pt, the per-call errors in :data:`COLUMN_ERROR_ROWS` staggered rows above the
    curves (the value axis made tall enough for them once the layout is known), the legend under the axes."""
    from laughlab.render.labels import layout_now
    from laughlab.render.layout import COLUMN, thin_ticks, wrapped
    from laughlab.render.savefig import new_figure, save_figure

    fig, ax = new_figure(figsize=(COLUMN.width_in, 2.8), dpi=150, layout="constrained")
    title = "Fig. 10 style: no call found"
    if bout:
        f0, f1, t, top = _bout_span(res, bout)
        ax.plot(t, res.target[f0:f1], color="tab:blue", lw=1.4, label="target (from audio)")
        ax.plot(t, res.simulated[f0:f1], color="tab:red", lw=1.4, ls="--", label="simulated (fitted)")
        for i in bout:
            ax.axvline(res.calls[i].call.start / res.fps, color="0.75", lw=0.6, zorder=0)
        ax.axvline(res.calls[bout[-1]].call.end / res.fps, color="0.75", lw=0.6, zorder=0)
        errs = [res.calls[i].error for i in bout]
        title = f"Fig. 10 style: a {len(bout)}-call bout; each call's normalised RMS error above (mean " \
                f"{np.nanmean(errs):.2f})"
        bottom = min(float(res.simulated[f0:f1].min()), 0.0) * 1.1
        ax.set_ylim(bottom, top)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("pressure (cm H$_2$O)")
    thin_ticks(ax, x=6, y=4)
    ax.set_title(wrapped(title, COLUMN.width_in, COLUMN.title), fontsize=COLUMN.title)
    fig.legend(loc="outside lower center", ncols=2, fontsize=COLUMN.legend, frameon=False)
    if bout:
        renderer = layout_now(fig)
        height_pt = ax.get_window_extent(renderer).height * 72 / fig.dpi
        room = 4 + 9.0 * COLUMN_ERROR_ROWS          # points above the highest pressure for the rows of errors
        ax.set_ylim(bottom, top + room / max(height_pt - room, 1.0) * (top - bottom))
        for k, i in enumerate(bout):
            cf = res.calls[i]
            ax.annotate(f"{cf.error:.2f}", ((cf.call.start + cf.call.end) / 2 / res.fps, top),
                        xytext=(0, 3 + 9.0 * (k % COLUMN_ERROR_ROWS)), textcoords="offset points", ha="center",
                        va="bottom", fontsize=7, color="0.3", annotation_clip=False).set_in_layout(False)
    save_figure(fig, path, pdf)


def figure_7(path: Path, comparison: dict, width: str = "page", pdf: bool = False) -> None:
    """Running best error against evaluations, one panel per call (the paper's Fig. 7), saved to ``path``.

    ``width``: ``page`` (5.2 in a call, side by side) or ``column`` (3.5 in, the calls stacked, every text at 7 pt
    or more), as the run's ``output.plots.width``; ``pdf``: a vector PDF beside the PNG, as ``output.plots.pdf``
    (it had neither: a page figure only, PNG only)."""
    from laughlab.render.layout import drawing, layout_of
    from laughlab.render.savefig import save_figure

    layout = layout_of(width)
    with drawing(layout):
        fig = figure_7_drawn(comparison, layout.column)
        path.parent.mkdir(parents=True, exist_ok=True)
        save_figure(fig, path, pdf, dpi=120 if not layout.column else None)


#: Fig. 7's optimisers: colour, line style (each its own: two were solid and as light as each other) and name
OPTIMISERS = {"nelder-mead": ("tab:green", "-", "simplex (Nelder-Mead)"),
              "annealing": ("tab:orange", "--", "simulated annealing (dual_annealing)"),
              "pds": ("tab:blue", "-.", "parallel direct search (batched)"),
              "cma": ("tab:purple", ":", "CMA-ES (batched)")}
#: their names in a column's legend (3.5 in)
COLUMN_NAMES = {"annealing": "simulated annealing"}


def figure_7_drawn(comparison: dict, column: bool = False):
    """The figure of :func:`figure_7`.  Each optimiser has a line style of its own as well as a hue: the blue and
    purple lines were both solid and within 15 CIE L* of each other, one line in a greyscale print (the figures
    review's check, ``laughlab.render.labels.lines_told_apart_by_hue``, had not run on this one).

    ``column``: 3.5 in wide, one call a row (2.7 in each), text 7-8 pt (:data:`laughlab.render.layout.COLUMN`:
    draw it under :func:`laughlab.render.layout.drawing`), each call's legend under its panel in one column."""
    from laughlab.render.layout import COLUMN, wrapped
    from laughlab.render.savefig import new_figure

    n = max(len(comparison), 1)
    if column:   # a sub-figure a call, its legend under it: the layout makes room for both
        fig, _ = new_figure(0, figsize=(COLUMN.width_in, 2.7 * n + 0.3), dpi=150, layout="constrained")
        axes = [sf.subplots() for sf in np.atleast_1d(fig.subfigures(n, 1))]
    else:
        fig, axes = new_figure(1, n, figsize=(5.2 * n, 5.2), squeeze=False, layout="constrained")
        axes = axes[0]
    for ax, (label, runs) in zip(axes, comparison.items()):
        for method, r in runs["methods"].items():
            colour, style, name = OPTIMISERS.get(method, (None, "-", method))
            h = np.asarray(r["history"], dtype=float)
            ax.plot(np.arange(1, len(h) + 1), h, color=colour, ls=style, lw=1.2 if column else 1.6,
                    label=f"{COLUMN_NAMES.get(method, name) if column else name}: {r['error']:.2f} in "
                          f"{r['seconds']:.2f} s")
        # the paper's "simplex" is OPT++'s parallel direct search (DiLorenzo et al. 2008, 6.2), laughlab's pds: its
        # colour, not Nelder-Mead's (a sweep researcher's review)
        ax.plot([PAPER["simplex"]["evals"]], [PAPER["simplex"]["error"]], "s", color=OPTIMISERS["pds"][0],
                ms=5 if column else 7, mfc="none", label="paper: simplex (parallel direct search) 0.18 @ ~400")
        ax.plot([PAPER["annealing"]["evals"]], [PAPER["annealing"]["error"]], "o", color="tab:orange",
                ms=5 if column else 7, mfc="none", label="paper: annealing 0.16 @ ~1800")
        ax.set_xscale("log")
        ax.set_xlabel("evaluations")
        ax.set_ylabel("best normalised RMS error" if not column else "best norm. RMS error")
        ax.set_title(label, fontsize=COLUMN.panel_title if column else 10)
        # every optimiser's best error inside the axes (a new-user review: Nelder-Mead's 1.62 was above 1.2, its
        # curve not drawn at all, only its legend entry)
        ax.set_ylim(0, max(1.2, 1.1 * max(float(r["error"]) for r in runs["methods"].values())))
        ax.grid(alpha=0.3)
        if column:
            ax.figure.legend(loc="outside lower center", ncols=1, fontsize=COLUMN.legend, frameon=False)
        else:   # under the panel: in its corner it hid the start of the descents (a review)
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)
    title = "Fig. 7 style: running best error of one call's optimisation"
    if column:
        fig.suptitle(wrapped(title, COLUMN.width_in, COLUMN.title), fontsize=COLUMN.title)
    else:
        fig.suptitle(title, fontsize=11)
    return fig


def compare(target, fps: float, res, fp, tp, spec: dict) -> dict:
    """Fig. 7's comparison on ``spec['calls']`` calls spread over the first bout (same start state per call)."""
    from laughlab.hill.fit import compare_methods

    n = int(spec.get("calls", 2))
    runs = _bouts(res, int(0.05 * fps))
    bout = max(runs, key=len) if runs else []
    picks = [bout[int(round(j * (len(bout) - 1) / max(n - 1, 1)))] for j in range(n)] if len(bout) >= n else bout
    out = {}
    for i in dict.fromkeys(picks):
        cf = res.calls[i]
        methods = compare_methods(target, fps, i, methods=tuple(spec.get("methods") or ("nelder-mead", "annealing")),
                                  max_evals=int(spec.get("max_evals", 2000)), fit_params=fp, torso_params=tp,
                                  prior=res)
        out[f"call {i} ({cf.call.start / fps:.2f}-{cf.call.end / fps:.2f} s)"] = {
            "call": i, "start_s": cf.call.start / fps, "end_s": cf.call.end / fps, "methods": methods}
    return out


def _corpus_inputs(cfg) -> list:
    """Corpus items fitted for the statistics: with synthetic input, the profiles x seeds of
    ``harness.corpus`` plus its folder; with a recording, only the recording."""
    from laughlab.harness.corpus import build_corpus

    if cfg.input.name != "synthetic":
        return []
    spec = OmegaConf.to_container(cfg.harness.get("corpus") or {}, resolve=True)
    if not spec.get("profiles") and not spec.get("folder"):
        return []
    return build_corpus(spec)


def run(cfg, out_dir) -> dict:
    """Fit the run's input (and the corpus), animate it, write the figures and the numbers."""
    from laughlab.core import pipeline
    from laughlab.harness import results as res_mod
    from laughlab.harness.runner import _compose
    from laughlab.hill.fit import fit

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fp, tp = fit_params(cfg), torso_params(cfg)
    t0 = time.perf_counter()
    target, fps, truth, level = extract_target(cfg)
    result = fit(target, fps, fp, tp, level=level)
    name = "input" if cfg.input.name != "file" else Path(str(cfg.input.path)).name
    summaries = {name: result.summary()}
    rows = _rows(name, result)
    # the animation: an ordinary run whose hill body plays the fitted activations
    pipe = pipeline.build(cfg)
    if pipe.body.name != "hill":
        from laughlab.core.errors import LaughlabError

        raise LaughlabError("experiment hill_fit needs body=hill")
    pipe.body.play(result.schedule)
    metrics = pipeline.execute(pipe, out_dir, OmegaConf.to_container(cfg, resolve=True))
    fig10 = figure_10(out_dir / "plots" / "fig10_pressure.png", result, truth,   # as the run's own figures
                      width=OmegaConf.select(cfg, "output.plots.width", default="page"),
                      pdf=bool(OmegaConf.select(cfg, "output.plots.pdf", default=False)))
    comparison = compare(target, fps, result, fp, tp, OmegaConf.to_container(cfg.harness.get("compare") or {},
                                                                             resolve=True))
    if comparison:
        figure_7(out_dir / "plots" / "fig7_optimisers.png", comparison,
                 width=OmegaConf.select(cfg, "output.plots.width", default="page"),
                 pdf=bool(OmegaConf.select(cfg, "output.plots.pdf", default=False)))
    # the corpus
    base = [f"extractor.{k}={v}" for k, v in OmegaConf.to_container(cfg.extractor, resolve=True).items()
            if k != "name" and not isinstance(v, (dict, list))]
    for item in _corpus_inputs(cfg):
        sub = _compose(["extractor=pressure", "body=hill", *base, *item.overrides])
        tgt, f, _, lev = extract_target(sub)
        r = fit(tgt, f, fp, tp, level=lev)
        summaries[item.id] = r.summary()
        rows += _rows(item.id, r)
    err = np.array([r["error"] for r in rows], dtype=float)
    fitted = [r for r in rows if r["driven"]]         # time and evaluations of the calls that were fitted
    secs = np.array([r["seconds"] for r in fitted], dtype=float)
    lens = np.array([r["duration_s"] for r in fitted], dtype=float)
    ok = np.isfinite(err)
    overall = {
        "calls": len(rows),
        "error_mean": float(err[ok].mean()) if ok.any() else None,
        "error_median": float(np.median(err[ok])) if ok.any() else None,
        "share_error_at_most_0.18": float((err[ok] <= 0.18).mean()) if ok.any() else None,
        "seconds_per_call_mean": float(secs.mean()) if len(secs) else None,
        "seconds_per_call_p90": float(np.percentile(secs, 90)) if len(secs) else None,
        "call_length_s_mean": float(lens.mean()) if len(lens) else None,
        "seconds_per_second_of_call": float(secs.sum() / lens.sum()) if lens.sum() > 0 else None,
        "seconds_per_call_median": float(np.median(secs)) if len(secs) else None,
        "evals_per_call_mean": float(np.mean([r["evals"] for r in fitted])) if fitted else None,
        "quiet_calls": len(rows) - len(fitted),
    }
    annotated = annotated_calls(cfg, truth)
    if annotated is not None:
        overall["input_calls_found"] = len(result.calls)
        overall["input_calls_annotated"] = annotated
    with open(out_dir / "calls.csv", "w", newline="", encoding="utf-8") as fh:
        if rows:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    doc = {
        "schema": "laughlab.hill.fit/1",
        "experiment": "hill_fit",
        "date": res_mod.now_iso(),
        "git_hash": res_mod.git_hash(),
        "git_diff_sha256": res_mod.git_diff_sha256(),
        "versions": res_mod.versions(),
        "config": OmegaConf.to_container(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]), resolve=True),
        "fit_params": dict(fp.__dict__),
        "paper": PAPER,
        "overall": overall,
        "inputs": summaries,
        "fig10": fig10,
        "comparison": {k: {**{kk: vv for kk, vv in v.items() if kk != "methods"},
                           "methods": {m: {kk: vv for kk, vv in r.items()} for m, r in v["methods"].items()}}
                       for k, v in comparison.items()},
        "animation_metrics": metrics,
        "wall_s": time.perf_counter() - t0,
    }
    res_mod.write_json(out_dir / "hill_fit.json", doc)
    found = (f" ({overall['input_calls_found']} found in the input, {overall['input_calls_annotated']} annotated)"
             if "input_calls_found" in overall else "")
    print(f"hill_fit: {overall['calls']} calls{found}, median error {overall['error_median']:.3f} "
          f"(mean {overall['error_mean']:.3f}), median {overall['seconds_per_call_median']:.3f} s and "
          f"{overall['evals_per_call_mean']:.0f} evaluations per call -> {out_dir / 'hill_fit.json'}")
    return doc
