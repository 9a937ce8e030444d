"""Ctrl-C, SIGTERM and SIGHUP end a command in one line and exit status 130, whatever they interrupt.

SIGHUP (the command's terminal closed: its window, a dropped ssh connection) is handled where it has its
default: the default killed the process where it stood, leaving ``.part`` files and a run folder marked in use
(a live review); the line then goes nowhere (the terminal is gone), but the clean-up is the same.  ``nohup``'s
ignored SIGHUP is left alone.

A signal raises ``KeyboardInterrupt`` wherever the program happens to be, and a few places turn it
into another exception: an extension module interrupted while it is imported reports
``ImportError: initialization failed``.  So the handler also records that a signal came, and the
command line treats any exception after one as the interrupt (:func:`interrupted`).
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

#: the terminal hung up (none on Windows): it stops a command, and ends a live session's input (:class:`StopOnSignal`)
_HUP = getattr(signal, "SIGHUP", None)
#: the signals that stop a command: Ctrl-C, SIGTERM (a killed job, a cluster's pre-emption) and SIGHUP
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, *((_HUP,) if _HUP is not None else ()))
#: the first stop signal received by this process, or None
received: int | None = None


#: inside :func:`deferred` blocks (their depth), and whether a stop signal came during one
_defer = 0
_pending = False


#: the command's work is done (:func:`finish`); :func:`reset` when a command starts
finished = False


_ignored = False

#: the command is the whole process (``python -m laughlab``, :func:`keep_lost_interrupts_quiet`), not a call in a test
_whole_process = False


def reset() -> None:
    """A new command (in the same process: the tests, a notebook) handles stop signals again, and an earlier
    command's signal is not taken for this one's (every exception after it was 'interrupted')."""
    global finished, _ignored, received
    finished = False
    received = None
    if _ignored:
        for sig in STOP_SIGNALS:
            if signal.getsignal(sig) == signal.SIG_IGN:
                signal.signal(sig, _handler)
        _ignored = False


def forget() -> None:
    """An in-process command ended: a signal it received is not a later caller's (``laughlab.cli.main`` in a
    notebook: a Session's next feed raised the command's Ctrl-C, ``interrupts.check``)."""
    global received, _pending
    received = None
    _pending = False


def _record(signum) -> None:
    """A stop signal came: remember it and ignore the stop signals from now on."""
    global received, _ignored
    if signum == _HUP:
        _away_from_the_terminal()
    received = received or signum
    if _whole_process:   # what a library prints as the KeyboardInterrupt passes through it is not the one line
        from laughlab.core.quiet import own_lines_only

        own_lines_only()
    # the command is stopping: another stop signal would cut its clean-up in two, and the processes the clean-up
    # starts inherit the signal ignored (the terminal's Ctrl-C reaches every process of the command: loky's pgrep,
    # run to end its workers, died of it and printed tracebacks, a review); Ctrl-\ (SIGQUIT) still ends it at once
    try:
        signal.signal(signum, signal.SIG_IGN)
        _ignored = True
    except ValueError:   # not the main thread
        pass


def _handler(signum, frame):
    global _pending
    if finished:
        return
    _record(signum)
    if _defer:
        _pending = True
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def deferred():
    """A block that a stop signal does not cut in two: its KeyboardInterrupt is raised when the block ends
    (a message to the sink helper process is sent whole).  Only with :func:`install`'s handler; under
    another one (a test runner's, Python's default) the signal acts at once, as before."""
    global _defer, _pending
    _defer += 1
    try:
        yield
    finally:
        _defer -= 1
        if not _defer and _pending:
            _pending = False
            raise KeyboardInterrupt


def check() -> None:
    """Raise the stop a signal asked for if its ``KeyboardInterrupt`` was lost on the way: raised inside a
    ``__del__`` or another callback Python cannot raise from, it is printed as "Exception ignored" and the
    program goes on (the handler has by then set the signal to be ignored).  A run calls this once a chunk
    and before it says it is done (a fuzz case under load: a Ctrl-C 1.7 s into a 300 s run, and the run went
    to its end, exit 0, a traceback on stderr)."""
    if received is not None and not finished and not _defer:
        raise KeyboardInterrupt


def _unraisable(info) -> None:
    """``sys.unraisablehook`` of ``python -m laughlab``: after a stop signal, nothing a finaliser raises is printed:
    the handler's ``KeyboardInterrupt`` raised where Python cannot raise it (:func:`check` raises it at the run's
    next chunk), and what breaks as the command stops (``study simulate``: Playwright's driver transport collected
    after its event loop closed, "Event loop is closed", a CI run).  Before one, everything is Python's."""
    if received is not None:
        return
    sys.__unraisablehook__(info)


