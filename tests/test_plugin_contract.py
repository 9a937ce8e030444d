"""A third-party plugin against the contract: ``laughlab.testing.check_plugin`` on broken plugins and on laughlab's
own, and the worked examples of docs/architecture.md's "Writing a plugin" run as the page gives them (a plugin
authors' review, 2026-11-27: laughlab had no way to check a plugin but a run, and no test ran the page's examples)."""
import re
import subprocess
import sys
import types
from dataclasses import dataclass
from pathlib import Path

import pytest

from laughlab import Body, Extractor, Scheduler, Sink, Source
from laughlab.core import plugins
from laughlab.core.frame import ClipEvent
from laughlab.testing import ContractError, check_plugin, run_frames

from test_plugin_errors import GoodFace

DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"


def face(name, step, base=GoodFace):
    return type(name, (base,), {"name": name, "step": step})


_COUNT = [0]


def _counting_smile(self, frame):
    """A module-level counter (a plugin author's review): an experiment's trials then depend on their order."""
    _COUNT[0] += 1
    GoodFace.step(self, frame)
    frame.channels["smile"] = min(1.0, (_COUNT[0] % 100) / 100)


def _random_smile(self, frame):   # a draw from numpy's global generator, not self.ctx.rng
    import numpy as np

    GoodFace.step(self, frame)
    frame.channels["smile"] = float(np.random.random())


class Untidy(Extractor):   # its state survives reset()
    name = "untidy"
    n = 0

    def step(self, block, frame):
        self.n += 1
        frame.control["mcs"] = min(1.0, self.n / 1000)


class Wanders(Body):
    name = "wanders"

    def step(self, frame):
        frame.channels.update(chest=0.5, belly=0.5)
        frame.offsets["Tail"] = (1.0, 0.0, 0.0)


class Dances(Scheduler):
    name = "dances"

    def step(self, frame):
        if frame.index == 3:
            frame.events.append(ClipEvent(frame.time_s, "start", "macarena", 10.0))


class Leaky(Sink):   # writes straight into the run folder, names no file and has no abort()
    name = "leaky"

    def open(self, run):
        super().open(run)
        self.f = open(run.out_dir / "frames.txt", "w")

    def write(self, chunk):
        self.f.write(f"{len(chunk.times)}\n")

    def close(self):
        self.f.close()
        return [self.run.out_dir / "frames.txt"]


def detector(name, step):
    from laughlab import Detector

    return type(name, (Detector,), {"name": name, "step": step})


def _shut_gate(self, block, frame):   # writes a shut gate but leaves mcs as it was: the character laughs on
    frame.control.update(laughter=0.0, laugh_gate=0.0)


