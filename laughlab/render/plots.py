"""Figures in the style of the thesis (van Duijn 2014): Figs. 3.1, 3.2, 4.1 and 4.2.

Each figure function writes a PNG at ``path`` and, with ``pdf`` (True: ``NAME.pdf`` beside it, or a path), the
same figure as a vector PDF for print (:func:`laughlab.render.savefig.save_figure`)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from laughlab.core.frame import clip_blocks  # noqa: E402,F401 (used here and by the plots sink)
from laughlab.render.savefig import save_figure  # noqa: E402
from laughlab.signals.smoothing import THESIS_TICK_HZ, rate_limit_series  # noqa: E402

#: the two rise/fall settings of the thesis' Fig. 3.2 (per tick): green 0.5/0.3, blue 0.2/0.1
#: Fig. 3.2's rise/fall settings and their colours and line styles: the dashes tell the curves apart in greyscale and
#: for red-green colour blindness (red, green and blue are about as light as each other)
FIG32_SETTINGS = ((0.5, 0.3, "tab:green", "--"), (0.2, 0.1, "tab:blue", ":"))


def _shade_bouts(ax, bouts) -> None:
    for i, b in enumerate(bouts or ()):
        ax.axvspan(b[0], b[1], color="0.9", zorder=0, label="laughter bout (truth)" if i == 0 else None)


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


def _titled(title: str, note: str) -> str:
    """A figure title with a note on what part of the run it shows (e.g. the first 60 s of a long one)."""
    if not note:
        return title
    return f"{title}\n{note}" if len(title) + len(note) > 90 else f"{title}; {note}"


def figure_3_2(path: Path, times: np.ndarray, mcs_raw: np.ndarray, dt: float, power: float = 2.0,
               bouts: Sequence | None = None, title: str = "", window_s: float = 4.0, note: str = "",
               pdf=False) -> Path:
    """Fig. 3.2: the MCS unfiltered and with two rise/fall settings (Eq. 3.2).

    Rates are the thesis' per-tick values converted at 60 ticks/s; all three
    curves are raised to ``power`` like the final MCS (listing 5.2).  Left: the
    whole run; right: the ``window_s`` seconds with the most laughter, where the
    individual calls and the effect of rise and fall can be seen.
    """
    raw = np.asarray(mcs_raw, float)
    curves = [(raw ** power, "tab:red", 0.8, "-", "MCS, no rise/fall")]
    for rise, fall, color, style in FIG32_SETTINGS:
        y = rate_limit_series(raw, rise * THESIS_TICK_HZ, fall * THESIS_TICK_HZ, dt) ** power
        curves.append((y, color, 1.3, style, f"rise {rise}, fall {fall} per tick"))
    fig, (ax_all, ax_zoom) = plt.subplots(1, 2, figsize=(8.0, 2.9), dpi=150, layout="constrained",
                                          width_ratios=(1, 1.6), sharey=True)
    # the zoom: the most laughter inside the truth's bouts when there are any (a review: on a scene of speech and
    # laughter the busiest signal was talk before the first bout), else the most signal anywhere
    inside = np.zeros(len(times), bool)
    for b in bouts or ():
        inside |= (times >= b[0]) & (times <= b[1])
    t0, t1 = busiest_window(times, raw * inside if np.any(raw * inside > 0) else raw, window_s)
    for ax, lo, hi in ((ax_all, times[0] if len(times) else 0, times[-1] if len(times) else 1), (ax_zoom, t0, t1)):
        _shade_bouts(ax, bouts)
        for k, (y, color, lw, style, label) in enumerate(curves if ax is ax_zoom else curves[:1]):
            # the unfiltered signal over the filtered ones, which otherwise hide it where they agree
            ax.plot(times, y, color=color, lw=lw, ls=style, label=label, zorder=3 if k == 0 else 2,
                    alpha=0.75 if k == 0 and ax is ax_zoom else 1.0)
        _set_xlim(ax, lo, hi)
        ax.set_xlabel("time (s)")
        _setup_axis(ax)
    ax_all.axvspan(t0, t1, color="tab:orange", alpha=0.15, lw=0)
    ax_all.set_ylabel("motion control signal")
    ax_all.set_ylim(-0.02, 1.05)
    ax_all.set_title("plotted stretch (zoom shaded)" if note else "whole run (zoom shaded)", fontsize=8)
    ax_zoom.set_title(f"zoom: {t0:.1f}-{t1:.1f} s", fontsize=8)
    fig.suptitle(_titled(title or "Motion control signal and rise/fall (cf. van Duijn 2014, Fig. 3.2)", note),
                 fontsize=9)
    fig.legend(*ax_zoom.get_legend_handles_labels(), fontsize=7, loc="outside lower center", ncols=4,
               frameon=False)
    save_figure(fig, path, pdf)
    plt.close(fig)
    return path


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
    cmap = plt.get_cmap("tab20")
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
        patch = ax.add_patch(plt.Rectangle((t0, 0), t1 - t0, e if e > 0 else ZERO_BLOCK * top,
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


def _label_blocks(fig, ax, blocks, lines, top: float) -> list:
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
            t = place_label(ax, renderer, name, inside, taken, paths, inside=box, fontsize=5.5)
        if t is None:
            others = [b for k, b in enumerate(boxes) if k != i and b.x1 > box.x0 - 80 and b.x0 < box.x1 + 80]
            t = place_label(ax, renderer, name, above, taken, paths, avoid=others, fontsize=5.5)
        if t is not None:
            placed.append(t)
            labelled.setdefault(name, []).append(box.x0)
    return placed


def figure_3_1(path: Path, times: np.ndarray, amp: np.ndarray, params, fps: float, calibration_s: float = 0.0,
               bouts: Sequence | None = None, title: str = "", note: str = "", pdf=False) -> Path:
    """Fig. 3.1: the MCS with min/max amplitude fixed after calibration (left) and drifting (right).

    Both columns run the rms extractor (listing 5.2) again on the run's
    amplitudes (:func:`laughlab.signals.mcs.replay`): left with no falloff, so
    a loud calibration burst keeps later laughter mapped low; right with the
    run's falloff (thesis: 0.001 per tick), maxAmp and minAmp drifting towards
    each other.  Top: the amplitude (grey) and the band from minAmp to maxAmp
    (blue, the thesis' "blue area"); bottom: the final MCS (red).
    """
    from dataclasses import replace

    from laughlab.signals.mcs import replay

    cal = {"calibration_s": calibration_s} if params.calibration_s is None else {}
    fixed = replay(amp, replace(params, falloff_per_s=0.0, **cal), fps)
    drift = replay(amp, replace(params, **cal), fps)
    fig, axes = plt.subplots(2, 2, figsize=(8.0, 4.4), dpi=150, sharex=True, sharey="row", layout="constrained",
                             height_ratios=(1.2, 1))
    unit = "amplitude\n(dB, 10 log10 RMS)" if params.scale == "loudness" else "amplitude\n(RMS, full scale)"
    fixed_label = "min/max fixed after calibration (no falloff)" if calibration_s > 0 else "min/max fixed (no falloff)"
    for col, (run, label) in enumerate(((fixed, fixed_label),
                                        (drift, f"min/max drifting (falloff {params.falloff_per_s:g} /s)"))):
        top, bottom = axes[0, col], axes[1, col]
        for ax in (top, bottom):
            _shade_bouts(ax, bouts)
            if calibration_s > 0:
                ax.axvspan(times[0], times[0] + calibration_s, color="tab:orange", alpha=0.15, lw=0,
                           label="calibration")
            _setup_axis(ax)
        top.fill_between(times, run["min_amp"], run["max_amp"], color="tab:blue", alpha=0.2, lw=0,
                         label="minAmp .. maxAmp")
        top.plot(times, amp, color="0.45", lw=0.5, label="amplitude")
        bottom.plot(times, run["mcs"], color="tab:red", lw=0.8, label="MCS")
        bottom.set_ylim(-0.02, 1.05)
        bottom.set_xlabel("time (s)")
        top.set_title(label, fontsize=8)
    # the plotted stretch, not the truth's bouts past it (a recording longer than output.plots.max_seconds)
    _set_xlim(axes[1, 0], times[0] if len(times) else 0.0, times[-1] if len(times) else 1.0)
    lo = float(np.min(amp)) if len(amp) else 0.0
    axes[0, 0].set_ylim(max(lo, float(np.percentile(amp, 1)) - 3) if len(amp) else 0, None)
    axes[0, 0].set_ylabel(unit)   # two lines at the axes' size (a review: one line at 7 pt read as a footnote)
    axes[1, 0].set_ylabel("MCS")
    fig.suptitle(_titled(title or "Calibration and min/max falloff (cf. van Duijn 2014, Fig. 3.1)", note),
                 fontsize=9)
    handles = {}
    for ax in (axes[0, 0], axes[1, 0]):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles), fontsize=7, loc="outside lower center", ncols=5, frameon=False)
    save_figure(fig, path, pdf)
    plt.close(fig)
    return path


def figure_4_1(path: Path, times: np.ndarray, mcs: np.ndarray, energy: np.ndarray, events: Sequence,
               gain_per_s: float, bouts: Sequence | None = None, title: str = "", note: str = "",
               pdf=False) -> Path:
    """Fig. 4.1: MCS (top); the primitive of the MCS, the actual laughing energy and the clips (bottom).

    The primitive ``sum(gain_per_s * MCS * dt)`` is the laughing energy with no
    clip consuming and no fixed decrease (the thesis' blue line); it grows
    without bound, so it has its own axis on the right.  The green line is the
    run's energy L, the blocks the clips played (height e(a), width their time).
    """
    times = np.asarray(times, float)
    dt = float(times[1] - times[0]) if len(times) > 1 else 0.0
    primitive = np.cumsum(np.asarray(mcs, float) * gain_per_s * dt)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.0, 4.2), dpi=150, sharex=True, layout="constrained",
                                   height_ratios=(1, 2))
    for ax in (ax1, ax2):
        _shade_bouts(ax, bouts)
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
    ax2.set_ylabel("laughing energy L /\nclip energy e(a)")
    ax2.set_xlabel("time (s)")
    axp = ax2.twinx()
    (prim,) = axp.plot(times, primitive, color="tab:blue", lw=1.0, ls="--",   # dashed: as light as the green
                       label="primitive of the MCS (right axis)")
    axp.set_ylim(0, max(1.0, float(primitive[-1]) if len(primitive) else 1.0) * 1.05)
    axp.set_ylabel("primitive of MCS", color="tab:blue", fontsize=8)
    axp.tick_params(axis="y", colors="tab:blue", labelsize=7)
    axp.spines[["top"]].set_visible(False)
    ax1.set_title(_titled(title or "The laughing energy process (cf. van Duijn 2014, Fig. 4.1)", note), fontsize=9)
    _legend_with_clip_key(fig, [ax2, axp], blocks)
    _label_blocks(fig, ax2, blocks, [line, prim], top)
    save_figure(fig, path, pdf)
    plt.close(fig)
    return path


def _legend_with_clip_key(fig, axes, blocks, max_cols: int = 7) -> None:
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
    rows = max(len(labels), 1, -(-(len(labels) + len(kl)) // max_cols))
    while len(labels) < rows:  # the clips start a column of their own
        handles.append(Patch(visible=False))
        labels.append("")
    handles, labels = handles + kh, labels + kl
    fig.legend(handles, labels, fontsize=6.5, loc="outside lower center", ncols=-(-len(labels) // rows),
               frameon=False, handlelength=1.4, columnspacing=1.0, handletextpad=0.5)


def figure_4_2(path: Path, times: np.ndarray, mcs: np.ndarray, energy: np.ndarray, events: Sequence,
               bouts: Sequence | None = None, title: str = "", note: str = "",
               energy_label: str = "laughing energy L", pdf=False) -> Path:
    """Fig. 4.2: MCS (top); laughing energy and the clips as blocks of height e(a) (bottom).

    ``energy_label`` names the green line: the thesis' L under the energy scheduler; another scheduler's
    ``energy`` channel is another quantity (the concat scheduler's: 40 x MCS smoothed over 0.5 s)."""
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.0, 4.2), dpi=150, sharex=True, layout="constrained",
                                   height_ratios=(1, 2))
    _shade_bouts(ax1, bouts)
    _shade_bouts(ax2, bouts)
    ax1.plot(times, mcs, color="tab:red", lw=0.8, label="MCS")
    ax1.set_ylabel("MCS")
    ax1.set_ylim(-0.02, 1.05)
    end = float(times[-1]) if len(times) else 0.0
    top = max([e for _, _, _, e in clip_blocks(events, end)] + [float(np.max(energy)) if len(energy) else 1.0, 1.0])
    blocks = _draw_clip_blocks(ax2, events, end, top)
    (line,) = ax2.plot(times, energy, color="tab:green", lw=1.0, label=energy_label)
    ax2.set_ylabel(f"{energy_label} /\nclip energy e(a)")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(_energy_floor(energy, top), top * 1.15)
    _set_xlim(ax2, times[0] if len(times) else 0, end or 1)
    ax1.set_title(_titled(title or "Laughing energy and clip selection (cf. van Duijn 2014, Fig. 4.2)", note),
                  fontsize=9)
    for ax in (ax1, ax2):
        _setup_axis(ax)
    _legend_with_clip_key(fig, [ax2], blocks)
    _label_blocks(fig, ax2, blocks, [line], top)
    if not blocks and not (len(energy) and np.any(energy)):   # scheduler=none: an empty panel said nothing
        ax2.text(0.5, 0.5, "no laughing energy and no clip in this run", transform=ax2.transAxes,
                 ha="center", va="center", fontsize=8, color="0.35")
    save_figure(fig, path, pdf)
    plt.close(fig)
    return path


def filmstrip_moments(times: np.ndarray, positions: np.ndarray, n: int, blocks: Sequence = ()) -> list[int]:
    """Which of the pose samples a filmstrip of ``n`` figures shows: distinct, telling moments.

    A sample's *pronouncedness* is how far its pose lies from the run's usual pose (the
    per-joint median over every sample; distance: the mean over joints, cm).

    1. One figure per clip played (``idle`` and clips of energy 0 aside): the most pronounced
       sample inside the clip's longest block.  With more clips than ``n``, the clips with the
       longest blocks.
    2. Figures left over, one at a time: the stretch from the first to the last sample is cut
       into ``n`` equal parts; among the samples in parts with no figure yet and at least half
       a part away from every figure chosen, the one least like the figures chosen (the
       largest distance to the nearest of their poses; the most pronounced one if none is
       chosen yet).

    So an energy run, whose clips last seconds, shows each clip once; a concatenation run,
    which plays hundreds of short segments of a few clips, shows each of those clips and
    then the poses least like them, spread over the run.

    Parameters
    ----------
    times : ndarray, shape (k,)
        The samples' times (s), increasing.
    positions : ndarray, shape (k, J, 3)
        Their world joint positions (cm).
    n : int
    blocks : sequence of (clip, start_s, stop_s, energy)
        The clips played (:func:`laughlab.core.frame.clip_blocks`).

    Returns
    -------
    list of int
        Indices into ``times``, increasing, at most ``n``, all different (so all times differ).
    """
    times = np.asarray(times, float)
    k = len(times)
    if k == 0 or n <= 0:
        return []
    pos = np.asarray(positions, float).reshape(k, -1, 3)
    away = np.linalg.norm(pos - np.median(pos, axis=0), axis=2).mean(axis=1)
    longest: dict = {}
    for name, b0, b1, e in blocks:
        if e > 0 and name != "idle" and (name not in longest or b1 - b0 > longest[name][1] - longest[name][0]):
            longest[name] = (b0, b1)
    picked: list[int] = []
    for name, (b0, b1) in sorted(longest.items(), key=lambda kv: (kv[1][0] - kv[1][1], kv[1][0])):
        idx = np.flatnonzero((times >= b0) & (times < b1))
        idx = idx[~np.isin(idx, picked)]
        if len(idx) and len(picked) < n:
            picked.append(int(idx[np.argmax(away[idx])]))
    t0, t1 = float(times[0]), float(times[-1])
    part = (t1 - t0) / n if t1 > t0 else 1.0
    which = np.minimum(((times - t0) / part).astype(int), n - 1)
    flat = pos.reshape(k, -1, 3)
    while len(picked) < n:
        free = ~np.isin(which, which[picked]) if picked else np.ones(k, bool)
        for j in picked:
            free &= np.abs(times - times[j]) >= 0.5 * part
        idx = np.flatnonzero(free)
        if not len(idx):
            break
        if picked:  # the pose least like any shown: the largest distance to its nearest shown pose
            d = np.stack([np.linalg.norm(flat[idx] - flat[j], axis=2).mean(axis=1) for j in picked])
            score = d.min(axis=0)
        else:
            score = away[idx]
        picked.append(int(idx[np.argmax(score)]))
    return sorted(picked)


def filmstrip(path: Path, skeleton, times: np.ndarray, poses: np.ndarray, captions: Sequence[str],
              title: str = "", note: str = "", pdf=False) -> Path:
    """A row of stick figures (the run's skeleton at chosen frames) with a caption under each."""
    from laughlab.render.figure import draw_skeleton
    from laughlab.motion.skeleton import forward_kinematics

    import textwrap

    from laughlab.render.figure import SIDE_KEY

    n = len(times)
    width = 1.25 * max(n, 1)
    # the title and the colours' key, wrapped to the figure's width (a strip of 3 cut a one-line title at both
    # edges); each line more makes the figure taller, the panels keeping their size
    chars = int(width * 72 / (0.6 * 8))   # DejaVu Sans at 8 pt: about 0.55 em a character on average
    head = _titled(title or "The character over the run (skeleton from motion.bvh)", note) + f". {SIDE_KEY}"
    lines = [w for para in head.split("\n") for w in textwrap.wrap(para, chars)]
    extra = 0.14 * (len(lines) - 1)
    height = 2.0 + extra
    fig, axes = plt.subplots(1, max(n, 1), figsize=(width, height), dpi=150, squeeze=False)
    if n:
        pos = forward_kinematics(skeleton, np.asarray(poses), end_sites=True)
    for k, ax in enumerate(axes[0]):
        ax.set_axis_off()
        if k >= n:
            continue
        draw_skeleton(ax, skeleton, pos[k, :skeleton.n_joints], pos[k, skeleton.n_joints:], 60.0, 10.0, lw=1.4)
        ax.set_xlim(-110, 110)
        ax.set_ylim(-8, 195)
        ax.set_title(f"{times[k]:.1f} s", fontsize=7, pad=1)
        ax.text(0.5, -0.02, captions[k], transform=ax.transAxes, ha="center", va="top", fontsize=5.5)
    fig.suptitle("\n".join(lines), fontsize=8)
    fig.subplots_adjust(left=0.01, right=0.99, top=1 - (0.32 + extra) / height, bottom=0.4 / height, wspace=0.05)
    save_figure(fig, path, pdf)
    plt.close(fig)
    return path
