"""Body driver ``hill``: a Hill-muscle torso with lungs (DiLorenzo, Zordan & Sanders 2008).

Per frame the driver chooses muscle-group activations (control), runs the
reduced-order torso of :mod:`laughlab.hill.torso` for the frame's substeps and turns
its state into

* ``frame.offsets``: spine flexion spread over ``spine``, ``spine1``,
  ``spine2`` (BVH ``x``, degrees, positive bends forward) and clavicle
  elevation (``left_clavicle`` ``z`` = +elevation, ``right_clavicle`` ``z`` =
  -elevation, which raises both shoulders), added to the clip pose;
* the channels ``chest`` and ``belly`` of the ``shapes`` driver (shape-key
  weights: 1 = the sculpted expanded shape, 0 = rest, outside [0, 1] =
  extrapolated): ``chest = chest_offset + chest_gain * x_rc / chest_expanded_cm``
  with ``x_rc`` the ribcage expansion, ``belly = belly_offset + belly_gain *
  x_ab / belly_expanded_cm`` with ``x_ab`` the area-weighted outward
  displacement of the five abdominal sections; negative while laughing, as
  the chest and belly are squeezed below rest;
* ``lung_pressure`` (cm H2O relative to the atmosphere), ``chest_volume``,
  ``lung_volume`` (L), ``airflow`` (L/s, expiratory positive) and the group
  activations ``act_abdomen``, ``act_diaphragm``, ``act_inner_ic``,
  ``act_outer_ic``.

Control (``control``)
---------------------
``track`` (real time, no fitting).  The target lung pressure is the extractor's
``control['pressure']`` (cm H2O; the ``pressure`` extractor), or, with an
extractor that has none, ``control['mcs'] * track.mcs_pressure_cmh2o``.  Per
frame, with ``e`` the target minus the torso's lung pressure at the end of the
previous frame (negative pressures count as 0: the recoil that breathes in
between calls and bouts is not the expiratory muscles' business)::

    a_abdomen = clip(target / track.full_cmh2o + kp e + ki I, 0, 1),   I = leaky sum of e dt

(the integral leaks with time constant ``leak_s`` and is frozen while the
activation saturates), then the paper's
laugh recipe (section 7) at that level, the outer intercostals left at 0 (our departure: docs/fidelity.md): inner intercostals ``ribcage_ratio * a_abdomen``
in phase with the abdomen, diaphragm tone ``diaphragm_tone`` (its "constant
activation throughout the laughter", load balancer) while laughing (gated by
``a_abdomen > gate``, ramped over ``tone_s``), clavicle elevators
``clavicle_ratio * a_abdomen`` and a spine flexion target ``spine_deg *
a_abdomen`` (the paper's exaggerated secondary motion).  What it uses, exactly:
the extractor's value of the current frame, and the torso's own state; the
look-behind is the extractor's (a 5 Hz low-pass, time constant 32 ms, for ``pressure``)
plus the integral term, far less than one call.  Between bouts the muscles
relax and the chest wall's recoil breathes in by itself.

``fit`` (default; the paper's per-call fit made causal, real time: docs/fidelity.md): per-call
fitted activations (:mod:`laughlab.hill.live`): each call plays the seven
parameters fitted to the last call that ended at least ``live.adopt_after_s``
(0.25 s) before it began, scaled to its own peak, and is fitted itself
(:mod:`laughlab.hill.fit`, section 6.2) when it ends, in the frame (files) or
in a background thread (live input, a ``Session``); the same bytes either way.  The target is the ``pressure`` control (or ``mcs`` times
``track.mcs_pressure_cmh2o``).

``preset``: plays the preset ``preset`` (:mod:`laughlab.hill.presets`) in a
loop, whatever the audio.  Programmatic: :meth:`HillBody.play` sets a
schedule of activations (e.g. fitted to the audio by :mod:`laughlab.hill.fit`)
that overrides ``control``.

The torso is advanced ``ceil(substep_hz / fps)`` equal substeps per frame
(240 Hz at 60 fps: 4 steps of 4.17 ms), each taking the frame's activation
(zero-order hold; a schedule is sampled at each substep's end).
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Body
from laughlab.hill.torso import GROUPS, IAB, ICL, IRC, ISP, Torso, TorsoParams
from laughlab.hill.live import LiveFitter, LiveParams
from laughlab.hill.presets import PRESETS
from laughlab.core.plugins import check_range

CONTROLS = ("fit", "track", "preset")
SPINE_JOINTS = ("spine", "spine1", "spine2")


@dataclass
class TrackParams:
    """Real-time control from the extractor's signals (``control=track``).

    Attributes
    ----------
    full_cmh2o : float
        Target lung pressure reached by abdominal activation 1 (cm H2O): the
        feed-forward term is ``target / full_cmh2o``.
    kp : float
        Proportional feedback on the pressure error (activation per cm H2O).
    ki : float
        Integral feedback (activation per cm H2O s).
    leak_s : float
        Time constant of the integral's leak (s): it forgets old errors, so an
        unreachable target (lungs near residual volume) cannot wind it up.
    ribcage_ratio : float
        Inner-intercostal activation per unit abdominal activation (the
        paper's laughs: 0.5 to 1.6 of the abdomen's level; ours 0.5, the deep laugh's).
    diaphragm_tone : float
        Diaphragm activation while laughing (the paper's laughs: 0.05).
    gate : float
        Abdominal activation above which the torso counts as laughing (for the tone).
    tone_s : float
        Time constant of the tone's rise and fall (s).
    clavicle_ratio : float
        Clavicle-elevator activation per unit abdominal activation.
    spine_deg : float
        Spine flexion target per unit abdominal activation (degrees).
    mcs_pressure_cmh2o : float
        Without a ``pressure`` control: target = MCS times this (cm H2O).
    """

    full_cmh2o: float = 4.0
    kp: float = 0.1
    ki: float = 5.0
    leak_s: float = 0.3
    ribcage_ratio: float = 0.5
    diaphragm_tone: float = 0.05
    gate: float = 0.05
    tone_s: float = 0.3
    clavicle_ratio: float = 1.0
    spine_deg: float = 30.0
    mcs_pressure_cmh2o: float = 0.2

    def __post_init__(self) -> None:
        check_range("full_cmh2o", self.full_cmh2o, 0, lo_open=True)
        check_range("leak_s", self.leak_s, 0, lo_open=True)
        for name in ("kp", "ki", "ribcage_ratio", "gate", "tone_s", "mcs_pressure_cmh2o"):
            check_range(name, getattr(self, name), 0)
        check_range("diaphragm_tone", self.diaphragm_tone, 0, 1)
        check_range("clavicle_ratio", self.clavicle_ratio, 0, 1)
        check_range("spine_deg", self.spine_deg, -90, 90)


@dataclass
class HillParams:
    """Parameters of the ``hill`` body driver.

    Attributes
    ----------
    control : str
        ``fit`` (per-call fitted activations, real time), ``track`` (a pressure controller) or ``preset``.
    preset : str
        Preset played by ``control=preset``: giggle, normal_laugh, deep_laugh, breath, cough, sneeze.
    substep_hz : float
        Largest rate of the torso's internal step (Hz); a frame takes ``ceil(substep_hz / fps)`` steps.
    chest_expanded_cm : float
        Ribcage expansion that the expanded chest shape (weight 1) shows (cm).
    belly_expanded_cm : float
        Outward abdominal wall displacement that the expanded belly shape shows (cm).
    chest_gain, belly_gain, chest_offset, belly_offset : float
        As the ``shapes`` driver: weight = offset + gain * displacement / expanded.
    spine_share, spine1_share, spine2_share : float
        Share of the spine flexion given to each joint (lumbar to thoracic; sum 1).
    track : TrackParams
        The pressure controller (``control=track``).
    live : LiveParams
        Live per-call fitting (``control=fit``, :class:`laughlab.hill.live.LiveParams`).
    torso : TorsoParams
        The torso, its muscles (the paper's table) and its lungs.
    """

    control: str = "fit"
    preset: str = "normal_laugh"
    substep_hz: float = 240.0
    chest_expanded_cm: float = 1.0
    belly_expanded_cm: float = 2.0
    chest_gain: float = 1.0
    belly_gain: float = 1.0
    chest_offset: float = 0.0
    belly_offset: float = 0.0
    spine_share: float = 0.4
    spine1_share: float = 0.3
    spine2_share: float = 0.3
    track: TrackParams = field(default_factory=TrackParams)
    live: LiveParams = field(default_factory=LiveParams)
    torso: TorsoParams = field(default_factory=TorsoParams)

    def __post_init__(self) -> None:
        if self.control not in CONTROLS:
            raise ValueError(f"control must be one of {', '.join(CONTROLS)} (got {self.control!r})")
        if self.preset not in PRESETS:
            raise ValueError(f"preset must be one of {', '.join(PRESETS)} (got {self.preset!r})")
        check_range("substep_hz", self.substep_hz, 10, 10000)
        check_range("chest_expanded_cm", self.chest_expanded_cm, 0, lo_open=True)
        check_range("belly_expanded_cm", self.belly_expanded_cm, 0, lo_open=True)
        for name in ("spine_share", "spine1_share", "spine2_share"):
            check_range(name, getattr(self, name), 0, 1)
        total = self.spine_share + self.spine1_share + self.spine2_share
        if abs(total - 1.0) > 1e-6:
            raise ValueError(f"spine_share + spine1_share + spine2_share must be 1 (got {total})")


def substeps(fps: float, substep_hz: float) -> int:
    """Torso steps per frame: ``ceil(substep_hz / fps)`` (equal steps of ``1 / (fps * n)`` s)."""
    return max(1, int(math.ceil(substep_hz / fps - 1e-9)))


def secondary(ab, track: TrackParams):
    """The recipe's other groups from the abdominal activation(s) ``ab``: inner intercostals,
    clavicle elevators (activations) and the spine target (rad)."""
    ab = np.asarray(ab, dtype=float)
    return track.ribcage_ratio * ab, track.clavicle_ratio * ab, np.radians(track.spine_deg) * ab


class HillBody(Body):
    """Hill-muscle torso with lungs driving the spine, the clavicles and the chest and belly shapes."""

    name = "hill"
    Params = HillParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p = self.params
        self.n_sub = substeps(self.ctx.fps, p.substep_hz)
        self.dt_sub = self.ctx.dt / self.n_sub
        self.torso = Torso(p.torso, batch=1)
        areas = np.array([s.area_l_per_m for s in p.torso.abdomen.sections()])
        self._belly_w = areas / areas.sum()
        self._shares = (p.spine_share, p.spine1_share, p.spine2_share)
        self._schedule = None
        self._act = np.zeros((1, len(GROUPS)))
        self._leak = math.exp(-self.ctx.dt / self.params.track.leak_s)
        self.live = LiveFitter(p.live, self.ctx.fps, p.torso, live=bool(getattr(self.ctx, "live", False))) \
            if p.control == "fit" else None
        self.reset()

    def play(self, schedule) -> None:
        """Drive the torso from ``schedule(times) -> (group activations (n, 6), spine target rad (n,))``
        instead of ``control`` (None returns to ``control``); times are each substep's end (s)."""
        self._schedule = schedule

    def reset(self) -> None:
        if not getattr(self, "_warm", False):
            # the first step loads the compiled torso (numba, about 0.4 s, 2 s with a cold cache): on a spare torso
            # when the plugin is made, not in frame 0 (a hitch that overflowed the microphone's buffer with
            # input.calibration_s=0; a Session, not live, took it in its first feed, a game's first frame: a frame
            # budget review, 2026-11-29); the same bytes, the spare torso being another
            Torso(self.params.torso, batch=1).step(np.zeros((1, len(GROUPS))), 0.0, self.dt_sub)
            self._warm = True
        self.torso.reset()
        if getattr(self, "live", None) is not None:
            self.live.reset()
        self.integral = 0.0
        self.tone = 0.0
        self.t = 0.0

    # -- control
    def _track(self, frame, dt: float):
        tp = self.params.track
        target = self._target(frame)
        err = target - max(0.0, float(self.torso.lung.gauge_cmh2o[0]))
        ff = target / tp.full_cmh2o + tp.kp * err
        integral = self.integral * self._leak + err * dt
        u = ff + tp.ki * integral
        if not ((u > 1.0 and err > 0.0) or (u < 0.0 and err < 0.0)):
            self.integral = integral                    # conditional integration (anti-windup)
        ab = min(1.0, max(0.0, ff + tp.ki * self.integral))
        laughing = 1.0 if ab > tp.gate else 0.0
        self.tone += (laughing - self.tone) * (1.0 - math.exp(-dt / tp.tone_s)) if tp.tone_s > 0 else \
            laughing - self.tone
        ii, cl, spine = secondary(ab, tp)
        act = np.array([[ab, tp.diaphragm_tone * self.tone, float(ii), 0.0, float(cl), 0.0]])
        return act, float(spine)

    def _target(self, frame) -> float:
        c = frame.control
        return float(c["pressure"]) if "pressure" in c else self.params.track.mcs_pressure_cmh2o * float(c.get("mcs", 0.0))

    def close(self) -> None:
        if self.live is not None:
            self.live.close()
            # live: frames held for a fit (the fit takes longer than adopt_after_s here); not from a Session or a
            # file, whose frames come faster than real time and so wait for fits that keep real time (a diff review:
            # the docs' own Session loop was told to raise adopt_after_s, which changes the output)
            if self.live.held and getattr(self.ctx, "live", False):
                print(f"laughlab: warning: body=hill held {self.live.held} frame(s) for a call's fit, up to "
                      f"{1000 * self.live.held_max_s:.0f} ms: this machine fits a call in more than body.live.adopt_after_s="
                      f"{self.live.p.adopt_after_s:g} s; raise it for a stream without stalls", file=sys.stderr)

    def metrics(self) -> dict:
        """``metrics.json``'s figures of the live fit (``control=fit``): the calls fitted and the quiet calls left
        unfitted (``fit.quiet_frac``; the counts were kept and said nowhere: a diff review)."""
        if self.live is None:
            return {}
        return {"hill_calls_fitted": int(self.live.fitted), "hill_calls_quiet": int(self.live.quiet)}

    def _preset(self, t_end: np.ndarray):
        pre = PRESETS[self.params.preset]
        local = np.mod(t_end, pre.duration_s)
        return pre.activations(local), pre.spine(local)

    def step(self, frame) -> None:
        dt, n, h = self.ctx.dt, self.n_sub, self.dt_sub
        torso = self.torso
        t0 = frame.time_s
        if self._schedule is None and self.live is not None:
            self.live.update(frame.index, self._target(frame), torso)
        if self._schedule is not None or self.params.control != "track":
            ends = t0 + h * np.arange(1, n + 1)
            if self._schedule is not None:
                acts, spine = self._schedule(ends)
            elif self.live is not None:
                acts, spine = self.live.schedule(ends)
            else:
                acts, spine = self._preset(ends)
            for i in range(n):
                torso.step(acts[i][None, :], spine[i], h)
            act = acts[-1][None, :]
        else:
            act, spine = self._track(frame, dt)
            for _ in range(n):
                torso.step(act, spine, h)
        self._write(frame, act[0])

    def _write(self, frame, act) -> None:
        p = self.params
        torso = self.torso
        q = torso.q[0]
        flex = math.degrees(q[ISP])
        for joint, share in zip(SPINE_JOINTS, self._shares):
            frame.offsets[joint] = (0.0, share * flex, 0.0)
        elev = math.degrees(q[ICL])
        frame.offsets["left_clavicle"] = (elev, 0.0, 0.0)
        frame.offsets["right_clavicle"] = (-elev, 0.0, 0.0)
        ch = frame.channels
        ch["chest"] = p.chest_offset + p.chest_gain * (100.0 * q[IRC]) / p.chest_expanded_cm
        ch["belly"] = p.belly_offset + p.belly_gain * (100.0 * float(q[IAB] @ self._belly_w)) / p.belly_expanded_cm
        ch["lung_pressure"] = float(torso.lung.gauge_cmh2o[0])
        ch["chest_volume"] = float(torso.v_cw[0])
        ch["lung_volume"] = float(torso.lung.v_lung[0])
        ch["airflow"] = float(torso.lung.q[0])
        ch["act_abdomen"] = float(act[0])
        ch["act_diaphragm"] = float(act[1])
        ch["act_inner_ic"] = float(act[2])
        ch["act_outer_ic"] = float(act[3])


@hookimpl
def register_bodies(register):
    register(HillBody)
