"""The detector metrics on hand-built gates, clip starts and bouts with known answers."""
import numpy as np
import pytest

from laughlab.harness.metrics import compute, registered
from test_metrics import FPS, events, trial, truth


def gate_between(*spans):
    def f(t):
        g = np.zeros(len(t))
        for a, b in spans:
            g[(t >= a) & (t < b)] = 1.0
        return g
    return f


def test_detector_metrics_are_registered_with_units():
    names = set(registered())
    assert {"detector_f1", "detector_precision", "detector_recall", "detection_latency_median_s",
            "detection_latency_p90_s", "false_starts_per_min", "bouts_answered"} <= names


def test_frame_scores_by_hand():
    # 20 s at 10 fps; bouts 2-6 s and 10-12 s (60 frames); gate open 3-7 s and 14-15 s (50 frames)
    tr = truth([(2.0, 6.0, 1.0), (10.0, 12.0, 1.0)])
    m = compute(trial(tr=tr, laugh_gate=gate_between((3.0, 7.0), (14.0, 15.0))))
    tp, fp, fn = 30, 20, 30          # 3-6 s; 6-7 s and 14-15 s; 2-3 s and 10-12 s
    assert m["detector_precision"] == pytest.approx(tp / (tp + fp))
    assert m["detector_recall"] == pytest.approx(tp / (tp + fn))
    assert m["detector_f1"] == pytest.approx(2 * tp / (2 * tp + fp + fn))
    # latency: bout 1 opens at frame 3.0 s -> 3.0 + 0.1 - 2.0; bout 2 never
    assert m["detection_latency_median_s"] == pytest.approx(1.1)
    assert m["detection_latency_p90_s"] == pytest.approx(1.1)


def test_the_probability_latency_by_hand():
    # 20 s at 10 fps; bouts 2-6 s, 10-12 s, 15-16 s; laughter >= 0.5 from 2.2 s, from 11.0 s, never in the third
    tr = truth([(2.0, 6.0, 1.0), (10.0, 12.0, 1.0), (15.0, 16.0, 1.0)])
    p = lambda t: np.where(((t >= 2.2) & (t < 6)) | ((t >= 11.0) & (t < 11.5)), 0.5, 0.49)  # noqa: E731
    m = compute(trial(tr=tr, laughter=p, laugh_gate=np.ones(200)))
    # 2.2 + 0.1 - 2.0 = 0.3 and 11.0 + 0.1 - 10.0 = 1.1: median 0.7 over the two that cross; 1 of 3 by 0.3 s
    assert m["probability_latency_median_s"] == pytest.approx(0.7)
    assert m["probability_in_time"] == pytest.approx(1 / 3)
    m = compute(trial(tr=tr, laugh_gate=np.ones(200)))   # no probability channel (detector=none)
    assert np.isnan(m["probability_latency_median_s"]) and np.isnan(m["probability_in_time"])


def test_false_starts_and_answered_bouts_by_hand():
    tr = truth([(2.0, 6.0, 1.0), (10.0, 12.0, 1.0)])
    ev = [(2.5, "start", "giggle", 20, 1.0, ""), (6.8, "start", "sway", 10, 1.0, ""),    # in bout 1, its tail
          (8.0, "start", "rofl", 90, 1.0, ""), (16.0, "start", "idle", 0, 1.0, "")]     # false; idle ignored
    m = compute(trial(tr=tr, ev=ev, laugh_gate=np.ones(200)))
    # non-laughter: 20 s - (4 + 1) - (2 + 1) = 12 s = 0.2 min; one false start
    assert m["false_starts_per_min"] == pytest.approx(1 / 0.2)
    assert m["bouts_answered"] == pytest.approx(0.5)
    # a metrics audit: bouts closer than their 1 s tail; the tail and the next bout overlap, counted once. Bouts
    # 2-6 and 6.5-12 with their tails span 2-13 s: 9 s of non-laughter in 20 (not 20 - 5 - 6.5 = 8.5 s); and three
    # bouts each inside the last's tail in a 3 s input
    tr = truth([(2.0, 6.0, 1.0), (6.5, 12.0, 1.0)])
    m = compute(trial(tr=tr, ev=[(16.0, "start", "rofl", 90, 1.0, "")], laugh_gate=np.ones(200)))
    assert m["false_starts_per_min"] == pytest.approx(1 / (9.0 / 60))
    tr = truth([(0.5, 1.0, 1.0), (1.2, 1.4, 1.0), (1.5, 1.6, 1.0)])
    m = compute(trial(3.0, tr=tr, ev=[(0.2, "start", "rofl", 90, 1.0, "")], laugh_gate=np.ones(30)))
    # with their tails the bouts span 0.5-2.6 s: 0.9 s of non-laughter (3 - 1.5 - 1.2 - 1.1 < 0 before: NaN)
    assert m["false_starts_per_min"] == pytest.approx(1 / (0.9 / 60))


