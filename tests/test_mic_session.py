"""How a live microphone session ends and what it reports (review-live 1, 4, 6, 8): Ctrl-C or SIGTERM with no
``input.duration_s`` ends the input and keeps the session, a microphone that stops ends it with a warning, an
overflow is counted, and a set duration reads exactly the samples asked for."""
from __future__ import annotations

import io
import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from test_sources import FakeSoundDevice

ROOT = Path(__file__).resolve().parents[1]


def noise(seconds: float, sr: int = 16000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * sr)) / sr
    return (rng.normal(0, 0.1, len(t)) * (1 + np.sin(2 * np.pi * 4 * t))).astype(np.float32)


def mic_pipe(monkeypatch, fake, *overrides, outputs=None, calibration_s=0):
    monkeypatch.setitem(sys.modules, "sounddevice", fake)
    cfg = compose_config(["input=mic", f"input.calibration_s={calibration_s}", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = outputs if outputs is not None else {"csv": {}, "bvh": {}}
    return pipeline.build(cfg)


@pytest.fixture
def default_ctrl_c():
    """Python's own Ctrl-C handler on SIGINT for the test (a test runner's worker may have another)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_ctrl_c_ends_a_session_with_no_duration_and_keeps_it(monkeypatch, tmp_path, capsys, default_ctrl_c):
    fake = FakeSoundDevice(noise(5), on_read=lambda k: k == 40 and signal.raise_signal(signal.SIGINT))
    pipe = mic_pipe(monkeypatch, fake)
    metrics = pipeline.execute(pipe, tmp_path)
    # the block read when the signal came is the last: 41 blocks of 267 samples, 41.05 frames of 266.67 (the
    # last one short, as the offline run of those samples has it); the loop finished as at any end of input
    assert fake.sizes == [267] * 41
    assert metrics["n_frames"] == 42 and metrics["input_stopped_by"] == "SIGINT"
    assert len(pd.read_csv(tmp_path / "channels.csv")) == 42 and "Frames: 42" in (tmp_path / "motion.bvh").read_text()
    assert json.loads((tmp_path / "metrics.json").read_text())["input_stopped_by"] == "SIGINT"
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "laughlab: Ctrl-C: the input ended after 0.7 s and the session is kept" in err, err
    assert fake.closed and signal.getsignal(signal.SIGINT) is signal.default_int_handler   # the handler is back


def test_a_second_ctrl_c_aborts_and_removes_what_was_written(monkeypatch, tmp_path, default_ctrl_c):
    def twice(k):
        if k == 40:
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)

    pipe = mic_pipe(monkeypatch, FakeSoundDevice(noise(5), on_read=twice))
    with pytest.raises(KeyboardInterrupt):
        pipeline.execute(pipe, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_with_a_duration_ctrl_c_aborts_as_in_an_offline_run(monkeypatch, tmp_path, default_ctrl_c):
    fake = FakeSoundDevice(noise(5), on_read=lambda k: k == 10 and signal.raise_signal(signal.SIGINT))
    pipe = mic_pipe(monkeypatch, fake, "input.duration_s=2")
    with pytest.raises(KeyboardInterrupt):
        pipeline.execute(pipe, tmp_path)
    assert not (tmp_path / "channels.csv").exists()


def test_a_microphone_that_stops_ends_the_input_with_one_warning(monkeypatch, tmp_path, capsys):
    pipe = mic_pipe(monkeypatch, FakeSoundDevice(noise(5), fail_at=60))
    metrics = pipeline.execute(pipe, tmp_path)
    # 60 blocks of 267 samples read: 60.08 frames, the last one short
    assert metrics["n_frames"] == 61 and metrics["input_stopped_by"] == "device"
    assert len(pd.read_csv(tmp_path / "channels.csv")) == 61
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("laughlab: warning: the microphone stopped after 1.0 s (Unanticipated host error "), err
    assert "the session up to there is kept" in err


def test_a_microphone_that_cannot_start_is_one_line(monkeypatch, tmp_path):
    from laughlab.core.errors import LaughlabError

    fake = FakeSoundDevice(noise(1))
    pipe = mic_pipe(monkeypatch, fake)

    def refuse(**kw):
        raise fake.PortAudioError("Error opening InputStream: Device unavailable [PaErrorCode -9985]")

    fake.InputStream = refuse
    with pytest.raises(LaughlabError, match=r"^the microphone could not be started \(Error opening InputStream"):
        pipeline.execute(pipe, tmp_path)


def test_a_microphone_that_fails_to_start_is_closed(monkeypatch, tmp_path):
    """A stream whose start() raised was never closed: its PortAudio handle was left open (diff-review 8)."""
    from laughlab.core.errors import LaughlabError

    fake = FakeSoundDevice(noise(1), start_error="Error starting stream: Device unavailable [PaErrorCode -9985]")
    with pytest.raises(LaughlabError, match=r"^the microphone could not be started \(Error starting stream"):
        pipeline.execute(mic_pipe(monkeypatch, fake), tmp_path)
    assert fake.closed


def test_closing_the_source_closes_the_stream_and_puts_the_handler_back(monkeypatch, default_ctrl_c):
    """close() put the signal handlers back but left the stream open until its generator was garbage-collected,
    later or never while a traceback held it (diff-review 8)."""
    fake = FakeSoundDevice(noise(1))
    src = mic_pipe(monkeypatch, fake).source
    blocks = src.blocks()   # held, as a traceback would hold it
    next(blocks)
    assert not fake.closed and signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    src.close()
    assert fake.closed and signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.parametrize("how", ["signal", "device"])
def test_a_stop_before_any_audio_is_read_keeps_nothing_in_one_line(monkeypatch, tmp_path, capsys, default_ctrl_c,
                                                                   how):
    """'the input ended after 0.0 s and the session is kept', then 'the input holds no audio frames' and nothing
    kept (diff-review 3).  A stop signal while the device starts now ends the input too."""
    from laughlab.core.errors import LaughlabError

    if how == "signal":
        fake = FakeSoundDevice(noise(1), on_start=lambda: signal.raise_signal(signal.SIGINT))
        says = r"^Ctrl-C: stopped before any audio was read; nothing to keep$"
    else:
        fake = FakeSoundDevice(noise(1), fail_at=0)
        says = (r"^the microphone stopped before any audio was read \(Unanticipated host error .*\); "
                r"nothing to keep$")
    with pytest.raises(LaughlabError, match=says) as raised:
        pipeline.execute(mic_pipe(monkeypatch, fake), tmp_path)
    assert raised.value.exit_code == (130 if how == "signal" else 2)
    assert capsys.readouterr().err == "" and list(tmp_path.iterdir()) == []
    assert fake.closed and signal.getsignal(signal.SIGINT) is signal.default_int_handler


class Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("how", ["signal", "device", "overflow", "abort", "bar"])
def test_a_line_during_the_calibration_starts_a_line_of_its_own(monkeypatch, tmp_path, default_ctrl_c, how):
    """On a terminal the calibration meter redraws its line after '\\r' with no newline: the Ctrl-C line, the
    microphone's warnings, and the error line after an abort were printed onto its end (diff-review 3).  So was
    the Ctrl-C line onto the progress bar of a session with no set length ('bar', no calibration)."""
    def twice(k):
        if k == 20:
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)

    fake = {"signal": FakeSoundDevice(noise(3), on_read=lambda k: k == 20 and signal.raise_signal(signal.SIGINT)),
            "device": FakeSoundDevice(noise(3), fail_at=20),
            "overflow": FakeSoundDevice(noise(3), overflow_at={20}),
            "abort": FakeSoundDevice(noise(3), on_read=twice),
            "bar": FakeSoundDevice(noise(3), on_read=lambda k: k == 20 and signal.raise_signal(signal.SIGINT))}[how]
    tty = Terminal()
    monkeypatch.setattr(sys, "stderr", tty)
    more = ["progress=on"] if how == "bar" else ["progress=off"]   # the bar and the meter: see the report
    if how == "overflow":
        more.append("input.duration_s=2")
    pipe = mic_pipe(monkeypatch, fake, *more, calibration_s=0 if how == "bar" else 1)
    if how == "abort":
        with pytest.raises(KeyboardInterrupt):
            pipeline.execute(pipe, tmp_path)
    else:
        pipeline.execute(pipe, tmp_path)
    err = tty.getvalue()
    # what a terminal shows of each line: the text after its last carriage return
    lines = [x.rsplit("\r", 1)[-1] for x in err.split("\n")]
    assert ("\rlaughlab: 0frame" if how == "bar" else "\r  [") in err, err   # the bar or the meter drew
    assert lines[-1].strip() == "", err   # and its line was ended (or cleared): an error line after starts its own
    assert all(x.startswith("laughlab: ") and x.count("laughlab: ") == 1 for x in lines if "laughlab: " in x), lines
    said = {"signal": "laughlab: Ctrl-C: the input ended after 0.4 s", "device": "laughlab: warning: the microphone "
            "stopped after 0.3 s", "overflow": "laughlab: warning: the microphone's buffer overflowed after 0.4 s",
            "abort": None, "bar": "laughlab: Ctrl-C: the input ended after 0.4 s"}[how]
    assert said is None or any(x.startswith(said) for x in lines), lines


FAKE_MODULE = '''
"""A fake sounddevice: noise as fast as it is read; read SIGNAL_AT sends the signal FAKE_SD_SIGNAL to this process
(with FAKE_SD_READY: after saying so in that file and waiting for the file FAKE_SD_CLOSED: a terminal the test
closed)."""
import os, signal, time
import numpy as np

def wait_for_the_test():
    if "FAKE_SD_READY" in os.environ:
        open(os.environ["FAKE_SD_READY"], "w").close()
        for _ in range(300):
            if os.path.exists(os.environ["FAKE_SD_CLOSED"]):
                return
            time.sleep(0.05)

class PortAudioError(Exception):
    pass

def check_input_settings(**kw):
    pass

class InputStream:
    def __init__(self, **kw):
        self.k, self.rng = 0, np.random.default_rng(0)
    def __enter__(self):
        if os.environ["FAKE_SD_SIGNAL_AT"] == "0":   # while the stream starts
            os.kill(os.getpid(), getattr(signal, os.environ["FAKE_SD_SIGNAL"]))
        return self
    def __exit__(self, *a):
        return False
    def close(self):
        pass
    def read(self, n):
        self.k += 1
        if self.k == int(os.environ["FAKE_SD_SIGNAL_AT"]):
            wait_for_the_test()
            for _ in range(int(os.environ.get("FAKE_SD_SIGNAL_TIMES", "1"))):
                os.kill(os.getpid(), getattr(signal, os.environ["FAKE_SD_SIGNAL"]))
        if self.k > 3000:   # a signal that did not end the input: the test fails, it does not hang
            raise PortAudioError("the fake ran out")
        return self.rng.normal(0, 0.1, (n, 1)).astype(np.float32), False
'''


@pytest.mark.parametrize("sig, key", [("SIGINT", "Ctrl-C"), ("SIGTERM", "SIGTERM")])
def test_the_command_keeps_a_session_stopped_by_a_signal(tmp_path, sig, key):
    """The whole command: exit 0, the files and metrics.json, the vmc summary, one line on stderr (90 blocks of
    267 samples: 91 frames, the last one short)."""
    (tmp_path / "fake").mkdir()
    (tmp_path / "fake" / "sounddevice.py").write_text(textwrap.dedent(FAKE_MODULE))
    run = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "fake"), str(ROOT)]),
           "FAKE_SD_SIGNAL_AT": "90", "FAKE_SD_SIGNAL": sig}
    from test_vmc import Receiver

    with Receiver() as rx:   # someone listens: else a note says nobody does
        p = subprocess.run([sys.executable, "-m", "laughlab", "input=mic", "input.calibration_s=0",
                            "output=[files,vmc]", "~output.plots", f"output.vmc.port={rx.port}",
                            f"hydra.run.dir={run}"],
                           cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # not inherited as ignored
    assert p.returncode == 0, p.stderr
    assert p.stderr.count("\n") == 1 and f"laughlab: {key}: the input ended after 1.5 s and the session is kept" \
        in p.stderr, p.stderr
    # live (the stand-in microphone hands its blocks over as fast as they are read, so the line also says the burst)
    assert f"vmc: 91 frames and 16 frames back to rest to 127.0.0.1:{rx.port} (live" in p.stdout, p.stdout
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["input_stopped_by"] == sig and metrics["n_frames"] == 91 == metrics["vmc_frames"]
    assert len(pd.read_csv(run / "channels.csv")) == 91


def test_the_command_stopped_before_any_audio_says_so_in_one_line(tmp_path):
    """A SIGTERM while the device starts: one line, no run folder, not a 'kept' line then 'the input holds no
    audio frames' (diff-review 3); and exit status 130, as any interrupt (it exited 2, a user error's status)."""
    (tmp_path / "fake").mkdir()
    (tmp_path / "fake" / "sounddevice.py").write_text(textwrap.dedent(FAKE_MODULE))
    run = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "fake"), str(ROOT)]),
           "FAKE_SD_SIGNAL_AT": "0", "FAKE_SD_SIGNAL": "SIGTERM"}
    p = subprocess.run([sys.executable, "-m", "laughlab", "input=mic", "input.calibration_s=0", "output=[files]",
                        "~output.plots", f"hydra.run.dir={run}"], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 130, p.stderr
    assert p.stderr == "laughlab: error: SIGTERM: stopped before any audio was read; nothing to keep\n", p.stderr
    assert not run.exists()


@pytest.mark.parametrize("sr", [16000, 44100])
def test_a_set_duration_reads_exactly_its_samples_and_matches_the_offline_run(monkeypatch, tmp_path, sr):
    """At 16 kHz the blocks of 267 samples read 720 x 267 = 192240 samples for 12 s and the run had one short frame
    more than the offline run of the same audio (721 rows, 'Frames: 721').  Now the last read is cut to what is left."""
    import soundfile as sf

    audio = noise(3.5, sr)
    fake = FakeSoundDevice(audio)
    mic = mic_pipe(monkeypatch, fake, "input.duration_s=3", f"input.sample_rate={sr}")
    pipeline.execute(mic, tmp_path / "mic")
    assert sum(fake.sizes) == 3 * sr and fake.sizes[:-1] == [math.ceil(sr / 60)] * (len(fake.sizes) - 1)
    sf.write(tmp_path / "in.wav", audio[:3 * sr], sr, subtype="FLOAT")
    cfg = compose_config(["input=file", f"input.path={tmp_path / 'in.wav'}"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "bvh": {}}
    pipeline.execute(pipeline.build(cfg), tmp_path / "file")
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert (tmp_path / "mic" / name).read_bytes() == (tmp_path / "file" / name).read_bytes(), name
    assert "Frames: 180" in (tmp_path / "mic" / "motion.bvh").read_text()


def test_body_hill_fits_in_its_thread_on_the_microphone_and_in_the_frame_on_a_file(monkeypatch):
    """threaded: auto read ctx.live, which Context did not have: the fit ran in the frame on the microphone too
    (60-170 ms stalls, review-live 3)."""
    mic = mic_pipe(monkeypatch, FakeSoundDevice(noise(1)), "input.duration_s=0.5", "body=hill", "extractor=pressure")
    try:
        assert mic.ctx.live is True and mic.body.live.threaded is True
    finally:
        mic.body.close()
    cfg = compose_config(["input.duration_s=0.5", "body=hill", "extractor=pressure"])
    offline = pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]))
    assert offline.ctx.live is False and offline.body.live.threaded is False


@pytest.mark.parametrize("backlog", [True, False])
def test_falling_behind_the_microphone_is_counted_warned_once_and_said(monkeypatch, tmp_path, capsys, backlog):
    """The device's overflow flag was dropped and the summary said all was well 26 s behind (review-live 4).
    The lag is the stream's backlog (read_available), or for a stream without it the wall clock's lag over its
    smallest of the last 10 s (diff-review 2)."""
    from laughlab.core.summary import speed

    sr = 16000
    behind = 0.4 * sr   # from 1 s of audio on, the reader comes back 0.4 s late
    fake = FakeSoundDevice(noise(3), overflow_at={50, 51, 90},
                           available=(lambda f: 40 + (behind if f.pos > sr else 0)) if backlog else None)
    pipe = mic_pipe(monkeypatch, fake, "input.duration_s=2")
    if not backlog:   # the wall clock, as the source reads it: each read returns 30 ms after its audio's end (the
        # device's own latency, not counted), and 0.4 s more from 1 s of audio on
        pipe.source.clock = lambda: fake.pos / sr + (0.03 if fake.pos else 0.0) + (0.4 if fake.pos > sr else 0.0)
    metrics = pipeline.execute(pipe, tmp_path)
    assert metrics["input_overflows"] == 3
    assert metrics["input_lag_s_max"] == pytest.approx(0.4 + (40 / sr if backlog else 0.0))
    assert json.loads((tmp_path / "metrics.json").read_text())["input_overflows"] == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("laughlab: warning: the microphone's buffer overflowed after 0.9 s: "
                                                   "laughlab fell behind the microphone and audio was lost"), err
    cfg = compose_config(["input=mic"])
    said = f"; fell behind the microphone by {metrics['input_lag_s_max']:.2f} s, audio lost 3 times"
    assert speed(cfg, metrics, 3.0).endswith(said)
    kept_up = {**metrics, "input_overflows": 0, "input_lag_s_max": 0.08}   # a warm-up stall at the start
    assert "fell behind" not in speed(cfg, kept_up, 3.0)


def test_a_sound_card_clock_slower_than_the_system_clock_is_not_falling_behind(monkeypatch):
    """An hour at 100 ppm slow: the reader keeps up, yet wall time less the audio read grows 0.36 s, and the lag
    over the session's smallest said 'fell behind the microphone by 0.36 s' (diff-review 2, 15).  A stream
    without read_available (the real one has it) takes the lag over the smallest of the last 10 s."""
    from laughlab.core.summary import speed

    sr, card = 16000, 16000 * (1 - 100e-6)
    fake = FakeSoundDevice(np.zeros(0))   # silence, as long as it is read
    pipe = mic_pipe(monkeypatch, fake, "input.duration_s=3600", "input.block_frames=10")
    src = pipe.source
    src.clock = lambda: fake.pos / card + 0.03   # a read returns when the card's clock has its audio, + latency
    assert sum(len(x) for x in src._chunks()) == 3600 * sr
    assert fake.pos / card - fake.pos / sr == pytest.approx(0.36, abs=1e-3)   # the drift the clock saw
    metrics = src.metrics()
    assert metrics["input_overflows"] == 0 and metrics["input_lag_s_max"] < 0.002
    assert "fell behind" not in speed(compose_config(["input=mic"]), metrics, 3600.0)


def test_the_latency_bench_replays_the_microphone_in_its_own_blocks():
    """bench_latency's stand-in cut blocks of round(sr/fps) samples where the mic reads ceil(sr/fps): 533 against
    534 at 16 kHz and 30 fps, 25 ms more latency in the bench than the mic has (review-live 9)."""
    import importlib.util

    from laughlab.core.bases import Context
    from laughlab_plugins.source_mic import MicParams, block_samples

    spec = importlib.util.spec_from_file_location("bench_latency", ROOT / "benchmarks" / "bench_latency.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert block_samples(16000, 30) == 534 and block_samples(16000, 60, 2) == 534 and block_samples(48000, 30) == 1600
    replay = bench.make_replay_mic()(np.zeros(3200, dtype=np.float32), MicParams(sample_rate=16000),
                                     Context(fps=30.0))   # 0.2 s, played at real time
    replay.open()
    sizes = [len(b) for b in replay._chunks()]
    assert sizes[:-1] == [534] * (len(sizes) - 1)


def test_an_offline_scheduler_on_the_microphone_is_refused_naming_the_setting_before_any_sink(monkeypatch, tmp_path):
    from laughlab.core.errors import LaughlabError

    with pytest.raises(LaughlabError) as err:   # by build: no pipeline, so no sink opened (it was in execute)
        mic_pipe(monkeypatch, FakeSoundDevice(noise(1)), "input.duration_s=0.5", "scheduler=concat",
                 "scheduler.mode=optimal")
    assert str(err.value) == ("scheduler=concat (scheduler.mode=optimal) plans over the whole input and cannot run "
                              "on a live source (input=mic); use scheduler.mode=greedy, its real-time mode")
    mic_pipe(monkeypatch, FakeSoundDevice(noise(1)), "input.duration_s=0.5", "scheduler=concat")   # greedy: fine


def test_body_hill_on_the_microphone_matches_the_offline_run_after_its_warm_up(monkeypatch, tmp_path):
    """body=hill warms its compiled torso up on a spare one when the input is live (frame 0 took 0.4 s); the
    frames are the offline run's, with the fit in a thread on the microphone and in the frame on the file (which
    fit a call plays is fixed by ``adopt_after_s``, not by the thread's speed)."""
    import soundfile as sf

    from laughlab_plugins import body_hill

    steps = []
    step = body_hill.Torso.step
    monkeypatch.setattr(body_hill.Torso, "step", lambda self, *a: (steps.append(self), step(self, *a))[1])
    audio = noise(2.5)
    hill = ["body=hill", "extractor=pressure"]
    mic = mic_pipe(monkeypatch, FakeSoundDevice(audio), "input.duration_s=2", *hill)
    pipeline.execute(mic, tmp_path / "mic")
    assert mic.body.live.threaded and len(mic.body.live.fits) >= 2   # calls were fitted (in the thread)
    assert steps[0] is not mic.body.torso and steps[1] is mic.body.torso   # one spare step, then frame 0
    sf.write(tmp_path / "in.wav", audio[:32000], 16000, subtype="FLOAT")
    cfg = compose_config(["input=file", f"input.path={tmp_path / 'in.wav'}", *hill])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "bvh": {}}
    pipeline.execute(pipeline.build(cfg), tmp_path / "file")
    for name in ("channels.csv", "motion.bvh"):
        assert (tmp_path / "mic" / name).read_bytes() == (tmp_path / "file" / name).read_bytes(), name


