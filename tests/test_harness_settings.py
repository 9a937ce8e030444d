"""The shared experiment settings (``harness.*``): a wrong type is one line before anything runs.

``harness.jobs=two`` or ``harness.corpus.profiles=mild`` used to end in a Python traceback (or, for
``profiles``, in the profile ``'m'``: the string read letter by letter)."""
import pytest
from hypothesis import given, settings, strategies as st
from omegaconf import OmegaConf

import fuzz
from laughlab.core.config import compose_config, group_options
from laughlab.core.errors import LaughlabError
from laughlab.harness.settings import check_harness


@pytest.mark.parametrize("experiment", group_options("experiment"))
def test_every_shipped_experiment_passes(experiment):
    cfg = compose_config([f"experiment={experiment}"])
    check_harness(OmegaConf.to_container(cfg.harness, resolve=True))


@pytest.mark.parametrize("experiment", group_options("experiment"))
def test_every_experiment_takes_the_shared_corpus_keys_without_a_plus(experiment):
    """docs/experiments.md calls corpus.* and corpus.real.* shared: concat_ablation, energy_ablation, fourier_blend,
    hill_fit and stimuli refused harness.corpus.real.sets=[real] as an unknown parameter (a researcher's review)."""
    cfg = compose_config([f"experiment={experiment}", "harness.corpus.real.sets=[real]", "harness.corpus.folder=null"])
    assert cfg.harness.corpus.real.sets == ["real"]
    default = compose_config([f"experiment={experiment}"]).harness.corpus.real
    real_by_default = ("detector_eval", "detector_others", "energy_readings", "energy_vs_concat", "smoke")
    if experiment not in real_by_default:   # the new blocks run nothing more unasked, and never need the corpus
        assert list(default.sets) == [] and default.if_missing == "skip" and default.split == "test"


@pytest.mark.parametrize("override,key", [
    ("harness.jobs=two", "jobs"),
    ("harness.jobs=0", "jobs"),
    ("harness.plots=maybe", "plots"),
    ("harness.keep_trials=3", "keep_trials"),
    ("harness.run_seeds=[a]", "run_seeds"),
    ("harness.showcase=3", "showcase"),
    ("harness.conditions=5", "conditions"),
    ("harness.corpus=3", "corpus"),
    ("harness.corpus.profiles=mild", "corpus.profiles"),
    ("harness.corpus.seeds=two", "corpus.seeds"),
    ("harness.corpus.seeds=true", "corpus.seeds"),
    ("harness.corpus.seeds=[-1]", "corpus.seeds"),   # a review: it passed, and failed after the run folder was made
    ("harness.corpus.seeds=[0,-1]", "corpus.seeds"),
    ("harness.run_seeds=[-2]", "run_seeds"),
    ("harness.corpus.seeds=[1,1]", "corpus.seeds"),   # a new-user review: a trial run twice into one folder
    ("harness.run_seeds=[0,0]", "run_seeds"),
    ("harness.corpus.real.seed=-1", "corpus.real.seed"),   # a diff review: numpy refused it in the first trial
    ("harness.corpus.duration_s=0", "corpus.duration_s"),
    ("harness.corpus.duration_s=inf", "corpus.duration_s"),
    ("harness.corpus.on_bad=ignore", "corpus.on_bad"),
    ("harness.corpus.real.snr_db=[x]", "corpus.real.snr_db"),
])
def test_a_wrong_setting_is_one_line_before_anything_is_written(tmp_path, override, key):
    run = tmp_path / "run"
    out = fuzz.run_cli(["experiment=smoke", override, f"hydra.run.dir={run}", "progress=off"])
    assert out.code == 2 and not out.exception and "Traceback" not in out.stderr + out.stdout
    assert out.stderr.count("\n") == 1 and out.stderr.startswith(f"laughlab: error: harness.{key} must be ")
    assert not run.exists()


