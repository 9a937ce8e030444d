"""Benchmark: audio-to-animation latency of the live path, measured on the OSC stream (issue 6, docs/latency.md).

Plays seeded synthetic laughter through the ``mic`` source's block interface
at real time (a stand-in: the audio comes from memory instead of the device,
block by block as PortAudio would deliver it), runs the default pipeline with
the ``vmc`` sink, and receives the VMC stream with a python-osc server on
127.0.0.1.  For every laughter call of the ground truth it finds the first
received frame whose ``jawOpen`` rose by at least ``--delta`` above its value
at the call onset, and reports

* ``end_to_end``: from the call onset (the wall-clock time its first sample
  was "captured") to the arrival of that frame at the receiver;
* ``algorithmic``: the same in animation time, from the onset to the end of
  the responding frame's audio block, ``(k + 1) / fps - onset`` (block length,
  frame quantisation and the extractor's and face's smoothing);
* ``system`` = end_to_end - algorithmic (waiting for the next block, chunking,
  compute, encoding, UDP, the receiver's thread);

median and p90 in ms, plus the sink's own capture-to-send latency.  Calls
whose jaw is still above 0.9 at the onset, or that get no response before the
next call, are counted as skipped.  Writes ``benchmarks/results/latency.json``.

Run: ``python benchmarks/bench_latency.py [--duration 20] [--fps 60] [--seed 0]``.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

HERE = Path(__file__).resolve().parent


class Receiver:
    """python-osc server on an ephemeral loopback port: (arrival ns, frame time, jawOpen) per frame."""

    def __init__(self):
        from pythonosc.dispatcher import Dispatcher
        from pythonosc.osc_server import BlockingOSCUDPServer

        self.frames: list[tuple[int, float, float]] = []
        self._t = self._jaw = None
        d = Dispatcher()
        d.map("/VMC/Ext/T", self._time)
        d.map("/VMC/Ext/Blend/Val", self._blend)
        d.map("/VMC/Ext/Blend/Apply", self._apply)
        self.server = BlockingOSCUDPServer(("127.0.0.1", 0), d)
        self.port = self.server.server_address[1]
        self.thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.01}, daemon=True)
        self.thread.start()

    def _time(self, _addr, t):
        self._t = t

    def _blend(self, _addr, name, value):
        if name == "jawOpen":
            self._jaw = value

    def _apply(self, _addr, *args):
        self.frames.append((time.perf_counter_ns(), self._t, self._jaw))

    def close(self):
        time.sleep(0.2)
        self.server.shutdown()
        self.server.server_close()


def make_replay_mic():
    from laughlab.io.vmc import paced_chunks
    from laughlab_plugins.source_mic import MicSource, block_samples

    class ReplayMic(MicSource):
        """The ``mic`` source reading from memory at real time instead of a device."""

        def __init__(self, audio, params, ctx):
            super().__init__(params, ctx)
            self.audio, self.t0 = audio, None

        def open(self):
            self.sample_rate, self.n_frames = self.params.sample_rate, None

        def _chunks(self):
            n = block_samples(self.sample_rate, self.ctx.fps, self.params.block_frames)   # the mic's own blocks
            yield from paced_chunks(self.audio, self.sample_rate, n, on_start=lambda t: setattr(self, "t0", t))

    return ReplayMic


def percentiles(x) -> dict:
    x = np.asarray(x, dtype=float)
    if not len(x):
        return {"median_ms": None, "p90_ms": None, "n": 0}
    return {"median_ms": float(np.median(x)), "p90_ms": float(np.percentile(x, 90)),
            "min_ms": float(x.min()), "max_ms": float(x.max()), "n": int(len(x))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="seconds of laughter (real time)")
    ap.add_argument("--fps", type=float, default=60.0)
    ap.add_argument("--profile", default="mixed")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--block-frames", type=int, default=1, help="the mic source's block_frames")
    ap.add_argument("--delta", type=float, default=0.02, help="jawOpen rise that counts as a response")
    ap.add_argument("--out", default=str(HERE / "results" / "latency.json"))
    ns = ap.parse_args(argv)

    from laughlab.core import pipeline
    from laughlab.core import plugins
    from laughlab.io.audio import read_blocks
    from laughlab.core.config import compose_config
    from laughlab.io.video import source_audio
    from laughlab_plugins import sink_vmc
    from laughlab_plugins.source_mic import MicParams

    if "vmc" not in plugins.registry()["sink"]:
        plugins.pm.register(sink_vmc, name="laughlab_plugins.sink_vmc")
    native = hasattr(pipeline, "chunk_frames")
    if not native:  # until the pipeline hands live sources' frames over one at a time
        pipeline.CHUNK_FRAMES = 1

    rx = Receiver()
    cfg = compose_config([f"input.duration_s={ns.duration}", f"input.profile={ns.profile}", f"seed={ns.seed}",
                          f"fps={ns.fps}", "input.save_audio=false"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    OmegaConf.set_struct(cfg, False)
    cfg.output = OmegaConf.create({"vmc": {"port": rx.port, "report": False}})
    pipe = pipeline.build(cfg)
    truth = pipe.source.truth
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        audio = np.concatenate(list(read_blocks(source_audio(pipe.source, Path(tmp)))))
        pipe.source.close()
        sr = int(pipe.source.sample_rate)
        mic = make_replay_mic()(audio, MicParams(sample_rate=sr, block_frames=ns.block_frames), pipe.ctx)
        mic.open()
        pipe.source = mic
        pipeline.execute(pipe, Path(tmp), {})
    rx.close()
    sink = next(s for s in pipe.sinks if s.name == "vmc")

    frames = [f for f in rx.frames if f[2] is not None]
    recv = np.array([f[0] for f in frames], dtype=np.int64)
    ftime = np.array([f[1] for f in frames])
    jaw = np.array([f[2] for f in frames])
    dt = 1.0 / ns.fps
    t0_ns = mic.t0 * 1e9
    onsets = [c.onset_s for c in truth.calls]
    e2e, alg, skipped = [], [], 0
    for i, on in enumerate(onsets):
        nxt = onsets[i + 1] if i + 1 < len(onsets) else on + 0.5
        before = np.nonzero(ftime < on)[0]
        base = jaw[before[-1]] if len(before) else 0.0
        after = np.nonzero((ftime >= on - dt) & (ftime < nxt) & (jaw >= base + ns.delta))[0]
        if base > 0.9 or not len(after):
            skipped += 1
            continue
        k = after[0]
        e2e.append((recv[k] - (t0_ns + on * 1e9)) / 1e6)
        alg.append(((ftime[k] + dt) - on) * 1e3)
    e2e, alg = np.array(e2e), np.array(alg)
    m = sink.metrics()
    result = {
        "what": "delay from a laughter call onset (synthetic ground truth) to the jaw's response in the VMC/OSC "
                "stream received on 127.0.0.1; see benchmarks/bench_latency.py and docs/latency.md",
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "processor": platform.processor() or platform.machine()},
        "config": {"duration_s": ns.duration, "fps": ns.fps, "sample_rate": sr, "profile": ns.profile,
                   "seed": ns.seed, "block_frames": ns.block_frames,
                   "block_samples": int(round(sr / ns.fps)) * ns.block_frames, "delta_jaw": ns.delta,
                   "pipeline_streaming": "native (chunk_frames)" if native else "CHUNK_FRAMES patched to 1"},
        "frames_received": len(frames),
        "frames_expected": int(np.ceil(len(audio) * ns.fps / sr - 1e-9)),
        "calls": len(onsets),
        "calls_measured": int(len(e2e)),
        "calls_skipped": skipped,
        "end_to_end": percentiles(e2e),
        "algorithmic": percentiles(alg),
        "system": percentiles(e2e - alg),
        "sink_capture_to_send": {"median_ms": m["vmc_latency_ms_p50"], "p90_ms": m["vmc_latency_ms_p90"],
                                 "max_ms": m["vmc_latency_ms_max"]},
        "block_ms": 1000.0 * ns.block_frames / ns.fps,
    }
    out = Path(ns.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    e, a, s = result["end_to_end"], result["algorithmic"], result["system"]
    print(f"latency call onset -> jaw response in the OSC stream ({len(e2e)} of {len(onsets)} calls, "
          f"{ns.fps:g} fps, blocks of {result['block_ms']:.1f} ms):")
    print(f"  end to end   median {e['median_ms']:.1f} ms   p90 {e['p90_ms']:.1f} ms")
    print(f"  algorithmic  median {a['median_ms']:.1f} ms   p90 {a['p90_ms']:.1f} ms")
    print(f"  system       median {s['median_ms']:.1f} ms   p90 {s['p90_ms']:.1f} ms")
    print(f"  sink capture -> send median {m['vmc_latency_ms_p50']:.2f} ms, p90 {m['vmc_latency_ms_p90']:.2f} ms")
    print(f"written: {out}")
    return result


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
