"""Sink ``plots``: the run's Figure 3.2- and 4.2-style plots in ``plots/``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.bases import Sink
from laughlab.outfiles import Staging
from laughlab.plugins import check_range


@dataclass
class PlotsParams:
    """Parameters of the ``plots`` sink.

    Attributes
    ----------
    max_seconds : float
        Plot at most this many seconds from the start (long runs stay readable).
    power : float
        Exponent of the MCS for Fig. 3.2 (the ``rms`` extractor's ``power``).
    """

    max_seconds: float = 60.0
    power: float = 2.0

    def __post_init__(self) -> None:
        check_range("max_seconds", self.max_seconds, 0, lo_open=True)


class PlotsSink(Sink):
    """Keeps the signals the figures need (a few floats per frame) and draws them at the end.

    ``plots/fig3_2_mcs.png`` needs the ``mcs_raw`` control (``rms`` extractor);
    ``plots/fig4_2_energy.png`` needs ``mcs`` and the ``energy`` channel.
    """

    name = "plots"
    Params = PlotsParams
    _keys = ("mcs_raw", "mcs", "energy")

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.cols: dict[str, list] = {k: [] for k in ("time", *self._keys)}
        self.events: list = []
        self.limit = int(self.params.max_seconds * run.fps)
        self.n = 0

    def write(self, chunk) -> None:
        take = max(0, min(len(chunk.times), self.limit - self.n))
        if take:
            self.cols["time"].append(chunk.times[:take])
            for k in self._keys:
                if k in chunk.channels:
                    self.cols[k].append(chunk.channels[k][:take])
            self.events.extend(ev for ev in chunk.events if ev.time_s < self.params.max_seconds)
        self.n += len(chunk.times)

    def close(self):
        from laughlab import plots

        if not self.cols["time"]:
            return []
        data = {k: np.concatenate(v) for k, v in self.cols.items() if v}
        truth = getattr(self.run.source, "truth", None)
        bouts = [(b.onset_s, b.offset_s) for b in truth.bouts] if truth is not None else None
        out = self.run.out_dir / "plots"
        t = data["time"]
        if "mcs_raw" in data:
            plots.figure_3_2(self.staging.path(out / "fig3_2_mcs.png"), t, data["mcs_raw"], 1.0 / self.run.fps,
                             self.params.power, bouts)
        if "mcs" in data and "energy" in data:
            plots.figure_4_2(self.staging.path(out / "fig4_2_energy.png"), t, data["mcs"], data["energy"],
                             self.events, bouts)
        return self.staging.commit()

    def abort(self) -> None:
        self.staging.abort()


@hookimpl
def register_sinks(register):
    register(PlotsSink)
