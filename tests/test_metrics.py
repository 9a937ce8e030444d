"""Every metric on hand-built channels, events and ground truth with known answers."""
import math

import numpy as np
import pandas as pd
import pytest

from laughlab.harness.metrics import best_lag_correlation, compute, registered
from laughlab.harness.trialdata import Truth, TrialData

FPS = 10.0


def truth(bouts, calls=()):
    rows = [("bout", i, on, off, inten, np.nan) for i, (on, off, inten) in enumerate(bouts)]
    rows += [("call", b, on, off, inten, 300.0) for b, on, off, inten in calls]
    t = pd.DataFrame(rows, columns=["kind", "bout", "onset_s", "offset_s", "intensity", "f0_hz"])
    return Truth(t[t.kind == "bout"].reset_index(drop=True), t[t.kind == "call"].reset_index(drop=True))


def events(rows):
    """rows: (time, event, clip, energy, speed, reason[, offset, end])"""
    full = [tuple(r) + (0.0, np.nan)[len(r) - 6:] if len(r) < 8 else tuple(r) for r in rows]
    return pd.DataFrame(full, columns=["time", "event", "clip", "energy", "speed", "reason", "offset", "end"])


def trial(seconds=20.0, tr=None, ev=(), **channels):
    n = int(seconds * FPS)
    ch = {"time": np.arange(n) / FPS}
    for k, v in channels.items():
        ch[k] = v(ch["time"]) if callable(v) else v
    return TrialData(pd.DataFrame(ch), events(list(ev)), FPS, tr,
                     {"frame_ms_p50": 0.02, "frame_ms_p99": 0.05, "realtime_factor": 800.0})


def test_registry_has_stable_names_with_docs():
    names = set(registered())
    assert {"intensity_r_clip", "onset_latency_median_s", "miss_rate", "cutoff_rate", "clip_entropy",
            "jaw_onset_latency_s", "frame_ms_p99", "realtime_factor"} <= names
    for m in registered().values():
        assert m.description and m.units
        assert m.higher_is_better in (True, False, None)


def test_best_lag_correlation_finds_a_known_delay():
    rng = np.random.default_rng(0)
    x = rng.normal(size=400)
    y = np.r_[np.zeros(7), x[:-7]]            # y(t + 7 frames) = x(t)
    r, lag_s, k = best_lag_correlation(x, y, FPS, 2.0)
    assert k == 7 and lag_s == pytest.approx(0.7) and r == pytest.approx(1.0)


def test_intensity_tracking_with_a_delayed_copy():
    tr = truth([(2.0, 6.0, 0.8)], [(0, 2.0, 2.2, 0.5), (0, 3.0, 3.2, 1.0), (0, 4.0, 4.2, 0.3)])
    t = trial(tr=tr)
    delayed = np.r_[np.zeros(5), t.laughter_intensity[:-5]] * 40.0   # clip energy answers 0.5 s late
    t.channels["clip_energy"] = delayed
    m = compute(t)
    assert m["intensity_r_clip"] == pytest.approx(1.0)
    assert m["intensity_rho_clip"] == pytest.approx(1.0, abs=0.02)
    assert m["intensity_lag_clip_s"] == pytest.approx(0.5)
    assert math.isnan(m["intensity_r_kinetic"])          # no motion.bvh


def test_ungraded_calls_take_the_sounds_loudness_inside_them_as_the_intensity():
    """A data user's review: the real corpus' and an annotation's calls all carry intensity 1.0, so I(t) was call
    activity there (a loud and a faint call alike) while the synthetic inputs' was the planted intensity.  Now calls
    of one value take the rms inside them, 0 outside (speech around them does not count); graded calls their own."""
    from laughlab.harness.trialdata import moving_average

    calls = [(0, 2.0, 3.0, 1.0), (0, 5.0, 6.0, 1.0)]
    rms = lambda t: np.where(t < 4.0, 0.8, 0.2)   # noqa: E731 - a loud call, then a faint one; loud talk at 0-2 s
    t = trial(tr=truth([(2.0, 6.0, 1.0)], calls), rms=rms)
    assert not t.truth.graded
    inside = ((t.times >= 2.0) & (t.times < 3.0)) * 0.8 + ((t.times >= 5.0) & (t.times < 6.0)) * 0.2
    want = moving_average(inside, 10)
    np.testing.assert_allclose(t.laughter_intensity, want / want.max())
    assert t.laughter_intensity[:15].max() == 0.0           # the talk before the bout is not laughter
    graded = trial(tr=truth([(2.0, 6.0, 1.0)], [(0, 2.0, 3.0, 0.9), (0, 5.0, 6.0, 0.3)]), rms=rms)
    assert graded.truth.graded
    np.testing.assert_allclose(graded.laughter_intensity, moving_average(graded.truth.intensity(graded.times), 10))
    blank = trial(tr=truth([(2.0, 6.0, 1.0)], [(b, on, off, np.nan) for b, on, off, _ in calls]), rms=rms)
    assert not blank.truth.graded   # blank intensities (unknown): inside the calls all the same (it was 0 throughout)
    np.testing.assert_allclose(blank.laughter_intensity, want / want.max())
    plain = trial(rms=rms)                                  # no truth: the loudness throughout
    np.testing.assert_allclose(plain.laughter_intensity, moving_average(rms(plain.times), 10) / 0.8)


