"""``python -m laughlab detect PATH... [--out DIR]``: laughter segments of recordings, offline.

Files and folders (searched recursively for audio files soundfile reads) go through
:func:`laughlab.detector.segments.laughter_prob` (YAMNet and the head, centred windows,
smoothed both ways), then a threshold and a minimum length.  Writes into ``--out``
(default ``laughter_segments``): ``segments.csv`` and ``recordings.csv`` for all inputs, and per input
``NAME.txt`` (Audacity labels) and ``NAME.TextGrid`` (Praat), on request ``NAME.eaf`` (ELAN) and each laugh's
audio (``NAME_laugh_K.wav``); ``NAME`` is a file's stem, or for a file found in
a given folder its path from that folder (:func:`inputs`).  A progress bar on stderr
when the inputs are longer than a minute in all.  An unreadable input stops the batch before anything is
written, or with ``--skip-unreadable`` is left out in one line on stderr.
"""
from __future__ import annotations

import collections
import json
import os
import re
import sys
import time
from pathlib import Path

from laughlab.core.errors import LaughlabError, number_word, one_line_parser, shown_names
from laughlab.core.interrupts import deferred
from laughlab.core.outfiles import edited_since, read_record, record_text, remove, unwrite
from laughlab.core.summary import counted, duration_text, factor_text
from laughlab.io.audio import AUDIO_SUFFIXES

FORMATS = ("csv", "audacity", "textgrid", "elan", "audio")


def inputs(paths: list[str]) -> list[tuple[Path, str]]:
    """The audio files of ``paths`` (a folder's hidden files and folders left out) with the name each one's
    outputs take: a file given by itself, its stem; a
    file found in a given folder, its path from that folder without the suffix (``day1/take1``), so a tree of
    recordings keeps its layout in ``--out`` and repeated take names in different folders do not collide.
    The files an earlier ``detect`` wrote into any ``--out`` below a given folder (its manifest, this run's
    ``--out`` too) are not searched for: its laughs' clips were read back as recordings by ``--overwrite``
    (``out/out/take_laugh_0_laugh_0.wav``, a new-user review)."""
    from laughlab.io.audio import OTHER_MEDIA

    out, seen, other = [], set(), {}   # other: a folder's recordings laughlab does not read, once each
    for p in paths:
        q = Path(p).expanduser()
        if q.is_dir():
            files, theirs = _folder_files(q)
            audio = [f for f in files if f.suffix.lower() in AUDIO_SUFFIXES]
            found = [f for f in audio if f.resolve() not in theirs]
            media = [f for f in files if f.suffix.lower() in OTHER_MEDIA]
            other.update((f.resolve(), f) for f in media)
            if not found:
                raise LaughlabError(f"no audio files in folder {p}" + (f" that laughlab reads: {_unread(media)}"
                                                                        if media else "")
                                    + (f" other than the {len(audio)} laugh clip(s) an earlier detect wrote (its --out)"
                                       if audio else ""))
            named = [(f, f.relative_to(q).with_suffix("").as_posix()) for f in found]
        elif q.exists():
            named = [(q, q.stem)]
        else:
            raise LaughlabError(f"input not found: {p}")
        for f, name in named:   # the same file twice (a folder and a file in it, overlapping globs): once
            if f.resolve() not in seen:
                seen.add(f.resolve())
                out.append((f, name))
    if other:   # a review: a folder's .m4a recordings were left out without a word
        print(f"laughlab: not read: {_unread(list(other.values()))}", file=sys.stderr)
    # case aside: Take.wav and take.flac wrote Take.TextGrid and take.TextGrid, one file on macOS' and Windows' file
    # systems (a review at scale); counted once each (names.count was quadratic: 18 s for 50,000 inputs)
    folded = [(f, n, _folded(n)) for f, n in out]
    counts = collections.Counter(k for _, _, k in folded)
    dup = sorted({k for _, _, k in folded if counts[k] > 1})
    if dup:
        both = [f for f, _, k in folded if k == dup[0]]
        spelt = sorted({n for _, n, k in folded if k == dup[0]})
        shown = repr(spelt[0]) + (f" and {spelt[1]!r}, which differ in case or Unicode form only (one file on macOS and Windows)"
                                  if len(spelt) > 1 else "")
        # files of one name in different folders (a shell glob, rec/*/*.wav): their common folder names each by its
        # path from it (a review: the line only said to run them separately)
        common = os.path.commonpath([str(f.resolve().parent) for f in both])
        apart = len({f.resolve().parent for f in both}) > 1
        fix = (f"give their folder instead ({common}: each file found in it is named by its path from it) or run "
               "them separately (--out)" if apart else "run them separately (--out)")
        listed = ", ".join(map(str, both))
        raise LaughlabError(f"{number_word(len(both))} inputs share the name {shown} ({listed}): "
                            "their label files "
                            f"would collide; {fix}")
    return out


