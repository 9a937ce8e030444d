"""The corpus of an experiment: synthetic laughter over seeds and profiles, plus recordings.

An item is one input: its id, the config overrides that select it, and its
ground truth if any.  Synthetic items carry their truth (``truth.csv`` written
by the run); a recording ``NAME.wav`` may have a ``NAME.truth.csv`` beside it in
the same format (columns kind, bout, onset_s, offset_s, intensity).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from laughlab.core.errors import LaughlabError

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
    from laughlab.synth.laughter import PROFILES

    items = []
    for p in profiles:
        if p not in PROFILES:
            raise LaughlabError(f"unknown synthetic profile {p!r}; choose from: {', '.join(PROFILES)}")
        for s in seeds:
            items.append(Item(f"{p}-s{int(s):02d}", ("input=synthetic", f"input.profile={p}", f"input.seed={int(s)}",
                                                    f"input.duration_s={float(duration_s)}", "input.save_audio=false"),
                              p, int(s)))
    return items


def _truth_beside(f: Path) -> str | None:
    """``NAME.truth.csv``, else an annotation ``NAME.txt`` (Audacity labels) or ``NAME.TextGrid``
    (checked now, so a bad label stops the experiment before any trial with one line naming it)."""
    truth = f.with_name(f.stem + ".truth.csv")
    if truth.exists():
        return str(truth)
    for ext in (".txt", ".TextGrid"):
        ann = f.with_name(f.stem + ext)
        if ann.exists():
            import soundfile as sf

            from laughlab.corpora.annotations import read

            try:
                duration = sf.info(str(f)).duration
            except RuntimeError:
                duration = None
            read(ann, duration)
            return str(ann)
    return None


def folder_items(folder: str | Path) -> list[Item]:
    """Every audio file in ``folder`` (sorted), with ``NAME.truth.csv`` (or an annotation ``NAME.txt``,
    ``NAME.TextGrid``: see ``laughlab.corpora.annotations``) as its truth when present."""
    d = Path(folder).expanduser()
    if not d.is_dir():
        raise LaughlabError(f"corpus folder not found: {folder}")
    files = sorted(p for p in d.iterdir() if p.suffix.lower() in AUDIO_SUFFIXES)
    if not files:
        raise LaughlabError(f"corpus folder {folder} holds no audio files ({', '.join(AUDIO_SUFFIXES)})")
    items = []
    for f in files:
        items.append(Item(f"rec-{f.stem}", ("input=file", f"input.path={f.resolve()}"), "recording", None,
                          _truth_beside(f)))
    return items


#: the named sets of real recordings (``laughlab.corpora``): their profile names in the results
REAL_SETS = ("real", "mixed", "speech")


def set_folder(name: str, split: str, n: int, duration_s: float) -> str:
    """The folder name of a written set: sets of other sizes live side by side."""
    return f"{name}-{split}" if name == "real" else f"{name}-{split}-{n}x{duration_s:g}s"


def real_items(spec) -> list[Item]:
    """Items of the real corpus: ``harness.corpus.real`` = {sets, split, scenes, duration_s, snr_db, seed}.

    - ``real``: every annotated laugh of the split, padded with 0.5 s of silence (profile ``real``);
    - ``mixed``: ``scenes`` scenes of ``duration_s`` with the split's laughs between speech and other
      sounds over room noise, SNR cycling through ``snr_db`` (profiles ``mixed-20dB``, ...);
    - ``speech``: ``scenes`` streams of ``duration_s`` of speech only (profile ``speech``).

    The WAVs and their ``truth.csv`` are written once under the data folder
    (``$LAUGHLAB_DATA/corpus/sets``) and reused; the corpus must be fetched
    (``python -m laughlab corpus fetch``).
    """
    sets = list(spec.get("sets") or [])
    if not sets:
        return []
    bad = [s for s in sets if s not in REAL_SETS]
    if bad:
        raise LaughlabError(f"unknown real corpus set {bad[0]!r}; choose from: {', '.join(REAL_SETS)}")
    from laughlab.corpora.fetch import corpus_dir
    from laughlab.corpora.mixed import write_set

    split = str(spec.get("split", "test"))
    if split not in ("train", "test", "all"):
        raise LaughlabError(f"harness.corpus.real.split must be train, test or all (got {split!r})")
    n, dur = int(spec.get("scenes", 6)), float(spec.get("duration_s", 60.0))
    snr = [float(x) for x in (spec.get("snr_db") or [])]
    seed = int(spec.get("seed", 0))
    items = []
    for s in sets:
        folder = corpus_dir() / "sets" / set_folder(s, split, n, dur)
        for wav in write_set(folder, s, split, n, dur, snr, seed):
            profile = s if s != "mixed" else "mixed-" + wav.stem.split("-")[1]
            items.append(Item(f"{s}-{wav.stem}" if s == "real" else wav.stem,
                              ("input=file", f"input.path={wav.resolve()}"), profile, None,
                              str(wav.with_name(wav.stem + ".truth.csv"))))
    return items


def build_corpus(spec) -> list[Item]:
    """Items from a ``harness.corpus`` config: ``profiles``, ``seeds`` (count or list), ``duration_s``,
    ``folder``, and ``real`` (see :func:`real_items`)."""
    seeds = spec.get("seeds", 20)
    seeds = list(range(int(seeds))) if isinstance(seeds, int) else [int(s) for s in seeds]
    items = synthetic_items(list(spec.get("profiles") or []), seeds, float(spec.get("duration_s", 30.0)))
    if spec.get("folder"):
        items += folder_items(spec["folder"])
    items += real_items(spec.get("real") or {})
    if not items:
        raise LaughlabError("the corpus is empty: give harness.corpus.profiles or harness.corpus.folder")
    return items
