"""Running an experiment: the corpus x conditions x seeds, then results, plots and a summary.

An experiment is a config under ``conf/experiment/`` with a ``harness``
section, plus optional code under ``experiments/`` (``harness.module``) that
adds experiment-specific numbers and figures::

    harness:
      name: energy_vs_concat
      module: laughlab_experiments.energy_vs_concat   # optional: def extra(run) -> dict
      conditions: {energy: [scheduler=energy], concat: [scheduler=concat]}
      corpus: {profiles: [mild, intense], seeds: 20, duration_s: 30.0, folder: null}
      run_seeds: [0]          # seeds of recordings (synthetic inputs use their own seed)
      showcase: mixed-s00     # the input drawn for every condition (Fig. 4.2 style)
      jobs: 2                 # parallel trial processes
      keep_trials: false      # keep every trial's outputs
      plots: true             # draw plots/metrics.png at the end (false: results.json only, for sweeps;
                              # ``python -m laughlab report`` draws the figures from results.json later)
"""
from __future__ import annotations

import hashlib
import importlib
import json
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import OmegaConf

from laughlab.core.errors import LaughlabError, nearest, shown_names
from laughlab.core.overrides import without_command_keys
from laughlab.core.summary import counted
from laughlab.harness import results as res
from laughlab.harness.corpus import Item, build_corpus, synthetic_items
from laughlab.harness.metrics import registered, warn_unmeasured
from laughlab.harness.runner import (Journal, Trial, check_conditions, input_hash, make_trials, plugin_code_hash,
                                     run_overrides, run_trials, trial_hash, write_records)
from laughlab.harness.settings import check_harness


@dataclass
class ExperimentRun:
    """What experiment code sees: the config, the output folder, the records."""

    cfg: object
    out_dir: Path
    harness: dict
    conditions: dict
    items: list
    records: list = field(default_factory=list)
    base_overrides: list = field(default_factory=list)  # the command line's overrides, repeated in trials
    showcase: dict = field(default_factory=dict)  # condition -> run dir of the showcase trial


def experiment_module(name: str | None):
    """Import an experiment's code (``harness.module``); None when it has none.

    A module defining ``run(cfg, out_dir)`` replaces the trial harness with its
    own procedure; one defining ``extra(run) -> dict`` adds numbers to results.json.
    """
    if not name:
        return None
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise LaughlabError(f"experiment module {name!r} not found: {exc}") from None


def _task_overrides() -> list[str]:
    """The command line's overrides of this (Hydra) job, to repeat in every trial."""
    try:
        from hydra.core.hydra_config import HydraConfig

        ovs = list(HydraConfig.get().overrides.task)
    except ValueError:  # not under Hydra (tests call run_experiment directly)
        return []
    return without_command_keys(ovs)


def not_fetched_line(name: str, sets: list, n_inputs: int) -> str:
    """The one line an experiment prints when it runs without the real corpus."""
    from laughlab.corpora.fetch import data_dir

    return (f"{name}: the real corpus is not fetched (in {data_dir()}), so its sets ({', '.join(sets)}) are left "
            f"out: running the other {n_inputs} inputs. To add them: python -m laughlab corpus fetch (once), then "
            "run this command again into a new hydra.run.dir")


def showcase_item(h: dict, items: list[Item]) -> Item | None:
    """The input ``harness.showcase`` names (None if it names none): one of the corpus' items, or a synthetic
    input ``PROFILE-sSEED`` outside it.  The command line calls it before any trial (a mistyped name was
    found only after every trial had run)."""
    from laughlab.synth.laughter import PROFILES

    show = h.get("showcase")
    if not show:
        return None
    item = next((i for i in items if i.id == show), None)
    if item is None and "-s" in show:  # a synthetic input outside the corpus
        prof, _, seed = show.rpartition("-s")
        if seed.isdigit() and prof in PROFILES:
            item = synthetic_items([prof], [int(seed)], float((h.get("corpus") or {}).get("duration_s", 30.0)))[0]
    if item is None:   # the nearest named first (a plugin author's review: mixed-10dB-00 with mixed-20dB-00 cut off)
        ids = [i.id for i in items]
        near = nearest(show, ids)
        meant = f"did you mean {near!r}? " if near else ""
        raise LaughlabError(f"harness.showcase {show!r} is not an input of the corpus ({meant}{len(ids)} inputs: "
                            f"{shown_names(ids)}) nor a synthetic one (PROFILE-sSEED: {', '.join(PROFILES)}); set one, "
                            "or harness.showcase=null")
    return item


