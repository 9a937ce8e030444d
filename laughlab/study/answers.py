"""The answers ``study analyze`` reads: a study database, or CSV files of answers checked row by row.

A database holds only what ``study serve`` checked against the design before storing it.  CSV files (the
page's "Download my answers" files, one file or a folder of them) may have been edited by hand, so every
row is checked as the server checks a post (:func:`check_row`), against the design given with ``--design``
or, without one, against what any study's answers look like:

- ``participant`` and ``trial`` whole numbers (``trial`` 0 for the audio check); with a design, the
  participant one of its participants and the trial one of theirs, showing that ``stimulus``;
- ``kind`` one of ``rating``, ``attention``, ``audio_check``; ``question`` one of the design's questions
  for a rating, ``attention`` and ``audio_check`` for the others;
- ``condition`` the stimulus's condition in the design;
- ``value`` a number: a rating or attention answer on the scale (a whole point of a Likert scale), the
  audio check 0 or 1; an attention item's ``expected`` a number.

The first row that does not fit stops the analysis with one line naming the file, its line, the column and
the value; nothing is dropped or added in silence.  The same answer in two files (a participant's download
and a re-download) is read once; two different values for one answer are refused, naming both places.
"""
from __future__ import annotations

import csv
import math
import shlex
from pathlib import Path

from laughlab.core.errors import LaughlabError
from laughlab.study import db as DB

#: the columns a CSV of answers must have (the others of :data:`DB.COLUMNS` may be missing)
REQUIRED = ("participant", "trial", "stimulus", "condition", "kind", "question", "value")
KINDS = ("rating", "attention", "audio_check")


