"""File sinks in the helper process (laughlab.core.background): same bytes, same failure contract."""
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from laughlab.core import background
from laughlab.core.bases import Chunk, RunInfo, Sink
from laughlab.core.errors import LaughlabError

pytestmark = pytest.mark.skipif(not background.enabled(), reason="needs Linux and two cores")


class FileSink(Sink):
    """Writes a marker at open, one line per chunk, and removes its file on abort."""

    name = "testfile"
    background = True

    def __init__(self, path, fail_at=None):
        self.path, self.fail_at, self.n = Path(path), fail_at, 0

    def open(self, run):
        super().open(run)
        self.f = open(self.path, "w")

    def write(self, chunk):
        self.n += 1
        if self.fail_at is not None and self.n == self.fail_at:
            raise LaughlabError(f"disk said no at chunk {self.n}")
        self.f.write(f"{len(chunk.times)} {chunk.times[0]:.3f} {self.run.source.truth}\n")

    def close(self):
        self.f.close()
        return [self.path]

    def abort(self):
        self.f.close()
        self.path.unlink(missing_ok=True)


def chunk(k, n=4):
    t = (np.arange(n) + k * n) / 60.0
    return Chunk(t, {"mcs": np.zeros(n)}, np.zeros((n, 3)), [], [None] * n)


def info(tmp_path):
    return RunInfo(tmp_path, 60.0, None, None, background.SourceView("x", False, 44100, None, truth="T"))


def test_a_helper_writes_what_the_sink_writes_in_process(tmp_path):
    h = background.Helper()
    try:
        h.open([FileSink(tmp_path / "a.txt")], info(tmp_path))
        for k in range(3):
            h.write(chunk(k))
        assert h.close() == [tmp_path / "a.txt"]
    finally:
        h.stop()
    assert (tmp_path / "a.txt").read_text() == "4 0.000 T\n4 0.067 T\n4 0.133 T\n"
    assert not h.proc.is_alive()


class ModulesSink(FileSink):
    """Writes at open whether the helper has imported ``module``."""

    def __init__(self, path, module):
        super().__init__(path)
        self.module = module

    def open(self, run):
        super().open(run)
        self.f.write(str(self.module in sys.modules))


@pytest.mark.skipif("tabnanny" in sys.modules, reason="the test process has imported it already")
def test_the_helper_imports_the_plotting_modules_only_when_asked(tmp_path):
    """A run without the plots sink does not pay for matplotlib in the helper (0.9 s of CPU): the helper
    imports what the main process asks for once it has composed its configuration (``warm``)."""
    said = {}
    for asked in (False, True):
        h = background.Helper()
        try:
            if asked:
                h.warm(["tabnanny"])     # a module nothing here imports: a stand-in for the plotting modules
            h.open([ModulesSink(tmp_path / f"{asked}.txt", "tabnanny")], info(tmp_path))
            h.close()
        finally:
            h.stop()
        said[asked] = (tmp_path / f"{asked}.txt").read_text()
    assert said == {False: "False", True: "True"}


def test_a_sink_error_in_the_helper_comes_back_as_the_same_error_and_nothing_is_left(tmp_path):
    h = background.Helper()
    try:
        h.open([FileSink(tmp_path / "a.txt", fail_at=2)], info(tmp_path))
        with pytest.raises(LaughlabError, match="disk said no at chunk 2"):
            for k in range(50):
                h.write(chunk(k))
                time.sleep(0.002)
            h.close()
        h.abort()
    finally:
        h.stop()
    assert not (tmp_path / "a.txt").exists()


def test_abort_removes_what_the_helper_wrote(tmp_path):
    h = background.Helper()
    try:
        h.open([FileSink(tmp_path / "a.txt")], info(tmp_path))
        h.write(chunk(0))
        h.abort()
    finally:
        h.stop()
    assert not (tmp_path / "a.txt").exists()


def test_stopping_the_helper_removes_what_no_one_closed_and_keeps_what_was(tmp_path):
    """A Ctrl-C right after the main process handed its sinks over (before it counted the helper among the
    sinks to abort) ended in stop() alone: the helper quit and left its staged files (CI: .channels.csv.part
    and .motion.bvh.part in an interrupted run's folder, which the next run then refused)."""
    h = background.Helper()
    try:
        h.open([FileSink(tmp_path / "a.txt")], info(tmp_path))
        h.write(chunk(0))
    finally:
        h.stop()
    assert not (tmp_path / "a.txt").exists()
    h = background.Helper()
    try:
        h.open([FileSink(tmp_path / "b.txt")], info(tmp_path))
        h.write(chunk(0))
        assert h.close() == [tmp_path / "b.txt"]
    finally:
        h.stop()
    assert (tmp_path / "b.txt").read_text().startswith("4 0.000 T")      # closed: the run's, kept


