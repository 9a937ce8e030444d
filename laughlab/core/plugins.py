"""Plugin manager and registry (the pattern of simonw/llm and tox).

Plugins come from three places, all through the same hooks:

* the ``laughlab`` entry-point group (built-ins and installed third-party packages);
* a folder of plugin modules given by path (``plugins_dir=...`` or
  :func:`load_plugin_dir`), like datasette's plugins directory;
* objects registered in code with ``pm.register(obj)`` (tests do this).
"""
from __future__ import annotations

import functools
import importlib.util
import math
import sys
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any

import pluggy
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from laughlab.core import hookspecs
from laughlab.core.errors import LaughlabError, UnknownParameter, nearest, shown_path
from laughlab.core.localpackage import LOCAL_PACKAGE, forget_if_changed, local_package

hookimpl = pluggy.HookimplMarker("laughlab")

#: plugin kind -> the hook that registers it
KINDS: dict[str, str] = {
    "source": "register_sources",
    "extractor": "register_extractors",
    "detector": "register_detectors",
    "face": "register_faces",
    "body": "register_bodies",
    "scheduler": "register_schedulers",
    "sink": "register_sinks",
    "metric": "register_metrics",
}

pm = pluggy.PluginManager("laughlab")
pm.add_hookspecs(hookspecs)
_loaded_entry_points = False
_EP_ORIGINS: dict[str, str] = {}  # entry-point plugin name -> "distribution version (entry point)"


@dataclass(frozen=True)
class PluginInfo:
    """One registered plugin: its kind, name, class and where it comes from."""

    kind: str
    name: str
    obj: Any
    origin: str


def load_entry_points() -> None:
    """Load every plugin of the ``laughlab`` entry-point group (once)."""
    global _loaded_entry_points
    if not _loaded_entry_points:
        _loaded_entry_points = True
        from importlib.metadata import entry_points

        for ep in entry_points(group="laughlab"):
            if pm.get_plugin(ep.name) is not None or pm.is_blocked(ep.name):
                continue
            try:
                plugin = ep.load()
            except Exception as exc:  # one broken plugin: say which, where and how to get laughlab back, no traceback
                dist = f"{ep.dist.metadata['name']}" if ep.dist else None
                fix = (f"; every laughlab command loads the installed plugins: mend it, or pip uninstall {dist}"
                       if dist else "")
                raise LaughlabError(f"plugin {ep.name} ({ep.value}{f', from {dist} {ep.dist.version}' if dist else ''}) "
                                    f"failed to load: {type(exc).__name__}: {exc}{_raised_at(exc)}{fix}") from exc
            if isinstance(plugin, type(sys)):   # a module: the hook checks of a plugins_dir module (a review: a
                _check_hooks(plugin, f"{ep.name} ({ep.value})")   # misspelt hook in a package was ignored)
            pm.register(plugin, name=ep.name)
            dist = ep.dist
            _EP_ORIGINS[ep.name] = f"{dist.metadata['name']} {dist.version} (entry point)" if dist else "entry point"


def load_plugin_dir(path: str | Path) -> list[str]:
    """Import every ``*.py`` module in ``path`` and register it as a plugin.

    Returns the names of the modules loaded.  Raises LaughlabError if the folder
    does not exist or a module fails to import.
    """
    folder = Path(path).expanduser()
    if not folder.is_dir():
        more = " (plugins_dir is one folder: put every plugin module and experiment/ in it)" \
            if str(path).startswith("[") else ""
        raise LaughlabError(f"plugins_dir {str(path)!r} is not a folder{more}")
    loaded = []
    forget_if_changed(folder, pm)
    local_package(folder)
    _warn_group_files(folder)
    from laughlab.core import background

    background.local_package(folder)   # the helper process unpickles a background sink of the folder by name
    for file in sorted(folder.glob("*.py")):
        mod_name = f"{LOCAL_PACKAGE}.{file.stem}"
        if pm.get_plugin(mod_name) is not None:
            continue
        module = sys.modules.get(mod_name)   # already imported by a sibling module (from .helpers import x)
        if module is None:
            spec = importlib.util.spec_from_file_location(mod_name, file)
            module = importlib.util.module_from_spec(spec)
            sys.modules[mod_name] = module  # before executing: dataclasses look their module up there
            try:
                spec.loader.exec_module(module)
            except Exception as exc:  # a broken user plugin is a user error
                sys.modules.pop(mod_name, None)
                raise LaughlabError(f"plugin {file} failed to import: {type(exc).__name__}: {exc}"
                                    f"{_raised_at(exc)}") from exc
        try:
            _check_hooks(module, file)
            pm.register(module, name=mod_name)
        except pluggy.PluginValidationError as exc:   # e.g. register_faces(reg): a hook argument not named as specified
            del sys.modules[mod_name]
            raise LaughlabError(f"plugin {file}: {' '.join(str(exc).split())}") from None
        except LaughlabError:
            del sys.modules[mod_name]
            raise
        loaded.append(mod_name)
    return loaded


