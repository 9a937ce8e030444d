"""A plugin's bug, said so the user reads it first: which plugin an unexpected exception came from, and a
channel value that is not a finite number.

An exception a plugin raises while a run steps it (a bug, not bad input: bad input is a
:class:`~laughlab.core.errors.LaughlabError`) used to end in a 40-line traceback through Hydra and the
command line, the plugin's own lines at the bottom, without its name or the frame.  :func:`mark` names the
plugin, its file and the frame on the exception (attributes that survive pickling, so a trial run in a worker
process keeps them); the command line then prints the traceback from the plugin's own call on, and one line.
"""
from __future__ import annotations

import inspect
import sys
import traceback

from laughlab.core.errors import LaughlabError

#: attribute set on an exception by :func:`mark`: the plugin and where (str)
WHERE = "laughlab_plugin"
#: the traceback from the plugin's own call on (str; a traceback object does not pickle)
TRACE = "laughlab_trace"
#: True when the plugin is one of laughlab's own (a bug to report), False for a third-party one
BUILT_IN = "laughlab_built_in"


def _source_file(cls: type) -> str:
    try:
        return inspect.getsourcefile(cls) or cls.__module__
    except TypeError:
        return cls.__module__


def mark(exc: BaseException, stages: list, frame: int | None, fps: float) -> None:
    """Name on ``exc`` the outermost call, in its traceback, of a method of one of ``stages`` (the run's plugin
    objects); ``frame`` is the frame being stepped (None: before the first, or while writing).  Exceptions
    with no such call (the pipeline's own) are left as they are."""
    if getattr(exc, WHERE, None) or not isinstance(exc, Exception) or isinstance(exc, (LaughlabError, OSError)):
        return   # already named, an interrupt, or one line already (bad input, a file-system fault)
    ids = {id(s): s for s in stages if s is not None}
    tb = exc.__traceback__
    while tb is not None:
        plugin = ids.get(id(tb.tb_frame.f_locals.get("self")))
        if plugin is not None:
            break
        tb = tb.tb_next
    if tb is None:
        return
    cls = type(plugin)
    from laughlab.core.plugins import group_of   # not at import: the command line starts without pluggy

    kind = group_of(getattr(plugin, "kind", "") or "plugin")
    method = tb.tb_frame.f_code.co_name
    when = f" at frame {frame} ({frame / fps:.2f} s)" if frame is not None and method == "step" else ""
    name = getattr(plugin, "name", "") or cls.__name__
    setattr(exc, WHERE, f"{kind} '{name}' ({_source_file(cls)}, {cls.__name__}.{method}){when}")
    # out of memory is the machine's limit, not a bug: no traceback (a review: 4K video at supersample 4)
    setattr(exc, TRACE, "" if isinstance(exc, MemoryError) else
            "".join(traceback.format_exception(type(exc), exc, tb)).rstrip())
    setattr(exc, BUILT_IN, cls.__module__.split(".")[0] in ("laughlab", "laughlab_plugins"))


def not_built(exc: Exception, cls: type, kind: str, name: str) -> "PluginBug":
    """The error for a plugin whose class raised while a run built it (``Cls(params, ctx)``: its ``__init__``, or a
    method that calls): one line naming it, its file and class, with the traceback from the plugin's own call on
    (:func:`trace`).  A plugin authors' review: a ``KeyError`` in a face's ``__init__`` ended in a 20-line
    traceback through the command line with no line naming the face."""
    tb = exc.__traceback__
    while tb is not None and not isinstance(tb.tb_frame.f_locals.get("self"), cls):
        tb = tb.tb_next
    text = str(exc).strip().splitlines()
    cause = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
    method = tb.tb_frame.f_code.co_name if tb is not None else "__init__"
    built_in = cls.__module__.split(".")[0] in ("laughlab", "laughlab_plugins")
    who = ("a bug in laughlab: please report it with the lines above" if built_in else
           "the lines above are from the plugin's code" if tb is not None else
           "laughlab builds a plugin as Cls(params, ctx): docs/architecture.md")
    bug = PluginBug(f"{kind} '{name}' ({_source_file(cls)}, {cls.__name__}.{method}) raised {cause} as the run "
                    f"built it ({who})")
    setattr(bug, TRACE, "".join(traceback.format_exception(type(exc), exc, tb)).rstrip() if tb is not None else "")
    return bug


def line(exc: BaseException) -> str | None:
    """The one line for an exception :func:`mark` named (None if it did not)."""
    where = getattr(exc, WHERE, None)
    if not where:
        return None
    if isinstance(exc, MemoryError):   # numpy says how much it asked for: a size that is a plugin's bug shows
        asked = (str(exc).strip().splitlines() or [""])[0]
        return (f"{where} ran out of memory{f' ({asked})' if asked else ''}: the machine could not give it more; a "
                "smaller output (a video's output.video.supersample, width, height), a shorter input or fewer jobs "
                "at once needs less")
    text = str(exc).strip().splitlines()
    cause = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
    who = ("a bug in laughlab: please report it with the lines above" if getattr(exc, BUILT_IN, False)
           else "the lines above are from the plugin's code")
    return f"{where} raised {cause} ({who})"