def test_the_helper_cleans_up_when_the_main_process_dies(tmp_path):
    code = (
        "import os, sys, time\n"
        "sys.path.insert(0, %r)\n"
        "from test_background import FileSink, chunk, info\n"
        "from laughlab.core import background\n"
        "from pathlib import Path\n"
        "h = background.Helper()\n"
        "h.open([FileSink(Path(sys.argv[1]) / 'a.txt')], info(Path(sys.argv[1])))\n"
        "h.write(chunk(0))\n"
        "while not (Path(sys.argv[1]) / 'a.txt').exists(): time.sleep(0.01)\n"
        "print(h.proc.pid, flush=True)\n"
        "os._exit(9)\n" % str(Path(__file__).parent)
    )
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 9, out.stderr
    pid = int(out.stdout.split()[0])
    for _ in range(200):
        if not (tmp_path / "a.txt").exists():
            break
        time.sleep(0.02)
    assert not (tmp_path / "a.txt").exists()
    for _ in range(100):  # gone, or a zombie waiting for a reaper (a container's init may not reap)
        status = Path(f"/proc/{pid}/status")
        state = status.read_text().split("State:")[1].split()[0] if status.exists() else "gone"
        if state in ("gone", "Z", "X"):
            break
        time.sleep(0.02)
    assert state in ("gone", "Z", "X")


def test_parallel_jobs_run_and_report_a_failure():
    background.parallel([lambda: None])  # outside the helper: in-process
    with pytest.raises(ZeroDivisionError):
        background.parallel([lambda: None, lambda: 1 / 0])


def _digests(run_dir: Path) -> dict:
    files = [p for p in sorted(run_dir.rglob("*")) if p.is_file() and ".hydra" not in p.parts
             and p.name != "metrics.json" and not p.name.startswith(".laughlab")]  # timings; the run's pid
    return {str(p.relative_to(run_dir)): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


@pytest.mark.parametrize("extra", [[], pytest.param(["face=facs", "body=hill", "extractor=pressure"],
                                                     marks=pytest.mark.slow)])  # the Hill run: make test-all
def test_a_run_writes_the_same_bytes_with_and_without_the_helper(tmp_path, extra):
    runs = {}
    for workers in ("1", "0"):
        out = tmp_path / f"w{workers}"
        env = {**os.environ, "LAUGHLAB_WORKERS": workers}
        r = subprocess.run([sys.executable, "-m", "laughlab", f"hydra.run.dir={out}", "input.duration_s=6", *extra],
                           capture_output=True, text=True, env=env)
        assert r.returncode == 0, r.stderr
        runs[workers] = _digests(out)
    assert "plots/fig4_2_energy.png" in runs["1"] and "motion.bvh" in runs["1"]
    assert runs["1"] == runs["0"]


def test_a_stop_signal_waits_for_a_message_to_the_helper_to_be_sent_whole():
    """A Ctrl-C between a chunk's head and its arrays left the helper waiting for the rest, reading the
    main process' "abort" as an array, while the main process waited for "aborted": a hang (CI, a run of
    1,800 s interrupted 0.5 s in).  The handler now holds the interrupt until the message is out."""
    import signal

    from laughlab.core import interrupts

    old = {s: signal.getsignal(s) for s in interrupts.STOP_SIGNALS}
    for s in interrupts.STOP_SIGNALS:
        signal.signal(s, signal.SIG_DFL)
    interrupts.install()
    sent = []

    class Pipe:
        def send_bytes(self, b):
            if not sent:
                os.kill(os.getpid(), signal.SIGINT)   # arrives after the head, before the arrays
                time.sleep(0.05)
            sent.append(bytes(b))

    try:
        with pytest.raises(KeyboardInterrupt):
            background._send_msg(Pipe(), ("write", chunk(0)))
        assert len(sent) > 1                          # the head and every array went out first
        n = int.from_bytes(sent[0][:4], "little")
        assert len(sent) == 1 + n
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        interrupts.received = None
