"""The run's filmstrip (``plots/filmstrip.png``): stick figures of the character at telling moments of a run."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from laughlab.render.layout import PAGE, Layout, in_layout, titled, wrapped
from laughlab.render.savefig import new_figure, save_figure


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


#: a filmstrip's least width on a page (in): its title on 2-3 lines, however few its figures
MIN_PAGE_IN = 5.0


@in_layout
def filmstrip(path: Path, skeleton, times: np.ndarray, poses: np.ndarray, captions: Sequence[str],
              title: str = "", note: str = "", pdf=False, layout: Layout = PAGE) -> Path:
    """Stick figures (the run's skeleton at chosen frames) with a caption under each: one row of 1.25 in a
    figure, or (``layout="column"``) rows of :attr:`Layout.strip_cols` across the column, each caption's parts
    (``, ``) on lines of their own and a part too long for its figure cut short with an ellipsis."""
    from laughlab.motion.skeleton import forward_kinematics
    from laughlab.render.figure import SIDE_KEY, draw_skeleton

    n = len(times)
    cols = max(1, min(n, layout.strip_cols) if layout.strip_cols else n)
    rows = -(-max(n, 1) // cols)
    # on a page 1.25 in a figure, and at least MIN_PAGE_IN wide, the figures in its middle: a strip of one (a run of
    # 0.2 s) was 1.25 in wide, its title wrapped to 7 lines of 2 words (a new-user review)
    strip_in = 1.25 * max(n, 1)
    width = layout.width_in if layout.column else max(strip_in, MIN_PAGE_IN)
    # the title and the colours' key, wrapped to the figure's width (a strip of 3 cut a one-line title at both
    # edges); each line more makes the figure taller, the panels keeping their size
    head = titled(title or "The character over the run (skeleton from motion.bvh)", note) + f". {SIDE_KEY}"
    lines = wrapped(head, width, layout.strip_title).split("\n")
    if layout.column:
        fits = int(width / cols * 72 / (0.6 * layout.caption))   # characters a caption's line may have
        captions = ["\n".join(p if len(p) <= fits else p[:fits - 1] + "\u2026"
                               for p in c.replace(", ", "\n").split("\n")) for c in captions]
        lines_under = max([c.count("\n") + 1 for c in captions] or [1])
        panel, gap = 0.82 * width / cols, (lines_under * 1.25 * layout.caption + 2.0 * layout.frame_title) / 72
        title_in = 1.6 * layout.frame_title / 72   # a figure's time above it
        top_in, bottom_in = 0.08 + 0.135 * len(lines) + title_in, gap - title_in
        height = top_in + rows * panel + (rows - 1) * gap + bottom_in
        adjust = dict(hspace=gap / panel, top=1 - top_in / height, bottom=bottom_in / height)
    else:
        extra = 0.14 * (len(lines) - 1)
        height = 2.0 + extra
        adjust = dict(top=1 - (0.32 + extra) / height, bottom=0.4 / height)
    fig, axes = new_figure(rows, cols, figsize=(width, height), dpi=150, squeeze=False)
    if n:
        pos = forward_kinematics(skeleton, np.asarray(poses), end_sites=True)
    for k, ax in enumerate(axes.flat):
        ax.set_axis_off()
        if k >= n:
            continue
        draw_skeleton(ax, skeleton, pos[k, :skeleton.n_joints], pos[k, skeleton.n_joints:], 60.0, 10.0, lw=1.4)
        ax.set_xlim(-110, 110)
        ax.set_ylim(-8, 195)
        ax.set_title(f"{times[k]:.1f} s", fontsize=layout.frame_title, pad=1)
        ax.text(0.5, -0.02, captions[k], transform=ax.transAxes, ha="center", va="top", fontsize=layout.caption)
    fig.suptitle("\n".join(lines), fontsize=layout.strip_title)
    side = 0.01 if layout.column else (0.01 * strip_in + (width - strip_in) / 2) / width
    fig.subplots_adjust(left=side, right=1 - side, wspace=0.05, **adjust)
    save_figure(fig, path, pdf)
    return path
