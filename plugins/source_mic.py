"""Source ``mic``: live input through sounddevice (PortAudio), block by block.

A live run starts with the thesis' calibration (van Duijn 2014, 3.1.1): for
``calibration_s`` seconds the terminal asks for one loud laugh or clap close to
the microphone and shows a level meter; the extractor takes the quietest and
loudest frame of that burst as its first minAmp and maxAmp.
"""
from __future__ import annotations

import collections
import contextlib
import math
import os
import shutil
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laughlab import hookimpl
from laughlab.io.audio import FloatWavWriter, cut_frames, n_frames_for
from laughlab.core.bases import Source
from laughlab.core.errors import LaughlabError, StoppedBySignal, first_line
from laughlab.core.interrupts import StopOnSignal
from laughlab.core.plugins import check_range
from laughlab.core.summary import SILENT_DBFS, silent_text


@dataclass
class MicParams:
    """Parameters of the ``mic`` source.

    Attributes
    ----------
    device : str or None
        Input device name or index as sounddevice understands it; None = default input. ``file:PATH`` plays a
        recording as the microphone, in real time (:mod:`laughlab.io.replay`: the live path without a microphone).
    sample_rate : int
        Capture rate (Hz).
    duration_s : float or None
        Stop after this many seconds; None runs until Ctrl-C or SIGTERM, which then end the input and keep the
        session (:class:`laughlab.core.interrupts.StopOnSignal`).
    block_frames : int
        Animation frames per audio block read from the device (1 = lowest latency).
    calibration_s : float
        Length of the calibration phase at the start (thesis 3.1.1), seconds; 0 = none.
    save_audio : bool
        Write the samples the session's frames read as ``input.wav`` (32-bit float) into the run directory, so the
        session can be replayed offline: ``input=file input.path=RUN/input.wav extractor.calibration_s=3`` (the
        calibration's length) gives its ``channels.csv``, ``events.csv`` and ``motion.bvh`` byte for byte.
    """

    device: str | None = None
    sample_rate: int = 16000
    duration_s: float | None = None
    block_frames: int = 1
    calibration_s: float = 3.0
    save_audio: bool = False

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
    #: the loudest sample read (1 is full scale): a session that stays silent says so in the run's line
    peak: float = 0.0
    #: how the reading went (:class:`InputHealth`: overflows, the worst lag), for metrics.json
    health: "InputHealth | None" = None
    clock = staticmethod(time.perf_counter)
    _gens: tuple = ()
    _line: "MeterLine | None" = None
    _spool: "FloatWavWriter | None" = None   # input.save_audio: the frames' samples so far, in a temporary file

    def open(self) -> None:
        from laughlab.io.replay import PREFIX, ReplayDevice

        if isinstance(self.params.device, str) and self.params.device.startswith(PREFIX):   # a recording played as
            self._open(ReplayDevice(self.params.device), self.params.device)   # the microphone, in real time
            return
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
            cause = str(exc).splitlines()[0]
            if _rate_refused(exc, cause):   # the microphone is there: it does not record at that rate
                which = "the default audio input" if device is None else f"input.device={device!r}"
                own = _own_rate(sd, device)
                fix = f"add input.sample_rate={own}, its own rate" if own and own != self.params.sample_rate else \
                    "set input.sample_rate to a rate it records at (python -m sounddevice lists the devices)"
                raise LaughlabError(f"{which} cannot record at input.sample_rate={self.params.sample_rate} "
                                    f"({cause}): {fix}") from None
            which = "no default audio input device" if device is None else f"input.device={device!r} cannot record"
            try:   # none at all: 'python -m sounddevice lists them' printed an empty line (a game developer's review)
                inputs = [d for d in sd.query_devices() if d.get("max_input_channels", 0) > 0]
            except Exception:
                inputs = None
            how = ("this machine has no audio input device (PortAudio finds none): connect a microphone, or stream "
                   "a recording with input=file input.path=LAUGH.wav" if inputs == [] else
                   "connect one, or name it with input.device=NAME_OR_INDEX (python -m sounddevice lists them)")
            raise LaughlabError(f"no usable microphone: {which} ({cause}); {how}") from None
        self._open(sd, device)

    def _open(self, sd, device) -> None:
        self._sd, self._device = sd, device
        self.sample_rate = self.params.sample_rate
        d = self.params.duration_s
        # the frames of the samples read (int(d * sr), as _chunks reads them), cut as any input's: ceil(d * fps) said
        # 250 for the 249 frames of 8.3 s at 30 fps (float rounding), 100 for the 99 of 1.1 s at 90 fps
        self.n_frames = None if d is None else n_frames_for(int(d * self.sample_rate), self.sample_rate, self.ctx.fps)
        self.duration_s = d
        self.calibration_s = float(self.params.calibration_s)

    def _say(self, text: str) -> None:
        """A line on stderr, on a line of its own: the calibration meter's line is ended first, and a progress
        bar (a session with no set length on a terminal) is cleared, and drawn again after it."""
        if self._line is not None:
            self._line.end()
        tqdm = sys.modules.get("tqdm")
        if tqdm is not None and getattr(tqdm.tqdm, "_instances", None):
            tqdm.tqdm.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def _chunks(self):
        n = block_samples(self.sample_rate, self.ctx.fps, self.params.block_frames)
        total = None if self.params.duration_s is None else int(self.params.duration_s * self.sample_rate)
        got = 0
        # a session silent this long says so while it runs (once), not only in its closing line
        silent_n, silent_peak, warned_silent = int(SILENT_WARN_S * self.sample_rate), 10 ** (SILENT_DBFS / 20), False
        sd = self._sd
        health = self.health = InputHealth(self.sample_rate, self.clock)
        with contextlib.ExitStack() as stack:
            # before the device starts: a stop signal during a slow start ends the input too
            stop = stack.enter_context(StopOnSignal()) if total is None else None
            try:
                stream = sd.InputStream(device=self._device, channels=1, samplerate=self.sample_rate,
                                        dtype="float32", blocksize=n)
                stack.enter_context(_running(stream, sd))
            except sd.PortAudioError as exc:
                raise LaughlabError(f"the microphone could not be started ({first_line(exc)}); check that it is "
                                    "connected and not in use (python -m sounddevice lists the devices)") from None
            waiting = _backlog(stream, sd)
            health.start()
            while total is None or got < total:
                block = self._read_block(stream, n if total is None else min(n, total - got), got, stop, waiting)
                if block is None:
                    return
                data, overflowed = block
                got += len(data)
                if len(data):
                    self.peak = max(self.peak, float(np.abs(data).max()))
                if not warned_silent and got >= silent_n and self.peak < silent_peak:
                    warned_silent = True   # said at the end only, a muted microphone left a user waiting (a review)
                    self._say(f"laughlab: warning: the microphone has been silent for {got / self.sample_rate:.1f} s "
                              f"({silent_text(self.peak)}): is it muted? input.device=NAME_OR_INDEX chooses another "
                              "(python -m sounddevice lists them)")
                if health.read(got, overflowed, clocked=waiting is None):
                    self._say(f"laughlab: warning: the microphone's buffer overflowed after "
                              f"{got / self.sample_rate:.1f} s: laughlab fell behind the microphone and audio was "
                              "lost (each time is counted: metrics.json input_overflows)")
                yield data[:, 0].copy()

    def _read_block(self, stream, n: int, got: int, stop, waiting):
        """The next ``n`` samples and the device's overflow flag, or None where the input ends (a stop signal,
        the device stopping: said in a line); either before any audio (``got == 0``) is an error."""
        if stop is not None and stop.signum is not None:
            self.stopped_by = signal.Signals(stop.signum).name
            key = "Ctrl-C" if stop.signum == signal.SIGINT else self.stopped_by
            if not got:   # pipeline.execute would fail on no frames after a line saying 'kept'
                raise StoppedBySignal(f"{key}: stopped before any audio was read; nothing to keep")
            self._say(f"laughlab: {key}: the input ended after {got / self.sample_rate:.1f} s and the session is "
                      "kept" + (" (the terminal hung up)" if key == "SIGHUP" else
                                f" ({key} again aborts it and removes what it wrote)"))
            return None
        if waiting is not None:
            self.health.waiting(waiting())
        try:
            return stream.read(n)
        except self._sd.PortAudioError as exc:   # a USB microphone pulled out, a device gone to sleep
            from laughlab.io.replay import ReplayEnded

            if isinstance(exc, ReplayEnded) and got:   # input.device=file:...: its end ends the input, kept
                self.stopped_by = "end"
                self._say(f"laughlab: the recording ended after {got / self.sample_rate:.1f} s; the session is kept")
                return None
            self.stopped_by = "device"
            if not got:
                raise LaughlabError(f"the microphone stopped before any audio was read ({first_line(exc)}); "
                                    "nothing to keep") from None
            self._say(f"laughlab: warning: the microphone stopped after {got / self.sample_rate:.1f} s "
                      f"({first_line(exc)}); the input ends there and the session up to there is kept")
            return None

    def metrics(self) -> dict:
        """For ``metrics.json``: what ended the input (``SIGINT``, ``SIGTERM``, ``SIGHUP``, ``device`` or None:
        its end), the reads the device flagged as overflowed, the worst lag behind the microphone (s) and the
        loudest sample read (``input_peak``, as a file's: a muted microphone says so in the run's line)."""
        h = self.health or InputHealth(self.sample_rate, self.clock)
        return {"input_stopped_by": self.stopped_by, "input_overflows": int(h.overflows),
                "input_lag_s_max": float(h.lag_s_max), "input_peak": float(self.peak)}

    def close(self) -> None:
        """The frame loop ended (or failed): its generators are closed, so the stream is closed and the signal
        handlers are back now, not when they are garbage-collected (a traceback holding them)."""
        gens, self._gens = self._gens, ()
        for gen in gens:
            with contextlib.suppress(Exception):   # cleanup, in the pipeline's finally: never hides its error
                gen.close()
        spool, self._spool = self._spool, None   # a run that failed: its audio is not kept
        if spool is not None:
            with contextlib.suppress(OSError):
                spool.f.close()
                os.unlink(spool.f.name)

    def blocks(self):
        reader = self._chunks()
        frames = cut_frames(reader, self.sample_rate, self.ctx.fps)
        n = int(round(self.ctx.calibration_s * self.ctx.fps))
        self._line = MeterLine()
        outer = calibration_meter(frames, n, self.ctx.fps, line=self._line) if n > 0 else frames
        if self.params.save_audio:
            outer = self._recorded(outer)
        self._gens = (outer, frames, reader)   # closed outermost first
        return outer

    def _recorded(self, frames):
        """Pass ``frames`` through, writing each one's samples (the float32 read, exactly) to a temporary WAV
        that :meth:`save_artifacts` puts into the run directory as ``input.wav``."""
        fd, name = tempfile.mkstemp(prefix="laughlab-mic-", suffix=".wav")
        os.close(fd)
        self._spool = spool = FloatWavWriter(name, self.sample_rate, long=True)   # RF64 past 4 GiB (6.8 h at 44.1 kHz)
        for block in frames:
            spool.write(block)
            yield block

    def save_artifacts(self, out_dir: Path) -> list[Path]:
        """``input.wav``: the session's audio (``input.save_audio``), whole or not at all; nothing without it."""
        spool, self._spool = self._spool, None
        if spool is None:
            return []
        from laughlab.core.outfiles import Staging

        staging = Staging()
        try:
            spool.close()
            shutil.move(spool.f.name, staging.path(Path(out_dir) / "input.wav"))
        except BaseException:
            staging.abort()
            raise
        finally:
            with contextlib.suppress(OSError):
                os.unlink(spool.f.name)
        return staging.commit()


