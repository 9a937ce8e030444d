"""A submitit job without a result (killed by Slurm, out of memory, or ended by laughlab's own error line) is one
line in the sweep's command (a cluster review: submitit's UncompletedJobError went through Hydra, which printed
its traceback and the job's, exit 1).  submitit is the cluster extra's: faked here, as tests/test_sweepcheck.py does."""
import sys
import types

from inprocess import laughlab
from laughlab.core.launchers import job_lost_line

KILLED = ("Job 17625 (task: 0) with path /nowhere/.submitit/17625/17625_0_result.pkl\nhas not produced any output "
          "(state: FINISHED)\nNo error stream produced. Look at stdout: /nowhere/.submitit/17625/17625_0_log.out")
SAID = ("Job 42 (task: 0) with path /nowhere/.submitit/42/42_0_result.pkl\nhas not produced any output (state: "
        "FINISHED)\nError stream produced:\n----------------------------------------\nlaughlab: error: input file "
        "/data/b.wav not found\n")


def test_the_line_names_the_job_and_what_it_said():
    assert job_lost_line(KILLED, "3 of 4 points finished") == (
        "sweep job 17625 ended without a result (killed, out of time or memory?); 3 of 4 points finished")
    assert job_lost_line(SAID, "1 of 2 points finished") == (
        "sweep job 42: input file /data/b.wav not found; 1 of 2 points finished")


def _fake_submitit(monkeypatch, message):
    from hydra.core.plugins import Plugins

    Plugins.instance()   # Hydra's scan runs its plugins' modules again: their classes as Hydra then holds them
    basic = sys.modules["hydra._internal.core_plugins.basic_launcher"].BasicLauncher

    class UncompletedJobError(RuntimeError):
        pass

    utils = types.ModuleType("submitit.core.utils")
    utils.UncompletedJobError = UncompletedJobError
    launcher = types.ModuleType("hydra_plugins.hydra_submitit_launcher.submitit_launcher")
    launcher.BaseSubmititLauncher = basic     # the basic launcher stands in for submitit's
    package = types.ModuleType("hydra_plugins.hydra_submitit_launcher")
    package.submitit_launcher = launcher
    for name, module in {"submitit": types.ModuleType("submitit"), "submitit.core": types.ModuleType("submitit.core"),
                         "submitit.core.utils": utils, "hydra_plugins.hydra_submitit_launcher": package,
                         "hydra_plugins.hydra_submitit_launcher.submitit_launcher": launcher}.items():
        monkeypatch.setitem(sys.modules, name, module)

    def launch(self, job_overrides, initial_job_idx):
        raise UncompletedJobError(message)

    monkeypatch.setattr(basic, "launch", launch)


def test_a_job_without_a_result_is_one_line(tmp_path, monkeypatch):
    _fake_submitit(monkeypatch, KILLED)
    sweep = tmp_path / "sweep"
    r = laughlab("-m", "seed=0,1", "input.duration_s=1", "hydra/launcher=basic", f"hydra.sweep.dir={sweep}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("laughlab: error: sweep job 17625 ended without a result (killed, out of time or "
                               "memory?); 0 of 2 points finished; run the same command again to resume"), r.stderr
    assert "Traceback" not in r.stderr
