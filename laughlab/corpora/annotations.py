"""Hand-made labels of the real recordings: Audacity label tracks (and Praat TextGrids).

An annotation file holds one label per line, ``start<TAB>end<TAB>label`` in
seconds (Audacity's "Export Labels" format; Audacity's optional frequency lines,
starting with ``\\``, are skipped).  Labels:

- ``laugh``: a laughter bout, from its first call's onset to its last call's end;
- ``call``: one call, inside a bout;
- ``inhale``, ``speech``, ``other``: non-laughter sounds in the file.

A Praat TextGrid with tiers ``bouts`` and ``calls`` (interval texts ``laugh``
and ``call``) is read the same way, and so is an ELAN document (``.eaf``) with those tiers.  What ``laughlab detect`` writes is an annotation too, so its segments,
corrected in Praat or Audacity, give a recording its truth: the TextGrid's tier ``laughter`` stands for
``bouts`` when there is no ``bouts`` (in an ELAN file too), and the label ``laughter`` (its Audacity files until 2026-11-27) for
``laugh``.  Without ``bouts``, every interval tier whose name holds "laugh" (``laughter`` too) is a bouts tier (one
per speaker: their union), and a tier named for laughter marks laughter whatever its texts (``@@@``, ``LA``), as
:func:`bout_tiers` and :func:`_tier_label` say.  The bundled annotations live in
``laughlab/data/annotations/<id with / as __>.txt``.

A label outside [0, duration], with end <= start, with an unknown text, a bout
that overlaps another bout or a call that overlaps another call or lies outside
every bout, is refused with one line naming the file and the line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from laughlab.core.errors import LaughlabError, first_line

LABELS = ("laugh", "call", "inhale", "speech", "other")
#: tolerance of the checks (s): labels are placed by hand to about 20 ms
TOL_S = 1e-3


@dataclass(frozen=True)
class Label:
    start: float
    end: float
    text: str
    line: int | str


@dataclass
class Annotation:
    """The labels of one recording."""

    path: str
    labels: list

    @property
    def bouts(self) -> list[tuple[float, float]]:
        return [(lab.start, lab.end) for lab in self.labels if lab.text == "laugh"]

    @property
    def calls(self) -> list[tuple[float, float]]:
        return [(lab.start, lab.end) for lab in self.labels if lab.text == "call"]

    def truth_rows(self, offset_s: float = 0.0, intensity: float = 1.0) -> list[dict]:
        """Rows of a ``truth.csv`` (kind, bout, onset_s, offset_s, intensity), shifted by ``offset_s``."""
        rows = []
        for b, (on, off) in enumerate(self.bouts):
            rows.append({"kind": "bout", "bout": b, "onset_s": on + offset_s, "offset_s": off + offset_s,
                         "intensity": intensity})
            for con, coff in self.calls:
                if on - TOL_S <= con and coff <= off + TOL_S:
                    rows.append({"kind": "call", "bout": b, "onset_s": con + offset_s, "offset_s": coff + offset_s,
                                 "intensity": intensity})
        return rows


def read_audacity(path: str | Path, duration_s: float | None = None) -> Annotation:
    """Read and check an Audacity label track (see the module docstring)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise LaughlabError(f"cannot read annotation {p}: {exc}") from None
    labels = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.startswith("\\"):
            continue
        parts = line.split("\t")
        if len(parts) < 2:
            raise LaughlabError(f"{p}:{n}: expected 'start<TAB>end<TAB>label'")
        try:
            start, end = float(parts[0]), float(parts[1])
        except ValueError:
            raise LaughlabError(f"{p}:{n}: start and end must be numbers (seconds)") from None
        lab = parts[2].strip().lower() if len(parts) > 2 else ""
        labels.append(Label(start, end, "laugh" if lab == "laughter" else lab, n))   # (detect's labels until 11-27)
    return check(Annotation(str(p), labels), duration_s)


def read_textgrid_annotation(path: str | Path, duration_s: float | None = None) -> Annotation:
    """Read tiers ``bouts`` and ``calls`` of a Praat TextGrid (praatio); other tiers are ignored.

    A bad interval is named by its tier and number as Praat numbers it (``bouts #2``, empty intervals counted) in
    place of a line.
    """
    from praatio import textgrid

    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
        tg = None if head == b"ooBinaryFile" else textgrid.openTextgrid(str(path), includeEmptyIntervals=True)
    except FileNotFoundError:
        raise LaughlabError(f"annotation not found: {path}") from None
    except Exception as exc:  # praatio raises many kinds on a malformed file
        raise LaughlabError(f"bad TextGrid {path}: {first_line(exc)}") from None
    if tg is None:   # Praat's "Save as binary file" (a review: praatio's "'utf-8' codec can't decode byte 0xa0")
        raise LaughlabError(f"bad TextGrid {path}: binary Praat files are not read; save it in Praat as a text file")
    # interval tiers only: a point tier (``laugh_peaks``) has no stretches (its entries ended in a traceback)
    bouts, calls = bout_tiers([n for n in tg.tierNames if isinstance(tg.getTier(n), textgrid.IntervalTier)],
                              f"bad TextGrid {path}")
    # intervals numbered as Praat numbers them, the empty ones counted (a review: the 2nd was called #1), and the
    # empty ones (no text, or blanks) not labels
    labels = [_tier_label(tier, i, a, b, t, kind) for tier, kind in [(t, "bouts") for t in bouts] + [(calls, "calls")]
              if tier for i, (a, b, t) in enumerate(tg.getTier(tier).entries, 1) if t.strip()]
    return check(Annotation(str(path), union_of_tiers(labels, bouts, str(path))), duration_s)


