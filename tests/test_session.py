"""``laughlab.session.Session``: laughlab stepped from another program's loop (the game-developer review found no
public way to). Fed any split of a recording, it gives the frames and files ``input=file`` gives (same bytes)."""
import filecmp
import re

import numpy as np
import pytest
import soundfile as sf
from hypothesis import given, settings, strategies as st

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.errors import LaughlabError
from laughlab.session import Session


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A real laugh at 44.1 kHz when the corpus is there (else the synthetic laughter), as a file."""
    from scipy.signal import resample_poly

    from laughlab.corpora.fetch import corpus_dir
    from laughlab.synth.laughter import SyntheticLaughter

    root = tmp_path_factory.mktemp("session")
    laugh = corpus_dir() / "files" / "btanks" / "laugh01.ogg"
    if laugh.exists():
        x, sr = sf.read(laugh, dtype="float64")
        x, sr = resample_poly(x, 44100, sr), 44100
    else:
        synth = SyntheticLaughter(seed=2, duration_s=4.0, sample_rate=44100, profile="intense")
        x, sr = synth.render(0, synth.n_samples), 44100
    sf.write(root / "laugh.wav", x, sr, subtype="FLOAT")
    return root / "laugh.wav"


def fed(path, overrides, pieces, **kw):
    x, sr = sf.read(path, dtype="float32")
    frames, i, k = [], 0, 0
    with Session(overrides, sample_rate=sr, **kw) as s:
        while i < len(x):
            n = pieces[k % len(pieces)]
            frames += s.feed(x[i:i + n])
            i, k = i + n, k + 1
        frames += s.close()
    return frames


@pytest.mark.parametrize("body", ["body=shapes", "body=hill"])   # hill: a review once measured 4e-6 apart
def test_the_files_are_the_commands_byte_for_byte_and_the_frames_its_rows(recording, tmp_path, body):
    frames = fed(recording, ["face=facs", body, "~output.plots"], [1, 734, 2900, 17, 44100], outputs=["files"],
                 out_dir=tmp_path / "s")   # no figures here nor below: the files compared are the data
    r = laughlab("input=file", f"input.path={recording}", "face=facs", body, "~output.plots",   # files compared below
                 f"hydra.run.dir={tmp_path / 'cli'}")
    assert r.returncode == 0, r.stderr
    for name in ("channels.csv", "events.csv", "motion.bvh", "face_arkit.csv"):
        assert filecmp.cmp(tmp_path / "s" / name, tmp_path / "cli" / name, shallow=False), name
    import pandas as pd

    from laughlab.io.bvh import read_bvh

    ch = pd.read_csv(tmp_path / "cli" / "channels.csv")
    _, motion, _ = read_bvh(tmp_path / "cli" / "motion.bvh")
    assert len(frames) == len(ch) == len(motion) and [f.index for f in frames] == list(range(len(frames)))
    np.testing.assert_allclose([f.channels["mcs"] for f in frames], ch["mcs"], atol=1e-6)
    np.testing.assert_allclose([f.time_s for f in frames], ch["time"], atol=1e-6)
    np.testing.assert_allclose(np.array([f.pose for f in frames]), motion, atol=1e-4)
    arkit = pd.read_csv(tmp_path / "cli" / "face_arkit.csv")
    np.testing.assert_allclose([f.arkit["jawOpen"] for f in frames], arkit["jawOpen"], atol=1e-6)
    starts = [(f.index, e.clip) for f in frames for e in f.events if e.kind == "start"]
    ev = pd.read_csv(tmp_path / "cli" / "events.csv")
    start = ev[ev["event"] == "start"]
    assert starts == [(round(t * 60), c) for t, c in zip(start["time"], start["clip"])] and starts


def test_a_sessions_hill_fits_its_calls_in_a_thread_unless_told(monkeypatch):
    """A frame budget review (2026-11-29): in a Session body=hill fitted each call in the frame (not live), 50-280 ms
    feeds in a 60 fps game; ``threaded: auto`` now means a thread in a Session (the same bytes: the test above);
    an explicit ``no`` is kept."""
    from laughlab.hill import live

    made, real = [], live.LiveFitter.__init__

    def init(self, *a, **k):
        real(self, *a, **k)
        made.append(self.threaded)

    monkeypatch.setattr(live.LiveFitter, "__init__", init)
    Session(["body=hill"], sample_rate=16000).close()
    Session(["body=hill", "body.live.threaded=no"], sample_rate=16000).close()
    assert made[-2:] == [True, False]


@pytest.fixture(scope="module")
def second(recording, tmp_path_factory):
    """The recording's first second: a split into pieces of one sample is 44,100 feeds, not 257,000."""
    x, sr = sf.read(recording, dtype="float32")
    path = tmp_path_factory.mktemp("second") / "laugh_1s.wav"
    sf.write(path, x[:sr], sr, subtype="FLOAT")
    return path


