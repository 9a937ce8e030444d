"""Benchmark of the pipeline on real-rate audio (issue 12).

The audio is real laughter: every laugh of the fetched corpus (``make corpus``), resampled to
the rate under test, joined with 0.5 s of silence and repeated to length, written as 16-bit WAV
files in a temporary folder (never committed).  On this machine it measures

1. the whole command ``python -m laughlab input=file input.path=X`` (start-up, configuration,
   the frame loop, every output, the plots) on 1 and 30 minutes at 44.1 kHz and 30 minutes at
   48 kHz, median of 3 runs; and the frame loop's real-time factor (``metrics.json``:
   reading audio, every plugin, handing chunks to the writers);
2. ``python -m laughlab --help``;
3. peak memory (max RSS of the main process) of whole runs on 1 and 30 minutes;
4. per-frame compute time p50/p99 of every extractor, detector, scheduler, face and body,
   each step alone, in-process, on 60 s of the same laughter at 44.1 and 48 kHz (the stages
   before it are the default pipeline's, or its partner's: ``body=hill`` after
   ``extractor=pressure``, ``face=cgm`` and ``scheduler=concat`` after ``extractor=phoneme``).

Targets (issue 12, the papers' pipeline: ``detector=none``): loop >= 1000x real time at 44.1 kHz; 30-min
command <= 3.6 s (>= 500x); 1-min command <= 1.5 s; ``--help`` <= 0.5 s; memory 30 min / 1 min <= 1.2.
Issue 27: the default (``detector=yamnet``) 30-min 44.1 kHz command >= 60x real time.

Run: ``make bench`` (or ``python benchmarks/bench_pipeline.py``); results in
``benchmarks/results/pipeline.json``.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RATES = (44100, 48000)
#: plugin kind -> (group, name, partner overrides)
PLUGINS = [
    ("extractor", "rms", []), ("extractor", "pressure", []), ("extractor", "phoneme", []),
    ("detector", "none", []), ("detector", "laugh", []), ("detector", "yamnet", []),
    ("scheduler", "energy", []), ("scheduler", "none", []), ("scheduler", "concat", ["extractor=phoneme"]),
    ("face", "smile", []), ("face", "facs", []), ("face", "cgm", ["extractor=phoneme"]),
    ("body", "shapes", []), ("body", "fourier", []), ("body", "follow", []),
    ("body", "hill", ["extractor=pressure"]),
]


def real_laughter(rate: int, seconds: float, path: Path) -> Path:
    """Every fetched laugh at ``rate``, 0.5 s apart, repeated to ``seconds``, as 16-bit WAV."""
    from math import gcd

    import soundfile as sf
    from scipy.signal import resample_poly

    from laughlab.corpora import fetch

    parts = []
    for _, p in sorted(fetch.require(kinds=["laugh"]).items()):
        x, sr = sf.read(str(p), dtype="float64", always_2d=True)
        x = x.mean(axis=1)
        if sr != rate:
            g = gcd(rate, sr)
            x = resample_poly(x, rate // g, sr // g)
        parts += [x, np.zeros(rate // 2)]
    one = np.concatenate(parts)
    n = int(seconds * rate)
    audio = np.tile(one, n // len(one) + 1)[:n]
    sf.write(str(path), np.clip(audio, -1, 1).astype(np.float32), rate, subtype="PCM_16")
    return path


def run_cli(*args: str, rss: bool = False) -> tuple[float, dict, float]:
    """One ``python -m laughlab`` in a child: wall seconds, metrics.json, peak RSS of the main process (MiB)."""
    # VmHWM, not ru_maxrss: Linux carries ru_maxrss across exec, so a child would report this
    # benchmark's own peak (it holds the long test signals)
    code = ("import sys\nfrom laughlab.cli import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit as e:\n    if e.code: raise\n"
            "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]\n"
            "print('RSS', hwm)\n")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-c", code] if rss else [sys.executable, "-m", "laughlab"]
        t0 = time.perf_counter()
        r = subprocess.run([*cmd, f"hydra.run.dir={out}", *args], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise SystemExit(f"run failed: {r.stderr.strip()}")
        mib = float(r.stdout.split("RSS")[-1].split()[0]) / 1024 if rss else float("nan")
        return wall, json.loads((out / "metrics.json").read_text()), mib


def whole_command(wav: Path, seconds: float, repeats: int = 3, detector: str = "yamnet") -> dict:
    run_cli("input=file", f"input.path={wav}", f"detector={detector}")  # warm-up: the new file into the page cache
    walls, loops = [], []
    for _ in range(repeats):
        wall, m, _ = run_cli("input=file", f"input.path={wav}", f"detector={detector}")
        walls.append(wall)
        loops.append(m["realtime_factor"])
    wall, loop = statistics.median(walls), statistics.median(loops)
    return {"command_s": wall, "command_realtime_factor": seconds / wall, "loop_realtime_factor": loop,
            "command_s_all": walls}


def help_seconds(repeats: int = 5) -> float:
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "laughlab", "--help"], capture_output=True, check=True)
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls)


def per_plugin(wav: Path, seconds: float = 60.0) -> dict:
    """p50/p99 (us) of each plugin's step alone, on ``seconds`` of ``wav``."""
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.core.config import compose_config, register_plugin_configs
    from laughlab.core.frame import Frame

    register_plugin_configs()
    out = {}
    for group, name, partner in PLUGINS:
        cfg = compose_config(["input=file", f"input.path={wav}", *partner, f"{group}={name}"])
        cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
        pipe = pipeline.build(cfg)
        stages = {"extractor": pipe.extractor, "detector": pipe.detector, "scheduler": pipe.scheduler,
                  "body": pipe.body, "face": pipe.face}
        for s in (*stages.values(), pipe.mixer):
            s.reset()
        if getattr(pipe.scheduler, "offline_plan", False):
            pipeline._plan_offline(pipe)
        dt, clock, ns = pipe.ctx.dt, time.perf_counter_ns, []
        n_max = int(seconds * pipe.ctx.fps)
        for k, block in enumerate(pipe.source.blocks()):
            if k >= n_max:
                break
            frame = Frame(k, k * dt, dt, {}, None, {}, {}, [], 0.0)
            for stage, plugin in stages.items():
                if stage == "body":
                    pipe.mixer.advance(frame)
                t0 = clock()
                plugin.step(block, frame) if stage in ("extractor", "detector") else plugin.step(frame)
                if stage == group:
                    ns.append(clock() - t0)
            pipe.mixer.note(frame)
            if k % 256 == 255:
                pipe.mixer.take()
        for s in (pipe.body, pipe.face):
            if callable(getattr(s, "close", None)):
                s.close()
        pipe.source.close()
        us = np.asarray(ns[int(pipe.ctx.fps):], dtype=float) / 1e3  # the first second warms caches and JITs
        out[f"{group}={name}"] = {"p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99))}
    return out


def main() -> None:
    results: dict = {"audio": "real laughter from the fetched corpus (every laugh, 0.5 s gaps, repeated), "
                              "16-bit WAV"}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        wav = {(r, m): real_laughter(r, m * 60, tmp / f"laugh_{r}_{m}min.wav") for r in RATES for m in (1, 30)}
        # the default (detector=yamnet) and the papers' pipeline (detector=none: issue 12's targets)
        for (rate, minutes, det) in ((44100, 1, "yamnet"), (44100, 30, "yamnet"), (44100, 1, "none"),
                                     (44100, 30, "none"), (48000, 30, "none")):
            res = whole_command(wav[(rate, minutes)], minutes * 60.0, detector=det)
            results[f"command_{rate}_{minutes}min" + ("_default" if det == "yamnet" else "")] = res
            print(f"{rate} Hz, {minutes} min, detector={det}: whole command {res['command_s']:.2f} s "
                  f"({res['command_realtime_factor']:.0f}x), frame loop {res['loop_realtime_factor']:.0f}x")
        results["help_s"] = help_seconds()
        print(f"--help: {results['help_s']:.2f} s")
        one = run_cli("input=file", f"input.path={wav[(44100, 1)]}", rss=True)[2]
        thirty = run_cli("input=file", f"input.path={wav[(44100, 30)]}", rss=True)[2]
        results["peak_rss_mib"] = {"1min": one, "30min": thirty, "ratio": thirty / one}
        print(f"peak memory: 1 min {one:.0f} MiB, 30 min {thirty:.0f} MiB, ratio {thirty / one:.2f}")
        results["per_plugin_us"] = {}
        for rate in RATES:
            table = per_plugin(wav[(rate, 1)])
            results["per_plugin_us"][str(rate)] = table
            for key, v in table.items():
                print(f"  {rate} Hz {key:<22} p50 {v['p50_us']:8.1f} us  p99 {v['p99_us']:8.1f} us")
    c1, c30 = results["command_44100_1min"], results["command_44100_30min"]
    results["targets_met"] = {
        "loop_ge_1000x_44k": c30["loop_realtime_factor"] >= 1000,
        "command_30min_le_3.6s": c30["command_s"] <= 3.6,
        "command_1min_le_1.5s": c1["command_s"] <= 1.5,
        "help_le_0.5s": results["help_s"] <= 0.5,
        "memory_ratio_le_1.2": results["peak_rss_mib"]["ratio"] <= 1.2,
        "default_30min_ge_60x": results["command_44100_30min_default"]["command_realtime_factor"] >= 60,
    }
    print("targets:", ", ".join(f"{k} {'met' if v else 'NOT met'}" for k, v in results["targets_met"].items()))
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "pipeline.json").write_text(json.dumps(results, indent=2) + "\n")
    print(f"written to {out / 'pipeline.json'}")


if __name__ == "__main__":   # --help prints what it measures; it took no arguments and ran (a review)
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
