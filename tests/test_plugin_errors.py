"""The lines a third-party plugin's bugs get from a run (a plugin authors' review, 2026-11-27: a plugin registered as
an object, a constructor that raised, an extractor without ``mcs``, a ``Literal`` parameter and a face's misspelt
ARKit names each ended in a traceback, a line blaming laughlab, or nothing at all).  The plugins are registered in
code and the command line runs in the test's process (tests/inprocess.py)."""
from dataclasses import dataclass

import pytest

import laughlab
from laughlab import Extractor, Face
from laughlab.core import blame, pipeline, plugins
from laughlab.core.bases import Context
from laughlab.core.errors import LaughlabError

from inprocess import laughlab as run_cli


class GoodFace(Face):
    name = "good_face"

    def step(self, frame):
        frame.channels.update(smile=min(1.0, frame.control["mcs"]), jaw=0.0, blink=0.0, eyes_closed=frame.clip_eyes)


class Registers:
    def __init__(self, obj, hook="register_faces"):
        setattr(self, hook, laughlab.hookimpl(specname=hook)(lambda register: register(obj)))


@pytest.fixture
def registered():
    done = []

    def add(obj, hook="register_faces"):
        plugin = Registers(obj, hook)
        plugins.pm.register(plugin, name=f"test-contract-{len(done)}")
        done.append(plugin)

    yield add
    for p in done:
        plugins.pm.unregister(p)


def test_a_plugin_registered_as_an_object_is_one_line(registered):
    registered(GoodFace())
    with pytest.raises(LaughlabError, match=r"^face plugin 'good_face' from registered: test-contract-0 is "
                                            r"registered as an object \(GoodFace\(\.\.\.\)\): register its class, "
                                            r"register\(GoodFace\)"):
        plugins.registry()


def test_a_register_hook_that_raises_is_one_line_naming_the_plugin_and_its_line():
    """A re-read: a ``register_faces`` that raised ended every command in a traceback."""
    def no_faces(register):
        raise KeyError("gape")

    plugin = type("Raises", (), {"register_faces": staticmethod(laughlab.hookimpl(specname="register_faces")(no_faces))})
    plugins.pm.register(plugin, name="test-raises")
    try:
        with pytest.raises(LaughlabError) as err:
            plugins.registry()
    finally:
        plugins.pm.unregister(plugin)
    line = no_faces.__code__.co_firstlineno + 1
    assert str(err.value) == (f"register_faces of plugin registered: test-raises raised KeyError: 'gape' (at {__file__}, "
                              f"line {line}); every laughlab command loads the installed plugins: mend it, or "
                              "uninstall it")


class Boom(GoodFace):
    name = "boom"

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        self.table = {}["x"]


class NoCtx(GoodFace):
    name = "no_ctx"

    def __init__(self, params):
        super().__init__(params)


def test_a_plugin_that_raises_as_it_is_built_is_named(registered):
    registered(Boom)
    registered(NoCtx)
    with pytest.raises(blame.PluginBug) as e:
        pipeline._built("face", "boom", {}, Context(), "face.boom")
    assert str(e.value) == (f"face 'boom' ({__file__}, Boom.__init__) raised KeyError: 'x' as the run built it (the "
                            "lines above are from the plugin's code)")
    assert blame.trace(e.value).splitlines()[-1] == "KeyError: 'x'" and "self.table" in blame.trace(e.value)
    with pytest.raises(blame.PluginBug, match=r"^face 'no_ctx' \(.*, NoCtx.__init__\) raised TypeError: .*takes 2 "
                                              r".*\(laughlab builds a plugin as Cls\(params, ctx\)"):
        pipeline._built("face", "no_ctx", {}, Context(), "face.no_ctx")
    r = run_cli("face=boom", "detector=none", "input.duration_s=1", "hydra.run.dir=never")
    assert r.returncode == 1 and r.stderr.startswith("Traceback (most recent call last):\n  File ")
    assert r.stderr.splitlines()[-1].startswith("laughlab: error: face 'boom' (") and r.stderr.count("laughlab:") == 1


