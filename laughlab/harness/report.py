"""Reports: Markdown tables and figures from a results directory or a sweep directory.

``python -m laughlab report RUN_DIR [--out DIR]`` reads ``RUN_DIR/results.json``
(one experiment) or every ``*/results.json`` below ``RUN_DIR`` (a Hydra
multirun sweep) and writes ``RUN_DIR/report/README.md`` with its figures (``--out DIR``: into
``DIR``, e.g. ``--out reports/<experiment>`` for the reports committed with laughlab).
"""
from __future__ import annotations

import json
import os
import math
import shutil
from itertools import combinations
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from laughlab.core.errors import LaughlabError, shown_names  # noqa: E402
from laughlab.harness.results import separated  # noqa: E402

#: metrics shown first in tables and heatmaps
KEY_METRICS = ("intensity_r_clip", "intensity_r_kinetic", "onset_latency_median_s", "miss_rate",
               "silent_start_rate", "offset_tail_s", "cutoff_rate", "repetition_rate", "clip_entropy")


def _fmt(v, digits=3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    v = v + 0.0  # -0.0 (an entropy of nothing) shows as 0
    return f"{v:.{digits}g}" if abs(v) < 1000 else f"{v:.0f}"


def _arrow(hib) -> str:
    return {True: "↑", False: "↓"}.get(hib, "")


def _heading(metric: str, info: dict) -> str:
    """A metric's name with its better direction, as in the tables' first column: ``miss_rate ↓``."""
    return f"{metric} {_arrow(info['higher_is_better'])}".rstrip()


def conditions_of(doc: dict) -> list[str]:
    """The conditions of a results document in the experiment's order (its config), not alphabetical."""
    have = list(doc["results"])
    return [c for c in doc.get("conditions", {}) if c in have] + [c for c in have if c not in doc.get("conditions", {})]


def metric_order(doc: dict) -> list[str]:
    """The metrics of a results document, :data:`KEY_METRICS` first."""
    return [m for m in KEY_METRICS if m in doc["metrics"]] + [m for m in doc["metrics"] if m not in KEY_METRICS]


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def same_everywhere(doc: dict, metric: str) -> bool:
    """True when two or more conditions were compared and ``metric`` came out the same under each:
    the same number of trials, mean and 95 % CI (e.g. a detector metric when only the scheduler
    changes).  Such a metric says nothing about the conditions; the report lists it apart."""
    rs = [doc["results"][c][metric] for c in conditions_of(doc)]
    if len(rs) < 2 or not rs[0]["n"]:
        return False
    first = rs[0]
    return all(r["n"] == first["n"] and _same(r["mean"], first["mean"])
               and all(_same(x, y) for x, y in zip(r["ci95"], first["ci95"])) for r in rs[1:])


def comparison_figure(doc: dict, path: Path) -> Path:
    """One panel per metric that differs between the conditions: each condition's mean with its 95 % CI.

    Metrics the same under every condition (:func:`same_everywhere`) get no panel; a line under
    the panels names them.
    """
    conds = conditions_of(doc)
    measured = [m for m in metric_order(doc) if any(doc["results"][c][m]["n"] for c in conds)]
    names = [m for m in measured if not same_everywhere(doc, m)]
    same = [m for m in measured if same_everywhere(doc, m)]
    if not names:
        return path
    cols = min(5, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.3 * cols, 1.9 * rows + (0.4 if same else 0)), dpi=130,
                             squeeze=False, layout="constrained")
    colors = plt.get_cmap("tab10")
    # condition names wider than their slot under a panel (about 0.55 em a character at 7 pt) stand upright
    slot_in = 2.3 / max(len(conds), 1)
    upright = max(len(c) for c in conds) * 0.55 * 7 / 72 > 0.9 * slot_in
    for ax, name in zip(axes.flat, names):
        drawn = []
        for i, c in enumerate(conds):
            r = doc["results"][c][name]
            m = r["mean"] if r["mean"] is not None else np.nan
            lo, hi = (r["ci95"] if r["ci95"][0] is not None else (m, m))
            ax.bar(i, m, color=colors(i), width=0.7)
            ax.errorbar(i, m, yerr=[[m - lo], [hi - m]], color="k", capsize=3, lw=0.8)
            # a bar of 0 and no bar (the metric does not apply, e.g. no clip played) look alike: say which
            if not math.isfinite(m) or m == 0:
                ax.annotate("n/a" if not math.isfinite(m) else "0", (i, 0), xytext=(0, 2), textcoords="offset points",
                            ha="center", va="bottom", fontsize=6, color="0.35")
            drawn += [v for v in (m, lo, hi) if math.isfinite(v)]
        if drawn and not any(drawn):
            ax.set_ylim(0, 1)  # all 0: an axis from 0 (matplotlib's default for nothing is -0.04..0.04)
        info = doc["metrics"][name]
        ax.set_title(f"{name} {_arrow(info['higher_is_better'])}", fontsize=7)
        ax.set_xticks(range(len(conds)), conds, fontsize=7)
        if upright:
            ax.set_xticklabels(conds, rotation=90, fontsize=7)
        ax.tick_params(axis="y", labelsize=6)
        ax.set_ylabel(info["units"], fontsize=6)
        ax.spines[["top", "right"]].set_visible(False)
    for ax in axes.flat[len(names):]:
        ax.set_axis_off()
    fig.suptitle(f"{doc['experiment']}: mean and 95% CI (bootstrap) over {doc['n_trials']} trials "
                 "(↑ higher is better, ↓ lower is better)", fontsize=9)
    if same:
        import textwrap

        fig.supxlabel("\n".join(textwrap.wrap(
            f"Not shown, the same under every condition: {', '.join(same)} (values in the report's table).",
            int(2.3 * cols * 15))), fontsize=7, color="0.3")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def table_metrics(doc: dict) -> list[str]:
    """The metrics the results table shows: measured under some condition and not the same under all."""
    gone = set(unmeasured(doc))
    return [m for m in metric_order(doc) if m not in gone and not same_everywhere(doc, m)]


