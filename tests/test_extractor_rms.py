"""The rms extractor (van Duijn 2014, 3.1, Eq. 3.1-3.2, listing 5.2) against hand-computed values."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab_plugins.extractor_rms import RmsExtractor, RmsParams, frame_rms


LINEAR = dict(scale="linear", min_amp=0.0, max_amp=0.1, max_floor=0.01)


def run(blocks, params=None, fps=60.0, sr=600):
    ext = RmsExtractor(params or RmsParams(**LINEAR), Context(fps=fps, sample_rate=sr))
    out = []
    for i, b in enumerate(blocks):
        f = Frame(i, i / fps, 1 / fps)
        ext.step(np.asarray(b, dtype=np.float32), f)
        out.append(dict(f.control))
    return ext, out


def test_rms_eq_3_1():
    x = np.array([3.0, -4.0, 0.0, 0.0], dtype=np.float32)
    assert frame_rms(x)[0] == pytest.approx(math.sqrt((9 + 16) / 4))
    assert frame_rms(np.zeros(0, dtype=np.float32)) == (0.0, 0)


def test_listing_5_2_by_hand():
    # 10 samples per frame; initial min 0, max 0.1; falloff 0.001, rise 0.4, fall 0.2 per tick
    blocks = [np.full(10, a) for a in (0.05, 0.2, 0.0)]
    _, out = run(blocks)
    # frame 1: mapped (0.05-0)/(0.1-0) = 0.5; rise-limited to 0.4; pow 2 -> 0.16
    assert out[0]["mcs_raw"] == pytest.approx(0.5)
    assert out[0]["mcs"] == pytest.approx(0.16)
    # frame 2: max -> 0.2, min = 0.001 after falloff: mapped 1.0; 0.4 + 0.4 = 0.8; -> 0.64
    assert out[1]["mcs_raw"] == pytest.approx(1.0)
    assert out[1]["mcs"] == pytest.approx(0.64)
    # frame 3: silence, min -> 0: mapped 0; fall-limited to 0.8 - 0.2 = 0.6 -> 0.36
    assert out[2]["mcs_raw"] == pytest.approx(0.0)
    assert out[2]["mcs"] == pytest.approx(0.36)


def test_falloff_moves_max_down_and_min_up():
    ext, _ = run([np.full(10, 0.05)] * 10)
    # max: 0.1 - 10 * 0.001; min: 0 + 10 * 0.001 (the amplitude never falls below it)
    assert ext.max_amp == pytest.approx(0.09)
    assert ext.min_amp == pytest.approx(0.01)


def test_silence_does_not_divide_by_zero():
    for p in (RmsParams(scale="linear", min_amp=0.0, max_amp=0.0, max_floor=0.0),
              RmsParams()):
        _, out = run([np.zeros(10)] * 5, p)
        assert all(o["mcs"] == 0.0 for o in out)


def test_loudness_scale_is_soundanalyse_db_by_hand():
    # SoundAnalyse loudness: 10 log10(rms), rms floored at 1e-7.  First frame sets min = max.
    blocks = [np.full(10, 0.001), np.full(10, 0.1), np.full(10, 0.01)]
    _, out = run(blocks, RmsParams())
    assert [o["amp"] for o in out] == pytest.approx([-30.0, -10.0, -20.0])
    assert out[0]["mcs"] == 0.0   # min = max = -30 -> silence
    # frame 2: max -10, min -30 + 0.001 -> mapped (20 - 0.001) / (20 - 0.001) = 1, rise-limited to 0.4
    assert out[1]["mcs_raw"] == pytest.approx(1.0)
    assert out[1]["mcs"] == pytest.approx(0.16)
    # frame 3: max -10.001, min -29.998: mapped (9.998) / (19.997); 0.4 + 0.4 limit does not bind
    mapped = (-20 + 29.998) / (-10.001 + 29.998)
    assert out[2]["mcs_raw"] == pytest.approx(mapped)
    assert out[2]["mcs"] == pytest.approx(mapped ** 2)
    _, out = run([np.zeros(10)], RmsParams(min_amp=-80, max_amp=0))
    assert out[0]["amp"] == pytest.approx(-70.0)


def test_max_floor_keeps_long_silence_silent():
    # after a loud laugh, 20 s of faint noise must not map to a large MCS
    rng = np.random.default_rng(1)
    blocks = [np.full(10, 0.3)] * 30 + [rng.normal(0, 1e-3, 10) for _ in range(1200)]
    _, out = run(blocks)
    assert max(o["mcs"] for o in out[-600:]) < 0.05


def test_rates_scale_with_frame_rate():
    """The same loud audio (mapped 1 every frame) at 30, 60 and 120 fps: the limited MCS rises 24 /s (0.4 a
    tick); at 120 fps its first frame takes one tick's step, 0.4, at once (the rise budget of
    laughlab.signals.smoothing: before, 0.2, and the MCS reached 0.64 a frame later in time than at 60 fps),
    then 0.2 a frame; at 30 fps a frame's 0.8, as before.  The MCS is the limited value squared."""
    _, o30 = run([np.full(20, 0.1)] * 3, fps=30, sr=600)
    _, o60 = run([np.full(10, 0.1)] * 6, fps=60, sr=600)
    _, o120 = run([np.full(5, 0.1)] * 12, fps=120, sr=600)
    assert [o["mcs"] for o in o30[:2]] == pytest.approx([0.64, 1.0])
    assert [o["mcs"] for o in o60[:3]] == pytest.approx([0.16, 0.64, 1.0])
    assert [o["mcs"] for o in o120[:4]] == pytest.approx([0.16, 0.36, 0.64, 1.0])