def keep_lost_interrupts_quiet() -> None:
    """For the whole process (``python -m laughlab``): :func:`_unraisable` as ``sys.unraisablehook``, and after a
    stop signal ``sys.stderr`` keeps laughlab's own lines only (:func:`laughlab.core.quiet.own_lines_only`)."""
    global _whole_process
    sys.unraisablehook = _unraisable
    _whole_process = True


def finish(whole_process: bool = True) -> None:
    """The command's work is done and said (its summary line is out): a stop signal from now on has nothing
    to stop, and is let go (its KeyboardInterrupt, during the interpreter's shutdown, printed a traceback
    after the summary)."""
    global finished, _ignored
    if not whole_process:   # a command run inside another program (the tests): its handling stays as it is
        return
    finished = True
    try:   # and ignored outright: Python puts the default handlers back while it shuts down (exit by SIGTERM)
        for sig in STOP_SIGNALS:
            if signal.getsignal(sig) is _handler:
                signal.signal(sig, signal.SIG_IGN)
                _ignored = True
    except ValueError:   # not the main thread
        pass


#: the process that runs the command (:func:`install`); a sweep's job in a launcher's worker process is not it
main_pid: int | None = None


def in_worker() -> bool:
    """Is this a launcher's worker process (a sweep's job under Hydra's joblib launcher), not the command's own?"""
    return main_pid != os.getpid()


@contextlib.contextmanager
def worker_job():
    """A sweep's job in a launcher's worker process: Ctrl-C stops the job through laughlab's handler (its
    clean-up, no traceback), and between jobs it is ignored; the command's own process stops the sweep and
    says so in one line (a review: a line per job, and an idle worker's KeyboardInterrupt traceback)."""
    if not in_worker() or threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def install() -> None:
    """Handle the stop signals, unless someone (an embedding program, a test runner, ``nohup``) set their own."""
    global main_pid
    main_pid = os.getpid()
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) in (signal.SIG_DFL, signal.default_int_handler):
            signal.signal(sig, _handler)


