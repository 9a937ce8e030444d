"""Golden runs: the default run and a few combinations write the golden outputs.

In the locked environment (``make test``) the files must be the golden bytes; anywhere else their
numbers must agree within ``golden.RTOL``/``golden.ATOL`` (the test's report line says which check
ran and why).  Regenerate with ``python tests/golden.py --update`` only when an output is meant to
change.
"""
import json

import pytest

from golden import (ATOL, GOLDEN, RTOL, RUNS, YAMNET_RUNS, cpu_family, exact_environment, expected_hashes,
                    golden_file, lock_mismatches, locked_pins, run, sha256, value_differences)

EXACT, WHY = exact_environment()


@pytest.mark.parametrize("name", sorted(RUNS))
def test_outputs_are_the_golden_outputs(name, tmp_path, record_property):
    expected = json.loads(GOLDEN.read_text())["runs"][name]
    if EXACT:
        expected, note = expected_hashes(name)
        if expected is None:   # a YAMNet run on a CPU family without recorded bytes
            pytest.skip(f"golden {name}: {note}")
    got = run(name, tmp_path / name)
    assert set(got) == set(expected), f"{name}: files differ"
    if EXACT:
        record_property("golden_check", note)
        changed = [f for f in expected if sha256(got[f]) != expected[f]]
        assert not changed, f"{name}: {changed} differ from the golden bytes"
    else:
        record_property("golden_check", f"values within rtol {RTOL:g}, atol {ATOL:g}: not the locked environment: {WHY}")
        problems = {f: value_differences(got[f], golden_file(name, f)) for f in expected}
        problems = {f: p for f, p in problems.items() if p}
        assert not problems, f"{name} (not the locked environment, {WHY}): {problems}"


def test_the_golden_files_are_the_recorded_bytes():
    """The gzipped golden files (used outside the lock) hold exactly the bytes whose digests are recorded."""
    recorded = json.loads(GOLDEN.read_text())["runs"]
    for name, files in recorded.items():
        for f, digest in files.items():
            assert sha256(golden_file(name, f)) == digest, f"{name}/{f}"


def test_the_yamnet_runs_are_recorded_per_cpu_family_and_the_rest_once():
    doc = json.loads(GOLDEN.read_text())
    assert set(YAMNET_RUNS) == {"default", "real_48k_yamnet"}        # every run not pinned to another detector
    family = doc["environment"]["cpu"]
    # the family the golden files were made on holds the same digests as "runs"
    assert doc["yamnet_cpu"][family] == {n: doc["runs"][n] for n in YAMNET_RUNS}
    for fam, runs in doc["yamnet_cpu"].items():
        assert set(runs) == set(YAMNET_RUNS), fam
        assert all(set(runs[n]) == set(doc["runs"][n]) for n in YAMNET_RUNS), fam
    assert cpu_family()                                             # e.g. avx+avx2, or the architecture


def test_value_comparison_tolerates_rounding_and_nothing_else():
    want = b"time,mcs,clip\n0.0,0.5,idle\n0.016667,0.25,rofl\n"
    assert value_differences(want, want) is None
    assert value_differences(b"time,mcs,clip\n0.0,0.50000001,idle\n0.016667,0.25,rofl\n", want) is None
    assert "numbers beyond" in value_differences(b"time,mcs,clip\n0.0,0.6,idle\n0.016667,0.25,rofl\n", want)
    assert "text differs" in value_differences(b"time,mcs,clip\n0.0,0.5,idle\n0.016667,0.25,giggle\n", want)
    assert value_differences(b"time,mcs,clip\n0.0,0.5,idle\n", want) is not None  # a row fewer


def test_the_lock_is_read_with_its_markers(tmp_path):
    lock = tmp_path / "requirements.lock"
    lock.write_text("numpy==1.0 ; python_full_version < '3.0' \\\n    --hash=sha256:00\n"
                    "numpy==2.0 ; python_full_version >= '3.0' \\\n    --hash=sha256:11\n"
                    "colorama==0.4.6 ; sys_platform == 'no-such-os' \\\n"
                    "Pluggy==99.0 \\\n    # via laughlab\n")
    assert locked_pins(lock) == {"numpy": "2.0", "pluggy": "99.0"}
    assert {m.split()[0] for m in lock_mismatches(lock)} == {"numpy", "pluggy"}
