"""End to end through ``python -m laughlab``: the run-directory contract, reproducibility, errors."""
import contextlib
import hashlib
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import soundfile as sf
from omegaconf import OmegaConf

from inprocess import laughlab  # what a run writes and says, in this process (tests/inprocess.py)

ROOT = Path(__file__).resolve().parents[1]


def laughlab_process(*args, cwd=None):
    """A real ``python -m laughlab`` child, for what only a process shows."""
    return subprocess.run([sys.executable, "-m", "laughlab", *args], capture_output=True, text=True,
                          cwd=cwd or ROOT, timeout=300)


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "default"
    r = laughlab(f"hydra.run.dir={out}", "input.duration_s=6")   # in this process: the same bytes (tests/inprocess.py)
    assert r.returncode == 0, r.stderr
    return out


def test_run_directory_contract(default_run):
    d = default_run
    for name in ("channels.csv", "events.csv", "motion.bvh", "metrics.json", ".hydra/config.yaml",
                 "plots/fig3_2_mcs.png", "plots/fig4_2_energy.png", "truth.csv", "input.wav"):
        assert (d / name).is_file(), name
    assert not list(d.rglob("*.part"))
    ch = pd.read_csv(d / "channels.csv")
    assert ch.columns[0] == "time"
    for col in ("mcs", "chest", "belly", "smile", "jaw", "eyes_closed", "energy", "clip_energy"):
        assert col in ch.columns
    assert len(ch) == 6 * 60
    assert np.allclose(np.diff(ch.time), 1 / 60, atol=1e-6)
    assert np.isfinite(ch.drop(columns="time").to_numpy()).all()
    ev = pd.read_csv(d / "events.csv")
    assert list(ev.columns) == ["time", "event", "clip", "energy", "speed", "reason", "offset", "end"]
    assert (ev.event == "start").sum() >= 1
    m = json.loads((d / "metrics.json").read_text())
    for key in ("frame_ms_p50", "frame_ms_p99", "realtime_factor", "n_frames"):
        assert key in m
    assert m["n_frames"] == 6 * 60


def test_bvh_parses_in_an_independent_reader(default_run):
    from bvh import Bvh

    mocap = Bvh((default_run / "motion.bvh").read_text())
    assert mocap.nframes == 6 * 60                    # frames = duration x fps
    assert mocap.frame_time == pytest.approx(1 / 60, abs=1e-6)
    assert len(mocap.get_joints_names()) == 22
    assert len(mocap.frames[0]) == 69


def test_same_seed_same_bytes_other_seed_differs(default_run, tmp_path):
    again = tmp_path / "again"
    assert laughlab(f"hydra.run.dir={again}", "input.duration_s=6", "~output.plots").returncode == 0
    for name in ("channels.csv", "events.csv", "motion.bvh", "truth.csv", "input.wav"):
        assert sha(default_run / name) == sha(again / name), name
    other = tmp_path / "other"
    assert laughlab(f"hydra.run.dir={other}", "input.duration_s=6", "seed=1", "~output.plots").returncode == 0
    assert sha(default_run / "channels.csv") != sha(other / "channels.csv")


def test_file_input_matches_the_synthetic_run(default_run, tmp_path):
    """The synthetic run's audio, read back from input.wav, gives the same channels and motion."""
    r = laughlab(f"hydra.run.dir={tmp_path / 'f'}", "input=file", f"input.path={default_run / 'input.wav'}", "~output.plots")
    assert r.returncode == 0, r.stderr
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert sha(default_run / name) == sha(tmp_path / "f" / name), name


def one_line_error(r):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laughlab: error: "), r.stderr
    assert "Traceback" not in r.stderr
    return lines[0]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    (d / "text.wav").write_text("this is not audio\n")
    (d / "empty.wav").write_bytes(b"")
    sf.write(d / "zero.wav", np.zeros(0, dtype=np.float32), 16000)
    allnan = np.full(70000, np.nan, np.float32)   # past one block of the scan for a finite sample
    allnan[::3] = np.inf
    sf.write(d / "allnan.wav", allnan, 16000, subtype="FLOAT")
    return d


