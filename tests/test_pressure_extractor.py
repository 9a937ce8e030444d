"""Extractor ``pressure`` (DiLorenzo 2008, 6): Butterworth envelope, linear fit, normalisation, MCS."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from omegaconf import OmegaConf
from scipy.signal import lfilter, lfilter_zi

from laughlab.core import pipeline
from laughlab.core import plugins
from laughlab.io.audio import cut_frames
from laughlab.core.bases import Context
from laughlab.core.config import compose_config
from laughlab.core.frame import Frame
from laughlab_plugins import body_hill, extractor_pressure
from laughlab_plugins.extractor_pressure import PressureExtractor, PressureParams, fit_line



def frames_of(ext, audio, sr, fps, sizes=None):
    """Run the extractor over ``audio`` cut into frames (optionally delivered in chunks of ``sizes``)."""
    if sizes is None:
        chunks = [audio]
    else:
        chunks, i, k = [], 0, 0
        while i < len(audio):
            chunks.append(audio[i:i + sizes[k % len(sizes)]])
            i, k = i + sizes[k % len(sizes)], k + 1
    out = []
    for k, block in enumerate(cut_frames(chunks, sr, fps)):
        f = Frame(k, k / fps, 1 / fps)
        ext.step(block, f)
        out.append(dict(f.control))
    return out


def test_first_order_butterworth_by_hand():
    """Bilinear transform of 1/(1 + s/wc) with prewarping: K = tan(pi fc / fs)."""
    ext = PressureExtractor(PressureParams(cutoff_hz=10.0), Context(fps=60, sample_rate=16000))
    k = math.tan(math.pi * 10.0 / 16000)
    np.testing.assert_allclose(ext.b, [k / (1 + k), k / (1 + k)], rtol=1e-12)
    np.testing.assert_allclose(ext.a, [1.0, (k - 1) / (k + 1)], rtol=1e-12)
    assert sum(ext.b) / sum(ext.a) == pytest.approx(1.0)          # unit DC gain


def test_step_response_time_constant():
    """|x| = 1 from t = 0: after one time constant 1/(2 pi fc) = 15.9 ms the envelope is 1 - 1/e."""
    sr = 16000
    ext = PressureExtractor(PressureParams(cutoff_hz=10.0), Context(fps=60, sample_rate=sr))
    y = ext.envelope(np.ones(sr // 2, dtype=np.float32))
    tau = 1 / (2 * math.pi * 10.0)
    assert y[int(round(tau * sr))] == pytest.approx(1 - math.exp(-1), abs=2e-3)
    assert y[-1] == pytest.approx(1.0, abs=1e-6)


def test_streaming_equals_offline_bit_for_bit():
    rng = np.random.default_rng(0)
    sr, fps = 16000, 60
    audio = (rng.standard_normal(sr * 2) * np.abs(np.sin(np.arange(sr * 2) * 2 * np.pi * 5 / sr))).astype(np.float32)
    ext = PressureExtractor(None, Context(fps=fps, sample_rate=sr))
    x = np.abs(audio.astype(np.float64))
    first = int(round(sr / fps))      # the first frame's block: the filter starts at rest at its mean level
    whole = lfilter(ext.b, ext.a, x, zi=lfilter_zi(ext.b, ext.a) * x[:first].mean())[0]
    ends = np.round(np.arange(1, 121) * sr / fps).astype(int) - 1
    a = frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr, fps)
    b = frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr, fps, [160, 1024, 37, 4096, 5])
    assert [f["env"] for f in a] == [float(v) for v in whole[ends]]     # the one-shot lfilter, exactly
    assert a == b                                                         # any chunking, every control


def test_linear_fit_noise_floor_and_normalisation_by_hand():
    """Envelope values set by hand (empty blocks keep them), values worked out by hand from the module's equations:
    raw = 2 env + 0.5; the floor is the lowest raw of the last 3 frames; the excess over it is normalised by the
    mean of (prior_weight 1 x the highest excess so far) and the peaks counted so far; a peak counts the frame
    after it (it must be a local maximum)."""
    p = PressureParams(slope_cmh2o=2.0, intercept_cmh2o=0.5, reference_cmh2o=0.5, floor_fraction=0.3,
                       prior_weight=1.0, intensity=1.0, mcs_full_cmh2o=1.0, noise_window_s=3 / 60, peak_over_noise=1.0)
    ext = PressureExtractor(p, Context(fps=60, sample_rate=8000))
    envs = [0.05, 0.05, 0.25, 0.05, 0.05, 0.35, 0.05, 0.15, 0.15, 0.15]
    out = []
    for e in envs:
        ext.env = e
        f = Frame()
        ext.step(np.zeros(0, dtype=np.float32), f)
        out.append(dict(f.control))
    assert [round(c["pressure_raw"], 12) for c in out] == [0.6, 0.6, 1.0, 0.6, 0.6, 1.2, 0.6, 0.8, 0.8, 0.8]
    pressure = [c["pressure"] for c in out]
    # frame 2: excess 0.4, the highest so far and the only term of the mean: r = 1, the reference
    assert pressure[2] == pytest.approx(0.5)
    # frame 3 counts the peak 0.4; frame 5: excess 0.6, mean (0.6 + 0.4) / 2 = 0.5, r = 1.2
    assert pressure[5] == pytest.approx(0.5 * (1.2 - 0.3) / 0.7)
    assert out[5]["mcs"] == pytest.approx(0.5 * 0.9 / 0.7)
    # frame 6 counts the peak 0.6: mean (0.6 + 0.4 + 0.6) / 3; frame 7's excess 0.2 is r = 0.375
    assert pressure[7] == pytest.approx(0.5 * (0.2 / (1.6 / 3) - 0.3) / 0.7)
    # frame 8 counts frame 7's 0.2 (0.3 of the mean is 0.16, the floor's 0.1 above the intercept): mean 1.8 / 4
    assert pressure[8] == pytest.approx(0.5 * (0.2 / 0.45 - 0.3) / 0.7)
    assert ext.peak_count == 3 and ext.peak_sum == pytest.approx(1.2)
    # frame 9: the last 3 frames all 0.8, the floor rose to it: no excess, no pressure
    assert ext.noise == pytest.approx(0.8) and pressure[9] == 0.0
    assert [pressure[k] for k in (0, 1, 3, 4, 6)] == [0.0] * 5


def test_the_recordings_level_does_not_matter():
    """The paper's normalisation "accounts for differences in recording levels": the same laugh at any gain from
    -60 dB to full scale gives the same pressure (the noise floor and the peaks scale with it)."""
    sr, fps = 16000, 60
    t = np.arange(sr * 4) / sr
    rng = np.random.default_rng(1)
    calls = np.where((t > 1.0) & ((t % 0.22) < 0.09), 1.0, 0.0)
    audio = (0.5 * calls * np.sin(2 * np.pi * 250 * t) + 0.003 * rng.standard_normal(t.size)).astype(np.float32)
    ref = [f["pressure"] for f in frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr, fps)]
    assert max(ref) > 0.05
    for gain in (0.3, 0.01, 0.001):
        got = [f["pressure"] for f in frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)),
                                                 (audio * np.float32(gain)), sr, fps)]
        np.testing.assert_allclose(got, ref, rtol=1e-4, atol=1e-9)


def test_a_rooms_steady_noise_drives_no_pressure():
    """Two seconds of white noise at -60, -50 and -40 dBFS before the calls: the noise floor takes it (the fixed
    prior had left -40 dBFS at 0 but a level-free one without the floor drove the full reference)."""
    sr, fps = 16000, 60
    rng = np.random.default_rng(2)
    t = np.arange(sr * 4) / sr
    calls = np.where((t > 2.0) & ((t % 0.22) < 0.09), 1.0, 0.0)
    for db in (-60, -50, -40):
        noise = 10 ** (db / 20) * rng.standard_normal(t.size)
        audio = (0.3 * calls * np.sin(2 * np.pi * 250 * t) + noise).astype(np.float32)
        p = [f["pressure"] for f in frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr,
                                              fps)]
        assert max(p[:2 * fps]) == 0.0, db
        assert max(p[2 * fps:]) > 0.05, db


def test_fit_line_recovers_a_line():
    e = np.linspace(0, 0.1, 50)
    slope, intercept = fit_line(e, 30.0 * e + 0.5)
    assert slope == pytest.approx(30.0) and intercept == pytest.approx(0.5)


def test_intensity_scales_the_pressure():
    rng = np.random.default_rng(2)
    audio = (rng.standard_normal(16000) * 0.1).astype(np.float32)
    one = frames_of(PressureExtractor(PressureParams(intensity=1.0), Context(fps=60, sample_rate=16000)), audio,
                    16000, 60)
    two = frames_of(PressureExtractor(PressureParams(intensity=2.0), Context(fps=60, sample_rate=16000)), audio,
                    16000, 60)
    np.testing.assert_allclose([f["pressure"] for f in two], [2 * f["pressure"] for f in one], rtol=1e-12)


def test_average_call_maps_to_the_reference():
    """16 equal calls after 50 ms of silence: each is counted once as a peak, and as the prior (the highest excess
    so far) and the peaks are all the call's height, every call, the first too, maps to the reference."""
    sr, fps = 16000, 60
    t = np.arange(sr * 4) / sr
    env = np.where((t >= 0.05) & (((t - 0.05) % 0.25) < 0.1), 1.0, 0.0)
    audio = (0.2 * env * np.sign(np.sin(2 * np.pi * 300 * t))).astype(np.float32)
    ext = PressureExtractor(None, Context(fps=fps, sample_rate=sr))
    frames = frames_of(ext, audio, sr, fps)
    raw = np.array([f["pressure_raw"] for f in frames])
    p = np.array([f["pressure"] for f in frames])
    h = raw[-60:].max()
    assert h == pytest.approx(0.2 * (1 - np.exp(-2 * np.pi * 5.0 * 0.1)), rel=0.002)   # a 0.1 s pulse through 5 Hz
    assert ext.peak_count == 16
    calls = [p[int((0.05 + 0.25 * i) * fps):int((0.05 + 0.25 * (i + 1)) * fps)].max() for i in range(16)]
    # the reference, 0.1 cm H2O, from the first call on: 1.3 % under it once the 2 s floor window has left the first
    # silence (the floor is then the valleys' ~1 % of a call, exp(-2 pi 5 Hz 0.15 s))
    np.testing.assert_allclose(calls[:8], 0.1, rtol=3e-4)
    np.testing.assert_allclose(calls[8:], 0.1 * (1 - np.exp(-2 * np.pi * 5 * 0.15)), rtol=0.006)
    assert ext.mean_peak == pytest.approx(h, rel=0.01)
    gaps = [p[int((0.05 + 0.25 * i + 0.2) * fps)] for i in range(15)]
    assert max(gaps) == 0.0                               # the floor fraction clears the gaps


