"""Sink ``csv``: ``channels.csv`` (time, then one column per channel) and ``events.csv``."""
from __future__ import annotations

import csv
from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.outfiles import Staging


@dataclass
class CsvParams:
    """Parameters of the ``csv`` sink.

    Attributes
    ----------
    precision : int
        Decimals written for channel values.
    """

    precision: int = 6

    def __post_init__(self) -> None:
        if not 1 <= self.precision <= 17:
            raise ValueError(f"precision must be in 1..17 (got {self.precision})")


EVENT_COLUMNS = ("time", "event", "clip", "energy", "speed", "reason", "offset", "end")


class CsvSink(Sink):
    """Streams ``channels.csv`` chunk by chunk; writes ``events.csv`` at the end.

    ``channels.csv``: column ``time`` (s), one column per named channel in the
    order the plugins wrote them, and ``label`` when the extractor gives
    pseudo-phoneme labels.  ``events.csv``: one row per clip start or stop with
    ``time`` (s), ``event``, ``clip``, ``energy``, ``speed``, ``reason``, and
    ``offset``/``end``: the stretch of clip time played (s; ``end`` empty = the
    clip's end), which segment concatenation uses.  ``phonemes.TextGrid``, with the labels: the same labels as a
    Praat interval tier ``phonemes`` (frame ``k``'s label from its ``time`` to the next frame's; a phonetician's
    review: the labels could be checked in Praat only by hand).
    """

    name = "csv"
    background = True  # only writes files: may run in the helper process
    files = ("channels.csv", "events.csv", "phonemes.TextGrid")
    Params = CsvParams

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self._f = open(self.staging.path(run.out_dir / "channels.csv"), "w", newline="", encoding="utf-8")
        self._events: list = []
        self._columns = None
        self._times: list = []
        self._label_seq: list = []

    def write(self, chunk) -> None:
        if self._columns is None:
            self._columns = list(chunk.channels)
            self._labels = any(lab is not None for lab in chunk.labels)
            self._f.write(",".join(["time", *self._columns] + (["label"] if self._labels else [])) + "\n")
        data = np.column_stack([chunk.times] + [chunk.channels[c] for c in self._columns])
        n, c = data.shape
        row = ",".join([f"%.{self.params.precision}f"] * c) + (",%s" if self._labels else "") + "\n"
        values = (data + 0.0).tolist()  # + 0.0 writes -0.0 as 0.0
        if self._labels:
            values = [[*r, lab or ""] for r, lab in zip(values, chunk.labels)]
            self._times.extend(float(t) for t in chunk.times)
            self._label_seq.extend(chunk.labels)
        # one %-format over the whole chunk: several times faster than np.savetxt's per-row loop
        self._f.write((row * n) % tuple(v for r in values for v in r))
        self._events.extend(chunk.events)

    def close(self):
        self._f.close()
        with open(self.staging.path(self.run.out_dir / "events.csv"), "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(EVENT_COLUMNS)
            for ev in self._events:
                end = "" if ev.end_s is None else f"{ev.end_s:.6f}"
                w.writerow([f"{ev.time_s:.6f}", ev.kind, ev.clip, f"{ev.energy:g}", f"{ev.speed:.6f}", ev.reason,
                            f"{ev.offset_s:.6f}", end])
        if self._times:
            from laughlab.io.textgrid import labels_to_intervals, write_textgrid

            dt = 1.0 / self.run.fps
            write_textgrid(self.staging.path(self.run.out_dir / "phonemes.TextGrid"),
                           labels_to_intervals(self._times, self._label_seq, dt), tier="phonemes", xmin=0.0,
                           xmax=self._times[-1] + dt)
        return self.staging.commit()

    def abort(self) -> None:
        self.staging.abort(getattr(self, "_f", None))  # closes it (a buffer that cannot be written is dropped) first


@hookimpl
def register_sinks(register):
    register(CsvSink)