def _results_table(doc: dict) -> list[str]:
    """The metrics that differ between the conditions: one column per condition, the best in bold when
    its interval is apart from the others' (:func:`_clear_best`)."""
    conds = conditions_of(doc)
    lines = ["| metric | units | " + " | ".join(f"{c} mean [95% CI]" for c in conds) + " |",
             "|---|---|" + "---|" * len(conds)]
    for m in table_metrics(doc):
        info = doc["metrics"][m]
        best = _clear_best(doc, m, conds)
        cells = [f"**{_cell(doc['results'][c][m])}**" if c == best else _cell(doc["results"][c][m]) for c in conds]
        lines.append(f"| {_heading(m, info)} | {info['units']} | " + " | ".join(cells) + " |")
    return lines


def unmeasured(doc: dict) -> list[str]:
    """The metrics with no value under any condition (e.g. false starts on coughs when the corpus holds no
    cough): the report names them in one line instead of a row of n/a."""
    return [m for m in metric_order(doc) if not any(doc["results"][c][m]["n"] for c in conditions_of(doc))]


def _clear_best(doc: dict, metric: str, conds: list[str]) -> str | None:
    """The condition with the best mean of ``metric`` when its 95 % interval is apart from every other
    condition's (:func:`~laughlab.harness.results.separated`); None when the intervals overlap, the
    metric has no better direction, or fewer than two conditions have a value."""
    if doc["metrics"][metric]["higher_is_better"] is None:
        return None
    rs = {c: doc["results"][c][metric] for c in conds}
    have = [c for c, r in rs.items() if r["n"] and r["mean"] is not None and math.isfinite(r["mean"])
            and not _vacuous(doc, metric, c)]
    if len(have) < 2:
        return None
    sign = 1 if doc["metrics"][metric]["higher_is_better"] else -1
    best = max(have, key=lambda c: sign * rs[c]["mean"])
    return best if all(separated(rs[best], rs[c]) for c in have if c != best) else None


def played_no_clip(doc: dict, cond: str) -> bool:
    """True when no trial of ``cond`` played a clip (e.g. ``scheduler=none``): ``cutoff_rate``, a fraction
    of the played clips, has no value in any of its trials although other metrics have."""
    rs = doc["results"][cond]
    return "cutoff_rate" in rs and not rs["cutoff_rate"]["n"] and any(r["n"] for r in rs.values())


def _vacuous(doc: dict, metric: str, cond: str) -> bool:
    """A lower-is-better value of 0 under a condition that played no clip (an offset tail of no clip): not a
    best, so :func:`_clear_best` leaves it out."""
    r = doc["results"][cond][metric]
    return doc["metrics"][metric]["higher_is_better"] is False and r["mean"] == 0 and played_no_clip(doc, cond)


