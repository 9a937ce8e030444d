"""One writer per run directory (issue 14, item 1): the lock, the marker, overwrite that keeps the user's files."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from inprocess import laughlab as run  # what a run writes and says, in this process (tests/inprocess.py)
from laughlab.core import rundir
from laughlab.core.errors import LaughlabError
from laughlab.harness.runner import journal_records


def _as_from_a_terminal():
    """Ctrl-C as a terminal delivers it: a shell running the tests in the background (CI, ``make test &``)
    hands its children SIGINT ignored, and a run then rightly keeps ignoring it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


#: the run folder is the subject here, not the figures: runs that do not need them skip drawing them
NO_PLOTS = ("~output.plots",)


def laughlab(*args, **kw):
    """A real ``python -m laughlab`` child: for two processes at once, signals and kills."""
    return subprocess.Popen([sys.executable, "-m", "laughlab", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_as_from_a_terminal, **kw)


def _started(d, settle_s=0.5):
    """Wait until a run's child has written its .hydra/ into ``d``, then a little longer (it is in its frames)."""
    deadline = time.time() + 60
    while not (d / ".hydra").exists() and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(settle_s)


def test_two_runs_into_one_directory_one_wins_and_the_other_says_why(tmp_path):
    d = tmp_path / "D"
    # 90 s of input: the winner must still hold the folder when the loser, started with it, gets there (20 s
    # took 1-2 s on a faster machine, and a loser slowed by the other test workers found a finished run)
    runs = {seed: laughlab("input.duration_s=90", f"hydra.run.dir={d}", f"seed={seed}", *NO_PLOTS) for seed in (0, 5)}
    out = {seed: (p.wait(timeout=300), p.stdout.read(), p.stderr.read()) for seed, p in runs.items()}
    codes = sorted(code for code, _, _ in out.values())
    assert codes == [0, 2], out
    winner = next(s for s, (code, _, _) in out.items() if code == 0)
    loser_err = next(err for code, _, err in out.values() if code == 2)
    assert loser_err.count("\n") == 1 and "in use by another laughlab run (pid " in loser_err and str(d) in loser_err
    # every file is the winner's: its seed in metrics and overrides, its channels as a run of its own
    assert json.loads((d / "metrics.json").read_text())["seed"] == winner
    assert f"seed={winner}" in (d / ".hydra" / "overrides.yaml").read_text()
    ref = tmp_path / "ref"
    assert run("input.duration_s=90", f"hydra.run.dir={ref}", f"seed={winner}", *NO_PLOTS).returncode == 0
    for name in ("channels.csv", "events.csv", "motion.bvh", "truth.csv", "input.wav"):
        assert (d / name).read_bytes() == (ref / name).read_bytes(), name


def test_a_folder_of_the_users_files_is_refused_and_overwrite_keeps_them(tmp_path):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "notes.txt").write_text("my notes")
    p = run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS)
    assert p.returncode == 2 and "not empty and not a laughlab run (notes.txt)" in p.stderr
    assert sorted(x.name for x in d.iterdir()) == ["notes.txt"]   # the refusal left no lock file behind
    r = run("input.duration_s=2", f"hydra.run.dir={d}", "overwrite=true", "output=gltf", *NO_PLOTS)
    assert r.returncode == 0 and "notes.txt" not in r.stdout     # the summary lists the run's files, not the user's
    assert (d / "character.glb").exists() and (d / "notes.txt").read_text() == "my notes"
    marker = json.loads((d / rundir.MARKER).read_text())
    assert marker["complete"] and "character.glb" in marker["files"] and "notes.txt" not in marker["files"]
    # overwriting that run removes its files the new run does not write, never the user's
    assert run("input.duration_s=2", f"hydra.run.dir={d}", "overwrite=true", *NO_PLOTS).returncode == 0
    assert not (d / "character.glb").exists() and (d / "notes.txt").read_text() == "my notes"
    p = run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS)
    assert p.returncode == 2 and "already holds a run" in p.stderr


@pytest.mark.parametrize("mine", ["motion.bvh", "video.mp4"])
def test_a_file_of_the_users_by_an_outputs_name_is_never_replaced(tmp_path, mine):
    """Neither in a folder of the user's (no marker) nor beside a finished run, even with overwrite=true: one line
    naming it, the file's bytes kept."""
    d = tmp_path / "mine"
    d.mkdir()
    if mine == "video.mp4":                                   # beside a finished run that wrote no video
        assert run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS).returncode == 0
    (d / mine).write_text("my own")
    for extra in ([], ["overwrite=true"], ["overwrite=true", "output=video"]):
        p = run("input.duration_s=2", f"hydra.run.dir={d}", *extra, *NO_PLOTS)
        if mine == "video.mp4" and not extra:
            assert p.returncode == 2 and "already holds a run" in p.stderr
            continue
        assert p.returncode == 2 and p.stderr.strip().splitlines() == [p.stderr.strip()]
        assert f"files by the names of a run's outputs that no laughlab run recorded writing ({mine})" in p.stderr
        assert (d / mine).read_text() == "my own"


