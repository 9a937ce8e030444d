"""A recording played as a microphone: ``input=mic input.device=file:LAUGH.wav``.

For trying the live path without a microphone (a game developer's review, 2026-11-29: on a machine without one, or
in a headless test, there was no way to see the calibration, a Ctrl-C that keeps the session, ``run_out`` after a
live input, or the stream's timing as a live session has them; ``input=file`` is an offline run, whose Ctrl-C
aborts it). :class:`ReplayDevice` stands where the ``mic`` source uses the ``sounddevice`` module: the recording is
read whole (its channels mixed by the mean, as ``input=file`` mixes them), resampled to ``input.sample_rate`` as a
microphone at that rate would record it (``scipy.signal.resample_poly``; the same rate: the samples themselves), and
handed out block by block at the pace a device would deliver it, in real time from the stream's start. When it ends,
the input ends, as a microphone unplugged would end it, and the session is kept.
"""
from __future__ import annotations

import math
import time

import numpy as np

from laughlab.core.errors import LaughlabError

#: how ``input.device`` names a recording to play as the microphone
PREFIX = "file:"


class PortAudioError(Exception):
    """What the stand-in raises where sounddevice raises its own."""


class ReplayEnded(PortAudioError):
    """The recording has been played to its end: the input ends there."""


class ReplayDevice:
    """The part of the ``sounddevice`` module the ``mic`` source uses, playing ``path``."""

    PortAudioError = PortAudioError

    def __init__(self, device: str):
        from laughlab.io.audio import probe_file

        self.path = device[len(PREFIX):]
        if not self.path:
            raise LaughlabError(f"input.device={device!r}: give the recording to play, input.device=file:LAUGH.wav")
        try:
            info = probe_file(self.path)
        except LaughlabError as exc:
            raise LaughlabError(f"input.device={device}: {exc}") from None
        self.rate = int(info.samplerate)
        self._audio: np.ndarray | None = None   # decoded when a stream starts: a run builds its source twice

    @property
    def audio(self) -> np.ndarray:
        """The recording, mono float32 (its channels mixed by the mean, as ``input=file`` mixes them)."""
        if self._audio is None:
            from laughlab.io.audio import read_blocks

            try:
                self._audio = np.concatenate(list(read_blocks(self.path)))
            except LaughlabError as exc:   # a damaged file: its line names the device setting too
                raise LaughlabError(f"input.device={PREFIX}{self.path}: {exc}") from None
        return self._audio

    def check_input_settings(self, device=None, channels=1, samplerate=None, dtype="float32") -> None:
        """Any rate: the recording is resampled to it."""

    def query_devices(self, device=None, kind=None):
        info = {"name": f"{PREFIX}{self.path}", "max_input_channels": 1, "default_samplerate": float(self.rate)}
        return info if device is not None or kind is not None else [info]

    def InputStream(self, device=None, channels=1, samplerate=None, dtype="float32", blocksize=0):  # noqa: N802
        return ReplayStream(self.resampled(int(samplerate)), int(samplerate))

    def resampled(self, rate: int) -> np.ndarray:
        """The recording at ``rate`` (Hz), float32."""
        if rate == self.rate:
            return self.audio.astype(np.float32, copy=False)
        from scipy.signal import resample_poly

        g = math.gcd(rate, self.rate)
        return resample_poly(self.audio, rate // g, self.rate // g).astype(np.float32)


class ReplayStream:
    """A started input stream: :meth:`read` returns ``n`` samples once they would have been recorded."""

    clock = staticmethod(time.perf_counter)

    def __init__(self, samples: np.ndarray, rate: int):
        self.samples, self.rate = samples, rate
        self.pos = 0
        self.t0: float | None = None

    def __enter__(self) -> "ReplayStream":
        self.t0 = self.clock()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.samples = self.samples[:0]

    @property
    def read_available(self) -> int:
        """Samples recorded and not yet read (the backlog a device reports)."""
        due = int((self.clock() - self.t0) * self.rate) if self.t0 is not None else 0
        return max(0, min(due, len(self.samples)) - self.pos)

    def read(self, n: int) -> tuple[np.ndarray, bool]:
        """The next ``n`` samples, ``(n, 1)`` float32, and no overflow; fewer at the recording's end, then
        :class:`ReplayEnded`."""
        if self.pos >= len(self.samples):
            raise ReplayEnded("the recording ended")
        block = self.samples[self.pos:self.pos + n]
        self.pos += len(block)
        wait = self.t0 + self.pos / self.rate - self.clock()
        if wait > 0:
            time.sleep(wait)
        return block.reshape(-1, 1), False