def test_laughlabs_own_handler_is_stood_in_for_by_identity_not_by_its_module_name():
    """StopOnSignal recognised laughlab's handler by ``__module__ == 'laughlab.core.interrupts'``: a rename or a
    wrapper turned the kept session off, and any handler claiming that module was taken over (diff-review 18)."""
    from laughlab.core import interrupts

    def lookalike(signum, frame):   # another program's handler, whatever its module says
        pass

    lookalike.__module__ = "laughlab.core.interrupts"
    old = signal.signal(signal.SIGTERM, lookalike)
    try:
        with interrupts.StopOnSignal():
            assert signal.getsignal(signal.SIGTERM) is lookalike
        signal.signal(signal.SIGTERM, interrupts._handler)
        with interrupts.StopOnSignal() as stop:
            assert signal.getsignal(signal.SIGTERM) == stop._on_signal
        assert signal.getsignal(signal.SIGTERM) is interrupts._handler
    finally:
        signal.signal(signal.SIGTERM, old)



def test_a_terminal_that_closes_ends_the_session_and_keeps_it(tmp_path):
    """The terminal of a live session closed (its window, an ssh connection dropped): SIGHUP killed the process
    where it stood (review-live-2 3): the avatar stayed frozen mid-laugh (no frame at rest), the session was lost
    and the run folder kept its .part files.  SIGHUP now ends the input as SIGTERM does; the lines that would go
    to the terminal that is gone go nowhere (a write to it fails), and the session is kept, a hang-up that comes
    twice (the kernel's, the shell's to its jobs) too."""
    import pty
    import threading

    from pythonosc.osc_packet import OscPacket

    (tmp_path / "fake").mkdir()
    (tmp_path / "fake" / "sounddevice.py").write_text(textwrap.dedent(FAKE_MODULE))
    run, ready, closed = tmp_path / "run", tmp_path / "ready", tmp_path / "closed"
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(0.5)
    got: list[bytes] = []

    def listen():
        while True:
            try:
                got.append(receiver.recv(65536))
            except OSError:   # timed out after the last datagram, or closed
                if p.poll() is not None:
                    return

    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "fake"), str(ROOT)]),
           "FAKE_SD_SIGNAL_AT": "90", "FAKE_SD_SIGNAL": "SIGHUP", "FAKE_SD_SIGNAL_TIMES": "2",
           "FAKE_SD_READY": str(ready),
           "FAKE_SD_CLOSED": str(closed)}
    p = subprocess.Popen([sys.executable, "-m", "laughlab", "input=mic", "input.calibration_s=0", "output=[files,vmc]",
                          "~output.plots", f"output.vmc.port={receiver.getsockname()[1]}", f"hydra.run.dir={run}"],
                         cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave)
    os.close(slave)
    drain = threading.Thread(target=lambda: _drain(master), daemon=True)
    drain.start()
    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    try:
        for _ in range(1200):
            if ready.exists() or p.poll() is not None:
                break
            time.sleep(0.05)
        os.close(master)   # the terminal is gone: a write to it fails (EIO)
        closed.touch()
        assert p.wait(timeout=120) == 0
    finally:
        if p.poll() is None:
            p.kill()
        listener.join(timeout=10)
        receiver.close()
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["input_stopped_by"] == "SIGHUP" and metrics["n_frames"] == 91 == metrics["vmc_frames"]
    assert len(pd.read_csv(run / "channels.csv")) == 91 and not list(run.glob(".*.part"))
    last = [m.message for m in OscPacket(got[-1]).messages]   # the frame at rest: the avatar is not left mid-laugh
    assert last[-1].address == "/VMC/Ext/Blend/Apply"
    assert all(m.params[1] == 0.0 for m in last if m.address == "/VMC/Ext/Blend/Val")


