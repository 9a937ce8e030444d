"""Running trials: one input x one plugin combination x one seed each.

Every trial composes its configuration exactly as the command line would
(the experiment's own overrides, then the condition's, then the input's and the
seed), runs the pipeline into its own folder, computes every registered metric
from the outputs and gives one record.  Trials run in parallel processes
(joblib); records are written to ``metrics.jsonl`` sorted by condition, input
and seed, so the file does not depend on the order in which trials finish.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from omegaconf import OmegaConf

from laughlab.core import blame, pipeline
from laughlab.core.errors import LaughlabError, RefusedFolder
from laughlab.core.overrides import override_key
from laughlab.core.progress import bar
from laughlab.harness.corpus import Item


@dataclass(frozen=True)
class Trial:
    """One trial: condition, input, seed, and where it writes."""

    condition: str
    item: Item
    seed: int
    overrides: tuple
    out_dir: str
    keep: bool = False
    plots: bool = False

    @property
    def key(self) -> tuple:
        return (self.condition, self.item.id, self.seed)


def _compose(overrides: list[str]):
    """The trial's configuration without ``hydra`` and ``harness`` (group choices composed once per process)."""
    from laughlab.core.config import compose_app

    return compose_app(overrides)


def _showcase_pdf(overrides, plots: bool) -> tuple:
    """``output.plots.pdf=true`` for a showcase run, unless the command line set ``output.plots.pdf`` itself."""
    told = any(override_key(o) == "output.plots.pdf" for o in overrides)
    return ("output.plots.pdf=true",) if plots and not told else ()


def run_trial(trial: Trial) -> dict:
    """Run one trial and return its record (metrics computed from its outputs)."""
    from laughlab.harness.metrics import compute
    from laughlab.harness.trialdata import TrialData

    out = Path(trial.out_dir)
    # a showcase run's figures go into the report, for print too: PDFs beside the PNGs, unless the command
    # line says output.plots.pdf=false (a quick look; until 2026-11-28 that was overridden)
    outputs = ("output=files",) if trial.plots else ("output=trial",)
    # the command line's output.plots.* (width=column) are for the showcase runs' figures: output=trial has none
    overrides = [o for o in trial.overrides if trial.plots or not override_key(o).startswith("output.plots.")]
    cfg = _compose([*overrides, *outputs, *_showcase_pdf(overrides, trial.plots)])
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    pipe = pipeline.build(cfg)
    try:
        pipeline.execute(pipe, out, OmegaConf.to_container(cfg, resolve=True))
    except Exception as exc:   # a plugin's exception: which trial (the line names the plugin and frame)
        where = getattr(exc, blame.WHERE, None)
        if where:
            setattr(exc, blame.WHERE, f"{where} in trial {trial.condition}/{trial.item.id} seed {trial.seed}")
        if isinstance(exc, blame.PluginBug):   # a plugin's value no writer takes: its line names the trial too
            exc.args = (f"in trial {trial.condition}/{trial.item.id} seed {trial.seed}, {exc}",)
        raise
    data = TrialData.load(out, trial.item.truth)
    why: dict = {}
    metrics = compute(data, why=why)
    record = {"condition": trial.condition, "input": trial.item.id, "profile": trial.item.profile,
              "seed": trial.seed, "duration_s": data.duration_s, "metrics": metrics}
    if why:   # a third-party metric that did not apply, and why (metrics.warn_unmeasured)
        record["metrics_na"] = why
    if trial.keep or trial.plots:
        record["run_dir"] = str(out)
    else:
        shutil.rmtree(out, ignore_errors=True)
    return record


