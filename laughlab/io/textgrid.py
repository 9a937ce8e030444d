"""Praat TextGrid files of laughter pseudo-phonemes: read (praatio), check, write.

Ding et al. (2014, section 3) drive their animation from the segmentation of
laughter into the 14 pseudo-phonemes of the AVLaughterCycle database
(Urbain et al.), annotated in Praat.  :func:`read_textgrid` turns one interval
tier of such a file into ``[(start_s, end_s, label), ...]`` with every label
mapped to one of :data:`PHONEMES`; :func:`write_textgrid` writes a segmentation
back (e.g. the one the ``phoneme`` extractor detected, via
:func:`labels_to_intervals`).

Parsing is praatio's (``praatio.utilities.textgrid_io.parseTextgridStr``: the
long and short text formats and praatio's JSON).  praatio's errors name no
line, so every text-format file is also scanned as Praat reads it (a stream of
free-standing numbers, quoted strings and ``<flags>``; everything else is a
comment): a malformed file or an unknown label raises
:class:`~laughlab.core.errors.LaughlabError` with one line naming the file and the
line number, e.g.::

    bad TextGrid laugh.TextGrid, line 17: unknown pseudo-phoneme 'haha' in tier "phones" ...

Labels
------
Matching is case-insensitive and ignores surrounding blanks.  Accepted besides
the 14 names (:data:`ALIASES`), each for a stated reason:

* ``""`` (an unlabelled interval; Praat leaves gaps empty), ``sil``, ``sp``,
  ``pau`` (the silence labels of HTK/Festival-style aligners): ``silence``;
* ``ne?`` and ``ni``: the AVLaughterCycle phonetic annotation (Urbain & Dutoit
  2011, its README) labels nareal fricatives ``ne?`` in exhalation and ``ni``
  in inhalation; Ding et al.'s 14 classes have one nareal class, ``ne``;
* ``\\ic\\O^``: the same annotation labels cackles so: ``cackle``;
* ``\\ic`` and ``ɪ``: Praat's and IPA's symbol of the lax close front vowel
  the class name ``ic`` abbreviates: ``ic``;
* ``\\?g`` and ``ʔ``, ``glottal stop``, ``glottal_stop``: Praat's and IPA's
  symbol for a glottal stop: ``glotstop``;
* ``h``: the h-like (glottal fricative) phones, the most frequent laughter
  consonant in that annotation: ``fricative``;
* ``hum``: a label added by that annotation for a closed-mouth voiced murmur,
  acoustically a nasal: ``nasal``;
* ``nareal fricative``, ``nareal_fricative``, ``glottalstop``: spelled-out names.
"""
from __future__ import annotations

import bisect
import math
import os
import re
from pathlib import Path
from typing import Iterable, Sequence

from laughlab.core.errors import LaughlabError, first_line

__all__ = ["PHONEMES", "ALIASES", "normalize_label", "read_textgrid", "write_textgrid", "labels_to_intervals"]

#: the 14 pseudo-phonemes of AVLaughterCycle (Ding et al. 2014, section 3), in the paper's order
PHONEMES: tuple[str, ...] = ("silence", "ne", "click", "nasal", "plosive", "fricative", "ic", "e", "o",
                             "grunt", "cackle", "a", "glotstop", "vowel")

#: other accepted spellings (lower case) -> pseudo-phoneme; see the module docstring for the reasons
ALIASES: dict[str, str] = {
    "": "silence", "sil": "silence", "sp": "silence", "pau": "silence",
    "ne?": "ne", "ni": "ne", "nareal fricative": "ne", "nareal_fricative": "ne",
    "\\ic\\o^": "cackle",
    "\\ic": "ic", "ɪ": "ic",
    "\\?g": "glotstop", "ʔ": "glotstop", "glottal stop": "glotstop", "glottal_stop": "glotstop",
    "glottalstop": "glotstop",
    "h": "fricative",
    "hum": "nasal",
}

_CANON = {name: name for name in PHONEMES} | ALIASES


def normalize_label(text: str) -> str | None:
    """The pseudo-phoneme of a label, or None if it is not one (case-insensitive)."""
    return _CANON.get(text.strip().lower())


# --------------------------------------------------------------------- scanning
# Praat's text format: free-standing numbers, "strings" ("" escapes a quote, may
# span lines) and <flags>; anything else is a comment.
_TOKEN = re.compile(r'"(?:[^"]|"")*"|<[A-Za-z]+>|(?<!\S)[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?!\S)')