@pytest.fixture(scope="module")
def whole(second):
    """Its frames fed in one piece (made once: each example below compares its split with it)."""
    return [(f.channels, f.pose.tolist()) for f in fed(second, ["detector=none"], [10 ** 7])]


@settings(max_examples=4, deadline=None, derandomize=True)
@given(st.lists(st.integers(1, 5000), min_size=1, max_size=6))
def test_any_split_of_the_samples_gives_the_same_frames(second, whole, pieces):
    frames = fed(second, ["detector=none"], pieces)
    assert [(f.channels, f.pose.tolist()) for f in frames] == whole


def test_each_feed_returns_the_frames_its_samples_completed():
    with Session(["detector=none"], sample_rate=16000) as s:
        assert s.feed(np.zeros(266, np.float32)) == []          # frame 0 ends at sample 267
        assert [f.index for f in s.feed(np.zeros(1, np.float32))] == [0]
        assert [f.index for f in s.feed(np.zeros(532, np.float32))] == [1]   # frame 2 ends at sample 800
        assert [f.index for f in s.feed(np.zeros(1, np.float32))] == [2]
        assert [f.index for f in s.feed(np.zeros(1, np.float32))] == []
        assert [f.index for f in s.close()] == [3]              # the last, partial frame: sample 801
    assert s.metrics["n_frames"] == 4


def test_mistakes_are_one_line():
    with pytest.raises(LaughlabError, match=r"^sample_rate must be 8000-192000 Hz \(got 4000\)$"):
        Session([], sample_rate=4000)
    # a new-user review: 44100.9 ran as 44100, and an unknown face was said to come from an experiment
    for bad in (44100.9, float("nan"), "44100"):
        with pytest.raises(LaughlabError, match=r"^sample_rate must be a whole number of Hz"):
            Session([], sample_rate=bad)
    assert Session([], sample_rate=np.int64(48000)).out_dir.is_dir()   # numpy's integers are whole numbers
    with pytest.raises(LaughlabError, match=r"^unknown face 'nope'; choose one of: cgm, facs, smile$"):
        Session(["face=nope"], sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"bad parameter"):
        Session(["fps=0"], sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"^output=vmc: a session's outputs are its outputs= argument"):
        Session(["output=vmc"], sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"^input.path=x.wav: a session's input is what feed\(\) is given"):
        Session(["input.path=x.wav"], sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"^scheduler=concat \(scheduler.mode=optimal\) plans over the whole "
                                            r"input and cannot run on a session fed as it goes; use scheduler.mode=greedy"):
        Session(["scheduler=concat", "scheduler.mode=optimal"], sample_rate=16000)
    s = Session(["detector=none"], sample_rate=16000)
    s.feed(np.zeros(1000, np.float32))
    s.close()
    with pytest.raises(LaughlabError, match=r"^the session is closed$"):
        s.feed(np.zeros(10, np.float32))


def test_an_api_users_mistakes_are_one_line_too():
    """An API user's review: a string of overrides failed as "Error parsing override 'f'", outputs="files" as
    "Could not load 'output/s'"; a forgotten sample_rate ran 48 kHz audio at 16 kHz's timing."""
    with pytest.raises(LaughlabError, match=r"^overrides must be a list of strings \(got the string 'face=facs': "
                                            r"overrides=\['face=facs'\]\)$"):
        Session("face=facs", sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"^outputs must be a list of strings \(got the string 'files'"):
        Session([], sample_rate=16000, outputs="files")
    with pytest.raises(LaughlabError, match=r"^overrides must be a list of strings \(got \['face=facs', 3\]\)$"):
        Session(["face=facs", 3], sample_rate=16000)
    with pytest.raises(LaughlabError, match=r"^Session needs sample_rate=, the rate of the samples you will feed"):
        Session(["face=facs"])
    with pytest.raises(LaughlabError, match=r"^outputs: 'bvh' is not an output; choose from files, gltf, video, "
                                            r"viewer, vmc, vrma \(files: channels.csv, events.csv, motion.bvh"):
        Session([], sample_rate=16000, outputs=["bvh"])
    for o in ("hydra.run.dir=foo", "hydra/launcher=joblib", "experiment=smoke", "overwrite=true"):   # taken, ignored
        with pytest.raises(LaughlabError, match=rf"^{re.escape(o)}: not a session's: its folder is out_dir="):
            Session([o], sample_rate=16000)
    s = Session((o for o in ["detector=none"]), sample_rate=16000)   # any iterable of strings
    assert len(s.feed(np.zeros(800, np.float32))) == 3   # three frames of 16 kHz at 60 fps
    s.close()


