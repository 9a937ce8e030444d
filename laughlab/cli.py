"""Command line: ``python -m laughlab [overrides]``, ``python -m laughlab plugins``.

User errors end with one line on stderr (``laughlab: error: ...``), exit status
2, no traceback and no half-written run directory.  The configuration is
composed and every plugin built and checked *before* Hydra creates the run
directory, so most errors leave nothing behind; an error during the run removes
what the run wrote.
"""
from __future__ import annotations

import os
import shlex
import shutil
import sys
import time
from pathlib import Path

from laughlab.core import blame, callerstate, clock, interrupts, quiet
from laughlab.core.config import (CONFIG_MODULE, GROUP_KINDS, NOT_IN_A_RUN, check_overrides,  # noqa: F401
                                  compose_config, conf_dir, given_twice, group_options, load_plugin_dirs,
                                  register_plugin_configs)
from laughlab.cli_help import check_flags, check_sweep_flags, help_text, local_options
from laughlab.core.errors import LaughlabError, RefusedFolder, os_error_line, shown_path  # noqa: F401
from laughlab.core.jobdir import anchor_paths, anchor_run_dir
from laughlab.core.summary import duration_text, summary_line  # noqa: F401 - summary_line: tests use it here


_STARTED_AS_PROCESS = False   # python -m laughlab, not a call from another program (tests)
#: the run directory this process holds (laughlab.core.rundir), from before Hydra writes into it to the end
_CLAIM = None
#: when the command started (time.monotonic()): the process' start; None in a sweep (each job's summary times it)
_STARTED: float | None = None
_HYDRA_FLAGS = {"--help", "-h", "--hydra-help", "--cfg", "-c", "--info", "-i", "--version",
                "--shell-completion", "-sc", "--resolve", "--package", "-p", "--config-path", "-cp",
                "--config-name", "-cn", "--config-dir", "-cd", "--experimental-rerun"}


def fail(message: str, code: int = 2) -> "None":
    if interrupts.received:  # whatever failed after a Ctrl-C or SIGTERM failed because of it
        message, code = ("interrupted" if code != 130 else message), 130
    if code != 130 or not interrupts.in_worker():   # a sweep's job in a launcher's process: the sweep says it once
        quiet.say(f"laughlab: error: {message}")   # on the real stderr even while fd 2 is silenced (core/quiet.py)
    if code == 130:
        interrupts.clear_exit_flag()
    sys.exit(code)


def _overrides(argv: list[str]) -> list[str]:
    return [a for a in argv if not a.startswith("-")]


def preflight(argv: list[str]):
    """Check everything a run needs before Hydra writes anything; the composed configuration."""
    from omegaconf import OmegaConf

    from laughlab.core import pipeline

    overrides = _overrides(argv)
    load_plugin_dirs(overrides)
    register_plugin_configs()
    check_overrides(overrides)
    cfg = compose_config(overrides, job_name="cli")
    if "plots" in (cfg.get("output") or {}):
        from laughlab.core import background

        background.warm(background.PLOTTING)   # the helper imports matplotlib while the run is built
    run_dir = Path(cfg.hydra.run.dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise LaughlabError(f"hydra.run.dir {run_dir} exists and is not a folder")
    conditions = None
    if cfg.get("harness"):
        from laughlab.harness.corpus import build_corpus
        from laughlab.harness.experiment import experiment_module, showcase_item
        from laughlab.harness.preflight import check_condition_runs, check_single_run_keys, resolved_harness
        from laughlab.harness.runner import check_conditions
        from laughlab.harness.settings import check_harness

        harness = resolved_harness(cfg)
        check_harness(harness, {o.split("=", 1)[0].split(".")[1] for o in overrides if o.startswith("+harness.")})
        module = experiment_module(cfg.harness.get("module"))
        if hasattr(module, "check"):   # the keys the experiment adds (experiments/stimuli.py: preset, loudness...)
            module.check(harness)
        check_single_run_keys(overrides)   # seed=, output=: a single run's, refused
        if module is None or not hasattr(module, "run"):  # trial experiments: conditions x corpus
            conditions = check_conditions(cfg.harness.get("conditions"))
            harness = OmegaConf.to_container(cfg.harness, resolve=True)
            showcase_item(harness, build_corpus(harness.get("corpus") or {}))
        if cfg.get("character") is not None:   # e.g. experiment=stimuli: its trials' sinks load it later
            from laughlab.avatar.load import load_character

            load_character(cfg.character)
    else:
        pipeline.check_character_used(cfg)
    anchor_run_dir(cfg)   # hydra.job.chdir=true: the run folder named from here
    full = cfg
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in NOT_IN_A_RUN])
    if conditions:   # trials run only the conditions' runs: build those (the base run: only to word an error)
        check_condition_runs(overrides, conditions, lambda: pipeline.build(cfg).source.close())
    else:
        pipeline.build(cfg).source.close()
    return full


