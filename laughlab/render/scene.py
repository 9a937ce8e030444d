"""Rendering a run as video frames: the character in perspective and a schematic face.

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

Encoding the frames into MP4: :mod:`laughlab.io.video`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from laughlab.render.face import HEAD_RADIUS_CM, OUTLINE, SKIN, _circle, _w, draw_face

__all__ = ["Camera", "Renderer", "draw_face"]

LEFT = (66, 110, 200)
RIGHT = (205, 75, 65)
TORSO = (92, 108, 138)


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

    def basis(self, target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Camera centre (cm) and the rows (right, up, forward) of its rotation.

        ``target``: the point looked at (cm); default on the vertical axis at ``target_height_cm``.
        """
        a, e = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        target = np.array([0.0, self.target_height_cm, 0.0]) if target is None else np.asarray(target, float)
        centre = target + self.distance_cm * np.array([math.sin(a) * math.cos(e), math.sin(e),
                                                       math.cos(a) * math.cos(e)])
        fwd = target - centre
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        return centre, np.stack([right, up, fwd])

    def projector(self, width: int, height: int,
                  target: np.ndarray | None = None) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """A function mapping world points ``(..., 3)`` (cm) to pixels ``(..., 2)`` and depth ``(...)`` (cm)."""
        centre, rot = self.basis(target)
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
            Body shape weights (0 the base shape, 1 expanded).
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
