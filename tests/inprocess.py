"""``python -m laughlab ARGS`` in the test's own process, reported as ``subprocess.run`` reports a child.

A child pays 2-3 s of imports (scipy.signal alone about 1 s) before it does anything; most tests of the
command line are about what it writes and says, not about the process.  Those call :func:`laughlab`;
the tests about the process itself (signals, two processes on one folder, the summary's time from the
process' start, ``python -m laughlab``'s own module) start a real one.

What a child would have printed stays visible: an uncaught exception is exit 1 with a ``Traceback``
line on stderr, and warning text is on stderr, so "one line on stderr" checks still catch both.
Helper processes for the sinks are off while the command runs (``LAUGHLAB_WORKERS=0``, as in ``fuzz``): the
bytes are the same (tests/test_background.py) and a fork of a test worker is avoided.
"""
from __future__ import annotations

import contextlib
import subprocess
from pathlib import Path

import fuzz

ROOT = Path(__file__).resolve().parents[1]


def laughlab(*args, cwd=None) -> subprocess.CompletedProcess:
    """Run the command line on ``args`` in this process, in ``cwd`` (the repository by default)."""
    argv = [str(a) for a in args]
    with contextlib.chdir(cwd or ROOT):
        out = fuzz.run_cli(argv)
    stderr = out.stderr + "".join(f"{w}\n" for w in out.warnings)
    if out.exception:
        stderr += f"Traceback (most recent call last):\n{out.exception}\n"
    return subprocess.CompletedProcess(["python", "-m", "laughlab", *argv], out.code, out.stdout, stderr)