def bout_tiers(names, bad: str) -> tuple[list[str], str | None]:
    """The bouts tiers and the calls tier (or None) among a TextGrid's interval tiers' or an ELAN file's tier
    ``names``: ``bouts`` in any case, else every tier whose name holds "laugh" (``laughter`` as ``laughlab detect``
    writes; ``laughs_A``, ``laughs_B``: a conversation's annotation has a tier per speaker and more, a review met
    ``speakerA``/``Laughter`` refused), read as their union (:func:`union_of_tiers`), but not a ``laughable`` tier
    (conversation analysis' name for what was laughed at); ``bad``: the start of the line when there is none."""
    low = {n.lower(): n for n in reversed(list(names))}
    if "bouts" in low:
        return [low["bouts"]], low.get("calls")
    laughs = [n for n in names if "laugh" in n.lower() and "laughable" not in n.lower()]
    if not laughs:
        raise LaughlabError(f"{bad}: it has no tier 'bouts' (nor 'laughter', as laughlab detect writes, nor one "
                            f"whose name holds 'laugh') (tiers: {', '.join(names)})")
    return laughs, low.get("calls")


def union_of_tiers(labels: list, tiers: list[str], where: str) -> list:
    """With several laughter tiers (one per speaker), the laughs of all of them, those that overlap (by more than
    ``TOL_S``) merged into one bout, named by its first interval: a detector hears one recording, in which two
    speakers laughing at once are one stretch of laughter (a conversation analyst's review: per-speaker tiers were
    refused, and so were two speakers' overlapping laughs).  Laughs that only touch stay apart, as within one tier,
    so an empty second tier changes nothing (a diff review).  Within one tier, overlapping laughs are still refused
    by :func:`check`."""
    if len(tiers) < 2:
        return labels
    for tier in tiers:   # each tier's own laughs checked first (``where``: the file, for the line)
        check(Annotation(where, [lab for lab in labels if lab.text == "laugh" and lab.line.startswith(f"{tier} #")]))
    laughs = sorted((lab for lab in labels if lab.text == "laugh"), key=lambda lab: (lab.start, lab.end))
    merged: list = []
    for lab in laughs:
        if merged and lab.start < merged[-1].end - TOL_S:
            last = merged[-1]
            merged[-1] = Label(last.start, max(last.end, lab.end), "laugh", last.line)
        else:
            merged.append(lab)
    return merged + [lab for lab in labels if lab.text != "laugh"]


def _tier_label(tier: str, i: int, start: float, end: float, text: str, kind: str = "bouts") -> Label:
    """Interval ``i`` of a TextGrid's or an ELAN file's tier as a label: the bouts tier's (``kind`` ``bouts``:
    ``bouts``, or detect's ``laughter``) ``laugh``, ``laughter``, ``x`` or empty text is a laugh; the calls tier's
    (``kind`` ``calls``) ``call``, ``x`` or empty text a call; any other text is checked as it is (the same in both
    readers: a diff review).  A tier named for laughter other than ``bouts`` (``laughter``, ``Laughs_A``) marks
    laughter whatever its texts say (a conversation analyst's ``@@@``, ``LA``, ``giggle``, ``call``: refused until
    2026-11-29), except this format's non-laughter labels (``inhale``, ``speech``, ``other``), which keep theirs."""
    want = "call" if kind == "calls" else "laugh"
    text = text.strip().lower()
    ok = (want, "x", "") + (("laughter",) if want == "laugh" else ())
    if want == "laugh" and tier.lower() != "bouts" and text not in ("inhale", "speech", "other"):
        text = "laugh"
    return Label(float(start), float(end), want if text in ok else text, f"{tier} #{i}")


