"""The study report's figures: condition means with 95 % CIs, and one line per participant.

Drawn with a bare ``matplotlib.figure.Figure`` on the Agg canvas (no pyplot: the global backend is
untouched), one panel per question, conditions in the design's order, the scale's range as the
y axis.  Each figure is written twice: a PNG at 300 dpi and a PDF (vector, for print), without a
creation date so that the same answers give the same bytes.  ``width="column"`` (``study analyze --width
column``) draws them 3.5 in wide for one column of a two-column paper, one panel a row, every text at 7 pt or
more (:data:`SIZES`); ``page`` (the default) as they always were.  A confidence interval that passes an end
of the axis is drawn to the end with an arrow there and its bound written beside it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from laughlab.render.savefig import save_figure


#: sizes: a panel's height (in), panels a row, font sizes (pt) and the characters before a condition's name or a
#: question's prompt is broken; ``page`` as they always were, ``column`` 3.5 in wide and no text under 7 pt
SIZES = {"page": dict(height=3.4, cols=3, ticks=8, title=9, label=None, suptitle=10, note=7, legend=8, tick_chars=12,
                      prompt_chars=48),
         "column": dict(height=2.9, cols=1, ticks=7.5, title=8, label=8, suptitle=8, note=7, legend=7.5,
                        tick_chars=8, prompt_chars=52)}


def _sizes(width: str) -> dict:
    from laughlab.render.layout import layout_of

    return SIZES["column" if layout_of(width).column else "page"]


def _panels(n: int, z: dict = SIZES["page"]):
    cols = min(n, z["cols"])
    rows = -(-n // cols)
    size = (3.6 * cols + 0.6, z["height"] * rows) if z is SIZES["page"] else (3.5, z["height"] * rows + 0.4)
    fig = Figure(figsize=size, dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes[:n]


def _wrap(title: str, z: dict) -> str:
    """A figure's title, wrapped to a column's width (a page's stays one line)."""
    from laughlab.render.layout import wrapped

    return title if z is SIZES["page"] else wrapped(title, 3.5, z["suptitle"])


def off_axis(low, high, ylim: tuple[float, float]) -> list[tuple[int, float, int]]:
    """The intervals (by position) that pass an end of the axis: (position, bound, +1 above / -1 below)."""
    out = []
    for i, (lo, hi) in enumerate(zip(low, high)):
        if np.isfinite(hi) and hi > ylim[1]:
            out.append((i, float(hi), 1))
        if np.isfinite(lo) and lo < ylim[0]:
            out.append((i, float(lo), -1))
    return out


def _mark_off_axis(ax, m, fontsize: float = 7) -> None:
    ylim = ax.get_ylim()
    for i, bound, way in off_axis(m["ci_low"].to_numpy(float), m["ci_high"].to_numpy(float), ylim):
        end = ylim[1] if way > 0 else ylim[0]
        ax.plot([i], [end], marker="^" if way > 0 else "v", color="tab:blue", ms=8, clip_on=False, zorder=4)
        ax.annotate(f"{bound:.2f}", (i, end), xytext=(7, -10 if way > 0 else 3), textcoords="offset points",
                    fontsize=fontsize, color="tab:blue")


def _ylim(ax, design, tidy) -> None:
    if design and design.get("scale") == "likert":
        ax.set_ylim(0.6, design["points"] + 0.4)
        ax.set_yticks(range(1, design["points"] + 1))
    elif design:
        ax.set_ylim(design["slider"]["min"], design["slider"]["max"])
    else:
        ax.set_ylim(tidy["value"].min() - 0.4, tidy["value"].max() + 0.4)


def _label(q: str, design, chars: int = 48) -> str:
    for item in (design or {}).get("questions", []):
        if item["id"] == q:
            import textwrap

            return q + "\n" + "\n".join(textwrap.wrap(item["prompt"], chars))
    return q


def _axes_text(ax, q: str, design, z: dict, ylabel: str) -> None:
    """A panel's condition ticks' size, title (the question and its prompt) and value label, at ``z``'s sizes (a
    column's tick and axis labels set on the axes: the ticks are made again when the figure is saved)."""
    ax.set_title(_label(q, design, z["prompt_chars"]), fontsize=z["title"])
    ax.set_ylabel(ylabel, **({"fontsize": z["label"]} if z["label"] else {}))
    if z["label"]:
        ax.tick_params(axis="y", labelsize=z["ticks"])


def _tick(condition: str, width: int = 12) -> str:
    """A condition's tick label: horizontal, a long name broken after its underscore nearest the middle."""
    cuts = [i for i, ch in enumerate(condition) if ch == "_"]
    if len(condition) <= width or not cuts:
        return condition
    i = min(cuts, key=lambda k: abs(k - len(condition) / 2))
    return condition[:i + 1] + "\n" + condition[i + 1:]


def means_plot(path: Path, means, tidy, questions: list[str], conditions: list[str], design=None,
               simulated: bool = False, width: str = "page") -> None:
    """Condition means with 95 % CIs per question; each participant's mean as a faint dot (``simulated``: the
    title says the participants were simulated)."""
    z = _sizes(width)
    fig, axes = _panels(len(questions), z)
    rng = np.random.default_rng(0)
    for ax, q in zip(axes, questions):
        m = means[means["question"] == q].set_index("condition").reindex(conditions)
        x = np.arange(len(conditions))
        pm = tidy[tidy["question"] == q].groupby(["condition", "participant"])["value"].mean()
        for i, c in enumerate(conditions):
            if c in pm.index.get_level_values(0):
                v = pm.loc[c].to_numpy(float)
                ax.scatter(i + rng.uniform(-0.12, 0.12, len(v)), v, s=10, color="0.65", zorder=1, linewidths=0)
        err = np.vstack([m["mean"] - m["ci_low"], m["ci_high"] - m["mean"]])
        ax.errorbar(x, m["mean"], yerr=err, fmt="o", color="tab:blue", ms=7, capsize=5, lw=1.8, zorder=3)
        ax.set_xticks(x, [_tick(c, z["tick_chars"]) for c in conditions], fontsize=z["ticks"])
        _axes_text(ax, q, design, z, "rating (mean, 95 % CI)")
        ax.grid(axis="y", alpha=0.3)
        _ylim(ax, design, tidy)
        _mark_off_axis(ax, m, z["note"])
    who = "simulated participants" if simulated else "participants"
    fig.suptitle(_wrap(f"Condition means, {tidy['participant'].nunique()} {who} (dots: each participant's mean)",
                       z), fontsize=z["suptitle"])
    save_figure(fig, path, dpi=300)   # and its PDF


def participant_lines(path: Path, tidy, means, questions: list[str], conditions: list[str], design=None,
                      simulated: bool = False, width: str = "page") -> None:
    """One line per participant (their mean per condition), the condition means in bold."""
    z = _sizes(width)
    fig, axes = _panels(len(questions), z)
    x = np.arange(len(conditions))
    for ax, q in zip(axes, questions):
        pm = tidy[tidy["question"] == q].pivot_table(index="participant", columns="condition", values="value",
                                                     aggfunc="mean").reindex(columns=conditions)
        for _, row in pm.iterrows():
            ax.plot(x, row.to_numpy(float), color="0.55", alpha=0.55, lw=1, marker="o", ms=3)
        m = means[means["question"] == q].set_index("condition").reindex(conditions)
        ax.plot(x, m["mean"], color="tab:red", lw=2.5, marker="o", ms=6, label="mean", zorder=3)
        ax.set_xticks(x, [_tick(c, z["tick_chars"]) for c in conditions], fontsize=z["ticks"])
        _axes_text(ax, q, design, z, "rating (participant mean)")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(loc="lower right", fontsize=z["legend"], frameon=False)
        if z is SIZES["column"]:   # the last condition's name clear of the figure's edge
            ax.set_xlim(-0.4, len(conditions) - 0.6)
        _ylim(ax, design, tidy)
    fig.suptitle(_wrap("Each simulated participant's ratings across the conditions" if simulated
                       else "Each participant's ratings across the conditions", z), fontsize=z["suptitle"])
    save_figure(fig, path, dpi=300)   # and its PDF