def trace(exc: BaseException) -> str:
    """The traceback from the plugin's own call on ('' if :func:`mark` did not name one)."""
    return getattr(exc, TRACE, "") or ""


def whose(key: str, owner=None) -> str:
    """:data:`WHOSE`, naming the plugin when ``owner(key)`` knows it (``face 'giggle'``: the stage that wrote the
    channel on the first frame, :class:`WatchedChannels`; a plugin author's review: the line did not name it)."""
    who = owner(key) if owner is not None else None
    return WHOSE.replace("writes it", f"writes it, {who}") if who else WHOSE


def not_a_number(key: str, values: list, first_frame: int, owner=None) -> str:
    """The line for a channel value that is not a number (a plugin's bug): the channel, the value, the frame."""
    for j, v in enumerate(values):
        try:
            float(v)
        except (TypeError, ValueError):
            break
    else:
        j, v = 0, values[0]
    return (f"channel {key!r} is {str(v)[:40]!r} ({type(v).__name__}) at frame {first_frame + j}: channel values "
            f"are numbers; {whose(key, owner)}; nothing was written")


class PluginBug(LaughlabError):
    """A plugin's value no writer takes (not a number, NaN, infinite): one line, and the exit status of a plugin
    that raises, 1 (it exited 2, a user error's, and asked the author of a plugin of their own to report it to
    laughlab: the plugin authors' review)."""

    exit_code = 1


#: what the line asks of the user: the plugin is theirs, or laughlab's
WHOSE = "a bug in the plugin that writes it (laughlab's own plugins: please report it)"


#: the controls that are 0-1, and what each is
UNIT = {"mcs": "the motion control signal", "laughter": "a detector's laughter probability",
        "laugh_gate": "a detector's gate", "clip_gate": "a detector's clip gate"}


def check_finite(vals: dict, poses, first_frame: int, raw=None, owner=None) -> None:
    """The guard before every writer: a NaN or infinite channel or pose value is a plugin's bug, never output.

    Raises :class:`PluginBug` naming the channel (or pose column), the value (``None`` as the plugin gave it:
    ``raw(key, j)``, the value written) and the first frame where it happens; the run then removes what it wrote.
    """
    import numpy as np   # not at import: the command line starts without numpy
    for k, arr in vals.items():
        if not np.isfinite(arr).all():
            j = int(np.argmin(np.isfinite(arr)))
            v = raw(k, j) if raw is not None else arr[j]
            raise PluginBug(f"channel {k!r} is {'None' if v is None else arr[j]} at frame {first_frame + j}: "
                            f"{whose(k, owner)}; nothing was written")
    for k, what in UNIT.items():   # a detector's too (a plugin author's review: laughter 50 went into the metrics)
        v = vals.get(k)
        if v is not None and len(v) and not ((v >= -1e-9) & (v <= 1.0 + 1e-9)).all():
            j = int(np.argmax((v < -1e-9) | (v > 1.0 + 1e-9)))
            raise PluginBug(f"channel {k!r} is {v[j]:g} at frame {first_frame + j}: {what} is 0-1 "
                            f"(docs/architecture.md); {whose(k, owner)}; nothing was written")
    if len(poses) and not np.isfinite(poses).all():
        j, c = (int(x[0]) for x in np.nonzero(~np.isfinite(poses)))
        raise PluginBug(f"pose column {c} is {poses[j, c]} at frame {first_frame + j}: a non-finite joint "
                        f"value, {WHOSE}; nothing was written")


def who(kind: str, plugin) -> str:
    """``body 'sway' (its file)``: a plugin as a line names it."""
    return f"{kind} '{plugin.name}' ({_source_file(type(plugin))})"


def first_step(kind: str, plugin, *args) -> None:
    """A stage's first step.  A ``step`` that cannot be called with its kind's arguments (a body written with an
    extractor's ``step(self, block, frame)``: a plugin author's review met a 39-line traceback) is said in one line
    naming the plugin and the signature its kind has; a TypeError raised inside the plugin is left to :func:`mark`."""
    try:
        plugin.step(*args)
    except TypeError as exc:
        if exc.__traceback__ is None or exc.__traceback__.tb_next is not None:   # the plugin's code ran: its own
            raise
        cls = type(plugin)
        want = "step(self, block, frame)" if kind in ("extractor", "detector") else "step(self, frame)"
        raise PluginBug(f"{kind} '{plugin.name}' ({_source_file(cls)}, {cls.__name__}.step) cannot be called as a "
                        f"{kind}'s {want} ({exc}): docs/architecture.md, 'Writing a plugin'") from None


