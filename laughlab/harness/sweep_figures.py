"""A sweep report's figures (:mod:`laughlab.harness.sweep_report`): heatmaps over two swept parameters and line
plots over one, each with its 95 % intervals, a title saying what it was measured on and a caption saying how to
read it (a review: bare means, no n, no setting, and value ranges that made a difference of 0.05 fill the scale).

Every figure is written as a PNG and, beside it, a PDF (vector; no creation date: the same data, the same bytes).
"""
from __future__ import annotations

import math
import textwrap

import numpy as np

from laughlab.harness.report_format import better_label, fmt, heading, panel_grid, param_label
from laughlab.render.savefig import save_figure


def _num(v: str):
    try:
        return float(v)
    except ValueError:
        return v


def order(v: str):
    """A sort key for a swept value: numbers by value, then words (a point without the parameter: "")."""
    x = _num(v)
    return (0, x, "") if isinstance(x, float) else (1, 0.0, x)


def distinct_labels(values, digits: int = 3, most: int = 6) -> list[str]:
    """``values`` written with ``digits`` significant figures, or as many more (up to ``most``) as it takes for two
    different values to read differently (a review: 2 figures showed cells of clearly different colour alike)."""
    finite = sorted({float(v) for v in values if v is not None and math.isfinite(v)})
    for d in range(digits, most + 1):
        shown = [fmt(v, d) for v in finite]
        if len(set(shown)) == len(shown):
            break
    return [fmt(v, d) for v in values]


def _ci(r: dict) -> tuple[float, float, float]:
    """A point's (mean, low, high); NaN where it has none (a bound missing: the mean)."""
    m = r["mean"] if r["mean"] is not None else math.nan
    lo, hi = r["ci95"] if r["ci95"] and r["ci95"][0] is not None else (m, m)
    return m, lo, hi


#: the figures' sizes: panel width and height (in) and panels a row of the heatmaps (``heat``) and line plots
#: (``line``), font sizes (pt) and ``notes_chars``, the caption's characters an inch.  ``page`` as it always was
#: (text 6-8 pt); ``column`` 3.5 in wide for one column of a paper, no text under 7 pt (``report --width column``)
SIZES = {"page": dict(heat=(3.4, 2.9, 3), line=(3.0, 2.4, 3), cell=6, ticks=7, labels=7, panel=8, bar=6.5,
                      bar_ticks=6, line_units=6, line_ticks=6, notes=6.5, notes_chars=15),
         "column": dict(heat=(3.5, 2.7, 1), line=(1.75, 2.2, 2), cell=7, ticks=7, labels=7, panel=7.5, bar=7,
                        bar_ticks=7, line_units=7, line_ticks=7, notes=7, notes_chars=14)}


def _sizes(width: str) -> dict:
    from laughlab.render.layout import layout_of

    return SIZES["column" if layout_of(width).column else "page"]


def _caption(fig, title: str, notes: list[str], width_in: float, z: dict = SIZES["page"]) -> None:
    """The figure's title (what it was measured on) above the panels and its notes (how to read it) below."""
    fig.suptitle("\n".join(textwrap.wrap(title, int(width_in * 12))), fontsize=8)
    fig.supxlabel("\n".join(line for note in notes for line in textwrap.wrap(note, int(width_in * z["notes_chars"]))),
                  fontsize=z["notes"], color="0.3")


def _panel_heading(m: str, info: dict, z: dict) -> str:
    """A panel's title; in a column broken after an underscore where it is wider than its panel."""
    from laughlab.harness.report_figure import panel_title

    text = heading(m, info)
    # the axes are about 0.7 of the panel's width (the value axis' label and ticks take the rest)
    return panel_title(text, 0.7 * z["line"][0], z["panel"]) if z is SIZES["column"] else text


