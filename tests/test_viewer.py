"""``python -m laughlab view``: the character in a real headless Chromium, in sync with the audio (issue 13, item 3)."""
import io
import json
import os
import threading
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.viewer import server as V
from laughlab.viewer.browser import Page


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer")
    cfg = compose_config(["face=facs", "input.duration_s=6", "~output.plots"])   # the page shows no figure
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    pipeline.execute(pipeline.build(cfg), out)
    return out


@pytest.fixture(scope="module")
def page(run_dir):
    httpd = V.server(run_dir, 0)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    p = Page(f"http://127.0.0.1:{httpd.server_address[1]}/")
    p.wait_ready()
    yield p
    p.close()
    httpd.shutdown()


@pytest.mark.browser
def test_the_page_loads_without_console_errors(page):
    assert page.eval("window.laughlab.error") is None
    assert page.problems() == []


@pytest.mark.browser
@pytest.mark.parametrize("t", [2.5, 0.4, 5.25])
def test_the_animation_follows_the_audio_clock_within_a_frame_after_a_seek(page, t):
    got = page.eval(f"window.laughlab.check({t})")
    assert got["audio"] == pytest.approx(t, abs=0.01)  # the audio really seeked (byte ranges served)
    assert abs(got["anim"] - got["audio"]) <= 1.0 / got["fps"]


def shows_the_character(png: bytes) -> None:
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    view = img[: int(0.6 * img.shape[0])]
    background = np.array([0x2a, 0x30, 0x40])
    figure = np.abs(view - background).sum(axis=2) > 60
    assert figure.mean() > 0.05  # the character and the floor cover a good part of the view
    r, g, b = view[..., 0], view[..., 1], view[..., 2]
    skin = figure & (r > g + 20) & (g > b) & (r > 150)
    shirt = figure & (b > r + 25)
    assert skin.sum() > 200 and shirt.sum() > 2000  # a face and hands, a blue shirt: not only a floor


@pytest.mark.browser
def test_a_screenshot_shows_the_character(page):
    page.eval("window.laughlab.check(3.0)")
    shows_the_character(page.screenshot())


def whole_character_above_the_bar(page, times=(0.5, 2.0, 4.0, 5.5)):
    """Issue 26: the control bar hid the character's feet.  Every vertex of the posed character projects
    into the 3D view, which ends where the bar starts."""
    for t in times:
        page.eval(f"window.laughlab.check({t})")
        at = page.eval("window.laughlab.onScreen()")
        assert at["viewBottom"] <= at["barTop"] + 0.5, at                     # the view ends above the bar
        assert at["viewTop"] < at["highest"] and at["feet"] < at["lowest"] < at["barTop"] - 4, (t, at)


@pytest.mark.browser
def test_the_control_bar_never_covers_the_character(page):
    whole_character_above_the_bar(page)


def test_bad_input_is_one_line(tmp_path, run_dir):
    r = laughlab("view", str(tmp_path / "nope"))
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no run directory" in r.stderr
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "channels.csv").write_text("time\n0\n")
    r = laughlab("view", str(tmp_path / "half"))
    assert r.returncode == 2 and "motion.bvh, events.csv" in r.stderr and "Traceback" not in r.stderr


def test_a_port_in_use_gives_a_free_one(run_dir):
    first = V.server(run_dir, 0)
    try:
        second = V.server(run_dir, first.server_address[1])
        assert second.server_address[1] != first.server_address[1]
        second.server_close()
    finally:
        first.server_close()


def test_the_page_can_be_written_for_static_hosting(run_dir, tmp_path):
    out, opens_as_file = V.write(run_dir, tmp_path / "site")
    assert out == tmp_path / "site" and opens_as_file
    names = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert {"index.html", "viewer.js", "run.json", "character.glb", "audio.wav", "vendor/three/LICENSE",
            "vendor/three/build/three.module.min.js"} <= names
    run = json.loads((out / "run.json").read_text())
    assert run["fps"] == 60.0 and run["duration"] == pytest.approx(6.0) and run["clips"]
    with pytest.raises(Exception, match="not an empty folder"):
        V.write(run_dir, tmp_path / "site")
    (tmp_path / "notes.txt").write_text("mine\n")   # a file was "not an empty folder" (a new-user review)
    for overwrite in (False, True):
        with pytest.raises(Exception, match=r"notes.txt exists and is not a folder; choose another --out$"):
            V.write(run_dir, tmp_path / "notes.txt", overwrite=overwrite)
    assert (tmp_path / "notes.txt").read_text() == "mine\n"