def _drain(fd: int) -> None:
    """Read a pty's output until it is closed (a terminal shows what it is sent)."""
    try:
        while os.read(fd, 4096):
            pass
    except OSError:
        pass


@pytest.mark.parametrize("gain, said", [(0.0, "2.0 s of mic input (silent: its loudest sample is 0; is the microphone "
                                              "muted? input.device=NAME_OR_INDEX chooses another), rms"),
                                        # a heard noise, not laughter: the detector kept the clips back, and says so
                                        (0.3, "2.0 s of mic input (no full-body clip: the laughter detector never "
                                              "heard laughter; detector=none starts clips on any loud sound, as the "
                                              "papers do), rms")])
def test_a_silent_microphone_says_so_in_the_closing_line(monkeypatch, tmp_path, gain, said):
    """A muted microphone (or the wrong one) gave a session in which nothing moved and nothing was said, where a
    silent file says so in the run's line (review-live-2 6): the microphone's loudest sample is input_peak too."""
    from laughlab.core.summary import summary_line

    audio = noise(3) / 0.4 * gain
    monkeypatch.setitem(sys.modules, "sounddevice", FakeSoundDevice(audio))
    cfg = compose_config(["input=mic", "input.calibration_s=0", "input.duration_s=2"])
    run_cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    run_cfg.output = {"csv": {}}
    metrics = pipeline.execute(pipeline.build(run_cfg), tmp_path)
    assert metrics["input_peak"] == pytest.approx(float(np.abs(audio[:32000]).max()))
    assert f"laughlab: {said}" in summary_line(cfg, metrics, tmp_path, 2.5)


