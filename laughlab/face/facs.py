"""Laughter as FACS action units, and their ARKit blendshape weights.

van Duijn (2014) drives one smile shape and notes as future work (6.1) that "the
different muscles that are used to obtain a smile do not necessarily move
synchronized and symmetric"; the face could be "improved by separately driving
each deformation that is caused by the contraction of a muscle ... using the
FACS of Ekman and Friesen".  This module holds what the ``facs`` face
(:mod:`laughlab_plugins.face_facs`) needs for that:

* :data:`ARKIT_BLENDSHAPES`: the 52 ARKit blendshape names (Apple,
  ``ARFaceAnchor.BlendShapeLocation``), spelled and ordered as Apple lists them;
* :data:`AU_TO_ARKIT`: the weight of each action unit on each ARKit shape
  (after Ozel's "ARKit to FACS" cheat sheet, melindaozel.com), and
  :class:`ArkitMap`, which applies it;
* :class:`Unit` / :class:`UnitParams`: one action unit driven by the laughter
  intensity, with its own threshold ramp and onset/offset rates (Eq. F1-F2);
* :class:`DelayLine` and :func:`draw_sides`: per-side gain and delay (small
  asymmetry and desynchronisation, Eq. F3);
* :class:`Blinker`: the thesis' blink rule (3.3.3): intervals ~ N(4 s, 2 s),
  a blink due while the eyes are closed or closing is skipped.

Duchenne laughter as action units
---------------------------------
==== ===================== ==========================================================
AU   name                  role in laughter
==== ===================== ==========================================================
6    cheek raiser          orbicularis oculi, pars lateralis: with AU12 the Duchenne
                           (felt) smile (Ekman, Davidson & Friesen 1990; thesis 3.3)
12   lip corner puller     zygomaticus major: the smile itself
25   lips part             the mouth opens more the more intense the laughter
26   jaw drop              (Ruch & Ekman 2001; thesis 3.3.2): lips part, then the
27   mouth stretch         jaw drops, then the mouth stretches wide open
43   eyes closed           eyes close in intense laughter (thesis 3.3.3)
45   blink                 blinks, N(4 s, 2 s) (thesis 3.3.3 after Doughty 2001)
4    brow lowerer          frowns appear when the laugh is very strong
                           (Ding et al. 2014, 1, after Niewiadomski & Pelachaud 2012)
1+2  inner/outer brow      from the head-and-eyebrow motion (``brow_raise``,
     raiser                :mod:`laughlab.concat.head_motion`)
==== ===================== ==========================================================

Intensity to action units
-------------------------
The laughter intensity ``i`` in [0, 1] is the motion control signal (MCS, as
the ``smile`` face uses), which rises and falls with every call, or, for the
units that should follow the laughter rather than each call (cheeks, lip
corners, eyes, brows), its envelope with instant attack and exponential
release (time constant ``release_s``)::

    env(t) = max(i(t), env(t - dt) exp(-dt / release_s))                    (F0)

Each unit's intensity gives it a target through a ramp between two
thresholds ``lo < hi``::

    target_u(i) = clip((i - lo_u) / (hi_u - lo_u), 0, 1)                      (F1)

so the units join in order of intensity (lips part at a whisper of laughter, the
jaw drops with more, the mouth stretches, eyes close and brows lower only when it
is strong).  AU43's target is ``max(clip eye key, target_43(i))``: the eyes
keyed per full-body clip (thesis 3.3.3) still close them.  Each unit then
follows its target with its own onset and offset rates (per second, the rise/fall
limit of thesis Eq. 3.2)::

    a_u(t) = rate_limit(target_u(t), a_u(t - dt), rise_u dt, fall_u dt)        (F2)

Left, right and desynchronisation
---------------------------------
Each unit acts on both sides of the face with a per-side gain ``g`` in
``[1 - asymmetry, 1]`` and delay ``d`` in ``[0, desync_s]``, drawn once per run
from the run's seeded generator::

    a_u,side(t) = g_u,side * a_u(t - d_u,side)                               (F3)

(delayed values are interpolated linearly between frames; before the first frame
the face is at rest, 0).  Spontaneous (felt) expressions are more symmetric
than posed ones (Ekman, Hager & Friesen 1981), so the defaults are small: gains
within 10 % and delays within 50 ms (our choice: below one blink's closing time,
80 ms, so the sides stay visibly one expression).  With the different onset and
offset rates of the units this gives the "not synchronized and not symmetric"
smile the thesis asks for (6.1).  Blinks (AU45) stay symmetric and synchronous, the eyes'
closure (AU43) keeps its delays but not its gains (a closed eye is closed on both sides), and
the midline shapes (``jawOpen``, ``browInnerUp``) take ``a_u(t)`` itself: a jaw has
no sides, and the mean of two delayed copies opened it a median 17 ms late.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from laughlab.face.blink import Blinker  # noqa: F401  (re-exported: the thesis blink rule)

from laughlab.core.plugins import check_range

__all__ = [
    "ARKIT_BLENDSHAPES",
    "SIDES",
    "ACTION_UNITS",
    "AU_NAMES",
    "AU_TO_ARKIT",
    "MAX_COMBINED",
    "ArkitMap",
    "UnitParams",
    "Unit",
    "UNIT_INPUTS",
    "Envelope",
    "DelayLine",
    "SideVariation",
    "draw_sides",
    "Blinker",
    "ramp",
]

ARKIT_BLENDSHAPES: tuple[str, ...] = (
    # left eye
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft", "eyeSquintLeft",
    "eyeWideLeft",
    # right eye
    "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight", "eyeSquintRight",
    "eyeWideRight",
    # mouth and jaw
    "jawForward", "jawLeft", "jawRight", "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft",
    "mouthRight", "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft",
    "mouthDimpleRight", "mouthStretchLeft", "mouthStretchRight", "mouthRollLower", "mouthRollUpper",
    "mouthShrugLower", "mouthShrugUpper", "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft",
    "mouthLowerDownRight", "mouthUpperUpLeft", "mouthUpperUpRight",
    # eyebrows, cheeks and nose
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight", "cheekPuff",
    "cheekSquintLeft", "cheekSquintRight", "noseSneerLeft", "noseSneerRight",
    # tongue
    "tongueOut",
)
"""The 52 ARKit blendshape names in Apple's order (``ARFaceAnchor.BlendShapeLocation``).

