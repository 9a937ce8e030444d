"""Benchmark of the default pipeline (issue: foundation, section 7).

Measures, on this machine:

1. per-frame compute time p50 and p99 (ms) of the default pipeline on 60 s of
   synthetic laughter (target: p99 <= 1 ms);
2. offline throughput on 10 minutes of audio read from a WAV file: the
   real-time factor of the frame loop (reading audio, every plugin, streaming
   channels.csv and motion.bvh), and the end-to-end wall time of the whole
   ``python -m laughlab`` command including start-up and drawing the plots
   (target: at least 500 times faster than real time);
3. peak memory (max RSS) of whole runs on 1 and 60 minutes of audio
   (target: 60 min at most 1.2 x 1 min).

Run: ``make bench`` (or ``python benchmarks/bench_pipeline.py``).  Results are
printed and written to ``benchmarks/results/pipeline.json``.
"""
from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def run_cli(*args: str) -> tuple[float, dict]:
    """Run ``python -m laughlab`` in a child; return wall seconds and metrics.json."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "laughlab", f"hydra.run.dir={out}", *args],
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise SystemExit(f"run failed: {r.stderr.strip()}")
        return wall, json.loads((out / "metrics.json").read_text())


def child_peak_rss(minutes: float) -> float:
    """Max RSS (MiB) of a whole default run on ``minutes`` of synthetic laughter, in a fresh process."""
    code = (
        "import resource, sys\n"
        "from laughlab.cli import main\n"
        "try:\n"
        "    main(sys.argv[1:])\n"
        "except SystemExit as e:\n"
        "    if e.code: raise\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    with tempfile.TemporaryDirectory() as tmp:
        r = subprocess.run([sys.executable, "-c", code, f"hydra.run.dir={tmp}/run",
                            f"input.duration_s={minutes * 60}", "input.save_audio=false"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"memory run failed: {r.stderr.strip()}")
        return int(r.stdout.strip().splitlines()[-1]) / 1024.0


def main() -> None:
    from laughlab.io.audio import FloatWavWriter
    from laughlab.synth.laughter import SyntheticLaughter

    results: dict = {}
    # 1. per-frame compute time
    _, m = run_cli("input.duration_s=60")
    results["frame_ms_p50"] = m["frame_ms_p50"]
    results["frame_ms_p99"] = m["frame_ms_p99"]
    print(f"per-frame compute (60 s input): p50 {m['frame_ms_p50'] * 1000:.1f} us, "
          f"p99 {m['frame_ms_p99'] * 1000:.1f} us  (target p99 <= 1000 us)")

    # 2. offline throughput on 10 minutes read from a file
    with tempfile.TemporaryDirectory() as tmp:
        wav = Path(tmp) / "ten_minutes.wav"
        synth = SyntheticLaughter(seed=0, duration_s=600.0)
        with FloatWavWriter(wav, synth.sample_rate) as f:
            for start in range(0, synth.n_samples, 16000):
                f.write(synth.render(start, min(16000, synth.n_samples - start)))
        wall, m = run_cli("input=file", f"input.path={wav}")
    results["offline_10min_loop_realtime_factor"] = m["realtime_factor"]
    results["offline_10min_loop_s"] = m["wall_s"]
    results["offline_10min_command_s"] = wall
    results["offline_10min_command_realtime_factor"] = 600.0 / wall
    print(f"offline, 10 min of audio: frame loop {m['wall_s']:.2f} s = {m['realtime_factor']:.0f}x real time; "
          f"whole command incl. start-up and plots {wall:.2f} s = {600.0 / wall:.0f}x  (target >= 500x)")

    # 3. peak memory, 1 vs 60 minutes
    one, sixty = child_peak_rss(1), child_peak_rss(60)
    results["peak_rss_1min_mib"] = one
    results["peak_rss_60min_mib"] = sixty
    results["peak_rss_ratio_60_over_1"] = sixty / one
    print(f"peak memory: 1 min {one:.0f} MiB, 60 min {sixty:.0f} MiB, ratio {sixty / one:.3f}  (target <= 1.2)")

    results["targets_met"] = {
        "p99_le_1ms": results["frame_ms_p99"] <= 1.0,
        "offline_ge_500x": results["offline_10min_loop_realtime_factor"] >= 500,
        "memory_ratio_le_1.2": results["peak_rss_ratio_60_over_1"] <= 1.2,
    }
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / "pipeline.json").write_text(json.dumps(results, indent=2) + "\n")
    print(f"written to {out / 'pipeline.json'}")


if __name__ == "__main__":
    main()