@pytest.fixture(scope="module")
def site(run_dir, tmp_path_factory):
    out, opens_as_file = V.write(run_dir, tmp_path_factory.mktemp("static") / "site")
    assert opens_as_file
    return out


@pytest.mark.browser
@pytest.mark.parametrize("width, height", [(960, 720), pytest.param(1280, 500, marks=pytest.mark.slow),
                                           pytest.param(480, 900, marks=pytest.mark.slow)])  # wide, tall: test-all
def test_the_written_page_plays_opened_as_a_file(site, width, height):
    """Issue 26: ``view RUN --out DIR`` opened as a file showed a blank page with '0.00 / 0.00 s'."""
    p = Page((site / "index.html").as_uri(), width=width, height=height)
    try:
        p.wait_ready()
        assert p.eval("window.laughlab.error") is None and p.problems() == []
        got = p.eval("window.laughlab.check(2.5)")
        assert got["audio"] == pytest.approx(2.5, abs=0.01)   # the audio beside the page loads and seeks
        assert abs(got["anim"] - got["audio"]) <= 1.0 / got["fps"]
        assert p.eval("document.getElementById('time').textContent") == "2.50 / 6.00 s"
        whole_character_above_the_bar(p)
        if width == 960:
            shows_the_character(p.screenshot())
            p.eval("document.getElementById('play').click()")
            p.eval("new Promise((r) => setTimeout(r, 1500))")
            after = p.eval("window.laughlab.check(window.laughlab.audioTime())")
            assert after["audio"] > 2.6 and abs(after["anim"] - after["audio"]) <= 1.0 / after["fps"]  # it plays
    finally:
        p.close()


def shown_message(p, timeout: float = 60):
    """The text of the page's message once it is shown (None if it is not within ``timeout`` seconds)."""
    import time

    t0, msg = time.time(), None
    while msg is None and time.time() - t0 < timeout:
        msg = p.eval("(m => m && !m.hidden ? m.textContent : null)(document.getElementById('msg'))")
        time.sleep(0.2)
    return msg


@pytest.mark.browser
def test_a_page_too_large_to_inline_says_on_the_page_how_to_serve_it(run_dir, tmp_path, monkeypatch):
    from laughlab.viewer import page as P

    monkeypatch.setattr(P, "INLINE_MAX_BYTES", 1000)
    out, opens_as_file = V.write(run_dir, tmp_path / "big")
    assert not opens_as_file
    p = Page((out / "index.html").as_uri())
    try:
        msg = shown_message(p)
        assert msg is not None and "opened as a file" in msg
        assert f"python -m http.server -d {out} 8000" in msg and f"python -m laughlab view {run_dir}" in msg
        assert p.eval("document.getElementById('time').textContent") == "not loaded"
    finally:
        p.close()


