"""Video frames of a user's avatar (``character=PATH``), rendered in software like the mannequin's.

Per frame: laughlab's pose is retargeted onto the avatar (:mod:`laughlab.avatar.retarget`), each mesh's
morph targets are added (:func:`laughlab.avatar.expressions.morph_weights`), skinned meshes are blended
by their joints' world matrices times the inverse bind matrices (up to four a vertex, as glTF does),
rigid meshes follow their node; the avatar is turned to face the camera (a VRM 0.x one, or one exported
facing any other way: :func:`laughlab.avatar.retarget.facing_matrix`, as in the viewer).  The vertices (in cm),
lit per vertex as the mannequin is, go through :func:`laughlab.render.raster.rasterise`.  The camera
is the mannequin's, its distance scaled by the avatar's height (x 1.5: avatars often have big heads),
or farther if the top of the mesh in the rest pose (hair above the head joint) would not fit within 85%
of the half field of view, aimed at a point 70% of the way from the chest to the head joint; it moves back,
smoothly and ahead of time, when a raised arm or a bent body would reach the top or a side of the frame
(:mod:`laughlab.render.framing`).  The ``body`` framing looks between the head and the feet and keeps the whole
avatar in the frame, as the mannequin's does (:meth:`laughlab.render.character_view.FollowingView._whole_body`).
"""
from __future__ import annotations

import numpy as np

from laughlab.avatar.load import Avatar
from laughlab.avatar.mesh import parts
from laughlab.avatar.retarget import animated_world, facing_matrix, retarget
from laughlab.render.character_view import FILL, KEY, FollowingView, background
from laughlab.render.framing import Framing
from laughlab.render.scene import Camera


