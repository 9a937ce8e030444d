"""File sinks in a helper process: the frame loop hands chunks over a pipe and goes on.

Formatting ``channels.csv`` and ``motion.bvh`` and drawing the plots cost about as much as
computing the frames.  On a machine with two or more cores an offline run forks one helper
process at start-up.  Once the main process has composed a configuration that draws figures,
the helper imports the plotting modules while the run is built (:func:`warm`).  It runs the file
sinks (those whose class sets ``background = True``) on the chunks the frame loop sends, and
draws the figures in parallel at the end.  The bytes written are the same as in-process (a test
holds the two equal).

Failures keep the sinks' contract: a sink error in the helper comes back to the main process
as the same exception (a ``LaughlabError`` stays one line); on any failure of the run the
helper aborts its sinks, which remove what they wrote; if the main process dies, the helper
sees its pipe close and aborts too.  ``LAUGHLAB_WORKERS=0`` runs every sink in-process.
Live sources and streaming sinks always run in-process (their frames go out one by one).
"""
from __future__ import annotations

import atexit
import os
import pickle
import signal
import sys
import traceback
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from laughlab.core import interrupts
from laughlab.core.interrupts import STOP_SIGNALS
from laughlab.core.outfiles import unwrite

#: modules the helper imports while the main process starts up
WARM = ("numpy",)
#: modules it imports once the main process has composed a configuration that draws figures (:func:`warm`):
#: 0.9 s of CPU a run without the plots sink (``~output.plots``, ``output=trial``, ...) used to spend for nothing
PLOTTING = ("laughlab.render.plots",)

_HELPER: "Helper | None" = None
#: True inside the helper process
IN_HELPER = False


def enabled() -> bool:
    """Fork-based helpers: Linux, at least two usable cores, ``LAUGHLAB_WORKERS`` not 0."""
    if os.environ.get("LAUGHLAB_WORKERS", "1").strip() == "0" or not sys.platform.startswith("linux"):
        return False
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except (AttributeError, OSError):
        return (os.cpu_count() or 1) >= 2


def start() -> "Helper | None":
    """Fork the helper now (early: before heavy imports and threads) if :func:`enabled`."""
    global _HELPER
    if _HELPER is None and enabled():
        _HELPER = Helper()
    return _HELPER


def helper() -> "Helper | None":
    """The helper started by :func:`start` and not yet used, or None."""
    return _HELPER


def warm(modules: Sequence[str]) -> None:
    """Have the helper (if one was started) import ``modules`` now, while the main process builds the run."""
    if _HELPER is not None:
        _HELPER.warm(modules)


def local_package(folder) -> None:
    """Have the helper (if one was started) know a ``plugins_dir`` as the main process does
    (:func:`laughlab.core.plugins.local_package`): it unpickles the folder's background sinks by name."""
    if _HELPER is not None:
        try:
            _send_msg(_HELPER.conn, ("package", str(folder)))
        except OSError:  # a helper that went away is reported when a run takes it
            pass


def take() -> "Helper | None":
    """Hand the helper to one run (a helper serves one run)."""
    global _HELPER
    h, _HELPER = _HELPER, None
    return h


@dataclass
class SourceView:
    """What a sink in the helper may ask of the source (the source itself stays in the main process)."""

    name: str
    live: bool
    sample_rate: int
    n_frames: int | None
    truth: Any = None


class Helper:
    """One forked process that runs a run's background sinks."""

    def __init__(self):
        import multiprocessing as mp

        ctx = mp.get_context("fork")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, self.conn), daemon=True, name="laughlab-sinks")
        # Ctrl-C and SIGTERM are for the main process, which aborts us: the helper ignores them, and they
        # stay blocked across the fork so that one arriving before it can say so does not reach it either
        held = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            self.proc.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        child.close()
        # registered after multiprocessing's own exit handler, so it runs first: that one would join a helper
        # no run took (the run failed or was interrupted before it began) after a SIGTERM the helper ignores
        atexit.register(self.stop)

    # the main process' side -------------------------------------------------------------
    def warm(self, modules: Sequence[str]) -> None:
        """Import ``modules`` in the helper, without waiting for it."""
        try:
            _send_msg(self.conn, ("warm", tuple(modules)))
        except OSError:  # a helper that went away is reported when a run takes it
            pass

    def open(self, sinks: Sequence, info) -> None:
        self._send(("open", list(sinks), info))

    def write(self, chunk) -> None:
        if self.conn.poll():  # an early failure in the helper ends the run now
            self._raise(self.conn.recv())
        self._send(("write", chunk))

    def close(self) -> list:
        self._send(("close",))
        reply = self._recv()
        if reply[0] != "ok":
            self._raise(reply)
        return reply[1]

    def abort(self) -> None:
        try:
            _send_msg(self.conn, ("abort",))
            while True:  # skip an error report sent before the abort
                if self.conn.recv()[0] == "aborted":
                    break
        except (OSError, EOFError):
            pass

    def stop(self) -> None:
        """Ask the helper to quit, kill it if it has not within 5 s (idempotent)."""
        if self.conn.closed:
            return
        try:
            _send_msg(self.conn, ("quit",))
        except OSError:
            pass
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
        self.conn.close()

    def _send(self, msg) -> None:
        try:
            _send_msg(self.conn, msg)
        except (BrokenPipeError, ConnectionResetError):
            self._raise(self._recv())

    def _recv(self):
        try:
            return self.conn.recv()
        except EOFError:
            raise RuntimeError(f"the sink helper process ended unexpectedly (exit {self.proc.exitcode})") from None

    @staticmethod
    def _raise(reply):
        if reply[0] == "error":
            raise reply[1]
        raise RuntimeError(f"sink helper: {reply[1]}")


