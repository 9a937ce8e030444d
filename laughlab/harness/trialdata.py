"""What the metrics read: one run's outputs, loaded from its run directory.

Metrics are computed from run outputs (``channels.csv``, ``events.csv``,
``motion.bvh``, ``metrics.json`` and an optional ground truth ``truth.csv``), so
they work for any extractor, scheduler, body or face.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas is imported where a table is read (it costs ~0.15 s at start-up)
    import pandas as pd

#: the library's idle clip: its plays are not laughter clips
IDLE = "idle"
#: smoothing window of intensity signals (s)
SMOOTH_S = 1.0


def moving_average(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving average over ``n`` samples (edges use the available samples)."""
    x = np.asarray(x, dtype=float)
    if n <= 1 or len(x) == 0:
        return x.copy()
    kernel = np.ones(n)
    num = np.convolve(x, kernel, mode="same")
    den = np.convolve(np.ones_like(x), kernel, mode="same")
    return num / den


def _inside(rows: pd.DataFrame, times: np.ndarray) -> np.ndarray:
    """Which of ``times`` lie inside one of ``rows``' ``[onset_s, offset_s)`` intervals."""
    out = np.zeros(len(times), dtype=bool)
    for on, off in rows[["onset_s", "offset_s"]].itertuples(index=False):
        out |= (times >= on) & (times < off)
    return out


@dataclass
class Truth:
    """Ground truth of a laughter recording: bouts and calls (from ``truth.csv``).

    Columns of ``truth.csv``: ``kind`` (``bout`` or ``call``), ``bout``,
    ``onset_s``, ``offset_s``, ``intensity`` (0..1), optionally ``f0_hz``.
    Rows of other kinds (``speech``, ``cough``, ... in the mixed scenes) are in ``others``.
    """

    bouts: pd.DataFrame
    calls: pd.DataFrame
    others: pd.DataFrame | None = None

    @classmethod
    def load(cls, path: str | Path) -> "Truth":
        """A ``truth.csv``, or an annotation (Audacity labels ``.txt``, Praat ``.TextGrid``, ELAN ``.eaf``)."""
        import pandas as pd

        from laughlab.corpora.annotations import SUFFIXES, read

        # every annotation the corpus folder takes (a review: a NAME.eaf beside its recording, written by detect and
        # corrected in ELAN, was read here as a CSV and every trial stopped in a pandas traceback)
        if str(path).lower().endswith(SUFFIXES):
            rows = read(path).truth_rows()
            t = pd.DataFrame(rows, columns=["kind", "bout", "onset_s", "offset_s", "intensity"])
        else:
            t = pd.read_csv(path)
        return cls(t[t.kind == "bout"].reset_index(drop=True), t[t.kind == "call"].reset_index(drop=True),
                   t[~t.kind.isin(["bout", "call"])].reset_index(drop=True))

    def in_bouts(self, times: np.ndarray) -> np.ndarray:
        """Which of ``times`` lie inside an annotated bout (onset included, offset not)."""
        return _inside(self.bouts, times)

    def in_calls(self, times: np.ndarray) -> np.ndarray:
        """Which of ``times`` lie inside an annotated call (onset included, offset not), whatever its intensity."""
        return _inside(self.calls, times)

    @property
    def graded(self) -> bool:
        """Whether the calls' intensities say how strong each call is (the synthetic generator's do); calls that all
        carry one value (the real corpus' and an annotation's 1.0) say where the laughter is, not how strong."""
        return self.calls["intensity"].dropna().nunique() > 1   # blanks (unknown) do not grade

    def intensity(self, times: np.ndarray) -> np.ndarray:
        """Laughter intensity at ``times``: the call's intensity inside a call, 0 elsewhere; a call whose intensity is
        blank (unknown, as ``truth.csv`` allows) counts 1, as an annotation's calls do (a metrics audit: its NaN made
        ``jaw_call_r`` NaN)."""
        out = np.zeros(len(times))
        for on, off, inten in self.calls[["onset_s", "offset_s", "intensity"]].itertuples(index=False):
            out[(times >= on) & (times < off)] = 1.0 if inten != inten else inten   # NaN: blank
        return out


