"""Google's YAMNet sound-event model on a stream, and its laughter score.

The bundled model and its split in its own layers are :mod:`laughlab.detector.yamnet_model`
(:class:`Yamnet`; its names are importable from here too).

:class:`Window16k` keeps the last second of a stream at its own rate and gives the
last :data:`WINDOW` samples at 16 kHz (a causal low-pass and linear interpolation,
:class:`Resampler16k`), so any rate from 8 kHz up works.  A stream shorter than the
window is padded with zeros *before* its start (the model hears silence there).  It also
keeps the windows' log-mel rows, so each 10 ms frame of audio goes through the front end once.
:class:`Ahead` computes an offline file's windows ahead in helper threads (same bytes).

:class:`Head` maps the 521 scores to one laughter probability: a logistic
regression fitted on the corpus' train split (``python -m laughlab.detector.yamnet_fit``,
``laughlab/data/yamnet/head.json``); without a head, the largest score of the
six laughter classes (Laughter, Baby laughter, Giggle, Snicker, Belly laugh,
Chuckle/chortle).
"""
from __future__ import annotations

import json
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laughlab.detector import yamnet_model as _model
from laughlab.detector.yamnet_model import (  # noqa: F401  (the names users of this module know)
    BANDS, FRAME, HOP, LAUGH_CLASSES, MODEL_SHA256, N_CLASSES, RATE, RESTORE, ROWS, WINDOW, ModelFileError, Yamnet,
    class_names, data_dir, frame_starts, frames, frames_at, laugh_indices)


#: the helper thread that runs model windows off the frame thread (``detector.async_frames``), per process
_HELPER: dict = {}


def _process_pool(store: dict, threads: int, prefix: str):
    """A thread pool that lives as long as the process (made again in a forked child, where it is gone)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    pid = os.getpid()
    if store.get("pid") != pid:
        store.update(pid=pid, pool=ThreadPoolExecutor(threads, thread_name_prefix=prefix))
    return store["pool"]


def helper():
    """The process' one helper thread for model windows (``detector.async_frames``)."""
    return _process_pool(_HELPER, 1, "laughlab-yamnet")


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


_SOS: list = []


def _sos_kernel():
    """scipy's compiled second-order-sections filter where scipy 1.11-1.16 keep it, else None (looked up
    once, when first used: importing ``scipy.signal`` takes about half a second)."""
    if not _SOS:
        try:
            from scipy.signal._sosfilt import _sosfilt
        except ImportError:
            _sosfilt = None
        _SOS.append(_sosfilt)
    return _SOS[0]


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


#: threads running the network on prefetched windows (``Ahead``)
NET_THREADS = 2


_NET_POOL: dict = {}


def net_pool():
    """The process' network threads for prefetched and offline windows; they live as long as the process,
    so their interpreters are loaded once."""
    return _process_pool(_NET_POOL, NET_THREADS, "laughlab-yamnet-net")


def _scores_here(y: np.ndarray, ends: list, model: Yamnet | None = None) -> np.ndarray:
    """The scores of the windows of the 16 kHz samples ``y`` (clipped) ending at the indices ``ends``, by this
    thread's own interpreters (or ``model``'s): each distinct frame's row once, then the patches in one call."""
    model = model or Yamnet()
    starts = np.stack([frame_starts(e) for e in ends])            # (windows, 96)
    distinct, where = np.unique(starts, return_inverse=True)
    rows = model.logmel(frames_at(y, distinct))
    return model.network(rows[where.reshape(starts.shape)])