def run_experiment(cfg, out_dir: Path, base_overrides: list[str] | None = None, progress: bool = True) -> dict:
    """Run the experiment described by ``cfg.harness`` into ``out_dir``; return results.json's content."""
    h = OmegaConf.to_container(cfg.harness, resolve=True)
    check_harness(h, added=set())   # the command line's + keys were checked before it ran (cli.preflight)
    name = h.get("name") or "experiment"
    conditions = check_conditions(h.get("conditions"))
    skipped: list = []  # corpus files left out (harness.corpus.on_bad=skip), with the reason
    not_fetched: list = []  # real sets left out: the real corpus is not fetched (harness.corpus.real.if_missing)
    items = build_corpus(h.get("corpus") or {}, skipped, not_fetched)
    if not_fetched:
        print(not_fetched_line(name, not_fetched, len(items)), file=sys.stderr)
    if skipped:   # said as it starts, not only in results.json (a new-user review found them nowhere on screen)
        print(f"{name}: left out {counted(len(skipped), 'bad corpus file')} (harness.corpus.on_bad=skip): "
              + "; ".join(f"{b['file']}: {b['reason']}" for b in skipped[:3]) + ("; ..." if len(skipped) > 3 else "")
              + " (all of them in results.json)", file=sys.stderr)
    run_seeds = [int(s) for s in h.get("run_seeds") or [0]]
    base = _task_overrides() if base_overrides is None else list(base_overrides)
    out_dir = Path(out_dir)
    jobs = int(h.get("jobs", 1))

    def seeds_for(item: Item):
        return [item.seed] if item.seed is not None else run_seeds

    run = ExperimentRun(cfg, out_dir, h, conditions, items, base_overrides=base)
    trials = make_trials(items, conditions, seeds_for, base, out_dir, bool(h.get("keep_trials", False)))
    # resume: trials already journaled in metrics.jsonl (same experiment, same trial, same input bytes) are kept
    same = {k: v for k, v in h.items() if k not in ("jobs", "plots")}  # how a run is carried out, not what it is
    key = {"harness": same, "base": run_overrides(base)}
    journal = Journal(out_dir / "metrics.jsonl",
                      hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:16],
                      plugin_code_hash())
    out_dir.mkdir(parents=True, exist_ok=True)
    done = journal.done()
    if journal.stale:
        print(f"{name}: {journal.stale} finished trial(s) were made by other plugin code (a plugin changed since): "
              "running them again", file=sys.stderr)

    def finished(t: Trial) -> bool:
        rec = done.get(t.key)
        return rec is not None and rec.get("trial_hash") == trial_hash(t) and rec.get("input_sha256") == input_hash(t.item)

    kept = [done[t.key] for t in trials if finished(t)]
    todo = [t for t in trials if not finished(t)]
    if kept:
        print(f"{name}: resuming: {len(kept)} of {counted(len(trials), 'trial')} were done, running {len(todo)}",
              file=sys.stderr)
    journal.path.write_text("".join(json.dumps(r, sort_keys=True) + "\n" for r in kept),
                            encoding="utf-8")  # drop stale lines
    new = run_trials(todo, jobs, progress, desc=name, on_record=journal.add)
    run.records = sorted([*kept, *new], key=lambda r: (r["condition"], r["input"], r["seed"]))
    write_records(out_dir / "metrics.jsonl", run.records)
    warn_unmeasured(run.records)
    _remove_empty_dirs(out_dir / "trials")

    shown = showcase_item(h, items)
    if shown is not None:
        plots = out_dir / "plots"
        plots.mkdir(parents=True, exist_ok=True)
        # a recording's annotation to its run, so that its figures shade the bouts as a synthetic input's do
        truth = (f"input.truth={shown.truth}",) if shown.truth and "input=file" in shown.overrides else ()
        seed = seeds_for(shown)[0]
        shows = [Trial(c, shown, seed, (*base, *ov, *shown.overrides, *truth, f"seed={seed}"),
                       str(out_dir / "showcase" / c), keep=True, plots=True) for c, ov in conditions.items()]
        for rec in run_trials(shows, jobs, progress, desc="showcase"):
            run.showcase[rec["condition"]] = rec["run_dir"]
            for fig in sorted(Path(rec["run_dir"], "plots").glob("*.p[nd][gf]")):   # the PNGs and their PDFs
                shutil.copyfile(fig, plots / f"{rec['condition']}_{fig.name}")

    metric_info = {n: {"higher_is_better": m.higher_is_better, "units": m.units, "description": m.description,
                       **({"search": list(m.search)} if getattr(m, "search", None) else {})}
                   for n, m in registered().items()}
    module = experiment_module(h.get("module"))
    if progress:  # the steps below take 5-30 s on 2 cores: say what is going on
        steps = ["means and bootstrap intervals",
                 *(["the experiment's own numbers"] if hasattr(module, "extra") else []),
                 *(["plots/metrics.png and timing.png"] if h.get("plots", True) else [])]
        print(f"{name}: summarising {counted(len(run.records), 'trial')}: {', '.join(steps)}", file=sys.stderr)
    results, by_profile = res.aggregate(run.records, list(metric_info))
    extra = {}
    if module is not None and hasattr(module, "extra"):
        extra = module.extra(run) or {}
    doc = {
        "schema": res.SCHEMA,
        "experiment": name,
        "date": res.now_iso(),
        "git_hash": res.git_hash(),
        "git_diff_sha256": res.git_diff_sha256(),
        "versions": res.versions(),
        "plugins": res.plugin_origins(),
        "config": OmegaConf.to_container(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]), resolve=True),
        "corpus": {"inputs": [i.id for i in items], "profiles": sorted({i.profile for i in items}),
                   "seeds": sorted({r["seed"] for r in run.records}), "skipped": skipped,
                   "not_fetched": not_fetched},
        "conditions": conditions,
        "showcase": shown.id if shown is not None else None,
        "n_trials": len(run.records),
        "metrics": metric_info,
        "results": results,
        "by_profile": by_profile,
        "extra": extra,
    }
    res.write_json(out_dir / "results.json", doc)
    if h.get("plots", True):
        from laughlab.harness.report import comparison_figure

        width = OmegaConf.select(cfg, "output.plots.width", default="page")   # as the showcase runs' figures
        comparison_figure(doc, out_dir / "plots" / "metrics.png", width=width)
        comparison_figure(doc, out_dir / "plots" / "timing.png", timing=True, width=width)   # it varies run to run
    return doc


def _remove_empty_dirs(root: Path) -> None:
    """Remove the folders of trials whose outputs were not kept."""
    if not root.is_dir():
        return
    for d in sorted(root.rglob("*"), key=lambda p: len(p.parts), reverse=True):
        if d.is_dir() and not any(d.iterdir()):
            d.rmdir()
    if not any(root.iterdir()):
        root.rmdir()
