"""The Hill-type muscle of DiLorenzo, Zordan & Sanders (2008), section 5.1: force from activation,
length and strain rate (Zajac 1989; Buchanan et al. 2004), and the paper's table of parameters.

Used by the torso (:mod:`laughlab.hill.torso`) and, as the same arithmetic, by its compiled step
(:mod:`laughlab.hill.kernel`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from laughlab.core.plugins import check_range

#: force-length width w (Zajac 1989: force from 0.5 to 1.5 rest lengths)
W_FL = 0.5
#: force-velocity constants a and b (Buchanan et al. 2004)
A_FV = 0.25
B_FV = 0.25
#: cap of the passive element's exponent (overflow guard)
_PE_EXP_CAP = 50.0


# --- the Hill muscle (5.1) --------------------------------------------------------------------

def force_length(l_norm):
    """Dimensionless force-length ``F~_l = 1 - ((l~ - 1)/w)^2``, w = 0.5, kept in [0, 1] (Fig. 3a)."""
    d = (np.asarray(l_norm, dtype=float) - 1.0) / W_FL
    return np.maximum(1.0 - d * d, 0.0)


def force_velocity(v_norm):
    """Dimensionless force-velocity ``F~_v = (b - a|v~|)/(b + |v~|)``, a = b = 0.25, kept in [0, 1] (Fig. 3b).

    Symmetric in ``v~`` as the paper writes it: lengthening loses force too.
    """
    av = np.abs(np.asarray(v_norm, dtype=float))
    return np.maximum((B_FV - A_FV * av) / (B_FV + av), 0.0)


def passive_force(l_norm, strain_rate, k_pe, b_pe):
    """Passive element ``F_PE = max(0, k_PE exp(10 (l~ - 1)) / exp(5) + b_PE s_dot)`` (force units).

    ``strain_rate`` is ``s_dot = v / l_o`` in 1/s (positive when lengthening).
    """
    e = np.exp(np.minimum(10.0 * (np.asarray(l_norm, dtype=float) - 1.0) - 5.0, _PE_EXP_CAP))
    return np.maximum(k_pe * e + b_pe * np.asarray(strain_rate, dtype=float), 0.0)


def contractile_force(activation, l_norm, strain_rate, v_max, f_max):
    """Contractile element ``F_CE = a F~_l(l~) F~_v(s_dot / v_max) F_max`` with ``a`` clipped to [0, 1]."""
    a = np.clip(activation, 0.0, 1.0)
    return a * force_length(l_norm) * force_velocity(np.asarray(strain_rate, dtype=float) / v_max) * f_max


def muscle_force(activation, l_norm, strain_rate, m: "MuscleParams"):
    """Total muscle force ``F_M = F_PE + F_CE`` (force units of the paper's table)."""
    return passive_force(l_norm, strain_rate, m.k_pe, m.b_pe) + contractile_force(
        activation, l_norm, strain_rate, m.v_max, m.f_max)


def _hill(a, l, s, k_pe, b_pe, inv_v_max, f_max):
    """Muscle forces and the weights of the implicit Jacobian, vectorised over muscles.

    ``l`` is the stretch ``l~ - 1``.

    Returns ``F`` (as :func:`muscle_force`, ``a`` already in [0, 1]) and the
    magnitudes of ``dF/dl~`` and ``dF/ds_dot`` used by the implicit step: the
    passive slope ``10 k_PE exp(10(l~-1)-5)`` plus the rising side of
    ``F~_l``, and ``b_PE`` plus the force-velocity slope taken for either
    direction.  (Linearly implicit Euler stays first-order with any matrix;
    the magnitudes keep it stable, the exact slopes would include the
    symmetric ``F~_v``'s negative damping when lengthening.)
    """
    d = l * (1.0 / W_FL)                     # l is l~ - 1
    fl = np.maximum(1.0 - d * d, 0.0)
    vt = s * inv_v_max
    den = B_FV + np.abs(vt)
    fv = np.maximum((B_FV + A_FV * B_FV) / den - A_FV, 0.0)   # = (b - a|v~|)/(b + |v~|)
    ee = k_pe * np.exp(np.minimum(10.0 * l - 5.0, _PE_EXP_CAP))
    af = a * f_max
    afv = af * fv
    force = np.maximum(ee + b_pe * s, 0.0) + afv * fl
    k_imp = 10.0 * ee + afv * np.maximum((-2.0 / W_FL) * d, 0.0)
    d_imp = b_pe + af * fl * (B_FV * (1.0 + A_FV) * inv_v_max) / (den * den)
    return force, k_imp, d_imp


@dataclass
class MuscleParams:
    """The four parameters of a Hill muscle element (paper 5.1).

    Attributes
    ----------
    k_pe : float
        Passive stiffness coefficient (force units; ``F_PE = k_PE`` at ``l~ = 1.5``).
    b_pe : float
        Passive damping coefficient (force units per 1/s of strain rate).
    v_max : float
        Maximum contraction velocity (rest lengths per second).
    f_max : float
        Maximum contractile force (force units).
    """

    k_pe: float = 1.5
    b_pe: float = 0.05
    v_max: float = 1.0
    f_max: float = 1.5

    def __post_init__(self) -> None:
        check_range("k_pe", self.k_pe, 0)
        check_range("b_pe", self.b_pe, 0)
        check_range("v_max", self.v_max, 0, lo_open=True)
        check_range("f_max", self.f_max, 0)


@dataclass
class MuscleTable:
    """Hill parameters per muscle group: the paper's table (5.1), clavicle muscles ours.

    Attributes
    ----------
    abdominals, diaphragm, inner_intercostals, outer_intercostals : MuscleParams
        The paper's table.
    clavicle : MuscleParams
        Clavicle elevators and depressors (not in the table; ours: the intercostals'
        k_PE, b_PE and F_max, the diaphragm's v_max of 5 so the shoulders can follow 5 Hz calls).
    """

    abdominals: MuscleParams = field(default_factory=lambda: MuscleParams(16.0, 0.16, 8.0, 8.0))
    diaphragm: MuscleParams = field(default_factory=lambda: MuscleParams(16.0, 0.16, 5.0, 5.0))
    inner_intercostals: MuscleParams = field(default_factory=lambda: MuscleParams(1.5, 0.05, 1.0, 1.5))
    outer_intercostals: MuscleParams = field(default_factory=lambda: MuscleParams(1.5, 0.05, 1.0, 1.5))
    clavicle: MuscleParams = field(default_factory=lambda: MuscleParams(1.5, 0.05, 5.0, 1.5))
