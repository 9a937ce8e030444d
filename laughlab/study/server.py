"""``python -m laughlab study serve STUDY_DIR``: the study page, and every answer into SQLite as it arrives.

The files are served by the viewer's server (``laughlab.viewer.server.http_server``: threads, byte
ranges); this module adds four JSON endpoints the page posts to (``Content-Type: application/json``,
at most :data:`MAX_BODY` bytes):

=================  ===========================================================================
``api/assign``     ``{external_id, design}``: a recruitment panel's ID for the participant (Prolific's
                   ``PROLIFIC_PID``, MTurk's ``workerId`` in the page's URL) gets a participant number,
                   the same one each time it comes back, the next free one otherwise
                   (``db.assign``: a number held without consent for half an hour, or declined, is
                   given again; 409 when every number is taken)
``api/start``      ``{participant, session, design, user_agent[, external_id]}``: opens a session (a
                   number given to a panel's ID only with that ID: 403; ``--panel``: every number);
                   answers the
                   trials already stored, whether the audio check is, and whether the participant
                   gave consent (the page resumes there; one who did is not asked again)
``api/response``   ``{participant, session, trial, stimulus, answers: {question: value}, rt_ms,
                   shown_at, answered_at, user_agent}``: one trial's answers, stored in one
                   transaction (``laughlab.study.db``)
``api/check``      ``{participant, session, attempts: [text], rt_ms, user_agent}``: the audio check;
                   the server decides whether the last attempt is the participant's word
``api/event``      ``{participant, session, event}``: ``consent``, ``decline``, ``finish``
=================  ===========================================================================

Answers (``api/response``, ``api/check``) and events are taken only from a session the participant
started (409 otherwise: another participant's session, or none), and answers and ``finish`` only once
the participant gave consent (403: since 2026-11-29; a review found answers stored from a page that
never asked, and declines not stored).

Everything is checked against the design before it is stored: the participant must be one of the
design's, the trial that participant's, the stimulus the one shown in that trial, the questions
exactly the trial's (the attention item only where the design puts one), every value a number on
the scale (a whole number for Likert), times and texts short.  Anything else is refused with a 4xx
and one JSON line in ``<db>.rejected.log`` (time, path, status, reason, the body's start: no client
address, as the default consent text promises that no IP address is kept),
and is never stored: 400 malformed JSON, 404 unknown endpoint, 409 already stored or another
study's page or another participant's session, 403 no consent, 411 no length, 413 too large, 415 not JSON, 422 not in the design or out of range.
"""
from __future__ import annotations

import hmac
import json
import math
import re
import sys
import threading
from datetime import datetime
from pathlib import Path

from laughlab.core.errors import LaughlabError
from laughlab.study import db as DB
from laughlab.study.build import OWN
from laughlab.study.design import load_design, normalise_word, scale_range
from laughlab.viewer.server import DEFAULT_PORT, _Handler, http_server

MAX_BODY = 16 * 1024
#: the refused-posts log stops at this size (bytes); the logs that reached it in this process
LOG_MAX = 10 * 1024 * 1024
_FULL: set = set()
_SESSION = re.compile(r"[A-Za-z0-9-]{1,64}")
_KEY = re.compile(r"[A-Za-z0-9_-]{16,64}")
_EXTERNAL = re.compile(r"[A-Za-z0-9_.@-]{1,128}")


class Refused(LaughlabError):
    def __init__(self, status: int, reason: str):
        super().__init__(reason)
        self.status = status


def _int(body: dict, key: str) -> int:
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise Refused(422, f"{key} must be a whole number (got {v!r})"[:200])
    return v