def test_nonfinite_samples_count_as_silence():
    ext = PressureExtractor(None, Context(fps=60, sample_rate=8000))
    f = Frame()
    ext.step(np.array([np.nan, np.inf, -np.inf, 0.5] * 40, dtype=np.float32), f)
    assert ext.nonfinite_samples == 120
    assert all(math.isfinite(v) for v in f.control.values())


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.floats(-1.5, 1.5, width=32),
                          st.sampled_from([0.0, 1e30, -1e30, float("nan"), float("inf"), 1e-30])),
                min_size=1, max_size=3000))
def test_outputs_finite_and_mcs_in_unit_interval(samples):
    ext = PressureExtractor(None, Context(fps=60, sample_rate=8000))
    for f in frames_of(ext, np.array(samples, dtype=np.float32), 8000, 60):
        assert all(math.isfinite(v) for v in f.values()), f
        assert 0.0 <= f["mcs"] <= 1.0 and f["pressure"] >= 0.0


def test_params_validate():
    for bad in (dict(cutoff_hz=0), dict(slope_cmh2o=0.0), dict(reference_cmh2o=0), dict(floor_fraction=1.0),
                dict(intensity=-1), dict(slope_cmh2o=-1.0), dict(noise_window_s=0),
                dict(peak_over_noise=-1), dict(slope_cmh2o=1e-320), dict(prior_weight=1e-320)):
        with pytest.raises(ValueError):
            PressureParams(**bad)
    with pytest.raises(ValueError):
        PressureExtractor(PressureParams(cutoff_hz=5000.0), Context(fps=60, sample_rate=8000))


