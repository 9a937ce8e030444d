"""The input stream at 16 kHz, as YAMNet takes it, and the log-mel rows of its windows.

:class:`Resampler16k` converts a stream at any rate from 8 kHz up to 16 kHz (causal, exact whatever the
block sizes); :class:`Window16k` keeps the last :data:`WINDOW` samples at 16 kHz and the log-mel rows
of its windows' frames, so each 10 ms frame of audio goes through the model's front end once;
:func:`to_16k` converts a whole signal.  :mod:`laughlab.detector.yamnet` runs the model on them (its
names are importable from there too).
"""
from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np

from laughlab.detector.yamnet_model import BANDS, FRAME, HOP, RATE, ROWS, WINDOW, frames, frames_at

if TYPE_CHECKING:
    from laughlab.detector.yamnet_model import Yamnet


def sosfilt_carry(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.sosfilt(sos, x, zi=zi)`` for a 1-D float64 ``x``: (filtered ``x``, final state).

    scipy 1.16's ``sosfilt`` spends about 0.15 ms per call checking and reshaping its arguments (array-API
    dispatch, validation) before its compiled kernel runs: more than filtering one 60 fps block at 44.1 kHz
    takes.  This calls that kernel (``scipy.signal._sosfilt._sosfilt``, which filters ``x`` in place) with
    the arguments already in its layout, bit for bit ``sosfilt``'s result (``tests/test_yamnet.py`` compares
    them on random blocks); where the kernel is not there (another scipy), ``sosfilt`` itself."""
    kernel = _sos_kernel()
    if kernel is not None:
        y = np.array(x, np.float64, order="C").reshape(1, -1)
        z = np.array(zi, np.float64, order="C").reshape(1, len(sos), 2)
        kernel(np.asarray(sos, np.float64), y, z)
        return y[0], z[0]
    from scipy.signal import sosfilt

    return sosfilt(sos, x, zi=zi)


@functools.cache
def _sos_kernel():
    """scipy's compiled second-order-sections filter where scipy 1.11-1.16 keep it, else None (looked up
    once, when first used: importing ``scipy.signal`` takes about half a second)."""
    try:
        from scipy.signal._sosfilt import _sosfilt
    except ImportError:
        return None
    return _sosfilt


class Resampler16k:
    """Streaming conversion to 16 kHz, exact whatever the block sizes (causal, stateful).

    Above 16 kHz: an 8th-order Butterworth low-pass at 7.2 kHz (``sosfilt`` with its state
    carried from block to block), then linear interpolation at the 16 kHz instants
    ``j / 16000`` (integer arithmetic for the positions).  At 8-16 kHz: linear interpolation.
    YAMNet's mel bands end at 7.5 kHz, so the band it hears is kept.  An output sample is
    made once the input sample after its instant has arrived.
    """

    def __init__(self, sample_rate: int):
        sr = int(sample_rate)
        if sr < 8000:
            raise ValueError(f"the yamnet detector needs a sample rate of at least 8000 Hz (got {sr})")
        self.sr = sr
        self.sos = None
        if sr > RATE:
            from scipy.signal import butter

            self.sos = butter(8, 7200.0, fs=sr, output="sos")
        self.reset()

    def reset(self) -> None:
        from scipy.signal import sosfilt_zi

        self.zi = None if self.sos is None else sosfilt_zi(self.sos) * 0.0
        self.n = 0          # input samples received
        self.j = 0          # output samples made
        self.last = 0.0     # the last filtered input sample (index n - 1)

    def state(self) -> tuple:
        """Everything the next ``push`` depends on (``restore`` takes it back)."""
        return (None if self.zi is None else self.zi.copy(), self.n, self.j, self.last)

    def restore(self, state: tuple) -> None:
        zi, self.n, self.j, self.last = state
        self.zi = None if zi is None else zi.copy()

    def j_after(self, n: int) -> int:
        """The 16 kHz samples made once ``n`` input samples have arrived (``push`` makes this many)."""
        if self.sr == RATE:
            return int(n)
        return ((int(n) - 1) * RATE - 1) // self.sr + 1 if n > 1 else 0

    def push(self, block: np.ndarray) -> np.ndarray:
        x = np.asarray(block, dtype=np.float64).ravel()
        if self.sr == RATE:
            self.n += len(x)
            self.j += len(x)
            return x
        if self.sos is not None and len(x):
            x, self.zi = sosfilt_carry(self.sos, x, self.zi)
        base = self.n - 1                   # index of ``self.last``
        ext = np.concatenate([[self.last], x])
        self.n += len(x)
        if len(x):
            self.last = float(x[-1])
        # outputs j with floor(j sr / 16000) + 1 <= n - 1, i.e. the sample after the instant is here
        j_end = self.j_after(self.n)
        j = np.arange(self.j, max(self.j, j_end), dtype=np.int64)
        self.j = max(self.j, j_end)
        num = j * self.sr
        i0 = num // RATE
        frac = (num % RATE) / RATE
        k = i0 - base
        return ext[k] * (1.0 - frac) + ext[k + 1] * frac


def cleaned(x: np.ndarray) -> np.ndarray:
    """Samples as the model's conversion takes them: non-finite ones (NaN, inf) read as 0, the rest clipped
    to [-1, 1] (in place: ``x`` is the caller's own copy)."""
    if not np.isfinite(x).all():
        x = np.where(np.isfinite(x), x, 0.0)
    return np.clip(x, -1.0, 1.0, out=x)


class Window16k:
    """The last ``WINDOW`` samples of a stream at 16 kHz, from blocks at the stream's own rate (causal).

    The 16 kHz samples come from :class:`Resampler16k`; a stream shorter than the window is
    padded with zeros before its start.  The result depends only on the samples received
    so far, never on how they were cut into blocks.  ``patch(model)`` gives the window's 96 x 64
    log-mel rows, computing only the rows of frames the previous window did not hold.
    """

    def __init__(self, sample_rate: int):
        self.rs = Resampler16k(sample_rate)
        self.buf = np.zeros(WINDOW, np.float32)
        self.pending: list = []
        self.rows = np.empty((0, BANDS), np.float32)  # log-mel rows of the frames starting at first + HOP i
        self.first = None         # the 16 kHz sample the first kept row's frame starts at
        self.last_end = None      # the 16 kHz sample count at the last window
        self.on_grid = True       # did the last window fall on the grid of the one before (stride a multiple of HOP)?

    def reset(self) -> None:
        self.rs.reset()
        self.buf[:] = 0.0
        self.pending = []
        self.rows = np.empty((0, BANDS), np.float32)
        self.first = None
        self.last_end = None
        self.on_grid = True

    def restore(self, state) -> None:
        """Take up a stream where :class:`Ahead` left it: ``state`` = (the conversion's state, the last
        ``WINDOW`` samples at 16 kHz) after the last window it served; None: the stream's start."""
        self.reset()
        if state is not None:
            self.rs.restore(state[0])
            self.buf[:] = state[1]

    def push(self, block: np.ndarray) -> None:
        """Keep a copy of a block; blocks are converted when the window is next asked for (the same bytes,
        cheaper).

        Samples outside [-1, 1] are clipped and non-finite ones (NaN, inf) read as 0, so one bad
        sample cannot poison the filter's state."""
        self.pending.append(np.array(block, dtype=np.float64).ravel())

    def _convert(self) -> None:
        if not self.pending:
            return
        x = self.pending[0] if len(self.pending) == 1 else np.concatenate(self.pending)
        self.pending = []
        y = self.rs.push(cleaned(x))
        k = len(y)
        if k >= WINDOW:
            self.buf[:] = y[-WINDOW:]
        elif k:
            self.buf[:-k] = self.buf[k:]
            self.buf[-k:] = y

    def window(self) -> np.ndarray:
        """The last 0.975 s at 16 kHz (zeros before the stream's start), float32 clipped to [-1, 1]."""
        self._convert()
        return np.clip(self.buf, -1.0, 1.0)

    def prepare(self, model: "Yamnet") -> None:
        """Between windows: convert the blocks kept so far and compute the log-mel rows of the next window's
        frames that are already complete (its frames lie on the last window's grid of 160 samples), so the
        window's own frame has less to do.  Changes no result, only when the work is done.

        Rows are computed only while windows fall on one another's grid: when the last two windows were not
        a multiple of 160 samples apart (at 30 fps a window every 8 frames is 4,266.7 samples), the next one
        will not be on the last one's grid either, and rows made on it would be thrown away (they were: 119
        rows a window instead of 96 before 2026-11-26)."""
        self._convert()
        if self.first is None or not self.on_grid:
            return
        j, s0 = self.rs.j, self.first + HOP * len(self.rows)   # the next frame on the last window's grid
        n = max(0, (j - FRAME - s0) // HOP + 1)      # frames starting at s0 + HOP i that end by sample j
        if n == 0:
            return
        w = np.clip(self.buf, -1.0, 1.0)
        a = s0 - (j - WINDOW)                         # the first frame's place in the buffer
        self.rows = np.concatenate([self.rows, model.logmel(frames_at(w, a + HOP * np.arange(n)))])

    def patch(self, model: "Yamnet", window: np.ndarray | None = None) -> np.ndarray:
        """The window's log-mel rows (96, 64): ``model.logmel(frames(window()))``, bit for bit, computing only
        the rows of frames no earlier window or ``prepare`` has (a row depends on its own frame only).

        The kept rows are one run on a grid of 160 samples (the last window's, then ``prepare``'s), so the
        rows this window can take from them are one run of its own, found by arithmetic."""
        w = self.window() if window is None else window
        j = self.rs.j
        start = j - WINDOW                                 # the window's first frame
        lo = hi = 0                                        # its rows [lo, hi) are kept ones
        if self.first is not None and (start - self.first) % HOP == 0:
            d = (start - self.first) // HOP                # the kept row of the window's first frame
            lo, hi = max(0, -d), min(ROWS, len(self.rows) - d)
        if lo >= hi:
            out = model.logmel(frames(w))
        else:
            out = np.empty((ROWS, BANDS), np.float32)
            out[lo:hi] = self.rows[lo + d:hi + d]
            if lo:
                out[:lo] = model.logmel(frames_at(w, HOP * np.arange(lo)))
            if hi < ROWS:
                out[hi:] = model.logmel(frames_at(w, HOP * np.arange(hi, ROWS)))
        self.rows, self.first = out, start
        self.on_grid = self.last_end is None or (j - self.last_end) % HOP == 0
        self.last_end = j
        return out


#: input samples converted at a time by ``to_16k`` and ``window_scores`` (:func:`chunks`): the conversion does not depend on how
#: the input is cut, and on a 30-minute file the whole-signal temporaries (hundreds of MB) cost more in page
#: faults than the arithmetic (``laughlab detect``: 10.9 s to convert it whole, 2026-11-26)
CONVERT_CHUNK = 1 << 18


def pieces_16k(audio: np.ndarray, sample_rate: int):
    """A whole signal at 16 kHz in pieces, ``CONVERT_CHUNK`` input samples at a time (the live conversion's
    bytes, :class:`Resampler16k`); at least one piece."""
    rs = Resampler16k(sample_rate)
    for piece in chunks(audio):   # each piece made float64 by push: no float64 copy of the whole signal
        yield rs.push(finite(piece))


def chunks(audio: np.ndarray):
    """A whole signal's samples ``CONVERT_CHUNK`` at a time, as views (at least one, empty for an empty signal)."""
    x = np.asarray(audio).ravel()
    return (x[i:i + CONVERT_CHUNK] for i in range(0, max(len(x), 1), CONVERT_CHUNK))


def finite(piece: np.ndarray) -> np.ndarray:
    """NaN/inf read as 0, as live (:func:`cleaned`): one would poison the filter's state for the rest of the file
    (a review: ``detect`` lost every laugh after a single NaN in a 44.1 kHz file)."""
    return piece if np.isfinite(piece).all() else np.where(np.isfinite(piece), piece, 0.0)


def to_16k(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """A whole signal at 16 kHz, the live conversion's bytes (:class:`Resampler16k`)."""
    parts = list(pieces_16k(audio, sample_rate))
    return parts[0] if len(parts) == 1 else np.concatenate(parts)
