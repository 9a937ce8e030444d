"""Lung pressure model of DiLorenzo, Zordan & Sanders (2008), section 6.1, Eqs. 1-4.

The lungs are a volume ``V_lung`` and a pressure ``P_lung``; the chest-wall
cavity ``V_cw`` (from the torso mechanics, :mod:`laughlab.hill.torso`) encloses them
and the pleural space ``V_pl = V_cw - V_lung``::

    P_lung = P_pl + P_tm(V_lung)                             (Eq. 1)
    P_pl,i = (V_pl,i-1 / V_pl,i) * P_pl,i-1                  (Eq. 2, Boyle's law)
    V_lung,i = V_lung,i-1 - Q * dt                           (Eq. 3)
    Q = sign(dP) * sqrt(|dP| / k),  dP = P_lung - P_atm      (Eq. 4)

Units: pressures are absolute, in atm, inside this module (the paper's unit of
``k``); :attr:`Lung.gauge_cmh2o` gives the lung pressure relative to the
atmosphere in cm H2O (1 atm = 1033.23 cm H2O).  Volumes in litres, flow in L/s.

Reading of the equations (docs/papers.md, "Reading notes")
----------------------------------------------------------
* Eq. 2 is Boyle's law for the pleural space: ``P_pl * V_pl`` is constant
  while only the walls move.
* Eq. 4 keeps the sign of ``dP``: ``Q`` is the *expiratory* flow, positive
  when the lung pressure is above atmospheric, so air leaves the lungs and
  Eq. 3 *subtracts* ``Q dt`` (the extraction prints ``+ Q dt``, which only
  holds for ``Q`` counted as inflow; with the sign of ``dP`` and ``+`` the lungs
  would inflate when squeezed and the model would run away).  Only the flow
  changes the lung volume (the paper's "approximate update due to flow"), so
  the lung volume change equals minus the integrated flow exactly.
* ``k = 8.2e-4 atm s^2/L^2`` (Slutsky et al. 1981, turbulent flow, as the paper).

The paper's two-loop update, per step (:meth:`Lung.step`)
---------------------------------------------------------
1. Eq. 2 with the *new* chest-wall volume and the *previous* lung volume;
   Eq. 1 with the *previous* ``P_tm`` -> an intermediate ``P_lung``.
2. Eq. 4 from the intermediate ``P_lung`` -> ``Q``; Eq. 3 -> new ``V_lung``;
   Eq. 1 again with the updated ``P_pl`` (Boyle's law once more, for the
   pleural volume the lung's own change gives back) and ``P_tm(V_lung,new)``.

Time stepping of the flow (``scheme``).  The square-root law is infinitely
stiff at ``dP = 0`` and the pleural gas is a stiff spring (``S = P_pl/V_pl +
1/C_L``, about 1400 cm H2O/L), so the paper's explicit loop 2, flow from the
*intermediate* pressure, needs steps far below a millisecond: at 4 ms it
overshoots atmospheric on every step and the pressure rattles (a two-cycle of
amplitude about ``dt^2 S^2 / (4 k)``).  ``scheme="implicit"`` (default) takes
the flow of Eq. 4 at the *end-of-step* pressure (backward Euler): with ``x`` the
volume leaving the lungs and ``P_lung(x) ~ P* - S x`` (``P*`` the intermediate
value of loop 1), ``x = dt sqrt((P* - S x)/k)`` is a quadratic solved in closed
form (:func:`implicit_volume`) and refined by one Newton step on the exact
(Boyle) end-of-step pressure; Eqs. 3, 2 and 1 then run exactly as in the
paper.  A steady squeeze of the chest at ``r`` L/s then drives an outflow ``Q``
that follows ``r`` (0.996 ``r`` in the test) and holds ``P_lung - P_atm = k Q^2``,
which the explicit loop only reaches as dt -> 0.
``scheme="explicit"`` is the paper's loop as printed.

Transmural pressure (Fig. 5 of the paper, after Mines 1993; the samples are not
in the text extraction) is linearised as ``P_tm(V) = P_tm,0 + (V - V_0) / C_L``
around the initial lung volume ``V_0``: ``P_tm,0 = 5 cm H2O`` (transpulmonary
pressure at functional residual capacity) and ``C_L = 0.2 L/cm H2O`` (static
lung compliance of an adult, West 2004, ch. 7).  Initial state (6.1): ``V_lung``
is 80 % of the chest wall's rest volume and ``P_lung`` is one atmosphere, so
``P_pl = 1 atm - P_tm,0``.

Every function and the :class:`Lung` state work on numpy arrays of any
shape, one element per simulated torso (a batch of parameter sets).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from laughlab.core.plugins import check_range

#: cm H2O per atmosphere (101325 Pa / 98.0665 Pa)
CMH2O_PER_ATM = 101325.0 / 98.0665
#: atmospheric pressure (atm)
P_ATM = 1.0


@dataclass
class LungParams:
    """Parameters of the lung pressure model (DiLorenzo 2008, 6.1).

    Attributes
    ----------
    k : float
        Turbulent flow coefficient of Eq. 4 (atm s^2 / L^2); the paper's
        8.2e-4 matches the pressure-flow curve of Slutsky et al. (1981).
    initial_fraction : float
        Initial lung volume as a fraction of the chest wall's rest volume
        (paper: eighty percent).
    ptm0_cmh2o : float
        Transmural pressure at the initial lung volume (cm H2O); 5, the
        transpulmonary pressure at functional residual capacity (West 2004).
    compliance_l_per_cmh2o : float
        Slope ``dV/dP_tm`` of the linearised transmural curve (L / cm H2O);
        0.2, the static lung compliance of an adult (West 2004).
    scheme : str
        ``implicit`` (default): the flow of Eq. 4 at the end-of-step pressure;
        ``explicit``: the paper's loop 2 as printed (flow at the intermediate
        pressure; needs steps well below 1 ms).  See the module notes.
    """

    k: float = 8.2e-4
    initial_fraction: float = 0.8
    ptm0_cmh2o: float = 5.0
    compliance_l_per_cmh2o: float = 0.2
    scheme: str = "implicit"

    def __post_init__(self) -> None:
        check_range("k", self.k, 0, lo_open=True)
        check_range("initial_fraction", self.initial_fraction, 0, 1, lo_open=True)
        if not self.initial_fraction < 1:
            raise ValueError(f"initial_fraction must be < 1 (got {self.initial_fraction})")
        check_range("ptm0_cmh2o", self.ptm0_cmh2o, -50, 50)
        check_range("compliance_l_per_cmh2o", self.compliance_l_per_cmh2o, 0, lo_open=True)
        if self.scheme not in ("implicit", "explicit"):
            raise ValueError(f"scheme must be implicit or explicit (got {self.scheme!r})")


def boyle(p_prev, v_prev, v_new):
    """Eq. 2: ``P_i = (V_i-1 / V_i) * P_i-1`` (any pressure unit; volumes in one unit)."""
    return v_prev / v_new * p_prev


def transmural(v_lung, v0, p: LungParams):
    """Linearised transmural pressure ``P_tm(V) = P_tm,0 + (V - V_0)/C_L`` (atm; Fig. 5)."""
    return (p.ptm0_cmh2o + (v_lung - v0) / p.compliance_l_per_cmh2o) / CMH2O_PER_ATM


def flow(dp_atm, k: float, xp=np):
    """Eq. 4: expiratory flow ``Q = sign(dP) sqrt(|dP| / k)`` (L/s) for ``dP`` in atm."""
    return xp.sign(dp_atm) * xp.sqrt(xp.abs(dp_atm) / k)


class _Scalar:
    """The few array functions the update needs, for plain floats (one torso: no numpy overhead)."""

    maximum = staticmethod(max)
    abs = staticmethod(abs)
    sqrt = staticmethod(math.sqrt)

    @staticmethod
    def sign(x):
        return (x > 0.0) - (x < 0.0)


def implicit_volume(dp_atm, stiffness_atm_per_l, dt: float, k: float, xp=np):
    """Volume (L) leaving the lungs in one backward-Euler step of Eq. 4.

    Solves ``x = sign(dP') dt sqrt(|dP'| / k)`` with the end-of-step pressure
    difference ``dP' = dP - S x`` (``dP`` the intermediate ``P_lung - P_atm`` in
    atm, ``S`` the lungs' stiffness ``-dP_lung/dx`` in atm/L): for ``dP > 0``,
    ``x^2 + (dt^2 S / k) x - dt^2 dP / k = 0``, positive root, computed without
    cancellation; odd in ``dP``.  ``0 <= x <= dP / S`` for ``dP >= 0``: the flow
    never carries the pressure past atmospheric.
    """
    beta = dt * dt * stiffness_atm_per_l / k
    c = dt * dt * xp.abs(dp_atm) / k
    return xp.sign(dp_atm) * (2.0 * c / (beta + xp.sqrt(beta * beta + 4.0 * c)))


class Lung:
    """State of the lungs of a batch of torsos, advanced by the paper's two-loop update.

    Parameters
    ----------
    params : LungParams
    v_cw0 : float or ndarray
        The chest wall's rest volume (L), per torso.
    shape : tuple
        Batch shape of the state arrays.

    Attributes
    ----------
    v_lung, v_pl : ndarray
        Lung and pleural volumes (L).
    p_pl, p_lung : ndarray
        Pleural and lung pressure, absolute (atm).
    q : ndarray
        Expiratory flow of the last step (L/s; negative = inspiration).

    The pleural volume is never let below 1e-3 of its initial value (a guard
    that no simulation of the torso reaches).
    """

    #: the state variables (arrays of the batch shape)
    STATE = ("v_lung", "v_pl", "p_pl", "p_lung", "ptm", "q")

    def __init__(self, params: LungParams, v_cw0, shape: tuple = ()):
        self.params = params
        self.v_cw0 = np.broadcast_to(np.asarray(v_cw0, dtype=float), shape).copy()
        self.shape = shape
        self._c_atm = params.compliance_l_per_cmh2o * CMH2O_PER_ATM  # L/atm
        self._implicit = params.scheme == "implicit"
        # one torso: the same update on plain floats (numpy's per-call overhead dominates tiny arrays)
        self._scalar = int(np.prod(shape)) == 1
        self.reset()

    def reset(self) -> None:
        p = self.params
        self.v0 = p.initial_fraction * self.v_cw0
        v_lung = self.v0.copy()
        p_lung = np.full(self.shape, P_ATM)
        ptm = transmural(v_lung, self.v0, p)
        self.p_pl0 = p_lung - ptm
        self.v_pl_min = 1e-3 * (self.v_cw0 - v_lung)
        self.load({"v_lung": v_lung, "v_pl": self.v_cw0 - v_lung, "p_pl": p_lung - ptm, "p_lung": p_lung,
                   "ptm": ptm, "q": np.zeros(self.shape)})
        self._ptm_a = (p.ptm0_cmh2o - self.v0 / p.compliance_l_per_cmh2o) / CMH2O_PER_ATM
        self._ptm_b = 1.0 / (p.compliance_l_per_cmh2o * CMH2O_PER_ATM)
        if self._scalar:
            self._ptm_a, self._p_pl0_f, self._v_pl_min_f = (float(self._ptm_a.flat[0]), float(self.p_pl0.flat[0]),
                                                            float(self.v_pl_min.flat[0]))

    def load(self, state: dict) -> None:
        """Set state variables (``STATE`` names; values broadcast to the batch shape)."""
        for k, v in state.items():
            setattr(self, k, np.broadcast_to(np.asarray(v, dtype=float), self.shape).copy())
        if self._scalar:
            self._f = {k: float(getattr(self, k).flat[0]) for k in self.STATE}

    @property
    def gauge_cmh2o(self) -> np.ndarray:
        """Lung pressure relative to the atmosphere (cm H2O)."""
        return (self.p_lung - P_ATM) * CMH2O_PER_ATM

    @property
    def pleural_gauge_cmh2o(self) -> np.ndarray:
        """Pleural pressure relative to its initial value (cm H2O)."""
        return (self.p_pl - self.p_pl0) * CMH2O_PER_ATM

    def stiffness_cmh2o_per_l(self) -> np.ndarray:
        """``-dP_pl/dV_cw`` at fixed lung volume (cm H2O / L): Boyle's law, ``P_pl / V_pl``."""
        return self.p_pl * CMH2O_PER_ATM / self.v_pl

    def _update(self, v_cw, dt: float, newton: bool, v_lung, v_pl_prev, p_pl_prev, ptm, v_pl_min, xp=np):
        """The two-loop update to chest-wall volume ``v_cw``, without storing it."""
        p = self.params
        # loop 1: Eq. 2 with the new chest wall and the previous lung volume, Eq. 1 with the previous P_tm
        v_pl = xp.maximum(v_cw - v_lung, v_pl_min)
        p_pl = boyle(p_pl_prev, v_pl_prev, v_pl)
        p_lung = p_pl + ptm
        # loop 2: Eq. 4 (flow), Eq. 3 (lung volume), then Eqs. 2 and 1 with the updated values
        s_pl = p_pl / v_pl
        if self._implicit:
            inv_c = 1.0 / self._c_atm
            x = implicit_volume(p_lung - P_ATM, s_pl + inv_c, dt, p.k, xp)
            if newton:  # one Newton step on the exact end-of-step pressure (Boyle's curvature)
                c = p.k / (dt * dt)
                vx = v_pl + x
                ax = xp.abs(x)
                f = c * x * ax - (p_pl * v_pl / vx + ptm - x * inv_c - P_ATM)
                x = x - f / (2.0 * c * ax + p_pl * v_pl / (vx * vx) + inv_c)
        else:
            x = flow(p_lung - P_ATM, p.k, xp) * dt
        v_pl_new = v_pl + x
        return x, v_pl_new, boyle(p_pl, v_pl, v_pl_new), s_pl

    def _args(self):
        if self._scalar:
            f = self._f
            return f["v_lung"], f["v_pl"], f["p_pl"], f["ptm"], self._v_pl_min_f, _Scalar
        return self.v_lung, self.v_pl, self.p_pl, self.ptm, self.v_pl_min, np

    def predict(self, v_cw, dt: float):
        """Pleural pressure after a step to ``v_cw`` and its slope, for an implicit torso step.

        Returns ``(P_pl - P_pl,0, dP_pl/dV_cw)`` in cm H2O and cm H2O/L, the slope
        of the linearised update: ``-S_pl (1/C + R/dt) / (S_pl + 1/C + R/dt)`` with
        ``S_pl = P_pl/V_pl`` (Boyle) and ``R = 2 k x / dt`` the incremental flow
        resistance at this step's flow ``x/dt`` (implicit scheme): the pleural gas
        in series with the airway.  The state is not changed.
        """
        if self._scalar:
            v_cw = float(v_cw.flat[0]) if isinstance(v_cw, np.ndarray) else float(v_cw)
        *args, xp = self._args()
        x, v_pl, p_pl, s_pl = self._update(v_cw, dt, False, *args, xp)
        inv_c = 1.0 / self._c_atm
        r_dt = 2.0 * self.params.k * xp.abs(x) / (dt * dt) if self._implicit else 0.0 * x
        slope = -s_pl * (inv_c + r_dt) / (s_pl + inv_c + r_dt)
        p0 = self._p_pl0_f if self._scalar else self.p_pl0
        return (p_pl - p0) * CMH2O_PER_ATM, slope * CMH2O_PER_ATM

    def step(self, v_cw, dt: float) -> np.ndarray:
        """Advance one step of ``dt`` seconds to the chest-wall volume ``v_cw`` (L).

        Returns the lung pressure relative to the atmosphere (cm H2O).
        """
        if self._scalar:
            v_cw = float(v_cw.flat[0]) if isinstance(v_cw, np.ndarray) else float(v_cw)
        *args, xp = self._args()
        x, v_pl, p_pl, _ = self._update(v_cw, dt, True, *args, xp)
        v_lung = args[0] - x
        ptm = self._ptm_a + self._ptm_b * v_lung       # P_tm(V) = P_tm,0 + (V - V_0) / C_L (atm)
        if self._scalar:
            f = self._f
            f["v_pl"], f["p_pl"], f["v_lung"], f["ptm"] = v_pl, p_pl, v_lung, ptm
            f["p_lung"], f["q"] = p_pl + ptm, x / dt
            for k in self.STATE:
                getattr(self, k)[...] = f[k]
        else:
            self.v_pl, self.p_pl, self.v_lung, self.ptm = v_pl, p_pl, v_lung, ptm
            self.p_lung = p_pl + ptm
            self.q = x / dt
        return self.gauge_cmh2o