def _folder_files(folder: Path) -> tuple[list[Path], frozenset]:
    """The files below ``folder``, sorted, through linked folders too (each real folder once: a link to a parent is
    no loop), and not its hidden files and folders: macOS's "._take1.wav" beside each recording copied to a USB
    drive is not audio and stopped the batch; .Trashes, .git hold no takes (the detect review, as was a linked
    session folder left out without a word: rglob does not follow links).  With them, the resolved paths of the
    files an earlier ``detect`` wrote into any folder below (its manifest): laugh clips of an ``--out`` inside
    the folder are not recordings (a review: a second ``detect rec --out rec/labB`` read ``rec/labA``'s clips)."""
    out, real, theirs = [], {os.path.realpath(folder)}, set()

    def unreadable(exc: OSError):   # os.walk skips a folder it cannot list, and its recordings went unsaid
        from laughlab.core.errors import os_error_line

        raise LaughlabError(os_error_line(exc, folder, verb="cannot read the folder"))

    for d, dirs, names in os.walk(folder, onerror=unreadable, followlinks=True):
        keep = []
        for sub in sorted(dirs):
            r = os.path.realpath(os.path.join(d, sub))
            if not sub.startswith(".") and r not in real:
                real.add(r)
                keep.append(sub)
        dirs[:] = keep
        out += [Path(d, n) for n in names if not n.startswith(".") and os.path.isfile(os.path.join(d, n))]
        if MANIFEST in names:
            theirs |= written_before(Path(d))
    return sorted(out), frozenset(theirs)


def _unread(files: list[Path]) -> str:
    """What a folder held that detect does not read, and how to read it, in a few words."""
    from laughlab.io.audio import convert_hint

    return f"{len(files)} file(s){convert_hint(files)}"


#: in --out, the names of the files the last ``detect`` wrote there (so that ``--overwrite`` removes only those)
MANIFEST = ".laughlab-detect.json"


def written_before(out: Path) -> frozenset:
    """The resolved paths of the files an earlier ``detect`` wrote into ``out`` (its manifest), not recordings."""
    names, _ = read_record(out / MANIFEST) or (set(), {})
    return frozenset((out / n).resolve() for n in names)


def out_folder_check(out: Path, overwrite: bool, planned: list[str]) -> list[Path]:
    """Refuse an --out that is a file, or a folder already holding files unless ``overwrite``, before any work
    (nothing the user has is replaced without asking).  With ``overwrite``: refuse when a file this run would
    write (``planned`` names) is there and an earlier ``detect`` did not write it (its manifest): a hand-made
    ``NAME.TextGrid`` beside ``NAME.wav`` is the user's.  Returns the files an earlier ``detect`` wrote there,
    to be removed once this run's are written unless this run writes them again."""
    if out.exists() and not out.is_dir():
        raise LaughlabError(f"--out {out} is a file, not a folder")
    held = sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) if out.is_dir() else []
    if held and not overwrite:
        raise LaughlabError(f"{out} already holds files ({shown_names(held)}); choose another --out or add --overwrite "
                            f"(replaces everything an earlier detect wrote there, its other recordings' files too; "
                            "keeps files of yours)")
    names, sums = read_record(out / MANIFEST) or (set(), {})
    # a label file edited since detect wrote it (corrected in Praat or Audacity: the documented loop) is the user's
    # now (a diff review: --overwrite replaced the corrections without a word)
    edited = set(edited_since(out, names, sums))
    names -= edited
    there = {n for n in set(planned) | names if (out / n).is_file()}
    theirs = sorted(set(planned) & (there | edited) - names)
    if theirs:
        one = len(theirs) == 1   # "it" of several files (a review)
        why = f"edited since detect wrote {'it' if one else 'them'}" if set(theirs) <= edited else \
            "which no earlier detect wrote there"
        raise LaughlabError(f"{out} holds {shown_names(theirs)}, {why}, and this run would replace "
                            f"{'it; move it' if one else 'them; move them'} or choose another --out (--overwrite "
                            "replaces only detect's own files, unedited)")
    return [out / n for n in sorted(names & there)]