def _number(v, what: str, lo: float, hi: float, whole: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise Refused(422, f"{what} must be a number (got {v!r})"[:200])
    if whole and v != int(v):
        raise Refused(422, f"{what} must be a whole number (got {v!r})")
    if not lo <= v <= hi:
        raise Refused(422, f"{what} {v!r} is out of range {lo:g}..{hi:g}")
    return float(v)


def _text(body: dict, key: str, limit: int, required: bool = False) -> str:
    v = body.get(key, "")
    if not isinstance(v, str) or len(v) > limit or (required and not v):
        raise Refused(422, f"{key} must be a text of at most {limit} characters")
    try:
        v.encode("utf-8")
    except UnicodeEncodeError:   # a lone surrogate ('\ud800'): SQLite's error dropped the connection
        raise Refused(422, f"{key} is not valid text (a lone surrogate)") from None
    return v


def _time(body: dict, key: str) -> str | None:
    v = _text(body, key, 40)
    if not v:
        return None
    try:
        datetime.fromisoformat(v.replace("Z", "+00:00"))
    except ValueError:
        raise Refused(422, f"{key} must be an ISO 8601 time (got {v!r})") from None
    return v


def _elsewhere(p: int) -> Refused:
    """403: participant ``p``'s key is another browser's."""
    return Refused(403, f"participant {p} takes part in another browser or on another device: please go on there "
                        "(tell the researcher if you cannot)")


def _keys(body: dict, allowed: set[str]) -> None:
    extra = sorted(set(body) - allowed)
    if extra:
        raise Refused(422, f"unknown field(s) {', '.join(map(str, extra))[:120]}")


class StudyHandler(_Handler):
    served = "this study's page"
    design: dict = {}
    db: Path = Path()
    log: Path = Path()
    quiet: bool = False
    panel_only: bool = False   # study serve --panel
    _lock = threading.Lock()

    # -- plumbing ---------------------------------------------------------------------------------------------------
    def _send(self, head: bool = False) -> None:   # GET and HEAD
        if not self.path.startswith("/api/"):
            super()._send(head)
        elif head:
            self.send_error(405)
        else:
            self._reply(405, {"error": "the study's endpoints take POST"})

    def do_POST(self):  # noqa: N802
        route = self.path.split("?", 1)[0].lstrip("/")
        raw = b""
        try:
            action = {"api/start": self.start, "api/response": self.response, "api/check": self.check,
                      "api/event": self.event, "api/assign": self.assign}.get(route)
            if action is None:
                raise Refused(404, f"no endpoint {route[:80]!r}")
            length = self.headers.get("Content-Length")
            if length is None or not (length.isascii() and length.isdigit()):   # not '²' (a security review)
                raise Refused(411, "a Content-Length is needed")
            if int(length) > MAX_BODY:
                self.close_connection = True  # the body is not read
                raise Refused(413, f"body of {int(length)} bytes, at most {MAX_BODY}")
            raw = self.rfile.read(int(length))
            if self.headers.get_content_type() != "application/json":
                raise Refused(415, "the body must be application/json")
            try:
                body = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, ValueError, RecursionError):   # nested 100,000 deep: a dropped connection
                raise Refused(400, "the body is not JSON") from None
            if not isinstance(body, dict):
                raise Refused(400, "the body must be a JSON object")
            status, payload = action(body)
        except Refused as exc:
            self._refuse(exc.status, str(exc), route, raw)
            return
        except (DB.Duplicate, DB.SessionRefused) as exc:
            self._refuse(409, str(exc), route, raw)
            return
        self._reply(status, payload)

    def _reply(self, status: int, payload: dict) -> None:
        data = json.dumps({"laughlab": True, **payload}).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(data)

    def _refuse(self, status: int, reason: str, route: str, raw: bytes) -> None:
        # no client address: the consent text promises that no IP address is kept (a review found it here)
        body = raw.decode("utf-8", "replace")
        try:   # a panel's ID stays out of the log (a study-pilot review found refused PIDs there), before the body is
            sent = json.loads(raw)   # cut (a security review: its start was left at the cut); a key too
            ext, key = sent.get("external_id"), sent.get("key")
            if isinstance(ext, str) and ext:
                body, reason = body.replace(ext, "<panel ID>"), reason.replace(ext[:40], "<panel ID>")
            if isinstance(key, str) and key:
                body = body.replace(key, "<key>")
        except (ValueError, AttributeError, RecursionError):
            pass
        line = {"time": DB.utc_now(), "path": route[:100], "status": status, "reason": reason, "body": body[:200]}
        with self._lock:   # at most LOG_MAX bytes: a client posting refusals all day filled the disk (a security review)
            size = self.log.stat().st_size if self.log.exists() else 0
            if size + 1000 >= LOG_MAX:   # said once, as the log's last line
                line = None if self.log in _FULL else {"time": DB.utc_now(), "note": f"the log reached {LOG_MAX} "
                                                       "bytes: later refusals are not logged"}
                _FULL.add(self.log)
            if line is not None:
                with open(self.log, "a", encoding="utf-8") as f:
                    f.write(json.dumps(line) + "\n")
        if not self.quiet:
            print(f"study: refused {route[:60]} ({status}): {reason}", file=sys.stderr, flush=True)
        self._reply(status, {"error": reason})

    # -- checks -----------------------------------------------------------------------------------------------------
    def _participant(self, body: dict) -> tuple[int, dict, str]:
        p = _int(body, "participant")
        entry = self.design["participants"].get(str(p))
        if entry is None:
            raise Refused(422, f"participant {p} is not in the design (1..{len(self.design['participants'])})")
        session = body.get("session")
        if not isinstance(session, str) or not _SESSION.fullmatch(session):
            raise Refused(422, "session must be 1-64 letters, digits or -")
        return p, entry, session

    def _key(self, p: int, body: dict) -> None:
        """Refuse a post for ``p`` without the key their browser was given when they consented (403)."""
        key = DB.participant_key(self.db, p)
        given = body.get("key")   # compared in constant time: a key's bytes are not told apart by the answer's time
        if key is not None and not (isinstance(given, str)   # a lone surrogate ('\ud800', legal JSON) encodes too
                                    and hmac.compare_digest(given.encode("utf-8", "surrogatepass"), key.encode())):
            raise _elsewhere(p)

    def _consented(self, p: int, session: str) -> None:
        if not DB.check_session(self.db, session, p):
            raise Refused(403, f"participant {p} has not given consent: nothing is stored before it")

    # -- endpoints --------------------------------------------------------------------------------------------------
    def _external(self, body: dict) -> str:
        ext = body.get("external_id")
        if not isinstance(ext, str) or not _EXTERNAL.fullmatch(ext):
            raise Refused(422, f"this link's ID from the recruitment site ({str(ext)[:40]!r}) is not one the study can "
                               "take (1-128 letters, digits or _.@-): please tell the researcher")
        return ext

    def start(self, body: dict):
        _keys(body, {"participant", "session", "design", "user_agent", "external_id", "key"})
        p, _, session = self._participant(body)
        self._key(p, body)
        if body.get("design") != self.design["id"]:
            raise Refused(409, "this page belongs to another build of the study: reload it")
        ext = self._external(body) if body.get("external_id") is not None else None
        held = DB.assigned_to(self.db, p)
        # a number given to a panel's ID answers only to it (a study-pilot review: ?participant=7 typed by hand went
        # on with another participant's study); --panel: no number typed by hand at all
        if (held is not None or self.panel_only) and (ext is None or ext != held):
            raise Refused(403, f"participant {p} takes part through the recruitment site's link only: please open "
                               "the study from there")
        agreed = DB.session_event(self.db, session, p, "start", _text(body, "user_agent", 512), ext)
        answered, checked = DB.progress(self.db, p)
        return 200, {"answered": answered, "audio_check": checked is not None, "audio_check_passed": checked,
                     "consented": agreed}

    def assign(self, body: dict):
        _keys(body, {"external_id", "design"})
        if body.get("design") != self.design["id"]:
            raise Refused(409, "this page belongs to another build of the study: reload it")
        ext = self._external(body)
        numbers = sorted(int(n) for n in self.design["participants"])
        p = DB.assign(self.db, ext, numbers)
        if p is None:
            raise Refused(409, f"the study is full for now (its {len(numbers)} places are taken): please return it on "
                               "the recruitment site, or try again in half an hour")
        return 200, {"participant": p}

    def response(self, body: dict):
        _keys(body, {"participant", "session", "trial", "stimulus", "answers", "rt_ms", "shown_at", "answered_at",
                     "user_agent", "key"})
        p, entry, session = self._participant(body)
        self._key(p, body)
        t = _int(body, "trial")
        if not 1 <= t <= len(entry["trials"]):
            raise Refused(422, f"participant {p} has no trial {t} (1..{len(entry['trials'])})")
        trial = entry["trials"][t - 1]
        stimulus = body.get("stimulus")
        if stimulus not in self.design["stimuli"]:
            raise Refused(422, f"unknown stimulus {str(stimulus)[:80]!r}")
        if stimulus != trial["stimulus"]:
            raise Refused(422, f"trial {t} of participant {p} shows {trial['stimulus']}, not {stimulus}")
        answers = body.get("answers")
        want = [q["id"] for q in self.design["questions"]] + (["attention"] if trial["attention"] else [])
        if not isinstance(answers, dict) or sorted(answers) != sorted(want):
            raise Refused(422, f"answers must give exactly {', '.join(want)}")
        lo, hi = scale_range(self.design)
        whole = self.design["scale"] == "likert"
        values = {q: _number(answers[q], q, lo, hi, whole) for q in want}
        rt = _number(body.get("rt_ms", 0), "rt_ms", 0, 86_400_000)
        common = {"participant": p, "order_row": entry["order_row"], "trial": t, "stimulus": stimulus,
                  "condition": trial["condition"], "audio_id": trial["audio_id"], "rt_ms": rt,
                  "shown_at": _time(body, "shown_at"), "answered_at": _time(body, "answered_at"),
                  "received_at": DB.utc_now(), "session": session, "user_agent": _text(body, "user_agent", 512)}
        rows = [{**common, "kind": "attention" if q == "attention" else "rating", "question": q, "value": v,
                 "text": "", "expected": float(self.design["attention"]["value"]) if q == "attention" else None}
                for q, v in values.items()]
        self._consented(p, session)   # after the body's checks: a malformed post is told what is wrong with it
        if self.design.get("audio_check_on_fail") == "end" and DB.progress(self.db, p)[1] is False:
            raise Refused(403, f"participant {p} did not pass the sound check: the study ended there")
        DB.insert_answers(self.db, rows)
        return 201, {"stored": len(rows)}

    def check(self, body: dict):
        _keys(body, {"participant", "session", "attempts", "rt_ms", "user_agent", "key"})
        p, entry, session = self._participant(body)
        self._key(p, body)
        attempts = body.get("attempts")
        n = int(self.design["audio_check"]["attempts"])
        if not isinstance(attempts, list) or not 1 <= len(attempts) <= n or \
                not all(isinstance(a, str) and len(a) <= 64 and "|" not in a for a in attempts):
            raise Refused(422, f"attempts must be 1..{n} texts of at most 64 characters")
        for a in attempts:   # and valid text (a lone surrogate)
            _text({"attempt": a}, "attempt", 64)
        word = self.design["audio_check"]["files"][entry["audio_check"]]["answer"]
        passed = normalise_word(attempts[-1]) == normalise_word(word)
        row = {"participant": p, "order_row": entry["order_row"], "trial": 0, "stimulus": "", "condition": "",
               "audio_id": "", "kind": "audio_check", "question": "audio_check", "value": 1.0 if passed else 0.0,
               "text": "|".join(attempts), "expected": None,
               "rt_ms": _number(body.get("rt_ms", 0), "rt_ms", 0, 86_400_000), "shown_at": None,
               "answered_at": None, "received_at": DB.utc_now(), "session": session,
               "user_agent": _text(body, "user_agent", 512)}
        self._consented(p, session)
        DB.insert_answers(self.db, [row])
        return 201, {"stored": 1, "passed": passed}

    def event(self, body: dict):
        _keys(body, {"participant", "session", "event", "key"})
        p, entry, session = self._participant(body)
        self._key(p, body)
        if body.get("event") not in ("consent", "decline", "finish"):
            raise Refused(422, "event must be consent, decline or finish")
        key = body.get("key")
        if key is not None and (not isinstance(key, str) or not _KEY.fullmatch(key)):   # before anything is stored
            raise Refused(422, "key must be 16-64 letters, digits, - or _")
        if body["event"] == "finish":
            self._consented(p, session)
            answered, n = len(DB.progress(self.db, p)[0]), len(entry["trials"])
            if answered < n:   # a security review: a finish posted by hand put a finished_at in the payment list
                raise Refused(409, f"participant {p} has answered {answered} of {n} trials: the study is finished "
                                   "with the last")
        agreed = DB.session_event(self.db, session, p, body["event"])
        # the participant's key, given with their consent (and to the page that holds it): every later post carries it
        if not (agreed and body["event"] == "consent"):
            return 200, {}
        import secrets

        offered = key or secrets.token_urlsafe(18)
        stored = DB.participant_key(self.db, p, give=offered)
        if stored != offered:   # two pages consenting at once (a diff review: the second was handed the first one's key)
            raise _elsewhere(p)
        return 200, {"key": stored}