def _refused(tmp_path, said: str, *args: str) -> None:
    """The run of ``args`` (1 s, into tmp_path/run) exits 1 with the one line ``said`` and writes nothing."""
    r = run_cli(*args, "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 1 and r.stderr == f"laughlab: error: {said}\n", r.stderr
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


def test_an_extractor_that_writes_no_mcs_is_named_not_laughlab(registered, tmp_path):
    class Loudness(Extractor):
        name = "loudness"

        def step(self, block, frame):
            frame.control["loud"] = float(abs(block).max(initial=0.0))

    registered(Loudness, "register_extractors")
    _refused(tmp_path, f"extractor 'loudness' ({__file__}, Loudness.step) wrote no mcs at frame 0 (it wrote loud): "
             "every extractor writes frame.control['mcs'] (0-1), the signal the detector, scheduler, body and face "
             "read; nothing was written", "extractor=loudness", "detector=none")


class Peak(Extractor):
    """An extractor whose mcs is given per test (a plugin author's review, 2026-11-29)."""
    name = "peak"
    value = None

    def step(self, block, frame):
        frame.control["mcs"] = type(self).value(block, frame)


@pytest.mark.parametrize("value, says", [
    (lambda block, f: abs(block) * 2, "wrote mcs as ndarray, shape (267,) at frame 0: mcs is one number a frame, 0-1"),
    (lambda block, f: "0.3", "wrote mcs as str at frame 0: mcs is one number a frame, 0-1"),
])
def test_an_extractors_mcs_that_is_not_one_number_is_its_line_not_a_later_stages(registered, tmp_path, value, says):
    """An array or a text as mcs: the next stage that read it (a built-in detector or scheduler) raised, and its line
    asked for a report to laughlab."""
    registered(type("Peak", (Peak,), {"value": staticmethod(value), "__module__": __name__}), "register_extractors")
    r = run_cli("extractor=peak", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 1 and r.stderr.startswith(f"laughlab: error: extractor 'peak' ({__file__}, Peak.step) "
                                                     f"{says}") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


@pytest.mark.parametrize("value", [5.0, -0.5])
def test_an_mcs_outside_0_1_is_refused_naming_the_extractor(registered, tmp_path, value):
    """architecture.md: mcs is 0-1; a value of 5 went into channels.csv and an energy of 65, exit 0."""
    registered(type("Peak", (Peak,), {"value": staticmethod(lambda b, f: value if f.index >= 30 else 0.0),
                                      "__module__": __name__}), "register_extractors")
    _refused(tmp_path, f"channel 'mcs' is {value:g} at frame 30: the motion control signal is 0-1 "
             "(docs/architecture.md); a bug in the plugin that writes it, extractor 'peak' (laughlab's own plugins: "
             "please report it); nothing was written", "extractor=peak", "detector=none")


class Scores(laughlab.Detector):
    name = "scores"

    def step(self, block, frame):
        type(self).value(self, frame)


def test_a_detector_that_writes_no_laughter_is_named(registered, tmp_path):
    """A plugin author's review: a detector that returned its score ran to the end, exit 0, its metrics n/a."""
    registered(type("Scores", (Scores,), {"value": lambda self, f: 0.5, "__module__": __name__}),
               "register_detectors")
    _refused(tmp_path, f"detector 'scores' ({__file__}, Scores.step) wrote no laughter and no laugh_gate at frame 0: "
             "every detector writes frame.control['laughter'] and ['laugh_gate'] (0-1) and gates the driving signals "
             "with laughlab.detector.model.apply_gate(frame, gain) (docs/architecture.md); nothing was written",
             "detector=scores")


@pytest.mark.parametrize("key, what", [("laughter", "a detector's laughter probability"),
                                       ("laugh_gate", "a detector's gate")])
def test_a_detectors_value_outside_0_1_is_refused_naming_it(registered, tmp_path, key, what):
    """A laughter of 50 went into channels.csv and the probability metrics, exit 0 (a plugin author's review)."""
    def value(self, f):
        f.control.update(laughter=0.5, laugh_gate=1.0)
        f.control[key] = 50.0 if f.index >= 20 else 0.5

    registered(type("Scores", (Scores,), {"value": value, "__module__": __name__}), "register_detectors")
    _refused(tmp_path, f"channel {key!r} is 50 at frame 20: {what} is 0-1 (docs/architecture.md); a bug in the plugin "
             "that writes it, detector 'scores' (laughlab's own plugins: please report it); nothing was written",
             "detector=scores")


def test_a_gain_above_1_is_the_detectors_bug_not_the_extractors(registered, tmp_path):
    """apply_gate(frame, 2.0) drove mcs to 1.6, and the line blamed the built-in rms extractor."""
    from laughlab.detector.model import apply_gate

    def value(self, f):
        f.control.update(laughter=1.0, laugh_gate=1.0)
        apply_gate(f, 2.0)

    registered(type("Scores", (Scores,), {"value": value, "__module__": __name__}), "register_detectors")
    r = run_cli("detector=scores", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 1 and "apply_gate: the gain is 0-1 (got 2.0)" in r.stderr, r.stderr
    assert "detector 'scores'" in last and "extractor 'rms'" not in r.stderr, last
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


class Sway(laughlab.Body):
    name = "sway"
    offset = None

    def step(self, frame):
        frame.channels.update(chest=1.0, belly=0.0)
        frame.offsets["spine"] = type(self).offset(frame)


@pytest.mark.parametrize("offset, shown", [((5.0, 1.0), "(5.0, 1.0)"), ((1.0, 2.0, 3.0, 4.0), "(1.0, 2.0, 3.0, 4.0)"),
                                           ((float("nan"), 0.0, 0.0), "(nan, 0.0, 0.0)"), ("abc", "abc")])
def test_a_body_offset_that_is_not_three_finite_angles_is_one_line_naming_body_and_joint(registered, tmp_path,
                                                                                         offset, shown):
    """A 2-tuple ended in a 45-line traceback in the mixer; a NaN said only 'pose column 6'."""
    registered(type("Sway", (Sway,), {"offset": staticmethod(lambda f: offset if f.index >= 7 else (0.0, 0.0, 0.0)),
                                      "__module__": __name__}), "register_bodies")
    _refused(tmp_path, f"body 'sway' ({__file__}) offsets joint 'spine' by {shown} at frame 7: an offset is three "
             "finite angles (z, x, y) in degrees; a bug in the plugin that writes it (laughlab's own plugins: please "
             "report it); nothing was written", "body=sway", "detector=none")


def test_a_step_of_another_kinds_signature_is_one_line(registered, tmp_path):
    """A body written with an extractor's step(self, block, frame): a 39-line traceback through the pipeline."""
    class Wrong(laughlab.Body):
        name = "wrong_sig"

        def step(self, block, frame):
            frame.channels.update(chest=1.0, belly=0.0)

    registered(Wrong, "register_bodies")
    r = run_cli("body=wrong_sig", "detector=none", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 1 and r.stderr.startswith(
        f"laughlab: error: body 'wrong_sig' ({__file__}, Wrong.step) cannot be called as a body's step(self, frame) ("
        ) and r.stderr.endswith("): docs/architecture.md, 'Writing a plugin'\n") and r.stderr.count("\n") == 1, r.stderr
    from laughlab.testing import ContractError, check_plugin

    with pytest.raises(ContractError, match=r"cannot be called as a body's step\(self, frame\)"):
        check_plugin(Wrong)


def test_arkit_names_that_are_not_arkits_are_warned_once(capsys):
    from laughlab_plugins import sink_arkit

    sink_arkit.warn_unknown({"jawOpen", "JawOpen", "mouthSmile"})
    sink_arkit.warn_unknown({"jawOpen", "JawOpen", "mouthSmile"})
    sink_arkit.warn_unknown({"jawOpen", "mouthSmileLeft"})
    assert capsys.readouterr().err == (
        "laughlab: warning: arkit.JawOpen (did you mean jawOpen?), arkit.mouthSmile (did you mean mouthSmileLeft?): "
        "not ARKit blendshape names, so face_arkit.csv leaves them out (the 52 names: "
        "laughlab.face.facs.ARKIT_BLENDSHAPES)\n")


def test_a_params_field_omegaconf_cannot_hold_is_one_line():
    from typing import Literal

    @dataclass
    class P:
        mode: Literal["soft", "hard"] = "soft"

    with pytest.raises(LaughlabError, match=r"^face=moody: its Params cannot be configured: Unexpected type "
                                            r"annotation: Literal\[soft, hard\] \(field mode\); a Params field is a "
                                            r"str, int, float, bool, an Enum"):
        plugins.make_params(type("Moody", (GoodFace,), {"name": "moody", "Params": P}), {}, "face.moody")


def test_a_resume_sees_an_edit_to_a_helper_module_of_a_plugins_package(registered, tmp_path, monkeypatch):
    """A plugin authors' review: an installed package's face imported its curve from a helper module of the package;
    an edit to the helper left plugin_code_hash as it was, so a resumed experiment mixed two codes' numbers."""
    import importlib
    import sys

    from laughlab.harness.runner import plugin_code_hash

    pkg = tmp_path / "giggle_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "curves.py").write_text("def curve(x):\n    return x\n")
    (pkg / "face.py").write_text(
        "from laughlab import Face\n\n\nclass Giggle(Face):\n    name = 'giggle_pkg_face'\n\n"
        "    def step(self, frame):\n        from .curves import curve   # imported when first stepped\n"
        "        frame.channels.update(smile=curve(frame.control['mcs']), jaw=0.0, blink=0.0, eyes_closed=0.0)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "giggle_pkg", raising=False)
    registered(importlib.import_module("giggle_pkg.face").Giggle)
    try:
        before = plugin_code_hash()
        assert plugin_code_hash() == before
        (pkg / "curves.py").write_text("def curve(x):\n    return x * x\n")
        assert plugin_code_hash() != before
    finally:
        for name in ("giggle_pkg", "giggle_pkg.face"):
            sys.modules.pop(name, None)


def test_a_plugin_module_that_fails_to_import_names_its_line_and_the_way_back(tmp_path, monkeypatch):
    """A plugin authors' review: an installed package whose module failed to import stopped every laughlab command
    with the error alone: not the line to mend, nor that ``pip uninstall`` gives laughlab back."""
    import functools
    import importlib.metadata
    import re
    import sys
    import types

    (tmp_path / "helpers.py").write_text("import numpy\n\n\ndef window(n):\n    return numpy.linspace(0, 1, n)\n")
    (tmp_path / "zcr.py").write_text("from .helpers import window\n\nWINDOW = window(-1)\n")

    pkg = types.ModuleType("laughlab_giggle_t")
    pkg.__path__ = [str(tmp_path)]
    monkeypatch.setitem(sys.modules, "laughlab_giggle_t", pkg)
    dist = types.SimpleNamespace(metadata={"name": "laughlab-giggle"}, version="0.1.0")
    ep = types.SimpleNamespace(name="zcr_t", value="laughlab_giggle_t.zcr", dist=dist,   # as EntryPoint.load imports
                               load=functools.partial(importlib.import_module, "laughlab_giggle_t.zcr"))
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [ep] if group == "laughlab" else [])
    monkeypatch.setattr(plugins, "_loaded_entry_points", False)
    with pytest.raises(LaughlabError) as e:
        plugins.load_entry_points()
    assert str(e.value) == (
        "plugin zcr_t (laughlab_giggle_t.zcr, from laughlab-giggle 0.1.0) failed to load: ValueError: Number of "
        f"samples, -1, must be non-negative. (at {tmp_path / 'helpers.py'}, line 5); every laughlab command loads "
        "the installed plugins: mend it, or pip uninstall laughlab-giggle")
    for name in ("laughlab_giggle_t.helpers", "laughlab_giggle_t.zcr"):
        sys.modules.pop(name, None)
    (tmp_path / "zcr.py").write_text("WINDOW = [0.0] * 4\nFIRST = WINDOW[4]\n")
    monkeypatch.setattr(plugins, "_loaded_entry_points", False)
    with pytest.raises(LaughlabError, match=re.escape(f"IndexError: list index out of range (at {tmp_path / 'zcr.py'}"
                                                      ", line 2); every laughlab command")):
        plugins.load_entry_points()
    sys.modules.pop("laughlab_giggle_t.zcr", None)


def test_a_third_party_metric_that_never_applies_is_warned_with_its_exception(registered, capsys):
    """A plugin authors' review: a metric reading a misspelt column was "n/a" in every cell of the report, and
    nothing said why."""
    import types

    import pandas as pd

    from laughlab.harness.metrics import compute, metric, warn_unmeasured

    @metric("jaw_open_mean_t", None, "jawOpen weight")
    def jaw_open_mean_t(trial):
        return float(trial.channels["arkit.jawopen"].mean())   # ARKit's name is jawOpen

    registered(jaw_open_mean_t, "register_metrics")
    trial = types.SimpleNamespace(channels=pd.DataFrame({"arkit.jawOpen": [0.2, 0.4]}), run_metrics={})
    records = []
    for _ in range(3):
        why: dict = {}
        records.append({"metrics": {**compute(trial, ["jaw_open_mean_t", "frame_ms_p50"], why=why)}, "metrics_na": why})
    assert set(records[0]["metrics_na"]) == {"jaw_open_mean_t"}   # not the built-in's
    warn_unmeasured(records)
    assert capsys.readouterr().err == (
        "laughlab: warning: metric 'jaw_open_mean_t' gave no number on any of the 3 trials (n/a in the report): it "
        "raised KeyError: 'arkit.jawopen', a column the trial does not have (did you mean 'arkit.jawOpen'?)\n")
    elsewhere = types.SimpleNamespace(channels=pd.DataFrame({"smile": [0.2]}), run_metrics={})   # face=smile's
    why = {}
    compute(elsewhere, ["jaw_open_mean_t"], why=why)
    assert why == {}   # a metric of channels these trials do not write: n/a, no word
    records[1]["metrics"]["jaw_open_mean_t"] = 0.3   # it applied once: no word
    warn_unmeasured(records)
    assert capsys.readouterr().err == ""


def test_a_slow_plugin_is_named_by_the_run(registered, tmp_path):
    """A plugin author's review: a body taking 20 ms a frame showed only as "frame loop 0.82x" (and a VMC stream's
    latency grew to 420 ms, unsaid). Every 64th frame is timed stage by stage (metrics.json stage_ms); the run's
    line names the slowest stage when the stages take over half a frame."""
    import json
    import time as _time

    class Slow(laughlab.Body):
        name = "slow_body"

        def step(self, frame):
            _time.sleep(0.012)
            frame.channels.update(chest=1.0, belly=0.0)

    registered(Slow, "register_bodies")
    r = run_cli("body=slow_body", "detector=none", "input.duration_s=2.2", "~output.plots",
                f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 0, r.stderr
    stages = json.loads((tmp_path / "run" / "metrics.json").read_text())["stage_ms"]
    assert set(stages) == {"extractor rms", "detector none", "scheduler energy", "mixer", "body slow_body",
                           "face smile"}
    assert stages["body slow_body"] >= 12.0 and max(stages, key=stages.get) == "body slow_body"
    assert f"; body slow_body {stages['body slow_body']:.1f} ms a frame of 16.7) -> " in r.stdout, r.stdout


def test_the_slowest_stage_is_said_only_past_half_a_frame():
    from laughlab.core.stages import slowest

    assert slowest({"body a": 5.0, "face b": 3.0}, 60.0) == ""                     # 8.0 ms of 16.7: under half
    assert slowest({"body a": 5.0, "face b": 3.5}, 60.0) == "; body a 5.0 ms a frame of 16.7"
    assert slowest({}, 60.0) == ""


def test_a_plugin_out_of_memory_is_one_line_without_a_traceback(registered, tmp_path):
    """A MemoryError (a review: 4K video at supersample 4 beside other jobs) is the machine's limit: one line naming
    the plugin and what needs less, no traceback, not 'a bug in laughlab'; the run's folder is removed."""
    class Hungry(Face):
        name = "hungry"

        def step(self, frame):
            if frame.index == 30:
                raise MemoryError()
            GoodFace.step(self, frame)

    registered(Hungry)
    r = run_cli("face=hungry", "detector=none", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 1 and r.stderr == (
        f"laughlab: error: face 'hungry' ({__file__}, Hungry.step) at frame 30 (0.50 s) ran out of memory: the "
        "machine could not give it more; a smaller output (a video's output.video.supersample, width, height), a "
        "shorter input or fewer jobs at once needs less; the run's partial output was removed\n"), r.stderr
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())
