"""Lines for settings Hydra cannot read or run: a value that needs quoting, a launcher that is not installed.

:func:`laughlab.core.config.composition_error` and the sweep check (:mod:`laughlab.core.sweepcheck`) turn
Hydra's errors into these one-line hints.
"""
from __future__ import annotations

import re


def unreadable_override(text: str, overrides=()) -> str | None:
    """The line for a setting Hydra's override grammar cannot read (a value with a space, ``(``, ``=``, ``[``, a
    quote or a character other than ASCII), naming the setting and how to quote it; None if ``text`` is not
    such an error.  Hydra's own line names the setting only for characters its lexer refuses
    (``LexerNoViableAltException: KEY=VALUE``); for the others (``mismatched input ' (' expecting <EOF>``) the
    setting is the first of ``overrides`` the parser refuses alone."""
    if not re.search(r"LexerNoViableAltException|mismatched input|extraneous input|no viable alternative", text):
        return None
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser, line = OverridesParser.create(), None
    for ov in overrides:
        try:
            parser.parse_overrides([ov])
        except Exception:  # the grammar's refusal, whatever its class
            line = ov
            break
    if line is None:
        m = re.search(r"LexerNoViableAltException: ([^\n]*)", text)
        line = m.group(1).strip() if m else None
    if line is None or "=" not in line:
        return None
    key, value = line.split("=", 1)
    if not re.fullmatch(r"[\w.+~/@-]+", key):
        return None
    if value[:1] + value[-1:] in ("[]", "{}") and "'" not in value and '"' not in value:
        # a list (a condition's overrides) or a mapping of lists: the items are quoted, not the whole value, which
        # would be one string the harness refuses (a diff review: the mapping got that hint)
        items = re.sub(r"\[([^\[\]]*)\]", lambda m: "[" + ",".join(f"'{i.strip()}'" for i in m.group(1).split(",")
                                                                if i.strip()) + "]", value)
        return (f"cannot read the setting {line}: in a list, items with characters such as = ( ) or letters "
                f"outside ASCII are quoted one by one: \"{key}={items}\" (the double quotes for the shell)")
    quoted = value.replace("'", "\\'")   # Hydra's quoted values: a backslash escapes the quote after it
    return (f"cannot read the setting {line}: a value with characters such as ( ) [ ] = , ' ~ or letters outside "
            f"ASCII must be quoted: \"{key}='{quoted}'\" (the double quotes for the shell)")


def launcher_missing(name: str) -> str:
    """The line for ``hydra/launcher=NAME`` that Hydra cannot find: the launchers this installation has, and for
    Hydra's submitit launchers (Slurm) the extra that installs them."""
    try:
        from hydra.core.global_hydra import GlobalHydra

        found = sorted(GlobalHydra.instance().config_loader().get_group_options("hydra/launcher"))
    except Exception:  # listing them is a courtesy
        found = []
    here = f"; launchers here: {', '.join(found)}" if found else ""
    if name.startswith("submitit"):
        return (f"hydra/launcher={name} is Hydra's submitit launcher, which is not installed: pip install -e "
                f"'.[cluster]' in laughlab's checkout (or pip install hydra-submitit-launcher){here}")
    return f"unknown launcher hydra/launcher={name}{here}"
