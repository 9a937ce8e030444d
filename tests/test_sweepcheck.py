"""A sweep is checked before any job starts (a new-user review: a mistyped key in ``-m`` printed Hydra's six-line
error, and a bad value was found only when its job ran, after the joblib launcher had started the others, which
were stopped part way and left empty results)."""
import pytest
from omegaconf import OmegaConf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.errors import LaughlabError
from laughlab.core.sweepcheck import check_sweep, sweep_values


def test_sweep_values_by_hand():
    base, sweeps = sweep_values(["experiment=x", "a=1,2", "+b=range(0,3)", "c=[1,2]", "d=interval(0,1)"])
    assert base == ["experiment=x", "a=1", "+b=0", "c=[1,2]"]          # interval(...): left to the jobs
    assert sweeps == {"a": ["a=1", "a=2"], "+b": ["+b=0", "+b=1", "+b=2"]}


def test_each_value_of_each_key_is_checked_with_the_others_at_their_first_values():
    """The command line's sweeps and the experiment's ``hydra.sweeper.params`` (a key swept on the command line
    replaces the experiment's sweep of it): one check per value, the others at their first values."""
    calls = []

    def preflight(overrides):
        calls.append(list(overrides))
        if "p=-1" in overrides:
            raise LaughlabError("p must be >= 0")
        return OmegaConf.create({"hydra": {"sweeper": {"params": {"p": "0,1", "q": "5,6,7", "a": "8,9"}}}})

    assert check_sweep(["experiment=x", "a=1,2"], preflight) == 1 + 1 + 1 + 1 + 2
    assert calls == [["experiment=x", "a=1"],                      # the first values compose; params read
                     ["experiment=x", "a=1", "p=0", "q=5"],        # ... with the experiment's sweeps
                     ["experiment=x", "a=2", "p=0", "q=5"],
                     ["experiment=x", "a=1", "p=1", "q=5"],
                     ["experiment=x", "a=1", "p=0", "q=6"],
                     ["experiment=x", "a=1", "p=0", "q=7"]]
    with pytest.raises(LaughlabError, match=r"^sweep value p=-1: p must be >= 0$"):
        check_sweep(["experiment=x", "p=0,-1"], preflight)


