"""Google's YAMNet sound-event model on a stream, and its laughter score.

The bundled model and its split in its own layers are :mod:`laughlab.detector.yamnet_model`
(:class:`Yamnet`), the stream at 16 kHz and its log-mel rows :mod:`laughlab.detector.stream16k`
(:class:`Window16k` keeps the last second of a stream at its own rate and gives the last
:data:`WINDOW` samples at 16 kHz, so any rate from 8 kHz up works; a stream shorter than the window
is padded with zeros *before* its start); their names are importable from here too.
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
from laughlab.detector.stream16k import (  # noqa: F401  (the names users of this module know)
    CONVERT_CHUNK, Resampler16k, Window16k, chunks, cleaned, finite, pieces_16k, sosfilt_carry, to_16k)
from laughlab.detector.yamnet_model import (  # noqa: F401  (the names users of this module know)
    BANDS, FRAME, HOP, LAUGH_CLASSES, MODEL_SHA256, N_CLASSES, NOISE_CLASSES, NOISE_VETO, OTHER_HUMAN_CLASSES, RATE,
    RESTORE, ROWS, WINDOW, ModelFileError, Yamnet, class_names, data_dir, frame_starts, frames, frames_at, laugh_indices,
    noise_vetoes)


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
        tail = np.zeros(WINDOW, np.float32)          # the last WINDOW samples at 16 kHz (zeros before the start)
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
        if item is None or not np.array_equal(item[0], raw, equal_nan=True):   # NaN samples read as 0 in both
            self.done = True
            return None
        self.served += 1
        self.state = item[2]
        return item[1]

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


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
        self.other_idx = laugh_indices(class_names(), OTHER_HUMAN_CLASSES)
        self.noise_idx = laugh_indices(class_names(), NOISE_CLASSES)
        self.head = Head.load(head) if use_head else None

    def noise(self, scores: np.ndarray) -> float:
        """The largest score of YAMNet's steady-noise classes (``NOISE_CLASSES``: white and pink noise, static,
        hiss...)."""
        return float(class_score(scores, self.noise_idx))

    def other_human(self, scores: np.ndarray) -> float:
        """The largest score of YAMNet's other non-speech human sounds (``OTHER_HUMAN_CLASSES``: coughs,
        sneezes, screams, cries, moans, groans, grunts, breathing, gasps, panting...)."""
        return float(class_score(scores, self.other_idx))

    def __call__(self, scores: np.ndarray) -> float:
        return self.both(scores)[0]

    def both(self, scores: np.ndarray) -> tuple[float, float]:
        q = float(class_score(scores, self.idx))
        return (float(self.head.prob(scores)) if self.head is not None else q), q


class WindowScores:
    """YAMNet's scores of windows of one signal that arrives in pieces at its own rate (offline: :func:`window_scores`,
    and ``detect``, which reads a file block by block and so holds its samples at 16 kHz only: a third of a 48 kHz
    file's, since 2026-11-29).

    ``push`` converts a piece to 16 kHz (:class:`Resampler16k`; NaN and inf read as 0, the 16 kHz samples clipped to
    [-1, 1]) into a buffer with ``WINDOW`` zeros before it (``frames_hint``: the input samples expected, to size it
    once; it grows past them); ``want`` queues windows by the input sample index they end at, which go to the model
    64 at a time as soon as their samples are converted (on the process' two network threads with the bundled model,
    while the rest is converted); ``finish`` pads the end with zeros and gives every wanted window's 521 scores, in
    order, the one-window-at-a-time scores bit for bit whatever the pieces."""

    def __init__(self, sample_rate: int, model: Yamnet | None = None, frames_hint: int = 0,
                 threads: bool | None = None):
        self.model = model or Yamnet()
        self.sr = int(sample_rate)
        self.rs = Resampler16k(self.sr)
        self.pad = np.zeros(self.rs.j_after(frames_hint) + 2 * WINDOW, np.float32)
        self.filled = WINDOW   # pad[:filled] holds its samples
        self.n = 0             # input samples pushed
        self.threads = self.model.bundled if threads is None else threads
        self.queue: list = []
        self.parts: list = []

    def end16(self, ends) -> list[int]:
        """The wanted windows' ends in the buffer (16 kHz samples, after its leading zeros)."""
        return [int(round(int(e) * RATE / self.sr)) + WINDOW for e in ends]

    def push(self, piece: np.ndarray) -> None:
        x = finite(np.asarray(piece).ravel())
        y = self.rs.push(x)
        if self.filled + len(y) + WINDOW > len(self.pad):   # longer than the hint: grown (a quarter more at least)
            grown = np.zeros(max(self.filled + len(y) + WINDOW, len(self.pad) + len(self.pad) // 4), np.float32)
            grown[:self.filled] = self.pad[:self.filled]   # (a thread still reading the old one keeps it)
            self.pad = grown
        self.pad[self.filled:self.filled + len(y)] = np.clip(y, -1.0, 1.0)
        self.filled += len(y)
        self.n += len(x)
        self._ready(False)

    def want(self, ends) -> None:
        self._want16(self.end16(ends))

    def _want16(self, e16: list[int]) -> None:
        if e16 and min(e16) < WINDOW:
            raise ValueError("a window ends outside the audio")
        self.queue.extend(e16)
        self._ready(False)

    def _ready(self, final: bool) -> None:
        while self.queue and (final or len(self.queue) >= 64) and max(self.queue[:64]) <= self.filled:
            c, self.queue = self.queue[:64], self.queue[64:]
            self.parts.append(net_pool().submit(_scores_here, self.pad, c) if self.threads
                              else _scores_here(self.pad, c, self.model))

    def finish(self) -> np.ndarray:
        size = self.rs.j_after(self.n) + 2 * WINDOW   # the signal and WINDOW zeros after it
        if self.queue and max(self.queue) > size:
            raise ValueError("a window ends outside the audio")
        if len(self.pad) < size:
            self.pad = np.concatenate([self.pad, np.zeros(size - len(self.pad), np.float32)])
        self.filled = size
        self._ready(True)
        parts = [p.result() if self.threads else p for p in self.parts]
        return np.concatenate(parts) if parts else np.empty((0, N_CLASSES))


def window_scores(audio: np.ndarray, sample_rate: int, ends: np.ndarray, model: Yamnet | None = None,
                  progress=None) -> np.ndarray:
    """The 521 scores of the windows ending at the sample indices ``ends`` of ``audio`` (zeros before 0).

    Offline use (``laughlab detect``, the fits and the benchmarks).  For a window ending at input sample
    ``e`` the model hears 16 kHz samples up to ``e * 16000 / sr`` (zeros past the end).  The signal is
    converted ``CONVERT_CHUNK`` samples at a time (:class:`WindowScores`), and windows go to the model 64 at a time
    as soon as their samples are converted, each distinct 10 ms frame's log-mel row computed once, on the process'
    two network threads (the bundled model), which run while the rest is converted.  The scores are the
    one-window-at-a-time scores bit for bit.  ``progress``: called with the seconds of input converted, piece by
    piece (``detect``'s bar moves through a long file: a review saw it at 0% for the whole of a 2-hour one).
    """
    model = model or Yamnet()
    sr, x = int(sample_rate), np.ravel(audio)
    w = WindowScores(sr, model, len(x), threads=model.bundled and len(ends) > 64)
    e16 = w.end16(ends)
    if e16 and max(e16) > len(w.pad):   # before any work (one ending before the audio: _want16)
        raise ValueError("a window ends outside the audio")
    w._want16(e16)
    for piece in chunks(x):
        w.push(piece)
        if progress is not None:
            progress(len(piece) / sr)
    return w.finish()