def test_without_truth_or_gate_the_metrics_are_nan():
    m = compute(trial(laugh_gate=np.ones(200)))
    assert np.isnan(m["detector_f1"]) and np.isnan(m["false_starts_per_min"])
    m = compute(trial(tr=truth([(2.0, 6.0, 1.0)])))
    assert np.isnan(m["detector_f1"])
    # without laughter in the truth: frame F1, precision and recall do not apply, whether the gate opened or not
    for gate in (np.zeros(200), np.ones(200)):
        m = compute(trial(tr=truth([]), laugh_gate=gate))
        assert np.isnan(m["detector_f1"]) and np.isnan(m["detector_recall"])


def test_false_starts_per_kind_by_hand():
    import pandas as pd

    tr = truth([(2.0, 6.0, 1.0)])
    tr.others = pd.DataFrame([("speech", -1, 8.0, 14.0, 1.0), ("cough", -1, 15.0, 15.5, 1.0)],
                             columns=["kind", "bout", "onset_s", "offset_s", "intensity"])
    ev = [(6.5, "start", "giggle", 20, 1.0, ""),                                          # the bout's tail
          (9.0, "start", "rofl", 90, 1.0, ""), (13.0, "start", "sway", 10, 1.0, ""),      # in speech: 2 in 6 s
          (15.2, "start", "giggle", 20, 1.0, ""), (17.0, "start", "sway", 10, 1.0, "")]   # cough: 1 in 0.5 s; none
    m = compute(trial(tr=tr, ev=ev, laugh_gate=np.ones(200)))
    assert m["false_starts_speech_per_min"] == pytest.approx(2 / 0.1)
    assert m["false_starts_cough_per_min"] == pytest.approx(1 / (0.5 / 60))
    assert np.isnan(m["false_starts_music_per_min"])                                     # no music in the truth


def test_human_sounds_starting_a_clip_by_hand():
    import pandas as pd

    tr = truth([(2.0, 6.0, 1.0)])
    tr.others = pd.DataFrame([("cough", -1, 8.0, 8.5, 0.0), ("vocal", -1, 10.0, 10.4, 0.0),
                              ("sneeze", -1, 13.0, 13.3, 0.0), ("speech", -1, 15.0, 19.0, 0.0)],
                             columns=["kind", "bout", "onset_s", "offset_s", "intensity"])
    ev = [(6.5, "start", "giggle", 20, 1.0, ""),    # the bout's tail: answers the laugh, not a sound
          (9.3, "start", "sway", 10, 1.0, ""),      # 0.8 s after the cough: within its 1 s tail
          (16.0, "start", "rofl", 90, 1.0, "")]     # in speech: not a human sound of this metric
    m = compute(trial(tr=tr, ev=ev, laugh_gate=np.ones(200)))
    assert m["human_sounds_starting_a_clip"] == pytest.approx(1 / 3)   # the cough; not the vocal, not the sneeze
    tr.others = tr.others[tr.others.kind == "speech"]
    assert np.isnan(compute(trial(tr=tr, ev=ev, laugh_gate=np.ones(200)))["human_sounds_starting_a_clip"])
