"""The schematic face of the video: features on the front of the head sphere, driven by ARKit weights.

See :mod:`laughlab.render.scene` for the table of which weights move which feature.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Callable

import numpy as np

SKIN = (238, 200, 170)
SKIN_DARK = (120, 80, 60)
OUTLINE = (38, 40, 48)
LIP = (150, 60, 60)
MOUTH = (70, 18, 28)
CHEEK = (235, 120, 120)


def _w(weights: dict, name: str) -> float:
    v = weights.get(name, 0.0)
    return float(v) if v == v else 0.0


@lru_cache(maxsize=None)
def _circle(n: int) -> np.ndarray:
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


@lru_cache(maxsize=None)
def _bezier_basis(n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)[:, None]
    return np.concatenate([(1 - t) ** 2, 2 * (1 - t) * t, t ** 2], axis=1)


def _ellipse(cx: float, cy: float, rx: float, ry: float, n: int = 14) -> np.ndarray:
    return _circle(n) * (rx, ry) + (cx, cy)


def _quad(p0, p1, p2, n: int = 8) -> np.ndarray:
    """Points of the quadratic Bezier curve through p0 and p2 whose middle passes through p1."""
    p0, p1, p2 = (np.asarray(p, dtype=np.float64) for p in (p0, p1, p2))
    c = 2 * p1 - 0.5 * (p0 + p2)  # control point so that B(1/2) = p1
    return _bezier_basis(n) @ np.stack([p0, c, p2])


HEAD_RADIUS_CM = 10.0


def _on_head(xy: np.ndarray, lift: float = 0.0) -> np.ndarray:
    """Head-local 3D points on the front of the head sphere (radius 10 cm) at face coordinates ``xy`` (cm)."""
    xy = np.asarray(xy, dtype=np.float64)
    r2 = (HEAD_RADIUS_CM + lift) ** 2 - (xy ** 2).sum(axis=-1)
    z = np.sqrt(np.maximum(r2, 0.0))
    return np.concatenate([xy, z[..., None]], axis=-1)


def draw_face(draw, to_screen: Callable[[np.ndarray], np.ndarray], px_per_cm: float, weights: dict,
              skin=SKIN) -> None:
    """Draw eyes, brows, cheeks, nose and mouth driven by ARKit ``weights`` (floats in [0, 1]).

    Parameters
    ----------
    draw : PIL.ImageDraw.ImageDraw
    to_screen : callable
        Head-local points ``(N, 3)`` (cm; x = the character's left, y up, z out
        of the face) to pixels ``(N, 2)``.
    px_per_cm : float
        Scale for line widths.
    weights : dict
        ARKit name -> value; missing names are 0.
    """
    def poly(xy, fill=None, outline=None, width=0.0, lift=0.0):
        pts = [tuple(p) for p in to_screen(_on_head(xy, lift)).tolist()]
        if fill is not None:
            draw.polygon(pts, fill=fill)
        if outline is not None and width > 0:
            draw.line(pts + [pts[0]], fill=outline, width=max(1, int(round(width * px_per_cm))), joint="curve")

    def line(xy, fill, width, lift=0.0):
        pts = [tuple(p) for p in to_screen(_on_head(xy, lift)).tolist()]
        draw.line(pts, fill=fill, width=max(1, int(round(width * px_per_cm))), joint="curve")

    def mix(a, b, t):
        t = min(1.0, max(0.0, t))
        return tuple(int(round(x + (y - x) * t)) for x, y in zip(a, b))

    for side, s in (("Left", 1.0), ("Right", -1.0)):
        cheek = _w(weights, f"cheekSquint{side}")
        # cheeks: rise and redden with cheekSquint (AU6)
        poly(_ellipse(s * 4.9, -2.0 + 0.9 * cheek, 2.0, 1.5, 12), fill=mix(skin, CHEEK, 0.18 + 0.55 * cheek))
        blink = _w(weights, f"eyeBlink{side}")
        squint = _w(weights, f"eyeSquint{side}")
        openness = (1.0 - blink) * (1.0 - 0.45 * squint)
        ex, ey, hw = s * 3.4, 1.9, 1.55
        if openness > 0.12:
            hh = 1.05 * openness
            poly(_ellipse(ex, ey, hw, hh, 14), fill=(250, 250, 250), outline=OUTLINE, width=0.28)
            pr = min(0.62, hh)
            poly(_ellipse(ex, ey - 0.1, 0.62, pr, 10), fill=(40, 30, 30), lift=0.05)
        else:  # closed lids: an arc bulging upwards (laughing eyes)
            xs = np.linspace(-hw, hw, 7)
            line(np.stack([ex + xs, ey + 0.55 * (1 - (xs / hw) ** 2) - 0.2], axis=-1), OUTLINE, 0.34)
        if cheek > 0.25:  # the lower-lid crease of the raised cheek
            xs = np.linspace(-1.2, 1.2, 5)
            line(np.stack([ex + xs, ey - 1.45 + 0.5 * cheek - 0.25 * (1 - (xs / 1.2) ** 2)], axis=-1),
                 mix(skin, SKIN_DARK, 0.6 * cheek), 0.2)
        # brows: inner end up with browInnerUp, outer with browOuterUp, both down with browDown
        inner = 1.25 * _w(weights, "browInnerUp") - 1.0 * _w(weights, f"browDown{side}")
        outer = 1.0 * _w(weights, f"browOuterUp{side}") - 0.45 * _w(weights, f"browDown{side}")
        by = 4.25
        brow = _quad((s * 1.6, by + inner), (s * 3.4, by + 0.45 + 0.5 * (inner + outer)),
                     (s * 5.2, by - 0.25 + outer), 6)
        line(brow, (70, 50, 40), 0.5)
    # nose
    line(np.array([[0.15, 0.6], [0.55, -1.6], [-0.35, -1.85]]), mix(skin, SKIN_DARK, 0.5), 0.22, lift=0.6)
    # mouth: corners rise with the smile, the lower lip drops with the jaw (less mouthClose)
    smile = 0.5 * (_w(weights, "mouthSmileLeft") + _w(weights, "mouthSmileRight"))
    frown = 0.5 * (_w(weights, "mouthFrownLeft") + _w(weights, "mouthFrownRight"))
    stretch = 0.5 * (_w(weights, "mouthStretchLeft") + _w(weights, "mouthStretchRight"))
    lower = 0.5 * (_w(weights, "mouthLowerDownLeft") + _w(weights, "mouthLowerDownRight"))
    upper = 0.5 * (_w(weights, "mouthUpperUpLeft") + _w(weights, "mouthUpperUpRight"))
    jaw = _w(weights, "jawOpen")
    close = _w(weights, "mouthClose")   # ARKit: the lips closed over the open jaw (face=cgm)
    my = -4.9
    corners = []
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        sm = _w(weights, f"mouthSmile{side}")
        fr = _w(weights, f"mouthFrown{side}")
        corners.append((s * (2.5 + 1.0 * sm + 0.6 * stretch), my + 1.3 * sm - 0.8 * fr - 0.35 * jaw))
    top_y = my + 0.15 + 0.35 * upper + 0.25 * smile
    bot_y = my - 0.15 - 3.4 * max(0.0, jaw - close) - 0.7 * lower + 0.25 * smile - 0.3 * frown
    top = _quad(corners[1], (0.0, top_y), corners[0], 9)
    bottom = _quad(corners[0], (0.0, bot_y), corners[1], 9)
    opening = top_y - bot_y
    poly(np.concatenate([top, bottom[1:-1]]), fill=MOUTH, outline=LIP, width=0.35)
    if opening > 0.9:  # upper teeth under the upper lip
        teeth_h = min(0.8, 0.35 * opening)
        t_top = _quad((corners[1][0] * 0.8, corners[1][1] - 0.05), (0.0, top_y - 0.12),
                      (corners[0][0] * 0.8, corners[0][1] - 0.05), 7)
        t_bot = t_top[::-1] - np.array([0.0, teeth_h])
        poly(np.concatenate([t_top, t_bot]), fill=(245, 245, 240), lift=0.02)