class InputHealth:
    """How the reading of the microphone went, for ``metrics.json``: the reads the device flagged as overflowed
    (audio lost: laughlab fell behind) and the worst lag behind the microphone (s).

    The lag is the stream's backlog when the reader comes back for the next block (``read_available``: the
    audio already waiting), which no clock enters.  A stream without it (a stand-in) measures wall time since
    the start minus the audio read, less the smallest such lag of the last :attr:`WINDOW_S` of audio (the
    device's own latency).  The smallest of the whole session drifted with the sound card's clock: 50 ppm
    slow, 0.18 s an hour, and a session that kept up 'fell behind' after half an hour (diff-review 2); and
    audio lost in an overflow stayed in the lag for the rest of the session.
    """

    #: the stand-in's lag is taken over the smallest of this much audio before it (s)
    WINDOW_S = 10.0

    def __init__(self, sample_rate: int, clock):
        self.sample_rate, self.clock = sample_rate, clock
        self.overflows = 0
        self.lag_s_max = 0.0
        self._t0 = 0.0
        self._low: collections.deque = collections.deque()   # (samples read, lag), lags rising: the sliding min

    def start(self) -> None:
        self._t0 = self.clock()

    def waiting(self, samples: int) -> None:
        """The stream's backlog before a read (samples)."""
        lag = max(0, samples) / self.sample_rate
        if lag > self.lag_s_max:
            self.lag_s_max = lag

    def read(self, got: int, overflowed: bool, clocked: bool) -> bool:
        """A read ended, ``got`` samples in all; ``clocked``: no backlog, the lag from the clock.  Whether it
        was the first overflow (the one warned of)."""
        if clocked:
            lag, low = self.clock() - self._t0 - got / self.sample_rate, self._low
            while low and low[-1][1] >= lag:
                low.pop()
            low.append((got, lag))
            while low[0][0] < got - self.WINDOW_S * self.sample_rate:
                low.popleft()
            self.lag_s_max = max(self.lag_s_max, lag - low[0][1])
        if overflowed:
            self.overflows += 1
        return bool(overflowed) and self.overflows == 1