def test_a_session_closed_before_any_audio_gives_no_frame_and_writes_nothing(tmp_path):
    """A game that opened a session and quit before any audio got "the input holds no audio frames"."""
    with Session(["detector=none"], sample_rate=16000, outputs=["files"], out_dir=tmp_path / "out") as s:
        pass
    assert s.metrics is None and list((tmp_path / "out").iterdir()) == []
    s = Session(["detector=none"], sample_rate=16000)
    s.feed(np.zeros(0, np.float32))      # an empty block is no audio either
    assert s.close() == [] and s.metrics is None


def test_frame_fields_as_documented():
    """label is "" where the extractor gives none (it was None); arkit is computed once a frame (a review: 8 reads
    a frame cost more than the feed)."""
    with Session(["face=facs"], sample_rate=16000) as s:
        frames = s.feed(np.random.default_rng(0).normal(0, 0.1, 8000).astype(np.float32)) + s.close()
    assert frames and all(f.label == "" for f in frames)
    f = frames[-1]
    assert f.arkit is f.arkit and f.arkit["jawOpen"] == pytest.approx(f.channels["arkit.jawOpen"], abs=1e-6)


def test_files_already_in_out_dir_are_not_replaced_without_asking(tmp_path):
    (tmp_path / "channels.csv").write_text("mine\n")
    with pytest.raises(LaughlabError, match=r"already holds channels.csv, which this session would replace; choose "
                                            r"another out_dir or pass overwrite=True$"):
        Session(["detector=none"], sample_rate=16000, outputs=["files"], out_dir=tmp_path)
    assert (tmp_path / "channels.csv").read_text() == "mine\n"
    with Session(["detector=none", "~output.plots"], sample_rate=16000, outputs=["files"], out_dir=tmp_path,
                 overwrite=True) as s:
        s.feed(np.zeros(1000, np.float32))
    assert (tmp_path / "channels.csv").read_text().startswith("time,")



def test_a_long_session_keeps_no_frame_it_has_handed_back():
    """A game's session runs for hours: the frames handed back are not kept (they were, 60 a second)."""
    with Session(["detector=none"], sample_rate=16000) as s:
        for _ in range(5):
            assert len(s.feed(np.zeros(16000, np.float32))) == 60
            assert s._frames == []
    assert s.metrics["n_frames"] == 300


def test_stereo_and_pcm_integers_are_read_as_input_file_reads_them(recording, tmp_path):
    """A 2-D array was flattened (channels interleaved: twice the frames, at the wrong pitch), int16 went in
    unscaled; now (frames, channels) is mixed by the mean and PCM integers are scaled, as for a file (same bytes)."""
    x, sr = sf.read(recording, dtype="float32")
    x = x[: sr * 2]
    sf.write(tmp_path / "st.wav", np.stack([x, 0.5 * x], axis=1), sr, subtype="PCM_16")
    pcm, _ = sf.read(tmp_path / "st.wav", dtype="int16")
    r = laughlab("input=file", f"input.path={tmp_path / 'st.wav'}", "face=facs", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'cli'}")
    assert r.returncode == 0, r.stderr
    for k, block in enumerate((pcm, pcm.astype(np.float32) / 32768)):
        with Session(["face=facs", "~output.plots"], sample_rate=sr, outputs=["files"],
                     out_dir=tmp_path / f"s{k}") as s:
            n = len(s.feed(block[:1000])) + len(s.feed(block[1000:]))
            n += len(s.close())
        assert n == len(x) // 735 == 120
        for name in ("channels.csv", "motion.bvh"):
            assert filecmp.cmp(tmp_path / f"s{k}" / name, tmp_path / "cli" / name, shallow=False), (k, name)