@pytest.mark.parametrize("gain", [0.0, 1e-4, 0.3])
def test_a_silent_microphone_is_warned_once_while_the_session_runs(monkeypatch, tmp_path, capsys, gain):
    """A muted microphone was said only in the closing line, after a session of any length in which nothing
    moved (a review): 5 s of input whose loudest sample stays under -60 dBFS are warned once, as they happen;
    a microphone that hears something is not; the calibration's line says it heard nothing."""
    audio = noise(12) / 0.4 * gain
    monkeypatch.setitem(sys.modules, "sounddevice", FakeSoundDevice(audio))
    pipe = mic_pipe(monkeypatch, FakeSoundDevice(audio), "input.duration_s=11", calibration_s=1)
    pipeline.execute(pipe, tmp_path)
    err = capsys.readouterr().err
    warned = [x for x in err.splitlines() if "the microphone has been silent" in x]
    if gain > 0.01:
        assert not warned and "heard nothing" not in err
    else:
        said = "is 0" if gain == 0 else f"{20 * math.log10(float(np.abs(audio[:80000]).max())):.0f} dBFS"
        assert warned == [f"laughlab: warning: the microphone has been silent for 5.0 s (its loudest sample {said}): "
                          "is it muted? input.device=NAME_OR_INDEX chooses another (python -m sounddevice lists them)"]
        assert "laughlab: calibrated (peak" in err and "; it heard nothing" in err


