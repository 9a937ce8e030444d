"""Rise/fall (van Duijn 2014, Eq. 3.2) and the Smoother (listing 5.3), checked by hand."""
import numpy as np
import pytest
from hypothesis import given, strategies as st

from laughlab.signals.smoothing import BELLY, CHEST, JAW, SMILE, Smoother, SmootherParams, rate_limit, rate_limit_series


def test_thesis_smoother_constants_are_per_tick_times_60():
    assert (JAW.rise, JAW.fall, JAW.max_e) == pytest.approx((1.8, 0.6, 0.8))
    assert (SMILE.rise, SMILE.fall, SMILE.max_e) == pytest.approx((1.8, 0.06, 0.3))
    assert (CHEST.rise, CHEST.fall) == pytest.approx((12.0, 6.0))
    assert (BELLY.rise, BELLY.fall) == pytest.approx((6.0, 3.0))


def test_rate_limit_eq_3_2_by_hand():
    assert rate_limit(1.0, 0.0, 0.4, 0.2) == 0.4      # rise limited
    assert rate_limit(0.3, 0.0, 0.4, 0.2) == 0.3      # small rise passes
    assert rate_limit(0.0, 0.9, 0.4, 0.2) == pytest.approx(0.7)  # fall limited
    assert rate_limit(0.8, 0.9, 0.4, 0.2) == 0.8      # small fall passes


def test_smile_smoother_listing_5_3_by_hand():
    # smile: rise 0.03/tick, fall 0.001/tick, maxE 0.3, at 60 fps
    s = Smoother(SMILE, 1 / 60)
    out = [s.smooth(1.0) for _ in range(3)]
    assert out == pytest.approx([0.03 / 0.3, 0.06 / 0.3, 0.09 / 0.3])
    for _ in range(20):
        s.smooth(1.0)
    assert s.smooth(1.0) == 1.0          # e = 0.72 > maxE -> 1, not 2.4
    e_before = s.e
    assert s.smooth(0.0) == 1.0          # falls only 0.001 per tick
    assert s.e == pytest.approx(e_before - 0.001)


def test_smoother_rescales_below_min_to_zero():
    s = Smoother(SmootherParams(rise=60.0, fall=60.0, min_e=0.2, max_e=0.6), 1 / 60)
    assert s.smooth(0.1) == 0.0
    assert s.smooth(0.4) == pytest.approx(0.5)


def test_rates_are_frame_rate_independent():
    x = np.r_[np.zeros(30), np.ones(300), np.zeros(300)]
    t60 = np.arange(len(x)) / 60
    y60 = rate_limit_series(x, 0.5, 0.3, 1 / 60)
    x120 = np.repeat(x, 2)
    y120 = rate_limit_series(x120, 0.5, 0.3, 1 / 120)
    assert np.interp(t60, np.arange(len(x120)) / 120, y120) == pytest.approx(y60, abs=0.01)


@given(st.lists(st.floats(-10, 10), min_size=1, max_size=200), st.floats(0.01, 100), st.floats(0.01, 100))
def test_rate_limit_never_exceeds_rates(xs, rise, fall):
    dt = 1 / 60
    y = rate_limit_series(np.array(xs), rise, fall, dt)
    d = np.diff(np.r_[0.0, y])
    assert np.all(d <= rise * dt + 1e-12) and np.all(d >= -fall * dt - 1e-12)
    # and it is the signal itself whenever one step can reach it, else one whole step towards it (an output stuck
    # at 0 passed the bounds above)
    prev = np.r_[0.0, y[:-1]]
    want = np.clip(np.array(xs), prev - fall * dt, prev + rise * dt)
    assert y == pytest.approx(want, abs=1e-9)


def test_value_rescales_the_state_without_a_step():
    """``Smoother.value()``: the state re-scaled as a step would (a face reads it after taking some back)."""
    s = Smoother(SmootherParams(60.0, 60.0, 0.2, 0.6), 1 / 60)
    for e, want in ((0.4, 0.5), (0.1, 0.0), (0.7, 1.0), (0.2, 0.0), (0.5, 0.75)):
        s.e = e
        assert s.value() == pytest.approx(want)
    assert s.e == 0.5                               # no step taken
