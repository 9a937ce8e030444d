"""The package a ``plugins_dir``'s modules belong to: ``laughlab_local_plugins.NAME`` for ``NAME.py``."""
from __future__ import annotations

import sys
import types
from pathlib import Path

LOCAL_PACKAGE = "laughlab_local_plugins"


def local_package(folder: Path) -> None:
    """Make ``plugins_dir`` the package :data:`LOCAL_PACKAGE` in this process: its modules import each other
    relatively (``from .helpers import x``) whatever their files' order, and pickle finds their classes by name
    (a background sink's, in the helper process: :mod:`laughlab.core.background`).  A review: a module importing
    a sibling worked only if the sibling's name sorted first, and a background sink of the folder failed every
    offline run."""
    pkg = sys.modules.get(LOCAL_PACKAGE)
    if pkg is None:
        pkg = types.ModuleType(LOCAL_PACKAGE, "the modules of plugins_dir")
        pkg.__path__ = []
        sys.modules[LOCAL_PACKAGE] = pkg
    if str(folder) not in pkg.__path__:
        pkg.__path__.append(str(folder))
