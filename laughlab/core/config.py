"""Composing the configuration: Hydra's config module, the plugin groups, plugins without YAML files.

The CLI, the experiment runner and the tests compose configurations through here, so the
harness never imports the command line.
"""
from __future__ import annotations

import re
from pathlib import Path

from laughlab.core.errors import LaughlabError, nearest
from laughlab.core.overrides import one_choice_each, override_key
from laughlab.core.overridehints import launcher_missing, unreadable_override
from laughlab.core import own_experiments


def _register_resolvers() -> None:
    """``${div:a,b}`` for configs that tie one parameter to another (e.g. fall = rise / 2)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver("div"):
        OmegaConf.register_new_resolver("div", lambda a, b: float(a) / float(b))


_register_resolvers()

CONFIG_MODULE = "laughlab_conf"
GROUP_KINDS = {"input": "source", "extractor": "extractor", "face": "face", "body": "body",
               "scheduler": "scheduler", "output": "sink",
               "detector": "detector"}


def conf_dir():
    from importlib.resources import files

    return files(CONFIG_MODULE)


def outputs_writing(sink: str) -> str:
    """The ``output=`` options whose YAML names sink ``sink``: ``output=files (also gltf, video, vrma)`` (its own
    option first, then the default), or ``+output.NAME={}`` when none does."""
    options = []
    for f in sorted(conf_dir().joinpath("output").iterdir(), key=lambda f: f.name):
        if f.name.endswith(".yaml") and f.name != "trial.yaml" and re.search(
                rf"^{re.escape(sink)}:", f.read_text(encoding="utf-8"), re.M):   # trial: the harness' own
            options.append(f.name[:-5])
    options.sort(key=lambda o: (o != sink, o != "files", o))
    if not options:
        return f"+output.{sink}={{}}"
    return f"output={options[0]}" + (f" (also {', '.join(options[1:])})" if options[1:] else "")


def group_options(group: str) -> list[str]:
    """Names selectable in a config group: YAML files plus registered plugins."""
    names = {p.name[:-5] for p in conf_dir().joinpath(group).iterdir() if p.name.endswith(".yaml")} \
        if conf_dir().joinpath(group).is_dir() else set()
    if group in GROUP_KINDS and group != "output":
        from laughlab.core import plugins

        names |= set(plugins.registry()[GROUP_KINDS[group]])
    if group == "experiment":   # a plugins_dir's and the installed packages'
        own_experiments.load_installed(conf_dir())
        names |= set(own_experiments.LOCAL)
    return sorted(names)


def load_plugin_dirs(overrides) -> None:
    """Load the plugins of every ``plugins_dir=PATH`` among ``overrides`` (before their configs can compose):
    the command line's single runs, sweeps and ``--cfg``, and an experiment's trial workers, which compose their
    own configuration in processes of their own (a review: ``face=NAME`` of a plugins_dir plugin was unknown there)."""
    from laughlab.core import plugins
    from laughlab.core.localpackage import plugins_dir_changed

    one_plugins_dir(overrides)
    for ov in overrides:
        key, _, value = str(ov).partition("=")
        value = unquoted(value)
        if override_key(key) == "plugins_dir" and value and value != "null":
            if Path(value).expanduser().is_dir() and plugins_dir_changed(value):   # another folder: the earlier
                own_experiments.forget_plugins_dirs()   # one's experiments go with it
            plugins.load_plugin_dir(value)
            own_experiments.load_folder(Path(value).expanduser() / "experiment", conf_dir())


def unquoted(value: str) -> str:
    """A value as Hydra reads it: ``plugins_dir='my plugins'`` is the folder ``my plugins`` (a review: the quotes
    Hydra asks for around a path with spaces stayed part of the folder's name, which was then not found)."""
    if len(value) < 2 or value[0] != value[-1] or value[0] not in "'\"":
        return value
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        return str(OverridesParser.create().parse_override(f"k={value}").value())
    except Exception:   # noqa: BLE001 - not Hydra's quoting after all: the value as typed
        return value


def one_plugins_dir(overrides) -> None:
    """``plugins_dir`` is one folder: given twice, each would load, but a run and its trial workers keep only the
    last (a review), and ``python -m laughlab plugins`` listed both (another)."""
    dirs = [str(ov) for ov in overrides if str(ov).split("=")[0].lstrip("+") == "plugins_dir"]
    if len(dirs) > 1:
        raise LaughlabError(f"plugins_dir is given {len(dirs)} times ({', '.join(dirs)}): it is one folder; put every "
                            "plugin module and experiment/ in it")


def register_plugin_configs() -> None:
    """Give every registered plugin without a YAML file a config group option.

    Third-party plugins then work as ``extractor=NAME`` with their dataclass defaults.
    """
    from dataclasses import is_dataclass

    from hydra.core.config_store import ConfigStore

    from laughlab.core import config_files, plugins

    config_files.install()   # before Hydra composes (a run, a sweep's checks, its basic launcher's jobs)
    cs = ConfigStore.instance()
    reg = plugins.registry()
    for group, kind in GROUP_KINDS.items():
        if group == "output":
            continue
        folder = conf_dir().joinpath(group)
        have = {p.name[:-5] for p in folder.iterdir()} if folder.is_dir() else set()
        for name, info in reg[kind].items():
            if name in have:
                continue
            params_cls = getattr(info.obj, "Params", None)
            node = {"name": name}
            if params_cls is not None and is_dataclass(params_cls):
                node.update(_defaults(params_cls))
            cs.store(group=group, name=name, node=node)
    own_experiments.load_installed(conf_dir())   # and the experiments the installed packages register


def _defaults(params_cls) -> dict:
    """A plugin's parameters as its config node: each field's default, and OmegaConf's ``???`` for a field with
    none, so that a run without it says "face.gain is required: set face.gain=VALUE" (a plugin author's review:
    ``gain: float`` with no default stopped every command, the plugin's own runs too, with a traceback)."""
    from dataclasses import MISSING, asdict, fields, is_dataclass

    try:
        return asdict(params_cls())
    except TypeError:   # a field without a default
        out = {}
        for f in fields(params_cls):
            value = f.default if f.default is not MISSING else \
                f.default_factory() if f.default_factory is not MISSING else "???"
            out[f.name] = asdict(value) if is_dataclass(value) and not isinstance(value, type) else value
        return out


def composition_error(exc: Exception, overrides: list[str] = ()) -> str:
    text = str(exc)
    m = re.search(r"Could not override '([^']+)'", text)
    if m:
        key = m.group(1)
        group = key.split(".")[0]
        hint = _misplaced(key, overrides)
        if hint:
            return hint
        valid = ""
        if group in GROUP_KINDS and group != "output" and "." in key:
            try:
                keys = valid_keys(group, overrides)
                head, _, last = key.rpartition(".")
                near = nearest(last, keys)
                hint = f" (did you mean {head}.{near}?)" if near and near != last else ""
                valid = (hint + "; valid: " + ", ".join(keys) if keys else f"; this {group} takes no parameters")
            except Exception:  # listing the keys is a courtesy
                valid = ""
        given = next((o.split("=", 1)[1] for o in overrides if o.split("=", 1)[0] == key), "")
        if key == "harness.conditions" and given.startswith("{"):   # a mapping merged into the experiment's
            return (f"{key}={given} would merge into the experiment's conditions, which takes no new names: replace "
                    f"them with '~{key}' \"+{key}={given}\", or add one with \"+{key}.NAME=['face=facs']\" "
                    "(docs/experiments.md)")
        if key.startswith("hydra.launcher."):   # the basic launcher has no n_jobs (a review)
            return (f"unknown parameter {key} of this launcher; Hydra's basic launcher runs one job at a time, "
                    f"hydra/launcher=joblib takes n_jobs")
        if "." in key and group not in (*GROUP_KINDS, "hydra"):   # harness.corpus.seed=1: its node's keys
            from laughlab.core.keyhints import unknown_in_node

            named = unknown_in_node(key, lambda: compose_config([o for o in overrides if is_group(override_key(o))]))
            if named:
                return named
        if "." not in key and group not in GROUP_KINDS:   # a top-level key mistyped: the nearest one (sed=3)
            near = _nearest_top_level(key)
            if near:
                return f"unknown parameter {key}; did you mean {near}?"
            # none near: the settings there are, and the groups (a review: 'unknown parameter bogus' said no more)
            settings = ", ".join(k for k in _top_level_keys() if k not in (*GROUP_KINDS, "hydra"))
            valid = (f"; the settings are {settings}, the groups {', '.join(GROUP_KINDS)}, and experiment=NAME "
                     "(python -m laughlab --help)")
        return f"unknown parameter {key}{valid}"
    m = re.search(r"Could not append to config\. An item is already at '([^']+)'", text)
    if m:   # +output.plots.width=column: Hydra's line spoke of appending (the top-level keys: check_overrides)
        given = next((o for o in overrides if o.startswith("+") and override_key(o) == m.group(1)), None)
        if given:
            return already_a_setting(m.group(1), given)
    unreadable = unreadable_override(text, overrides)
    if unreadable:  # Hydra's override grammar reads only plain ASCII values unquoted (a path with é or a space)
        return unreadable
    m = re.search(r"Ambiguous value for argument '([^=']+)=([^']*)'", text)
    if m:  # Hydra's three numbered lines, as one: a comma is a sweep (-m), or a list in brackets
        key, value = m.groups()
        if key == "output":
            return (f"output={value}: several outputs are a list, write 'output=[{value}]' (quoted for the shell); "
                    f"without brackets a comma means a sweep (-m)")
        as_list = f"for a list write '{key}=[{value}]'" if not _one_value(key, overrides) else f"{key} takes one value"
        return (f"{key}={value} gives several values: to run each, add -m (a sweep: python -m laughlab -m "
                f"{key}={value}); {as_list}; one value with a comma in it is quoted: \"{key}='{value}'\"")
    m = re.match(r"Error merging override (\S+)", text)
    if m and exc.__cause__ is not None:   # Hydra's line names the override, its cause says what is wrong with it
        cause = str(exc.__cause__).strip().splitlines()
        return f"bad setting {m.group(1)}: {cause[0]}" if cause else text
    m = re.search(r"Could not find '(input|extractor|detector|face|body|scheduler|output|experiment)/([^']+)'", text)
    if m:  # a defaults list naming a plugin that does not exist (an experiment's ``override /extractor: nosuch``)
        group, name = m.groups()
        return (f"unknown {group} {name!r} in a defaults list (an experiment's override /{group}); choose one of: "
                f"{', '.join(group_options(group))}")
    m = re.search(r"Could not find 'hydra/launcher/([^']+)'", text)
    if m:  # Hydra's line says nothing of where a launcher comes from
        return launcher_missing(m.group(1))
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[0] if lines else type(exc).__name__


def _one_value(key: str, overrides: list[str]) -> bool:
    """Is ``key`` a parameter that takes one number, string or flag (``seed``, ``output.vmc.host``, ``input.path``)?
    Then a list in brackets is no way to give it several (a game-developer review: for two VMC receivers the line
    said to write 'output.vmc.host=[A,B]', which failed on OmegaConf's "Cannot convert 'ListConfig' to string")."""
    from dataclasses import fields, is_dataclass

    from laughlab.core import plugins

    scalar = {"str", "int", "float", "bool", str, int, float, bool}
    parts = override_key(key).split(".")
    try:
        if len(parts) == 1:   # a run's own parameter (seed, fps): its default's type
            from hydra import compose

            choices = [o for o in overrides if override_key(o) in (*GROUP_KINDS, "experiment")]
            return type(compose("config", overrides=choices).get(parts[0])) in scalar
        if parts[0] == "output" and len(parts) == 3:
            params, name = plugins.get("sink", parts[1]).obj.Params, parts[2]
        elif parts[0] in GROUP_KINDS and parts[0] != "output" and len(parts) == 2:
            params, name = plugins.get(GROUP_KINDS[parts[0]], chosen(overrides)[parts[0]]).obj.Params, parts[1]
        else:
            return False
    except Exception:  # a hint is a courtesy: unknown, keep the list's
        return False
    found = [f for f in fields(params) if f.name == name] if is_dataclass(params) else []
    return bool(found) and found[0].type in scalar


def _owners(group: str, path: str) -> list[str]:
    """The options of ``group`` that have the parameter ``path`` (:mod:`laughlab.core.keyhints`)."""
    from laughlab.core import keyhints

    kind = GROUP_KINDS.get(group) if group != "output" else None
    return keyhints.options_with(conf_dir().joinpath(group), kind, path)


def misplaced_parameter(group: str, current: str, key: str, explicit: bool = False) -> str | None:
    """``group.key`` is not a parameter of ``group=current``: the line naming the options that have it."""
    from laughlab.core import keyhints

    kind = GROUP_KINDS.get(group) if group != "output" else None
    nested = keyhints.nested_in(conf_dir().joinpath(group), kind, current, key)
    return keyhints.elsewhere(group, key, current, _owners(group, key), explicit, nested)


def _nearest_top_level(key: str) -> str | None:
    """The configuration's top-level key or group nearest ``key`` (:func:`~laughlab.core.errors.nearest`)."""
    # experiment: a group of its own, not a plugin's (a review: experimnt=smoke got no "did you mean")
    return nearest(key, [k for k in _top_level_keys() if k != "hydra"] + list(GROUP_KINDS) + ["experiment"])


def _plugin_sink_key(rest: str, overrides: list[str]) -> str | None:
    """``output.NAME.KEY`` of a plugin's sink with no output option (``conf/output/NAME.yaml``): its node is not
    in the configuration until ``+`` adds it, so a parameter is set as ``+output.NAME.KEY=V`` (a review: the line
    listed the plots' parameters as the valid ones)."""
    from laughlab.core import keyhints, plugins

    sink, _, param = rest.partition(".")
    if not param or conf_dir().joinpath("output", f"{sink}.yaml").is_file() \
            or sink not in plugins.registry()["sink"]:
        return None
    outputs = keyhints.option_keys(conf_dir().joinpath("output"), None).values()
    if any(k == sink or k.startswith(sink + ".") for keys in outputs for k in keys):
        return None   # a sink the outputs list (output.plots.KEY): not a plugin's (a review: it said so)
    value = next((o.split("=", 1)[1] for o in overrides if o.lstrip("+").split("=", 1)[0] == f"output.{rest}"), "V")
    return (f"output.{sink} is a plugin's sink, which has no output option: its parameters are added with +, "
            f"+output.{rest}={value} (that also adds the sink)")


def _misplaced(key: str, overrides: list[str]) -> str | None:
    """An unknown ``key`` that another option of its group has (``scheduler.mode`` under scheduler=energy),
    or that a group has when given without the group (``mode=fast``): the line saying what to write."""
    from laughlab.core import keyhints

    try:
        choices = chosen(overrides)
    except Exception:  # a hint is a courtesy
        return None
    group, _, rest = key.partition(".")
    if group in GROUP_KINDS and rest:
        explicit = any(override_key(o) == group for o in overrides)
        hint = misplaced_parameter(group, choices.get(group), rest, explicit)
        if hint is None and group == "output":
            hint = _plugin_sink_key(rest, overrides)
        if hint is None and group == "output":
            # an output's parameters sit under its name (output.vmc.port): say which outputs have this one
            options = keyhints.option_keys(conf_dir().joinpath("output"), None)
            given = next((o.split("=", 1)[1] for o in overrides if o.split("=", 1)[0] == "output"), None)
            hint = keyhints.under_output(rest, options, choices.get("output") or given)  # a list: not a choice
        return hint
    if group not in GROUP_KINDS and group not in ("hydra", "harness", "experiment"):
        value = next((o.split("=", 1)[1] for o in overrides if override_key(o) == key), None)
        found = [(g, o) for g in keyhints.SEARCHED for o in _owners(g, key)]
        return keyhints.without_group(key, value, choices, found)
    return None


def chosen(overrides: list[str]) -> dict[str, str]:
    """Group -> the option the user's group choices (and the defaults) select."""
    from hydra import compose

    choices = [o for o in overrides if "=" in o and "." not in override_key(o)
               and override_key(o) in (*GROUP_KINDS, "experiment")]
    cfg = compose("config", overrides=choices, return_hydra_config=True)
    return {g: str(v) for g, v in cfg.hydra.runtime.choices.items() if g in GROUP_KINDS and v is not None}


def valid_keys(group: str, overrides: list[str]) -> list[str]:
    """Parameter names of the plugin chosen for ``group`` (with the user's group choices)."""
    from dataclasses import fields

    from laughlab.core import plugins

    info = plugins.get(GROUP_KINDS[group], chosen(overrides)[group])
    return [f.name for f in fields(info.obj.Params)]


def compose_config(overrides: list[str], job_name: str = "app"):
    """Compose the configuration as Hydra would, turning errors into LaughlabError."""
    from hydra import compose, initialize_config_module

    one_choice_each(overrides, [g for g in GROUP_KINDS if g != "output"])   # output: sinks, a list

    from laughlab.core import config_files
    from laughlab.core.callerstate import their_hydra

    config_files.install()
    with their_hydra(), initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3", job_name=job_name):
        try:
            return compose("config", overrides=overrides, return_hydra_config=True)
        except Exception as exc:
            if isinstance(exc, LaughlabError):
                raise
            raise LaughlabError(composition_error(exc, overrides)) from None


#: compositions of the config-group choices (Hydra's slow part), by the choices and the registered plugins
_COMPOSED: dict = {}
#: the top-level nodes a run never gets: Hydra's own and the experiment's
NOT_IN_A_RUN = ("hydra", "harness")


def reaches_run(key: str) -> bool:
    """Does an override of ``key`` (``seed``, ``+input.path``, ``harness.jobs``) reach a run's configuration?"""
    return override_key(key).split(".")[0] not in NOT_IN_A_RUN


def is_group(key: str) -> bool:
    """Does an override's key name a config group (``detector``, ``hydra/launcher``), not a value
    (``seed``, ``input.path``)?  Groups are the config module's folders and the ConfigStore's groups."""
    if "." in key:
        return False
    if key.split("/")[0] == "hydra":
        return True
    from hydra.core.config_store import ConfigStore

    node = ConfigStore.instance().repo
    for part in key.split("/"):
        node = node.get(part) if isinstance(node, dict) else None
    return isinstance(node, dict) or conf_dir().joinpath(key).is_dir()


def compose_app(overrides) -> "DictConfig":  # noqa: F821
    """``compose_config(overrides)`` without its ``hydra`` node, as a run uses it; composed once per set
    of config-group choices in a process.

    Hydra composes the defaults list from the group overrides, then applies the value overrides in
    order to the result (``ConfigLoaderImpl._apply_overrides_to_config``).  This does the same with
    the group composition kept: an experiment's trials differ in their input's values and seed, and
    Hydra's composition takes 0.25-0.3 s a trial on a 2-core machine (a copy takes 0.02 s).  The result
    equals a fresh composition's (``tests/test_config.py`` compares them over experiments' trials)."""
    import copy

    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    from laughlab.core import plugins

    overrides = list(overrides)
    load_plugin_dirs(overrides)
    register_plugin_configs()
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except Exception as exc:
        raise LaughlabError(composition_error(exc, overrides)) from None
    grouped = [is_group(p.key_or_group) for p in parsed]
    groups = [p.input_line for p, g in zip(parsed, grouped) if g]
    values = [p for p, g in zip(parsed, grouped) if not g and reaches_run(p.key_or_group)]
    key = (tuple(groups), tuple((kind, tuple(sorted(reg))) for kind, reg in sorted(plugins.registry().items())))
    base = _COMPOSED.get(key)
    if base is None:
        full = compose_config(groups)
        base = OmegaConf.masked_copy(full, [k for k in full if k not in NOT_IN_A_RUN])
        _COMPOSED[key] = base
    cfg = copy.deepcopy(base)
    flag = OmegaConf.is_struct(cfg)      # None on the masked copy (inherit), as Hydra's result gives it
    OmegaConf.set_struct(cfg, True)      # as Hydra applies them: a value override cannot add a key
    try:
        ConfigLoaderImpl._apply_overrides_to_config(values, cfg)
    except Exception as exc:
        raise LaughlabError(composition_error(exc, overrides)) from None
    OmegaConf.set_struct(cfg, flag)      # then as the masked copy of Hydra's result has it
    return cfg


def _top_level_keys() -> tuple[str, ...]:
    """The settings at the top of ``config.yaml`` (``seed``, ``fps``, ``character``...), in the file's order."""
    import yaml

    doc = yaml.safe_load(conf_dir().joinpath("config.yaml").read_text(encoding="utf-8")) or {}
    return tuple(k for k in doc if k != "defaults")


def already_a_setting(key: str, given: str) -> str:
    """The line for ``+KEY=V`` (``given``) on a key the configuration already has, top-level or nested."""
    return f"{key} is already a setting: write {given.lstrip('+')} (without +)"


def given_twice(overrides: list[str]) -> list[str]:
    """A line for each plugin group chosen twice (``output=gltf output=vrma``): Hydra keeps the last, and the first
    was dropped without a word (a new-user review lost its ``character.glb`` so).  The last still wins, as Hydra
    documents and scripts use (a base command with a choice changed after it); a value given twice (``fps=30
    fps=60``) is Hydra's rule alone and gets no line.  Only plain ``GROUP=OPTION`` overrides are compared."""
    seen: dict[str, str] = {}
    lines = []
    for ov in overrides:
        key, sep, value = ov.partition("=")
        if not sep or ov[:1] in "+~" or key not in (*GROUP_KINDS, "experiment"):
            continue
        if key in seen and seen[key] != value:
            lines.append(f"laughlab: {key}= is given twice ({seen[key]}, then {value}): {value} is used"
                         + (f"; for both outputs: '{key}=[{seen[key]},{value}]'" if key == "output" else ""))
        seen[key] = value
    return lines


def check_overrides(overrides: list[str]) -> None:
    """Unknown group options raise :class:`LaughlabError` with the list of valid ones; so does ``+KEY=...`` for a
    key no part of laughlab reads (``+fsp=30``, a typo of ``fps``, was added and ignored)."""
    from laughlab.core import plugins

    one_plugins_dir(overrides)
    for ov in overrides:
        key = override_key(ov)
        root = re.split(r"[./]", key)[0]
        if ov.startswith("+") and root not in (*GROUP_KINDS, "experiment", "hydra", "harness"):
            if root in _top_level_keys():
                if not ov.startswith("++"):
                    raise LaughlabError(already_a_setting(root, ov))
            else:
                raise LaughlabError(f"unknown setting {key!r}: + adds a key that nothing reads; python -m laughlab "
                                    "--help lists the settings")
        m = re.fullmatch(r"\+?([a-z_]+)=(.*)", ov)
        if not m or m.group(1) not in (*GROUP_KINDS, "experiment"):
            continue
        group, value = m.groups()
        choices, options = [v.strip() for v in value.strip("[]").split(",")], group_options(group)
        if value in ("", "null") or ov[:1] == "+":   # Hydra's lines for these spoke of its own syntax (a review)
            raise LaughlabError(f"write {ov[1:]} without +: {group} is in the defaults already" if ov[:1] == "+"
                                else f"{group}={value} needs an option: choose one of: {', '.join(options)}")
        for choice in choices:
            if group == "experiment" and choice in own_experiments.BAD:
                raise LaughlabError(own_experiments.BAD[choice])
            if choice not in options:
                own = (f" (an experiment of your own: plugins_dir=DIR with DIR/experiment/{choice}.yaml)"
                       if group == "experiment" else "")
                # a sink's name (output=bvh): the outputs that write it (a review: "registered as a sink" said no more)
                hint = (f" ({choice!r} is a sink, written by {outputs_writing(choice)})"
                        if choice in plugins.registry()["sink"] else plugins.other_kind_hint(choice))
                raise LaughlabError(f"unknown {group} {choice!r}; choose one of: {', '.join(options) or '(none)'}"
                                    f"{hint}{own}")
