"""Byte-identity: the default run and a few combinations write exactly the golden bytes.

Holds refactors (issue 12's layout) and speed-ups (block-vectorised paths) to the outputs they
replace.  Regenerate with ``python tests/golden.py --update`` only when an output is meant to change.
"""
import json

import pytest

from golden import GOLDEN, RUNS, run


@pytest.mark.parametrize("name", sorted(RUNS))
def test_outputs_are_the_golden_bytes(name, tmp_path):
    expected = json.loads(GOLDEN.read_text())[name]
    got = run(name, tmp_path / name)
    assert set(got) == set(expected), f"{name}: files differ"
    changed = [f for f in expected if got[f] != expected[f]]
    assert not changed, f"{name}: {changed} differ from the golden bytes"