def run_composed(cfg) -> None:
    """Run one job on the configuration :func:`preflight` composed, as ``hydra.main`` would: the same steps as
    Hydra's own single run (``hydra.core.utils.run_job``: the run directory, ``.hydra/`` with config, hydra and
    overrides, the job's logging), without composing the configuration twice more (about 0.3 s of every start-up).
    """
    from hydra._internal.callbacks import Callbacks
    from hydra.core.utils import run_job
    from hydra.types import HydraContext, RunMode
    from omegaconf import open_dict

    with open_dict(cfg):
        cfg.hydra.mode = RunMode.RUN
    callbacks = Callbacks(cfg)
    callbacks.on_run_start(config=cfg, config_name="config")
    ret = run_job(hydra_context=HydraContext(config_loader=None, callbacks=callbacks), task_function=task,
                  config=cfg, job_dir_key="hydra.run.dir", job_subdir_key=None, configure_logging=True)
    callbacks.on_run_end(config=cfg, config_name="config", job_return=ret)
    _ = ret.return_value  # re-raises what the job raised


def task(cfg) -> dict:
    """The Hydra task: build and run the pipeline into the run directory."""
    from hydra.core.hydra_config import HydraConfig

    out_dir = Path(HydraConfig.get().runtime.output_dir)
    if HydraConfig.get().job.chdir:   # the job runs in out_dir: the files the user named, from where they ran it
        anchor_paths(cfg, HydraConfig.get().runtime.cwd)
    t0 = time.monotonic() if _STARTED is None else _STARTED
    cfg_hash = config_hash(cfg)
    with interrupts.worker_job():
        return _task(cfg, out_dir, t0, cfg_hash)


