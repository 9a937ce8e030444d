"""A sweep (``python -m laughlab -m ...``) checked before any job starts.

Each value of each swept key, from the command line or the experiment's ``hydra.sweeper.params``, is checked
as a single run checks its configuration (:func:`laughlab.cli.preflight`: the keys exist, every plugin takes
its parameters, the experiment's corpus and conditions), with the other swept keys at their first values.
A mistyped key or a bad value then stops the sweep in one line before the launcher starts a job, instead of
Hydra's own multi-line error, or a job failing part way through the sweep after others had begun (with the
joblib launcher the other points were stopped mid-run, leaving empty results behind).

Values are checked one key at a time, not every combination: the checks are of single parameters, and a
sweep of thousands of points on a cluster costs a check per value (about 0.1 s each), not per point.  A
sweep the parser cannot list (``interval(...)`` for an optimising sweeper) is left out of the checks and to
its jobs.  A sweep over a config group (``experiment=a,b``) leaves the experiments' ``hydra.sweeper.params``
unswept, as Hydra does (it composes the sweeper's configuration without swept groups), so they are not read.
"""
from __future__ import annotations

from typing import Callable

from laughlab.core.errors import LaughlabError
from laughlab.core.overrides import given_value, override_key, without_command_keys


def sweep_values(overrides: list[str]) -> tuple[list[str], dict[str, list[str]]]:
    """(the overrides with every sweep at its first value, {key: its sweep's values as overrides ``key=value``})
    for the sweeps the parser can list; a sweep it cannot list is left out of both."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except HydraException as exc:
        from laughlab.core.overridehints import unreadable_override

        raise LaughlabError(unreadable_override(str(exc), overrides)
                            or f"cannot read the overrides: {str(exc).splitlines()[0]}") from None
    base, sweeps = [], {}
    for ov in parsed:
        key = ov.get_key_element()
        values = None
        if ov.is_sweep_override():
            try:
                values = [f"{key}={v}" for v in ov.sweep_string_iterator()]
            except HydraException:   # interval(...): for an optimising sweeper, left to the jobs
                continue
        if values:
            sweeps[key] = values
            base.append(values[0])
        else:
            base.append(ov.input_line)
    return base, sweeps


def check_sweep(overrides: list[str], preflight: Callable[[list[str]], object]) -> int:
    """Check every value of every swept key with ``preflight`` (which raises LaughlabError); the number of
    configurations checked.  The experiment's own ``hydra.sweeper.params`` are read from the configuration
    the first values compose; a key swept on the command line replaces the experiment's sweep of it, as
    Hydra's basic sweeper does."""
    from omegaconf import OmegaConf

    from laughlab.core.config import is_group

    check_sweep_folder(overrides)
    base, sweeps = sweep_values(overrides)
    if any(override_key(k) == "experiment" for k in sweeps):
        # Hydra composes the sweep's own configuration (for its sweeper and launcher) without the swept group, where
        # harness.* does not exist: its "Could not override" came after the check (a review)
        plain = [o for o in base if override_key(o).startswith("harness.") and not o.startswith("++")]
        if plain:
            raise LaughlabError(f"{plain[0]} with a sweep over experiments: Hydra composes the sweep itself without "
                                f"an experiment, where harness does not exist; write ++{plain[0].lstrip('+')} "
                                "(++ sets a key whether it exists or not), or sweep each experiment on its own")
    try:
        cfg = preflight(base)
    except LaughlabError as exc:
        raise LaughlabError(_quoting_the_sweep(str(exc), overrides, sweeps)) from None
    check_launcher(cfg.hydra.get("launcher") or {})
    check_viewer(cfg)
    params = None if any(is_group(override_key(k)) for k in sweeps) else cfg.hydra.get("sweeper", {}).get("params")
    params = OmegaConf.to_container(params, resolve=False) if OmegaConf.is_config(params) else dict(params or {})
    given = {override_key(k) for k in sweeps} | {override_key(o) for o in base}
    extra = [f"{k}={v}" for k, v in params.items() if override_key(k) not in given]
    more_base, more = sweep_values(extra)
    base, sweeps = base + more_base, {**sweeps, **more}
    checked = 1
    if more_base:
        preflight(base)
        checked += 1
    for key, values in sweeps.items():
        first = base.index(values[0])
        for value in values[1:]:
            point = base[:first] + [value] + base[first + 1:]
            try:
                preflight(point)
            except LaughlabError as exc:
                raise LaughlabError(f"sweep value {value}: {exc}") from None
            checked += 1
    return checked