def test_a_written_page_holds_no_absolute_path_and_is_the_same_bytes_in_another_folder(run_dir, tmp_path):
    """A re-read: the page named its folder and the run's by their absolute paths (for the message on how to serve
    it), so a published page showed its author's folders; it finds its folder where it is opened now, and holds
    the run's path relative to it (the browser test above: the message still names both in full)."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    pages = [(V.write(run_dir, tmp_path / k / "page")[0] / "index.html").read_bytes() for k in ("a", "b")]
    assert pages[0] == pages[1]
    assert str(tmp_path).encode() not in pages[0] and str(run_dir).encode() not in pages[0]
    rel = os.path.relpath(run_dir, tmp_path / "a" / "page")
    assert f'<body data-run="{rel}">'.encode() in pages[0]


@pytest.mark.browser
def test_the_folders_the_page_names_are_quoted_as_shlex_quotes_them_and_windows_ones_as_cmd_takes_them(run_dir,
                                                                                                        tmp_path):
    """The folders in the line on how to serve the page come from where it was opened: one with a space is quoted
    (a shell split it), and the run's is resolved from its path relative to the page.

    A re-read: the page's quoting missed a backslash, brackets and a tilde in a POSIX path (a shell reads them),
    and its Windows branch was never run. Here each is worked out from a page's address as a browser gives it (the
    same function the page runs on a failure): a POSIX folder exactly as shlex.quote quotes it, a Windows one with
    backslashes, in double quotes where cmd would split it, a drive's root as C:\\.  (One page for both: the
    function is there once the page is parsed, before the viewer is ready.)"""
    import posixpath
    import shlex
    import time
    from urllib.parse import quote

    posix = ["/tmp/my page/index.html", "/tmp/it's/index.html", "/tmp/a\\b/index.html", "/tmp/[1]/index.html",
             "/tmp/~ann/index.html", "/tmp/ünï/index.html", "/tmp/a$b&c/index.html", "/index.html",
             "/tmp/plain-dir_1.2+x@y%z=w:v,u/index.html"]
    windows = {"/C:/Users/Ann Lee/site/index.html": ('"C:\\Users\\Ann Lee\\site"', '"C:\\Users\\Ann Lee\\run"'),
               "/D:/data/site/index.html": ("D:\\data\\site", "D:\\data\\run"),
               "/C:/index.html": ("C:\\", "C:\\run")}
    out, _ = V.write(run_dir, tmp_path / "my page")
    p = Page((out / "index.html").as_uri())
    try:
        t0 = time.time()
        while not p.eval("typeof window.laughlabHere === 'function' && document.readyState !== 'loading'"):
            assert time.time() - t0 < 60, p.problems()
            time.sleep(0.1)
        here = p.eval("window.laughlabHere()")   # where it was opened
        p.eval("document.body.dataset.run = '../run'")
        got = p.eval(f"{json.dumps([quote(x) for x in posix + list(windows)])}.map(x => window.laughlabHere(x))")
    finally:
        p.close()
    assert here == {"folder": shlex.quote(str(out)), "run": shlex.quote(str(run_dir))}
    assert here["folder"].startswith("'") and " " in here["folder"]
    for path, h in zip(posix, got):
        folder = posixpath.dirname(path)
        assert h == {"folder": shlex.quote(folder), "run": shlex.quote(posixpath.normpath(posixpath.join(folder, "../run")))}, path
    assert [(h["folder"], h["run"]) for h in got[len(posix):]] == list(windows.values())


@pytest.mark.browser
def test_a_folder_with_markup_in_its_name_is_text_in_the_pages_message(run_dir, tmp_path, monkeypatch):
    """The message on how to serve a page opened as a file was set as HTML with the folder's name in it: a folder
    named with a '<' became markup. It is text now, quoted as a shell takes it."""
    import shlex

    from laughlab.viewer import page as P

    monkeypatch.setattr(P, "INLINE_MAX_BYTES", 1000)   # a page that cannot open as a file: it says how to serve it
    out, _ = V.write(run_dir, tmp_path / "a <b>c</b>")
    p = Page((out / "index.html").as_uri())
    try:
        msg = shown_message(p)
        bold = p.eval("document.querySelectorAll('#msg b').length")
    finally:
        p.close()
    assert msg is not None and f"python -m http.server -d {shlex.quote(str(out))} 8000" in msg
    assert bold == 0


def test_view_out_says_how_to_open_the_page(run_dir, tmp_path):
    r = laughlab("view", str(run_dir), "--out", str(tmp_path / "s"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == (f"laughlab: viewer of {run_dir} written to {tmp_path / 's'}/: open "
                                f"{tmp_path / 's' / 'index.html'} in a browser, or put the folder on any web server "
                                f"(e.g. python -m http.server -d {tmp_path / 's'})")
    # a folder with a space: both commands quoted for the shell (a game developer's review: the first was not)
    r = laughlab("view", str(run_dir), "--out", str(tmp_path / "my site"))
    assert r.returncode == 0, r.stderr
    assert f"open '{tmp_path / 'my site' / 'index.html'}' in a browser" in r.stdout
    assert f"python -m http.server -d '{tmp_path / 'my site'}'" in r.stdout


def test_a_closed_browser_leaves_nothing_in_the_temporary_folder(monkeypatch):
    """Chromium keeps a singleton socket folder (``org.chromium.Chromium.*``) in TMPDIR and leaves it behind when
    killed: before, every screenshot or viewer test left one in /tmp. It now goes with the profile."""
    import shutil
    import tempfile

    # a short folder of its own: Chromium does not start where its socket's path passes 108 bytes (pytest's
    # tmp_path under xdist is that long)
    tmp = Path(tempfile.mkdtemp(prefix="ll", dir="/tmp"))
    try:
        monkeypatch.setenv("TMPDIR", str(tmp))
        monkeypatch.setattr(tempfile, "tempdir", None)   # tempfile reads TMPDIR again
        p = Page("about:blank")
        assert p.eval("1 + 1") == 2
        p.close()
        assert list(tmp.iterdir()) == []
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def test_chromium_that_cannot_start_says_why_in_one_line_and_leaves_nothing(monkeypatch):
    """A TMPDIR so long that Chromium's singleton socket path passes 108 bytes: Chromium stops at once."""
    import shutil
    import tempfile

    from laughlab.core.errors import LaughlabError

    tmp = Path(tempfile.mkdtemp(prefix="ll" + "x" * 90, dir="/tmp"))
    try:
        monkeypatch.setenv("TMPDIR", str(tmp))
        monkeypatch.setattr(tempfile, "tempdir", None)
        with pytest.raises(LaughlabError) as err:
            Page("about:blank")
        msg = str(err.value)
        assert msg.startswith("chromium did not start its DevTools endpoint: ") and "\n" not in msg
        assert "Socket path too long" in msg
        # no profile left (Chromium itself leaves the socket folder it could not use)
        assert [p.name for p in tmp.iterdir() if not p.name.startswith("org.chromium.")] == []
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def test_a_file_runs_audio_is_found_from_any_folder_and_dropped_when_it_changed(tmp_path, monkeypatch, capsys):
    """Found by a second new-user review: a run given a relative input.path had no audio when viewed from another
    folder (the path was taken from the viewer's folder), and a file replaced after the run was served out of
    step with the animation. The path is taken from the run's own folder; a changed or missing file is left out,
    in one line."""
    import soundfile as sf

    from inprocess import laughlab
    from laughlab.viewer.server import assets

    (tmp_path / "work").mkdir()
    sf.write(tmp_path / "work" / "take.wav", 0.1 * np.sin(np.arange(44100) * 0.05), 44100)
    run_dir = tmp_path / "run"
    r = laughlab("input=file", "input.path=take.wav", f"hydra.run.dir={run_dir}", "detector=none", "~output.plots",
                 cwd=tmp_path / "work")
    assert r.returncode == 0, r.stderr
    monkeypatch.chdir(tmp_path)
    assert assets(run_dir)["audio.wav"] == tmp_path / "work" / "take.wav"
    sf.write(tmp_path / "work" / "take.wav", np.zeros(3 * 44100), 44100)   # replaced by a 3 s file
    capsys.readouterr()
    assert "audio.wav" not in assets(run_dir)
    assert "is not the run's audio any more (3.00 s, the run 1.00 s)" in capsys.readouterr().err
    (tmp_path / "work" / "take.wav").unlink()
    assert "audio.wav" not in assets(run_dir) and "is gone" in capsys.readouterr().err