def test_another_hydra_applications_configuration_is_never_replaced(tmp_path):
    """A review: overwrite=true into another Hydra application's output folder replaced its .hydra/config.yaml
    (the refusal said "files laughlab did not write are kept").  A laughlab run's own .hydra is replaced as before."""
    d = tmp_path / "theirs"
    (d / ".hydra").mkdir(parents=True)
    (d / ".hydra" / "config.yaml").write_text("other_app: 1\n")
    for extra in ([], ["overwrite=true"]):
        p = run("input.duration_s=2", f"hydra.run.dir={d}", *extra, *NO_PLOTS)
        assert p.returncode == 2 and "no laughlab run recorded writing (.hydra)" in p.stderr
        assert (d / ".hydra" / "config.yaml").read_text() == "other_app: 1\n" and sorted(os.listdir(d)) == [".hydra"]
    ours = tmp_path / "ours"
    for seed in (1, 2):
        assert run(f"seed={seed}", "input.duration_s=2", f"hydra.run.dir={ours}", "overwrite=true",
                   *NO_PLOTS).returncode == 0
    assert "seed: 2" in (ours / ".hydra" / "config.yaml").read_text()


def test_the_names_a_sink_declares_or_is_given_are_protected_too(tmp_path):
    """The protected names come from the sinks (their ``files``, ``output.video.file``), not a list kept by hand:
    a third-party sink's file and a video named by the user are kept like motion.bvh."""
    from laughlab.core.config import compose_config
    from laughlab.core.pipeline import planned_files

    names = planned_files(compose_config(["output=video", "output.video.file=take1.mp4"]))
    assert {"motion.bvh", "channels.csv", "events.csv", "face_arkit.csv", "plots", "character.glb",
            "animation.vrma", "video.mp4", "take1.mp4"} <= names
    d = tmp_path / "mine"
    d.mkdir()
    (d / "take1.mp4").write_text("my take")
    p = run("input.duration_s=1", f"hydra.run.dir={d}", "overwrite=true", "output=video", "output.video.file=take1.mp4",
            *NO_PLOTS)
    assert p.returncode == 2 and "recorded writing (take1.mp4)" in p.stderr
    assert (d / "take1.mp4").read_text() == "my take"
    plug = tmp_path / "plug"
    plug.mkdir()
    (plug / "jsonsink.py").write_text(
        "import laughlab\nfrom laughlab.core.bases import Sink\n"
        "class Json(Sink):\n    name = 'json'\n    files = ('frames.json',)\n"
        "@laughlab.hookimpl\ndef register_sinks(register):\n    register(Json)\n")
    (d / "frames.json").write_text("{}")
    p = run("input.duration_s=1", f"hydra.run.dir={d}", "overwrite=true", f"plugins_dir={plug}", "+output.json={}",
            *NO_PLOTS)
    assert p.returncode == 2 and "recorded writing (frames.json)" in p.stderr   # take1.mp4: not this run's name
    assert (d / "frames.json").read_text() == "{}"


def test_a_crashed_run_leaves_no_stale_lock(tmp_path):
    d = tmp_path / "D"
    code = ("import sys, time\nfrom laughlab.core import rundir\nrundir.claim(sys.argv[1])\n"
            "print('held', flush=True)\ntime.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code, str(d)], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "held"
    with pytest.raises(LaughlabError, match=f"pid {p.pid}"):
        rundir.claim(d, overwrite=True)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    c = rundir.claim(d, overwrite=True)  # the OS released the dead process' lock
    c.release()


def test_a_failed_run_leaves_no_folder_behind(tmp_path):
    d = tmp_path / "new"
    assert run("input=file", f"input.path={tmp_path / 'missing.wav'}", f"hydra.run.dir={d}").returncode == 2
    assert not d.exists()


def test_interrupting_a_run_leaves_no_visible_partial_file(tmp_path):
    d = tmp_path / "D"
    p = laughlab("input.duration_s=1800", f"hydra.run.dir={d}", start_new_session=True)
    _started(d)
    os.killpg(p.pid, signal.SIGINT)
    assert p.wait(timeout=60) == 130
    visible = [x.name for x in d.iterdir() if not x.name.startswith(".")] if d.exists() else []
    assert visible == []  # the sinks removed what they had staged; the folder went with them
    assert run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS).returncode == 0  # the next run works


