"""Figures in the style of the thesis (van Duijn 2014): Figs. 3.1, 3.2, 4.1 and 4.2.

Each figure function writes a PNG at ``path`` and, with ``pdf`` (True: ``NAME.pdf`` beside it, or a path), the
same figure as a vector PDF for print (:func:`laughlab.render.savefig.save_figure`)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib
import numpy as np
from matplotlib.patches import Rectangle

from laughlab.core.frame import clip_blocks  # noqa: F401 (used here and by the plots sink)
from laughlab.render.filmstrip import filmstrip, filmstrip_moments  # noqa: F401 (the plots sink draws it)
from laughlab.render.layout import PAGE, Layout, in_layout, thin_ticks, titled, wrapped
from laughlab.render.savefig import new_figure, save_figure
from laughlab.signals.smoothing import THESIS_TICK_HZ, rate_limit_series

#: the two rise/fall settings of the thesis' Fig. 3.2 (per tick): green 0.5/0.3, blue 0.2/0.1
#: Fig. 3.2's rise/fall settings and their colours and line styles: the dashes tell the curves apart in greyscale and
#: for red-green colour blindness (red, green and blue are about as light as each other)
FIG32_SETTINGS = ((0.5, 0.3, "tab:green", "--"), (0.2, 0.1, "tab:blue", ":"))


def _shade_bouts(ax, bouts) -> None:
    for i, b in enumerate(bouts or ()):
        ax.axvspan(b[0], b[1], color="0.9", zorder=0, label="laughter bout (truth)" if i == 0 else None)


def shade_run_out(ax, times, input_end_s: float | None, named: bool = True) -> None:
    """Hatch the frames after the input's end, the silence ``run_out=true`` added to play the last clip out (a
    review: the figures drew it as the laugh's own); ``named`` in the legend, else by the title
    (:func:`hatch_note`: a column's legends had no room for it, and were cut by the figure's edge).  Every figure
    of a run hatches it so (this module's and :mod:`laughlab.render.method_plots`)."""
    if not ran_out(times, input_end_s):
        return
    ax.axvspan(input_end_s, float(times[-1]), facecolor="none", edgecolor="0.6", hatch="///", lw=0, zorder=0,
               label="after the input: silence (run_out)" if named else None)


def ran_out(times, input_end_s: float | None) -> bool:
    """The frames go on past ``input_end_s``, where the input ended (``run_out``)."""
    return input_end_s is not None and len(times) > 0 and input_end_s < float(times[-1])


def hatch_note(note: str, times, input_end_s: float | None, named: bool) -> str:
    """``note`` with the hatching named, for a figure whose legends do not name it (``named`` False)."""
    if not named and ran_out(times, input_end_s):
        return "; ".join(n for n in (note, "hatched: silence after the input (run_out)") if n)
    return note


def _set_xlim(ax, lo: float, hi: float) -> None:
    """``ax.set_xlim`` for any run, however short: a run of one frame spans one frame's width, not zero
    (matplotlib would widen it itself, with a UserWarning on the terminal)."""
    lo, hi = float(lo), float(hi)
    if not hi > lo:
        hi = lo + 1.0 / 60
    ax.set_xlim(lo, hi)


def _setup_axis(ax) -> None:
    ax.spines[["top", "right"]].set_visible(False)
    ax.grid(alpha=0.3, linewidth=0.5)


def busiest_window(times: np.ndarray, signal: np.ndarray, window_s: float) -> tuple[float, float]:
    """The ``window_s``-long stretch of ``times`` where ``signal`` has the most mass."""
    if len(times) < 2 or times[-1] - times[0] <= window_s:
        return (float(times[0]) if len(times) else 0.0, float(times[-1]) if len(times) else window_s)
    dt = times[1] - times[0]
    n = max(1, int(round(window_s / dt)))
    mass = np.convolve(np.asarray(signal, float), np.ones(n), mode="valid")
    tied = np.flatnonzero(mass >= mass.max() - 1e-9 * max(abs(mass.max()), 1.0))
    i = int(tied[len(tied) // 2])   # the middle of equal windows: a bout shorter than the window sits centred
    return float(times[i]), float(times[i] + window_s)


@in_layout
def figure_3_2(path: Path, times: np.ndarray, mcs_raw: np.ndarray, dt: float, power: float = 2.0,
               bouts: Sequence | None = None, title: str = "", window_s: float = 4.0, note: str = "",
               pdf=False, layout: Layout = PAGE, input_end_s: float | None = None) -> Path:
    """Fig. 3.2: the MCS unfiltered and with two rise/fall settings (Eq. 3.2).

    Rates are the thesis' per-tick values converted at 60 ticks/s; all three
    curves are raised to ``power`` like the final MCS (listing 5.2).  Left (``layout="column"``: top): the
    whole run; right (below): the ``window_s`` seconds with the most laughter, where the
    individual calls and the effect of rise and fall can be seen.  ``input_end_s``: where the input ended, when
    ``run_out`` went on in silence (:func:`shade_run_out`; the same in every figure of this module).
    """
    col = layout.column
    raw = np.asarray(mcs_raw, float)
    curves = [(raw ** power, "tab:red", 0.8, "-", "no rise/fall" if col else "MCS, no rise/fall")]
    for rise, fall, color, style in FIG32_SETTINGS:
        y = rate_limit_series(raw, rise * THESIS_TICK_HZ, fall * THESIS_TICK_HZ, dt) ** power
        curves.append((y, color, 1.3, style, f"rise {rise}, fall {fall}" + (" /tick" if col else " per tick")))
    if col:
        fig, (ax_all, ax_zoom) = new_figure(2, 1, figsize=(layout.width_in, 3.6), dpi=150, layout="constrained",
                                              height_ratios=(1, 1.3), sharey=True)
    else:
        fig, (ax_all, ax_zoom) = new_figure(1, 2, figsize=(8.0, 2.9), dpi=150, layout="constrained",
                                              width_ratios=(1, 1.6), sharey=True)
    # the zoom: the most laughter inside the truth's bouts when there are any (a review: on a scene of speech and
    # laughter the busiest signal was talk before the first bout), else the most signal anywhere
    inside = np.zeros(len(times), bool)
    for b in bouts or ():
        inside |= (times >= b[0]) & (times <= b[1])
    t0, t1 = busiest_window(times, raw * inside if np.any(raw * inside > 0) else raw, window_s)
    for ax, lo, hi in ((ax_all, times[0] if len(times) else 0, times[-1] if len(times) else 1), (ax_zoom, t0, t1)):
        _shade_bouts(ax, bouts)
        shade_run_out(ax, times, input_end_s, not layout.column)
        for k, (y, color, lw, style, label) in enumerate(curves if ax is ax_zoom else curves[:1]):
            # the unfiltered signal over the filtered ones, which otherwise hide it where they agree
            ax.plot(times, y, color=color, lw=lw, ls=style, label=label, zorder=3 if k == 0 else 2,
                    alpha=0.75 if k == 0 and ax is ax_zoom else 1.0)
        _set_xlim(ax, lo, hi)
        ax.set_xlabel("time (s)")
        _setup_axis(ax)
    ax_all.axvspan(t0, t1, color="tab:orange", alpha=0.15, lw=0)
    ax_all.set_ylabel("MCS" if col else "motion control signal")
    if col:
        ax_zoom.set_ylabel("MCS")
        ax_all.set_xlabel("")
        thin_ticks(ax_all, ax_zoom, x=6, y=3)
    ax_all.set_ylim(-0.02, 1.05)
    ax_all.set_title("plotted stretch (zoom shaded)" if note else "whole run (zoom shaded)",
                     fontsize=layout.panel_title)
    ax_zoom.set_title(f"zoom: {t0:.1f}-{t1:.1f} s", fontsize=layout.panel_title)
    head = "MCS and rise/fall (cf. van Duijn 2014, Fig. 3.2)" if col else \
        "Motion control signal and rise/fall (cf. van Duijn 2014, Fig. 3.2)"
    fig.suptitle(_head(title or head, hatch_note(note, times, input_end_s, not layout.column), layout), fontsize=layout.title)
    handles = {}
    for ax in (ax_zoom, ax_all):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles), fontsize=layout.legend, loc="outside lower center",
               ncols=2 if col else 4, frameon=False, **(_TIGHT_LEGEND if col else {}))
    save_figure(fig, path, pdf)
    return path


def _head(title: str, note: str, layout: Layout) -> str:
    """A figure's title with its note; in a column, wrapped to the column's width."""
    text = titled(title, note)
    return wrapped(text, layout.width_in, layout.title) if layout.column else text


#: a legend's spacing in a column (matplotlib's own is for a page's width)
_TIGHT_LEGEND = dict(handlelength=1.6, columnspacing=1.0, handletextpad=0.4, borderaxespad=0.2)


def _energy_floor(energy: np.ndarray, top: float) -> float:
    """The energy axis' bottom: 0, or below the lowest energy if it went negative (listing 5.4 has no floor)."""
    low = float(np.min(energy)) if len(energy) else 0.0
    return 0.0 if low >= 0.0 else low - 0.05 * (top - low)


#: each bundled clip's tab20 colour (the same in every figure); other clips take the spare ones by name
CLIP_COLORS = {"lean_front1": 17, "lean_back1": 19, "lean_front2": 2, "lean_back2": 3, "clap_hands": 16,
               "hands_on_belly": 18, "point1": 12, "point2": 13, "slap_leg": 8, "stop_it": 9, "rofl": 10,
               "idle": 14}
#: tab20 colours left for other clips (blue, green and red draw the figures' lines)
_SPARE_COLORS = (1, 5, 7, 11, 15, 0, 4, 6)
#: a block of energy 0 (idle) is drawn this high, as a fraction of the energy axis, so that it shows
ZERO_BLOCK = 0.02


def clip_colors(names) -> dict:
    """A colour per clip name: the bundled clips' fixed ones (:data:`CLIP_COLORS`), then the spare ones."""
    cmap = matplotlib.colormaps["tab20"]
    out, k = {}, 0
    for n in sorted(set(names)):
        if n in CLIP_COLORS:
            out[n] = cmap(CLIP_COLORS[n])
        else:
            out[n] = cmap(_SPARE_COLORS[k % len(_SPARE_COLORS)])
            k += 1
    return out


def _draw_clip_blocks(ax, events: Sequence, end: float, top: float) -> list:
    """The clips played as blocks: width their time on screen, height their energy e(a) (Figs. 4.1, 4.2).

    Returns the blocks ``(clip, start, stop, energy)``; :func:`_clip_key` and :func:`_label_blocks`
    say which block is which clip.
    """
    blocks = clip_blocks(events, end)
    colors = clip_colors(b[0] for b in blocks)
    for name, t0, t1, e in blocks:
        patch = ax.add_patch(Rectangle((t0, 0), t1 - t0, e if e > 0 else ZERO_BLOCK * top,
                                           facecolor=colors[name], alpha=0.7 if e > 0 else 0.9, edgecolor="0.3",
                                           lw=0.4))
        patch.set_in_layout(False)  # inside the axes: the layout need not measure hundreds of them
    return blocks


def _clip_key(blocks) -> tuple[list, list]:
    """Legend handles and labels naming every clip shown, mildest first: the colour key of the blocks."""
    from matplotlib.patches import Patch

    energy = {}
    for name, _, _, e in blocks:
        energy.setdefault(name, e)
    colors = clip_colors(energy)
    names = sorted(energy, key=lambda n: (energy[n], n))
    return ([Patch(facecolor=colors[n], alpha=0.7 if energy[n] > 0 else 0.9, edgecolor="0.3", lw=0.4)
             for n in names], [f"{n}, e={energy[n]:g}" for n in names])


def _label_blocks(fig, ax, blocks, lines, top: float, fontsize: float = 5.5) -> list:
    """Write each clip's name on its block where it fits, clear of the other labels and of ``lines``.

    Tried in order: inside the block (at its top, three quarters, half, a quarter of its height, its
    bottom), inside it turned upright (at half, 0.7, 0.3 of its height), above it (centred, then flush
    left, then flush right).  A block with no free spot stays unlabelled: the colour key names
    it.  Blocks are labelled widest first; blocks narrower than a label's height are skipped, and so is
    a block whose clip is already named within a quarter of the axes' width (concatenation plays
    the same clips many times over).  A label above a block keeps off the other blocks.
    """
    from matplotlib.transforms import Bbox, ScaledTranslation

    from laughlab.render.labels import layout_now, line_pixels, place_label

    renderer = layout_now(fig)
    paths = [line_pixels(ln) for ln in lines]
    taken: list = []
    down = ax.transData + ScaledTranslation(0, -1.5 / 72, fig.dpi_scale_trans)
    up = ax.transData + ScaledTranslation(0, 1.0 / 72, fig.dpi_scale_trans)
    up_bottom = ax.transData + ScaledTranslation(0, 1.5 / 72, fig.dpi_scale_trans)
    to_px = ax.transData.transform
    boxes = []
    for _, t0, t1, e in blocks:
        (x0, y0), (x1, y1) = to_px((t0, 0.0)), to_px((t1, e if e > 0 else ZERO_BLOCK * top))
        boxes.append(Bbox.from_extents(x0, y0, x1, y1))
    spacing = 0.25 * ax.get_window_extent(renderer).width  # a clip's name again only this far (pixels) from itself
    labelled: dict = {}
    placed = []
    order = sorted(range(len(blocks)), key=lambda i: (-(blocks[i][2] - blocks[i][1]), blocks[i][1]))
    for i in order:
        name, t0, t1, e = blocks[i]
        box = boxes[i]
        if box.width < 7 or any(abs(box.x0 - x) < spacing for x in labelled.get(name, ())):
            continue
        h = e if e > 0 else ZERO_BLOCK * top
        mid = 0.5 * (t0 + t1)
        inside = ([dict(x=mid, y=h, ha="center", va="top", transform=down)]
                  + [dict(x=mid, y=f * h, ha="center", va="center") for f in (0.75, 0.5, 0.25)]
                  + [dict(x=mid, y=0, ha="center", va="bottom", transform=up_bottom)]
                  + [dict(x=mid, y=f * h, ha="center", va="center", rotation=90) for f in (0.5, 0.7, 0.3)])
        above = [dict(x=mid, y=h, ha="center", va="bottom", transform=up),
                 dict(x=t0, y=h, ha="left", va="bottom", transform=up),
                 dict(x=t1, y=h, ha="right", va="bottom", transform=up)]
        t = None
        if e > 0:
            t = place_label(ax, renderer, name, inside, taken, paths, inside=box, fontsize=fontsize)
        if t is None:
            others = [b for k, b in enumerate(boxes) if k != i and b.x1 > box.x0 - 80 and b.x0 < box.x1 + 80]
            t = place_label(ax, renderer, name, above, taken, paths, avoid=others, fontsize=fontsize)
        if t is not None:
            placed.append(t)
            labelled.setdefault(name, []).append(box.x0)
    return placed


@in_layout
def figure_3_1(path: Path, times: np.ndarray, amp: np.ndarray, params, fps: float, calibration_s: float = 0.0,
               bouts: Sequence | None = None, title: str = "", note: str = "", pdf=False,
               layout: Layout = PAGE, input_end_s: float | None = None, mcs_label: str = "MCS") -> Path:
    """Fig. 3.1: the MCS with min/max amplitude fixed after calibration (left) and drifting (right).

    Both columns run the rms extractor (listing 5.2) again on the run's
    amplitudes (:func:`laughlab.signals.mcs.replay`): left with no falloff, so
    a loud calibration burst keeps later laughter mapped low; right with the
    run's falloff (thesis: 0.001 per tick), maxAmp and minAmp drifting towards
    each other.  Top: the amplitude (grey) and the band from minAmp to maxAmp
    (blue, the thesis' "blue area"); bottom: the final MCS (red), named ``mcs_label`` (another extractor's run:
    the rms mapping's MCS, not the run's own).
    """
    from dataclasses import replace

    from laughlab.signals.mcs import replay

    cal = {"calibration_s": calibration_s} if params.calibration_s is None else {}
    fixed = replay(amp, replace(params, falloff_per_s=0.0, **cal), fps)
    drift = replay(amp, replace(params, **cal), fps)
    narrow = layout.column
    fig, axes = new_figure(2, 2, figsize=(layout.width_in, 3.7) if narrow else (8.0, 4.4), dpi=150, sharex=True,
                             sharey="row", layout="constrained", height_ratios=(1.2, 1))
    unit = "amplitude\n(dB, 10 log10 RMS)" if params.scale == "loudness" else "amplitude\n(RMS, full scale)"
    fixed_label = "min/max fixed after calibration (no falloff)" if calibration_s > 0 else "min/max fixed (no falloff)"
    drift_label = f"min/max drifting (falloff {params.falloff_per_s:g} /s)"
    if narrow:   # the title says "min/max"; the panels' titles only what differs
        unit = "amplitude (dB)" if params.scale == "loudness" else "amplitude (RMS)"
        fixed_label, drift_label = "fixed (no falloff)", f"falloff {params.falloff_per_s:g} /s"
        thin_ticks(*axes.flat, x=3, y=3)
    for col, (run, label) in enumerate(((fixed, fixed_label), (drift, drift_label))):
        top, bottom = axes[0, col], axes[1, col]
        for ax in (top, bottom):
            _shade_bouts(ax, bouts)
            shade_run_out(ax, times, input_end_s, not layout.column)
            if calibration_s > 0:
                ax.axvspan(times[0], times[0] + calibration_s, color="tab:orange", alpha=0.15, lw=0,
                           label="calibration")
            _setup_axis(ax)
        top.fill_between(times, run["min_amp"], run["max_amp"], color="tab:blue", alpha=0.2, lw=0,
                         label="minAmp .. maxAmp")
        top.plot(times, amp, color="0.45", lw=0.5, label="amplitude")
        bottom.plot(times, run["mcs"], color="tab:red", lw=0.8, label=mcs_label)
        bottom.set_ylim(-0.02, 1.05)
        bottom.set_xlabel("time (s)")
        top.set_title(label, fontsize=layout.panel_title)
    # the plotted stretch, not the truth's bouts past it (a recording longer than output.plots.max_seconds)
    _set_xlim(axes[1, 0], times[0] if len(times) else 0.0, times[-1] if len(times) else 1.0)
    lo = float(np.min(amp)) if len(amp) else 0.0
    axes[0, 0].set_ylim(max(lo, float(np.percentile(amp, 1)) - 3) if len(amp) else 0, None)
    axes[0, 0].set_ylabel(unit)   # two lines at the axes' size (a review: one line at 7 pt read as a footnote)
    axes[1, 0].set_ylabel(mcs_label)
    head = "Calibration, min/max amplitude fixed or drifting (cf. van Duijn 2014, Fig. 3.1)" if narrow else \
        "Calibration and min/max falloff (cf. van Duijn 2014, Fig. 3.1)"
    fig.suptitle(_head(title or head, hatch_note(note, times, input_end_s, not layout.column), layout), fontsize=layout.title)
    handles = {}
    for ax in (axes[0, 0], axes[1, 0]):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles), fontsize=layout.legend, loc="outside lower center",
               ncols=3 if narrow else 5, frameon=False, **(_TIGHT_LEGEND if narrow else {}))
    save_figure(fig, path, pdf)
    return path


