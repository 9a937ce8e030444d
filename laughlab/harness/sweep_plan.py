"""A sweep's planned points against its finished ones: the report of a half-finished sweep says which are missing.

Hydra writes ``multirun.yaml`` into the sweep folder before any job starts: its ``hydra.overrides.task`` (the
command line) and ``hydra.sweeper.params`` (an experiment's own sweep) list every point the sweep will run, as
the cross product of the swept values (Hydra's basic sweeper).  A point is finished when its folder's run marker
says so (:func:`laughlab.core.rundir.finished`: an experiment's or a plain run's; only ``results.json`` counted,
and a finished sweep of plain runs was '0 finished', a diff review); its swept values are in its
``.hydra/overrides.yaml``.  A point stopped by Ctrl-C, or never started, is not finished, so :func:`unfinished`
names it.
"""
from __future__ import annotations

import shlex
from itertools import product
from pathlib import Path

from laughlab.core.errors import LaughlabError
from laughlab.core.overrides import COMMAND_ONLY, override_key

#: override keys that are not a point's parameters (the report's points leave them out too): the experiment, Hydra's
#: own, and the command's (``overwrite``, ``progress``: a sweep run again with overwrite=true read it as swept)
NOT_PARAMS = ("experiment", "hydra", *COMMAND_ONLY)


def multirun(root: Path) -> dict | None:
    """The ``hydra`` section of the sweep's ``multirun.yaml`` in ``root``; None when it has none readable."""
    import yaml

    path = root / "multirun.yaml"
    if not path.is_file():
        return None
    try:
        return (yaml.safe_load(path.read_text(encoding="utf-8")) or {}).get("hydra") or {}
    except (OSError, yaml.YAMLError, AttributeError):
        return None


def planned_points(root: Path) -> list[dict[str, str]] | None:
    """Each planned point's swept values, ``{key: value}`` as its ``.hydra/overrides.yaml`` writes them, in the
    sweeper's order; None when ``root`` has no readable ``multirun.yaml`` or a sweep the parser cannot list."""
    plan = _plan(root)
    return None if plan is None else plan[1]


def _plan(root: Path) -> tuple[dict[str, str], list[dict[str, str]]] | None:
    """(the parameters every planned point shares, each point's swept values), or None (:func:`planned_points`)."""
    from laughlab.core.sweepcheck import sweep_values

    hydra = multirun(Path(root))
    if hydra is None:
        return None
    task = [str(o) for o in ((hydra.get("overrides") or {}).get("task") or [])]
    given = {override_key(o) for o in task}
    params = (hydra.get("sweeper") or {}).get("params") or {}
    if any(override_key(o) == "experiment" and "," in o for o in task):
        params = {}   # a sweep over experiments composes the sweeper without them (laughlab.core.sweepcheck)
    extra = [f"{k}={v}" for k, v in params.items() if override_key(k) not in given]
    try:
        base, sweeps = sweep_values(task + extra)
    except LaughlabError:
        return None
    keys = list(sweeps)
    swept = {override_key(values[0]) for values in sweeps.values()}
    fixed = {k: v for k, v in _params(_as_written(base)).items() if override_key(k) not in swept}
    return fixed, [dict(v.split("=", 1) for v in combo) for combo in product(*(sweeps[k] for k in keys))]


def _as_written(overrides: list[str]) -> list[str]:
    """``overrides`` as Hydra's basic sweeper writes them into a point's ``overrides.yaml`` (``harness.plots=false``
    is written ``harness.plots=False``); one it cannot read, as given."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    out = []
    for o in overrides:
        try:
            (ov,) = OverridesParser.create().parse_overrides([o])
            out.append(f"{ov.get_key_element()}={ov.get_value_element_as_str()}")   # ~key: ~key=null, as Hydra
        except (HydraException, ValueError):
            out.append(o)
    return out


def _params(overrides: list) -> dict[str, str]:
    return dict(str(o).split("=", 1) for o in overrides if "=" in str(o) and not str(o).startswith(NOT_PARAMS))


def stale_points(root: Path, params: dict[Path, dict[str, str]]) -> list[Path]:
    """The point folders of ``params`` (``{folder: its parameters}``, without :data:`NOT_PARAMS`, as a point's
    ``overrides.yaml`` read by :func:`_params`) that are no point of the sweep in ``root``: an
    earlier sweep's, left there when ``overwrite=true`` ran a sweep of fewer or other points over it (a sweep
    researcher's review: its report mixed both sweeps, unsaid).  None are stale when the plan is unknown."""
    plan = _plan(Path(root))
    if plan is None:
        return []
    fixed, points = plan
    wanted = [{**fixed, **point} for point in points]
    return [job for job, p in params.items() if p not in wanted]


