"""An experiment report's figure of its results, ``metrics.png`` (and ``timing.png``): one panel per metric that
differs between the conditions, each condition's mean with its 95 % CI; and what it reads of a results document
(the conditions in order, the metrics that differ).  :mod:`laughlab.harness.report` writes the report around it.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.ticker import MaxNLocator

from laughlab.harness.report_format import KEY_METRICS
from laughlab.harness.report_format import heading as _heading
from laughlab.render.savefig import new_figure, save_figure


#: means of fewer trials say how many (``(n=4)``): their bootstrap interval is too narrow to be a 95 % one
FEW = 10


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
    changes), or one constant value under every condition (every trial the same, so the CI is that
    value) whatever the number of trials (a review: detector_others drew a panel of zeros over n=3, 9
    and 253).  Such a metric says nothing about the conditions; the report lists it apart."""
    rs = [doc["results"][c][metric] for c in conditions_of(doc)]
    if len(rs) < 2 or not all(r["n"] for r in rs):
        return False
    first = rs[0]
    alike = all(_same(r["mean"], first["mean"]) and all(_same(x, y) for x, y in zip(r["ci95"], first["ci95"]))
                for r in rs[1:])
    constant = first["ci95"] is not None and all(_same(x, first["mean"]) for x in first["ci95"])
    return alike and (constant or all(r["n"] == first["n"] for r in rs[1:]))


def condition_colors(conds: list[str]) -> dict:
    """A colour per condition: ``none`` (no detector, no scheduler: the baseline) always grey, the others tab10's
    colours in their order, so the baseline reads alike in every report (a review: colours went by position)."""
    cmap = matplotlib.colormaps["tab10"]
    others = [c for c in conds if c != "none"]
    return {c: ("0.6" if c == "none" else cmap(others.index(c) % 10)) for c in conds}


#: metrics.png's sizes: a panel's width and height (in), panels a row, and font sizes (pt); ``chars``: title
#: characters an inch.  ``page`` as it always was (text 5.5-9 pt, up to 5 panels a row: 11.5 in); ``column``
#: 3.5 in wide for one column of a two-column paper, no text under 7 pt (``report --width column``)
SIZES = {"page": dict(w=2.3, h=1.9, cols=5, title=9, panel=7, names=7, yticks=6, units=6, note=7, zero=6,
                      few=5.5, chars=11),
         "column": dict(w=1.75, h=1.75, cols=2, title=8, panel=7.5, names=7, yticks=7, units=7, note=7, zero=7,
                        few=7, chars=13)}


def panel_title(text: str, width_in: float, fontsize: float) -> str:
    """A panel's title on lines that fit its width, broken after an underscore (metric names are long)."""
    fits = int(width_in * 72 / (0.6 * fontsize))
    out = ""
    while len(text) > fits and "_" in text[:fits]:
        cut = text.rindex("_", 0, fits) + 1
        out, text = out + text[:cut] + "\n", text[cut:]
    return out + text


def comparison_figure(doc: dict, path: Path, pdf: bool = False, timing: bool = False, width: str = "page",
                      panels: list[str] | None = None) -> Path:
    """One panel per metric that differs between the conditions: each condition's mean with its 95 % CI (``pdf``:
    a vector PDF beside the PNG, as a report writes it).  The compute-time metrics (:func:`is_compute`) are drawn
    only with ``timing`` (``timing.png``), and then alone: they differ run to run, so ``metrics.png`` without
    them gives the same bytes for the same seed (a review: it never did).

    Metrics the same under every condition (:func:`same_everywhere`) get no panel; a line under
    the panels names them.  ``width``: ``page`` (up to 5 panels a row) or ``column`` (3.5 in, 2 a row, every text
    at 7 pt or more: :data:`SIZES`).  ``panels``: only these metrics, in this order (``report --panels``: a
    column holds about 10 panels; :func:`laughlab.harness.report_format.check_panels` first).
    """
    from laughlab.render.layout import drawing, layout_of

    narrow = layout_of(width).column
    z = SIZES["column" if narrow else "page"]
    with drawing(layout_of(width)):
        return _comparison_figure(doc, path, pdf, timing, narrow, z, panels)