def test_sigterm_to_a_run_leaves_no_visible_partial_file(tmp_path):
    d = tmp_path / "D"
    p = laughlab("input.duration_s=1800", f"hydra.run.dir={d}")
    _started(d)
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=60) == 130
    visible = [x.name for x in d.iterdir() if not x.name.startswith(".")] if d.exists() else []
    assert visible == []
    assert run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS).returncode == 0


#: 8 short trials, no figures: the run folder's life is the subject
SMOKE = ["experiment=smoke", "harness.jobs=1", "harness.showcase=null", "progress=off", "harness.corpus.seeds=2",
         "harness.corpus.duration_s=4", "harness.plots=false"]


def _results_without_timings(path):
    doc = json.loads(path.read_text())
    return {c: {m: v for m, v in ms.items() if not m.startswith(("frame_ms", "realtime"))}
            for c, ms in doc["results"].items()}, doc["n_trials"]


def test_an_experiment_killed_after_some_trials_resumes_to_the_same_results(tmp_path):
    d, ref = tmp_path / "killed", tmp_path / "whole"
    p = laughlab(*SMOKE, f"hydra.run.dir={d}")
    journal = d / "metrics.jsonl"
    deadline = time.time() + 120
    while len(journal_records(journal)) < 3:
        assert time.time() < deadline and p.poll() is None, "the experiment did not journal its trials"
        time.sleep(0.05)
    p.kill()
    p.wait()
    done = len(journal_records(journal))  # a line the kill cut is not a trial done
    assert 3 <= done < 8
    # how the rest is run (in parallel, with the figure) is not what the experiment is: it still resumes
    again = run(*SMOKE, "harness.jobs=2", "harness.plots=true", f"hydra.run.dir={d}")
    assert again.returncode == 0, again.stderr
    assert f"resuming: {done} of 8 trials were done, running {8 - done}" in again.stderr
    assert run(*SMOKE, f"hydra.run.dir={ref}").returncode == 0
    assert (d / "plots" / "metrics.png").exists() and not (ref / "plots").exists()
    assert _results_without_timings(d / "results.json") == _results_without_timings(ref / "results.json")
    leftovers = list((d / "trials").glob("**/*")) if (d / "trials").exists() else []
    assert leftovers == []  # the killed trial's half-written folder went with the rerun


def _experiment_with_a_trial_in(d):
    """The smoke experiment started into ``d`` in a child process, once its first trial is journaled."""
    p = laughlab(*SMOKE, f"hydra.run.dir={d}")
    journal = d / "metrics.jsonl"
    deadline = time.time() + 120
    while not (journal.exists() and journal.read_text().strip()):
        assert time.time() < deadline and p.poll() is None
        time.sleep(0.05)
    return p


def test_a_changed_config_does_not_mix_into_an_interrupted_experiment(tmp_path):
    d = tmp_path / "D"
    journal = d / "metrics.jsonl"
    p = _experiment_with_a_trial_in(d)
    p.kill()
    p.wait()
    other = run(*SMOKE, "harness.corpus.duration_s=7", f"hydra.run.dir={d}")
    assert other.returncode == 2 and other.stderr.count("\n") == 1
    assert "interrupted experiment with another configuration" in other.stderr
    # a refusal, not a stop: no "run the same command again to resume" after it (a review: it contradicted itself)
    assert other.stderr.rstrip().endswith("or add overwrite=true") and "to resume" not in other.stderr
    # the refusal leaves the interrupted experiment to its own command, as it says (a review: it removed the
    # folder's marker, and the own command was then refused, "files ... no laughlab run recorded writing")
    done = len(journal_records(journal))
    again = run(*SMOKE, f"hydra.run.dir={d}")
    assert again.returncode == 0, again.stderr
    assert (d / "results.json").exists() and (not done or f"resuming: {done} of 8 trials were done" in again.stderr)


def _interrupted_experiment(d):
    """An experiment stopped by Ctrl-C once its first trial is in: kept for its command to resume."""
    p = _experiment_with_a_trial_in(d)
    p.send_signal(signal.SIGINT)
    assert p.wait(timeout=120) == 130


