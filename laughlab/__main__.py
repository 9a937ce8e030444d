"""``python -m laughlab``: a SIGTERM or Ctrl-C ends in one line (exit 130) from the moment this module runs.

Before it, the interpreter starts (``site``) and imports the package's ``__init__`` (kept to a few
milliseconds: no ``importlib.abc``, no typing); a signal in that window is Python's own, which no
program can answer.
"""
from laughlab.core import clock  # noqa: F401 - first: where the kernel keeps no start time, its import is it
from laughlab.core import interrupts

if __name__ == "__main__":
    interrupts.install()
    interrupts.keep_lost_interrupts_quiet()
    try:
        from laughlab.cli import main
    except BaseException as exc:  # interrupted while importing (nothing was written yet)
        if not interrupts.interrupted(exc):
            raise
        interrupts.exit_interrupted()
    main()
