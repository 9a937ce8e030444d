import os
import sys

os.environ.setdefault("MPLBACKEND", "Agg")

import laughlab  # noqa: E402,F401 - first, before any test module imports numpy: laughlab/_kernels.py pins its kernels

import pytest


@pytest.fixture(scope="session")
def registered():
    """Every plugin, registered through the ``laughlab`` entry points as users get them."""
    from laughlab.core import plugins

    return plugins.registry()


@pytest.fixture(scope="session")
def hill_plugins(registered):
    """The Hill-torso plugins (``body=hill``, ``extractor=pressure``) from their entry points."""
    assert "hill" in registered["body"] and "pressure" in registered["extractor"]
    return registered


@pytest.fixture(autouse=True)
def _plugins_dir_unloaded():
    """Plugins a test loads from a ``plugins_dir`` outside the command line (a ``Session``, ``load_plugin_dirs``) are
    unloaded after it, as a process' end would, as ``fuzz.run_cli`` does for the command line: test_session's
    ``boom`` extractor was listed among another file's choices in the same worker (a clean clone's run)."""
    from laughlab.core import own_experiments
    from laughlab.core.plugins import pm

    before = {name for name, _ in pm.list_name_plugin()}
    yield
    for name, plugin in pm.list_name_plugin():
        if name not in before and name.startswith("laughlab_local_plugins."):
            pm.unregister(plugin)
            sys.modules.pop(name, None)
    own_experiments.forget_plugins_dirs()   # a plugins_dir's smoke.yaml refused every later experiment=smoke


@pytest.fixture(scope="module")
def lib():
    """The bundled clip library."""
    from laughlab.motion.clips import ClipLibrary

    return ClipLibrary.load()


#: the fuzz cases the workers ran (pytest-xdist): kind -> count, added up as each worker ends
_WORKER_FUZZ: dict = {}


def _fuzz_counts() -> dict:
    fuzz = sys.modules.get("fuzz")
    return dict(getattr(fuzz, "COUNTS", None) or {})


def pytest_sessionfinish(session):
    """In a pytest-xdist worker: hand the fuzz suite's counts to the controller."""
    if hasattr(session.config, "workeroutput"):
        session.config.workeroutput["fuzz_counts"] = _fuzz_counts()


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """In the pytest-xdist controller: add up a finished worker's fuzz counts."""
    for kind, n in (getattr(node, "workeroutput", None) or {}).get("fuzz_counts", {}).items():
        _WORKER_FUZZ[kind] = _WORKER_FUZZ.get(kind, 0) + n


def pytest_terminal_summary(terminalreporter):
    """The fuzz suite's case count (tests/test_fuzz.py), so CI's log says how many cases it tried, and
    which check the golden runs made (tests/test_golden.py: exact bytes or values within a tolerance)."""
    ran = {r.nodeid.split("::")[0] for rs in terminalreporter.stats.values() for r in rs if hasattr(r, "nodeid")}
    if "tests/test_golden.py" in ran:
        from golden import ATOL, RTOL, YAMNET_RUNS, exact_environment, expected_hashes

        exact, why = exact_environment()
        yamnet = expected_hashes(YAMNET_RUNS[0])[1] if exact else ""
        terminalreporter.write_line("golden: " + ("exact bytes (the locked environment)" if exact else
                                                  f"values within rtol {RTOL:g}, atol {ATOL:g} "
                                                  f"(not the locked environment: {why})")
                                    + (f"; the YAMNet runs ({', '.join(YAMNET_RUNS)}): {yamnet}" if yamnet else ""))
    counts = _fuzz_counts()
    for kind, n in _WORKER_FUZZ.items():
        counts[kind] = counts.get(kind, 0) + n
    if counts:
        terminalreporter.write_line(f"fuzz: {sum(counts.values())} cases, every one one line or finite output: "
                                    + "; ".join(f"{n} {k}" for k, n in sorted(counts.items())))