def test_floats_at_int16_scale_are_warned_once(recording):
    """A Python user's review: floats of int16's scale (up to 32768) were taken as they came, without a word, and
    changed every output; one warning now says so and how to feed them (none for floats within full scale)."""
    import warnings

    x, sr = sf.read(recording, dtype="float32")
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with Session(["detector=none"], sample_rate=sr) as s:
            s.feed(x[:4000])
            s.feed(x[4000:8000] * 32768)
            s.feed(x[8000:12000] * 32768)
    ours = [w for w in said if "Session.feed" in str(w.message)]
    assert len(ours) == 1 and "divide int16-scale floats by 32768, or feed them as np.int16" in str(ours[0].message)
    assert ours[0].filename == __file__   # said at the caller's line


@pytest.mark.parametrize("block, message", [
    (np.zeros((2, 5000), np.float32), r"^feed \(frames, channels\) \(got shape \(2, 5000\): \(channels, frames\)\? "
                                      r"pass its \.T\)$"),
    (np.zeros((10, 2, 2), np.float32), r"^feed mono samples or \(frames, channels\) \(got shape \(10, 2, 2\)\)$"),
    (np.array(["a", "b"]), r"^feed audio samples: floats in \[-1, 1\] or PCM integers \(got an array of <U1\)$"),
    # a list of Python ints is int64: scaled by 2^63 it played as silence (an API user's review)
    ([0, 16000, -16000], r"^feed audio samples: floats in \[-1, 1\] or PCM integers \(int16, int32, uint8\); got "
                         r"int64 \(a list of Python ints\?\): give np.asarray\(samples, np.int16\) for 16-bit PCM$"),
])
def test_a_block_it_cannot_read_is_one_clear_error_not_the_closing_one(block, message):
    with pytest.raises(LaughlabError, match=message):
        with Session(["detector=none"], sample_rate=16000) as s:
            s.feed(block)