Values are in [0, 1] (0 neutral, 1 the full movement).  ``Left``/``Right`` are
the character's own left and right (its left is +X in :mod:`laughlab.motion.skeleton`)."""

SIDES: tuple[str, str] = ("Left", "Right")

ACTION_UNITS: tuple[str, ...] = ("au6", "au12", "au25", "au26", "au27", "au43", "au4")
"""The action units the ``facs`` face drives from the laughter intensity, in channel order."""

AU_NAMES: dict[str, str] = {
    "au1": "inner brow raiser", "au2": "outer brow raiser", "au4": "brow lowerer", "au6": "cheek raiser",
    "au12": "lip corner puller", "au25": "lips part", "au26": "jaw drop", "au27": "mouth stretch",
    "au43": "eyes closed", "au45": "blink",
}

AU_TO_ARKIT: dict[str, dict[str, float]] = {
    "au6": {"cheekSquint{side}": 1.0, "eyeSquint{side}": 0.4},
    "au12": {"mouthSmile{side}": 1.0},
    "au25": {"jawOpen": 0.1, "mouthLowerDown{side}": 0.4, "mouthUpperUp{side}": 0.3},
    "au26": {"jawOpen": 0.6},
    "au27": {"jawOpen": 0.3, "mouthStretch{side}": 0.4},
    "au43": {"eyeBlink{side}": 1.0},
    "au45": {"eyeBlink{side}": 1.0},
    "au4": {"browDown{side}": 1.0},
    "au1": {"browInnerUp": 1.0},
    "au2": {"browOuterUp{side}": 1.0},
}
"""Weight of each action unit on each ARKit shape; ``{side}`` is ``Left`` or ``Right``.

An ARKit value is ``clip(sum_u w_u a_u, 0, 1)`` over the units acting on it
(``a_u`` of that side; a name without ``{side}``, ``jawOpen`` and ``browInnerUp``, takes
the unit's activation before Eq. F3's per-side gain and delay when the caller gives it, else the mean of the
two sides), except the names in :data:`MAX_COMBINED`, which take the largest
``w_u a_u``.  Sources and choices (after Ozel's ARKit-to-FACS cheat sheet):

* AU6 -> ``cheekSquint`` (the cheek raiser itself) plus 0.4 ``eyeSquint``: the
  raised cheek narrows the eye from below (ARKit's eyeSquint is mainly AU7).
* AU12 -> ``mouthSmile``.
* AU25 -> ``mouthLowerDown`` 0.4 and ``mouthUpperUp`` 0.3 (the lips part and
  bare the teeth, as in laughter) and 0.1 ``jawOpen``.
* AU26 -> 0.6 ``jawOpen``; AU27 -> the remaining 0.3 ``jawOpen`` plus 0.4
  ``mouthStretch`` (the wide-open laughing mouth pulls the lips sideways;
  ARKit's mouthStretch is AU20, our approximation).  The ``jawOpen`` weights of
  AU25, 26 and 27 add up to 1: the full mouth opening opens the jaw fully.
* AU43, AU45 -> ``eyeBlink`` (both close the lids; combined by maximum).
* AU4 -> ``browDown``; AU1 -> ``browInnerUp``; AU2 -> ``browOuterUp``.
"""