class _Scan:
    """Tokens of a text TextGrid with their line numbers; raises LaughlabError naming the line."""

    def __init__(self, text: str, where: str):
        self.where = where
        self.lines = text.split("\n")
        self.nl = [m.start() for m in re.finditer("\n", text)]
        self.tokens = [(m.group(), m.start()) for m in _TOKEN.finditer(text)]
        self.i = 0
        self.last_line = len(self.nl) + 1

    def line(self, pos: int) -> int:
        return bisect.bisect_left(self.nl, pos) + 1

    def fail(self, line: int | None, msg: str):
        at = f", line {line}" if line else ""
        raise LaughlabError(f"bad TextGrid {self.where}{at}: {msg}")

    def _next(self, what: str):
        if self.i >= len(self.tokens):
            self.fail(self.last_line, f"the file ends where {what} should be")
        tok, pos = self.tokens[self.i]
        self.i += 1
        return tok, self.line(pos)

    def string(self, what: str) -> tuple[str, int]:
        tok, line = self._next(what)
        if not tok.startswith('"'):
            self.fail(line, f"expected {what} (a quoted text), found {tok!r}")
        return tok[1:-1].replace('""', '"'), line

    def number(self, what: str) -> tuple[float, int]:
        prev_line = self.line(self.tokens[self.i - 1][1]) if self.i else 0
        tok, line = self._next(what)
        try:
            val = float(tok)
        except ValueError:
            val = math.nan
        if not math.isfinite(val):
            # Praat skips a word that is not a number as a comment; name the line that holds it
            for ln in range(prev_line + 1, line + 1):
                m = re.search(r"=\s*(\S[^\n]*)$", self.lines[ln - 1]) if ln - 1 < len(self.lines) else None
                if m and ln != line:
                    self.fail(ln, f"expected {what} (a number), found {m.group(1).strip()[:40]!r}")
            self.fail(line, f"expected {what} (a number), found {tok[:40]!r}")
        return val, line

    def count(self, what: str) -> tuple[int, int]:
        val, line = self.number(what)
        if val < 0 or val != int(val):
            self.fail(line, f"expected {what} (a whole number >= 0), found {val:g}")
        return int(val), line

    def flag(self, what: str) -> tuple[str, int]:
        tok, line = self._next(what)
        if not tok.startswith("<"):
            self.fail(line, f"expected {what} (<exists> or <absent>), found {tok!r}")
        return tok, line


def _scan_textgrid(text: str, where: str) -> list[dict]:
    """Check a text TextGrid as Praat reads it; return its tiers with the line of every entry."""
    s = _Scan(text, where)
    if not s.tokens or not s.tokens[0][0].startswith('"'):
        s.fail(s.line(s.tokens[0][1]) if s.tokens else 1, 'not a Praat text file (no "ooTextFile" header)')
    kind, line = s.string('the file type ("ooTextFile")')
    if not kind.startswith("ooTextFile"):
        s.fail(line, f'not a Praat text file (file type {kind!r}, expected "ooTextFile")')
    cls, line = s.string('the object class ("TextGrid")')
    if not cls.startswith("TextGrid"):
        s.fail(line, f'not a TextGrid (object class {cls!r})')
    xmin, _ = s.number("the start time xmin")
    xmax, line = s.number("the end time xmax")
    if xmax < xmin:
        s.fail(line, f"xmax {xmax:g} is before xmin {xmin:g}")
    flag, line = s.flag("the tiers flag")
    n_tiers = 0
    if flag == "<exists>":
        n_tiers, _ = s.count("the number of tiers")
    elif flag != "<absent>":
        s.fail(line, f"expected <exists> or <absent>, found {flag!r}")
    tiers = []
    for k in range(1, n_tiers + 1):
        tclass, cline = s.string(f"the class of tier {k}")
        if tclass not in ("IntervalTier", "TextTier"):
            s.fail(cline, f'tier {k} has class {tclass!r}; expected "IntervalTier" or "TextTier"')
        name, _ = s.string(f"the name of tier {k}")
        t0, _ = s.number(f'the start time of tier "{name}"')
        t1, line = s.number(f'the end time of tier "{name}"')
        if t1 < t0:
            s.fail(line, f'tier "{name}" ends ({t1:g}) before it starts ({t0:g})')
        n, _ = s.count(f'the number of entries of tier "{name}"')
        entries = []
        if tclass == "IntervalTier":
            prev_end = t0
            for j in range(1, n + 1):
                a, aline = s.number(f'the start of interval {j} of tier "{name}"')
                b, bline = s.number(f'the end of interval {j} of tier "{name}"')
                label, lline = s.string(f'the text of interval {j} of tier "{name}"')
                if not b > a:
                    s.fail(bline, f'interval {j} of tier "{name}" ends ({b:g}) at or before its start ({a:g})')
                if abs(a - prev_end) > 1e-6:
                    s.fail(aline, f'interval {j} of tier "{name}" starts at {a:g}, not where the previous one '
                                  f"ends ({prev_end:g}): intervals must be contiguous")
                prev_end = b
                entries.append((a, b, label, lline))
        else:
            for j in range(1, n + 1):
                t, tline = s.number(f'the time of point {j} of tier "{name}"')
                label, _ = s.string(f'the mark of point {j} of tier "{name}"')
                entries.append((t, t, label, tline))
        tiers.append({"class": tclass, "name": name, "line": cline, "entries": entries})
    if s.i < len(s.tokens):
        tok, pos = s.tokens[s.i]
        s.fail(s.line(pos), f"unexpected {tok[:40]!r} after the last of {n_tiers} tier(s)")
    return tiers


