"""An installed package's experiments are ``experiment=NAME`` (``register_experiments``), as a plugins_dir's are.

A plugin authors' review: a package could ship a face, not the experiment that compares it with laughlab's;
the docs sent its users to a plugins_dir folder beside the package.  The package here is installed as pip
leaves one (a ``.dist-info`` with its entry point, on the child's path), so every process of the command, the
experiment's trial workers too, finds it through ``importlib.metadata``."""
import json
import os
import subprocess
import sys

import pytest

from test_plugin_dir import EXPERIMENT, PLUGIN   # the gape face, and gape_vs_smile.yaml comparing it with smile

PACKAGE = "from pathlib import Path\n" + PLUGIN + '''

@laughlab.hookimpl
def register_experiments(register):
    register(Path(__file__).parent / "experiments" / "gape_vs_smile.yaml")
    REGISTER_MORE
'''

def install(site, more=""):
    """The package ``laughlab-gape`` 0.1.0 as pip installs it, into the folder ``site``."""
    pkg = site / "laughlab_gape"
    (pkg / "experiments").mkdir(parents=True)
    (pkg / "__init__.py").write_text(PACKAGE.replace("REGISTER_MORE", more or "pass"))
    (pkg / "experiments" / "gape_vs_smile.yaml").write_text(EXPERIMENT)
    info = site / "laughlab_gape-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: laughlab-gape\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[laughlab]\ngape = laughlab_gape\n")


def run(*args, site, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "laughlab", *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=300)


def test_a_packages_experiment_runs_by_name_in_its_trial_workers_and_is_listed(tmp_path):
    install(tmp_path / "site")
    r = run("experiment=gape_vs_smile", "harness.jobs=2", "hydra.run.dir=exp", site=tmp_path / "site", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "exp" / "results.json").read_text())
    assert doc["experiment"] == "gape_vs_smile" and doc["n_trials"] == 4
    assert doc["conditions"] == {"smile": ["face=smile", "detector=none"],
                                 "gape": ["face=gape", "face.gain=3", "detector=none"]}
    assert doc["config"]["extractor"]["name"] == "phoneme"   # its defaults list applied
    assert doc["config"]["harness"]["jobs"] == 2 and doc["config"]["harness"]["corpus"]["seeds"] == 2
    # the gape face writes no smile channel: its smile onset is n/a, the smile face's a latency
    smiles = {}
    for line in (tmp_path / "exp" / "metrics.jsonl").read_text().splitlines():
        rec = json.loads(line)
        smiles.setdefault(rec["condition"], []).append(rec["metrics"]["smile_onset_latency_s"])
    assert all(v is not None for v in smiles["smile"]) and all(v is None for v in smiles["gape"])
    r = run("plugins", site=tmp_path / "site", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    row = [ln.split() for ln in r.stdout.splitlines() if ln.startswith("experiment ")]
    assert row == [["experiment", "gape_vs_smile", "laughlab-gape", "0.1.0", "(entry", "point)",
                    "experiment=gape_vs_smile"]]


@pytest.mark.parametrize("more, asked, said", [
    ('register("missing.yaml")', "missing",
     "experiment file missing.yaml registered by laughlab-gape 0.1.0 (entry point) is not a .yaml file that exists"),
    ("", "gape_vs_smile", "two experiments are named 'gape_vs_smile': "),
])
def test_a_packages_experiment_that_cannot_be_one_is_one_line_when_asked_for(tmp_path, more, asked, said):
    install(tmp_path / "site", more)
    (tmp_path / "mine" / "experiment").mkdir(parents=True)
    if asked == "gape_vs_smile":   # a plugins_dir with an experiment of the same name: which one would run?
        (tmp_path / "mine" / "experiment" / "gape_vs_smile.yaml").write_text(EXPERIMENT)
    r = run("plugins_dir=mine", f"experiment={asked}", "hydra.run.dir=exp", site=tmp_path / "site", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and said in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "exp").exists()
    if asked == "gape_vs_smile":
        assert "rename one" in r.stderr
    else:   # the package's good experiment still runs
        r = run("plugins_dir=mine", "experiment=gape_vs_smile", "harness.jobs=1", "harness.corpus.seeds=1",
                "hydra.run.dir=ok", site=tmp_path / "site", cwd=tmp_path)
        assert r.returncode == 0, r.stderr


def test_a_register_hook_that_raises_is_one_line_naming_the_package_and_its_line(tmp_path):
    """A re-read: a package's ``register_experiments`` that raised ended every command in a traceback."""
    install(tmp_path / "site", 'raise RuntimeError("no experiments folder")')
    r = run("experiment=gape_vs_smile", "hydra.run.dir=exp", site=tmp_path / "site", cwd=tmp_path)
    init = tmp_path / "site" / "laughlab_gape" / "__init__.py"
    line = next(i for i, t in enumerate(init.read_text().splitlines(), 1) if "no experiments folder" in t)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr == (f"laughlab: error: register_experiments of plugin laughlab-gape 0.1.0 (entry point) raised "
                        f"RuntimeError: no experiments folder (at {init}, line {line}); every laughlab command loads "
                        "the installed plugins: mend it, or uninstall it\n"), r.stderr
    assert not (tmp_path / "exp").exists()
