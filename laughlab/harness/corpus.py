"""The corpus of an experiment: synthetic laughter over seeds and profiles, plus recordings.

An item is one input: its id, the config overrides that select it, and its
ground truth if any.  Synthetic items carry their truth (``truth.csv`` written
by the run); a recording ``NAME.wav`` may have a ``NAME.truth.csv`` beside it in
the same format (columns kind, bout, onset_s, offset_s, intensity).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import LaughlabError

AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".mp3", ".aiff", ".aif")


@dataclass(frozen=True)
class Item:
    """One input of the corpus.

    Attributes
    ----------
    id : str
        Unique name, e.g. ``intense-s03`` or ``rec-laugh01``.
    overrides : tuple[str, ...]
        Config overrides selecting the input.
    profile : str
        Synthetic profile, or ``recording``.
    seed : int or None
        The synthetic laughter's seed (None for recordings).
    truth : str or None
        Path of a ground-truth CSV for recordings.
    """

    id: str
    overrides: tuple = field(default_factory=tuple)
    profile: str = "recording"
    seed: int | None = None
    truth: str | None = None


def synthetic_items(profiles, seeds, duration_s: float) -> list[Item]:
    """Synthetic laughter: one item per profile and seed (giggle ignores the duration)."""
    from ..synth import PROFILES

    items = []
    for p in profiles:
        if p not in PROFILES:
            raise LaughlabError(f"unknown synthetic profile {p!r}; choose from: {', '.join(PROFILES)}")
        for s in seeds:
            items.append(Item(f"{p}-s{int(s):02d}", ("input=synthetic", f"input.profile={p}", f"input.seed={int(s)}",
                                                    f"input.duration_s={float(duration_s)}", "input.save_audio=false"),
                              p, int(s)))
    return items


def folder_items(folder: str | Path) -> list[Item]:
    """Every audio file in ``folder`` (sorted), with ``NAME.truth.csv`` as its truth when present."""
    d = Path(folder).expanduser()
    if not d.is_dir():
        raise LaughlabError(f"corpus folder not found: {folder}")
    files = sorted(p for p in d.iterdir() if p.suffix.lower() in AUDIO_SUFFIXES)
    if not files:
        raise LaughlabError(f"corpus folder {folder} holds no audio files ({', '.join(AUDIO_SUFFIXES)})")
    items = []
    for f in files:
        truth = f.with_name(f.stem + ".truth.csv")
        items.append(Item(f"rec-{f.stem}", ("input=file", f"input.path={f.resolve()}"), "recording", None,
                          str(truth) if truth.exists() else None))
    return items


def build_corpus(spec) -> list[Item]:
    """Items from a ``harness.corpus`` config: ``profiles``, ``seeds`` (count or list), ``duration_s``, ``folder``."""
    seeds = spec.get("seeds", 20)
    seeds = list(range(int(seeds))) if isinstance(seeds, int) else [int(s) for s in seeds]
    items = synthetic_items(list(spec.get("profiles") or []), seeds, float(spec.get("duration_s", 30.0)))
    if spec.get("folder"):
        items += folder_items(spec["folder"])
    if not items:
        raise LaughlabError("the corpus is empty: give harness.corpus.profiles or harness.corpus.folder")
    return items