def make_trials(items: list[Item], conditions: dict, seeds_for, base_overrides: list[str], out_dir: Path,
                keep: bool = False) -> list[Trial]:
    """The cross product of conditions, items and seeds.

    ``seeds_for(item)`` gives the run seeds of an item (a synthetic item's own
    seed; for recordings the experiment's seed list).
    """
    trials = []
    for cond, cond_overrides in conditions.items():
        for item in items:
            for seed in seeds_for(item):
                trials.append(Trial(cond, item, int(seed),
                                    (*base_overrides, *cond_overrides, *item.overrides, f"seed={int(seed)}"),
                                    str(out_dir / "trials" / cond / f"{item.id}-seed{int(seed)}"), keep))
    return trials


def progress_bar(total: int, desc: str, progress: bool):
    """A tqdm bar on a terminal; :class:`LogProgress` lines when stderr is not one; silence without ``progress``."""
    return bar(total if progress else None, desc, "trials", unit="trial", disable=not progress)


def ignore_stop_signals() -> None:
    """A trial process ignores Ctrl-C: the terminal's SIGINT reaches every process of the command, and the workers'
    own KeyboardInterrupt tracebacks followed the one line (a review); this process stops them and says it."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_trials(trials: list[Trial], jobs: int = 1, progress: bool = True, desc: str = "trials",
               on_record=None) -> list[dict]:
    """Run trials (in ``jobs`` processes); return their records sorted by condition, input and seed.

    ``on_record(trial, record)`` is called in this process as each trial completes (the experiment
    journals it, so an interrupted experiment resumes from there).
    """
    bar = progress_bar(len(trials), desc, progress)
    records = []
    by_key = {t.key: t for t in trials}
    try:
        if jobs <= 1:
            for t in trials:
                rec = run_trial(t)
                records.append(rec)
                if on_record is not None:
                    on_record(t, rec)
                bar.update()
        else:
            from joblib import Parallel, delayed

            for rec in Parallel(n_jobs=jobs, return_as="generator_unordered", initializer=ignore_stop_signals)(
                    delayed(run_trial)(t) for t in trials):
                records.append(rec)
                if on_record is not None:
                    on_record(by_key[(rec["condition"], rec["input"], rec["seed"])], rec)
                bar.update()
    finally:
        bar.close()
    return sorted(records, key=lambda r: (r["condition"], r["input"], r["seed"]))


def journal_records(path: Path) -> list[dict]:
    """The complete records of a ``metrics.jsonl`` (none if there is no file); a line cut by a kill is left out."""
    path = Path(path)
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:  # the last line of a killed run
            continue
    return out


class Journal:
    """``metrics.jsonl`` written as trials complete, so a stopped experiment resumes.

    Each line is a complete record with ``trial_hash`` (the trial's overrides) and ``input_sha256``
    (the recording's bytes, or the synthetic input's overrides) and the experiment's
    ``experiment_hash``; a line cut by a kill is ignored when the journal is read back.
    """

    def __init__(self, path: Path, experiment_hash: str, code: str = ""):
        self.path, self.experiment_hash, self.code = Path(path), experiment_hash, code
        self.stale = 0   # records of :meth:`done` left out: made by other plugin code

    def done(self) -> dict:
        """The complete records already journaled, by trial key; a different experiment refuses to mix.  Records
        made by other plugin code (``code``, :func:`plugin_code_hash`: a plugin fixed after a crash) are left out
        and counted in ``stale``, so their trials run again rather than mixing old and new code's numbers."""
        out = {}
        self.stale = 0
        for rec in journal_records(self.path):
            if rec.get("experiment_hash") != self.experiment_hash:
                raise RefusedFolder(f"{self.path.parent} holds an interrupted experiment with another configuration "
                                    "(every setting counts but harness.jobs and harness.plots, paths as written, and the "
                                    "overrides' order); "
                                    "resume it with its own command, or choose another hydra.run.dir, or add "
                                    "overwrite=true")
            if rec.get("code_hash", "") != self.code:
                self.stale += 1
                continue
            out[(rec["condition"], rec["input"], rec["seed"])] = rec
        return out

    def add(self, trial: Trial, record: dict) -> None:
        from laughlab.harness.results import json_clean

        record.update(trial_hash=trial_hash(trial), input_sha256=input_hash(trial.item),
                      experiment_hash=self.experiment_hash, code_hash=self.code)
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(json.dumps(json_clean(record), sort_keys=True) + "\n")
            f.flush()
            os.fsync(f.fileno())


def plugin_code_hash() -> str:
    """A short hash of the source files of every registered plugin (built-in, installed or from plugins_dir) and of
    every ``.py`` file of the package each comes from: a resumed experiment keeps only the trials this code made (a
    review resumed after editing a plugin and got one results.json of two codes' numbers; a plugin authors' review:
    an edit to a helper module of an installed plugin's package, ``laughlab_giggle/curves.py``, was not seen)."""
    import inspect
    import sys

    from laughlab.core import plugins

    files = {}   # module name -> its file: the names, not the paths, so a moved checkout resumes its runs
    for named in plugins.registry().values():
        for info in named.values():
            obj = getattr(info.obj, "fn", info.obj)   # a Metric's function
            try:
                path = inspect.getsourcefile(obj)
            except TypeError:
                continue
            if path:
                files[obj.__module__] = path
    # the plugins' packages, helpers imported lazily too; laughlab's own method code is laughlab's version (its
    # commit in results.json), as before: a resume after an edit of cli.py would otherwise run every trial again
    for top in sorted({m.split(".")[0] for m in files} - {"laughlab"}):
        for root in getattr(sys.modules.get(top), "__path__", None) or ():
            for f in sorted(Path(root).rglob("*.py")):
                files.setdefault(".".join((top, *f.relative_to(root).with_suffix("").parts)), str(f))
    h = hashlib.sha256()
    for module, path in sorted(files.items()):
        h.update(module.encode() + b"\0" + Path(path).read_bytes())
    return h.hexdigest()[:16]


def run_overrides(overrides) -> list[str]:
    """The overrides that reach a trial's run (``laughlab.core.config.reaches_run``, the rule :func:`_compose`
    applies): ``harness.*`` ones never do (the harness' values are hashed as the experiment's), so
    ``harness.jobs`` or ``harness.plots`` given again differently still resumes."""
    from laughlab.core.config import reaches_run

    return [o for o in overrides if reaches_run(o.split("=", 1)[0])]


def trial_hash(trial: Trial) -> str:
    return hashlib.sha256(json.dumps([trial.condition, trial.item.id, trial.seed, run_overrides(trial.overrides)])
                          .encode()).hexdigest()[:16]


#: file hashes already computed, by (path, size, mtime): one read per recording per process
_FILE_HASHES: dict = {}


def input_hash(item: Item) -> str:
    """sha256 of a recording's bytes, or of a synthetic input's overrides.

    Keyed by what the hash is of, not by the input's id: a sweep runs its experiments in one process, and the
    same id (``mild-s00``) can be another input there (another ``harness.corpus.duration_s``)."""
    path = item.path
    if path is None or not Path(path).exists():
        return hashlib.sha256(json.dumps(list(item.overrides)).encode()).hexdigest()
    st = Path(path).stat()
    key = (str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
    if key not in _FILE_HASHES:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _FILE_HASHES[key] = h.hexdigest()
    return _FILE_HASHES[key]


def write_records(path: Path, records: list[dict]) -> None:
    """``metrics.jsonl``: one JSON record per trial (NaN written as null)."""
    from laughlab.harness.results import json_clean

    tmp = path.with_name(f".{path.name}.part")
    with open(tmp, "w", encoding="utf-8") as f:
        for r in records:
            f.write(json.dumps(json_clean(r), sort_keys=True) + "\n")
    tmp.replace(path)


def check_conditions(conditions) -> dict:
    if not conditions:
        raise LaughlabError("the experiment has no conditions (harness.conditions)")
    return {str(k): [str(o) for o in (v or [])] for k, v in dict(conditions).items()}
