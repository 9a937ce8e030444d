"""laughlab stepped from your own program: give it audio as it comes, take each frame as it is computed.

    import soundfile as sf
    from laughlab.session import Session

    with Session(["face=facs"], sample_rate=sf.info("laugh.wav").samplerate) as s:   # overrides; 8-192 kHz
        for block in sf.blocks("laugh.wav", blocksize=800):   # your audio as it comes: floats in [-1, 1],
            for frame in s.feed(block):                       # int16, or (n, channels); the frames completed
                frame.arkit["jawOpen"], frame.pose            # ARKit weights; the BVH channel vector (cm, degrees)
        for frame in s.close():                               # the input's end: the last, partial frame
            frame.arkit["jawOpen"], frame.pose

The frames are the ones ``python -m laughlab input=file`` computes from the same samples (same seed, same
bytes, ``body=hill`` included): the run is :func:`laughlab.core.pipeline.execute` itself, in a thread of its own, on a source fed by
:meth:`Session.feed` and cut into frames as the file and microphone sources cut theirs
(:func:`laughlab.io.audio.cut_frames`), with a sink that hands each frame back as soon as it is computed. Outputs
(``outputs=["files"]``, ``"vmc"``, ``"viewer"``) write into ``out_dir`` or stream as they do from the command line.
Errors are one :class:`laughlab.core.errors.LaughlabError` each (a plugin's own exception is raised as it is, once).
The input plugin of the overrides is not used; the session is the input (not live: ``body=hill`` fits its
calls in a thread, as live, with a file's bytes; the calibration of ``extractor=rms`` is ``calibration_s``, 0 as for a file).
"""
from __future__ import annotations

import atexit
import functools
import importlib
import numbers
import queue
import re
import sys
import tempfile
import threading
import warnings
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError, NoAudio
from laughlab.core.overrides import override_key


@dataclass
class SessionFrame:
    """One animation frame.

    Attributes
    ----------
    index : int
    time_s : float
        The frame's time (s from the first sample fed).
    channels : dict
        Every channel of ``channels.csv`` for this frame (``mcs``, ``smile``, ``jaw``, ``energy``, ``arkit.*``...).
    pose : ndarray
        The skeleton's pose as ``motion.bvh`` holds it: root position (cm), then ZXY Euler angles (degrees) per
        joint (``laughlab.motion.skeleton.HUMANOID``).
    events : list
        Clips that start or stop on this frame (:class:`laughlab.core.frame.ClipEvent`).
    label : str
        The extractor's pseudo-phoneme label, where it gives one ("" otherwise).
    """

    index: int
    time_s: float
    channels: dict
    pose: np.ndarray
    events: list = field(default_factory=list)
    label: str = ""

    @functools.cached_property
    def arkit(self) -> dict:
        """The face as ARKit blendshape weights in [0, 1] (the names ``face_arkit.csv`` and the VMC stream use);
        computed on the first read, kept for the next (a review: 0.05 ms a read, 8 reads cost more than the feed)."""
        from laughlab.io.vmc import arkit_weights

        weights = arkit_weights({k: np.asarray([v]) for k, v in self.channels.items()})
        return {k: float(v[0]) for k, v in weights.items()}


@dataclass
class FedParams:
    """What the session's input records in ``metrics.json``'s configuration: the rate fed (Hz), the calibration (s),
    the high-pass (Hz; 0: none)."""

    sample_rate: int
    calibration_s: float
    highpass_hz: float = 0.0


class _FedSource:
    """The session's input: the samples :meth:`Session.feed` queued, cut into frames."""

    name = "session"
    #: for the outputs: the samples come as the program feeds them, so it sets the pace (``vmc`` and ``viewer``
    #: are not paced at the frame clock, and ``viewer`` does not wait for a page: it held the first feed until one
    #: opened); the plugins were built on the synthetic input, so ``body=hill`` and rms still run as for a file
    live = True
    n_frames = None
    truth = None

    def __init__(self, sample_rate: int, calibration_s: float, fps: float, highpass_hz: float = 0.0):
        self.sample_rate, self.calibration_s, self.fps = int(sample_rate), float(calibration_s), fps
        self.params = FedParams(self.sample_rate, self.calibration_s, float(highpass_hz))
        if highpass_hz:   # input=file's input.highpass_hz: the same filter, so the same bytes
            from laughlab.signals.highpass import CausalHighpass

            self._hp = CausalHighpass(float(highpass_hz), self.sample_rate)
        else:
            self._hp = None
        self.samples: queue.Queue = queue.Queue()
        self.hungry = threading.Event()   # every sample fed is cut into frames, and every whole frame computed

    def _chunks(self):
        while True:
            if self.samples.empty():
                self.hungry.set()
            x = self.samples.get()
            if x is None:
                return
            yield x if self._hp is None else self._hp.step(x)

    def blocks(self):
        from laughlab.io.audio import cut_frames

        return cut_frames(self._chunks(), self.sample_rate, self.fps)

    def close(self) -> None:
        pass


