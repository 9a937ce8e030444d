"""What ``laughlab.session.Session`` costs a program that feeds it one frame of audio at a time: the time of each
``feed`` (hand-over to the session's thread, the frame computed, handed back), against the frame loop's own time
for that frame (``metrics.json``'s ``frame_ms_*``, measured inside the same run).

Input: the corpus' btanks ``laugh01`` brought to 48 kHz by scipy's ``resample_poly`` (without the corpus, 6 s of
the synthetic laughter, said in the output), fed in blocks of 800 samples (one 60 fps frame), ``face=facs``, the
default detector, 3 passes over it.

Run: ``python benchmarks/bench_session.py`` (about 20 s); writes ``benchmarks/results/session.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def audio_48k() -> tuple[np.ndarray, str]:
    from bench_viewer_live import laugh01

    x = laugh01(48000)
    if x is not None:
        return np.tile(x, 3).astype(np.float32), "btanks laugh01 at 48 kHz, 3 passes"
    from laughlab.synth.laughter import SyntheticLaughter

    synth = SyntheticLaughter(seed=0, duration_s=18.0, sample_rate=48000, profile="intense")
    return synth.render(0, synth.n_samples).astype(np.float32), "synthetic laughter, 18 s at 48 kHz (no corpus)"


def main() -> None:
    from laughlab.session import Session

    x, what = audio_48k()
    feed_ms = []
    with Session(["face=facs"], sample_rate=48000) as s:
        for i in range(0, len(x), 800):
            t0 = time.perf_counter()
            s.feed(x[i:i + 800])
            feed_ms.append((time.perf_counter() - t0) * 1000)
        s.close()
        m = s.metrics
    ms = np.array(feed_ms[30:])   # the first frames load the model
    result = {"input": what, "frames": int(m["n_frames"]), "feed_ms_mean": round(float(ms.mean()), 3),
              "feed_ms_p50": round(float(np.median(ms)), 3), "feed_ms_p99": round(float(np.percentile(ms, 99)), 3),
              "frame_loop_ms_p50": round(float(m["frame_ms_p50"]), 3),
              "frame_loop_ms_p99": round(float(m["frame_ms_p99"]), 3)}
    print(f"feed of one frame: mean {result['feed_ms_mean']} ms, median {result['feed_ms_p50']} ms, p99 "
          f"{result['feed_ms_p99']} ms; the frame loop inside: median {result['frame_loop_ms_p50']} ms, p99 "
          f"{result['frame_loop_ms_p99']} ms ({what}, {result['frames']} frames)")
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "session.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":   # --help prints what it measures; it took no arguments and ran (a review)
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
