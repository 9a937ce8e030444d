"""Hydra's override strings (``key=value``, ``+key=value``, ``++key=value``, ``~key``): their keys, and which of
them a run repeats.

The CLI, the experiment runner, the sweep check and the session read overrides by their keys; they read them
through here, so that ``+seed=1`` and ``~seed`` are ``seed`` everywhere.
"""
from __future__ import annotations

from laughlab.core.errors import LaughlabError

#: the keys of Hydra's own settings and of the command's (overwrite, progress): an experiment's trials and a
#: condition's check run without them
COMMAND_ONLY = ("hydra", "overwrite", "progress")


def override_key(override) -> str:
    """The key an override sets, adds or deletes: ``+input.path=a=b.wav`` -> ``input.path``, ``~seed`` -> ``seed``.

    A key alone (``++harness.jobs``) gives the key without its ``+``/``~``."""
    return str(override).split("=", 1)[0].lstrip("+~")


def without_command_keys(overrides) -> list:
    """``overrides`` without Hydra's own settings and the command's (``COMMAND_ONLY``), in their order."""
    return [o for o in overrides if not override_key(o).startswith(COMMAND_ONLY)]


def given_value(overrides, key: str) -> str | None:
    """The value ``overrides`` give ``key`` (the last, as Hydra takes it), or None: ``hydra.sweep.dir``'s for the
    sweep's checks (:mod:`laughlab.core.sweepcheck`) and its clean-up (:func:`laughlab.core.rundir.sweep_state`)."""
    values = [str(o).split("=", 1)[1] for o in overrides if "=" in str(o) and override_key(o) == key]
    return values[-1] if values else None


def one_choice_each(overrides, groups) -> None:
    """Refuse a list for a group that takes one plugin (``face=[facs,cgm]``: Hydra merges both, and the run then
    said "face.au6 is a parameter of face=facs, not of face=cgm"; a facial animator's review). ``groups``: the groups
    of one plugin (not ``output``, which takes a list); a sweep's ``face=facs,cgm`` (``-m``) is not a list."""
    for o in overrides:
        key, sep, value = str(o).partition("=")
        key = key.lstrip("+~")
        value = value.strip()
        if sep and key in groups and value.startswith("["):
            items = [v.strip() for v in value.strip("[]").split(",") if v.strip()]
            if len(items) == 1:
                raise LaughlabError(f"{key} takes one option, not a list (got {key}={value}): write {key}={items[0]}")
            hint = f": choose one, e.g. {key}={items[0]}" if items else ""
            raise LaughlabError(f"{key} takes one option, not a list (got {key}={value}){hint}; "
                                f"to compare several, sweep them: -m {key}={','.join(items) or '...'}")
