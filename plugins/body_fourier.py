"""Body driver ``fourier``: laughter as a blend of calm and intense Fourier motions (Unuma et al. 1995).

Two periodic motions of the upper body are fitted as rescaled Fourier
functional models (Eqs. 1 and 2, :mod:`laughlab.fourier.model`): a *calm* one
(default: the looping ``idle`` clip, calm breathing and weight shift) and an
*intense* one (default: the rhythmic part of the ``hands_on_belly`` laughing
clip, 4.5 Hz shoulder and torso shaking on a ~1.2 s forward-back rocking).
Every frame the driver plays Eq. 3 between them with ``s`` driven by the
smoothed motion control signal, extrapolating (``s > 1``) when the laughter
is strong, and writes the result as joint rotation offsets that the mixer
adds to whatever clip plays.

Departure (ours): the paper gives each motion one period ``T_Theta`` (2.2); a
laughing motion has two, the 4.5 Hz shake and the ~1.2 s rocking, in no
small whole ratio, so one period would need dozens of harmonics where the
paper uses "usually 3, and 7 at most".  Each motion is therefore band-split
into a *shake* layer (``shake_min_hz``-``shake_max_hz``) and a *sway* layer
(below ``sway_max_hz``), each fitted as its own rescaled Fourier model with
its own period (:class:`LaughMotion`), and Eq. 3 blends layer by layer (a
layer absent from one motion blends from zero amplitude).  Eq. 3's constant
terms are left out by default (``posture_gain`` 0: the offsets add to a clip
whose posture they would shift).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laughlab import hookimpl
from laughlab.fourier import blend as fb
from laughlab.fourier import model as fr
from laughlab.core.bases import Body
from laughlab.core.plugins import check_range
from laughlab.signals.smoothing import Smoother, SmootherParams

#: the joints the driver moves (their Z, X, Y Euler offsets, degrees)
JOINTS = ("spine", "spine1", "spine2", "neck", "head", "left_clavicle", "right_clavicle",
          "left_upper_arm", "right_upper_arm")
#: a layer whose band-limited motion never exceeds this RMS (deg, over all channels) is absent
MIN_LAYER_DEG = 0.05
#: the channel whose fundamental sets rescaled time 0 (``sin(t)``: shoulder rising), per layer
ALIGN = {"shake": "left_clavicle_Zrotation", "sway": "spine2_Xrotation"}
#: labels of the 27 offset values, ``<joint>_<axis>rotation`` in Z X Y order per joint
CHANNELS = tuple(f"{j}_{a}rotation" for j in JOINTS for a in "ZXY")
_CLAVICLE_Z = [3 * JOINTS.index(f"{side}_clavicle") for side in ("left", "right")]
_ARM_Z = [3 * JOINTS.index(f"{side}_upper_arm") for side in ("left", "right")]
_ARMS = slice(3 * JOINTS.index("left_upper_arm"), 3 * len(JOINTS))
#: periods a non-looping rhythmic segment must hold for its sway period to be estimated
MIN_SWAY_PERIODS = 1.5


@dataclass
class FourierParams:
    """Parameters of the ``fourier`` body driver.

    Attributes
    ----------
    smoother : SmootherParams
        Smoother (van Duijn 2014, 5.3; rates per second) applied to the MCS
        before it drives the blend: slower than the calls, so ``s`` follows
        the intensity of a bout rather than each "ha" (rise 3 /s, fall 1 /s,
        full scale at 0.8).
    gain, offset : float
        The blend parameter of Eq. 3 is ``s = offset + gain * S(MCS)``: 0 plays
        the calm motion, 1 the intense one; the default gain 1.25 extrapolates
        to ``s = 1.25`` at full intensity (exaggeration, Unuma et al. Fig. 3(d)).
    calm_clip, intense_clip : str
        Library clips the calm and intense motions are fitted from.
    calm_bvh, intense_bvh : str or None
        A BVH file to fit instead of the clip (it must have the driven joints
        by name; frame rate from its ``Frame Time``).  Its rhythmic part is
        found as for clips (see :func:`fit_motion`).
    calm_bvh_loop, intense_bvh_loop : bool
        The BVH file is one loop (as the library's ``idle``): its duration is
        the period of its slow layer.
    harmonics : int
        Harmonics per layer, 1 to 7 (Unuma et al. 2.3: "usually 3, and 7 at
        most"); capped by the Nyquist rate of the source data.
    shake_min_hz, shake_max_hz : float
        Band of the laughter shake (the call rate, ~4.5-5 Hz): the fast layer
        is band-passed to it and its period searched within it (Hz).
    sway_max_hz : float
        The slow layer (sway, rocking, breathing) is low-passed below this and
        its period searched above ``1 / sway_max_hz`` (Hz).
    shake_step, sway_step : float
        Unuma's *step* (3.1) of each layer: its Fourier amplitudes are scaled
        by it (1 = as fitted).
    speed : float
        Unuma's *speed* (3.1): rescaled time runs this many times faster (a
        time warp; 2 halves every period, 0 freezes the motion).
    posture_gain : float
        Weight of the change of mean pose ``s (B_m0 - A_m0)`` (Eq. 3's constant
        terms) in the offsets; 0 (default) leaves posture to the clips and
        only the oscillation is added.
    pulse_depth : float
        Share of the ``chest``/``belly`` channels that pulses with each shake
        cycle (0: they follow ``s`` alone, 1: they pulse fully), see
        :class:`FourierBody`.
    arm_step : float
        Extra *step* of the upper-arm channels (both layers).  The default
        intense clip holds the hands on the belly, so its arms counter its
        rocking; on freely hanging arms that reads as flapping, hence 0.3.
    arm_counter : float
        Share of each clavicle's Z offset that its upper arm turns back (0 to
        1).  1 (default): the shoulders rise and fall while the arms keep
        hanging (a shrug; exact, since both rotate about Z first in the ZXY
        order); 0: the arms swing out with the clavicles, as in the clips.
    shiver_deg : float
        Largest amplitude of randomised high-frequency terms (harmonics 8-15 of
        the sway, Unuma et al. 3.3) added to the intense motion, so shivering
        grows with ``s``; 0 (default) adds none.  Drawn from the run's seeded
        generator.
    """

    smoother: SmootherParams = field(default_factory=lambda: SmootherParams(3.0, 1.0, 0.0, 0.8))
    gain: float = 1.25
    offset: float = 0.0
    calm_clip: str = "idle"
    intense_clip: str = "hands_on_belly"
    calm_bvh: str | None = None
    intense_bvh: str | None = None
    calm_bvh_loop: bool = False
    intense_bvh_loop: bool = False
    harmonics: int = 3
    shake_min_hz: float = 3.0
    shake_max_hz: float = 7.0
    sway_max_hz: float = 2.0
    shake_step: float = 1.0
    sway_step: float = 0.5
    speed: float = 1.0
    posture_gain: float = 0.0
    pulse_depth: float = 0.5
    arm_step: float = 0.3
    arm_counter: float = 1.0
    shiver_deg: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.smoother, dict):
            self.smoother = SmootherParams(**self.smoother)
        check_range("gain", self.gain, -100, 100)
        check_range("offset", self.offset, -100, 100)
        check_range("harmonics", self.harmonics, 1, fr.MAX_HARMONICS)
        check_range("shake_min_hz", self.shake_min_hz, 0, lo_open=True)
        check_range("shake_max_hz", self.shake_max_hz, self.shake_min_hz, lo_open=True)
        check_range("sway_max_hz", self.sway_max_hz, 0, self.shake_min_hz, lo_open=True)
        check_range("shake_step", self.shake_step, 0, 100)
        check_range("sway_step", self.sway_step, 0, 100)
        check_range("speed", self.speed, 0, 100)
        check_range("posture_gain", self.posture_gain, -100, 100)
        check_range("pulse_depth", self.pulse_depth, 0, 1)
        check_range("arm_step", self.arm_step, 0, 100)
        check_range("arm_counter", self.arm_counter, 0, 1)
        check_range("shiver_deg", self.shiver_deg, 0, 90)
        for key in ("calm_bvh", "intense_bvh"):
            path = getattr(self, key)
            if path is not None and not Path(path).expanduser().is_file():
                raise ValueError(f"{key}: BVH file {path!r} not found")


# ----------------------------------------------------------------------------- fitting the motions
@dataclass(frozen=True)
class LaughMotion:
    """One motion as two rescaled Fourier models over the channels of :data:`JOINTS`.

    ``sway``: the slow layer (period ~1-4 s), ``shake``: the call-rate layer
    (period ~0.2 s); either may be None (absent from the data).
    """

    sway: fr.FourierModel | None
    shake: fr.FourierModel | None
    source: str


def _source_series(clip: str, bvh: str | None, bvh_loop: bool, library) -> tuple[np.ndarray, float, bool, str]:
    """The driven joints' angle series ``(F, 27)`` of a clip or BVH file, its frame time and loop flag."""
    if bvh is not None:
        from laughlab.io.bvh import read_bvh

        sk, motion, frame_time = read_bvh(Path(bvh).expanduser())
        missing = [j for j in JOINTS if j not in sk.names]
        if missing:
            raise ValueError(f"BVH file {bvh} lacks the joints {', '.join(missing)}")
        y, _ = fr.joint_channels(sk, motion, JOINTS)
        return y, float(frame_time), bool(bvh_loop), str(bvh)
    try:
        c = library[clip]
    except KeyError as exc:
        raise ValueError(exc.args[0]) from None
    y, _ = fr.joint_channels(library.skeleton, c.poses, JOINTS)
    return y, 1.0 / c.fps, bool(c.loop), f"clip {clip}"


