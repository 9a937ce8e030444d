"""laughlab/_kernels.py: numpy's and OpenBLAS's kernels pinned to AVX2's before numpy loads, so that runs give
the same bytes on AVX2 and AVX-512 machines (tests/golden.py checks the bytes; this checks the switch)."""
import json
import os
import platform
import subprocess
import sys

import pytest

from laughlab import _kernels

X86_AVX2 = platform.machine() in ("x86_64", "AMD64") and {"avx2", "fma"} <= _kernels.cpu_flags()
PROBE = ("import json, os, laughlab, numpy; from numpy._core._multiarray_umath import __cpu_features__ as f; "
         "from laughlab import _kernels; print(json.dumps({'v4': bool(f.get('X86_V4')), "
         "'blas': os.environ.get('OPENBLAS_CORETYPE'), 'state': _kernels.state()}))")


def probe(code: str = PROBE, **env) -> dict:
    base = {k: v for k, v in os.environ.items()
            if k not in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE", "LAUGHLAB_NATIVE_KERNELS")}
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                         timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not X86_AVX2, reason="the pin applies to x86-64 Linux with AVX2 and FMA")
def test_import_laughlab_first_pins_numpy_and_openblas_to_avx2():
    got = probe()
    assert got == {"v4": False, "blas": "Haswell", "state": "x86-64-v3 (pinned)"}


@pytest.mark.skipif(not X86_AVX2, reason="the pin applies to x86-64 Linux with AVX2 and FMA")
def test_the_users_choice_and_an_earlier_numpy_are_left_alone_and_said():
    native = probe(LAUGHLAB_NATIVE_KERNELS="1")
    assert native["blas"] is None and native["state"] == "native (LAUGHLAB_NATIVE_KERNELS=1)"
    assert native["v4"] == ("avx512bw" in _kernels.cpu_flags())  # numpy's own choice
    assert probe(OPENBLAS_CORETYPE="Zen")["blas"] == "Zen"          # a value the user set is kept
    first = probe("import numpy; " + PROBE)                          # numpy loaded before laughlab
    assert first["blas"] is None
    if "avx512bw" in _kernels.cpu_flags():
        assert first["v4"] and first["state"].startswith("native (numpy was imported before laughlab")
        # a reproducibility review: the user's own NPY_DISABLE_CPU_FEATURES without X86_V4 was said to be numpy's
        # import order; it names the variable
        own = probe(NPY_DISABLE_CPU_FEATURES="AVX512_SPR")
        assert own["v4"] and own["state"] == "native (NPY_DISABLE_CPU_FEATURES=AVX512_SPR leaves numpy's AVX-512 " \
            "loops on)"


def test_this_test_session_runs_pinned():
    """conftest.py imports laughlab before any test module imports numpy: the suite checks the pinned kernels."""
    if X86_AVX2:
        assert _kernels.state() == "x86-64-v3 (pinned)"
    from laughlab.harness.results import versions

    assert versions()["cpu_kernels"] == _kernels.state()
    assert versions()["hill_kernel"] == ("numpy (LAUGHLAB_NUMBA=0)" if os.environ.get("LAUGHLAB_NUMBA") == "0" else
                                         "numba")


def test_laughlab_numba_0_is_recorded(monkeypatch):
    """A reproducibility review: LAUGHLAB_NUMBA=0 (body=hill's torso in numpy) changes the last bits of a hill run
    and nothing recorded it."""
    import laughlab.hill.kernel  # noqa: F401  (the kernel this process runs)
    from laughlab.harness.results import versions

    code = ("import laughlab.hill.kernel, json; from laughlab.harness.results import versions; "
            "print(json.dumps(versions()['hill_kernel']))")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "LAUGHLAB_NUMBA": "0"},
                         capture_output=True, text=True, timeout=120, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == "numpy (LAUGHLAB_NUMBA=0)"
    # what ran, not the variable read again (a diff review): this process compiled its kernel before
    monkeypatch.setenv("LAUGHLAB_NUMBA", "0")
    assert versions()["hill_kernel"] == "numba"
