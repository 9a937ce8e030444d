"""Top-level input signals and the activation presets of DiLorenzo, Zordan & Sanders (2008).

The highest level of the three-tier controller (section 5.2): smooth
time-varying input signals, chosen by "period, offset, and amplitude", one per
muscle group; the mid level (:func:`laughlab.hill.torso.group_matrix`) splits the
abdominal activation over its five sections; the lowest level is the Hill
muscles (:mod:`laughlab.hill.torso`).

A :class:`Signal` is one shape active on ``[start, start + duration)``::

    sine     offset + amplitude * sin(2 pi ((t - start) / period + phase))
    bump     offset + amplitude * (1 - cos(2 pi ((t - start) / period + phase))) / 2
    hold     offset + amplitude * ramp-up (ramp s), plateau (hold s), ramp-down (ramp s)
    constant offset + amplitude

Signals of one group are summed and the sum is kept in [0, 1] (an activation);
so a ``sine`` of offset 0 is a train of half-wave pulses.  ``growth`` makes the
cycles of a periodic signal grow: cycle ``k`` of ``n`` has amplitude
``amplitude * (1 - growth * (1 - k / (n - 1)))``.  The spine signals are a
flexion target in degrees (positive = forward), fed to the spine's PD servo
(section 5.3).

Presets (section 7, activation table; "intercostals" is the inner intercostals
in phase with the abdomen and the outer intercostals out of phase, as the text
says, except where the table says "outer only" / "inner only")::

                     diaphragm  abdomen  intercostals
    giggle             0.05      0.125      0.2
    normal laugh       0.05      0.5        0.5
    deep laugh         0.05      1.0        0.5
    breath             0.1       -          0.3
    cough              0.05      1.0        1.0
    sneeze: ah-        0.1       0          0.2 (outer only)
    sneeze: -choo      0.0       1.0        0.8 (inner only)

Laughs: the abdomen is "a sine wave with a frequency of 5 Hz" (a ``bump``: a
full sine between 0 and the table's level, so the activation never goes
negative and stays a pure 5 Hz wave, on a tonic 25 % of the level, ours:
without it the chest wall springs back between calls and the volume does not
fall over the bout); the diaphragm
"a constant activation throughout the laughter"; spine flexion and clavicle
elevation are the paper's exaggerated secondary motion (their amplitudes are
ours).  Breath: the abdomen is passive; the diaphragm and outer intercostals
drive inspiration, the inner intercostals expiration (period 4 s, ours).
Cough: "the abdomen ... quickly activates, holds the contraction for 250 ms
and quickly releases", a smooth wave for the inner intercostals on the
exhale and for the outer intercostals on the inhales between coughs.  Sneeze:
"short quick inhales that increase in intensity" (three, ours), then "a single
severe, extended exhale".  Timings not in the paper are ours.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from laughlab.hill.torso import GROUPS

SHAPES = ("sine", "bump", "hold", "constant")


@dataclass(frozen=True)
class Signal:
    """One input signal (see the module notes for the shapes).

    Attributes
    ----------
    shape : str
        ``sine``, ``bump``, ``hold`` or ``constant``.
    amplitude, offset : float
        Activation units (degrees for the spine).
    period : float
        Period of ``sine`` and ``bump`` (s).
    start : float
        Time the signal starts (s).
    duration : float
        How long it lasts (s); ``inf`` = until the end.
    phase : float
        Phase of a periodic shape, in periods (0.5 = out of phase).
    growth : float
        Growth of the cycles' amplitude in [0, 1] (0 = all equal).
    hold, ramp : float
        Plateau and ramp times of ``hold`` (s).
    """

    shape: str = "sine"
    amplitude: float = 0.0
    offset: float = 0.0
    period: float = 0.2
    start: float = 0.0
    duration: float = math.inf
    phase: float = 0.0
    growth: float = 0.0
    hold: float = 0.25
    ramp: float = 0.03

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"shape must be one of {', '.join(SHAPES)} (got {self.shape!r})")
        if not self.period > 0 or not self.duration >= 0 or not self.ramp >= 0 or not self.hold >= 0:
            raise ValueError("period must be > 0 and duration, hold, ramp >= 0")
        if not 0 <= self.growth <= 1:
            raise ValueError(f"growth must be in [0, 1] (got {self.growth})")

    def __call__(self, t) -> np.ndarray:
        """Value at times ``t`` (s), 0 outside ``[start, start + duration)``."""
        t = np.asarray(t, dtype=float)
        u = t - self.start
        if self.shape == "hold":
            end = min(self.duration, 2 * self.ramp + self.hold)
            r = max(self.ramp, 1e-9)
            up = 0.5 - 0.5 * np.cos(np.pi * np.clip(u / r, 0.0, 1.0))
            down = 0.5 - 0.5 * np.cos(np.pi * np.clip((end - u) / r, 0.0, 1.0))
            val = self.offset + self.amplitude * np.minimum(up, down)
        else:
            end = self.duration
            x = u / self.period + self.phase
            if self.shape == "sine":
                wave = np.sin(2.0 * np.pi * x)
            elif self.shape == "bump":
                wave = 0.5 - 0.5 * np.cos(2.0 * np.pi * x)
            else:
                wave = np.ones_like(u)
            amp = self.amplitude
            if self.growth and self.shape != "constant" and math.isfinite(end):
                n = max(1, int(math.ceil(end / self.period - 1e-9)))
                k = np.clip(np.floor(u / self.period), 0, n - 1)
                amp = amp * (1.0 - self.growth * (1.0 - k / max(n - 1, 1)))
            val = self.offset + amp * wave
        return np.where((u >= 0.0) & (u < end), val, 0.0)


@dataclass(frozen=True)
class Preset:
    """A hand-crafted behaviour: input signals per muscle group and for the spine.

    Attributes
    ----------
    name : str
    duration_s : float
        Length of the behaviour (s), relaxation included.
    signals : dict[str, tuple[Signal, ...]]
        Group name (``laughlab.hill.torso.GROUPS``) -> its signals (summed, kept in [0, 1]).
    spine_deg : tuple[Signal, ...]
        Spine flexion target (degrees, forward positive).
    pattern : str
        The characteristic pressure / volume pattern it produces (tested).
    """

    name: str
    duration_s: float
    signals: dict = field(default_factory=dict)
    spine_deg: tuple = ()
    pattern: str = ""

    def activations(self, times) -> np.ndarray:
        """Group activations ``(len(times), 6)`` in ``GROUPS`` order, each in [0, 1]."""
        t = np.asarray(times, dtype=float)
        out = np.zeros((t.size, len(GROUPS)))
        for g, sigs in self.signals.items():
            col = GROUPS.index(g)
            for s in sigs:
                out[:, col] += s(t)
        return np.clip(out, 0.0, 1.0)

    def spine(self, times) -> np.ndarray:
        """Spine flexion target (rad) at ``times``."""
        t = np.asarray(times, dtype=float)
        deg = np.zeros(t.size)
        for s in self.spine_deg:
            deg += s(t)
        return np.radians(deg)


#: tonic share of the expiratory drive in the laughs (ours): the abdomen and inner intercostals
#: oscillate between 25 % and 100 % of the table's level, so lung volume drops over the bout
TONIC = 0.25


def _laugh(name: str, diaphragm: float, abdomen: float, intercostals: float, clavicle: float,
           spine_offset: float, spine_amp: float, calls: int, pattern: str) -> Preset:
    start, period = 0.2, 0.2          # 5 Hz (section 7)
    dur = calls * period
    sine = dict(shape="bump", period=period, start=start, duration=dur)
    return Preset(
        name, start + dur + 1.0,
        {"diaphragm": (Signal("constant", diaphragm, start=start, duration=dur),),
         "abdomen": (Signal(amplitude=(1 - TONIC) * abdomen, offset=TONIC * abdomen, **sine),),
         "inner_intercostals": (Signal(amplitude=(1 - TONIC) * intercostals, offset=TONIC * intercostals, **sine),),
         "outer_intercostals": (Signal(amplitude=intercostals, phase=0.5, **sine),),
         "clavicle_up": (Signal(amplitude=clavicle, **sine),)},
        (Signal("hold", spine_offset, start=start - 0.1, hold=dur, ramp=0.3),
         Signal(amplitude=spine_amp, **sine)),
        pattern)


PRESETS: dict[str, Preset] = {
    "giggle": _laugh("giggle", 0.05, 0.125, 0.2, 0.2, 2.0, 1.0, 8,
                     "small lung-pressure pulses at 5 Hz, one per call; the smallest laugh"),
    "normal_laugh": _laugh("normal_laugh", 0.05, 0.5, 0.5, 0.4, 5.0, 2.0, 10,
                           "pressure pulses at 5 Hz, higher than the giggle's; lung volume falls over the bout"),
    "deep_laugh": _laugh("deep_laugh", 0.05, 1.0, 0.5, 0.6, 9.0, 4.0, 12,
                         "the highest laugh pulses at 5 Hz; the largest fall of lung volume"),
    "breath": Preset(
        "breath", 8.5,
        {"diaphragm": (Signal(amplitude=0.1, period=4.0, start=0.25, duration=8.0),),
         "outer_intercostals": (Signal(amplitude=0.3, period=4.0, start=0.25, duration=8.0),),
         "inner_intercostals": (Signal(amplitude=0.3, period=4.0, start=0.25, duration=8.0, phase=0.5),)},
        (), "two slow breaths: lung volume rises then falls by a tidal volume; small pressures, "
            "negative on inspiration, positive on expiration"),
    "cough": Preset(
        "cough", 3.0,
        {"diaphragm": (Signal("constant", 0.05, start=0.1, duration=2.4),),
         "outer_intercostals": (Signal("bump", 1.0, period=0.5, start=0.1, duration=0.5),
                                Signal("bump", 1.0, period=0.5, start=1.1, duration=0.5)),
         "abdomen": (Signal("hold", 1.0, start=0.7, hold=0.25, ramp=0.03),
                     Signal("hold", 1.0, start=1.7, hold=0.25, ramp=0.03)),
         "inner_intercostals": (Signal("bump", 1.0, period=0.35, start=0.7, duration=0.35),
                                Signal("bump", 1.0, period=0.35, start=1.7, duration=0.35))},
        (Signal("hold", 6.0, start=0.7, hold=0.25, ramp=0.05), Signal("hold", 6.0, start=1.7, hold=0.25, ramp=0.05)),
        "two coughs: an inhale (negative pressure) then one high pressure peak held about 250 ms"),
    "sneeze": Preset(
        "sneeze", 3.0,
        {"diaphragm": (Signal("bump", 0.1, period=0.3, start=0.2, duration=0.9, growth=2 / 3),),
         "outer_intercostals": (Signal("bump", 0.2, period=0.3, start=0.2, duration=0.9, growth=2 / 3),),
         "abdomen": (Signal("hold", 1.0, start=1.25, hold=0.4, ramp=0.05),),
         "inner_intercostals": (Signal("hold", 0.8, start=1.25, hold=0.4, ramp=0.05),)},
        (Signal("hold", 12.0, start=1.25, hold=0.4, ramp=0.08),),
        "ah-: three quick inhales growing in depth (lung volume steps up); "
        "-choo: one severe extended exhale, the highest pressure and a large volume drop"),
}


def preset(name: str) -> Preset:
    """The preset ``name`` (``giggle``, ``normal_laugh``, ``deep_laugh``, ``breath``, ``cough``, ``sneeze``)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of: {', '.join(PRESETS)}") from None


def run_preset(name: str, params=None, hz: float = 240.0, record=("p_lung", "v_lung", "v_cw", "q", "flow")) -> dict:
    """Simulate a preset on one torso; return ``t`` (s) and the recorded signals (see :func:`laughlab.hill.torso.simulate`)."""
    from laughlab.hill.torso import Torso, simulate

    pre = preset(name)
    n = int(round(pre.duration_s * hz))
    t = (np.arange(n) + 1) / hz            # each step takes its inputs at its end (backward Euler)
    torso = Torso(params)
    out = simulate(torso, pre.activations(t), pre.spine(t), dt=1.0 / hz, record=record)
    out = {k: v[:, 0] for k, v in out.items()}
    out["t"] = t
    out["act"] = pre.activations(t)
    return out
