"""The corpus of an experiment: synthetic laughter over seeds and profiles, plus recordings.

An item is one input: its id, the config overrides that select it, and its
ground truth if any.  Synthetic items carry their truth (``truth.csv`` written
by the run); a recording ``NAME.wav`` may have a ``NAME.truth.csv`` beside it in
the same format (columns kind, bout, onset_s, offset_s, intensity).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from laughlab.core.errors import LaughlabError, first_line, number_word, shown_names
from laughlab.core.summary import counted
from laughlab.io.audio import AUDIO_SUFFIXES, WAV_FORMATS


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

    @property
    def path(self) -> str | None:
        """The recording's file (its ``input.path=`` override); None for a synthetic input."""
        return next((o.split("=", 1)[1] for o in self.overrides if o.startswith("input.path=")), None)


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


ON_BAD = ("stop", "skip")


def check_audio(f: Path) -> float:
    """Open an audio file (header and a short read, as a trial would); its duration (s).

    Raises LaughlabError with the reason (not audio, truncated, empty, ...)."""
    import soundfile as sf

    try:
        info = sf.info(str(f))
        with sf.SoundFile(str(f)) as fh:
            fh.read(min(info.frames, 4096), dtype="float32")
            if info.frames > 4096:  # the end too: a truncated file fails there
                fh.seek(max(0, info.frames - 4096))
                fh.read(4096, dtype="float32")
    except Exception as exc:  # libsndfile's errors carry the reason
        reason = first_line(exc)
        raise LaughlabError(f"cannot read audio: {reason}") from None
    if info.frames <= 0:
        raise LaughlabError("no audio samples")
    if info.format in WAV_FORMATS:   # a WAV cut short reads without error: its header says how long it should be
        from laughlab.io.audio import check_wav_length

        check_wav_length(f, info, "the file")
    return info.frames / info.samplerate


def check_truth_csv(path: Path, duration: float | None) -> None:
    """A ``NAME.truth.csv`` checked as the annotations are, before any trial (a review: a malformed one failed
    after the trials had run, and bouts past the recording's end or overlapping were taken silently): the
    columns ``kind``, ``onset_s``, ``offset_s`` (and ``intensity`` with bouts or calls); times numbers with ``0 <= onset < offset``, not past the end;
    bouts apart.  Raises LaughlabError naming the file and the row (its line in the file)."""
    import pandas as pd

    from laughlab.corpora.annotations import TOL_S

    try:
        t = pd.read_csv(path)
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        raise LaughlabError(f"{path.name}: not a truth CSV ({str(exc).splitlines()[0]})") from None
    missing = [c for c in ("kind", "onset_s", "offset_s") if c not in t.columns]
    if missing:
        raise LaughlabError(f"{path.name}: no column {', '.join(missing)} (truth.csv columns: kind, bout, onset_s, "
                            "offset_s, intensity)")
    if t["kind"].isin(["bout", "call"]).any() and "intensity" not in t.columns:   # Truth.intensity reads it
        raise LaughlabError(f"{path.name}: no column intensity (0..1) for its bouts and calls")
    on, off = (pd.to_numeric(t[c], errors="coerce") for c in ("onset_s", "offset_s"))
    for i in range(len(t)):
        line = i + 2   # the header is line 1
        if not (pd.notna(on[i]) and pd.notna(off[i])):
            raise LaughlabError(f"{path.name}, line {line}: onset_s and offset_s must be numbers")
        if not 0.0 <= on[i] < off[i]:
            raise LaughlabError(f"{path.name}, line {line}: need 0 <= onset_s < offset_s (got {on[i]:g}, {off[i]:g})")
        if duration is not None and off[i] > duration + TOL_S:
            raise LaughlabError(f"{path.name}, line {line}: offset_s {off[i]:g} is past the recording's end "
                                f"({duration:.3f} s)")
    bouts = sorted((on[i], off[i], i + 2) for i in range(len(t)) if t["kind"][i] == "bout")
    for (a0, a1, _), (b0, b1, line) in zip(bouts, bouts[1:]):
        if b0 < a1:
            raise LaughlabError(f"{path.name}, line {line}: the bout at {b0:g}-{b1:g} s overlaps the one at "
                                f"{a0:g}-{a1:g} s")