#: PortAudio's paInvalidSampleRate
PA_INVALID_SAMPLE_RATE = -9997


def _rate_refused(exc: Exception, cause: str) -> bool:
    """Whether ``check_input_settings`` refused the sample rate (not the device): sounddevice's
    ``PortAudioError(text, code)``; the text is said 'Invalid sample rate [PaErrorCode -9997]'."""
    return PA_INVALID_SAMPLE_RATE in getattr(exc, "args", ())[1:2] or f"[PaErrorCode {PA_INVALID_SAMPLE_RATE}]" in cause


def _own_rate(sd, device) -> int | None:
    """The input device's own sample rate (Hz), or None where PortAudio does not say one input.sample_rate takes."""
    try:
        rate = int(round(float(sd.query_devices(device, "input")["default_samplerate"])))
    except Exception:
        return None
    return rate if 8000 <= rate <= 192000 else None


def _backlog(stream, sd):
    """A function giving the samples waiting in ``stream`` (``read_available``), or None if it has none."""
    if not hasattr(stream, "read_available"):
        return None

    def waiting() -> int:
        try:
            return int(stream.read_available)
        except sd.PortAudioError:   # the read that follows says what happened
            return 0

    return waiting


def block_samples(sample_rate: int, fps: float, block_frames: int = 1) -> int:
    """Samples the microphone is read in: ``block_frames`` frames, rounded up (a block a sample short of a
    frame would make every frame wait one more block).  ``benchmarks/bench_latency.py`` replays by it."""
    return math.ceil(sample_rate / fps) * block_frames


