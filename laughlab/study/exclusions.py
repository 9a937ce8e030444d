"""Which participants ``study analyze`` leaves out, and why (:func:`exclusions`; the rules are the design's
``exclusions``, the preset's block of that name).

- ``audio_check``: no attempt of the audio check was right (or none is stored);
- ``attention_max_fail``: more failed attention items than this (a slider item fails more than 5 % of the scale
  away from the value asked for);
- ``straightline``: every rating of every question the same value, over at least four ratings;
- ``complete`` (since 2026-11-29): fewer ratings or attention items than the participant's trials ask for, a
  participant who left part way (a study researcher's review: one who stopped after 2 of 16 trials, before any
  attention item, was counted as included, unsaid).  The trials are the design's for that participant (with
  ``--design`` or a database); without a design, the most any participant gave.  ``complete: false`` keeps them.
- ``consent`` (since 2026-11-29): answers in a server's database with no consent in any of the participant's
  sessions there (``laughlab.study.participation.unconsented``: a database from before the server refused them, or
  edited).  Answer files from a static host carry no consent record and are not judged by it.
"""
from __future__ import annotations

import re

import numpy as np


def shown_typed(text: str) -> str:
    """A participant's typed attempts as a report shows them: letters, digits, spaces and ' . , - kept, anything
    else a ``?`` (a security review: ``<img src=x onerror=...>`` went raw into the report's README.md)."""
    return re.sub(r"[^\w\s'.,-]", "?", str(text).replace("|", ", "))


def cell_safe(value):
    """A text cell a spreadsheet would run as a formula (``=``, ``+``, ``-``, ``@``, tab, CR first) with a ``'``
    before it (OWASP's CSV injection rule; a security review: a user agent ``=HYPERLINK(...)`` in tidy.csv)."""
    return "'" + value if isinstance(value, str) and value[:1] in ("=", "+", "-", "@", "\t", "\r") else value


DEFAULT_RULES = {"audio_check": True, "attention_max_fail": 0, "straightline": True, "complete": True,
                 "consent": True}


def expected_counts(design: dict | None, df) -> dict[int, tuple[int, int]]:
    """Participant -> (ratings, attention items) their trials ask for: each trial is rated on every question, and an
    attention trial adds its item; without a design (or a participant it does not list), the most any gave."""
    kinds = df.groupby(["participant", "kind"]).size().unstack(fill_value=0)
    most = (int(kinds["rating"].max()) if "rating" in kinds else 0,
            int(kinds["attention"].max()) if "attention" in kinds else 0)
    plan = (design or {}).get("participants") or {}
    n_q = len((design or {}).get("questions") or []) or 1
    out = {}
    for p in kinds.index:
        trials = (plan.get(str(int(p))) or {}).get("trials")
        out[int(p)] = (len(trials) * n_q, sum(bool(t.get("attention")) for t in trials)) if trials else most
    return out


def exclusions(df, rules: dict, slider_range: float | None = None,
               expected: dict[int, tuple[int, int]] | None = None,
               unconsented: set[int] = frozenset()) -> dict[int, list[str]]:
    """Participant -> the reasons they are excluded (see the module doc); only participants with a reason.
    ``expected``: each participant's ratings and attention items (:func:`expected_counts`) for ``complete``;
    ``unconsented``: the participants a database holds answers of without consent, for ``consent``."""
    out: dict[int, list[str]] = {}
    tol = 0.05 * slider_range if slider_range else 1e-9
    for p, g in df.groupby("participant"):
        why = []
        if rules.get("consent", True) and int(p) in unconsented:
            why.append("no consent recorded (answers in the database without it)")
        if rules.get("audio_check", True):
            chk = g[g["kind"] == "audio_check"]
            if chk.empty:
                why.append("no audio check stored")
            elif not (chk["value"] == 1).any():
                why.append(f"audio check failed (typed {shown_typed(chk['text'].iloc[0])!r})")
        att = g[g["kind"] == "attention"]
        failed = int((np.abs(att["value"] - att["expected"]) > tol).sum())
        if failed > int(rules.get("attention_max_fail", 0)):
            why.append(f"failed {failed} of {len(att)} attention items")
        ratings = g[g["kind"] == "rating"]["value"]
        if rules.get("straightline", True) and len(ratings) >= 4 and ratings.nunique() == 1:
            why.append(f"straight-lining: all {len(ratings)} ratings were {ratings.iloc[0]:g}")
        want = (expected or {}).get(int(p))
        if rules.get("complete", True) and want and (len(ratings) < want[0] or len(att) < want[1]):
            why.append(f"incomplete: {len(ratings)} of {want[0]} ratings"
                       + (f", {len(att)} of {want[1]} attention items" if want[1] else ""))
        if why:
            out[int(p)] = why
    return out


def reason_counts(excluded: dict) -> str:
    """The exclusions' reasons, each kind once with how many participants it excluded (the reasons' words before
    any detail in brackets), each number the values it took: ``no audio check stored: 12; failed 1 or 2 of 2
    attention items: 2`` (a review read "all N ratings were N: 1" as placeholders left unfilled)."""
    import re

    kinds: dict = {}
    for reasons in excluded.values():
        for r in reasons:
            text = r.split(" (")[0]
            kinds.setdefault(re.sub(r"\d+(\.\d+)?", "N", text), []).append(re.split(r"(\d+(?:\.\d+)?)", text))
    out = []
    for parts in sorted(kinds.values(), key=len, reverse=True):   # most participants first, ties as met
        words = list(parts[0])
        for i in range(1, len(words), 2):   # the numbers: each slot's values, as taken
            seen = sorted({p[i] for p in parts}, key=float)
            words[i] = seen[0] if len(seen) == 1 else " or ".join(seen) if len(seen) <= 3 else f"{seen[0]}-{seen[-1]}"
        out.append(f"{''.join(words)}: {len(parts)}")
    return "; ".join(out)
