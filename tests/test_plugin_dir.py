"""A plugin in a ``plugins_dir=`` folder works wherever a built-in one does (a review of writing a plugin: its
``face=NAME`` was unknown to an experiment's trial workers, to sweeps and to ``--cfg job``, though a single run
used it).  A case that starts trial workers (``harness.jobs=2``) or the sinks' helper process is a real
``python -m laughlab`` child: joblib keeps its worker processes for the next experiment, and a worker that had
loaded another test's ``gape.py`` would run that one (a module already registered is not loaded again).  The
other cases run in the test's process (tests/inprocess.py: the folder's plugins are unloaded after each)."""
import csv
import json
import subprocess
import sys

import pytest
from inprocess import laughlab

PLUGIN = '''
from dataclasses import dataclass

import laughlab
from laughlab import Face


@dataclass
class GapeParams:
    gain: float = 1.0


class Gape(Face):
    """The jaw opens in proportion to the motion control signal."""
    name = "gape"
    Params = GapeParams

    def step(self, frame):
        frame.channels["jaw"] = min(1.0, frame.control["mcs"] * self.params.gain)
        frame.channels.update(smile=0.5, blink=0.0, eyes_closed=0.0)   # the rest of a face's channels


@laughlab.hookimpl
def register_faces(register):
    register(Gape)
'''


