"""Video frames of the skinned character (:mod:`laughlab.character.body`), rendered in software.

The camera follows the upper body: it looks at the point between the chest (``spine2``) and the
head, smoothed over about a fifth of a second, from the azimuth, elevation and distance of
``camera`` (its ``target_height_cm`` is not used), so the face stays in frame when the character
bends over or rolls on the floor; it moves back, smoothly and ahead of time, when a raised arm or a
bent body would reach the top or a side of the frame (:mod:`laughlab.render.framing`).  The ``body`` framing
(``output.video.framing=body``) looks at the middle of the body instead, between the head and the feet, from at
least the distance at which the whole character standing at rest fits, and keeps the feet in the frame too.

Per frame: the morph targets are added in the rest pose (face and breathing weights), the mesh
is skinned by the pose's joint transforms (linear blend, as glTF does), lit by a key light, a
fill from the other side and an ambient term (Lambert, per vertex), projected by the scene's
pinhole camera and drawn by :func:`laughlab.render.raster.rasterise` at ``supersample`` times
the size, then averaged down (anti-aliasing).  No GPU, no display: the same pixels for the same
pose on the same machine.
"""
from __future__ import annotations

import numpy as np

from dataclasses import replace

from laughlab.character.body import build
from laughlab.motion.skeleton import global_transforms, rest_pose
from laughlab.render.framing import Framing
from laughlab.render.raster import draw_frames, rasterise
from laughlab.render.scene import Camera

#: key light (from the camera's upper left), fill light (right), ambient
KEY = np.array([-0.45, 0.65, 0.6])
FILL = np.array([0.7, 0.2, 0.5])


class FollowingView:
    """What the mannequin's and an avatar's software renderers share: the camera's aim, smoothed frame by frame
    (:attr:`follow` per rendered frame), its distance looking ahead (:attr:`framing`), and the frames skinned
    and painted by threads.  A subclass sets :attr:`camera`, :attr:`framing`, :attr:`follow`, :attr:`tris`,
    :attr:`background`, the size, and ``_mesh(*job) -> (vertices cm, colours)``."""

    aim: np.ndarray | None = None
    body_offset = np.zeros(3)   # the body framing's aim from the joints' midpoint (cm): :meth:`_whole_body`

    def _whole_body(self, camera: Camera, rest_vertices: np.ndarray, rest_target: np.ndarray) -> Camera:
        """The ``body`` framing: :attr:`framing` keeps the bottom edge too, and the camera's distance is the one at
        which the whole character standing at rest just fits, with the margin (the configured distance, a close-up
        of the upper body, is not used); kneeling does not bring it closer, a raise moves it back as before.
        Returns that camera."""
        # the aim a little up or down from the joints' midpoint, to the middle of the mesh's height at rest (hair
        # and soles reach past the head and foot joints): the standing character centred, not against the top
        self.body_offset = np.array([0.0, 0.5 * (rest_vertices[:, 1].min() + rest_vertices[:, 1].max())
                                     - rest_target[1], 0.0])
        need = Framing(replace(camera, distance_cm=1e-6), self.width, self.height, bottom=True).need(
            rest_vertices, rest_target + self.body_offset)
        camera = replace(camera, distance_cm=need)
        self.framing = Framing(camera, self.width, self.height, bottom=True)
        return camera

    def _smooth_aim(self, target: np.ndarray) -> np.ndarray:
        """The camera's aim after a frame whose aim point is ``target`` (cm)."""
        self.aim = target if self.aim is None else self.aim + self.follow * (target - self.aim)
        return self.aim

    def _draw_ready(self, jobs: list, aims: list, threads: int) -> list[np.ndarray]:
        """Skin ``jobs`` (each a ``_mesh`` argument tuple), let the framing look ahead, paint what it releases:
        each frame skinned and drawn on its own, so the frames are the same bytes however a run is cut."""
        ready = []
        for (v, colour), aim in zip(draw_frames(self._mesh, jobs, threads), aims):
            ready += self.framing.push((v, colour, aim), self.framing.need(v, aim))
        return draw_frames(self._paint, [(*job, d) for job, d in ready], threads)

    def flush(self, threads: int = 2) -> list[np.ndarray]:
        """The frames ``render_many`` still holds (the run has ended)."""
        return draw_frames(self._paint, [(*job, d) for job, d in self.framing.flush()], threads)

    def _paint(self, v: np.ndarray, colour: np.ndarray, aim: np.ndarray, distance: float) -> np.ndarray:
        cam = self.camera if distance == self.camera.distance_cm else replace(self.camera, distance_cm=distance)
        xy, depth = cam.projector(self.width * self.ss, self.height * self.ss, target=aim)(v)
        return downsample(rasterise(xy, depth, colour, self.tris, self.background), self.ss)