MAX_COMBINED: frozenset[str] = frozenset({"eyeBlinkLeft", "eyeBlinkRight"})
"""ARKit names whose units combine by maximum (eye closure and blink close the same lid)."""


class ArkitMap:
    """Applies :data:`AU_TO_ARKIT` to per-side unit values.

    Parameters
    ----------
    units : sequence of str
        The units that will be given (keys of the table), in the order of the
        values passed to :meth:`__call__`.
    table : dict, optional
        Defaults to :data:`AU_TO_ARKIT`.

    Attributes
    ----------
    names : tuple of str
        The ARKit names these units reach, in :data:`ARKIT_BLENDSHAPES` order.
    """

    def __init__(self, units: Sequence[str], table: dict | None = None):
        table = AU_TO_ARKIT if table is None else table
        self.units = tuple(units)
        rules: dict[str, list] = {}
        for k, u in enumerate(self.units):
            for target, w in table[u].items():
                if "{side}" in target:
                    for s, side in enumerate(SIDES):
                        rules.setdefault(target.format(side=side), []).append((k, s, w))
                else:
                    rules.setdefault(target, []).append((k, -1, w))
        unknown = sorted(set(rules) - set(ARKIT_BLENDSHAPES))
        if unknown:
            raise ValueError(f"not an ARKit blendshape: {unknown[0]!r}")
        self.names = tuple(n for n in ARKIT_BLENDSHAPES if n in rules)
        self._rules = [(n, n in MAX_COMBINED, tuple(rules[n])) for n in self.names]

    def __call__(self, values: Sequence[tuple[float, float]],
                 centre: Sequence[float] | None = None) -> dict[str, float]:
        """ARKit weights from ``values[k] = (left, right)`` of unit ``k``; each in [0, 1].

        ``centre[k]``, if given, is unit ``k``'s own activation, which the names without a side take (a jaw has no
        sides: Eq. F3's two delayed copies averaged delayed ``jawOpen`` by a frame and smoothed it); without it,
        the mean of the two sides.
        """
        out = {}
        for name, use_max, rule in self._rules:
            acc = 0.0
            for k, s, w in rule:
                lr = values[k]
                v = w * (lr[s] if s >= 0 else 0.5 * (lr[0] + lr[1]) if centre is None else centre[k])
                acc = max(acc, v) if use_max else acc + v
            out[name] = 0.0 if acc < 0.0 else (1.0 if acc > 1.0 else acc)
        return out


def ramp(x: float, lo: float, hi: float) -> float:
    """Eq. F1: ``clip((x - lo) / (hi - lo), 0, 1)``."""
    if x <= lo:
        return 0.0
    if x >= hi:
        return 1.0
    return (x - lo) / (hi - lo)


UNIT_INPUTS: tuple[str, ...] = ("mcs", "envelope")
"""What drives a unit: the call-by-call ``mcs`` or its ``envelope`` (see :class:`Envelope`)."""