def _filtered(y: np.ndarray, dt: float, lo: float | None, hi: float | None, loop: bool) -> np.ndarray:
    """Band-limit; a loop is filtered as three copies end to end so it wraps without edge effects."""
    if not loop:
        return fr.band_limit(y, dt, lo, hi)
    f = len(y)
    return fr.band_limit(np.concatenate([y, y, y]), dt, lo, hi)[f:2 * f]


def fit_motion(y: np.ndarray, dt: float, loop: bool, p: FourierParams, source: str = "") -> LaughMotion:
    """Fit the sway and shake layers of one motion (Eq. 1) from joint-angle samples ``y`` (deg).

    Shake: band-passed to ``[shake_min_hz, shake_max_hz]``; where it is
    present (RMS over channels above :data:`MIN_LAYER_DEG`) the longest stretch
    where its envelope exceeds half its peak is the *rhythmic part*, fitted
    with the period estimated in the band.  Sway: low-passed below
    ``sway_max_hz``; a loop is fitted with its own duration as the period, any
    other data on the rhythmic part (the whole data without a shake) with the
    period estimated between ``1 / sway_max_hz`` and the part's duration / 1.5.
    Harmonics are capped by the data's Nyquist rate.  Each layer is then
    synchronised (:func:`laughlab.fourier.model.align`) so its rescaled time 0 is
    where the reference channel (:data:`ALIGN`) rises through its mean.
    """
    labels = CHANNELS
    shake = sway = None
    hp = _filtered(y, dt, p.shake_min_hz, p.shake_max_hz, loop)
    seg = (0, len(y))
    if np.sqrt(np.sum(hp * hp, axis=1)).max() > MIN_LAYER_DEG:
        seg = fr.active_segment(hp, dt, 1.0 / p.shake_min_hz)
        n = min(p.harmonics, fr.max_harmonics_for(1.0 / p.shake_max_hz, dt))
        part = hp[seg[0]:seg[1]]
        if len(part) >= 2 * n + 2:
            shake = fr.align(fr.fit(part, dt, None, n, (1.0 / p.shake_max_hz, 1.0 / p.shake_min_hz), labels),
                             ALIGN["shake"])
        if not loop and seg[1] - seg[0] < 2 * n + 2:
            seg = (0, len(y))
    lp = _filtered(y, dt, None, p.sway_max_hz, loop)
    if np.sqrt(np.sum((lp - lp.mean(axis=0)) ** 2, axis=1)).max() > MIN_LAYER_DEG:
        if loop:
            period = len(y) * dt
            sway = fr.fit(lp, dt, period, min(p.harmonics, fr.max_harmonics_for(period, dt)), channels=labels)
        else:
            part = lp[seg[0]:seg[1]]
            lo, hi = 1.0 / p.sway_max_hz, len(part) * dt / MIN_SWAY_PERIODS
            if hi > lo and len(part) >= 2 * p.harmonics + 2:
                sway = fr.fit(part, dt, None, min(p.harmonics, fr.max_harmonics_for(lo, dt)), (lo, hi), labels)
        if sway is not None:
            sway = fr.align(sway, ALIGN["sway"])
    return LaughMotion(sway, shake, source)


