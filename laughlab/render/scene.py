"""Rendering a run as video: the character in perspective, a schematic face, and MP4 encoding.

Drawing
-------
Frames are drawn with Pillow's ``ImageDraw`` on a pre-rendered background
(sky gradient, floor with a perspective grid), one frame in a few
milliseconds; no matplotlib per frame.

* **Camera** (:class:`Camera`): a pinhole camera (true perspective) on a
  sphere around a target point on the character's vertical axis: azimuth
  (0 = straight in front, positive = towards the character's left), elevation,
  distance and vertical field of view.  A world point ``P`` (cm, the skeleton's
  frame: Y up, the character faces +Z) is seen at
  ``(W/2 + f x_c / z_c, H/2 - f y_c / z_c)`` with ``f = (H/2) / tan(fov/2)``,
  ``(x_c, y_c, z_c)`` its coordinates in the camera frame.
* **Figure** (:class:`Renderer`): limbs as capsules whose width shrinks with
  distance (the character's left side blue, right side red, as in
  :mod:`laughlab.render.figure`), a torso outline through the spine joints whose
  chest and belly widen and bulge with the ``chest`` and ``belly`` body
  channels (breathing shows), a head whose chin drops with the jaw; items are
  painted far to near.
* **Face** (:func:`draw_face`): features laid on the front of the head sphere
  (head-local coordinates, so they turn and foreshorten with the head and are
  hidden when it faces away), driven by ARKit weights
  (:func:`laughlab.io.vmc.arkit_weights`: a face's ``arkit.*`` channels, or the
  ``smile`` face's smile/jaw/eyes mapped to ARKit names):

  ========================== =================================================
  mouth                      opens with ``jawOpen`` (+ ``mouthLowerDown``),
                             corners rise and widen with ``mouthSmile``, drop
                             with ``mouthFrown``, widen with ``mouthStretch``;
                             upper teeth show when open
  cheeks                     rise and redden with ``cheekSquint``
  eyes                       close with ``eyeBlink``, narrow with ``eyeSquint``;
                             closed eyes are drawn as lid arcs
  brows                      inner ends rise with ``browInnerUp``, outer ends
                             with ``browOuterUp``; lower with ``browDown``
  ========================== =================================================

* **Face inset** (van Duijn 2014, 6.1: "an extra view that is zoomed in on the
  face"): the same face drawn large and frontal in a corner box, as a camera
  that follows the head would see it.

Encoding
--------
:class:`VideoEncoder` pipes raw RGB frames into ffmpeg (the binary shipped by
imageio-ffmpeg): H.264 (libx264), yuv420p, constant frame rate, AAC audio
from a WAV file, MP4 with ``+faststart``.  The flags ``-fflags +bitexact
-flags:v +bitexact -flags:a +bitexact -map_metadata -1`` and a fixed x264
thread count make repeated renders byte-identical (given the same ffmpeg build).
"""
from __future__ import annotations

import math
import re
import subprocess
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from laughlab.core.errors import LaughlabError

__all__ = ["Camera", "Renderer", "draw_face", "VideoEncoder", "ffmpeg_exe", "probe", "decode_frames",
           "decode_audio", "source_audio"]

SKIN = (238, 200, 170)
SKIN_DARK = (120, 80, 60)
LEFT = (66, 110, 200)
RIGHT = (205, 75, 65)
TORSO = (92, 108, 138)
OUTLINE = (38, 40, 48)
LIP = (150, 60, 60)
MOUTH = (70, 18, 28)
CHEEK = (235, 120, 120)


