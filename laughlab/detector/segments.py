"""Laughter segments of whole recordings (offline), their files, and their scores against a truth.

:func:`laughter_prob` runs YAMNet over a whole signal, one window every ``hop_s``; the
head's probability of a window ending at ``e`` is about ``[e - 0.5 s, e]``
(``yamnet_fit.LABEL_S``), so offline it is placed at ``e - 0.25 s``: the window reaches
0.74 s past the time it speaks for (look-ahead is allowed offline).  The probabilities
are smoothed both ways (a centred moving average of ``smooth`` windows), cut at a
threshold, and runs shorter than ``min_length_s`` dropped (as Gillick et al.'s
``segment_laughter.py``: threshold 0.5, minimum length 0.2 s).  A recording shorter
than a window is padded with zeros (silence) either side.

Files: one CSV for a whole command (``file,start,end,probability``), and per input an
Audacity label file (``NAME.txt``: ``start<TAB>end<TAB>laugh``) and a Praat TextGrid
(``NAME.TextGrid``, tier ``laughter``); on request ELAN (``NAME.eaf``) and each laugh's audio
(``NAME_laugh_K.wav``).  :func:`read_folder` reads such a folder back
(Audacity labels, or a CSV with ``file,start,end``), ours or a peer detector's, and
:func:`score` compares segments with a truth file, so both are scored by the same code
(``benchmarks/bench_detector.py --peer DIR``).
"""
from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError
from laughlab.detector.yamnet_model import noise_vetoes

#: the time a window's probability speaks for, before the window's end (s)
SPEAKS_FOR_S = 0.25


@dataclass(frozen=True)
class Segment:
    start: float
    end: float
    prob: float = 1.0


def laughter_prob(audio: np.ndarray, sample_rate: int, hop_s: float = 0.5, model=None, score=None, progress=None):
    """(times (s), probabilities) of a whole signal: the head's probability, one window every ``hop_s``
    (``progress``: see :func:`laughlab.detector.yamnet.window_scores`)."""
    from laughlab.detector.yamnet import chunks

    t, p, _ = laughter_prob_blocks(chunks(audio), sample_rate, hop_s, model, score, progress, np.size(audio))
    return t, p


