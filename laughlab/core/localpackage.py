"""The package a ``plugins_dir``'s modules belong to: ``laughlab_local_plugins.NAME`` for ``NAME.py``; and which folder
it holds now, imported afresh when another folder or an edited file comes (:func:`forget_if_changed`)."""
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


#: the plugins_dir whose modules are registered, as (folder, its files' names, sizes and modification times)
_LOADED_DIR: tuple | None = None


def forget_if_changed(folder: Path, pm) -> None:
    """Another folder, or an edited file, since the registered plugins_dir modules were loaded (in one process: a
    notebook's second Session, ``cli.main`` called again): unregister them and import afresh.  A Python user's
    review: an edited plugin ran its old code, and a second folder's ``loud.py`` ran the first folder's.  ``pm``:
    laughlab's plugin manager (``laughlab.core.plugins.pm``)."""
    global _LOADED_DIR
    state = _dir_state(folder)
    if state == _LOADED_DIR:
        return
    if _LOADED_DIR is not None:
        for name, plugin in pm.list_name_plugin():
            if name.startswith(LOCAL_PACKAGE + "."):
                pm.unregister(plugin)
        for name in [m for m in sys.modules if m.startswith(LOCAL_PACKAGE + ".")]:
            del sys.modules[name]
        pkg = sys.modules.get(LOCAL_PACKAGE)
        if pkg is not None:
            pkg.__path__ = []
    _LOADED_DIR = state


def _dir_state(folder: Path) -> tuple | None:
    try:
        return (str(folder.resolve()), tuple((f.name, f.stat().st_size, f.stat().st_mtime_ns)
                                             for f in sorted(folder.glob("*.py"))))
    except OSError:
        return None


def plugins_dir_changed(path: str | Path) -> bool:
    """Whether ``laughlab.core.plugins.load_plugin_dir`` of ``path`` will import afresh (another folder, or a file changed), so the
    earlier folder's experiments go too (``laughlab.core.config.load_plugin_dirs``; the diff review)."""
    return _LOADED_DIR is not None and _dir_state(Path(path).expanduser()) != _LOADED_DIR
