"""Experiment ``fourier_blend``: Unuma et al. (1995) Eq. 3 between calm and intense laughter.

``python -m laughlab experiment=fourier_blend`` writes into the run directory:

* ``plots/fig3_blend.png`` -- in the manner of Unuma et al.'s Fig. 3: one
  joint's angle over one (rescaled) period of the calm (``s = 0``) and intense
  (``s = 1``) motions of the ``fourier`` body driver, interpolated (``s = 0.5``)
  and extrapolated (``s = -0.5, 1.5``), for the slow layer (torso rocking) and
  the call-rate layer (shoulder shake), with side views of the figure;
* ``plots/fig3_transition.png`` -- a transition (Eq. 3 with ``s`` varying in
  time, extrapolating at the end): ``s(t)``, the layers' periods and the
  driver's offsets;
* the outputs of an ordinary run with ``body=fourier`` (``channels.csv``,
  ``events.csv``, ``motion.bvh``, ``metrics.json``, ``plots/``) on the first
  input of ``harness.corpus``, composed exactly as the harness composes a trial
  (the command line's overrides, the condition's, the input's, the seed).
  With several conditions each run goes to ``runs/<condition>/``.

The module defines ``run(cfg, out_dir)``, which replaces the trial harness.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from omegaconf import OmegaConf

#: degrees -> a readable label of a channel
_AXIS_WORDS = {"X": "pitch (X)", "Y": "turn (Y)", "Z": "roll (Z)"}


def _driver(body_cfg, fps: float):
    """The ``fourier`` body driver built from a config section (its defaults when None)."""
    from laughlab.core import plugins
    from laughlab.core.bases import Context

    values = {} if body_cfg is None else body_cfg
    info = plugins.get("body", "fourier")
    params = plugins.make_params(info.obj, values, "body.fourier")
    return info.obj(params, Context(fps=float(fps)))


def _label(channel: str) -> str:
    joint, axis = channel.rsplit("_", 1)
    return f"{joint} {_AXIS_WORDS.get(axis[0], axis)}"


def figure_3(path: Path, body, s_values, panels) -> Path:
    """Unuma Fig. 3-style plot: Eq. 3 over one rescaled period at each ``s``, and side views.

    Parameters
    ----------
    path : Path
    body : FourierBody
    s_values : list of float
    panels : list of ``"layer:channel"`` (e.g. ``sway:spine2_Xrotation``)
    """
    from laughlab.motion.clips import ClipLibrary
    from laughlab.render.figure import draw_skeleton
    from laughlab.motion.skeleton import forward_kinematics
    from laughlab_plugins.body_fourier import JOINTS

    theta = np.linspace(0.0, 2.0 * np.pi, 241)
    colors = _s_colors(s_values)
    fig = Figure(figsize=(5.0 * len(panels), 8.0), dpi=110)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, len(s_values), height_ratios=[1.0, 1.0])
    for k, spec in enumerate(panels):
        layer, channel = spec.split(":", 1)
        tr = body.layers[layer]
        c = tr.channels.index(channel)
        step = body.params.shake_step if layer == "shake" else body.params.sway_step
        ax = fig.add_subplot(grid[0, :]) if len(panels) == 1 else fig.add_subplot(_half(grid, k, len(panels)))
        for s, col in zip(s_values, colors):
            y = np.array([tr.value(s, th, mean=False)[c] for th in theta]) * step
            ax.plot(theta / (2 * np.pi), y, color=col, lw=2.2 if s in (0.0, 1.0) else 1.3,
                    ls="-" if 0.0 <= s <= 1.0 else "--", label=f"s = {s:g}  (T = {tr.period(s):.2f} s)")
        ax.axhline(0.0, color="0.7", lw=0.6)
        ax.set_xlabel("rescaled time t / 2\u03c0 (one period)")
        ax.set_ylabel("offset (deg)")
        ax.set_title(f"{layer} layer: {_label(channel)}", fontsize=10)
        ax.legend(fontsize=7, loc="upper right", frameon=False)
        ax.spines[["top", "right"]].set_visible(False)
    # side views of the figure over one sway period at each s (Unuma's Fig. 3 shows the walks)
    lib = ClipLibrary.load()
    sk = lib.skeleton
    base = lib.idle.poses[0]
    cols = [3 + 3 * sk.index(j) + a for j in JOINTS for a in range(3)]
    slow = "sway" if "sway" in body.layers else next(iter(body.layers))
    for i, (s, col) in enumerate(zip(s_values, colors)):
        ax = fig.add_subplot(grid[1, i])
        ax.set_axis_off()
        poses = []
        for th in np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False):
            # the fast layer at the phase it has when the slow one is at th (stills of the motion)
            off = body.offsets(s, {name: th if name == slow else th * body.layers[slow].period(s) / tr.period(s)
                                   for name, tr in body.layers.items()})
            pose = base.copy()
            pose[cols] += off
            poses.append(pose)
        pos = forward_kinematics(sk, np.array(poses), end_sites=True)
        for p in pos:
            draw_skeleton(ax, sk, p[:sk.n_joints], p[sk.n_joints:], 90.0, 5.0, lw=1.0, alpha=0.35, floor=False)
        ax.set_xlim(-45, 45)
        ax.set_ylim(-2, 192)   # the whole figure: cropped at the hips, the legs looked cut off
        ax.set_title(f"s = {s:g}: 8 stills over\none {slow} period (side view)", fontsize=8, color=col)
    fig.suptitle("Eq. 3 between calm (s = 0) and intense (s = 1) laughter; s < 0 and s > 1 extrapolate "
                 "(cf. Unuma et al. 1995, Fig. 3)", fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.99, top=0.92, bottom=0.02, hspace=0.25, wspace=0.3)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _half(grid, k: int, n: int):
    """The k-th of n side-by-side panels across the top row of ``grid``."""
    from matplotlib.gridspec import GridSpecFromSubplotSpec

    sub = GridSpecFromSubplotSpec(1, n, subplot_spec=grid[0, :], wspace=0.25)
    return sub[0, k]


def _s_colors(s_values) -> list:
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    lo, hi = min(s_values), max(s_values)
    return [cmap(0.9 * (s - lo) / (hi - lo or 1.0)) for s in s_values]


def transition_figure(path: Path, body, times, values, fps: float, channels) -> Path:
    """A transition: ``s(t)`` through the knots ``(times, values)``, the periods and the driver's offsets."""
    from laughlab_plugins.body_fourier import CHANNELS

    t_end = float(times[-1])
    t = np.arange(int(round(t_end * fps))) / fps
    s = np.interp(t, times, values)
    body.reset()
    out = body.play(s)
    fig = Figure(figsize=(10, 7.5), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2 + len(channels), 1, sharex=True)
    ax = axes[0]
    ax.plot(t, s, color="k", lw=1.5, label="s (Eq. 3)")
    ax.axhspan(0, 1, color="0.93", zorder=0)
    ax.set_ylabel("s")
    ax.text(0.2, 0.97, "shaded: 0 <= s <= 1 (interpolation); outside: extrapolation", transform=ax.transAxes,
            fontsize=7, ha="left", va="top")
    ax2 = ax.twinx()
    for name, tr in body.layers.items():
        ax2.plot(t, [tr.period(v) for v in s], lw=1.0, ls="--", label=f"period of {name}")
    periods = [tr.period(v) for tr in body.layers.values() for v in s]
    # a log scale: the layers' periods differ tenfold (sway about 1-4 s, shake a fraction of a second), and on
    # a linear one from 0 the shake's line lay on the axis and on s = 0 (a review)
    ax2.set_yscale("log")
    lo, hi = min(periods) / 1.6, max(periods) * 1.6
    ax2.set_ylim(lo, hi)
    ax2.set_yticks([v for v in (0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20) if lo <= v <= hi], minor=False)
    ax2.set_yticks([], minor=True)
    ax2.yaxis.set_major_formatter("{x:g}")
    ax2.set_ylabel("blended period T (s, log scale)")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="center left", frameon=False)
    axes[1].plot(t, out["chest"], lw=0.8, label="chest")
    axes[1].plot(t, out["belly"], lw=0.8, label="belly")
    axes[1].set_ylabel("shape weight")
    axes[1].legend(fontsize=7, loc="upper left", ncol=2, frameon=False)
    for ax, ch in zip(axes[2:], channels):
        ax.plot(t, out["offsets"][:, CHANNELS.index(ch)], lw=0.8)
        ax.set_ylabel(f"{_label(ch)}\n(deg)", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    for ax in axes:
        ax.spines[["top"]].set_visible(False)
    fig.suptitle("Transition calm -> intense -> exaggerated -> calm (Eq. 3 with time-varying s; "
                 "phase advances with real time)", fontsize=10)
    fig.subplots_adjust(left=0.12, right=0.9, top=0.94, bottom=0.07, hspace=0.15)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def render_runs(cfg, out_dir: Path, base_overrides: list[str]) -> dict:
    """An ordinary run per condition on the corpus' first input; returns ``{condition: metrics}``."""
    from laughlab.core import pipeline
    from laughlab.harness.corpus import build_corpus
    from laughlab.harness.runner import _compose, check_conditions

    h = OmegaConf.to_container(cfg.harness, resolve=True)
    conditions = check_conditions(h.get("conditions"))
    item = build_corpus(h.get("corpus") or {})[0]
    seed = item.seed if item.seed is not None else int((h.get("run_seeds") or [0])[0])
    out = {}
    for cond, ov in conditions.items():
        run_dir = out_dir if len(conditions) == 1 else out_dir / "runs" / cond
        run_dir.mkdir(parents=True, exist_ok=True)
        # the synthetic input's audio is kept (the trials drop it): the run folder is one to watch (``view``)
        keep = ["input.save_audio=true" if o == "input.save_audio=false" else o for o in item.overrides]
        run_cfg = _compose([*base_overrides, *ov, *keep, f"seed={seed}", "output=files"])
        pipe = pipeline.build(run_cfg)
        out[cond] = pipeline.execute(pipe, run_dir, OmegaConf.to_container(run_cfg, resolve=True))
    return out


def run(cfg, out_dir) -> dict:
    """The experiment: Fig. 3-style blend plot, transition plot, and an ordinary ``body=fourier`` run."""
    from laughlab.harness.experiment import _task_overrides

    out_dir = Path(out_dir)
    h = OmegaConf.to_container(cfg.harness, resolve=True)
    body_cfg = cfg.get("body")
    body_cfg = body_cfg if body_cfg is not None and body_cfg.get("name") == "fourier" else None
    fps = float(cfg.get("fps", 60))
    metrics = render_runs(cfg, out_dir, _task_overrides())
    body = _driver(body_cfg, fps)
    s_values = [float(v) for v in h.get("blend_s", [-0.5, 0.0, 0.5, 1.0, 1.5])]
    panels = [p for p in h.get("fig3_panels", ["sway:spine2_Xrotation", "shake:left_clavicle_Zrotation"])
              if p.split(":", 1)[0] in body.layers]
    fig3 = figure_3(out_dir / "plots" / "fig3_blend.png", body, s_values, panels)
    tr = h.get("transition", {})
    knots = tr.get("knots", [[0, 0], [1, 0], [4, 1], [6, 1], [8, 1.5], [10, 1.5], [12, 0]])
    times, values = zip(*knots)
    trans = transition_figure(out_dir / "plots" / "fig3_transition.png", body, times, values, fps,
                              tr.get("channels", ["spine2_Xrotation", "left_clavicle_Zrotation"]))
    print(f"fourier_blend: {fig3}, {trans}; run outputs in {out_dir}")
    return {"experiment": h.get("name", "fourier_blend"), "plots": [str(fig3), str(trans)], "runs": metrics}