def test_works_with_every_face_and_scheduler(hill_plugins, tmp_path):
    """The extractor writes mcs, so the thesis' face, body and scheduler run on it unchanged."""
    cfg = compose_config(["extractor=pressure", "input.duration_s=4", "input.save_audio=false"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    pipe = pipeline.build(cfg)
    pipe.sinks = [plugins.create("sink", "csv", {}, pipe.ctx)]
    pipeline.execute(pipe, tmp_path)
    head = (tmp_path / "channels.csv").read_text().splitlines()[0].split(",")
    for col in ("rms", "env", "pressure", "mcs", "energy", "chest", "belly", "smile", "jaw"):
        assert col in head


def test_the_mean_peak_forgets_past_peak_memory_and_is_the_cumulative_mean_before():
    """A soak review: the mean peak height was the cumulative mean of every peak since the start, so after hours a
    change of room or gain barely moved it.  Below ``peak_memory`` peaks it is that mean, as before; past it each new
    peak replaces 1/peak_memory of the sum, and a level held long enough becomes the mean."""
    ext = PressureExtractor(PressureParams(peak_memory=20, prior_weight=1.0), Context(fps=60, sample_rate=16000))
    ext.noise = 0.0

    def pulses(height, n):
        for _ in range(n):
            for v in (0.0, height, 0.0):   # a local maximum, then a fall below valley_fraction of it
                ext._peak(v)

    pulses(1.0, 10)
    assert ext.peak_count == 10 and ext.peak_sum == pytest.approx(10.0)   # the cumulative mean, as before
    pulses(1.0, 30)
    assert ext.peak_count == 20 and ext.peak_sum == pytest.approx(20.0)
    pulses(3.0, 200)                                            # the room got louder and stayed so
    prior = max(ext.top, ext._least())   # the prior's peak (step() keeps the top; here only _peak ran)
    held = 3.0 * 20 * (1 - (1 - 1 / 20) ** 200) + 20 * (1 - 1 / 20) ** 200   # the sum after 200 louder peaks
    assert ext.peak_count == 20 and ext.peak_sum == pytest.approx(held, rel=1e-9)
    assert ext.mean_peak == pytest.approx((prior + held) / 21, rel=1e-9) and ext.peak_sum / 20 > 2.99
    with pytest.raises(ValueError, match="peak_memory"):
        PressureParams(peak_memory=0)
