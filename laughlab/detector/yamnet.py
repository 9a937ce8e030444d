"""Google's YAMNet sound-event model, bundled as TensorFlow Lite, and its laughter score.

YAMNet (tensorflow/models, ``research/audioset/yamnet``; Apache-2.0) is a MobileNet v1
trained on AudioSet's 521 classes.  The bundled file (``laughlab/data/yamnet/``, see
``PROVENANCE.md`` there) takes one window of :data:`WINDOW` = 15,600 samples (0.975 s)
of 16 kHz mono float audio in [-1, 1] and returns the 521 class scores in the order of
``yamnet_class_map.csv``.  It runs with ``ai-edge-litert`` (Google's LiteRT
interpreter, on PyPI), one thread, no network.

:class:`Window16k` keeps the last second of a stream at its own rate and gives the
last :data:`WINDOW` samples at 16 kHz (a causal low-pass and linear interpolation,
:class:`Resampler16k`), so any rate from 8 kHz up works.  A stream shorter than the
window is padded with zeros *before* its start (the model hears silence there).

:class:`Head` maps the 521 scores to one laughter probability: a logistic
regression fitted on the corpus' train split (``python -m laughlab.detector.yamnet_fit``,
``laughlab/data/yamnet/head.json``); without a head, the largest score of the
six laughter classes (Laughter, Baby laughter, Giggle, Snicker, Belly laugh,
Chuckle/chortle).
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import threading
import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

#: the model's input: samples at 16 kHz (0.975 s)
RATE = 16000
WINDOW = 15600
N_CLASSES = 521
#: the AudioSet laughter classes (display names of the class map)
LAUGH_CLASSES = ("Laughter", "Baby laughter", "Giggle", "Snicker", "Belly laugh", "Chuckle, chortle")
MODEL_SHA256 = "469be6a3421cbc52cf97e9f2f966cba984198e8e7af9854d68b3e3ebb1e04194"
RESTORE = ("restore it with `git checkout laughlab/data/yamnet` in a source checkout, "
           "or reinstall laughlab (pip install --force-reinstall laughlab)")


class ModelFileError(ValueError):
    """The model file is missing or not the bundled YAMNet: the message names the file and the fix."""


def data_dir() -> Path:
    return Path(str(resources.files("laughlab").joinpath("data", "yamnet")))


def class_names(path: str | Path | None = None) -> list[str]:
    p = Path(path) if path is not None else data_dir() / "yamnet_class_map.csv"
    try:
        with open(p, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise ModelFileError(f"cannot read the YAMNet class map {p} ({exc.strerror}): {RESTORE}") from None
    names = [r[2] for r in rows[1:] if len(r) >= 3]
    if rows[:1] != [["index", "mid", "display_name"]] or len(names) != N_CLASSES:
        raise ModelFileError(f"the YAMNet class map {p} is damaged (expected {N_CLASSES} classes): {RESTORE}")
    return names


def laugh_indices(names: list[str]) -> list[int]:
    return [names.index(n) for n in LAUGH_CLASSES]


@contextlib.contextmanager
def _quiet_stderr():
    """Silence file descriptor 2 (C++ logging) for the duration of the block."""
    import os
    import sys

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


#: loaded interpreters (with a lock) by (file, bundled, size, mtime, thread): a changed file is read and checked
#: again
_LOADED: dict = {}


class Yamnet:
    """The bundled YAMNet: ``scores(window)`` -> 521 class scores of one 0.975 s window at 16 kHz."""

    def __init__(self, path: str | Path | None = None):
        p = Path(path) if path is not None else data_dir() / "yamnet.tflite"
        self.path = p
        try:
            st = p.stat()
        except OSError as exc:
            raise ModelFileError(f"cannot read the YAMNet model {p} ({exc.strerror or exc}): {RESTORE}") from None
        key = (str(p.resolve()), path is None, st.st_size, st.st_mtime_ns, threading.get_ident())
        cached = _LOADED.get(key)
        if cached is None:
            cached = _LOADED[key] = self._load(p, path is None)
        self.it, self._in, self._out, self._lock = cached
        self._buf = np.zeros((1, WINDOW), np.float32)

    @staticmethod
    def _load(p: Path, bundled: bool):
        """Read, check and load the model file once per process (an interpreter holds no state between
        windows, so runs in one thread share it: the fuzz suite and the harness build many pipelines)."""
        path = None if bundled else p
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise ModelFileError(f"cannot read the YAMNet model {p} ({exc.strerror or exc}): {RESTORE}") from None
        if path is None and hashlib.sha256(data).hexdigest() != MODEL_SHA256:
            raise ModelFileError(f"the YAMNet model {p} is damaged (sha256 differs from the bundled file's): {RESTORE}")
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise ModelFileError("the yamnet detector needs ai-edge-litert (pip install ai-edge-litert); "
                                 "where it has no wheel (Intel Macs), use detector=laugh or detector=none") from None
        try:
            with _quiet_stderr():  # LiteRT prints "INFO: Created TensorFlow Lite XNNPACK delegate" on fd 2
                it = Interpreter(model_content=data, num_threads=1)
                it.allocate_tensors()
            inp, out = it.get_input_details()[0], it.get_output_details()[0]
        except (ValueError, RuntimeError, IndexError) as exc:
            raise ModelFileError(f"the YAMNet model {p} cannot be loaded ({str(exc).splitlines()[0][:120]}): "
                                 f"{RESTORE}") from None
        if list(inp["shape"]) != [1, WINDOW] or list(out["shape"]) != [1, N_CLASSES]:
            raise ModelFileError(f"{p} is not the YAMNet model (input {list(inp['shape'])}, output "
                                 f"{list(out['shape'])}): {RESTORE}")
        return it, inp["index"], out["index"], threading.Lock()

    def scores(self, window: np.ndarray) -> np.ndarray:
        """The 521 scores of one window (``WINDOW`` samples at 16 kHz, float in [-1, 1]).

        Safe from any thread: the interpreter is used by one call at a time (LiteRT releases the GIL
        while it runs, so a call in a helper thread leaves the frame thread free)."""
        with self._lock:
            self._buf[0] = window
            self.it.set_tensor(self._in, self._buf)
            self.it.invoke()
            return self.it.get_tensor(self._out)[0].astype(np.float64)


#: the helper thread that runs model windows off the frame thread (``detector.async_frames``), per process
_HELPER: dict = {}


def helper():
    """The process' one helper thread for model windows (made again in a forked child, where it is gone)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    pid = os.getpid()
    if _HELPER.get("pid") != pid:
        _HELPER.update(pid=pid, pool=ThreadPoolExecutor(1, thread_name_prefix="laughlab-yamnet"))
    return _HELPER["pool"]


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

    def push(self, block: np.ndarray) -> np.ndarray:
        x = np.asarray(block, dtype=np.float64).ravel()
        if self.sr == RATE:
            self.n += len(x)
            self.j += len(x)
            return x
        if self.sos is not None and len(x):
            from scipy.signal import sosfilt

            x, self.zi = sosfilt(self.sos, x, zi=self.zi)
        base = self.n - 1                   # index of ``self.last``
        ext = np.concatenate([[self.last], x])
        self.n += len(x)
        if len(x):
            self.last = float(x[-1])
        # outputs j with floor(j sr / 16000) + 1 <= n - 1, i.e. the sample after the instant is here
        j_end = ((self.n - 1) * RATE - 1) // self.sr + 1 if self.n > 1 else 0
        j = np.arange(self.j, max(self.j, j_end), dtype=np.int64)
        self.j = max(self.j, j_end)
        num = j * self.sr
        i0 = num // RATE
        frac = (num % RATE) / RATE
        k = i0 - base
        return ext[k] * (1.0 - frac) + ext[k + 1] * frac


