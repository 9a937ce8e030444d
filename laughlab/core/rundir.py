"""One writer per run directory: an OS lock held for the whole run, and a marker that says "a run".

:func:`claim` is called before anything is written into the directory:

* it takes an exclusive ``flock`` on ``DIR/.laughlab.lock`` (the process id inside) for the life
  of the process; a second run into the same directory ends at once with one line naming the
  directory and the first run's pid.  The OS releases the lock on any exit, a crash included,
  so a stale lock cannot exist: the next run simply gets it;
* a directory is "a run" when it holds the marker ``DIR/.laughlab-run.json`` (written by the
  claim, completed with the list of the run's files at the end).  A run directory is refused unless
  ``overwrite=true``; a non-empty folder that is not a run (the user's own files) is refused too
  unless ``overwrite=true``;
* ``overwrite=true`` deletes only what the marker lists as the earlier run's files, so the
  folder ends up holding one run's outputs and nothing of the user's is touched; a file that no run
  recorded writing but named as a run's output (``OUTPUTS``: ``motion.bvh``, ``video.mp4``...) refuses
  the run even then, as the run would replace it (so does a run of laughlab 0.1, which wrote no marker);
* a run that was interrupted (its marker says ``complete: false``: killed, or stopped by a
  failure the process could not clean up) may be run again into its folder without
  ``overwrite``: an experiment then resumes (:mod:`laughlab.harness.experiment`), a single run
  starts over.  Such a claim has ``resumed`` set.
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from laughlab.core.errors import LaughlabError, shown_names

LOCK = ".laughlab.lock"
MARKER = ".laughlab-run.json"
#: the outputs of laughlab 0.1's runs (which wrote no marker)
LEGACY = ("channels.csv", "events.csv", "motion.bvh", "metrics.json", "results.json", "manifest.csv")
#: the names the pipeline and experiments write at the top of a run folder (a sink's own: its ``files``,
#: :func:`laughlab.core.pipeline.planned_files`): a file of the user's by one of these names is never replaced,
#: even with ``overwrite=true`` (the run is refused instead)
OUTPUTS = frozenset(LEGACY + ("input.wav", "truth.csv", "metrics.jsonl", "plots", "trials", "report", "showcase"))


class Claim:
    """A run directory held by this process."""

    def __init__(self, path: Path, fd: int, created: bool, user_files: set[str], resumed: bool = False,
                 done: bool = False):
        self.path, self.fd, self.created, self.user_files = path, fd, created, user_files
        self.resumed, self.done = resumed, done

    def finish(self, config_hash: str | None = None) -> None:
        """Record the run's files (every entry but the user's and ours) and its configuration's hash."""
        files = sorted(p.name for p in self.path.iterdir() if p.name not in self.user_files | {LOCK, MARKER})
        hydra = self.path / ".hydra"   # kept, so that a refused sweep job can put back what Hydra overwrote
        saved = {p.name: p.read_text() for p in sorted(hydra.glob("*.yaml"))} if hydra.is_dir() else {}
        _write_marker(self.path, {"pid": os.getpid(), "complete": True, "files": files, "config_hash": config_hash,
                                  "user_files": sorted(self.user_files), "hydra": saved})

    def abandon(self) -> None:
        """After a failure: remove the marker, and the folder if this run created it and it is empty."""
        (self.path / MARKER).unlink(missing_ok=True)
        if self.created and {p.name for p in self.path.iterdir()} <= {LOCK}:
            (self.path / LOCK).unlink(missing_ok=True)
            try:
                self.path.rmdir()
            except OSError:
                pass

    def release(self) -> None:
        try:
            os.close(self.fd)
        except OSError:
            pass


