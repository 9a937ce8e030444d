"""When this process started, for the run's summary: the time the user waited, interpreter start-up included;
and :class:`FramePacer`, the frame clock a stream is paced at.

On Linux the kernel records a process' start (``/proc/self/stat``, field 22, in clock ticks since boot,
measured on the clock ``CLOCK_BOOTTIME`` reads); elsewhere the moment this module is first imported stands in
(``python -m laughlab`` imports it before anything else of laughlab).
"""
from __future__ import annotations

import os
import time

_IMPORTED = time.monotonic()


def process_age() -> float | None:
    """Seconds since this process started, from the kernel's record; None where there is none."""
    try:
        with open("/proc/self/stat", encoding="ascii") as fh:
            text = fh.read()
        start_ticks = int(text[text.rindex(")") + 2:].split()[19])  # field 22; fields 1-2 end at ")"
        age = time.clock_gettime(time.CLOCK_BOOTTIME) - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    return age if 0.0 <= age < 7 * 86400 else None


def process_start() -> float:
    """The process' start on the ``time.monotonic()`` clock."""
    age = process_age()
    return time.monotonic() - age if age is not None else _IMPORTED


class FramePacer:
    """Paces a stream at the frame clock (``output=vmc``, ``output=viewer`` on a file): frame ``k`` is due
    ``(k + 1) / fps`` after the first frame's start, when its audio would have been captured live."""

    def __init__(self, fps: float):
        self.dt_ns = int(round(1e9 / fps))
        self.origin_ns: int | None = None

    def wait(self, k: int) -> int:
        """Sleep until frame ``k`` is due; return when it was due (``time.perf_counter_ns``)."""
        if self.origin_ns is None:
            self.origin_ns = time.perf_counter_ns() - self.dt_ns
        due = self.origin_ns + (k + 1) * self.dt_ns
        wait = due - time.perf_counter_ns()
        if wait > 0:
            time.sleep(wait / 1e9)
        return due