@functools.lru_cache(maxsize=16)
def _motions(key: tuple, library) -> tuple[LaughMotion, LaughMotion]:
    p = FourierParams(**dict(key))
    out = []
    for clip, bvh, loop in ((p.calm_clip, p.calm_bvh, p.calm_bvh_loop),
                            (p.intense_clip, p.intense_bvh, p.intense_bvh_loop)):
        y, dt, loop, source = _source_series(clip, bvh, loop, library)
        out.append(fit_motion(y, dt, loop, p, source))
    return out[0], out[1]


#: the parameters the fitted motions depend on
_FIT_KEYS = ("calm_clip", "intense_clip", "calm_bvh", "intense_bvh", "calm_bvh_loop", "intense_bvh_loop",
             "harmonics", "shake_min_hz", "shake_max_hz", "sway_max_hz")


def laughter_motions(p: FourierParams, library) -> tuple[LaughMotion, LaughMotion]:
    """The calm and intense motions of parameters ``p`` (fitted once per parameter set and library)."""
    return _motions(tuple((k, getattr(p, k)) for k in _FIT_KEYS), library)


def _zero_like(m: fr.FourierModel) -> fr.FourierModel:
    """A motion that stands still, with ``m``'s period and phases (a layer absent from one motion)."""
    return fr.FourierModel(np.zeros(m.n_channels), np.zeros_like(m.amp), m.phase, m.period_s, 0.0, m.channels)