def window_grid(n: int, sample_rate: int, hop_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(times (s), window ends (input samples)) of a signal of ``n`` samples: a window for every hop that begins
    inside the recording, the last one too (it stopped at the last whole hop's centre, and a recording's tail
    shorter than half a hop was never judged: 4.9 s of laughter at --hop 2 was labelled to 4.0 s, a new-user
    review); the tail's window ends at most ``SPEAKS_FOR_S`` past the recording (zeros after it), as every other
    one does.  A window whose time is inside the first ``n`` samples has the same time and end for every longer
    signal (``np.arange`` makes its values from the start)."""
    sr = int(sample_rate)
    dur = n / sr
    times = np.arange(hop_s / 2.0, max(dur + hop_s / 2.0 - 1e-9, hop_s / 2.0 + 1e-9), hop_s)
    return times, np.round(np.minimum(times + SPEAKS_FOR_S, dur + SPEAKS_FOR_S) * sr).astype(np.int64)


def laughter_prob_blocks(blocks, sample_rate: int, hop_s: float = 0.5, model=None, score=None, progress=None,
                         frames_hint: int = 0):
    """:func:`laughter_prob` of a signal given block by block (``detect`` reads a file so: it holds the 16 kHz
    samples alone, :class:`laughlab.detector.yamnet.WindowScores`), the same values bit for bit whatever the
    blocks; a window goes to the model once the samples up to its time have arrived, the last ones when the
    signal's length is known.  (times, probabilities, samples read)."""
    from laughlab.detector.yamnet import LaughterScore, WindowScores, Yamnet

    sr = int(sample_rate)
    w, k = WindowScores(sr, model or Yamnet(), frames_hint), 0   # k: the windows wanted so far
    for b in blocks:
        w.push(b)
        if progress is not None:
            progress(np.size(b) / sr)
        times, ends = window_grid(w.n, sr, hop_s)
        sure = int(np.searchsorted(times, w.n / sr, side="right"))   # their ends can no longer change
        if sure > k:
            w.want(ends[k:sure])
            k = sure
    times, ends = window_grid(w.n, sr, hop_s)
    w.want(ends[k:])
    S = w.finish()
    score = score or LaughterScore()
    return times, np.array([_prob(score, s) for s in S]), w.n


def _prob(score, s: np.ndarray) -> float:
    """A window's laughter probability, 0 where steady noise is louder than laughter (the live gate's
    ``noise_veto``: 3 s of white noise gave a segment, a new-user review)."""
    p, q = score.both(s)
    return 0.0 if noise_vetoes(score.noise(s), q) else p


def smooth(p: np.ndarray, n: int) -> np.ndarray:
    """Centred moving average over ``n`` values (odd; the edges averaged over what exists), as long as ``p``.

    The middle of the full convolution, not numpy's ``"same"``: that is as long as the longer of its inputs,
    so a file with fewer windows than ``n`` got ``n`` values, shifted, and a run reaching past its last
    window ended in an IndexError (before 2026-11-26).  For ``len(p) >= n`` the values are the same bits."""
    if n <= 1 or len(p) == 0:
        return p.copy()
    k, h, m = np.ones(n), (n - 1) // 2, len(p)
    return np.convolve(p, k)[h:h + m] / np.convolve(np.ones(m), k)[h:h + m]


def segments(times: np.ndarray, p: np.ndarray, hop_s: float, threshold: float = 0.5, min_length_s: float = 0.2,
             duration_s: float | None = None) -> list[Segment]:
    """Runs of ``p >= threshold``; each value covers ``time +- hop_s / 2``; runs shorter than ``min_length_s`` dropped."""
    on = p >= threshold
    out = []
    k = 0
    n = len(p)
    end_cap = duration_s if duration_s is not None else math.inf
    while k < n:
        if not on[k]:
            k += 1
            continue
        j = k
        while j + 1 < n and on[j + 1]:
            j += 1
        a, b = max(0.0, times[k] - hop_s / 2.0), min(end_cap, times[j] + hop_s / 2.0)
        if b - a >= min_length_s - 1e-9:   # to 0.1 ms, the end never past the recording's (a review: 4 us past)
            out.append(Segment(round(float(a), 4), min(round(float(b), 4), floor_to(end_cap, 4)),
                               round(float(p[k:j + 1].mean()), 4)))
        k = j + 1
    return out


def floor_to(t: float, digits: int) -> float:
    """``t`` (s) rounded down to ``digits`` decimals, as written: a time that stays inside a recording of ``t`` s
    (a duration that already has ``digits`` decimals is kept: no 5.8376 -> 5.8375 from its binary form)."""
    if not math.isfinite(t):
        return t
    q = 10 ** digits
    return math.floor(t * q + 1e-6) / q


def atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)   # a name with folders (a tree of recordings)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def audacity_text(segs: list[Segment]) -> str:
    return "".join(f"{s.start:.4f}\t{s.end:.4f}\tlaugh\n" for s in segs)   # the corpus' label: a folder's annotation


def textgrid_text(segs: list[Segment], duration_s: float) -> str:
    """A Praat TextGrid (long text format), one interval tier ``laughter``: ``laugh`` or empty.

    Times are written to 0.1 ms, as the segments are: the duration too is rounded (down) first, so a segment that
    ends with the recording leaves no empty interval of zero length after it (Praat and praatio refuse one); a
    recording shorter than 0.1 ms gets one interval of 0.1 ms (a review: a 1-sample file's 0 to 0 was refused)."""
    return textgrid_tiers([("laughter", segs)], duration_s)


def textgrid_tiers(tiers: list[tuple[str, list[Segment]]], duration_s: float) -> str:
    """A Praat TextGrid (long text format) of interval tiers ``(name, segments)``, as :func:`textgrid_text`'s."""
    duration_s = max(floor_to(float(duration_s), 4), 1e-4)
    lines = ['File type = "ooTextFile"', 'Object class = "TextGrid"', "", "xmin = 0", f"xmax = {duration_s:.4f}",
             "tiers? <exists>", f"size = {len(tiers)}", "item []:"]
    for k, (name, segs) in enumerate(tiers, 1):
        iv = []
        t = 0.0
        for s in segs:
            if s.start > t:
                iv.append((t, s.start, ""))
            iv.append((s.start, s.end, "laugh"))
            t = s.end
        if duration_s > t or not iv:
            iv.append((t, max(duration_s, t), ""))
        lines += [f"    item [{k}]:", '        class = "IntervalTier"', f'        name = "{name}"', "        xmin = 0",
                  f"        xmax = {duration_s:.4f}", f"        intervals: size = {len(iv)}"]
        for i, (a, b, lab) in enumerate(iv, 1):
            lines += [f"        intervals [{i}]:", f"            xmin = {a:.4f}", f"            xmax = {b:.4f}",
                      f'            text = "{lab}"']
    return "\n".join(lines) + "\n"


