"""Errors that reach the user as one clear line (no traceback)."""


class LaughlabError(Exception):
    """A user error: bad input, unknown plugin, bad parameter.

    The command line prints ``laughlab: error: <message>`` on stderr and exits
    with status 2; nothing half-written is left behind.
    """


class UnknownParameter(LaughlabError):
    """A key that the plugin's ``Params`` does not have; ``key`` is that key (the pipeline adds which other
    plugins of the group have it: ``laughlab.core.config.misplaced_parameter``)."""

    def __init__(self, message: str, key: str):
        super().__init__(message)
        self.key = key


def shown_path(path, limit: int = 200) -> str:
    """``path`` as an error line shows it: whole up to ``limit`` characters, else its start, its last 40
    characters and its length (a 3000-character path would bury the cause)."""
    text = str(path)
    return text if len(text) <= limit else f"{text[:limit // 2]}...{text[-40:]} ({len(text)} characters)"


def shown_names(names, most: int = 3) -> str:
    """The first ``most`` of ``names`` as an error line lists a folder's files: ``a, b, c, ...``."""
    names = list(names)
    return ", ".join(names[:most]) + (", ..." if len(names) > most else "")


def one_line_parser(**kwargs):
    """An ``argparse.ArgumentParser`` whose usage errors are a :class:`LaughlabError` (one line, exit 2),
    not argparse's usage block; ``--help`` is unchanged."""
    import argparse

    class _Parser(argparse.ArgumentParser):
        def error(self, message):
            raise LaughlabError(f"{self.prog}: {message} (see --help)")

    return _Parser(**kwargs)