_GROUP_FILES_SAID: set = set()


def _warn_group_files(folder: Path) -> None:
    """One warning (once a process) for config files in a plugins_dir's group folders (``body/sway.yaml``, the
    Hydra way): they are not read, only ``experiment/*.yaml`` is; a plugin's defaults are its ``Params`` (a plugin
    author's review: such a file was ignored, silently)."""
    files = sorted(str(f.relative_to(folder)) for g in (*_GROUPS, "output") for f in (folder / g).glob("*.yaml"))
    if files and str(folder) not in _GROUP_FILES_SAID:
        _GROUP_FILES_SAID.add(str(folder))
        print(f"laughlab: warning: {', '.join(files[:3])}{' ...' if len(files) > 3 else ''} in plugins_dir {folder} "
              "not read: a plugin's defaults are its Params dataclass (set them as GROUP.KEY=VALUE or in an "
              "experiment/NAME.yaml, the one kind of config file a plugins_dir holds)", file=sys.stderr)


def _raised_at(exc: BaseException) -> str:
    """`` (at FILE, line N)``: where a plugin module's import failed, the innermost line of the plugin's own folder
    (a plugin authors' review: the line named the module and the error, not the line to mend; not a line of
    Python's import machinery or of numpy); a SyntaxError's own place says it already."""
    import sysconfig

    if isinstance(exc, SyntaxError):
        return ""
    tb = exc.__traceback__
    stdlib, root, at, tb = sysconfig.get_paths()["stdlib"], None, "", tb and tb.tb_next   # not the catching frame
    while tb is not None:
        name = tb.tb_frame.f_code.co_filename
        if not name.startswith("<") and not name.startswith(stdlib):
            root = root or str(Path(name).parent)   # the plugin module's own folder: its first line of its own
            if name.startswith(root):
                at = f" (at {name}, line {tb.tb_lineno})"
        tb = tb.tb_next
    return at


def _check_hooks(module, file: Path | str) -> None:
    """Refuse, in one line, a plugin module whose hooks laughlab would never call: a ``@hookimpl`` of no hook of
    laughlab's (``register_face``), or a ``register_*`` function left without ``@hookimpl`` (a review: both left
    the plugin silently unregistered, and the run said only that its name was unknown)."""
    specs = sorted([*KINDS.values(), "register_experiments"])
    for attr in sorted(vars(module)):
        if attr.startswith("_") or not callable(getattr(module, attr)):
            continue
        opts = pm.parse_hookimpl_opts(module, attr)
        marked = opts is not None
        hook = (opts or {}).get("specname") or attr   # @hookimpl(specname="register_faces") def my_faces(...)
        if marked and hook not in specs:
            raise LaughlabError(f"plugin {file}: {hook} is not a laughlab hook; the hooks are {', '.join(specs)}")
        if not marked and attr in specs and getattr(getattr(module, attr), "__module__", None) == module.__name__:
            raise LaughlabError(f"plugin {file}: {attr} is not marked @laughlab.hookimpl, so laughlab never calls it")


def plugins_dir_origin(file) -> str:
    """The origin of a plugin or an experiment a plugins_dir's ``file`` gives (the one place that spells it)."""
    return f"plugins dir: {file}"


def from_plugins_dir(origin: str) -> bool:
    """Whether ``origin`` (:func:`origin_of`, ``own_experiments.ORIGINS``) is a plugins_dir's file, not a package's."""
    return origin.startswith(plugins_dir_origin(""))


def origin_of(plugin: Any) -> str:
    """Where a registered plugin (module) comes from: a distribution's entry point, a plugins_dir file, or a name."""
    name = pm.get_name(plugin) or repr(plugin)
    if name in _EP_ORIGINS:
        return _EP_ORIGINS[name]
    if name.startswith(LOCAL_PACKAGE + "."):
        return plugins_dir_origin(getattr(plugin, '__file__', name))
    return f"registered: {name}"


