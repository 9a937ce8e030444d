"""Fourier functional models (Unuma, Anjyo, Takeuchi 1995) and the ``fourier`` body driver."""
from __future__ import annotations

from dataclasses import fields
from importlib.resources import files

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from laughlab.fourier import blend as fb
from laughlab.fourier import model as fr
from laughlab.core import plugins
from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab.signals.smoothing import Smoother
from laughlab_plugins import body_fourier as bf

TWO_PI = 2 * np.pi


def synthetic(mean, amp, phase, t):
    """Eq. 1 written out: mean + sum_n amp_n sin(n t + phase_n), shape (len(t), C)."""
    out = np.tile(np.asarray(mean, float), (len(t), 1))
    for n in range(len(amp)):
        out += np.asarray(amp[n]) * np.sin((n + 1) * t[:, None] + np.asarray(phase[n]))
    return out


MEAN = np.array([1.0, -2.0, 0.5])
AMP = np.array([[3.0, 1.0, 0.2], [0.5, 2.0, 0.0], [0.25, 0.1, 1.5]])
PHASE = np.array([[0.3, -1.0, 2.0], [2.0, 0.1, 0.0], [-2.5, 1.2, -0.7]])


# --- fitting (Eqs. 1 and 2, rescaled period) ------------------------------------------------------

@pytest.mark.parametrize("period, dt, n_frames", [(0.8, 1 / 60, 300), (0.7371, 1 / 30, 97), (2.31, 1 / 24, 150)])
def test_fit_recovers_known_coefficients_and_period(period, dt, n_frames):
    t = np.arange(n_frames) * dt
    y = synthetic(MEAN, AMP, PHASE, TWO_PI * t / period)
    for given_period in (period, None):  # known period, then estimated from the data
        m = fr.fit(y, dt, given_period, n_harmonics=3, period_range=(0.2, 3.0))
        assert m.period_s == pytest.approx(period, rel=1e-9, abs=0)
        np.testing.assert_allclose(m.mean, MEAN, atol=1e-9)
        np.testing.assert_allclose(m.amp, AMP, atol=1e-9)
        live = AMP > 0  # a zero amplitude has no phase
        np.testing.assert_allclose(fr.wrap(m.phase - PHASE)[live], 0.0, atol=1e-9)
        # rescaled time: one period of real time is 2 pi, and the model reproduces the samples
        assert m.rescaled(period) == pytest.approx(TWO_PI)
        np.testing.assert_allclose(m.at_time(t), y, atol=1e-9)


def test_fit_prefers_the_period_over_its_multiples_and_checks_its_input():
    dt = 1 / 60
    t = np.arange(400) * dt
    y = synthetic([0.0], [[2.0]], [[0.4]], TWO_PI * t / 0.5)  # one harmonic: 1.0 s fits as well with 2 harmonics
    assert fr.fit(y, dt, n_harmonics=2, period_range=(0.3, 1.6)).period_s == pytest.approx(0.5, rel=1e-9)
    with pytest.raises(ValueError, match="n_harmonics"):
        fr.fit(y, dt, 0.5, n_harmonics=8)  # at most 7 (Unuma 2.3)
    with pytest.raises(ValueError, match="too few"):
        fr.fit(y[:5], dt, 0.5, n_harmonics=3)
    with pytest.raises(ValueError, match="non-finite"):
        fr.fit(np.r_[y[:-1, 0], np.nan], dt, 0.5)
    assert fr.max_harmonics_for(1 / 4.5, 1 / 24) == 2 and fr.max_harmonics_for(4.0, 1 / 24) == 7


# --- Eq. 3: interpolation, extrapolation, transition ---------------------------------------------

A = fr.FourierModel([1.0, 0.0], [[2.0, 1.0], [0.5, 0.0]], [[0.2, -0.5], [1.0, 0.0]], period_s=4.0)
B = fr.FourierModel([3.0, -1.0], [[4.0, 3.0], [1.5, 2.0]], [[0.6, 0.5], [-1.0, 1.0]], period_s=1.0)


