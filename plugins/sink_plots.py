"""Sink ``plots``: the run's Figure 3.1-, 3.2-, 4.1- and 4.2-style plots in ``plots/`` (PNG; with
``output.plots.pdf=true`` a vector PDF of each beside it)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.core.background import parallel
from laughlab.core.bases import Sink
from laughlab.core.outfiles import Staging
from laughlab.core.plugins import check_range
from laughlab.render.method_plots import CHANNELS as METHOD_CHANNELS


@dataclass
class PlotsParams:
    """Parameters of the ``plots`` sink.

    Attributes
    ----------
    max_seconds : float
        Plot at most this many seconds from the start (long runs stay readable).
    power : float
        Exponent of the MCS for Fig. 3.2 (the ``rms`` extractor's ``power``).
    filmstrip_frames : int
        Stick figures in ``plots/filmstrip.png`` (0: no filmstrip): each clip
        played at its most pronounced pose (the farthest from the run's usual
        pose), then the most pronounced poses of the parts of the run not shown
        yet, all at different times, in time order
        (:func:`laughlab.render.plots.filmstrip_moments`); under each, the clip
        playing then and the smile and jaw weights.
    pdf : bool
        Also write each figure as a vector PDF beside its PNG (``fig4_2_energy.pdf``...), for print; an
        experiment's showcase runs do (their report links them).
    width : str
        ``page``: the figures 7-8 in wide, for a page's full width (``figure*``) or a screen; ``column``: 3.5 in
        wide, for one column of a two-column paper, every text at 7 pt or more at that size
        (:mod:`laughlab.render.layout`).
    """

    max_seconds: float = 60.0
    power: float = 2.0
    filmstrip_frames: int = 8
    pdf: bool = False
    width: str = "page"

    def __post_init__(self) -> None:
        from laughlab.render.layout import layout_of

        layout_of(self.width)   # page or column, else one line naming them
        check_range("max_seconds", self.max_seconds, 0, lo_open=True)
        check_range("filmstrip_frames", self.filmstrip_frames, 0, 24)


class PlotsSink(Sink):
    """Keeps the signals the figures need (a few floats per frame) and draws them at the end.

    ``plots/fig3_1_calibration.png`` needs the ``amp`` control (``rms`` and
    ``phoneme`` extractors) or, for other extractors, ``rms``, from which it
    shows what the thesis' mapping with default parameters would do;
    ``plots/fig3_2_mcs.png`` needs the ``mcs_raw`` control (``rms`` extractor);
    ``plots/fig4_2_energy.png`` needs ``mcs``, the ``energy`` channel and a scheduler (not ``none``);
    ``plots/fig4_1_energy.png`` also the ``energy`` scheduler (its gain);
    ``plots/filmstrip.png`` shows the skeleton at a few moments (poses are kept
    at 5 Hz over the plotted stretch).
    """

    name = "plots"
    background = True  # only writes files: may run in the helper process
    files = ("plots",)
    Params = PlotsParams
    _keys = tuple(dict.fromkeys(("rms", "amp", "calibrating", "mcs_raw", "mcs", "energy", "smile", "jaw",
                                 "eyes_closed", "clip_gate") + METHOD_CHANNELS))
    _pose_hz = 5.0

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.cols: dict[str, list] = {k: [] for k in ("time", *self._keys)}
        self.events: list = []
        self.limit = int(self.params.max_seconds * run.fps)
        self.n = 0
        self.input_end_s = None   # where the input ended, when run_out went on in silence
        self.pose_every = max(1, int(round(run.fps / self._pose_hz)))
        self.pose_idx: list = []
        self.poses: list = []

    def write(self, chunk) -> None:
        take = max(0, min(len(chunk.times), self.limit - self.n))
        if take:
            self.cols["time"].append(chunk.times[:take])
            for k in self._keys:
                if k in chunk.channels:
                    self.cols[k].append(chunk.channels[k][:take])
            self.events.extend(ev for ev in chunk.events if ev.time_s < self.params.max_seconds)
            first = (-self.n) % self.pose_every
            idx = np.arange(first, take, self.pose_every)
            self.pose_idx.append(idx + self.n)
            self.poses.append(chunk.poses[idx])
        self.n += len(chunk.times)
        self.input_end_s = chunk.input_end_s

    def close(self):
        from laughlab.render import plots

        if not self.cols["time"]:
            return []
        data = {k: np.concatenate(v) for k, v in self.cols.items() if v}
        truth = getattr(self.run.source, "truth", None)
        bouts = [(b.onset_s, b.offset_s) for b in truth.bouts] if truth is not None else None
        out = self.run.out_dir / "plots"
        t = data["time"]
        # a long run is plotted over its first max_seconds (readable, and drawn in constant time): say so
        note = (f"first {self.params.max_seconds:g} s of {self.n / self.run.fps:.0f} s (output.plots.max_seconds)"
                if self.n > self.limit else "")
        jobs = []
        if "mcs_raw" in data:
            path, pdf = self._paths(out / "fig3_2_mcs.png")
            jobs.append(lambda: plots.figure_3_2(path, t, data["mcs_raw"], 1.0 / self.run.fps, self.params.power,
                                                 bouts, note=note, pdf=pdf, layout=self.params.width,
                                                 input_end_s=self.input_end_s))
        scheduler = (self.run.config or {}).get("scheduler") or {}
        # scheduler=none writes its energy as 0 and starts no clip: Fig. 4.2 would be an MCS over an empty panel,
        # which a report copied too (a researcher's review); Fig. 3.2 shows that MCS
        if "mcs" in data and "energy" in data and scheduler.get("name") != "none":
            path42, pdf42 = self._paths(out / "fig4_2_energy.png")
            label = {"energy": "laughing energy L", "concat": "energy (40 MCS, 0.5 s low-pass)"}.get(
                scheduler.get("name"), "energy channel")
            gate = data.get("clip_gate")   # the detector's clip gain: a closed gate is said (plots._closed_gate_note)
            jobs.append(lambda: plots.figure_4_2(path42, t, data["mcs"], data["energy"], self.events, bouts,
                                                 note=note, energy_label=label, pdf=pdf42,
                                                 layout=self.params.width, gate=gate,
                                                 input_end_s=self.input_end_s))
            if scheduler.get("name") == "energy":
                path41, pdf41 = self._paths(out / "fig4_1_energy.png")
                jobs.append(lambda: plots.figure_4_1(path41, t, data["mcs"], data["energy"], self.events,
                                                     float(scheduler.get("gain_per_s", 60.0)), bouts, note=note,
                                                     pdf=pdf41, layout=self.params.width, gate=gate,
                                                     input_end_s=self.input_end_s))
        fig31 = self._figure_3_1_args(data)
        if fig31 is not None:
            path31, pdf31 = self._paths(out / "fig3_1_calibration.png")
            jobs.append(lambda: plots.figure_3_1(path31, t, **fig31, bouts=bouts, note=note, pdf=pdf31,
                                                 layout=self.params.width, input_end_s=self.input_end_s))
        from laughlab.render.method_plots import method_figure, method_panels

        if method_panels(data):   # the method's own signals (a researcher's review: channels.csv held them alone)
            path_m, pdf_m = self._paths(out / "method.png")
            cfg = self.run.config or {}
            chain = ", ".join(f"{g}={(cfg.get(g) or {}).get('name')}" for g in ("extractor", "body", "face",
                                                                              "scheduler") if cfg.get(g))
            jobs.append(lambda: method_figure(path_m, t, data, title=f"The method's own signals ({chain})".replace(
                " ()", ""), note=note, pdf=pdf_m, layout=self.params.width, input_end_s=self.input_end_s))
        if self.params.filmstrip_frames and self.poses:
            strip, strip_pdf = self._paths(out / "filmstrip.png")
            jobs.append(lambda: self._filmstrip(strip, data, note, strip_pdf))
        parallel(jobs)  # side by side in the helper process, one by one otherwise
        return self.staging.commit()

    def _paths(self, png):
        """The staging paths of a figure's PNG and, with ``pdf``, of its PDF (None without)."""
        return self.staging.path(png), self.staging.path(png.with_suffix(".pdf")) if self.params.pdf else None

    def _figure_3_1_args(self, data) -> dict | None:
        """Fig. 3.1's amplitudes, rms parameters, fps, calibration length and title, or None without ``rms``."""
        from laughlab.signals.mcs import LOUDNESS_FLOOR_RMS, RmsParams, params_of_run

        params = params_of_run(self.run.config)
        cal_s = float(np.count_nonzero(data["calibrating"])) / self.run.fps if "calibrating" in data else 0.0
        if params is not None and "amp" in data:
            return dict(amp=data["amp"], params=params, fps=self.run.fps, calibration_s=cal_s)
        if "rms" not in data:
            return None
        amp = 10.0 * np.log10(np.maximum(data["rms"], LOUDNESS_FLOOR_RMS))
        name = ((self.run.config or {}).get("extractor") or {}).get("name", "?")
        # what the rms extractor would make of the sound, not this run's MCS (a researcher's review: its panels,
        # labelled MCS, reached 1 where the pressure extractor's MCS was 0)
        return dict(amp=amp, params=RmsParams(), fps=self.run.fps, mcs_label="rms's MCS",
                    title=f"The thesis' rms mapping of this run's sound, not the MCS of this run (extractor={name}; "
                          "cf. Fig. 3.1)")

    def _filmstrip(self, path, data, note: str = "", pdf=None) -> None:
        from laughlab.motion.skeleton import forward_kinematics
        from laughlab.render import plots

        idx = np.concatenate(self.pose_idx)
        poses = np.concatenate(self.poses)
        times = idx / self.run.fps
        positions = forward_kinematics(self.run.skeleton, poses)
        blocks = plots.clip_blocks(self.events, float(data["time"][-1]))
        pick = plots.filmstrip_moments(times, positions, self.params.filmstrip_frames, blocks)
        caps = []
        for i in pick:
            t = times[i]
            playing = [b[0] for b in blocks if b[1] <= t < b[2]]
            face = ", ".join(f"{k} {data[k][idx[i]]:.2f}" for k in ("smile", "jaw") if k in data)
            caps.append(f"{playing[-1] if playing else 'no clip'}\n{face}")
        title = ("The character over the run: each clip's most pronounced pose, then the run's (skeleton from "
                 "motion.bvh)") if self.params.width == "page" else "Each clip's most pronounced pose, then the run's"
        plots.filmstrip(path, self.run.skeleton, times[pick], poses[pick], caps, note=note, title=title, pdf=pdf,
                        layout=self.params.width)

    def abort(self) -> None:
        self.staging.abort()


@hookimpl
def register_sinks(register):
    register(PlotsSink)