def registry() -> dict[str, dict[str, PluginInfo]]:
    """All plugins, ``{kind: {name: PluginInfo}}``, names sorted."""
    load_entry_points()
    out: dict[str, dict[str, PluginInfo]] = {k: {} for k in KINDS}
    for kind, hook_name in KINDS.items():
        hook = getattr(pm.hook, hook_name)
        for impl in hook.get_hookimpls():
            found = collect(impl, hook_name)
            for obj in found:
                name = getattr(obj, "name", None) or (None if isinstance(obj, type) else getattr(obj, "__name__", None))
                if not name:
                    what = f" ({obj.__name__})" if isinstance(obj, type) else ""
                    raise LaughlabError(f"a {kind} plugin{what} from {origin_of(impl.plugin)} has no name: give its class "
                                        "name = '...', the name configurations choose it by")
                if isinstance(obj, type):
                    _check_class(kind, name, obj, origin_of(impl.plugin))
                elif kind != "metric":   # a plugin authors' review: register(Giggle()) ended in a traceback,
                    # "'Giggle' object is not callable", once a run chose it
                    raise LaughlabError(f"{kind} plugin {name!r} from {origin_of(impl.plugin)} is registered as an "
                                        f"object ({type(obj).__name__}(...)): register its class, "
                                        f"register({type(obj).__name__}); laughlab builds it for each run")
                if kind == "metric" and not all(hasattr(obj, a) for a in ("fn", "higher_is_better", "units")):
                    raise LaughlabError(f"metric {name!r} from {origin_of(impl.plugin)} is not a Metric: decorate its "
                                        "function with @laughlab.harness.metrics.metric(name, higher_is_better, units)")
                if name in out[kind]:
                    prev = out[kind][name]
                    raise LaughlabError(
                        f"{kind} plugin {name!r} is registered twice: {prev.origin} and {origin_of(impl.plugin)}"
                    )
                out[kind][name] = PluginInfo(kind, name, obj, origin_of(impl.plugin))
        out[kind] = dict(sorted(out[kind].items()))
    return out


def collect(impl, hook_name: str) -> list:
    """What one plugin's ``register_*`` hook registers; a hook that raises is one line naming the plugin, the
    error and the plugin's line (a re-read: a package's ``register_experiments`` or ``register_faces`` that
    raised ended every command in a traceback)."""
    found: list = []
    try:
        impl.function(found.append)
    except Exception as exc:
        raise LaughlabError(f"{hook_name} of plugin {origin_of(impl.plugin)} raised {type(exc).__name__}: {exc}"
                            f"{_raised_at(exc)}; every laughlab command loads the installed plugins: "
                            "mend it, or uninstall it") from exc
    return found


def _check_class(kind: str, name: str, cls: type, origin: str) -> None:
    """A plugin class that could not run is refused when it registers, in one line (a review: a body without
    step() failed only when chosen, in a 23-line traceback; a Params that is not a dataclass was taken, and its
    parameters were then called another plugin's)."""
    import inspect

    own = getattr(cls, "kind", "")   # each base class names its kind (laughlab.core.bases: Face.kind == "face")
    if own in KINDS and own != kind:   # a plugin authors' review: a Face registered by register_bodies ran as the body
        raise LaughlabError(f"{kind} plugin {name!r} ({cls.__name__}, {origin}) is a {own.capitalize()}: register "
                            f"it with {KINDS[own]}")
    if inspect.isabstract(cls):
        missing = ", ".join(f"{m}()" for m in sorted(cls.__abstractmethods__))
        raise LaughlabError(f"{kind} plugin {name!r} ({cls.__name__}, {origin}) does not define {missing}")
    params = getattr(cls, "Params", None)
    if params is not None and not is_dataclass(params):
        raise LaughlabError(f"{kind} plugin {name!r} ({cls.__name__}, {origin}): its Params must be a @dataclass "
                            f"(got {getattr(params, '__name__', params)!r})")


def other_kind_hint(name: str) -> str:
    """`` ('gape' is registered as a body, plugins dir: ...)`` when a plugin of that name is of another kind (a
    review: a face registered through register_bodies was only an unknown face); else empty."""
    reg = registry()
    other = [k for k, found in reg.items() if name in found]
    return f" ({name!r} is registered as a {other[0]}, {reg[other[0]][name].origin})" if other else ""


def get(kind: str, name: str) -> PluginInfo:
    """Look up one plugin; unknown names fail with the list of known ones."""
    known = registry()[kind]
    if name not in known:
        raise LaughlabError(f"unknown {kind} {name!r}; choose one of: {', '.join(known) or '(none)'}"
                            f"{other_kind_hint(name)}")
    return known[name]


#: the groups whose plugin is chosen by name (``face=facs``): their parameters are typed without that name
_GROUPS = ("input", "extractor", "detector", "scheduler", "body", "face")