def read_start(path: Path) -> None:
    """Decode a recording's first block (a second): a file damaged right past its header fails here, before any
    work, as reading it whole would fail at its turn."""
    from laughlab.io.audio import read_blocks

    next(iter(read_blocks(path, 1.0)), None)


def main(argv: list[str]) -> None:
    ap = one_line_parser(prog="python -m laughlab detect",
                         description="Laughter segments of recordings (YAMNet and a head fitted on the corpus' "
                                     "train split; offline: centred windows, smoothed both ways). Writes "
                                     "segments.csv (file, start, end in seconds, probability; a row a segment), "
                                     "recordings.csv (a row a recording, with the settings) and "
                                     "per recording NAME.txt (Audacity) and NAME.TextGrid (Praat, tier laughter); "
                                     "docs/detector.md, 'Offline'.")
    ap.add_argument("paths", nargs="+", help="audio files or folders")
    ap.add_argument("--out", default="laughter_segments",
                    help="output folder (default: laughter_segments), written when every input is done; one that "
                         "already holds files is refused without --overwrite")
    ap.add_argument("--threshold", type=float, default=0.5, help="laughter probability threshold (default 0.5)")
    ap.add_argument("--min-length", type=float, default=0.2, help="shortest segment kept (s, default 0.2)")
    ap.add_argument("--hop", type=float, default=0.5, help="time between model windows (s, default 0.5)")
    ap.add_argument("--smooth", type=int, default=3,
                    help="centred moving average over this many windows, odd (default 3)")
    ap.add_argument("--formats", default="csv,audacity,textgrid", help="comma-separated: csv, audacity, textgrid, elan, audio (each laugh as NAME_laugh_K.wav; "
                         "default: the first three)")
    ap.add_argument("--channels", choices=("mix", "each"), default="mix",
                    help="mix: a recording's channels mixed (default); each: every channel of a multichannel "
                         "recording its own input, NAME.ch1, NAME.ch2, ... (a dyad, one speaker a channel), and "
                         "NAME.TextGrid a tier a channel")
    ap.add_argument("--progress", choices=("auto", "on", "off"), default="auto",
                    help="a progress bar on stderr: auto (default) when the inputs are over a minute in all")
    ap.add_argument("--overwrite", action="store_true",
                    help="write into an --out folder that already holds files: everything an earlier detect wrote "
                         "there is replaced by this run's output, its files of recordings this run does not read "
                         "removed (said in a line); files of yours are kept, and one by a name this run writes "
                         "(NAME.TextGrid beside NAME.wav) is refused")
    ap.add_argument("--score", action="store_true",
                    help="score the segments against each input's annotation beside it (NAME.truth.csv, NAME.txt, "
                         "NAME.TextGrid or NAME.eaf): bouts found, frame precision, recall and F1, segments outside "
                         "laughter, in scores.csv and the closing line")
    ap.add_argument("--skip-unreadable", action="store_true",
                    help="leave out an input that cannot be read (one line on stderr each) instead of stopping "
                         "the batch before any work")
    ns = ap.parse_args(argv)
    if not 0.0 <= ns.threshold <= 1.0:
        raise LaughlabError(f"--threshold must be in [0, 1] (got {ns.threshold})")
    if not ns.min_length >= 0.0:
        raise LaughlabError(f"--min-length must be >= 0 (got {ns.min_length})")
    if not 0.05 <= ns.hop <= 2.0:
        raise LaughlabError(f"--hop must be in [0.05, 2] s (got {ns.hop})")
    if ns.smooth < 1 or ns.smooth % 2 == 0:   # an even count is not centred: 4 looked a window further ahead than back,
        # its segments half a hop late (the detect review: --hop 0.1 --smooth 4 started where --smooth 1 did, 3 and 5 a
        # window earlier)
        raise LaughlabError(f"--smooth must be a positive odd number of windows (a centred average: 1, 3, 5, ...; "
                            f"got {ns.smooth})")
    if ns.out.strip() in ("-", ""):
        raise LaughlabError(f"--out {ns.out!r}: detect writes files into a folder (segments.csv and a label file a "
                            "recording); give a folder's name")
    formats = tuple(f.strip().lower() for f in ns.formats.split(",") if f.strip())   # TextGrid as Praat spells it
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise LaughlabError(f"unknown format {bad[0] if bad else '(none)'}: choose from {', '.join(FORMATS)}")
    from laughlab.detector import detect_score as DS
    from laughlab.detector import segments as S
    from laughlab.detector.yamnet import LaughterScore, ModelFileError, Yamnet
    from laughlab.io.audio import probe_file, read_blocks

    named = [(f, name, None) for f, name in inputs(ns.paths)]
    if ns.channels == "each":   # every channel its own input (a mono file stays as it is)
        named = [(f, f"{name}.ch{c + 1}" if k > 1 else name, c if k > 1 else None)
                 for f, name, _ in named for k in [_channels(f)] for c in range(k)]
        names = [n for _, n, _ in named]
        keys = [_folded(n) for n in names]
        counts = collections.Counter(keys)
        dup = next((n for n, k in zip(names, keys) if counts[k] > 1), None)
        if dup:   # take.wav's second channel and a file take.ch2.wav
            raise LaughlabError(f"two inputs share the name {dup!r} with --channels each: rename the file {dup}.*")
    scored = ["scores.csv"] if ns.score else []
    # --channels each: a multichannel recording's name, for the TextGrid of all its channels' tiers (no other input
    # has it: two inputs of one name are refused above)
    recording_of = {n: S.recording_name(n) for _, n, c in named if c is not None}
    stale = out_folder_check(Path(ns.out), ns.overwrite, S.output_names([n for _, n, _ in named], formats,
                                                                        list(recording_of.values())) + scored)
    total_s, kept, gone, durations = 0.0, [], {}, {}   # gone: the inputs left out (--skip-unreadable): name -> why
    order = {n: i for i, (_, n, _) in enumerate(named)}   # recordings.csv's rows, skipped ones among them

    bar = None

    def unreadable(name: str, exc: LaughlabError) -> None:
        """An input found unreadable while the batch runs stops it, or with --skip-unreadable is left out in one
        stderr line (above the progress bar, not into its line; its seconds taken off the bar's total)."""
        if not ns.skip_unreadable:
            raise LaughlabError(f"{exc} (--skip-unreadable leaves such files out)") from None
        if bar is not None:
            bar.total = max(bar.n, bar.total - durations.get(name, 0.0))
            bar.write(f"laughlab: skipped: {exc}", file=sys.stderr)
            bar.refresh()
        else:
            print(f"laughlab: skipped: {exc}", file=sys.stderr)
        gone[name] = str(exc)

    bad = []
    for f, name, channel in named:  # every input checked before any work or any file written: its header and first
        try:                        # block decoded (a file damaged past its header stopped the batch at its turn)
            info = probe_file(f)
            read_start(f)
        except LaughlabError as exc:
            bad.append((name, exc))
            continue
        kept.append((f, name, channel))
        durations[name] = info.frames / info.samplerate
        total_s += durations[name]
    if bad and not ns.skip_unreadable:   # every one in the line, not the first alone (a review)
        raise LaughlabError(f"{counted(len(bad), 'input')} cannot be read: "
                            + "; ".join(str(exc) for _, exc in bad[:5]) + ("; ..." if len(bad) > 5 else "")
                            + " (--skip-unreadable leaves such files out)")
    for name, exc in bad:
        unreadable(name, exc)
    if not kept:
        raise LaughlabError("no readable audio among the inputs")
    named = kept
    # an earlier detect's labels are not truths: those its manifest lists, in --out or in an input's own folder
    # (a review: labels a detect had written beside the recordings were scored as their annotations)
    folders = {Path(ns.out)} | {Path(f).parent for f, _, _ in named} if ns.score else set()
    ours = frozenset((d / n).resolve() for d in folders for n in ((read_record(d / MANIFEST) or ((),))[0]))
    truths = DS.find_truths(named, durations, ours) if ns.score else {}   # checked before any work
    try:
        model, score = Yamnet(), LaughterScore()
    except ModelFileError as exc:
        raise LaughlabError(str(exc)) from None
    show = ns.progress == "on" or (ns.progress == "auto" and total_s > 60.0)
    if show:  # seconds of audio, to 0.1 s
        from laughlab.core.progress import bar as progress_bar

        bar = progress_bar(total_s, "detect", "s of audio", digits=1, unit="s", leave=False,
                           bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s of audio "
                                      "[{elapsed}<{remaining}]")
    t0 = time.perf_counter()
    results = []
    from laughlab.detector import detect_cache as DC

    cache = DC.DetectCache({"hop": ns.hop, "smooth": ns.smooth, "threshold": ns.threshold, "min_length": ns.min_length})
    reused = 0
    try:
        for f, name, channel in named:
            key = DC.file_key(f)          # before it is read: a file changed while it is computed is not kept
            hit = cache.get(key, channel)   # an earlier, unfinished run of these settings found it (the file unchanged)
            if hit is not None:
                results.append((name, hit[0], hit[1], f, channel))
                reused += 1
                if bar is not None:
                    bar.update(durations[name])
                continue
            before = bar.n if bar is not None else 0.0
            try:   # block by block: the 16 kHz samples alone held (the whole file was, 0.9 GB an hour at 48 kHz)
                info = probe_file(f)
                t, p, n = S.laughter_prob_blocks(read_blocks(f, 10.0, channel), info.samplerate, ns.hop, model,
                                                 score, None if bar is None else bar.update, info.frames)
            except LaughlabError as exc:  # damaged past its header: found only when read
                if bar is not None:   # its seconds read so far off the bar too (a diff review: 61.7/31.7 s)
                    bar.n = before
                unreadable(name, exc)
                continue
            p = S.smooth(p, ns.smooth)
            dur = n / info.samplerate
            results.append((name, dur, S.segments(t, p, ns.hop, ns.threshold, ns.min_length, dur), f, channel))
            if DC.file_key(f) == key:
                cache.put(key, channel, dur, results[-1][2])
            else:
                cache.ok = False
    except KeyboardInterrupt:   # before any file is written: say so (a review: "interrupted" left it to guess)
        if bar is not None:
            bar.close()
            bar = None
        from laughlab.core.interrupts import exit_interrupted

        exit_interrupted(f"interrupted after {len(results)} of {len(named)} input(s); nothing was written to "
                         f"{ns.out} (detect writes when every input is done)"
                         + ("; the same command goes on from there" if cache.ok else ""))
    finally:   # also on Ctrl-C: the error line then starts a line of its own, not the end of the bar's (a review)
        if bar is not None:
            bar.close()
    if not results:
        raise LaughlabError("no readable audio among the inputs")
    out = Path(ns.out)
    # the manifest first lists every name this run may leave (the earlier run's and this one's): a run stopped
    # while writing leaves no file that a later --overwrite would take for the user's
    planned = S.output_names([r[0] for r in results], formats, list(S.channel_groups(results))) + \
        S.clip_names(results, formats) + scored
    score_rows = DS.score_rows(results, truths) if ns.score else []
    if "audio" in formats:   # the clips' names are known now: a file of yours by one of them is refused as above
        stale = out_folder_check(out, ns.overwrite, planned)

    def rel(paths):
        return {p.relative_to(out).as_posix() for p in paths}

    fresh = not out.exists()
    try:
        # the earlier run's hashes kept: a run stopped here leaves its files' record as it was (their edits found)
        sums = (read_record(out / MANIFEST) or (set(), {}))[1]
        names = sorted(rel(stale) | set(planned))
        S.atomic_write(out / MANIFEST, json.dumps({"files": names, "sha256": {n: sums[n] for n in names if n in sums}},
                                                  indent=1) + "\n")
        written = S.write_outputs(out, results, formats,   # all or none
                                  {"scores.csv": DS.scores_text(score_rows)} if ns.score else None,
                                  {"threshold": ns.threshold, "min_length_s": ns.min_length, "hop_s": ns.hop,
                                   "smooth_windows": ns.smooth, "channels": ns.channels},
                                  gone, order)
    except BaseException:   # a Ctrl-C or a full disk: a folder this run made goes (its manifest alone was left)
        if fresh:
            remove(out)
        raise
    # an earlier detect's files of an input skipped now stay (it could not be read again: its labels are not stale)
    theirs = set(S.output_names(gone, formats, [recording_of[g] for g in gone if g in recording_of])) - rel(written)
    clip = re.compile("|".join(f"{re.escape(g)}_laugh_[0-9]+\\.wav" for g in gone) or "(?!)")   # their clips
    kept_old = {p for p in stale if p.relative_to(out).as_posix() in theirs
                or clip.fullmatch(p.relative_to(out).as_posix())}
    dropped = sorted(set(stale) - set(written) - kept_old)
    with deferred():   # the old files' removal and the manifest that says so, not cut in two by a Ctrl-C
        unwrite(dropped, out)   # --overwrite: an earlier detect's files not written now
        done = sorted(rel(written) | rel(kept_old))
        S.atomic_write(out / MANIFEST, record_text(out, done))
    wall = time.perf_counter() - t0
    read = set(S.output_names([r[0] for r in results], FORMATS, list(S.channel_groups(results))))   # and their clips
    others = sorted(n for n in rel(dropped) if n not in read and not any(
        n.startswith(f"{r[0]}_laugh_") for r in results))
    if others:   # a review: a run of one recording into a batch's folder removed the other recordings' files unsaid
        print(f"laughlab: --overwrite removed {counted(len(others), 'file')} an earlier detect wrote into {out} for "
              f"recordings this run did not read ({shown_names(others)})", file=sys.stderr)
    cache.forget()   # written whole: a later run computes afresh
    if reused:
        print(f"laughlab: {reused} of {len(results)} input(s) as an earlier, unfinished run of these settings found "
              "them", file=sys.stderr)
    print(summary_line(results, list(gone), wall, out)
          + DS.score_summary(score_rows, sum(r[0] not in truths for r in results)))