#: a recording's annotation beside it, looked for in this order (a corpus folder's, ``detect --score``'s)
ANNOTATION_SUFFIXES = (".truth.csv", ".txt", ".TextGrid", ".eaf")


def annotation_beside(recording: Path, stem: str | None = None, skip: frozenset = frozenset()) -> Path | None:
    """``NAME.truth.csv``, else an annotation ``NAME.txt`` (Audacity labels), ``NAME.TextGrid`` or ``NAME.eaf`` beside
    ``recording`` (``NAME`` its stem, or ``stem``: ``NAME.ch2`` for a channel), not one of ``skip`` (resolved
    paths: the labels an earlier ``detect`` wrote); None without one."""
    for ext in ANNOTATION_SUFFIXES:
        p = recording.with_name((stem or recording.stem) + ext)
        if p.is_file() and p.resolve() not in skip:
            return p
    return None


def checked_truth_rows(truth: Path, duration: float | None) -> list[dict]:
    """A truth file's rows, checked (overlaps, labels, times past the end raise LaughlabError naming the file)."""
    if truth.name.endswith(".truth.csv"):
        check_truth_csv(truth, duration)
    return truth_file_rows(truth, duration)   # an annotation's reader checks it


def _truth_beside(f: Path, duration: float | None) -> tuple[str, list[dict]] | None:
    """The recording's truth file (:func:`annotation_beside`) and its rows, parsed now (:func:`checked_truth_rows`)."""
    truth = annotation_beside(f)
    return None if truth is None else (str(truth), checked_truth_rows(truth, duration))


#: the annotations a warning was printed for (a corpus is read twice: the showcase's check, then the trials)
_WARNED: set = set()


def _warn_thin(truth: Path, item: str, rows: list[dict]) -> None:
    """One warning line for an annotation that holds no bout (an empty export: the recording counts as one without
    laughter) or bouts but no calls (the intensity metrics are left blank for it): a new-user review found both
    taken without a word, the report's n one short."""
    import sys

    if truth in _WARNED:
        return
    _WARNED.add(truth)
    kinds = [r["kind"] for r in rows]
    if "bout" not in kinds:
        why = (f"holds no laughter bout: {item} counts as a recording without laughter (its false starts count, "
               "its detector scores are blank)")
    elif "call" not in kinds:
        why = (f"marks bouts but no calls: {item}'s metrics of laughter intensity (intensity_r_*, intensity_rho_*, "
               "jaw_call_r) are left blank (docs/experiments.md: annotate the calls)")
    else:
        return
    print(f"laughlab: warning: {truth} {why}", file=sys.stderr)


def truth_file_rows(truth: Path, duration_s: float | None = None) -> list[dict]:
    """A truth file's rows (``kind``, ``onset_s``, ``offset_s``...: strings from a ``truth.csv``), a ``truth.csv`` or
    an annotation (:mod:`laughlab.corpora.annotations`, checked against ``duration_s``)."""
    import csv

    from laughlab.corpora.annotations import read

    if truth.name.endswith(".truth.csv"):
        with truth.open(newline="", encoding="utf-8") as fh:
            return list(csv.DictReader(fh))
    return read(truth, duration_s).truth_rows()


