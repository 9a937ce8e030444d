"""The cached trial composition (``laughlab.core.config.compose_app``) equals Hydra's own, trial by trial."""
from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from laughlab.core.config import compose_app, compose_config, register_plugin_configs
from laughlab.core.errors import LaughlabError
from laughlab.harness.corpus import build_corpus
from laughlab.harness.runner import check_conditions, make_trials


def fresh(overrides):
    """A trial's configuration the way the runner composed it before the cache: Hydra, every time."""
    register_plugin_configs()
    cfg = compose_config(list(overrides))
    return OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])


def same(a, b) -> None:
    assert OmegaConf.to_yaml(a) == OmegaConf.to_yaml(b)                      # the values, interpolations unresolved
    assert OmegaConf.to_container(a, resolve=True) == OmegaConf.to_container(b, resolve=True)
    assert OmegaConf.is_struct(a) == OmegaConf.is_struct(b)


def trials_of(experiment: str, base: list[str]):
    cfg = compose_config([f"experiment={experiment}", *base])
    h = OmegaConf.to_container(cfg.harness, resolve=True)
    h["corpus"].setdefault("real", {})["if_missing"] = "skip"
    items = build_corpus(h["corpus"])
    seeds = [int(s) for s in h.get("run_seeds") or [0]]
    return make_trials(items, check_conditions(h["conditions"]), lambda i: [i.seed] if i.seed is not None else seeds,
                       base, Path("unused"))


@pytest.mark.parametrize("experiment,base", [
    ("smoke", ["experiment=smoke", "harness.corpus.seeds=2", "fps=30"]),
    ("energy_vs_concat", ["experiment=energy_vs_concat", "hydra.run.dir=/tmp/x", "seed=4"]),
    ("detector_eval", ["experiment=detector_eval"]),
    ("detector_others", ["experiment=detector_others"]),
])
def test_every_trial_composes_as_hydra_composes_it(experiment, base):
    trials = trials_of(experiment, base)
    picked = {}
    for t in trials:   # a trial of each condition and each kind of input (synthetic, a recording)
        picked.setdefault((t.condition, t.item.overrides[:1]), t)
    picked = list(picked.values())
    assert len({t.condition for t in picked}) >= 2
    for t in picked:
        ov = [*t.overrides, "output=trial"]
        same(compose_app(ov), fresh(ov))


def test_value_overrides_apply_in_order_to_a_copy_and_bad_ones_are_one_message():
    a = compose_app(["detector=none", "seed=3", "input.duration_s=2", "seed=5"])
    b = compose_app(["detector=none", "seed=1"])
    same(a, fresh(["detector=none", "seed=3", "input.duration_s=2", "seed=5"]))
    assert (a.seed, a.input.duration_s, b.seed) == (5, 2, 1)   # b's copy kept nothing of a's values
    same(compose_app(["~output.plots", "detector=yamnet", "detector.open_at=0.4"]),
         fresh(["~output.plots", "detector=yamnet", "detector.open_at=0.4"]))
    with pytest.raises(LaughlabError) as bad:
        compose_app(["detector=none", "input.no_such_key=1"])
    assert "no_such_key" in str(bad.value) and "\n" not in str(bad.value).strip()
    with pytest.raises(LaughlabError):
        compose_app(["detector=no_such_detector"])


@pytest.mark.parametrize("given", ["face=[facs,cgm]", "body=[hill, shapes]", "detector=[none,laugh]"])
def test_a_list_for_a_group_of_one_plugin_is_one_line_saying_so(given, tmp_path):
    """A facial animator's review: face=[facs,cgm] (Hydra merges both configs) answered "face.au6 is a parameter of
    face=facs, not of face=cgm: add face=facs". It says the group takes one option, and how to compare several."""
    from inprocess import laughlab

    group = given.lstrip("+").split("=")[0]
    r = laughlab(given, "input.duration_s=1", f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"laughlab: error: {group} takes one option, not a list") and "-m " in r.stderr
    assert not (tmp_path / "r").exists()
    assert compose_config(["output=[files,vmc]"]).output.vmc is not None   # output takes a list
    r = laughlab("face=[facs]", "input.duration_s=1", f"hydra.run.dir={tmp_path / 'one'}")   # a list of one: no sweep
    assert r.returncode == 2 and r.stderr == ("laughlab: error: face takes one option, not a list (got face=[facs]): "
                                              "write face=facs\n"), r.stderr
