"""``detect --score``: the segments scored against your own annotations of the same recordings.

A new-user review (2026-11-29): a researcher with annotated recordings had no documented way to measure what
``detect`` found against them (the harness scores the live gate, ``bench_detector`` the corpus' sets only).  With
``--score`` each input's annotation beside it is read, as a corpus folder's are (``NAME.truth.csv``, else Audacity
labels ``NAME.txt``, a Praat ``NAME.TextGrid`` or an ELAN ``NAME.eaf``: :mod:`laughlab.corpora.annotations`), and
the segments are scored as ``benchmarks/bench_detector.py`` scores them (:func:`laughlab.detector.segments.score`):
frames of 10 ms inside a bout (precision, recall and F1 of the laughter frames), bouts found (a segment overlapping
the bout), segments outside every bout.  ``scores.csv`` holds a row per scored input and the pooled row ``all``.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

from laughlab.core.errors import LaughlabError

COLUMNS = ("file", "annotation", "bouts", "found", "precision", "recall", "f1", "segments_outside", "seconds")


def truth_rows(annotation: Path, duration_s: float) -> list[dict]:
    """The annotation's rows (``kind``, ``onset_s``, ``offset_s`` in s), checked as a corpus folder's are
    (:func:`laughlab.harness.corpus.checked_truth_rows`: one line naming the file for an unknown label, overlapping
    bouts or a time past the recording's end)."""
    from laughlab.harness.corpus import checked_truth_rows

    return [{"kind": r["kind"], "onset_s": float(r["onset_s"]), "offset_s": float(r["offset_s"])}
            for r in checked_truth_rows(annotation, duration_s)]


def score_rows(results: list, truths: dict[str, tuple[Path, list[dict]]]) -> list[dict]:
    """A row per input with a truth (``results`` as detect makes them: name, duration, segments, ...), then the
    pooled row ``all`` (frames summed over the inputs, so a long recording weighs more)."""
    from laughlab.detector.segments import f1, score

    rows, tot = [], {"tp": 0, "fp": 0, "fn": 0, "bouts": 0, "found": 0, "outside": 0, "seconds": 0.0}

    def row(name, ann, r, outside, seconds) -> dict:
        tp, fp, fn = r["tp"], r["fp"], r["fn"]
        return {"file": name, "annotation": ann, "bouts": r["bouts"], "found": r["found"],
                "precision": tp / (tp + fp) if tp + fp else None, "recall": tp / (tp + fn) if tp + fn else None,
                "f1": f1(tp, fp, fn) if tp + fp + fn else None, "segments_outside": outside, "seconds": seconds}

    for name, dur, segs, *_ in results:
        if name not in truths:
            continue
        ann, truth = truths[name]
        r = score(segs, truth, dur)
        outside = sum(r["false_segments"].values())
        rows.append(row(name, str(ann), r, outside, dur))
        for k in ("tp", "fp", "fn", "bouts", "found"):
            tot[k] += r[k]
        tot["outside"] += outside
        tot["seconds"] += dur
    if rows:
        rows.append(row("all", "", tot, tot["outside"], tot["seconds"]))
    return rows


def scores_text(rows: list[dict]) -> str:
    """``scores.csv``: :data:`COLUMNS`, ratios to 4 decimals, empty where undefined (no bout and no segment)."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([f"{r[c]:.4f}" if isinstance(r[c], float) else "" if r[c] is None else r[c] for c in COLUMNS])
    return text.getvalue()


def score_summary(rows: list[dict], unscored: int) -> str:
    """The closing line's part: ``; scored against 4 annotations: 4 of 8 bouts found, frame F1 0.45 (precision
    0.50, recall 0.41), 5 segments outside laughter -> scores.csv``."""
    if not rows:
        return ""
    a = rows[-1]
    fmt = lambda v: "n/a" if v is None else f"{v:.2f}"   # noqa: E731
    n = len(rows) - 1
    return (f"; scored against {n} annotation{'s' * (n != 1)}: {a['found']} of {a['bouts']} bouts found, frame F1 "
            f"{fmt(a['f1'])} (precision {fmt(a['precision'])}, recall {fmt(a['recall'])}), "
            f"{a['segments_outside']} segment{'s' * (a['segments_outside'] != 1)} outside laughter"
            + (f", {unscored} input{'s' * (unscored != 1)} without an annotation" if unscored else "")
            + " -> scores.csv")


def find_truths(named: list, durations: dict, ours: frozenset) -> dict[str, tuple[Path, list[dict]]]:
    """``--score``: every input's annotation read and checked before any work (one line for the first bad one);
    ``ours``: the files earlier detects' manifests list (resolved), which are not annotations.  None at all is an error that says
    where they are looked for."""
    from laughlab.harness.corpus import annotation_beside

    found = {}
    for f, name, _ in named:
        ann = annotation_beside(Path(f), Path(name).name, ours)
        if ann is not None:
            found[name] = (ann, truth_rows(ann, durations[name]))
    if not found:
        each = any(name != Path(f).stem and ".ch" in name for f, name, _ in named)   # --channels each
        raise LaughlabError("--score: no input has an annotation beside it (NAME.truth.csv, NAME.txt, NAME.TextGrid "
                            "or NAME.eaf next to NAME.wav" + ("; with --channels each, one a channel: NAME.ch1.txt, "
                                                               "NAME.ch2.txt, ..." if each else "")
                            + "; docs/detector.md)")
    return found