def claim(path: str | Path, overwrite: bool = False, ours: frozenset = frozenset(),
          done_if: str | None = None, writes: frozenset = frozenset(), where: str = "hydra.run.dir") -> Claim:
    """Lock ``path`` for this run (creating it) and check it may be written; see the module notes.

    ``ours``: entries this run has already written (a Hydra sweep job's ``.hydra``).
    ``writes``: the names the run's sinks write (:func:`laughlab.core.pipeline.planned_files`), protected
    like :data:`OUTPUTS`.
    ``where``: the setting the error lines tell to change (``hydra.sweep.dir`` for a sweep's job).
    ``done_if``: a configuration hash; a finished run of that configuration in ``path`` is returned
    as a claim with ``done`` set, untouched (a rerun sweep skips its finished jobs).
    """
    import fcntl

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise LaughlabError(f"hydra.run.dir {path} exists and is not a folder")
    created = not path.exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise LaughlabError(f"cannot create the run directory {path}: {exc.strerror or exc}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        other = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        raise LaughlabError(f"{path} is in use by another laughlab run (pid {other}); wait for it to finish or "
                            f"choose another {where}") from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    try:
        entries = {p.name for p in path.iterdir()} - {LOCK} - set(ours)
        marker = _read_marker(path)
        earlier = set(marker.get("files", [])) if marker is not None else set()
        if marker is not None and marker.get("complete") and done_if is not None and not overwrite \
                and marker.get("config_hash") == done_if:
            return Claim(path, fd, created, set(marker.get("user_files", [])), done=True)
        if marker is not None and not marker.get("complete", False) and not overwrite:
            # an interrupted run: the same command may take it up again (an experiment resumes)
            user = set(marker.get("user_files", entries - {MARKER}))
            _write_marker(path, {"pid": os.getpid(), "complete": False, "files": [], "user_files": sorted(user)})
            return Claim(path, fd, created, user, resumed=True)
        # files no run recorded writing (the user's, or a marker-less 0.1 run's: they cannot be told apart) named
        # as a run's outputs: a run would replace them, so they refuse it, whether or not overwrite=true
        clash = sorted((entries - earlier) & (OUTPUTS | writes)) if overwrite or marker is None else []
        if clash:
            raise LaughlabError(f"{path} holds files by the names of a run's outputs that no laughlab run recorded "
                                f"writing ({', '.join(clash)}); move them or choose another {where} "
                                "(overwrite=true never replaces files laughlab did not write)")
        if entries and not overwrite:
            if marker is not None:
                raise LaughlabError(f"{path} already holds a run; choose another {where} or add overwrite=true")
            raise LaughlabError(f"{path} is not empty and not a laughlab run ({shown_names(sorted(entries))}); "
                                "choose an empty folder or add overwrite=true (files laughlab did not write are kept)")
        for name in sorted(earlier & entries):  # overwrite: the earlier run's own files only
            p = path / name
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink(missing_ok=True)
        (path / MARKER).unlink(missing_ok=True)
        user = entries - earlier - {MARKER}
        _write_marker(path, {"pid": os.getpid(), "complete": False, "files": [], "user_files": sorted(user)})
    except BaseException:
        os.close(fd)
        raise
    return Claim(path, fd, created, user)


def restore_hydra(path: str | Path) -> bool:
    """A sweep job refused by a finished run in its folder: Hydra has already written the new job's ``.hydra/``
    over the finished run's; put the finished run's back from its marker (True), or do nothing (False: no
    finished run, or one recorded before its ``.hydra`` was)."""
    marker = _read_marker(Path(path))
    if not (marker and marker.get("complete") and marker.get("hydra")):
        return False
    hydra = Path(path) / ".hydra"
    hydra.mkdir(exist_ok=True)
    for p in hydra.glob("*.yaml"):
        if p.name not in marker["hydra"]:
            p.unlink()
    for name, text in marker["hydra"].items():
        (hydra / name).write_text(text)
    return True


def record(path: str | Path, name: str) -> None:
    """Count ``name`` (written into the finished run ``path`` by a later command: ``laughlab report``'s
    ``report/``) among the run's files, so that ``overwrite=true`` removes it with the rest of the run."""
    marker = _read_marker(Path(path))
    if marker is not None and marker.get("complete") and name not in marker.get("files", []):
        marker["files"] = sorted({*marker.get("files", []), name})
        marker["user_files"] = sorted(set(marker.get("user_files", [])) - {name})
        _write_marker(Path(path), marker)


def _read_marker(path: Path) -> dict | None:
    try:
        return json.loads((path / MARKER).read_text())
    except (OSError, ValueError):
        return None


def _write_marker(path: Path, doc: dict) -> None:
    tmp = path / f".{MARKER}.part"
    tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path / MARKER)