#: means of fewer trials say how many (``(n=4)``): their bootstrap interval is too narrow to be a 95 % one
FEW = 10


def _cell(r: dict) -> str:
    if not r["n"]:
        return "n/a"
    few = f" (n={r['n']})" if r["n"] < FEW else ""
    return f"{_fmt(r['mean'])} [{_fmt(r['ci95'][0])}, {_fmt(r['ci95'][1])}]{few}"


def _same_table(doc: dict) -> list[str]:
    """The metrics the same under every condition, once each (empty when there are none)."""
    same = [m for m in metric_order(doc) if same_everywhere(doc, m)]
    if not same:
        return []
    first = conditions_of(doc)[0]
    lines = ["These metrics came out the same under every condition (the same trials, mean and 95% CI), so "
             "they are left out of the table and the figure above:", "",
             "| metric | units | every condition: mean [95% CI] |", "|---|---|---|"]
    for m in same:
        info = doc["metrics"][m]
        lines.append(f"| {_heading(m, info)} | {info['units']} | {_cell(doc['results'][first][m])} |")
    return lines


def _profile_table(doc: dict, metric: str) -> list[str]:
    conds = [c for c in conditions_of(doc) if c in doc["by_profile"]]
    profiles = sorted({p for c in conds for p in doc["by_profile"][c]})
    lines = [f"| profile | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for p in profiles:
        lines.append(f"| {p} | " + " | ".join(_fmt(doc["by_profile"][c].get(p, {}).get(metric)) for c in conds) + " |")
    return lines


def _extra_lines(key: str, value) -> list[str]:
    """An experiment's extra numbers: scalars as a list, lists of records as a table."""
    if not isinstance(value, dict):
        return [f"- {key}: {_fmt(value) if isinstance(value, float) else value}", ""]
    lines = [f"### {key}", ""]
    tables = []
    for k, v in value.items():
        if isinstance(v, list) and v and isinstance(v[0], dict):
            tables.append((k, v))
        else:
            lines.append(f"- {k}: {_fmt(v) if isinstance(v, float) else v}")
    lines.append("")
    for k, rows in tables:
        cols = list(rows[0])
        lines += [f"{k}:", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        for r in rows:
            lines.append("| " + " | ".join(_fmt(r[c]) if isinstance(r[c], float) else str(r[c]) for c in cols) + " |")
        lines.append("")
    return lines


def experiment_report(run_dir: Path, out: Path, command: str) -> Path:
    doc = json.loads((run_dir / "results.json").read_text())
    figs = out / "figures"
    if figs.exists():
        shutil.rmtree(figs)
    figs.mkdir(parents=True)
    comparison_figure(doc, figs / "metrics.png")
    for png in sorted((run_dir / "plots").glob("*.png")) if (run_dir / "plots").is_dir() else []:
        if png.name != "metrics.png":
            shutil.copyfile(png, figs / png.name)
    lines = [f"# {doc['experiment']}", "",
             f"Generated by `{command}` from `{run_dir}`.",
             "", f"- date: {doc['date']}", f"- laughlab commit: `{doc['git_hash']}`",
             f"- trials: {doc['n_trials']} ({len(doc['corpus']['inputs'])} inputs x "
             f"{len(doc['conditions'])} conditions; profiles {', '.join(doc['corpus']['profiles'])}; "
             f"seeds {doc['corpus']['seeds'][0]}..{doc['corpus']['seeds'][-1]})",
             "- conditions: " + "; ".join(f"**{c}** `{' '.join(o)}`" for c, o in doc["conditions"].items()),
             *[f"- skipped corpus file (harness.corpus.on_bad=skip): `{s['file']}`: {s['reason']}"
               for s in doc["corpus"].get("skipped", [])],
             *([f"- **without the real recordings**: the real corpus was not fetched, so its sets "
                f"({', '.join(doc['corpus']['not_fetched'])}) were left out; `python -m laughlab corpus fetch` "
                "adds them"] if doc["corpus"].get("not_fetched") else []),
             "", "## Results", "",
             "Mean over trials with its 95% confidence interval (percentile bootstrap of the trials, "
             "seeded; it stays within the values' range). ↑ higher is better, ↓ lower is better; the best "
             "condition is in bold only where its interval does not overlap any other condition's (a "
             "conservative rule: no bold is not evidence of no difference). "
             f"The compute rows (frame_ms_*, realtime_factor) were measured with "
             f"{(doc.get('config', {}).get('harness') or {}).get('jobs', 1)} trial process(es) sharing the "
             "machine; `make bench` measures them alone.", ""]
    if any(0 < doc["results"][c][m]["n"] < FEW for m in table_metrics(doc) for c in conditions_of(doc)):
        # a bootstrap of a handful covers less
        lines[-1:-1] = ["", f"(n=K): a mean of fewer than {FEW} trials (e.g. the few inputs holding that kind of "
                        "sound); its bootstrap interval is narrower than a 95% interval should be: read it as the "
                        "spread of those trials."]
    lines += _results_table(doc)
    gone = unmeasured(doc)
    if gone:
        lines += ["", "No value under any condition (nothing in these inputs for them to measure): "
                  + ", ".join(f"`{m}`" for m in gone) + "."]
    lines += ["", "![metrics](figures/metrics.png)", ""]
    same = _same_table(doc)
    if same:
        lines += same + [""]
    shows = sorted(p.name for p in figs.glob("*_fig4_2_energy.png"))
    if shows:
        lines += ["## The same input under each condition", ""]
        for name in shows:
            lines += [f"**{name.split('_fig4_2')[0]}**", "", f"![{name}](figures/{name})", ""]
    thesis = sorted(p.name for p in figs.glob("*.png") if "_fig4_1" in p.name or "_fig3_1" in p.name)
    if thesis:
        lines += ["## How the energy is made (thesis Figs. 4.1 and 3.1) on the same input", "",
                  "Fig. 4.1: the MCS, its primitive (the energy if no clip consumed), the actual energy and the "
                  "clips. Fig. 3.1: the MCS with min/max amplitude fixed against drifting.", ""]
        for name in thesis:
            lines += [f"**{name.split('_fig')[0]}**", "", f"![{name}](figures/{name})", ""]
    others = sorted(p.name for p in figs.glob("*.png") if p.name != "metrics.png" and p.name not in shows
                    and p.name not in thesis and "fig3_2" not in p.name and "filmstrip" not in p.name)
    for name in others:
        lines += [f"![{name}](figures/{name})", ""]
    lines += ["## By profile", ""]
    for m in ("intensity_r_clip", "miss_rate", "silent_start_rate", "bouts_answered", "false_starts_per_min"):
        if m in doc["metrics"]:
            lines += [f"`{m}`", ""] + _profile_table(doc, m) + [""]
    if doc.get("extra"):
        lines += ["## Experiment-specific results", ""]
        for k, v in doc["extra"].items():
            lines += _extra_lines(k, v)
    lines += ["## Metrics", "", "| metric | units | definition |", "|---|---|---|"]
    for m, info in doc["metrics"].items():
        lines.append(f"| {m} | {info['units']} | {info['description']} |")
    (out / "README.md").write_text("\n".join(lines) + "\n")
    return out / "README.md"


def _sweep_points(root: Path) -> list[dict]:
    import yaml

    points = []
    for rj in sorted(root.rglob("results.json")):
        job = rj.parent
        ov_file = job / ".hydra" / "overrides.yaml"
        overrides = yaml.safe_load(ov_file.read_text()) if ov_file.exists() else []
        params = dict(o.split("=", 1) for o in overrides if "=" in o and not o.startswith(("experiment=", "hydra")))
        points.append({"dir": job, "params": params, "doc": json.loads(rj.read_text())})
    return points


def _num(v: str):
    try:
        return float(v)
    except ValueError:
        return v


def _order(v: str):
    """A sort key for a swept value: numbers by value, then words (a point without the parameter: "")."""
    x = _num(v)
    return (0, x, "") if isinstance(x, float) else (1, 0.0, x)


def sweep_report(root: Path, out: Path, command: str) -> Path:
    points = _sweep_points(root)
    experiments = sorted({p["doc"]["experiment"] for p in points})
    if len(experiments) > 1:
        raise LaughlabError(f"{root} holds the results of {len(experiments)} experiments ({', '.join(experiments)}); "
                            "report each sweep's folder on its own")
    keys = sorted({k for p in points for k in p["params"]})
    varying = [k for k in keys if len({p["params"].get(k) for p in points}) > 1]
    doc0 = points[0]["doc"]
    cond = list(doc0["results"])[0]
    metrics = [m for m in KEY_METRICS if m in doc0["metrics"]]
    figs = out / "figures"
    if figs.exists():
        shutil.rmtree(figs)
    figs.mkdir(parents=True)
    lines = [f"# {doc0['experiment']} (sweep)", "", f"Generated by `{command}` from `{root}`.", "",
             f"- sweep points: {len(points)}; swept: {', '.join(varying) or '(nothing)'}",
             f"- each point: {doc0['n_trials']} trials of condition **{cond}** "
             f"(profiles {', '.join(doc0['corpus']['profiles'])})", f"- laughlab commit: `{doc0['git_hash']}`", "",
             "## Every point", "", "One column per metric: its name, ↑ higher is better or ↓ lower is better, and "
             "(its units).", ""]
    info = doc0["metrics"]
    lines.append("| " + " | ".join(varying) + " | "
                 + " | ".join(f"{_heading(m, info[m])} ({info[m]['units']})" for m in metrics) + " |")
    lines.append("|" + "---|" * (len(varying) + len(metrics)))

    def val(p, m):
        r = p["doc"]["results"][cond][m]
        return r["mean"] if r["mean"] is not None else float("nan")

    for p in sorted(points, key=lambda p: [_order(p["params"].get(k, "")) for k in varying]):
        lines.append("| " + " | ".join(p["params"].get(k, "") for k in varying) + " | "
                     + " | ".join(_fmt(val(p, m)) for m in metrics) + " |")
    lines.append("")
    heat_metrics, flat = [], []
    for m in metrics:
        values = [v for v in (val(p, m) for p in points) if math.isfinite(v)]
        if not values:
            flat.append(f"`{m}` (no value at any point)")
        elif max(values) - min(values) <= 1e-12 * max(1.0, abs(max(values))):
            flat.append(f"`{m}` ({_fmt(values[0])} at every point)")
        else:
            heat_metrics.append(m)
    pairs = list(combinations(varying, 2))
    if pairs:
        lines += ["## Heatmaps", "", "Each cell: the metric's mean over the sweep points with those two values "
                  "(averaged over the other swept parameters). In every heatmap the bright (yellow) end is the "
                  "better one: each colour bar has its better end at the top and says so, so the bar of a "
                  "lower-is-better metric (↓) runs from high values at the bottom to low ones at the top.", ""]
    if (pairs or len(varying) == 1) and flat:
        lines += ["No figure for " + ", ".join(flat) + ": the sweep did not change it.", ""]
    for a, b in (pairs if heat_metrics else []):
        name = f"heatmap_{a}_{b}.png".replace("/", "_")
        _heatmaps(points, a, b, heat_metrics, val, figs / name, doc0["metrics"])
        lines += [f"![{a} x {b}](figures/{name})", ""]
    if len(varying) == 1 and heat_metrics:
        name = f"line_{varying[0]}.png"
        _lines(points, varying[0], heat_metrics, val, figs / name, doc0["metrics"])
        lines += [f"![{varying[0]}](figures/{name})", ""]
    (out / "README.md").write_text("\n".join(lines) + "\n")
    return out / "README.md"


def better_label(higher_is_better, units: str = "") -> str:
    """A colour bar's or value axis' label saying which way is better, under the values' ``units`` if given."""
    way = {True: "better ↑ (higher is better)", False: "better ↑ (lower is better)"}.get(
        higher_is_better, "neither end is better")
    return f"{units}\n{way}" if units else way


def _panel_grid(n: int, w: float, h: float, cols: int = 3):
    cols = max(1, min(cols, n))
    rows = max(1, math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(w * cols, h * rows), dpi=130, squeeze=False, layout="constrained")
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def _heatmaps(points, a, b, metrics, val, path, info) -> None:
    """One heatmap per metric over parameters ``a`` (x) and ``b`` (y); bright is better in each."""
    xs = sorted({p["params"].get(a, "") for p in points}, key=_order)
    ys = sorted({p["params"].get(b, "") for p in points}, key=_order)
    fig, axes = _panel_grid(len(metrics), 3.4, 2.7)
    for ax, m in zip(axes, metrics):
        grid = np.full((len(ys), len(xs)), np.nan)
        for i, y in enumerate(ys):
            for j, x in enumerate(xs):
                v = [val(p, m) for p in points if p["params"].get(a, "") == x and p["params"].get(b, "") == y]
                v = [u for u in v if math.isfinite(u)]
                grid[i, j] = np.mean(v) if v else np.nan
        hib = info[m]["higher_is_better"]
        # bright (yellow) is the better end: viridis runs dark to bright with the value, so flip it when lower is better
        im = ax.imshow(grid, origin="lower", cmap="viridis" if hib is not False else "viridis_r", aspect="auto")
        for i in range(len(ys)):
            for j in range(len(xs)):
                bright = np.mean(im.cmap(im.norm(grid[i, j]))[:3]) > 0.5
                ax.text(j, i, _fmt(grid[i, j], 2), ha="center", va="center", fontsize=6, color="k" if bright else "w")
        ax.set_xticks(range(len(xs)), xs, fontsize=7)
        ax.set_yticks(range(len(ys)), ys, fontsize=7)
        ax.set_xlabel(a, fontsize=7)
        ax.set_ylabel(b, fontsize=7)
        ax.set_title(f"{m} {_arrow(hib)}", fontsize=8)
        cb = fig.colorbar(im, ax=ax, shrink=0.9)
        if hib is False:
            cb.ax.invert_yaxis()  # the better (lower) end at the top, as on every other bar
        cb.set_label(better_label(hib, info[m]["units"]), fontsize=6.5)
        cb.ax.tick_params(labelsize=6)
    fig.savefig(path)
    plt.close(fig)


def _lines(points, a, metrics, val, path, info) -> None:
    """One panel per metric against the one swept parameter ``a``."""
    xs = sorted({p["params"].get(a, "") for p in points}, key=_order)
    fig, axes = _panel_grid(len(metrics), 3.0, 2.3)
    for ax, m in zip(axes, metrics):
        ys = [np.nanmean([val(p, m) for p in points if p["params"].get(a, "") == x]) for x in xs]
        ax.plot([_num(x) for x in xs], ys, "o-")
        ax.set_xlabel(a, fontsize=7)
        hib = info[m]["higher_is_better"]
        way = {True: " (higher is better)", False: " (lower is better)"}.get(hib, "")
        ax.set_ylabel(info[m]["units"] + way, fontsize=6)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{m} {_arrow(hib)}", fontsize=8)
        ax.spines[["top", "right"]].set_visible(False)
    fig.savefig(path)
    plt.close(fig)


def write_report(run_dir: str | Path, out: str | Path | None = None, command: str = "") -> Path:
    """Write the report of an experiment run or a sweep; return the README path.

    The report goes into ``out``, by default ``run_dir/report`` (beside the results it is made
    from, so that reporting never touches the committed ``reports/``).
    The report is written into a hidden sibling folder first and moved into place
    only when it is whole: a failure (a full disk, a bad figure) leaves the
    earlier report as it was, or no report.
    """
    root = Path(run_dir)
    if not root.exists():
        raise LaughlabError(f"{run_dir} not found")
    if (root / "results.json").exists():
        results, write = root / "results.json", experiment_report
    elif root.is_dir() and any(root.rglob("results.json")):
        results, write = next(root.rglob("results.json")), sweep_report
    else:
        raise LaughlabError(f"{run_dir} holds no results.json (run an experiment first)")
    json.loads(results.read_text())["experiment"]  # a results.json of an experiment, else a clear KeyError
    target = Path(out) if out else root / "report"
    if target.exists() and not target.is_dir():
        raise LaughlabError(f"report folder {target} exists and is not a folder")
    held = sorted(p.name for p in target.iterdir() if not p.name.startswith(".")) if target.is_dir() else []
    if held and not _is_a_report(target):
        raise LaughlabError(f"{target} holds files that are not a laughlab report ({shown_names(held)}); choose "
                            "another --out "
                            "(a report replaces only an earlier report)")
    staging = target.with_name(f".{target.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        write(root, staging, command or f"python -m laughlab report {run_dir}")
        target.mkdir(parents=True, exist_ok=True)
        for item in sorted(staging.iterdir()):
            old = target / item.name
            if old.is_dir():
                shutil.rmtree(old)
            os.replace(item, old)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    if target == root / "report":
        from laughlab.core import rundir

        rundir.record(root, "report")   # the run's own now: overwriting the run removes it with the rest
    return target / "README.md"


def _is_a_report(folder: Path) -> bool:
    """Does ``folder`` hold a report this command wrote (its README's third line says so)?"""
    try:
        with open(folder / "README.md", encoding="utf-8") as f:
            head = [next(f, "") for _ in range(3)]
    except (OSError, UnicodeDecodeError):
        return False
    return head[0].startswith("# ") and head[2].startswith("Generated by `")