def _decode(data: bytes, where: str) -> str:
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        enc = "utf-16"
    elif data.startswith(b"\xef\xbb\xbf"):
        enc = "utf-8-sig"
    else:
        enc = "utf-8"
    try:
        return data.decode(enc).replace("\r\n", "\n").replace("\r", "\n")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise LaughlabError(f"bad TextGrid {where}, line {line}: not {enc.upper()} text") from None


def read_textgrid(path: str | os.PathLike, tier: str | None = None) -> list[tuple[float, float, str]]:
    """Read one interval tier of pseudo-phoneme labels from a Praat TextGrid.

    Parameters
    ----------
    path : str or PathLike
        A TextGrid in Praat's long or short text format (UTF-8 or UTF-16), or
        praatio's JSON.
    tier : str or None
        Name of the interval tier; None takes the first interval tier (the
        AVLaughterCycle annotation keeps its phonetic labels in the first tier
        and the airflow direction in the second).

    Returns
    -------
    list of (start_s, end_s, label)
        The tier's intervals in time order, ``label`` one of :data:`PHONEMES`
        (empty intervals are ``silence``).

    Raises
    ------
    LaughlabError
        One line naming the file (and the line, for text files) when the file
        is missing, unreadable or malformed, when the tier is missing or not an
        interval tier, or when a label is not a pseudo-phoneme.
    """
    from praatio.utilities import textgrid_io  # praatio's parser

    where = str(path)
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise LaughlabError(f"TextGrid not found: {where}") from None
    except OSError as exc:
        raise LaughlabError(f"cannot read TextGrid {where}: {exc.strerror or exc}") from None
    if data.startswith(b"ooBinaryFile"):
        raise LaughlabError(f"bad TextGrid {where}: binary Praat files are not read; save it as a text file")
    text = _decode(data, where)
    is_json = text.lstrip().startswith("{")
    scanned = None if is_json else _scan_textgrid(text, where)
    try:
        parsed = textgrid_io.parseTextgridStr(text, includeEmptyIntervals=True)
    except Exception as exc:  # praatio raises many kinds; any of them means a file it cannot read
        msg = first_line(exc)
        raise LaughlabError(f"bad TextGrid {where}: praatio cannot read it ({msg})") from None

    tiers = parsed.get("tiers", [])
    interval_tiers = [t for t in tiers if t.get("class") == "IntervalTier"]
    if tier is None:
        if not interval_tiers:
            raise LaughlabError(f"bad TextGrid {where}: it has no interval tier")
        chosen = interval_tiers[0]
    else:
        named = [t for t in tiers if t.get("name") == tier]
        if not named:
            names = ", ".join(repr(t.get("name")) for t in tiers) or "(none)"
            raise LaughlabError(f"TextGrid {where} has no tier {tier!r}; its tiers: {names}")
        chosen = named[0]
        if chosen.get("class") != "IntervalTier":
            raise LaughlabError(f"tier {tier!r} of TextGrid {where} is a point tier, not an interval tier")
    lines: list[int | None] = [None] * len(chosen["entries"])
    if scanned is not None:
        k = tiers.index(chosen)
        entries = scanned[k]["entries"] if k < len(scanned) else []
        if len(entries) != len(chosen["entries"]):
            line = scanned[k]["line"] if k < len(scanned) else None
            raise LaughlabError(f"bad TextGrid {where}" + (f", line {line}" if line else "") +
                                f': praatio reads {len(chosen["entries"])} intervals in tier '
                                f'"{chosen["name"]}" where the file declares {len(entries)}')
        lines = [e[3] for e in entries]
    out = []
    for (start, end, label), line in zip(chosen["entries"], lines):
        at = f", line {line}" if line else ""
        try:
            a, b = float(start), float(end)
        except (TypeError, ValueError):
            raise LaughlabError(f"bad TextGrid {where}{at}: interval times {start!r}, {end!r} are not numbers") \
                from None
        if not (math.isfinite(a) and math.isfinite(b) and b > a):
            raise LaughlabError(f"bad TextGrid {where}{at}: interval [{a:g}, {b:g}] is empty or not finite")
        name = normalize_label(str(label))
        if name is None:
            raise LaughlabError(f"bad TextGrid {where}{at}: unknown pseudo-phoneme {str(label)[:40]!r} in tier "
                                f'"{chosen["name"]}"; use one of: {", ".join(PHONEMES)}')
        out.append((a, b, name))
    out.sort(key=lambda iv: iv[0])
    for (a0, b0, _), (a1, _, _), line in zip(out, out[1:], lines[1:]):
        if a1 < b0 - 1e-9:
            at = f", line {line}" if line else ""
            raise LaughlabError(f"bad TextGrid {where}{at}: interval starting at {a1:g} overlaps the previous one")
    return out