class _Handback:
    """A streaming sink: each frame back to the session as it is computed."""

    name = "session"
    streaming = True
    background = False
    files = ()

    def __init__(self, out: list):
        self.out = out   # the frames not yet taken by the session (emptied as it takes them: a session of hours)
        self.n = 0

    def open(self, run) -> None:
        self.run = run

    def write(self, chunk) -> None:
        for i, (t, events) in enumerate(zip(chunk.times, chunk.events_by_frame(self.run.fps))):
            self.out.append(SessionFrame(self.n, float(t), {k: float(np.asarray(v)[i]) for k, v in
                                                                 chunk.channels.items()},
                                         np.array(chunk.poses[i], dtype=np.float64), events,
                                         (chunk.labels[i] if i < len(chunk.labels) else None) or ""))
            self.n += 1

    def close(self):
        return []

    def abort(self) -> None:
        pass


def mono_samples(samples) -> np.ndarray:
    """``samples`` as the 1-D float32 array a session feeds (:meth:`Session.feed`), or one clear error."""
    x = np.asarray(samples)
    if x.dtype.kind in "iu" and x.dtype.itemsize == 8:   # a list of Python ints: scaled by 2^63 it played as silence
        raise LaughlabError(f"feed audio samples: floats in [-1, 1] or PCM integers (int16, int32, uint8); got "
                            f"{x.dtype}{' (a list of Python ints?)' if not isinstance(samples, np.ndarray) else ''}: "
                            "give np.asarray(samples, np.int16) for 16-bit PCM")
    if x.dtype.kind in "iu":   # PCM integers, scaled as soundfile reads them (int16: x / 32768)
        half = 2.0 ** (8 * x.dtype.itemsize - 1)
        x = (x.astype(np.float64) - (half if x.dtype.kind == "u" else 0.0)) / half
    elif x.dtype.kind != "f":
        raise LaughlabError(f"feed audio samples: floats in [-1, 1] or PCM integers (got an array of {x.dtype})")
    if x.ndim == 2 and x.shape[1] > 64 and x.shape[0] <= 64:
        raise LaughlabError(f"feed (frames, channels) (got shape {x.shape}: (channels, frames)? pass its .T)")
    if x.ndim > 2:
        raise LaughlabError(f"feed mono samples or (frames, channels) (got shape {x.shape})")
    if x.ndim == 2:
        return x.mean(axis=1, dtype=np.float32) if x.shape[1] > 1 else x[:, 0].astype(np.float32)
    return x.astype(np.float32).reshape(-1)


@dataclass
class _State:
    """What the session's thread hands back: ``metrics.json``'s numbers or the error that stopped the run."""

    metrics: dict | None = None
    error: BaseException | None = None
    raised: bool = False
    abandoned: bool = False


def _abandon(src: _FedSource, state: _State) -> None:
    state.abandoned = True
    src.samples.put(None)


#: how long the interpreter's exit waits for each unclosed session to write its outputs (s)
FINISH_AT_EXIT_S = 120.0

_START = threading.Lock()   # a run that ends at once removes itself after it was added

#: the runs of sessions not closed: (input, state, thread) by the thread's id, each removed when its run ends
_RUNNING: dict[int, tuple] = {}


