"""An override's key, as the CLI, the runner, the sweep check and the session read it (laughlab.core.overrides)."""
from __future__ import annotations

from hypothesis import given, strategies as st

from laughlab.core.overrides import override_key, without_command_keys

KEYS = st.from_regex(r"[a-z_][a-z0-9_]*(\.[a-z_][a-z0-9_]*){0,3}", fullmatch=True)
PREFIXES = st.sampled_from(["", "+", "++", "~"])


@given(PREFIXES, KEYS, st.text(max_size=20))
def test_the_key_is_before_the_first_equals_sign_without_its_plus_or_tilde(prefix, key, value):
    assert override_key(f"{prefix}{key}={value}") == key
    assert override_key(f"{prefix}{key}") == key   # ~seed, or a sweep's key alone


def test_keys_by_hand():
    assert override_key("+input.path=a=b.wav") == "input.path"
    assert override_key("~seed") == "seed"
    assert override_key("++harness.jobs=2") == "harness.jobs"
    assert override_key("output.plots.width=column") == "output.plots.width"


@given(st.lists(st.tuples(PREFIXES, KEYS, st.text(alphabet="abc=,", max_size=5)), max_size=8))
def test_the_commands_own_keys_are_dropped_and_the_rest_kept_in_order(parts):
    ovs = [f"{p}{k}={v}" for p, k, v in parts]
    kept = without_command_keys(ovs)
    assert kept == [o for o in ovs if o in kept]            # in their order
    for o in ovs:   # Hydra's own (hydra.*, hydra/launcher) and the command's go; every other stays
        assert (o in kept) == (not override_key(o).startswith(("hydra", "overwrite", "progress")))


def test_the_commands_own_keys_by_hand():
    ovs = ["hydra.run.dir=x", "+hydra/launcher=joblib", "overwrite=true", "progress=off", "face=facs", "seed=3"]
    assert without_command_keys(ovs) == ["face=facs", "seed=3"]
