"""Body ``follow`` (Ding et al. 2014, 4.3): the PD controller by hand and independent of the frame rate,
Perlin noise properties, the head-pitch sources and the one-frame delay, chest/belly as ``shapes``."""
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings, strategies as st
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core import plugins
from laughlab.core.bases import Context
from laughlab.core.config import compose_config
from laughlab.motion.clips import ClipLibrary
from laughlab.core.frame import ClipEvent, Frame
from laughlab.motion.noise import NoiseSignal, Perlin1D, fade, splitmix64
from laughlab_plugins import body_follow, face_facs
from laughlab_plugins.body_follow import FollowBody, FollowParams, PDController, clip_head_pitch, pd_torque
from laughlab_plugins.body_shapes import ShapesBody, ShapesParams

ROOT = Path(__file__).resolve().parents[1]
FPS = 60.0
DT = 1.0 / FPS
JOINTS = ("spine", "spine1", "spine2", "left_clavicle", "right_clavicle")


@pytest.fixture(scope="module")
def lib():
    return ClipLibrary.load()


# --- PD controller ----------------------------------------------------------------------------

def test_pd_torque_by_hand():
    # tau = kp (target - alpha) - kd alpha_dot = 10 (5 - 1) - 2 * 3 = 34
    assert pd_torque(5.0, 1.0, 3.0, 10.0, 2.0) == pytest.approx(34.0)
    assert pd_torque(0.0, 0.0, 0.0, 10.0, 2.0) == 0.0


def test_pd_one_step_by_hand():
    # critically damped (kp = w^2 = 4, kd = 2w = 4) from rest towards 1:
    # alpha(t) = 1 - (1 + 2t) e^-2t, alpha_dot(t) = 4t e^-2t; one step of 0.1 s:
    pd = PDController(4.0, 4.0)
    assert pd.step(1.0, 0.1) == pytest.approx(1.0 - 1.2 * math.exp(-0.2), rel=1e-12)  # 0.0175231
    assert pd.alpha_dot == pytest.approx(0.4 * math.exp(-0.2), rel=1e-12)              # 0.3274923
    # the step solves alpha'' = tau of Eq. PD: compare with a fine explicit integration
    a = v = 0.0
    h = 1e-5
    for _ in range(10000):
        v += h * pd_torque(1.0, a, v, 4.0, 4.0)
        a += h * v
    assert a == pytest.approx(1.0 - 1.2 * math.exp(-0.2), abs=1e-5)


@pytest.mark.parametrize("kp,kd", [(36.0, 9.6), (100.0, 14.0), (4.0, 0.5), (0.0, 3.0)])
def test_pd_does_not_depend_on_the_frame_rate(kp, kd):
    ends = []
    for fps in (24, 30, 60, 120, 1000):
        pd = PDController(kp, kd)
        n = int(round(0.5 * fps))
        for k in range(n):
            pd.step(10.0, 1.0 / fps)
        ends.append((pd.alpha, pd.alpha_dot))
    np.testing.assert_allclose(ends, [ends[0]] * len(ends), rtol=1e-9, atol=1e-9)


# --- Perlin noise -----------------------------------------------------------------------------

def test_perlin_zero_at_the_lattice_points():
    n = Perlin1D(seed=7, stream=2)
    pts = np.arange(-50, 51)
    assert np.all(n(pts.astype(float)) == 0.0)
    assert all(n(float(i)) == 0.0 for i in pts)


def test_perlin_fade_and_formula_by_hand():
    assert fade(0.0) == 0.0 and fade(1.0) == 1.0 and fade(0.5) == 0.5
    n = Perlin1D(seed=3)
    g0, g1 = n.gradient(4), n.gradient(5)
    u = 0.25
    s = 6 * u**5 - 15 * u**4 + 10 * u**3
    assert n(4.25) == pytest.approx((1 - s) * g0 * u + s * g1 * (u - 1))
    assert -1.0 <= g0 <= 1.0 and g0 != g1


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-1e4, 1e4), seed=st.integers(0, 2**40))
def test_perlin_continuous_bounded_and_slope_at_lattice(x, seed):
    n = Perlin1D(seed)
    h = 1e-7
    assert abs(n(x + h) - n(x)) < 1e-5          # continuity (|n'| <= 2)
    assert abs(n(x)) <= 0.5                      # the bound of Eq. N1
    i = math.floor(x)
    slope = (n(i + 1e-7) - n(i - 1e-7)) / 2e-7   # C1 across the lattice point: slope = its gradient
    assert slope == pytest.approx(n.gradient(i), abs=1e-5)


