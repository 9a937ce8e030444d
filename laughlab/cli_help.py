"""The command line's words to the user before a run: ``--help``'s text and the line for an unknown ``--flag``."""
from __future__ import annotations

import re

from laughlab.core.config import conf_dir
from laughlab.core.errors import LaughlabError

HELP_GROUPS = ("input", "extractor", "detector", "face", "body", "scheduler", "output", "experiment")
HELP_EXAMPLES = """\
examples:
  python -m laughlab                                        synthetic laughter, the thesis' pipeline
  python -m laughlab input=file input.path=LAUGH.wav face=facs body=hill extractor=pressure
  python -m laughlab input=mic output=vmc face=facs         live: an avatar over OSC (VMC)
  python -m laughlab output=video face=facs                 + video.mp4 of the character
  python -m laughlab output=gltf face=facs                  + character.glb (Blender, three.js, Unity)
  python -m laughlab view runs/demo                         the run on the character in a browser
  python -m laughlab view runs/demo --character my.vrm      ... on your VRM or humanoid glTF avatar
  python -m laughlab study build runs/stimuli               the stimuli's perception study (study --help)
  python -m laughlab experiment=energy_vs_concat hydra.run.dir=runs/evc; python -m laughlab report runs/evc
  python -m laughlab -m experiment=energy_ablation          a parameter sweep
  python -m laughlab corpus fetch                           the real corpus (openly licensed, by package)
  python -m laughlab detect talk.wav recordings/ --out laughs   laughter segments (TextGrid, Audacity, CSV)
  python -m laughlab plugins                                every plugin: where it comes from, how to use it
  python -m laughlab face=facs --cfg job                    print the composed config, run nothing
"""


def help_text(extra: dict | None = None) -> str:
    """``--help``: the groups and their options, examples, where the docs are (no Hydra, no plugins import).
    ``extra``: group -> the options a ``plugins_dir`` adds (``plugins_dir=PATH --help``; a plugin's sink is
    ``+output.NAME={}``)."""
    lines = ["usage: python -m laughlab [group=option ...] [key.path=value ...] [-m for a sweep]", "",
             "Audio-driven laughter animation: pick one plugin per group, set any parameter by its path.", "",
             "groups (default first; third-party plugins add options: python -m laughlab plugins; a folder of",
             "your own plugin modules: plugins_dir=PATH, docs/architecture.md 'Writing a plugin'; its",
             "experiment/NAME.yaml files are experiment=NAME, docs/experiments.md):"]
    defaults = {}
    for line in conf_dir().joinpath("config.yaml").read_text(encoding="utf-8").splitlines():
        m = re.match(r"\s+- (\w+): (\w+)", line)
        if m:
            defaults[m.group(1)] = m.group(2)
    for g in HELP_GROUPS:
        d = conf_dir().joinpath(g)
        names = sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".yaml")) if d.is_dir() else []
        first = defaults.get(g)
        names = ([first] if first in names else []) + [n for n in names if n != first]
        mine = [f"+output.{n}={{}}" if g == "output" else n for n in (extra or {}).get(g, ())]
        lines.append(f"  {g + ':':<12} {', '.join(names)}" + (f"; plugins_dir: {', '.join(mine)}" if mine else ""))
    packages = plugin_packages()
    if packages:   # a plugin author's review: --help named plugins_dir's plugins, not an installed package's
        lines.append(f"  installed plugin packages: {', '.join(packages)} (their plugins: python -m laughlab plugins)")
    from laughlab.core.install import clone_dir

    root = clone_dir()   # an installed wheel has no README.md or conf/ beside it (a packaging review)
    where = (f"{root}/README.md and the docs/ pages it links" if root else
             "the README.md and docs/ of laughlab's source repository (an installed package carries neither)")
    confs = f"{root}/conf" if root else str(conf_dir())
    lines += ["", HELP_EXAMPLES.rstrip(), "",
              f"docs: {where}",
              "(pipeline.md: outputs; experiments.md; papers.md: what each plugin implements; benchmarks.md);",
              f"parameters: each {confs}/<group>/<option>.yaml explains its own.",
              "Hydra's own flags: python -m laughlab --hydra-help"]
    return "\n".join(lines)


def plugin_packages() -> list[str]:
    """The installed distributions other than laughlab that add plugins (entry points of the group ``laughlab``),
    read from their metadata without importing them: ``--help`` stays quick."""
    from importlib.metadata import entry_points

    return sorted({ep.dist.name for ep in entry_points(group="laughlab")
                   if ep.dist is not None and ep.dist.name.lower() != "laughlab"})


def local_options(argv: list[str]) -> dict:
    """group -> the plugins and experiments a ``plugins_dir=`` among ``argv`` adds, for ``--help``."""
    from laughlab.core import config, own_experiments, plugins

    config.load_plugin_dirs(argv)
    out = {plugins.group_of(kind): sorted(n for n, info in named.items() if plugins.from_plugins_dir(info.origin))
           for kind, named in plugins.registry().items()}
    builtin = {p.name[:-5] for p in conf_dir().joinpath("experiment").glob("*.yaml")}
    out["experiment"] = [n for n in config.group_options("experiment") if n not in builtin
                         and plugins.from_plugins_dir(own_experiments.ORIGINS.get(n, ""))]   # not a package's
    return out


#: top-level keys a user may write as a --flag out of habit (--seed 3): the line says to write KEY=VALUE
_RUN_KEYS = ("seed", "fps", "overwrite", "progress", "character", "plugins_dir", "experiment")


def check_flags(argv: list[str], known: set[str]) -> None:
    """An argument starting with '-' that is not one of the ``known`` flags (Hydra's, -m) is refused in one line
    (it was dropped without a word and the default run started: --overwrite, --hlep)."""
    for a in argv:
        flag = a.split("=", 1)[0]
        if not a.startswith("-") or flag in known:
            continue
        key = flag.lstrip("-").replace("-", "_")
        if key in _RUN_KEYS:
            hint = f"write {key}=" + {"overwrite": "true", "seed": "N", "character": "PATH", "plugins_dir": "PATH",
                                      "experiment": "NAME"}.get(key, "VALUE")
        elif key in ("out", "outdir", "output_dir", "run_dir"):
            hint = "a run's folder is hydra.run.dir=PATH (--out is an option of view, detect and report)"
        else:
            hint = "a run takes overrides key=value (python -m laughlab --help)"
        raise LaughlabError(f"unknown option {flag!r}: {hint}")


#: Hydra's flags that show something instead of running (one configuration): Hydra refuses them beside -m with a
#: ValueError traceback ("Only one of --run, --multirun, --cfg, --info and --shell_completion can be specified")
_SHOW_FLAGS = ("--cfg", "-c", "--info", "-i", "--shell-completion", "-sc")


def check_sweep_flags(argv: list[str]) -> None:
    """``-m`` with a flag that shows one configuration (``--cfg hydra``) is refused in one line saying how to see
    a sweep's settings."""
    if not any(a in ("-m", "--multirun") for a in argv):
        return
    shown = next((a for a in argv if a.split("=", 1)[0] in _SHOW_FLAGS), None)
    if shown:
        raise LaughlabError(f"{shown} shows one configuration and does not combine with -m: drop -m and give each "
                            "swept key one value to see that point's (its hydra node, --cfg hydra, holds the "
                            "experiment's hydra.sweeper.params and the launcher)")
