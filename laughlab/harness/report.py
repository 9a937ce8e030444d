"""Reports: Markdown tables and figures from a results directory or a sweep directory.

``python -m laughlab report RUN_DIR [--out DIR]`` reads ``RUN_DIR/results.json``
(one experiment) or every ``*/results.json`` below ``RUN_DIR`` (a Hydra
multirun sweep) and writes ``RUN_DIR/report/README.md`` with its figures (``--out DIR``: into
``DIR``, e.g. ``--out reports/<experiment>`` for the reports committed with laughlab).
"""
from __future__ import annotations

import os
import math
import shlex
import shutil
from pathlib import Path

from laughlab.core.errors import LaughlabError, shown_names
from laughlab.core.summary import counted
from laughlab.harness.report_format import EDGE, KEY_METRICS, at_search_edge, edge_note  # noqa: F401 (KEY_METRICS)
from laughlab.harness.report_format import DETECTOR_OWN
from laughlab.harness.report_recordings import recordings_table
from laughlab.harness.report_format import check_panels, vacuous, vector_link
from laughlab.harness.report_format import fmt as _fmt
from laughlab.harness.report_format import heading as _heading
# the figure and what it reads of the results: here too, where the report's callers have always found them
from laughlab.harness.report_figure import (FEW, comparison_figure, condition_colors,  # noqa: F401
                                            conditions_of, is_compute, metric_order, same_everywhere)
from laughlab.harness.results import made_by, read_results, separated
from laughlab.harness.sweep_report import sweep_report

def table_metrics(doc: dict) -> list[str]:
    """The metrics the results table shows: measured under some condition and not the same under all."""
    gone = set(unmeasured(doc))
    return [m for m in metric_order(doc) if m not in gone and not same_everywhere(doc, m)]


def _results_table(doc: dict) -> list[str]:
    """The metrics that differ between the conditions: one column per condition, the best in bold when
    its interval is apart from the others' (:func:`_clear_best`)."""
    conds = conditions_of(doc)
    lines = ["| metric | units | " + " | ".join(f"{c} mean [95% CI]" for c in conds) + " |",
             "|---|---|" + "---|" * len(conds)]
    edge = []
    for m in table_metrics(doc):
        info = doc["metrics"][m]
        best = _clear_best(doc, m, conds)
        cells = [f"**{_cell(doc['results'][c][m])}**" if c == best else _cell(doc["results"][c][m]) for c in conds]
        marks = [at_search_edge(info, doc["results"][c][m]) for c in conds]
        cells = [f"{cell} {EDGE}" if mark else cell for cell, mark in zip(cells, marks)]
        edge += [m] if any(marks) else []
        lines.append(f"| {_heading(m, info)} | {info['units']} | " + " | ".join(cells) + " |")
    return lines + (["", edge_note(edge, doc["metrics"])] if edge else [])


def unmeasured(doc: dict) -> list[str]:
    """The metrics with no value under any condition (e.g. false starts on coughs when the corpus holds no
    cough): the report names them in one line instead of a row of n/a."""
    return [m for m in metric_order(doc) if not any(doc["results"][c][m]["n"] for c in conditions_of(doc))]


def _clear_best(doc: dict, metric: str, conds: list[str]) -> str | None:
    """The condition with the best mean of ``metric`` when its 95 % interval is apart from every other
    condition's (:func:`~laughlab.harness.results.separated`); None when the intervals overlap, the
    metric has no better direction, fewer than two conditions have a value, or one of them has fewer than ``FEW``
    trials."""
    if doc["metrics"][metric]["higher_is_better"] is None or is_compute(metric):
        return None
    rs = {c: doc["results"][c][metric] for c in conds}
    have = [c for c, r in rs.items() if r["n"] and r["mean"] is not None and math.isfinite(r["mean"])
            and not vacuous(doc, metric, c)]
    # a single trial's "interval" is its value: two of them never overlap, so one trial apiece bolded a winner every
    # time (a new-user review); two trials' [0, 0] did too (a data user's review): a best needs FEW (10) trials
    # under every condition compared, the number below which a cell says its n
    if len(have) < 2 or any(rs[c]["n"] < FEW for c in have):
        return None
    sign = 1 if doc["metrics"][metric]["higher_is_better"] else -1
    best = max(have, key=lambda c: sign * rs[c]["mean"])
    return best if all(separated(rs[best], rs[c]) for c in have if c != best) else None


