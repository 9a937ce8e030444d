"""Equations, tables and printed values of DiLorenzo 2008, Unuma 1995 and Ding 2014 checked on cases
worked by hand (docs/fidelity.md cites these tests; the equations already checked by hand
elsewhere are cited there, not repeated here).

Every expected number is computed from the paper's equation or copied from the paper, never from the
code under test; the arithmetic is in the comments.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

# --- DiLorenzo, Zordan & Sanders 2008 ------------------------------------------------------------

#: cm H2O per atmosphere: 101325 Pa / 98.0665 Pa
ATM_CMH2O = 101325.0 / 98.0665          # 1033.2274528


def test_dilorenzo_eq4_k_as_printed_and_flow_by_hand():
    """Eq. 4, Q = sqrt(dP / k), k = 8.2e-4 atm s^2/L^2 (6.1, after Slutsky et al.), sign of dP kept."""
    from laughlab.hill.lung import LungParams, flow

    assert LungParams().k == 8.2e-4
    # dP = 1 cm H2O = 1 / 1033.2275 atm = 9.67842e-4 atm; dP / k = 1.180295; sqrt = 1.086413 L/s
    dp = 1.0 / ATM_CMH2O
    assert flow(dp, LungParams().k) == pytest.approx(1.086413, rel=1e-6)
    assert flow(-dp, LungParams().k) == pytest.approx(-1.086413, rel=1e-6)   # suction: inflow


def test_dilorenzo_6_1_initial_state_as_printed():
    """6.1: V_lung = 80 % of the chest wall's rest volume; P_lung = one atmosphere."""
    from laughlab.hill.lung import Lung, LungParams

    assert LungParams().initial_fraction == 0.8
    lung = Lung(LungParams(), 3.75)
    assert float(lung.v_lung) == pytest.approx(0.8 * 3.75)               # 3.0 L
    assert float(lung.p_lung) == 1.0                                     # 1 atm, absolute
    # Eq. 1 at the start: P_pl = P_lung - P_tm = 1 atm - 5 cm H2O (P_tm,0 ours) = 0.99516 atm
    assert float(lung.p_pl) == pytest.approx(1.0 - 5.0 / ATM_CMH2O, rel=1e-12)


def test_dilorenzo_eq1_uses_the_previous_ptm_on_the_second_step_by_hand():
    """Eqs. 1-4 over two steps of the printed two-loop update (scheme ``explicit``): on the second
    step the intermediate P_lung takes the P_tm left by the first step, not the initial one.

    Chest wall 5.0 L at rest (V_lung 4.0 L, V_pl 1.0 L), squeezed to 4.9 L, then 4.85 L, dt = 1 ms;
    P_tm(V) = 5 cm H2O + (V - 4.0) / 0.2 L/cmH2O (Fig. 5 linearised, our values); k = 8.2e-4.
    Step 1 (as test_lung.py::test_explicit_two_loop_step_by_hand):
      V_pl 1.0 -> 0.9; P_pl = (1 - 5/1033.2275) / 0.9 = 1.1057342 atm        (Eq. 2)
      P* = P_pl + 5/1033.2275 = 1.1105734 atm                               (Eq. 1, previous P_tm)
      Q = sqrt(0.1105734 / 8.2e-4) = 11.612305 L/s; x1 = Q dt = 0.011612305 L (Eq. 4)
      V_lung = 4.0 - x1 = 3.9883877 L                                       (Eq. 3, outflow)
      V_pl = 0.9 + x1 = 0.9116123 L; P_pl = 1.1057342 * 0.9 / 0.9116123 = 1.0916491 atm
      P_tm = (5 - x1 / 0.2) / 1033.2275 atm = 4.9419385 cm H2O
    Step 2:
      V_pl = 4.85 - 3.9883877 = 0.8616123 L; P_pl = 1.0916491 * 0.9116123 / 0.8616123 = 1.1549984 atm
      P* = 1.1549984 + 4.9419385 / 1033.2275 = 1.1597814 atm (gauge 165.0905 cm H2O)
      Q = sqrt(0.1597814 / 8.2e-4) = 13.959059 L/s; x2 = 0.013959059 L
      V_lung = 3.9883877 - 0.0139591 = 3.9744286 L; V_pl = 0.8616123 + 0.0139591 = 0.8755714 L
      P_pl = 1.1549984 * 0.8616123 / 0.8755714 = 1.1365844 atm
      P_tm = 5 - (x1 + x2) / 0.2 = 4.8721432 cm H2O
      P_lung = 1.1365844 atm + 4.8721432 cm H2O: gauge 145.99494 cm H2O
    """
    from laughlab.hill.lung import Lung, LungParams

    lung = Lung(LungParams(scheme="explicit"), 5.0)
    lung.step(4.9, 1e-3)
    assert float(lung.v_lung) == pytest.approx(3.9883877, abs=1e-7)
    assert float(lung.ptm) * ATM_CMH2O == pytest.approx(4.9419385, abs=1e-7)
    lung.step(4.85, 1e-3)
    assert float(lung.q) == pytest.approx(13.959059, rel=1e-7)
    assert float(lung.v_lung) == pytest.approx(3.9744286, abs=1e-7)
    assert float(lung.v_pl) == pytest.approx(0.8755714, abs=1e-7)
    assert float(lung.p_pl) == pytest.approx(1.1365844, rel=1e-7)
    assert float(lung.ptm) * ATM_CMH2O == pytest.approx(4.8721432, abs=1e-7)
    assert float(lung.gauge_cmh2o) == pytest.approx(145.99494, rel=1e-6)