def _send_msg(conn, msg) -> None:
    """Send to the helper with pickle protocol 5: arrays go to the pipe from their own memory
    (out of band), not copied into the pickle first.

    A message is several sends (its head, then each buffer), so Ctrl-C and SIGTERM wait until the last is
    out (:func:`laughlab.core.interrupts.deferred`): a KeyboardInterrupt between them left the helper
    waiting for the rest of a chunk, reading the main process' "abort" as one of its buffers, while the
    main process waited for "aborted" (a hang, found by the clean-clone CI)."""
    buffers: list = []
    head = pickle.dumps(msg, protocol=5, buffer_callback=buffers.append)
    with interrupts.deferred():
        conn.send_bytes(len(buffers).to_bytes(4, "little") + head)
        for b in buffers:
            conn.send_bytes(b.raw())


def _recv_msg(conn):
    raw = conn.recv_bytes()
    n = int.from_bytes(raw[:4], "little")
    return pickle.loads(memoryview(raw)[4:], buffers=[conn.recv_bytes() for _ in range(n)])


def _error(exc: BaseException):
    """The exception itself if it survives pickling, else a RuntimeError with its traceback."""
    try:
        pickle.loads(pickle.dumps(exc))
        return ("error", exc)
    except Exception:
        return ("error", RuntimeError("".join(traceback.format_exception(exc)).rstrip()))


def _serve(conn, parent_end) -> None:
    """The helper's loop: open, write, close or abort its sinks as the main process asks."""
    global IN_HELPER
    IN_HELPER = True
    parent_end.close()
    for sig in STOP_SIGNALS:  # Ctrl-C and SIGTERM reach the main process, which aborts us
        signal.signal(sig, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    _import(WARM)
    sinks: list = []
    out_dir = None
    failed = False
    try:
        while True:
            try:
                msg = _recv_msg(conn)
            except EOFError:  # the main process is gone: remove what we wrote
                _abort(sinks)
                break
            op = msg[0]
            try:
                if op == "warm":
                    _import(msg[1])
                elif op == "package":
                    from pathlib import Path

                    from laughlab.core.localpackage import local_package

                    local_package(Path(msg[1]))
                elif op == "write":
                    if not failed:
                        for s in sinks:
                            s.write(msg[1])
                elif op == "open":
                    sinks, out_dir = msg[1], msg[2].out_dir
                    for s in sinks:
                        s.open(msg[2])
                elif op == "close":
                    if not failed:
                        written = []
                        try:
                            for s in sinks:
                                written += s.close() or []
                        except BaseException:   # a later sink failed: the earlier ones' files go too
                            unwrite(written, out_dir)
                            raise
                        sinks = []  # closed: their files are the run's now
                        conn.send(("ok", written))
                elif op == "abort":
                    _abort(sinks)
                    sinks = []
                    conn.send(("aborted",))
                elif op == "quit":
                    # sinks still open: the main process was stopped before it could ask (a Ctrl-C while it
                    # handed them over left .channels.csv.part behind, and the folder could not be removed)
                    _abort(sinks)
                    break
            except BaseException as exc:  # noqa: BLE001 - every failure goes back to the main process
                failed = True
                _abort(sinks)
                sinks = []
                conn.send(_error(exc))
    finally:
        conn.close()
        os._exit(0)  # no atexit handlers of the main process' state


def _import(modules) -> None:
    for name in modules:
        try:
            __import__(name)
        except Exception:  # a missing optional module shows up where it is used
            pass


def _abort(sinks) -> None:
    for s in sinks:
        try:
            s.abort()
        except Exception:  # cleanup must not hide the original error
            pass


def parallel(jobs: Sequence[Callable[[], Any]]) -> None:
    """Run independent jobs (e.g. drawing figures); in the helper, each in a forked child.

    The helper has the cores to itself while the main process waits for it, so the jobs run
    side by side; elsewhere they run one after another.  A job that fails in a child raises
    here with its traceback.
    """
    if not IN_HELPER or len(jobs) < 2:
        for job in jobs:
            job()
        return
    children = []
    for job in jobs:
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: draw, report, leave without running the parent's exit handlers
            os.close(r)
            try:
                job()
                msg, code = b"", 0
            except BaseException:  # noqa: BLE001
                msg, code = traceback.format_exc().encode(), 1
            os.write(w, msg)
            os._exit(code)
        os.close(w)
        children.append((pid, r))
    errors = []
    for pid, r in children:
        with os.fdopen(r, "rb") as f:
            msg = f.read()
        _, status = os.waitpid(pid, 0)
        if status:
            errors.append(msg.decode(errors="replace") or f"a drawing process ended with status {status}")
    if errors:
        raise RuntimeError(errors[0])