def heatmaps(points, a, b, metrics, result, path, info, title: str, width: str = "page") -> None:
    """One heatmap per metric over parameters ``a`` (x) and ``b`` (y); bright is better in each.

    A cell is the mean of its points' means (over the other swept parameters) and, under it, ``[lo, hi]``: those
    points' 95 % bootstrap intervals, their ends averaged (it was ``±h``, the mean half-width, which read as
    ``0.0833 ±0.12`` for a fraction whose interval is [0, 0.25]: a sweep researcher's review).  The colour range
    spans the cells' means, widened to a point's median interval width where the means differ by less, so that
    noise does not fill the scale.
    ``width``: ``page`` (3 panels a row) or ``column`` (3.5 in, one a row, no text under 7 pt: :data:`SIZES`)."""
    z = _sizes(width)
    xs = sorted({p["params"].get(a, "") for p in points}, key=order)
    ys = sorted({p["params"].get(b, "") for p in points}, key=order)
    fig, axes = panel_grid(len(metrics), *z["heat"])
    widened, most, single = [], 1, False
    for ax, m in zip(axes, metrics):
        grid = np.full((len(ys), len(xs)), np.nan)
        ends = np.full((len(ys), len(xs), 2), np.nan)
        widths, lows, highs = [], [], []
        for i, y in enumerate(ys):
            for j, x in enumerate(xs):
                rs = [result(p, m) for p in points if p["params"].get(a, "") == x and p["params"].get(b, "") == y]
                cis = [_ci(r) for r in rs if math.isfinite(_ci(r)[0])]
                # a point of one trial has no interval (its "[v, v]" read as ±0, a new-user review): none from it
                spread = [_ci(r) for r in rs if math.isfinite(_ci(r)[0]) and (r.get("n") or 0) >= 2]
                most = max(most, len(cis))
                single = single or len(spread) < len(cis)
                if cis:
                    grid[i, j] = np.mean([c[0] for c in cis])
                    lows += [c[1] for c in cis]
                    highs += [c[2] for c in cis]
                if spread:
                    ends[i, j] = np.mean([c[1] for c in spread]), np.mean([c[2] for c in spread])
                    widths += [c[2] - c[1] for c in spread]
        lo, hi = np.nanmin(grid), np.nanmax(grid)
        noise = float(np.median(widths)) if widths else 0.0
        if hi - lo < noise:   # the cells differ by less than one point's interval: do not stretch that over the scale
            mid = (lo + hi) / 2   # ... nor past the intervals' own ends (a fraction's scale below 0)
            lo, hi = max(mid - noise / 2, min(lows)), min(mid + noise / 2, max(highs))
            widened.append(m)
        hib = info[m]["higher_is_better"]
        # bright (yellow) is the better end: viridis runs dark to bright with the value, so flip it when lower is better
        im = ax.imshow(grid, origin="lower", cmap="viridis" if hib is not False else "viridis_r", aspect="auto",
                       vmin=lo, vmax=hi if hi > lo else None)
        labels = distinct_labels(grid.ravel())
        for k, text in enumerate(labels):
            i, j = divmod(k, len(xs))
            bright = np.mean(im.cmap(im.norm(grid[i, j]))[:3]) > 0.5
            colour = ("0.35" if not math.isfinite(grid[i, j])   # n/a on the blank cell, not white on white
                      else "k" if bright else "w")
            spread = (f"\n[{fmt(ends[i, j, 0], 2)}, {fmt(ends[i, j, 1], 2)}]" if math.isfinite(ends[i, j, 0])
                      else "")
            ax.text(j, i, text + spread, ha="center", va="center", fontsize=z["cell"], color=colour, linespacing=1.1)
        ax.set_xticks(range(len(xs)), xs, fontsize=z["ticks"])
        ax.set_yticks(range(len(ys)), ys, fontsize=z["ticks"])
        ax.set_xlabel(param_label(a), fontsize=z["labels"])
        ax.set_ylabel(param_label(b), fontsize=z["labels"])
        ax.set_title(heading(m, info[m]), fontsize=8)
        cb = fig.colorbar(im, ax=ax, shrink=0.9)
        if hib is False:
            cb.ax.invert_yaxis()  # the better (lower) end at the top, as on every other bar
        cb.set_label(better_label(hib, info[m]["units"]), fontsize=z["bar"])
        cb.ax.tick_params(labelsize=z["bar_ticks"])
    notes = ["Each cell: the mean of its point's trials"
             + (f" (averaged over the other swept parameters: up to {most} points a cell)" if most > 1 else "")
             + "; under it a point's 95% bootstrap CI (the ends averaged over the cell's points"
             + (", those of one trial, which have none, left out; none where every point has one trial)." if single
                else ").")]
    if widened:
        notes.append("Colour range widened to a point's median CI width, as the cells differ by less: "
                     + ", ".join(widened) + ".")
    _caption(fig, title, notes, fig.get_figwidth(), z)
    save_figure(fig, path)


def lines(points, a, metrics, result, path, info, title: str, width: str = "page") -> None:
    """One panel per metric against the one swept parameter ``a``: each point's mean with its 95 % CI as an error
    bar; the value axis spans the intervals (not from 0, which the caption says).  ``width``: as :func:`heatmaps`
    (a column: 2 panels a row)."""
    z = _sizes(width)
    xs = sorted({p["params"].get(a, "") for p in points}, key=order)
    fig, axes = panel_grid(len(metrics), *z["line"])
    zoomed, within = [], []
    for ax, m in zip(axes, metrics):
        cis = []
        for x in xs:
            at = [_ci(result(p, m)) for p in points if p["params"].get(a, "") == x]
            cis.append(tuple(np.nanmean([c[k] for c in at]) if at else math.nan for k in range(3)))
        mean, lo, hi = (np.array(v, dtype=float) for v in zip(*cis))
        xv = [_num(x) for x in xs]
        ax.errorbar(xv, mean, yerr=[mean - lo, hi - mean], fmt="o-", capsize=3, lw=1, ms=4)
        ends = np.concatenate([lo[np.isfinite(lo)], hi[np.isfinite(hi)]])
        if ends.size:
            bottom, top = float(ends.min()), float(ends.max())
            pad = 0.08 * (top - bottom) if top > bottom else 0.05 * max(abs(top), 1.0)
            ax.set_ylim(bottom - pad, top + pad)
            if bottom - pad > 0 or top + pad < 0:
                zoomed.append(m)
            if np.isfinite(lo).all() and np.isfinite(hi).all() and lo.max() <= hi.min():
                within.append(m)   # one value lies inside every point's interval: no difference shown
        ax.set_xlabel(param_label(a), fontsize=z["labels"])
        hib = info[m]["higher_is_better"]
        way = {True: " (higher is better)", False: " (lower is better)"}.get(hib, "")
        ax.set_ylabel(info[m]["units"] + ("\n" + way.strip() if z is SIZES["column"] and way else way),
                      fontsize=z["line_units"])
        ax.tick_params(labelsize=z["line_ticks"])
        ax.set_title(_panel_heading(m, info[m], z), fontsize=z["panel"])
        ax.spines[["top", "right"]].set_visible(False)
    notes = ["Error bars: each point's 95% bootstrap CI over its trials."]
    if zoomed:
        notes.append("Value axis zoomed to the CIs (not from 0): " + ", ".join(zoomed) + ".")
    if within:
        notes.append("Every point's CI overlaps every other's (no difference shown): " + ", ".join(within) + ".")
    _caption(fig, title, notes, fig.get_figwidth(), z)
    save_figure(fig, path)