def group_of(kind: str) -> str:
    """The config group that chooses a plugin of ``kind``: ``input`` for a source, ``output`` for a sink, else the
    kind itself (``face``)."""
    return {"source": "input", "sink": "output"}.get(kind, kind)


def typed(where: str, key: str | None = None) -> str:
    """A parameter as the user types it, with the plugin it belongs to: ``where`` is ``GROUP.NAME[.SUB]``
    (``face.facs.au12``) for a plugin group, shown as ``face.au12.hi (face=facs)`` (with no key and no sub-group
    ``face=facs``), or ``output.NAME`` for a
    sink, whose name is part of the key (``output.video.fps``)."""
    group, _, rest = where.partition(".")
    name, _, sub = rest.partition(".")
    if group not in _GROUPS or not name:
        return ".".join(p for p in (where, key) if p)
    if not (sub or key):
        return f"{group}={name}"   # "bad parameter in face=smile: blink_mean_s must be > 0"
    return f"{'.'.join(p for p in (group, sub, key) if p)} ({group}={name})"


def make_params(cls: type, values: Any, where: str) -> Any:
    """Validate ``values`` against the plugin's ``Params`` dataclass.

    Unknown keys, wrong types and out-of-range values (checked by the dataclass'
    ``__post_init__``) raise LaughlabError with one line naming the valid keys.
    """
    params_cls = getattr(cls, "Params", None)
    if values is None:
        values = {}
    if isinstance(values, DictConfig):
        values = OmegaConf.to_container(values, resolve=True)
    values = {k: v for k, v in dict(values).items() if k != "name"}
    if params_cls is None or not is_dataclass(params_cls):
        if values:
            raise LaughlabError(f"{where} takes no parameters (got {', '.join(values)})")
        return None
    valid = [f.name for f in fields(params_cls)]
    for key in values:
        if key not in valid:
            near = nearest(key, valid)
            raise UnknownParameter(f"unknown parameter {typed(where, key)}"
                                   + (f" (did you mean {near}?)" if near else "")
                                   + f"; valid: {', '.join(valid) or '(none)'}", key)
    try:
        groups = _nested(params_cls)
    except OmegaConfBaseException as exc:   # a plugin authors' review: Literal["a", "b"] ended in a traceback
        field_ = getattr(exc, "full_key", None)
        raise LaughlabError(f"{typed(where)}: its Params cannot be configured: {str(exc).splitlines()[0]}"
                            f"{f' (field {field_})' if field_ else ''}; a Params field is a str, int, float, bool, "
                            "an Enum, a list, a dict, a dataclass or Optional of one (OmegaConf's types)") from None
    for key, value in values.items():
        if key in groups and not isinstance(value, (dict, DictConfig)):
            sub = [f.name for f in fields(groups[key])]
            example = f"{where.partition('.')[0]}.{key}.{sub[0]}=..."
            raise LaughlabError(f"bad parameter {typed(where, key)}: it is a group of parameters ({', '.join(sub)}), "
                                f"not one value (got {value!r}); set one of them, e.g. {example}")
    merged = None
    try:
        merged = OmegaConf.merge(_schema(params_cls), values)
        large = large_ok(params_cls)
        bad = first_nonfinite(OmegaConf.to_container(merged, resolve=True), nonfinite_ok(params_cls), large=large)
        if bad is not None:
            bound = "" if bad[0] in large else f" of magnitude at most {MAX_MAGNITUDE:g}"
            raise LaughlabError(f"bad parameter {typed(where, bad[0])}: it must be a finite number{bound} (got {bad[1]})")
        return OmegaConf.to_object(merged)
    except OmegaConfBaseException as exc:
        msg = str(exc).splitlines()[0]
        key = getattr(exc, "full_key", None)
        raise LaughlabError(f"bad parameter {typed(where, key)}: {msg}" if key else
                            f"bad parameter in {typed(where)}: {msg}") from None
    except (ValueError, TypeError, AssertionError) as exc:   # __post_init__'s checks (an assert: a plugin's own)
        # a nested group's own check (face.au12's hi): name the group, not only the plugin
        inner = next((k for k in groups if k in values and merged is not None and not _builds(merged[k])), None)
        raise LaughlabError(f"bad parameter in {typed(where, inner)}: {exc}") from None
    except OSError as exc:  # a path parameter the system refuses to look at (too long, no permission, ...)
        raise _path_error(exc, where) from None


def _path_error(exc: OSError, where: str) -> LaughlabError:
    """One line for a path parameter the system refuses: the path (:func:`shown_path`, 80 characters) and
    the cause."""
    return LaughlabError(f"bad parameter in {typed(where)}: cannot use {shown_path(exc.filename, 80)}: "
                         f"{exc.strerror or exc}")


