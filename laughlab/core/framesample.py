"""Per-frame figures (a frame's compute time, a stream's latency) kept in bounded memory for their percentiles
(:class:`FrameSample`): the frame loop's and the vmc sink's, for a session that runs until it is stopped."""
from __future__ import annotations

from array import array

import numpy as np


class FrameSample:
    """Per-frame figures (compute ns, latency ms) for their percentiles, in bounded memory for a session that
    runs until stopped (review-live 10: a list grew 34 bytes a frame, about 1 GB a day).

    ``values`` is appended to once a frame (``values.append``, the frame loop's fast path) and :meth:`settle`
    is called now and then (every chunk).  Every frame is kept until ``2 * cap`` are; then every second one,
    then every fourth...: those of frames ``0, s, 2s, ...`` for a stride ``s`` that doubles each time the
    array fills, so the kept ones stay evenly spread over the whole run.  The count and the maximum stay
    exact.  A run shorter than ``2 * cap`` frames (73 min at 60 fps) keeps every value, as before.
    """

    #: ``cap`` unless one is given: 2**17, so at most 2**18 values (2 MB of 8-byte values)
    CAP = 1 << 17

    def __init__(self, typecode: str, cap: int | None = None):
        self.values = array(typecode)
        self.cap = int(cap or self.CAP)
        self.stride = 1
        self.n = 0          # frames settled
        self._peak = None   # the maximum of the frames settled and no longer kept
        self._kept = 0      # len(values) at the last settle

    def append(self, x) -> None:
        self.values.append(x)

    def settle(self) -> None:
        a, start = self.values, self._kept
        new = len(a) - start
        if self.stride > 1 and new:
            tail = a[start:]
            self._peak = max(self._peak, max(tail))
            first = -self.n % self.stride   # the first new frame whose index is a multiple of the stride
            del a[start:]
            a.extend(tail[first::self.stride])
        self.n += new
        while len(a) >= 2 * self.cap:
            self._peak = max(a) if self._peak is None else max(self._peak, max(a))
            del a[1::2]
            self.stride *= 2
        self._kept = len(a)

    def array(self, dtype):
        """The kept values as a numpy array (settled first)."""
        self.settle()
        return np.frombuffer(self.values, dtype=dtype) if len(self.values) else np.zeros(0, dtype=dtype)

    def max(self):
        """The largest value of every frame (None when there were none)."""
        self.settle()
        top = max(self.values) if len(self.values) else None
        return top if self._peak is None else self._peak if top is None else max(top, self._peak)
