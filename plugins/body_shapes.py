"""Body driver ``shapes``: chest and belly shape interpolation (van Duijn 2014, 3.2 and 5.3)."""
from __future__ import annotations

from dataclasses import dataclass, field

from laughlab import hookimpl
from laughlab.core.bases import Body
from laughlab.signals.smoothing import BELLY, CHEST, Smoother, SmootherParams


@dataclass
class ShapesParams:
    """Parameters of the ``shapes`` body driver.

    Attributes
    ----------
    chest, belly : SmootherParams
        Smoothers applied to the MCS before it drives each shape (thesis 5.3:
        chest rise 0.2, fall 0.1; belly rise 0.1, fall 0.05 per tick, x 60 /s).
    chest_gain, belly_gain : float
        Scale of each influence.  Values above 1 exaggerate the shape by linear
        extrapolation (thesis Fig. 3.5); influences are never clipped to [0, 1].
    chest_offset, belly_offset : float
        Added to each influence; a negative chest offset lets strong exhalation
        contract the chest below its rest shape (influence < 0, Fig. 3.5).
    """

    chest: SmootherParams = field(default_factory=lambda: SmootherParams(**vars(CHEST)))
    belly: SmootherParams = field(default_factory=lambda: SmootherParams(**vars(BELLY)))
    chest_gain: float = 1.0
    belly_gain: float = 1.0
    chest_offset: float = 0.0
    belly_offset: float = 0.0


class ShapesBody(Body):
    """Chest and belly shape influences from the MCS (van Duijn 2014, Eqs. 3.3 and 3.4).

    ``chest(t) = offset + gain * (1 - S_chest(MCS(t)))`` (Eq. 3.3) and
    ``belly(t) = offset + gain * S_belly(MCS(t))`` (Eq. 3.4), where ``S`` is the
    thesis' Smoother.  Dimensionless shape-key weights: 1 = the sculpted
    expanded shape, 0 = the mesh's base shape, outside [0, 1] = extrapolated; in
    silence the chest is 1 (full) and the belly 0.
    """

    name = "shapes"
    Params = ShapesParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        self.chest = Smoother(self.params.chest, self.ctx.dt)
        self.belly = Smoother(self.params.belly, self.ctx.dt)

    def reset(self) -> None:
        self.chest.reset()
        self.belly.reset()

    def step(self, frame) -> None:
        p = self.params
        mcs = frame.control["mcs"]
        frame.channels["chest"] = p.chest_offset + p.chest_gain * (1.0 - self.chest.smooth(mcs))
        frame.channels["belly"] = p.belly_offset + p.belly_gain * self.belly.smooth(mcs)


@hookimpl
def register_bodies(register):
    register(ShapesBody)
