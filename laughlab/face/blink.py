"""Blinks (van Duijn 2014, 3.3.3), shared by every face."""
from __future__ import annotations

import numpy as np


class Blinker:
    """Blinks every N(mean, sd) seconds, skipped while the eyes are closed or closing (thesis 3.3.3).

    The rule of the ``smile`` face: the first interval is drawn at the first
    frame; when a blink is due and ``busy`` (the eyes are closed or closing for
    another reason) it is skipped and the next interval drawn; otherwise the
    lids close linearly over ``close_s`` and open over ``open_s``, and the next
    interval is drawn when the blink ends.  Intervals below ``min_interval_s``
    (the normal can go negative) are raised to it.

    With ``dt`` (the frame period, s) the thesis' "very short keyframed
    animation that closes and opens the eyes" is played on the frame grid: it
    closes over ``close_s`` and opens over ``open_s`` each rounded to whole
    frames (at least one), so one frame always shows the eyes closed (our
    departure of under half a frame: sampled in time, at 30 fps no frame fell on
    the closed key, and every blink stopped at 0.83; 0.97 at 24 and 60 fps; a
    facial animator's review).  Without ``dt`` the key times are seconds.
    """

    def __init__(self, rng: np.random.Generator, mean_s: float = 4.0, sd_s: float = 2.0,
                 min_interval_s: float = 0.5, close_s: float = 0.08, open_s: float = 0.12, dt: float | None = None):
        self.rng = rng
        self.mean_s, self.sd_s, self.min_interval_s = mean_s, sd_s, min_interval_s
        self.frames = None if dt is None else tuple(max(1, round(d / dt)) for d in (close_s, open_s))
        if dt is not None:   # whole frames: the closed key on a frame
            close_s, open_s = (n * dt for n in self.frames)
        self.close_s, self.open_s, self.dt = close_s, open_s, dt
        self.reset()

    def reset(self) -> None:
        self.next_blink = None
        self.blink_start = None

    def _interval(self) -> float:
        return max(self.min_interval_s, float(self.rng.normal(self.mean_s, self.sd_s)))

    def step(self, t: float, busy: bool) -> float:
        """The blink's lid closure at time ``t`` (s), in [0, 1]."""
        if self.next_blink is None:
            self.next_blink = t + self._interval()
        if self.blink_start is None and t >= self.next_blink:
            if busy:
                self.next_blink = t + self._interval()
            else:
                self.blink_start = t
        if self.blink_start is None:
            return 0.0
        u = t - self.blink_start
        if self.dt is not None:   # frames since the blink began, exact on the frame grid
            k, (n_close, n_open) = round(u / self.dt), self.frames
            if k <= n_close:
                return k / n_close
            if k < n_close + n_open:
                return 1.0 - (k - n_close) / n_open
        elif u < self.close_s:
            return u / self.close_s
        elif u - self.close_s < self.open_s:
            return 1.0 - (u - self.close_s) / self.open_s
        self.blink_start = None
        self.next_blink = t + self._interval()
        return 0.0