# the activation table of section 7, as printed: diaphragm, abdomen, intercostals ("-" = not active)
ACTIVATION_TABLE = {
    "giggle": (0.05, 0.125, 0.2),
    "normal_laugh": (0.05, 0.5, 0.5),
    "deep_laugh": (0.05, 1.0, 0.5),
    "breath": (0.1, 0.0, 0.3),
    "cough": (0.05, 1.0, 1.0),
}


@pytest.mark.parametrize("name", sorted(ACTIVATION_TABLE))
def test_dilorenzo_activation_table_every_row_as_printed(name):
    """Peak group activations of each hand-crafted behaviour equal the printed table (section 7);
    laughs: inner intercostals in phase with the abdomen, outer out of phase (the text)."""
    from laughlab.hill.presets import preset
    from laughlab.hill.torso import GROUPS

    t = np.arange(0, preset(name).duration_s, 1 / 1000)
    a = preset(name).activations(t)
    di, ab, ic = ACTIVATION_TABLE[name]
    col = {g: a[:, GROUPS.index(g)] for g in GROUPS}
    assert col["diaphragm"].max() == pytest.approx(di, abs=1e-6)
    assert col["abdomen"].max() == pytest.approx(ab, abs=1e-4)
    assert col["inner_intercostals"].max() == pytest.approx(ic, abs=1e-4)
    assert col["outer_intercostals"].max() == pytest.approx(ic, abs=1e-4)
    if name.endswith("laugh") or name == "giggle":
        # calls at 5 Hz from t = 0.2 s: the abdomen peaks half a period in (0.3 s), the outer
        # intercostals half a period later (0.4 s), when the abdomen is at its trough
        k_peak, k_trough = 300, 400
        assert col["abdomen"][k_peak] == pytest.approx(ab, abs=1e-9)
        assert col["inner_intercostals"][k_peak] == pytest.approx(ic, abs=1e-9)
        assert col["outer_intercostals"][k_peak] == pytest.approx(0.0, abs=1e-9)
        assert col["outer_intercostals"][k_trough] == pytest.approx(ic, abs=1e-9)


def test_dilorenzo_activation_table_sneeze_rows_as_printed():
    """sneeze: ah- 0.1 / 0 / 0.2 (outer only); -choo 0.0 / 1.0 / 0.8 (inner only)."""
    from laughlab.hill.presets import preset
    from laughlab.hill.torso import GROUPS

    p = preset("sneeze")
    t = np.arange(0, p.duration_s, 1 / 1000)
    a = p.activations(t)
    g = {name: a[:, GROUPS.index(name)] for name in GROUPS}
    ah = t < 1.2                        # the three inhales (0.2 s to 1.1 s); -choo starts at 1.25 s
    choo = ~ah
    assert g["diaphragm"][ah].max() == pytest.approx(0.1, abs=1e-6)
    assert g["abdomen"][ah].max() == 0.0
    assert g["outer_intercostals"][ah].max() == pytest.approx(0.2, abs=1e-6)
    assert g["inner_intercostals"][ah].max() == 0.0
    assert g["diaphragm"][choo].max() == 0.0
    assert g["abdomen"][choo].max() == pytest.approx(1.0, abs=1e-9)
    assert g["inner_intercostals"][choo].max() == pytest.approx(0.8, abs=1e-9)
    assert g["outer_intercostals"][choo].max() == 0.0