def _finish_unclosed() -> None:
    """End the input of every session still running at the interpreter's exit and wait for its outputs (a
    Python user's program that never closed its session: the daemon thread was cut off mid-run, leaving hidden
    ``.part`` files and no outputs, and under load Python aborted, exit 134).  Registered to run before Python
    stops the thread pools (``threading._register_atexit``, after ``concurrent.futures`` registered its own: they
    run last first), so a video's frames are still drawn in theirs (a diff review: from ``atexit`` the video
    output was refused and the folder left empty, without a word); an error that ends such a run is said."""
    running = list(_RUNNING.values())
    for src, state, _ in running:
        _abandon(src, state)
    for _, state, thread in running:
        thread.join(FINISH_AT_EXIT_S)
        if thread.is_alive():
            sys.stderr.write(f"laughlab: an unclosed Session did not finish within {FINISH_AT_EXIT_S:g} s of the "
                             "program's end; its outputs are not written (close it: Session.close())\n")
        elif state.error is not None and not state.raised and not isinstance(state.error, NoAudio):   # never fed
            sys.stderr.write(f"laughlab: an unclosed Session ended on an error at the program's end, its outputs not "
                             f"written: {type(state.error).__name__}: {state.error}\n")


importlib.import_module("concurrent.futures.thread")   # its hook first: ours, registered after, runs before it

if hasattr(threading, "_register_atexit"):
    threading._register_atexit(_finish_unclosed)
atexit.register(_finish_unclosed)   # a Python without it; nothing is left to finish when the first one ran