@functools.lru_cache(maxsize=None)
def _nested(params_cls: type) -> dict[str, type]:
    """The fields of a ``Params`` dataclass that are dataclasses themselves (``face=facs``'s ``au12``):
    name -> class."""
    schema = _schema(params_cls)
    return {f.name: OmegaConf.get_type(schema, f.name) for f in fields(params_cls)
            if is_dataclass(OmegaConf.get_type(schema, f.name))}


def _builds(node) -> bool:
    """True when a merged nested group makes its dataclass (its own ``__post_init__`` checks pass)."""
    try:
        OmegaConf.to_object(node)
        return True
    except (ValueError, TypeError, AssertionError):
        return False


@functools.lru_cache(maxsize=None)
def _schema(params_cls: type) -> DictConfig:
    """The dataclass as an OmegaConf schema, built once per class (merging copies it; building costs ~10 ms)."""
    return OmegaConf.structured(params_cls)


#: no parameter needs a larger number; beyond it gains and rates overflow the arithmetic (1e308 * x = inf)
MAX_MAGNITUDE = 1e6


def nonfinite_ok(params_cls: type) -> frozenset:
    """Fields of a ``Params`` dataclass that document taking NaN or infinities (``metadata={"nonfinite": True}``)."""
    return frozenset(f.name for f in fields(params_cls) if f.metadata.get("nonfinite"))


def large_ok(params_cls: type) -> frozenset:
    """Fields of a ``Params`` dataclass that take finite numbers beyond :data:`MAX_MAGNITUDE`
    (``metadata={"large": True}``: a count of samples, an FFT size; a plugin review: a 2,000,000-sample window,
    the plugin's own default, was refused)."""
    return frozenset(f.name for f in fields(params_cls) if f.metadata.get("large"))


def first_nonfinite(values: Any, allowed: frozenset = frozenset(), path: str = "",
                    large: frozenset = frozenset()) -> tuple[str, float] | None:
    """The first NaN, infinite or huge float in nested parameter values: ``(dotted key, value)``, or None.

    One place for every plugin: a numeric parameter that is NaN, infinite or beyond
    ``MAX_MAGNITUDE`` (whole numbers too, but seeds) is a user error unless its field is in ``allowed``
    (any number) or ``large`` (any finite number).
    """
    if not path and isinstance(values, dict) and large:
        for k in large & values.keys():
            v = values[k]
            if isinstance(v, float) and not math.isfinite(v):
                return k, v
        values = {k: v for k, v in values.items() if k not in large}
    if isinstance(values, float):
        return None if math.isfinite(values) and abs(values) <= MAX_MAGNITUDE else (path, values)
    if isinstance(values, int) and not isinstance(values, bool):  # seeds are names, not amounts
        return None if abs(values) <= MAX_MAGNITUDE or path.rsplit(".", 1)[-1] == "seed" else (path, values)
    if isinstance(values, dict):
        items = ((k, v) for k, v in values.items() if k not in allowed or path)
    elif isinstance(values, (list, tuple)):
        items = ((str(i), v) for i, v in enumerate(values))
    else:
        return None
    for k, v in items:
        found = first_nonfinite(v, allowed, f"{path}.{k}" if path else str(k))
        if found is not None:
            return found
    return None


def create(kind: str, name: str, values: Any, ctx: Any, where: str | None = None) -> Any:
    """Build a plugin instance from its name and parameter values."""
    from laughlab.core.bases import Context

    info = get(kind, name)
    params = make_params(info.obj, values, where or f"{group_of(kind)}.{name}")
    if isinstance(ctx, Context):   # its own random stream: one per group, a sink's per output (Context.for_plugin)
        ctx = ctx.for_plugin(f"output.{name}" if kind == "sink" else group_of(kind))
    try:
        return info.obj(params, ctx)
    except OSError as exc:  # a file the plugin opens as it starts (a model, a BVH)
        raise _path_error(exc, where or f"{kind}.{name}") from None


def check_range(name: str, value: float, lo: float | None = None, hi: float | None = None,
                lo_open: bool = False) -> None:
    """Raise ValueError naming ``name`` if ``value`` is outside [lo, hi] (or (lo, hi])."""
    if value != value:  # NaN
        raise ValueError(f"{name} must be a number (got nan)")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise ValueError(f"{name} must be {'>' if lo_open else '>='} {lo} (got {value})")
    if hi is not None and value > hi:
        raise ValueError(f"{name} must be <= {hi} (got {value})")
