"""Does the face grin through talk?  The default pipeline's face on held-out speech and laughs, with the face's
provisional answers taken back when the model says "not laughter" (``face.retract_s``, the default 0.3 s) and
kept (``face.retract_s=null``, the behaviour before 2026-11-27), and without a detector (``detector=none``, the
papers: every sound drives the face), each face, in one run (``face=cgm`` since 2026-11-29: it takes back nothing,
and follows the detector's face gain since then).

A review found the ``smile`` face above 0.5 in 99% of the frames of a minute of real speech with the default
``detector=yamnet``: each phrase opens the face gain provisionally for 0.3-0.55 s, the smile (van Duijn 2014,
5.3: rise 0.03, fall 0.001 per tick, maxE 0.3) is full within 0.17 s of it and takes 5 s to fade.

Sets (the corpus' held-out test split, 44.1 kHz; ``bench_detector.held_out_sets``): ``speech`` (6 x 100 s of
speech, 20 voices, 5 languages), ``real`` (27 annotated laughs alone, 34 bouts), ``between`` (6 x 100 s of those
laughs between speech, coughs, music; 45 bouts).  Per face and setting:

- speech: share of frames with ``smile`` > 0.5 and with ``jaw`` > 0.3, mean smile;
- ``between``: share of the truth's speech frames with smile > 0.5; mean smile inside laughter bouts;
- ``real`` and ``between``: the smile's first reaching 0.5 after a bout's start (median over the bouts where it
  does, up to 0.5 s after the bout), and in how many bouts it does.

Run: ``python benchmarks/bench_face_talk.py [--jobs 2]`` (about 2 minutes on 2 cores); writes
``benchmarks/results/face_talk.json``.  Nothing here was tuned on these sets: ``retract_s`` is the detector's
``release_s`` (0.25 s) rounded up.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import bench_detector as B  # noqa: E402

SETTINGS = {"taken back (0.3 s, default)": [], "kept (retract_s=null)": ["face.retract_s=null"],
            "detector=none (the papers)": ["detector=none"]}
FACES = ("smile", "facs", "cgm")
#: faces without a provisional answer to take back (no ``retract_s``): the "kept" setting is theirs already
NO_RETRACT = ("cgm",)


def run(job) -> dict:
    """One file through the default pipeline: the frames' smile and jaw, and the truth's bouts and speech."""
    wav, out, face, extra = job
    t = B.run_trial(wav, out, [f"face={face}", *extra])
    times = t.channels["time"].to_numpy()
    smile, jaw = t.channels["smile"].to_numpy(), t.channels["jaw"].to_numpy()
    res = {"frames": len(times), "smile_over": int((smile > 0.5).sum()), "jaw_over": int((jaw > 0.3).sum()),
           "smile_sum": float(smile.sum()), "onsets": [], "bouts": 0, "bout_frames": 0, "bout_smile": 0.0,
           "speech_frames": 0, "speech_smile_over": 0}
    if t.truth is not None:
        for on, off in t.truth.bouts[["onset_s", "offset_s"]].itertuples(index=False):
            res["bouts"] += 1
            inside = (times >= on) & (times < off)
            res["bout_frames"] += int(inside.sum())
            res["bout_smile"] += float(smile[inside].sum())
            seen = np.nonzero((times >= on) & (times < off + 0.5) & (smile >= 0.5))[0]
            if len(seen):
                res["onsets"].append(float(times[seen[0]] - on))
        others = t.truth.others
        if others is not None and len(others):
            for on, off in others[others.kind == "speech"][["onset_s", "offset_s"]].itertuples(index=False):
                inside = (times >= on) & (times < off)
                res["speech_frames"] += int(inside.sum())
                res["speech_smile_over"] += int((smile[inside] > 0.5).sum())
    return res


def summary(rows: list[dict]) -> dict:
    total = {k: sum(r[k] for r in rows) for k in ("frames", "smile_over", "jaw_over", "smile_sum", "bouts",
                                                    "bout_frames", "bout_smile", "speech_frames",
                                                    "speech_smile_over")}
    onsets = [o for r in rows for o in r["onsets"]]
    return {"smile_over_0.5": total["smile_over"] / max(1, total["frames"]),
            "jaw_over_0.3": total["jaw_over"] / max(1, total["frames"]),
            "mean_smile": total["smile_sum"] / max(1, total["frames"]),
            "bouts": total["bouts"], "bouts_smile_reaches_0.5": len(onsets),
            "smile_onset_median_s": float(np.median(onsets)) if onsets else None,
            "mean_smile_in_bouts": total["bout_smile"] / max(1, total["bout_frames"]),
            "speech_frames_smile_over_0.5": (total["speech_smile_over"] / total["speech_frames"]
                                             if total["speech_frames"] else None)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--faces", default=",".join(FACES), help="comma-separated faces (default: all three)")
    ns = ap.parse_args()
    faces = [f for f in ns.faces.split(",") if f]
    sets = B.held_out_sets()
    wanted = {k: sets[k] for k in ("speech", "real", "between")}
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp, cf.ProcessPoolExecutor(ns.jobs) as pool:
        jobs = {}
        for face in faces:
            for label, extra in SETTINGS.items():
                if face in NO_RETRACT and "face.retract_s=null" in extra:
                    continue
                for name, wavs in wanted.items():
                    for w in wavs:
                        jobs[(face, label, name, w.name)] = (w, Path(tmp) / face / str(len(jobs)), face, extra)
        done = dict(zip(jobs, pool.map(run, jobs.values())))
    for face in faces:
        for label in SETTINGS:
            if face in NO_RETRACT and "face.retract_s=null" in SETTINGS[label]:
                continue
            for name in wanted:
                rows = [r for (f, lab, n, _), r in done.items() if (f, lab, n) == (face, label, name)]
                out.setdefault(face, {}).setdefault(label, {})[name] = summary(rows)
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "face_talk.json").write_text(json.dumps(out, indent=1) + "\n")
    for face, by in out.items():
        for label, s in by.items():
            sp, re_, bt = s["speech"], s["real"], s["between"]
            if face in NO_RETRACT and label.startswith("taken back"):
                label = "default detector"
            print(f"face={face:5s} {label:28s} speech: smile>0.5 {sp['smile_over_0.5']:6.1%}, jaw>0.3 "
                  f"{sp['jaw_over_0.3']:6.1%}, mean smile {sp['mean_smile']:.3f} | between: speech frames smile>0.5 "
                  f"{bt['speech_frames_smile_over_0.5']:6.1%}, mean smile in laughs {bt['mean_smile_in_bouts']:.3f}, "
                  f"smile at 0.5 in {bt['bouts_smile_reaches_0.5']}/{bt['bouts']} bouts "
                  f"(median {bt['smile_onset_median_s']:.2f} s) | real: in {re_['bouts_smile_reaches_0.5']}/"
                  f"{re_['bouts']} (median {re_['smile_onset_median_s']:.2f} s), mean smile in laughs "
                  f"{re_['mean_smile_in_bouts']:.3f}")


if __name__ == "__main__":
    main()