def test_onset_latency_miss_rate_offset_and_silent_starts():
    tr = truth([(1.0, 3.0, 0.5), (6.0, 8.0, 0.9), (12.0, 13.0, 0.4)])
    ev = [(1.5, "start", "lean_front1", 5, 1.0, ""),          # 0.5 s into bout 0
          (2.5, "stop", "lean_front1", 5, 1.0, "overruled"),
          (2.5, "start", "clap_hands", 15, 1.0, ""),           # plays until 4.5: tail 1.5 s after bout 0
          (4.5, "stop", "clap_hands", 15, 1.0, "finished"),
          (7.0, "start", "rofl", 40, 1.0, ""),                 # 1.0 s into bout 1; ends 9.0 -> tail 1.0
          (9.0, "stop", "rofl", 40, 1.0, "finished"),
          (10.5, "start", "point1", 20, 1.0, ""),              # 2.5 s after bout 1 ended: silent start
          (11.5, "stop", "point1", 20, 1.0, "overruled")]      # bout 2 has no start: a miss
    m = compute(trial(tr=tr, ev=ev))
    assert m["onset_latency_median_s"] == pytest.approx(0.75)   # median(0.5, 1.0)
    assert m["onset_latency_p90_s"] == pytest.approx(0.95)      # 0.5 + 0.9 * 0.5
    assert m["miss_rate"] == pytest.approx(1 / 3)
    # tails: bout 0 -> 1.5; bout 1 -> max(9.0, 11.5) - 8 = 3.5; bout 2 -> 0 (nothing plays after 13)
    assert m["offset_tail_s"] == pytest.approx(1.5)
    assert m["silent_start_rate"] == pytest.approx(1 / 4)


def test_cutoff_repetition_and_entropy():
    # lean_front1 lasts 22/24 s; stopped after 0.2 s at speed 1 -> 22% played: a cut-off
    ev = [(0.0, "start", "lean_front1", 5, 1.0, ""), (0.2, "stop", "lean_front1", 5, 1.0, "overruled"),
          (0.2, "start", "rofl", 40, 1.0, ""), (5.075, "stop", "rofl", 40, 1.0, "finished"),
          (6.0, "start", "lean_front1", 5, 1.0, ""), (6.5, "stop", "lean_front1", 5, 1.0, "overruled"),
          (6.5, "start", "lean_front1", 5, 1.0, ""), (7.5, "stop", "lean_front1", 5, 1.0, "finished")]
    m = compute(trial(ev=ev))
    assert m["cutoff_rate"] == pytest.approx(1 / 4)            # 0.5 s of 0.917 s is more than half
    assert m["repetition_rate"] == pytest.approx(1 / 4)        # only the start at 6.5 (after 6.0)
    p = np.array([3, 1]) / 4
    assert m["clip_entropy"] == pytest.approx(-(p * np.log(p)).sum() / np.log(11))


def test_segment_played_fraction_uses_offset_and_end():
    ev = [(0.0, "start", "rofl", 40, 2.0, "", 1.0, 2.0),        # a 1 s segment at double speed
          (0.2, "stop", "rofl", 40, 2.0, "next", 1.0, 2.0)]     # 0.4 s of clip time played
    t = trial(ev=ev)
    p = t.plays()
    assert p.fraction[0] == pytest.approx(0.4) and p.length[0] == pytest.approx(1.0)
    assert compute(t)["cutoff_rate"] == 1.0


def test_face_latency_and_jaw_correlation():
    tr = truth([(1.0, 5.0, 0.8)], [(0, 1.0, 1.3, 1.0), (0, 3.0, 3.3, 0.5)])
    t = trial(10.0, tr=tr)
    env = tr.intensity(t.times)
    jaw = np.r_[np.zeros(2), env[:-2]]                       # rises 0.2 s after each call onset
    smile = np.clip((t.times - 1.4) * 0.5, 0, 1)             # starts rising at 1.4 s, 0.05 every 0.1 s
    t.channels["jaw"] = jaw
    t.channels["smile"] = smile
    m = compute(t)
    assert m["jaw_onset_latency_s"] == pytest.approx(0.2)
    assert m["jaw_call_r"] == pytest.approx(1.0)
    # call 1 at 1.0: smile rises 0.05 at 1.5 s -> 0.5 s; call 2 at 3.0: already rising -> 0.1 s
    assert m["smile_onset_latency_s"] == pytest.approx(0.3)