@pytest.mark.parametrize("cls, says", [
    (detector("loud", lambda self, b, f: f.control.update(laughter=50.0, laugh_gate=1.0)),
     "laughter is 50.0 at frame 0: a weight in [0, 1]"),
    (detector("gate_only", lambda self, b, f: f.control.update(laugh_gate=1.0)),
     "wrote no laughter at frame 0: every detector writes frame.control['laughter'] and ['laugh_gate']"),
    (detector("returns", lambda self, b, f: 0.5), "wrote no laughter and no laugh_gate at frame 0"),
    (detector("nogate", lambda self, b, f: f.control.update(laughter=0.5, laugh_gate=None if f.index == 3 else 1.0)),
     "control 'laugh_gate' is None (NoneType) at frame 3: a finite number"),
    (detector("shut", _shut_gate), "laugh_gate is 0 at frame 4 but mcs 0.00430146 is not gated: a detector gates"),
    (face("no_eyes", lambda self, f: f.channels.update(smile=0.1, jaw=0.1, blink=0.0)), "writes no eyes_closed"),
    (face("grins", lambda self, f: f.channels.update(smile=2.0, jaw=0.0, blink=0.0, eyes_closed=0.0)),
     "smile is 2.0 at frame 0: a weight in [0, 1]"),
    (face("texty", lambda self, f: f.channels.update(smile="wide", jaw=0.0, blink=0.0, eyes_closed=0.0)),
     "channels 'smile' is 'wide' (str) at frame 0: a finite number"),
    (face("rig", lambda self, f: (GoodFace.step(self, f), f.channels.update({"arkit.JawOpen": 0.5}))),
     "arkit.JawOpen: not ARKit blendshape names"),
    (face("sometimes", lambda self, f: (GoodFace.step(self, f), f.index == 5 and f.channels.update(x=1.0))),
     "frame 5 writes other channels than frame 0 (x)"),
    (face("dice", _random_smile), "two plugins on the same seed give different values: keep state on self"),
    (face("counts", _counting_smile), "and draw randomness from self.ctx.rng only"),
    (Untidy, "after a run and reset() its values differ from a new one's"),
    (Wanders, "wrote an offset for joint 'Tail', which the skeleton does not have"),
    (Dances, "scheduler 'dances': the scheduler started clip 'macarena' at 0.05 s (frame 3), which the clip "
             "library does not hold"),
])
def test_check_plugin_names_the_rule_a_plugin_breaks(cls, says):
    with pytest.raises(ContractError) as e:
        check_plugin(cls)
    assert says in str(e.value) and "\n" not in str(e.value), str(e.value)


class Hum(Source):
    """A good source: 2 s of a seeded hum at 16 kHz, cut as a run cuts a file's samples."""
    name = "hum"
    reread = True
    scale = 0.5

    def open(self):
        import numpy as np

        from laughlab.io.audio import n_frames_for

        self.sample_rate = 16000
        t = np.arange(2 * self.sample_rate) / self.sample_rate
        self.audio = (self.scale * np.sin(2 * np.pi * 220 * t) * self.ctx.rng.uniform(0.5, 1.0)).astype("float32")
        self.n_frames = n_frames_for(len(self.audio), self.sample_rate, self.ctx.fps)

    def blocks(self):
        from laughlab.io.audio import cut_frames

        return cut_frames([self.audio], self.sample_rate, self.ctx.fps)


def _source(name, **attrs):
    return type(name, (Hum,), {"name": name, **attrs})


def _unseeded_open(self):
    import numpy as np

    Hum.open(self)
    self.audio = self.audio * np.float32(np.random.uniform(0.5, 1.0))   # numpy's global generator


def _fixed_blocks(self):
    return iter([self.audio[i:i + 256] for i in range(0, len(self.audio), 256)])


def _float_rate_open(self):
    Hum.open(self)
    self.sample_rate = 16000.0


def _n_more_open(self):
    Hum.open(self)
    self.n_frames += 5


def _stereo_blocks(self):
    import numpy as np

    return (np.stack([b, b], axis=1) for b in Hum.blocks(self))


def _drifting_blocks(self):   # reread = True, but each call reads further on
    self.calls = getattr(self, "calls", 0) + 1
    return (b * (1.0 - 0.1 * self.calls) for b in Hum.blocks(self))