@dataclass
class UnitParams:
    """One action unit: intensity thresholds (Eq. F1) and onset/offset rates (Eq. F2).

    Attributes
    ----------
    lo, hi : float
        The unit starts at intensity ``lo`` and is full at ``hi`` (MCS units, 0..1).
    rise, fall : float
        Largest increase and decrease of the unit per second (1/s): the onset
        takes at least ``1 / rise`` s, the offset ``1 / fall`` s.
    input : str
        ``mcs``: the intensity is the motion control signal, which rises and
        falls with every call; ``envelope``: its envelope (:class:`Envelope`),
        the intensity of the laughter rather than of each call.
    """

    lo: float
    hi: float
    rise: float
    fall: float
    input: str = "mcs"

    def __post_init__(self) -> None:
        check_range("lo", self.lo, 0, 1)
        check_range("hi", self.hi, 0, 1)
        if not self.hi > self.lo:
            raise ValueError(f"hi must be > lo (got lo={self.lo}, hi={self.hi})")
        check_range("rise", self.rise, 0, lo_open=True)
        check_range("fall", self.fall, 0, lo_open=True)
        if self.input not in UNIT_INPUTS:
            raise ValueError(f"input must be mcs or envelope (got {self.input!r})")


class Envelope:
    """Envelope of the intensity: instant attack, exponential release (Eq. F0).

    ``env(t) = max(i(t), env(t - dt) exp(-dt / release_s))``: it holds the peaks
    of the calls across the gaps between them (calls come every ~0.2 s), so the
    units it drives follow the laughter, not each call.  The decay is exact for
    any frame period.
    """

    __slots__ = ("decay", "e")

    def __init__(self, release_s: float, dt: float):
        self.decay = math.exp(-dt / release_s) if release_s > 0 else 0.0
        self.e = 0.0

    def reset(self) -> None:
        self.e = 0.0

    def step(self, x: float) -> float:
        e = self.e * self.decay
        self.e = x if x > e else e
        return self.e


class Unit:
    """One action unit's activation ``a_u`` (Eqs. F1-F2)."""

    __slots__ = ("lo", "hi", "rise", "fall", "a")

    def __init__(self, params: UnitParams, dt: float):
        self.lo, self.hi = params.lo, params.hi
        self.rise, self.fall = params.rise * dt, params.fall * dt
        self.a = 0.0

    def reset(self) -> None:
        self.a = 0.0

    def target(self, intensity: float) -> float:
        """Eq. F1."""
        return ramp(intensity, self.lo, self.hi)

    def follow(self, target: float) -> float:
        """Eq. F2: one rate-limited step towards ``target``; returns ``a_u``."""
        a = self.a
        if target > a:
            a = min(target, a + self.rise)
        else:
            a = max(target, a - self.fall)
        self.a = a
        return a


class DelayLine:
    """The recent past of a signal, read at a delay with linear interpolation (Eq. F3).

    Parameters
    ----------
    max_delay_s : float
        Longest delay that will be read (s).
    dt : float
        Frame period (s).
    """

    __slots__ = ("dt", "buf", "n", "head")

    def __init__(self, max_delay_s: float, dt: float):
        self.dt = dt
        self.n = int(math.ceil(max_delay_s / dt)) + 2
        self.buf = [0.0] * self.n
        self.head = 0

    def reset(self) -> None:
        self.buf = [0.0] * self.n
        self.head = 0

    def push(self, v: float) -> None:
        """Append this frame's value."""
        self.head = (self.head + 1) % self.n
        self.buf[self.head] = v

    def get(self, delay_s: float) -> float:
        """The value ``delay_s`` seconds ago (0 before the first frame)."""
        f = delay_s / self.dt
        k = int(f)
        w = f - k
        a = self.buf[(self.head - k) % self.n]
        if w == 0.0:
            return a
        b = self.buf[(self.head - k - 1) % self.n]
        return a + w * (b - a)


@dataclass(frozen=True)
class SideVariation:
    """Per-side gain and delay of one unit (Eq. F3)."""

    gain: tuple[float, float]
    delay_s: tuple[float, float]


def draw_sides(rng: np.random.Generator, units: Sequence[str], asymmetry: float,
               desync_s: float) -> dict[str, SideVariation]:
    """Draw the gain in ``[1 - asymmetry, 1]`` and delay in ``[0, desync_s]`` of each unit and side.

    Draws ``4 * len(units)`` uniform numbers, unit by unit (left gain, right gain,
    left delay, right delay).
    """
    out = {}
    for u in units:
        g = rng.random(2)
        d = rng.random(2)
        out[u] = SideVariation((1.0 - asymmetry * float(g[0]), 1.0 - asymmetry * float(g[1])),
                               (desync_s * float(d[0]), desync_s * float(d[1])))
    return out