class CharacterRenderer(FollowingView):
    """Renders the character at ``width`` x ``height`` with ``camera`` (cm, as the schematic scene's)."""

    def __init__(self, skeleton, width: int = 640, height: int = 480, camera: Camera | None = None,
                 supersample: int = 2, framing: str = "upper"):
        self.char = build(skeleton)
        self.whole = framing == "body"
        self.skeleton = skeleton
        self.width, self.height, self.ss = width, height, supersample
        self.camera = camera or Camera(azimuth_deg=15.0, elevation_deg=3.0, distance_cm=170.0,
                                       target_height_cm=138.0, fov_deg=30.0)
        self.aim: np.ndarray | None = None  # set by the first frame
        self.follow = 1.0 - np.exp(-1.0 / 6.0)  # per rendered frame: a time constant of 6 frames (0.2 s at 30 fps)
        self.tris = self.char.indices.reshape(-1, 3).astype(np.int64)
        self.base = self.char.positions.astype(np.float64) * 100.0     # cm
        self.morphs = self.char.morphs.astype(np.float64) * 100.0
        self.normals = self.char.normals.astype(np.float64)
        self.albedo = self.char.colors.astype(np.float64) * 255.0
        rest, _ = global_transforms(skeleton, rest_pose(skeleton))
        self.rest = rest                                                # joints' rest positions, cm
        key, fill = KEY / np.linalg.norm(KEY), FILL / np.linalg.norm(FILL)
        self.key, self.fill = key, fill
        self.background = background(height * supersample, width * supersample)
        self.framing = Framing(self.camera, width, height)
        if self.whole:
            rest_pos, rest_rot = global_transforms(skeleton, rest_pose(skeleton))
            v, _ = self._mesh(rest_pos, rest_rot, np.zeros(len(self.morphs)))
            self.camera = self._whole_body(self.camera, v, self._target(rest_pos))

    def render(self, pose: np.ndarray, morph_weights: np.ndarray) -> np.ndarray:
        """One frame ``(height, width, 3)`` uint8 of ``pose`` (BVH channel vector) with ``morph_weights``, framed on
        its own (no frames ahead: the distance is this frame's :meth:`Framing.need`)."""
        pos, rot = global_transforms(self.skeleton, np.asarray(pose, dtype=np.float64))
        v, colour = self._mesh(pos, rot, morph_weights)
        aim = self._follow(pos)
        return self._paint(v, colour, aim, self.framing.need(v, aim))

    def render_many(self, poses: np.ndarray, morph_weights: np.ndarray, threads: int = 2) -> list[np.ndarray]:
        """The frames of a chunk that are ready (the camera's distance looks ahead: :mod:`laughlab.render.framing`;
        the last ones come from :meth:`flush`), drawn by ``threads`` threads at once: the camera follows frame by
        frame first (the only state), then each frame is skinned and drawn on its own, so the frames are the
        same bytes however the run is cut into chunks."""
        jobs, aims = [], []
        for pose, w in zip(np.asarray(poses, dtype=np.float64), morph_weights):
            pos, rot = global_transforms(self.skeleton, pose)   # frame by frame, as render does: the same bits
            jobs.append((pos, rot, w))
            aims.append(self._follow(pos))
        return self._draw_ready(jobs, aims, threads)

    def _target(self, pos: np.ndarray) -> np.ndarray:
        """Where the camera looks for a frame's joint positions (cm): between the chest and the head, or with the
        ``body`` framing between the head and the middle of the feet."""
        sk = self.skeleton
        if self.whole:
            feet = 0.5 * (pos[sk.index("left_foot")] + pos[sk.index("right_foot")])
            return 0.5 * (pos[sk.index("head")] + feet) + self.body_offset
        return 0.5 * (pos[sk.index("spine2")] + pos[sk.index("head")])

    def _follow(self, pos: np.ndarray) -> np.ndarray:
        """The camera's aim for a frame's joint positions (:meth:`_target`), smoothed (cm)."""
        return self._smooth_aim(self._target(pos))

    def _mesh(self, pos: np.ndarray, rot: np.ndarray, morph_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The skinned vertices (cm) and their lit colours for a frame's joint positions and rotations."""
        v = self.base + np.tensordot(np.asarray(morph_weights, dtype=np.float64), self.morphs, axes=1)
        j, wt = self.char.joints, self.char.weights.astype(np.float64)
        out = np.zeros_like(v)
        nrm = np.zeros_like(v)
        for k in range(2):  # two bones a vertex (linear blend skinning)
            r = rot[j[:, k]]
            local = v - self.rest[j[:, k]]
            out += wt[:, k:k + 1] * (np.einsum("vab,vb->va", r, local) + pos[j[:, k]])
            nrm += wt[:, k:k + 1] * np.einsum("vab,vb->va", r, self.normals)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-9)
        light = 0.30 + 0.75 * np.clip(nrm @ self.key, 0.0, None) + 0.25 * np.clip(nrm @ self.fill, 0.0, None)
        return out, np.clip(self.albedo * light[:, None], 0.0, 255.0)


def background(height: int, width: int) -> np.ndarray:
    """The frames' backdrop: a vertical gradient from blue-grey to dark, float32 ``(height, width, 3)``."""
    top, bottom = np.array([58.0, 66.0, 84.0]), np.array([28.0, 31.0, 40.0])
    ramp = np.linspace(0.0, 1.0, height)[:, None, None]
    return np.broadcast_to(top + (bottom - top) * ramp, (height, width, 3)).astype(np.float32)


def downsample(img: np.ndarray, s: int) -> np.ndarray:
    """A frame drawn at ``s`` times the size, averaged down to uint8 (anti-aliasing)."""
    if s > 1:  # the mean of each s x s block, summed slice by slice (a strided mean is 10x slower)
        acc = np.zeros((img.shape[0] // s, img.shape[1] // s, 3), dtype=np.float32)
        for dy in range(s):
            for dx in range(s):
                acc += img[dy::s, dx::s]
        img = acc * np.float32(1.0 / (s * s))
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)