@pytest.mark.parametrize("args, message", [
    (["input=file", "input.path=missing.wav"], "input file not found"),
    (["input=file", "input.path=empty.wav"], "input file is empty"),
    (["input=file", "input.path=text.wav"], "cannot read audio"),
    (["input=file", "input.path=zero.wav"], "no audio samples"),
    (["input=file"], "input.path is required"),
    # a review: a file of NaN and infinities ran as a silence of its length, exit 0
    (["input=file", "input.path=allnan.wav"], "allnan.wav holds no finite samples (every one is NaN or infinite)"),
    (["extractor=nope"], "unknown extractor 'nope'; choose one of: phoneme, pressure, rms"),
    # a review: Hydra's own lines, "In 'config': Could not find 'face/'", "Multiple values for face. To override a
    # value use 'override face: facs'" and "Config group override must be a string or a list. Got NoneType"
    (["face="], "face= needs an option: choose one of: cgm, facs, smile"),
    (["+face=facs"], "write face=facs without +: face is in the defaults already"),
    (["+experiment=smoke"], "write experiment=smoke without +: experiment is in the defaults already"),
    (["face=null"], "face=null needs an option: choose one of: cgm, facs, smile"),
    (["extractor.bogus=1"], "unknown parameter extractor.bogus; valid: scale"),
    (["extractor.rise_per_s=-1"], "rise_per_s must be > 0"),
    (["fps=0"], "fps must be a positive number"),
    (["fps=-30"], "fps must be a positive number"),
    (["fps=0.5"], "fps must be 1-1000 animation frames a second (got 0.5)"),   # a review: ran, no events
    (["fps=1001"], "fps must be 1-1000 animation frames a second (got 1001)"),
    (["experiment=nope"], "unknown experiment 'nope'"),
    (["input=file", "input.path=rire_é.wav"], "a value with characters such as ( ) [ ] = , ' ~ or letters outside "
                                              "ASCII must be quoted: \"input.path='rire_é.wav'\""),
    # a review: a browser download's name "Avatar (1).vrm", "=" and "[" gave Hydra's "mismatched input ' ('
    # expecting <EOF>" without the setting; a quote was hinted inside the very quotes it ends
    (["input=file", "character=Avatar (1).vrm"], "cannot read the setting character=Avatar (1).vrm: a value with "
     "characters such as ( ) [ ] = , ' ~ or letters outside ASCII must be quoted: \"character='Avatar (1).vrm'\""),
    # a first-contact review: a home folder written ~/ (a shell expands it only at a word's start) was not named
    (["input=file", "input.path=~/laugh.wav"], "characters such as ( ) [ ] = , ' ~ or letters outside ASCII must be "
     "quoted: \"input.path='~/laugh.wav'\""),
    (["input.path=a=b.wav"], "cannot read the setting input.path=a=b.wav: a value with characters such as"),
    (["input=file", "input.path=a,b.wav"], "one value with a comma in it is quoted: \"input.path='a,b.wav'\""),
    # a plugin authors' review: the list was quoted whole (a string), which the harness then refused
    (["experiment=smoke", "+harness.conditions.mine=[face=facs,body=hill]"], "in a list, items with characters "
     "such as = ( ) or letters outside ASCII are quoted one by one: \"+harness.conditions.mine=['face=facs',"
     "'body=hill']\""),
    (["experiment=smoke", "harness.conditions={a:['face=facs']}"], "harness.conditions={a:['face=facs']} would merge "
     "into the experiment's conditions, which takes no new names: replace them with '~harness.conditions' "
     "\"+harness.conditions={a:['face=facs']}\", or add one with \"+harness.conditions.NAME=['face=facs']\""),
    (["experiment=smoke", "harness.conditions={a:[face=facs],b:[face=smile,body=hill]}"], "quoted one by one: "
     "\"harness.conditions={a:['face=facs'],b:['face=smile','body=hill']}\""),   # a diff review: a mapping
    (["seed=2", "input.path=x[1].wav"], "cannot read the setting input.path=x[1].wav: "),
    (["input.path=it's.wav"], "must be quoted: \"input.path='it\\'s.wav'\" (the double quotes for the shell)"),
    (["-m", "seed=1,2", "input.path=a (1).wav"], "cannot read the setting input.path=a (1).wav: "),
    (["output=video", "output.video.file=input.wav"], "file must be a file name ending in .mp4 (got 'input.wav')"),
    (["detekt"], "unknown command 'detekt': the commands are detect, report, corpus, study, view, plugins;"),   # was Hydra's 'Error parsing override'
    # a flag was dropped without a word and the default run started (a review: --hlep, --overwrite)
    (["--hlep"], "unknown option '--hlep': a run takes overrides key=value (python -m laughlab --help)"),
    (["-x", "face=facs"], "unknown option '-x': a run takes overrides key=value"),
    (["--overwrite"], "unknown option '--overwrite': write overwrite=true"),
    (["--seed=3"], "unknown option '--seed': write seed=N"),
    (["--character", "my.vrm"], "unknown option '--character': write character=PATH"),
    (["--out", "runs/x"], "unknown option '--out': a run's folder is hydra.run.dir=PATH (--out is an option of view"),
    (["-m", "seed=1,2", "--foo"], "unknown option '--foo'"),
    # a review: a mistyped showcase was found after every trial; seed= was recorded but changed nothing
    (["experiment=smoke", "harness.showcase=rec-laugh_x"], "harness.showcase 'rec-laugh_x' is not an input of the "
     "corpus (4 inputs: mild-s00, mild-s01, intense-s00, ...) nor a synthetic one (PROFILE-sSEED: mixed, mild, "),
    (["experiment=smoke", "harness.showcase=mild-sx"], "harness.showcase 'mild-sx' is not an input of the corpus"),
    (["experiment=smoke", "seed=5"], "seed= does not apply to an experiment: its runs' seeds are harness.corpus.seeds"),
    (["-m", "experiment=smoke", "seed=5,6"], "seed= does not apply to an experiment"),
    # output= was dropped without a word (the trials set their own); output.plots.* (the showcase runs') apply
    (["experiment=smoke", "output=[files,viewer]"], "output settings do not apply to an experiment (but "
                                                    "output.plots.*, its showcase figures'): its trials"),
    (["experiment=smoke", "output.csv.precision=4"], "output settings do not apply to an experiment"),
    # a key a condition's plugin lacks: found before any trial (a review: after the first trials; silently in a
    # parallel sweep)
    (["experiment=smoke", "scheduler.overrule_c=2"],
     "condition 'none' (scheduler=none): unknown parameter scheduler.overrule_c"),
    (["-m", "experiment=smoke", "scheduler.overrule_c=2,3"], "condition 'none' (scheduler=none): unknown parameter "),
    # the stimuli experiment's own keys, checked before anything is written (a review: tracebacks, a folder left)
    (["experiment=stimuli", "harness.preset=nope"], "unknown harness.preset 'nope'; choose one of: laughlab, riddle"),
    (["experiment=stimuli", "harness.loudness.target_lufs=loud"],
     "harness.loudness.target_lufs must be a number (dB; got 'loud')"),
    (["experiment=stimuli", "harness.participants=0"], "harness.participants must be a whole number >= 1 (got 0)"),
    # a mistyped top-level key: the nearest one (a review: 'unknown parameter sed')
    (["sed=3"], "unknown parameter sed; did you mean seed?"),
    (["facee=facs"], "unknown parameter facee; did you mean face?"),
    (["bogus=1"], "unknown parameter bogus; the settings are seed, fps, progress, overwrite, run_out, plugins_dir, character, "
                  "the groups input, extractor, face, body, scheduler, output, detector, and experiment=NAME "
                  "(python -m laughlab --help)"),
    (["experimnt=smoke"], "unknown parameter experimnt; did you mean experiment?"),   # a researcher's review
    # a sink's name given to output= (a new-user review: "'bvh' is registered as a sink" said not what to write)
    (["output=bvh"], "unknown output 'bvh'; choose one of: files, gltf, trial, video, viewer, vmc, vrma ('bvh' is a sink, "
                     "written by output=files (also gltf, video, vrma))"),
])
def test_bad_input_one_line_no_output(bad_files, args, message):
    out = bad_files / "run"
    r = laughlab(*args, f"hydra.run.dir={out}", cwd=bad_files)
    assert message in one_line_error(r)
    assert not out.exists()


def test_detect_refuses_a_file_without_a_finite_sample(bad_files):
    r = laughlab("detect", "allnan.wav", "--out", "segs", cwd=bad_files)
    assert "allnan.wav holds no finite samples" in one_line_error(r) and not (bad_files / "segs").exists()