def eq3_by_hand(s, t):
    """Eq. 3 with the numbers of A and B typed in (B's 2nd-harmonic phase of channel 1 stands in for A's,
    whose amplitude is 0)."""
    c0 = (1 - s) * 1.0 + s * 3.0 + ((1 - s) * 2.0 + s * 4.0) * np.sin(t + (1 - s) * 0.2 + s * 0.6) \
        + ((1 - s) * 0.5 + s * 1.5) * np.sin(2 * t + (1 - s) * 1.0 + s * -1.0)
    c1 = (1 - s) * 0.0 + s * -1.0 + ((1 - s) * 1.0 + s * 3.0) * np.sin(t + (1 - s) * -0.5 + s * 0.5) \
        + (s * 2.0) * np.sin(2 * t + 1.0)
    return np.stack([c0, c1], axis=-1)


@pytest.mark.parametrize("s", [0.0, 1.0, 0.5, 1.5, -0.5])
def test_eq3_by_hand(s):
    t = np.linspace(0, TWO_PI, 50)
    xi = fb.interpolate(A, B, s)
    np.testing.assert_allclose(xi(t), eq3_by_hand(s, t), atol=1e-12)
    tr = fb.Transition(A, B)
    np.testing.assert_allclose([tr.value(s, th) for th in t], eq3_by_hand(s, t), atol=1e-12)
    assert xi.period_s == pytest.approx(4.0 ** (1 - s) * 1.0 ** s)  # geometric, > 0 for every s
    assert tr.period(s) == pytest.approx(xi.period_s)


def test_eq3_endpoints_midpoint_and_extrapolation():
    t = np.linspace(0, TWO_PI, 40)
    np.testing.assert_allclose(fb.interpolate(A, B, 0.0)(t), A(t), atol=1e-12)
    np.testing.assert_allclose(fb.interpolate(A, B, 1.0)(t), B(t), atol=1e-12)
    mid = fb.interpolate(A, B, 0.5)
    assert mid.amp[0, 0] == pytest.approx(3.0) and mid.phase[0, 0] == pytest.approx(0.4)  # amplitude, phase
    assert mid.mean[1] == pytest.approx(-0.5)
    ext = fb.interpolate(A, B, 1.5)
    assert ext.amp[0, 1] == pytest.approx(1.5 * 3.0 - 0.5 * 1.0) and ext.phase[0, 1] == pytest.approx(1.0)
    # phases blend the short way round: 3.0 and -3.0 rad are 0.28 rad apart, not 6
    a = fr.FourierModel([0.0], [[1.0]], [[3.0]])
    b = fr.FourierModel([0.0], [[1.0]], [[-3.0]])
    assert fb.interpolate(a, b, 0.5).phase[0, 0] == pytest.approx(np.pi)
    # the time-domain alternative (text reconstructed: (1-s) Theta + s Pi)
    np.testing.assert_allclose(fb.blend_time_domain(A, B, 0.25, t), 0.75 * A(t) + 0.25 * B(t))


def test_transition_follows_time_varying_s_and_speed():
    dt = 1 / 60
    tr = fb.Transition(A, B)
    s = np.linspace(0.0, 1.0, 240)
    out = tr.run(s, dt)
    theta = 0.0
    for k, v in enumerate(s):  # by hand: phase rate 2 pi / T(s), trapezoid over each frame, then Eq. 3
        if k:
            theta += dt * 0.5 * (TWO_PI / 4.0 ** (1 - s[k - 1]) + TWO_PI / 4.0 ** (1 - v))
        np.testing.assert_allclose(out[k], eq3_by_hand(v, theta), atol=1e-9)
    fast = fb.Transition(A, B, speed=2.0)
    fast.run(np.ones(31), dt)  # 30 frames = 0.5 s at s = 1 (T = 1 s) and speed 2: one full period
    assert min(fast.theta, TWO_PI - fast.theta) == pytest.approx(0.0, abs=1e-9)


# --- step and speed (3.1) ---------------------------------------------------------------------------

def test_speed_halves_the_period_and_step_scales_the_amplitudes():
    m = fr.FourierModel(MEAN, AMP, PHASE, period_s=0.8)
    t = np.linspace(0.0, 2.0, 301)
    np.testing.assert_allclose(m.at_time(t + 0.4, speed=2.0), m.at_time(t, speed=2.0), atol=1e-12)
    assert not np.allclose(m.at_time(t + 0.2, speed=2.0), m.at_time(t, speed=2.0), atol=1e-3)
    dt = 1 / 60
    refit = fr.fit(m.at_time(np.arange(200) * dt, speed=2.0), dt, n_harmonics=3, period_range=(0.25, 1.0))
    assert refit.period_s == pytest.approx(0.4, rel=1e-9)
    aligned = fr.align(m, 1)  # synchronised: channel 1's fundamental has phase 0, real-time motion unchanged
    assert aligned.phase[0, 1] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(aligned.at_time(t), m.at_time(t), atol=1e-12)
    big = m.with_step(1.8)
    np.testing.assert_allclose(big(t) - big.mean, 1.8 * (m(t) - m.mean), atol=1e-12)


