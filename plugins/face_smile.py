"""Face ``smile``: one smile shape, the jaw, and the eyes (van Duijn 2014, 3.3 and 5.3)."""
from __future__ import annotations

from dataclasses import dataclass, field

from laughlab import hookimpl
from laughlab.core.bases import Face
from laughlab.face.blink import Blinker
from laughlab.face.provisional import Retraction
from laughlab.core.plugins import check_range
from laughlab.signals.smoothing import JAW, SMILE, Smoother, SmootherParams


@dataclass
class SmileParams:
    """Parameters of the ``smile`` face.

    Attributes
    ----------
    smile, jaw : SmootherParams
        Thesis 5.3: smile rise 0.03, fall 0.001, maxE 0.3; jaw rise 0.03,
        fall 0.01, maxE 0.8 (per tick, x 60 /s).
    blink_mean_s, blink_sd_s : float
        Blink interval ~ N(4 s, 2 s) (thesis 3.3.3, after Doughty [43]).
    blink_min_interval_s : float
        Shortest interval; draws below it (the normal can go negative) are raised to it.
    blink_close_s, blink_open_s : float
        Duration of the closing and the opening half of a blink (s).
    retract_s : float or None
        With ``detector=yamnet``: how long the smile and the jaw take to come back to where they were when the
        model takes back the face's provisional answer to a new sound (``laughlab.face.provisional``; s); None
        keeps what the answer built (the smile then lingers 5 s after each phrase of talk).  Not in the thesis,
        which has no detector; without one it does nothing.
    """

    smile: SmootherParams = field(default_factory=lambda: SmootherParams(**vars(SMILE)))
    jaw: SmootherParams = field(default_factory=lambda: SmootherParams(**vars(JAW)))
    blink_mean_s: float = 4.0
    blink_sd_s: float = 2.0
    blink_min_interval_s: float = 0.5
    blink_close_s: float = 0.08
    blink_open_s: float = 0.12
    retract_s: float | None = 0.3

    def __post_init__(self) -> None:
        if self.retract_s is not None:
            check_range("retract_s", self.retract_s, 0)
        check_range("blink_mean_s", self.blink_mean_s, 0, lo_open=True)
        check_range("blink_sd_s", self.blink_sd_s, 0)
        check_range("blink_min_interval_s", self.blink_min_interval_s, 0, lo_open=True)
        check_range("blink_close_s", self.blink_close_s, 0, lo_open=True)
        check_range("blink_open_s", self.blink_open_s, 0, lo_open=True)


class SmileFace(Face):
    """Smile and jaw weights from the smoothed MCS, eyes from clip keys plus blinks.

    Channels (dimensionless shape weights in [0, 1]): ``smile`` = S_smile(MCS),
    ``jaw`` = S_jaw(MCS) (thesis 3.3.1-3.3.2, 5.3); ``blink`` the blink
    animation; ``eyes_closed`` = max(clip eye key, blink) (3.3.3).  A blink due
    while the playing clip holds the eyes closed or closing is skipped and the
    next interval drawn.
    """

    name = "smile"
    Params = SmileParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        p = self.params
        self.smile = Smoother(p.smile, self.ctx.dt)
        self.jaw = Smoother(p.jaw, self.ctx.dt)
        self.blinker = Blinker(self.ctx.rng, p.blink_mean_s, p.blink_sd_s, p.blink_min_interval_s,
                               p.blink_close_s, p.blink_open_s, dt=self.ctx.dt)
        self.retraction = (None if p.retract_s is None else
                           Retraction([(self.smile, "e"), (self.jaw, "e")], p.retract_s, self.ctx.dt))
        self.reset()

    def reset(self) -> None:
        self.smile.reset()
        self.jaw.reset()
        self.blinker.reset()
        if self.retraction is not None:
            self.retraction.reset()

    def step(self, frame) -> None:
        mcs = frame.control["mcs"]
        ch = frame.channels
        back = self.retraction
        if back is not None:
            back.begin(frame.control)
        ch["smile"] = self.smile.smooth(mcs)
        ch["jaw"] = self.jaw.smooth(mcs)
        if back is not None and back.clamp():   # a provisional answer taken back (detector=yamnet)
            ch["smile"], ch["jaw"] = self.smile.value(), self.jaw.value()
        blink = self.blinker.step(frame.time_s, frame.clip_eyes > 0.0)  # skipped while the clip closes the eyes
        ch["blink"] = blink
        ch["eyes_closed"] = max(frame.clip_eyes, blink)


@hookimpl
def register_faces(register):
    register(SmileFace)
