"""How laughlab is installed, for the hints that say what to install: a clone (``pip install -e .``) or a wheel."""
from __future__ import annotations

from pathlib import Path


def clone_dir() -> Path | None:
    """The source checkout laughlab runs from (its ``pyproject.toml`` names the project ``laughlab``), or None
    when laughlab is installed from a wheel."""
    root = Path(__file__).resolve().parents[2]
    try:
        text = (root / "pyproject.toml").read_text(encoding="utf-8")
    except OSError:
        return None
    return root if 'name = "laughlab"' in text else None


def extra_command(extra: str) -> str:
    """The pip command that adds an optional extra (``mic``, ``cluster``, ...) to this installation:
    ``pip install -e '.[mic]'`` in a clone, ``pip install 'laughlab[mic]'`` otherwise."""
    root = clone_dir()
    if root is None:
        return f"pip install 'laughlab[{extra}]'"
    return f"pip install -e '.[{extra}]' in {root}"
