"""experiment=energy_readings: its summary of the two readings, by hand, and one input end to end."""
import numpy as np
import pytest

from laughlab_experiments.energy_readings import energy_trace, summarise


def test_summary_by_hand():
    traces = [{"energy": np.array([1.0, -2.0, 3.0]), "starts": [5.0, 40.0], "seconds": 30.0, "playing_s": 6.0},
              {"energy": np.array([0.0]), "starts": [5.0], "seconds": 30.0, "playing_s": 3.0}]
    s = summarise(traces)
    assert s["clip_starts_per_min"] == pytest.approx(3.0)          # 3 starts in 1 minute
    assert s["mean_clip_energy"] == pytest.approx(50 / 3)
    assert s["share_e5"] == pytest.approx(2 / 3) and s["share_e40"] == pytest.approx(1 / 3) and s["share_e10"] == 0
    assert s["clip_playing_fraction"] == pytest.approx(9 / 60)
    assert s["energy_min"] == -2.0 and s["energy_median"] == 0.5 and s["energy_below_zero_fraction"] == 0.25


def test_the_listing_reading_runs_low_and_plays_the_mildest_clips():
    base = ["input.duration_s=20", "input.profile=intense", "scheduler=energy"]
    eq = energy_trace([*base, "scheduler.consumption=equation"])
    li = energy_trace([*base, "scheduler.consumption=listing"])
    assert eq["energy"].min() >= 0 and li["energy"].min() < -50
    assert len(li["starts"]) < len(eq["starts"]) and set(li["starts"]) == {5.0}