def folder_items(folder: str | Path, on_bad: str = "stop", skipped: list | None = None) -> list[Item]:
    """Every audio file in ``folder`` (sorted), with ``NAME.truth.csv`` (or an annotation ``NAME.txt``,
    ``NAME.TextGrid``: see ``laughlab.corpora.annotations``) as its truth when present.

    Every file is checked before any trial runs (:func:`check_audio`, the annotation parsed), and all
    problems are reported together: ``on_bad="stop"`` raises one LaughlabError listing each file and
    its reason; ``"skip"`` leaves those files out and appends ``{"file", "reason"}`` to ``skipped``.
    A file with an audio suffix that is not audio counts as bad; other files are not part of a corpus.
    """
    if on_bad not in ON_BAD:
        raise LaughlabError(f"harness.corpus.on_bad must be stop or skip (got {on_bad!r})")
    d = Path(folder).expanduser()
    if not d.is_dir():   # a file named as the folder: said so (a review: "not found" of a file that is there)
        raise LaughlabError(f"harness.corpus.folder {folder} is a file, not a folder of recordings" if d.exists()
                            else f"corpus folder not found: {folder}")
    # not a hidden file: macOS's "._take1.wav" beside each recording on a USB drive is not audio, and stopped the
    # experiment (a detect review: the same folder detect, corrections and the harness share)
    files = sorted(p for p in d.iterdir() if p.suffix.lower() in AUDIO_SUFFIXES and not p.name.startswith("."))
    if not files:
        # a folder of session folders: said, and which to give (the harness reads one folder, not a tree: its trials
        # are named by file name, rec-NAME, a review found the line said the folder held no audio)
        below = sorted({p.relative_to(d).parts[0] for p in d.rglob("*") if p.suffix.lower() in AUDIO_SUFFIXES
                        and not any(part.startswith(".") for part in p.relative_to(d).parts)})
        raise LaughlabError(f"corpus folder {folder} holds no audio files ({', '.join(AUDIO_SUFFIXES)})"
                            + (f" itself; its subfolder(s) {shown_names(below)} do: give one of them as "
                               f"harness.corpus.folder (subfolders are not searched)" if below else ""))
    stems: dict[str, list[str]] = {}
    for f in files:
        stems.setdefault(f.stem, []).append(f.name)
    for stem, names in stems.items():   # a review: NAME.flac beside NAME.mp3 ran both as trial rec-NAME, into one
        if len(names) > 1:              # folder, and the second stopped the experiment with an OSError
            raise LaughlabError(f"corpus folder {folder}: {number_word(len(names))} "
                                f"recordings share the name {stem!r} "
                                f"({', '.join(names)}): "
                                f"their trials (rec-{stem}) and their annotation ({stem}.truth.csv, {stem}.txt, ...) "
                                "would collide; keep one of them in the folder")
    items, bad = [], []
    for f in files:
        try:
            found = _truth_beside(f, check_audio(f))
        except LaughlabError as exc:
            bad.append({"file": f.name, "reason": str(exc)})
            continue
        items.append(Item(f"rec-{f.stem}", ("input=file", f"input.path={f.resolve()}"), "recording", None,
                          found and found[0]))
        if found:
            _warn_thin(Path(found[0]), f"rec-{f.stem}", found[1])
    if bad and on_bad == "stop":
        listed = "; ".join(f"{b['file']}: {b['reason']}" for b in bad)
        raise LaughlabError(f"corpus folder {folder}: {len(bad)} of {counted(len(files), 'file')} "
                            f"{'is' if len(bad) == 1 else 'are'} bad ({listed}); fix or "
                            "remove them, or set harness.corpus.on_bad=skip to run the rest")
    if skipped is not None:
        skipped.extend(bad)
    if not items:
        raise LaughlabError(f"corpus folder {folder}: every audio file is bad")
    return items


#: the named sets of real recordings (``laughlab.corpora``): their profile names in the results
REAL_SETS = ("real", "mixed", "between", "speech", "others")


def set_folder(name: str, split: str, n: int, duration_s: float) -> str:
    """The folder name of a written set: sets of other sizes live side by side."""
    return f"{name}-{split}" if name in ("real", "others") else f"{name}-{split}-{n}x{duration_s:g}s"


#: what an experiment does when the real corpus is not fetched (``harness.corpus.real.if_missing``)
IF_MISSING = ("skip", "stop")