@pytest.mark.parametrize("then", ["overwrite", pytest.param("resume, then overwrite", marks=pytest.mark.slow)])
def test_a_file_put_into_an_interrupted_experiment_stays_the_users(tmp_path, then):
    """A first-contact review: notes.txt put into an experiment's folder after a Ctrl-C was counted as the run's (an
    interrupted run's files were every entry but the user's), so overwrite=true deleted it, and a resumed run's end
    listed it among its files for a later overwrite=true to delete.  A kept experiment records its files."""
    d = tmp_path / "D"
    _interrupted_experiment(d)
    (d / "notes.txt").write_text("my notes")
    if then.startswith("resume"):
        assert run(*SMOKE, f"hydra.run.dir={d}").returncode == 0
        assert "notes.txt" not in json.loads((d / rundir.MARKER).read_text())["files"]
    again = run(*SMOKE, f"hydra.run.dir={d}", "overwrite=true")
    assert again.returncode == 0, again.stderr
    assert (d / "notes.txt").read_text() == "my notes" and (d / "results.json").exists()


def test_a_sweep_run_again_skips_its_finished_jobs_and_runs_the_rest(tmp_path):
    d = tmp_path / "sweep"
    args = ["-m", "seed=0,1", "input.duration_s=1", f"hydra.sweep.dir={d}", *NO_PLOTS]
    assert run(*args).returncode == 0
    before = (d / "0" / "channels.csv").read_bytes()
    import shutil

    shutil.rmtree(d / "1")  # as if the sweep had been stopped before its second job
    again = run(*args)
    assert again.returncode == 0, again.stderr
    out = again.stdout
    assert out.count("already holds this job's finished run; skipped") == 1 and f"{d / '1'}/:" in out
    assert (d / "0" / "channels.csv").read_bytes() == before and (d / "1" / "channels.csv").exists()
    hydra = {f.name: f.read_text() for f in (d / "0" / ".hydra").glob("*.yaml")}
    assert "input.duration_s=1" in hydra["overrides.yaml"]
    root = (d / "multirun.yaml").read_bytes()
    changed = run("-m", "seed=0,1", "input.duration_s=2", f"hydra.sweep.dir={d}")
    # refused before any job: the folder's multirun.yaml is a sweep of other settings (sweepcheck.check_sweep_folder)
    assert changed.returncode == 2 and "holds a sweep of other settings (input.duration_s=2 (there: 1)" in \
        changed.stderr, changed.stderr
    assert (d / "multirun.yaml").read_bytes() == root
    assert {f.name: f.read_text() for f in (d / "0" / ".hydra").glob("*.yaml")} == hydra
    # behind that check, each job's own: a folder whose multirun.yaml names this sweep while its points hold runs
    # of other settings (a point run over by hand) refuses job by job, and leaves the folder as it was
    import yaml

    doc = yaml.safe_load(root)
    doc["hydra"]["overrides"]["task"] = ["seed=0,1", "input.duration_s=2"]
    (d / "multirun.yaml").write_text(yaml.safe_dump(doc))
    root = (d / "multirun.yaml").read_bytes()
    changed = run("-m", "seed=0,1", "input.duration_s=2", f"hydra.sweep.dir={d}")
    assert changed.returncode != 0 and "already holds a run; choose another hydra.sweep.dir" in changed.stderr
    assert (d / "multirun.yaml").read_bytes() == root   # Hydra rewrote it for the refused sweep; put back
    # found by a new-user review: the refusal deleted the finished job's .hydra/ (Hydra had already written the
    # new job's over it); it is put back, so the folder still describes its results
    assert {f.name: f.read_text() for f in (d / "0" / ".hydra").glob("*.yaml")} == hydra
    assert (d / "0" / "channels.csv").read_bytes() == before
    # found by a second review: with the joblib launcher the jobs run at once, and a job stopped when another was
    # refused had already had this sweep's .hydra/ written over its finished point (report then showed the
    # point's results under a value never run). Every point where no run finished gets its own .hydra/ back
    one = {f.name: f.read_text() for f in (d / "1" / ".hydra").glob("*.yaml")}
    (d / "1" / ".hydra" / "overrides.yaml").write_text("- seed=1\n- input.duration_s=2\n")   # as the stopped job left it
    changed = run("-m", "seed=0,1", "input.duration_s=2", f"hydra.sweep.dir={d}")
    assert changed.returncode != 0
    assert {f.name: f.read_text() for f in (d / "1" / ".hydra").glob("*.yaml")} == one


def _tree(d):
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*"))
            if p.is_file() and p.name != rundir.LOCK}