def load(source, design_dir=None):
    """The answers (a DataFrame in :data:`DB.COLUMNS`) and the design (or None) of a database or CSV(s)."""
    import pandas as pd

    from laughlab.study.design import load_design

    source = Path(source).expanduser()
    design = load_design(Path(design_dir).expanduser()) if design_dir is not None else None
    if source.is_dir():
        files = sorted(source.glob("*.csv"))
        dbs = sorted(source.glob("*.sqlite"))
        if not files:   # a study folder holds its answers in a database: name it (a new-user review)
            raise LaughlabError(f"{source} holds no .csv files of answers" + (
                f"; its answers are in {' and '.join(d.name for d in dbs)}: python -m laughlab study analyze "
                f"{shlex.quote(str(dbs[0]))}" if dbs else ""))
        # a database beside the files is read with them (a study-server review: a participant's downloaded file
        # beside the server's database was analysed alone, the database skipped unsaid); an answer in both counts once
        simulated = [db.name for db in dbs if DB.participants_kind(db) == "simulated"]
        if simulated:   # simulated participants are never mixed with people's answers
            raise LaughlabError(f"{source} holds study simulate's {', '.join(simulated)} beside answer files: move it "
                                "out, or analyze it on its own")
        design = design or next(filter(None, map(DB.stored_design, dbs)), None)
        rows = [r for db in dbs for r in _database_rows(db, design, design_dir or dbs[0])]   # one study's
        rows += [r for f in files for r in read_csv(f, design)]
    elif source.suffix.lower() == ".csv":
        rows = read_csv(source, design)
    elif source.is_file():
        rows = _database_rows(source, design, design_dir)
        design = design or DB.stored_design(source)
    else:   # before any participant: the study folder may hold only study simulate's database (a review)
        beside = sorted(p.name for p in source.parent.glob("*.sqlite")) if source.parent.is_dir() else []
        raise LaughlabError(f"no database or CSV at {source}" + (
            f" (no participant has answered yet; beside it: {', '.join(beside)}, e.g. study simulate's)" if beside
            else ""))
    if not rows:
        raise LaughlabError(f"{source} holds no answers yet")
    rows = _once(rows)
    df = pd.DataFrame([{c: r.get(c) for c in DB.COLUMNS} for r in rows], columns=list(DB.COLUMNS))
    for c in ("participant", "trial", "order_row"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype("Int64")
    for c in ("value", "expected", "rt_ms"):
        df[c] = pd.to_numeric(df[c], errors="coerce")
    for c in ("stimulus", "condition", "audio_id", "kind", "question", "text"):
        df[c] = df[c].fillna("").astype(str)
    return df, design


def _database_rows(source: Path, design: dict | None, design_dir) -> list[dict]:
    """A database's answers, refused when its stored design is not ``design`` (answers to other videos read against
    this one's: a user-study review)."""
    stored = DB.stored_design(source)
    if design is not None and stored is not None and stored.get("id") != design.get("id"):
        raise LaughlabError(f"{source} holds the answers of another study (design {stored.get('id')}; "
                            f"{design_dir}'s is {design.get('id')}): give its own study folder as --design, or "
                            "leave --design out (the database holds its design)")
    return DB.rows(source)


def _once(rows: list[dict]) -> list[dict]:
    """Each answer once: a repeat of the same value is left out, a different value refused (naming both)."""
    seen: dict[tuple, dict] = {}
    out = []
    for r in rows:
        key = (r["participant"], r["trial"], r["question"])
        first = seen.get(key)
        if first is None:
            seen[key] = r
            out.append(r)
        elif first["value"] != r["value"]:
            raise LaughlabError(f"{_where(r)}: participant {key[0]} trial {key[1]} {key[2]} is answered "
                                f"{r['value']:g} here and {first['value']:g} at {_where(first)}; keep one")
    return out


def _where(r: dict) -> str:
    return f"{r['_file']}, line {r['_line']}" if "_file" in r else "the database"


def read_csv(path: Path, design: dict | None = None) -> list[dict]:
    """The rows of one CSV of answers, each checked (:func:`check_row`); one line for the first that does not fit."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.DictReader(f)
            header = reader.fieldnames or []
            missing = [c for c in REQUIRED if c not in header]
            if missing:
                raise LaughlabError(f"{path} lacks the column(s) {', '.join(missing)} of a study's answers")
            rows = []
            for raw in reader:
                row = {c: (raw.get(c) or "").strip() for c in DB.COLUMNS}
                rows.append(check_row(row, design, f"{path}, line {reader.line_num}"))
                rows[-1].update(_file=str(path), _line=reader.line_num)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise LaughlabError(f"cannot read {path}: {exc}") from None
    return rows


def _whole(text: str, column: str, where: str) -> int:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v) or v != int(v):
        raise LaughlabError(f"{where}, column {column}: {text!r} is not a whole number")
    return int(v)


def _num(text: str, column: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v):
        raise LaughlabError(f"{where}, column {column}: {text!r} is not a number")
    return v


def check_row(row: dict, design: dict | None, where: str) -> dict:
    """``row`` (texts by column) with its numbers read, or a one-line error naming ``where`` and the column."""
    from laughlab.study.design import scale_range

    def bad(column: str, why: str):
        raise LaughlabError(f"{where}, column {column}: {why}")

    p = _whole(row["participant"], "participant", where)
    t = _whole(row["trial"], "trial", where)
    kind, q, cond = row["kind"], row["question"], row["condition"]
    if kind not in KINDS:
        bad("kind", f"{kind!r} is not one of {', '.join(KINDS)}")
    people = (design or {}).get("participants")   # (a design written by hand may leave them out)
    entry = (people or {}).get(str(p))
    if people is not None and entry is None:
        bad("participant", f"participant {p} is not in the design (1..{len(people)})")
    if kind == "audio_check":
        if q != "audio_check":
            bad("question", f"{q!r} is not audio_check, the question of an audio-check row")
    else:
        questions = [x["id"] for x in design["questions"]] if (design or {}).get("questions") else None
        if kind == "attention" and q != "attention":
            bad("question", f"{q!r} is not attention, the question of an attention row")
        if kind == "rating" and (q in ("", *KINDS) or (questions is not None and q not in questions)):
            bad("question", f"{q!r} is not a question of the design" + (f" ({', '.join(questions)})"
                                                                          if questions else ""))
        if not cond:
            bad("condition", "the condition is empty")
        if (design or {}).get("conditions") and cond not in design["conditions"]:
            bad("condition", f"{cond!r} is not a condition of the design ({', '.join(design['conditions'])})")
        if entry is not None:
            if not 1 <= t <= len(entry["trials"]):
                bad("trial", f"participant {p} has no trial {t} (1..{len(entry['trials'])})")
            shown = entry["trials"][t - 1]
            if row["stimulus"] != shown["stimulus"]:
                bad("stimulus", f"{row['stimulus']!r}: trial {t} of participant {p} shows {shown['stimulus']}")
            if cond != shown["condition"]:
                bad("condition", f"{cond!r}: the stimulus {shown['stimulus']} is of the condition {shown['condition']}")
    value = _num(row["value"], "value", where)
    if kind == "audio_check" and value not in (0.0, 1.0):
        bad("value", f"{row['value']!r}: the audio check is 0 (failed) or 1 (passed)")
    if kind != "audio_check" and design is not None and "scale" in design:
        lo, hi = scale_range(design)
        likert = design["scale"] == "likert"
        if not lo <= value <= hi or (likert and value != int(value)):
            bad("value", f"{row['value']!r} is not on the scale ({'a whole point ' if likert else ''}{lo:g}..{hi:g})")
    out = {**row, "participant": p, "trial": t, "value": value}
    if kind == "attention":
        out["expected"] = _num(row["expected"], "expected", where)
    return out