def _cell(r: dict) -> str:
    if not r["n"]:
        return "n/a"
    few = f" (n={r['n']})" if r["n"] < FEW else ""
    return f"{_fmt(r['mean'])} [{_fmt(r['ci95'][0])}, {_fmt(r['ci95'][1])}]{few}"


def _same_table(doc: dict) -> list[str]:
    """The metrics the same under every condition, once each (empty when there are none)."""
    same = [m for m in metric_order(doc) if same_everywhere(doc, m)]
    if not same:
        return []
    first = conditions_of(doc)[0]
    lines = ["These metrics came out the same under every condition (the same trials, mean and 95% CI), so "
             "they are left out of the table and the figure above:", "",
             "| metric | units | every condition: mean [95% CI] |", "|---|---|---|"]
    for m in same:
        info = doc["metrics"][m]
        ns = sorted({doc["results"][c][m]["n"] for c in conditions_of(doc)})
        cell = _cell(doc["results"][first][m]) if len(ns) == 1 else \
            _cell({**doc["results"][first][m], "n": FEW}) + f" (every trial; n={ns[0]}-{ns[-1]} by condition)"
        lines.append(f"| {_heading(m, info)} | {info['units']} | {cell} |")
    return lines


def _profile_table(doc: dict, metric: str) -> list[str]:
    conds = [c for c in conditions_of(doc) if c in doc["by_profile"]]
    profiles = sorted({p for c in conds for p in doc["by_profile"][c]})
    lines = ["| profile | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for p in profiles:
        lines.append(f"| {p} | " + " | ".join(_fmt(doc["by_profile"][c].get(p, {}).get(metric)) for c in conds) + " |")
    return lines


def _trials_line(doc: dict) -> str:
    """How the trials come about: inputs, runs of the recordings, conditions (a review: with two run seeds a
    recording is run twice, and '4 inputs x 2 conditions' did not add up to 14 trials)."""
    n, inputs, conds = doc["n_trials"], len(doc["corpus"]["inputs"]), max(len(doc["conditions"]), 1)
    seeds = doc["corpus"]["seeds"]
    seed_text = (f"seed {seeds[0]}" if len(seeds) == 1 or seeds[0] == seeds[-1] else f"seeds {seeds[0]}..{seeds[-1]}")
    runs = n // conds
    run_seeds = ((doc.get("config") or {}).get("harness") or {}).get("run_seeds") or []
    how = (f"{counted(runs, 'run')} of {counted(inputs, 'input')}, the recordings once per run seed "
           f"({', '.join(map(str, run_seeds))})" if runs != inputs and run_seeds else counted(inputs, "input"))
    return (f"- trials: {n} ({how} x {counted(conds, 'condition')}; profiles {', '.join(doc['corpus']['profiles'])}; "
            f"{seed_text})")


def _base_line(doc: dict) -> list[str]:
    """The plugins every condition starts from (a review: energy_vs_concat's shared extractor=phoneme, set by the
    experiment's defaults, was said nowhere in its report)."""
    from laughlab.core.summary import CHAIN

    cfg = doc.get("config") or {}
    picked = [f"{g}={cfg[g]['name']}" for g in CHAIN
              if isinstance(cfg.get(g), dict) and cfg[g].get("name")]
    return [f"- every condition starts from `{' '.join(picked)}` (its overrides replace these)"] if picked else []


def _flat(d: dict, prefix: str = "") -> dict:
    """A nested mapping's leaves by dotted key: ``{'a': {'b': 1}}`` -> ``{'a.b': 1}``."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _extra_lines(key: str, value) -> list[str]:
    """An experiment's extra numbers: scalars as a list, lists of records and mappings of records as tables
    (a review: a mapping of mappings was printed as a Python dict with 17 digits)."""
    if not isinstance(value, dict):
        return [f"- {key}: {_fmt(value) if isinstance(value, float) else value}", ""]
    lines = [f"### {key}", ""]
    tables = []
    for k, v in value.items():
        if isinstance(v, list) and v and isinstance(v[0], dict):
            tables.append((k, v))
        elif isinstance(v, dict) and v and all(isinstance(x, dict) for x in v.values()):
            tables.append((k, [{"": name, **_flat(rec)} for name, rec in v.items()]))
        elif isinstance(v, dict):
            lines.append(f"- {k}: " + ", ".join(f"{a} {_fmt(b) if isinstance(b, float) else b}"
                                                 for a, b in _flat(v).items()))
        else:
            lines.append(f"- {k}: {_fmt(v) if isinstance(v, float) else v}")
    lines.append("")
    for k, rows in tables:
        cols = list(dict.fromkeys(c for r in rows for c in r))   # every record's keys, in order of appearance
        lines += [f"{k}:", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        for r in rows:
            lines.append("| " + " | ".join(_fmt(r[c]) if isinstance(r.get(c), float) else str(r.get(c, ""))
                                           for c in cols) + " |")
        lines.append("")
    return lines


def _run_command(run_dir: Path, doc: dict) -> list[str]:
    """The experiment's own command, from Hydra's ``.hydra/overrides.yaml`` in its folder, with the folder, and
    the corpus it needs first (a review: the reports named only their report step)."""
    import shlex

    from laughlab.core.overrides import without_command_keys

    given = _overrides_of(run_dir)
    if given is None:
        return []
    # what the experiment computes: not overwrite=true or progress=off (a run made again into its folder recorded
    # overwrite=true, and the committed report's command then told readers to replace their own run)
    task = without_command_keys(given) + [f"hydra.run.dir={run_dir}"]
    real = (((doc.get("config") or {}).get("harness") or {}).get("corpus") or {}).get("real") or {}
    first = " (after `python -m laughlab corpus fetch`: the real corpus)" if real.get("sets") else ""
    return [f"- the run{first}: `python -m laughlab {' '.join(shlex.quote(o) for o in task)}`"]


def experiment_report(run_dir: Path, out: Path, command: str, width: str = "page",
                      panels: list[str] | None = None) -> Path:
    doc = read_results(run_dir / "results.json")
    check_panels(doc, panels)
    figs = out / "figures"
    if figs.exists():
        shutil.rmtree(figs)
    figs.mkdir(parents=True)
    comparison_figure(doc, figs / "metrics.png", pdf=True, width=width, panels=panels)
    comparison_figure(doc, figs / "timing.png", pdf=True, timing=True, width=width, panels=panels)
    from laughlab.harness.report_trials import trials_text

    (out / "trials.csv").write_text(trials_text([("", {}, run_dir)], list(doc["metrics"])), encoding="utf-8")
    for fig in sorted((run_dir / "plots").glob("*.p[nd][gf]")) if (run_dir / "plots").is_dir() else []:
        if fig.stem not in ("metrics", "timing"):   # the PNGs and their PDFs (drawn again above)
            shutil.copyfile(fig, figs / fig.name)
    lines = [f"# {doc['experiment']}", "",
             f"Generated by `{command}` from `{run_dir}`.",
             "", *_run_command(run_dir, doc), f"- date: {doc['date']}", made_by(doc),
             _trials_line(doc) + ", a row each in [trials.csv](trials.csv) with every metric",
             "- conditions: " + "; ".join(f"**{c}** `{' '.join(o)}`" for c, o in doc["conditions"].items()),
             *_base_line(doc),
             *[f"- skipped corpus file (harness.corpus.on_bad=skip): `{s['file']}`: {s['reason']}"
               for s in doc["corpus"].get("skipped", [])],
             *([f"- **without the real recordings**: the real corpus was not fetched, so its sets "
                f"({', '.join(doc['corpus']['not_fetched'])}) were left out; `python -m laughlab corpus fetch` "
                "adds them"] if doc["corpus"].get("not_fetched") else []),
             "", "## Results", "",
             "Mean over trials with its 95% confidence interval (percentile bootstrap of the trials, "
             "seeded; it stays within the values' range). ↑ higher is better, ↓ lower is better; the best "
             "condition is in bold only where its interval does not overlap any other condition's (a "
             "conservative rule: no bold is not evidence of no difference). "
             f"The compute rows (frame_ms_*, realtime_factor; never in bold) were measured with "
             f"{(doc.get('config', {}).get('harness') or {}).get('jobs', 1)} trial process(es) sharing the "
             "machine; `make bench` measures them alone.", ""]
    if any(0 < doc["results"][c][m]["n"] < FEW for m in table_metrics(doc) for c in conditions_of(doc)):
        # a bootstrap of a handful covers less
        lines[-1:-1] = ["", f"(n=K): a mean of fewer than {FEW} trials (e.g. the few inputs holding that kind of "
                        "sound); its bootstrap interval is narrower than a 95% interval should be: read it as the "
                        "spread of those trials, never in bold."]
    nones = [c for c in conditions_of(doc) if "detector=none" in doc["conditions"].get(c, ())]
    if 0 < len(nones) < len(conditions_of(doc)) and any(m in doc["metrics"] for m in DETECTOR_OWN):
        # compared with detectors, detector=none's own detector metrics were bolded (a review)
        lines[-1:-1] = ["", f"{' and '.join(f'**{c}**' for c in nones)} (detector=none) hears laughter in every "
                        "frame, so its detector metrics (recall 1, latency one frame) hold by construction and are "
                        "never in bold."]
    lines += _results_table(doc)
    gone = unmeasured(doc)
    if gone:
        lines += ["", "No value under any condition (nothing in these inputs for them to measure): "
                  + ", ".join(f"`{m}`" for m in gone) + "."]
    if (figs / "metrics.png").exists():   # --panels of compute metrics only: timing.png alone
        lines += ["", "![metrics](figures/metrics.png)", "", vector_link("metrics.png"), ""]
    if (figs / "timing.png").exists():
        lines += ["The compute rows, apart: measured on the machine while the trials ran, they differ run to run "
                  "(the one figure that does; the same seed gives the same bytes of every other).", "",
                  "![timing](figures/timing.png)", "", vector_link("timing.png"), ""]
    same = _same_table(doc)
    if same:
        lines += same + [""]
    mine = recordings_table(run_dir, doc)   # your own recordings one by one (a review: they were pooled only)
    if mine:
        lines += (mine if lines[-1] else mine[1:]) + [""]
    # in the experiment's order of conditions, as the tables (a plugin author's review: the figures went by name)
    order = conditions_of(doc)

    def by_condition(name: str) -> tuple:
        cond = name.split("_fig")[0].split("_filmstrip")[0].split("_method")[0]
        return (order.index(cond) if cond in order else len(order), name)

    shows = sorted((p.name for p in figs.glob("*_fig4_2_energy.png")), key=by_condition)
    if shows:
        shown = f" (`{doc['showcase']}`, `harness.showcase`)" if doc.get("showcase") else ""
        lines += [f"## The same input under each condition{shown}", ""]
        if _one_figure(figs, shows):   # a face comparison: the same body figures under every condition (a review)
            lines += [f"{SAME_FIGURE} ({_copies(shows[1:])})", "", f"![{shows[0]}](figures/{shows[0]})", ""]
        else:
            for name in shows:
                lines += [f"**{name.split('_fig4_2')[0]}**", "", f"![{name}](figures/{name})", ""]
    thesis = sorted((p.name for p in figs.glob("*.png") if "_fig4_1" in p.name or "_fig3_1" in p.name),
                    key=by_condition)
    if thesis:
        lines += ["## How the energy is made (thesis Figs. 4.1 and 3.1) on the same input", "",
                  "Fig. 4.1: the MCS, its primitive (the energy if no clip consumed), the actual energy and the "
                  "clips. Fig. 3.1: the MCS with min/max amplitude fixed against drifting.", ""]
        same, drawn = {k for k in ("_fig3_1", "_fig4_1") if _one_figure(figs, [n for n in thesis if k in n])}, set()
        for name in thesis:   # each captioned with its condition and figure (a review: "energy" twice, unexplained)
            kind = "_fig4_1" if "_fig4_1" in name else "_fig3_1"
            fig = "Fig. 4.1" if kind == "_fig4_1" else "Fig. 3.1"
            caption = f"**{name.split('_fig')[0]}**, {fig}"
            if kind in same:   # the same bytes under every condition: once
                if kind in drawn:
                    continue
                drawn.add(kind)
                caption = (f"**every condition**, {fig} (the same bytes under each: "
                           f"{_copies([n for n in thesis if kind in n][1:])})")
            lines += [caption, "", f"![{name}](figures/{name})", ""]
    others = sorted(p.name for p in figs.glob("*.png") if p.name not in ("metrics.png", "timing.png")
                    and p.name not in shows
                    and p.name not in thesis and not any(k in p.name for k in LINKED))
    for name in others:
        lines += [f"![{name}](figures/{name})", ""]
    linked = sorted((p.name for p in figs.glob("*.png") if any(k in p.name for k in LINKED)), key=by_condition)
    if linked:   # in figures/ but not inline (a review found them there unmentioned)
        lines += ["More figures of the same input, per condition (not shown inline): " + ", ".join(
            f"[{name}](figures/{name})" for name in linked) + " (Fig. 3.2: the MCS with a zoom on one bout; "
            "the filmstrip: the character at telling moments"
            + ("; method: the method's own signals" if any("_method" in n for n in linked) else "") + ").", ""]
    if any(p.stem not in ("metrics", "timing") for p in figs.glob("*.pdf")):
        lines += ["Each run figure above has a vector PDF of the same name beside it in `figures/`, for print.", ""]
    lines += ["## By profile", ""]
    for m in ("intensity_r_clip", "miss_rate", "silent_start_rate", "bouts_answered", "false_starts_per_min"):
        if m in doc["metrics"]:
            lines += [f"`{m}`", ""] + _profile_table(doc, m) + [""]
    if doc.get("extra"):
        lines += ["## Experiment-specific results", ""]
        for k, v in doc["extra"].items():
            lines += _extra_lines(k, v)
    lines += ["## Metrics", "", "| metric | units | definition |", "|---|---|---|"]
    for m, info in doc["metrics"].items():
        lines.append(f"| {m} | {info['units']} | {info['description']} |")
    (out / "README.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out / "README.md"


def _overrides_of(run_dir: Path) -> list[str] | None:
    """A run folder's command-line overrides, from Hydra's ``.hydra/overrides.yaml``; None without a readable list."""
    import yaml

    try:
        given = yaml.safe_load((run_dir / ".hydra" / "overrides.yaml").read_text(encoding="utf-8")) or []
    except (OSError, yaml.YAMLError):
        return None
    return [str(o) for o in given] if isinstance(given, list) else None   # not Hydra's list: none


def _own_outputs_experiment(root: Path) -> str | None:
    """The experiment a run folder was made by (its ``.hydra/overrides.yaml``), when it is not one that writes
    ``results.json`` (``hill_fit``, ``fourier_blend``: their modules replace the trial harness); else None."""
    name = next((o.split("=", 1)[1] for o in _overrides_of(root) or [] if o.startswith("experiment=")), None)
    return name if name in OWN_OUTPUTS else None


#: experiments whose module writes its own figures and numbers instead of the trial harness' results.json
OWN_OUTPUTS = ("hill_fit", "fourier_blend")


def write_report(run_dir: str | Path, out: str | Path | None = None, command: str = "", overwrite: bool = False,
                 metrics: list[str] | None = None, width: str = "page", panels: list[str] | None = None) -> Path:
    """Write the report of an experiment run or a sweep; return the README path.

    ``width``: ``page``, or ``column`` for the figures it draws 3.5 in wide (an experiment's ``metrics.png`` and
    ``timing.png``, a sweep's heatmaps and line plots), no text under 7 pt.  ``panels``: those figures show only
    these metrics, in this order (the tables keep every metric).

    The report goes into ``out``, by default ``run_dir/report`` (beside the results it is made
    from, so that reporting never touches the committed ``reports/``).
    The report is written into a hidden sibling folder first and moved into place
    only when it is whole: a failure (a full disk, a bad figure) leaves the
    earlier report as it was, or no report.
    """
    root = Path(run_dir)
    if not root.exists():
        raise LaughlabError(f"{run_dir} not found")
    if not root.is_dir():   # a review: a file was said to hold no results.json
        raise LaughlabError(f"{run_dir} is a file; report takes an experiment's run folder (its hydra.run.dir)")
    if (root / "results.json").exists():
        results, write = root / "results.json", experiment_report
    elif root.is_dir() and any(root.rglob("results.json")):
        sweeps = [] if (root / "multirun.yaml").is_file() else sorted({m.parent for m in root.rglob("multirun.yaml")})
        if sweeps:   # a folder above sweeps (a review: "report each point's folder", or another tool's results.json)
            named = shown_names([str(s.relative_to(root)) for s in sweeps])
            raise LaughlabError(f"{run_dir} is no run or sweep folder; it holds {len(sweeps)} sweep"
                                f"{'s' if len(sweeps) > 1 else ''} ({named}): report each on its own, "
                                f"python -m laughlab report {shlex.quote(str(sweeps[0]))}")
        results, write = next(root.rglob("results.json")), sweep_report
    else:
        from laughlab.harness.sweep_plan import missing_text, unfinished

        state = unfinished(root)   # a sweep stopped before any point finished (a review: "run an experiment first")
        if state and state[1]:
            raise LaughlabError(missing_text(root, *state))
        if (root / "stimuli.json").is_file():   # experiment=stimuli: its report is the study's (a new-user review)
            build = f"python -m laughlab study build {shlex.quote(str(run_dir))}"
            raise LaughlabError(f"{run_dir} holds stimuli for a perception study, not results: {build}, then study "
                                "serve and study analyze (docs/study.md)")
        own = _own_outputs_experiment(root)
        if own:   # an experiment that writes its own figures and numbers (a new-user review: "run an experiment first")
            held = sorted(p.name + "/" * p.is_dir() for p in root.iterdir() if p.name == "plots" or p.suffix == ".json")
            raise LaughlabError(f"{run_dir} is an experiment={own} run: it writes its own figures and numbers "
                                f"({', '.join(held)}), not the results.json of compared conditions that report reads")
        runs = sorted(m.parent for m in root.rglob("metrics.json"))   # a single run's folder, or a sweep of runs
        raise LaughlabError(f"{run_dir} holds no results.json (run an experiment first)" + (
            f"; report is for experiments: to watch {'this run' if runs[0] == root else 'a run'}, python -m "
            f"laughlab view {runs[0]}" if runs else ""))
    if width not in ("page", "column"):
        raise LaughlabError(f"--width must be page or column (got {width!r})")
    name = read_results(results)["experiment"]
    target = Path(out) if out else root / "report"
    if target.exists() and not target.is_dir():
        raise LaughlabError(f"report folder {target} exists and is not a folder")
    held = sorted(p.name for p in target.iterdir() if not p.name.startswith(".")) if target.is_dir() else []
    if held and not _is_a_report(target):
        raise LaughlabError(f"{target} holds files that are not a laughlab report ({shown_names(held)}); choose "
                            "another --out "
                            "(a report replaces only an earlier report)")
    title = f"# {name} (sweep)" if write is sweep_report else f"# {name}"
    if held and not overwrite and _report_title(target) != title:   # another experiment's report (a review)
        raise LaughlabError(f"{target} holds the report of another experiment ({_report_title(target)[2:]!r}, "
                            f"not {title[2:]!r}); choose another --out, or add --overwrite to replace it")
    staging = target.with_name(f".{target.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        args = (metrics, width, panels) if write is sweep_report else (width, panels)   # an experiment's table: all
        write(root, staging, command or f"python -m laughlab report {shlex.quote(str(run_dir))}", *args)
        from laughlab.harness.report_files import replace_report

        replace_report(staging, target, overwrite)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    if target == root / "report":
        from laughlab.core import rundir

        rundir.record(root, "report")   # the run's own now: overwriting the run removes it with the rest
    return target / "README.md"


def _readme_head(folder: Path) -> list[str]:
    """The first three lines of ``folder``'s README.md (empty if there is none to read)."""
    try:
        with open(folder / "README.md", encoding="utf-8") as f:
            return [next(f, "").rstrip("\n") for _ in range(3)]
    except (OSError, UnicodeDecodeError):
        return []


def _report_title(folder: Path) -> str:
    """The first line of the report in ``folder`` (``# NAME`` or ``# NAME (sweep)``)."""
    return (_readme_head(folder) or [""])[0]


def _is_a_report(folder: Path) -> bool:
    """Does ``folder`` hold a report this command wrote (its README's third line says so)?"""
    head = _readme_head(folder)
    return len(head) == 3 and head[0].startswith("# ") and head[2].startswith("Generated by `")


#: the showcase figures a report links rather than shows (Fig. 3.2, the filmstrip, the method's own signals)
LINKED = ("fig3_2", "filmstrip", "_method")

#: the caption of a showcase figure that is the same under every condition
SAME_FIGURE = ("**Every condition**: this figure is byte for byte the same under each (the conditions differ in "
               "what it does not show, such as the face)")


def _copies(names: list[str]) -> str:
    """Links to the other conditions' copies of a figure shown once."""
    return ", ".join(f"[{n}](figures/{n})" for n in names)


def _one_figure(figs: Path, names: list[str]) -> bool:
    """Two or more conditions' copies of one showcase figure, all the same bytes (a plugin author's review: a face
    comparison's report showed the same 12 body figures, each under a face's name)."""
    if len(names) < 2:
        return False
    first = (figs / names[0]).read_bytes()
    return all((figs / n).read_bytes() == first for n in names[1:])

