"""What ``laughlab.session.Session`` costs a program that feeds it one frame of audio at a time: the time of each
``feed`` (hand-over to the session's thread, the frame computed, handed back), against the frame loop's own time
for that frame (``metrics.json``'s ``frame_ms_*``, measured inside the same run).

Input: the corpus' btanks ``laugh01`` brought to 48 kHz by scipy's ``resample_poly`` (without the corpus, 6 s of
the synthetic laughter, said in the output), fed in blocks of 800 samples (one 60 fps frame), ``face=facs``, the
default detector, 3 passes over it.

Run: ``python benchmarks/bench_session.py`` (about 20 s); writes ``benchmarks/results/session.json``.
``--paced`` feeds one block every 1/60 s, as a game's loop does (a frame budget review, 2026-11-29: back to back,
the figures were up to 2.5-3 times lower than paced under load, where each feed wakes the session's thread; 1.1-2.5
times in quieter sittings); ``--overrides
body=hill`` (any of the command line's) measures another pipeline.  Besides the mean, median and p99 it gives the
first feed (warm-up), the worst of the feeds after the first 30 (the model's first windows) and how many of them
took over 1 ms, and how many feeds of all took over a 60 fps frame (16.7 ms).
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


def main(paced: bool = False, overrides: tuple[str, ...] = ()) -> None:
    from laughlab.session import Session

    x, what = audio_48k()
    feed_ms = []
    with Session(["face=facs", *overrides], sample_rate=48000) as s:
        due = time.perf_counter()
        for i in range(0, len(x), 800):
            if paced:   # the game's frame clock: each block when its frame is due
                due += 1 / 60
                time.sleep(max(0.0, due - time.perf_counter()))
            t0 = time.perf_counter()
            s.feed(x[i:i + 800])
            feed_ms.append((time.perf_counter() - t0) * 1000)
        s.close()
        m = s.metrics
    ms = np.array(feed_ms[30:])   # the first frames load the model
    result = {"input": what, "frames": int(m["n_frames"]), "paced": paced, "overrides": list(overrides),
              "feed_ms_first": round(feed_ms[0], 3), "feed_ms_mean": round(float(ms.mean()), 3),
              "feed_ms_p50": round(float(np.median(ms)), 3), "feed_ms_p99": round(float(np.percentile(ms, 99)), 3),
              "feed_ms_max": round(float(ms.max()), 3), "feeds_over_1ms": int((ms > 1).sum()),
              "feeds_over_16_7ms": int((np.array(feed_ms) > 1000 / 60).sum()),
              "frame_loop_ms_p50": round(float(m["frame_ms_p50"]), 3),
              "frame_loop_ms_p99": round(float(m["frame_ms_p99"]), 3)}
    print(f"feed of one frame{' (paced at 60 fps)' if paced else ''}{' ' + ' '.join(overrides) if overrides else ''}:"
          f" first {result['feed_ms_first']} ms; then mean {result['feed_ms_mean']} ms, median {result['feed_ms_p50']}"
          f" ms, p99 {result['feed_ms_p99']} ms, max {result['feed_ms_max']} ms, {result['feeds_over_1ms']} over 1 ms,"
          f" {result['feeds_over_16_7ms']} over 16.7 ms; the frame loop inside: median {result['frame_loop_ms_p50']}"
          f" ms, p99 {result['frame_loop_ms_p99']} ms ({what}, {result['frames']} frames)")
    (HERE / "results").mkdir(exist_ok=True)
    name = "session" + ("_paced" if paced else "") + "".join("_" + o.replace("=", "-") for o in overrides)
    (HERE / "results" / f"{name}.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":   # --help prints what it measures (a review: it took no arguments and ran)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--paced", action="store_true", help="one block every 1/60 s, as a game's loop feeds")
    ap.add_argument("--overrides", nargs="*", default=[], help="the command line's overrides, e.g. body=hill")
    ns = ap.parse_args()
    main(ns.paced, tuple(ns.overrides))
