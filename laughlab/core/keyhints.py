"""Where an unknown parameter belongs: the options of a config group that have it.

``scheduler.mode=fast`` under the default ``scheduler=energy`` is an unknown parameter, but
``scheduler=concat`` has ``mode``; ``input.path=...`` belongs to ``input=file``.  The error line
then says what to add instead of only listing the keys of the plugin that is chosen.

An option's parameters are the keys of its YAML file (``conf/<group>/<option>.yaml``, nested keys
as dotted paths, e.g. ``video.fps`` of ``output=video``) and, for a registered plugin, the fields of
its ``Params`` dataclass.  ``laughlab.core.config`` wires these functions to the groups.
"""
from __future__ import annotations

#: the groups searched for a key given without its group (e.g. ``mode=fast``)
SEARCHED = ("input", "extractor", "detector", "face", "body", "scheduler", "output")


def _paths(node, prefix: str = "") -> set[str]:
    out = set()
    if isinstance(node, dict):
        for k, v in node.items():
            path = f"{prefix}{k}"
            out.add(path)
            out |= _paths(v, path + ".")
    return out


def option_keys(folder, kind: str | None) -> dict[str, set]:
    """Option name -> its parameter paths, for one group: ``folder`` its YAML files (a path or a
    ``Traversable``), ``kind`` the plugin kind whose registered plugins' ``Params`` count too (None: only YAML)."""
    from dataclasses import fields, is_dataclass

    from omegaconf import OmegaConf

    keys: dict[str, set] = {}
    if folder is not None and folder.is_dir():
        for f in folder.iterdir():
            if f.name.endswith(".yaml"):
                doc = OmegaConf.to_container(OmegaConf.create(f.read_text(encoding="utf-8")), resolve=False) or {}
                keys[f.name[:-5]] = _paths(doc) - {"name", "defaults"}
    if kind is not None:
        from laughlab.core import plugins

        for name, info in plugins.registry()[kind].items():
            params = getattr(info.obj, "Params", None)
            if params is not None and is_dataclass(params):
                keys.setdefault(name, set()).update(f.name for f in fields(params))
    return keys


def options_with(folder, kind: str | None, path: str) -> list[str]:
    """The options of a group (see :func:`option_keys`) that have the parameter ``path``, sorted."""
    try:
        return sorted(name for name, keys in option_keys(folder, kind).items() if path in keys)
    except Exception:  # a hint is a courtesy: never let it hide the error it explains
        return []


def nested_in(folder, kind: str | None, option: str | None, path: str) -> list[str]:
    """The parameters of ``option`` that end in ``.path`` (``rms.calibration_s`` of ``extractor=phoneme`` for
    ``calibration_s``), sorted: the same setting one level down."""
    try:
        return sorted(k for k in option_keys(folder, kind).get(option, ()) if k.endswith("." + path))
    except Exception:  # a hint is a courtesy: never let it hide the error it explains
        return []


def _choices(owners: list[str], group: str) -> str:
    named = [f"{group}={o}" for o in owners]
    return named[0] if len(named) == 1 else ", ".join(named[:-1]) + " and " + named[-1]


def elsewhere(group: str, path: str, current: str | None, owners: list[str], explicit: bool = False,
              nested: list[str] = ()) -> str | None:
    """``group.path`` is unknown for ``group=current`` but ``owners`` have it: the line saying which and what
    to add (None if no other option has it).  ``explicit``: the user chose ``group=current`` on the command
    line (then the line says to switch rather than to add).  ``nested``: ``current``'s own parameters that end
    in ``.path`` (:func:`nested_in`), named first: the user may want those rather than another option."""
    owners = [o for o in owners if o != current]
    if not owners:
        return None
    if nested:
        keys = " or ".join(f"{group}.{k}" for k in nested)
        return (f"{group}.{path} is not a parameter of {group}={current}, which has {keys}; {group}.{path} is "
                f"a parameter of {_choices(owners, group)}")
    now = f", not of {group}={current}" if current else ""
    if explicit:
        todo = f"use {group}={owners[0]} instead" if len(owners) == 1 else "use one of them instead"
    else:
        todo = f"add {group}={owners[0]}" if len(owners) == 1 else f"add one of them, e.g. {group}={owners[0]}"
    return f"{group}.{path} is a parameter of {_choices(owners, group)}{now}: {todo}"


def without_group(key: str, value: str | None, current: dict[str, str], found: list[tuple[str, str]]) -> str | None:
    """A key given without its group (``mode=fast``, ``video.fps=10``) that ``found`` (group, option) pairs
    have: a line naming the group's key, or None.  ``current``: group -> the option chosen now."""
    if not found:
        return None
    group, option = found[0]
    setting = f"{group}.{key}" + (f"={value}" if value is not None else "")
    if current.get(group) == option:
        return f"there is no top-level parameter {key}; did you mean {setting}?"
    return (f"there is no top-level parameter {key}; {group}={option} has {group}.{key}: "
            f"write {group}={option} {setting}")


def under_output(path: str, options: dict[str, set], current) -> str:
    """``output.path`` is not a parameter: every output's parameters sit under a node of its own
    (``output.vmc.port``, ``output.plots.max_seconds``).  ``options``: output option -> its parameter paths
    (:func:`option_keys`); ``current``: the outputs chosen now (a name or a list of names).  The line names
    the full keys that end in ``path`` and the output to add, else the parameters of the chosen outputs."""
    if isinstance(current, str):  # Hydra shows a list of outputs as "[files, vmc]"
        current = current.strip("[]").split(",")
    chosen = {c.strip() for c in current or ()}
    found = sorted((o, k) for o, keys in options.items() for k in keys
                   if "." in k and k.split(".", 1)[1] == path)
    if found:
        mine = [(o, k) for o, k in found if o in chosen]   # an output chosen has it: that one's key only
        found = mine or found
        keys = " or ".join(f"output.{k}" for k in sorted({k for _, k in found}))
        owners = sorted({o for o, _ in found})
        add = "" if chosen & set(owners) else f" (with output={owners[0]})"
        return f"there is no parameter output.{path}: an output's parameters go under its name, {keys}{add}"
    valid = sorted(f"output.{k}" for o in chosen for k in options.get(o, ()) if "." in k)
    return f"unknown parameter output.{path}; valid: {', '.join(valid) or '(none)'}"


def unknown_in_node(key: str, compose) -> str | None:
    """``unknown parameter a.b.c: a.b takes x, y; did you mean a.b.y?`` for a key of no plugin group that its node in
    the configuration ``compose()`` gives (the command's group choices: the experiment's ``harness.corpus``) does
    not have; None when the node is not there or has the key (a sweep researcher's review:
    ``harness.corpus.seed=1,2`` said only "unknown parameter", where ``+harness.corpus.seed`` named ``seeds``)."""
    from omegaconf import DictConfig, OmegaConf

    from laughlab.core.errors import nearest

    head, _, last = key.rpartition(".")
    try:
        node = OmegaConf.select(compose(), head)
    except Exception:   # the listing is a courtesy
        return None
    if not isinstance(node, DictConfig) or last in node:
        return None
    keys = [str(k) for k in node]
    near = nearest(last, keys)
    return f"unknown parameter {key}: {head} takes {', '.join(keys)}" + (f"; did you mean {head}.{near}?" if near
                                                                          else "")