def child(*args, cwd):
    """``python -m laughlab ARGS``, a process of its own."""
    return subprocess.run([sys.executable, "-m", "laughlab", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def test_a_plugins_dir_face_in_an_experiment_a_sweep_and_cfg_job(tmp_path):
    (tmp_path / "myplugins").mkdir()
    # the hook under a name of its own, pluggy's specname (a re-read: the hook check refused it)
    (tmp_path / "myplugins" / "gape.py").write_text(PLUGIN.replace(
        "@laughlab.hookimpl\ndef register_faces(", '@laughlab.hookimpl(specname="register_faces")\ndef my_faces('))
    assert "def my_faces(" in (tmp_path / "myplugins" / "gape.py").read_text()
    # an experiment with its trials in two worker processes, the folder given relative to the working directory
    r = child("plugins_dir=myplugins", "experiment=smoke", "face=gape", "face.gain=2", "detector=none",
              "harness.corpus.seeds=1",
              "harness.corpus.duration_s=1", "harness.corpus.profiles=[mild,intense]", "harness.jobs=2",
              "harness.showcase=null", "harness.plots=false", "hydra.run.dir=exp", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "exp" / "results.json").read_text())
    assert doc["config"]["face"] == {"name": "gape", "gain": 2.0} and doc["n_trials"] == 4
    # a sweep: each point's run used the plugin with its own gain
    r = laughlab("-m", "plugins_dir=myplugins", "face=gape", "face.gain=0.5,3", "input.duration_s=1",
                 "~output.plots", "hydra.sweep.dir=sweep", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    peaks = []
    for point in ("0", "1"):
        with open(tmp_path / "sweep" / point / "channels.csv") as f:
            peaks.append(max(float(row["jaw"]) for row in csv.DictReader(f)))
    assert 0 < peaks[0] < peaks[1] <= 1.0
    # Hydra's --cfg job composes the configuration with it
    r = laughlab("plugins_dir=myplugins", "face=gape", "--cfg", "job", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "face:\n  name: gape\n  gain: 1.0" in r.stdout


BAD = {
    # a hook name of no laughlab hook
    "typo": (PLUGIN.replace("def register_faces", "def register_face"),
             "register_face is not a laughlab hook; the hooks are register_bodies, "),
    # the hook without its marker
    "no_marker": (PLUGIN.replace("@laughlab.hookimpl\n", ""),
                  "register_faces is not marked @laughlab.hookimpl, so laughlab never calls it"),
    # the hook's argument not named as the hookspec names it
    "argument": (PLUGIN.replace("register_faces(register):\n    register(Gape)", "register_faces(reg):\n    reg(Gape)"),
                 "Argument(s) {'reg'} are declared in the hookimpl but can not be found in the hookspec"),
    # a class that could not run, refused when it registers (a review: found only when chosen, in a traceback)
    "no_step": (PLUGIN.replace("    def step(self, frame):", "    def stp(self, frame):"), "p.py) does not define step()"),
    "params": (PLUGIN.replace("@dataclass\nclass GapeParams", "class GapeParams"),
               "p.py): its Params must be a @dataclass (got 'GapeParams')"),
    "no_name": (PLUGIN.replace('    name = "gape"\n', ""), "p.py has no name: give its class name = '...', the name "),
    # a face registered as a body (the plugin authors' review: `body=gape` then ran it as the body, no chest/belly)
    "kind": (PLUGIN.replace("register_faces", "register_bodies"),
             "body plugin 'gape' (Gape, plugins dir: "),
    "kind_duck": (PLUGIN.replace("register_faces", "register_bodies").replace("class Gape(Face)", "class Gape"),
                  "unknown face 'gape'; choose one of: cgm, facs, smile ('gape' is registered as a body, plugins dir: "),
    # a plain function as a metric
    "metric": ("import laughlab\n\ndef gape_mean(trial):\n    return 0.0\n\n@laughlab.hookimpl\n"
               "def register_metrics(register):\n    register(gape_mean)\n",
               "metric 'gape_mean' from plugins dir: "),
}


def test_a_plugin_laughlab_would_never_call_is_one_line(tmp_path):
    """A review: a mistyped hook, a hook without @hookimpl and a face registered as a body each left the plugin
    unregistered with only "unknown face 'gape'"; a hook argument named otherwise was a pluggy traceback, and a
    plain function as a metric failed only after every trial had run."""
    for case, (text, message) in BAD.items():
        folder = tmp_path / case
        folder.mkdir()
        (folder / "p.py").write_text(text)
        r = laughlab(f"plugins_dir={folder}", "face=gape", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}",
                     cwd=tmp_path)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and message in r.stderr, (case, r.stderr)
        assert "Traceback" not in r.stderr and not (tmp_path / "run").exists()


def test_a_metric_that_fails_is_one_line_naming_it(tmp_path):
    """The plugin review: a metric returning None ended an experiment in a traceback that named neither the metric
    nor its plugin. (A KeyError or ValueError stays NaN: the built-in metrics use it for 'does not apply'.)"""
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "p.py").write_text(
        "import laughlab\nfrom laughlab.harness.metrics import metric\n\n@metric('jaw_none', True, 'x')\n"
        "def jaw_none(trial):\n    trial.channels['jaw'].mean()\n\n@laughlab.hookimpl\n"
        "def register_metrics(register):\n    register(jaw_none)\n")
    r = laughlab("plugins_dir=m", "experiment=smoke", "detector=none", "harness.corpus.seeds=1",
                 "harness.corpus.duration_s=1",
                 "harness.corpus.profiles=[mild]", "harness.showcase=null", "harness.plots=false", "harness.jobs=1",
                 "hydra.run.dir=exp", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("laughlab: error: metric 'jaw_none' failed: TypeError: ")
    # the folder is an unfinished experiment, not a stranger's files: a review found it refused by the next run
    assert r.stderr.strip().endswith("; the finished trials are kept: run the same command again to resume")
    r = laughlab("experiment=smoke", "detector=none", "harness.corpus.seeds=1", "harness.corpus.duration_s=1",
                 "harness.corpus.profiles=[mild]", "harness.showcase=null", "harness.plots=false", "harness.jobs=1",
                 "hydra.run.dir=exp", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "exp" / "results.json").exists(), r.stderr


def test_a_plugin_that_raises_is_named_with_its_frame_and_its_own_lines(tmp_path):
    """The plugin review: an exception in a plugin's step() was a 40-line traceback through Hydra and the command
    line, without the plugin's name or the frame.  Now: the plugin's own lines of the traceback, then one line
    naming the plugin, its file and class, the frame and its time; the run's folder removed.  In an experiment
    (trials in two worker processes) the line names the trial too, and the finished trials are kept."""
    (tmp_path / "p").mkdir()
    plugin = tmp_path / "p" / "gape.py"
    plugin.write_text(PLUGIN.replace('        frame.channels["jaw"]', '        if frame.index == 30:\n'
                                     '            raise ValueError("no jaw today")\n        frame.channels["jaw"]'))
    r = laughlab("plugins_dir=p", "face=gape", "input.duration_s=1", "hydra.run.dir=run", cwd=tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and not (tmp_path / "run").exists(), r.stderr
    assert lines[-1] == (f"laughlab: error: face 'gape' ({plugin}, Gape.step) at frame 30 (0.50 s) raised "
                         "ValueError: no jaw today (the lines above are from the plugin's code); the run's partial "
                         "output was removed")
    # the traceback starts at the plugin's step: none of laughlab's, Hydra's or pluggy's lines
    assert lines[0] == "Traceback (most recent call last):" and f'File "{plugin}", line ' in lines[1]
    assert "laughlab/" not in r.stderr.replace(str(tmp_path), "") and "hydra" not in r.stderr
    r = child("plugins_dir=p", "experiment=smoke", "face=gape", "detector=none", "harness.corpus.seeds=1",
              "harness.corpus.duration_s=1",
              "harness.corpus.profiles=[mild,intense]", "harness.jobs=2", "harness.showcase=null",
              "harness.plots=false", "hydra.run.dir=exp", cwd=tmp_path)
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 1 and "Traceback (most recent call last):" in r.stderr, r.stderr
    assert last.startswith(f"laughlab: error: face 'gape' ({plugin}, Gape.step) at frame 30 (0.50 s) in trial ")
    assert last.endswith("raised ValueError: no jaw today (the lines above are from the plugin's code); the "
                         "finished trials are kept: run the same command again to resume")
    assert not (tmp_path / "exp" / "results.json").exists()


@pytest.mark.parametrize("value, says", [
    ('"wide" if frame.index == 7 else 0.5', "channel 'jaw' is 'wide' (str) at frame 7: channel values are numbers; "),
    # None: numpy took it for NaN ("is nan ... please report it", exit 2: the plugin authors' review)
    ("None if frame.index == 20 else 0.5", "channel 'jaw' is None at frame 20: "),
])
def test_a_channel_that_is_not_a_number_is_one_line_naming_it(tmp_path, value, says):
    """The plugin review: a face writing a string into a channel failed in numpy's conversion, a traceback that
    named neither the channel nor the frame.  Exit status 1, as a plugin that raises."""
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "gape.py").write_text(PLUGIN.replace(
        'frame.channels["jaw"] = min(1.0, frame.control["mcs"] * self.params.gain)', f'frame.channels["jaw"] = {value}'))
    r = laughlab("plugins_dir=p", "face=gape", "input.duration_s=1", "hydra.run.dir=run", cwd=tmp_path)
    # the plugin named (a plugin author's review: the line said "the plugin that writes it", not which)
    assert r.returncode == 1 and r.stderr == (
        f"laughlab: error: {says}a bug in the plugin that writes it, face 'gape' (laughlab's own plugins: please "
        "report it); nothing was written\n"), r.stderr
    assert not (tmp_path / "run").exists()
    # in an experiment: the trial named, exit status 1 too (a diff review: 2, no trial)
    r = laughlab("plugins_dir=p", "experiment=smoke", "~harness.conditions", "+harness.conditions={g:['face=gape']}",
                 "harness.corpus.profiles=[mild]", "harness.corpus.seeds=1", "harness.corpus.duration_s=1",
                 "harness.jobs=1", "harness.plots=false", "progress=off", "hydra.run.dir=exp", cwd=tmp_path)
    assert r.returncode == 1 and r.stderr.startswith(f"laughlab: error: in trial g/mild-s00 seed 0, {says}a bug in "
                                                     "the plugin") and r.stderr.count("\n") == 1, r.stderr


def _code_hash(folder) -> str:
    """``plugin_code_hash()`` with ``folder``'s plugins loaded, as a process given ``plugins_dir=folder`` has it;
    they are unloaded after."""
    from laughlab.core.plugins import load_plugin_dir, pm
    from laughlab.harness.runner import plugin_code_hash

    loaded = load_plugin_dir(folder)
    try:
        return plugin_code_hash()
    finally:
        for name in loaded:
            pm.unregister(name=name)
            sys.modules.pop(name, None)


def test_a_resumed_experiment_does_not_mix_two_codes_numbers(tmp_path):
    """A review: an experiment stopped, a plugin's code changed, the same command resumed: one results.json held
    17 trials of the old code and 1 of the new.  The journal records the plugins' code (plugin_code_hash); trials
    of other code run again."""
    from laughlab.harness.runner import Journal, Trial
    from laughlab.harness.corpus import Item

    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "gape.py").write_text(PLUGIN)
    before = _code_hash(tmp_path / "p")
    (tmp_path / "p" / "gape.py").write_text(PLUGIN.replace("* self.params.gain", "* self.params.gain * 0.5"))
    after = _code_hash(tmp_path / "p")
    assert len(before.strip()) == 16 and before != after
    journal = Journal(tmp_path / "metrics.jsonl", "exp", before.strip())
    item = Item("mild-s00", ("input=synthetic",), "mild", 0)
    for cond in ("energy", "none"):
        journal.add(Trial(cond, item, 0, (), str(tmp_path / cond)), {"condition": cond, "input": item.id, "seed": 0})
    assert len(Journal(tmp_path / "metrics.jsonl", "exp", before.strip()).done()) == 2
    resumed = Journal(tmp_path / "metrics.jsonl", "exp", after.strip())
    assert resumed.done() == {} and resumed.stale == 2


def test_a_scheduler_or_body_writing_what_the_character_lacks_is_one_line(tmp_path):
    """A review: a scheduler starting a clip the library lacks, or a body offsetting a joint the skeleton lacks, ended
    in a Hydra traceback from the mixer (KeyError), the plugin unnamed."""
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "s.py").write_text(
        "import laughlab\nfrom laughlab import Body, Scheduler\nfrom laughlab.core.frame import ClipEvent\n\n"
        "class Bad(Scheduler):\n    name = 'badsched'\n\n    def step(self, frame):\n        if frame.index == 30:\n"
        "            frame.events.append(ClipEvent(frame.time_s, 'start', 'nosuchclip', 5, 1.0))\n\n"
        "class BadBody(Body):\n    name = 'badbody'\n\n    def step(self, frame):\n"
        "        frame.offsets['nosuchjoint'] = (1.0, 0.0, 0.0)\n        frame.channels['chest'] = 0.0\n"
        "        frame.channels['belly'] = 0.0\n\n@laughlab.hookimpl\ndef register_schedulers(register):\n"
        "    register(Bad)\n\n@laughlab.hookimpl\ndef register_bodies(register):\n    register(BadBody)\n")
    r = laughlab("plugins_dir=p", "scheduler=badsched", "input.duration_s=2", "hydra.run.dir=run", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.startswith(
        "laughlab: error: the scheduler started clip 'nosuchclip' at 0.50 s (frame 30), which the clip library does not "
        "hold (no clip 'nosuchclip'; have lean_front1, ") and r.stderr.count("\n") == 1
    r = laughlab("plugins_dir=p", "body=badbody", "input.duration_s=2", "hydra.run.dir=run", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.startswith(
        f"laughlab: error: body 'badbody' ({tmp_path / 'p' / 's.py'}) wrote an offset for joint 'nosuchjoint', which "
        "the skeleton does not have (its joints: hips, spine, ") and r.stderr.count("\n") == 1
    assert not (tmp_path / "run").exists()


EXPERIMENT = """# @package _global_
defaults:
  - override /extractor: phoneme

harness:
  name: gape_vs_smile
  conditions:
    smile: [face=smile, detector=none]
    gape: [face=gape, face.gain=3, detector=none]
  corpus:
    profiles: [mild]
    seeds: 2
    duration_s: 1.0
  showcase: null
  plots: false
"""


def test_an_experiment_of_ones_own_in_the_plugins_dir(tmp_path):
    """A review: one's own conditions could only be added to an experiment (``+harness.conditions.NAME=``), and
    nothing said how to write an experiment without editing laughlab's configs.  ``DIR/experiment/NAME.yaml`` is
    ``experiment=NAME`` with ``plugins_dir=DIR``, in its trial workers too, with its ``defaults`` overrides."""
    (tmp_path / "mine" / "experiment").mkdir(parents=True)
    (tmp_path / "mine" / "gape.py").write_text(PLUGIN)
    (tmp_path / "mine" / "experiment" / "gape_vs_smile.yaml").write_text(EXPERIMENT)
    r = child("plugins_dir=mine", "experiment=gape_vs_smile", "harness.jobs=2", "hydra.run.dir=exp", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "exp" / "results.json").read_text())
    assert doc["experiment"] == "gape_vs_smile" and doc["n_trials"] == 4
    assert doc["config"]["extractor"]["name"] == "phoneme"            # its defaults list applied
    # recorded as the folder's absolute path, so the report's run line and a resume hold from anywhere (a review:
    # a relative path was recorded as typed, and the same folder spelled otherwise refused the resume)
    assert doc["config"]["plugins_dir"] == str(tmp_path / "mine")
    assert f"- plugins_dir={tmp_path / 'mine'}" in (tmp_path / "exp" / ".hydra" / "overrides.yaml").read_text()
    assert doc["conditions"] == {"smile": ["face=smile", "detector=none"],
                                 "gape": ["face=gape", "face.gain=3", "detector=none"]}
    smiles = {}   # the gape face writes no smile channel: its smile onset is n/a, the smile face's a latency
    for line in (tmp_path / "exp" / "metrics.jsonl").read_text().splitlines():
        rec = json.loads(line)
        smiles.setdefault(rec["condition"], []).append(rec["metrics"]["smile_onset_latency_s"])
    assert all(v is not None and v == v for v in smiles["smile"]) and len(smiles["smile"]) == 2
    assert all(v is None or v != v for v in smiles["gape"]) and len(smiles["gape"]) == 2
    # without the folder the name is unknown, and the line says where one's own experiments go
    r = laughlab("experiment=gape_vs_smile", cwd=tmp_path)
    assert r.returncode == 2 and "plugins_dir=DIR with DIR/experiment/gape_vs_smile.yaml" in r.stderr, r.stderr
    # a built-in experiment's name, a file that is not YAML, a harness.name of another: one line naming the file,
    # when that experiment is asked for; the folder's other experiments still run (a review: one bad file stopped
    # every run with the folder)
    folder = tmp_path / "mine" / "experiment"
    (folder / "smoke.yaml").write_text(EXPERIMENT)
    (folder / "bad.yaml").write_text("harness: {conditions: [unclosed\n")
    (folder / "named.yaml").write_text(EXPERIMENT.replace("name: gape_vs_smile", "name: energy_vs_concat"))
    (folder / "dflt.yaml").write_text(EXPERIMENT.replace("/extractor: phoneme", "/extractor: nosuch").replace(
        "name: gape_vs_smile", "name: dflt"))
    for asked, said in (("smoke", "smoke.yaml: laughlab has an experiment named 'smoke'; give yours another name"),
                        ("bad", "bad.yaml: not a readable experiment: expected ',' or ']', but got '<stream end>' "
                                "(line 2, column 1)"),
                        ("named", "named.yaml: harness.name 'energy_vs_concat' is not the file's name: an "
                                  "experiment's name is its file's (named); remove harness.name or rename the file"),
                        ("dflt", "unknown extractor 'nosuch' in a defaults list (an experiment's override /extractor); "
                                 "choose one of: phoneme, pressure, rms")):
        r = laughlab("plugins_dir=mine", f"experiment={asked}", "hydra.run.dir=x", cwd=tmp_path)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and said in r.stderr, (asked, r.stderr)
        assert not (tmp_path / "x").exists()
    r = laughlab("plugins_dir=mine", "experiment=gape_vs_smile", "harness.corpus.seeds=1", "hydra.run.dir=again",
                 cwd=tmp_path)
    assert r.returncode == 0, r.stderr


def test_plugins_dir_is_one_folder(tmp_path):
    """A review: plugins_dir=a plugins_dir=b kept the last without a word (both were loaded, the trial workers got
    one), and plugins_dir=[a,b] said only that it was not a folder."""
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
    r = laughlab("plugins_dir=a", "plugins_dir=b", "input.duration_s=1", "hydra.run.dir=x", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and not (tmp_path / "x").exists()
    assert (f"plugins_dir is given 2 times (plugins_dir={tmp_path / 'a'}, plugins_dir={tmp_path / 'b'}): it is one "
            "folder") in r.stderr
    r = laughlab("plugins_dir=[a,b]", "input.duration_s=1", cwd=tmp_path)
    assert r.returncode == 2 and "is not a folder (plugins_dir is one folder: put every plugin module" in r.stderr
    # the plugin authors' review: `plugins` listed both folders' plugins, a set-up no run accepts
    r = laughlab("plugins", "plugins_dir=a", "plugins_dir=b", cwd=tmp_path)
    assert r.returncode == 2 and r.stdout == "" and r.stderr == (
        "laughlab: error: plugins_dir is given 2 times (plugins_dir=a, plugins_dir=b): it is one folder; put every "
        "plugin module and experiment/ in it\n"), r.stderr


BACKGROUND_SINK = '''
from pathlib import Path

import laughlab
from laughlab import Sink

from .zz_helpers import label   # a sibling module whose file sorts after this one


class Frames(Sink):
    """Counts the frames into frames.txt; it only writes a file, so it runs in the helper process."""
    name = "frames"
    files = ("frames.txt",)
    background = True

    def open(self, run):
        super().open(run)
        self.n = 0

    def write(self, chunk):
        self.n += len(chunk.times)

    def close(self):
        p = Path(self.run.out_dir) / "frames.txt"
        from laughlab.core import background

        p.write_text(f"{label()} {self.n} {background.IN_HELPER}\\n")
        return [p]


@laughlab.hookimpl
def register_sinks(register):
    register(Frames)
'''


def test_a_background_sink_and_a_helper_module_in_the_plugins_dir(tmp_path):
    """The plugin authors' review: a sink of the folder with ``background = True`` (as architecture.md allows)
    failed every offline run with a PicklingError traceback (the helper process could not import
    ``laughlab_local_plugins.NAME``); ``from .helpers import x`` worked only if the helper's file sorted first.
    The folder is now the package ``laughlab_local_plugins`` in both processes.  The sink ran in the helper
    process (and in the run's own with LAUGHLAB_WORKERS=0)."""
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "bgsink.py").write_text(BACKGROUND_SINK)
    (tmp_path / "p" / "zz_helpers.py").write_text("def label():\n    return 'frames'\n")
    r = child("plugins_dir=p", "detector=none", "input.duration_s=3", "hydra.run.dir=run", "+output.frames={}",
              cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run" / "frames.txt").read_text().split() == ["frames", "180", "True"]
    r = laughlab("plugins_dir=p", "detector=none", "input.duration_s=3", "hydra.run.dir=run2", "+output.frames={}",
                 "output.plots=null", cwd=tmp_path)   # in this process: LAUGHLAB_WORKERS=0
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run2" / "frames.txt").read_text().split() == ["frames", "180", "False"]


def test_a_plugin_sinks_parameter_without_plus_says_how(tmp_path):
    """The plugin authors' review: ``+output.frames={} output.frames.precision=5`` said "unknown parameter
    output.frames.precision; valid: output.plots.max_seconds" (another sink's); the sink's node exists only once
    ``+`` adds it."""
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "bgsink.py").write_text(BACKGROUND_SINK.replace("from .zz_helpers import label", "label = str"))
    r = laughlab("plugins_dir=p", "input.duration_s=1", "hydra.run.dir=run", "+output.frames={}",
                 "output.frames.precision=5", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == (
        "laughlab: error: output.frames is a plugin's sink, which has no output option: its parameters are added "
        "with +, +output.frames.precision=5 (that also adds the sink)\n"), r.stderr
    assert not (tmp_path / "run").exists()


def test_help_with_a_plugins_dir_lists_its_plugins_in_laughlabs_own_help(tmp_path):
    """The plugin authors' review: ``plugins_dir=p --help`` gave Hydra's generic 125-line help, not laughlab's."""
    (tmp_path / "p" / "experiment").mkdir(parents=True)
    (tmp_path / "p" / "gape.py").write_text(PLUGIN)
    (tmp_path / "p" / "experiment" / "mine.yaml").write_text("# @package _global_\nharness:\n  conditions:\n"
                                                             "    a: [face=gape]\n")
    r = child("plugins_dir=p", "--help", cwd=tmp_path)   # Hydra's search path is per process
    assert r.returncode == 0 and r.stdout.startswith("usage: python -m laughlab [group=option ...]"), r.stderr
    lines = r.stdout.splitlines()
    assert "  face:        smile, cgm, facs; plugins_dir: gape" in lines
    assert any(ln.startswith("  experiment:  ") and ln.endswith("; plugins_dir: mine") for ln in lines)
    assert "Hydra" not in r.stdout.split("Hydra's own flags")[0]
    r = laughlab("plugins_dir=nope", "--help", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == "laughlab: error: plugins_dir 'nope' is not a folder\n"


def test_a_face_that_writes_only_the_jaw_runs_with_one_warning(tmp_path):
    """The plugin authors' review: a face without blink or eyes_closed ran without a word (an experiment's jaw and
    blink metrics then went n/a).  A face of the jaw alone is a fair experiment: it runs, and one line says what
    stays at rest."""
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "gape.py").write_text(PLUGIN.replace("smile=0.5, blink=0.0, eyes_closed=0.0", "smile=0.5"))
    r = laughlab("plugins_dir=p", "face=gape", "detector=none", "input.duration_s=1", "~output.plots", "hydra.run.dir=run",
                 cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == (
        "laughlab: warning: face 'gape' writes no blink, eyes_closed (a face writes smile, jaw, blink, eyes_closed: "
        "docs/architecture.md); the character's blink/eyes_closed stay at rest and the metrics that read them are "
        "n/a\n"), r.stderr


def test_a_plugins_dir_with_a_space_quoted_as_hydra_asks(tmp_path):
    """``plugins_dir='my plugins'``, quoted as Hydra asks for a value with a space (and as ``hydra.run.dir=`` takes
    it), is the folder ``my plugins`` for a run, ``plugins`` and ``--help`` (a review: the quotes stayed part of
    the name, ``plugins_dir "'my plugins'" is not a folder``)."""
    (tmp_path / "my plugins").mkdir()
    (tmp_path / "my plugins" / "gape.py").write_text(PLUGIN)
    r = laughlab("plugins_dir='my plugins'", "face=gape", "input.duration_s=1", "detector=none", "output=[files]",
                 "~output.plots", "hydra.run.dir='my run'", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert " > gape > " in r.stdout and (tmp_path / "my run" / "channels.csv").exists()
    listed = laughlab("plugins", 'plugins_dir="my plugins"', cwd=tmp_path)
    assert listed.returncode == 0 and "gape" in listed.stdout, listed.stderr
    missing = laughlab("plugins_dir='no such'", cwd=tmp_path)
    assert missing.returncode == 2 and missing.stderr == "laughlab: error: plugins_dir 'no such' is not a folder\n"


def test_a_parameter_without_a_default_is_required_in_one_line(tmp_path):
    """A plugin author's review: ``gain: float`` with no default stopped every command with a TypeError traceback,
    the face's own runs with face.gain=2 too.  It is a required parameter now, as ``= MISSING`` makes one."""
    folder = tmp_path / "req"
    folder.mkdir()
    (folder / "gape.py").write_text(PLUGIN.replace("gain: float = 1.0", "gain: float\n    bias: float = 0.0"))
    r = laughlab(f"plugins_dir={folder}", "face=gape", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'a'}",
                 cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == "laughlab: error: face.gain is required: set face.gain=VALUE\n"
    assert not (tmp_path / "a").exists()
    r = laughlab(f"plugins_dir={folder}", "face=gape", "face.gain=2", "input.duration_s=1", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'b'}", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "b" / "channels.csv").is_file()


@pytest.mark.parametrize("how", ['frame.channels["energy"] = 0.3', 'frame.channels.update(energy=0.3)',
                                 'frame.channels |= {"energy": 0.3}'])
def test_a_face_writing_an_earlier_stages_channel_is_said_once(tmp_path, how, monkeypatch):
    """A plugin author's review: a face that wrote energy (or chest, mcs) replaced the scheduler's in
    channels.csv and the metrics without a word.  One warning names both writers; the face's value is kept."""
    from laughlab.core import blame

    monkeypatch.setattr(blame, "_CLASHES_SAID", set())   # said once a process: this one runs the command thrice
    folder = tmp_path / "clash"
    folder.mkdir()
    (folder / "gape.py").write_text(PLUGIN.replace(
        "frame.channels.update(smile=0.5, blink=0.0, eyes_closed=0.0)",
        f"frame.channels.update(smile=0.5, blink=0.0, eyes_closed=0.0)\n        {how}"))
    r = laughlab(f"plugins_dir={folder}", "face=gape", "input.duration_s=1", "~output.plots", "detector=none",
                 f"hydra.run.dir={tmp_path / 'r'}", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    said = [line for line in r.stderr.splitlines() if "warning" in line]
    assert said == ["laughlab: warning: face 'gape' writes energy, which scheduler 'energy' wrote on the same frame: "
                    "channels.csv, the character and the metrics keep the face's (each channel has one writer: "
                    "docs/architecture.md)"]
    with open(tmp_path / "r" / "channels.csv", newline="") as f:
        assert {row["energy"] for row in csv.DictReader(f)} == {"0.300000"}


def test_config_files_in_a_plugins_dirs_group_folders_are_said_not_read(tmp_path):
    """A plugin author's review: myplugins/body/sway.yaml (a Hydra group file) was ignored, silently."""
    (tmp_path / "p" / "body").mkdir(parents=True)
    (tmp_path / "p" / "body" / "sway.yaml").write_text("gain: 2\n")
    r = laughlab("plugins_dir=p", "detector=none", "input.duration_s=1", "hydra.run.dir=run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr.startswith(f"laughlab: warning: body/sway.yaml in plugins_dir {tmp_path / 'p'} not read: a "
                               "plugin's defaults are its Params dataclass")


def test_another_folder_or_an_edited_plugin_is_loaded_afresh_in_one_process(tmp_path):
    """A Python user's review: in one process (a notebook), an edited plugin kept its old code, and a second
    folder's ``gape.py`` ran the first folder's (modules were kept by file name); a face only the first folder had
    stayed registered for the second."""
    import os

    from laughlab.core import plugins

    def folder(name, gain, extra=False):
        d = tmp_path / name
        d.mkdir(exist_ok=True)
        (d / "gape.py").write_text(PLUGIN.replace("gain: float = 1.0", f"gain: float = {gain}"), encoding="utf-8")
        if extra:
            (d / "grin.py").write_text(PLUGIN.replace('"gape"', '"grin"').replace("class Gape(Face)", "class Grin(Face)")
                                       .replace("register(Gape)", "register(Grin)"), encoding="utf-8")
        return d

    def gain():
        return plugins.registry()["face"]["gape"].obj.Params().gain

    a = folder("a", 2.0, extra=True)
    plugins.load_plugin_dir(a)
    assert gain() == 2.0 and "grin" in plugins.registry()["face"]
    plugins.load_plugin_dir(a)                      # the same folder, unchanged: the same classes
    assert gain() == 2.0
    plugins.load_plugin_dir(folder("b", 3.0))       # another folder with a gape.py of its own
    assert gain() == 3.0 and "grin" not in plugins.registry()["face"]
    from laughlab.core import own_experiments
    from laughlab.core.config import load_plugin_dirs

    (a / "experiment").mkdir()
    (a / "experiment" / "gape_vs_smile.yaml").write_text(EXPERIMENT, encoding="utf-8")
    load_plugin_dirs([f"plugins_dir={a}"])
    assert "gape_vs_smile" in own_experiments.LOCAL
    load_plugin_dirs([f"plugins_dir={tmp_path / 'b'}"])   # the earlier folder's experiments go with its plugins
    assert "gape_vs_smile" not in own_experiments.LOCAL and gain() == 3.0
    b = folder("b", 4.0)                            # edited (a later modification time, as an editor saves it)
    st = (b / "gape.py").stat()
    os.utime(b / "gape.py", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    plugins.load_plugin_dir(b)
    assert gain() == 4.0
