"""Extractor ``pressure`` (DiLorenzo 2008, 6): Butterworth envelope, linear fit, normalisation, MCS."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from omegaconf import OmegaConf
from scipy.signal import lfilter

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
    whole = lfilter(ext.b, ext.a, np.abs(audio.astype(np.float64)))
    ends = np.round(np.arange(1, 121) * sr / fps).astype(int) - 1
    a = frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr, fps)
    b = frames_of(PressureExtractor(None, Context(fps=fps, sample_rate=sr)), audio, sr, fps, [160, 1024, 37, 4096, 5])
    assert [f["env"] for f in a] == [float(v) for v in whole[ends]]     # the one-shot lfilter, exactly
    assert a == b                                                         # any chunking, every control


def test_linear_fit_and_normalisation_by_hand():
    p = PressureParams(slope_cmh2o=2.0, intercept_cmh2o=0.0, reference_cmh2o=0.5, floor_fraction=0.3,
                       peak_prior=0.1, prior_weight=1.0, intensity=1.0, mcs_full_cmh2o=1.0)
    ext = PressureExtractor(p, Context(fps=60, sample_rate=8000))
    # feed pressure_raw values directly through the peak picker: peaks of 0.4 (env 0.2)
    raws = [0.0, 0.4, 0.0, 0.0, 0.4, 0.0]
    for r in raws:
        ext._peak(r)
    # two peaks seen: mean = (1 * 0.1 + 0.4 + 0.4) / 3 = 0.3
    assert ext.mean_peak == pytest.approx(0.3)
    f = Frame()
    ext.env = 0.15                       # raw = 2 * 0.15 = 0.3 = the mean peak: r = 1
    ext._prev = (0.0, 0.0)
    block = np.zeros(0, dtype=np.float32)  # empty block keeps the envelope
    ext.step(block, f)
    assert f.control["pressure_raw"] == pytest.approx(0.3)
    # r = 0.3 / mean; the frame's own raw 0.3 is not a peak yet (needs the next frame)
    r = 0.3 / ext.mean_peak
    assert f.control["pressure"] == pytest.approx(0.5 * max(0.0, r - 0.3) / 0.7)
    assert f.control["mcs"] == pytest.approx(min(1.0, f.control["pressure"] / 1.0))


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
    """16 equal calls: each is counted once as a peak, the mean peak is (prior + 16 h) / 17, and a
    call's peak maps to reference * (h / mean - floor) / (1 - floor), -> reference as calls accumulate."""
    sr, fps = 16000, 60
    t = np.arange(sr * 4) / sr
    env = np.where((t % 0.25) < 0.1, 1.0, 0.0)
    audio = (0.2 * env * np.sign(np.sin(2 * np.pi * 300 * t))).astype(np.float32)
    ext = PressureExtractor(None, Context(fps=fps, sample_rate=sr))
    frames = frames_of(ext, audio, sr, fps)
    raw = np.array([f["pressure_raw"] for f in frames])
    p = np.array([f["pressure"] for f in frames])
    h = raw[-60:].max()
    assert h == pytest.approx(0.2 * (1 - np.exp(-2 * np.pi * 5.0 * 0.1)), rel=0.002)   # a 0.1 s pulse through 5 Hz
    assert ext.peak_count == 1 + 16
    mean = (0.05 + ext.peak_sum - 0.05) / 17
    assert ext.mean_peak == pytest.approx(mean)
    assert mean == pytest.approx((0.05 + 16 * h) / 17, rel=1e-3)
    # the last call's peak is scaled by the mean of the 15 peaks before it (a peak counts one frame later)
    before = (ext.peak_sum - ext.last_peak) / (ext.peak_count - 1)
    assert p[-15:].max() == pytest.approx(0.1 * (ext.last_peak / before - 0.3) / 0.7, rel=1e-9)
    assert 0.1 < p[-15:].max() < 0.112                 # -> the reference, 0.1 cm H2O, as the prior fades
    assert p[-60:].min() == 0.0                         # the floor clears the gaps


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
                dict(intensity=-1), dict(peak_prior=0)):
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