def read_eaf_annotation(path: str | Path, duration_s: float | None = None) -> Annotation:
    """Read tiers ``bouts`` (or ``laughter``, as ``laughlab detect --formats ...,elan`` writes) and ``calls`` of an
    ELAN document (EAF: time slots in milliseconds, time-alignable annotations), as the TextGrid's are read; so
    segments corrected in ELAN give a recording its truth too.  A bad annotation is named by its tier and number."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(str(path)).getroot()
    except FileNotFoundError:
        raise LaughlabError(f"annotation not found: {path}") from None
    except (OSError, ET.ParseError) as exc:
        raise LaughlabError(f"bad ELAN file {path}: {first_line(exc)}") from None
    try:
        slots = {ts.get("TIME_SLOT_ID"): int(ts.get("TIME_VALUE")) / 1000.0
                 for ts in root.iter("TIME_SLOT") if ts.get("TIME_VALUE") is not None}
    except ValueError:
        raise LaughlabError(f"bad ELAN file {path}: a TIME_VALUE is not a whole number of milliseconds") from None
    elems = list(root.iter("TIER"))
    ids = [t.get("TIER_ID") for t in elems]
    tiers = dict(zip(ids, elems))
    twice = sorted({str(i) for i in ids if ids.count(i) > 1})
    if twice:   # the last of them was read alone, the others' laughs dropped unsaid (a diff review)
        raise LaughlabError(f"bad ELAN file {path}: two tiers share the id {twice[0]!r}; ELAN needs each tier's own")
    bouts, calls = bout_tiers([str(t) for t in tiers], f"bad ELAN file {path}")
    labels = []
    for tier, kind in [(t, "bouts") for t in bouts] + [(calls, "calls")]:
        for i, ann in enumerate(tiers[tier].iter("ALIGNABLE_ANNOTATION") if tier in tiers else (), 1):
            a, b = slots.get(ann.get("TIME_SLOT_REF1")), slots.get(ann.get("TIME_SLOT_REF2"))
            if a is None or b is None:   # an unaligned slot (ELAN allows them): no time to check against
                raise LaughlabError(f"{path}:{tier} #{i}: the annotation has no time (an unaligned time slot)")
            labels.append(_tier_label(tier, i, a, b, ann.findtext("ANNOTATION_VALUE") or "", kind))
    return check(Annotation(str(path), union_of_tiers(labels, bouts, str(path))), duration_s)


#: the annotation formats, by suffix (lower case): Audacity labels, Praat TextGrid, ELAN
SUFFIXES = (".txt", ".textgrid", ".eaf")


def read(path: str | Path, duration_s: float | None = None) -> Annotation:
    """An Audacity label track (``.txt``), a Praat TextGrid (``.TextGrid``) or an ELAN document (``.eaf``)."""
    if str(path).lower().endswith(".textgrid"):
        return read_textgrid_annotation(path, duration_s)
    if str(path).lower().endswith(".eaf"):
        return read_eaf_annotation(path, duration_s)
    return read_audacity(path, duration_s)


def check(ann: Annotation, duration_s: float | None = None) -> Annotation:
    """Refuse bad labels with one line naming the file and the line."""
    where = ann.path
    for lab in ann.labels:
        if lab.text not in LABELS:
            raise LaughlabError(f"{where}:{lab.line}: unknown label {lab.text!r}; use one of: {', '.join(LABELS)}")
        if not (math.isfinite(lab.start) and math.isfinite(lab.end)):
            raise LaughlabError(f"{where}:{lab.line}: start and end must be finite")
        if lab.end <= lab.start:
            raise LaughlabError(f"{where}:{lab.line}: end {lab.end:.3f} s is not after start {lab.start:.3f} s")
        if lab.start < -TOL_S or (duration_s is not None and lab.end > duration_s + TOL_S):
            rng = f"[0, {duration_s:.3f}] s" if duration_s is not None else "[0, ...)"
            raise LaughlabError(f"{where}:{lab.line}: interval {lab.start:.3f}-{lab.end:.3f} s is outside the "
                                f"recording {rng}")
    for kind in ("laugh", "call"):
        same = sorted((lab for lab in ann.labels if lab.text == kind), key=lambda lab: lab.start)
        for a, b in zip(same, same[1:]):
            if b.start < a.end - TOL_S:
                raise LaughlabError(f"{where}:{b.line}: {kind} {b.start:.3f}-{b.end:.3f} s overlaps the {kind} "
                                    f"on line {a.line} ({a.start:.3f}-{a.end:.3f} s)")
    bouts = [lab for lab in ann.labels if lab.text == "laugh"]
    for c in (lab for lab in ann.labels if lab.text == "call"):
        if not any(b.start - TOL_S <= c.start and c.end <= b.end + TOL_S for b in bouts):
            raise LaughlabError(f"{where}:{c.line}: call {c.start:.3f}-{c.end:.3f} s lies outside every laugh bout")
    return ann


def bundled_path(item_id: str) -> Path | None:
    """The bundled annotation of a corpus item, if there is one."""
    p = resources.files("laughlab").joinpath("data", "annotations", item_id.replace("/", "__") + ".txt")
    return Path(str(p)) if p.is_file() else None


def bundled(item_id: str, duration_s: float | None = None) -> Annotation | None:
    p = bundled_path(item_id)
    return read_audacity(p, duration_s) if p is not None else None


def digest() -> str:
    """A short hash of every bundled annotation (sets built from them are rebuilt when one changes)."""
    import hashlib

    h = hashlib.sha256()
    folder = resources.files("laughlab").joinpath("data", "annotations")
    if folder.is_dir():
        for p in sorted(folder.iterdir(), key=lambda q: q.name):
            if p.name.endswith(".txt"):
                h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:16]