@pytest.mark.parametrize("args, message", [
    (["scheduler.mode=fast"],
     "laughlab: error: scheduler.mode is a parameter of scheduler=concat, not of scheduler=energy: add scheduler=concat"),
    (["input.path=laugh.wav"],
     "laughlab: error: input.path is a parameter of input=file, not of input=synthetic: add input=file"),
])
def test_a_parameter_of_another_plugin_says_what_to_add(tmp_path, args, message):
    """Issue 26: the two errors that were clear but left the user stuck."""
    r = laughlab(*args, f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and r.stderr.strip() == message and r.stdout == ""
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("args, message", [
    (["+scheduler.mode=fast"], "scheduler.mode is a parameter of scheduler=concat, not of scheduler=energy: "
                               "add scheduler=concat"),       # added with +: caught by the plugin's Params
    (["scheduler=none", "scheduler.mode=fast"],                # chosen explicitly: switch, not add
     "scheduler.mode is a parameter of scheduler=concat, not of scheduler=none: use scheduler=concat instead"),
    (["input=file", "input.profile=mild"],
     "input.profile is a parameter of input=synthetic, not of input=file: use input=synthetic instead"),
    (["output.video.fps=10"], "output.video.fps is a parameter of output=video, not of output=files: add output=video"),
    (["body.preset=deep_laugh"], "body.preset is a parameter of body=hill, not of body=shapes: add body=hill"),
    # the chosen plugin has the setting one level down: named first (repro review: replaying a microphone session
    # with extractor=phoneme, the line said to switch to extractor=rms, where extractor.rms.calibration_s was meant)
    (["extractor=phoneme", "extractor.calibration_s=3"],
     "extractor.calibration_s is not a parameter of extractor=phoneme, which has extractor.rms.calibration_s; "
     "extractor.calibration_s is a parameter of extractor=rms"),
    (["mode=fast"], "there is no top-level parameter mode; scheduler=concat has scheduler.mode: "
                    "write scheduler=concat scheduler.mode=fast"),
    (["scheduler=concat", "mode=optimal"], "there is no top-level parameter mode; did you mean scheduler.mode=optimal?"),
    (["video.fps=10"], "there is no top-level parameter video.fps; output=video has output.video.fps: "
                       "write output=video output.video.fps=10"),
    (["face.bogus=1"], "unknown parameter face.bogus; valid: smile, jaw, blink_mean_s"),   # no plugin has it
    # an output's parameter without its node (was "unknown parameter output.port", no hint)
    (["output.port=9000"], "there is no parameter output.port: an output's parameters go under its name, "
                           "output.viewer.port or output.vmc.port (with output=viewer)"),
    (["output=vmc", "output.port=9000"], "there is no parameter output.port: an output's parameters go under "
                                         "its name, output.vmc.port"),
    (["output.max_seconds=5"], "there is no parameter output.max_seconds: an output's parameters go under its "
                               "name, output.plots.max_seconds"),
    (["output=[files,vmc]", "output.bogus=1"], "unknown parameter output.bogus; valid: output.arkit.livelink, "
                                               "output.arkit.precision, output.csv.precision, "
                                               "output.plots.filmstrip_frames, "
                                               "output.plots.max_seconds, output.plots.pdf, output.plots.power, "
                                               "output.plots.width, "
                                               "output.vmc.blend_case, output.vmc.character, output.vmc.host,"),
    # a nested group given one value, or failing its own check (was OmegaConf's "Merge error: str is not a
    # subclass of UnitParams" and "bad parameter in face.facs: hi must be >= 0", no AU named)
    (["face=facs", "face.au12=abc"], "bad parameter face.au12 (face=facs): it is a group of parameters (lo, hi, rise, "
                                     "fall, input), not one value (got 'abc'); set one of them, e.g. face.au12.lo=..."),
    (["face=facs", "face.au12.hi=-1"], "bad parameter in face.au12 (face=facs): hi must be >= 0 (got -1.0)"),
    (["face=facs", "face.au6.lo=0.5", "face.au6.hi=0.4"], "bad parameter in face.au6 (face=facs): hi must be > lo"),
    # a comma without brackets (was Hydra's "Ambiguous value for argument")
    (["output=gltf,video"], "output=gltf,video: several outputs are a list, write 'output=[gltf,video]'"),
    (["face=facs,smile"], "face=facs,smile gives several values: to run each, add -m"),
    (["bogus=1"], "unknown parameter bogus"),
])
def test_an_unknown_key_names_the_plugins_that_have_it(args, message):
    from laughlab.core import pipeline
    from laughlab.core.config import compose_config
    from laughlab.core.errors import LaughlabError

    with pytest.raises(LaughlabError) as err:
        cfg = compose_config(args)
        pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")]))
    assert str(err.value).startswith(message)



@pytest.mark.parametrize("args, said, list_hint", [
    # a game developer's two receivers: the line said to write output.vmc.host=[A,B], which then failed on
    # OmegaConf's "Cannot convert 'ListConfig' to string"
    (["output=vmc", "output.vmc.host=127.0.0.1,192.168.1.2"], "output.vmc.host takes one value", False),
    (["seed=1,2"], "seed takes one value", False),
    (["input=file", "input.path=a.wav,b.wav"], "input.path takes one value", False),
    (["scheduler.clips=rofl,giggle"], "for a list write 'scheduler.clips=[rofl,giggle]'", True),   # a list[str]
    (["face=facs,smile"], "for a list write 'face=[facs,smile]'", True),
])
def test_several_values_offer_a_list_only_to_a_parameter_that_takes_one(args, said, list_hint):
    from laughlab.core.config import compose_config
    from laughlab.core.errors import LaughlabError

    with pytest.raises(LaughlabError) as err:
        compose_config(args)
    text = str(err.value)
    assert "gives several values: to run each, add -m" in text and said in text
    assert ("=[" in text) == list_hint


def test_failure_during_the_run_leaves_nothing(tmp_path):
    plugdir = tmp_path / "plug"
    plugdir.mkdir()
    (plugdir / "fragile.py").write_text(
        "import laughlab\n"
        "from laughlab.core.errors import LaughlabError\n"
        "from laughlab_plugins.extractor_rms import RmsExtractor\n"
        "class Fragile(RmsExtractor):\n"
        "    name = 'fragile'\n"
        "    def step(self, block, frame):\n"
        "        if frame.index == 700:\n"
        "            raise LaughlabError('audio went away at frame 700')\n"
        "        super().step(block, frame)\n"
        "@laughlab.hookimpl\n"
        "def register_extractors(register):\n"
        "    register(Fragile)\n")
    out = tmp_path / "run"
    r = laughlab_process(f"plugins_dir={plugdir}", "extractor=fragile", f"hydra.run.dir={out}")  # its own registry
    assert "audio went away at frame 700" in one_line_error(r)
    assert not out.exists()


def test_existing_run_is_not_overwritten_without_asking(default_run, tmp_path):
    before = sha(default_run / "channels.csv")
    r = laughlab(f"hydra.run.dir={default_run}", "seed=5")
    assert "already holds a run" in one_line_error(r)
    assert sha(default_run / "channels.csv") == before
    target = tmp_path / "o"
    assert laughlab(f"hydra.run.dir={target}", "input.duration_s=2", "~output.plots").returncode == 0
    r = laughlab(f"hydra.run.dir={target}", "input.duration_s=3", "overwrite=true", "~output.plots")
    assert r.returncode == 0, r.stderr
    assert len(pd.read_csv(target / "channels.csv")) == 180


def test_plugins_has_a_help_and_refuses_other_arguments():
    """A review: 'plugins --help' and 'plugins bogus' printed the table, exit 0."""
    r = laughlab("plugins", "--help")
    assert r.returncode == 0 and r.stdout.startswith("usage: python -m laughlab plugins [plugins_dir=DIR]")
    assert "kind" not in r.stdout.split()
    r = laughlab("plugins", "bogus")
    assert one_line_error(r).endswith("plugins takes no argument but plugins_dir=DIR (got 'bogus'); see python -m "
                                      "laughlab plugins --help") and r.stdout == ""


def test_a_command_after_plugins_dir(tmp_path):
    """A plugin author's review: 'plugins_dir=D plugins' said "plugins takes no argument (got 'plugins')", and
    'plugins_dir=D report RUN' gave Hydra's "Error parsing override 'report'"."""
    r = laughlab(f"plugins_dir={tmp_path}", "plugins")
    assert r.returncode == 0 and r.stdout.split()[:4] == ["kind", "name", "origin", "use"], r.stderr
    r = laughlab(f"plugins_dir={tmp_path}", "report", "runs/x")
    assert one_line_error(r) == "laughlab: error: report is a command: it comes first"


def test_plugins_command_lists_kind_name_origin_and_how_to_use_it(tmp_path):
    r = laughlab("plugins")
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    assert lines[0].split() == ["kind", "name", "origin", "use", "with"]
    rows = {tuple(ln.split()[:2]) for ln in lines[1:]}
    for row in [("source", "synthetic"), ("extractor", "rms"), ("face", "smile"), ("body", "shapes"),
                ("scheduler", "energy"), ("sink", "bvh")]:
        assert row in rows
    # the plugin kind "source" is chosen with the group "input"; a sink through the output that has it
    use = {tuple(ln.split()[:2]): ln.split(")  ", 1)[1].strip() for ln in lines[1:]}
    assert use["source", "file"] == "input=file"
    assert use["sink", "video"] == "output=video"
    assert use["sink", "bvh"] == "output=files (also gltf, video, vrma)"
    assert use["metric", "miss_rate"] == "every experiment (harness)"
    # a preset of another name that runs the plugin (a second review: detector=yamnet_fused was not listed)
    assert use["detector", "yamnet"] == "detector=yamnet (also detector=yamnet_fused)"
    assert use["detector", "none"] == "detector=none"
    # a third-party sink no output option names: added by its own node
    (tmp_path / "mysink.py").write_text(
        "import laughlab\nfrom laughlab.core.bases import Sink\n"
        "class Mine(Sink):\n    name = 'mine'\n"
        "@laughlab.hookimpl\ndef register_sinks(register):\n    register(Mine)\n")
    r = laughlab("plugins", f"plugins_dir={tmp_path}")
    assert r.returncode == 0, r.stderr
    assert any(ln.split()[:2] == ["sink", "mine"] and ln.endswith("+output.mine={}") for ln in r.stdout.splitlines())
    # the command is 'plugins' first (or with plugins_dir= only): 'plugins' among a run's overrides is a typo of that
    # run, not the table (a review: 'face=facs plugins' printed the table and exit 0)
    r = laughlab("face=facs", "plugins", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "plugins" in r.stderr and not r.stdout
    assert not (tmp_path / "run").exists()


def test_a_successful_run_says_what_ran_how_long_and_where(tmp_path):
    out = tmp_path / "run"
    r = laughlab(f"hydra.run.dir={out}", "input.duration_s=2")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 1
    line = lines[0]
    # (the input ends mid-clip: the line says which and how to let it finish, tests/test_run_out.py)
    assert line.startswith("laughlab: 2.0 s of synthetic input (ends mid-clap_hands: run_out=true plays it out), "
                           "rms > yamnet > smile > shapes > energy, in ")
    assert "x real time" in line and f"-> {out}/: " in line
    for name in ("channels.csv", "events.csv", "motion.bvh", "plots/"):
        assert name in line and (out / name.rstrip("/")).exists()
    assert line.endswith(f"truth.csv; watch it: python -m laughlab view {out}")   # the next step (a review)


def test_progress_in_a_log_is_a_line_every_few_seconds_not_a_bar():
    import io

    from laughlab.core.progress import LogProgress

    buf = io.StringIO()
    p = LogProgress(5, "smoke", every_s=3600.0, stream=buf)
    for _ in range(5):
        p.update()
    assert buf.getvalue() == ""                              # nothing until every_s has passed
    p.close()
    assert buf.getvalue().startswith("smoke: 5/5 trials, ") and "\r" not in buf.getvalue()
    p = LogProgress(5, "smoke", every_s=0.0, stream=(buf := io.StringIO()))
    p.update()
    p.update()
    assert buf.getvalue().splitlines()[:2] == ["smoke: 1/5 trials, 0 s", "smoke: 2/5 trials, 0 s"]
    p.close()   # the same line as the last update's is not printed again (a review: detect's last line twice)
    assert buf.getvalue().splitlines() == ["smoke: 1/5 trials, 0 s", "smoke: 2/5 trials, 0 s"]


def test_help_lists_every_group_with_examples_and_docs():
    r = laughlab("--help")
    assert r.returncode == 0 and "Hydra" not in r.stdout.splitlines()[0]
    assert r.stdout.startswith("usage: python -m laughlab")
    for line in ("  face:        smile, cgm, facs", "  body:        shapes, follow, fourier, hill",
                 "  detector:    yamnet, laugh, none"):
        assert line in r.stdout
    assert "examples:" in r.stdout and "README.md" in r.stdout and "--hydra-help" in r.stdout
    # after settings too (a first-contact review: Hydra's 130-line "cli is powered by Hydra." came instead)
    for args in (["input=file", "input.path=x.wav", "--help"], ["-h", "face=facs"], ["help"]):
        again = laughlab(*args)
        assert again.returncode == 0 and again.stdout == r.stdout, args
        assert "powered by Hydra" not in again.stdout


def test_the_summary_times_the_whole_command_from_the_process_start(tmp_path):
    """Issue 26: the summary said 'in 1.7 s' for a command that took 3.4 s (it timed from the task's start,
    after start-up and composition)."""
    import re
    import time

    out = tmp_path / "run"
    t_spawn = time.monotonic()
    p = subprocess.Popen([sys.executable, "-m", "laughlab", f"hydra.run.dir={out}", "input.duration_s=4",
                          "~output.plots"],   # the figures' helper process: tests/test_fuzz.py's 10 ms run
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    line = p.stdout.readline()
    waited = time.monotonic() - t_spawn         # spawn to the summary line, as the user sees it
    rest, err = p.communicate(timeout=300)
    assert p.returncode == 0, err
    m = re.fullmatch(r"laughlab: 4\.0 s of synthetic input.*, .* in (\d+\.\d) s \((\S+)x real time; "
                     r"frame loop (\S+)x\) -> .*\n", line)
    assert m, line
    said = float(m.group(1))
    loop_s = json.loads((out / "metrics.json").read_text())["wall_s"]
    assert said >= loop_s - 0.05                       # the frame loop is part of the command
    assert waited - 0.5 <= said <= waited + 0.06, (waited, said)  # started after the spawn; 0.05: rounding
    assert float(m.group(2)) == pytest.approx(4.0 / said, rel=0.1, abs=0.01)   # printed to 2 digits


#: the speed each output group's summary states, for 30 s of audio in 3.4 s (metrics below)
SPEEDS = {
    "files": "8.8x real time; frame loop 219x",
    "gltf": "8.8x real time; frame loop 219x",
    "vrma": "8.8x real time; frame loop 219x",
    "trial": "8.8x real time; frame loop 219x",
    "video": "8.8x real time; video: 900 frames rendered at 4.5 frames/s",
    "vmc": "paced at the frame clock for the vmc stream",
    "viewer": "paced at the frame clock for the live viewer",
}


@pytest.mark.parametrize("output", sorted(p.stem for p in (ROOT / "conf" / "output").glob("*.yaml")))
def test_every_output_group_states_a_meaningful_speed(output):
    """Issue 26: output=video said 'frame loop 0x real time'.  A new output group fails here until its
    speed is stated (SPEEDS)."""
    from laughlab.cli import summary_line
    from laughlab.core.config import compose_config

    cfg = compose_config([f"output={output}"])
    metrics = {"duration_s": 30.0, "fps": 60.0, "realtime_factor": 219.4, "frame_ms_p99": 0.23}
    if output == "video":
        metrics.update(video_frames=900, video_render_fps=4.51, realtime_factor=0.149)
    line = summary_line(cfg, metrics, ROOT / "conf" / "output", 3.4)
    assert f"rms > yamnet > smile > shapes > energy, in 3.4 s ({SPEEDS[output]}) -> " in line


def test_the_closing_line_offers_view_only_for_what_view_plays(tmp_path):
    """A review: "watch it" was offered for a folder with motion.bvh but no channels.csv, which view refuses; a
    folder with a space is quoted for the shell."""
    from laughlab.core.config import compose_config
    from laughlab.core.summary import summary_line

    cfg = compose_config([])
    out = tmp_path / "my run"
    out.mkdir()
    (out / "motion.bvh").write_text("")
    assert "watch it" not in summary_line(cfg, {"duration_s": 1.0}, out, 1.0)
    for name in ("channels.csv", "events.csv"):
        (out / name).write_text("")
    assert summary_line(cfg, {"duration_s": 1.0}, out, 1.0).endswith(f"; watch it: python -m laughlab view '{out}'")


@pytest.mark.parametrize("gain, said", [(0.0, " (silent: its loudest sample is 0), "),
                                         (10 ** (-72 / 20), " (silent: its loudest sample -72 dBFS), "),
                                         # quiet but not silent: the energy it made is said (tests/test_no_clip.py)
                                         (10 ** (-50 / 20), " (no full-body clip: the laughing energy peaked at 0.0, "
                                                            "under the mildest clip's 5), ")])
def test_a_silent_file_says_so_in_the_closing_line(tmp_path, gain, said):
    """A review: a file of digital silence (or a level no method moves at, below -60 dBFS) ran as any other, its
    figures empty and nothing said.  ``input_peak`` (metrics.json) is the loudest sample read, 1 full scale."""
    t = np.arange(44100 * 2) / 44100
    x = np.sin(2 * np.pi * 300 * t) * (t < 1.5)
    x = x / np.abs(x).max() * gain
    sf.write(tmp_path / "a.wav", x.astype(np.float32), 44100, subtype="FLOAT")
    r = laughlab("input=file", f"input.path={tmp_path / 'a.wav'}", "output=[files]", "~output.plots", "detector=none",
                 f"hydra.run.dir={tmp_path / 'r'}")   # no figures: the closing line and metrics.json say it
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"laughlab: 2.0 s of a.wav{said}rms > none"), r.stdout
    peak = json.loads((tmp_path / "r" / "metrics.json").read_text())["input_peak"]
    assert peak == pytest.approx(gain, rel=1e-6)


@pytest.mark.parametrize("args, seconds, metrics, said", [
    (["input=mic"], 31.0, {"duration_s": 30.0, "fps": 60.0, "frame_ms_p99": 0.234},
     "in 31.0 s (live; compute per frame p99 0.23 ms of 16.7 ms)"),
    (["input=mic", "output=vmc"], 31.0, {"duration_s": 30.0, "fps": 30.0, "frame_ms_p99": 1.5},
     "in 31.0 s (live; compute per frame p99 1.50 ms of 33.3 ms)"),
    (["output=vmc", "output.vmc.realtime=off"], 0.8, {"duration_s": 30.0, "realtime_factor": 80.0},
     "in 0.8 s (38x real time; frame loop 80x)"),
    (["output=video"], 21.7, {"duration_s": 2.0, "realtime_factor": 0.1, "video_frames": 60,
                              "video_render_fps": 9.17}, "in 21.7 s (0.092x real time; video: 60 frames rendered at 9.2 frames/s)"),
    (["output=video"], 3.1, {"duration_s": 0.005, "realtime_factor": 0.01, "video_frames": 1,
                             "video_render_fps": 1.9}, "video: 1 frame rendered at 1.9 frames/s)"),   # not "1 frames"
    ([], 1925.0, {"duration_s": 1800.0, "realtime_factor": 716.0}, "in 32 min 05 s (0.94x real time; frame loop 716x)"),
    # the fused head says so (a review: its line read as plain yamnet's)
    (["detector=yamnet_fused"], 3.4, {"duration_s": 30.0, "realtime_factor": 219.4},
     "rms > yamnet (fused) > smile > shapes > energy, in 3.4 s"),
])
def test_the_speed_by_hand(args, seconds, metrics, said):
    from laughlab.cli import summary_line
    from laughlab.core.config import compose_config

    assert said in summary_line(compose_config(args), metrics, ROOT / "conf" / "output", seconds)


def test_a_sweep_of_experiments_prints_one_report_hint_at_its_end(tmp_path):
    """Each point of a sweep prints its own line, and the sweep one ``report:`` line for its folder (it
    used to print one per point: 36 for the README's 'small' sweep)."""
    out = laughlab("-m", "experiment=smoke", "extractor.rise_per_s=12,24", "harness.corpus.seeds=1",
              "harness.corpus.duration_s=1", "harness.corpus.profiles=[mild]", "harness.showcase=null",
              "harness.jobs=1", "harness.plots=false", "progress=off", f"hydra.sweep.dir={tmp_path / 'sweep'}")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert [line for line in lines if "report" in line] == [f"report: python -m laughlab report {tmp_path / 'sweep'}"]
    assert lines[-1].startswith("report: ")
    assert sum(line.startswith("smoke: 2 trials in ") for line in lines) == 2


@pytest.mark.parametrize("args, message", [
    (["view", "runs/demo", "--port", "70000"], "argument --port: a port is 0 to 65535 (got 70000)"),   # was a traceback
    (["study", "serve", "x", "--port", "-5"], "argument --port: a port is 0 to 65535 (got -5)"),
    (["study", "power", "x", "--contrast", "a:b", "--effect", "nan"], "argument --effect: must be a finite number"),
])
def test_out_of_range_command_options_are_one_line(tmp_path, args, message):
    r = laughlab(*args, cwd=tmp_path)
    assert r.returncode == 2 and message in r.stderr and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


@pytest.mark.parametrize("argv", [["corpus", "list"], ["plugins"], ["--info"], ["--cfg", "job"]])
def test_output_piped_into_a_reader_that_stops_ends_quietly(argv):
    """``python -m laughlab corpus list | head -1``: the reader goes away before the command writes; the command
    ends quietly (it said 'cannot write list: Broken pipe'; Hydra's ``--info`` printed 2,284 lines of logging's
    tracebacks)."""
    p = subprocess.Popen([sys.executable, "-m", "laughlab", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    p.stdout.close()   # long before the command has imported what it needs and printed
    err = p.stderr.read()
    assert p.wait(timeout=120) == 0 and err == "", err


def test_a_closed_standard_output_or_error_is_no_traceback(tmp_path):
    """``--cfg job >&-`` (stdout closed: Python's ``sys.stdout`` is None) printed three tracebacks and exit 1; what
    would have gone there goes nowhere, as ``print`` drops it, and a mistake's exit code still says it."""
    sh = f"cd {tmp_path} && {sys.executable} -m laughlab"
    shown = subprocess.run(["sh", "-c", f"{sh} --cfg job >&-; echo $?; {sh} bogus=1 2>&- ; echo $?"],
                           capture_output=True, text=True, timeout=120)
    assert shown.stdout.split() == ["0", "2"] and shown.stderr == "", shown.stderr
    # descriptor 1 itself is /dev/null's (a diff review: the next file opened took fd 1, where a child's writes went)
    probe = ("import os, sys, tempfile\nfrom laughlab.core import quiet\nquiet.closed_streams_to_devnull()\n"
             "f = tempfile.TemporaryFile()\nsys.stderr.write(str(f.fileno()) + ' ' + os.readlink('/proc/self/fd/1'))")
    import os

    held = subprocess.run([sys.executable, "-c", probe], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          timeout=60, preexec_fn=lambda: (os.close(0), os.close(1)))   # <&- >&-
    fd, where = held.stderr.split()
    assert int(fd) not in (1, 2) and where == "/dev/null", held.stderr


@pytest.mark.parametrize("args, says", [
    (["+fsp=30"], "unknown setting 'fsp': + adds a key that nothing reads"),        # a typo of fps, was ignored
    (["+foo.bar=1"], "unknown setting 'foo.bar'"),
    (["++fsp=30"], "unknown setting 'fsp'"),
    (["+fps=30"], "fps is already a setting: write fps=30 (without +)"),
    (["+output.plots.width=column"], "output.plots.width is already a setting: write output.plots.width=column (without +)"),
    (["+detector.hop_s=0.5"], "detector.hop_s is already a setting: write detector.hop_s=0.5 (without +)"),
])
def test_a_key_added_with_plus_that_nothing_reads_is_refused(tmp_path, args, says):
    from inprocess import laughlab

    r = laughlab(*args, "input.duration_s=1", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [r.stderr.strip()] and says in r.stderr
    assert not (tmp_path / "run").exists()


def test_a_group_chosen_twice_is_said_and_the_last_wins(tmp_path):
    """Hydra keeps the last choice: output=gltf was dropped without a word, and no character.glb (a new-user
    review).  The last still wins (a script's base command with a choice changed after it), now said in one line."""
    r = laughlab("output=gltf", "output=vrma", "face=facs", "face=facs", "input.duration_s=1", "~output.plots",
                 f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 0, r.stderr
    said = [ln for ln in r.stderr.splitlines() if "given twice" in ln]
    assert said == ["laughlab: output= is given twice (gltf, then vrma): vrma is used; for both outputs: "
                    "'output=[gltf,vrma]'"], r.stderr   # face=facs twice: the same choice, nothing to say
    assert (tmp_path / "run" / "animation.vrma").is_file() and not (tmp_path / "run" / "character.glb").exists()


def test_only_a_group_chosen_twice_is_said():
    """A value given twice is Hydra's rule (the last wins) that scripts use; +, ++ and ~ say what they do."""
    from laughlab.core.config import given_twice

    assert given_twice(["face=facs", "input.seed=1", "face=smile", "input.seed=2", "experiment=smoke",
                        "experiment=stimuli"]) == [
        "laughlab: face= is given twice (facs, then smile): smile is used",
        "laughlab: experiment= is given twice (smoke, then stimuli): stimuli is used"]
    assert given_twice(["~output.plots", "output.plots.width=column", "output=[gltf,vrma]", "+harness.jobs=2",
                        "harness.jobs=3", "fps=30", "fps=60", "input=file"]) == []


def test_report_on_a_stimuli_folder_points_to_the_study(tmp_path):
    """``experiment=stimuli`` writes stimuli.json, not results.json: report said "run an experiment first" of an
    experiment's folder (a new-user review).  Its report is the study's."""
    stim = tmp_path / "stimuli run"
    stim.mkdir()
    (stim / "stimuli.json").write_text("{}\n")
    r = laughlab("report", stim)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {stim} holds stimuli for a perception study, not "
                                              f"results: python -m laughlab study build '{stim}', then study serve and "
                                              "study analyze (docs/study.md)\n"), r.stderr
    assert sorted(p.name for p in stim.iterdir()) == ["stimuli.json"]


def test_a_missing_report_folder_says_not_found_and_a_short_file_its_own_length(tmp_path):
    from inprocess import laughlab

    r = laughlab("report", str(tmp_path / "nothing"))
    assert r.returncode == 2 and f"{tmp_path / 'nothing'} not found" in r.stderr
    import soundfile as sf

    sf.write(tmp_path / "short.wav", 0.1 * np.sin(np.arange(2205) * 0.05), 44100)   # 0.05 s
    r = laughlab("input=file", f"input.path={tmp_path / 'short.wav'}", f"hydra.run.dir={tmp_path / 'run'}",
                 "detector=none", "~output.plots")
    assert r.returncode == 0 and "laughlab: 0.05 s of short.wav" in r.stdout, r.stdout


def test_version_is_laughlabs():
    """--version printed Hydra's version (a review)."""
    from laughlab import __version__

    r = laughlab("--version")
    assert r.returncode == 0 and r.stdout == f"laughlab {__version__}\n" and r.stderr == ""


def test_a_single_run_records_what_made_it(tmp_path):
    """A review: an experiment's results.json names laughlab's commit and versions, a single run's folder did not
    (nor the input file's bytes).  metrics.json's provenance: the commit, the versions, the input's sha256."""
    import hashlib

    from laughlab.harness.results import git_diff_sha256, git_hash, versions

    wav = tmp_path / "in.wav"
    sf.write(wav, 0.1 * np.sin(np.arange(16000) / 7), 16000)
    r = laughlab("input=file", f"input.path={wav}", "~output.plots", f"hydra.run.dir={tmp_path / 'run'}")
    assert r.returncode == 0, r.stderr
    made = json.loads((tmp_path / "run" / "metrics.json").read_text())["provenance"]
    assert made == {"git_hash": git_hash(), "git_diff_sha256": git_diff_sha256(), "versions": versions(),
                    "input_path": str(wav.resolve()),
                    "input_sha256": hashlib.sha256(wav.read_bytes()).hexdigest()}
    r = laughlab("input.duration_s=1", "~output.plots", f"hydra.run.dir={tmp_path / 'synth'}")
    assert json.loads((tmp_path / "synth" / "metrics.json").read_text())["provenance"]["input_sha256"] is None


def test_a_run_whose_stdout_is_closed_is_kept_whole(tmp_path):
    """The plugin authors' review: ``python -m laughlab ... | true`` finished the run, then the closing line's
    broken pipe was taken for a failed write: "the run's partial output was removed", the marker went, every file
    stayed and overwrite=true refused the folder as the user's.  The run is kept, its marker written, exit 0."""
    run = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "laughlab", "detector=none", "input.duration_s=1", "output=[files]",
                          "~output.plots", f"hydra.run.dir={run}"], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    p.stdout.close()   # the reader went away before the closing line (| true, | head -0)
    err = p.stderr.read()
    assert p.wait(timeout=300) == 0 and err == "", err
    marker = json.loads((run / ".laughlab-run.json").read_text())
    assert marker["complete"] and {"channels.csv", "events.csv", "motion.bvh"} <= set(marker["files"])
    r = laughlab("detector=none", "input.duration_s=1", "output=[files]", "~output.plots",   # in this process
                 f"hydra.run.dir={run}", "overwrite=true")
    assert r.returncode == 0, r.stderr


def test_the_documented_way_to_add_a_condition_composes():
    """docs/experiments.md's form (the plugin authors' review: its earlier '[face=facs]' was refused)."""
    from laughlab.core.config import compose_config

    cfg = compose_config(["experiment=smoke", "+harness.conditions.facs=['face=facs']"])
    assert list(cfg.harness.conditions.facs) == ["face=facs"] and len(cfg.harness.conditions) >= 2
    assert "`\"+harness.conditions.facs=['face=facs']\"` adds one" in (ROOT / "docs" / "experiments.md").read_text()


def test_the_next_commands_it_prints_quote_a_folder_with_a_space(tmp_path):
    """The command lines laughlab prints for the next step (report an experiment, report a sweep, serve a viewer
    page) and the one a report records run when pasted into a shell for a folder with a space in its name (a
    review: ``report: python -m laughlab report /home/me/my runs/smoke`` split at the space)."""
    import shlex

    tiny = ("harness.corpus.seeds=1", "harness.corpus.duration_s=1", "harness.corpus.profiles=[mild]",
            "harness.showcase=null", "harness.jobs=1", "harness.plots=false", "progress=off")
    run = tmp_path / "my runs" / "smoke"
    out = laughlab("experiment=smoke", *tiny, f"hydra.run.dir='{run}'")
    assert out.returncode == 0, out.stderr
    hint = shlex.split(out.stdout.splitlines()[-1].split("; report: ")[1])
    assert hint == ["python", "-m", "laughlab", "report", str(run)]
    report = tmp_path / "my report"
    assert laughlab(*hint[3:], "--out", str(report)).returncode == 0
    generated = (report / "README.md").read_text().splitlines()[2]   # Generated by `COMMAND` from ...
    assert shlex.split(generated.split("`")[1]) == [*hint, "--out", str(report)]
    sweep = laughlab("-m", "experiment=smoke", "extractor.rise_per_s=12,24", *tiny,
                     f"hydra.sweep.dir='{tmp_path / 'my sweep'}'")
    assert sweep.returncode == 0, sweep.stderr
    assert shlex.split(sweep.stdout.splitlines()[-1]) == ["report:", *hint[:4], str(tmp_path / "my sweep")]
    single = tmp_path / "my runs" / "one"
    assert laughlab("input.duration_s=1", "detector=none", "output=[files]", f"hydra.run.dir='{single}'").returncode == 0
    page = laughlab("view", str(single), "--out", str(tmp_path / "my site"))
    assert page.returncode == 0, page.stderr
    serve = page.stdout.split("(e.g. ")[1].rsplit(")", 1)[0]
    assert shlex.split(serve) == ["python", "-m", "http.server", "-d", str(tmp_path / "my site")]


def test_a_file_fault_outside_the_runs_folder_is_not_called_a_write(tmp_path):
    """A sweep job whose input had gone from the node said 'cannot write /data/in.wav: No such file or directory'
    (the cluster review): a fault on a file outside the run's folder says 'cannot use'; one inside, or a full disk
    with no file named, 'cannot write'."""
    import errno
    from laughlab import cli

    run = tmp_path / "run"
    inside = OSError(errno.ENOSPC, "No space left on device", str(run / "motion.bvh"))
    assert cli._fault(inside, run, {}) == (f"cannot write {run / 'motion.bvh'}: No space left on device "
                                           "(the disk is full)", 2)
    gone = FileNotFoundError(errno.ENOENT, "No such file or directory", str(tmp_path / "data" / "in.wav"))
    assert cli._fault(gone, run, {}) == (f"cannot use {tmp_path / 'data' / 'in.wav'}: No such file or directory", 2)
    assert cli._fault(OSError(errno.EFBIG, "File too large"), "runs/x", {}) == \
        ("cannot write runs/x: File too large (a file size limit: ulimit -f)", 2)
    assert cli._fault(FileNotFoundError(errno.ENOENT, "No such file", "runs/x/a.csv"), "runs/x", {})[0] == \
        "cannot write runs/x/a.csv: No such file"


def test_hydra_job_chdir_runs_in_the_run_folder_with_the_paths_named_from_where_it_ran(tmp_path):
    """hydra.job.chdir=true ended every run in two lines (Hydra's, then 'cannot write outputs/...') after its files
    were written; a relative input.path was looked up in the run folder."""
    import soundfile as sf

    from laughlab.synth.laughter import SyntheticLaughter

    s = SyntheticLaughter(seed=1, duration_s=2.0, sample_rate=16000)
    sf.write(tmp_path / "laugh.wav", s.render(0, s.n_samples), 16000, subtype="FLOAT")
    a = laughlab("input=file", "input.path=laugh.wav", "detector=none", "hydra.job.chdir=true",
                 "hydra.run.dir=out", cwd=tmp_path)
    assert a.returncode == 0, a.stderr
    b = laughlab("input=file", "input.path=laugh.wav", "detector=none", "~output.plots", "hydra.run.dir=plain",
                 cwd=tmp_path)   # the files to compare with (the figures are the chdir run's)
    assert b.returncode == 0, b.stderr
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert (tmp_path / "out" / name).read_bytes() == (tmp_path / "plain" / name).read_bytes(), name
    assert not (tmp_path / "out" / "out").exists()
    r = laughlab("experiment=smoke", "hydra.job.chdir=true", "hydra.run.dir=exp", cwd=tmp_path)
    assert one_line_error(r) == ("laughlab: error: hydra.job.chdir=true does not apply to an experiment: its trials "
                                 "read their inputs from where the command runs; drop it")
    assert not (tmp_path / "exp").exists()


def test_a_sweep_over_experiments_ends_with_a_hint_report_takes(tmp_path, capsys):
    """A review: a sweep of experiment=smoke,energy_ablation ended 'report: python -m laughlab report SWEEP', which
    report refuses (two experiments); the hint now names a point's folder."""
    from omegaconf import OmegaConf

    from laughlab.sweep_hint import SweepReportHint

    sweep = tmp_path / "my sweep"
    for point, name in (("0", "smoke"), ("1", "energy_ablation"), ("2", "smoke")):
        (sweep / point).mkdir(parents=True)
        (sweep / point / "results.json").write_text(json.dumps({"experiment": name, "results": {}}))
    (sweep / "3").mkdir()
    (sweep / "3" / "results.json").write_text("{")   # damaged: report says so, the hint ignores it
    cfg = OmegaConf.create({"harness": {"module": None}, "hydra": {"sweep": {"dir": str(sweep)}}})
    SweepReportHint().on_multirun_end(cfg)
    assert capsys.readouterr().out == ("report: the sweep holds 2 experiments (energy_ablation, smoke): report each "
                                       f"point's folder, e.g. python -m laughlab report '{sweep / '0'}'\n")
    (sweep / "1" / "results.json").unlink()
    SweepReportHint().on_multirun_end(cfg)
    assert capsys.readouterr().out == f"report: python -m laughlab report '{sweep}'\n"


@pytest.mark.parametrize("args,line", [
    (["corpus"], "python -m laughlab corpus: name a command: fetch, list, lock (see --help)"),
    (["study"], "python -m laughlab study: name a command: build, serve, simulate, analyze, assignments, power (see --help)"),
    (["corpus", "fetchh"], "python -m laughlab corpus: unknown command 'fetchh': its commands are fetch, list, lock "
                           "(see --help)"),
])
def test_a_command_without_its_own_command_names_them(args, line):
    """A new-user review: ``python -m laughlab corpus`` said "the following arguments are required: cmd"."""
    r = laughlab(*args)
    assert r.returncode == 2 and r.stderr == f"laughlab: error: {line}\n"


def test_a_float_file_with_nan_and_samples_over_full_scale_is_said_in_the_summary(tmp_path):
    """A new-user review: a float WAV with NaN and samples at 4.0 ran without a word (only metrics.json counted
    them).  End to end: 100 NaN samples, and a peak of 4.0, +12.0 dBFS (20 log10 4 = 12.04)."""
    x = 0.1 * np.sin(2 * np.pi * 220 * np.arange(32000) / 16000).astype(np.float32)
    x[1000:1100] = np.nan
    x[5000:5010] = 4.0
    sf.write(tmp_path / "odd.wav", x, 16000, subtype="FLOAT")
    r = laughlab("input=file", f"input.path={tmp_path / 'odd.wav'}", f"hydra.run.dir={tmp_path / 'run'}",
                 "~output.plots", "detector=none")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("laughlab: 2.0 s of odd.wav (100 NaN or infinite samples read as silence; its loudest "
                               "sample +12.0 dBFS, over full scale), "), r.stdout
    sf.write(tmp_path / "fine.wav", x[2000:4000], 16000, subtype="FLOAT")   # neither: nothing said
    r = laughlab("input=file", f"input.path={tmp_path / 'fine.wav'}", f"hydra.run.dir={tmp_path / 'run2'}",
                 "~output.plots", "detector=none")
    assert r.stdout.startswith("laughlab: 0.12 s of fine.wav, "), r.stdout


def test_report_on_a_hill_fit_run_says_it_has_figures_of_its_own(tmp_path):
    """A new-user review: ``report runs/hill`` of an ``experiment=hill_fit`` run said "run an experiment first";
    that experiment writes hill_fit.json and plots/, not results.json (the folder as the experiment leaves it)."""
    run = tmp_path / "hill"
    (run / ".hydra").mkdir(parents=True)
    (run / ".hydra" / "overrides.yaml").write_text("- experiment=hill_fit\n- harness.compare.calls=1\n")
    (run / "plots").mkdir()
    for name in ("hill_fit.json", "metrics.json", "motion.bvh"):
        (run / name).write_text("{}\n")
    r = laughlab("report", run)
    assert r.returncode == 2 and r.stderr == (f"laughlab: error: {run} is an experiment=hill_fit run: it writes its own "
                                              "figures and numbers (hill_fit.json, metrics.json, plots/), not the "
                                              "results.json of compared conditions that report reads\n"), r.stderr
    assert not (run / "report").exists()


def test_help_names_the_installed_plugin_packages(monkeypatch):
    """A plugin author's review: --help listed a plugins_dir's plugins but not those of an installed package (the
    package is named from its metadata, without importing it; laughlab's own entry points are not a package)."""
    import importlib.metadata as md
    from types import SimpleNamespace

    from laughlab.cli_help import help_text

    eps = [SimpleNamespace(dist=SimpleNamespace(name=n)) for n in ("laughlab", "laughlab-giggle", "laughlab-giggle",
                                                                   "acme-faces")]
    monkeypatch.setattr(md, "entry_points", lambda group: eps if group == "laughlab" else [])
    assert ("  installed plugin packages: acme-faces, laughlab-giggle (their plugins: python -m laughlab plugins)"
            in help_text().splitlines())
    monkeypatch.setattr(md, "entry_points", lambda group: eps[:1])
    assert "installed plugin packages" not in help_text()


def test_a_stopped_stimuli_run_says_its_videos_are_kept(tmp_path):
    """A user-study review: an interrupted experiment=stimuli said "the finished trials are kept"; its trials are
    videos."""
    from omegaconf import OmegaConf

    from laughlab.cli import _stopped

    said = _stopped(OmegaConf.create({"harness": {"name": "stimuli"}}), tmp_path, "interrupted")
    assert said == "interrupted; the videos rendered are kept: run the same command again to resume"
    said = _stopped(OmegaConf.create({"harness": {"name": "smoke"}}), tmp_path, "interrupted")
    assert said == "interrupted; the finished trials are kept: run the same command again to resume"


@pytest.mark.parametrize("args, line", [
    (["scheduler=concat", "scheduler.gama=0.5"], "unknown parameter scheduler.gama (did you mean scheduler.gamma?); "
                                                 "valid: gamma, mode, blend_s, "),
    (["body=hill", "body.zzz=3"], "unknown parameter body.zzz; valid: control, preset, "),   # nothing near: no guess
])
def test_a_mistyped_plugin_parameter_names_the_nearest(args, line, tmp_path):
    """A researcher's review: scheduler.gama listed the valid keys but named none, where harness keys did."""
    r = laughlab(*args, f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 2 and r.stderr == f"laughlab: error: {r.stderr.split('error: ')[1]}"
    assert r.stderr.startswith(f"laughlab: error: {line}"), r.stderr
    assert not (tmp_path / "r").exists()


def test_cfg_job_with_a_mistyped_key_is_one_line_as_a_run(tmp_path):
    """A plugin author's review: ``body.bogus=1 --cfg job`` printed Hydra's five lines ("Could not override ...")
    and exit 1, where the run says it in one line with exit 2; --cfg job of good settings still prints them."""
    bad = laughlab("body=shapes", "body.bogus=1", "--cfg", "job", cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr == ("laughlab: error: unknown parameter body.bogus; valid: chest, belly, "
                                                  "chest_gain, belly_gain, chest_offset, belly_offset\n"), bad.stderr
    good = laughlab("face=facs", "~output.plots", "--cfg", "job", cwd=tmp_path)
    assert good.returncode == 0 and "name: facs" in good.stdout and "plots:" not in good.stdout, good.stderr


def test_a_command_called_in_process_leaves_the_callers_logging_and_signal_handlers(tmp_path):
    """A Python user's review: after ``cli.main([...])`` a notebook's own logger was disabled, the root logger at
    ERROR without its handlers (Hydra's ``job_logging: disabled``), and Ctrl-C worked once: the command's stop
    handlers stayed, and after the first signal they ignored every later one.  All are as the caller had them."""
    import logging
    import signal

    from laughlab import cli
    from laughlab.core import interrupts

    mine = logging.getLogger("my_analysis")
    handler = logging.StreamHandler()
    root = logging.getLogger()
    before = (root.level, list(root.handlers))
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    signals = {sig: signal.getsignal(sig) for sig in interrupts.STOP_SIGNALS}
    try:
        for args in (["input.duration_s=0.5", f"hydra.run.dir={tmp_path / 'run'}", "progress=off"],
                     ["face=facs", "--cfg", "job"], ["body.bogus=1"]):
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                try:
                    cli.main(args)
                except SystemExit:
                    pass
            assert not mine.disabled and root.level == logging.INFO and handler in root.handlers, args
            assert {sig: signal.getsignal(sig) for sig in interrupts.STOP_SIGNALS} == signals, args
    finally:
        root.removeHandler(handler)
        root.setLevel(before[0])


def test_composing_a_configuration_keeps_the_callers_own_hydra(tmp_path):
    """A Python user's review: ``with hydra.initialize(...)``, a Session, then the caller's ``compose()`` failed
    ('GlobalHydra is not initialized'): laughlab's composition cleared it."""
    from hydra import compose, initialize_config_dir

    from laughlab.core.config import compose_config

    from laughlab import cli
    from laughlab.core import callerstate, interrupts

    (tmp_path / "mine.yaml").write_text("answer: 42\n", encoding="utf-8")
    with initialize_config_dir(config_dir=str(tmp_path), version_base="1.3"):
        assert compose_config(["face=facs"]).face.name == "facs"
        assert compose("mine").answer == 42
        # a sweep from Python: hydra.main refused to start beside the caller's Hydra (the diff review)
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            cli.main(["-m", "input.duration_s=0.3", "face=smile,facs", "~output.plots",
                      f"hydra.sweep.dir={tmp_path / 'sweep'}"])
        assert len(list((tmp_path / "sweep").glob("*/motion.bvh"))) == 2, err.getvalue()
        assert compose("mine").answer == 42
    # an in-process command's Ctrl-C is not a later Session's (its feed raised it: interrupts.check)
    with callerstate.kept(in_process=True):
        interrupts.received = 2
    assert interrupts.received is None


def test_a_command_called_in_process_leaves_no_overrides_to_the_next_experiment(registered, tmp_path):
    """A clean clone's CI: after ``main([... '~output.plots' ...])`` in the same process, Hydra still held that
    job's overrides, so the next experiment run from Python repeated them in its runs (fourier_blend lost its
    Fig. 4.2).  Each way out of ``main`` (a job, ``--cfg job``, an error) leaves none."""
    from hydra.core.hydra_config import HydraConfig

    from laughlab.core.config import compose_config
    from laughlab.harness.experiment import _task_overrides
    from laughlab_experiments import fourier_blend

    for args in (("face=facs", "~output.plots", "--cfg", "job"), ("~output.plots", "input.duration_s=1",
                 f"hydra.run.dir={tmp_path / 'run'}"), ("~output.plots", "body.bogus=1")):
        laughlab(*args, cwd=tmp_path)
        assert not HydraConfig.initialized() and _task_overrides() == [], args
    cfg = compose_config(["experiment=fourier_blend", "harness.corpus.duration_s=1"])
    fourier_blend.run(cfg, tmp_path / "exp")
    assert (tmp_path / "exp" / "plots" / "fig4_2_energy.png").is_file()


def test_help_names_where_the_docs_and_configs_are_when_installed(monkeypatch):
    """A packaging review: an installed wheel's --help sent the user to README.md, docs/ and conf/, none of which
    it has; it now names the configs' installed folder, and a clone's own files by their path."""
    from laughlab import cli_help
    from laughlab.core import install
    from laughlab.core.config import conf_dir

    text = cli_help.help_text()
    assert f"docs: {install.clone_dir()}/README.md" in text and f"each {install.clone_dir()}/conf/<group>" in text
    monkeypatch.setattr(install, "clone_dir", lambda: None)
    text = cli_help.help_text()
    assert "an installed package carries neither" in text and f"each {conf_dir()}/<group>/<option>.yaml" in text


def test_progress_without_a_total_in_a_log_is_a_line_a_minute(monkeypatch):
    """A soak review: ``progress=on`` on a microphone session into a service's journal (no total, stderr not a
    terminal) drew tqdm's carriage returns onto one endless line (32 MB a day); it is a plain line a minute."""
    from laughlab.core import progress

    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    p = progress.bar(None, "laughlab", "frames", unit="frame", leave=False)
    assert isinstance(p, progress.LogProgress) and p.every_s == 60.0
    p.stream = buf = io.StringIO()
    p.update(120)
    p.close()
    assert buf.getvalue().startswith("laughlab: 120 frames, ") and "\r" not in buf.getvalue()
    assert not isinstance(progress.bar(None, "x", "trials", disable=True), progress.LogProgress)   # progress off
