"""Lung pressure model (DiLorenzo 2008, 6.1, Eqs. 1-4) against hand-computed values."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from laughlab.hill.lung import (CMH2O_PER_ATM, Lung, LungParams, boyle, flow, implicit_volume,
                           transmural)

ATM = CMH2O_PER_ATM  # 1033.2275 cm H2O


def test_units_and_initial_state():
    assert ATM == pytest.approx(1033.2275, rel=1e-7)
    lung = Lung(LungParams(), 5.0)
    # 6.1: lung volume 80 % of the chest wall's rest volume, lung pressure one atmosphere
    assert lung.v_lung == pytest.approx(4.0)
    assert lung.p_lung == pytest.approx(1.0)
    assert lung.v_pl == pytest.approx(1.0)
    # Eq. 1 at the start: P_pl = P_lung - P_tm(V_0) = 1 atm - 5 cm H2O
    assert lung.p_pl == pytest.approx(1.0 - 5.0 / ATM)
    assert lung.gauge_cmh2o == pytest.approx(0.0)


def test_transmural_is_linear_in_volume():
    p = LungParams()
    # P_tm(V) = 5 cm H2O + (V - V0) / 0.2 L/cmH2O
    assert transmural(3.0, 3.0, p) * ATM == pytest.approx(5.0)
    assert transmural(3.2, 3.0, p) * ATM == pytest.approx(6.0)
    assert transmural(2.5, 3.0, p) * ATM == pytest.approx(2.5)


def test_eq2_boyle():
    assert boyle(1.0, 1.0, 0.9) == pytest.approx(1.0 / 0.9)
    assert boyle(0.9951608, 1.0, 0.9) == pytest.approx(1.1057342, rel=1e-7)
    assert boyle(2.0, 0.5, 1.0) == pytest.approx(1.0)


def test_eq4_flow_keeps_the_sign_of_dp():
    k = 8.2e-4
    assert flow(8.2e-4, k) == pytest.approx(1.0)          # dP = k -> 1 L/s out
    assert flow(-8.2e-4 * 4, k) == pytest.approx(-2.0)    # suction: 2 L/s in
    assert flow(0.0, k) == 0.0
    assert flow(0.11057342, k) == pytest.approx(11.61231, rel=1e-5)


def test_explicit_two_loop_step_by_hand():
    """The paper's loop as printed, one 1 ms step after squeezing the chest from 5.0 to 4.9 L."""
    lung = Lung(LungParams(scheme="explicit"), 5.0)
    dt = 1e-3
    lung.step(4.9, dt)
    # loop 1: Eq. 2 with the new V_cw and the old V_lung (V_pl 1.0 -> 0.9); Eq. 1 with the old P_tm
    p_pl = (1.0 - 5.0 / ATM) / 0.9                         # 1.1057342 atm
    p_star = p_pl + 5.0 / ATM                              # intermediate P_lung
    assert p_pl == pytest.approx(1.1057342, rel=1e-7)
    # loop 2: Eq. 4 from the intermediate pressure, Eq. 3, then Eqs. 2 and 1 again
    q = math.sqrt((p_star - 1.0) / 8.2e-4)                 # 11.6123 L/s out
    x = q * dt
    assert lung.q == pytest.approx(q)
    assert lung.v_lung == pytest.approx(4.0 - x)
    assert lung.v_pl == pytest.approx(0.9 + x)
    p_pl2 = p_pl * 0.9 / (0.9 + x)
    assert lung.p_pl == pytest.approx(p_pl2)
    assert lung.p_lung == pytest.approx(p_pl2 + (5.0 - x / 0.2) / ATM)


def test_implicit_step_takes_the_flow_at_the_end_of_step_pressure():
    dp, s, dt, k = 0.01, 1.4, 4e-3, 8.2e-4
    x = implicit_volume(dp, s, dt, k)
    assert x == pytest.approx(dt * math.sqrt((dp - s * x) / k), rel=1e-12)
    assert 0.0 < x < dp / s                                # never past atmospheric
    assert implicit_volume(-dp, s, dt, k) == pytest.approx(-x)
    assert implicit_volume(0.0, s, dt, k) == 0.0