def recording_name(channel_input: str) -> str:
    """The recording a ``--channels each`` input is a channel of: ``take`` of ``take.ch2``."""
    return channel_input.rsplit(".ch", 1)[0]


def channel_groups(results: list) -> dict[str, list[tuple]]:
    """``--channels each``: the channel inputs of each multichannel recording, by its name (:func:`recording_name`),
    in channel order (a result's fifth item is its channel; None for a recording read whole)."""
    out: dict[str, list[tuple]] = {}
    for r in results:
        if len(r) > 4 and r[4] is not None:
            out.setdefault(recording_name(r[0]), []).append(r)
    return out


#: ELAN's MIME types of the recordings it links (any other audio: ``audio/*``, ELAN's GENERIC_AUDIO_TYPE, which it
#: gives an mp3 too: "audio/mpeg" is none of ELAN's types, and it took such an mp3 for a video, not audio)
MIME_TYPES = {".wav": "audio/x-wav"}


def elan_url(path: Path) -> str:
    """``path`` (absolute) as ELAN's own MEDIA_URL: ``file:///`` and the path with forward slashes, not
    percent-encoded; a path starting with two slashes (a network share) keeps ``file://`` (ELAN's
    ``FileUtility.pathToURLString``)."""
    p = path.as_posix()
    rest = p.lstrip("/")
    return ("file://" if len(p) - len(rest) == 2 else "file:///") + rest


def eaf_text(segs: list[Segment], media: Path | None = None, beside: Path | None = None,
             duration_s: float = math.inf) -> str:
    """An ELAN annotation document (EAF 3.0): one time-alignable tier ``laughter``, ``laugh`` per segment.

    Times in whole milliseconds (ELAN's unit) and a fixed DATE, so the same input gives the same bytes.
    ``media``: the recording, linked in the header (its absolute ``file:`` URL, and its path relative to
    ``beside``, the EAF's folder, which ELAN tries when the folders have moved together); None: no link, and
    ELAN asks for the recording when the file is opened.  No time past ``duration_s`` (whole ms, rounded down)."""
    import os
    from xml.sax.saxutils import quoteattr

    header = ['    <HEADER MEDIA_FILE="" TIME_UNITS="milliseconds"/>']
    if media is not None:
        media = Path(media).resolve()
        try:
            rel = Path(os.path.relpath(media, Path(beside).resolve())).as_posix() if beside is not None else media.name
            rel = rel if rel.startswith("..") else f"./{rel}"
        except ValueError:   # on Windows, another drive than --out's: no relative path (ELAN's getRelativePath: null)
            rel = None
        # both links as ELAN writes and reads them: the path itself, not percent-encoded (ELAN's
        # FileUtility.pathToURLString; its checkMedia opens what follows "file:" as it stands, so "day%201" or
        # "M%C3%BCller" is a file it does not find and it asks for the recording)
        header = ['    <HEADER MEDIA_FILE="" TIME_UNITS="milliseconds">',
                  f"        <MEDIA_DESCRIPTOR MEDIA_URL={quoteattr(elan_url(media))} "
                  f"MIME_TYPE={quoteattr(MIME_TYPES.get(media.suffix.lower(), 'audio/*'))}"
                  + (f" RELATIVE_MEDIA_URL={quoteattr(rel)}" if rel is not None else "") + "/>",
                  "    </HEADER>"]

    slots, anns = [], []
    for i, seg in enumerate(segs):
        a, b = 2 * i + 1, 2 * i + 2
        slots += [f'        <TIME_SLOT TIME_SLOT_ID="ts{a}" TIME_VALUE="{int(round(seg.start * 1000))}"/>',
                  f'        <TIME_SLOT TIME_SLOT_ID="ts{b}" TIME_VALUE="{int(min(round(seg.end * 1000), floor_to(duration_s * 1000, 0)))}"/>']
        anns += ["        <ANNOTATION>",
                 f'            <ALIGNABLE_ANNOTATION ANNOTATION_ID="a{i + 1}" TIME_SLOT_REF1="ts{a}" '
                 f'TIME_SLOT_REF2="ts{b}">',
                 "                <ANNOTATION_VALUE>laugh</ANNOTATION_VALUE>",
                 "            </ALIGNABLE_ANNOTATION>", "        </ANNOTATION>"]
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<ANNOTATION_DOCUMENT AUTHOR=' + quoteattr("laughlab detect") + ' DATE="1970-01-01T00:00:00Z" '
             'FORMAT="3.0" VERSION="3.0" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
             'xsi:noNamespaceSchemaLocation="http://www.mpi.nl/tools/elan/EAFv3.0.xsd">',
             *header,
             "    <TIME_ORDER>" if slots else "    <TIME_ORDER/>", *slots, *(["    </TIME_ORDER>"] if slots else []),
             '    <TIER LINGUISTIC_TYPE_REF="default-lt" TIER_ID="laughter">' if anns else
             '    <TIER LINGUISTIC_TYPE_REF="default-lt" TIER_ID="laughter"/>',
             *anns, *(["    </TIER>"] if anns else []),
             '    <LINGUISTIC_TYPE GRAPHIC_REFERENCES="false" LINGUISTIC_TYPE_ID="default-lt" TIME_ALIGNABLE="true"/>',
             "</ANNOTATION_DOCUMENT>"]
    return "\n".join(lines) + "\n"