def labels_to_intervals(times: Sequence[float], labels: Sequence[str | None], dt: float,
                        end_s: float | None = None) -> list[tuple[float, float, str]]:
    """Merge per-frame labels into intervals ``(start_s, end_s, label)``.

    Frame ``k`` covers ``[times[k], times[k] + dt)``; consecutive frames with the
    same label form one interval; frames without a label (None) count as
    ``silence``.  ``end_s`` (default: the end of the last frame) closes the last one.
    """
    out: list[tuple[float, float, str]] = []
    for t, lab in zip(times, labels):
        lab = lab or "silence"
        if out and out[-1][2] == lab:
            continue
        if out:
            out[-1] = (out[-1][0], float(t), out[-1][2])
        out.append((float(t), float(t) + dt, lab))
    if out:
        last_end = float(times[-1]) + dt if end_s is None else float(end_s)
        out[-1] = (out[-1][0], max(last_end, out[-1][0] + 1e-9), out[-1][2])
    return out


def write_textgrid(path: str | os.PathLike, intervals: Iterable[tuple[float, float, str]],
                   tier: str = "phonemes", xmin: float | None = None, xmax: float | None = None) -> Path:
    """Write intervals as a one-tier TextGrid (Praat's long text format, UTF-8) with praatio.

    Parameters
    ----------
    path : str or PathLike
        File to write (replaced atomically: written to a temporary name, then moved).
    intervals : iterable of (start_s, end_s, label)
        Non-overlapping intervals; gaps are filled with empty (silence) intervals.
    tier : str
        Tier name.
    xmin, xmax : float or None
        Time range of the TextGrid (default: that of the intervals).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    LaughlabError
        If an interval is empty, not finite or overlaps another, or there is none.
    """
    from praatio import textgrid as tgio
    from praatio.data_classes.interval_tier import IntervalTier

    ivs = sorted((float(a), float(b), str(lab)) for a, b, lab in intervals)
    if not ivs:
        raise LaughlabError(f"cannot write TextGrid {path}: no intervals")
    for a, b, lab in ivs:
        if not (math.isfinite(a) and math.isfinite(b) and b > a):
            raise LaughlabError(f"cannot write TextGrid {path}: interval [{a:g}, {b:g}] {lab!r} is empty or not finite")
    for (a0, b0, l0), (a1, b1, l1) in zip(ivs, ivs[1:]):
        if a1 < b0 - 1e-9:
            raise LaughlabError(f"cannot write TextGrid {path}: interval {l1!r} at {a1:g} overlaps {l0!r}")
    lo = ivs[0][0] if xmin is None else float(xmin)
    hi = ivs[-1][1] if xmax is None else float(xmax)
    if lo > ivs[0][0] or hi < ivs[-1][1]:
        raise LaughlabError(f"cannot write TextGrid {path}: xmin/xmax do not cover the intervals")
    # snap boundaries that differ by round-off so praatio sees contiguous intervals
    fixed = []
    for a, b, lab in ivs:
        if fixed and abs(a - fixed[-1][1]) < 1e-9:
            a = fixed[-1][1]
        fixed.append((a, b, lab))
    tg = tgio.Textgrid(lo, hi)
    tg.addTier(IntervalTier(tier, fixed, lo, hi))
    path = Path(path)
    tmp = path.with_name(f".{path.name}.part")
    try:
        tg.save(str(tmp), format="long_textgrid", includeBlankSpaces=True, minimumIntervalLength=None)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