samples = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.sampled_from([0.0, 1.0, -1.0]))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(samples, min_size=0, max_size=20), min_size=1, max_size=40))
def test_mcs_in_unit_interval_for_any_input(blocks):
    """Silence, DC, clipping, NaN and Inf samples: MCS stays in [0, 1] and finite."""
    for params in (RmsParams(**LINEAR), RmsParams()):
        ext, out = run([np.array(b, dtype=np.float32) for b in blocks], params)
        check_unit(out)


def check_unit(out):
    for o in out:
        assert 0.0 <= o["mcs"] <= 1.0
        assert all(math.isfinite(v) for v in o.values())


def test_nonfinite_samples_are_counted_and_treated_as_silence():
    ext, out = run([np.array([np.nan, np.inf, 0.5, -np.inf] + [0.5] * 6)])
    assert ext.nonfinite_samples == 3
    assert out[0]["rms"] == pytest.approx(math.sqrt(7 * 0.25 / 10))


def test_bad_params_rejected():
    with pytest.raises(ValueError, match="rise_per_s"):
        RmsParams(rise_per_s=0)
    with pytest.raises(ValueError, match="max_amp"):
        RmsParams(min_amp=0.5, max_amp=0.1)
    with pytest.raises(ValueError, match="scale"):
        RmsParams(scale="log")


# --- calibration (thesis 3.1.1) ---------------------------------------------------------------

def test_calibration_phase_sets_min_and_max_from_the_burst_by_hand():
    # 3 calibration frames at 60 fps (0.05 s): levels 0.02, 0.5, 0.1 set min 0.02 and max 0.5; the MCS waits
    p = RmsParams(scale="linear", max_floor=0.01, calibration_s=0.05)
    blocks = [np.full(10, a) for a in (0.02, 0.5, 0.1, 0.25)]
    ext, out = run(blocks, p)
    assert [o["calibrating"] for o in out] == [1.0, 1.0, 1.0, 0.0]
    assert all(o["mcs"] == 0.0 and o["mcs_raw"] == 0.0 for o in out[:3])
    # frame 4 runs listing 5.2 from min 0.02, max 0.5: mapped (0.25 - 0.02) / 0.48; rise-limited to 0.4; ^2
    assert out[3]["mcs_raw"] == pytest.approx(0.23 / 0.48)
    assert out[3]["mcs"] == pytest.approx(0.16)
    assert ext.max_amp == pytest.approx(0.5 - 0.001) and ext.min_amp == pytest.approx(0.02 + 0.001)
    ext.reset()  # a reset starts a new calibration
    assert ext._cal_left == 3


