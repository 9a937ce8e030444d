"""Source ``mic``: live input through sounddevice (PortAudio), block by block.

A live run starts with the thesis' calibration (van Duijn 2014, 3.1.1): for
``calibration_s`` seconds the terminal asks for one loud laugh or clap close to
the microphone and shows a level meter; the extractor takes the quietest and
loudest frame of that burst as its first minAmp and maxAmp.
"""
from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.io.audio import cut_frames
from laughlab.core.bases import Source
from laughlab.core.errors import LaughlabError
from laughlab.core.plugins import check_range


@dataclass
class MicParams:
    """Parameters of the ``mic`` source.

    Attributes
    ----------
    device : str or None
        Input device name or index as sounddevice understands it; None = default input.
    sample_rate : int
        Capture rate (Hz).
    duration_s : float or None
        Stop after this many seconds; None runs until Ctrl-C or SIGTERM, which then end the input and keep the
        session (:class:`StopOnSignal`).
    block_frames : int
        Animation frames per audio block read from the device (1 = lowest latency).
    calibration_s : float
        Length of the calibration phase at the start (thesis 3.1.1), seconds; 0 = none.
    """

    device: str | None = None
    sample_rate: int = 16000
    duration_s: float | None = None
    block_frames: int = 1
    calibration_s: float = 3.0

    def __post_init__(self) -> None:
        check_range("sample_rate", self.sample_rate, 8000, 192000)
        check_range("block_frames", self.block_frames, 1)
        check_range("calibration_s", self.calibration_s, 0, 600)
        if self.duration_s is not None:
            check_range("duration_s", self.duration_s, 0, lo_open=True)


class MicSource(Source):
    """Reads the microphone in blocks of one frame (or ``block_frames``) and yields frames."""

    name = "mic"
    Params = MicParams
    live = True
    stopped_by: str | None = None
    _stop: "StopOnSignal | None" = None
    #: reads the device flagged as overflowed (audio lost: laughlab fell behind), and the worst lag behind the
    #: microphone (s: wall time since the stream started minus the audio read, less the smallest such lag so
    #: far, which is the device's own latency), for metrics.json
    overflows: int = 0
    lag_s_max: float = 0.0
    clock = staticmethod(time.perf_counter)

    def open(self) -> None:
        try:
            import sounddevice as sd
        except ImportError:
            from laughlab.core.install import extra_command

            raise LaughlabError(f"input=mic needs the sounddevice package: {extra_command('mic')}") from None
        except OSError as exc:  # sounddevice is there, the PortAudio library it loads is not
            raise LaughlabError(f"input=mic needs the PortAudio library ({str(exc).splitlines()[0]}): "
                                "apt-get install libportaudio2 (Debian, Ubuntu) or brew install portaudio "
                                "(macOS)") from None
        device = self.params.device
        if isinstance(device, str) and device.isdigit():
            device = int(device)
        try:
            sd.check_input_settings(device=device, channels=1, samplerate=self.params.sample_rate,
                                    dtype="float32")
        except Exception as exc:
            which = "no default audio input device" if device is None else f"input.device={device!r} cannot record"
            raise LaughlabError(f"no usable microphone: {which} ({str(exc).splitlines()[0]}); connect one, or name "
                                "it with input.device=NAME_OR_INDEX (python -m sounddevice lists them)") from None
        self._sd, self._device = sd, device
        self.sample_rate = self.params.sample_rate
        d = self.params.duration_s
        self.n_frames = None if d is None else int(np.ceil(d * self.ctx.fps))
        self.duration_s = d
        self.calibration_s = float(self.params.calibration_s)

    def _chunks(self):
        n = block_samples(self.sample_rate, self.ctx.fps, self.params.block_frames)
        total = None if self.params.duration_s is None else int(self.params.duration_s * self.sample_rate)
        got = 0
        sd = self._sd
        with contextlib.ExitStack() as stack:
            try:
                stream = sd.InputStream(device=self._device, channels=1, samplerate=self.sample_rate,
                                        dtype="float32", blocksize=n)
                stack.enter_context(_running(stream, sd))
            except sd.PortAudioError as exc:
                raise LaughlabError(f"the microphone could not be started ({_first_line(exc)}); check that it is "
                                    "connected and not in use (python -m sounddevice lists the devices)") from None
            stop = self._stop = stack.enter_context(StopOnSignal()) if total is None else None
            clock = self.clock
            t0, base = clock(), math.inf
            while total is None or got < total:
                if stop is not None and stop.signum is not None:
                    self.stopped_by = signal.Signals(stop.signum).name
                    key = "Ctrl-C" if stop.signum == signal.SIGINT else self.stopped_by
                    print(f"laughlab: {key}: the input ended after {got / self.sample_rate:.1f} s and the session is "
                          f"kept ({key} again aborts it and removes what it wrote)", file=sys.stderr, flush=True)
                    return
                try:
                    data, overflowed = stream.read(n if total is None else min(n, total - got))
                except sd.PortAudioError as exc:   # a USB microphone pulled out, a device gone to sleep
                    self.stopped_by = "device"
                    print(f"laughlab: warning: the microphone stopped after {got / self.sample_rate:.1f} s "
                          f"({_first_line(exc)}); the input ends there and the session up to there is kept",
                          file=sys.stderr, flush=True)
                    return
                got += len(data)
                if overflowed:
                    self.overflows += 1
                    if self.overflows == 1:
                        print(f"laughlab: warning: the microphone's buffer overflowed after "
                              f"{got / self.sample_rate:.1f} s: laughlab fell behind the microphone and audio was "
                              "lost (each time is counted: metrics.json input_overflows)", file=sys.stderr, flush=True)
                lag = clock() - t0 - got / self.sample_rate   # the device's own latency, and more if behind
                if lag < base:
                    base = lag
                elif lag - base > self.lag_s_max:
                    self.lag_s_max = lag - base
                yield data[:, 0].copy()

    def metrics(self) -> dict:
        """For ``metrics.json``: what ended the input (``SIGINT``, ``SIGTERM``, ``device`` or None: its end),
        the reads the device flagged as overflowed, and the worst lag behind the microphone (s)."""
        return {"input_stopped_by": self.stopped_by, "input_overflows": int(self.overflows),
                "input_lag_s_max": float(self.lag_s_max)}

    def close(self) -> None:
        if self._stop is not None:   # the frame loop failed while the stream was open: the handlers go back
            self._stop.restore()

    def blocks(self):
        frames = cut_frames(self._chunks(), self.sample_rate, self.ctx.fps)
        n = int(round(self.ctx.calibration_s * self.ctx.fps))
        return calibration_meter(frames, n, self.ctx.fps) if n > 0 else frames


