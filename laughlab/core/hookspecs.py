"""The hooks a laughlab plugin can implement (the one place they are declared).

A plugin is any module or object with functions marked ``@laughlab.hookimpl``.
Each ``register_*`` hook receives a ``register`` callable and calls it once per
plugin class it provides::

    import laughlab

    @laughlab.hookimpl
    def register_extractors(register):
        register(MyExtractor)

The class must carry a ``name`` (unique within its kind) and a ``Params``
dataclass whose fields are its configurable parameters; see
:mod:`laughlab.core.bases` for the interface of every kind.  Built-in plugins are
registered exactly like this, through the ``laughlab`` entry-point group.
"""
from __future__ import annotations

from typing import Callable

import pluggy

hookspec = pluggy.HookspecMarker("laughlab")

Register = Callable[[type], None]


@hookspec
def register_sources(register: Register) -> None:
    """Register audio sources (:class:`laughlab.core.bases.Source` subclasses)."""


@hookspec
def register_extractors(register: Register) -> None:
    """Register signal extractors (audio frame -> :class:`laughlab.core.frame.Frame` controls)."""


@hookspec
def register_detectors(register: Register) -> None:
    """Register laughter detectors (audio + controls -> ``laughter`` probability, gated controls)."""


@hookspec
def register_faces(register: Register) -> None:
    """Register face models (controls -> face channels)."""


@hookspec
def register_bodies(register: Register) -> None:
    """Register body drivers (controls -> body channels and joint offsets)."""


@hookspec
def register_schedulers(register: Register) -> None:
    """Register schedulers of full-body clips (controls -> clip start/stop events)."""


@hookspec
def register_sinks(register: Register) -> None:
    """Register output sinks (frames -> files or live streams)."""


@hookspec
def register_metrics(register: Register) -> None:
    """Register metric functions (run outputs -> named numbers)."""


@hookspec
def register_experiments(register: Callable[[object], None]) -> None:
    """Register experiments: the path of each YAML file (``str`` or ``pathlib.Path``) a package ships, written as a
    plugins_dir's ``experiment/NAME.yaml`` (docs/experiments.md, 'An experiment of your own'); each is then
    ``experiment=NAME``, its file's stem."""