def test_viewing_a_run_without_animation_files_says_why(tmp_path):
    """A review: `output=vmc` (a live stream) writes only metrics.json, and `view` called the run unfinished."""
    (tmp_path / "live").mkdir()
    (tmp_path / "live" / "metrics.json").write_text("{}")
    r = laughlab("view", str(tmp_path / "live"), "--out", str(tmp_path / "s"))
    assert r.returncode == 2 and r.stderr == (
        f"laughlab: error: {tmp_path / 'live'} holds no motion.bvh, channels.csv, events.csv: its run wrote no "
        "animation files (output=vmc alone streams only); run it with output=[files,vmc] to keep them\n")
    (tmp_path / "half").mkdir()
    r = laughlab("view", str(tmp_path / "half"), "--out", str(tmp_path / "s"))
    assert r.returncode == 2 and "is not a finished run: it has no motion.bvh" in r.stderr
    assert not (tmp_path / "s").exists()
    # an experiment's folder (a first-contact review: "not a finished run", its showcase runs not named)
    for cond in ("energy", "concat"):
        (tmp_path / "exp" / "showcase" / cond).mkdir(parents=True)
        (tmp_path / "exp" / "showcase" / cond / "motion.bvh").write_text("")
    r = laughlab("view", str(tmp_path / "exp"), "--out", str(tmp_path / "s"))
    assert r.returncode == 2 and r.stderr == (
        f"laughlab: error: {tmp_path / 'exp'} is an experiment, not a run: view one of its showcase runs, e.g. python "
        f"-m laughlab view {tmp_path / 'exp' / 'showcase' / 'concat'} (conditions: concat, energy)\n")


