"""Rise/fall rate limiting and the thesis' ``Smoother`` (van Duijn 2014, Eq. 3.2 and 5.3).

The thesis applies its constants once per 60 Hz game tick; here every rate is
per second (per-tick value x 60), so results do not change with the frame rate.

A limiter stepped once a frame lets a signal that starts rising anywhere inside a frame's block rise a whole
frame's worth, ``rise * dt``, by the block's end: at 60 fps one thesis tick's step (the jaw 0.03 of its range in
16.7 ms), at 144 fps only 0.0125 in 6.9 ms.  Above 60 fps that made the first response to a call smaller, and
the jaw and the MCS answered later than at 60 fps (docs/latency.md: a median of 44.1 ms at 144 fps against
37.1 ms at 60).  So above 60 fps a limiter keeps a **rise budget** (:func:`rise_budget`): it may rise by one
thesis tick's step, ``rise / 60``, at once, and the budget refills at ``rise`` per second, up to that step again
(a token bucket).  Over any stretch of frames the rise is then at most ``rise / 60 + rise * (T - dt)`` for a
stretch ``T`` long, which at 60 fps is the thesis' ``rise * T`` exactly; at and below 60 fps nothing changes
(the same bytes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: ticks per second of the thesis' Blender game engine, used to convert its per-tick constants
THESIS_TICK_HZ = 60.0


def rate_limit(x: float, prev: float, rise: float, fall: float) -> float:
    """One step of the rise/fall limit (van Duijn 2014, Eq. 3.2).

    ``final = min(x, prev + rise)`` if ``x > prev`` else ``max(x, prev - fall)``.

    Parameters
    ----------
    x : float
        New value of the signal.
    prev : float
        Limited value of the previous step.
    rise, fall : float
        Largest increase and decrease in this step (signal units per step,
        i.e. rate per second times dt).
    """
    if x > prev:
        return min(x, prev + rise)
    return max(x, prev - fall)


def rise_budget(rise_per_s: float, dt: float) -> float | None:
    """The most a limiter stepped every ``dt`` seconds may rise at once: one thesis tick's step,
    ``rise_per_s / 60``, when a frame is shorter than a tick (above 60 fps); None at 60 fps and below, where
    every frame may rise ``rise_per_s * dt`` (Eq. 3.2 as the thesis steps it, unchanged)."""
    return rise_per_s / THESIS_TICK_HZ if dt * THESIS_TICK_HZ < 1.0 - 1e-9 else None


def refill(left: float, used: float, step: float, cap: float) -> float:
    """The rise budget of the next frame: what this frame left (``left - used``), plus one frame's refill
    ``step`` (``rise * dt``), at most ``cap`` (:func:`rise_budget`)."""
    left = left - used
    return min(cap, (left if left > 0.0 else 0.0) + step)


def rate_limit_series(x: np.ndarray, rise_per_s: float, fall_per_s: float, dt: float,
                      start: float = 0.0) -> np.ndarray:
    """Apply :func:`rate_limit` along a series (Eq. 3.2), starting from ``start``, with the rise budget of
    frames shorter than a thesis tick (:func:`rise_budget`) as the extractor and the smoothers keep it.

    Rates are in signal units per second; ``dt`` is the step (s).
    """
    out = np.empty(len(x))
    prev = float(start)
    rise, fall = rise_per_s * dt, fall_per_s * dt
    cap = rise_budget(rise_per_s, dt)
    left = rise if cap is None else cap
    for i, v in enumerate(np.asarray(x, dtype=float).tolist()):
        y = rate_limit(v, prev, left, fall)
        if cap is not None:
            left = refill(left, y - prev if y > prev else 0.0, rise, cap)
        out[i] = prev = y
    return out


@dataclass
class SmootherParams:
    """Parameters of one :class:`Smoother` (thesis 5.3), rates per second.

    Attributes
    ----------
    rise : float
        Largest rise of the smoothed signal (1/s).
    fall : float
        Largest fall (1/s).
    min_e, max_e : float
        Input range re-scaled to [0, 1]: below ``min_e`` gives 0, above ``max_e`` gives 1.
    """

    rise: float
    fall: float
    min_e: float = 0.0
    max_e: float = 1.0

    def __post_init__(self) -> None:
        if not self.rise > 0 or not self.fall > 0:
            raise ValueError(f"rise and fall must be > 0 (got {self.rise}, {self.fall})")
        if not self.max_e > self.min_e:
            raise ValueError(f"max_e must be > min_e (got {self.min_e}, {self.max_e})")


def thesis_smoother(rise_per_tick: float, fall_per_tick: float, min_e: float = 0.0,
                    max_e: float = 1.0) -> SmootherParams:
    """SmootherParams from the thesis' per-tick constants (x 60 ticks/s)."""
    return SmootherParams(rise_per_tick * THESIS_TICK_HZ, fall_per_tick * THESIS_TICK_HZ, min_e, max_e)


#: the thesis' four smoothers (5.3), converted to per-second rates
JAW = thesis_smoother(0.03, 0.01, 0.0, 0.8)
SMILE = thesis_smoother(0.03, 0.001, 0.0, 0.3)
CHEST = thesis_smoother(0.2, 0.1, 0.0, 1.0)
BELLY = thesis_smoother(0.1, 0.05, 0.0, 1.0)


class Smoother:
    """Rise/fall limit followed by re-scaling to [0, 1] (van Duijn 2014, listing in 5.3).

    ``e <- rate_limit(x, e, rise*dt, fall*dt)``; output is 0 if ``e < min_e``,
    1 if ``e > max_e``, else ``(e - min_e) / (max_e - min_e)``.  Above 60 fps the rise keeps
    the budget of :func:`rise_budget` (one thesis tick's step at once).
    """

    __slots__ = ("rise", "fall", "min_e", "max_e", "range", "e", "cap", "left")

    def __init__(self, params: SmootherParams, dt: float):
        self.rise = params.rise * dt
        self.fall = params.fall * dt
        self.min_e = params.min_e
        self.max_e = params.max_e
        self.range = params.max_e - params.min_e
        self.cap = rise_budget(params.rise, dt)   # None at 60 fps and below: ``left`` stays ``rise``
        self.reset()

    def reset(self) -> None:
        self.e = 0.0
        self.left = self.rise if self.cap is None else self.cap

    def smooth(self, x: float) -> float:
        """One step: the smoothed and re-scaled value of input ``x`` (dimensionless)."""
        e = self.e
        # min()/max() written out (the same comparisons: min(a, b) is b only if b < a); this runs
        # four times a frame
        if x > e:
            up = e + self.left
            e = up if up < x else x
        else:
            down = e - self.fall
            e = down if down > x else x
        if self.cap is not None:   # above 60 fps: the rise budget (rise_budget)
            self.left = refill(self.left, e - self.e if e > self.e else 0.0, self.rise, self.cap)
        self.e = e
        if e < self.min_e:
            return 0.0
        if e > self.max_e:
            return 1.0
        return (e - self.min_e) / self.range

    def value(self) -> float:
        """The re-scaled value of the current state, without a step (after a face took some of it back).  The
        tail of :meth:`smooth` computes the same inline: calling this there cost 28 ns a call (87 -> 115 ns),
        four times a frame."""
        e = self.e
        return 0.0 if e < self.min_e else 1.0 if e > self.max_e else (e - self.min_e) / self.range
