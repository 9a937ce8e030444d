"""The fuzz harness of tests/test_fuzz.py: cases generated from the composed configuration, and the invariant.

Every case ends one of two ways, and nothing else is allowed:

* exit 0, every number in channels.csv finite; or
* a non-zero exit with exactly one line on stderr, starting ``laughlab: error:`` and ending in a
  newline, and no partial output (the run directory absent, or as it was);

and in both, no traceback and no warning text (a warning that Python would print on a terminal:
anything but the Deprecation/Pending/Import/Resource categories, which it hides by default).

Two ways of running a case, both in-process:

* :func:`run_cli`: ``laughlab.cli.main(argv)`` itself, catching ``SystemExit`` (the whole command:
  composition, preflight, the run directory, cleanup);
* :func:`run_fast`: the configuration as the harness composes a trial's (``laughlab.core.config.compose_app``:
  each choice of plugins composed once, the case's values applied to a copy by Hydra's own code), then
  the run built and executed as the CLI's task does, its errors printed as the CLI prints them.  Hydra's
  composition (0.25-0.3 s a case) is the only step it skips, so a thousand parameter cases fit in CI's time.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path

#: cases run in this session, by kind (printed at the end of the session by tests/conftest.py)
COUNTS: dict = {}
#: values every parameter is tried with: wrong types, NaN/inf, out of range, empty, very long
BAD_VALUES = ("abc", "nan", "inf", "-inf", "-1e9", "1e9", "0", "-1", "[1,2]", "''", "null", "true",
              "{a: 1}", "x" * 2000, "1e308", "0.5")
#: the top-level keys of config.yaml (hydra's own are Hydra's business)
TOP_LEVEL = ("seed", "fps", "progress", "overwrite", "plugins_dir")
#: top-level keys the command line acts on before it composes the configuration (run through :func:`run_cli`)
CLI_ONLY = ("plugins_dir",)
GROUPS = ("input", "extractor", "detector", "face", "body", "scheduler", "output")
HIDDEN = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)
#: every case: short, quiet, the trial outputs (channels, events, motion) unless it is about output
BASE = ("input.duration_s=0.3", "progress=off", "output=trial")


@dataclass
class Outcome:
    code: int
    stdout: str
    stderr: str
    warnings: list = field(default_factory=list)
    exception: str = ""


@contextlib.contextmanager
def _sinks_in_this_process():
    """``LAUGHLAB_WORKERS=0`` while a case runs, unless the environment sets it (every sink in this process: no
    fork of a test worker); unset again afterwards, so that the child processes other tests start run as a
    user's would."""
    before = os.environ.get("LAUGHLAB_WORKERS")
    os.environ["LAUGHLAB_WORKERS"] = "0" if before is None else before
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("LAUGHLAB_WORKERS", None)


def _capture(fn) -> Outcome:
    out, err = io.StringIO(), io.StringIO()
    code, exc = 0, ""
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _sinks_in_this_process(), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fn()
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except BaseException as e:  # noqa: BLE001 - anything else is what a user would see as a traceback
            code, exc = 1, f"{type(e).__name__}: {e}"
    shown = [f"{w.category.__name__}: {w.message}" for w in caught if not issubclass(w.category, HIDDEN)]
    return Outcome(code, out.getvalue(), err.getvalue(), shown, exc)


def run_cli(argv: list[str]) -> Outcome:
    """``python -m laughlab ARGV`` in this process.  Plugins it loads from a ``plugins_dir`` are unloaded after
    it, as a process' end would (another test's ``laughlab plugins`` must not list them)."""
    import sys

    from laughlab import cli
    from laughlab.core.plugins import pm

    before = {name for name, _ in pm.list_name_plugin()}
    try:
        return _capture(lambda: cli.main(list(argv)))
    finally:
        for name, plugin in pm.list_name_plugin():
            if name not in before and name.startswith("laughlab_local_plugins."):
                pm.unregister(plugin)
                sys.modules.pop(name, None)