def test_flow_sign_squeeze_and_expand():
    lung = Lung(LungParams(), 3.75)
    lung.step(3.70, 4e-3)                                  # chest squeezed
    assert lung.gauge_cmh2o > 0 and lung.q > 0 and lung.v_lung < 3.0
    lung = Lung(LungParams(), 3.75)
    lung.step(3.80, 4e-3)                                  # chest expanded
    assert lung.gauge_cmh2o < 0 and lung.q < 0 and lung.v_lung > 3.0


@pytest.mark.parametrize("scheme,dt", [("implicit", 1 / 240), ("explicit", 1e-4)])
def test_lung_volume_change_equals_integrated_flow(scheme, dt):
    rng = np.random.default_rng(1)
    lung = Lung(LungParams(scheme=scheme), 3.75)
    v_cw = 3.75 + 0.3 * np.sin(np.linspace(0, 12, 2000)) + 0.01 * rng.standard_normal(2000)
    integral = 0.0
    for v in v_cw:
        lung.step(v, dt)
        integral += lung.q * dt
    assert lung.v_lung - 3.0 == pytest.approx(-integral, abs=1e-12)


def test_boyle_product_is_conserved():
    """Eq. 2 holds across wall motion and flow: P_pl V_pl never changes."""
    lung = Lung(LungParams(), 3.75)
    c0 = lung.p_pl * lung.v_pl
    for v in 3.75 + 0.4 * np.sin(np.linspace(0, 20, 500)):
        lung.step(v, 1 / 240)
        assert lung.p_pl * lung.v_pl == pytest.approx(c0, rel=1e-12)


def test_steady_squeeze_holds_k_q_squared():
    """Squeezing the chest at r = 1 L/s: the flow settles at Q = r / (1 + V_pl / (P_pl C_L)), the
    lung pressure at k Q^2 (about 8.2e-4 atm = 0.847 cm H2O).

    Q < r by the pleural space's own shrinkage: as the lungs empty, P_tm falls at Q/C_L, P_pl rises
    as much, and Boyle's law shrinks V_pl at V_pl/P_pl times that rate.
    """
    lung = Lung(LungParams(), 3.75)
    dt = 1 / 240
    for i in range(1, 121):                                # 0.5 s
        lung.step(3.75 - 1.0 * i * dt, dt)
    q = 1.0 / (1.0 + lung.v_pl / (lung.p_pl * 0.2 * ATM))  # 0.99638 L/s
    assert q == pytest.approx(0.99638, abs=1e-4)
    assert lung.q == pytest.approx(q, rel=1e-4)
    assert lung.gauge_cmh2o == pytest.approx(8.2e-4 * q * q * ATM, rel=1e-3)


def test_implicit_relaxation_never_overshoots():
    lung = Lung(LungParams(), 3.75)
    lung.step(3.70, 1 / 240)
    prev = lung.gauge_cmh2o
    for _ in range(200):                                   # chest held: pressure decays to 0 without changing sign
        lung.step(3.70, 1 / 240)
        assert -1e-9 <= lung.gauge_cmh2o <= prev + 1e-12
        prev = lung.gauge_cmh2o
    assert prev < 1e-3


def test_explicit_loop_rattles_at_large_steps():
    """Why the default is implicit: the printed explicit loop at 4 ms overshoots atmospheric."""
    lung = Lung(LungParams(scheme="explicit"), 3.75)
    signs = set()
    for _ in range(50):
        lung.step(3.70, 4e-3)
        signs.add(np.sign(lung.gauge_cmh2o))
    assert {-1.0, 1.0} <= signs


def test_params_validate():
    with pytest.raises(ValueError):
        LungParams(k=0)
    with pytest.raises(ValueError):
        LungParams(initial_fraction=1.0)
    with pytest.raises(ValueError):
        LungParams(scheme="rk4")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(2.2, 7.0), min_size=1, max_size=60), st.sampled_from([1 / 60, 1 / 240, 1e-3]))
def test_any_chest_volume_path_keeps_volumes_positive_and_finite(path, dt):
    lung = Lung(LungParams(), np.full(3, 3.75), (3,))
    for v in path:
        lung.step(np.array([v, v * 0.99, v * 1.01]), dt)
        for arr in (lung.v_lung, lung.v_pl, lung.p_pl, lung.p_lung, lung.q):
            assert np.isfinite(arr).all()
        assert (lung.v_lung > 0).all() and (lung.v_pl > 0).all() and (lung.p_pl > 0).all()
