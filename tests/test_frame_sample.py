"""Per-frame figures in bounded memory (review-live 10) and the vmc sink's capture times from the chunk only
(review-live 11: BlockClock wrapped source.blocks, whose read-ahead thread left one stale entry a frame)."""
from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.core.summary import FrameSample


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


def run_vmc(tmp_path, *overrides, **vmc):
    cfg = compose_config(["fps=30", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"vmc": {"port": 39597, "report": False, **vmc}}
    pipe = pipeline.build(cfg)
    sink = next(s for s in pipe.sinks if s.name == "vmc")
    wrapped = []
    write = sink.write

    def watch(chunk):
        wrapped.append("blocks" in vars(pipe.source))
        write(chunk)

    sink.write = watch
    return pipe, sink, pipeline.execute(pipe, tmp_path, {}), wrapped


def test_a_long_stream_keeps_bounded_latencies_and_its_metrics(tmp_path, monkeypatch):
    monkeypatch.setattr(FrameSample, "CAP", 16)
    pipe, sink, metrics, wrapped = run_vmc(tmp_path, "input.duration_s=10", "detector=none", realtime="off")
    assert metrics["n_frames"] == 300 == sink.lat_ms.n and len(sink.lat_ms.values) < 32
    assert 0 <= metrics["vmc_latency_ms_p50"] <= metrics["vmc_latency_ms_max"]
    assert metrics["frame_ms_p50"] <= metrics["frame_ms_p99"] <= metrics["frame_ms_max"]


def test_the_sink_does_not_wrap_the_source(tmp_path):
    """A file read ahead by the detector (detector=yamnet prefetch) and paced: the capture times come from the
    chunk (paced: when the audio would have been captured), not from a wrapper around source.blocks."""
    pipe, sink, metrics, wrapped = run_vmc(tmp_path, "input.duration_s=0.3", realtime="on")
    assert wrapped == [False] * 9 and "blocks" not in vars(pipe.source)
    assert metrics["vmc_frames"] == 9 and np.isfinite(metrics["vmc_latency_ms_p50"])
