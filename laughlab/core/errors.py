"""Errors that reach the user as one clear line (no traceback)."""


class LaughlabError(Exception):
    """A user error: bad input, unknown plugin, bad parameter.

    The command line prints ``laughlab: error: <message>`` on stderr and exits
    with status 2 (:attr:`exit_code`); nothing half-written is left behind.
    """

    exit_code = 2


class StoppedBySignal(LaughlabError):
    """A stop signal (Ctrl-C, SIGTERM) that ended the work before there was anything to keep: its own line,
    and the exit status of any interrupt, 130 (it exited 2, as a user error did)."""

    exit_code = 130


class NoAudio(LaughlabError):
    """The input ended before its first frame (``pipeline.execute``): a ``Session`` closed before any audio returns
    no frame instead, without matching the line's words."""


class UnknownParameter(LaughlabError):
    """A key that the plugin's ``Params`` does not have; ``key`` is that key (the pipeline adds which other
    plugins of the group have it: ``laughlab.core.config.misplaced_parameter``)."""

    def __init__(self, message: str, key: str):
        super().__init__(message)
        self.key = key


class RefusedFolder(LaughlabError):
    """A run folder that holds another run: refused before anything ran in it, so nothing of it is to be kept
    or resumed (the command line says only why)."""


def shown_path(path, limit: int = 200) -> str:
    """``path`` as an error line shows it: whole up to ``limit`` characters, else its start, its last 40
    characters and its length (a 3000-character path would bury the cause)."""
    text = str(path)
    return text if len(text) <= limit else f"{text[:limit // 2]}...{text[-40:]} ({len(text)} characters)"


def number_word(n: int) -> str:
    """``two``, ``three``, ``four``; a larger count in digits ("three inputs share the name 'f'": it said two)."""
    return {2: "two", 3: "three", 4: "four"}.get(n, str(n))


def nearest(name: str, valid) -> str | None:
    """The name in ``valid`` nearest ``name`` (difflib), or None (a researcher's review: ``scheduler.gama`` listed
    the valid keys but did not name the one meant, as a mistyped top-level key did)."""
    import difflib

    found = difflib.get_close_matches(name, list(valid), n=1, cutoff=0.6)
    return found[0] if found else None


def shown_names(names, most: int = 3) -> str:
    """The first ``most`` of ``names`` as an error line lists a folder's files: ``a, b, c, ...``."""
    names = list(names)
    return ", ".join(names[:most]) + (", ..." if len(names) > most else "")


def one_line_parser(**kwargs):
    """An ``argparse.ArgumentParser`` whose usage errors are a :class:`LaughlabError` (one line, exit 2),
    not argparse's usage block; ``--help`` is unchanged."""
    import argparse
    import re

    class _Parser(argparse.ArgumentParser):
        def error(self, message):
            # a command's own commands (corpus fetch, study build...) by name, not argparse's "required: cmd"
            # (a new-user review) or "argument cmd: invalid choice"
            sub = next((a for a in self._actions if isinstance(a, argparse._SubParsersAction)), None)
            if sub is not None and (message.endswith(f"required: {sub.dest}") or f"argument {sub.dest}:" in message):
                names = ", ".join(sub.choices)
                bad = re.search(r"invalid choice: '([^']*)'", message)
                message = (f"unknown command {bad.group(1)!r}: its commands are {names}" if bad
                           else f"name a command: {names}")
            raise LaughlabError(f"{self.prog}: {message} (see --help)")

    return _Parser(**kwargs)


def port_number(text: str) -> int:
    """An argparse type: a TCP port, 0-65535 (0: any free one); a bad one is argparse's one-line error."""
    import argparse

    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 0 to 65535 (got {port})")
    return port


def finite_number(text: str) -> float:
    """An argparse type: a finite float (``nan`` and ``inf`` refused in one line)."""
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number (got {text})")
    return value


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (a library's reason), or its type's name if it has none."""
    text = str(exc).strip()   # (PortAudio's messages may start with a newline)
    return text.splitlines()[0] if text else type(exc).__name__


def read_json_object(path, fix: str, damaged: str = "is damaged", keys: dict | None = None) -> dict:
    """A JSON object laughlab wrote (``results.json``, ``stimuli.json``, ``design.json``...), with ``keys`` (name:
    type) in it; a damaged one (truncated, empty, not text, another program's JSON) is one line naming it:
    ``{path} {damaged} ({why}){fix}`` (reviews: tracebacks)."""
    import json
    from pathlib import Path

    text = None
    try:
        text = Path(path).read_text(encoding="utf-8")
        doc = json.loads(text)
    except UnicodeDecodeError:
        why = "not text"
    except json.JSONDecodeError as exc:
        why = f"not JSON: {exc.msg} at line {exc.lineno}" if text.strip() else "empty"
    else:
        keys = keys or {}
        if isinstance(doc, dict) and all(isinstance(doc.get(k), t) for k, t in keys.items()):
            return doc
        why = f"no {' and '.join(keys)} in it" if keys else "not a JSON object"
    raise LaughlabError(f"{path} {damaged} ({why}){fix}")


def os_error_line(exc: OSError, where: str, verb: str = "cannot write") -> str:
    """One line for a file-system fault: the path (the file if known, else ``where``; :func:`shown_path`)
    and the cause."""
    import errno

    path = shown_path(exc.filename or where)
    cause = exc.strerror or type(exc).__name__
    hint = {errno.EFBIG: " (a file size limit: ulimit -f)", errno.ENOSPC: " (the disk is full)",
            errno.EDQUOT: " (the disk quota is used up)", errno.EROFS: " (a read-only file system)"}.get(exc.errno, "")
    return f"{verb} {path}: {cause}{hint}"