#: the per-input file of each format (``NAME`` + suffix); ``csv`` is one ``segments.csv`` for every input
SUFFIXES = {"audacity": ".txt", "textgrid": ".TextGrid", "elan": ".eaf"}


def output_names(stems: list[str], formats: tuple[str, ...], recordings: list[str] = ()) -> list[str]:
    """The names ``write_outputs`` writes for inputs ``stems`` in ``formats``, in its order; ``recordings``: the
    names of multichannel recordings read a channel each (:func:`channel_groups`), each one TextGrid of its own."""
    names = [stem + suffix for stem in stems for f, suffix in SUFFIXES.items() if f in formats]
    names += [r + SUFFIXES["textgrid"] for r in dict.fromkeys(recordings)] if "textgrid" in formats else []
    return names + (["segments.csv", "recordings.csv"] if "csv" in formats else [])


def recordings_text(results: list, settings: dict, skipped: dict[str, str] | None = None,
                    order: dict[str, int] | None = None) -> str:
    """``recordings.csv``: a row an input, those without laughter too (``segments.csv`` has no row for them, so "no
    laughter" and "not read" looked alike: a data user's review): its name, length (s), segments and their seconds,
    then the settings that made them (``settings``: name -> value), the same in every row, to join on, and
    ``skipped``: empty, or for an input ``--skip-unreadable`` left out (``skipped``: name -> reason; a row with no
    length or segments since 2026-11-29: they were missing from the table, said on stderr alone), the rows in the
    inputs' ``order`` (name -> place) when given, else the read ones first."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(["file", "duration_s", "segments", "laughter_s", *settings, "skipped"])
    rows = [[name, f"{dur:.4f}", len(segs), f"{sum(s.end - s.start for s in segs):.4f}", *settings.values(), ""]
            for name, dur, segs, *_ in results]
    rows += [[name, "", "", "", *settings.values(), why] for name, why in (skipped or {}).items()]
    w.writerows(sorted(rows, key=lambda r: order.get(r[0], len(order))) if order else rows)
    return text.getvalue()


def clip_names(results: list, formats: tuple[str, ...]) -> list[str]:
    """With ``audio`` in ``formats``: ``NAME_laugh_K.wav`` for segment ``K`` (from 0) of each input ``NAME``, as
    ``segment_laughter.py`` numbers its ``laugh_K.wav`` (Gillick et al. 2021)."""
    return [f"{r[0]}_laugh_{i}.wav" for r in results for i in range(len(r[2]))] if "audio" in formats else []


#: libsndfile's command (sndfile.h) that leaves out a float WAV's PEAK chunk, whose time stamp changes every run
SFC_SET_ADD_PEAK_CHUNK = 0x1050


def write_clip(path: Path, media: Path, seg: Segment, channel: int | None = None) -> None:
    """The recording's samples ``[round(start * sr), round(end * sr))`` as a WAV file at ``path`` (a staging file:
    :func:`write_outputs`): its own rate and channels (or channel ``channel`` alone), its own sample format where
    WAV holds it (16-bit PCM for a compressed recording)."""
    import soundfile as sf

    info = sf.info(str(media))
    subtype = info.subtype if info.subtype in ("PCM_U8", "PCM_16", "PCM_24", "PCM_32", "FLOAT", "DOUBLE") else "PCM_16"
    x, sr = sf.read(str(media), start=round(seg.start * info.samplerate), stop=round(seg.end * info.samplerate),
                    always_2d=True, dtype="float64" if subtype in ("FLOAT", "DOUBLE") else "int32")
    if channel is not None:
        x = x[:, channel]
    if x.ndim == 1:   # one channel picked (an empty clip too: reshape(0, -1) failed, a diff review)
        x = x[:, None]
    with sf.SoundFile(str(path), "w", sr, x.shape[1], subtype=subtype, format="WAV") as f:
        if subtype in ("FLOAT", "DOUBLE"):   # libsndfile's PEAK chunk holds the time it was written: a float
            try:                            # recording's clips were other bytes on every run (a review at scale)
                sf._snd.sf_command(f._file, SFC_SET_ADD_PEAK_CHUNK, sf._ffi.NULL, 0)
            except AttributeError:   # a soundfile without its libsndfile handle: the chunk stays
                pass
        f.write(x)


def write_outputs(out_dir: Path, results: list[tuple[str, float, list[Segment]]], formats: tuple[str, ...],
                  extra: dict[str, str] | None = None, settings: dict | None = None,
                  skipped: dict[str, str] | None = None, order: dict[str, int] | None = None) -> list[Path]:
    """Write ``segments.csv``, ``recordings.csv`` (with ``settings`` and ``skipped``: :func:`recordings_text`) and
    per-input
    ``NAME.txt`` / ``NAME.TextGrid`` / ``NAME.eaf`` (and with ``audio`` each
    laugh as ``NAME_laugh_K.wav``, from the recording, the results' fourth item), and ``extra``'s files (name ->
    text: ``scores.csv``); all of them or none.

    Each file is written under a hidden temporary name beside its place, and all are moved into place together at
    the end, a stop signal held off while they move (:func:`laughlab.core.interrupts.deferred`); a failure or a
    Ctrl-C before that removes the temporary files.  Each file was moved into place as it was written: a Ctrl-C
    while the clips were written left 85 of 146 of them and no ``segments.csv`` (a new-user review, 2026-11-28)."""
    from laughlab.core.interrupts import deferred
    from laughlab.core.outfiles import Staging

    stage, written = Staging(), []

    def put(final: Path, text: str) -> None:
        written.append(final)
        stage.path(final).write_text(text, encoding="utf-8")

    try:
        for name, dur, segs, *media in results:   # (stem, duration, segments[, the recording's path])
            text = {"audacity": lambda: audacity_text(segs), "textgrid": lambda: textgrid_text(segs, dur),
                    "elan": lambda: eaf_text(segs, media[0] if media else None, (out_dir / name).parent, dur)}
            for f, suffix in SUFFIXES.items():
                if f in formats:
                    put(out_dir / (name + suffix), text[f]())
            for i, seg in enumerate(segs if "audio" in formats else []):
                written.append(out_dir / f"{name}_laugh_{i}.wav")
                write_clip(stage.path(written[-1]), media[0], seg, media[1] if len(media) > 1 else None)
        if "textgrid" in formats:   # --channels each: a recording's channels as the tiers of one TextGrid too
            for rec, chans in channel_groups(results).items():
                put(out_dir / (rec + SUFFIXES["textgrid"]),
                    textgrid_tiers([(f"laughter-ch{r[4] + 1}", r[2]) for r in chans], max(r[1] for r in chans)))
        if "csv" in formats:   # through csv: a name with a comma or a quote is quoted (a review: it split the row)
            text = io.StringIO()
            w = csv.writer(text, lineterminator="\n")
            w.writerow(["file", "start", "end", "probability"])
            w.writerows([name, f"{s.start:.4f}", f"{s.end:.4f}", f"{s.prob:.4f}"] for name, _, segs, *_ in results
                        for s in segs)
            put(out_dir / "segments.csv", text.getvalue())
            put(out_dir / "recordings.csv", recordings_text(results, settings or {}, skipped, order))
        for name, text in (extra or {}).items():
            put(out_dir / name, text)
        with deferred():
            stage.commit()
    except BaseException:
        stage.abort()
        raise
    return written


def read_folder(folder: str | Path) -> dict[str, list[Segment]]:
    """Segments by file stem from a folder of Audacity label files (``NAME.txt``) and/or CSVs with
    ``file,start,end`` columns (ours or a peer detector's); a stem with a label file takes its segments
    from it.  A stem absent from both has no entry (callers count it as no segment)."""
    d = Path(folder)
    if not d.is_dir():
        raise LaughlabError(f"segment folder not found: {folder}")
    out: dict[str, list[Segment]] = {}
    from_csv: dict[str, list[Segment]] = {}
    for f in sorted(d.iterdir()):
        if f.suffix == ".txt":
            segs = []
            for line in f.read_text(encoding="utf-8").splitlines():
                parts = line.split("\t")
                if len(parts) >= 2 and parts[0].strip() not in ("", "\\"):
                    segs.append(Segment(float(parts[0]), float(parts[1])))
            out[f.stem] = segs
        elif f.suffix == ".csv":
            with f.open(newline="", encoding="utf-8") as fh:
                rows = csv.DictReader(fh)
                if not {"file", "start", "end"} <= set(rows.fieldnames or ()):
                    if f.name in ("recordings.csv", "scores.csv"):   # detect's own tables, not of segments
                        continue
                    raise LaughlabError(f"{f}: a table of segments needs the columns file, start, end (it has "
                                        f"{', '.join(rows.fieldnames or []) or 'none'})")
                for r in rows:
                    stem = Path(r["file"]).stem
                    from_csv.setdefault(stem, []).append(Segment(float(r["start"]), float(r["end"])))
    for stem, segs in from_csv.items():  # a file's label file, when there is one, is what counts
        out.setdefault(stem, segs)
    return out


def score(segs: list[Segment], truth_rows: list[dict], duration_s: float, step_s: float = 0.01) -> dict:
    """Frame counts (10 ms) against the truth's bouts, bouts found, and segments outside laughter by the
    kind of sound they overlap most (``speech``, ``cough``, ... or ``none``)."""
    n = int(math.ceil(duration_s / step_s))
    t = (np.arange(n) + 0.5) * step_s
    truth = np.zeros(n, bool)
    bouts = [(r["onset_s"], r["offset_s"]) for r in truth_rows if r["kind"] == "bout"]
    for a, b in bouts:
        truth |= (t >= a) & (t < b)
    det = np.zeros(n, bool)
    for s in segs:
        det |= (t >= s.start) & (t < s.end)
    found = sum(any(s.start < b and s.end > a for s in segs) for a, b in bouts)
    false_by_kind: dict[str, int] = {}
    others = [r for r in truth_rows if r["kind"] not in ("bout", "call")]
    for s in segs:
        if any(s.start < b and s.end > a for a, b in bouts):
            continue
        best, kind = 0.0, "none"
        for r in others:
            ov = min(s.end, r["offset_s"]) - max(s.start, r["onset_s"])
            if ov > best:
                best, kind = ov, r["kind"]
        false_by_kind[kind] = false_by_kind.get(kind, 0) + 1
    return {"tp": int((det & truth).sum()), "fp": int((det & ~truth).sum()), "fn": int((~det & truth).sum()),
            "bouts": len(bouts), "found": int(found), "false_segments": false_by_kind}


def f1(tp: int, fp: int, fn: int) -> float:
    return 1.0 if tp + fp + fn == 0 else 2 * tp / (2 * tp + fp + fn)