# --- characteristics and superposition (Eqs. 6-8, 3.2) ----------------------------------------------

def test_characteristics_and_superposition_by_hand():
    walk = fr.FourierModel([0.0], [[10.0], [2.0]], [[0.0], [0.5]], period_s=1.0)        # Phi^2 (Eq. 6-2)
    brisk = fr.FourierModel([1.0], [[14.0], [3.0]], [[0.3], [0.2]], period_s=0.8)       # Phi^1 (Eq. 6-1)
    run = fr.FourierModel([5.0], [[20.0], [1.0]], [[-0.4], [1.0]], period_s=0.6)        # Pi (Eq. 2)
    ch = fb.characteristic(brisk, walk)
    np.testing.assert_allclose(ch.amp, [[4.0], [1.0]])            # Eq. 7-1
    np.testing.assert_allclose(ch.phase, [[0.3], [-0.3]])          # Eq. 7-2
    assert ch.mean[0] == pytest.approx(1.0) and ch.period_ratio == pytest.approx(0.8)
    t = np.linspace(0, TWO_PI, 30)
    np.testing.assert_allclose(ch(t)[:, 0], 1.0 + 4.0 * np.sin(t + 0.3) + 1.0 * np.sin(2 * t - 0.3))  # Eq. 8
    brisk_run = fb.superpose(run, ch, 1.0)
    by_hand = 6.0 + 24.0 * np.sin(t - 0.1) + 2.0 * np.sin(2 * t + 0.7)
    np.testing.assert_allclose(brisk_run(t)[:, 0], by_hand, atol=1e-12)
    assert brisk_run.period_s == pytest.approx(0.48)
    half = fb.superpose(run, ch, 0.5)
    np.testing.assert_allclose(half(t)[:, 0], 5.5 + 22.0 * np.sin(t - 0.25) + 1.5 * np.sin(2 * t + 0.85), atol=1e-12)
    # the difference of two motions superposed back onto the second gives the first
    np.testing.assert_allclose(fb.superpose(walk, ch, 1.0)(t), brisk(t), atol=1e-12)
    # Eq. 3 is the special case: interpolate(a, b, s) == superpose(a, characteristic(b, a), s)
    for s in (-0.5, 0.3, 1.7):
        np.testing.assert_allclose(fb.superpose(walk, fb.characteristic(run, walk), s)(t),
                                   fb.interpolate(walk, run, s)(t), atol=1e-12)


# --- shivering (3.3) ---------------------------------------------------------------------------------

def test_shiver_is_seeded_and_high_frequency():
    m = fr.FourierModel(MEAN, AMP, PHASE, period_s=1.0)
    a = fb.shiver(m, np.random.default_rng(7), 0.5)
    b = fb.shiver(m, np.random.default_rng(7), 0.5)
    c = fb.shiver(m, np.random.default_rng(8), 0.5)
    t = np.linspace(0, TWO_PI, 256, endpoint=False)
    np.testing.assert_array_equal(a(t), b(t))
    assert not np.allclose(a(t), c(t))
    noise = a(t) - m(t)
    spectrum = np.abs(np.fft.rfft(noise, axis=0)) ** 2  # bin n = harmonic n over one period
    assert spectrum[:8].sum() < 1e-20 * spectrum.sum()  # nothing at or below the 7th harmonic
    assert spectrum[8:16].sum() > 0.99 * spectrum.sum() and np.abs(noise).max() > 0.1
    with pytest.raises(ValueError):
        fb.shiver(m, np.random.default_rng(0), 0.5, first=3)


# --- the ``fourier`` body driver -----------------------------------------------------------------

@pytest.fixture(scope="module")
def registered():
    """The driver in the registry (its entry point once the lead adds it; registered here until then)."""
    if "fourier" in plugins.registry()["body"]:
        yield
        return
    plugins.pm.register(bf, name="test_fourier.body_fourier")
    try:
        yield
    finally:
        plugins.pm.unregister(name="test_fourier.body_fourier")