class Ahead:
    """Model windows of an offline input computed ahead, in a helper thread, several at once.

    ``blocks()`` gives the run's blocks from the start (a second reading of the file).  The thread
    converts them as :class:`Window16k` does (its own), takes a window every ``hop`` blocks, computes
    the windows' log-mel rows and runs the network on ``batch`` patches in one call.
    ``scores(raw)`` gives the next window's scores if the input samples the helper read since the
    window before (its ``hop`` blocks) are ``raw`` sample for sample, else None: the conversion
    depends on the samples only, so equal samples mean the frame thread's own window, and the
    scores are bit for bit the frame thread's.  The frame thread therefore converts nothing while
    the helper serves it; ``state`` is the conversion's state at the end of the last window served
    (``Window16k.restore``), from which the frame thread takes over on a mismatch.  At most
    ``ahead`` windows wait; ``close()`` stops the thread.
    """

    def __init__(self, blocks, sample_rate: int, hop: int, batch: int = 16, ahead: int = 96):
        import queue

        self.q: "queue.Queue" = queue.Queue(maxsize=ahead)
        self.stop = threading.Event()
        self.done = False
        self.served = 0     # windows whose scores the frame thread took
        self.state = None   # the conversion's state after the last window served (None: the start)
        self.thread = threading.Thread(target=self._run, args=(blocks, int(sample_rate), int(hop), int(batch)),
                                       name="laughlab-yamnet-ahead", daemon=True)
        self.thread.start()

    def _put(self, item) -> bool:
        import queue

        while not self.stop.is_set():
            try:
                self.q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _run(self, blocks, sr: int, hop: int, batch: int) -> None:
        try:
            self._windows(blocks, sr, hop, batch)
        except BaseException:   # the frame thread reads the input itself and meets the error there
            pass
        self._put(None)

    def _windows(self, blocks, sr: int, hop: int, batch: int) -> None:
        """``batch`` windows at a time: each window's blocks converted in one piece (the conversion does not
        depend on how blocks are cut), the conversion's state kept at each window's end, then the windows'
        log-mel rows and scores computed by the process' two network threads (one set of interpreters each,
        ``net_pool``), whose results are queued in order.  The threads take the GIL a few times per batch,
        not per window; the frame thread and the helpers share the two cores."""
        from collections import deque

        rs = Resampler16k(sr)
        tail = np.zeros(WINDOW, np.float32)          # the 16 kHz samples before ``base`` (zeros before the start)
        base = 0                                     # 16 kHz sample index of the sample after ``tail``
        kept: list = []                              # the blocks since the last window
        raws, pieces, states = [], [], []            # per window of the batch: its input samples, 16 kHz, state
        running: deque = deque()                     # (raws, states, windows' ends, y, future of scores)
        it = iter(blocks())
        k = 0
        pool = net_pool()
        try:
            while not self.stop.is_set():
                for block in it:
                    kept.append(np.array(block, dtype=np.float64).ravel())
                    k += 1
                    if k % hop == 0:
                        raw = np.concatenate(kept)
                        kept = []
                        raws.append(raw)
                        pieces.append(rs.push(cleaned(raw.copy())).astype(np.float32))
                        states.append(rs.state())
                        if len(raws) == batch:
                            break
                if not raws:
                    break
                y = np.concatenate([tail, *pieces])
                ends = list(np.cumsum([len(q) for q in pieces]) + WINDOW)
                running.append((raws, states, ends, y, pool.submit(_scores_here, np.clip(y, -1.0, 1.0), ends)))
                base += len(y) - WINDOW
                tail = y[-WINDOW:]
                raws, pieces, states = [], [], []
                while len(running) > NET_THREADS and not self._flush(running.popleft()):
                    return
            while running and self._flush(running.popleft()):
                pass
        finally:
            for *_, fut in running:
                fut.cancel()

    def _flush(self, job) -> bool:
        raws, states, ends, y, fut = job
        for raw, st, e, sc in zip(raws, states, ends, fut.result()):
            if not self._put((raw, sc, (st, y[e - WINDOW:e]))):
                return False
        return True

    def scores(self, raw: np.ndarray) -> np.ndarray | None:
        """The next window's scores if the helper read ``raw`` (the input samples since the window before);
        None when it did not or the helper has stopped (from then on it is not asked again)."""
        if self.done:
            return None
        item = self.q.get()
        if item is None or not np.array_equal(item[0], raw):
            self.done = True
            return None
        self.served += 1
        self.state = item[2]
        return item[1]

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


#: input samples converted at a time by ``to_16k`` and ``window_scores``: the conversion does not depend on how
#: the input is cut, and on a 30-minute file the whole-signal temporaries (hundreds of MB) cost more in page
#: faults than the arithmetic (``laughlab detect``: 10.9 s to convert it whole, 2026-11-26)
CONVERT_CHUNK = 1 << 18