def _job_params(job: Path) -> dict[str, str] | None:
    import yaml

    try:
        return _params(yaml.safe_load((job / ".hydra" / "overrides.yaml").read_text(encoding="utf-8")) or [])
    except (OSError, yaml.YAMLError, TypeError):
        return None


def unfinished(root: Path) -> tuple[int, list[str]] | None:
    """``(planned points, [each unfinished point])`` of the sweep in ``root``, or None when its plan is unknown
    (no ``multirun.yaml``).  A point is named by its values, after its folder when Hydra made one
    (``2 (scheduler.overrule_c=1.5 scheduler.decrease_per_s=20)``: a review found ``2`` alone beside the others'
    values).  A folder matches a point when it has the plan's every parameter, the fixed ones too (an earlier
    sweep's folder with other fixed values is not this sweep's point: :func:`stale_points`)."""
    root = Path(root)
    plan = _plan(root)
    if plan is None:
        return None
    fixed, points = plan
    jobs = {p: _job_params(p) for p in sorted({h.parent for h in root.glob("**/.hydra")}) if p != root}
    jobs = {job: params for job, params in jobs.items() if params is not None}
    from laughlab.core.rundir import finished

    done = [params for job, params in jobs.items() if finished(job)]
    missing = []
    for point in points:
        want = {**fixed, **point}
        if want in done:
            continue
        folder = next((job for job, params in jobs.items() if params == want), None)
        values = " ".join(f"{k}={v}" for k, v in point.items())
        missing.append(f"{folder.relative_to(root)} ({values})" if folder is not None else values)
    return len(points), missing


def swept_keys(root: Path) -> list[str]:
    """The keys the sweep in ``root`` sweeps over more than one value (none when its plan is unknown)."""
    plan = planned_points(Path(root)) or []
    keys = dict.fromkeys(k for point in plan for k in point if not override_key(k).startswith(NOT_PARAMS))
    return [k for k in keys if len({point.get(k) for point in plan}) > 1]


def missing_text(root: Path, planned: int, missing: list[str]) -> str:
    """One line: how many points are unfinished, which (the first 6), and how to finish them."""
    shown = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more" if len(missing) > 6 else "")
    what = (f"a sweep with no finished point (0 of {planned})" if len(missing) >= planned
            else f"{len(missing)} of {planned} sweep points unfinished ({shown})")
    return f"{root}: {what}: run the sweep's command again to finish it: {sweep_command(root)}"


def sweep_command(root: Path) -> str:
    """The sweep's own command, from ``multirun.yaml`` (empty when there is none): its overrides (not ``overwrite``
    or ``progress``), then Hydra's own as given (``hydra/launcher=submitit_slurm``, ``hydra.launcher.*``: a reader
    reran a Slurm or joblib sweep in one process, the launcher was not named), and the folder it is in."""
    hydra = multirun(Path(root))
    if hydra is None:
        return ""
    given = hydra.get("overrides") or {}
    # without the command's overwrite=true (run again, it would redo the finished points, not resume) and progress
    task = [str(o) for o in given.get("task") or [] if override_key(o) not in ("overwrite", "progress")]
    task = [o for o in [*task, *map(str, given.get("hydra") or [])]
            if not o.startswith(("hydra.mode=", "hydra.sweep.dir="))] + [f"hydra.sweep.dir={root}"]
    return f"python -m laughlab -m {' '.join(shlex.quote(o) for o in task)}"


def interrupted_line(argv: list[str]) -> str:
    """The one line of a sweep stopped by Ctrl-C: how many of its points finished, and how to resume it (a sweep
    into a folder of its own, ``hydra.sweep.dir=``, resumes by the same command)."""
    words = progress_words(argv)
    return f"interrupted{';' if words.startswith('the ') else ':'} {words}"


def progress_words(argv: list[str]) -> str:
    """How far the sweep of ``argv`` got and how to resume it: ``2 of 9 points finished; run the same command again
    to resume`` (also a sweep whose job ended without a result, :mod:`laughlab.core.launchers`)."""
    given = next((a.split("=", 1)[1] for a in argv if a.startswith("hydra.sweep.dir=")), None)
    state = unfinished(Path(given).expanduser()) if given else None
    if state is None:
        return ("the finished points are kept in the sweep's folder (a sweep resumes into its own "
                "hydra.sweep.dir=DIR, given again with the same command)")
    planned, missing = state
    return f"{planned - len(missing)} of {planned} points finished; run the same command again to resume"


def partial_warning(root: Path) -> None:
    """After the report of a half-finished sweep: one warning line on stderr (the report says PARTIAL)."""
    import sys

    state = None if (root / "results.json").exists() else unfinished(root)
    if state and state[1]:
        print(f"laughlab: warning: {missing_text(root, *state)}; the report covers only the finished points",
              file=sys.stderr)
