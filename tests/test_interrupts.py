"""A stop signal whose ``KeyboardInterrupt`` Python cannot raise still stops the run.

The handler raises ``KeyboardInterrupt`` wherever the main thread is; inside a ``__del__`` (or another
callback) Python prints it as "Exception ignored" and goes on, and the handler has by then set the signal
to be ignored.  The fuzz suite met it under load: a Ctrl-C 1.7 s into a 300 s run, and the run went to its
end, exit 0, with a traceback on stderr."""
import subprocess
import sys

import pytest

# a face that, at frame 30, drops an object whose __del__ is where the Ctrl-C arrives
PLUGIN = '''
import signal

import laughlab
from laughlab import Face


class Dropped:
    def __del__(self):
        signal.raise_signal(signal.SIGINT)   # the handler runs here: its KeyboardInterrupt cannot leave __del__


class Late(Face):
    """A jaw on the motion control signal; the Ctrl-C comes while frame 30's garbage is collected."""
    name = "late"

    def step(self, frame):
        if frame.index == 30:
            Dropped()
        frame.channels["jaw"] = min(1.0, frame.control["mcs"])
        frame.channels.update(smile=0.5, blink=0.0, eyes_closed=0.0)


@laughlab.hookimpl
def register_faces(register):
    register(Late)
'''


