"""A run directory's lock file, on every operating system (:mod:`laughlab.core.rundir`).

POSIX (Linux, macOS): ``flock`` on the whole file, and the holder's pid read and written at offset 0 with
``pread``/``pwrite``.  Windows has neither (a portability review, 2026-11-29: every run ended in
``ModuleNotFoundError: fcntl``): ``msvcrt.locking`` locks one byte far past the pid (Windows' byte-range locks are
mandatory, so a lock over the pid would keep a second run from reading whose it is), and the pid is read and written
with ``lseek`` and ``read``/``write``.  Either lock goes with the process, a crash included.
"""
from __future__ import annotations

import os

try:
    import fcntl
except ImportError:   # Windows
    fcntl = None

#: where the Windows lock sits: one byte past anything the file holds
_WINDOWS_BYTE = 1 << 30


def try_lock(fd: int, shared: bool = False) -> bool:
    """Take the lock on ``fd`` without waiting: True if taken, False if another process holds it.  ``shared`` (a
    reader asking whether a run holds it): POSIX's shared lock; on Windows the exclusive one, given back at once."""
    if fcntl is not None:
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return True
    import msvcrt

    os.lseek(fd, _WINDOWS_BYTE, os.SEEK_SET)
    try:
        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    if shared:
        os.lseek(fd, _WINDOWS_BYTE, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
    return True


def read_head(fd: int, n: int = 32) -> bytes:
    """The first ``n`` bytes of the file (the holder's pid)."""
    if hasattr(os, "pread"):
        return os.pread(fd, n, 0)
    os.lseek(fd, 0, os.SEEK_SET)
    return os.read(fd, n)


def write_head(fd: int, data: bytes) -> None:
    """The file's content becomes ``data``."""
    os.ftruncate(fd, 0)
    if hasattr(os, "pwrite"):
        os.pwrite(fd, data, 0)
        return
    os.lseek(fd, 0, os.SEEK_SET)
    os.write(fd, data)