def driver(fps=60.0, **kw):
    return bf.FourierBody(bf.FourierParams(**kw), Context(fps=fps))


def test_the_default_motions_come_from_the_clips():
    body = driver()
    sway_a, sway_b = body.layers["sway"].a, body.layers["sway"].b
    shake_b = body.layers["shake"].b
    assert sway_a.period_s == pytest.approx(4.0)                   # the idle loop
    assert 0.8 < sway_b.period_s < 1.6                               # hands_on_belly's rocking
    assert 1 / shake_b.period_s == pytest.approx(4.5, abs=0.05)      # the clips' 4.5 Hz laughter shake
    assert np.abs(body.layers["shake"].a.amp).max() == 0.0           # idle does not shake
    assert all(m.n_harmonics <= fr.MAX_HARMONICS for m in (sway_a, sway_b, shake_b))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=200))
def test_driver_offsets_are_finite_and_s_tracks_the_smoothed_mcs(mcs):
    body = driver(gain=1.5, offset=-0.1)
    ref = Smoother(body.params.smoother, 1 / 60)
    for k, v in enumerate(mcs):
        f = Frame(k, k / 60, 1 / 60, {"mcs": v})
        body.step(f)
        assert f.channels["fourier_s"] == pytest.approx(-0.1 + 1.5 * ref.smooth(v), abs=1e-12)
        assert set(f.offsets) == set(bf.JOINTS)
        assert all(np.isfinite(f.offsets[j]).all() for j in bf.JOINTS)
        assert np.isfinite(f.channels["chest"]) and np.isfinite(f.channels["belly"])


def test_driver_is_frame_rate_independent():
    def run(fps, seconds=6.0):
        body = driver(fps)
        rows = []
        for k in range(int(seconds * fps)):
            t = k / fps
            # an MCS slower than the smoother's limits (0.63 /s < 1 /s), so both rates see the same s(t)
            f = Frame(k, t, 1 / fps, {"mcs": 0.5 - 0.5 * np.cos(TWO_PI * 0.2 * t)})
            body.step(f)
            rows.append([*np.ravel([f.offsets[j] for j in bf.JOINTS]), f.channels["fourier_s"], f.channels["chest"]])
        return np.array(rows)

    slow, fast = run(30.0), run(60.0)
    diff = np.abs(slow - fast[::2])
    assert diff[:, :27].max() < 0.01                 # degrees (trapezoid phase), offsets reach ~6 degrees
    assert np.abs(fast[:, :27]).max() > 3.0
    assert diff[:, 27].max() < 1e-9                   # s: the smoother's per-second rates
    assert diff[:, 28].max() < 1e-3                   # chest


def test_driver_chest_and_belly_pulse_with_the_shake():
    body = driver(pulse_depth=0.5)
    out = body.play(np.full(120, 1.0))
    assert np.allclose(out["chest"] + out["belly"], 1.0)
    assert out["belly"].min() == pytest.approx(0.5, abs=0.01) and out["belly"].max() == pytest.approx(1.0, abs=0.01)
    still = driver().play(np.zeros(60))
    assert np.allclose(still["chest"], 1.0) and np.allclose(still["belly"], 0.0)   # as body=shapes at rest
    # shoulders up when the belly squeezes: the exhalation pulse peaks with the left clavicle
    clav = out["offsets"][:, bf.CHANNELS.index("left_clavicle_Zrotation")]
    assert np.corrcoef(clav - clav.mean(), out["belly"])[0, 1] > 0.8


def test_driver_params_are_checked():
    for bad in ({"harmonics": 8}, {"pulse_depth": 1.5}, {"speed": -1.0}, {"shake_max_hz": 2.0},
                {"intense_bvh": "/nonexistent.bvh"}, {"arm_counter": 2.0}):
        with pytest.raises(ValueError):
            bf.FourierParams(**bad)
    with pytest.raises(ValueError, match="no clip"):
        driver(intense_clip="nope")