def test_a_burst_quieter_than_max_floor_leaves_max_at_the_floor():
    """Ours (listing 5.2 lines 11-13): maxAmp >= max_floor, at the calibration's end too, so a quiet burst does not
    map room noise to full-scale MCS (a mutation dropping the floor there survived every test).  Levels 0.002 and
    0.005 under a floor of 0.01: max 0.01, min 0.002; the next frame at 0.006 maps to (0.006 - 0.002) / 0.008 = 0.5,
    then the falloff (0.001 a tick at 60 fps) moves min to 0.003 and would move max to 0.009, but the floor holds
    it at 0.01."""
    p = RmsParams(scale="linear", max_floor=0.01, calibration_s=2 / 60)
    ext, out = run([np.full(10, a) for a in (0.002, 0.005, 0.006)], p)
    assert [o["calibrating"] for o in out] == [1.0, 1.0, 0.0]
    assert out[2]["mcs_raw"] == pytest.approx(0.5)
    assert ext.max_amp == 0.01 and ext.min_amp == pytest.approx(0.002 + 0.001)


def test_without_calibration_there_is_no_calibrating_channel():
    _, out = run([np.full(10, 0.05)] * 3)
    assert "calibrating" not in out[0]


def test_calibration_length_comes_from_the_input_unless_the_extractor_sets_it():
    ctx = Context(fps=60.0, sample_rate=600, calibration_s=3.0)   # what input=mic asks for
    assert RmsExtractor(RmsParams(), ctx)._cal_frames == 180
    ctx = Context(fps=60.0, sample_rate=600, calibration_s=3.0)
    ext = RmsExtractor(RmsParams(calibration_s=0.0), ctx)          # extractor.calibration_s=0 switches it off
    assert ext._cal_frames == 0 and ctx.calibration_s == 0.0
    with pytest.raises(ValueError, match="calibration_s"):
        RmsParams(calibration_s=-1.0)


def test_a_loud_burst_with_fixed_min_max_maps_the_laughter_low_and_the_falloff_recovers_it():
    # Fig. 3.1: a burst at full scale, then laughter 20 dB quieter.  Without the falloff the laughter's MCS
    # stays low; with the thesis' falloff (0.06 dB/s on the loudness scale) maxAmp drifts down towards it
    rng = np.random.default_rng(0)
    burst = [rng.normal(0, 0.5, 10) for _ in range(30)]
    laugh = [rng.normal(0, 0.05 * (1 + np.sin(2 * np.pi * 5 * k / 60)), 10) for k in range(60 * 120)]
    fixed = RmsParams(calibration_s=0.5, falloff_per_s=0.0)
    drift = RmsParams(calibration_s=0.5)
    late = slice(-600, None)   # the last 10 s of two minutes of laughter
    m_fixed = np.mean([o["mcs_raw"] for o in run(burst + laugh, fixed)[1][late]])
    m_drift = np.mean([o["mcs_raw"] for o in run(burst + laugh, drift)[1][late]])
    assert m_drift > m_fixed + 0.05


def test_the_calibration_meter_says_what_to_do_and_passes_the_audio_through():
    import io
    from laughlab_plugins.source_mic import calibration_meter, meter_line

    out = io.StringIO()
    blocks = [np.full(10, 0.3), np.full(10, 0.6), np.full(10, 0.01)]
    got = list(calibration_meter(iter(blocks), 2, 60.0, out))
    assert all(a is b for a, b in zip(got, blocks))
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and "laugh or clap once" in lines[0] and "input.calibration_s=0" in lines[0]
    assert lines[1] == f"laughlab: calibrated (peak {20 * math.log10(0.6):.1f} dBFS); go ahead and laugh"
    out = io.StringIO()
    list(calibration_meter(iter([np.full(10, 0.001)]), 1, 60.0, out))
    assert "closer to the microphone" in out.getvalue()

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    list(calibration_meter(iter(blocks), 2, 60.0, tty))
    assert "\r" + meter_line(20 * math.log10(0.3), 20 * math.log10(0.3), 1 / 60) in tty.getvalue()
    assert meter_line(-30.0, -6.0, 1.0, width=10) == "  [#####     ]  -30.0 dBFS, peak   -6.0,  1.0 s left"