class AvatarRenderer(FollowingView):
    """Renders ``avatar`` driven by ``skeleton`` poses at ``width`` x ``height``."""

    def __init__(self, avatar: Avatar, skeleton, width: int = 640, height: int = 480, camera: Camera | None = None,
                 supersample: int = 2, framing: str = "upper"):
        self.avatar, self.skeleton = avatar, skeleton
        self.whole = framing == "body"
        self.width, self.height, self.ss = width, height, supersample
        self.parts = parts(avatar)
        offsets = np.cumsum([0] + [len(p.positions) for p in self.parts])
        self.tris = np.concatenate([p.triangles + o for p, o in zip(self.parts, offsets)]).astype(np.int64)
        self.albedo = np.concatenate([p.colours for p in self.parts])
        rest_head = avatar.rest_world[avatar.bones["head"], 1, 3] - min(0.0, avatar.rest_world[:, 1, 3].min())
        scale = max(0.2, 1.5 * float(rest_head) / 1.55)  # laughlab's head joint is 155 cm above the floor; a
        # little farther than for the mannequin: avatars often have big heads
        cam = camera or Camera(azimuth_deg=15.0, elevation_deg=3.0, distance_cm=170.0, target_height_cm=138.0,
                               fov_deg=30.0)
        self.turn = facing_matrix(avatar)   # rows @ turn: the avatar's frame into laughlab's (facing the camera)
        # and far enough that the top of the mesh in the rest pose (hair, ears, a hat: above the head joint) lies
        # within 85% of the half field of view above the aim (the joint-based distance cut Godette's hair buns off)
        top = float(self.vertices(avatar.rest_world, {})[0][:, 1].max())
        above = top - float(self._target(avatar.rest_world)[1])
        fits = above / np.tan(np.radians(0.85 * cam.fov_deg / 2)) if above > 0 else 0.0
        self.camera = Camera(**{**vars(cam), "distance_cm": max(cam.distance_cm * scale, fits)})
        self.aim: np.ndarray | None = None
        self.follow = 1.0 - np.exp(-1.0 / 6.0)
        self.key, self.fill = KEY / np.linalg.norm(KEY), FILL / np.linalg.norm(FILL)
        self.background = background(height * supersample, width * supersample)
        self.framing = Framing(self.camera, width, height)
        if self.whole:
            self.camera = self._whole_body(self.camera, self.vertices(avatar.rest_world, {})[0],
                                           self._target(avatar.rest_world))

    def worlds(self, poses: np.ndarray) -> np.ndarray:
        """The avatar's node world matrices ``(F, N, 4, 4)`` for ``poses`` (F, 3 + 3J), retargeted at once."""
        return animated_world(self.avatar, retarget(self.avatar, np.atleast_2d(np.asarray(poses, dtype=np.float64))))

    def vertices(self, world: np.ndarray, morphs: dict) -> tuple[np.ndarray, np.ndarray]:
        """World vertices (cm, facing +Z) and normals for one frame's node world matrices ``world`` (N, 4, 4)."""
        vs, ns = [], []
        for p in self.parts:
            v = p.positions
            w = morphs.get(p.node)
            if w is not None and len(p.morphs):
                v = v + np.tensordot(w[: len(p.morphs)], p.morphs, axes=1)
            if p.joints is not None:
                joint = world[p.joints] @ p.inverse_bind                    # (J, 4, 4), once per skin joint
                out, nrm = np.zeros_like(v), np.zeros_like(v)
                for k in range(4):  # linear blend skinning: four joints a vertex
                    m, wk = joint[p.skin_slots[:, k]], p.weights[:, k:k + 1]
                    out += wk * (np.einsum("vab,vb->va", m[:, :3, :3], v) + m[:, :3, 3])
                    nrm += wk * np.einsum("vab,vb->va", m[:, :3, :3], p.normals)
            else:
                m = world[p.node]
                out = v @ m[:3, :3].T + m[:3, 3]
                nrm = p.normals @ m[:3, :3].T
            vs.append(out)
            ns.append(nrm)
        v = np.concatenate(vs) @ self.turn * 100.0
        n = np.concatenate(ns) @ self.turn
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)
        return v, n

    def render(self, pose: np.ndarray, morphs: dict, world: np.ndarray | None = None) -> np.ndarray:
        """One frame ``(height, width, 3)`` uint8: ``pose`` (BVH channel vector), ``morphs`` mesh node -> weights
        (``world``: the frame's node world matrices if :meth:`worlds` made them for a whole chunk), framed on its
        own (no frames ahead: the distance is this frame's :meth:`Framing.need`)."""
        world = self.worlds(pose)[0] if world is None else world
        v, colour = self._mesh(world, morphs)
        aim = self._follow(world)
        return self._paint(v, colour, aim, self.framing.need(v, aim))

    def render_many(self, worlds: np.ndarray, morphs: list[dict], threads: int = 2) -> list[np.ndarray]:
        """The frames of a chunk that are ready (the camera's distance looks ahead: :mod:`laughlab.render.framing`;
        the last ones come from :meth:`flush`; ``worlds`` from :meth:`worlds`, one ``morphs`` dict a frame), by
        ``threads`` threads at once: the camera follows frame by frame first (the only state), then each frame is
        skinned and drawn on its own, so the frames are the same bytes however the run is cut into chunks."""
        aims = [self._follow(w) for w in worlds]
        return self._draw_ready(list(zip(worlds, morphs)), aims, threads)

    def _target(self, world: np.ndarray) -> np.ndarray:
        """The point 70% of the way from the chest to the head joint (cm, facing +Z); with the ``body`` framing
        the point between the head and the middle of the feet."""
        b = self.avatar.bones
        if self.whole:
            feet = 0.5 * (world[b["leftFoot"], :3, 3] + world[b["rightFoot"], :3, 3])
            return 0.5 * (world[b["head"], :3, 3] + feet) @ self.turn * 100.0 + self.body_offset
        chest = b.get("upperChest", b.get("chest", b["spine"]))
        return (0.3 * world[chest, :3, 3] + 0.7 * world[b["head"], :3, 3]) @ self.turn * 100.0

    def _follow(self, world: np.ndarray) -> np.ndarray:
        """The camera's aim for a frame: it follows the chest and head, smoothed from frame to frame (cm)."""
        return self._smooth_aim(self._target(world))

    def _mesh(self, world: np.ndarray, morphs: dict) -> tuple[np.ndarray, np.ndarray]:
        """The frame's vertices (cm, facing +Z) and their lit colours."""
        v, n = self.vertices(world, morphs)
        light = 0.45 + 0.6 * np.clip(n @ self.key, 0.0, None) + 0.2 * np.clip(n @ self.fill, 0.0, None)
        return v, np.clip(self.albedo * light[:, None], 0.0, 255.0)
