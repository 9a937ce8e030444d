"""The clip-gate rules of ``detector=yamnet`` on the held-out (test) split: ``either`` (the default), ``classes``
(YAMNet's own laughter classes), ``head`` (the first rule: the head alone, every 0.5 s, two windows in a row) and
``fused`` (``detector=yamnet_fused``; ``fused-0.5x2`` and ``fused-0.7x1`` are two more points of its train curve).

Runs the default live pipeline (``benchmarks/bench_detector.py``'s ``run_pipeline``, the metrics of
``experiment=detector_eval``) on the sets ``speech``, ``mixed``, ``between``, ``real`` and ``others`` of the test split
once per rule, and prints per rule: clip starts per minute of speech, bouts answered (per-file mean and pooled),
the gate's frame F1, the first clip after a bout starts (median), false starts in ``mixed`` (on speech,
on other sounds), clip starts in the second after a bout ended, and the other human sounds alone that start a
clip.  Writes
``benchmarks/results/yamnet_rules.json``.  The thresholds were chosen on the train split
(``python -m laughlab.detector.yamnet_fit --rules``); nothing here feeds back into them.

Run: ``python benchmarks/bench_yamnet_rules.py [--work DIR] [--jobs 2]`` (about a minute per rule on 2
cores: the pipelines run in-process, ``--jobs`` at once; ``--work`` keeps the runs, and a run already there
is not repeated).
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import bench_detector as B  # noqa: E402
from laughlab.harness.trialdata import TrialData  # noqa: E402

RULES = {
    "either": [],   # the defaults of conf/detector/yamnet.yaml
    # the veto of windows where YAMNet hears another human sound more than laughter (detector.veto): the default
    # vetoes the classes' score; none (the default before 2026-11-26) and both (the head's probability too)
    "either-noveto": ["detector.veto=none"],
    "either-vetoboth": ["detector.veto=both"],
    "classes": ["detector.rule=classes"],
    "head": ["detector.rule=head", "detector.hop_s=0.5", "detector.open_windows=2", "detector.close_quiet_s=0"],
    # detector=yamnet_fused: the fused head (YAMNet with the feature MLP's cues) at the rule chosen on the train split
    # (yamnet_fit --fuse --rules): detector.fuse=true detector.open_at=0.6 detector.open_windows=2
    "fused": ["detector.fuse=true", "detector.open_at=0.6", "detector.open_windows=2"],
    # two more of its operating points on the train split's curve, for the trade-off (not chosen here)
    "fused-0.5x2": ["detector.fuse=true", "detector.open_at=0.5", "detector.open_windows=2"],
    "fused-0.7x1": ["detector.fuse=true", "detector.open_at=0.7", "detector.open_windows=1"],
}
SETS = ("speech", "mixed", "between", "real", "others")
OTHER = ("cough", "sneeze", "scream", "music", "noise", "vocal")


def _mean(rows: list[dict], key: str) -> float:
    v = [r[key] for r in rows if isinstance(r.get(key), (int, float)) and not math.isnan(r[key])]
    return float(np.mean(v)) if v else float("nan")


def pooled(run_dir: Path, wav: Path) -> dict:
    """Counts of one run: bouts, bouts answered, first-clip delays, late starts, false starts by kind."""
    truth = wav.with_name(wav.stem + ".truth.csv")
    t = TrialData.load(run_dir, truth if truth.exists() else None)
    s = t.starts()
    st = s.time.to_numpy() if len(s) else np.zeros(0)
    out = {"starts": len(st), "minutes": t.duration_s / 60, "bouts": 0, "answered": 0, "late": 0, "delays": [],
           "false_speech": 0, "speech_min": 0.0, "false_other": 0, "other_min": 0.0}
    if t.truth is None:
        return out
    heard = np.zeros(len(st), bool)
    for on, off in t.truth.bouts[["onset_s", "offset_s"]].itertuples(index=False):
        inside = (st >= on) & (st <= off + 1.0)
        heard |= inside
        out["bouts"] += 1
        out["answered"] += int(inside.any())
        out["late"] += int(((st > off) & (st <= off + 1.0)).sum())
        if inside.any():
            out["delays"].append(float(st[inside].min() - on))
    o = t.truth.others
    if o is not None and not o.empty:
        for kinds, key in ((("speech",), "speech"), (OTHER, "other")):
            ev = o[o.kind.isin(kinds)]
            out[f"{key}_min"] += float((ev.offset_s - ev.onset_s).sum()) / 60
            a, b = ev.onset_s.to_numpy(), ev.offset_s.to_numpy()
            out[f"false_{key}"] += sum(bool(((a <= x) & (x < b)).any()) for x in st[~heard])
    return out


def _one(job):
    """One file under one rule (a process-pool job): (set, metrics, counts)."""
    rule, work, s, w = job
    d = work / rule / f"{s}-{w.stem}"
    if (d / "metrics.json").exists():   # kept from an earlier call with --work
        truth = w.with_name(w.stem + ".truth.csv")
        m = B.compute(TrialData.load(d, truth if truth.exists() else None))
    else:
        m = B.run_pipeline(w, d, "yamnet", RULES[rule])
    return s, m, pooled(d, w)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", default=None, help="keep the runs here (default: a temporary folder)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rules", default=",".join(RULES))
    ns = ap.parse_args()
    work = Path(ns.work or tempfile.mkdtemp(prefix="bench_yamnet_rules_"))
    sets = B.held_out_sets()
    res = {}
    for rule in ns.rules.split(","):
        jobs = [(s, w) for s in SETS for w in sets[s]]
        with cf.ProcessPoolExecutor(ns.jobs) as ex:
            got = list(ex.map(_one, [(rule, work, s, w) for s, w in jobs]))
        r = {}
        for s in SETS:
            ms = [m for k, m, _ in got if k == s]
            ps = [p for k, _, p in got if k == s]
            tot = {k: sum(p[k] for p in ps) for k in ps[0] if k != "delays"}
            delays = [d for p in ps for d in p["delays"]]
            r[s] = {**tot, "files": len(ms), "bouts_answered_mean": _mean(ms, "bouts_answered"),
                    "detector_f1_mean": _mean(ms, "detector_f1"),
                    "first_clip_median_s_mean": _mean(ms, "onset_latency_median_s"),
                    "gate_open_median_s_mean": _mean(ms, "detection_latency_median_s"),
                    "first_clip_median_s_pooled": float(np.median(delays)) if delays else float("nan"),
                    "false_starts_per_min_mean": _mean(ms, "false_starts_per_min"),
                    "started": sum(int(m.get("human_sounds_starting_a_clip", 0) > 0) for m in ms),
                    "started_by_kind": B.by_kind([w for k, w in jobs if k == s],
                                                 [m.get("human_sounds_starting_a_clip", 0) > 0 for m in ms]),
                    "by_file": [{"file": w.stem, **{k: m.get(k) for k in ("bouts_answered", "false_starts_per_min",
                                                                           "false_starts_speech_per_min")}}
                                for (k, w), (_, m, _) in zip(jobs, got) if k == s]}
        res[rule] = {"overrides": RULES[rule], "sets": r}
        sp, mx, re, bt, ot = r["speech"], r["mixed"], r["real"], r["between"], r["others"]
        print(f"{rule}: speech {sp['starts'] / max(sp['minutes'], 1e-9):.2f} starts/min; real answered "
              f"{re['bouts_answered_mean']:.2f} ({re['answered']}/{re['bouts']}), F1 {re['detector_f1_mean']:.2f}, "
              f"first clip {re['first_clip_median_s_mean']:.2f} s (pooled {re['first_clip_median_s_pooled']:.2f} s); "
              f"mixed answered {mx['answered']}/{mx['bouts']}, F1 {mx['detector_f1_mean']:.2f}, false starts on "
              f"speech {mx['false_speech']} ({mx['speech_min']:.1f} min), on other sounds {mx['false_other']} "
              f"({mx['other_min']:.1f} min); between speech answered {bt['answered']}/{bt['bouts']}, false starts on "
              f"speech {bt['false_speech']} ({bt['speech_min']:.1f} min), first clip {bt['first_clip_median_s_pooled']:.2f} s"
              f"; starts in the second after a bout: {mx['late'] + re['late']}; other human sounds alone starting a "
              f"clip: {ot['started']}/{ot['files']}",
              flush=True)
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "yamnet_rules.json").write_text(json.dumps({"data": "test split", **res}, indent=1) + "\n")


if __name__ == "__main__":
    main()
