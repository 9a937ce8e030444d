"""The video camera's distance: far enough that the whole character stays inside the frame, chosen ahead of time.

The character views (:mod:`laughlab.render.character_view`, :mod:`laughlab.render.avatar_view`) aim the camera at
the upper body (their ``_follow``) from the configured distance, which frames the chest and the face.  A laugh's
arm raised over the head, or a body bent far sideways, reaches beyond that framing (the media review of
2026-11-27: a hand cut by the top edge in 16 of 960 frames of the stimuli's ``laugh_energy`` videos).

For each frame, :meth:`Framing.need` is the smallest distance at which every vertex of the mesh lies inside the
frame with a margin (``margin`` x the height) at the top, left and right (the bottom cuts the body by design:
the framing shows the upper body; with ``bottom``, the ``body`` framing, at the bottom too); never less than the
configured distance.  A vertex at ``(x, y, z)`` in the
camera's frame relative to the aim is seen at ``f y / (z + d)`` from the centre at distance ``d``, so the
distance is ``max(y / t_y - z, |x| / t_x - z)`` over the vertices, with ``t`` the half frame less the margin
over the focal length.

The distance used for frame ``i`` is that need, widened to its maximum over ``hold`` frames either side, then
averaged twice over ``smooth`` frames either side: never less than any frame's own need (every average only
takes maxima over windows that contain frame ``i``, as ``hold >= 2 smooth``), it moves in ramps of about
``4 smooth`` frames with no jump, and two raises less than ``2 hold`` frames apart are one zoom out, not two
(no pumping).  Frames that need no more than the configured distance, with neighbours that need none either,
keep it exactly (the same bytes as before this framing).  It needs ``hold + 2 smooth`` frames ahead: a frame
is drawn that many frames after it is given (:meth:`Framing.push`), the rest at the end (:meth:`Framing.flush`);
the distances depend only on the frames, not on how a run is cut into chunks.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

#: the framing's version: part of a stimulus video's render key (experiments/stimuli.py), so a video framed
#: otherwise is rendered again
VERSION = "look-ahead 2026-11-27"


class Framing:
    """The look-ahead distance of a camera (:class:`laughlab.render.scene.Camera`) for frames ``width`` x ``height``.

    Parameters
    ----------
    camera : Camera
        The configured camera (its azimuth, elevation, field of view and distance: the closest it comes).
    margin : float
        Background kept at the top, left and right edges, as a fraction of the height.
    bottom : bool
        Keep it at the bottom edge too (the whole body in the frame, ``output.video.framing=body``).
    hold, smooth : int
        Frames (rendered frames) either side: a raise's zoom is held ``hold``, ramped over about ``4 smooth``.
    """

    def __init__(self, camera, width: int, height: int, margin: float = 0.04, hold: int = 24, smooth: int = 8,
                 bottom: bool = False):
        if hold < 2 * smooth:
            raise ValueError("hold must be at least 2 smooth (else a frame could need more than it gets)")
        _, self.rot = camera.basis(np.zeros(3))   # right, up, forward: the same for any aim and distance
        self.base = float(camera.distance_cm)
        focal = 0.5 * height / math.tan(math.radians(camera.fov_deg) / 2)
        self.ty = (0.5 * height - margin * height) / focal
        self.tx = (0.5 * width - margin * height) / focal
        self.hold, self.smooth, self.bottom = int(hold), int(smooth), bool(bottom)
        self.needs: list[float] = []
        self.queue: deque = deque()   # (frame index, job) not drawn yet
        self.done = 0                 # frames handed out

    def need(self, vertices: np.ndarray, aim: np.ndarray) -> float:
        """The smallest distance (cm, at least the configured one) keeping ``vertices`` (cm) inside the frame."""
        c = (np.asarray(vertices, dtype=np.float64) - aim) @ self.rot.T
        up = np.abs(c[:, 1]) if self.bottom else c[:, 1]
        d = max(float(np.max(up / self.ty - c[:, 2])), float(np.max(np.abs(c[:, 0]) / self.tx - c[:, 2])))
        return max(self.base, d)

    def push(self, job, need: float) -> list:
        """Add a frame (``job``: what draws it) and its :meth:`need`; return the ``(job, distance)`` now ready."""
        self.needs.append(float(need))
        self.queue.append(job)
        ready = []
        while self.queue and self.done + self.hold + 2 * self.smooth < len(self.needs):
            ready.append(self._next())
        return ready

    def flush(self) -> list:
        """The frames still held, with their distances (the run has ended: no more frames ahead)."""
        out = [self._next() for _ in range(len(self.queue))]
        self.needs, self.done = [], 0
        return out

    def _next(self):
        i = self.done
        self.done += 1
        return self.queue.popleft(), self._distance(i)

    def _distance(self, i: int) -> float:
        n, h, s = len(self.needs), self.hold, self.smooth
        lo = max(0, i - 2 * s - h)
        a = np.asarray(self.needs[lo: min(n, i + 2 * s + h + 1)])
        widened = {k: float(a[max(0, k - h) - lo: min(n, k + h + 1) - lo].max())
                   for k in range(max(0, i - 2 * s), min(n, i + 2 * s + 1))}
        once = {k: _mean([widened[j] for j in range(max(0, k - s), min(n, k + s + 1))])
                for k in range(max(0, i - s), min(n, i + s + 1))}
        return _mean([once[k] for k in range(max(0, i - s), min(n, i + s + 1))])


def _mean(values: list[float]) -> float:
    """The mean, exactly the value when all are equal (the configured distance stays bit for bit)."""
    return values[0] if min(values) == max(values) else float(np.mean(values))
