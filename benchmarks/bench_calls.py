"""Benchmark of the ``phoneme`` extractor's call detection, labels, prosody and cost.

On the synthetic corpus (``laughlab.synth.laughter.SyntheticLaughter``, every profile of
``PROFILES``, seeds 0..N-1), the extractor runs frame by frame exactly as in a
run (60 fps, 16 kHz) and is scored against the ground truth:

1. **call onsets**: detections (frames with ``call_onset`` = 1, at the frame's
   start time) matched one to one to the true ``Call.onset_s`` within +/-50 ms
   (:func:`laughlab.harness.events.match_onsets`); precision, recall and F1 per profile,
   pooled over all runs and averaged over runs; the onset error distribution
   (detected - true: median, and median / p90 / max of its magnitude, ms);
2. **labels**: per frame, the truth at the analysis window's centre is
   ``fricative`` in a call's breathy onset and in the in-breaths, ``a`` in a
   call's voiced part and decay, ``silence`` elsewhere (the breath-noise gaps
   between calls count as either silence or fricative); the confusion counts and
   the agreement (the only three classes the corpus holds);
3. **prosody against Praat** (first ``--praat-seeds`` seeds): intensity
   correlation and median absolute difference (dB); F0 error in cents over the
   frames both call voiced (median, p90, share within 50 cents); voicing agreement;
4. **cost**: time of ``step`` per frame (us, p50 / p99 / mean).

Run: ``python benchmarks/bench_calls.py [--seeds 20] [--duration 30]``.  Prints
a table and writes ``benchmarks/results/calls.json``.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from laughlab.io.audio import cut_frames  # noqa: E402
from laughlab.core.bases import Context  # noqa: E402
from laughlab.harness.events import match_onsets, prf  # noqa: E402
from laughlab.core.frame import Frame  # noqa: E402
from laughlab.signals.prosody import frame_centers, praat_prosody  # noqa: E402
from laughlab.synth.laughter import PROFILES, SyntheticLaughter  # noqa: E402
from laughlab_plugins.extractor_phoneme import PhonemeExtractor, PhonemeParams  # noqa: E402

SR, FPS, TOL_S = 16000, 60.0, 0.05


def truth_labels(s: SyntheticLaughter, times: np.ndarray) -> list[str]:
    """Frame truth: fricative (breathy onset, in-breath), a (voiced part, decay), gap, silence."""
    on, off = s._call_on, s._call_off
    out = []
    for t in times:
        i = int(np.searchsorted(on, t, side="right")) - 1
        if i >= 0 and t < off[i]:
            out.append("fricative" if t - on[i] < s._asp[i] else "a")
            continue
        lab = "silence"
        for a, b, _ in s._inhales:
            if a <= t < b:
                lab = "fricative"
        if lab == "silence" and i >= 0 and i + 1 < len(on) and s.calls[i + 1].bout == s.calls[i].bout:
            lab = "gap"  # breath noise between two calls of a bout
        out.append(lab)
    return out


def run_one(profile: str, seed: int, duration: float, praat: bool) -> dict:
    s = SyntheticLaughter(seed=seed, duration_s=duration, sample_rate=SR, profile=profile)
    x = s.audio()
    ext = PhonemeExtractor(PhonemeParams(), Context(fps=FPS, sample_rate=SR))
    onsets, labels, f0, db, cost = [], [], [], [], []
    clock = time.perf_counter_ns
    for k, block in enumerate(cut_frames([x], SR, FPS)):
        frame = Frame(k, k / FPS, 1 / FPS)
        t0 = clock()
        ext.step(block, frame)
        cost.append(clock() - t0)
        c = frame.control
        if c["call_onset"] > 0:
            onsets.append(frame.time_s)
        labels.append(frame.label)
        f0.append(c["f0"])
        db.append(c["intensity"])
    tp, fp, fn, err = match_onsets(onsets, [c.onset_s for c in s.calls], TOL_S)
    centers = frame_centers(len(labels), SR, FPS, ext.params.window_s)
    conf = Counter(zip(truth_labels(s, centers), labels))
    out = {"profile": profile, "seed": seed, "tp": tp, "fp": fp, "fn": fn, "errors_s": err,
           "confusion": conf, "cost_ns": cost}
    if praat:
        p = ext.params
        pf0, pdb = praat_prosody(x, SR, centers, window_s=p.window_s, pitch_floor_hz=p.pitch_floor_hz,
                                 pitch_ceiling_hz=p.pitch_ceiling_hz)
        out["praat"] = (np.array(f0), np.array(db), pf0, pdb)
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds per profile (default 20)")
    ap.add_argument("--duration", type=float, default=30.0, help="seconds of laughter per run (default 30)")
    ap.add_argument("--praat-seeds", type=int, default=3, help="seeds per profile compared with Praat")
    ap.add_argument("--out", default=str(HERE / "results" / "calls.json"))
    args = ap.parse_args(argv)

    t_start = time.perf_counter()
    per_profile, all_err, all_runs, conf, costs, praat = {}, [], [], Counter(), [], []
    for profile in PROFILES:
        runs = [run_one(profile, seed, args.duration, seed < args.praat_seeds) for seed in range(args.seeds)]
        tp, fp, fn = (sum(r[k] for r in runs) for k in ("tp", "fp", "fn"))
        p, r, f = prf(tp, fp, fn)
        err = [e for run in runs for e in run["errors_s"]]
        run_f1 = [prf(x["tp"], x["fp"], x["fn"])[2] for x in runs]
        per_profile[profile] = {"tp": tp, "fp": fp, "fn": fn, "precision": p, "recall": r, "f1": f,
                                "f1_mean_over_seeds": float(np.mean(run_f1)), "f1_min_over_seeds": float(np.min(run_f1)),
                                "onset_error_median_ms": 1e3 * float(np.median(err)) if err else None,
                                "onset_abs_error_p90_ms": 1e3 * float(np.percentile(np.abs(err), 90)) if err else None}
        all_err += err
        all_runs += runs
        for run in runs:
            conf.update(run["confusion"])
            costs += run["cost_ns"]
            if "praat" in run:
                praat.append(run["praat"])
        print(f"{profile:15s} P {p:.3f}  R {r:.3f}  F1 {f:.3f}  (mean over seeds {np.mean(run_f1):.3f}, "
              f"min {np.min(run_f1):.3f})  tp {tp} fp {fp} fn {fn}", flush=True)

    tp, fp, fn = (sum(r[k] for r in all_runs) for k in ("tp", "fp", "fn"))
    p, r, f = prf(tp, fp, fn)
    err_ms = 1e3 * np.array(all_err)
    run_f1 = [prf(x["tp"], x["fp"], x["fn"])[2] for x in all_runs]
    overall = {"tp": tp, "fp": fp, "fn": fn, "precision": p, "recall": r, "f1": f,
               "f1_mean_over_runs": float(np.mean(run_f1)), "f1_min_over_runs": float(np.min(run_f1)),
               "onset_error_median_ms": float(np.median(err_ms)),
               "onset_abs_error_median_ms": float(np.median(np.abs(err_ms))),
               "onset_abs_error_p90_ms": float(np.percentile(np.abs(err_ms), 90)),
               "onset_abs_error_max_ms": float(np.max(np.abs(err_ms))),
               "onset_error_histogram_ms": dict(zip(
                   [f"{a:+d}..{b:+d}" for a, b in zip(range(-50, 50, 10), range(-40, 60, 10))],
                   np.histogram(err_ms, bins=np.arange(-50, 51, 10))[0].tolist()))}

    # labels: the three classes the corpus holds; gaps may be silence or fricative
    ok = sum(n for (t, lab), n in conf.items() if t == lab or (t == "gap" and lab in ("silence", "fricative")))
    total = sum(conf.values())
    confusion = {t: {lab: n for (tt, lab), n in sorted(conf.items()) if tt == t}
                 for t in ("silence", "gap", "fricative", "a")}
    labels = {"agreement": ok / total, "frames": total, "confusion": confusion,
              "per_class_recall": {t: (sum(n for lab, n in confusion[t].items()
                                           if lab == t or (t == "gap" and lab in ("silence", "fricative")))
                                       / max(1, sum(confusion[t].values())))
                                   for t in confusion}}

    f0, db, pf0, pdb = (np.concatenate([x[i] for x in praat]) for i in range(4))
    fin = np.isfinite(pf0) & np.isfinite(pdb)
    both = fin & (f0 > 0) & (pf0 > 0)
    cents = np.abs(1200 * np.log2(f0[both] / pf0[both]))
    prosody = {"frames": int(fin.sum()), "runs": len(praat),
               "intensity_r": float(np.corrcoef(db[fin], pdb[fin])[0, 1]),
               "intensity_abs_diff_median_db": float(np.median(np.abs(db[fin] - pdb[fin]))),
               "intensity_abs_diff_p99_db": float(np.percentile(np.abs(db[fin] - pdb[fin]), 99)),
               "f0_frames_both_voiced": int(both.sum()),
               "f0_cents_median": float(np.median(cents)), "f0_cents_p90": float(np.percentile(cents, 90)),
               "f0_within_50_cents": float(np.mean(cents < 50)),
               "f0_octave_errors": float(np.mean(cents > 600)),
               "voicing_agreement": float(np.mean((f0[fin] > 0) == (pf0[fin] > 0)))}

    c_us = np.array(costs) / 1e3
    cost = {"frames": int(c_us.size), "p50_us": float(np.median(c_us)), "p99_us": float(np.percentile(c_us, 99)),
            "mean_us": float(c_us.mean()), "budget_us": 150.0}

    result = {"benchmark": "phoneme extractor: call onsets, labels, prosody vs Praat, cost",
              "corpus": {"profiles": list(PROFILES), "seeds_per_profile": args.seeds,
                         "duration_s": args.duration, "sample_rate": SR, "fps": FPS, "tolerance_s": TOL_S},
              "calls": {"per_profile": per_profile, "overall": overall},
              "labels": labels, "prosody_vs_praat": prosody, "cost_per_frame": cost,
              "machine": {"python": platform.python_version(), "platform": platform.platform()},
              "wall_s": time.perf_counter() - t_start}
    print(f"{'overall':15s} P {p:.3f}  R {r:.3f}  F1 {f:.3f}  (mean over {len(all_runs)} runs "
          f"{overall['f1_mean_over_runs']:.3f}, min {overall['f1_min_over_runs']:.3f})")
    print(f"onset error: median {overall['onset_error_median_ms']:+.1f} ms, |error| median "
          f"{overall['onset_abs_error_median_ms']:.1f} ms, p90 {overall['onset_abs_error_p90_ms']:.1f} ms, "
          f"max {overall['onset_abs_error_max_ms']:.1f} ms")
    print(f"labels: agreement {labels['agreement']:.3f} over {total} frames; recall per truth class "
          + ", ".join(f"{k} {v:.3f}" for k, v in labels["per_class_recall"].items()))
    print(f"vs Praat: intensity r {prosody['intensity_r']:.5f}, median |diff| "
          f"{prosody['intensity_abs_diff_median_db']:.3f} dB; F0 median {prosody['f0_cents_median']:.1f} cents, "
          f"{100 * prosody['f0_within_50_cents']:.1f}% within 50 cents, voicing agreement "
          f"{prosody['voicing_agreement']:.3f}")
    print(f"cost per frame: p50 {cost['p50_us']:.0f} us, p99 {cost['p99_us']:.0f} us, mean {cost['mean_us']:.0f} us")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2, sort_keys=False) + "\n")
    print(f"wrote {out}")
    return result


if __name__ == "__main__":
    main()
