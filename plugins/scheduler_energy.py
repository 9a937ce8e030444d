"""Scheduler ``energy``: full-body clips chosen by laughing energy (van Duijn 2014, ch. 4, 5.4, 5.5).

Units.  The thesis adds MCS to the laughing energy L once per 60 Hz tick
(Eq. 4.1) and an active clip consumes e(a)/l(a) per tick, so a clip uses up its
whole energy e over its length l.  Here both are rates per second: L gains
``gain_per_s * MCS`` per second (60, i.e. once per thesis tick) and a clip
consumes ``e * speed / duration_s`` per second, so a clip played to its end has
consumed exactly e whatever its speed and the frame rate.  Clip lengths (22 to
117 frames) are frames at 24 fps, Blender's scene rate at which the game engine
played actions (0.9 s to 4.9 s); the blend-in of 10 frames is 10/24 s.

The thesis gives no values for the fixed decrease, the cap, c and I.  c = 2 is
the thesis' own example.  The fixed decrease of 12 /s (0.2 per tick) was
chosen on the synthetic corpus (6 seeds x 60 s of mixed laughter), trading how
well the playing clip's energy follows the true intensity (Pearson r, 1 s
smoothing, 0.5 s lag) against how many bouts get a clip at all:
3 /s: r 0.19 and 11% of clip starts more than 1 s after a bout ended;
6 /s: r 0.26, 94% of bouts, 6%; 12 /s: r 0.39, 88%, 0.6%;
20 /s: r 0.66, but mild bouts get no clip at all.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from laughlab import hookimpl
from laughlab.core.bases import Scheduler
from laughlab.core.frame import ClipEvent
from laughlab.core.plugins import check_range
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
        Keep L >= 0.  Departure from listing 5.4: without it the fixed decrease
        drives L ever more negative during long silences, delaying the next bout.
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
    clips: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        check_range("gain_per_s", self.gain_per_s, 0)
        check_range("decrease_per_s", self.decrease_per_s, 0)
        check_range("max_energy", self.max_energy, 0, lo_open=True)
        check_range("overrule_c", self.overrule_c, 0)
        check_range("min_inactive_s", self.min_inactive_s, 0)
        check_range("speed_min", self.speed_min, 0, lo_open=True)
        check_range("blend_in_s", self.blend_in_s, 0)
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

    Per frame (dt seconds):

    1. ``L -= decrease*dt``; ``L = min(L, L_max)``; ``L += gain * MCS * dt`` (listing 5.4);
    2. candidates: ``e(a) < L`` (1), ``e(a) > c * e(a_active)`` (2, e = 0 when no
       clip plays), ``i(a) > I`` (3), not active; the highest energy wins, ties
       broken uniformly at random (what the thesis' shuffle achieves);
    3. the active clip stops when played to its end, else consumes
       ``e * speed / duration * dt`` (Eq. 4.1 term e(a)/l(a));
    4. a chosen clip overrules the active one and starts with speed ~ U(0.9, 1.4);
       it consumes from its first frame, so a clip played to its end has used up
       exactly e (in listing 5.5 the start frame consumes nothing, a 1/l error).

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
        self.reset()

    def reset(self) -> None:
        self.actions = [_Action(*spec) for spec in self._specs]
        self.energy = 0.0
        self.active: _Action | None = None

    def step(self, frame) -> None:
        p, dt = self.params, frame.dt
        L = self.energy - p.decrease_per_s * dt
        if p.floor_zero and L < 0.0:
            L = 0.0
        L = min(p.max_energy, L)
        L += frame.control["mcs"] * p.gain_per_s * dt
        active = self.active
        limit = active.energy * p.overrule_c if active is not None else 0.0
        min_inactive = p.min_inactive_s
        best_e = -1.0
        best: list[_Action] = []
        for a in self.actions:
            if a.active:
                a.elapsed_s += dt
                if a.elapsed_s * a.speed >= a.duration_s:
                    a.active = False
                    self.active = None
                    frame.events.append(ClipEvent(frame.time_s, "stop", a.name, a.energy, a.speed,
                                                  reason="finished"))
                else:
                    L -= a.energy * a.speed / a.duration_s * dt
                a.inactive_s = 0.0
                continue
            if L > a.energy and a.energy > limit and a.inactive_s > min_inactive:
                if a.energy > best_e:
                    best_e, best = a.energy, [a]
                elif a.energy == best_e:
                    best.append(a)
            a.inactive_s += dt
        if best:
            rng = self.ctx.rng
            chosen = best[0] if len(best) == 1 else best[int(rng.integers(len(best)))]
            if self.active is not None:
                old = self.active
                old.active = False
                frame.events.append(ClipEvent(frame.time_s, "stop", old.name, old.energy, old.speed,
                                              reason="overruled"))
            chosen.active = True
            chosen.elapsed_s = 0.0
            chosen.inactive_s = 0.0
            chosen.speed = float(rng.uniform(p.speed_min, p.speed_max))
            L -= chosen.energy * chosen.speed / chosen.duration_s * dt  # it plays from this frame
            self.active = chosen
            frame.events.append(ClipEvent(frame.time_s, "start", chosen.name, chosen.energy,
                                          chosen.speed, blend_s=p.blend_in_s))
        self.energy = L
        frame.channels["energy"] = L
        frame.channels["clip_energy"] = self.active.energy if self.active is not None else 0.0


@hookimpl
def register_schedulers(register):
    register(EnergyScheduler)