# --- Unuma, Anjyo & Takeuchi 1995 ----------------------------------------------------------------

def test_unuma_eq1_rescaled_fourier_model_by_hand():
    """Eq. 1, Theta(t) = A0 + sum_n A_n sin(n t + phi_n), with real time rescaled to period 2 pi.

    A0 = 1, A1 = 2, phi1 = 0, A2 = 0.5, phi2 = pi/2; measured period T = 0.8 s.
    At tau = 0.2 s: t = 2 pi 0.2 / 0.8 = pi/2; Theta = 1 + 2 sin(pi/2) + 0.5 sin(pi + pi/2) = 1 + 2 - 0.5 = 2.5.
    At tau = 0.4 s: t = pi; Theta = 1 + 2 sin(pi) + 0.5 sin(2 pi + pi/2) = 1 + 0 + 0.5 = 1.5.
    step = 1.8 (Fig. 9): A_n -> 1.8 A_n, A0 kept: at t = pi/2, 1 + 3.6 - 0.9 = 3.7.
    """
    from laughlab.fourier.model import FourierModel

    m = FourierModel([1.0], [[2.0], [0.5]], [[0.0], [math.pi / 2]], period_s=0.8)
    assert m.at_time(np.array([0.2, 0.4]))[:, 0] == pytest.approx([2.5, 1.5], abs=1e-12)
    assert m.with_step(1.8)(math.pi / 2)[0] == pytest.approx(3.7, abs=1e-12)


def test_unuma_eq7_eq8_characteristic_function_by_hand():
    """Eqs. 7-1, 7-2 and 8 with phases 3.0 and -3.0 rad: Eq. 7-2 gives phi^12 = 6.0 rad (laughlab
    keeps it as 6.0 - 2 pi, the same angle), and Psi(t) = (A^1 - A^2) + A^12 sin(t + 6.0).

    Phi^1: A0 = 2, A1 = 3, phi1 = 3.0; Phi^2: A0 = 0.5, A1 = 1, phi1 = -3.0.
    A0^12 = 1.5, A1^12 = 2, phi1^12 = 6.0.  At t = 0: Psi = 1.5 + 2 sin(6.0) = 1.5 - 0.558831 = 0.941169.
    At t = 1: Psi = 1.5 + 2 sin(7.0) = 1.5 + 1.313973 = 2.813973.
    """
    from laughlab.fourier.blend import characteristic
    from laughlab.fourier.model import FourierModel

    p1 = FourierModel([2.0], [[3.0]], [[3.0]])
    p2 = FourierModel([0.5], [[1.0]], [[-3.0]])
    ch = characteristic(p1, p2)
    assert ch.amp[0, 0] == pytest.approx(2.0)
    assert math.cos(ch.phase[0, 0]) == pytest.approx(math.cos(6.0)) and math.sin(ch.phase[0, 0]) == pytest.approx(
        math.sin(6.0))
    assert ch(np.array([0.0, 1.0]))[:, 0] == pytest.approx([0.941169, 2.813973], abs=1e-6)


# --- Ding, Prepin, Huang, Pelachaud & Artieres 2014 ---------------------------------------------

#: section 3, in the order printed (occurrences in AVLaughterCycle in parentheses there)
DING_PSEUDO_PHONEMES = ("silence", "ne", "click", "nasal", "plosive", "fricative", "ic", "e", "o", "grunt",
                        "cackle", "a", "glotstop", "vowel")


def test_ding_section3_fourteen_pseudo_phonemes_as_printed():
    from laughlab.concat.segments import PSEUDO_PHONEMES
    from laughlab.face import cgm
    from laughlab.io.textgrid import PHONEMES

    assert len(DING_PSEUDO_PHONEMES) == 14
    assert tuple(PSEUDO_PHONEMES) == DING_PSEUDO_PHONEMES
    assert tuple(PHONEMES) == DING_PSEUDO_PHONEMES
    # one CGM per pseudo-phoneme (4.1: "a set of 14 CGMs")
    assert set(cgm.load_default().models) == set(DING_PSEUDO_PHONEMES)


