"""Source ``file``: a recording read in blocks (any format and rate soundfile reads)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from laughlab import hookimpl
from laughlab.io.audio import cut_frames, n_frames_for, probe_file, read_blocks
from laughlab.core.bases import Source
from laughlab.core.errors import LaughlabError


@dataclass
class FileParams:
    """Parameters of the ``file`` source.

    Attributes
    ----------
    path : str
        Audio file (WAV, FLAC, OGG, MP3, ... as soundfile reads; 8-192 kHz; channels mixed to mono).
    """

    path: str = ""


class FileSource(Source):
    """Reads ``path`` in one-second blocks and cuts it into frames; memory does not grow with length."""

    name = "file"
    Params = FileParams
    reread = True   # blocks() opens the file again

    def open(self) -> None:
        if not self.params.path:
            raise LaughlabError("input=file needs input.path=FILE")
        info = probe_file(self.params.path)
        self.sample_rate = int(info.samplerate)
        self.n_frames = n_frames_for(info.frames, self.sample_rate, self.ctx.fps)
        self.duration_s = info.frames / info.samplerate

    def blocks(self):
        return cut_frames(read_blocks(self.params.path), self.sample_rate, self.ctx.fps)

    def audio_path(self):
        return Path(self.params.path).expanduser()


@hookimpl
def register_sources(register):
    register(FileSource)