@dataclass
class Camera:
    """A perspective (pinhole) camera looking at the character.

    Attributes
    ----------
    azimuth_deg : float
        Camera position around the vertical axis: 0 = straight in front of the
        character (on +Z), positive = towards the character's left (+X).
    elevation_deg : float
        Height angle above the target (degrees).
    distance_cm : float
        Distance from the target (cm).
    target_height_cm : float
        Height of the point looked at, on the vertical axis through the origin (cm).
    fov_deg : float
        Vertical field of view (degrees).
    """

    azimuth_deg: float = 20.0
    elevation_deg: float = 6.0
    distance_cm: float = 360.0
    target_height_cm: float = 96.0
    fov_deg: float = 36.0

    def basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Camera centre (cm) and the rows (right, up, forward) of its rotation."""
        a, e = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        target = np.array([0.0, self.target_height_cm, 0.0])
        centre = target + self.distance_cm * np.array([math.sin(a) * math.cos(e), math.sin(e),
                                                       math.cos(a) * math.cos(e)])
        fwd = target - centre
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        return centre, np.stack([right, up, fwd])

    def projector(self, width: int, height: int) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """A function mapping world points ``(..., 3)`` (cm) to pixels ``(..., 2)`` and depth ``(...)`` (cm)."""
        centre, rot = self.basis()
        focal = 0.5 * height / math.tan(math.radians(self.fov_deg) / 2)
        cx, cy = 0.5 * width, 0.5 * height

        def project(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            c = (np.asarray(points, dtype=np.float64) - centre) @ rot.T
            z = np.maximum(c[..., 2], 1.0)  # points behind the camera are pushed in front of it
            xy = np.stack([cx + focal * c[..., 0] / z, cy - focal * c[..., 1] / z], axis=-1)
            return np.clip(xy, -1e5, 1e5), z  # far off-screen points stay drawable

        project.focal = focal  # type: ignore[attr-defined]
        project.centre = centre  # type: ignore[attr-defined]
        return project


# -- the face -----------------------------------------------------------------------------------------------------

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
    # mouth: corners rise with the smile, the lower lip drops with the jaw
    smile = 0.5 * (_w(weights, "mouthSmileLeft") + _w(weights, "mouthSmileRight"))
    frown = 0.5 * (_w(weights, "mouthFrownLeft") + _w(weights, "mouthFrownRight"))
    stretch = 0.5 * (_w(weights, "mouthStretchLeft") + _w(weights, "mouthStretchRight"))
    lower = 0.5 * (_w(weights, "mouthLowerDownLeft") + _w(weights, "mouthLowerDownRight"))
    upper = 0.5 * (_w(weights, "mouthUpperUpLeft") + _w(weights, "mouthUpperUpRight"))
    jaw = _w(weights, "jawOpen")
    my = -4.9
    corners = []
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        sm = _w(weights, f"mouthSmile{side}")
        fr = _w(weights, f"mouthFrown{side}")
        corners.append((s * (2.5 + 1.0 * sm + 0.6 * stretch), my + 1.3 * sm - 0.8 * fr - 0.35 * jaw))
    top_y = my + 0.15 + 0.35 * upper + 0.25 * smile
    bot_y = my - 0.15 - 3.4 * jaw - 0.7 * lower + 0.25 * smile - 0.3 * frown
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


# -- the figure ---------------------------------------------------------------------------------------------------

_TORSO_JOINTS = ("hips", "spine", "spine1", "spine2", "neck", "left_upper_arm", "right_upper_arm", "left_thigh",
                 "right_thigh", "head")


def _hull(points: np.ndarray) -> list[tuple[float, float]]:
    """Convex hull of 2D points (Andrew's monotone chain), counter-clockwise."""
    pts = sorted(set(map(tuple, np.round(points, 3).tolist())))
    if len(pts) < 3:
        return pts

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return lower[:-1] + upper[:-1]


def _side_colour(name: str, base: tuple) -> tuple:
    if name.startswith("left_"):
        return LEFT
    if name.startswith("right_"):
        return RIGHT
    return base


def _darker(c, f=0.78):
    return tuple(int(x * f) for x in c)


class Renderer:
    """Draws frames of a skeleton with a face; ``render(...)`` returns an ``(H, W, 3)`` uint8 array.

    Parameters
    ----------
    skeleton : Skeleton
    width, height : int
        Output size (pixels).
    camera : Camera
    inset : bool
        Draw the zoomed face inset (top right).
    inset_size : float
        Inset box side as a fraction of the height.
    supersample : int
        Draw at this multiple of the size and downsample (anti-aliasing; 1 = off).
    """

    def __init__(self, skeleton, width: int = 640, height: int = 480, camera: Camera | None = None,
                 inset: bool = True, inset_size: float = 0.36, supersample: int = 2):
        from PIL import Image, ImageDraw

        self._Image, self._ImageDraw = Image, ImageDraw
        self.skeleton = skeleton
        self.width, self.height = int(width), int(height)
        self.ss = int(supersample)
        self.W, self.H = self.width * self.ss, self.height * self.ss
        self.camera = camera or Camera()
        self.project = self.camera.projector(self.W, self.H)
        self.inset = inset
        self.inset_size = float(inset_size)
        names = skeleton.names
        self.humanoid = all(n in names for n in _TORSO_JOINTS)
        self.idx = {n: i for i, n in enumerate(names)}
        leaves = skeleton.leaves()
        self.end_of = {j: skeleton.n_joints + k for k, j in enumerate(leaves)}
        self.segments = self._segments()
        self.background = self._background()
        t = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
        self._cos, self._sin = np.cos(t), np.sin(t)
        self._shadow = _circle(20)
        self._shift = np.zeros(2)
        self.background_small = self.background.reduce(self.ss) if self.ss > 1 else self.background
        self._inset_bg, self._inset_at, self._inset_size = self._inset_box()

    # -- static parts
    def _segments(self) -> list[tuple[int, int, float, tuple]]:
        """(from point, to point, diameter cm, colour) of every limb capsule."""
        sk, idx = self.skeleton, self.idx
        out = []
        if not self.humanoid:
            for j, p in enumerate(sk.parents):
                if p >= 0:
                    out.append((p, j, 5.0, _side_colour(sk.names[j], TORSO)))
            return out
        widths = {"clavicle": 9.0, "upper_arm": 8.5, "forearm": 7.0, "hand": 5.5, "thigh": 13.0, "shin": 10.0,
                  "foot": 7.5, "toe": 6.0}
        for side in ("left", "right"):
            base = LEFT if side == "left" else RIGHT
            chain = [f"{side}_upper_arm", f"{side}_forearm", f"{side}_hand"]
            for a, b in zip(chain, chain[1:]):
                out.append((idx[a], idx[b], widths[a.split("_", 1)[1]], base))
            h = idx[f"{side}_hand"]
            out.append((h, self.end_of.get(h, h), widths["hand"], SKIN))
            legs = [f"{side}_thigh", f"{side}_shin", f"{side}_foot", f"{side}_toe"]
            for a, b in zip(legs, legs[1:]):
                out.append((idx[a], idx[b], widths[a.split("_", 1)[1]], _darker(base, 0.62)))
            t = idx[f"{side}_toe"]
            out.append((t, self.end_of.get(t, t), widths["toe"], _darker(base, 0.62)))
        out.append((idx["neck"], idx["head"], 6.5, _darker(SKIN, 0.92)))
        return out

    def _background(self):
        Image, ImageDraw = self._Image, self._ImageDraw
        top, bottom = np.array([206, 220, 236.0]), np.array([244, 244, 240.0])
        t = np.linspace(0, 1, self.H)[:, None]
        grad = (top * (1 - t) + bottom * t).astype(np.uint8)
        img = Image.fromarray(np.repeat(grad[:, None, :], self.W, axis=1), "RGB")
        d = ImageDraw.Draw(img)
        ext = 160.0
        corners = np.array([[-ext, 0, -ext], [ext, 0, -ext], [ext, 0, ext], [-ext, 0, ext]])
        xy, _ = self.project(corners)
        d.polygon([tuple(p) for p in xy.tolist()], fill=(214, 208, 196))
        for v in np.arange(-ext, ext + 1, 40.0):
            for a, b in (([v, 0, -ext], [v, 0, ext]), ([-ext, 0, v], [ext, 0, v])):
                pa, _ = self.project(np.array(a))
                pb, _ = self.project(np.array(b))
                d.line([tuple(pa), tuple(pb)], fill=(190, 183, 170), width=max(1, self.ss))
        return img

    # -- per frame
    def render(self, positions: np.ndarray, rotations: np.ndarray, end_positions: np.ndarray | None,
               weights: dict, chest: float = 0.0, belly: float = 0.0) -> np.ndarray:
        """One frame.

        Parameters
        ----------
        positions : ndarray (J, 3)
            World joint positions (cm).
        rotations : ndarray (J, 3, 3)
            World joint rotations.
        end_positions : ndarray (n_leaves, 3) or None
            End Site positions.
        weights : dict
            ARKit weights of the face (floats).
        chest, belly : float
            Body shape weights (0 rest, 1 expanded).
        """
        ss = self.ss
        pts = positions if end_positions is None else np.concatenate([positions, end_positions])
        xy, depth = self.project(pts)
        f = self.project.focal
        hips = positions[0]
        shadow = np.column_stack([hips[0] + 30 * self._shadow[:, 0], np.zeros(len(self._shadow)),
                                  hips[2] + 18 * self._shadow[:, 1]])
        sxy, _ = self.project(shadow)
        # only the figure's bounding box is drawn at the supersampled size, then pasted on the background
        margin = f * 24.0 / float(depth.min()) + 4 * ss  # the torso and the head reach ~20 cm beyond the joints
        both = np.concatenate([xy, sxy])
        lo = np.floor((both.min(axis=0) - margin) / ss) * ss
        hi = np.ceil((both.max(axis=0) + margin) / ss) * ss
        x0, y0 = (int(v) for v in np.maximum(lo, 0))
        x1, y1 = int(min(hi[0], self.W)), int(min(hi[1], self.H))
        out = self.background_small.copy()
        if x1 > x0 and y1 > y0:
            self._shift = np.array([x0, y0], dtype=np.float64)
            canvas = self.background.crop((x0, y0, x1, y1))
            d = self._ImageDraw.Draw(canvas)
            xy = xy - self._shift
            d.polygon([tuple(p) for p in (sxy - self._shift).tolist()], fill=(188, 180, 166))  # shadow
            items: list[tuple[float, Callable]] = []
            for a, b, dia, colour in self.segments:
                za = 0.5 * (depth[a] + depth[b])
                items.append((za, self._capsule(d, xy[a], xy[b], f * dia / depth[a], f * dia / depth[b], colour)))
            if self.humanoid:
                items.append(self._torso(d, positions, rotations, chest, belly))
                items.append(self._head(d, positions, rotations, weights))
            for _, paint in sorted(items, key=lambda it: -it[0]):
                paint()
            out.paste(canvas.reduce(ss) if ss > 1 else canvas, (x0 // ss, y0 // ss))
        if self.inset:
            box = self._inset_bg.copy()
            self._inset(self._ImageDraw.Draw(box), weights)
            out.paste(box.reduce(ss) if ss > 1 else box, (self._inset_at[0] // ss, self._inset_at[1] // ss))
        return np.asarray(out)

    def _px(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels on the current canvas (the figure's crop) and depths of world points."""
        xy, z = self.project(points)
        return xy - self._shift, z

    def _capsule(self, d, pa, pb, wa, wb, colour):
        def paint():
            w = max(2.0, 0.5 * (wa + wb))
            edge = _darker(colour, 0.7)
            ow = max(1.0, 0.12 * w)
            for r, c in ((0.5 * w + ow, edge), (0.5 * w, colour)):
                d.line([tuple(pa), tuple(pb)], fill=c, width=int(round(2 * r)))
                for p, rr in ((pa, r), (pb, r)):
                    d.ellipse([p[0] - rr, p[1] - rr, p[0] + rr, p[1] + rr], fill=c)
        return paint

    def _torso(self, d, pos, rot, chest, belly):
        idx = self.idx
        chest = float(np.clip(chest if chest == chest else 0.0, -0.5, 1.5))
        belly = float(np.clip(belly if belly == belly else 0.0, -0.5, 1.5))
        # elliptic cross-sections from hips to shoulders: (joint, lateral half-width cm, back half-depth cm,
        # front half-depth cm, height offset cm); the chest and the belly widen and bulge with their channels
        levels = [("hips", 15.5, 10.0, 10.0, -7.0),
                  ("spine", 14.0 + 2.5 * belly, 9.0, 9.5 + 6.0 * belly, 0.0),
                  ("spine1", 14.0 + 2.0 * chest + 0.8 * belly, 9.5, 10.0 + 3.0 * chest + 1.5 * belly, 0.0),
                  ("spine2", 15.5 + 2.2 * chest, 9.5, 10.0 + 2.5 * chest, 2.0),
                  ("neck", 12.0, 6.5, 6.5, -4.0)]
        ring = []
        for name, hw, back, front, dy in levels:
            j = idx[name]
            r = rot[j]
            fwd = np.where(self._sin > 0, front, back) * self._sin
            local = np.stack([hw * self._cos, np.full_like(self._cos, dy), fwd], axis=-1)
            ring.append(pos[j] + local @ r.T)
        for side in ("left", "right"):
            ring.append(pos[idx[f"{side}_upper_arm"]][None] + rot[idx["spine2"]][:, 1] * 3.0)
        xy, _ = self._px(np.concatenate(ring))
        pts = _hull(xy)
        zmid = float(self._px(pos[idx["spine1"]])[1]) - 9.0  # painted at the depth of its front surface
        width = max(1, int(round(self.project.focal * 0.9 / zmid)))

        def paint():
            d.polygon(pts, fill=TORSO)
            d.line(pts + [pts[0]], fill=OUTLINE, width=width, joint="curve")
        return zmid, paint

    def _head(self, d, pos, rot, weights):
        idx = self.idx
        h = idx["head"]
        r = rot[h]
        centre = pos[h] + r @ np.array([0.0, 10.0, 1.5])
        cxy, cz = self._px(centre)
        f = self.project.focal
        rad = f * HEAD_RADIUS_CM / cz
        jaw = _w(weights, "jawOpen")
        chin = centre + r @ np.array([0.0, -6.5 - 2.6 * jaw, 3.0])
        kxy, _ = self._px(chin)
        krx, kry = f * 6.8 / cz, f * (4.6 + 1.2 * jaw) / cz
        view = self.project.centre - centre
        facing = float(r[:, 2] @ view) / float(np.linalg.norm(view))
        ow = max(1, int(round(f * 0.7 / cz)))

        def to_screen(p):
            return self._px(centre + p @ r.T)[0]

        def paint():
            for extra, colour in ((ow, OUTLINE), (0, SKIN)):
                d.ellipse([kxy[0] - krx - extra, kxy[1] - kry - extra, kxy[0] + krx + extra, kxy[1] + kry + extra],
                          fill=colour)
                d.ellipse([cxy[0] - rad - extra, cxy[1] - rad - extra, cxy[0] + rad + extra, cxy[1] + rad + extra],
                          fill=colour)
            if facing > 0.15:
                draw_face(d, to_screen, f / cz, weights)
        return float(cz) - HEAD_RADIUS_CM, paint

    def _inset_box(self):
        """The inset's empty box (supersampled) and where it goes on the frame (supersampled pixels)."""
        ss = self.ss
        s = int(self.inset_size * self.H) // ss * ss
        m = int(0.025 * self.H) // ss * ss
        img = self._Image.new("RGB", (s + ss, s + ss), (250, 248, 244))
        self._ImageDraw.Draw(img).rectangle([0, 0, s, s], outline=OUTLINE, width=max(1, ss * 2))
        return img, (self.W - s - m, m), s

    def _inset(self, d, weights):
        """The zoomed face, frontal, drawn into the inset box."""
        s = self._inset_size
        scale = s / 30.0  # px per cm: the box shows 30 cm
        cx, cy = 0.5 * s, 0.48 * s
        jaw = _w(weights, "jawOpen")
        ow = max(1, int(round(0.5 * scale)))
        for extra, colour in ((ow, OUTLINE), (0, SKIN)):
            rx, ry = 6.8 * scale + extra, (4.6 + 1.2 * jaw) * scale + extra
            ky = cy + (6.5 + 2.6 * jaw) * scale
            d.ellipse([cx - rx, ky - ry, cx + rx, ky + ry], fill=colour)
            r = HEAD_RADIUS_CM * scale + extra
            d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=colour)

        def to_screen(p):
            return np.stack([cx - scale * p[:, 0], cy - scale * p[:, 1]], axis=-1)

        draw_face(d, to_screen, scale, weights)


# -- ffmpeg ---------------------------------------------------------------------------------------------------------

def ffmpeg_exe() -> str:
    """The ffmpeg binary shipped with imageio-ffmpeg (or ``IMAGEIO_FFMPEG_EXE``)."""
    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise LaughlabError(f"video output needs imageio-ffmpeg (pip install imageio-ffmpeg): {exc}") from None
    return imageio_ffmpeg.get_ffmpeg_exe()


BITEXACT = ["-fflags", "+bitexact", "-flags:v", "+bitexact", "-flags:a", "+bitexact", "-map_metadata", "-1"]


class VideoEncoder:
    """Pipes RGB frames into ffmpeg: H.264 yuv420p at a constant frame rate, AAC audio, MP4.

    Parameters
    ----------
    path : Path
        Output file (written as MP4 whatever its suffix).
    width, height : int
        Frame size (even numbers: yuv420p halves the chroma).
    fps : float
        Video frame rate (constant).
    audio : Path or None
        A WAV (or any ffmpeg-readable) file muxed as AAC from time 0; None: video only.
    crf, preset, threads : x264 quality, speed preset and thread count (fixed for identical bytes).
    audio_bitrate_k, audio_rate : AAC bit rate (kbit/s) and sample rate (Hz).
    """

    def __init__(self, path: Path, width: int, height: int, fps: float, audio: Path | None = None, crf: int = 20,
                 preset: str = "veryfast", threads: int = 2, audio_bitrate_k: int = 128, audio_rate: int = 48000):
        self.path = Path(path)
        self.shape = (int(height), int(width), 3)
        rate = _rate(fps)
        cmd = [ffmpeg_exe(), "-nostdin", "-y", "-hide_banner", "-loglevel", "error",
               "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", rate, "-i", "pipe:0"]
        if audio is not None:
            cmd += ["-i", str(audio)]
        cmd += ["-map", "0:v:0"] + (["-map", "1:a:0"] if audio is not None else [])
        cmd += ["-c:v", "libx264", "-preset", preset, "-crf", str(crf), "-pix_fmt", "yuv420p", "-threads", str(threads),
                "-fps_mode", "cfr", "-r", rate, "-movflags", "+faststart"]
        if audio is not None:
            cmd += ["-c:a", "aac", "-b:a", f"{audio_bitrate_k}k", "-ar", str(audio_rate)]
        cmd += BITEXACT + ["-f", "mp4", str(self.path)]
        self.cmd = cmd
        self._err = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._err)
        except OSError as exc:
            self._err.close()
            raise LaughlabError(f"cannot start ffmpeg: {exc}") from None
        self.frames = 0

    def write(self, frame: np.ndarray) -> None:
        if frame.shape != self.shape or frame.dtype != np.uint8:
            raise ValueError(f"frame must be uint8 {self.shape}, got {frame.dtype} {frame.shape}")
        try:
            self.proc.stdin.write(np.ascontiguousarray(frame).tobytes())
        except BrokenPipeError:
            raise LaughlabError(f"ffmpeg stopped: {self._error_text()}") from None
        self.frames += 1

    def _error_text(self) -> str:
        self.proc.wait()
        self._err.seek(0)
        lines = [ln for ln in self._err.read().decode(errors="replace").splitlines() if ln.strip()]
        return lines[-1] if lines else f"exit status {self.proc.returncode}"

    def close(self) -> None:
        """Finish the file; raise LaughlabError if ffmpeg failed."""
        try:
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        code = self.proc.wait()
        try:
            if code != 0:
                raise LaughlabError(f"ffmpeg failed: {self._error_text()}")
        finally:
            self._err.close()

    def abort(self) -> None:
        """Stop ffmpeg without finishing the file (the caller removes it)."""
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.stdin.close()
        except (BrokenPipeError, OSError, ValueError):
            pass
        self.proc.wait()
        if not self._err.closed:
            self._err.close()


def _rate(fps: float) -> str:
    """ffmpeg's rate string: an integer, or a fraction for rates like 29.97."""
    from fractions import Fraction

    fr = Fraction(float(fps)).limit_denominator(1001)
    return str(fr.numerator) if fr.denominator == 1 else f"{fr.numerator}/{fr.denominator}"


def probe(path: str | Path) -> dict:
    """Stream facts of a media file from ``ffmpeg -i`` (imageio-ffmpeg ships no ffprobe).

    Returns ``duration_s``, ``video`` (``codec``, ``pix_fmt``, ``width``,
    ``height``, ``fps``) and ``audio`` (``codec``, ``sample_rate``) or None.
    """
    r = subprocess.run([ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", str(path)], capture_output=True, text=True)
    err = r.stderr
    out: dict = {"duration_s": None, "video": None, "audio": None}
    m = re.search(r"Duration: (\d+):(\d+):(\d+(?:\.\d+)?)", err)
    if m:
        out["duration_s"] = int(m.group(1)) * 3600 + int(m.group(2)) * 60 + float(m.group(3))
    m = re.search(r"Stream #\d+:\d+.*?: Video: (\w+)[^,]*, (\w+)[^,]*?(?:\([^)]*\))?, (\d+)x(\d+).*?, ([\d.]+) fps",
                  err)
    if m:
        out["video"] = {"codec": m.group(1), "pix_fmt": m.group(2), "width": int(m.group(3)),
                        "height": int(m.group(4)), "fps": float(m.group(5))}
    m = re.search(r"Stream #\d+:\d+.*?: Audio: (\w+)[^,]*, (\d+) Hz", err)
    if m:
        out["audio"] = {"codec": m.group(1), "sample_rate": int(m.group(2))}
    return out


def decode_frames(path: str | Path, width: int, height: int) -> np.ndarray:
    """Every video frame of a file as ``(N, height, width, 3)`` uint8 (decoded by ffmpeg)."""
    r = subprocess.run([ffmpeg_exe(), "-nostdin", "-loglevel", "error", "-i", str(path), "-map", "0:v:0",
                        "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True)
    if r.returncode != 0:
        raise LaughlabError(f"cannot decode {path}: {r.stderr.decode(errors='replace').strip()}")
    return np.frombuffer(r.stdout, np.uint8).reshape(-1, height, width, 3)


def decode_audio(path: str | Path, sample_rate: int = 48000) -> np.ndarray:
    """The first audio stream of a file as mono float32 samples at ``sample_rate`` (decoded by ffmpeg)."""
    r = subprocess.run([ffmpeg_exe(), "-nostdin", "-loglevel", "error", "-i", str(path), "-map", "0:a:0",
                        "-ac", "1", "-ar", str(sample_rate), "-f", "f32le", "-"], capture_output=True)
    if r.returncode != 0:
        raise LaughlabError(f"cannot decode audio of {path}: {r.stderr.decode(errors='replace').strip()}")
    return np.frombuffer(r.stdout, "<f4").copy()


def source_audio(source, tmp_dir: Path) -> Path | None:
    """A file holding the source's audio, or None (live input: video only).

    ``source.audio_path()`` when the source reads a file; else, for a source
    that writes its audio as an artifact (the ``synthetic`` source's
    ``input.wav``), the same audio rendered into ``tmp_dir`` (the source
    writes ``input.wav`` only after the sinks close, and it is deterministic,
    so the copy is identical).
    """
    if source is None:
        return None
    path = source.audio_path() if hasattr(source, "audio_path") else None
    if path is not None and Path(path).exists():
        return Path(path)
    truth = getattr(source, "truth", None)
    if truth is not None and hasattr(truth, "render") and hasattr(truth, "n_samples"):
        from laughlab.io.audio import FloatWavWriter

        tmp_dir = Path(tmp_dir)
        tmp_dir.mkdir(parents=True, exist_ok=True)
        wav = tmp_dir / "input.wav"
        with FloatWavWriter(wav, source.sample_rate) as f:
            block = 16384
            for start in range(0, truth.n_samples, block):
                f.write(truth.render(start, min(block, truth.n_samples - start)))
        return wav
    return None