def run_fast(overrides: list[str], run_dir: Path) -> Outcome:
    """The case with the harness' trial composition (``compose_app``: each choice of plugins composed once,
    the values applied by Hydra's own code), then built and run as the CLI does."""
    from omegaconf import OmegaConf

    from laughlab import cli
    from laughlab.core import pipeline
    from laughlab.core.config import compose_app
    from laughlab.core.errors import LaughlabError

    def case():
        try:
            cfg = compose_app(overrides)
        except LaughlabError as exc:
            cli.fail(str(exc))
        try:
            pipe = pipeline.build(cfg)
        except LaughlabError as exc:
            cli.fail(str(exc))
        try:
            pipeline.execute(pipe, run_dir, OmegaConf.to_container(cfg, resolve=True))
        except LaughlabError as exc:
            shutil.rmtree(run_dir, ignore_errors=True)  # what the CLI's task does with a failed run's folder
            cli.fail(str(exc))

    return _capture(case)


def check(outcome: Outcome, run_dir: Path | None, what: str) -> list[str]:
    """The invariant; the list of ways ``outcome`` breaks it (empty: it holds)."""
    problems = []
    text = outcome.stdout + outcome.stderr
    if outcome.exception:
        problems.append(f"uncaught {outcome.exception}")
    if "Traceback" in text:
        problems.append("a traceback reached the terminal")
    if outcome.warnings:
        problems.append(f"warning text: {outcome.warnings[0]}")
    if outcome.code == 0:
        if run_dir is not None and (run_dir / "channels.csv").exists():
            bad = _nonfinite_csv(run_dir / "channels.csv")
            if bad:
                problems.append(f"non-finite value in channels.csv: {bad}")
    else:
        lines = outcome.stderr.splitlines()
        if len(lines) != 1 or not lines[0].startswith("laughlab: error:"):
            problems.append(f"exit {outcome.code} with stderr {outcome.stderr[:300]!r} (not one error line)")
        elif not outcome.stderr.endswith("\n"):
            problems.append("the error line has no final newline")
        if run_dir is not None and run_dir.exists() and any(p.name not in PRE_EXISTING for p in run_dir.iterdir()):
            problems.append(f"partial output left: {sorted(p.name for p in run_dir.iterdir())[:5]}")
    return [f"{what}: {p}" for p in problems]


#: entries a case's run directory may hold before the case (none: every case gets a new one)
PRE_EXISTING: frozenset = frozenset()


def _nonfinite_csv(path: Path) -> str:
    import numpy as np

    with path.open() as f:
        header = f.readline().strip().split(",")
        for i, line in enumerate(f):
            for name, cell in zip(header, line.strip().split(",")):
                try:
                    v = float(cell)
                except ValueError:
                    continue  # a label column
                if not math.isfinite(v):
                    return f"{name} at row {i}"
    return "" if np.isfinite(0.0) else "numpy"


def parameter_cases() -> list[tuple[tuple, str]]:
    """Every (group choices, dotted key) of the composed configuration: each option of each group, and the top level.

    Generated from the configuration itself, so a new plugin (a YAML file or a registered
    plugin without one) or a new parameter is fuzzed the day it lands.
    """
    from omegaconf import OmegaConf

    from laughlab.core.config import compose_app, group_options, register_plugin_configs

    register_plugin_configs()
    cases = [((), key) for key in TOP_LEVEL]
    for group in GROUPS:
        for option in group_options(group):
            choices = (f"{group}={option}",)
            if (group, option) == ("input", "file"):
                continue  # its one key (path) is fuzzed with files by the audio cases
            cfg = compose_app(choices)
            node = OmegaConf.to_container(cfg[group], resolve=False)
            for key in _leaves(node):
                if key != "name":
                    cases.append((choices, f"{group}.{key}"))
    return cases


def _leaves(node, prefix: str = "") -> list[str]:
    if isinstance(node, dict):
        out = []
        for k, v in node.items():
            out += _leaves(v, f"{prefix}.{k}" if prefix else str(k)) if isinstance(v, dict) and v else \
                [f"{prefix}.{k}" if prefix else str(k)]
        return out
    return [prefix] if prefix else []


def overrides_for(choices: tuple, key: str, value: str) -> list[str]:
    """The case's command line: the base, the plugin choices, the key set to the value."""
    base = [b for b in BASE if not (b.startswith("output=") and any(c.startswith("output=") for c in choices))]
    if any(c.startswith("input=") for c in choices) and not any(c == "input=synthetic" for c in choices):
        base = [b for b in base if not b.startswith("input.duration_s")]
        if "input=mic" in choices:
            base.append("input.duration_s=0.3")
    if "output=viewer" in choices:   # the live viewer would wait for a page to open, on a port others may hold
        base += ["output.viewer.wait=off", "output.viewer.realtime=off", "output.viewer.port=0"]
    return [*choices, *base, f"{key}={value}"]
