"""Progress for a log (stderr not a terminal): plain lines instead of a bar's carriage returns."""
from __future__ import annotations

import sys
import time


class LogProgress:
    """Progress for a log file (stderr not a terminal): a plain line every ``every_s`` seconds and one at
    the end, instead of a bar's thousands of carriage-return updates."""

    def __init__(self, total: float | None, desc: str, every_s: float = 10.0, stream=None, unit: str = "trials",
                 digits: int | None = None):
        self.total, self.desc, self.every_s, self.unit = total, desc, every_s, unit
        self.fmt = f".{digits}f" if digits is not None else ".10g"   # seconds of audio: 0.1 s
        self.stream = stream or sys.stderr
        self.n = 0
        self.t0 = self.last = time.monotonic()
        self.said = None   # the last line printed

    def update(self, k: int = 1) -> None:
        self.n += k
        now = time.monotonic()
        if now - self.last >= self.every_s:
            self.last = now
            self._line(now)

    def _line(self, now: float) -> None:
        done = f"{self.n:{self.fmt}}" + (f"/{self.total:{self.fmt}}" if self.total is not None else "")
        line = f"{self.desc}: {done} {self.unit}, {now - self.t0:.0f} s"
        if line != self.said:   # the closing line is not the last update's again (a review: printed twice)
            print(line, file=self.stream, flush=True)
            self.said = line

    def close(self) -> None:
        self._line(time.monotonic())

    def write(self, line: str, file=None) -> None:
        """A line of its own among the progress lines (as ``tqdm.write`` puts one above a bar)."""
        print(line, file=file or self.stream, flush=True)

    def refresh(self) -> None:
        """(A bar redraws; a log's next line says the new total.)"""


def bar(total, desc: str, log_unit: str, digits: int | None = None, **tqdm_kwargs):
    """Progress on stderr: a tqdm bar on a terminal (``tqdm_kwargs``: its unit, format...), or
    :class:`LogProgress` lines in ``log_unit`` when stderr is not one (a log, CI): every 10 s, or every minute
    without a total (a session that runs until stopped: a bar's carriage returns made one endless line in a
    service's journal, 32 MB a day, a soak review)."""
    if not sys.stderr.isatty() and not tqdm_kwargs.get("disable"):
        return LogProgress(total, desc, every_s=10.0 if total is not None else 60.0, unit=log_unit, digits=digits)
    import threading

    from tqdm import tqdm

    if getattr(tqdm, "_lock", None) is None:
        # a lock of this process only: tqdm's default is a multiprocessing semaphore, which a sweep job's process
        # stopped by its launcher left behind ("resource_tracker: ... leaked semaphore objects", a review); laughlab
        # draws every bar from one process
        tqdm.set_lock(threading.RLock())
    return tqdm(total=total, desc=desc, file=sys.stderr, **tqdm_kwargs)