def test_viewing_a_run_still_going_says_so(tmp_path):
    """A live session with output=[files,vmc] viewed while it runs was 'not a finished run: it has no motion.bvh,
    ...' (review-live-2 4): the viewer has no live mode, and the line said neither that the run was still going nor
    when it could be viewed.  The run's lock (rundir: an OS lock held for its whole life) says who holds it."""
    import fcntl

    from laughlab.core import rundir

    live = tmp_path / "live"
    live.mkdir()
    (live / ".motion.bvh.part").write_text("")
    fd = os.open(live / rundir.LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)   # as a running laughlab holds it
        os.write(fd, b"4242\n")
        r = laughlab("view", str(live), "--out", str(tmp_path / "s"))
    finally:
        os.close(fd)
    assert r.returncode == 2 and r.stderr == (
        f"laughlab: error: {live} is a run still going (pid 4242): the viewer plays a finished run; view it when it "
        "ends (Ctrl-C ends a live session and keeps it); to watch a run as it goes, give it "
        "output=[files,viewer] (docs/pipeline.md)\n")
    r = laughlab("view", str(live), "--out", str(tmp_path / "s"))   # the lock let go: a run that did not finish
    assert r.returncode == 2 and "is not a finished run: it has no motion.bvh" in r.stderr


def test_view_out_overwrite_replaces_only_an_earlier_page(run_dir, tmp_path):
    """A review: re-exporting a site into its own folder was refused with no way round it but deleting it."""
    out = tmp_path / "site"
    assert laughlab("view", str(run_dir), "--out", str(out)).returncode == 0
    r = laughlab("view", str(run_dir), "--out", str(out))
    assert r.returncode == 2 and r.stderr.endswith("or add --overwrite to replace the viewer page in it\n")
    (out / "index.html").write_text("stale")
    r = laughlab("view", str(run_dir), "--out", str(out), "--overwrite")
    assert r.returncode == 0 and (out / "index.html").read_text() != "stale"
    (out / "notes.txt").write_text("mine")                          # a file of the user's: never replaced
    r = laughlab("view", str(run_dir), "--out", str(out), "--overwrite")
    assert r.returncode == 2 and (out / "notes.txt").read_text() == "mine"
    assert "holds a viewer page and files that are not its (notes.txt); --overwrite replaces only" in r.stderr
    (out / "notes.txt").unlink()
    # a review: a file in vendor/ and an audio.* the page does not name were deleted
    for mine in ("vendor/mynotes.txt", "audio.mp3"):
        (out / mine).write_text("mine")
        r = laughlab("view", str(run_dir), "--out", str(out), "--overwrite")
        assert r.returncode == 2 and (out / mine).read_text() == "mine" and f"not its ({mine})" in r.stderr
        (out / mine).unlink()
    assert laughlab("view", str(run_dir), "--out", str(out), "--overwrite").returncode == 0
    r = laughlab("view", str(run_dir), "--overwrite")
    assert r.returncode == 2 and r.stderr == "laughlab: error: view: --overwrite goes with --out FOLDER (see --help)\n"


