"""Source ``mic``: live input through sounddevice (PortAudio), block by block.

A live run starts with the thesis' calibration (van Duijn 2014, 3.1.1): for
``calibration_s`` seconds the terminal asks for one loud laugh or clap close to
the microphone and shows a level meter; the extractor takes the quietest and
loudest frame of that burst as its first minAmp and maxAmp.
"""
from __future__ import annotations

import math
import sys
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
        frames = cut_frames(self._chunks(), self.sample_rate, self.ctx.fps)
        n = int(round(self.ctx.calibration_s * self.ctx.fps))
        return calibration_meter(frames, n, self.ctx.fps) if n > 0 else frames


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