def test_ding_eq1_face_mean_with_intensity_and_f0_by_hand(tmp_path):
    """Eq. 1, mu(theta) = W theta + mu_bar, on the face's own path (CgmFace.predict), theta = (I dB, F0 Hz).

    W = [[0.01, 0.001], [0.005, 0.0005], [0.0, 0.002]], mu_bar = [-0.5, 0.0, 0.1]; theta = (60, 200):
      jaw        = 0.01 * 60 + 0.001 * 200 - 0.5 = 0.6 + 0.2 - 0.5 = 0.3
      lip_open   = 0.005 * 60 + 0.0005 * 200 + 0 = 0.3 + 0.1 = 0.4
      lip_corner = 0 * 60 + 0.002 * 200 + 0.1 = 0.5
    theta = (90, 400): jaw = 0.9 + 0.4 - 0.5 = 0.8; lip 0.45 + 0.2 = 0.65; corner 0.8 + 0.1 = 0.9.
    theta = (20, 100): jaw = 0.2 + 0.1 - 0.5 = -0.2, kept at 0 (outputs in [0, 1]).
    """
    from laughlab.core.bases import Context
    from laughlab.face.cgm import CGM, CGMSet
    from laughlab_plugins.face_cgm import CgmFace, CgmParams

    z = np.array([[0.01, 0.001, -0.5], [0.005, 0.0005, 0.0], [0.0, 0.002, 0.1]])
    m = CGM(z, np.eye(3) * 0.01, 10, np.array([60.0, 250.0]))
    assert m.mean([60.0, 200.0]) == pytest.approx([0.3, 0.4, 0.5], abs=1e-12)
    path = CGMSet({"a": m}).save(tmp_path / "hand.json")
    face = CgmFace(CgmParams(model=str(path)), Context(rng=np.random.default_rng(0)))
    assert face.predict("a", 60.0, 200.0) == pytest.approx((0.3, 0.4, 0.5), abs=1e-12)
    assert face.predict("a", 90.0, 400.0) == pytest.approx((0.8, 0.65, 0.9), abs=1e-12)
    assert face.predict("a", 20.0, 100.0)[0] == 0.0


def test_ding_fig3_duration_cost_rises_faster_than_continuity_cost_by_hand():
    """Fig. 3: C_Dur = f(v) = e^v - 1 against C_Cont = g(v) = v^2 ("the duration cost increases much
    quicker than the continuity cost").  v = 0.5: 0.648721 vs 0.25; v = 1: 1.718282 vs 1;
    v = 2: 6.389056 vs 4; v = 3: 19.085537 vs 9.  (C_cont's argument is a distance: 1 m = 100 cm.)"""
    from laughlab.concat.costs import c_cont, c_dur

    for v, f, g in ((0.5, 0.648721, 0.25), (1.0, 1.718282, 1.0), (2.0, 6.389056, 4.0), (3.0, 19.085537, 9.0)):
        assert c_dur(v, 0.0) == pytest.approx(f, abs=1e-6)
        assert c_dur(0.0, v) == pytest.approx(f, abs=1e-6)          # |d - d'|
        assert c_cont([0.0], [100.0 * v]) == pytest.approx(g, abs=1e-12)
        assert f > g


def test_ding_greedy_local_cost_by_hand():
    """4.2, the real-time variant: gamma C_Dur(d(s), d(p)) + (1 - gamma) C_Cont(s', s), segment by segment.

    gamma = 0.25, target d(p) = 1.0 s, previous segment ends at 0 cm.  Candidates of class a:
      s0: 1.2 s, first pose at 50 cm:  0.25 (e^0.2 - 1) + 0.75 * 0.5^2 = 0.25 * 0.221403 + 0.1875 = 0.242851
      s1: 1.6 s, first pose at 0 cm:   0.25 (e^0.6 - 1) + 0 = 0.25 * 0.822119 = 0.205530
    s1 is chosen.  Without a previous segment the continuity term is 0: 0.055351 vs 0.205530, s0.
    """
    from laughlab.concat.costs import choose, local_costs
    from laughlab.concat.segments import Segment, SegmentDB

    db = SegmentDB([Segment("c0", 0.0, 1.2, "a", np.array([50.0]), np.array([0.0]), 0.0),
                    Segment("c1", 0.0, 1.6, "a", np.array([0.0]), np.array([0.0]), 0.0),
                    Segment("p", 0.0, 1.0, "silence", np.array([0.0]), np.array([0.0]), 0.0)])
    assert local_costs(db, np.array([0, 1]), 1.0, 0.25, prev=2) == pytest.approx([0.242851, 0.205530], abs=1e-6)
    assert choose(db, "a", 1.0, 0.25, prev=2) == 1
    assert local_costs(db, np.array([0, 1]), 1.0, 0.25) == pytest.approx([0.055351, 0.205530], abs=1e-6)
    assert choose(db, "a", 1.0, 0.25) == 0
