"""A report folder's own files: a new report replaces only the files the earlier one wrote (its manifest), never a
file of the user's beside them (``python -m laughlab report``, :func:`laughlab.harness.report.write_report`)."""
from __future__ import annotations

import os
from pathlib import Path

from laughlab.core.errors import LaughlabError, shown_names
from laughlab.core.outfiles import edited_since, read_record, record_text

#: in a report folder, the files the report wrote there (so that a new report replaces only those)
MANIFEST = ".laughlab-report.json"


def replace_report(staging: Path, target: Path, overwrite: bool = False) -> None:
    """Move the new report's files from ``staging`` into ``target``; remove the files only the earlier report wrote
    (its manifest; a report without one: its README and the figures it names) and keep the user's (a review: a
    caption and an edited figure in figures/ were deleted).  A file of the user's in the way is refused, and so,
    without ``overwrite``, is a file of the earlier report edited since (its sha256 in the manifest: notes added
    to the README, a figure retouched in place; a diff review: they were replaced without a word)."""
    import re

    new = sorted(p.relative_to(staging).as_posix() for p in staging.rglob("*") if p.is_file())
    record = read_record(target / MANIFEST)
    if record is not None:
        old, sums = record
    else:
        readme = target / "README.md"
        text = readme.read_text(encoding="utf-8", errors="replace") if readme.is_file() else ""
        old = {"README.md"} | {f"figures/{n}" for n in re.findall(r"\]\(figures/([^)\s]+)\)", text)}
        old, sums = {n for n in old if ".." not in Path(n).parts}, {}
    theirs = [n for n in new if (target / n).exists() and n not in old]
    if theirs:
        raise LaughlabError(f"{target} holds {shown_names(theirs)}, which no earlier report wrote and this one would "
                            "replace; move them, or choose another --out")
    edited = edited_since(target, old, sums)
    if edited and not overwrite:
        them = "them" if len(edited) > 1 else "it"
        raise LaughlabError(f"{target}: {shown_names(edited)} changed since the report wrote {them}; choose another "
                            f"--out, or add --overwrite to replace {them}")
    for name in new:
        (target / name).parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / name, target / name)
    for name in sorted(old - set(new)):
        (target / name).unlink(missing_ok=True)
    (target / MANIFEST).write_text(record_text(target, new), encoding="utf-8")