@in_layout
def figure_4_1(path: Path, times: np.ndarray, mcs: np.ndarray, energy: np.ndarray, events: Sequence,
               gain_per_s: float, bouts: Sequence | None = None, title: str = "", note: str = "",
               pdf=False, layout: Layout = PAGE, gate: np.ndarray | None = None,
               input_end_s: float | None = None) -> Path:
    """Fig. 4.1: MCS (top); the primitive of the MCS, the actual laughing energy and the clips (bottom).
    ``gate``: the detector's clip gain per frame (``clip_gate``), if the run has one (:func:`_closed_gate_note`).

    The primitive ``sum(gain_per_s * MCS * dt)`` is the laughing energy with no
    clip consuming and no fixed decrease (the thesis' blue line); it grows
    without bound, so it has its own axis on the right.  The green line is the
    run's energy L, the blocks the clips played (height e(a), width their time).
    """
    times = np.asarray(times, float)
    dt = float(times[1] - times[0]) if len(times) > 1 else 0.0
    primitive = np.cumsum(np.asarray(mcs, float) * gain_per_s * dt)
    fig, (ax1, ax2) = _energy_axes(layout)
    for ax in (ax1, ax2):
        _shade_bouts(ax, bouts)
        shade_run_out(ax, times, input_end_s, not layout.column)
        _setup_axis(ax)
    ax1.plot(times, mcs, color="tab:red", lw=0.8)
    ax1.set_ylabel("MCS")
    ax1.set_ylim(-0.02, 1.05)
    end = float(times[-1]) if len(times) else 0.0
    top = max([e for _, _, _, e in clip_blocks(events, end)] + [float(np.max(energy)) if len(energy) else 1.0, 1.0])
    blocks = _draw_clip_blocks(ax2, events, end, top)
    (line,) = ax2.plot(times, energy, color="tab:green", lw=1.0, label="laughing energy L")
    ax2.set_ylim(_energy_floor(energy, top), top * 1.15)
    _set_xlim(ax2, times[0] if len(times) else 0, end or 1)
    ax2.set_ylabel("L / clip energy e(a)" if layout.column else "laughing energy L /\nclip energy e(a)")
    ax2.set_xlabel("time (s)")
    axp = ax2.twinx()
    (prim,) = axp.plot(times, primitive, color="tab:blue", lw=1.0, ls="--",   # dashed: as light as the green
                       label="MCS primitive (right axis)" if layout.column else "primitive of the MCS (right axis)")
    axp.set_ylim(0, max(1.0, float(primitive[-1]) if len(primitive) else 1.0) * 1.05)
    axp.set_ylabel("primitive of MCS", color="tab:blue", fontsize=layout.side_label)
    axp.tick_params(axis="y", colors="tab:blue", labelsize=layout.side_ticks)
    axp.spines[["top"]].set_visible(False)
    if layout.column:
        thin_ticks(ax1, ax2, axp, x=6, y=3)
    head = "Laughing energy (cf. van Duijn 2014, Fig. 4.1)" if layout.column else \
        "The laughing energy process (cf. van Duijn 2014, Fig. 4.1)"
    ax1.set_title(_head(title or head, hatch_note(note, times, input_end_s, not layout.column), layout), fontsize=layout.title)
    _legend_with_clip_key(fig, [ax2, axp], blocks, layout)
    _label_blocks(fig, ax2, blocks, [line, prim], top, layout.block_label)
    _closed_gate_note(ax2, energy, blocks, gate, layout)
    save_figure(fig, path, pdf)
    return path