@pytest.mark.parametrize("name, cut, why", [
    ("channels.csv", lambda t: t[:len(t) // 2], "line "),
    ("channels.csv", lambda t: "time,mcs\nabc,def\n", "could not convert string to float: 'abc'"),
    ("motion.bvh", lambda t: t[:len(t) // 2], "line "),
    ("motion.bvh", lambda t: "garbage\n", "expected 'HIERARCHY'"),
    ("events.csv", lambda t: "when,what\n1,2\n", "(no column 'time')"),
])
def test_a_damaged_file_of_the_run_is_one_line(run_dir, tmp_path, name, cut, why):
    """A review: a channels.csv saved back by a spreadsheet or a copy cut short gave a traceback."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    (run / name).write_text(cut((run / name).read_text()))
    r = laughlab("view", str(run), "--out", str(tmp_path / "site"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith(f"laughlab: error: {run / name} is damaged (") and why in r.stderr
    assert r.stderr.endswith("; run it again to write it whole\n") and not (tmp_path / "site").exists()


def test_view_out_writes_into_the_folder_named_and_leaves_nothing_on_failure(run_dir, tmp_path, monkeypatch):
    """A review: --out a link to a folder failed ("cannot write RUN: OSError") and left an 8 MB .NAME.part; an
    empty folder of mode 700 came back 755."""
    import os

    (tmp_path / "target").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "target")
    out, _ = V.write(run_dir, tmp_path / "link")
    assert out == tmp_path / "target" and (tmp_path / "link" / "index.html").is_file()
    assert (tmp_path / "link").is_symlink() and sorted(os.listdir(tmp_path)) == ["link", "target"]
    (tmp_path / "mine").mkdir(mode=0o700)
    (tmp_path / "mine").chmod(0o700)
    inode = (tmp_path / "mine").stat().st_ino
    V.write(run_dir, tmp_path / "mine")
    V.write(run_dir, tmp_path / "mine", overwrite=True)
    # written in place: the same folder (its owner, permissions, any mount on it), holding the page only
    assert (tmp_path / "mine").stat().st_ino == inode and (tmp_path / "mine").stat().st_mode & 0o777 == 0o700
    assert V._not_the_pages(tmp_path / "mine") == []

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(V.shutil, "copyfile", full)
    with pytest.raises(V.LaughlabError, match=r"^cannot write the viewer page into .*site: No space left on device$"):
        V.write(run_dir, tmp_path / "site")
    assert sorted(os.listdir(tmp_path)) == ["link", "mine", "target"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(V.LaughlabError, match=r"^cannot write the viewer page into .*empty: No space left"):
        V.write(run_dir, tmp_path / "empty")
    assert os.listdir(tmp_path / "empty") == []   # left as it was


def test_port_0_is_any_free_port_not_a_taken_one(run_dir, monkeypatch, capsys):
    from laughlab.viewer import cli as view_cli

    monkeypatch.setattr(V, "serve_until_interrupted", lambda httpd: httpd.server_close())
    view_cli.main([str(run_dir), "--port", "0"])
    said = capsys.readouterr().out
    assert said.startswith(f"laughlab: viewing {run_dir} at http://127.0.0.1:") and "taken" not in said


def test_overwrite_takes_an_older_pages_scripts_and_puts_the_page_back_if_the_swap_fails(run_dir, tmp_path,
                                                                                        monkeypatch):
    """A review: a page of an earlier laughlab (other three.js files) was refused as holding files not its own, a
    leftover .laughlab-view.part blocked the folder, and a failure while the new page moved in left neither page."""
    out = tmp_path / "site"
    V.write(run_dir, out)
    (out / "vendor" / "three" / "build" / "three.old.js").write_text("an earlier three.js")
    (out / V.PART).mkdir()                                   # a killed run's leftover
    V.write(run_dir, out, overwrite=True)
    assert not (out / "vendor" / "three" / "build" / "three.old.js").exists() and not (out / V.PART).exists()
    (out / "index.html").write_text("the earlier page")
    before = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    real, moved = V.Path.rename, []

    def rename(self, target):   # the third file of the new page cannot move in
        if self.parent.name == V.PART:
            moved.append(self.name)
            if len(moved) == 3:
                raise OSError(16, "Device or resource busy")
        return real(self, target)

    monkeypatch.setattr(V.Path, "rename", rename)
    with pytest.raises(V.LaughlabError, match="Device or resource busy"):
        V.write(run_dir, out, overwrite=True)
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == before
    assert (out / "index.html").read_text() == "the earlier page"


@pytest.mark.parametrize("server_class", ["laughlab's", "socketserver's"])
def test_a_client_gone_while_it_is_answered_prints_nothing(capsys, server_class, monkeypatch):
    """Found trying ``study simulate`` with a Ctrl-C to its process group: Chromium, stopped by the same Ctrl-C,
    left a 20-line BrokenPipeError from the server's thread before the command's one line. A client that resets
    the connection during a 20 MB answer: nothing on stderr (socketserver's own class prints the traceback)."""
    import socket
    import struct
    import time
    from http.server import ThreadingHTTPServer

    if server_class != "laughlab's":
        monkeypatch.setattr(V, "_Server", ThreadingHTTPServer)
    httpd = V.http_server({"big.bin": b"x" * 20_000_000}, 0)
    before = threading.active_count()
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        c = socket.create_connection(httpd.server_address[:2])
        c.sendall(b"GET /big.bin HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        assert c.recv(1024).startswith(b"HTTP/1.0 200")
        c.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        c.close()   # a reset, as a killed browser's
        deadline = time.time() + 10
        while threading.active_count() > before + 1 and time.time() < deadline:   # the request's thread ends
            time.sleep(0.05)
    finally:
        httpd.shutdown()
        httpd.server_close()
    err = capsys.readouterr().err
    assert ("Traceback" in err) == (server_class != "laughlab's"), err


def test_a_server_on_this_computer_answers_its_own_names_only_and_head_as_get():
    """A security review: a page of another site whose name points at 127.0.0.1 (DNS rebinding) read a run's audio
    from `view` (no Host check), and HEAD answered from the working folder (SimpleHTTPRequestHandler's own)."""
    import http.client

    httpd = V.http_server({"index.html": b"<p>page</p>"}, 0)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    port = httpd.server_address[1]

    def ask(method, path, host):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        try:
            conn.request(method, path, headers={"Host": host})
            r = conn.getresponse()
            return r.status, r.read()
        finally:
            conn.close()

    try:
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", "localhost", f"[::1]:{port}"):
            assert ask("GET", "/index.html", host) == (200, b"<p>page</p>"), host
        assert ask("GET", "/index.html", "attacker.example")[0] == 403
        assert ask("GET", "/index.html", f"attacker.example:{port}")[0] == 403
        assert ask("HEAD", "/index.html", "localhost") == (200, b"")
        assert ask("HEAD", "/README.md", "localhost")[0] == 404     # nothing of the working folder
    finally:
        httpd.shutdown()
        httpd.server_close()


def test_an_answer_longer_than_the_read_timeout_is_sent_whole(monkeypatch):
    """A diff review: the 60 s timeout meant for reading a request also limited the whole answer's sending, so a
    video to a participant on a slow link was cut off after a minute (here 0.5 s against a 2 MB answer read slowly)."""
    import socket
    import time

    monkeypatch.setattr(V._Handler, "timeout", 0.5)
    body = b"x" * (2 * 1024 * 1024)
    httpd = V.http_server({"video.mp4": body}, 0)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        s = socket.create_connection(httpd.server_address[:2])
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16384)
        s.sendall(b"GET /video.mp4 HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        got, t0 = b"", time.time()
        while len(got) < len(body) and time.time() - t0 < 30:
            d = s.recv(65536)
            if not d:
                break
            got += d
            time.sleep(0.02)
        s.close()
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert time.time() - t0 > 1.0 and got.endswith(body[-1000:]) and len(got) > len(body), (len(got), time.time() - t0)