def test_overwrite_puts_the_earlier_run_back_when_the_new_one_is_stopped(tmp_path):
    """overwrite=true deleted the earlier run before the new one started, so a Ctrl-C lost both.  Now the
    earlier run waits aside and comes back byte for byte (its marker too: the folder is still a finished run)."""
    d = tmp_path / "D"
    assert run("input.duration_s=2", f"hydra.run.dir={d}", "output=gltf", *NO_PLOTS).returncode == 0
    (d / "notes.txt").write_text("mine")
    before = _tree(d)
    p = laughlab("input.duration_s=1800", f"hydra.run.dir={d}", "overwrite=true", start_new_session=True)
    deadline = time.time() + 60
    while not (d / rundir.PREVIOUS).exists() and time.time() < deadline:
        time.sleep(0.05)
    assert (d / rundir.PREVIOUS / "character.glb").exists()   # aside while the new run runs
    time.sleep(1.0)
    os.killpg(p.pid, signal.SIGINT)
    assert p.wait(timeout=60) == 130
    assert _tree(d) == before and not (d / rundir.PREVIOUS).exists()
    p = run("input.duration_s=2", f"hydra.run.dir={d}", *NO_PLOTS)
    assert p.returncode == 2 and "already holds a run" in p.stderr
    # a new run that finishes replaces it and leaves nothing aside
    assert run("input.duration_s=1", f"hydra.run.dir={d}", "overwrite=true", *NO_PLOTS).returncode == 0
    assert not (d / rundir.PREVIOUS).exists() and not (d / "character.glb").exists()
    assert (d / "notes.txt").read_text() == "mine"


def test_overwrite_puts_the_earlier_run_back_after_a_crash_or_a_kill(tmp_path):
    """Found by a new-user review: a run that crashed (a bug's traceback) or was killed (SIGKILL) during
    overwrite=true left the earlier run in .laughlab-previous/, and the next run deleted it.  A crash now puts it
    back at once; after a kill, the next run puts it back first (and, without overwrite=true, is refused)."""
    d = tmp_path / "D"
    assert run("input.duration_s=2", f"hydra.run.dir={d}", "output=gltf", *NO_PLOTS).returncode == 0
    before = _tree(d)
    plug = tmp_path / "plug"
    plug.mkdir()
    (plug / "buggy.py").write_text(
        "import laughlab\nfrom laughlab.core.bases import Sink\n"
        "class Buggy(Sink):\n    name = 'buggy'\n    def write(self, chunk):\n        raise ValueError('a bug')\n"
        "@laughlab.hookimpl\ndef register_sinks(register):\n    register(Buggy)\n")
    p = run("input.duration_s=2", f"hydra.run.dir={d}", "overwrite=true", f"plugins_dir={plug}", "+output.buggy={}",
            *NO_PLOTS)
    assert p.returncode != 0 and "ValueError: a bug" in p.stderr
    assert _tree(d) == before and not (d / rundir.PREVIOUS).exists()
    p = laughlab("input.duration_s=1800", f"hydra.run.dir={d}", "overwrite=true", "output=video")
    deadline = time.time() + 60
    while not list(d.glob(".*.part")) and time.time() < deadline:
        time.sleep(0.05)
    p.kill()
    p.wait()
    assert (d / rundir.PREVIOUS).is_dir()
    again = run("input.duration_s=1", f"hydra.run.dir={d}", *NO_PLOTS)
    assert again.returncode == 2 and "already holds a run" in again.stderr, again.stderr
    assert _tree(d) == before and not (d / rundir.PREVIOUS).exists()


@pytest.mark.parametrize("background", [True, False], ids=["in-the-helper", "in-process"])
def test_a_sink_that_fails_as_it_closes_leaves_no_half_written_run(tmp_path, background):
    """Found by a new-user review: a sink whose close raised (an avatar with a zero scale, in the gltf sink) left
    channels.csv, events.csv, motion.bvh, plots/ and the lock of the sinks that had closed before it, which the
    next run refused as files no run recorded writing.  Their files now go too, in the helper process or not."""
    plug = tmp_path / "plug"
    plug.mkdir()
    (plug / "late_bug.py").write_text(
        "import laughlab\nfrom laughlab.core.bases import Sink\n"
        f"class LateBug(Sink):\n    name = 'late_bug'\n    background = {background}\n"
        "    def write(self, chunk):\n        pass\n"
        "    def close(self):\n        raise ValueError('a bug as it closes')\n"
        "@laughlab.hookimpl\ndef register_sinks(register):\n    register(LateBug)\n")
    d = tmp_path / "D"
    p = run("input.duration_s=2", f"hydra.run.dir={d}", f"plugins_dir={plug}", "+output.late_bug={}")
    assert p.returncode != 0 and "ValueError: a bug as it closes" in p.stderr
    assert not d.exists(), sorted(x.name for x in d.iterdir())