def real_items(spec, left_out: list | None = None) -> list[Item]:
    """Items of the real corpus: ``harness.corpus.real`` = {sets, split, scenes, duration_s, snr_db, seed,
    if_missing}.

    - ``real``: every annotated laugh of the split, padded with 0.5 s of silence (profile ``real``);
    - ``mixed``: ``scenes`` scenes of ``duration_s`` with the split's laughs between speech and other
      sounds over room noise, SNR cycling through ``snr_db`` (profiles ``mixed-20dB``, ...);
    - ``between``: ``scenes`` scenes like ``mixed`` but with no noise bed (seed ``seed + 1``): laughs spliced
      between real speech (profile ``between``);
    - ``speech``: ``scenes`` streams of ``duration_s`` of speech only (profile ``speech``);
    - ``others``: every human sound of the split that is neither laughter nor speech (coughs, sneezes,
      screams, a breath, cries, moans, grunts, shouts), alone, padded with 0.5 s of silence (profile ``others``).

    The WAVs and their ``truth.csv`` are written once under the data folder
    (``$LAUGHLAB_DATA/corpus/sets``) and reused; the corpus must be fetched
    (``python -m laughlab corpus fetch``).  When it is not, ``if_missing="stop"`` (the default) raises the
    one line that says how to fetch it; ``"skip"`` leaves the real sets out and appends their names to
    ``left_out`` (the experiment says so, in one line and in results.json).
    """
    sets = list(spec.get("sets") or [])
    if not sets:
        return []
    bad = [s for s in sets if s not in REAL_SETS]
    if bad:
        raise LaughlabError(f"unknown real corpus set {bad[0]!r}; choose from: {', '.join(REAL_SETS)}")
    from laughlab.corpora.fetch import CorpusNotFetched, corpus_dir
    from laughlab.corpora.mixed import write_set

    if_missing = str(spec.get("if_missing", "stop"))
    if if_missing not in IF_MISSING:
        raise LaughlabError(f"harness.corpus.real.if_missing must be skip or stop (got {if_missing!r})")
    split = str(spec.get("split", "test"))
    if split not in ("train", "test", "all"):
        raise LaughlabError(f"harness.corpus.real.split must be train, test or all (got {split!r})")
    n, dur = int(spec.get("scenes", 6)), float(spec.get("duration_s", 60.0))
    snr = [float(x) for x in (spec.get("snr_db") or [])]
    seed = int(spec.get("seed", 0))
    items = []
    for s in sets:
        folder = corpus_dir() / "sets" / set_folder(s, split, n, dur)
        try:
            if s == "between":   # the mixed scenes' kind with no noise bed, another seed
                wavs = write_set(folder, "mixed", split, n, dur, [], seed + 1)
            else:
                wavs = write_set(folder, s, split, n, dur, snr, seed)
        except CorpusNotFetched:
            if if_missing == "stop":
                raise
            if left_out is not None:
                left_out.append(s)
            continue
        for wav in wavs:
            profile = s if s != "mixed" else "mixed-" + wav.stem.split("-")[1]
            items.append(Item(f"{s}-{wav.stem}" if s in ("real", "others") else wav.stem,
                              ("input=file", f"input.path={wav.resolve()}"), profile, None,
                              str(wav.with_name(wav.stem + ".truth.csv"))))
    return items


def build_corpus(spec, skipped: list | None = None, left_out: list | None = None) -> list[Item]:
    """Items from a ``harness.corpus`` config: ``profiles``, ``seeds`` (count or list), ``duration_s``,
    ``folder`` (checked up front; ``on_bad``: see :func:`folder_items`), and ``real`` (see :func:`real_items`;
    the real sets left out because the corpus is not fetched go into ``left_out``)."""
    seeds = spec.get("seeds", 20)
    seeds = list(range(int(seeds))) if isinstance(seeds, int) else [int(s) for s in seeds]
    items = synthetic_items(list(spec.get("profiles") or []), seeds, float(spec.get("duration_s", 30.0)))
    if spec.get("folder"):
        items += folder_items(spec["folder"], str(spec.get("on_bad") or "stop"), skipped)
    missing: list = []
    items += real_items(spec.get("real") or {}, missing)
    if not items and missing:
        from laughlab.corpora.fetch import require

        require()  # only real sets, none fetched: the line that says how to fetch them
    if left_out is not None:
        left_out.extend(missing)
    if not items:
        if spec.get("profiles") and not seeds:   # a review: profiles were given, seeds=0 emptied them
            raise LaughlabError("the corpus is empty: harness.corpus.seeds gives no seed for its profiles "
                                "(a count of at least 1, or a list)")
        raise LaughlabError("the corpus is empty: give harness.corpus.profiles or harness.corpus.folder")
    return items
