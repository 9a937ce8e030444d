"""``python -m laughlab``: a SIGTERM or Ctrl-C from the very first moment ends in one line (exit 130)."""
from laughlab.core import clock  # noqa: F401 - first: where the kernel keeps no start time, its import is it
from laughlab.core import interrupts

if __name__ == "__main__":
    interrupts.install()
    try:
        from laughlab.cli import main
    except BaseException as exc:  # interrupted while importing (nothing was written yet)
        if not interrupts.interrupted(exc):
            raise
        interrupts.exit_interrupted()
    main()
