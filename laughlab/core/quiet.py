"""File descriptor 2 silenced while C++ libraries log to it, without losing laughlab's own lines.

LiteRT prints "INFO: Created TensorFlow Lite XNNPACK delegate" on fd 2 whenever an interpreter is built, and
the offline detector builds them on two network threads, some lazily while a run goes on.  :func:`quiet_stderr`
sends fd 2 to /dev/null for the block, from any number of threads at once: the first to enter silences it and
the last to leave restores it (each thread saving and restoring fd 2 on its own interleaved, and /dev/null stayed
for the rest of the process: a review).  :func:`say` writes a line of laughlab's (an error line) to the real
stderr even inside such a block, so it is never lost.  No numpy here: the command line's start-up imports it.
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading

#: shared by the threads: fd 2 is silenced by the first to enter and restored by the last to leave
_STATE = {"lock": threading.Lock(), "depth": 0, "saved": None}


@contextlib.contextmanager
def quiet_stderr():
    """Silence file descriptor 2 (C++ logging) for the duration of the block, from any number of threads."""
    with _STATE["lock"]:
        if _STATE["depth"] == 0:
            try:
                sys.stderr.flush()
                saved = os.dup(2)
            except (OSError, ValueError):
                saved = None
            if saved is not None:
                with open(os.devnull, "w") as null:
                    os.dup2(null.fileno(), 2)
            _STATE["saved"] = saved
        _STATE["depth"] += 1
    try:
        yield
    finally:
        with _STATE["lock"]:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0 and _STATE["saved"] is not None:
                os.dup2(_STATE["saved"], 2)
                os.close(_STATE["saved"])
                _STATE["saved"] = None


def say(line: str) -> None:
    """Print ``line`` on stderr; while fd 2 is silenced (another thread building an interpreter), on the real one
    (a review: an error line printed in that window was lost)."""
    with _STATE["lock"]:
        err = sys.stderr.stream if isinstance(sys.stderr, OwnLinesOnly) else sys.stderr
        if _STATE["depth"] and _STATE["saved"] is not None and err is sys.__stderr__:
            sys.stderr.flush()
            os.write(_STATE["saved"], (line + "\n").encode(errors="replace"))
        else:
            print(line, file=sys.stderr, flush=True)


def to_devnull(fd: int) -> None:
    """File descriptor ``fd`` goes to /dev/null for the rest of the process: standard output after a broken pipe
    (``... | head``), or standard output and error on a terminal that hung up (SIGHUP; a write there fails)."""
    null = os.open(os.devnull, os.O_WRONLY)
    if null == fd:   # fd was closed (>&-): /dev/null took its number, and stays
        return
    try:
        os.dup2(null, fd)
    finally:
        os.close(null)


def stdout_gone() -> None:
    """After a broken pipe (``... | head``): what is still buffered for stdout goes nowhere, silently."""
    to_devnull(sys.stdout.fileno())


def closed_streams_to_devnull() -> None:
    """A standard stream the caller closed (``2>&-``, ``>&-``: Python's ``sys.stdout`` is None) takes writes into
    /dev/null, as ``print`` drops them (``--cfg job >&-`` printed three tracebacks and exit 1)."""
    for fd, name in ((1, "stdout"), (2, "stderr")):
        if getattr(sys, name) is None:   # the descriptor itself held by /dev/null: the next file opened is not
            to_devnull(fd)               # given fd 1 or 2, where a child's or C's writes would land in it
            setattr(sys, name, open(fd, "w", encoding="utf-8", closefd=False))  # noqa: SIM115 - for the process


class PipeMayClose:
    """``sys.stdout`` where Hydra writes (``--info``, ``--cfg job``, a sweep's lines): once the reader has gone
    (``... | head``) the rest goes nowhere, silently (Hydra's ``--info`` printed 2,284 lines of logging's tracebacks,
    ``--cfg job`` Hydra's traceback and exit 1)."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        try:
            return self.stream.write(text)
        except BrokenPipeError:
            stdout_gone()
            return len(text)

    def flush(self) -> None:
        try:
            self.stream.flush()
        except BrokenPipeError:
            stdout_gone()

    def __getattr__(self, name):
        return getattr(self.stream, name)


class OwnLinesOnly:
    """``sys.stderr`` after a stop signal (:func:`laughlab.core.interrupts.keep_lost_interrupts_quiet`): only
    laughlab's own lines (``laughlab: ...``) pass, whole lines at a time; what a library prints as the signal's
    ``KeyboardInterrupt`` goes through it is dropped (scipy's decorator module prints "Error in generated code:" and
    the function's source for whatever an ``exec`` raises, a signal during ``import scipy.spatial`` among them: a
    fuzz case's SIGHUP, three lines before the one)."""

    def __init__(self, stream):
        self.stream = stream
        self._lock = threading.Lock()   # a thread's partial line does not glue to another's (a diff review)
        self._partial: dict = {}

    def write(self, text: str) -> int:
        me = threading.get_ident()
        with self._lock:
            line = self._partial.pop(me, "") + text
            *lines, rest = line.split("\n")
            if rest:
                self._partial[me] = rest
            for line in lines:
                if line.startswith("laughlab:"):
                    self.stream.write(line + "\n")
        return len(text)

    def flush(self) -> None:
        try:
            self.stream.flush()
        except (OSError, ValueError):
            pass

    def __getattr__(self, name):   # fileno, encoding, isatty...: the stream's own
        return getattr(self.stream, name)


def own_lines_only() -> None:
    """From now on ``sys.stderr`` carries laughlab's own lines only (:class:`OwnLinesOnly`); once."""
    if not isinstance(sys.stderr, OwnLinesOnly) and sys.stderr is not None:
        sys.stderr = OwnLinesOnly(sys.stderr)
