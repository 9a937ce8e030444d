"""Errors that reach the user as one clear line (no traceback)."""


class LaughlabError(Exception):
    """A user error: bad input, unknown plugin, bad parameter.

    The command line prints ``laughlab: error: <message>`` on stderr and exits
    with status 2; nothing half-written is left behind.
    """


def one_line_parser(**kwargs):
    """An ``argparse.ArgumentParser`` whose usage errors are a :class:`LaughlabError` (one line, exit 2),
    not argparse's usage block; ``--help`` is unchanged."""
    import argparse

    class _Parser(argparse.ArgumentParser):
        def error(self, message):
            raise LaughlabError(f"{self.prog}: {message} (see --help)")

    return _Parser(**kwargs)
