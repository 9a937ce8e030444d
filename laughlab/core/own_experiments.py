"""Experiments that are not laughlab's: a ``plugins_dir``'s ``experiment/NAME.yaml`` files and the YAML files an
installed package registers (``register_experiments``, :mod:`laughlab.core.hookspecs`).

Each file becomes the option ``experiment=NAME`` (its file's stem), written as ``conf/experiment/``'s are
(``# @package _global_``, a ``defaults`` list, a ``harness`` node) and starting from :func:`base`, so an
experiment of one's own needs no copy of laughlab's configs (docs/experiments.md).  A file that cannot be one is
kept with its reason, said only when that experiment is asked for (a review: one bad file stopped every run with
the folder, naming the bad file whatever was asked).
"""
from __future__ import annotations

from pathlib import Path

from laughlab.core.errors import first_line

#: experiments not laughlab's: name -> file
LOCAL: dict[str, Path] = {}
#: where each came from, for ``python -m laughlab plugins``: name -> origin
ORIGINS: dict[str, str] = {}
#: experiments that cannot be loaded: name -> the line that says why
BAD: dict[str, str] = {}
_loaded_installed = False


def base(name: str, conf) -> dict:
    """The ``harness`` an experiment of one's own starts from: ``conf/experiment/smoke.yaml``'s shared settings (its
    corpus, seeds, jobs, plots...), named ``name``, with no conditions, module or showcase.  Its YAML gives what
    differs, and the command line can set every one of them (``harness.jobs=4``), as for a built-in experiment,
    which spells them all out.  ``conf``: laughlab's config folder (:func:`laughlab.core.config.conf_dir`)."""
    from omegaconf import OmegaConf

    smoke = OmegaConf.to_container(OmegaConf.load(conf.joinpath("experiment", "smoke.yaml")).harness)
    return {**smoke, "name": name, "module": None, "conditions": None, "showcase": None}


def load_folder(folder: Path, conf) -> None:
    """Each ``NAME.yaml`` in a plugins_dir's ``experiment/`` folder as ``experiment=NAME``."""
    from laughlab.core import plugins

    if folder.is_dir():
        for file in sorted(folder.glob("*.yaml")):
            load_file(file, plugins.plugins_dir_origin(file), conf)


def forget_plugins_dirs() -> None:
    """Forget every plugins_dir's experiments, as a process' end would (a ``plugins_dir`` of the tests' in-process
    commands left its ``smoke.yaml`` refused, and every later ``experiment=smoke`` in that process with it)."""
    from hydra.core.config_store import ConfigStore

    from laughlab.core.plugins import from_plugins_dir

    stored = ConfigStore.instance().repo.get("experiment", {})
    for name in [n for n, origin in ORIGINS.items() if from_plugins_dir(origin)]:
        for table in (LOCAL, ORIGINS, BAD):
            table.pop(name, None)
        stored.pop(f"{name}.yaml", None)


def load_installed(conf) -> None:
    """The experiment files the installed packages register (once a process)."""
    global _loaded_installed
    if _loaded_installed:
        return
    _loaded_installed = True
    from laughlab.core import plugins

    plugins.load_entry_points()
    for impl in plugins.pm.hook.register_experiments.get_hookimpls():
        found = plugins.collect(impl, "register_experiments")
        origin = plugins.origin_of(impl.plugin)
        for file in found:
            file = Path(str(file))
            if file.suffix != ".yaml" or not file.is_file():
                ORIGINS[file.stem] = origin
                BAD[file.stem] = (f"experiment file {file} registered by {origin} is not a .yaml file that exists: "
                                  "register the path of a YAML file the package ships (docs/experiments.md)")
                continue
            load_file(file, origin, conf)


def load_file(file: Path, origin: str, conf) -> None:
    """``file`` as ``experiment=NAME`` (``NAME``: its stem), or the reason it cannot be in :data:`BAD`."""
    from hydra.core.config_store import ConfigStore

    from laughlab.core.plugins import from_plugins_dir

    name = file.stem
    if LOCAL.get(name) == file.resolve():
        return
    if name in LOCAL and not (from_plugins_dir(origin) and from_plugins_dir(ORIGINS[name])):
        # a package's and a folder's, or two packages': the command could not say which it ran (another
        # plugins_dir's in the same process, the tests', replaces it, as one process loads one folder)
        BAD[name] = (f"two experiments are named {name!r}: {LOCAL[name]} ({ORIGINS[name]}) and {file} ({origin}); "
                     "rename one")
        return
    node, why = _node(file, conf)
    LOCAL[name], ORIGINS[name] = file.resolve(), origin
    if why:
        BAD[name] = f"{file}: {why}"
        return
    BAD.pop(name, None)
    ConfigStore.instance().store(group="experiment", name=name, node=node, package="_global_")


def _node(file: Path, conf):
    """(the experiment's configuration, None) or (None, why it is not one)."""
    from omegaconf import OmegaConf

    name = file.stem
    if conf.joinpath("experiment", file.name).is_file():
        return None, f"laughlab has an experiment named {name!r}; give yours another name"
    try:
        node = OmegaConf.load(file)
    except Exception as exc:   # a YAML error: what and where
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        what = getattr(exc, "problem", None) or first_line(exc)
        return None, f"not a readable experiment: {what}{where}"
    if not OmegaConf.is_dict(node) or not OmegaConf.is_dict(node.get("harness")):
        return None, ("not an experiment: it needs a harness: mapping of settings (docs/experiments.md, "
                      "'An experiment of your own')")
    given = node.harness.get("name")
    if given is not None and given != name:
        return None, (f"harness.name {given!r} is not the file's name: an experiment's name is its file's "
                      f"({name}); remove harness.name or rename the file")
    return OmegaConf.merge({"harness": base(name, conf)}, node), None