def test_a_ctrl_c_raised_inside_a_del_stops_the_run_in_one_line(tmp_path):
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "late.py").write_text(PLUGIN)
    r = subprocess.run([sys.executable, "-m", "laughlab", "plugins_dir=plugins", "face=late", "input.duration_s=5",
                        "hydra.run.dir=run", "progress=off"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=300)
    assert r.returncode == 130, r.stderr
    assert r.stderr == "laughlab: error: interrupted; the run's partial output was removed\n"   # no traceback
    assert r.stdout == ""                                   # no summary line: the run did not finish
    assert not (tmp_path / "run").exists()                  # and left nothing behind


# a face that prints a line of its own at frame 10, and at frame 30 is where a SIGHUP arrives inside an exec whose
# bare except prints the generated code and raises again (scipy's decorator module: a signal during
# ``import scipy.spatial``, a fuzz case)
NOISY = '''
import sys

import laughlab
from laughlab import Face


class Noisy(Face):
    name = "noisy"

    def step(self, frame):
        if frame.index == 10:
            print("a library's own line before", file=sys.stderr)
        if frame.index == 30:
            try:
                exec("import signal; signal.raise_signal(signal.SIGHUP)")
            except:  # noqa: E722
                print("Error in generated code:", file=sys.stderr)
                print("def delaunay_plot_2d(tri, ax):", file=sys.stderr, end="")
                print("\\n    return _call_(_func_, tri, ax)", file=sys.stderr)
                raise
        frame.channels.update(jaw=0.0, smile=0.5, blink=0.0, eyes_closed=0.0)


@laughlab.hookimpl
def register_faces(register):
    register(Noisy)
'''


def test_what_a_library_prints_as_the_stop_signal_passes_through_it_is_not_printed(tmp_path):
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "noisy.py").write_text(NOISY, encoding="utf-8")
    r = subprocess.run([sys.executable, "-m", "laughlab", "plugins_dir=plugins", "face=noisy", "input.duration_s=5",
                        "hydra.run.dir=run", "progress=off"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=300)
    assert r.returncode == 130, r.stderr
    # before the signal a library's line is its own; after it only laughlab's one line
    assert r.stderr == ("a library's own line before\n"
                        "laughlab: error: interrupted; the run's partial output was removed\n"), r.stderr
    assert not (tmp_path / "run").exists()


def test_after_a_stop_signal_stderr_passes_laughlabs_own_whole_lines_only():
    import io

    from laughlab.core.quiet import OwnLinesOnly

    out = io.StringIO()
    err = OwnLinesOnly(out)
    print("Error in generated code:", file=err)
    err.write("laugh")
    err.write("lab: error: interrupted\nhalf a line of a library's")
    print("laughlab: kept the session", file=err)
    assert out.getvalue() == "laughlab: error: interrupted\n"   # the library's half line took the next one in
    err.write("\nlaughlab: kept\n")
    assert out.getvalue() == "laughlab: error: interrupted\nlaughlab: kept\n"
    assert err.encoding == out.encoding


def test_check_raises_only_after_a_stop_signal_and_before_the_command_is_done(monkeypatch):
    from laughlab.core import interrupts

    monkeypatch.setattr(interrupts, "received", None)
    monkeypatch.setattr(interrupts, "finished", False)
    interrupts.check()                                      # no signal: nothing
    monkeypatch.setattr(interrupts, "received", 2)
    with pytest.raises(KeyboardInterrupt):
        interrupts.check()
    monkeypatch.setattr(interrupts, "finished", True)       # the command's work is done: let go
    interrupts.check()


def test_the_unraisable_hook_hides_what_breaks_after_a_stop_signal_only(monkeypatch):
    from types import SimpleNamespace

    from laughlab.core import interrupts

    seen = []
    monkeypatch.setattr(sys, "__unraisablehook__", seen.append)
    ki = SimpleNamespace(exc_type=KeyboardInterrupt)
    other = SimpleNamespace(exc_type=RuntimeError)   # asyncio's "Event loop is closed" from a transport's __del__
    monkeypatch.setattr(interrupts, "received", None)       # no stop signal: Python's, both
    interrupts._unraisable(ki)
    interrupts._unraisable(other)
    assert seen == [ki, other]
    monkeypatch.setattr(interrupts, "received", 2)          # the command is stopping: neither is printed
    interrupts._unraisable(ki)
    interrupts._unraisable(other)
    assert seen == [ki, other]


# a coroutine whose clean-up needs another task alive: Playwright's reader of its driver's answers, busy most of
# the time (so a KeyboardInterrupt raised where the main thread stands lands in it), and a Ctrl-C 0.3 s in
ASYNC = '''
import asyncio, os, signal, sys, threading, time
from laughlab.core import interrupts

interrupts.install()
cleaned = []


async def reader(q):
    while True:
        t = time.perf_counter()
        while time.perf_counter() - t < 0.02:
            pass
        await asyncio.sleep(0)
        while not q.empty():
            q.get_nowait().set_result("answered")


async def work():
    q = asyncio.Queue()
    r = asyncio.create_task(reader(q))
    try:
        await asyncio.sleep(30)
    finally:
        fut = asyncio.get_running_loop().create_future()
        q.put_nowait(fut)
        try:
            cleaned.append(await asyncio.wait_for(fut, 5))
        except asyncio.TimeoutError:
            cleaned.append("nobody answered")
        r.cancel()


threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
try:
    if sys.argv[1] == "plain":
        asyncio.run(work())
    else:
        interrupts.run_coroutine(work())
except KeyboardInterrupt:
    print("stopped", cleaned, signal.getsignal(signal.SIGINT) is signal.SIG_IGN, interrupts.received)
'''


def test_a_ctrl_c_in_an_event_loop_cancels_the_coroutine_whose_clean_up_then_runs_whole():
    """Found by a CI run: ``study simulate`` did not exit within 60 s of a Ctrl-C. The handler's KeyboardInterrupt
    landed in Playwright's reader task, and the browser's clean-up waited for an answer nobody read. Under
    ``run_coroutine`` the signal cancels the coroutine's task; the reader lives to answer its clean-up, then
    KeyboardInterrupt, the signal ignored from there on (plain ``asyncio.run`` under laughlab's handler: "nobody
    answered", 5 s later)."""
    r = subprocess.run([sys.executable, "-c", ASYNC, "ours"], capture_output=True, text=True, timeout=60)
    assert r.stdout == "stopped ['answered'] True 2\n", r.stdout + r.stderr


def test_laughlabs_line_reaches_the_real_stderr_while_a_thread_silences_fd_2_after_a_stop_signal(capfd, monkeypatch):
    """A diff review: after the filter took sys.stderr, say() no longer knew it for the real one and wrote the
    interrupt line to fd 2, which a detector thread had sent to /dev/null."""
    import sys

    from laughlab.core import quiet

    monkeypatch.setattr(sys, "stderr", sys.__stderr__)
    quiet.own_lines_only()
    try:
        with quiet.quiet_stderr():
            quiet.say("laughlab: error: interrupted")
            print("a library's line", file=sys.stderr)
    finally:
        sys.stderr = sys.stderr.stream
    assert capfd.readouterr().err == "laughlab: error: interrupted\n"


def test_another_threads_half_line_does_not_take_laughlabs_line_with_it():
    """A diff review: the filter kept one partial line for every thread, so a library's unfinished write in another
    thread glued itself to the front of laughlab's line, which was then dropped."""
    import io
    import threading

    from laughlab.core.quiet import OwnLinesOnly

    out = io.StringIO()
    err = OwnLinesOnly(out)
    t = threading.Thread(target=lambda: err.write("a library's half line "))
    t.start()
    t.join()
    err.write("laughlab: error: interrupted\n")
    assert out.getvalue() == "laughlab: error: interrupted\n"


def test_a_new_command_forgets_an_earlier_commands_signal():
    """In one process (a notebook, the tests) a Ctrl-C of one ``cli.main`` call made every exception of every later
    call 'interrupted' (exit 130), a plugin's bug and a full disk too."""
    import signal

    from laughlab.core import interrupts

    keep = interrupts.received
    try:
        interrupts.received = signal.SIGINT
        interrupts.reset()
        assert interrupts.received is None and not interrupts.interrupted(ValueError("a plugin's bug"))
    finally:
        interrupts.received = keep