def layer_pairs(calm: LaughMotion, intense: LaughMotion) -> dict[str, tuple[fr.FourierModel, fr.FourierModel]]:
    """``{layer: (calm model, intense model)}`` for the layers present in either motion."""
    out = {}
    for layer in ("sway", "shake"):
        a, b = getattr(calm, layer), getattr(intense, layer)
        if a is None and b is None:
            continue
        out[layer] = (a if a is not None else _zero_like(b), b if b is not None else _zero_like(a))
    return out


# ----------------------------------------------------------------------------- the driver
class FourierBody(Body):
    """Laughter body motion by Unuma et al.'s Eq. 3 between a calm and an intense motion.

    Per frame (``dt = 1 / fps`` s):

    * ``s = offset + gain * S(MCS)`` with ``S`` the smoother (van Duijn 2014,
      5.3); ``s`` is written to the channel ``fourier_s``.
    * Each layer ``L`` (sway, shake) plays Eq. 3, ``Xi_m(s, t_L)``, without its
      constant terms (offsets are relative: 0 changes nothing), times its
      *step*; the layers are summed, plus ``posture_gain * s * (B_m0 - A_m0)``;
      the upper-arm channels are scaled by ``arm_step``, then each upper
      arm's Z offset loses ``arm_counter`` times its clavicle's (a shrug
      rather than a flap).  The result (degrees, Z X Y per joint) goes to
      ``frame.offsets`` for the spine, neck, head, clavicles and upper arms
      (added to any offsets already there); the mixer adds it to the playing
      clip's pose.
    * Rescaled times advance with real time, ``d t_L / d tau = 2 pi speed /
      T_L(s)`` with ``T_L(s) = T_A^(1-s) T_B^s`` (the blended period),
      integrated over each frame by the trapezoid rule
      (:meth:`laughlab.fourier.blend.Transition.move`), so the motion does not
      depend on the frame rate.
    * ``chest`` and ``belly`` (the shape weights of the ``shapes`` driver, so
      drivers are interchangeable): each shake cycle is one laughter call, an
      exhalation pulse ``pulse = (1 + sin t_shake) / 2``, largest when the
      shoulders are highest (the shake is synchronised so the left clavicle
      goes ``sin t``).  ``exhale = s ((1 - d) + d pulse)`` with ``d =
      pulse_depth``; ``belly = exhale`` and ``chest = 1 - exhale``: at rest
      (``s = 0``) chest 1 and belly 0 as with ``shapes``; intense laughter
      squeezes the chest and pumps the belly at the call rate; ``s > 1``
      extrapolates the shapes as ``shapes`` does with gains above 1.
    """

    name = "fourier"
    Params = FourierParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p = self.params
        self.dt = self.ctx.dt
        self.smoother = Smoother(p.smoother, self.dt)
        calm, intense = laughter_motions(p, self.ctx.clips)
        if p.shiver_deg > 0:
            layer = "sway" if intense.sway is not None else "shake"
            model = getattr(intense, layer) or getattr(calm, layer)
            shivered = fb.shiver(model, self.ctx.rng, p.shiver_deg, first=fr.MAX_HARMONICS + 1)
            intense = LaughMotion(**{**intense.__dict__, layer: shivered})
        self.calm, self.intense = calm, intense
        pairs = layer_pairs(calm, intense)
        if not pairs:
            raise ValueError(f"neither {calm.source} nor {intense.source} moves the driven joints")
        self.layers = {k: fb.Transition(a, b, p.speed) for k, (a, b) in pairs.items()}
        self._steps = [(self.layers[k], p.shake_step if k == "shake" else p.sway_step) for k in self.layers]
        self._pulse = self.layers.get("shake") or self.layers["sway"]
        self._posture = p.posture_gain * sum(t.mean_change for t in self.layers.values())
        self.s = 0.0

    def reset(self) -> None:
        self.smoother.reset()
        for t in self.layers.values():
            t.reset()
        self.s = 0.0

    def offsets(self, s: float, theta: dict | None = None) -> np.ndarray:
        """The joint offsets (27 values, deg, Z X Y per joint of :data:`JOINTS`) at blend ``s``.

        At the layers' current rescaled times, or at ``theta`` ``{layer: radians}``.
        """
        out = self._posture * s
        for name, (tr, step) in zip(self.layers, self._steps):
            out = out + step * tr.value(s, None if theta is None else theta[name], mean=False)
        out[_ARMS] *= self.params.arm_step
        out[_ARM_Z] -= self.params.arm_counter * out[_CLAVICLE_Z]
        return out

    def _advance(self, s: float) -> tuple[list, float, float]:
        """Move every layer one frame on (to blend ``s``); return the offsets (27 floats), chest and belly."""
        for tr in self.layers.values():
            tr.move(s, self.dt)
        v = self.offsets(s).tolist()
        pulse = 0.5 * (1.0 + math.sin(self._pulse.theta))
        exhale = s * (1.0 - self.params.pulse_depth + self.params.pulse_depth * pulse)
        return v, 1.0 - exhale, exhale

    def step(self, frame) -> None:
        p = self.params
        s = float(p.offset + p.gain * self.smoother.smooth(frame.control["mcs"]))
        self.s = s
        v, chest, belly = self._advance(s)
        offs = frame.offsets
        for k, joint in enumerate(JOINTS):
            z, x, y = v[3 * k], v[3 * k + 1], v[3 * k + 2]
            if joint in offs:
                oz, ox, oy = offs[joint]
                z, x, y = z + oz, x + ox, y + oy
            offs[joint] = (z, x, y)
        frame.channels["fourier_s"] = s
        frame.channels["chest"] = chest
        frame.channels["belly"] = belly

    def play(self, s) -> dict:
        """Play a prescribed blend ``s`` (one value per frame, any range) from the current state.

        What :meth:`step` does without the smoother: returns ``offsets`` (F, 27)
        degrees (columns ``channels``), ``chest`` and ``belly`` (F,).
        """
        rows, chest, belly = [], [], []
        for v in np.asarray(s, dtype=np.float64).ravel().tolist():
            o, c, b = self._advance(v)
            rows.append(o)
            chest.append(c)
            belly.append(b)
        return {"offsets": np.array(rows).reshape(-1, 3 * len(JOINTS)), "chest": np.array(chest),
                "belly": np.array(belly), "channels": CHANNELS}


@hookimpl
def register_bodies(register):
    register(FourierBody)
