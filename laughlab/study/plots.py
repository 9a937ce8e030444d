"""The study report's figures: condition means with 95 % CIs, and one line per participant.

Drawn with a bare ``matplotlib.figure.Figure`` on the Agg canvas (no pyplot: the global backend is
untouched), one panel per question, conditions in the design's order, the scale's range as the
y axis.  Each figure is written twice: a PNG at 300 dpi and a PDF (vector, for print), without a
creation date so that the same answers give the same bytes.  A confidence interval that passes an end
of the axis is drawn to the end with an arrow there and its bound written beside it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from laughlab.render.savefig import save_figure


def _panels(n: int, height: float = 3.4):
    cols = min(n, 3)
    rows = -(-n // cols)
    fig = Figure(figsize=(3.6 * cols + 0.6, height * rows), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes[:n]


def off_axis(low, high, ylim: tuple[float, float]) -> list[tuple[int, float, int]]:
    """The intervals (by position) that pass an end of the axis: (position, bound, +1 above / -1 below)."""
    out = []
    for i, (lo, hi) in enumerate(zip(low, high)):
        if np.isfinite(hi) and hi > ylim[1]:
            out.append((i, float(hi), 1))
        if np.isfinite(lo) and lo < ylim[0]:
            out.append((i, float(lo), -1))
    return out


def _mark_off_axis(ax, m) -> None:
    ylim = ax.get_ylim()
    for i, bound, way in off_axis(m["ci_low"].to_numpy(float), m["ci_high"].to_numpy(float), ylim):
        end = ylim[1] if way > 0 else ylim[0]
        ax.plot([i], [end], marker="^" if way > 0 else "v", color="tab:blue", ms=8, clip_on=False, zorder=4)
        ax.annotate(f"{bound:.2f}", (i, end), xytext=(7, -10 if way > 0 else 3), textcoords="offset points",
                    fontsize=7, color="tab:blue")


def _ylim(ax, design, tidy) -> None:
    if design and design.get("scale") == "likert":
        ax.set_ylim(0.6, design["points"] + 0.4)
        ax.set_yticks(range(1, design["points"] + 1))
    elif design:
        ax.set_ylim(design["slider"]["min"], design["slider"]["max"])
    else:
        ax.set_ylim(tidy["value"].min() - 0.4, tidy["value"].max() + 0.4)


def _label(q: str, design) -> str:
    for item in (design or {}).get("questions", []):
        if item["id"] == q:
            import textwrap

            return q + "\n" + "\n".join(textwrap.wrap(item["prompt"], 48))
    return q


def _tick(condition: str, width: int = 12) -> str:
    """A condition's tick label: horizontal, a long name broken after its underscore nearest the middle."""
    cuts = [i for i, ch in enumerate(condition) if ch == "_"]
    if len(condition) <= width or not cuts:
        return condition
    i = min(cuts, key=lambda k: abs(k - len(condition) / 2))
    return condition[:i + 1] + "\n" + condition[i + 1:]


def means_plot(path: Path, means, tidy, questions: list[str], conditions: list[str], design=None,
               simulated: bool = False) -> None:
    """Condition means with 95 % CIs per question; each participant's mean as a faint dot (``simulated``: the
    title says the participants were simulated)."""
    fig, axes = _panels(len(questions))
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
        ax.set_xticks(x, [_tick(c) for c in conditions], fontsize=8)
        ax.set_title(_label(q, design), fontsize=9)
        ax.set_ylabel("rating (mean, 95 % CI)")
        ax.grid(axis="y", alpha=0.3)
        _ylim(ax, design, tidy)
        _mark_off_axis(ax, m)
    who = "simulated participants" if simulated else "participants"
    fig.suptitle(f"Condition means, {tidy['participant'].nunique()} {who} (dots: each participant's mean)",
                 fontsize=10)
    save_figure(fig, path, dpi=300)   # and its PDF


def participant_lines(path: Path, tidy, means, questions: list[str], conditions: list[str], design=None,
                      simulated: bool = False) -> None:
    """One line per participant (their mean per condition), the condition means in bold."""
    fig, axes = _panels(len(questions))
    x = np.arange(len(conditions))
    for ax, q in zip(axes, questions):
        pm = tidy[tidy["question"] == q].pivot_table(index="participant", columns="condition", values="value",
                                                     aggfunc="mean").reindex(columns=conditions)
        for _, row in pm.iterrows():
            ax.plot(x, row.to_numpy(float), color="0.55", alpha=0.55, lw=1, marker="o", ms=3)
        m = means[means["question"] == q].set_index("condition").reindex(conditions)
        ax.plot(x, m["mean"], color="tab:red", lw=2.5, marker="o", ms=6, label="mean", zorder=3)
        ax.set_xticks(x, [_tick(c) for c in conditions], fontsize=8)
        ax.set_title(_label(q, design), fontsize=9)
        ax.set_ylabel("rating (participant mean)")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(loc="lower right", fontsize=8, frameon=False)
        _ylim(ax, design, tidy)
    fig.suptitle("Each simulated participant's ratings across the conditions" if simulated
                 else "Each participant's ratings across the conditions", fontsize=10)
    save_figure(fig, path, dpi=300)   # and its PDF
