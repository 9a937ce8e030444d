"""Source ``file``: a recording read in blocks (any format and rate soundfile reads)."""
from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from laughlab import hookimpl
from laughlab.io.audio import cut_frames, n_frames_for, probe_file, read_blocks
from laughlab.core.bases import Source
from laughlab.core.errors import LaughlabError
from laughlab.core.plugins import check_range
from laughlab.core.summary import SILENT_DBFS


@dataclass
class FileParams:
    """Parameters of the ``file`` source.

    Attributes
    ----------
    path : str
        Audio file (WAV, FLAC, OGG, MP3, ... as soundfile reads; 8-192 kHz; channels mixed to mono).
    truth : str
        Optional ground truth of the recording: a ``truth.csv`` (laughlab's columns) or an annotation
        (Audacity labels ``.txt``, Praat ``.TextGrid``, ELAN ``.eaf``; ``laughlab.corpora.annotations``), checked
        when the run starts.  Its bouts shade the figures as a synthetic input's do, and the run writes it as
        ``truth.csv`` (an experiment's showcase of a recording passes its annotation here).
    channel : int or None
        Read this channel alone (0 the first, left), not the mean of them all (a recording whose channels cancel
        when mixed, or a dyad with one speaker a channel).
    highpass_hz : float
        Remove a DC offset and rumble below this frequency (Hz; a 2nd-order Butterworth high-pass run causally
        block by block: scipy's ``sosfilt`` with its state, the same samples however the file is cut); 0, the
        default, reads the samples as they are, as the papers do.  A new-user review: a DC offset of 0.05
        full scale left a real laugh without a clip (the rms extractor maps the level between its min and max).
    """

    path: str = ""
    truth: str = ""
    channel: Optional[int] = None
    highpass_hz: float = 0.0

    def __post_init__(self) -> None:
        if self.channel is not None:
            check_range("channel", self.channel, 0)
        check_range("highpass_hz", self.highpass_hz, 0, 1000)   # under any rate's Nyquist (8 kHz: 4 kHz)


@dataclass(frozen=True)
class Bout:
    """A laughter bout of the truth, in seconds."""

    onset_s: float
    offset_s: float


@dataclass
class RecordingTruth:
    """A recording's ground truth from ``input.truth``: its ``bouts`` (what the figures shade) and the
    ``rows`` of its ``truth.csv``."""

    bouts: list
    rows: list
    columns: tuple = ()   # the header as read (a truth with no row, laughter-free, keeps it)

    @classmethod
    def read(cls, path: str, duration_s: float) -> "RecordingTruth":
        import csv

        from laughlab.harness.corpus import check_truth_csv

        p = Path(path).expanduser()
        if not p.is_file():
            raise LaughlabError(f"input.truth not found: {path}")
        from laughlab.corpora.annotations import SUFFIXES, read

        columns: tuple = ()
        if p.suffix.lower() in SUFFIXES:
            rows = read(p, duration_s).truth_rows()
        else:
            check_truth_csv(p, duration_s)
            with p.open(newline="", encoding="utf-8") as fh:
                reader = csv.DictReader(fh)
                rows = [dict(r) for r in reader]
                columns = tuple(reader.fieldnames or ())
        bouts = [Bout(float(r["onset_s"]), float(r["offset_s"])) for r in rows if r["kind"] == "bout"]
        return cls(bouts, rows, columns)

    def write(self, path: Path) -> None:
        """``truth.csv``: the rows under the header as read; a truth without laughter, no row, keeps its header (a
        metrics audit: it was written as an empty line, which the metrics then could not read: a traceback)."""
        import csv

        from laughlab.corpora.mixed import TRUTH_COLUMNS

        columns = list(dict.fromkeys([*self.columns, *(k for r in self.rows for k in r)])) or list(TRUTH_COLUMNS)
        with open(path, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, columns, lineterminator="\n")
            w.writeheader()
            w.writerows(self.rows)


class FileSource(Source):
    """Reads ``path`` in one-second blocks and cuts it into frames; memory does not grow with length."""

    name = "file"
    Params = FileParams
    reread = True   # blocks() opens the file again

    def open(self) -> None:
        if not self.params.path:
            raise LaughlabError("input=file needs input.path=FILE")
        info = probe_file(self.params.path)
        if self.params.channel is not None and self.params.channel >= info.channels:
            raise LaughlabError(f"input.channel={self.params.channel}: {self.params.path} has {info.channels} "
                                f"channel(s), numbered from 0")
        self.channels = int(info.channels)
        self.sample_rate = int(info.samplerate)
        self.n_frames = n_frames_for(info.frames, self.sample_rate, self.ctx.fps)
        self.duration_s = info.frames / info.samplerate
        self.truth = RecordingTruth.read(self.params.truth, self.duration_s) if self.params.truth else None
        # the loudest finite sample, and the finite samples' sum and number (the file's DC offset, input_dc), of the
        # reader furthest into the file: the main loop's and the detector's look-ahead read it in the same order;
        # both added to one sum from two threads, updates were lost and the order varied (a reproducibility
        # review: input_dc differed in 1 of 25 runs, and in 1-4 of an experiment's 64 trials)
        self.peak, self.total, self.count = 0.0, 0.0, 0
        self._stats = threading.Lock()

    def save_artifacts(self, out_dir: Path) -> list[Path]:
        """``truth.csv`` from ``input.truth``, whole or not at all (nothing without it)."""
        if self.truth is None:
            return []
        from laughlab.core.outfiles import Staging

        staging = Staging()
        try:
            self.truth.write(staging.path(Path(out_dir) / "truth.csv"))
        except BaseException:
            staging.abort()
            raise
        return staging.commit()

    def blocks(self):
        return cut_frames(self._read(), self.sample_rate, self.ctx.fps)

    def _read(self):
        """The file's chunks (``channel``'s alone, high-passed at ``highpass_hz``), noting the loudest finite sample
        (a silent file says so in the run's line) and the samples' mean (so does a DC offset) as read."""
        hp = None
        if self.params.highpass_hz > 0:
            from laughlab.signals.highpass import CausalHighpass

            hp = CausalHighpass(self.params.highpass_hz, self.sample_rate)
        peak, total, count = 0.0, 0.0, 0
        for chunk in read_blocks(self.params.path, channel=self.params.channel):
            finite = chunk[np.isfinite(chunk)]
            if finite.size:
                peak = max(peak, float(np.abs(finite).max()))
                total += float(finite.sum(dtype=np.float64))
                count += finite.size
                with self._stats:
                    if count > self.count:
                        self.peak, self.total, self.count = peak, total, count
            if hp is not None:
                chunk = hp.step(chunk)
            yield chunk

    def metrics(self) -> dict:
        """For ``metrics.json``: the loudest sample read, ``input_peak`` (1 is full scale; 0 digital silence), and
        the samples' mean, ``input_dc`` (full scale; before ``highpass_hz``); for a silent mix of several
        channels, ``input_channel_peaks``, each channel's loudest sample (channels that cancel when mixed)."""
        out = {"input_peak": float(self.peak), "input_dc": self.total / self.count if self.count else 0.0}
        if self.peak < 10 ** (SILENT_DBFS / 20) and self.channels > 1 and self.params.channel is None:
            out["input_channel_peaks"] = [max((float(np.nanmax(np.abs(c))) for c in read_blocks(
                self.params.path, channel=k) if c.size), default=0.0) for k in range(self.channels)]
        return out

    def audio_path(self):
        return Path(self.params.path).expanduser()


@hookimpl
def register_sources(register):
    register(FileSource)