def test_overwrite_refuses_an_input_that_is_a_file_of_the_run_it_replaces(tmp_path):
    """Found by a new-user review: input.path=D/input.wav with overwrite=true into D said "input file not found"
    (the earlier run, its input.wav with it, had been moved aside).  It is refused in one line; D is kept."""
    d = tmp_path / "D"
    assert run("input.duration_s=1", f"hydra.run.dir={d}", *NO_PLOTS).returncode == 0
    before = _tree(d)
    p = run("input=file", f"input.path={d / 'input.wav'}", f"hydra.run.dir={d}", "overwrite=true", *NO_PLOTS)
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [p.stderr.strip()], p.stderr
    assert "is a file of the earlier run" in p.stderr and "copy it out" in p.stderr
    assert _tree(d) == before
    (tmp_path / "mine.wav").write_bytes((d / "input.wav").read_bytes())   # a copy outside: replaced as asked
    assert run("input=file", f"input.path={tmp_path / 'mine.wav'}", f"hydra.run.dir={d}", "overwrite=true",
               *NO_PLOTS).returncode == 0


def test_an_interrupted_overwrite_of_an_experiment_resumes_by_the_same_command(tmp_path):
    d = tmp_path / "D"
    assert run(*SMOKE, "harness.corpus.duration_s=3", f"hydra.run.dir={d}").returncode == 0
    # long enough to be killed part way; on a fast machine whose test process was kept off the cores for a moment
    # the 8 trials of 30 s all ended before the kill (a run of the suite): then again with longer trials
    for seconds in (30, 120):
        longer = [*SMOKE, f"harness.corpus.duration_s={seconds}", "overwrite=true"]
        p = laughlab(*longer, f"hydra.run.dir={d}")
        journal = d / "metrics.jsonl"
        deadline = time.time() + 120
        while not (d / rundir.PREVIOUS).exists():   # the finished run's journal goes aside first
            assert time.time() < deadline and p.poll() is None
            time.sleep(0.02)
        while len(journal_records(journal)) < 2:
            assert time.time() < deadline and p.poll() is None
            time.sleep(0.05)
        p.kill()
        p.wait()
        done = len(journal_records(journal))
        if done < 8:
            break
    assert 2 <= done < 8
    again = run(*longer, f"hydra.run.dir={d}")
    assert again.returncode == 0, again.stderr
    assert f"resuming: {done} of 8 trials were done" in again.stderr and not (d / rundir.PREVIOUS).exists()


def test_a_stopped_run_leaves_a_folder_of_the_users_files_as_it_was(tmp_path):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    p = laughlab("input.duration_s=1800", f"hydra.run.dir={d}", "overwrite=true")
    _started(d)
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=60) == 130
    assert sorted(x.name for x in d.iterdir()) == ["notes.txt"]   # its .laughlab.lock stayed


def test_overwrite_of_an_interrupted_experiment_starts_it_over(tmp_path):
    """An interrupted experiment's own files (its journal) were taken for the user's by overwrite=true, which
    then refused the folder; they are the run's, and go."""
    d = tmp_path / "D"
    p = laughlab(*SMOKE, f"hydra.run.dir={d}")
    journal = d / "metrics.jsonl"
    deadline = time.time() + 120
    while len(journal_records(journal)) < 2:
        assert time.time() < deadline and p.poll() is None
        time.sleep(0.05)
    p.kill()
    p.wait()
    again = run(*SMOKE, "harness.corpus.duration_s=3", "overwrite=true", f"hydra.run.dir={d}")
    assert again.returncode == 0, again.stderr
    assert "resuming" not in again.stderr and len(journal_records(journal)) == 8