@dataclass
class TrialData:
    """The outputs of one run.

    Attributes
    ----------
    channels : DataFrame
        ``channels.csv``.
    events : DataFrame
        ``events.csv``.
    fps : float
    truth : Truth or None
    run_metrics : dict
        ``metrics.json`` (compute time).
    motion_path : Path or None
        ``motion.bvh``, read on first use of ``poses``.
    """

    channels: pd.DataFrame
    events: pd.DataFrame
    fps: float
    truth: Truth | None = None
    run_metrics: dict = field(default_factory=dict)
    motion_path: Path | None = None

    @classmethod
    def load(cls, run_dir: str | Path, truth: str | Path | None = None) -> "TrialData":
        import pandas as pd

        d = Path(run_dir)
        ch = pd.read_csv(d / "channels.csv")
        ev = pd.read_csv(d / "events.csv", keep_default_na=False, na_values={"end": [""]})
        m = json.loads((d / "metrics.json").read_text(encoding="utf-8")) if (d / "metrics.json").exists() else {}
        fps = float(m.get("fps") or 1.0 / np.median(np.diff(ch.time)))
        tp = Path(truth) if truth else d / "truth.csv"
        return cls(ch, ev, fps, Truth.load(tp) if tp.exists() else None, m,
                   d / "motion.bvh" if (d / "motion.bvh").exists() else None)

    @property
    def times(self) -> np.ndarray:
        return self.channels["time"].to_numpy()

    @property
    def duration_s(self) -> float:
        return len(self.channels) / self.fps

    @cached_property
    def poses(self) -> np.ndarray | None:
        if self.motion_path is None:
            return None
        from laughlab.io.bvh import read_bvh

        self._skeleton, motion, _ = read_bvh(self.motion_path)
        return motion

    @cached_property
    def kinetic_energy(self) -> np.ndarray | None:
        """Kinetic energy of the skeleton per unit mass, ``0.5 * sum_j |v_j|^2`` in (m/s)^2 (J/kg).

        Every joint weighs the same; velocities are finite differences of the
        joint positions from forward kinematics (cm -> m).
        """
        poses = self.poses
        if poses is None or len(poses) < 2:
            return None
        from laughlab.motion.skeleton import forward_kinematics

        pos = forward_kinematics(self._skeleton, poses) / 100.0
        v = np.diff(pos, axis=0) * self.fps
        ke = 0.5 * np.sum(v * v, axis=(1, 2))
        return np.r_[ke[:1], ke]

    @cached_property
    def laughter_intensity(self) -> np.ndarray:
        """Laughter intensity I(t) per frame (0-1), smoothed over 1 s.

        The ground truth's call intensities when they are graded (:attr:`Truth.graded`: the synthetic inputs);
        when its calls are not graded (real recordings, annotations), the sound's loudness inside them, 0 outside
        (until 2026-11-29 the calls' 1.0: a data user's review found I(t) was then call activity, not intensity);
        without a truth, the loudness throughout.  The loudness: the ``rms`` channel, or 10^(intensity/20) from
        the ``intensity`` control in dB, normalised by its maximum.
        """
        n = max(1, int(round(SMOOTH_S * self.fps)))
        if self.truth is not None and self.truth.graded:
            return moving_average(self.truth.intensity(self.times), n)
        if "rms" in self.channels:
            x = self.channels["rms"].to_numpy()
        elif "intensity" in self.channels:
            x = 10 ** (self.channels["intensity"].to_numpy() / 20.0)
        else:
            raise KeyError("no graded ground truth and no rms or intensity channel to measure laughter intensity")
        if self.truth is not None:   # where the truth's calls are (their intensity blank or 0 too: a diff review)
            x = x * self.truth.in_calls(self.times)
        x = moving_average(x, n)
        return x / x.max() if x.max() > 0 else x

    def starts(self) -> pd.DataFrame:
        """Start events of laughter clips (the idle clip, which segment concatenation also
        plays pieces of during silence, is not a laughter clip)."""
        ev = self.events
        return ev[(ev.event == "start") & (ev["clip"] != IDLE)].reset_index(drop=True)

    def plays(self) -> pd.DataFrame:
        """One row per played clip: clip, energy, start, stop (s), speed, length (clip s), played fraction, reason."""
        import pandas as pd

        rows, open_ = [], {}
        end_of_run = self.duration_s
        for ev in self.events.itertuples(index=False):
            if ev.clip == IDLE:
                continue
            if ev.event == "start":
                open_[ev.clip] = ev
            elif ev.event == "stop" and ev.clip in open_:
                rows.append(_play(open_.pop(ev.clip), ev.time, ev.reason))
        for s in open_.values():
            rows.append(_play(s, end_of_run, "end"))
        cols = ["clip", "energy", "start", "stop", "speed", "length", "fraction", "reason"]
        return pd.DataFrame(rows, columns=cols).sort_values("start", kind="stable").reset_index(drop=True)


@lru_cache(maxsize=1)
def clip_durations() -> dict[str, float]:
    """Duration (s) of every clip of the bundled library."""
    from laughlab.motion.clips import ClipLibrary

    return {c.name: c.duration_s for c in ClipLibrary.load()}


def _clip_length(ev) -> float:
    """Clip time (s) a start event means to play: ``end - offset``, ``end`` defaulting to the clip's end."""
    end = getattr(ev, "end", float("nan"))
    if end is None or end == "" or (isinstance(end, float) and np.isnan(end)):
        end = clip_durations().get(ev.clip, float("nan"))
    return float(end) - float(getattr(ev, "offset", 0.0) or 0.0)


def _play(start, stop_time: float, reason: str) -> tuple:
    length = _clip_length(start)
    played = (stop_time - start.time) * start.speed
    frac = played / length if length > 0 else float("nan")
    return (start.clip, float(start.energy), float(start.time), float(stop_time), float(start.speed), length,
            min(frac, 1.0), reason)
