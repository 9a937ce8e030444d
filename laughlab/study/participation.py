"""Who came, who agreed and who stayed: ``study analyze``'s participation line from the server's sessions (page loads)
and the answers' sessions (since 2026-11-29: a study-server review found attrition, declines and participants working
in two tabs at once not reported); and how the included fill the Latin square's rows (:func:`order_rows`).

- from the databases' ``sessions`` table: participants who opened the page, gave consent, declined (and never
  consented: nothing of theirs is stored), reached the end page; a participant is their panel ID when they came with
  one (a number given again after a decline is then two people), else their number;
- from the answers (a database's or answer files'): participants whose answers came from more than one page load
  (they came back), and of those, the ones whose two page loads' answers interleave in time (two tabs at once, or two
  devices: a trial shown twice, or answers given out of order), and with the design, those who answered a trial
  sooner after the one before than its video lasts (no page can: a script), said and not excluded.

:func:`unconsented` names the participants a database holds answers of but no consent for (a database written
before the server refused them, or edited): ``study analyze`` leaves them out (the rule ``consent``).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from laughlab.study import db as DB


def unconsented(dbs: list[Path]) -> set[int]:
    """Participants with answers in one of ``dbs`` and no consent in any of their sessions there."""
    answered, agreed = set(), set()
    for path in dbs:
        answered |= set(DB.participants_stored(path))
        agreed |= {int(s["participant"]) for s in DB.sessions(path) if s["consent_at"]}
    return answered - agreed


def _two_at_once(df) -> set[int]:
    """Participants whose answers from two sessions interleave in time (received by the server, else given)."""
    out = set()
    at = df["received_at"].where(df["received_at"].fillna("") != "", df["answered_at"]).fillna("")
    for p, g in df.assign(at=at)[at != ""].groupby("participant"):
        spans = sorted((grp["at"].min(), grp["at"].max()) for _, grp in g.groupby("session"))
        if any(b[0] < a[1] for a, b in zip(spans, spans[1:])):
            out.add(int(p))
    return out


def _too_fast(df, durations: dict) -> set[int]:
    """Participants a trial of whose answers reached the server sooner after their previous trial's than its video
    lasts: no page can (a trial's questions come after its video), a script can (a security review: six made-up
    participants answered the whole study in under a second each, and every one was included)."""
    out = set()
    rows = df[(df["kind"] != "audio_check") & (df["received_at"].fillna("") != "")]
    for p, g in rows.groupby("participant"):
        first = g.groupby("trial").agg(at=("received_at", "min"), given=("answered_at", "min"),
                                       stimulus=("stimulus", "first")).sort_index()
        if len(first) < 2:
            continue
        need = 0.9 * first["stimulus"].map(durations).iloc[1:]   # 0.9: a post's sending against its receipt

        def gap(col):
            return pd.to_datetime(first[col], utc=True, errors="coerce").diff().dt.total_seconds().iloc[1:]

        # both the server's clock and the page's: answers a page kept through a network failure arrive together
        # with the next (their times given are the trials' own)
        given = gap("given")
        if ((gap("at") < need) & (given.isna() | (given < need)) & need.notna()).any():
            out.add(int(p))
    return out


def participation(dbs: list[Path], df, durations: dict | None = None) -> dict:
    """The counts (module doc); the sessions' part is None without a database; ``durations``: each stimulus' video
    length (s), from the design, for the participants who answered faster than the videos play."""
    out: dict = {}
    if dbs:
        rows = [s for path in dbs for s in DB.sessions(path)]
        # a person: their panel ID, else their number (a panel's number given again after a decline is two people)
        who = lambda s: s["external_id"] or int(s["participant"])   # noqa: E731
        by = lambda key: {who(s) for s in rows if s[key]}   # noqa: E731
        agreed = by("consent_at")
        out.update(opened=len({who(s) for s in rows}), page_loads=len(rows), consented=len(agreed),
                   declined=len(by("declined_at") - agreed), finished=len(by("finished_at")))
    sessions = df[df["session"].fillna("") != ""].groupby("participant")["session"].nunique()
    out.update(came_back=int((sessions > 1).sum()), two_at_once=sorted(_two_at_once(df)))
    if durations:
        out["too_fast"] = sorted(_too_fast(df, durations))
    return out


def line(doc: dict) -> str:
    """The report's sentence: ``31 participants opened the page (34 page loads): 30 gave consent, 1 declined, 26
    reached the end. 3 answered from more than one page load; 1 of them from two at once (participant 7).``"""
    parts = []
    if "opened" in doc:
        parts.append(f"{doc['opened']} participant{'' if doc['opened'] == 1 else 's'} opened the page "
                     f"({doc['page_loads']} page loads): {doc['consented']} gave consent, {doc['declined']} declined "
                     f"(no answer of theirs is stored), {doc['finished']} reached the end.")
    if doc.get("came_back"):
        two = doc["two_at_once"]
        parts.append(f"{doc['came_back']} answered from more than one page load" + (
            f"; {len(two)} of them from two at once, their answers interleaved in time (two tabs or devices: "
            f"participant{'' if len(two) == 1 else 's'} {', '.join(map(str, two))})." if two else " (they came back)."))
    fast = doc.get("too_fast")
    if fast:   # said, not excluded: check them against the panel's records (docs/study.md, "Online")
        parts.append(f"{len(fast)} answered a trial sooner after the one before than its video lasts, which the page "
                     f"cannot do (a script?): participant{'' if len(fast) == 1 else 's'} {', '.join(map(str, fast))}.")
    return " ".join(parts)


def order_rows(df, excluded: dict) -> dict[int, list[int]]:
    """Latin-square row -> [included participants, participants] (a statistician's review: excluding two of a
    row's three moved the contrasts by 0.1 with no order effect in the model, and nothing showed the imbalance)."""
    rows: dict[int, list[int]] = {}
    for p, r in df.groupby("participant")["order_row"].first().items():
        if not pd.isna(r):
            entry = rows.setdefault(int(r), [0, 0])
            entry[0] += int(p) not in excluded
            entry[1] += 1
    return dict(sorted(rows.items()))