def to_16k(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """A whole signal at 16 kHz, the live conversion's bytes (:class:`Resampler16k`)."""
    rs = Resampler16k(sample_rate)
    x = np.asarray(audio, dtype=np.float64).ravel()
    if len(x) <= CONVERT_CHUNK:
        return rs.push(x)
    return np.concatenate([rs.push(x[i:i + CONVERT_CHUNK]) for i in range(0, len(x), CONVERT_CHUNK)])


@dataclass
class Head:
    """Logistic regression on the 521 scores: ``p = sigmoid(w . log(scores + eps) + b)``."""

    w: np.ndarray
    b: float
    eps: float
    meta: dict

    @classmethod
    def load(cls, path: str | Path | None = None) -> "Head | None":
        p = Path(path) if path is not None else _model.data_dir() / "head.json"
        if path is None and not p.exists():
            return None
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
            w = np.array(d["weights"], dtype=np.float64)
            if w.shape != (N_CLASSES,):
                raise ValueError("wrong length")
            return cls(w, float(d["bias"]), float(d["eps"]), d)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ModelFileError(f"cannot read the YAMNet head {p} ({exc}): {RESTORE}; "
                                 f"or refit it: python -m laughlab.detector.yamnet_fit") from None

    def features(self, scores: np.ndarray) -> np.ndarray:
        return np.log(np.asarray(scores, dtype=np.float64) + self.eps)

    def prob(self, scores: np.ndarray) -> np.ndarray:
        z = self.features(scores) @ self.w + self.b
        return 1.0 / (1.0 + np.exp(-np.clip(z, -30.0, 30.0)))


def class_score(scores: np.ndarray, idx) -> np.ndarray:
    """YAMNet's own laughter score, untuned: the largest of the six laughter classes' scores."""
    return np.max(np.asarray(scores)[..., idx], axis=-1)


class LaughterScore:
    """Scores -> laughter probability: the head when bundled, else the largest laughter-class score.

    ``both(scores)`` gives ``(head probability, laughter-class score)`` (the head's is the class
    score when there is no head)."""

    def __init__(self, head: str | Path | None = None, use_head: bool = True):
        self.idx = laugh_indices(class_names())
        self.head = Head.load(head) if use_head else None

    def __call__(self, scores: np.ndarray) -> float:
        return self.both(scores)[0]

    def both(self, scores: np.ndarray) -> tuple[float, float]:
        q = float(class_score(scores, self.idx))
        return (float(self.head.prob(scores)) if self.head is not None else q), q


def window_scores(audio: np.ndarray, sample_rate: int, ends: np.ndarray, model: Yamnet | None = None) -> np.ndarray:
    """The 521 scores of the windows ending at the sample indices ``ends`` of ``audio`` (zeros before 0).

    Offline use (``laughlab detect``, the fits and the benchmarks).  For a window ending at input sample
    ``e`` the model hears 16 kHz samples up to ``e * 16000 / sr`` (zeros past the end).  The signal is
    converted ``CONVERT_CHUNK`` samples at a time, and windows go to the model 64 at a time as soon as
    their samples are converted, each distinct 10 ms frame's log-mel row computed once, on the process'
    two network threads (the bundled model), which run while the rest is converted.  The scores are the
    one-window-at-a-time scores bit for bit.
    """
    model = model or Yamnet()
    sr = int(sample_rate)
    x = np.asarray(audio, dtype=np.float64).ravel()
    rs = Resampler16k(sr)
    pad = np.zeros(rs.j_after(len(x)) + 2 * WINDOW, np.float32)     # zeros before the start and past the end
    e16 = [int(round(int(e) * RATE / sr)) + WINDOW for e in ends]
    if e16 and (min(e16) < WINDOW or max(e16) > len(pad)):
        raise ValueError("a window ends outside the audio")
    chunks = [e16[a:a + 64] for a in range(0, len(e16), 64)]
    threads = model.bundled and len(chunks) > 1     # the process' two network threads, 64 windows each at a time
    parts: list = []
    filled = WINDOW                                 # pad[:filled] holds its samples

    def ready(upto: int) -> None:
        while len(parts) < len(chunks) and max(chunks[len(parts)]) <= upto:
            c = chunks[len(parts)]
            parts.append(net_pool().submit(_scores_here, pad, c) if threads else _scores_here(pad, c, model))

    for i in range(0, len(x), CONVERT_CHUNK):
        y = rs.push(x[i:i + CONVERT_CHUNK])
        pad[filled:filled + len(y)] = np.clip(y, -1.0, 1.0)
        filled += len(y)
        ready(filled)
    ready(len(pad))
    parts = [p.result() if threads else p for p in parts]
    return np.concatenate(parts) if parts else np.empty((0, N_CLASSES))