def test_a_sweep_job_refused_by_a_running_job_leaves_its_hydra_alone(tmp_path):
    """Hydra writes a sweep job's .hydra/ before laughlab can claim the folder: a second sweep into the folder
    of a job still running used to delete that job's .hydra/ when it was refused; now it puts it back."""
    d = tmp_path / "sweep"
    first = laughlab("-m", "seed=3", "input.duration_s=600", f"hydra.sweep.dir={d}", *NO_PLOTS)
    deadline = time.time() + 60
    while not (d / "0" / rundir.MARKER).exists() and time.time() < deadline:
        time.sleep(0.05)
    mine = {f.name: f.read_text() for f in (d / "0" / ".hydra").glob("*.yaml")}
    assert "seed=3" in mine["overrides.yaml"]
    # the same sweep (another's settings are refused before any job, sweepcheck.check_sweep_folder)
    second = run("-m", "seed=3", "input.duration_s=600", f"hydra.sweep.dir={d}", *NO_PLOTS)
    assert second.returncode != 0 and "in use by another laughlab run" in second.stderr
    assert {f.name: f.read_text() for f in (d / "0" / ".hydra").glob("*.yaml")} == mine
    first.send_signal(signal.SIGTERM)
    first.wait(timeout=60)


def test_an_aborted_writer_leaves_no_staged_file_even_when_its_buffer_cannot_be_flushed(tmp_path):
    """Past a file size limit (or on a full disk) closing the open file raises: the staged file went with the
    first abort only because the helper aborted twice (CI: .channels.csv.part left at RLIMIT_FSIZE 40 KiB)."""
    from laughlab.core.outfiles import Staging

    class Unflushable:
        closed = False

        def close(self):
            raise OSError(27, "File too large")

    staging = Staging()
    tmp = staging.path(tmp_path / "channels.csv")
    tmp.write_text("partial")
    staging.abort(Unflushable(), None)
    assert list(tmp_path.iterdir()) == []


def test_a_stop_signal_after_the_summary_line_prints_nothing_more(tmp_path):
    """Found by the clean clone's fuzz (SIGTERM at a random moment): a signal that came after a run's summary
    line, while the interpreter shut down, printed a KeyboardInterrupt traceback.  Once a single run's work is
    done and said, a stop signal is let go; a new command handles them again."""
    from laughlab.core import interrupts

    interrupts.finished = True   # as finish() leaves it (without touching this process' handlers)
    try:
        interrupts._handler(signal.SIGTERM, None)   # let go: no KeyboardInterrupt
    finally:
        interrupts.reset()
    with pytest.raises(KeyboardInterrupt):
        interrupts._handler(signal.SIGTERM, None)
    interrupts.received = None
    for k in range(3):   # the real thing: SIGTERM as soon as the summary line is out (4 of 8 tracebacks before)
        p = laughlab("input.duration_s=5", f"hydra.run.dir={tmp_path / str(k)}", *NO_PLOTS, start_new_session=True)
        assert p.stdout.readline().startswith("laughlab: 5.0 s of synthetic input")
        os.killpg(p.pid, signal.SIGTERM)
        _, err = p.communicate(timeout=60)
        assert p.returncode == 0 and err == "", err


def test_a_writer_that_aborts_removes_the_folders_it_made_and_only_those(tmp_path):
    """A sink that failed in its own close left the plots/ folder its staging had made, and the next run took
    it for a file of the user's (session review): abort removes the folders the writer created, if empty."""
    from laughlab.core.outfiles import Staging

    (tmp_path / "kept").mkdir()
    st = Staging()
    st.path(tmp_path / "plots" / "deep" / "fig.png").write_text("part")
    st.path(tmp_path / "kept" / "a.csv").write_text("part")
    st.path(tmp_path / "b.csv").write_text("part")
    st.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"] and not list((tmp_path / "kept").iterdir())
    st = Staging()
    st.path(tmp_path / "plots" / "fig.png").write_text("done")
    assert [p.name for p in st.commit()] == ["fig.png"] and (tmp_path / "plots" / "fig.png").read_text() == "done"


def test_an_overwrite_killed_as_it_marks_its_start_puts_the_earlier_run_back(tmp_path):
    """The kill test above once hit this instant (under a loaded machine): the earlier run was aside in
    .laughlab-previous/ and the new run's marker was half-written (..laughlab-run.json.part), and the next run
    called the folder "not a laughlab run".  Made here without a kill: that state, then the next run."""
    d = tmp_path / "D"
    assert run("input.duration_s=1", f"hydra.run.dir={d}", *NO_PLOTS).returncode == 0
    before = _tree(d)
    aside = d / rundir.PREVIOUS
    aside.mkdir()
    for p in list(d.iterdir()):
        if p.name not in (rundir.PREVIOUS, rundir.LOCK):
            os.replace(p, aside / p.name)
    (d / rundir.MARKER_PART).write_text('{"complete": fal')          # cut mid-write
    again = run("input.duration_s=1", f"hydra.run.dir={d}", *NO_PLOTS)
    assert again.returncode == 2 and "already holds a run" in again.stderr, again.stderr
    assert _tree(d) == before and not aside.exists() and not (d / rundir.MARKER_PART).exists()