@pytest.mark.parametrize("cls, says", [
    (_source("loud", scale=20000.0), "block 0 holds samples up to 15744.7: full-scale floats in [-1, 1]"),
    (_source("chunky", blocks=_fixed_blocks), "block 0 has 256 samples: frame k holds round((k+1)*sr/fps) - "
                                              "round(k*sr/fps) samples (267 here"),
    (_source("unseeded", open=_unseeded_open), "two sources on the same seed give different blocks"),
    (_source("float_rate", open=_float_rate_open), "sample_rate is 16000.0 after open(): a whole number of Hz"),
    (_source("more", open=_n_more_open), "blocks() gave 120 blocks for n_frames = 125"),
    (_source("stereo", blocks=_stereo_blocks), "block 0 is a ndarray (267, 2) float64: a 1-D numpy array"),
    (_source("counted_live", live=True), "n_frames is 120 and live is True: a live source has no n_frames"),
    (_source("drifting", blocks=_drifting_blocks), "reread = True but blocks() again gives other blocks"),
])
def test_check_plugin_names_the_rule_a_source_breaks(cls, says):
    """check_plugin refused a source ("checked by a run on it"): a source handing 16-bit integers, blocks of its
    own length or a count it does not give was found only by what a run then did with them."""
    with pytest.raises(ContractError) as e:
        check_plugin(cls)
    assert says in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_laughlabs_own_sources_and_streaming_sinks_keep_the_contract(tmp_path):
    """The synthetic generator and a 44.1 kHz WAV through input=file; the live sinks a frame a chunk, as a run on
    a microphone gives them (output.viewer without waiting for a page)."""
    import numpy as np
    import soundfile as sf

    check_plugin(Hum)
    check_plugin(plugins.get("source", "synthetic").obj, {"duration_s": 2.0})
    t = np.arange(int(1.5 * 44100)) / 44100
    sf.write(tmp_path / "a.wav", 0.3 * np.sin(2 * np.pi * 300 * t), 44100, subtype="PCM_16")
    check_plugin(plugins.get("source", "file").obj, {"path": str(tmp_path / "a.wav")})
    check_plugin(plugins.get("sink", "viewer").obj, {"wait": "off"}, seconds=1.0)
    with pytest.raises(ContractError, match="source 'file' does not open with {'path': '.*nothing.wav'}: "):
        check_plugin(plugins.get("source", "file").obj, {"path": str(tmp_path / "nothing.wav")})


def test_check_plugin_on_a_sink_that_leaves_files_behind():
    with pytest.raises(ContractError) as e:
        check_plugin(Leaky)
    text = str(e.value)
    assert "it wrote frames.txt, which its files (or planned()) do not name" in text
    assert "abort() after a chunk left frames.txt" in text


@pytest.mark.parametrize("kind, name", [("extractor", "rms"), ("detector", "none"), ("scheduler", "energy"),
                                        ("scheduler", "none"), ("body", "shapes"), ("face", "smile"),
                                        ("face", "facs"), ("face", "cgm"), ("sink", "csv"), ("sink", "arkit"),
                                        ("sink", "bvh")])
def test_laughlabs_own_plugins_keep_the_contract(kind, name):
    check_plugin(plugins.get(kind, name).obj)


@pytest.mark.parametrize("name", ["fourier", "hill"])
def test_a_body_may_extrapolate_its_shapes_but_a_face_not_its_weights(name):
    """body=fourier's chest/belly leave [0, 1] by 0.005 and body=hill's by 0.0003, as their docs say they may (shape
    weights extrapolate); a face's weights may not."""
    check_plugin(plugins.get("body", name).obj)

    class Over(GoodFace):
        name = "over_face"

        def step(self, frame):
            super().step(frame)
            frame.channels["jaw"] = 1.01

    with pytest.raises(ContractError, match=r"jaw is 1.01 at frame 0: a weight in \[0, 1\]"):
        check_plugin(Over)


def test_check_plugin_refuses_bad_defaults_as_the_command_line_does():
    @dataclass
    class P:
        gain: float = float("inf")

    with pytest.raises(ContractError, match=r"bad parameter face.gain \(face=inf_face\): it must be a finite number"):
        check_plugin(type("InfFace", (GoodFace,), {"name": "inf_face", "Params": P}))


def test_run_frames_steps_the_plugin_between_the_built_ins():
    frames = run_frames(GoodFace, seconds=2.0)
    assert len(frames) == 120 and [f.index for f in frames] == list(range(120))
    assert all(f.channels["smile"] == min(1.0, f.control["mcs"]) for f in frames)
    assert max(f.control["mcs"] for f in frames) > 0.3 and "energy" in frames[-1].channels   # the energy scheduler ran


# docs/architecture.md's examples, as the page gives them