def _folded(name: str) -> str:
    """A name as a case-insensitive file system compares it: one Unicode form (NFC: macOS keeps NFD), lower case
    (not casefold, which makes 'ß' 'ss': Straße and Strasse are two files everywhere)."""
    import unicodedata

    return unicodedata.normalize("NFC", name).lower()


def _channels(path: Path) -> int:
    """A recording's channel count (1 for a file soundfile cannot read: the check before any work says why)."""
    import soundfile as sf

    try:
        return sf.info(str(path)).channels
    except Exception:   # noqa: BLE001 - any unreadable file: probe_file's line names it
        return 1


def summary_line(results: list, skipped: list[str], wall: float, out: Path) -> str:   # skipped: their names
    """The closing line: files, audio, segments, how many files had none (no row in segments.csv, a row in
    recordings.csv, an empty TextGrid tier), how many were skipped, and the speed."""
    n = sum(len(r[2]) for r in results)
    audio_s = sum(r[1] for r in results)
    none = sum(1 for r in results if not r[2])
    # --channels each: a stereo file is one file of two inputs (it was counted as 2 files, a new-user review)
    files = len({(str(r[3]) if len(r) > 3 else r[0]) for r in results})
    apart = f" as {len(results)} inputs (a channel each)" if files < len(results) else ""
    extra = "".join([f", {none} without laughter" if none else "", f", {len(skipped)} skipped" if skipped else ""])
    return (f"laughlab: {files} file(s){apart}{extra}, {audio_s:.1f} s of audio, {n} laughter segment(s) in "
            f"{duration_text(wall)} ({factor_text(audio_s / max(wall, 1e-9))}x real time) -> {out}/")