@pytest.mark.parametrize("duration, fps", [(8.3, 30), (1.1, 90), (2.0, 72), (1.37, 144)])
def test_a_set_duration_declares_the_frames_it_yields(monkeypatch, tmp_path, duration, fps):
    """The microphone's n_frames (RunInfo.n_frames, the progress bar's total) said ceil(duration * fps): 250 for
    the 249 frames of 8.3 s at 30 fps (8.3 * 30 is 249.00000000000003) and 100 for the 99 of 1.1 s at 90 fps, as
    the file source said one more at game rates (a game developer's review)."""
    seen = []

    class Count:
        name, streaming = "count", False

        def open(self, run):
            seen.append(run.n_frames)

        def write(self, chunk):
            seen.append(len(chunk.times))

        def close(self):
            return []

        def abort(self):
            pass

    pipe = mic_pipe(monkeypatch, FakeSoundDevice(noise(duration + 1)), f"input.duration_s={duration}", f"fps={fps}",
                    outputs={})
    pipe.sinks = [Count()]
    metrics = pipeline.execute(pipe, tmp_path)
    assert seen[0] == sum(seen[1:]) == metrics["n_frames"]


@pytest.mark.parametrize("sr", [44100, 48000])
def test_a_session_saved_with_its_audio_replays_offline_to_the_same_bytes(monkeypatch, tmp_path, sr):
    """A live session kept no audio, so the promise that a live and an offline run agree could not be used on
    a real session (repro review): ``input.save_audio=true`` writes the samples its frames read as input.wav,
    and the file run of it, with the calibration's length, gives the same bytes."""
    import soundfile as sf

    audio = noise(3.0, sr)
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    mic = mic_pipe(monkeypatch, FakeSoundDevice(audio), "input.duration_s=2.5", f"input.sample_rate={sr}",
                   "input.save_audio=true", calibration_s=1)
    pipeline.execute(mic, tmp_path / "mic")
    saved, rate = sf.read(tmp_path / "mic" / "input.wav", dtype="float32")
    assert rate == sr and np.array_equal(saved, audio[: int(2.5 * sr)])
    cfg = compose_config(["input=file", f"input.path={tmp_path / 'mic' / 'input.wav'}", "extractor.calibration_s=1"])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    cfg.output = {"csv": {}, "bvh": {}}
    pipeline.execute(pipeline.build(cfg), tmp_path / "file")
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert (tmp_path / "mic" / name).read_bytes() == (tmp_path / "file" / name).read_bytes(), name
    assert not list((tmp_path / "tmp").iterdir())   # the spooled audio was moved into the run, none left behind