@contextlib.contextmanager
def _running(stream, sd):
    """The stream, started, and closed in the end; stopping a device that went away raises nothing more.  A
    stream that fails to start is closed too (its PortAudio handle was left open, diff-review 8)."""
    try:
        stream.__enter__()
    except BaseException:
        with contextlib.suppress(Exception):
            stream.close()
        raise
    try:
        yield stream
    finally:
        try:
            stream.__exit__(None, None, None)   # stop, then close: a stop that fails skips the close
        except sd.PortAudioError:
            with contextlib.suppress(sd.PortAudioError):
                stream.close()


#: the level meter's scale: dBFS from METER_FLOOR_DB to 0
METER_FLOOR_DB = -60.0
#: a calibration burst quieter than this (dBFS) maps laughter to a small range: say so
QUIET_BURST_DB = -35.0
#: a session whose loudest sample stays under SILENT_DBFS this long (s) is warned, once, while it runs
SILENT_WARN_S = 5.0


def meter_line(level_db: float, peak_db: float, left_s: float, width: int = 30) -> str:
    """One line of the calibration meter: a bar of the level, the peak so far and the time left."""
    fill = int(round(width * min(1.0, max(0.0, 1.0 - level_db / METER_FLOOR_DB))))
    return f"  [{'#' * fill}{' ' * (width - fill)}] {level_db:6.1f} dBFS, peak {peak_db:6.1f}, {left_s:4.1f} s left"


class MeterLine:
    """The calibration meter's line while it is left open on a terminal (redrawn after ``"\\r"``, no newline):
    a line written meanwhile ends it first, or it is glued to the meter's text (diff-review 3)."""

    def __init__(self):
        self.out = None

    def end(self) -> None:
        if self.out is not None:
            out, self.out = self.out, None
            out.write("\n")
            out.flush()


def calibration_meter(frames, n: int, fps: float, out=None, line: MeterLine | None = None):
    """Pass ``frames`` through; over the first ``n`` say what to do and show their level on ``out`` (stderr).

    The meter redraws about 10 times a second on a terminal; elsewhere only the
    first and the last line are written.  Its line is ended when the input ends, or fails, before the
    calibration does, or when ``line.end()`` is called (:meth:`MicSource._say`).
    """
    out = out or sys.stderr
    line = line or MeterLine()
    live = out.isatty()
    every = max(1, int(round(fps / 10)))
    print(f"laughlab: calibrating for {n / fps:g} s (van Duijn 2014, 3.1.1): laugh or clap once, loudly, "
          "close to the microphone (input.calibration_s=0 skips this)", file=out, flush=True)
    peak = -math.inf
    try:
        for k, block in enumerate(frames):
            if k < n:
                ms = float(np.dot(block, block)) / max(1, len(block))
                level = 10.0 * math.log10(max(ms, 1e-14))
                peak = max(peak, level)
                if live and (k % every == 0 or k == n - 1):
                    out.write("\r" + meter_line(level, peak, (n - 1 - k) / fps))
                    out.flush()
                    line.out = out
                if k == n - 1:
                    line.end()
                    hint = ("; it heard nothing" if peak < SILENT_DBFS else
                            "; the burst was quiet, so laughter will move the character little: run again closer "
                            "to the microphone" if peak < QUIET_BURST_DB else "; go ahead and laugh")
                    print(f"laughlab: calibrated (peak {peak:.1f} dBFS){hint}", file=out, flush=True)
            yield block
    finally:
        line.end()


@hookimpl
def register_sources(register):
    register(MicSource)