def _task(cfg, out_dir: Path, t0: float, cfg_hash: str) -> dict:
    from omegaconf import OmegaConf

    from laughlab.core import pipeline, rundir

    global _CLAIM
    try:
        if _CLAIM is None:  # a sweep's job: Hydra made the folder and wrote .hydra/ into it
            _CLAIM = rundir.claim(out_dir, bool(cfg.get("overwrite", False)), ours=frozenset({".hydra"}),
                                  done_if=cfg_hash, writes=pipeline.planned_files(cfg), where="hydra.sweep.dir",
                                  resumable=bool(cfg.get("harness")))
            if _CLAIM.done:  # the same sweep run again: this job finished before
                print(f"laughlab: {out_dir} already holds this job's finished run; skipped")
                return {}
        if cfg.get("harness"):
            from laughlab.harness.experiment import experiment_module, run_experiment
            from laughlab.harness.settings import check_harness

            check_harness(OmegaConf.to_container(cfg.harness, resolve=True), added=set())   # + keys: preflight
            module = experiment_module(cfg.harness.get("module"))
            if module is not None and hasattr(module, "run"):  # an experiment with its own procedure
                doc = module.run(cfg, out_dir)
                _CLAIM.finish(cfg_hash)
                _finished()
                return doc
            doc = run_experiment(cfg, out_dir, progress=cfg.get("progress", "auto") != "off")
            _CLAIM.finish(cfg_hash)
            _finished()
            # a sweep: one hint at its end
            hint = "" if _in_sweep() else f"; report: python -m laughlab report {shlex.quote(str(out_dir))}"
            _done_line(f"{doc['experiment']}: {doc['n_trials']} trials in {duration_text(time.monotonic() - t0)} -> "
                       f"{out_dir / 'results.json'}{hint}")
            return doc
        pipe = pipeline.build(cfg)
        from laughlab.harness.results import provenance

        made = provenance(pipe.source.params.path if pipe.source.name == "file" else None)
        metrics = pipeline.execute(pipe, out_dir, OmegaConf.to_container(cfg, resolve=True), {"provenance": made})
        _CLAIM.finish(cfg_hash)
        _finished()
        _done_line(summary_line(cfg, metrics, out_dir, time.monotonic() - t0, skip=_CLAIM.user_files))
        return metrics
    except rundir.InUse as exc:  # another process' run: touch nothing of it but what Hydra wrote over
        rundir.restore_hydra(out_dir, running=True)
        fail(str(exc))
    except LaughlabError as exc:
        if cfg.get("harness") and _CLAIM is not None and (out_dir / "metrics.jsonl").exists() \
                and not isinstance(exc, RefusedFolder):
            fail(_stopped(cfg, out_dir, str(exc)), code=exc.exit_code)   # after trials: kept, resumable
        if isinstance(exc, RefusedFolder) and _CLAIM is not None and _CLAIM.resumed:   # another experiment's journal:
            fail(str(exc), code=exc.exit_code)   # its folder stays for its own command (a review: the marker went)
        # a sweep job refused by a finished run: Hydra wrote this job's .hydra/ over that run's; put it back
        if _CLAIM is not None or not rundir.restore_hydra(out_dir):
            _remove_new_run_dir(out_dir)
        fail(str(exc), code=exc.exit_code)
    except (KeyboardInterrupt, Exception) as exc:
        what, code = _fault(exc, out_dir, cfg)
        what = _stopped(cfg, out_dir, what)
        if code == 130 and _in_sweep():   # the sweep says it once, in the command's process (_main)
            raise KeyboardInterrupt from None
        fail(what, code=code)
    finally:
        if _CLAIM is not None:
            _CLAIM.release()
            _CLAIM = None


def _read_paths(cfg) -> tuple:
    """The files a run reads that the user named: the input file and its truth, the avatar, the TextGrid, the
    plugins."""
    found = [cfg.get("input", {}).get("path"), cfg.get("input", {}).get("truth"), cfg.get("character"),
             cfg.get("extractor", {}).get("textgrid"), cfg.get("plugins_dir")]
    found += [(sink or {}).get("character") for sink in (cfg.get("output") or {}).values()   # a sink's own avatar
              if hasattr(sink, "get")]
    return tuple(str(p) for p in found if isinstance(p, str) and p)


def _finished() -> None:
    """A single run is done (marker complete): a stop signal is let go from now on (not in a sweep)."""
    if not _in_sweep():
        interrupts.finish(whole_process=_STARTED_AS_PROCESS)