@pytest.mark.parametrize("override, line", [
    ("+harness.corpus.seed=5", "harness.corpus.seed: harness.corpus takes profiles, seeds, duration_s, folder, on_bad, "
                               "real; did you mean harness.corpus.seeds?"),
    ("+harness.showcas=null", "harness.showcas: harness takes name, module, conditions, run_seeds, showcase, jobs, "
                              "keep_trials, plots, corpus; did you mean harness.showcase?"),
    ("+harness.corpus.real.sedd=1", "harness.corpus.real.sedd: harness.corpus.real takes sets, split, scenes, "
                                    "duration_s, snr_db, seed, if_missing; did you mean harness.corpus.real.seed?"),
])
def test_a_misspelt_harness_key_added_with_plus_is_one_line(tmp_path, override, line):
    """A review: a key Hydra had to be told to add (+) was silently ignored, in a sweep as two identical points."""
    run = tmp_path / "run"
    out = fuzz.run_cli(["experiment=smoke", override, f"hydra.run.dir={run}", "progress=off"])
    assert out.code == 2 and out.stderr == f"laughlab: error: unknown parameter {line}\n" and not run.exists()
    out = fuzz.run_cli(["-m", "experiment=smoke", override.replace("=5", "=1,2"), f"hydra.sweep.dir={tmp_path / 'sw'}"])
    assert out.code == 2 and "unknown parameter harness." in out.stderr and not (tmp_path / "sw").exists()


@pytest.mark.parametrize("override, line", [
    ("harness.corpus.seed=5", "harness.corpus.seed: harness.corpus takes profiles, seeds, duration_s, folder, on_bad, "
                              "real; did you mean harness.corpus.seeds?"),
    ("harness.corpus.real.sedd=1", "harness.corpus.real.sedd: harness.corpus.real takes sets, split, scenes, "
                                   "duration_s, snr_db, seed, if_missing; did you mean harness.corpus.real.seed?"),
    ("harness.jobz=2", "harness.jobz: harness takes name, conditions, corpus, run_seeds, showcase, jobs, keep_trials, "
                       "plots; did you mean harness.jobs?"),   # the experiment's own keys (smoke's: the shared ones)
    ("harness.bogus=2", "harness.bogus: harness takes name, conditions, corpus, run_seeds, showcase, jobs, "
                        "keep_trials, plots"),
])
def test_a_misspelt_harness_key_without_plus_names_the_setting_meant(tmp_path, override, line):
    """A sweep researcher's review: ``harness.corpus.seed=1,2`` said only 'unknown parameter harness.corpus.seed'
    where the ``+`` form above named ``seeds``; the same line now, in a run and in a sweep, from the keys the
    experiment's configuration has there (an experiment's own section too: hill_fit's ``harness.fit``)."""
    run = tmp_path / "run"
    out = fuzz.run_cli(["experiment=smoke", override, f"hydra.run.dir={run}", "progress=off"])
    assert out.code == 2 and out.stderr == f"laughlab: error: unknown parameter {line}\n" and not run.exists()
    swept = override.replace("=5", "=1,2").replace("=2", "=1,2")
    out = fuzz.run_cli(["-m", "experiment=smoke", swept, f"hydra.sweep.dir={tmp_path / 'sw'}"])
    assert out.code == 2 and out.stderr == f"laughlab: error: unknown parameter {line}\n"
    assert not (tmp_path / "sw").exists()


def test_a_misspelt_key_of_an_experiments_own_section_names_its_keys(tmp_path):
    out = fuzz.run_cli(["experiment=hill_fit", "harness.fit.metod=cma", f"hydra.run.dir={tmp_path / 'run'}"])
    assert out.code == 2 and out.stderr.startswith("laughlab: error: unknown parameter harness.fit.metod: harness.fit "
                                                   "takes method, max_evals, ") and out.stderr.endswith(
        "; did you mean harness.fit.method?\n") and out.stderr.count("\n") == 1