def test_driver_fits_given_bvh_files(tmp_path):
    from laughlab.io.bvh import write_bvh
    from laughlab.motion.clips import ClipLibrary

    lib = ClipLibrary.load()
    for name in ("idle", "hands_on_belly"):
        write_bvh(tmp_path / f"{name}.bvh", lib.skeleton, lib[name].poses, 1 / 24)
    body = driver(calm_bvh=str(tmp_path / "idle.bvh"), calm_bvh_loop=True,
                  intense_bvh=str(tmp_path / "hands_on_belly.bvh"))
    ref = driver()
    for layer in ("sway", "shake"):
        for side in ("a", "b"):
            got, want = getattr(body.layers[layer], side), getattr(ref.layers[layer], side)
            assert got.period_s == pytest.approx(want.period_s, rel=1e-3)
            np.testing.assert_allclose(got.amp, want.amp, atol=0.02)


def test_driver_shiver_and_speed():
    a = driver(shiver_deg=0.5)
    b = driver(shiver_deg=0.5)
    s = np.linspace(0, 1.25, 200)
    np.testing.assert_array_equal(a.play(s)["offsets"], b.play(s)["offsets"])  # same seed, same shiver
    assert a.layers["sway"].b.n_harmonics == 15
    fast = driver(speed=2.0)
    assert fast.layers["shake"].theta == 0.0
    fast.play(np.ones(61))  # 1 s at speed 2
    slow = driver()
    slow.play(np.ones(121))  # 2 s at speed 1: the same rescaled time
    assert fast.layers["shake"].theta == pytest.approx(slow.layers["shake"].theta, abs=1e-9)
    # its cost per frame is measured by benchmarks/bench_pipeline.py (per-plugin p50/p99), not here


def test_conf_yaml_equals_the_params_defaults():
    values = yaml.safe_load(files("laughlab_conf").joinpath("body", "fourier.yaml").read_text())
    assert values.pop("name") == "fourier"
    defaults = OmegaConf.to_container(OmegaConf.structured(bf.FourierParams))
    assert set(values) == {f.name for f in fields(bf.FourierParams)}
    for key, v in values.items():
        assert v == (pytest.approx(defaults[key]) if isinstance(v, float) else defaults[key]), key


def test_pipeline_with_body_fourier(registered, tmp_path):
    from laughlab.core import pipeline
    from laughlab.harness.runner import _compose

    cfg = _compose(["body=fourier", "input.duration_s=3", "input.save_audio=false", "~output.plots"])
    pipeline.execute(pipeline.build(cfg), tmp_path, {})
    import pandas as pd

    ch = pd.read_csv(tmp_path / "channels.csv")
    assert {"fourier_s", "chest", "belly"} <= set(ch.columns)
    assert ch["fourier_s"].max() > 0.5 and np.isfinite(ch.to_numpy()).all()


def test_experiment_fourier_blend(registered, tmp_path):
    from laughlab.core.config import compose_config
    from laughlab_experiments import fourier_blend

    cfg = compose_config(["experiment=fourier_blend", "harness.corpus.duration_s=3"])
    assert cfg.body.name == "fourier"
    doc = fourier_blend.run(cfg, tmp_path)
    for name in ("plots/fig3_blend.png", "plots/fig3_transition.png", "channels.csv", "events.csv", "motion.bvh",
                 "plots/fig4_2_energy.png", "metrics.json"):
        assert (tmp_path / name).is_file(), name
    assert doc["runs"]["fourier"]["duration_s"] == pytest.approx(3.0)


def test_a_motion_with_a_shake_and_a_rocking_is_fitted_as_two_layers_each_with_its_own_period():
    """The departure from 2.2's one period: a 4.5 Hz shake on a 1.25 s rocking (in no small whole ratio) gives a
    shake layer of period 1 / 4.5 s and a sway layer of 1.25 s, each with the paper's 3 harmonics."""
    from laughlab_plugins.body_fourier import CHANNELS, FourierParams, fit_motion

    dt = 1 / 60
    t = np.arange(int(10 / dt)) * dt
    y = np.zeros((t.size, len(CHANNELS)))
    y[:, CHANNELS.index("left_clavicle_Zrotation")] = 3.0 * np.sin(2 * np.pi * 4.5 * t)
    y[:, CHANNELS.index("spine2_Xrotation")] = 5.0 * np.sin(2 * np.pi * 0.8 * t)
    m = fit_motion(y, dt, False, FourierParams())
    assert m.shake.period_s == pytest.approx(1 / 4.5, rel=0.01)
    assert m.sway.period_s == pytest.approx(1.25, rel=0.02)
    assert m.shake.n_harmonics == 3 and m.sway.n_harmonics == 3