def _legend_with_clip_key(fig, axes, blocks, layout: Layout = PAGE) -> None:
    """One legend under the figure: the lines and shades of ``axes`` in the first column, then the
    colour key of the clips (every clip shown, mildest first) in the next ones."""
    from matplotlib.patches import Patch

    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    kh, kl = _clip_key(blocks)
    # the clips start a column of their own; in a column's width (2 columns) they follow the lines
    rows = max(1, -(-(len(labels) + len(kl)) // layout.key_cols), 0 if layout.column else len(labels))
    while len(labels) < rows and not layout.column:
        handles.append(Patch(visible=False))
        labels.append("")
    handles, labels = handles + kh, labels + kl
    fig.legend(handles, labels, fontsize=layout.key, loc="outside lower center", ncols=-(-len(labels) // rows),
               frameon=False, handlelength=1.4, columnspacing=1.0, handletextpad=0.5)


def _energy_axes(layout: Layout):
    """The figure and the two panels of Figs. 4.1 and 4.2: the MCS above the energy and the clips."""
    size = (layout.width_in, 3.3) if layout.column else (7.0, 4.2)
    return new_figure(2, 1, figsize=size, dpi=150, sharex=True, layout="constrained", height_ratios=(1, 2))


@in_layout
def figure_4_2(path: Path, times: np.ndarray, mcs: np.ndarray, energy: np.ndarray, events: Sequence,
               bouts: Sequence | None = None, title: str = "", note: str = "",
               energy_label: str = "laughing energy L", pdf=False, layout: Layout = PAGE,
               gate: np.ndarray | None = None, input_end_s: float | None = None) -> Path:
    """Fig. 4.2: MCS (top); laughing energy and the clips as blocks of height e(a) (bottom); ``gate`` as in
    :func:`figure_4_1`.

    ``energy_label`` names the green line: the thesis' L under the energy scheduler; another scheduler's
    ``energy`` channel is another quantity (the concat scheduler's: 40 x MCS smoothed over 0.5 s)."""
    fig, (ax1, ax2) = _energy_axes(layout)
    for ax in (ax1, ax2):
        _shade_bouts(ax, bouts)
        shade_run_out(ax, times, input_end_s, not layout.column)
    ax1.plot(times, mcs, color="tab:red", lw=0.8, label="MCS")
    ax1.set_ylabel("MCS")
    ax1.set_ylim(-0.02, 1.05)
    end = float(times[-1]) if len(times) else 0.0
    top = max([e for _, _, _, e in clip_blocks(events, end)] + [float(np.max(energy)) if len(energy) else 1.0, 1.0])
    blocks = _draw_clip_blocks(ax2, events, end, top)
    (line,) = ax2.plot(times, energy, color="tab:green", lw=1.0, label=energy_label)
    short = "L" if energy_label == "laughing energy L" else "energy"
    ax2.set_ylabel(f"{short} / clip energy e(a)" if layout.column else f"{energy_label} /\nclip energy e(a)")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(_energy_floor(energy, top), top * 1.15)
    _set_xlim(ax2, times[0] if len(times) else 0, end or 1)
    head = "Energy and clips (cf. van Duijn 2014, Fig. 4.2)" if layout.column else \
        "Laughing energy and clip selection (cf. van Duijn 2014, Fig. 4.2)"
    ax1.set_title(_head(title or head, hatch_note(note, times, input_end_s, not layout.column), layout), fontsize=layout.title)
    for ax in (ax1, ax2):
        _setup_axis(ax)
    if layout.column:
        thin_ticks(ax1, ax2, x=6, y=3)
    empty = not blocks and not (len(energy) and np.any(energy))
    if empty:   # its line lies on the axis: not in the legend (a review: it named a line one could not see)
        line.set_label(f"_{energy_label}")
    _legend_with_clip_key(fig, [ax2], blocks, layout)
    _label_blocks(fig, ax2, blocks, [line], top, layout.block_label)
    if empty:   # scheduler=none: an empty panel said nothing
        ax2.text(0.5, 0.5, "no laughing energy and no clip in this run", transform=ax2.transAxes,
                 ha="center", va="center", fontsize=layout.side_label, color="0.35")
    _closed_gate_note(ax2, energy, blocks, gate, layout)
    save_figure(fig, path, pdf)
    return path


def _closed_gate_note(ax, energy, blocks, gate, layout: Layout) -> None:
    """Energy rose but no clip played, and the detector's clip gain never opened: said in the panel (a
    researcher's review: L rose to 19 over a Russian laugh between speech, with no clip and no word why)."""
    if gate is None or blocks or not (len(energy) and np.any(energy)) or np.any(np.asarray(gate) > 0):
        return
    ax.text(0.5, 0.96, "no clip: the laughter detector's clip gate stayed closed", transform=ax.transAxes,
            ha="center", va="top", fontsize=layout.side_label, color="0.35")