def test_a_folder_that_cannot_be_written_is_not_said_to_be_created(tmp_path, monkeypatch):
    """A review: an existing read-only run folder was "cannot create the run directory"."""
    def refused(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(rundir.os, "open", refused)
    with pytest.raises(LaughlabError, match=r"^cannot write into the run directory .*: Permission denied$"):
        rundir.claim(tmp_path)
    with pytest.raises(LaughlabError, match=r"^cannot create the run directory .*new: Permission denied$"):
        rundir.claim(tmp_path / "new")


@pytest.mark.parametrize("launcher", [("hydra/launcher=joblib",), ()], ids=["joblib", "basic"])
def test_ctrl_c_in_a_sweep_is_one_line(tmp_path, launcher):
    """A sweeps review: Ctrl-C in a joblib-launched sweep printed a line per running job, the launcher's own line and a
    'leaked semaphore objects' warning (tqdm's lock in the jobs' processes); Hydra's basic launcher, the job's
    line.  Now one line says how far the sweep got."""
    d = tmp_path / "sw"
    p = laughlab("-m", "experiment=smoke", "extractor.rise_per_s=12,48", "harness.corpus.duration_s=60", *launcher,
                 "harness.corpus.seeds=1", "harness.plots=false", "harness.jobs=1", "progress=off", f"hydra.sweep.dir={d}",
                 start_new_session=True)
    deadline = time.time() + 90
    while not list(d.glob("*/trials/*/*")) and time.time() < deadline:   # the jobs' trials are running
        time.sleep(0.05)
    time.sleep(0.5)
    os.killpg(p.pid, signal.SIGINT)   # as the terminal sends it: to every process of the command
    out, err = p.communicate(timeout=90)
    assert p.returncode == 130
    assert err == "laughlab: error: interrupted: 0 of 2 points finished; run the same command again to resume\n", err


def test_a_stop_while_the_marker_is_written_leaves_no_part_file(tmp_path, monkeypatch):
    """A clean clone's fuzz run (SIGTERM 1.42 s into a run) found ``.laughlab-run.json.part`` left behind: the
    signal came between the marker's temporary file and its move into place, and abandon() removed only the
    marker.  Here the move is interrupted as that signal would; the folder this run made goes whole."""
    from laughlab.core import rundir

    run = tmp_path / "run"
    claim = rundir.claim(run)
    real = rundir.os.replace

    def stopped(src, dst):
        if str(dst).endswith(rundir.MARKER):
            raise KeyboardInterrupt
        real(src, dst)

    monkeypatch.setattr(rundir.os, "replace", stopped)
    with pytest.raises(KeyboardInterrupt):
        claim.finish("abc")
    assert (run / rundir.MARKER_PART).exists()
    claim.abandon()
    claim.release()
    assert not run.exists()


@pytest.mark.parametrize("positional", [True, False], ids=["pread", "lseek"])
def test_the_lock_says_whose_it_is_with_or_without_pread(tmp_path, monkeypatch, positional):
    """laughlab.core.oslock: Windows has no pread/pwrite (a portability review: every run ended in a traceback there),
    so the holder's pid is also written and read with lseek and write/read; a second process is refused the lock and
    reads the pid either way, and gets the lock once the holder lets go."""
    from laughlab.core import oslock

    if not positional:
        monkeypatch.delattr(os, "pread")
        monkeypatch.delattr(os, "pwrite")
    lock = tmp_path / ".laughlab.lock"
    child = ("import os, sys\nfrom laughlab.core import oslock\n"
             + ("" if positional else "del os.pread, os.pwrite\n")
             + "fd = os.open(sys.argv[1], os.O_RDWR)\nprint(oslock.try_lock(fd), oslock.read_head(fd).decode().strip())\n")
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        assert oslock.try_lock(fd)
        oslock.write_head(fd, b"123456789\n")
        oslock.write_head(fd, b"4242\n")   # the file becomes the new pid alone
        other = subprocess.run([sys.executable, "-c", child, str(lock)], capture_output=True, text=True, timeout=60)
        assert other.stdout.split() == ["False", "4242"], other.stderr
    finally:
        os.close(fd)
    other = subprocess.run([sys.executable, "-c", child, str(lock)], capture_output=True, text=True, timeout=60)
    assert other.stdout.split() == ["True", "4242"], other.stderr
    assert lock.read_bytes() == b"4242\n"
