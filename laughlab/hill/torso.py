"""Hill-type muscles and a reduced-order torso (DiLorenzo, Zordan & Sanders 2008, sections 4-5).

Muscle model (section 5.1)
--------------------------
Every muscle element produces ``F_M = F_PE + F_CE`` (force units of the
paper's table) from its activation ``a`` in [0, 1], its normalised fibre length
``l~ = l / l_o`` and its strain rate ``s_dot = v / l_o`` (1/s, ``v = dl/dt``,
positive when lengthening)::

    F_PE = max(0, k_PE * exp(10 (l~ - 1)) / exp(5) + b_PE * s_dot)   passive element
    F_CE = a * F~_l(l~) * F~_v(v~) * F_max                           contractile element
    F~_l(l~) = 1 - ((l~ - 1) / w)^2,  w = 0.5                         force-length
    F~_v(v~) = (b - a_v |v~|) / (b + |v~|),  a_v = b = 0.25           force-velocity
    v~ = s_dot / v_max

Each of ``a``, ``F~_l`` and ``F~_v`` is kept in [0, 1] as the paper asks:
``a`` is clipped; ``F~_l`` is clipped at 0 outside ``0.5 <= l~ <= 1.5``, the
range of force generation (Zajac 1989) (it is at most 1 by construction);
``F~_v`` is clipped at 0 for ``|v~| > b / a_v = 1`` (it is at most 1, at
``v~ = 0``).  ``v_max`` is read in rest lengths per second.

Note (reading notes in docs/papers.md): ``F~_v`` uses ``|v~|``, so it
is symmetric: a *lengthening* active muscle loses force exactly like a
shortening one, unlike most Hill models (where eccentric force exceeds
isometric).  It is implemented as written.  Numerically that is negative
damping while lengthening; the integrator treats only the positive part of the
damping implicitly (see :class:`Torso`).

The exponent of ``F_PE`` is capped at 50 (``10 (l~ - 1) - 5 = 50``: ``l~ > 6.5``) to avoid overflow; no
simulation gets near it.

Parameter table (paper, 5.1): abdominals k_PE 16.0, b_PE 0.16, v_max 8.0,
F_max 8.0; diaphragm 16.0, 0.16, 5.0, 5.0; inner and outer intercostals 1.5,
0.05, 1.0, 1.5.  The clavicle muscles are not in the table; they take the
intercostals' values except v_max = 5 (ours).

Reduced-order torso (sections 4 and 5.3)
----------------------------------------
The paper simulates hundreds of rigid and deformable elements (DiLorenzo 2008);
here nine generalised coordinates carry the same structure:

====  =====================  ====  ===============================================
 i    coordinate             unit  positive means
====  =====================  ====  ===============================================
 0    ribcage expansion       m    ribcage wall moves out (inspiration)
 1    diaphragm descent       m    dome moves down into the abdomen (inspiration)
 2-6  abdominal wall, 5       m    section moves out (rectus upper, rectus lower,
      sections                     external oblique, internal oblique, transversus)
 7    spine flexion           rad  trunk bends forward
 8    clavicle elevation      rad  shoulders rise
====  =====================  ====  ===============================================

Chest-wall cavity (Fig. 6: the volume enclosed by the ribcage and the
diaphragm) - an elliptic cylinder of the ribcage's cross-section closed below
by the diaphragm as a piston::

    V_cw = (V_cw,0 + A_di x_di) (1 + x_rc / R)^2              (L)

so ``dV_cw/dx_rc = 2 V_cw,0 / R`` at rest (50 L/m with V_cw,0 = 3.75 L and R = 0.15 m).

Abdomen: its contents are nearly incompressible, so diaphragm descent pushes the
wall out; the volume change ``dV_ab = sum_j A_j x_j - A_di x_di`` raises the
abdominal pressure ``P_ab = -E_ab dV_ab`` (E_ab = 50 cm H2O/L, five times the
wall's own elastance).  The five sections are activated from one abdominal
activation in fixed proportions (Hoit et al. 1988: the lateral wall, obliques
and transversus, works harder than the rectus in expiratory tasks; the exact
proportions of the paper's Fig. 2(d) are not in the text, ours are 0.4, 0.6,
0.8, 1.0, 1.0).

Equations of motion (virtual work; ``c_p = 0.0980665 N per cm H2O L/m``)::

    M q'' = sum_m -G_m F_M,m J_m                               muscles
            + c_p (P_pl - P_pl,0 + P_stop(V_cw)) dV_cw/dq      pleural pressure on the chest wall
            + c_p P_ab dV_ab/dq                                abdominal contents
            - K q - D q' + F_pre                                tissue elasticity and damping
            + k_p (theta_d - theta) - k_d theta'                spine PD servo (5.3)

with muscle lengths ``l~_m = 1 + J_m . q / L_m``.  ``J`` couples: an abdominal
section shortens when its wall moves in, when the ribcage closes (the obliques
and rectus insert on the lower ribs, coupling ``beta_j``) and when the trunk
flexes (moment arm ``r_j``), so abdominal effort squeezes the abdomen,
compresses the lower ribcage and bends the spine forward; the diaphragm
shortens as it descends; the inner intercostals shorten as the ribcage closes,
the outer ones as it opens; clavicle elevators and depressors rotate the
shoulder girdle, which a spring ties to the ribcage (ribcage expansion lifts
the clavicles).  ``G_m`` turns one force unit of the table into newtons:
``G = c_p A force_unit_cmh2o`` for a muscle acting on a wall of area ``A``
(L/m), so one force unit of the table is ``force_unit_cmh2o`` (6) cm H2O on the
wall it moves: full abdominal effort (F_max 8) is about 48 cm H2O, the
diaphragm's (5) 30, an intercostal group's (1.5) 9 cm H2O.  ``F_pre`` holds
the rest pose (all coordinates 0) in equilibrium at the rest activations.

Masses, stiffness and damping come from per-compartment compliance ``C``,
resistance ``R`` and inertance ``I`` (``M = c_p A^2 I``, ``K = c_p A^2 / C``,
``D = c_p A^2 R``): ribcage 0.1 L/cm H2O, 0.5 cm H2O s/L, 0.005 cm H2O s^2/L;
diaphragm 0.5, 0.2, 0.003; abdominal wall 0.1, 0.5, 0.01 (relaxed chest wall
and abdomen compliances of about 0.1 L/cm H2O, chest wall tissue resistance of
0.5-1 cm H2O s/L; the resulting resonances of 5-8 Hz match forced-oscillation
measurements of the respiratory system).  Near residual volume and total lung
capacity the chest wall stiffens (``P_stop``, exponential with a 0.15 L scale).

Integration: linearly implicit (semi-implicit backward) Euler at a fixed step,
``(M + dt D + dt^2 K) dv = dt (F - dt K v)``, ``q += dt (v + dv)``, with ``K`` and
``D`` the analytic force Jacobians of the muscles (their magnitudes: any matrix
keeps the scheme first-order, these keep it stable), tissue and abdominal
contents; the pressure on the chest wall (pleural gas and volume stops) is
taken at the predicted volume ``V_cw(q + dt q')`` with its slope there, the
pleural part from the lung's own update (the pleural gas in series with the
airway, :meth:`laughlab.hill.lung.Lung.predict`), so the step stays accurate though
the gas equilibrates within a millisecond; then the lung's two-loop update
(:class:`laughlab.hill.lung.Lung`) with the new ``V_cw``.  Inputs are taken at the
end of each step.  240 Hz (the default) is within 20 % RMS of a 3840 Hz
reference on a deep laugh and within 10 % once its one-step lag is removed
(``tests/test_hill.py``); stable for any activation in [0, 1] (tested).

All state arrays carry a leading batch axis: one torso per parameter set, so
an optimiser evaluates many candidates in one vectorised simulation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from laughlab.hill.lung import CMH2O_PER_ATM, P_ATM, Lung, LungParams
from laughlab.hill.muscle import _PE_EXP_CAP, A_FV, B_FV, W_FL, MuscleTable, _hill
from laughlab.core.plugins import check_range

try:  # the gufunc behind np.linalg.solve, without its per-call checks (a third of a small solve's cost)
    from numpy.linalg import _umath_linalg

    def _solve(a, b):
        return _umath_linalg.solve(a, b, signature="dd->d")
    _solve(np.eye(2)[None], np.ones((1, 2, 1)))
except Exception:  # pragma: no cover - other numpy builds
    _solve = np.linalg.solve

#: N per (cm H2O x L/m): the force of 1 cm H2O on a wall sweeping 1 L per metre
C_P = 98.0665e-3

COORDS = ("ribcage", "diaphragm", "rectus_upper", "rectus_lower", "external_oblique", "internal_oblique",
          "transversus", "spine", "clavicle")
SECTIONS = ("rectus_upper", "rectus_lower", "external_oblique", "internal_oblique", "transversus")
MUSCLES = (*SECTIONS, "diaphragm", "inner_intercostals", "outer_intercostals", "clavicle_elevators",
           "clavicle_depressors")
#: activation groups (mid-level control, 5.2)
GROUPS = ("abdomen", "diaphragm", "inner_intercostals", "outer_intercostals", "clavicle_up", "clavicle_down")
IRC, IDI, IAB, ISP, ICL = 0, 1, slice(2, 7), 7, 8
NQ, NM, NG = len(COORDS), len(MUSCLES), len(GROUPS)


@dataclass
class AbdomenSection:
    """One of the five abdominal sections (paper section 4, Fig. 2d).

    Attributes
    ----------
    ratio : float
        Share of the abdominal activation this section receives (fixed; Hoit et al. 1988).
    area_l_per_m : float
        Volume swept per metre of outward wall displacement (L/m, i.e. area in 10 cm^2).
    ribcage_coupling : float
        Muscle length change per unit ribcage expansion, relative to the section's own wall
        displacement (the muscle's insertion on the lower ribs).
    spine_arm_m : float
        Moment arm about the spine (m): shortening per radian of trunk flexion.
    """

    ratio: float = 1.0
    area_l_per_m: float = 12.0
    ribcage_coupling: float = 0.2
    spine_arm_m: float = 0.0

    def __post_init__(self) -> None:
        check_range("ratio", self.ratio, 0, 1)
        check_range("area_l_per_m", self.area_l_per_m, 0, lo_open=True)
        check_range("ribcage_coupling", self.ribcage_coupling, 0, 2)
        check_range("spine_arm_m", self.spine_arm_m, 0, 0.3)


@dataclass
class AbdomenParams:
    """The abdominal wall: five sections, their common tissue properties and the contents.

    Attributes
    ----------
    rectus_upper, rectus_lower, external_oblique, internal_oblique, transversus : AbdomenSection
        The sections; ratios 0.4, 0.6, 0.8, 1.0, 1.0 (lateral wall more active than the
        rectus, Hoit et al. 1988; the paper's exact proportions are in a figure).
    compliance_l_per_cmh2o : float
        Relaxed abdominal wall compliance, all sections together (L / cm H2O).
    resistance_cmh2o_s_per_l : float
        Wall tissue resistance (cm H2O s / L).
    inertance_cmh2o_s2_per_l : float
        Wall and viscera inertance (cm H2O s^2 / L).
    contents_elastance_cmh2o_per_l : float
        Elastance of the abdominal contents (cm H2O / L); high: nearly incompressible.
    muscle_length_m : float
        Wall displacement that changes the fibre length by one rest length (m): a
        circumference of about 0.8 m grows by 2 pi x when the wall moves out by x.
    """

    rectus_upper: AbdomenSection = field(default_factory=lambda: AbdomenSection(0.4, 8.0, 0.3, 0.10))
    rectus_lower: AbdomenSection = field(default_factory=lambda: AbdomenSection(0.6, 10.0, 0.1, 0.10))
    external_oblique: AbdomenSection = field(default_factory=lambda: AbdomenSection(0.8, 14.0, 0.4, 0.05))
    internal_oblique: AbdomenSection = field(default_factory=lambda: AbdomenSection(1.0, 14.0, 0.3, 0.04))
    transversus: AbdomenSection = field(default_factory=lambda: AbdomenSection(1.0, 14.0, 0.1, 0.0))
    compliance_l_per_cmh2o: float = 0.1
    resistance_cmh2o_s_per_l: float = 0.5
    inertance_cmh2o_s2_per_l: float = 0.01
    contents_elastance_cmh2o_per_l: float = 50.0
    muscle_length_m: float = 0.13

    def __post_init__(self) -> None:
        check_range("compliance_l_per_cmh2o", self.compliance_l_per_cmh2o, 0, lo_open=True)
        check_range("resistance_cmh2o_s_per_l", self.resistance_cmh2o_s_per_l, 0)
        check_range("inertance_cmh2o_s2_per_l", self.inertance_cmh2o_s2_per_l, 0, lo_open=True)
        check_range("contents_elastance_cmh2o_per_l", self.contents_elastance_cmh2o_per_l, 0)
        check_range("muscle_length_m", self.muscle_length_m, 0, lo_open=True)

    def sections(self) -> list[AbdomenSection]:
        return [getattr(self, n) for n in SECTIONS]


@dataclass
class TorsoParams:
    """Anatomy and tissue properties of the reduced-order torso (units in each name).

    Attributes
    ----------
    chest_volume_l : float
        Chest-wall cavity volume at rest, V_cw,0 (L); the lungs start at
        ``lung.initial_fraction`` of it (3.0 L, a functional residual capacity).
    ribcage_radius_m : float
        Effective radius R of the ribcage cylinder (m); ``dV_cw/dx_rc = 2 V_cw,0 / R``.
    ribcage_compliance_l_per_cmh2o, ribcage_resistance_cmh2o_s_per_l, ribcage_inertance_cmh2o_s2_per_l : float
        Relaxed ribcage compliance, tissue resistance and inertance.
    diaphragm_area_l_per_m : float
        Volume swept per metre of diaphragm descent (L/m).
    diaphragm_compliance_l_per_cmh2o, diaphragm_resistance_cmh2o_s_per_l, diaphragm_inertance_cmh2o_s2_per_l : float
        The diaphragm's own (non-muscle) tissue properties.
    residual_chest_volume_l, total_chest_volume_l : float
        Chest-wall volumes where the wall stiffens (near residual volume and
        total lung capacity): ``P_stop = p (exp((V_lo - V)/s) - exp((V - V_hi)/s))``.
    stop_pressure_cmh2o, stop_width_l : float
        ``p`` and ``s`` of ``P_stop``.
    force_unit_cmh2o : float
        Pressure that one force unit of the paper's table exerts on the wall its
        muscle moves (cm H2O); sets the muscles' strength in physical units.
    intercostal_length_m, diaphragm_length_m : float
        Coordinate displacement that changes the fibre length by one rest length (m).
    spine_inertia_kg_m2, spine_kp_nm_per_rad, spine_kd_nms_per_rad : float
        Trunk inertia about the lumbar spine and the PD servo that holds it (5.3).
    clavicle_inertia_kg_m2, clavicle_stiffness_nm_per_rad, clavicle_damping_nms_per_rad : float
        Shoulder girdle inertia and passive restraint.
    clavicle_ribcage_rad_per_m, clavicle_coupling_nm_per_rad : float
        The spring tying the clavicles to the ribcage: rest elevation per metre of
        ribcage expansion and its stiffness.
    clavicle_torque_nm : float
        Torque of one force unit of a clavicle muscle (N m).
    clavicle_length_rad : float
        Elevation that changes a clavicle muscle's length by one rest length (rad).
    abdomen : AbdomenParams
    muscles : MuscleTable
    lung : LungParams
    """

    chest_volume_l: float = 3.75
    ribcage_radius_m: float = 0.15
    ribcage_compliance_l_per_cmh2o: float = 0.1
    ribcage_resistance_cmh2o_s_per_l: float = 0.5
    ribcage_inertance_cmh2o_s2_per_l: float = 0.005
    diaphragm_area_l_per_m: float = 25.0
    diaphragm_compliance_l_per_cmh2o: float = 0.5
    diaphragm_resistance_cmh2o_s_per_l: float = 0.2
    diaphragm_inertance_cmh2o_s2_per_l: float = 0.003
    residual_chest_volume_l: float = 2.1
    total_chest_volume_l: float = 7.0
    stop_pressure_cmh2o: float = 1.0
    stop_width_l: float = 0.15
    force_unit_cmh2o: float = 6.0
    intercostal_length_m: float = 0.15
    diaphragm_length_m: float = 0.25
    spine_inertia_kg_m2: float = 2.0
    spine_kp_nm_per_rad: float = 150.0
    spine_kd_nms_per_rad: float = 25.0
    clavicle_inertia_kg_m2: float = 0.06
    clavicle_stiffness_nm_per_rad: float = 15.0
    clavicle_damping_nms_per_rad: float = 1.5
    clavicle_ribcage_rad_per_m: float = 2.0
    clavicle_coupling_nm_per_rad: float = 20.0
    clavicle_torque_nm: float = 8.0
    clavicle_length_rad: float = 0.5
    abdomen: AbdomenParams = field(default_factory=AbdomenParams)
    muscles: MuscleTable = field(default_factory=MuscleTable)
    lung: LungParams = field(default_factory=LungParams)

    def __post_init__(self) -> None:
        for name in ("chest_volume_l", "ribcage_radius_m", "ribcage_compliance_l_per_cmh2o",
                     "ribcage_inertance_cmh2o_s2_per_l", "diaphragm_area_l_per_m",
                     "diaphragm_compliance_l_per_cmh2o", "diaphragm_inertance_cmh2o_s2_per_l",
                     "stop_width_l", "force_unit_cmh2o", "intercostal_length_m", "diaphragm_length_m",
                     "spine_inertia_kg_m2", "clavicle_inertia_kg_m2", "clavicle_length_rad"):
            check_range(name, getattr(self, name), 0, lo_open=True)
        for name in ("ribcage_resistance_cmh2o_s_per_l", "diaphragm_resistance_cmh2o_s_per_l", "stop_pressure_cmh2o",
                     "spine_kp_nm_per_rad", "spine_kd_nms_per_rad", "clavicle_stiffness_nm_per_rad",
                     "clavicle_damping_nms_per_rad", "clavicle_ribcage_rad_per_m", "clavicle_coupling_nm_per_rad",
                     "clavicle_torque_nm"):
            check_range(name, getattr(self, name), 0)
        if not self.residual_chest_volume_l < self.chest_volume_l < self.total_chest_volume_l:
            raise ValueError("need residual_chest_volume_l < chest_volume_l < total_chest_volume_l "
                             f"(got {self.residual_chest_volume_l}, {self.chest_volume_l}, {self.total_chest_volume_l})")
        if self.residual_chest_volume_l <= (1 - self.lung.initial_fraction) * self.chest_volume_l:
            raise ValueError("residual_chest_volume_l must exceed the pleural volume "
                             "(1 - lung.initial_fraction) * chest_volume_l")

    @property
    def ribcage_area_l_per_m(self) -> float:
        """``dV_cw/dx_rc`` at rest (L/m)."""
        return 2.0 * self.chest_volume_l / self.ribcage_radius_m


def group_matrix(p: TorsoParams) -> np.ndarray:
    """Mid-level control (5.2): the (groups x muscles) matrix of fixed activation ratios."""
    r = np.zeros((NG, NM))
    for j, s in enumerate(p.abdomen.sections()):
        r[0, j] = s.ratio
    for g, m in ((1, 5), (2, 6), (3, 7), (4, 8), (5, 9)):
        r[g, m] = 1.0
    return r


# --- the torso ------------------------------------------------------------------------------

class Torso:
    """A batch of reduced-order torsos with their lungs (see the module notes for the model).

    Parameters
    ----------
    params : TorsoParams
    batch : int
        Number of torsos simulated together (one per parameter set).
    rest_activation : array_like, optional
        Group activations (``GROUPS`` order) at which the rest pose is an
        equilibrium (default all 0).

    Attributes
    ----------
    q, qd : ndarray (batch, 9)
        Generalised coordinates (``COORDS``) and their velocities.
    lung : laughlab.hill.lung.Lung
        The lungs (volumes, pressures, flow).
    v_cw : ndarray (batch,)
        Chest-wall cavity volume (L).
    t : float
        Simulated time (s).
    """

    def __init__(self, params: TorsoParams | None = None, batch: int = 1, rest_activation=None):
        self.params = p = params if params is not None else TorsoParams()
        self.batch = int(batch)
        ab = p.abdomen
        secs = ab.sections()
        area = np.array([s.area_l_per_m for s in secs])
        a_sum = float(area.sum())
        a_rc, a_di = p.ribcage_area_l_per_m, p.diaphragm_area_l_per_m
        self._rest_act = np.zeros(NG) if rest_activation is None else np.clip(
            np.asarray(rest_activation, dtype=float), 0.0, 1.0)
        # masses, stiffness, damping from compliance / resistance / inertance
        m = np.empty(NQ)
        kd = np.empty(NQ)
        dd = np.empty(NQ)
        m[IRC], kd[IRC], dd[IRC] = (C_P * a_rc ** 2 * p.ribcage_inertance_cmh2o_s2_per_l,
                                    C_P * a_rc ** 2 / p.ribcage_compliance_l_per_cmh2o,
                                    C_P * a_rc ** 2 * p.ribcage_resistance_cmh2o_s_per_l)
        m[IDI], kd[IDI], dd[IDI] = (C_P * a_di ** 2 * p.diaphragm_inertance_cmh2o_s2_per_l,
                                    C_P * a_di ** 2 / p.diaphragm_compliance_l_per_cmh2o,
                                    C_P * a_di ** 2 * p.diaphragm_resistance_cmh2o_s_per_l)
        m[IAB] = C_P * area * a_sum * ab.inertance_cmh2o_s2_per_l
        kd[IAB] = C_P * area * a_sum / ab.compliance_l_per_cmh2o
        dd[IAB] = C_P * area * a_sum * ab.resistance_cmh2o_s_per_l
        m[ISP], kd[ISP], dd[ISP] = p.spine_inertia_kg_m2, p.spine_kp_nm_per_rad, p.spine_kd_nms_per_rad
        m[ICL], kd[ICL], dd[ICL] = p.clavicle_inertia_kg_m2, p.clavicle_stiffness_nm_per_rad, \
            p.clavicle_damping_nms_per_rad
        k = np.diag(kd)
        # abdominal contents: P_ab = -E dV_ab, dV_ab = a_ab . q
        self.a_ab = np.zeros(NQ)
        self.a_ab[IDI] = -a_di
        self.a_ab[IAB] = area
        k += C_P * ab.contents_elastance_cmh2o_per_l * np.outer(self.a_ab, self.a_ab)
        # clavicle-ribcage spring 1/2 k_c (e - c x_rc)^2
        kc, ce = p.clavicle_coupling_nm_per_rad, p.clavicle_ribcage_rad_per_m
        k[IRC, IRC] += kc * ce * ce
        k[ICL, ICL] += kc
        k[IRC, ICL] -= kc * ce
        k[ICL, IRC] -= kc * ce
        self.mass = m
        self.k_lin = k
        self.d_lin = np.diag(dd)
        # muscles: l~ = 1 + J.q / L, generalised force -G F J
        j = np.zeros((NM, NQ))
        length = np.empty(NM)
        gain = np.empty(NM)
        fu = p.force_unit_cmh2o
        for i, s in enumerate(secs):
            j[i, 2 + i], j[i, IRC], j[i, ISP] = 1.0, s.ribcage_coupling, -s.spine_arm_m
            length[i], gain[i] = ab.muscle_length_m, C_P * s.area_l_per_m * fu
        j[5, IDI], length[5], gain[5] = -1.0, p.diaphragm_length_m, C_P * a_di * fu
        j[6, IRC], length[6], gain[6] = 1.0, p.intercostal_length_m, C_P * a_rc * fu
        j[7, IRC], length[7], gain[7] = -1.0, p.intercostal_length_m, C_P * a_rc * fu
        j[8, ICL], length[8], gain[8] = -1.0, p.clavicle_length_rad, p.clavicle_torque_nm
        j[9, ICL], length[9], gain[9] = 1.0, p.clavicle_length_rad, p.clavicle_torque_nm
        self.J = j
        self._jt_over_l = (j / length[:, None]).T.copy()      # (NQ, NM): q @ -> (l~ - 1)
        self._gj = gain[:, None] * j                           # (NM, NQ): F @ -> -force
        self._jj = np.einsum("mi,mj->mij", j, j).reshape(NM, NQ * NQ)
        self._g_over_l = gain / length
        mt = p.muscles
        per = [mt.abdominals] * 5 + [mt.diaphragm, mt.inner_intercostals, mt.outer_intercostals,
                                     mt.clavicle, mt.clavicle]
        self._k_pe = np.array([x.k_pe for x in per])
        self._b_pe = np.array([x.b_pe for x in per])
        self._inv_v_max = 1.0 / np.array([x.v_max for x in per])
        self._f_max = np.array([x.f_max for x in per])
        self.ratios = group_matrix(p)
        self.gain, self.length = gain, length
        self.lung = Lung(p.lung, p.chest_volume_l, (self.batch,))
        self._inv_r = 1.0 / p.ribcage_radius_m
        self._v_lo, self._inv_sw = p.residual_chest_volume_l, 1.0 / p.stop_width_l
        self._stop_c = math.exp((p.residual_chest_volume_l - p.total_chest_volume_l) / p.stop_width_l)
        self._v0, self._a_di = p.chest_volume_l, a_di
        self._w_dt, self._w_cache = None, None
        self._kp = p.spine_kp_nm_per_rad
        # the step runs in one compiled loop when numba is there (laughlab.hill.kernel); the explicit
        # flow scheme has no compiled step
        if p.lung.scheme == "implicit":
            from laughlab.hill import kernel as hill_kernel  # numba: imported only when a torso is built

            self._kernel = hill_kernel.AVAILABLE
        else:
            self._kernel = False
        self.reset()
        # preload: the rest pose is an equilibrium at the rest activations
        z = np.zeros((1, NQ))
        f0 = self._forces(z, z, (self._rest_act @ self.ratios)[None, :])[0][0]
        f0[:2] += C_P * self._stop(np.array([p.chest_volume_l]))[0][0] * self._chest_jacobian(z)[0]
        self.f_pre = -f0

    # -- state
    def reset(self) -> None:
        """Rest pose (all coordinates 0, at rest), lungs at their initial state (6.1)."""
        self.q = np.zeros((self.batch, NQ))
        self.qd = np.zeros((self.batch, NQ))
        self.t = 0.0
        self.lung.reset()
        self.v_cw = self.chest_volume(self.q)
        self.muscle_act = np.zeros((self.batch, NM))

    def set_state(self, q, qd, lung_state: dict) -> None:
        """Set coordinates, velocities and lung state (from :meth:`get_state`), broadcast to the batch."""
        self.q = np.broadcast_to(q, (self.batch, NQ)).copy()
        self.qd = np.broadcast_to(qd, (self.batch, NQ)).copy()
        self.lung.load(lung_state)
        self.v_cw = self.chest_volume(self.q)

    def get_state(self, index: int | None = None) -> tuple:
        """``(q, qd, lung_state)`` of the whole batch, or of one torso."""
        sl = slice(None) if index is None else index
        lung = {k: getattr(self.lung, k)[sl].copy() for k in ("v_lung", "v_pl", "p_pl", "p_lung", "ptm", "q")}
        return self.q[sl].copy(), self.qd[sl].copy(), lung

    # -- geometry
    def chest_volume(self, q) -> np.ndarray:
        """Chest-wall cavity volume ``V_cw = (V_cw,0 + A_di x_di)(1 + x_rc/R)^2`` (L)."""
        p = self.params
        rho = 1.0 + q[..., IRC] / p.ribcage_radius_m
        return (p.chest_volume_l + p.diaphragm_area_l_per_m * q[..., IDI]) * rho * rho

    def _chest_jacobian(self, q):
        p = self.params
        rho = 1.0 + q[:, IRC] / p.ribcage_radius_m
        base = p.chest_volume_l + p.diaphragm_area_l_per_m * q[:, IDI]
        return np.stack([2.0 * base * rho / p.ribcage_radius_m, p.diaphragm_area_l_per_m * rho * rho], axis=1)

    def _stop(self, v):
        """Chest-wall stop pressure near residual volume / total capacity (cm H2O) and its slope (per L).

        ``P_stop = p (e^{(V_lo - V)/s} - e^{(V - V_hi)/s})``; the second exponential is the
        first's reciprocal times ``e^{(V_lo - V_hi)/s}`` (one ``exp`` per call).
        """
        lo = np.exp(np.minimum(np.maximum((self._v_lo - v) * self._inv_sw, -50.0), 50.0))
        hi = self._stop_c / lo
        ps = self.params.stop_pressure_cmh2o
        return ps * (lo - hi), -(ps * self._inv_sw) * (lo + hi)

    def abdominal_pressure(self, q=None) -> np.ndarray:
        """Abdominal pressure relative to rest ``P_ab = -E_ab dV_ab`` (cm H2O)."""
        q = self.q if q is None else q
        return -self.params.abdomen.contents_elastance_cmh2o_per_l * (q @ self.a_ab)

    # -- dynamics
    def _forces(self, q, qd, act):
        """Generalised forces of the muscles, tissue and abdominal contents (no pressure, preload, spine target).

        Returns the forces and the muscles' implicit weights (:func:`_hill`) and strain rates.
        """
        dl = q @ self._jt_over_l                  # l~ - 1
        s = qd @ self._jt_over_l
        f, k_imp, d_imp = _hill(act, dl, s, self._k_pe, self._b_pe, self._inv_v_max, self._f_max)
        force = -(f @ self._gj) - q @ self.k_lin - qd @ self.d_lin
        return force, k_imp, d_imp, s

    def step(self, group_act, spine_target=0.0, dt: float = 1.0 / 240.0) -> None:
        """Advance one step of ``dt`` s with group activations ``(batch, 6)`` (``GROUPS`` order).

        ``spine_target`` is the spine flexion the PD servo aims at (rad).
        """
        self._step(np.minimum(np.maximum(group_act, 0.0), 1.0) @ self.ratios, spine_target, dt)

    def step_muscles(self, muscle_act, spine_target=0.0, dt: float = 1.0 / 240.0) -> None:
        """Advance one step with activations per muscle ``(batch, 10)`` (``MUSCLES`` order; lowest level).

        Linearly implicit Euler (module notes): ``(M + dt D + dt^2 K) dv = dt (F -
        dt K v)``.  The pressure on the chest wall (pleural pressure and volume
        stops) is taken at the predicted volume ``V_cw(q + dt q')`` with its
        slope there, the pleural part from the lung's own update
        (:meth:`laughlab.hill.lung.Lung.predict`: the pleural gas in series with the
        airway), so the step stays accurate when the gas equilibrates faster
        than ``dt``.
        """
        self._step(np.clip(muscle_act, 0.0, 1.0), spine_target, dt)

    def _step(self, a, spine_target, dt: float) -> None:
        if self._kernel:
            return self._step_compiled(a, spine_target, dt)
        self.muscle_act = a
        q, qd, b = self.q, self.qd, self.batch
        force, k_imp, d_imp, s = self._forces(q, qd, a)
        force += self.f_pre
        force[:, ISP] += self._kp * spine_target
        # implicit matrix W = M + dt D + dt^2 K and the right side dt (F - dt K v)
        w = ((dt * d_imp + (dt * dt) * k_imp) * self._g_over_l) @ self._jj
        w = w.reshape(b, NQ, NQ)
        w += self._w_cache if dt == self._w_dt else self._w_lin(dt)
        rhs = force - dt * ((k_imp * s * self.gain) @ self.J + qd @ self.k_lin)
        # chest wall: pleural pressure and volume stops at the predicted volume, with their slope
        rho = 1.0 + q[:, IRC] * self._inv_r
        base = self._v0 + self._a_di * q[:, IDI]
        a2 = np.empty((b, 2))
        a2[:, 0] = (2.0 * self._inv_r) * base * rho
        a2[:, 1] = self._a_di * rho * rho
        v_pred = self.chest_volume(q + dt * qd)
        p_stop, dstop = self._stop(v_pred)
        p_pl, slope = self.lung.predict(v_pred, dt)
        rhs[:, :2] += (C_P * (p_pl + p_stop))[:, None] * a2
        w[:, :2, :2] -= ((dt * dt * C_P) * (slope + dstop))[:, None, None] * (a2[:, :, None] * a2[:, None, :])
        dv = _solve(w, (dt * rhs)[:, :, None])[:, :, 0]
        self.qd = qd = qd + dv
        self.q = q + dt * qd
        self.v_cw = self.chest_volume(self.q)
        self.lung.step(self.v_cw, dt)
        self.t += dt

    def _step_compiled(self, a, spine_target, dt: float) -> None:
        """:meth:`_step` by :func:`laughlab.hill.kernel.step_batch` (same arithmetic, one compiled loop)."""
        b = self.batch
        # activations of one torso may come as (10,) (the numpy step broadcasts them): one row per torso
        self.muscle_act = a = np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), (b, NM)))
        spine = np.broadcast_to(np.asarray(spine_target, dtype=float), (b,)).copy()
        lung, lp = self.lung, self.lung.params
        if self.q.base is not None or not self.q.flags.c_contiguous:
            self.q, self.qd = self.q.copy(), self.qd.copy()
        for name in Lung.STATE:
            arr = getattr(lung, name)
            if arr.base is not None or not arr.flags.c_contiguous:
                setattr(lung, name, arr.copy())
        v_cw = np.empty(b)
        ptm_a = lung._ptm_a if isinstance(lung._ptm_a, np.ndarray) else np.full(b, lung._ptm_a)
        from laughlab.hill import kernel as hill_kernel

        hill_kernel.step_batch(
            self.q, self.qd, a, spine, float(dt), self._jt_over_l, self._gj, self.k_lin, self.d_lin, self.f_pre,
            float(self._kp), ISP, self.J, self.gain, self._g_over_l, self._w_lin(dt), self._k_pe, self._b_pe,
            self._inv_v_max, self._f_max, W_FL, A_FV, B_FV, _PE_EXP_CAP, self._inv_r, self._v0, self._a_di, IRC,
            IDI, self._v_lo, self._inv_sw, self._stop_c, float(self.params.stop_pressure_cmh2o), C_P,
            lung.v_lung, lung.v_pl, lung.p_pl, lung.ptm, lung.p_lung, lung.q, lung.v_pl_min, lung.p_pl0,
            ptm_a, float(lung._ptm_b), float(lung._c_atm), float(lp.k), P_ATM, CMH2O_PER_ATM, v_cw)
        if lung._scalar:   # the plain-float copy of the state a single torso's lungs keep (laughlab.hill.lung)
            lung._f = {k: float(getattr(lung, k).flat[0]) for k in Lung.STATE}
        self.v_cw = v_cw
        self.t += dt

    def _w_lin(self, dt: float) -> np.ndarray:
        """``M + dt D_lin + dt^2 K_lin`` (cached per step size)."""
        if self._w_dt != dt:
            self._w_cache = np.diag(self.mass) + dt * self.d_lin + dt * dt * self.k_lin
            self._w_dt = dt
        return self._w_cache

    # -- outputs
    @property
    def lung_pressure(self) -> np.ndarray:
        """Lung pressure relative to the atmosphere (cm H2O)."""
        return self.lung.gauge_cmh2o


def simulate(torso: Torso, group_act, spine_target=None, dt: float = 1.0 / 240.0, every: int = 1,
             record=("p_lung", "v_cw", "v_lung")) -> dict:
    """Run ``torso`` through ``S`` steps of group activations; record every ``every``-th step.

    Parameters
    ----------
    group_act : ndarray (S, batch, 6) or (S, 6)
        Group activations per step (``GROUPS`` order).
    spine_target : ndarray (S, batch) or (S,), optional
        Spine flexion target per step (rad).
    dt : float
        Step (s).
    every : int
        Record after steps ``every-1, 2*every-1, ...``.
    record : tuple of str
        Any of ``p_lung`` (cm H2O), ``v_cw``, ``v_lung`` (L), ``flow`` (L/s), ``q`` (coordinates),
        ``p_ab`` (cm H2O).

    Returns
    -------
    dict of ndarray, each (S // every, batch[, ...]).
    """
    acts = np.asarray(group_act, dtype=float)
    if acts.ndim == 2:
        acts = acts[:, None, :]
    n = acts.shape[0]
    spine = np.zeros((n, 1)) if spine_target is None else np.asarray(spine_target, dtype=float).reshape(n, -1)
    out = {k: [] for k in record}
    for i in range(n):
        torso.step(acts[i], spine[i], dt)
        if (i + 1) % every == 0:
            for k in record:
                out[k].append(_value(torso, k))
    return {k: np.array(v) for k, v in out.items()}


def _value(torso: Torso, key: str) -> np.ndarray:
    if key == "p_lung":
        return torso.lung.gauge_cmh2o.copy()
    if key == "v_cw":
        return torso.v_cw.copy()
    if key == "v_lung":
        return torso.lung.v_lung.copy()
    if key == "flow":
        return torso.lung.q.copy()
    if key == "q":
        return torso.q.copy()
    if key == "p_ab":
        return torso.abdominal_pressure()
    raise KeyError(f"unknown record {key!r}")
