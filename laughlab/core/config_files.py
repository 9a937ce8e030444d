"""laughlab's own YAML configuration files, read once per process and copied for each composition.

Hydra reads and parses every file of the defaults list again on each composition: the 14 files of a default
run took about a third of a composition's 0.2 s on a 2-core machine, and laughlab composes once per run, once
per value a sweep checks (``core/sweepcheck.py``), once per Hydra job of a sweep, and for an unknown key's hint.
:func:`install` wraps the reader of Hydra's package configuration source (``pkg://``: the ``conf`` package) so
that a file whose text was already parsed gives a deep copy of that result instead: the same ``DictConfig`` a
fresh parse gives (``tests/test_config_files.py`` composes every option and experiment both ways).  A composition
of ``face=facs output=[files,gltf]`` took 144-152 ms, now 112-123 ms (best of 6 rounds of 10, 2026-11-28).
The cache is kept per process (the basic launcher's jobs share it, a joblib worker parses its files again) and
keyed by each file's text, so a file edited while a process runs (a test, a notebook) is parsed again.  Files on
disk (``file://``: a plugins_dir's ``conf``) and structured configs are Hydra's own business, unchanged.
"""
from __future__ import annotations

import copy
import dataclasses

#: (source package, file, its text) -> the ConfigResult Hydra's reader made of it
_PARSED: dict = {}
#: Hydra's own reader, as it was before :func:`install` (None before)
hydra_reader = None


def install() -> None:
    """Wrap Hydra's package config reader with the cache (once per process; a no-op after)."""
    global hydra_reader
    if hydra_reader is not None:
        return
    from hydra._internal.sources_registry import SourcesRegistry
    from hydra.core.plugins import Plugins

    Plugins.instance()   # Hydra's plugin scan makes the source classes it uses (fresh module objects): then take pkg's
    source = SourcesRegistry.instance().resolve("pkg")
    read = hydra_reader = source._read_config

    def _read_config(self, res):
        try:
            key = (self.path, str(res), res.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError):   # Hydra's own reader words these
            return read(self, res)
        parsed = _PARSED.get(key)
        if parsed is None:
            parsed = _PARSED[key] = read(self, res)
        return dataclasses.replace(parsed, config=copy.deepcopy(parsed.config), header=dict(parsed.header))

    source._read_config = _read_config
