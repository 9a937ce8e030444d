import os

os.environ.setdefault("MPLBACKEND", "Agg")

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


@pytest.fixture(scope="module")
def lib():
    """The bundled clip library."""
    from laughlab.motion.clips import ClipLibrary

    return ClipLibrary.load()


def pytest_terminal_summary(terminalreporter):
    """The fuzz suite's case count (tests/test_fuzz.py), so CI's log says how many cases it tried, and
    which check the golden runs made (tests/test_golden.py: exact bytes or values within a tolerance)."""
    golden = __import__("sys").modules.get("test_golden")
    if golden is not None:
        terminalreporter.write_line("golden: " + ("exact bytes (the locked environment)" if golden.EXACT else
                                                  f"values within rtol {golden.RTOL:g}, atol {golden.ATOL:g} "
                                                  f"(not the locked environment: {golden.WHY})"))
    fuzz = __import__("sys").modules.get("fuzz")
    counts = getattr(fuzz, "COUNTS", None)
    if counts:
        terminalreporter.write_line(f"fuzz: {sum(counts.values())} cases, every one one line or finite output: "
                                    + "; ".join(f"{n} {k}" for k, n in sorted(counts.items())))