def _comparison_figure(doc: dict, path: Path, pdf: bool, timing: bool, narrow: bool, z: dict,
                       panels: list[str] | None = None) -> Path:
    conds = conditions_of(doc)
    measured = [m for m in (panels or metric_order(doc)) if any(doc["results"][c][m]["n"] for c in conds)
                and is_compute(m) == timing]
    same = [m for m in measured if same_everywhere(doc, m)]
    # a metric measured under one condition of several compares nothing: no panel, its value named under the
    # panels (a researcher's review: 3 of smoke's 5 panels were one "0 (n=2)" beside an "n/a"); --panels asked for
    alone = {m: [c for c in conds if doc["results"][c][m]["n"]] for m in measured} \
        if len(conds) > 1 and not panels else {}
    alone = {m: cs[0] for m, cs in alone.items() if len(cs) == 1}
    names = [m for m in measured if m not in same and m not in alone]
    if not names:
        return path
    cols = min(z["cols"], len(names))
    rows = math.ceil(len(names) / cols)
    # a column's figure is the column's width: one panel alone spans it (at 1.75 in its title ran to 9 lines)
    pw = z["w"] * z["cols"] / cols if narrow else z["w"]
    few = any(0 < doc["results"][c][m]["n"] < FEW for c in conds for m in names)
    # the title wrapped to the figure's width (about 11 characters an inch at 9 pt; two panels cut it off at both
    # ends), each line of it given its height
    per = max((doc["results"][c][m]["n"] for c in conds for m in names), default=0)  # a condition's trials
    title = textwrap.wrap(f"{doc['experiment']}: " + ("compute time, measured on this machine: differs run to run; "
                                                      if timing else "")
                          + (f"mean and 95% CI (bootstrap) over up to {per} trials per condition" if per > 1
                             else "the value of 1 trial per condition (no interval)")
                          + (f"; n=k over a bar: a mean of fewer than {FEW} trials" if few else "")
                          + " (↑ higher is better, ↓ lower is better)", int(pw * cols * z["chars"]))
    told = ([f"the same under every condition: {', '.join(same)}"] if same else []) + (
        ["measured under one condition only: " + ", ".join(
            f"{m} ({c}: {doc['results'][c][m]['mean']:.3g})" for m, c in alone.items())] if alone else [])
    note = textwrap.wrap(f"Not shown, {'; '.join(told)} (values in the report's table).",
                         int(pw * cols * 15)) if told else []
    # a column's note: many lines; a page's had room for two (a longer one with the one-condition metrics)
    below = (0.13 * len(note) + 0.1 if narrow else 0.4 + 0.13 * max(0, len(note) - 2)) if note else 0
    fig, axes = new_figure(rows, cols, figsize=(pw * cols, z["h"] * rows + below + 0.17 * (len(title) - 1)),
                             dpi=130, squeeze=False, layout="constrained")
    colors = condition_colors(conds)
    # condition names wider than their slot under a panel (about 0.55 em a character at 7 pt) stand upright
    slot_in = pw / max(len(conds), 1)
    upright = max(len(c) for c in conds) * 0.55 * z["names"] / 72 > 0.9 * slot_in
    for ax, name in zip(axes.flat, names):
        drawn = []
        for i, c in enumerate(conds):
            r = doc["results"][c][name]
            m = r["mean"] if r["mean"] is not None else np.nan
            lo, hi = (r["ci95"] if r["ci95"][0] is not None else (m, m))
            ax.bar(i, m, color=colors[c], width=0.7)
            ax.errorbar(i, m, yerr=[[m - lo], [hi - m]], color="k", capsize=3, lw=0.8)
            # a bar of 0 and no bar (the metric does not apply, e.g. no clip played) look alike: say which
            if not math.isfinite(m) or m == 0:
                few_n = f" (n={r['n']})" if 0 < r["n"] < FEW else ""   # a zero of 2 trials says so, as the table
                ax.annotate("n/a" if not math.isfinite(m) else "0" + few_n, (i, 0), xytext=(0, 2),
                            textcoords="offset points",
                            ha="center", va="bottom", fontsize=z["zero"], color="0.35")
            elif 0 < r["n"] < FEW:   # as the table's "(n=2)": its interval is too narrow to be a 95 % one
                ax.annotate(f"n={r['n']}", (i, max(v for v in (m, hi) if math.isfinite(v))), xytext=(0, 1.5),
                            textcoords="offset points", ha="center", va="bottom", fontsize=z["few"], color="0.35")
            drawn += [v for v in (m, lo, hi) if math.isfinite(v)]
        if drawn and not any(drawn):
            ax.set_ylim(0, 1)  # all 0: an axis from 0 (matplotlib's default for nothing is -0.04..0.04)
        elif few:   # room above the highest bar for its n=k, under the panel's title
            lo_y, hi_y = ax.get_ylim()
            ax.set_ylim(lo_y, hi_y + 0.15 * (hi_y - lo_y))
        info = doc["metrics"][name]
        heading = _heading(name, info)
        # pad: clear of the value axis' top tick label, which can sit at the axes' top
        ax.set_title(panel_title(heading, pw, z["panel"]) if narrow else heading, fontsize=z["panel"],
                     **({"pad": 6.0} if narrow else {}))
        ax.set_xticks(range(len(conds)), conds, fontsize=z["names"])
        if upright:
            ax.set_xticklabels(conds, rotation=90, fontsize=z["names"])
        ax.tick_params(axis="y", labelsize=z["yticks"])
        if narrow:
            ax.yaxis.set_major_locator(MaxNLocator(4))
        ax.set_ylabel(info["units"], fontsize=z["units"])
        ax.spines[["top", "right"]].set_visible(False)
    for ax in axes.flat[len(names):]:
        ax.set_axis_off()
    fig.suptitle("\n".join(title), fontsize=z["title"])
    if note:
        fig.supxlabel("\n".join(note), fontsize=z["note"], color="0.3")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path) if pdf else fig.savefig(path)
    return path


def is_compute(metric: str) -> bool:
    """A row of the machine's time (``frame_ms_*``, ``realtime_factor``): measured with the trial processes
    sharing the machine, so never in bold (a review: its 'best' did not hold in a rerun)."""
    return metric.startswith("frame_ms") or metric == "realtime_factor"