def check_sweep_folder(overrides: list[str]) -> None:
    """A ``hydra.sweep.dir`` that holds a sweep of other settings (its ``multirun.yaml``) is refused before any job,
    unless ``overwrite=true``: its points are numbered as that sweep's, so point 1 of the new sweep met point 1 of
    the old one part way through, with a line that did not say why (a researcher's review).  The same command
    again (a sweep resumed) passes: its finished points are skipped."""
    from pathlib import Path

    import yaml

    given = given_value(overrides, "hydra.sweep.dir")
    if not given or str(given_value(overrides, "overwrite")).lower() == "true":
        return
    folder = Path(given).expanduser()
    try:
        before = yaml.safe_load((folder / "multirun.yaml").read_text(encoding="utf-8"))["hydra"]["overrides"]["task"]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return   # no earlier sweep there (or not one laughlab can read): the jobs' own checks hold
    # Hydra's own settings (hydra.launcher.n_jobs, hydra/launcher=joblib) are not in multirun.yaml's task list, and
    # the command's (overwrite, progress) change no point's results
    now = {override_key(o): o for o in without_command_keys(overrides)}
    old = {override_key(o): o for o in without_command_keys(o for o in before if isinstance(o, str))} \
        if isinstance(before, list) else {}
    if sorted(now.values()) == sorted(old.values()):
        return
    said = [f"{o} (there: {old[k].split('=', 1)[1] if '=' in old[k] else old[k]})" if k in old else o
            for k, o in now.items() if old.get(k) != o]
    said += [f"{o} there, not now" for k, o in old.items() if k not in now]
    raise LaughlabError(f"{folder} holds a sweep of other settings ({', '.join(said[:3])}"
                        f"{', ...' if len(said) > 3 else ''}): its points are numbered as that sweep's; choose "
                        "another hydra.sweep.dir, or add overwrite=true to run these points over it")


def _quoting_the_sweep(message: str, overrides: list[str], sweeps: dict[str, list[str]]) -> str:
    """``message`` with a fix it words on a sweep's first value (``write detector.hop_s=0.5 (without +)``, from the
    check of the first values) worded on the whole sweep the user gave (``detector.hop_s=0.5,1``)."""
    for values in sweeps.values():
        given = next((o for o in overrides if override_key(o) == override_key(values[0])), None)
        if given is not None:
            message = message.replace(f"write {values[0].lstrip('+')} ", f"write {given.lstrip('+')} ")
    return message


def check_launcher(launcher) -> None:
    """The launcher's settings that would otherwise fail in its own traceback once the sweep starts: the joblib
    launcher's ``n_jobs`` (0 is joblib's ValueError), and the Slurm launcher off a cluster (submitit's "Could not
    detect srun" after Hydra had written the sweep's folder)."""
    import shutil

    target = str(launcher.get("_target_", ""))
    if "joblib" in target.lower():
        n = launcher.get("n_jobs")
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n == 0):
            raise LaughlabError(f"hydra.launcher.n_jobs={n}: the joblib launcher runs that many points at once, a "
                                "whole number other than 0 (-1: one per core)")
    if "SlurmLauncher" in target and shutil.which("sbatch") is None:
        raise LaughlabError("hydra/launcher=submitit_slurm submits every point with Slurm's sbatch, which this machine "
                            "does not have: run the command on the cluster's login node, or hydra/launcher="
                            "submitit_local to run the same jobs here")


def check_viewer(cfg) -> None:
    """``output=viewer`` in a sweep: a file or synthetic input waits for a page to open before its first frame
    (``output.viewer.wait=auto``), so the sweep stood still at its first point until someone opened a browser."""
    viewer = None if cfg.get("harness") else (cfg.get("output") or {}).get("viewer")   # an experiment runs trials
    if viewer is not None and viewer.get("wait") == "auto" and (cfg.get("input") or {}).get("name") != "mic":
        raise LaughlabError("output=viewer in a sweep: each point would wait for a page to open before it starts; "
                            "set output.viewer.wait=off (each point runs at once, paced at the frame clock; "
                            "output.viewer.realtime=off: as fast as computed) or output.viewer.wait=on, or drop "
                            "output=viewer")