def _done_line(text: str) -> None:
    """A finished run's closing line; a closed stdout (``| head``, ``| true``) is no fault of the run, which is
    kept (a review: the broken pipe was taken for a failed write, the marker removed and the files left)."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        quiet.stdout_gone()


def _in_sweep() -> bool:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    return HydraConfig.get().mode == RunMode.MULTIRUN


def _fault(exc: BaseException, where: Path | str, cfg) -> tuple[str, int]:
    """What a run stopped by ``exc`` says, and its exit status: an interrupt (or anything after one) 130, a
    file-system fault (a full disk, a file size limit, a folder that went away) 2, a plugin's exception
    (:mod:`laughlab.core.blame`) 1 after the plugin's lines of the traceback.  Anything else is a bug,
    re-raised: its traceback is what a report needs, but a single run's folder is first left as a failed run
    leaves it (an earlier run it was replacing put back)."""
    if interrupts.interrupted(exc):
        return "interrupted", 130
    if isinstance(exc, OSError):   # outside the run's folder: read or written (an input gone from a node)
        outside = exc.filename is not None and not Path(os.path.abspath(str(exc.filename))).is_relative_to(
            os.path.abspath(str(where)))
        return os_error_line(exc, where, verb="cannot use" if outside else "cannot write"), 2
    if blame.line(exc):   # a plugin's bug: its own lines of the traceback, then the line naming it
        if blame.trace(exc):   # (none when out of memory)
            print(blame.trace(exc), file=sys.stderr)
        return blame.line(exc), 1
    if _CLAIM is not None and not cfg.get("harness"):
        _remove_new_run_dir(Path(where))
    raise exc


def config_hash(cfg) -> str:
    """A short hash of the run's resolved configuration (without overwrite and progress)."""
    import hashlib
    import json

    from omegaconf import OmegaConf

    doc = OmegaConf.to_container(cfg, resolve=True)
    for k in ("overwrite", "progress", "hydra"):
        doc.pop(k, None)
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _stopped(cfg, out_dir: Path, what: str) -> str:
    """Clean up after a run stopped by a signal or a file-system fault; the one line that says so.

    A single run removes what it wrote.  An experiment keeps its journal of finished trials (stimuli: videos) and
    its unfinished marker (any ``results.json`` goes: it is written only when every trial is in), so the same
    command resumes it."""
    if cfg.get("harness"):
        from laughlab.core import rundir

        (out_dir / "results.json").unlink(missing_ok=True)
        if _CLAIM is not None:
            _CLAIM.keep()   # what it has written so far: a file the user adds now stays theirs
        aside = out_dir / rundir.PREVIOUS
        kept = f" (the run it replaces is kept in {aside} until it finishes)" if aside.is_dir() else ""
        done = "videos rendered" if cfg.harness.get("name") == "stimuli" else "finished trials"   # (a review)
        return f"{what}; the {done} are kept: run the same command again to resume{kept}"
    _remove_new_run_dir(out_dir)
    return f"{what}; the run's partial output was removed"


def _remove_new_run_dir(out_dir: Path) -> None:
    """Remove what Hydra created for a failed run (.hydra/), our marker, and the folder if we made it."""
    shutil.rmtree(out_dir / ".hydra", ignore_errors=True)
    if _CLAIM is not None:
        _CLAIM.abandon()
    else:
        try:
            out_dir.rmdir()
        except OSError:
            pass


#: the commands besides a run: each module's ``main(args)``, imported when its command is used
COMMANDS = {
    "report": "laughlab.harness.report_cli",  # a Markdown report with figures of a run or a sweep
    "detect": "laughlab.detector.detect",   # laughter segments of recordings
    "corpus": "laughlab.corpora.cli",       # fetch|list|lock: the real development corpus
    "study": "laughlab.study.cli",          # build|serve|analyze|power: the perception study
    "view": "laughlab.viewer.cli",          # the run on the character (or the user's avatar) in a browser
}


def _command(name: str):
    import importlib

    return importlib.import_module(COMMANDS[name]).main


def main(argv: list[str] | None = None) -> None:
    """The command line; a Ctrl-C or SIGTERM at any moment ends in one line and exit 130."""
    global _STARTED, _STARTED_AS_PROCESS
    with callerstate.kept(in_process=argv is not None):   # in-process: the caller's logging and signals kept
        interrupts.install()  # SIGTERM cleans up as Ctrl-C does
        interrupts.reset()
        quiet.closed_streams_to_devnull()
        _STARTED_AS_PROCESS = argv is None
        _STARTED = clock.process_start() if argv is None else time.monotonic()  # argv given: called in-process
        try:
            _main(list(sys.argv[1:] if argv is None else argv))
        except SystemExit:
            raise
        except BaseException as exc:  # before the run directory was claimed, or after it was released
            if not interrupts.interrupted(exc):
                raise
            fail("interrupted", code=130)