def test_feeds_from_several_threads_each_get_the_frames_their_samples_completed():
    """Two threads feeding at once could take each other's frames (0 or 3 back for one frame's samples)."""
    import threading

    counts = []
    with Session(["detector=none"], sample_rate=16000) as s:
        def feeder():
            for _ in range(60):
                counts.append(len(s.feed(np.zeros(800, np.float32))))   # three frames of 16 kHz at 60 fps

        threads = [threading.Thread(target=feeder) for _ in range(3)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert counts == [3] * 180


def test_a_session_dropped_unclosed_is_collected_and_its_thread_ends():
    """Its thread held the session, so it was never collected: the thread and the temporary folder stayed."""
    import gc
    import threading

    s = Session(["detector=none"], sample_rate=16000)
    s.feed(np.zeros(16000, np.float32))
    out, thread = s.out_dir, s._thread
    del s
    gc.collect()
    thread.join(10)
    assert not thread.is_alive() and not out.exists()
    assert "laughlab-session" not in [t.name for t in threading.enumerate()]


def test_file_outputs_without_out_dir_are_refused_streams_are_not():
    """A game developer's review: Session(..., outputs=["files"]) with no out_dir wrote into a temporary folder and
    removed it at close(), so the files asked for were never there; now one line asks for out_dir."""
    for outputs in (["files"], ["gltf"], ["files", "vmc"]):
        with pytest.raises(LaughlabError, match=r"^outputs=\[.*\] writes files \(.*\): give out_dir=PATH, or they "
                                                r"would go to a temporary folder removed at close\(\)$"):
            Session(["detector=none"], sample_rate=16000, outputs=outputs)
    with Session(["detector=none"], sample_rate=16000, outputs=["vmc"]) as s:   # a stream: nothing to keep
        assert len(s.feed(np.zeros(1600, np.float32))) == 6


def test_streaming_outputs_go_at_the_pace_the_program_feeds():
    """outputs=["viewer"] held the first feed until a browser page opened (a game's loop stood still), and
    ["vmc"] slept each feed to the frame clock: the program feeding the samples sets the pace."""
    import socket
    import time

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    try:
        for outputs, extra in ((["viewer"], ["output.viewer.port=0"]),
                               (["vmc"], [f"output.vmc.port={rx.getsockname()[1]}"])):
            result = {}

            def go():
                with Session(["detector=none", *extra], sample_rate=16000, outputs=outputs) as s:
                    t = time.perf_counter()
                    result["n"] = len(s.feed(np.zeros(32000, np.float32)))   # 2 s of audio
                    result["s"] = time.perf_counter() - t

            import threading

            th = threading.Thread(target=go, daemon=True)
            th.start()
            th.join(30)
            assert not th.is_alive() and result["n"] == 120 and result["s"] < 1.5, (outputs, result)
    finally:
        rx.close()


def test_a_plugin_error_is_raised_once_then_one_line(tmp_path):
    """A plugin that raises: its exception from the feed that meets it; every later feed re-raised the same object
    (its traceback grew by three frames a feed) and queued samples for a run that had ended."""
    (tmp_path / "boom.py").write_text(
        "from dataclasses import dataclass\nimport laughlab\nfrom laughlab import Extractor\n\n\n"
        "@dataclass\nclass BoomParams:\n    at_frame: int = 30\n\n\n"
        "class Boom(Extractor):\n    name = 'boom'\n    Params = BoomParams\n\n"
        "    def step(self, block, frame):\n        if frame.index >= self.params.at_frame:\n"
        "            raise RuntimeError(f'boom at frame {frame.index}')\n        frame.control['mcs'] = 0.5\n\n\n"
        "@laughlab.hookimpl\ndef register_extractors(register):\n    register(Boom)\n")
    s = Session([f"plugins_dir={tmp_path}", "extractor=boom"], sample_rate=16000)
    assert len(s.feed(np.zeros(8000, np.float32))) == 30
    with pytest.raises(RuntimeError, match=r"^boom at frame 30$"):
        s.feed(np.zeros(8000, np.float32))
    for _ in range(2):
        with pytest.raises(LaughlabError, match=r"^the session stopped on an error: RuntimeError: boom at frame 30$"):
            s.feed(np.zeros(8000, np.float32))
    assert s._src.samples.qsize() == 0
    with pytest.raises(LaughlabError, match=r"^the session stopped on an error"):
        s.close()
    assert s.close() == [] and not s.out_dir.exists()


def _examples():
    """The Session examples as a reader copies them: docs/pipeline.md's and the module docstring's."""
    import inspect
    import re
    from pathlib import Path

    import laughlab.session

    page = (Path(__file__).resolve().parents[1] / "docs" / "pipeline.md").read_text()
    (doc,) = [b for b in re.findall(r"```python\n(.*?)```", page, re.S) if "from laughlab.session import" in b]
    module = inspect.getdoc(laughlab.session).split("\n\n", 1)[1].split("\nThe frames are")[0]
    return {"pipeline.md": doc, "session.py": inspect.cleandoc(module)}


@pytest.mark.parametrize("where", ["pipeline.md", "session.py"])
def test_the_documented_examples_run_as_written_and_give_every_frame(where, recording, monkeypatch):
    """An API user's review: pipeline.md's example called an undefined my_audio_blocks(), and the module's lost
    the last frame (no close()). Run on a real laugh, each reads the face of every frame input=file computes."""
    from laughlab.io import vmc
    from laughlab.io.audio import n_frames_for

    read = []   # each example reads frame.arkit once a frame it is given: computed once a frame
    original = vmc.arkit_weights
    monkeypatch.setattr(vmc, "arkit_weights", lambda ch: read.append(1) or original(ch))
    ns: dict = {}
    exec(compile(_examples()[where].replace('"laugh.wav"', repr(str(recording))), where, "exec"), ns)
    info = sf.info(recording)
    assert len(read) == ns["s"].metrics["n_frames"] == n_frames_for(info.frames, info.samplerate, 60)


def test_a_vmc_host_that_does_not_resolve_is_said_when_the_session_is_made():
    """An API user's review: output.vmc.host=no.such.host.invalid was raised only by the first feed."""
    with pytest.raises(LaughlabError, match=r"^output.vmc: cannot reach host 'no-such-host.invalid': "):
        Session(["detector=none", "output.vmc.host=no-such-host.invalid"], sample_rate=16000, outputs=["vmc"])


def test_a_sessions_metrics_say_what_made_them(tmp_path):
    """A reproducibility review: a Session's metrics.json had no commit, versions or CPU family (a command's has
    them), nor the session's own arguments; a command's records its input's absolute path too (with
    hydra.job.chdir=true its .hydra/config.yaml keeps '../a44.wav', which does not lead there from the run)."""
    import json

    import soundfile as sf

    with Session(["detector=none", "~output.plots"], sample_rate=16000, outputs=["files"], out_dir=tmp_path / "s") as s:
        s.feed(np.zeros(3200, np.float32))
    made = json.loads((tmp_path / "s" / "metrics.json").read_text())["provenance"]
    assert made["session"] == {"overrides": ["detector=none", "~output.plots"], "sample_rate": 16000,
                               "outputs": ["files"]}
    assert made["input_path"] is None and made["input_sha256"] is None and "cpu_family" in made["versions"]
    assert set(made) >= {"git_hash", "versions"}
    sf.write(tmp_path / "a.wav", np.zeros(1600, np.float32), 16000)
    (tmp_path / "cwd").mkdir()
    r = laughlab("input=file", "input.path=../a.wav", "detector=none", "~output.plots", "hydra.job.chdir=true",
                 f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path / "cwd")
    assert r.returncode == 0, r.stderr
    made = json.loads((tmp_path / "run" / "metrics.json").read_text())["provenance"]
    assert made["input_path"] == str((tmp_path / "a.wav").resolve()) and len(made["input_sha256"]) == 64


def test_the_documented_tables_of_a_sessions_frames(recording):
    """docs/pipeline.md's notebook lines turn a session's frames into a channels table, a pose array and an ARKit
    table: run as written on a real laugh's frames."""
    import re
    from pathlib import Path

    import laughlab

    page = (Path(__file__).resolve().parents[1] / "docs" / "pipeline.md").read_text(encoding="utf-8")
    (doc,) = [b for b in re.findall(r"```python\n(.*?)```", page, re.S) if "pd.DataFrame([f.channels" in b]
    x, sr = sf.read(recording, dtype="float32")
    with laughlab.Session(["face=facs"], sample_rate=sr) as s:
        frames = s.feed(x[: sr]) + s.close()
    space = {"frames": frames}
    exec(doc, space)
    n = len(frames)
    assert len(space["channels"]) == n and "jaw" in space["channels"]
    assert space["channels"].index.name == "time" and space["channels"].index[1] == pytest.approx(1 / 60)
    assert space["pose"].shape == (n, len(frames[0].pose)) and "jawOpen" in space["arkit"]
    assert laughlab.Session is laughlab.session.Session


def test_the_documented_session_loop_and_tables_run_as_written(recording, tmp_path):
    """A docs review (2026-11-29): the page's Session loop, run as written, warned that numpy came before laughlab
    (it imported soundfile first), and its notebook tables used a ``frames`` no snippet made.  Both snippets, in
    one fresh interpreter beside a ``laugh.wav``: no warning, every frame of the file (the same as a Session fed
    the whole file at once), the tables as long."""
    import re
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "pipeline.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", page, re.S)
    (loop,) = [b for b in blocks if "with Session(" in b and "s.feed(block)" in b]
    (tables,) = [b for b in blocks if "pd.DataFrame([f.channels" in b]
    shutil.copy(recording, tmp_path / "laugh.wav")
    code = loop + tables + "print(len(frames), len(channels), pose.shape[0], len(arkit))\n"
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "Warning" not in r.stderr, r.stderr
    x, sr = sf.read(recording, dtype="float32")
    with Session([], sample_rate=sr) as s:
        n = len(s.feed(x) + s.close())
    assert r.stdout.split() == [str(n)] * 4