class Window16k:
    """The last ``WINDOW`` samples of a stream at 16 kHz, from blocks at the stream's own rate (causal).

    The 16 kHz samples come from :class:`Resampler16k`; a stream shorter than the window is
    padded with zeros before its start.  The result depends only on the samples received
    so far, never on how they were cut into blocks.
    """

    def __init__(self, sample_rate: int):
        self.rs = Resampler16k(sample_rate)
        self.buf = np.zeros(WINDOW, np.float32)
        self.pending: list = []

    def reset(self) -> None:
        self.rs.reset()
        self.buf[:] = 0.0
        self.pending = []

    def push(self, block: np.ndarray) -> None:
        """Keep a block; it is converted when the window is next asked for (the same bytes, cheaper).

        Samples outside [-1, 1] are clipped and non-finite ones (NaN, inf) read as 0, so one bad
        sample cannot poison the filter's state."""
        b = np.array(block, dtype=np.float64).ravel()
        if not np.isfinite(b).all():
            b = np.where(np.isfinite(b), b, 0.0)
        self.pending.append(np.clip(b, -1.0, 1.0, out=b))

    def _convert(self) -> None:
        if not self.pending:
            return
        x = self.pending[0] if len(self.pending) == 1 else np.concatenate(self.pending)
        self.pending = []
        y = self.rs.push(x)
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


def to_16k(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """A whole signal at 16 kHz, the live conversion's bytes (:class:`Resampler16k`)."""
    return Resampler16k(sample_rate).push(audio)


@dataclass
class Head:
    """Logistic regression on the 521 scores: ``p = sigmoid(w . log(scores + eps) + b)``."""

    w: np.ndarray
    b: float
    eps: float
    meta: dict

    @classmethod
    def load(cls, path: str | Path | None = None) -> "Head | None":
        p = Path(path) if path is not None else data_dir() / "head.json"
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

    The whole signal is resampled once (offline use: ``laughlab detect``, the fits and the benchmarks);
    for a window ending at input sample ``e`` the model hears 16 kHz samples up to ``e * 16000 / sr``.
    """
    model = model or Yamnet()
    sr = int(sample_rate)
    x = np.clip(to_16k(audio, sr), -1.0, 1.0).astype(np.float32)
    pad = np.concatenate([np.zeros(WINDOW, np.float32), x, np.zeros(WINDOW, np.float32)])
    out = np.empty((len(ends), N_CLASSES))
    for i, e in enumerate(ends):
        e16 = int(round(int(e) * RATE / sr)) + WINDOW
        out[i] = model.scores(pad[e16 - WINDOW:e16])
    return out
