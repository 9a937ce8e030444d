"""Writing output files so that a failed run leaves nothing half-written.

Every file is written under a temporary name (``.NAME.part``) and moved into
place only when the run succeeds (:meth:`Staging.commit`); :meth:`Staging.abort`
removes the temporary files.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path


def file_sha256(path) -> str:
    """The sha256 of a file's bytes, read 1 MiB at a time (the records of the files a command wrote: ``detect``,
    ``report``, ``study analyze``; the stimuli manifest; a run's ``input_sha256``)."""
    import hashlib

    h = hashlib.sha256()
    with open(Path(path).expanduser(), "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_record(path) -> tuple[set, dict] | None:
    """A command's record of the files it wrote into a folder (``{"files": [...], "sha256": {name: hash}}``, as
    ``detect`` and ``report`` keep it): the names that stay inside the folder (relative, no ``..``: no other file
    is ever removed) and their hashes; None if there is no readable record."""
    import json

    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        names, sums = doc["files"], doc.get("sha256") or {}
        names = {n for n in names if isinstance(n, str) and n and not Path(n).is_absolute() and ".." not in
                 Path(n).parts}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    return names, sums if isinstance(sums, dict) else {}


def edited_since(folder: Path, names, sums: dict) -> list[str]:
    """Of ``names`` (files a command wrote into ``folder``), those whose bytes differ from the record's hash: edited
    by the user since (the user's now)."""
    return sorted(n for n in names if n in sums and (folder / n).is_file() and file_sha256(folder / n) != sums[n])


def record_text(folder: Path, names) -> str:
    """The record (:func:`read_record`) of the files ``names`` in ``folder`` as written now."""
    import json

    names = sorted(names)
    return json.dumps({"files": names, "sha256": {n: file_sha256(folder / n) for n in names}}, indent=1) + "\n"


def remove(p: Path) -> None:
    """Remove a file, a link (not what it points to) or a folder with its contents, if it is there."""
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p)
    else:
        p.unlink(missing_ok=True)


def unwrite(paths, out_dir: Path | None = None) -> None:
    """Remove files a failed run had already put in place (``paths``), then their folders below ``out_dir``
    (``plots/``) if that leaves them empty."""
    for p in paths:
        try:
            Path(p).unlink(missing_ok=True)
        except OSError:   # cleanup must not hide the failure it cleans up after
            pass
    for folder in {Path(p).parent for p in paths} - {Path(out_dir) if out_dir is not None else None}:
        try:
            folder.rmdir()
        except OSError:   # not empty: another file is there
            pass


class Staging:
    """Temporary output files of one writer, committed or removed together."""

    def __init__(self) -> None:
        self.pending: dict[Path, Path] = {}
        self.made: list[Path] = []   # folders this writer created (plots/), removed by abort if left empty

    def path(self, final: Path) -> Path:
        """The temporary path to write in place of ``final``."""
        final = Path(final)
        missing, d = [], final.parent
        while not d.exists():   # up to the first folder that is there
            missing.append(d)
            d = d.parent
        final.parent.mkdir(parents=True, exist_ok=True)
        self.made += [d for d in reversed(missing) if d not in self.made]
        tmp = final.with_name(f".{final.name}.part")
        self.pending[final] = tmp
        return tmp

    def commit(self) -> list[Path]:
        done = []
        for final, tmp in self.pending.items():
            os.replace(tmp, final)
            done.append(final)
        self.pending.clear()
        return done

    def abort(self, *files) -> None:
        """Close ``files`` (the writer's open files; a buffer that cannot be flushed, on a full disk or
        past a file size limit, is dropped) and remove the temporary files."""
        for f in files:
            if f is not None and not f.closed:
                try:
                    f.close()
                except OSError:  # the failure being cleaned up after: its file goes all the same
                    pass
        for tmp in self.pending.values():
            tmp.unlink(missing_ok=True)
        self.pending.clear()
        for d in reversed(self.made):   # deepest first; a folder with anything else in it stays
            try:
                d.rmdir()
            except OSError:
                pass
        self.made.clear()
