"""Errors that reach the user as one clear line (no traceback)."""


class LaughlabError(Exception):
    """A user error: bad input, unknown plugin, bad parameter.

    The command line prints ``laughlab: error: <message>`` on stderr and exits
    with status 2; nothing half-written is left behind.
    """
