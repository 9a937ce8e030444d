"""One writer per run directory: an OS lock held for the whole run, and a marker that says "a run".

:func:`claim` is called before anything is written into the directory:

* it takes an exclusive lock (:mod:`laughlab.core.oslock`: ``flock``, Windows' ``msvcrt.locking``) on
  ``DIR/.laughlab.lock`` (the process id inside) for the life
  of the process; a second run into the same directory ends at once with one line naming the
  directory and the first run's pid.  The OS releases the lock on any exit, a crash included,
  so a stale lock cannot exist: the next run simply gets it;
* a directory is "a run" when it holds the marker ``DIR/.laughlab-run.json`` (written by the
  claim, completed with the list of the run's files at the end).  A run directory is refused unless
  ``overwrite=true``; a non-empty folder that is not a run (the user's own files) is refused too
  unless ``overwrite=true``;
* ``overwrite=true`` replaces only what the marker lists as the earlier run's files, so the
  folder ends up holding one run's outputs and nothing of the user's is touched.  The earlier run is
  moved aside into ``DIR/.laughlab-previous/`` when the new one starts and deleted when it finishes; a
  run that fails or is stopped puts it back (an interrupted experiment, which can resume, keeps it
  aside until it finishes).  A file that no run
  recorded writing but named as a run's output (``OUTPUTS``: ``motion.bvh``, ``video.mp4``...) refuses
  the run even then, as the run would replace it (so does a run of laughlab 0.1, which wrote no marker, and
  another Hydra application's ``.hydra/``);
* a run that was interrupted (its marker says ``complete: false``: killed, or stopped by a
  failure the process could not clean up) may be run again into its folder without
  ``overwrite``: an experiment then resumes (:mod:`laughlab.harness.experiment`), a single run
  starts over.  Such a claim has ``resumed`` set.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from laughlab.core import interrupts, oslock
from laughlab.core.errors import LaughlabError, shown_names
from laughlab.core.outfiles import remove as _remove
from laughlab.core.overrides import given_value

LOCK = ".laughlab.lock"
MARKER = ".laughlab-run.json"
PREVIOUS = ".laughlab-previous"
"""The earlier run that ``overwrite=true`` replaces, kept aside until the new run finishes."""
MARKER_PART = f".{MARKER}.part"
"""The marker being written (then renamed): a run killed in that instant leaves it."""
OWN = frozenset({LOCK, MARKER, PREVIOUS, MARKER_PART})


class InUse(LaughlabError):
    """The run directory is held by another laughlab process."""


#: the outputs of laughlab 0.1's runs (which wrote no marker)
LEGACY = ("channels.csv", "events.csv", "motion.bvh", "metrics.json", "results.json", "manifest.csv")
#: the names the pipeline and experiments write at the top of a run folder (a sink's own: its ``files``,
#: :func:`laughlab.core.pipeline.planned_files`): a file of the user's by one of these names is never replaced,
#: even with ``overwrite=true`` (the run is refused instead)
OUTPUTS = frozenset(LEGACY + ("input.wav", "truth.csv", "metrics.jsonl", "plots", "trials", "report", "showcase"))


class Claim:
    """A run directory held by this process."""

    def __init__(self, path: Path, fd: int, created: bool, user_files: set[str], resumed: bool = False,
                 done: bool = False, lock_made: bool = False):
        self.path, self.fd, self.created, self.user_files = path, fd, created, user_files
        self.resumed, self.done, self.lock_made = resumed, done, lock_made

    def finish(self, config_hash: str | None = None) -> None:
        """Record the run's files (every entry but the user's and ours) and its configuration's hash; delete
        the earlier run it replaced.  Not after a stop signal whose interrupt was lost on the way
        (:func:`laughlab.core.interrupts.check` raises it here)."""
        interrupts.check()
        files = sorted(p.name for p in self.path.iterdir() if p.name not in self.user_files | OWN)
        _write_marker(self.path, {"pid": os.getpid(), "complete": True, "files": files, "config_hash": config_hash,
                                  "user_files": sorted(self.user_files), "hydra": _hydra_files(self.path)})
        _remove(self.path / PREVIOUS)

    def keep(self) -> None:
        """An experiment stopped part way and kept for its command to resume: record the files it has written so
        far (every entry but the user's and ours), so that a file the user puts in the folder afterwards (notes)
        is theirs, never the run's: ``overwrite=true`` and a resumed run's end removed it (a first-contact review).
        Not called where a run is killed (SIGKILL): then every entry but the user's counts as the run's."""
        marker = _read_marker(self.path) or {}
        files = sorted(p.name for p in self.path.iterdir() if p.name not in self.user_files | OWN)
        _write_marker(self.path, {**marker, "pid": os.getpid(), "complete": False, "files": files,
                                  "user_files": sorted(self.user_files), "kept": True})

    def abandon(self) -> None:
        """After a failure: remove the marker and put back the earlier run this one was replacing (or remove
        the folder if this run created it and it is empty).  The marker's temporary file goes too: a stop signal
        that came while the marker was written left it (a clean clone's fuzz run hit it, SIGTERM at 1.42 s)."""
        if oslock.fcntl is None:   # Windows: an open file cannot be deleted (the lock goes with it, as at exit)
            self.release()
        for name in (MARKER, MARKER_PART):
            (self.path / name).unlink(missing_ok=True)
        if _put_back(self.path):
            return
        if self.lock_made and not self.created:   # a folder of the user's: left as it was
            (self.path / LOCK).unlink(missing_ok=True)
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
        self.fd = -1   # a second release closes nothing (the number may be another file's by then)


def claim(path: str | Path, overwrite: bool = False, ours: frozenset = frozenset(),
          done_if: str | None = None, writes: frozenset = frozenset(), where: str = "hydra.run.dir",
          resumable: bool = False, reads: tuple = ()) -> Claim:
    """Lock ``path`` for this run (creating it) and check it may be written; see the module notes.

    ``reads``: the files the run reads (``input.path``, ``character``...); one that is among the earlier run's
    files, which ``overwrite=true`` moves aside, refuses the run (it would not find its input).

    ``ours``: entries this run has already written (a Hydra sweep job's ``.hydra``).
    ``writes``: the names the run's sinks write (:func:`laughlab.core.pipeline.planned_files`), protected
    like :data:`OUTPUTS`.
    ``where``: the setting the error lines tell to change (``hydra.sweep.dir`` for a sweep's job).
    ``done_if``: a configuration hash; a finished run of that configuration in ``path`` is returned
    as a claim with ``done`` set, untouched (a rerun sweep skips its finished jobs).
    ``resumable``: the run can take up an interrupted one (an experiment).  An ``overwrite=true`` run that was
    killed left the run it replaced aside: a run that cannot resume first puts that one back (and is then
    refused without ``overwrite=true``); one that can resumes, with or without ``overwrite=true`` (the same
    command), and the run aside goes when it finishes.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise LaughlabError(f"hydra.run.dir {path} exists and is not a folder")
    created = not path.exists()
    lock_made = not (path / LOCK).exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        verb = "write into" if not created else "create"   # a review: an existing read-only folder was "created"
        raise LaughlabError(f"cannot {verb} the run directory {path}: {exc.strerror or exc}") from None
    if not oslock.try_lock(fd):
        other = oslock.read_head(fd).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        raise InUse(f"{path} is in use by another laughlab run (pid {other}); wait for it to finish or "
                    f"choose another {where}")
    oslock.write_head(fd, f"{os.getpid()}\n".encode())
    try:
        entries = {p.name for p in path.iterdir()} - OWN - set(ours)
        (path / MARKER_PART).unlink(missing_ok=True)   # a run killed as it wrote its marker (a test hit it)
        marker = _read_marker(path)
        complete = marker is not None and marker.get("complete", False)
        aside = (path / PREVIOUS / MARKER).is_file()
        if marker is None and aside and not resumable and not entries:
            # an overwrite killed between putting the earlier run aside and marking its own start: nothing of it
            # was written yet, so the earlier run simply comes back
            _put_back(path)
            entries = {p.name for p in path.iterdir()} - OWN - set(ours)
            marker, complete, aside = _read_marker(path), True, False
        elif marker is not None and not complete and aside and not resumable:
            # a killed (or crashed) overwrite: its partial files go, the run it was replacing comes back
            for name in entries - set(marker.get("user_files", [])) - {MARKER}:
                _remove(path / name)
            (path / MARKER).unlink(missing_ok=True)
            _put_back(path)
            entries = {p.name for p in path.iterdir()} - OWN - set(ours)
            marker, complete, aside = _read_marker(path), True, False
        if marker is None:
            earlier = set()
        elif complete:
            earlier = set(marker.get("files", []))
        elif marker.get("kept"):   # an interrupted experiment kept to resume: the files it had written then
            earlier = set(marker.get("files", [])) & entries
        else:   # a killed run lists no files yet: all but the user's are its own
            earlier = entries - set(marker.get("user_files", [])) - {MARKER}
        if marker is not None and marker.get("complete") and done_if is not None and not overwrite \
                and marker.get("config_hash") == done_if:
            return Claim(path, fd, created, set(marker.get("user_files", [])), done=True)
        if marker is not None and not complete and (not overwrite or aside):
            # an interrupted run: the same command may take it up again (an experiment resumes)
            user = set(marker.get("user_files", entries - {MARKER})) | (entries - earlier - {MARKER})
            _mark_running(path, user, ours)
            return Claim(path, fd, created, user, resumed=True, lock_made=lock_made)
        # files no run recorded writing (the user's, or a marker-less 0.1 run's: they cannot be told apart) named
        # as a run's outputs: a run would replace them, so they refuse it, whether or not overwrite=true
        # (and a .hydra/ of another Hydra application's, which this run's would replace: a review)
        named = OUTPUTS | writes | ({".hydra"} - set(ours))
        clash = sorted((entries - earlier) & named) if overwrite or marker is None else []
        if clash:
            raise LaughlabError(f"{path} holds files by the names of a run's outputs that no laughlab run recorded "
                                f"writing ({', '.join(clash)}); move them or choose another {where} "
                                "(overwrite=true never replaces files laughlab did not write)")
        if entries and not overwrite:
            if marker is not None:
                raise LaughlabError(f"{path} already holds a run; choose another {where} or add overwrite=true")
            raise LaughlabError(f"{path} is not empty and not a laughlab run ({shown_names(sorted(entries))}); "
                                "choose an empty folder or add overwrite=true (files laughlab did not write are kept)")
        for read in reads:   # e.g. input.path=D/input.wav with overwrite=true into D
            try:
                inside = Path(read).expanduser().resolve().relative_to(path.resolve()).parts
            except (ValueError, OSError):
                continue
            if inside and inside[0] in earlier & entries:
                raise LaughlabError(f"{read} is a file of the earlier run in {path}, which overwrite=true replaces; "
                                    f"copy it out of that folder first or choose another {where}")
        # overwrite: the earlier run's own files only.  A finished run goes aside (back if this one fails); an
        # interrupted one is partial and goes, and the finished run an earlier overwrite put aside stays there
        aside = path / PREVIOUS
        if complete and earlier & entries:
            _remove(aside)
            aside.mkdir()
            for name in sorted(earlier & entries):
                os.replace(path / name, aside / name)
            os.replace(path / MARKER, aside / MARKER)
        else:
            for name in sorted(earlier & entries):
                _remove(path / name)
            (path / MARKER).unlink(missing_ok=True)
        user = entries - earlier - {MARKER}
        _mark_running(path, user, ours)
    except BaseException:
        os.close(fd)
        if lock_made and _read_marker(path) is None:   # refused: leave the user's folder as it was
            (path / LOCK).unlink(missing_ok=True)
            if created:
                try:
                    path.rmdir()
                except OSError:
                    pass
        raise
    return Claim(path, fd, created, user, lock_made=lock_made)


def _mark_running(path: Path, user: set[str], ours: frozenset) -> None:
    """The marker of a run that has begun: not complete, the user's files, and a sweep job's ``.hydra`` (which
    Hydra wrote before the claim; kept so that a job refused by this one can put it back)."""
    _write_marker(path, {"pid": os.getpid(), "complete": False, "files": [], "user_files": sorted(user),
                         "hydra": _hydra_files(path) if ".hydra" in ours else {}})


def _hydra_files(path: Path) -> dict:
    """The run's ``.hydra/*.yaml`` texts (kept in the marker, so that a refused sweep job can put back what
    Hydra wrote over them)."""
    hydra = path / ".hydra"
    return {p.name: p.read_text(encoding="utf-8") for p in sorted(hydra.glob("*.yaml"))} if hydra.is_dir() else {}


def _put_back(path: Path) -> bool:
    """Move the run that ``overwrite=true`` put aside back into ``path`` (over what a failed run left); True
    if there was one."""
    aside = path / PREVIOUS
    if not (aside / MARKER).is_file():
        return False
    for item in sorted(aside.iterdir()):
        if item.name != MARKER:
            _remove(path / item.name)
            os.replace(item, path / item.name)
    os.replace(aside / MARKER, path / MARKER)
    aside.rmdir()
    restore_hydra(path)
    return True


def restore_hydra(path: str | Path, running: bool = False) -> bool:
    """A sweep job refused by a finished run in its folder: Hydra has already written the new job's ``.hydra/``
    over the finished run's; put the finished run's back from its marker (True), or do nothing (False: no
    finished run, or one recorded before its ``.hydra`` was).  ``running``: refused by a run in progress
    (:class:`InUse`), whose marker holds its ``.hydra`` from its start."""
    marker = _read_marker(Path(path))
    if not (marker and (marker.get("complete") or running) and marker.get("hydra")):
        return False
    hydra = Path(path) / ".hydra"
    hydra.mkdir(exist_ok=True)
    for p in hydra.glob("*.yaml"):
        if p.name not in marker["hydra"]:
            p.unlink()
    for name, text in marker["hydra"].items():
        (hydra / name).write_text(text, encoding="utf-8")
    return True


def record(path: str | Path, name: str) -> None:
    """Count ``name`` (written into the finished run ``path`` by a later command: ``laughlab report``'s
    ``report/``) among the run's files, so that ``overwrite=true`` removes it with the rest of the run."""
    marker = _read_marker(Path(path))
    if marker is not None and marker.get("complete") and name not in marker.get("files", []):
        marker["files"] = sorted({*marker.get("files", []), name})
        marker["user_files"] = sorted(set(marker.get("user_files", [])) - {name})
        _write_marker(Path(path), marker)


def holder(path: str | Path) -> str | None:
    """The pid of the laughlab run that holds ``path``'s lock now (a run still going), or None."""
    try:
        fd = os.open(Path(path) / LOCK, os.O_RDONLY if oslock.fcntl is not None else os.O_RDWR)
    except OSError:
        return None
    try:
        if oslock.try_lock(fd, shared=True):
            return None
        return oslock.read_head(fd).decode(errors="replace").strip() or "unknown"
    except OSError:
        return None
    finally:
        os.close(fd)   # and the shared lock with it


def finished(path: Path) -> bool:
    """Whether ``path`` holds a finished run (its marker says complete): a plain run's, an experiment's, a sweep
    job's alike (a sweep's report and its Ctrl-C line count its points by it)."""
    marker = _read_marker(Path(path))
    return bool(marker and marker.get("complete"))


def _read_marker(path: Path) -> dict | None:
    try:
        return json.loads((path / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _write_marker(path: Path, doc: dict) -> None:
    tmp = path / MARKER_PART
    tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path / MARKER)


def sweep_state(argv: list[str]) -> tuple[Path, bytes, dict] | None:
    """A sweep into a folder given on the command line that already holds one: its ``multirun.yaml`` and
    its jobs' markers (a job that runs rewrites its marker)."""
    given = given_value(argv, "hydra.sweep.dir")
    if not given:
        return None
    root = Path(given).expanduser()
    try:
        text = (root / "multirun.yaml").read_bytes()
        markers = {p.parent.name: p.read_bytes() for p in sorted(root.glob(f"*/{MARKER}"))}
    except OSError:
        return None
    return root / "multirun.yaml", text, markers
