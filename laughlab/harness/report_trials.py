"""A report's ``trials.csv``: the trials behind its tables, a row each, every metric a column.

A data user's review: an experiment's numbers came only as nested JSON (``metrics.jsonl``, ``results.json``) and
Markdown, and a sweep's per-trial records did not say which point they came from.  The rows carry the sweep point's
folder and its swept settings (a sweep), then the trial's condition, input, profile, seed and length, then each
metric in the results' order (empty: not measured), then ``trial_hash`` (the trial's identity in ``metrics.jsonl``).
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from laughlab.harness.runner import journal_records

#: the columns that say which trial a row is
TRIAL_COLUMNS = ("condition", "input", "profile", "seed", "duration_s")


def _value(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return repr(v) if isinstance(v, float) else str(v)


def trials_text(points: list[tuple[str, dict, Path]], metrics: list[str]) -> str:
    """The CSV of ``points`` (``(point folder, swept settings, run folder)``; one ``("", {}, run)`` for an
    experiment), each run folder's ``metrics.jsonl`` a row a trial, ``metrics`` its metric columns."""
    swept = list(dict.fromkeys(k for _, params, _ in points for k in params))
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    point = ["point"] if any(name for name, _, _ in points) else []
    w.writerow([*point, *swept, *TRIAL_COLUMNS, *metrics, "trial_hash"])
    for name, params, run in points:
        for r in journal_records(Path(run) / "metrics.jsonl"):
            got = r.get("metrics") or {}
            w.writerow([*([name] if point else []), *(params.get(k, "") for k in swept),
                        *(_value(r.get(k)) for k in TRIAL_COLUMNS), *(_value(got.get(m)) for m in metrics),
                        r.get("trial_hash", "")])
    return text.getvalue()