def test_perlin_seeded_reproducibility_and_vector_equals_scalar():
    x = np.linspace(-20, 20, 2001)
    a, b = Perlin1D(11, 1)(x), Perlin1D(11, 1)(x)
    assert np.array_equal(a, b)
    assert not np.allclose(a, Perlin1D(12, 1)(x)) and not np.allclose(a, Perlin1D(11, 2)(x))
    n = Perlin1D(11, 1)
    np.testing.assert_allclose([n(float(v)) for v in x], a, rtol=0, atol=1e-15)
    assert splitmix64(0) == 0xE220A8397B1DCDAF  # SplitMix64's first output for state 0
    assert np.abs(a).max() > 0.1  # not degenerate


def test_noise_signal_peak_and_time_scale():
    s = NoiseSignal(seed=1, stream=0, frequency_hz=0.5, amplitude=2.0, octaves=3)
    v = np.array([s(t) for t in np.arange(0, 60, 0.01)])
    assert np.abs(v).max() <= 2.0 and np.abs(v).max() > 0.5
    assert np.abs(np.diff(v)).max() < 0.2  # smooth at 100 Hz sampling


# --- the body ---------------------------------------------------------------------------------

def body(seed=0, fps=FPS, lib=None, **kw):
    ctx = Context(fps=fps, rng=np.random.default_rng(seed), seed=seed)
    if lib is not None:
        ctx._clips = lib
    return FollowBody(FollowParams(**kw), ctx)


def test_offsets_channels_and_chest_belly_as_shapes(lib):
    b = body(lib=lib)
    s = ShapesBody(ShapesParams(), Context())
    for k in range(120):
        fr, fs = Frame(k, k * DT, DT, {"mcs": 0.7 * (k % 20 < 8)}), Frame(k, k * DT, DT, {"mcs": 0.7 * (k % 20 < 8)})
        b.step(fr)
        s.step(fs)
        assert set(fr.offsets) == set(JOINTS)
        assert (fr.channels["chest"], fr.channels["belly"]) == (fs.channels["chest"], fs.channels["belly"])
        for j in JOINTS:
            assert len(fr.offsets[j]) == 3 and all(math.isfinite(v) for v in fr.offsets[j])


def test_face_head_pitch_one_frame_late_drives_the_torso(lib):
    p = FollowParams(head_source="face", noise_deg=0.0, noise_shoulder_deg=0.0)
    b = body(lib=lib, **{k: getattr(p, k) for k in ("head_source", "noise_deg", "noise_shoulder_deg")})
    pd_t, pd_s = PDController(p.torso_kp, p.torso_kd), PDController(p.shoulder_kp, p.shoulder_kd)
    face_pitch = [0.0] * 10 + [12.0] * 50
    for k, hp in enumerate(face_pitch):
        fr = Frame(k, k * DT, DT, {"mcs": 0.0})
        b.step(fr)
        used = face_pitch[k - 1] if k else 0.0  # the value the face wrote in the previous frame
        assert fr.channels["follow_head_pitch"] == used
        a_t, a_s = pd_t.step(p.torso_gain * used, DT), pd_s.step(p.shoulder_gain * used, DT)
        assert fr.channels["torso_pitch"] == pytest.approx(a_t) and fr.channels["shoulder_angle"] == pytest.approx(a_s)
        for j, share in zip(("spine", "spine1", "spine2"), p.torso_split):
            assert fr.offsets[j] == pytest.approx((0.0, share * a_t, 0.0))
        assert fr.offsets["left_clavicle"] == pytest.approx((a_s, 0.0, -0.5 * a_s))
        assert fr.offsets["right_clavicle"] == pytest.approx((-a_s, 0.0, 0.5 * a_s))
        fr.channels["head_pitch"] = hp  # the face steps after the body
    assert fr.channels["torso_pitch"] == pytest.approx(0.4 * 12.0, rel=0.02)  # settled: torso_gain x head pitch