def test_compute_metrics_pass_through_and_missing_truth_gives_nan():
    m = compute(trial(rms=lambda t: np.abs(np.sin(t))))
    assert m["frame_ms_p99"] == 0.05 and m["realtime_factor"] == 800.0
    for name in ("onset_latency_median_s", "miss_rate", "silent_start_rate", "jaw_onset_latency_s"):
        assert math.isnan(m[name]), name


def test_kinetic_energy_of_a_skeleton_gliding_at_1_m_per_s(tmp_path):
    """Every joint moves at 1 m/s: K = 0.5 * J * 1^2 = 11 (m/s)^2 for the 22 joints."""
    from laughlab.io.bvh import write_bvh
    from laughlab.motion.skeleton import HUMANOID, rest_pose

    poses = np.tile(rest_pose(HUMANOID), (40, 1))
    poses[:, 0] = np.arange(40) * 100.0 / FPS        # root x in cm: 1 m/s
    write_bvh(tmp_path / "motion.bvh", HUMANOID, poses, 1 / FPS)
    t = trial(4.0)
    t.motion_path = tmp_path / "motion.bvh"
    assert t.kinetic_energy == pytest.approx(np.full(40, 0.5 * HUMANOID.n_joints), rel=1e-6)
    # kinetic energy that follows the intensity 0.3 s later gives r = 1 at lag 0.3 s
    tr = truth([(0.5, 3.5, 1.0)], [(0, 1.0, 1.3, 1.0), (0, 2.0, 2.6, 0.4)])
    t2 = trial(4.0, tr=tr)
    ke = np.r_[np.zeros(3), t2.laughter_intensity[:-3]]
    t2.__dict__["kinetic_energy"] = ke                  # cached_property: set the value directly
    m = compute(t2)
    assert m["intensity_lag_kinetic_s"] == pytest.approx(0.3, abs=0.11)
    assert m["intensity_r_kinetic"] > 0.9             # K is smoothed once more over 1 s by the metric


def test_jaw_envelope_r_allows_at_most_0_1_s_of_lag_and_prefers_arkit():
    rng = np.random.default_rng(3)
    n = int(10.0 * FPS)
    rms = np.abs(rng.standard_normal(n))                                           # a call-by-call envelope
    late = lambda k: np.r_[np.zeros(k), rms[:-k]]
    assert compute(trial(10.0, rms=rms, jaw=late(1)))["jaw_envelope_r"] == pytest.approx(1.0)   # 0.1 s behind
    assert compute(trial(10.0, rms=rms, jaw=late(3)))["jaw_envelope_r"] < 0.5                  # 0.3 s: too late
    t = trial(10.0, rms=rms, jaw=np.zeros(n))
    t.channels["arkit.jawOpen"] = rms                                              # the ARKit weight wins
    assert compute(t)["jaw_envelope_r"] == pytest.approx(1.0)
    assert math.isnan(compute(trial(10.0, jaw=rms))["jaw_envelope_r"])            # no rms channel


def test_calls_of_blank_intensity_count_one():
    """A metrics audit: truth.csv allows a call's intensity blank (unknown); Truth.intensity wrote its NaN into the
    call envelope, and jaw_call_r was NaN (0.645 with the intensities given). A blank call counts 1, as an
    annotation's calls do: a jaw that follows the calls correlates."""
    tr = truth([(1.0, 5.0, np.nan)], [(0, 1.0, 1.3, np.nan), (0, 3.0, 3.3, np.nan)])
    t = trial(10.0, tr=tr)
    env = tr.intensity(t.times)
    assert set(np.unique(env)) == {0.0, 1.0}
    t.channels["jaw"] = np.r_[np.zeros(2), env[:-2]]
    assert compute(t)["jaw_call_r"] == pytest.approx(1.0)


def test_a_run_without_a_clip_start_has_no_silent_start_rate():
    """A metrics audit: with no clip start silent_start_rate was 0, a perfect score for a run that never moved (the
    1 s input, scheduler=none), where cutoff_rate, repetition_rate and clip_entropy are NaN. It is NaN too."""
    m = compute(trial(tr=truth([(1.0, 5.0, 0.8)])))
    assert math.isnan(m["silent_start_rate"]) and math.isnan(m["cutoff_rate"])
