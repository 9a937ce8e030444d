"""Stick-figure drawings of skeleton poses.

:func:`contact_sheet` renders with matplotlib's Agg canvas through a bare
``matplotlib.figure.Figure`` (no pyplot, so the global backend is untouched).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from laughlab.motion.skeleton import Skeleton, forward_kinematics

__all__ = ["project", "draw_skeleton", "contact_sheet"]

_SIDE_COLORS = {"left": "tab:blue", "right": "tab:red"}
#: what the colours of :func:`draw_skeleton` mean, for a figure's title or caption
SIDE_KEY = "Blue: the left arm and leg; red: the right"


def project(points: np.ndarray, azimuth_deg: float = 35.0, elevation_deg: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Orthographic view of world points (cm).

    The camera looks at the character's front (+Z faces the viewer) after
    turning the figure by ``azimuth_deg`` about Y and tilting the view down by
    ``elevation_deg``.

    Returns
    -------
    xy : ndarray, shape (..., 2)
        Screen coordinates, cm.
    depth : ndarray, shape (...,)
        Larger is closer to the viewer.
    """
    p = np.asarray(points, dtype=np.float64)
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    x = p[..., 0] * np.cos(a) + p[..., 2] * np.sin(a)
    z = -p[..., 0] * np.sin(a) + p[..., 2] * np.cos(a)
    y = p[..., 1] * np.cos(e) - z * np.sin(e)
    depth = z * np.cos(e) + p[..., 1] * np.sin(e)
    return np.stack([x, y], axis=-1), depth


def draw_skeleton(ax, skeleton: Skeleton, positions: np.ndarray, end_positions: np.ndarray | None = None,
                  azimuth_deg: float = 35.0, elevation_deg: float = 10.0, lw: float = 2.0,
                  head_radius_cm: float = 10.0, alpha: float = 1.0, floor: bool = True) -> None:
    """Draw one pose as a stick figure with a head circle.

    Parameters
    ----------
    ax : matplotlib Axes
    skeleton : Skeleton
    positions : ndarray, shape (J, 3)
        World joint positions, cm (from :func:`forward_kinematics`).
    end_positions : ndarray, shape (n_leaves, 3), optional
        End Site positions (``forward_kinematics(..., end_sites=True)[J:]``);
        drawn as hand/foot/head tips when given.
    azimuth_deg, elevation_deg : float
        View angles, see :func:`project`.
    lw : float
        Line width, points.
    head_radius_cm : float
    alpha : float
    floor : bool
        Draw the floor line ``y = 0``.
    """
    pts = np.asarray(positions, dtype=np.float64)
    # segments (parent point, child point, colour-giving joint name)
    segs = [(p, j, skeleton.names[j]) for j, p in enumerate(skeleton.parents) if p >= 0]
    if end_positions is not None:
        pts = np.concatenate([pts, end_positions])
        segs += [(j, skeleton.n_joints + k, skeleton.names[j]) for k, j in enumerate(skeleton.leaves())
                 if skeleton.names[j] != "head"]  # the head circle replaces the head End Site
    xy, depth = project(pts, azimuth_deg, elevation_deg)
    dmin, dmax = depth.min(), depth.max() + 1e-9
    for a, b, name in segs:
        side = name.split("_")[0]
        d = 0.5 * (depth[a] + depth[b])
        ax.plot(xy[[a, b], 0], xy[[a, b], 1], color=_SIDE_COLORS.get(side, "0.15"), lw=lw,
                solid_capstyle="round", alpha=alpha, zorder=2 + (d - dmin) / (dmax - dmin))
    if "head" in skeleton.names:
        h = skeleton.index("head")
        up = pts[h] - pts[skeleton.parents[h]]
        centre = pts[h] + up / (np.linalg.norm(up) + 1e-9) * head_radius_cm
        cxy, cd = project(centre, azimuth_deg, elevation_deg)
        ax.add_patch(Circle(tuple(cxy), head_radius_cm, fill=True, fc="white", ec="0.15", lw=lw,
                            alpha=alpha, zorder=2 + (cd - dmin) / (dmax - dmin)))
    if floor:
        ax.axhline(0.0, color="0.6", lw=0.8, zorder=1)
    ax.set_aspect("equal")


def contact_sheet(path: str | Path, library, n_frames: int = 6, azimuth_deg: float = 65.0,
                  elevation_deg: float = 12.0, dpi: int = 80) -> Path:
    """Write a PNG grid of stick figures: one row per clip, frames spread over its length.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    library : ClipLibrary
    n_frames : int
        Columns per row (first and last frame included).
    azimuth_deg, elevation_deg : float
        View angles, see :func:`project`.
    dpi : int

    Returns
    -------
    Path
    """
    clips = list(library)
    sk = library.skeleton
    fig = Figure(figsize=(1.7 * n_frames, 2.0 * len(clips)))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(clips), n_frames, squeeze=False)
    for row, clip in zip(axes, clips):
        frames = np.unique(np.round(np.linspace(0, clip.length_frames - 1, n_frames)).astype(int))
        pos = forward_kinematics(sk, clip.poses[frames], end_sites=True)
        for k, ax in enumerate(row):
            ax.set_axis_off()
            if k >= len(frames):
                continue
            draw_skeleton(ax, sk, pos[k, :sk.n_joints], pos[k, sk.n_joints:], azimuth_deg, elevation_deg, lw=1.6)
            ax.set_xlim(-110, 110)
            ax.set_ylim(-8, 195)
            t = frames[k] / clip.fps
            eyes = "closed" if clip.eyes_closed(t) > 0.5 else "open"
            ax.set_title(f"f{frames[k]}  eyes {eyes}", fontsize=7, pad=1)
        row[0].text(-0.02, 0.5, f"{clip.name}\nE={clip.energy:g}\n{clip.length_frames} fr",
                    transform=row[0].transAxes, ha="right", va="center", fontsize=8)
    fig.subplots_adjust(left=0.1, right=0.99, top=0.98, bottom=0.01, wspace=0.02, hspace=0.15)
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path
