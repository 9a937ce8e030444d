"""``plots/method.png``: the signals of the method a run used beyond the thesis' figures, one panel each.

A paper-reproducing researcher's review (2026-11-29): a run under ``body=hill``, ``body=fourier`` or Ding et al.'s
pipeline drew only van Duijn's Figs. 3.1-4.2, and the method's own channels (the lungs, the muscles, the Fourier
blend, the torso angles, the lips, the prosody) were in ``channels.csv`` alone.  Each panel is drawn when the run
wrote its channels; units as docs/pipeline.md's columns table gives them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from laughlab.render.layout import PAGE, Layout, in_layout, thin_ticks, wrapped

#: a line's style by its place in a panel: told apart without its hue (docs/plots.md)
STYLES = ("-", "--", ":", "-.")

#: the panels: (title, unit, channels with their legend names); a panel is drawn when its first channel is there
PANELS = (
    ("Lung pressure (DiLorenzo et al. 2008, Eqs. 1-4) and its target from the audio (Sec. 6)", "cm H2O",
     (("lung_pressure", "lung pressure (simulated)"), ("pressure", "target from the audio"))),
    ("Pressure target from the audio (DiLorenzo et al. 2008, Sec. 6: |audio| low-passed, fitted)", "cm H2O",
     (("pressure", "target from the audio"),)),
    ("Muscle activations (Hill model, Sec. 5.1)", "0-1",
     (("act_abdomen", "abdomen"), ("act_diaphragm", "diaphragm"), ("act_inner_ic", "inner intercostals"),
      ("act_outer_ic", "outer intercostals"))),
    ("Airflow (out positive)", "L/s", (("airflow", "airflow"),)),
    ("Fourier blend s, calm 0 to intense 1, past 1 extrapolated (Unuma et al. 1995, Eq. 3)", "s; MCS",
     (("fourier_s", "blend s"), ("mcs", "MCS"))),
    ("Torso following the head (Ding et al. 2014)", "deg",
     (("follow_head_pitch", "head pitch"), ("torso_pitch", "torso pitch"), ("shoulder_angle", "shoulders"))),
    ("Prosody (Ding et al. 2014: Praat's pitch)", "Hz", (("f0", "F0 (gaps: unvoiced)"),)),
    ("Lips and jaw (Ding et al. 2014, contextual Gaussian model, Eq. 1)", "0-1",
     (("lip_open", "lips open"), ("lip_corner", "lip corners"), ("jaw", "jaw"))),
    ("Concatenation cost of the segments so far (Ding et al. 2014, Eq. 4)", "cost",
     (("concat_cost", "Eq. 4 so far"),)),
)

#: every channel a panel may draw (the plots sink keeps these)
CHANNELS = tuple(dict.fromkeys(k for _, _, lines in PANELS for k, _ in lines))


def method_panels(data: dict) -> list:
    """The panels whose first channel the run wrote, each with the lines it has (the pressure target alone only
    without the simulated lungs, beside which it is drawn)."""
    out = []
    for title, unit, lines in PANELS:
        if lines[0][0] in data and not (lines[0][0] == "pressure" and "lung_pressure" in data):
            out.append((title, unit, [(k, name) for k, name in lines if k in data]))
    return out


@in_layout
def method_figure(path: Path, times: np.ndarray, data: dict, title: str = "", note: str = "", pdf=False,
                  layout: Layout = PAGE, input_end_s: float | None = None) -> Path | None:
    """One panel per :data:`PANELS` entry the run has, stacked on one time axis; None when it has none (a run of
    van Duijn's pipeline alone: its figures are Figs. 3.1-4.2)."""
    from laughlab.render.plots import hatch_note, shade_run_out
    from laughlab.render.savefig import new_figure, save_figure

    panels = method_panels(data)
    if not panels:
        return None
    col = layout.column
    width = layout.width_in if col else 7.0
    fig, axes = new_figure(len(panels), 1, figsize=(width, 0.35 + 1.35 * len(panels)), dpi=150, sharex=True,
                             layout="constrained", squeeze=False)
    axes = axes[:, 0]
    note = hatch_note(note, times, input_end_s, named=False)   # in each legend it widened them past a column's axes
    for ax, (head, unit, lines) in zip(axes, panels):
        for i, (key, name) in enumerate(lines):
            y = np.asarray(data[key], float)
            if key == "f0":   # unvoiced frames are 0 Hz in the channel: gaps here, not drops to 0
                y = np.where(y > 0, y, np.nan)
            ax.plot(times, y, lw=1.0, ls=STYLES[i % len(STYLES)], label=name)
        shade_run_out(ax, times, input_end_s, named=False)
        ax.set_ylabel(unit, fontsize=layout.panel_title if col else 8)
        # the axes start after the y label and its ticks: a title at the left wraps to the axes' width (a review:
        # at the figure's width less 0.7 in, titles were cut at the right edge)
        ax.set_title(wrapped(head, width - 1.0, layout.panel_title) if col else head, fontsize=layout.panel_title,
                     loc="left")
        ax.spines[["top", "right"]].set_visible(False)
        ax.grid(alpha=0.3, linewidth=0.5)
        if len(lines) > 1:
            # a column's legend in one column when its names are long: two spilled past the axes (a review)
            ncols = (1 if max(len(n) for _, n in lines) > 14 else 2) if col else 4
            ax.legend(fontsize=layout.legend, frameon=False, ncols=ncols, loc="best")   # least over the data
        if col:
            thin_ticks(ax, x=6, y=3)
    axes[-1].set_xlabel("time (s)")
    if len(times):
        axes[-1].set_xlim(float(times[0]), float(times[-1]) if times[-1] > times[0] else float(times[0]) + 1 / 60)
    head = title or "The method's own signals"
    fig.suptitle(wrapped(f"{head}; {note}" if note else head, width, layout.title) if col else
                 (f"{head}; {note}" if note else head), fontsize=layout.title)
    save_figure(fig, path, pdf)
    return path
