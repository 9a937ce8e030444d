"""A software z-buffer rasteriser (numba): the skinned character drawn without a GPU.

Triangles are filled by edge functions over their bounding boxes, with top-left fill rules so
that shared edges are drawn once; depth is interpolated linearly in screen space and tested per
pixel; colours are interpolated per vertex (Gouraud).  Same input, same pixels: the arithmetic
is fixed, there is no thread or driver in it.
"""
from __future__ import annotations

import numpy as np

try:  # numba is a dependency; LAUGHLAB_NUMBA=0 still needs a way out
    from numba import njit
except ImportError:  # pragma: no cover
    njit = None


def _rasterise(xy, depth, colour, tris, image, zbuf):
    h, w = zbuf.shape
    for t in range(tris.shape[0]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        x0, y0 = xy[i0, 0], xy[i0, 1]
        x1, y1 = xy[i1, 0], xy[i1, 1]
        x2, y2 = xy[i2, 0], xy[i2, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area >= 0.0:  # back-facing (counter-clockwise in the world is clockwise with y down) or empty
            continue
        inv = 1.0 / area
        xmin = max(int(np.floor(min(x0, x1, x2))), 0)
        xmax = min(int(np.ceil(max(x0, x1, x2))), w - 1)
        ymin = max(int(np.floor(min(y0, y1, y2))), 0)
        ymax = min(int(np.ceil(max(y0, y1, y2))), h - 1)
        if xmin > xmax or ymin > ymax:
            continue
        z0, z1, z2 = depth[i0], depth[i1], depth[i2]
        for py in range(ymin, ymax + 1):
            sy = py + 0.5
            for px in range(xmin, xmax + 1):
                sx = px + 0.5
                w0 = ((x2 - x1) * (sy - y1) - (y2 - y1) * (sx - x1)) * inv
                w1 = ((x0 - x2) * (sy - y2) - (y0 - y2) * (sx - x2)) * inv
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2
                if z >= zbuf[py, px]:
                    continue
                zbuf[py, px] = z
                for c in range(3):
                    image[py, px, c] = w0 * colour[i0, c] + w1 * colour[i1, c] + w2 * colour[i2, c]


_compiled = njit(cache=True, nogil=True)(_rasterise) if njit is not None else _rasterise


def rasterise(xy: np.ndarray, depth: np.ndarray, colour: np.ndarray, tris: np.ndarray,
              background: np.ndarray) -> np.ndarray:
    """Draw triangles into a copy of ``background``.

    Parameters
    ----------
    xy : ndarray (V, 2) float64
        Vertices in pixels (x right, y down).
    depth : ndarray (V,) float64
        Distance along the view axis (smaller is nearer).
    colour : ndarray (V, 3) float64
        Shaded vertex colours, 0..255.
    tris : ndarray (T, 3) int64
        Counter-clockwise as seen from the front in the world (clockwise on screen): others are culled.
    background : ndarray (H, W, 3) float32

    Returns
    -------
    ndarray (H, W, 3) float32
    """
    image = np.array(background, dtype=np.float32, copy=True)
    zbuf = np.full(image.shape[:2], np.inf, dtype=np.float32)
    _compiled(np.ascontiguousarray(xy, dtype=np.float64), np.ascontiguousarray(depth, dtype=np.float64),
              np.ascontiguousarray(colour, dtype=np.float64), np.ascontiguousarray(tris, dtype=np.int64), image, zbuf)
    return image


def draw_frames(draw, jobs: list, threads: int = 2) -> list:
    """``[draw(*job) for job in jobs]``, by ``threads`` threads at once (:func:`rasterise` releases the GIL).

    ``draw`` must be a pure function of its job (a renderer's per-frame state, such as a camera that follows
    the body, is computed into the jobs first), so the frames are the bytes one thread would draw."""
    if threads <= 1 or len(jobs) < 2:
        return [draw(*j) for j in jobs]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(threads, thread_name_prefix="laughlab-render") as pool:
        return list(pool.map(lambda j: draw(*j), jobs))
