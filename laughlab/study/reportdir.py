"""The folder ``study analyze`` writes its report into: what it may replace, and how.

The report is written beside the folder first and then moved in (:func:`put`), with a record of what it
wrote (:data:`STAMP`: each file's sha256).  An earlier report is replaced when nothing in it changed; one
whose files were edited or added to since (a researcher's notes in its README, a file of their own) is
refused unless ``--overwrite``, and then only the report's own files are replaced: the others are kept.  A
folder that holds anything but a study report is never written into.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from laughlab.core.errors import LaughlabError
from laughlab.core.outfiles import file_sha256

REPORT_FILES = {"README.md", "report.json", "tidy.csv", "exclusions.csv", "means.csv", "model.csv", "variance.csv",
                "contrasts.csv", "fig_means.png", "fig_participants.png", "fig_means.pdf", "fig_participants.pdf"}


#: the report's record of what it wrote (name: sha256), to tell the researcher's changes from its own files
STAMP = ".study-report.json"


def check_out(out: Path, overwrite: bool = False) -> None:
    """Refuse a report folder that holds anything but an earlier study report; and, without ``overwrite``, an
    earlier report whose files were changed or added to since it was written (a review: notes added to its
    README were deleted by the next run).  With ``overwrite`` the report's own files are replaced, the others
    kept."""
    if not out.exists():
        return
    if not out.is_dir():
        raise LaughlabError(f"{out} exists and is not a folder; choose another --out")
    held = {p.name for p in out.iterdir()} - {STAMP}
    if not held:
        return
    try:
        ours = (out / "README.md").read_text(encoding="utf-8").startswith("# Study report: ")
    except (OSError, UnicodeDecodeError):
        ours = False
    if not ours:
        raise LaughlabError(f"{out} holds files that are not a study report ({', '.join(sorted(held)[:3])}"
                            f"{', ...' if len(held) > 3 else ''}); choose another --out "
                            "(a report replaces only an earlier report)")
    try:
        stamp = json.loads((out / STAMP).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        stamp = None   # a report written before the record (2026-11-27): replaced as it was then (a diff review:
        # every one was refused as "changed since it was written", the committed demo's command among them)
    changed = [] if stamp is None else \
        sorted(n for n in held & REPORT_FILES if not isinstance(stamp, dict) or stamp.get(n) != file_sha256(out / n))
    added = sorted(held - REPORT_FILES)
    if (changed or added) and not overwrite:
        what = ([f"changed since it was written: {', '.join(changed[:3])}"] if changed else []) + \
               ([f"not a study report's: {', '.join(added[:3])}"] if added else [])
        raise LaughlabError(f"{out} holds files {'; '.join(what)}; choose another --out, or add --overwrite to "
                            "replace the report's own files (the others are kept)")


def put(tmp: Path, out: Path) -> None:
    """Move the report written in ``tmp`` to ``out`` (checked by :func:`check_out`), stamped with its files' sha256;
    of an earlier report in ``out`` only its own files are replaced or removed."""
    stamp = {f.name: file_sha256(f) for f in sorted(tmp.iterdir())}
    (tmp / STAMP).write_text(json.dumps(stamp, indent=1) + "\n", encoding="utf-8")
    if not out.exists():
        tmp.rename(out)
        return
    for name in REPORT_FILES | {STAMP}:   # an earlier report's files only: what the researcher added stays
        if (tmp / name).exists():
            (tmp / name).replace(out / name)
        else:
            (out / name).unlink(missing_ok=True)
    shutil.rmtree(tmp, ignore_errors=True)
