"""What a command run in-process leaves of its caller's process: as it found it.

``laughlab.cli.main(argv)`` (a notebook, a script, the tests) and a :class:`~laughlab.session.Session` run in the
caller's interpreter. A Python user's review (2026-11-29) found four things they changed for good: Hydra's
``job_logging: disabled`` set the root logger to ERROR, removed its handlers and disabled every logger that
existed (the user's own went silent); the stop-signal handlers stayed installed, so after the first Ctrl-C a
notebook ignored every later one; Hydra's record of the job (``HydraConfig``) repeated its overrides in the next
experiment composed in the process; and composing a configuration cleared a caller's own ``hydra.initialize()``.
"""
from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading

from laughlab.core import interrupts


def _logging_state() -> tuple:
    loggers = {name: (lg.level, list(lg.handlers), lg.disabled, lg.propagate)
               for name, lg in logging.root.manager.loggerDict.items() if isinstance(lg, logging.Logger)}
    root = logging.getLogger()
    return (root.level, list(root.handlers), root.disabled), loggers, logging.root.manager.disable


def _restore_logging(state: tuple) -> None:
    (level, handlers, disabled), loggers, disable = state
    root = logging.getLogger()
    root.setLevel(level)
    root.handlers[:] = handlers
    root.disabled = disabled
    for name, (lv, hs, dis, prop) in loggers.items():
        lg = logging.getLogger(name)
        lg.setLevel(lv)
        lg.handlers[:] = hs
        lg.disabled, lg.propagate = dis, prop
    logging.disable(disable)


def forget_hydra_job() -> None:
    """Clear Hydra's record of the job, as a process' end would (in-process, the next call's experiment repeated
    this one's overrides: a CI flake); a command without Hydra does not import it."""
    held = sys.modules.get("hydra.core.hydra_config")
    if held is not None:
        held.HydraConfig.instance().cfg = None


@contextlib.contextmanager
def kept(in_process: bool):
    """Around a command: Hydra's job record cleared at the end; ``in_process`` (``main(argv)``), also the caller's
    logging configuration and stop-signal handlers put back as they were."""
    main_thread = threading.current_thread() is threading.main_thread()
    handlers = {sig: signal.getsignal(sig) for sig in interrupts.STOP_SIGNALS} if in_process and main_thread else {}
    logs = _logging_state() if in_process else None
    # a caller's own hydra.initialize(), set aside for the command (a sweep's hydra.main refused to start beside it:
    # 'GlobalHydra is already initialized', the diff review); Hydra not imported yet has nothing to set aside
    aside = in_process and "hydra.core.global_hydra" in sys.modules
    with their_hydra(clear_after=True) if aside else contextlib.nullcontext():
        try:
            yield
        finally:
            forget_hydra_job()
            if in_process:
                interrupts.forget()   # this command's Ctrl-C is not the caller's: a later Session's feed raised it
                held = sys.modules.get("hydra.core.global_hydra")
                if not aside and held is not None:   # imported by the command: left as found, not initialized
                    held.GlobalHydra.instance().clear()   # (hydra.main may leave its own behind)
            if logs is not None:
                _restore_logging(logs)
            for sig, handler in handlers.items():
                if handler is not None:
                    signal.signal(sig, handler)


@contextlib.contextmanager
def their_hydra(clear_after: bool = False):
    """Hydra cleared for laughlab's own composition, and a caller's own initialized ``GlobalHydra`` put back after
    (``hydra.initialize(...)`` then a Session: the caller's ``compose()`` failed, 'GlobalHydra is not
    initialized'); with none to put back and ``clear_after``, left cleared (a command's own is not left behind)."""
    from hydra.core.global_hydra import GlobalHydra
    from hydra.initialize import get_gh_backup, restore_gh_from_backup

    theirs = get_gh_backup() if GlobalHydra.instance().is_initialized() else None
    GlobalHydra.instance().clear()
    try:
        yield
    finally:
        if theirs is not None:
            restore_gh_from_backup(theirs)
        elif clear_after:
            GlobalHydra.instance().clear()
