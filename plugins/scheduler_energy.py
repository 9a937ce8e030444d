"""Scheduler ``energy``: full-body clips chosen by laughing energy (van Duijn 2014, ch. 4, 5.4, 5.5).

Two readings of the energy update, chosen by ``consumption``:

``equation`` (default): Eq. 4.1, ``L_t = L_{t-1} + MCS(t) - e(a)/l(a)`` per
60 Hz tick, so a clip of length l and energy e uses up exactly e over its
length.  Here both terms are rates per second: L gains ``gain_per_s * MCS`` per
second (60, i.e. once per thesis tick) and a clip consumes
``e * speed / duration_s`` per second, so a clip played to its end has consumed
exactly e whatever its speed and the frame rate.  ``floor_zero`` keeps L >= 0
(a departure: listing 5.4 has no floor, and without one the fixed decrease
drives L ever lower in long silences, delaying the next bout).

``listing``: listings 5.4 and 5.5 as printed.  Line 9 of 5.4 adds
``motionSignal * dt`` and line 26 of 5.5 subtracts ``act.energy * dt``: with one
unit of dt for both, a clip consumes its energy e per unit of time in which MCS
= 1 adds 1, i.e. ``e * gain_per_s`` per second (with the default 60: e per
60 Hz tick, l times Eq. 4.1's rate).  The actions are shuffled every tick
(``random.shuffle``), the candidate test and the consumption of the active clip
happen in one loop in that order, a clip consumes nothing on its start frame,
and there is no floor (``floor_zero`` is ignored).  The listing compares with
``activeAnimation.energy``; we take it as 0 when no clip plays (the idle
animation), as the rest of the code the thesis leaves out must do for clips to
start at all.

Clip lengths (22 to 117 frames) are our reading: frames at 24 fps, Blender's
default scene rate at which the game engine played actions (0.9 s to 4.9 s);
the thesis states no rate.  The blend-in of 10 frames is 10/24 s.

The thesis gives no values for the fixed decrease, the cap, c and I.  c = 2 is
the thesis' own example.  The fixed decrease of 12 /s (0.2 per tick) was
chosen on the synthetic corpus (6 seeds x 60 s of mixed laughter), trading how
well the playing clip's energy follows the true intensity (Pearson r, 1 s
smoothing, 0.5 s lag) against how many bouts get a clip at all:
3 /s: r 0.19 and 11% of clip starts more than 1 s after a bout ended;
6 /s: r 0.26, 94% of bouts, 6%; 12 /s: r 0.39, 88%, 0.6%;
20 /s: r 0.66, but mild bouts get no clip at all.

With a detector that holds clips back (``detector=yamnet``: ``clip_gate``), L is fed by the
``mcs`` the detector passes on (``energy_drive``) and a clip may start only on frames where the
detector allows it (``clip_allowed``): the candidate test gains one condition, the update of L is
unchanged.  Without one (``detector=none``) both are the plain Eq. 4.1 / listing 5.4.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from laughlab import hookimpl
from laughlab.core.bases import Scheduler
from laughlab.core.frame import ClipEvent
from laughlab.core.plugins import check_range
from laughlab.detector.model import clip_allowed, energy_drive
from laughlab.signals.smoothing import THESIS_TICK_HZ


@dataclass
class EnergyParams:
    """Parameters of the ``energy`` scheduler (laughing-energy units as in Eq. 4.1).

    Attributes
    ----------
    gain_per_s : float
        Energy added per second at MCS = 1 (Eq. 4.1 adds MCS once per tick: 60 /s).
    decrease_per_s : float
        Fixed decrease of L per second (listing 5.4 line 3).
    max_energy : float
        Cap of L (listing 5.4 line 6); above the largest clip energy (40).
    overrule_c : float
        Constraint 2: a clip can overrule the active one only if e(a) > c * e(active).
    min_inactive_s : float
        Constraint 3: a clip must have been inactive for more than I seconds.
    speed_min, speed_max : float
        Playback speed drawn from U(speed_min, speed_max) (thesis: 0.9, 1.4).
    blend_in_s : float
        Linear pose blend at each start (thesis: 10 frames at 24 fps).
    floor_zero : bool
        Keep L >= 0 (``equation`` only): after the fixed decrease and again after
        the clips' consumption, so the recorded ``energy`` is never negative.
        Departure from listing 5.4: without it the fixed decrease drives L ever
        more negative during long silences, delaying the next bout.
    consumption : str
        ``equation`` (Eq. 4.1: a clip consumes e over its length) or ``listing``
        (listings 5.4/5.5 as printed: e per unit of dt, no floor); see the module.
    clips : list[str]
        Clips to choose from; empty means every non-looping clip of the library.
    """

    gain_per_s: float = THESIS_TICK_HZ
    decrease_per_s: float = 12.0
    max_energy: float = 60.0
    overrule_c: float = 2.0
    min_inactive_s: float = 2.0
    speed_min: float = 0.9
    speed_max: float = 1.4
    blend_in_s: float = 10.0 / 24.0
    floor_zero: bool = True
    consumption: str = "equation"
    clips: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        check_range("gain_per_s", self.gain_per_s, 0)
        check_range("decrease_per_s", self.decrease_per_s, 0)
        check_range("max_energy", self.max_energy, 0, lo_open=True)
        check_range("overrule_c", self.overrule_c, 0)
        check_range("min_inactive_s", self.min_inactive_s, 0)
        check_range("speed_min", self.speed_min, 0, lo_open=True)
        check_range("blend_in_s", self.blend_in_s, 0)
        if self.consumption not in ("equation", "listing"):
            raise ValueError(f"consumption must be equation or listing (got {self.consumption!r})")
        if self.speed_max < self.speed_min:
            raise ValueError(f"speed_max must be >= speed_min (got {self.speed_max} < {self.speed_min})")


class _Action:
    """Bookkeeping of one clip (the thesis' ``Action`` class, 5.5)."""

    __slots__ = ("name", "energy", "duration_s", "active", "inactive_s", "elapsed_s", "speed")

    def __init__(self, name: str, energy: float, duration_s: float):
        self.name, self.energy, self.duration_s = name, float(energy), float(duration_s)
        self.active = False
        self.inactive_s = float("inf")  # thesis: inactive_tics = 10000
        self.elapsed_s = 0.0
        self.speed = 1.0


class EnergyScheduler(Scheduler):
    """Laughing energy (Eq. 4.1) with constraints 1-3 and highest-energy choice (5.4, 5.5).

    Per frame (dt seconds), ``consumption=equation``:

    1. ``L -= decrease*dt``; ``L = max(L, 0)`` (``floor_zero``); ``L = min(L, L_max)``;
       ``L += gain * MCS * dt`` (listing 5.4 lines 3, 6, 9; the floor is ours);
    2. candidates: ``e(a) < L`` (1), ``e(a) > c * e(a_active)`` (2, e = 0 when no
       clip plays), ``i(a) > I`` (3), not active; the highest energy wins, ties
       broken uniformly at random (what the thesis' shuffle achieves);
    3. the active clip stops when played to its end, else consumes
       ``e * speed / duration * dt`` (Eq. 4.1 term e(a)/l(a) per tick);
    4. a chosen clip overrules the active one and starts with speed ~ U(0.9, 1.4);
       it consumes from its first frame, so a clip played to its end has used up
       exactly e (in listing 5.5 the start frame consumes nothing);
    5. ``L = max(L, 0)`` again (``floor_zero``), so the recorded energy is never negative.

    ``consumption=listing`` runs listings 5.4/5.5 line by line instead (see the
    module docstring): shuffle, one loop of candidate test then consumption of
    ``e * gain * dt``, start without consumption, no floor.

    Writes channels ``energy`` (L) and ``clip_energy`` (e of the playing clip, 0 if none).
    """

    name = "energy"
    Params = EnergyParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        lib = self.ctx.clips
        names = list(self.params.clips) or [c.name for c in lib if not c.loop]
        unknown = [n for n in names if n not in lib.names]
        if unknown:
            raise ValueError(f"unknown clip {unknown[0]!r}; choose from: {', '.join(lib.names)}")
        self._specs = [(lib[n].name, lib[n].energy, lib[n].duration_s) for n in names]
        self._listing = self.params.consumption == "listing"
        self.reset()

    def reset(self) -> None:
        self.actions = [_Action(*spec) for spec in self._specs]
        self.energy = 0.0
        self.active: _Action | None = None

    def _produce(self, mcs: float, dt: float, floor: bool) -> float:
        """Listing 5.4: fixed decrease, (our floor), cap, then MCS times the elapsed time."""
        p = self.params
        L = self.energy - p.decrease_per_s * dt
        if floor and L < 0.0:
            L = 0.0
        L = min(p.max_energy, L)
        return L + mcs * p.gain_per_s * dt

    def _finish_if_done(self, a: _Action, frame) -> bool:
        """Advance the active clip by one frame; stop it if played to its end (5.5: frame == length)."""
        a.elapsed_s += frame.dt
        if a.elapsed_s * a.speed < a.duration_s:
            return False
        a.active = False
        self.active = None
        frame.events.append(ClipEvent(frame.time_s, "stop", a.name, a.energy, a.speed, reason="finished"))
        return True

    def _start(self, chosen: _Action, frame) -> None:
        """Overrule the playing clip (if any) and start ``chosen`` at a speed ~ U(speed_min, speed_max)."""
        p = self.params
        if self.active is not None:
            old = self.active
            old.active = False
            frame.events.append(ClipEvent(frame.time_s, "stop", old.name, old.energy, old.speed,
                                          reason="overruled"))
        chosen.active = True
        chosen.elapsed_s = 0.0
        chosen.inactive_s = 0.0
        chosen.speed = float(self.ctx.rng.uniform(p.speed_min, p.speed_max))
        self.active = chosen
        frame.events.append(ClipEvent(frame.time_s, "start", chosen.name, chosen.energy,
                                      chosen.speed, blend_s=p.blend_in_s))

    def step(self, frame) -> None:
        L = self._step_listing(frame) if self._listing else self._step_equation(frame)
        self.energy = L
        frame.channels["energy"] = L
        frame.channels["clip_energy"] = self.active.energy if self.active is not None else 0.0

    def _step_equation(self, frame) -> float:
        p, dt = self.params, frame.dt
        L = self._produce(energy_drive(frame.control), dt, p.floor_zero)
        allowed = clip_allowed(frame.control)
        # the playing clip first: it consumes its tick, or ends on it (a fidelity review, 2026-11-29: constraint 2
        # read its energy from before the tick, so a clip ending on it still blocked that tick's candidates)
        consumed, was_active = 0.0, None
        for a in self.actions:
            if a.active:
                was_active = a
                if not self._finish_if_done(a, frame):
                    consumed = a.energy * a.speed / a.duration_s * dt
                    L -= consumed
                a.inactive_s = 0.0
        active = self.active
        limit = active.energy * p.overrule_c if active is not None else 0.0
        min_inactive = p.min_inactive_s
        best_e = -1.0
        best: list[_Action] = []
        for a in self.actions:
            if a is was_active:
                continue
            if allowed and L > a.energy and a.energy > limit and a.inactive_s > min_inactive:
                if a.energy > best_e:
                    best_e, best = a.energy, [a]
                elif a.energy == best_e:
                    best.append(a)
            a.inactive_s += dt
        if best:
            chosen = best[0] if len(best) == 1 else best[int(self.ctx.rng.integers(len(best)))]
            self._start(chosen, frame)
            # it plays from this frame, and the clip it overrules gives its tick back: Eq. 4.1 subtracts one clip's
            # e(a)/l(a) a step (both consumed on the overrule tick: 0.83 of a step where the equation has 0.92)
            L += consumed - chosen.energy * chosen.speed / chosen.duration_s * dt
        if p.floor_zero and L < 0.0:
            L = 0.0
        return L

    def _step_listing(self, frame) -> float:
        """Listings 5.4 and 5.5 line by line (one thesis tick per frame at 60 fps)."""
        p, dt = self.params, frame.dt
        L = self._produce(energy_drive(frame.control), dt, False)
        allowed = clip_allowed(frame.control)
        self.ctx.rng.shuffle(self.actions)          # random.shuffle(animationActions)
        best: _Action | None = None
        for a in self.actions:
            # activeAnimation.energy is read per action: a clip that finished earlier in this loop counts 0
            limit = self.active.energy * p.overrule_c if self.active is not None else 0.0
            if allowed and L > a.energy and not a.active and a.energy > limit and a.inactive_s > p.min_inactive_s:
                if best is None or a.energy > best.energy:
                    best = a
            if a.active:
                if not self._finish_if_done(a, frame):
                    L -= a.energy * p.gain_per_s * dt   # laughingEnergy -= act.energy * dt
                a.inactive_s = 0.0
            else:
                a.inactive_s += dt
        if best is not None:
            self._start(best, frame)
        return L


@hookimpl
def register_schedulers(register):
    register(EnergyScheduler)
