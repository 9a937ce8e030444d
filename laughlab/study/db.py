"""The responses of a study in SQLite: one row per answer, written in one transaction per trial.

Tables (``responses.sqlite`` in the study folder unless ``--db`` says otherwise):

``answers``
    one row per question answered in a trial (``kind`` ``rating`` or ``attention``) and one per
    participant for the audio check (``kind`` ``audio_check``, ``trial`` 0, ``value`` 1 if the last
    attempt was the word, ``text`` the attempts joined by ``|``).  Columns: :data:`COLUMNS`; times are
    ISO 8601 UTC (``shown_at``: the video started, ``answered_at``: the rating was given, both by
    the browser's clock; ``received_at``: by the server's), ``rt_ms`` the rating screen's response
    time.  ``(participant, trial, question)`` is unique: an answer is stored once, a second post of
    it is refused.
``sessions``
    one row per page load: ``session``, ``participant``, ``started_at``, ``consent_at``,
    ``finished_at``, ``user_agent``, ``declined_at`` (since 2026-11-29: a decline was not stored), ``external_id``
    (the panel's ID the page came with, if any).  Answers
    are stored only from a session the participant started, and only once they gave consent in one of
    their sessions (:func:`consented`).
``assignments``
    a recruitment panel's ID for a participant (``external_id``: Prolific's ``PROLIFIC_PID``, MTurk's
    ``workerId``) and the participant number the server gave it (:func:`assign`), with ``assigned_at``.
``study``
    ``design_id`` and the design itself (``design``, JSON), so the database alone can be analysed and
    is never mixed with another study's; ``participants``: ``people`` (``study serve``) or
    ``simulated`` (``study simulate``), so simulated answers never mix with people's.

The database runs in WAL mode; every write is one ``BEGIN IMMEDIATE`` transaction, so two
participants posting at once are serialised and a trial is stored whole or not at all.
"""
from __future__ import annotations

import csv
import io
import json
import sqlite3
import sys
from datetime import datetime, timezone
from pathlib import Path

from laughlab.core.errors import LaughlabError

COLUMNS = ("participant", "order_row", "trial", "stimulus", "condition", "audio_id", "kind", "question", "value",
           "text", "expected", "rt_ms", "shown_at", "answered_at", "received_at", "session", "user_agent")

SCHEMA = """
CREATE TABLE IF NOT EXISTS answers (
  id INTEGER PRIMARY KEY,
  participant INTEGER NOT NULL, order_row INTEGER NOT NULL, trial INTEGER NOT NULL,
  stimulus TEXT NOT NULL, condition TEXT NOT NULL, audio_id TEXT NOT NULL,
  kind TEXT NOT NULL CHECK (kind IN ('rating', 'attention', 'audio_check')),
  question TEXT NOT NULL, value REAL, text TEXT NOT NULL DEFAULT '', expected REAL, rt_ms REAL,
  shown_at TEXT, answered_at TEXT, received_at TEXT NOT NULL, session TEXT NOT NULL, user_agent TEXT,
  UNIQUE (participant, trial, question));
CREATE TABLE IF NOT EXISTS sessions (
  session TEXT PRIMARY KEY, participant INTEGER NOT NULL, started_at TEXT NOT NULL, consent_at TEXT,
  finished_at TEXT, user_agent TEXT, declined_at TEXT, external_id TEXT);
CREATE TABLE IF NOT EXISTS assignments (
  external_id TEXT PRIMARY KEY, participant INTEGER NOT NULL UNIQUE, assigned_at TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS study (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS participant_keys (participant INTEGER PRIMARY KEY, key TEXT NOT NULL);
"""


class Duplicate(LaughlabError):
    """An answer that is already stored."""


class SessionRefused(LaughlabError):
    """A post from a session that was not started, or started for another participant."""


def utc_now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _age_s(at: str, now: datetime) -> float:
    """Seconds from ``at`` (a :func:`utc_now` stamp) to ``now``."""
    return (now - datetime.fromisoformat(at.replace("Z", "+00:00"))).total_seconds()


def connect(path: Path) -> sqlite3.Connection:
    conn = sqlite3.connect(str(path), timeout=30, isolation_level=None)
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=FULL")
    return conn


DEFAULT_NAMES = {"people": "responses.sqlite", "simulated": "simulated.sqlite"}