def doc_block(first_line: str) -> str:
    """The fenced block of docs/architecture.md whose first line is ``first_line``."""
    blocks = re.findall(r"```(?:python|toml|bash)\n(.*?)```", DOC.read_text(), re.S)
    found = [b for b in blocks if b.splitlines()[0] == first_line]
    assert len(found) == 1, first_line
    return found[0]


def doc_module(path: str) -> types.ModuleType:
    module = types.ModuleType(Path(path).stem)
    sys.modules[module.__name__] = module   # dataclasses look their module up
    try:
        exec(compile(doc_block(f"# {path}"), path, "exec"), module.__dict__)
    finally:
        del sys.modules[module.__name__]
    return module


def test_the_docs_loud_extractor_and_giggle_face_keep_the_contract():
    check_plugin(doc_module("myplugins/loud.py").Loud)
    loudness = doc_module("myplugins/loudness.py").Loudness   # the detector, at the synthetic's rate and a file's
    check_plugin(loudness)
    check_plugin(loudness, sample_rate=44100)
    giggle = doc_module("myplugins/giggle.py")
    check_plugin(giggle.Giggle)
    check_plugin(giggle.Giggle, {"gain": 3.0, "tau_s": 0.5})
    with pytest.raises(ContractError, match=r"bad parameter in face=giggle: tau_s must be > 0 \(got 0.0\)"):
        check_plugin(giggle.Giggle, {"tau_s": 0})


def test_the_docs_jsonl_sink_keeps_the_contract_and_writes_a_line_a_frame(tmp_path):
    import json

    from laughlab.core.bases import RunInfo
    from laughlab.testing import _chunks

    jsonl = doc_module("myplugins/jsonl.py")
    check_plugin(jsonl.Jsonl)
    chunks, skeleton, n = _chunks(1.0, 0, 60.0, 16000)
    sink = jsonl.Jsonl(jsonl.JsonlParams(precision=3))
    sink.open(RunInfo(tmp_path, 60.0, skeleton, n, None, {}))
    for chunk in chunks:
        sink.write(chunk)
    assert sink.close() == [tmp_path / "frames.jsonl"]
    rows = [json.loads(line) for line in (tmp_path / "frames.jsonl").read_text().splitlines()]
    assert len(rows) == n == 60 and rows[30]["time"] == 0.5
    assert rows[30]["mcs"] == round(float(chunks[0].channels["mcs"][30]), 3) and "eyes_closed" in rows[30]


def test_the_docs_test_of_a_package_passes_as_written(monkeypatch):
    giggle = doc_module("myplugins/giggle.py")
    monkeypatch.setitem(sys.modules, "laughlab_giggle", types.ModuleType("laughlab_giggle"))
    monkeypatch.setitem(sys.modules, "laughlab_giggle.giggle", giggle)
    tests: dict = {}
    exec(doc_block("# tests/test_giggle.py of your package"), tests)
    tests["test_giggle_keeps_the_contract"]()
    tests["test_giggle_opens_the_jaw_on_the_calls"]()


def test_the_docs_giggle_and_jsonl_commands_in_one_run(tmp_path):
    (tmp_path / "myplugins").mkdir()
    for name in ("giggle", "jsonl"):
        (tmp_path / "myplugins" / f"{name}.py").write_text(doc_block(f"# myplugins/{name}.py"))
    text = DOC.read_text()
    face = re.search(r"`python -m laughlab (plugins_dir=myplugins face=giggle[^`]*)`", text).group(1).split()
    sink = re.search(r"`python -m laughlab plugins_dir=myplugins (\+output.jsonl=\{\})`", text).group(1)
    r = subprocess.run([sys.executable, "-m", "laughlab", *face, sink, "input.duration_s=2", "hydra.run.dir=run"],
                       capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert (tmp_path / "run" / "face_arkit.csv").read_text().splitlines()[0] == \
        "time,eyeBlinkLeft,eyeBlinkRight,jawOpen,mouthSmileLeft,mouthSmileRight"
    assert len((tmp_path / "run" / "frames.jsonl").read_text().splitlines()) == 120