def test_a_session_after_numpy_was_imported_first_says_what_it_means_for_the_bytes():
    """A Python user's review: a notebook imports numpy before laughlab, and on an AVX-512 machine numpy's loops are
    then not pinned: the outputs differed from the command line's in the last bits (``body=hill``'s more), said only
    in results.json. One warning now, at the caller's line; none when laughlab came first."""
    import subprocess
    import sys

    from laughlab import _kernels

    code = "import {}, {}\ns = laughlab.Session([], sample_rate=16000); s.close()\n" \
           "s = laughlab.Session([], sample_rate=16000); s.close()\n"
    env = {k: v for k, v in __import__("os").environ.items()
           if k not in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE", "LAUGHLAB_NATIVE_KERNELS")}
    first, after = (subprocess.run([sys.executable, "-W", "always", "-c", code.format(*order)], capture_output=True,
                                   text=True, timeout=120, env=env) for order in (("numpy", "laughlab"),
                                                                                  ("laughlab", "numpy")))
    assert first.returncode == 0 and after.returncode == 0, first.stderr + after.stderr
    assert "numpy was imported before laughlab" not in after.stderr
    avx512 = _kernels.platform.machine().lower() in ("x86_64", "amd64") and {"avx2", "fma", "avx512f"} <= \
        _kernels.cpu_flags()
    said = [line for line in first.stderr.splitlines() if "numpy was imported before laughlab" in line]
    assert len(said) == (1 if avx512 else 0), first.stderr
    assert not said or said[0].startswith("<string>:2: UserWarning:")


def test_a_sessions_high_pass_is_input_files(recording, tmp_path):
    """A Python user's review: a session refused every input.* override, so a DC offset could not be removed as the
    command line removes it (input.highpass_hz=20). ``highpass_hz=`` is the same filter: the same bytes as the
    file run, however the samples are split."""
    x, sr = sf.read(recording, dtype="float32")
    x = x[: 2 * sr] + np.float32(0.05)   # a DC offset
    sf.write(tmp_path / "dc.wav", x, sr, subtype="FLOAT")
    r = laughlab("input=file", f"input.path={tmp_path / 'dc.wav'}", "input.highpass_hz=20", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'cli'}")
    assert r.returncode == 0, r.stderr
    with Session(["~output.plots"], sample_rate=sr, outputs=["files"], out_dir=tmp_path / "s", highpass_hz=20) as s:
        for a in range(0, len(x), 3001):
            s.feed(x[a:a + 3001])
        s.close()
    for name in ("channels.csv", "motion.bvh"):
        assert filecmp.cmp(tmp_path / "s" / name, tmp_path / "cli" / name, shallow=False), name
    with pytest.raises(LaughlabError, match=r"^highpass_hz must be 0-1000 Hz \(got -1\)$"):
        Session([], sample_rate=sr, highpass_hz=-1)


@pytest.mark.parametrize("overrides, outputs, seconds, files", [
    (["body=hill", "extractor=pressure"], ["files"], None, ("channels.csv", "motion.bvh", "face_arkit.csv")),
    (["detector=none"], ["video"], 2.0, ("channels.csv", "video.mp4")),   # drawn in a thread pool
])
def test_a_session_left_unclosed_at_the_programs_end_writes_its_outputs(recording, tmp_path, overrides, outputs,
                                                                       seconds, files):
    """The seventeenth session's note: at the interpreter's exit the daemon thread of an unclosed ``body=hill``
    session was cut off mid-run: its outputs stayed hidden ``.part`` files (and under load Python aborted, exit
    134). The exit now ends its input and waits for the outputs: the files a closed session writes, byte for byte;
    a video too, whose frames are drawn in a thread pool (a diff review: from ``atexit`` Python had stopped the
    pools, and the folder was left empty without a word)."""
    import subprocess
    import sys

    code = ("import sys, laughlab, soundfile as sf\n"
            "x, sr = sf.read(sys.argv[1], dtype='float32')\n"
            f"x = x[:{'len(x)' if seconds is None else f'int({seconds} * sr)'}]\n"
            f"s = laughlab.Session({overrides!r}, sample_rate=sr, outputs={outputs!r}, out_dir=sys.argv[2])\n"
            "for i in range(0, len(x), 4410):\n"
            "    s.feed(x[i:i + 4410])\n"
            "if sys.argv[3] == 'close':\n"
            "    s.close()\n")
    procs = {how: subprocess.Popen([sys.executable, "-c", code, str(recording), str(tmp_path / how), how],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for how in ("close", "leave")}   # side by side: each is mostly Python and numba starting
    for how, proc in procs.items():
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0 and "laughlab:" not in err, (how, err[-2000:])
    left = sorted(p.name for p in (tmp_path / "leave").iterdir())
    assert left == sorted(p.name for p in (tmp_path / "close").iterdir()) and set(files) <= set(left)
    assert not [n for n in left if n.endswith(".part")]
    for name in files:
        assert filecmp.cmp(tmp_path / "leave" / name, tmp_path / "close" / name, shallow=False), name


def test_a_session_never_fed_and_left_unclosed_ends_without_a_word():
    """The exit that finishes unclosed sessions says an error that ended one; a session made and never fed (a game
    that quit before any audio) has nothing to say, as its close() has not."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", "import laughlab\ns = laughlab.Session([], sample_rate=16000)\n"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "laughlab:" not in r.stderr, r.stderr