class Session:
    """A laughlab run fed by your program (module docstring).

    Parameters
    ----------
    overrides : list of str
        As on the command line (``face=facs``, ``detector=none``, ``seed=3``...).
    sample_rate : int
        The rate of the samples you feed (Hz, 8000-192000), required: a wrong rate runs without an error at the
        wrong speed (it had a default of 16000 until 2026-11-29).
    outputs : list of str
        Output groups to write or stream as well (``files``, ``gltf``, ``vmc``, ``viewer``...); none by default.
    out_dir : path or None
        Where outputs and ``metrics.json`` go (a new temporary folder, removed at :meth:`close`, when None: then
        only the streaming outputs, ``vmc`` and ``viewer``, may be asked for; a file-writing one needs ``out_dir``).
    calibration_s : float
        The rms extractor's calibration phase at the start (s; van Duijn 2014, 3.1.1): 0, as for a file.
    highpass_hz : float
        A causal high-pass of the samples before the extractors (Hz; 0: none): ``input=file``'s
        ``input.highpass_hz``, which removes a DC offset (20 Hz does), the same filter and bytes.
    overwrite : bool
        Let the outputs replace files of theirs already in ``out_dir`` (refused otherwise: nothing of yours is
        overwritten without asking).

    Raises :class:`~laughlab.core.errors.LaughlabError` with one line for bad arguments and, from :meth:`feed` and
    :meth:`close`, for bad samples or a run that stopped. A session closed before any audio returns no frame,
    writes nothing and has ``metrics`` None.
    """

    def __init__(self, overrides=(), sample_rate: int | None = None, outputs=(), out_dir=None,
                 calibration_s: float = 0.0, overwrite: bool = False, highpass_hz: float = 0.0):
        from omegaconf import OmegaConf

        from laughlab.core import pipeline
        from laughlab.core.config import check_overrides, compose_app, load_plugin_dirs

        if sample_rate is None:
            raise LaughlabError("Session needs sample_rate=, the rate of the samples you will feed (Hz)")
        if isinstance(overrides, str) or isinstance(outputs, str):   # "face=facs" was read as 9 overrides
            name, value = ("overrides", overrides) if isinstance(overrides, str) else ("outputs", outputs)
            raise LaughlabError(f"{name} must be a list of strings (got the string {value!r}: {name}=[{value!r}])")
        overrides, outputs = list(overrides), list(outputs)
        for name, value in (("overrides", overrides), ("outputs", outputs)):
            if not all(isinstance(v, str) for v in value):
                raise LaughlabError(f"{name} must be a list of strings (got {value!r})")
        # a whole number of Hz: 44100.9 ran as 44100 without a word (a new-user review)
        if (isinstance(sample_rate, bool) or not isinstance(sample_rate, numbers.Real) or not np.isfinite(sample_rate)
                or sample_rate != int(sample_rate)):
            raise LaughlabError(f"sample_rate must be a whole number of Hz (got {sample_rate!r})")
        if not 8000 <= int(sample_rate) <= 192000:
            raise LaughlabError(f"sample_rate must be 8000-192000 Hz (got {sample_rate})")
        if (isinstance(highpass_hz, bool) or not isinstance(highpass_hz, numbers.Real)
                or not 0 <= highpass_hz <= 1000):   # as input.highpass_hz: under any rate's Nyquist
            raise LaughlabError(f"highpass_hz must be 0-1000 Hz (got {highpass_hz!r})")
        for o in overrides:
            key = override_key(o)
            if key == "output":   # an output's own parameters (output.vmc.port=...) are welcome
                raise LaughlabError(f"{o}: a session's outputs are its outputs= argument (outputs=['files'])")
            if key == "input" or key.startswith("input."):
                raise LaughlabError(f"{o}: a session's input is what feed() is given (sample_rate= its rate)")
            # the command line's own settings were taken and ignored (a Python user's review)
            if re.split(r"[./]", key)[0] in ("hydra", "experiment", "harness", "overwrite", "progress"):
                raise LaughlabError(f"{o}: not a session's: its folder is out_dir=, overwrite= its argument; an "
                                    "experiment runs from the command line or laughlab.cli.main([...])")
        from laughlab.core.config import group_options

        known = group_options("output")
        for o in outputs:   # 'bvh' was "unknown output 'bvh' in a defaults list (an experiment's override ...)"
            if o not in known or o == "trial":
                raise LaughlabError(f"outputs: {o!r} is not an output; choose from "
                                    f"{', '.join(k for k in known if k != 'trial')} (files: channels.csv, events.csv, "
                                    "motion.bvh, face_arkit.csv and plots/)")
        from laughlab import _kernels

        _kernels.warn_if_unpinned()   # a notebook that imported numpy first: say what it means for the bytes
        load_plugin_dirs(list(overrides))   # then the command line's lines: 'unknown face ...; choose one of: ...'
        check_overrides(list(overrides))
        out = list(outputs)
        cfg = compose_app([*overrides, "input=synthetic", f"input.sample_rate={int(sample_rate)}",
                           f"output={out[0] if len(out) == 1 else '[' + ','.join(out) + ']'}" if out else "output=trial",
                           "progress=off"])
        cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
        if OmegaConf.select(cfg, "body.live.threaded") == "auto":
            # body=hill's call fits in a thread, as for a microphone: a program's frames keep their pace (in the
            # frame, a fit made a 60 fps game's frame 50-280 ms, 130 an hour: a frame budget review, 2026-11-29);
            # the same bytes, which fit a call plays being fixed by frame numbers
            cfg.body.live.threaded = "yes"
        if not out:
            cfg.output = {}
        if out_dir is not None and out and not overwrite:
            held = sorted(n for n in pipeline.planned_files(cfg) | {"metrics.json"} if (Path(out_dir) / n).exists())
            if held:
                raise LaughlabError(f"{out_dir} already holds {', '.join(held)}, which this session would replace; "
                                    "choose another out_dir or pass overwrite=True")
        pipe = pipeline.build(cfg)
        pipe.source.close()
        writers = [s.name for s in pipe.sinks if not getattr(s, "streaming", False)]
        if out_dir is None and writers:   # they went to a temporary folder, gone at close() (a game dev's review)
            raise LaughlabError(f"outputs={out!r} writes files ({', '.join(writers)}): give out_dir=PATH, or they "
                                "would go to a temporary folder removed at close()")
        for sink in pipe.sinks:   # a VMC host that does not resolve: said here, not at the first feed (a review)
            getattr(sink, "check_host", lambda: None)()
        if getattr(pipe.scheduler, "offline_plan", False):
            raise LaughlabError(pipeline._offline_only(pipe.scheduler, "a session fed as it goes"))
        self._frames: list[SessionFrame] = []
        pipe.ctx.calibration_s = float(calibration_s) if getattr(pipe.extractor, "calibrates", False) else 0.0
        self._src = pipe.source = _FedSource(sample_rate, pipe.ctx.calibration_s, pipe.ctx.fps, highpass_hz)
        pipe.sinks.append(_Handback(self._frames))
        self._tmp = None if out_dir is not None else tempfile.TemporaryDirectory(prefix="laughlab-session-")
        self.out_dir = Path(out_dir if out_dir is not None else self._tmp.name)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._state = state = _State()
        self._closed = self._fed = self._said_scale = False
        self._lock = threading.Lock()
        src, tmp, out_dir = self._src, self._tmp, self.out_dir
        from laughlab.harness.results import provenance

        # what made the folder, as a command's metrics.json says it (a reproducibility review: a Session's had no
        # commit, versions or CPU family), and the session's own arguments
        made = {"provenance": {**provenance(None), "session": {"overrides": overrides, "sample_rate": int(sample_rate),
                                                              "outputs": out}}}

        def run() -> None:   # holds no reference to the session: an unclosed one is still collected
            try:
                state.metrics = pipeline.execute(pipe, out_dir, None, made)
            except BaseException as exc:   # handed to the caller's thread by feed() or close()
                state.error = exc
            finally:
                with _START:
                    _RUNNING.pop(threading.get_ident(), None)
                src.hungry.set()
                if state.abandoned and tmp is not None:
                    tmp.cleanup()

        self._thread = threading.Thread(target=run, name="laughlab-session", daemon=True)
        # a session dropped unclosed ends its input: its thread computes the last frame, writes the outputs, stops
        self._finalizer = weakref.finalize(self, _abandon, src, state)
        with _START:
            self._thread.start()
            _RUNNING[self._thread.ident] = (src, state, self._thread)

    @property
    def metrics(self) -> dict | None:
        """``metrics.json``'s numbers, after :meth:`close` (None before)."""
        return self._state.metrics

    def _new(self) -> list[SessionFrame]:
        err = self._state.error
        if err is not None:   # the plugin's own exception once; then one line (re-raising it grew its traceback)
            if self._state.raised:
                raise LaughlabError(f"the session stopped on an error: {type(err).__name__}: {err}") from None
            self._state.raised = True
            raise err
        n = len(self._frames)   # the session's thread only appends; it is waiting now (or done)
        frames = self._frames[:n]
        del self._frames[:n]
        return frames

    def feed(self, samples) -> list[SessionFrame]:
        """Queue ``samples`` and return the frames they completed, computed. ``samples``: mono floats in [-1, 1];
        a 2-D array is ``(frames, channels)`` (soundfile's and sounddevice's layout), mixed to mono by the mean
        as ``input=file`` mixes a stereo file; integer PCM (``int16``, ``int32``, ``uint8``) is scaled to
        [-1, 1) as soundfile reads it. Feeds from several threads take turns (one lock), each returning its
        own frames."""
        x = mono_samples(samples)
        if not self._said_scale and len(x) and float(np.nanmax(np.abs(x))) > 1.5:   # floats of int16 PCM's scale
            self._said_scale = True   # were taken as they came and changed every output (a Python user's review)
            warnings.warn(f"Session.feed: samples up to {float(np.nanmax(np.abs(x))):.4g}: floats are read with "
                          "full scale at +-1, as a float WAV's are; divide int16-scale floats by 32768, or feed them "
                          "as np.int16", stacklevel=2)
        with self._lock:
            if self._closed:
                raise LaughlabError("the session is closed")
            if len(x) and self._state.error is None:   # after an error nothing is queued for a run that has ended
                self._fed = True
                self._src.hungry.clear()
                self._src.samples.put(x)
                while not self._src.hungry.wait(0.05) and self._thread.is_alive():
                    pass
            return self._new()

    def close(self) -> list[SessionFrame]:
        """End the input: the last, partial frame is computed and the outputs written; return the frames not
        yet returned. ``metrics`` then holds ``metrics.json``'s numbers (None, with no frame and no file written,
        when no sample was fed)."""
        with self._lock:
            if self._closed:
                return []
            self._closed = True
            self._finalizer.detach()
            self._src.samples.put(None)
            self._thread.join()
            if not self._fed and isinstance(self._state.error, NoAudio):   # no frame, no file
                self._state.error = None   # (a review: a game that quit before any audio got "holds no audio")
            try:
                return self._new()
            finally:
                if self._tmp is not None:
                    self._tmp.cleanup()

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if kind is None:
            self.close()
            return
        try:   # the error that left the block is the one to see, not what closing a half-fed run says
            self.close()
        except Exception:
            pass