def _main(argv: list[str]) -> None:
    commands = ("detect", "report", "corpus", "study", "view")
    if argv == ["help"] or {"--help", "-h"} & set(argv) and argv[0] not in (*commands, "plugins"):
        try:   # with settings too: Hydra's generic help replaced laughlab's (reviews: alone, after input.path=x.wav)
            print(help_text(local_options(argv)))
        except LaughlabError as exc:
            fail(str(exc))
        except BrokenPipeError:  # piped into head: stop quietly
            quiet.stdout_gone()
        return
    for name in commands:
        if argv[:1] == [name]:
            try:
                _command(name)(argv[1:])
            except LaughlabError as exc:
                fail(str(exc))
            except BrokenPipeError:  # e.g. piped into head: stop quietly
                quiet.stdout_gone()
            except OSError as exc:
                fail(os_error_line(exc, argv[1] if len(argv) > 1 else "."))
            return
    if argv[:1] == ["plugins"] or ("plugins" in argv and all(a == "plugins" or a.startswith("plugins_dir=")
                                                            for a in argv)):   # not 'face=x plugins': a run's typo
        rest = [a for a in argv if not a.startswith("plugins_dir=")]   # the command wherever it is among them (a
        rest.remove("plugins")                                           # review: "no argument (got 'plugins')")
        if rest[:1] in (["-h"], ["--help"]):
            print("usage: python -m laughlab plugins [plugins_dir=DIR]\n\nList every plugin: its kind, name, origin "
                  "and the setting that chooses it (with plugins_dir=DIR, your own too).")
            return
        if rest:   # a review: 'plugins bogus' printed the table
            fail(f"plugins takes no argument but plugins_dir=DIR (got {rest[0]!r}); see python -m laughlab plugins "
                 "--help")
        try:
            load_plugin_dirs(argv)
            from laughlab.core.plugin_table import list_plugins

            list_plugins()
        except LaughlabError as exc:
            fail(str(exc))
        except BrokenPipeError:  # e.g. piped into head: stop quietly
            quiet.stdout_gone()
        return
    if argv and "=" in argv[0] and set(argv[1:]) & set(commands):   # plugins_dir=my report RUN: Hydra's "Error
        fail(f"{min(set(argv[1:]) & set(commands))} is a command: it comes first")   # parsing override" (a review)
    if argv and "=" not in argv[0] and not argv[0].startswith(("~", "-")):   # e.g. a mistyped command
        fail(f"unknown command {argv[0]!r}: the commands are {', '.join(commands)}, plugins; a run "
             "takes overrides key=value (python -m laughlab --help)")
    if argv == ["--version"]:
        from laughlab import __version__

        print(f"laughlab {__version__}")
        return
    argv = _absolute_plugins_dir(argv)
    try:
        check_flags(argv, _HYDRA_FLAGS | {"-m", "--multirun", "-r", "--run"})
        check_sweep_flags(argv)
    except LaughlabError as exc:
        fail(str(exc))
    multirun = any(a in ("-m", "--multirun") for a in argv)
    if multirun:
        global _STARTED
        _STARTED = None
    hydra_only = any(a.split("=")[0] in _HYDRA_FLAGS for a in argv)
    for line in given_twice(_overrides(argv)):   # a group chosen twice: the last wins, said once (a review)
        print(line, file=sys.stderr, flush=True)
    if not multirun and not hydra_only and "input=mic" not in argv:
        from laughlab.core import background

        background.start()  # forked now, before heavy imports and threads (preflight has it warm the plots)
    try:
        if not multirun and not hydra_only:
            cfg = preflight(argv)
        else:   # a sweep, or Hydra's own flags (--cfg job): its plugins_dir's plugins before Hydra composes
            load_plugin_dirs(_overrides(argv))
            register_plugin_configs()
            check_overrides(_overrides(argv))
            if not multirun:   # --cfg job: a mistyped key in one line, as a run says it (Hydra's took five lines)
                compose_config([o for o in _overrides(argv) if "=" in o or o[:1] == "~"], job_name="cli")
            elif not hydra_only:   # every swept value, before the launcher starts a job
                from laughlab.core.sweepcheck import check_sweep

                check_sweep(_overrides(argv), preflight)
    except blame.PluginBug as exc:   # a plugin that raised as it was built: its own lines, then the line naming it
        if blame.trace(exc):
            print(blame.trace(exc), file=sys.stderr)
        fail(str(exc), code=exc.exit_code)
    except LaughlabError as exc:
        fail(str(exc))
    except OSError as exc:  # a path the user gave that the system refuses (too long, no permission, ...)
        fail(os_error_line(exc, ".", verb="cannot use"))
    if not multirun and not hydra_only:
        global _CLAIM
        from laughlab.core import pipeline, rundir

        try:  # one writer per run directory, before anything is written into it
            _CLAIM = rundir.claim(Path(cfg.hydra.run.dir), bool(cfg.get("overwrite", False)),
                                  writes=pipeline.planned_files(cfg), resumable=bool(cfg.get("harness")),
                                  reads=_read_paths(cfg))
        except LaughlabError as exc:
            fail(str(exc))
        try:
            run_composed(cfg)
        except (KeyboardInterrupt, Exception) as exc:  # outside the task: Hydra writing .hydra/, say
            what, code = _fault(exc, cfg.hydra.run.dir, cfg)
            if _CLAIM is not None:  # the task had not finished: clean up as it would have
                what = _stopped(cfg, Path(cfg.hydra.run.dir), what)
                _CLAIM.release()
                _CLAIM = None
            fail(what, code=code)
        return
    import hydra

    sys.argv = [sys.argv[0], *argv]
    from laughlab.core import rundir

    from laughlab.core.launchers import JobLost, guard_submitit
    from laughlab.harness.sweep_plan import progress_words

    before = rundir.sweep_state(argv) if multirun else None
    guard_submitit(lambda: progress_words(argv))   # a submitit job without a result: one line, not a traceback
    out = sys.stdout = quiet.PipeMayClose(sys.stdout)   # --info | head: Hydra's lines into a closed pipe, quietly
    try:
        hydra.main(config_path=f"pkg://{CONFIG_MODULE}", config_name="config", version_base="1.3")(task)()
    except BaseException as exc:   # one line for the whole sweep: how far it got (its jobs say nothing, fail())
        if isinstance(exc, JobLost) and not interrupts.received:
            fail(str(exc))
        if isinstance(exc, SystemExit) or not interrupts.interrupted(exc):
            raise
        from laughlab.harness.sweep_plan import interrupted_line

        fail(interrupted_line(argv), code=130)
    finally:
        out.flush()
        sys.stdout = out.stream
        after = rundir.sweep_state(argv) if before is not None else None
        for job in [j for j, m in (after[2] if after else {}).items() if before[2].get(j) == m]:
            # no run finished there, but Hydra may have written this sweep's .hydra/ over the finished run's (a
            # job stopped when another was refused): the point's own configuration is put back
            rundir.restore_hydra(before[0].parent / job)
        if after is not None and after[2] == before[2]:
            # no job ran (each was refused, or had finished before): the sweep folder still describes the
            # earlier sweep, so its multirun.yaml, which Hydra wrote at the start, is put back
            before[0].write_bytes(before[1])


def _absolute_plugins_dir(argv: list[str]) -> list[str]:
    """``plugins_dir=my`` as the absolute path of an existing folder: what results.json, the report's run line and a
    resumed experiment compare then hold from any working directory (a review: a relative path was recorded as typed,
    and the same folder spelled otherwise refused the resume)."""
    import os
    import re

    out = []
    for a in argv:
        key, eq, value = a.partition("=")
        if eq and key.lstrip("+") == "plugins_dir" and value and Path(value).expanduser().is_dir():
            full = os.path.abspath(Path(value).expanduser())
            if re.fullmatch(r"[A-Za-z0-9_./-]+", full):   # else left as typed: Hydra's grammar reads it only quoted
                a = f"{key}={full}"
        out.append(a)
    return out
