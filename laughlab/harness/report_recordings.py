"""An experiment report's table of each of your own recordings (``harness.corpus.folder``) under each condition.

A new-user review (2026-11-29): with four annotated recordings of one's own, the report gave only the conditions'
means, and ``laugh`` missing both bouts of one recording (F1 0) was hidden in them; the per-trial numbers were in
``metrics.jsonl`` alone.  The corpus' own sets (dozens of files) and the synthetic inputs stay pooled.
"""
from __future__ import annotations

import math
from pathlib import Path

from laughlab.harness.report_format import fmt, heading

#: the columns, in this order, those the experiment measured on the recordings (at most :data:`MOST`)
PREFERRED = ("bouts_answered", "detector_f1", "false_starts_per_min", "onset_latency_median_s", "miss_rate",
             "intensity_r_clip", "jaw_call_r", "offset_tail_s", "cutoff_rate")
MOST = 6


def recordings_table(run_dir: Path, doc: dict) -> list[str]:
    """Markdown lines: a row per recording of ``harness.corpus.folder`` and condition (the mean over its run seeds),
    the first :data:`MOST` of :data:`PREFERRED` that have a value; empty without such recordings."""
    from laughlab.harness.runner import journal_records

    recs = [r for r in journal_records(Path(run_dir) / "metrics.jsonl") if str(r.get("input", "")).startswith("rec-")]
    if not recs:
        return []
    have = [m for m in PREFERRED if m in doc["metrics"]
            and any(_number((r.get("metrics") or {}).get(m)) for r in recs)][:MOST]
    if not have:
        return []
    conds = list(doc["conditions"])
    inputs = sorted({r["input"] for r in recs})
    lines = ["", "## Each of your recordings", "",
             "The recordings of `harness.corpus.folder`, one row each under each condition (the mean over its run "
             "seeds; the tables above pool every input); n/a where the recording has nothing to measure.", "",
             "| recording | condition | " + " | ".join(heading(m, doc["metrics"][m]) for m in have) + " |",
             "|---|---|" + "---|" * len(have)]
    for name in inputs:
        for c in conds:
            mine = [r for r in recs if r["input"] == name and r["condition"] == c]
            if not mine:
                continue
            cells = []
            for m in have:
                vals = [v for r in mine for v in [(r.get("metrics") or {}).get(m)] if _number(v)]
                cells.append(fmt(sum(vals) / len(vals)) if vals else "n/a")
            lines.append(f"| {name.removeprefix('rec-')} | {c} | " + " | ".join(cells) + " |")
    return lines


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