def run_coroutine(coro, exception_handler=None):
    """``asyncio.run(coro)``, a stop signal ending it as a cancel of ``coro``'s task, then ``KeyboardInterrupt``.

    The handler's ``KeyboardInterrupt`` is raised wherever the main thread stands; in an event loop that may be a
    task other than ``coro``'s, which then dies of it: ``study simulate``'s Playwright reads its driver's answers
    in such a task, and the browser's clean-up after a Ctrl-C waited for an answer nobody read any more (a CI run:
    no exit within 60 s). So while the loop runs, a stop signal raises nothing: it is recorded as :func:`_handler`
    records it, at once (a terminal's Ctrl-C stops Playwright's driver and Chromium too, and what then fails is
    the interrupt's consequence, :func:`interrupted`), and cancels ``coro``'s task, whose clean-up runs whole, as
    ``asyncio.Runner`` does with a Ctrl-C under Python's default handler. Under another handler (a test runner's,
    an embedding program's) nothing changes, as with :func:`install`."""
    import asyncio

    ours = []
    try:
        ours = [sig for sig in STOP_SIGNALS if signal.getsignal(sig) is _handler]
    except ValueError:   # not the main thread
        pass

    async def main():
        loop, task = asyncio.get_running_loop(), asyncio.current_task()
        if exception_handler is not None:
            loop.set_exception_handler(exception_handler)

        def stop(signum, frame):
            if finished or received is not None:
                return
            _record(signum)   # the stop signals ignored from here: a second Ctrl-C cuts no clean-up in two
            task.cancel()
            loop.call_soon_threadsafe(lambda: None)   # wake the loop if it waits in select()

        for sig in ours:
            signal.signal(sig, stop)
        return await coro

    try:
        with asyncio.Runner() as runner:
            out = runner.run(main())
        if received is not None:   # the coroutine let the cancel go and returned: the command still stops
            raise KeyboardInterrupt
        return out
    except asyncio.CancelledError:
        if received is not None:
            raise KeyboardInterrupt from None
        raise
    finally:   # laughlab's handler again, or the signals ignored once one came
        for sig in ours:
            signal.signal(sig, signal.SIG_IGN if received is not None else _handler)


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is an interrupt, or came after one (and so is its consequence)."""
    return isinstance(exc, KeyboardInterrupt) or (received is not None and not isinstance(exc, SystemExit))


def clear_exit_flag() -> None:
    """Make ``sys.exit(130)`` exit with status 130 after an interrupt.

    CPython 3.11 marks an interrupt raised inside ``exec()`` (dataclasses and other libraries build
    their methods with it) as unhandled even when it was caught, and then ends the process by SIGINT
    instead of the exit status asked for; any later ``exec`` of a string clears the mark.
    """
    exec("0")


def exit_interrupted(message: str = "interrupted") -> None:
    """The one line, then exit status 130."""
    print(f"laughlab: error: {message}", file=sys.stderr)
    clear_exit_flag()
    sys.exit(130)


class StopOnSignal:
    """While a session with no set length (``input.duration_s=null``) reads the microphone, the first Ctrl-C
    (SIGINT) or SIGTERM ends the input: the frame loop finishes, the sinks close and the session is kept (the
    stop signal *is* its end; SIGTERM too, as a process manager stops an always-on installation).  The second
    signal goes to the handler this one stood in for (laughlab's: abort, remove what was written, exit 130).

    Only laughlab's own handler (:func:`install`'s, by identity: it recognised it by its module's name, which
    a rename or a wrapper would have quietly defeated, diff-review 18) and Python's default Ctrl-C handler are
    stood in for, on the main thread; an ignored signal or another program's handler is left alone.  The input
    source (``input=mic``) enters it.

    SIGHUP (the session's terminal closed: its window, a dropped ssh connection) ends the input too, where
    laughlab's handler has it (:func:`install`: not under ``nohup``): the default killed the process
    where it stood, the avatar frozen mid-laugh and the session lost (review-live-2 3).  Standard output and
    error on the terminal that hung up go to /dev/null from then on (a write to it fails), and a SIGHUP after it is
    ignored until the command ends: a hang-up comes more than once (the kernel's, the shell's to its jobs), and it
    would have aborted the session it had just kept."""

    def __init__(self):
        self.signum: int | None = None
        self._old: dict = {}    # the handler to put back, by signal

    def __enter__(self) -> "StopOnSignal":
        if threading.current_thread() is threading.main_thread():
            for sig in STOP_SIGNALS:
                old = signal.getsignal(sig)
                if old is signal.default_int_handler or old is _handler:
                    self._old[sig] = old
                    signal.signal(sig, self._on_signal)
        return self

    def _on_signal(self, signum, frame) -> None:
        if signum == _HUP:
            _away_from_the_terminal()
            self._old[_HUP] = signal.SIG_IGN   # the rest of the command: the terminal is gone, its repeats too
            if self.signum is not None:
                return
        if self.signum is None:
            self.signum = signum   # the read loop ends the input at its next block
            return
        old = self._old.get(signum, signal.default_int_handler)
        self.restore()
        old(signum, frame)

    def restore(self) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}

    def __exit__(self, *exc) -> bool:
        self.restore()
        return False


def _away_from_the_terminal() -> None:
    """Standard output and error that are a terminal go to /dev/null: it hung up, and a write to it fails (EIO)."""
    from laughlab.core.quiet import to_devnull

    for fd in (1, 2):
        try:
            if os.isatty(fd):
                to_devnull(fd)
        except OSError:
            pass
