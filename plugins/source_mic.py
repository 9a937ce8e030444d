"""Source ``mic``: live input through sounddevice (PortAudio), block by block."""
from __future__ import annotations

import math
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
        Stop after this many seconds; None runs until Ctrl-C.
    block_frames : int
        Animation frames per audio block read from the device (1 = lowest latency).
    """

    device: str | None = None
    sample_rate: int = 16000
    duration_s: float | None = None
    block_frames: int = 1

    def __post_init__(self) -> None:
        check_range("sample_rate", self.sample_rate, 8000, 192000)
        check_range("block_frames", self.block_frames, 1)
        if self.duration_s is not None:
            check_range("duration_s", self.duration_s, 0, lo_open=True)


class MicSource(Source):
    """Reads the microphone in blocks of one frame (or ``block_frames``) and yields frames."""

    name = "mic"
    Params = MicParams
    live = True

    def open(self) -> None:
        try:
            import sounddevice as sd
        except (ImportError, OSError) as exc:
            raise LaughlabError(
                f"input=mic needs sounddevice and PortAudio (pip install 'laughlab[mic]'): {exc}"
            ) from None
        device = self.params.device
        if isinstance(device, str) and device.isdigit():
            device = int(device)
        try:
            sd.check_input_settings(device=device, channels=1, samplerate=self.params.sample_rate,
                                    dtype="float32")
        except Exception as exc:
            raise LaughlabError(f"no usable microphone: {str(exc).splitlines()[0]}") from None
        self._sd, self._device = sd, device
        self.sample_rate = self.params.sample_rate
        d = self.params.duration_s
        self.n_frames = None if d is None else int(np.ceil(d * self.ctx.fps))
        self.duration_s = d

    def _chunks(self):
        # round up: a block a sample short of a frame would make every frame wait one more block
        n = math.ceil(self.sample_rate / self.ctx.fps) * self.params.block_frames
        total = None if self.params.duration_s is None else int(self.params.duration_s * self.sample_rate)
        got = 0
        with self._sd.InputStream(device=self._device, channels=1, samplerate=self.sample_rate,
                                  dtype="float32", blocksize=n) as stream:
            while total is None or got < total:
                data, _overflow = stream.read(n)
                got += len(data)
                yield data[:, 0].copy()

    def blocks(self):
        return cut_frames(self._chunks(), self.sample_rate, self.ctx.fps)


@hookimpl
def register_sources(register):
    register(MicSource)
