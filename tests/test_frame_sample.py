"""Per-frame figures in bounded memory (review-live 10), end to end through the frame loop and the vmc sink."""
from __future__ import annotations

from array import array

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.core.framesample import FrameSample


@pytest.mark.parametrize("n, chunk", [(10, 1), (31, 1), (1000, 1), (1000, 7), (5003, 256), (100_000, 1)])
def test_every_frame_until_the_cap_then_evenly_spread_with_count_and_max_exact(n, chunk):
    xs = np.random.default_rng(n).integers(0, 10**9, n)
    f = FrameSample("q", cap=16)
    for i, x in enumerate(xs):
        f.append(int(x))
        if (i + 1) % chunk == 0:
            f.settle()
        assert len(f.values) < 2 * 16 + chunk
    kept = f.array(np.int64)
    assert f.n == n and f.max() == xs.max()
    assert kept.tolist() == xs[::f.stride].tolist()   # frames 0, s, 2s, ...: the whole run, evenly
    assert (f.stride == 1) == (n < 32)


def test_a_short_run_keeps_every_value_as_before():
    f = FrameSample("d")
    for x in (3.0, 1.0, 2.0):
        f.append(x)
    assert f.array(np.float64).tolist() == [3.0, 1.0, 2.0] and f.max() == 3.0 and f.n == 3


class Recording(array):
    """The values array of a FrameSample that also keeps every value appended (the frame loop's ``append``)."""

    def __new__(cls, typecode):
        out = super().__new__(cls, typecode)
        out.every = []
        return out

    def append(self, x):
        self.every.append(x)
        super().append(x)


class Recorded(FrameSample):
    made: list = []

    def __init__(self, typecode, cap=None):
        super().__init__(typecode, cap)
        self.values = Recording(typecode)
        Recorded.made.append(self)


def test_a_long_stream_keeps_bounded_figures_evenly_spread_and_its_max_exact(tmp_path, monkeypatch):
    """End to end, against every value the frame loop and the vmc sink appended (diff-review 14: the test asserted
    only p50 <= p99 <= max, true of any sample): the kept ones are frames 0, s, 2s..., the percentiles are theirs,
    and the max is of every frame."""
    from laughlab_plugins import sink_vmc

    monkeypatch.setattr(FrameSample, "CAP", 16)
    monkeypatch.setattr(Recorded, "made", [])
    monkeypatch.setattr(pipeline, "FrameSample", Recorded)
    monkeypatch.setattr(sink_vmc, "FrameSample", Recorded)
    cfg = compose_config(["fps=30", "input.duration_s=10", "detector=none"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"vmc": {"port": 39597, "report": False, "realtime": "off"}}
    metrics = pipeline.execute(pipeline.build(cfg), tmp_path, {})
    (times,) = [f for f in Recorded.made if f.values.typecode == "q"]   # compute per frame (ns)
    (lat,) = [f for f in Recorded.made if f.values.typecode == "d"]     # the sink's latency (ms)
    assert metrics["n_frames"] == 300 == times.n == lat.n == len(times.values.every) == len(lat.values.every)
    for f, scale, key in ((times, 1e6, "frame_ms"), (lat, 1.0, "vmc_latency_ms")):
        every = np.array(f.values.every, dtype=np.float64) / scale
        kept = every[::f.stride]
        assert f.stride > 1 and len(f.values) < 32 and len(kept) == len(f.values)
        np.testing.assert_array_equal(np.frombuffer(f.values, dtype=np.int64 if f is times else np.float64) / scale,
                                      kept)
        assert metrics[f"{key}_max"] == every.max()
        assert metrics[f"{key}_p50"] == np.percentile(kept, 50) and metrics[f"{key}_p99"] == np.percentile(kept, 99)
