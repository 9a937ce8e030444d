"""Benchmark: audio-to-animation latency of the live path, measured on the OSC stream (issue 6, docs/latency.md).

Plays seeded synthetic laughter through the ``mic`` source's block interface
at real time (a stand-in: the audio comes from memory instead of the device,
block by block as PortAudio would deliver it), runs the default pipeline with
the ``vmc`` sink, and receives the VMC stream with a python-osc server on
127.0.0.1 (in a process of its own; ``--receiver thread``: in a thread of the benchmark's, as before
2026-11-28).  For every laughter call of the ground truth it finds the first
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

With ``--fps 60,120,144`` the rates run one after the other in one process (the figures then compare: the
same machine, the same minute) and the medians are also given over the calls measured at every rate.  Each run
also reports every frame's arrival after its audio block's end (the pipeline, the sink and the in-process
receiver thread together), how late the frame loop took each block after it was due (its backlog: the part of
the arrival that is the pipeline's, on top of the sink's capture-to-send) and the share of a core the process
and its frame thread used, so a rate the machine cannot keep up with shows.

Run: ``python benchmarks/bench_latency.py [--duration 20] [--fps 60[,120,...]] [--seed 0] [OVERRIDE...]``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
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


def _serve(conn, stop) -> None:
    """The receiver in a process of its own (``--receiver process``): its port, then its frames when told to stop."""
    rx = Receiver()
    conn.send(rx.port)
    stop.wait()
    rx.close()
    conn.send(rx.frames)


class ProcessReceiver:
    """:class:`Receiver` in another process, as an avatar program is: its parsing does not share the frame loop's
    interpreter (in a thread of the benchmark's own process it took the GIL from the frame loop at 144 fps).
    Arrival times are ``perf_counter_ns``, the system's monotonic clock, the same in both processes."""

    def __init__(self):
        import multiprocessing as mp

        ctx = mp.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._stop = ctx.Event()
        self.proc = ctx.Process(target=_serve, args=(child, self._stop), daemon=True)
        self.proc.start()
        self.port = self._conn.recv()
        self.frames: list[tuple[int, float, float]] = []

    def close(self):
        self._stop.set()
        self.frames = self._conn.recv()
        self.proc.join()


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
            self.late_ms, end = [], 0
            for b in paced_chunks(self.audio, self.sample_rate, n, on_start=lambda t: setattr(self, "t0", t)):
                end += len(b)   # how late the frame loop asks for the block after it was due: its backlog
                self.late_ms.append((time.perf_counter() - self.t0 - end / self.sample_rate) * 1e3)
                yield b

    return ReplayMic


def percentiles(x) -> dict:
    x = np.asarray(x, dtype=float)
    if not len(x):
        return {"median_ms": None, "p90_ms": None, "n": 0}
    return {"median_ms": float(np.median(x)), "p90_ms": float(np.percentile(x, 90)),
            "min_ms": float(x.min()), "max_ms": float(x.max()), "n": int(len(x))}


def responses(ftime: np.ndarray, jaw: np.ndarray, onsets, dt: float, delta: float) -> list:
    """For each call onset (s), the index of the first frame (start times ``ftime``) whose ``jaw`` rose by
    ``delta`` above its value at the onset, before the next call; None for a call whose jaw is still above 0.9
    at its onset or that gets no response (skipped)."""
    out = []
    for i, on in enumerate(onsets):
        nxt = onsets[i + 1] if i + 1 < len(onsets) else on + 0.5
        before = np.nonzero(ftime < on)[0]
        base = jaw[before[-1]] if len(before) else 0.0
        after = np.nonzero((ftime >= on - dt) & (ftime < nxt) & (jaw >= base + delta))[0]
        out.append(None if base > 0.9 or not len(after) else int(after[0]))
    return out


def measure(ns, fps: float) -> dict:
    """One real-time run at ``fps``: the figures of the module's docstring, and each call's."""
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

    rx = ProcessReceiver() if ns.receiver == "process" else Receiver()
    cfg = compose_config([f"input.duration_s={ns.duration}", f"input.profile={ns.profile}", f"seed={ns.seed}",
                          f"fps={fps}", "input.save_audio=false", *ns.override])
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
        cpu0, thread0, load0 = time.process_time(), time.thread_time(), os.getloadavg()
        wall0 = time.perf_counter()
        pipeline.execute(pipe, Path(tmp), {})
        cpu, thread = time.process_time() - cpu0, time.thread_time() - thread0
        wall = time.perf_counter() - wall0
    rx.close()
    sink = next(s for s in pipe.sinks if s.name == "vmc")

    frames = [f for f in rx.frames if f[2] is not None]
    recv = np.array([f[0] for f in frames], dtype=np.int64)
    ftime = np.array([f[1] for f in frames])
    jaw = np.array([f[2] for f in frames])
    dt = 1.0 / fps
    t0_ns = mic.t0 * 1e9
    onsets = [c.onset_s for c in truth.calls]
    found = responses(ftime, jaw, onsets, dt, ns.delta)
    calls = [None if k is None else {"onset_s": on, "end_to_end_ms": (recv[k] - (t0_ns + on * 1e9)) / 1e6,
                                      "algorithmic_ms": ((ftime[k] + dt) - on) * 1e3}
             for on, k in zip(onsets, found)]
    e2e = np.array([c["end_to_end_ms"] for c in calls if c])
    alg = np.array([c["algorithmic_ms"] for c in calls if c])
    # every frame's arrival after its audio block's end: the pipeline, the sink and the receiver thread together
    arrival = (recv - (t0_ns + (ftime + dt) * 1e9)) / 1e6
    m = sink.metrics()
    return {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "loadavg_1_5_15_before": [round(x, 2) for x in load0],
        "config": {"duration_s": ns.duration, "fps": fps, "receiver": ns.receiver, "sample_rate": sr, "profile": ns.profile,
                   "seed": ns.seed, "block_frames": ns.block_frames, "overrides": list(ns.override),
                   "block_samples": int(math.ceil(sr / fps)) * ns.block_frames, "delta_jaw": ns.delta,
                   "pipeline_streaming": "native (chunk_frames)" if native else "CHUNK_FRAMES patched to 1"},
        "frames_received": len(frames),
        "frames_expected": int(np.ceil(len(audio) * fps / sr - 1e-9)),
        "calls": len(onsets),
        "calls_measured": int(len(e2e)),
        "calls_skipped": len(onsets) - int(len(e2e)),
        "end_to_end": percentiles(e2e),
        "algorithmic": percentiles(alg),
        "system": percentiles(e2e - alg),
        "sink_capture_to_send": {"median_ms": m["vmc_latency_ms_p50"], "p90_ms": m["vmc_latency_ms_p90"],
                                 "max_ms": m["vmc_latency_ms_max"]},
        "every_frame_arrival_after_block": {**percentiles(arrival), "p99_ms": float(np.percentile(arrival, 99))},
        "frame_loop_behind": {**percentiles(mic.late_ms), "p99_ms": float(np.percentile(mic.late_ms, 99))},
        "process_cpu_share": cpu / wall,
        "frame_thread_cpu_share": thread / wall,   # the pipeline and the sink, without the receiver's thread
        "block_ms": 1000.0 * ns.block_frames / fps,
        "per_call": calls,
    }


def common_calls(runs: list) -> dict:
    """Medians over the calls measured at every fps of ``runs`` (each fps skips other calls)."""
    both = [i for i in range(runs[0]["calls"]) if all(r["per_call"][i] for r in runs)]
    out = {"calls": len(both)}
    for r in runs:
        out[f"{r['config']['fps']:g}"] = {
            key: float(np.median([r["per_call"][i][f"{key}_ms"] for i in both])) if both else None
            for key in ("algorithmic", "end_to_end")}
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="seconds of laughter (real time)")
    ap.add_argument("--fps", default="60", help="frame rate, or several to compare in one run: 60,120,144")
    ap.add_argument("--profile", default="mixed")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--block-frames", type=int, default=1, help="the mic source's block_frames")
    ap.add_argument("--delta", type=float, default=0.02, help="jawOpen rise that counts as a response")
    ap.add_argument("--out", default=str(HERE / "results" / "latency.json"))
    ap.add_argument("--receiver", choices=("process", "thread"), default="process",
                    help="the OSC receiver in a process of its own, as an avatar program is (default), or in a "
                         "thread of this one (before 2026-11-28)")
    ap.add_argument("override", nargs="*", help="configuration overrides (detector=none, face.jaw.rise=3...)")
    ns = ap.parse_args(argv)
    try:
        fpss = [float(f) for f in ns.fps.split(",")]
    except ValueError:
        ap.error(f"--fps takes numbers separated by commas (got {ns.fps!r})")

    runs = []
    for fps in fpss:
        r = measure(ns, fps)
        runs.append(r)
        e, a, s = r["end_to_end"], r["algorithmic"], r["system"]
        print(f"latency call onset -> jaw response in the OSC stream ({r['calls_measured']} of {r['calls']} calls, "
              f"{fps:g} fps, blocks of {r['block_ms']:.1f} ms; load {r['loadavg_1_5_15_before'][0]:.2f}):")
        print(f"  end to end   median {e['median_ms']:.1f} ms   p90 {e['p90_ms']:.1f} ms")
        print(f"  algorithmic  median {a['median_ms']:.1f} ms   p90 {a['p90_ms']:.1f} ms")
        print(f"  system       median {s['median_ms']:.1f} ms   p90 {s['p90_ms']:.1f} ms")
        sk, fa, fl = r["sink_capture_to_send"], r["every_frame_arrival_after_block"], r["frame_loop_behind"]
        print(f"  sink capture -> send median {sk['median_ms']:.2f} ms, p90 {sk['p90_ms']:.2f} ms, "
              f"max {sk['max_ms']:.2f} ms")
        print(f"  the frame loop took its blocks after they were due by: median {fl['median_ms']:.1f} ms, "
              f"p99 {fl['p99_ms']:.1f} ms, max {fl['max_ms']:.1f} ms")
        print(f"  every frame's arrival after its block: median {fa['median_ms']:.1f} ms, p99 {fa['p99_ms']:.1f} ms,"
              f" max {fa['max_ms']:.1f} ms; the process used {100 * r['process_cpu_share']:.0f}% of a core, its frame "
              f"thread {100 * r['frame_thread_cpu_share']:.0f}%")
    result = {
        "what": "delay from a laughter call onset (synthetic ground truth) to the jaw's response in the VMC/OSC "
                "stream received on 127.0.0.1; see benchmarks/bench_latency.py and docs/latency.md",
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "processor": platform.processor() or platform.machine(), "cpus": os.cpu_count()},
        **(runs[0] if len(runs) == 1 else {"runs": runs, "common_calls": common_calls(runs)}),
    }
    if len(runs) > 1:
        c = result["common_calls"]
        print(f"on the {c['calls']} calls measured at every fps: " + "; ".join(
            f"{f} fps algorithmic {v['algorithmic']:.1f} ms, end to end {v['end_to_end']:.1f} ms"
            for f, v in c.items() if f != "calls"))
    out = Path(ns.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"written: {out}")
    return result


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