@pytest.mark.parametrize("swept, message", [
    ("scheduler.overule_c=1.5,3", "unknown parameter scheduler.overule_c (did you mean scheduler.overrule_c?); valid: "),
    ("nosuchkey=1", "unknown parameter nosuchkey"),
    ("scheduler.overrule_c=1.5,-2", "sweep value scheduler.overrule_c=-2: bad parameter in scheduler=energy: "
                                    "overrule_c must be >= 0 (got -2.0)"),
    ("scheduler.overrule_c=1.5,abc", "sweep value scheduler.overrule_c=abc: bad parameter scheduler.overrule_c (scheduler=energy)"),
    # the launcher's own settings (a review: joblib's and Hydra's tracebacks after the sweep had started)
    ("hydra.launcher.n_jobs=0", "hydra.launcher.n_jobs=0: the joblib launcher runs that many points at once, a whole "
                                "number other than 0 (-1: one per core)"),
    ("hydra.launcher.n_jobs=two", "bad setting hydra.launcher.n_jobs=two: Value 'two' of type 'str' could not be "
                                  "converted to Integer"),
    ("hydra/launcher=nope", "unknown launcher hydra/launcher=nope; launchers here: basic, joblib"),
    ("experiment=smoke hydra.launcher.n_jobs=2", "unknown parameter hydra.launcher.n_jobs of this launcher; Hydra's "
                                                 "basic launcher runs one job at a time, hydra/launcher=joblib takes n_jobs"),
    ("--cfg=hydra", "--cfg=hydra shows one configuration and does not combine with -m: drop -m"),
    # a sweep over experiments: Hydra's own composition has no harness (its "Could not override" came after the check)
    ("experiment=smoke,energy_readings harness.corpus.seeds=1",
     "harness.corpus.seeds=1 with a sweep over experiments: Hydra composes the sweep itself without an experiment, "
     "where harness does not exist; write ++harness.corpus.seeds=1"),
    ("experiment=smoke,energy_readings +harness.corpus.seeds=1", "write ++harness.corpus.seeds=1"),
    # + on a nested key that exists: the fix quotes the whole sweep, not its first value
    ("+scheduler.overrule_c=1.5,3", "scheduler.overrule_c is already a setting: write scheduler.overrule_c=1.5,3 "
                                    "(without +)\n"),
    # the live viewer: the sweep stood still at its first point, waiting for a page (the live-viewer review)
    ("scheduler.decrease_per_s=6,12 output=viewer", "output=viewer in a sweep: each point would wait for a page to "
                                                    "open before it starts; set output.viewer.wait=off"),
])
def test_a_bad_sweep_is_one_line_before_any_job(tmp_path, swept, message):
    sweep = tmp_path / "sweep"
    first = [] if swept.startswith(("experiment=", "scheduler.decrease")) else ["experiment=energy_ablation"]   # its launcher: joblib
    r = laughlab("-m", *first, *swept.split(), f"hydra.sweep.dir={sweep}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and message in r.stderr
    assert "Traceback" not in r.stderr and "HYDRA_FULL_ERROR" not in r.stderr
    assert not sweep.exists()                                      # no job started, no folder made


def test_a_sweep_over_experiments_does_not_read_their_sweeper_params():
    """Hydra composes the sweeper's configuration without swept groups, so ``experiment=a,b`` runs each experiment
    once and their own params are not swept (a re-read: the check applied a's params to b and refused it)."""
    calls = []

    def preflight(overrides):
        calls.append(list(overrides))
        return OmegaConf.create({"hydra": {"sweeper": {"params": {"p": "0,-1"}}}})

    assert check_sweep(["experiment=a,b", "seed=1"], preflight) == 2
    assert calls == [["experiment=a", "seed=1"], ["experiment=b", "seed=1"]]


def test_the_committed_experiments_sweep_together(tmp_path):
    from laughlab import cli

    assert check_sweep(["experiment=energy_ablation,concat_ablation"], cli.preflight) == 2


def test_the_slurm_launcher_names_what_it_needs(tmp_path, monkeypatch):
    """Without the cluster extra, Hydra's "Could not find 'hydra/launcher/submitit_slurm'" said nothing of how to
    install it; with it, off a cluster, submitit's traceback came after Hydra had written the sweep's folder."""
    import importlib.util

    sweep = tmp_path / "sweep"
    r = laughlab("-m", "experiment=energy_ablation", "hydra/launcher=submitit_slurm", f"hydra.sweep.dir={sweep}")
    installed = importlib.util.find_spec("hydra_plugins.hydra_submitit_launcher") is not None
    want = "sbatch, which this machine does not have" if installed else "pip install -e '.[cluster]'"
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and want in r.stderr, r.stderr
    assert not sweep.exists()
    from laughlab.core import sweepcheck

    slurm = {"_target_": "hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher"}
    monkeypatch.setattr("shutil.which", lambda name: None)
    with pytest.raises(LaughlabError, match="submitit_slurm submits every point with Slurm's sbatch"):
        sweepcheck.check_launcher(slurm)
    monkeypatch.setattr("shutil.which", lambda name: f"/usr/bin/{name}")
    sweepcheck.check_launcher(slurm)                                # on a login node: left to the launcher
    sweepcheck.check_launcher({"_target_": "hydra_plugins.hydra_joblib_launcher.joblib_launcher.JoblibLauncher",
                               "n_jobs": -1})                       # -1: one per core


def test_a_sweep_shown_live_runs_without_a_page_when_told_not_to_wait(tmp_path):
    r = laughlab("-m", "scheduler.decrease_per_s=6,12", "output=viewer", "output.viewer.wait=off",
                 "output.viewer.realtime=off", "output.viewer.port=0", "input.duration_s=0.5",
                 f"hydra.sweep.dir={tmp_path / 'sweep'}")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("viewer: 30 frames sent to no page") == 2


def _earlier_sweep(folder, task):
    import yaml

    folder.mkdir(parents=True)
    (folder / "multirun.yaml").write_text(yaml.safe_dump({"hydra": {"overrides": {
        "hydra": [f"hydra.sweep.dir={folder}", "hydra.mode=MULTIRUN"], "task": task}}}))


def test_a_sweep_folder_of_other_settings_is_refused_before_any_job(tmp_path):
    """A researcher's review: the documented small sweep run again with decrease_per_s=6,30 into the same
    hydra.sweep.dir skipped point 0, then stopped at point 1 ("already holds a run") without saying why, and
    rewrote multirun.yaml.  Now one line before any job names what differs; the same sweep again resumes;
    overwrite=true runs over it."""
    from laughlab.core.sweepcheck import check_sweep_folder

    sweep = tmp_path / "small"
    task = ["experiment=energy_ablation", "scheduler.overrule_c=1.5,3", "scheduler.decrease_per_s=6,20",
            "harness.corpus.seeds=1"]
    _earlier_sweep(sweep, task)
    before = (sweep / "multirun.yaml").read_bytes()
    changed = [*task[:2], "scheduler.decrease_per_s=6,30", "fps=30"]
    r = laughlab("-m", *changed, f"hydra.sweep.dir={sweep}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr == (f"laughlab: error: {sweep} holds a sweep of other settings (scheduler.decrease_per_s=6,30 "
                        "(there: 6,20), fps=30, harness.corpus.seeds=1 there, not now): its points are numbered as "
                        "that sweep's; choose another hydra.sweep.dir, or add overwrite=true to run these points "
                        "over it\n")
    assert sorted(p.name for p in sweep.iterdir()) == ["multirun.yaml"]
    assert (sweep / "multirun.yaml").read_bytes() == before
    # the same sweep (in another order) resumes; overwrite=true runs over it; a new folder has nothing to compare
    check_sweep_folder([*reversed(task), f"hydra.sweep.dir={sweep}", "hydra/launcher=basic"])
    check_sweep_folder([*task, "progress=off", f"hydra.sweep.dir={sweep}"])   # the command's settings: no matter
    check_sweep_folder([*changed, f"hydra.sweep.dir={sweep}", f"hydra.sweep.dir={tmp_path / 'new'}"])   # Hydra's: last
    check_sweep_folder([*changed, f"hydra.sweep.dir={sweep}", "overwrite=true"])
    check_sweep_folder([*changed, f"hydra.sweep.dir={tmp_path / 'new'}"])
    check_sweep_folder(changed)   # the default folder is named by the time: a new one
    with pytest.raises(LaughlabError, match=r"\(scheduler.decrease_per_s=6,30 \(there: 6,20\), fps=30, seed=3, ...\)"):
        check_sweep_folder([*changed, "seed=3", f"hydra.sweep.dir={sweep}"])