def files_of(study_dir: Path) -> dict[str, Path]:
    """The page's files by their URL path: only what ``study build`` wrote (``build.OWN``: the page, ``design.js``,
    the stimuli, the audio check's words, the vendored jsPsych), hidden files and ``design.json`` (it holds the audio
    check's words; the page reads ``design.js``) left out.  Anything else in the folder is never sent: the databases,
    their logs, and ``study analyze``'s and ``study power``'s reports, which hold every answer and sit beside the
    database by default (a review found ``simulated-report/tidy.csv`` served to anyone)."""
    out = {}
    for name in OWN:
        top = study_dir / name
        for f in ([top] if top.is_file() else sorted(top.rglob("*")) if top.is_dir() else []):
            rel = f.relative_to(study_dir).as_posix()
            # no symbolic link (a security review: stimuli/x.mp4 -> ../design.json sent the audio check's words)
            linked = any((study_dir / "/".join(rel.split("/")[:k])).is_symlink() for k in range(1, rel.count("/") + 2))
            if f.is_file() and not linked and not any(part.startswith(".") for part in rel.split("/")) \
                    and rel != "design.json":
                out[rel] = f
    return dict(sorted(out.items()))


def server(study_dir, db: str | Path | None = None, port: int = DEFAULT_PORT, host: str = "127.0.0.1",
           quiet: bool = False, participants: str = "people", panel: bool = False):
    """The study's server (not yet serving): the page's files and the endpoints above.  ``participants``
    (``people`` or ``simulated``) chooses the default database and is checked against a given one; ``panel``: every
    participant comes through a recruitment site's link (``api/assign``), none by a number typed by hand."""
    study_dir = Path(study_dir).expanduser()
    design = load_design(study_dir)
    db_path = DB.open_db(Path(db).expanduser() if db else study_dir / DB.DEFAULT_NAMES[participants], design,
                         participants)
    # loopback=False: a study behind a reverse proxy (HTTPS on its own domain) is reached by the proxy's Host, and its
    # page is public by nature
    return http_server(files_of(study_dir), port, base=StudyHandler, host=host, design=design, db=db_path,
                       loopback=False, log=db_path.with_name(db_path.name + ".rejected.log"), quiet=quiet,
                       panel_only=panel)
