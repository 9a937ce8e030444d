"""Every face x body on real laughter, next to the synthetic generator (issue 11).

For each held-out real laugh with hand-annotated calls (the real corpus'
``test`` split: ``python -m laughlab corpus list``), and for two synthetic
inputs with their ground truth, each face (smile, facs, cgm) x body (shapes,
fourier, follow, hill) runs as a user would run it (``input=file`` at the
file's own rate, 44.1 or 48 kHz; default scheduler).  Extractor: ``phoneme``
for ``face=cgm`` (its Gaussian model reads pitch and phonemes), else
``pressure`` for ``body=hill`` (its lung pressure), else ``rms``.

Per combination it prints the median over inputs of:

* ``jaw_env_r``: the ``jaw_envelope_r`` metric, jawOpen (or ``jaw``) against
  the sound's frame RMS at the best lag in [0, 0.1] s; and the share of inputs
  where it reaches the issue's target (facs >= 0.6, cgm >= 0.7);
* ``calls``: calls found / annotated, and the share of inputs within +/-1:
  for ``body=hill`` the calls ``experiment=hill_fit`` cuts
  (:func:`laughlab.hill.fit.find_calls`), otherwise the phoneme extractor's
  call onsets (``-`` when the combination finds no calls);
* for ``body=hill``: the offline per-call fit (``experiment=hill_fit``'s
  :func:`laughlab.hill.fit.fit`): median normalised error, median seconds and
  mean evaluations per call (one core; fits run one after the other), over the
  calls it fits (quiet calls, whose pressure the extractor's floor cleared, are
  counted but not driven: ``FitParams.quiet_frac``).

Run: ``python benchmarks/bench_real.py [--split test|train] [--limit N]``;
prints a table and writes ``benchmarks/results/real.json``.  Needs the real
corpus (``make corpus``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FACES = ("smile", "facs", "cgm")
BODIES = ("shapes", "fourier", "follow", "hill")
TARGET_R = {"facs": 0.6, "cgm": 0.7}
SYNTHETIC = (("synthetic/mixed-s00", ["input=synthetic", "input.profile=mixed", "input.seed=0", "input.duration_s=20"]),
             ("synthetic/intense-s01", ["input=synthetic", "input.profile=intense", "input.seed=1",
                                        "input.duration_s=20"]))


def extractor_for(face: str, body: str) -> str:
    return "phoneme" if face == "cgm" else ("pressure" if body == "hill" else "rms")


def real_items(split: str) -> list[tuple[str, list[str], int]]:
    """``(id, overrides, annotated calls)`` of the real laughs of ``split`` with annotated calls."""
    import csv

    from laughlab.corpora import annotations, fetch

    root = fetch.corpus_dir()
    manifest = {r["id"]: r for r in csv.DictReader(open(root / "manifest.csv"))}
    out = []
    for iid, path in sorted(fetch.available().items()):
        ann = annotations.bundled(iid)
        if ann is None or not ann.calls or manifest[iid]["split"] != split:
            continue
        out.append((iid, ["input=file", f"input.path={path}"], len(ann.calls)))
    return out


def synthetic_items() -> list[tuple[str, list[str], int]]:
    from laughlab.harness.runner import _compose
    from laughlab.synth.laughter import SyntheticLaughter

    out = []
    for iid, ov in SYNTHETIC:
        cfg = _compose(ov)
        s = SyntheticLaughter(seed=int(cfg.input.seed), duration_s=float(cfg.input.duration_s),
                              profile=str(cfg.input.profile))
        out.append((iid, ov, len(s.calls)))
    return out


def run_combo(face: str, body: str, overrides: list[str], out: Path) -> dict:
    """One run; its jaw-envelope r and the phoneme extractor's call count (None without one)."""
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.harness.metrics import compute
    from laughlab.harness.runner import _compose
    from laughlab.harness.trialdata import TrialData

    cfg = _compose([*overrides, f"face={face}", f"body={body}", f"extractor={extractor_for(face, body)}",
                    "output=trial", "seed=0"])
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    pipe = pipeline.build(cfg)
    pipeline.execute(pipe, out, OmegaConf.to_container(cfg, resolve=True))
    data = TrialData.load(out)
    m = compute(data)
    ch = data.channels
    calls = int((ch["call_onset"] > 0).sum()) if "call_onset" in ch else None
    shutil.rmtree(out, ignore_errors=True)
    return {"jaw_envelope_r": m["jaw_envelope_r"], "calls": calls}