VALUES = st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(allow_nan=True), st.text(max_size=5),
                   st.lists(st.one_of(st.integers(-2, 2), st.text(max_size=3)), max_size=3),
                   st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
KEYS = ("name", "module", "conditions", "run_seeds", "showcase", "jobs", "keep_trials", "plots", "corpus",
        "corpus.profiles", "corpus.seeds", "corpus.duration_s", "corpus.folder", "corpus.on_bad", "corpus.real",
        "corpus.real.sets", "corpus.real.split", "corpus.real.scenes", "corpus.real.duration_s",
        "corpus.real.snr_db", "corpus.real.seed", "corpus.real.if_missing")


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.sampled_from(KEYS), VALUES), min_size=1, max_size=3))
def test_any_values_pass_or_are_one_error_naming_a_key(picks):
    h = {"name": "x", "conditions": {"a": ["scheduler=energy"]}, "jobs": 1,
         "corpus": {"profiles": ["mild"], "seeds": 1, "real": {"sets": []}}}
    for key, value in picks:
        *parents, leaf = key.split(".")
        node = h
        for p in parents:
            if not isinstance(node.get(p), dict):
                node[p] = {}
            node = node[p]
        node[leaf] = value
    try:
        check_harness(h)
    except LaughlabError as exc:
        assert str(exc).startswith(("harness.", "unknown parameter harness.")) and "\n" not in str(exc)
        return
    # accepted: every value is of the kind the runner reads (a check that accepted everything passed above)
    c = h.get("corpus") or {}
    real = c.get("real") or {}
    assert isinstance(h["jobs"], int) and not isinstance(h["jobs"], bool) and h["jobs"] >= 1
    assert isinstance(c.get("profiles", []), list) and all(isinstance(x, str) for x in c.get("profiles", []))
    seeds = c.get("seeds", 0)
    assert (isinstance(seeds, int) and not isinstance(seeds, bool) and seeds >= 0) or (
        isinstance(seeds, list) and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in seeds))
    assert h.get("plots", True) in (True, False) and h.get("keep_trials", False) in (True, False)
    assert isinstance(real.get("sets", []), list) and real.get("split", "test") in ("train", "test", "all")
    for key in ("duration_s",):
        v = c.get(key, 1.0)
        assert isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < float("inf")


def test_an_experiments_own_key_near_a_shared_name_is_not_refused():
    """A diff review: the near-miss check of top-level harness keys ran on the composed section, so an experiment of
    one's own with a key ``condition`` or ``plot`` could not run at all.  It now runs on the keys the command line
    added with + (``+harness.showcas``, above); the experiment's own keys are its module's to check."""
    h = {"name": "x", "conditions": {"a": ["face=smile"]}, "condition": 1, "plot": True}
    check_harness(h, added=set())
    with pytest.raises(LaughlabError, match=r"^unknown parameter harness\.condition: .*did you mean harness\.conditions\?$"):
        check_harness(h, added={"condition"})
    with pytest.raises(LaughlabError, match=r"did you mean harness\.conditions\?"):
        check_harness(h)   # no command line: every key


def test_a_mistyped_showcase_names_the_nearest_input():
    """A plugin author's review: harness.showcase=mixed-10dB-00 listed three other inputs and cut off the one that
    existed (mixed-20dB-00)."""
    from types import SimpleNamespace

    import pytest

    from laughlab.core.errors import LaughlabError
    from laughlab.harness.experiment import showcase_item

    items = [SimpleNamespace(id=i) for i in ("mixed-s00", "intense-s00", "giggle-s00", "mixed-20dB-00")]
    with pytest.raises(LaughlabError, match=r"^harness.showcase 'mixed-10dB-00' is not an input of the corpus \(did "
                                            r"you mean 'mixed-20dB-00'\? 4 inputs: mixed-s00, intense-s00, giggle-s00, "
                                            r"\.\.\.\) nor a synthetic one"):
        showcase_item({"showcase": "mixed-10dB-00"}, items)
