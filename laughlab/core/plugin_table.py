"""``python -m laughlab plugins``: every plugin, where it comes from and how a run uses it."""
from __future__ import annotations

import re

from laughlab.core.config import GROUP_KINDS, conf_dir, outputs_writing


def list_plugins() -> None:
    """Print every plugin: kind, name, where it comes from and how a run chooses it (the plugin kind
    ``source`` is the config group ``input``; a sink is in the output options whose YAML names it)."""
    from laughlab.core import own_experiments, plugins

    header = ("kind", "name", "origin", "use with")
    rows = [(kind, name, info.origin, chosen_by(kind, name))
            for kind, named in plugins.registry().items() for name, info in named.items()]
    own_experiments.load_installed(conf_dir())   # experiments of a plugins_dir or a package (laughlab's own: --help)
    rows += [("experiment", name, own_experiments.ORIGINS.get(name, "?"),
              f"experiment={name}" + (" (cannot load: run it to see why)" if name in own_experiments.BAD else ""))
             for name in sorted(set(own_experiments.LOCAL) | set(own_experiments.BAD))]
    width = [max(len(r[i]) for r in rows + [header]) for i in range(3)]
    for row in [header, *rows]:
        print("  ".join(f"{v:<{w}}" for v, w in zip(row, width)) + "  " + row[3])


def chosen_by(kind: str, name: str) -> str:
    """How a run uses plugin ``kind/name``: ``input=file``, ``output=video`` (a sink: the output options
    that include it, its own first), ``every experiment`` (a metric)."""
    if kind == "metric":
        return "every experiment (harness)"
    group = next((g for g, k in GROUP_KINDS.items() if k == kind), None)
    if group is None:
        return ""
    if group != "output":   # its own option, and the presets of other names that run it (detector=yamnet_fused)
        presets = sorted(f.name[:-5] for f in conf_dir().joinpath(group).iterdir()
                         if f.name.endswith(".yaml") and f.name[:-5] != name
                         and re.search(rf"^(name: *{re.escape(name)}|  - {re.escape(name)}) *$",
                                       f.read_text(encoding="utf-8"), re.M))
        return f"{group}={name}" + (f" (also {', '.join(f'{group}={p}' for p in presets)})" if presets else "")
    return outputs_writing(name)