def test_clip_head_pitch_source_tracks_the_playing_clip(lib):
    b = body(lib=lib, head_source="clip", noise_deg=0.0, noise_shoulder_deg=0.0)
    pitch = clip_head_pitch(lib)
    rofl = lib["rofl"]
    for k in range(200):
        fr = Frame(k, k * DT, DT, {"mcs": 0.5})
        if k == 30:
            fr.events.append(ClipEvent(fr.time_s, "start", "rofl", 40.0, speed=1.5))
        b.step(fr)
        if 30 <= k < 30 + rofl.duration_s / 1.5 * FPS - 1:
            f = (k - 30) * DT * 1.5 * rofl.fps
            i = int(f)
            want = pitch["rofl"][i] + (f - i) * (pitch["rofl"][i + 1] - pitch["rofl"][i])
            assert fr.channels["follow_head_pitch"] == pytest.approx(want)
    assert max(pitch["rofl"]) > 60  # rofl bends far forward
    # auto: the clip until a face writes head_pitch, then the face
    b = body(lib=lib)
    fr0 = Frame(0, 0.0, DT, {"mcs": 0.0})
    b.step(fr0)
    fr1 = Frame(1, DT, DT, {"mcs": 0.0})
    b.step(fr1)
    fr1.channels["head_pitch"] = -7.0
    fr2 = Frame(2, 2 * DT, DT, {"mcs": 0.0})
    b.step(fr2)
    assert fr2.channels["follow_head_pitch"] == -7.0


def test_noise_keeps_it_moving_seeded_from_ctx_seed(lib):
    def offsets(seed):
        b = body(seed, lib=lib, head_source="none")
        out = []
        for k in range(300):
            fr = Frame(k, k * DT, DT, {"mcs": 0.0})
            b.step(fr)
            out.append([v for j in JOINTS for v in fr.offsets[j]])
        return np.array(out)
    a = offsets(4)
    assert np.array_equal(a, offsets(4)) and not np.allclose(a, offsets(5))
    moving = np.ptp(a, axis=0)
    assert (moving[[0, 1, 2, 3, 4, 5, 6, 7, 8]] > 0.05).all()  # every torso axis moves (no freezing)
    assert np.abs(a[:, :9]).max() <= 1.0 + 1e-9                 # peak noise_deg on the torso


def test_body_is_nearly_frame_rate_independent(lib):
    def torso_at_1s(fps):
        b = body(fps=fps, lib=lib, head_source="face", noise_deg=0.0, noise_shoulder_deg=0.0)
        n = int(round(1.0 * fps))
        for k in range(n):
            fr = Frame(k, k / fps, 1.0 / fps, {"mcs": 0.0})
            b.step(fr)
            fr.channels["head_pitch"] = 10.0 if k / fps >= 0.2 else 0.0
        return fr.channels["torso_pitch"]
    vals = [torso_at_1s(f) for f in (30, 60, 120)]
    np.testing.assert_allclose(vals, vals[1], rtol=0.01)


def test_params_validated():
    with pytest.raises(ValueError, match="head_source"):
        FollowParams(head_source="neck")
    with pytest.raises(ValueError, match="torso_split"):
        FollowParams(torso_split=[0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="noise_hz"):
        FollowParams(noise_hz=0.0)


def test_yaml_equals_the_dataclass_defaults():
    values = yaml.safe_load((ROOT / "conf/body/follow.yaml").read_text())
    assert values.pop("name") == "follow"
    assert values == OmegaConf.to_container(OmegaConf.structured(FollowParams))



def run(tmp, *overrides):
    cfg = compose_config(["input.duration_s=4", "input.save_audio=false", "output=trial", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    pipeline.execute(pipeline.build(cfg), tmp)
    return pd.read_csv(tmp / "channels.csv")


def test_end_to_end_interchangeable_with_shapes(registered, tmp_path):
    shapes = run(tmp_path / "shapes", "body=shapes", "face=facs")
    follow = run(tmp_path / "follow", "body=follow", "face=facs")
    np.testing.assert_array_equal(follow["chest"], shapes["chest"])
    np.testing.assert_array_equal(follow["belly"], shapes["belly"])
    np.testing.assert_array_equal(follow["head_pitch"].shift(1).fillna(0.0)[1:], follow["follow_head_pitch"][1:])
    assert (tmp_path / "follow" / "motion.bvh").read_text() != (tmp_path / "shapes" / "motion.bvh").read_text()