def test_a_failed_session_leaves_no_spooled_audio(monkeypatch, tmp_path):
    """The temporary file the audio is spooled to goes with a run that fails, and no input.wav is written."""
    fake = FakeSoundDevice(noise(2.0), fail_at=30)
    mic = mic_pipe(monkeypatch, fake, "input.save_audio=true")
    blocks = mic.source.blocks()
    next(blocks)
    spool = Path(mic.source._spool.f.name)
    assert spool.exists()
    mic.source.close()
    assert not spool.exists() and mic.source._spool is None


@pytest.mark.parametrize("rate", [44100, 16000])
def test_a_recording_played_as_the_microphone_is_a_live_session(tmp_path, rate):
    """A game developer's review: without a microphone there was no way to try the live path (a file run is
    offline).  ``input.device=file:PATH`` plays a recording as the microphone, in real time, resampled to
    ``input.sample_rate`` (44.1 kHz: the samples themselves); its end ends the input and keeps the session, whose
    saved audio replays offline to the same bytes."""
    import soundfile as sf

    from inprocess import laughlab
    from laughlab.io.replay import ReplayDevice

    from laughlab.corpora.fetch import corpus_dir

    real = corpus_dir() / "files" / "ovos" / "female-132252__robinhood76__02940-insane-women-laughter.wav"
    src, sr = sf.read(real, dtype="float32") if real.exists() else (noise(2.0, 44100), 44100)   # a real 44.1 kHz
    src = (src if src.ndim == 1 else src.mean(axis=1))[int(0.5 * sr): int(1.7 * sr)]            # laugh, 1.2 s of it
    sf.write(tmp_path / "laugh.wav", src, sr, subtype="FLOAT")
    t0 = time.perf_counter()
    r = laughlab("input=mic", f"input.device=file:{tmp_path / 'laugh.wav'}", f"input.sample_rate={rate}",
                 "input.calibration_s=0", "input.save_audio=true", "output=files", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'live'}")
    took = time.perf_counter() - t0
    assert r.returncode == 0, r.stderr
    assert "laughlab: the recording ended after 1.2 s; the session is kept\n" in r.stderr
    assert took >= 1.1   # in real time
    assert json.loads((tmp_path / "live" / "metrics.json").read_text())["input_stopped_by"] == "end"
    saved, got = sf.read(tmp_path / "live" / "input.wav", dtype="float32")
    played = ReplayDevice(f"file:{tmp_path / 'laugh.wav'}").resampled(rate)
    assert got == rate and np.array_equal(saved, played[: len(saved)]) and len(saved) >= len(played) - rate // 60
    if rate == sr:
        assert np.array_equal(played, src)
    r = laughlab("input=file", f"input.path={tmp_path / 'live' / 'input.wav'}", "extractor.calibration_s=0",
                 "output=files", "~output.plots", f"hydra.run.dir={tmp_path / 'file'}")
    assert r.returncode == 0, r.stderr
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert (tmp_path / "live" / name).read_bytes() == (tmp_path / "file" / name).read_bytes(), name
    bad = laughlab("input=mic", f"input.device=file:{tmp_path / 'none.wav'}", f"hydra.run.dir={tmp_path / 'bad'}")
    assert bad.returncode == 2 and bad.stderr == (f"laughlab: error: input.device=file:{tmp_path / 'none.wav'}: "
                                                  f"input file not found: {tmp_path / 'none.wav'}\n"), bad.stderr