def open_db(path: Path, design: dict, participants: str = "people") -> Path:
    """Create the database (or check that it belongs to ``design`` and holds ``participants``:
    ``people`` or ``simulated``); its path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.is_dir():
        raise LaughlabError(f"{path} is a folder, not a database; give --db a file")
    try:
        conn = connect(path)
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if tables and "study" not in tables:
            conn.close()
            raise LaughlabError(f"{path} is a database of something else (tables {', '.join(sorted(tables)[:3])}); "
                                "give another --db")
        conn.executescript(SCHEMA)
        have = {r[1] for r in conn.execute("PRAGMA table_info(sessions)")}
        for column in ("declined_at", "external_id"):   # a database from before 2026-11-29
            if column not in have:
                conn.execute(f"ALTER TABLE sessions ADD COLUMN {column} TEXT")
    except sqlite3.DatabaseError as exc:
        raise LaughlabError(f"{path} is not a study database ({exc}); give another --db") from None
    try:
        row = conn.execute("SELECT value FROM study WHERE key = 'design_id'").fetchone()
        if row is None:
            with _transaction(conn):
                conn.execute("INSERT INTO study VALUES ('design_id', ?), ('design', ?), ('participants', ?)",
                             (design["id"], json.dumps(design, sort_keys=True), participants))
            return path
        if row[0] != design["id"]:
            from laughlab.study.design import extends

            old = json.loads((conn.execute("SELECT value FROM study WHERE key = 'design'").fetchone() or ["{}"])[0])
            if not extends(design, old):
                raise LaughlabError(f"{path} holds the responses of another study (design {row[0]}, this one is "
                                    f"{design['id']}); give another --db")
            with _transaction(conn):   # the same study built for more participants: its answers stay valid
                conn.execute("UPDATE study SET value = ? WHERE key = 'design_id'", (design["id"],))
                conn.execute("UPDATE study SET value = ? WHERE key = 'design'", (json.dumps(design, sort_keys=True),))
            print(f"laughlab: note: {path} now belongs to this build of the study, the same one for "
                  f"{len(design['participants'])} participants where it had {len(old.get('participants') or {})}",
                  file=sys.stderr)
        held = _participants(conn)
        if held != participants:
            other = DEFAULT_NAMES[participants]
            what = "simulated participants' answers" if held == "simulated" else "the answers of people"
            mine = "people's answers" if participants == "people" else "simulated answers"
            raise LaughlabError(f"{path} holds {what}; {mine} go into a database of their own "
                                f"(give another --db, e.g. {path.with_name(other)})")
    finally:
        conn.close()
    return path


def participants_stored(path: Path) -> list[int]:
    """The participants with at least one stored answer."""
    conn = _reader(path)
    try:
        return [r[0] for r in conn.execute("SELECT DISTINCT participant FROM answers ORDER BY participant")]
    finally:
        conn.close()


def _participants(conn: sqlite3.Connection) -> str:
    """``people`` or ``simulated``.  A database written before the key existed is ``simulated`` when
    every session came from headless Chromium (``study simulate``), else ``people``."""
    row = conn.execute("SELECT value FROM study WHERE key = 'participants'").fetchone()
    if row:
        return row[0]
    agents = [r[0] or "" for r in conn.execute("SELECT user_agent FROM sessions")]
    return "simulated" if agents and all("HeadlessChrome" in a for a in agents) else "people"


def participants_kind(path: Path) -> str | None:
    """``people`` or ``simulated`` for a study database (None if it is not one)."""
    if not Path(path).is_file():
        return None
    conn = _reader(path)
    try:
        return _participants(conn)
    except sqlite3.DatabaseError:
        return None
    finally:
        conn.close()


def _reader(path: Path) -> sqlite3.Connection:
    """A connection for reading an existing database.  Not ``mode=ro``: a read-only connection to a database in
    WAL mode leaves its ``-wal`` and ``-shm`` files beside it; this one removes them when it closes (it writes
    nothing)."""
    return sqlite3.connect(str(path), timeout=30)


class _transaction:
    def __init__(self, conn):
        self.conn = conn

    def __enter__(self):
        self.conn.execute("BEGIN IMMEDIATE")
        return self.conn

    def __exit__(self, kind, exc, tb):
        self.conn.execute("COMMIT" if kind is None else "ROLLBACK")


def insert_answers(path: Path, rows: list[dict]) -> None:
    """Store ``rows`` (dicts with :data:`COLUMNS`) in one transaction; :class:`Duplicate` if any is stored."""
    conn = connect(path)
    try:
        with _transaction(conn):
            for r in rows:
                try:
                    conn.execute(f"INSERT INTO answers ({', '.join(COLUMNS)}) VALUES ({', '.join('?' * len(COLUMNS))})",
                                 [r.get(c) for c in COLUMNS])
                except sqlite3.IntegrityError:
                    raise Duplicate(f"participant {r['participant']} trial {r['trial']} {r['question']} "
                                    "is already stored") from None
    finally:
        conn.close()


def session_event(path: Path, session: str, participant: int, event: str, user_agent: str = "",
                  external_id: str | None = None) -> bool:
    """``start`` inserts the session (:class:`SessionRefused` if it is another participant's), with the panel's ID
    the page came with; ``consent``, ``decline`` and ``finish`` stamp it (the first time), and only a session
    ``participant`` started.  Whether the participant has given consent (:func:`consented`), after the event."""
    conn = connect(path)
    try:
        with _transaction(conn):
            if event == "start":
                conn.execute("INSERT OR IGNORE INTO sessions (session, participant, started_at, user_agent, "
                             "external_id) VALUES (?, ?, ?, ?, ?)",
                             (session, participant, utc_now(), user_agent, external_id))
            _check_session(conn, session, participant)
            column = {"consent": "consent_at", "decline": "declined_at", "finish": "finished_at"}.get(event)
            if column:
                conn.execute(f"UPDATE sessions SET {column} = COALESCE({column}, ?) WHERE session = ?",
                             (utc_now(), session))
            return consented(conn, participant)
    finally:
        conn.close()


def _check_session(conn: sqlite3.Connection, session: str, participant: int) -> None:
    row = conn.execute("SELECT participant, external_id FROM sessions WHERE session = ?", (session,)).fetchone()
    if row is None:
        raise SessionRefused(f"session {session} was never started (api/start): reload the page")
    if row[0] != participant:
        raise SessionRefused(f"session {session} belongs to participant {row[0]}, not {participant}: reload the page")
    held = conn.execute("SELECT external_id FROM assignments WHERE participant = ?", (participant,)).fetchone()
    # a panel's page: its number may have gone to another ID after half an hour (assign); a number typed by hand
    # likewise (a diff review: its reader consented after the number went to a panel's ID, and both held it)
    if (row[1] is not None and (held is None or held[0] != row[1])) or (row[1] is None and held is not None):
        raise SessionRefused("this page's place in the study went to another participant after half an hour "
                             "without consent: reload the page to take part")


def check_session(path: Path, session: str, participant: int) -> bool:
    """:class:`SessionRefused` unless ``participant`` started ``session``; whether they gave consent (in any of
    their sessions: one who comes back is not asked again)."""
    conn = connect(path)
    try:
        _check_session(conn, session, participant)
        return consented(conn, participant)
    finally:
        conn.close()


def participant_key(path: Path, participant: int, give: str | None = None) -> str | None:
    """The key of ``participant``'s browser, taken with their consent (None before); ``give``: the key to take if
    there is none yet (the page's own, made before it posts the consent, so a reload right after finds it, or the
    server's).  Every later post of theirs carries it, so no one else can answer as them (a security review: their
    number, or their panel ID, was all it took to answer, screen them out or end their study)."""
    conn = connect(path)
    try:
        with _transaction(conn):
            if give:
                conn.execute("INSERT OR IGNORE INTO participant_keys VALUES (?, ?)", (participant, give))
            row = conn.execute("SELECT key FROM participant_keys WHERE participant = ?", (participant,)).fetchone()
            return row[0] if row else None
    finally:
        conn.close()


def consented(conn: sqlite3.Connection, participant: int) -> bool:
    return conn.execute("SELECT 1 FROM sessions WHERE participant = ? AND consent_at IS NOT NULL",
                        (participant,)).fetchone() is not None


#: a panel's number held this long (s) without consent is given to the next ID (a study-pilot review: fake IDs took
#: every number in 0.03 s, for good); a decline gives it back at once
HOLD_S = 30 * 60


def assign(path: Path, external_id: str, numbers: list[int], hold_s: float = HOLD_S) -> int | None:
    """The participant number of a panel's ID: the one it was given before, else the first of ``numbers`` free; None
    when every number is taken.  Free: never given, or used by hand (a session without a panel's ID) with no consent
    for ``hold_s``, or given to an ID that declined, or that gave no consent within ``hold_s`` (that ID loses it:
    coming back, it gets another).  A number whose holder consented is theirs for good.  One transaction, so two participants arriving at
    once get two numbers."""
    conn = connect(path)
    try:
        with _transaction(conn):
            row = conn.execute("SELECT participant FROM assignments WHERE external_id = ?", (external_id,)).fetchone()
            if row:
                return int(row[0])
            now = datetime.now(timezone.utc)
            for ext, p, at in conn.execute("SELECT external_id, participant, assigned_at FROM assignments").fetchall():
                mine = conn.execute("SELECT MAX(consent_at IS NOT NULL), MAX(declined_at IS NOT NULL) FROM sessions "
                                    "WHERE participant = ? AND external_id = ?", (p, ext)).fetchone()
                if mine[0]:
                    continue
                old = _age_s(at, now) > hold_s
                if mine[1] or old:
                    conn.execute("DELETE FROM assignments WHERE external_id = ?", (ext,))
            taken = {r[0] for r in conn.execute(
                "SELECT participant FROM assignments UNION SELECT participant FROM sessions "
                "WHERE consent_at IS NOT NULL")}
            # a number typed by hand (no panel ID) is held as a panel's is: for half an hour without consent (a
            # security review: 24 page loads by hand took every place from the panel for good)
            # from its first page load: a script starting again every 29 minutes does not renew it (a diff review)
            for p, at in conn.execute("SELECT participant, MIN(started_at) FROM sessions WHERE external_id IS NULL "
                                      "GROUP BY participant").fetchall():
                if _age_s(at, now) <= hold_s:
                    taken.add(p)
            free = next((n for n in numbers if n not in taken), None)
            if free is not None:
                conn.execute("INSERT INTO assignments VALUES (?, ?, ?)", (external_id, free, utc_now()))
            return free
    finally:
        conn.close()


def assigned_to(path: Path, participant: int) -> str | None:
    """The panel's ID ``participant``'s number is given to now, or None."""
    conn = connect(path)
    try:
        row = conn.execute("SELECT external_id FROM assignments WHERE participant = ?", (participant,)).fetchone()
        return row[0] if row else None
    finally:
        conn.close()


def assignments(path: Path) -> list[dict]:
    """Each panel ID with its participant number and that participant's sessions' consent, decline and finish
    (the first of each) and sound check (``passed``, ``failed`` or empty), for paying and approving submissions
    (a failed check ends the study by default: a screen-out)."""
    conn = _reader(path)
    try:
        cur = conn.execute(
            "SELECT a.external_id, a.participant, a.assigned_at, MIN(s.consent_at), MIN(s.declined_at), "
            "MIN(s.finished_at), (SELECT value FROM answers WHERE participant = a.participant AND kind = "
            "'audio_check') FROM assignments a LEFT JOIN sessions s ON s.participant = a.participant "
            "AND s.external_id = a.external_id "
            "GROUP BY a.external_id ORDER BY a.participant")
        keys = ("external_id", "participant", "assigned_at", "consent_at", "declined_at", "finished_at", "sound_check")
        check = {None: "", 1.0: "passed", 0.0: "failed"}
        return [{**dict(zip(keys, r)), "sound_check": check[r[6]]} for r in cur]
    finally:
        conn.close()


def sessions(path: Path) -> list[dict]:
    """Every session's row (older databases: ``declined_at`` and ``external_id`` None)."""
    conn = _reader(path)
    try:
        conn.row_factory = sqlite3.Row
        return [{"declined_at": None, "external_id": None, **dict(r)}
                for r in conn.execute("SELECT * FROM sessions ORDER BY started_at")]
    finally:
        conn.close()


def progress(path: Path, participant: int) -> tuple[list[int], bool | None]:
    """The trials a participant has answered and their audio check: passed (True), failed (False) or not stored."""
    conn = connect(path)
    try:
        trials = [r[0] for r in conn.execute("SELECT DISTINCT trial FROM answers WHERE participant = ? AND trial > 0 "
                                             "ORDER BY trial", (participant,))]
        checked = conn.execute("SELECT value FROM answers WHERE participant = ? AND kind = 'audio_check'",
                               (participant,)).fetchone()
    finally:
        conn.close()
    return trials, None if checked is None else checked[0] == 1


def rows(path: Path) -> list[dict]:
    """Every stored answer, by participant, trial and question (:data:`COLUMNS`)."""
    path = Path(path)
    if not path.is_file():
        raise LaughlabError(f"no database at {path}")
    conn = _reader(path)
    try:
        cur = conn.execute(f"SELECT {', '.join(COLUMNS)} FROM answers ORDER BY participant, trial, question")
        return [dict(zip(COLUMNS, r)) for r in cur]
    except sqlite3.DatabaseError as exc:
        raise LaughlabError(f"{path} is not a study database: {exc}") from None
    finally:
        conn.close()


def stored_design(path: Path) -> dict | None:
    return stored(path, "design")


def stored(path: Path, key: str):
    """The JSON value stored under ``key`` in the study table (``design``, ``simulation``), or None."""
    if not Path(path).is_file():
        return None
    conn = _reader(path)
    try:
        row = conn.execute("SELECT value FROM study WHERE key = ?", (key,)).fetchone()
    except sqlite3.DatabaseError:
        row = None
    finally:
        conn.close()
    return json.loads(row[0]) if row else None


def store(path: Path, key: str, value) -> None:
    """Store ``value`` (JSON) under ``key`` in the study table (``simulation``: what ``study simulate`` planted)."""
    conn = connect(Path(path))
    try:
        with _transaction(conn):
            conn.execute("INSERT OR REPLACE INTO study VALUES (?, ?)", (key, json.dumps(value, sort_keys=True)))
    finally:
        conn.close()


def to_csv(rows_: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    w.writerows(rows_)
    return buf.getvalue()