def block_samples(sample_rate: int, fps: float, block_frames: int = 1) -> int:
    """Samples the microphone is read in: ``block_frames`` frames, rounded up (a block a sample short of a
    frame would make every frame wait one more block).  ``benchmarks/bench_latency.py`` replays by it."""
    return math.ceil(sample_rate / fps) * block_frames


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


@contextlib.contextmanager
def _running(stream, sd):
    """The stream, started; stopping a device that went away raises nothing more."""
    stream.__enter__()
    try:
        yield stream
    finally:
        try:
            stream.__exit__(None, None, None)
        except sd.PortAudioError:
            pass


class StopOnSignal:
    """While a session with no set length (``input.duration_s=null``) reads the microphone, the first Ctrl-C
    (SIGINT) or SIGTERM ends the input: the frame loop finishes, the sinks close and the session is kept (the
    stop signal *is* its end; SIGTERM too, as a process manager stops an always-on installation).  The second
    signal goes to the handler this one stood in for (laughlab's: abort, remove what was written, exit 130).

    Only laughlab's own handler and Python's default Ctrl-C handler are stood in for, on the main thread;
    an ignored signal or another program's handler is left alone."""

    def __init__(self):
        self.signum: int | None = None
        self._old: dict = {}

    def __enter__(self) -> "StopOnSignal":
        from laughlab.core.interrupts import STOP_SIGNALS

        if threading.current_thread() is threading.main_thread():
            for sig in STOP_SIGNALS:
                old = signal.getsignal(sig)
                if old is signal.default_int_handler or getattr(old, "__module__", "") == "laughlab.core.interrupts":
                    self._old[sig] = old
                    signal.signal(sig, self._on_signal)
        return self

    def _on_signal(self, signum, frame) -> None:
        if self.signum is None:
            self.signum = signum   # the read loop ends the input at its next block
            return
        old = self._old.get(signum, signal.default_int_handler)
        self.restore()
        old(signum, frame)

    def restore(self) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}

    def __exit__(self, *exc) -> bool:
        self.restore()
        return False


#: the level meter's scale: dBFS from METER_FLOOR_DB to 0
METER_FLOOR_DB = -60.0
#: a calibration burst quieter than this (dBFS) maps laughter to a small range: say so
QUIET_BURST_DB = -35.0


def meter_line(level_db: float, peak_db: float, left_s: float, width: int = 30) -> str:
    """One line of the calibration meter: a bar of the level, the peak so far and the time left."""
    fill = int(round(width * min(1.0, max(0.0, 1.0 - level_db / METER_FLOOR_DB))))
    return f"  [{'#' * fill}{' ' * (width - fill)}] {level_db:6.1f} dBFS, peak {peak_db:6.1f}, {left_s:4.1f} s left"


def calibration_meter(frames, n: int, fps: float, out=None):
    """Pass ``frames`` through; over the first ``n`` say what to do and show their level on ``out`` (stderr).

    The meter redraws about 10 times a second on a terminal; elsewhere only the
    first and the last line are written.
    """
    out = out or sys.stderr
    live = out.isatty()
    every = max(1, int(round(fps / 10)))
    print(f"laughlab: calibrating for {n / fps:g} s (van Duijn 2014, 3.1.1): laugh or clap once, loudly, "
          "close to the microphone (input.calibration_s=0 skips this)", file=out, flush=True)
    peak = -math.inf
    for k, block in enumerate(frames):
        if k < n:
            ms = float(np.dot(block, block)) / max(1, len(block))
            level = 10.0 * math.log10(max(ms, 1e-14))
            peak = max(peak, level)
            if live and (k % every == 0 or k == n - 1):
                out.write("\r" + meter_line(level, peak, (n - 1 - k) / fps))
                out.flush()
            if k == n - 1:
                hint = (f"; the burst was quiet, so laughter will move the character little: run again closer "
                        f"to the microphone" if peak < QUIET_BURST_DB else "; go ahead and laugh")
                print(("\n" if live else "") + f"laughlab: calibrated (peak {peak:.1f} dBFS){hint}",
                      file=out, flush=True)
        yield block


@hookimpl
def register_sources(register):
    register(MicSource)