def hill_fit_of(overrides: list[str]) -> dict:
    """``experiment=hill_fit``'s offline fit of an input: calls found, per-call error, seconds, evaluations."""
    from laughlab.harness.runner import _compose
    from laughlab.hill.fit import FitParams, fit
    from laughlab_experiments.hill_fit import extract_target

    cfg = _compose([*overrides, "extractor=pressure", "body=hill"])
    target, fps, _, level = extract_target(cfg)
    res = fit(target, fps, FitParams(), level=level)
    fitted = [c for c in res.calls if c.driven]      # quiet calls are not fitted (FitParams.quiet_frac)
    return {"calls": len(res.calls), "quiet": len(res.calls) - len(fitted), "errors": [c.error for c in fitted],
            "seconds": [c.seconds for c in fitted], "evals": [c.evals for c in fitted]}


def summarise(rows: list[dict], face: str, body: str) -> dict:
    r = np.array([x["jaw_envelope_r"] for x in rows], dtype=float)
    found = [(x["calls"], x["annotated"]) for x in rows if x["calls"] is not None]
    out = {"inputs": len(rows), "jaw_envelope_r_median": float(np.nanmedian(r)) if np.isfinite(r).any() else None,
           "jaw_envelope_r_min": float(np.nanmin(r)) if np.isfinite(r).any() else None}
    if face in TARGET_R:
        out["share_at_target_r"] = float(np.mean(r >= TARGET_R[face]))
    if found:
        f = np.array(found, dtype=float)
        out["calls_found"], out["calls_annotated"] = int(f[:, 0].sum()), int(f[:, 1].sum())
        out["share_calls_within_1"] = float(np.mean(np.abs(f[:, 0] - f[:, 1]) <= 1))
    if body == "hill":
        errs = np.concatenate([x["hill"]["errors"] for x in rows])
        secs = np.concatenate([x["hill"]["seconds"] for x in rows])
        evals = np.concatenate([x["hill"]["evals"] for x in rows])
        out.update({"hill_error_median": float(np.nanmedian(errs)), "hill_error_mean": float(np.nanmean(errs)),
                    "hill_seconds_per_call_median": float(np.median(secs)),
                    "hill_evals_per_call_mean": float(np.mean(evals)), "hill_calls_fitted": int(len(errs)),
                    "hill_quiet_calls": int(sum(x["hill"]["quiet"] for x in rows))})
    return out


def fmt(v, spec=".2f") -> str:
    return "-" if v is None else format(v, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="test", choices=["test", "train"])
    ap.add_argument("--limit", type=int, default=0, help="only the first N real laughs (a quick look)")
    ap.add_argument("--out", default=str(HERE / "results" / "real.json"))
    ap.add_argument("--detector", default=None,
                    help="run every combination with this detector (default: the default configuration's, yamnet; "
                         "none: the papers' pipelines, as the figures before 2026-11-25 were measured)")
    args = ap.parse_args(argv)
    from laughlab.corpora import fetch

    fetch.require(["laugh"])
    sets = {"real": real_items(args.split), "synthetic": synthetic_items()}
    if args.limit:
        sets["real"] = sets["real"][: args.limit]
    if args.detector:   # each input's overrides: the detector for every face x body
        sets = {k: [(iid, [*ov, f"detector={args.detector}"], n) for iid, ov, n in items] for k, items in sets.items()}
    tmp = Path(tempfile.mkdtemp(prefix="bench_real-"))
    results = {"machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                           "cpus": os.cpu_count()}, "split": args.split, "detector": args.detector or "default",
               "sets": {}}
    t_start = time.perf_counter()
    try:
        for set_name, items in sets.items():
            print(f"\n{set_name}: {len(items)} inputs", flush=True)
            hill = {iid: hill_fit_of(ov) for iid, ov, _ in items}
            table = {}
            for face in FACES:
                for body in BODIES:
                    rows = []
                    for iid, ov, annotated in items:
                        r = run_combo(face, body, ov, tmp / "run")
                        if body == "hill":
                            r["calls"], r["hill"] = hill[iid]["calls"], hill[iid]
                        rows.append({**r, "annotated": annotated, "input": iid})
                    s = summarise(rows, face, body)
                    table[f"{face}/{body}"] = {**s, "per_input": [{k: v for k, v in x.items() if k != "hill"}
                                                                  for x in rows]}
                    calls = (f"{s['calls_found']}/{s['calls_annotated']} ({s['share_calls_within_1']:.0%} +/-1)"
                             if "calls_found" in s else "-")
                    hill_txt = (f"err {s['hill_error_median']:.3f}  {s['hill_seconds_per_call_median']:.3f} s/call  "
                                f"{s['hill_evals_per_call_mean']:.0f} evals" if body == "hill" else "")
                    at = f" ({s['share_at_target_r']:.0%} at target)" if "share_at_target_r" in s else ""
                    print(f"  face={face:5s} body={body:7s} ex={extractor_for(face, body):8s} "
                          f"jaw_env_r {fmt(s['jaw_envelope_r_median'])}{at:16s} calls {calls:24s} {hill_txt}",
                          flush=True)
            results["sets"][set_name] = table
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    results["wall_s"] = time.perf_counter() - t_start
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    print(f"\nwritten to {args.out} ({results['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