def one_number(v) -> bool:
    """A plain number (int, float, or a numpy scalar or 0-d array of one), not a bool, a text or an array."""
    return not isinstance(v, bool) and (isinstance(v, (int, float)) or (
        hasattr(v, "dtype") and getattr(v, "ndim", 1) == 0 and v.dtype.kind in "fiu"))


def check_extractor(control: dict, extractor, writers: dict | None = None) -> None:
    """On a run's first frame: the extractor wrote ``control['mcs']``, which the detectors, schedulers, bodies and
    faces read (docs/architecture.md, "Writing a plugin").  An extractor without it stopped the run in the next
    stage that read it, a built-in one, whose line asked for a report to laughlab (a plugin authors' review)."""
    if "mcs" not in control:
        cls = type(extractor)
        wrote = ", ".join(control) or "nothing"
        raise PluginBug(f"extractor '{extractor.name}' ({_source_file(cls)}, {cls.__name__}.step) wrote no mcs at "
                        f"frame 0 (it wrote {wrote}): every extractor writes frame.control['mcs'] (0-1), the signal "
                        "the detector, scheduler, body and face read; nothing was written")
    mcs = control["mcs"]
    if not one_number(mcs):
        cls = type(extractor)
        shape = f", shape {mcs.shape}" if hasattr(mcs, "shape") else ""
        raise PluginBug(f"extractor '{extractor.name}' ({_source_file(cls)}, {cls.__name__}.step) wrote mcs as "
                        f"{type(mcs).__name__}{shape} at frame 0: mcs is one number a frame, 0-1 (a plugin author's "
                        "review: a later stage, one of laughlab's, was blamed); nothing was written")
    if writers is not None:   # a line about mcs names the extractor (:meth:`Recorder._owner`)
        writers.setdefault("mcs", [("extractor", extractor.name)])


def check_detector(control: dict, detector, writers: dict | None = None) -> None:
    """On a run's first frame: the detector wrote ``laughter`` and ``laugh_gate``, one number each (a plugin
    author's review: one that wrote neither, or returned its score, ran to the end, exit 0, its metrics n/a)."""
    cls = type(detector)
    where = f"detector '{detector.name}' ({_source_file(cls)}, {cls.__name__}.step)"
    missing = [k for k in ("laughter", "laugh_gate") if k not in control]
    if missing:
        raise PluginBug(f"{where} wrote no {' and no '.join(missing)} at frame 0: every detector writes "
                        "frame.control['laughter'] and ['laugh_gate'] (0-1) and gates the driving signals with "
                        "laughlab.detector.model.apply_gate(frame, gain) (docs/architecture.md); nothing was written")
    for k in ("laughter", "laugh_gate"):
        if not one_number(control[k]):
            raise PluginBug(f"{where} wrote {k} as {type(control[k]).__name__} at frame 0: one number a frame, 0-1; "
                            "nothing was written")
    if writers is not None:
        for k in ("laughter", "laugh_gate", "clip_gate"):
            if k in control:
                writers.setdefault(k, [("detector", detector.name)])


class WatchedChannels(dict):
    """``frame.channels`` on a run's first frame: which stage (``stage``: its kind and name) writes each channel,
    through ``[]``, ``update``, ``setdefault`` and ``|=`` alike (:func:`warn_clashes`)."""

    stage: tuple = ("", "")

    def __init__(self):
        super().__init__()
        self.writers: dict = {}

    def __setitem__(self, key, value) -> None:
        self.writers.setdefault(key, [])
        if self.stage not in self.writers[key]:
            self.writers[key].append(self.stage)
        super().__setitem__(key, value)

    def update(self, *args, **kwargs) -> None:
        for key, value in dict(*args, **kwargs).items():
            self[key] = value

    def setdefault(self, key, default=None):
        if key not in self:
            self[key] = default
        return self[key]

    def __ior__(self, other):
        self.update(other)
        return self


_CLASHES_SAID: set = set()


def warn_clashes(watched: WatchedChannels) -> None:
    """One warning line (once a process) per pair of stages that wrote the same channel on the first frame: the
    later one's value is what ``channels.csv``, the character and the metrics keep.  A warning, not a refusal: a
    plugin may mean to refine an earlier one's channel; laughlab's own stages never do."""
    pairs: dict = {}
    for key, who in watched.writers.items():
        for later in who[1:]:
            pairs.setdefault((who[0], later), []).append(key)
    for (first, later), keys in pairs.items():
        if (first, later, tuple(keys)) in _CLASHES_SAID:
            continue
        _CLASHES_SAID.add((first, later, tuple(keys)))
        print(f"laughlab: warning: {later[0]} {later[1]!r} writes {', '.join(keys)}, which {first[0]} {first[1]!r} "
              f"wrote on the same frame: channels.csv, the character and the metrics keep the {later[0]}'s "
              "(each channel has one writer: docs/architecture.md)", file=sys.stderr)
