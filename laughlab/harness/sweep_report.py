"""The report of a Hydra multirun sweep: a table of every point and heatmaps or lines of the key metrics over
the swept parameters (``python -m laughlab report SWEEP_DIR``, through :func:`laughlab.harness.report.write_report`)."""
from __future__ import annotations

import json
import math
import shlex
import shutil
from itertools import combinations
from pathlib import Path

from laughlab.core.errors import LaughlabError
from laughlab.harness.results import made_by, read_results
from laughlab.harness.sweep_plan import NOT_PARAMS, multirun, stale_points, swept_keys, sweep_command, unfinished
from laughlab.harness.report_format import (EDGE, KEY_METRICS, at_search_edge, check_panels, refuse_unmeasured,
                                            vector_link)
from laughlab.harness.report_format import NO_VALUE, vacuous
from laughlab.harness.report_format import fmt as _fmt
from laughlab.harness.report_format import heading as _heading
from laughlab.harness.sweep_figures import heatmaps, lines as line_plots
from laughlab.harness.sweep_figures import order as _order


def _sweep_points(root: Path) -> list[dict]:
    import yaml

    points = []
    for rj in sorted(root.rglob("results.json")):
        job = rj.parent
        ov_file = job / ".hydra" / "overrides.yaml"
        overrides = yaml.safe_load(ov_file.read_text(encoding="utf-8")) if ov_file.exists() else []
        params = dict(o.split("=", 1) for o in overrides if "=" in o and not o.startswith(NOT_PARAMS))
        points.append({"dir": job, "params": params, "doc": read_results(rj)})
    return points


def _sweep_command(root: Path) -> list[str]:
    """The sweep's own command, from Hydra's ``multirun.yaml``: its overrides and the values an experiment's
    ``hydra.sweeper.params`` swept (a reader reruns the sweep from these lines)."""
    command = sweep_command(root)
    if not command:
        return []
    hydra = multirun(root) or {}
    task = list((hydra.get("overrides") or {}).get("task") or [])
    out = [f"- the sweep: `{command}`"]
    given = {str(o).split("=", 1)[0] for o in task}
    params = {k: v for k, v in ((hydra.get("sweeper") or {}).get("params") or {}).items() if k not in given}
    if params:
        out.append("- swept by the experiment's `hydra.sweeper.params`: "
                   + ", ".join(f"`{k}={v}`" for k, v in params.items()))
    return out


def _partial_lines(state) -> list[str]:
    """A half-finished sweep's warning (``state``: :func:`unfinished`), under the report's title (a review: the
    report of 2 of 4 points read as a whole sweep and listed a swept parameter as fixed)."""
    if not state or not state[1]:
        return []
    planned, missing = state
    return [f"**PARTIAL: {len(missing)} of the sweep's {planned} points have no results** (unfinished: "
            + ", ".join(f"`{m}`" for m in missing) + "). Every table and figure below covers only the "
            f"{planned - len(missing)} finished points; run the sweep's command (below) again to finish it, "
            "then this report's command.", ""]


def _edge_lines(points: list[dict], varying: list[str]) -> list[str]:
    """The points where a bounded search's best (a lag) sat at the edge of its range in every trial, so that the
    correlation in the table was measured there (a review found r at a lag of 2.0 [2.0, 2.0] s unflagged)."""
    out = []
    infos = points[0]["doc"]["metrics"]
    for m, info in infos.items():
        at = [p for p in points if at_search_edge(info, p["doc"]["results"][p["cond"]][m])]
        if at:
            where = "; ".join(", ".join(f"{k}={p['params'].get(k, '')}" for k in varying) for p in at[:6])
            more = f" and {len(at) - 6} more" if len(at) > 6 else ""
            out.append(f"- {EDGE} `{m}` sat at the edge of its search, [{_fmt(info['search'][0])}, "
                       f"{_fmt(info['search'][1])}] {info['units']}, in every trial of {len(at)} point(s) ({where}"
                       f"{more}): the correlation that goes with it was measured there, and the best may lie beyond.")
    return out + [""] if out else []


def shown_metrics(doc: dict, asked: list[str] | None = None) -> list[str]:
    """The metrics a sweep's table and figures show: :data:`KEY_METRICS`, every metric a plugin other than
    laughlab registered (a plugin authors' review: a researcher's own metric never appeared), and ``asked``
    (``report --metrics``); a name the sweep did not measure is refused in one line."""
    refuse_unmeasured("--metrics", "the sweep", asked, doc["metrics"])
    origins = doc.get("plugins") or {}
    theirs = [m for m in doc["metrics"] if not origins.get(f"metric/{m}", "laughlab ").startswith("laughlab ")]
    return list(dict.fromkeys([m for m in KEY_METRICS if m in doc["metrics"]] + theirs + list(asked or [])))


def _without_stale(root: Path, points: list[dict]) -> tuple[list[dict], list[str]]:
    """``points`` without an earlier sweep's folders (:func:`stale_points`), and the lines that say so: a note under
    the title and one warning on stderr."""
    import sys

    from laughlab.core.errors import shown_names

    stale = set(stale_points(root, {p["dir"]: p["params"] for p in points}))
    if not stale:
        return points, []
    names = sorted((str(d.relative_to(root)) for d in stale), key=_order)
    said = (f"{len(stale)} folder{'s' if len(stale) > 1 else ''} with results here ({shown_names(names, 6)}) "
            f"{'are' if len(stale) > 1 else 'is'} no point of this sweep (an earlier sweep's, run over with "
            "overwrite=true): left out")
    kept = [p for p in points if p["dir"] not in stale]
    if not kept:
        raise LaughlabError(f"{root}: no finished point of its sweep; {said}: run the sweep's command again: "
                            f"{sweep_command(root)}")
    print(f"laughlab: warning: {root}: {said} of the report", file=sys.stderr)
    return kept, [f"- {said[0].upper()}{said[1:]} of every table and figure below"]


def sweep_report(root: Path, out: Path, command: str, metrics: list[str] | None = None, width: str = "page",
                 panels: list[str] | None = None) -> Path:
    points, stale_lines = _without_stale(root, _sweep_points(root))
    experiments = sorted({p["doc"]["experiment"] for p in points})
    if len(experiments) > 1:
        raise LaughlabError(f"{root} holds the results of {len(experiments)} experiments ({', '.join(experiments)}); "
                            "report each point's folder on its own (python -m laughlab report POINT_DIR)")
    if not (root / "multirun.yaml").is_file():   # not Hydra's sweep: a folder of separate runs? (a review: a "sweep"
        seen: dict[str, Path] = {}              # report of two copies of one run, its rows duplicated and unnamed)
        for p in points:
            key = json.dumps(p["params"], sort_keys=True)
            if key in seen:
                raise LaughlabError(
                    f"{root} is not a sweep (no multirun.yaml) and two of its runs have the same settings "
                    f"({seen[key].relative_to(root)}, {p['dir'].relative_to(root)}); report each run on its own: "
                    f"python -m laughlab report {shlex.quote(str(seen[key]))}")
            seen[key] = p["dir"]
    doc0 = points[0]["doc"]
    conds = list(doc0["results"])
    # an experiment of several conditions: each (point, condition) is a row, the condition a swept dimension of its
    # own (a review: only the first condition was reported, and its trial count was the whole point's)
    points = [{**p, "cond": c, "params": {**p["params"], **({"condition": c} if len(conds) > 1 else {})}}
              for p in points for c in conds if c in p["doc"]["results"]]
    keys = sorted({k for p in points for k in p["params"]})
    state = unfinished(root)
    planned = set(swept_keys(root))   # swept by the plan, though the finished points may hold only one value
    varying = [k for k in keys if len({p["params"].get(k) for p in points}) > 1 or k in planned]
    check_panels(doc0, panels)
    metrics = shown_metrics(doc0, [*(metrics or []), *(panels or [])])
    key = [m for m in metrics if m in KEY_METRICS]
    per = sorted({p["doc"]["n_trials"] // max(len(p["doc"]["results"]), 1) for p in points})   # a condition's trials
    per_text = str(per[0]) if len(per) == 1 else f"{per[0]}-{per[-1]}"
    figs = out / "figures"
    if figs.exists():
        shutil.rmtree(figs)
    figs.mkdir(parents=True)
    fixed = [f"{k}={points[0]['params'][k]}" for k in keys if k not in varying]
    seeds = doc0["corpus"]["seeds"]
    lines = [f"# {doc0['experiment']} (sweep)", "", f"Generated by `{command}` from `{root}`.", "",
             *_partial_lines(state), *stale_lines, *_sweep_command(root),
             f"- sweep points: {len({str(p['dir']) for p in points})}"
             + (f" of {state[0]} planned" if state and state[1] else "")
             + (f" x {len(conds)} conditions" if len(conds) > 1 else "")
             + f"; swept: {', '.join(varying) or '(nothing)'}",
             *([f"- fixed at every point: {', '.join(fixed)}"] if fixed else []),
             f"- each point: {per_text} trial{'' if per == [1] else 's'} of "
             + (f"each condition ({', '.join(f'**{c}**' for c in conds)}; " if len(conds) > 1
                else f"condition **{conds[0]}** (")
             + f"profiles {', '.join(doc0['corpus']['profiles'])}; seeds {', '.join(map(str, seeds))}"
             + (" at the first point)" if any(p["doc"]["corpus"]["seeds"] != seeds for p in points) else ")"),
             made_by(doc0), "",
             "## Every point", "", "One column per metric: its name, ↑ higher is better or ↓ lower is better, and "
             f"(its units). Each cell is the mean of a point's {per_text} trial"
             f"{'' if per == [1] else 's'} of that condition; the table shows "
             f"{len(key)} key metrics" + (" and " + ", ".join(f"`{m}`" for m in metrics[len(key):])
                                          + " (a plugin's own, or asked for with `report --metrics`)"
                                          if len(metrics) > len(key) else "")
             + f" of the {len(doc0['metrics'])} each point measured: a point's folder "
             "has them all, with 95% bootstrap intervals (`results.json`; `python -m laughlab report POINT_DIR`).",
             ""]
    info = doc0["metrics"]
    lines.append("| " + " | ".join(varying) + " | "
                 + " | ".join(f"{_heading(m, info[m])} ({info[m]['units']})" for m in metrics) + " |")
    lines.append("|" + "---|" * (len(varying) + len(metrics)))

    def result(p, m):
        return p["doc"]["results"][p["cond"]][m]

    def shown(p, m):
        """A point's result as the figures show it: an offset tail of 0 where no clip played (``scheduler=none``)
        is no value (it was the brightest, "best", cell; the experiment's table bolds no such best either)."""
        return NO_VALUE if vacuous(p["doc"], m, p["cond"]) else result(p, m)

    def val(p, m):
        r = result(p, m)
        return r["mean"] if r["mean"] is not None else float("nan")

    for p in sorted(points, key=lambda p: [_order(p["params"].get(k, "")) for k in varying]):
        lines.append("| " + " | ".join(p["params"].get(k, "") for k in varying) + " | "
                     + " | ".join(_fmt(val(p, m)) for m in metrics) + " |")
    lines.append("")
    lines += _edge_lines(points, varying)
    heat_metrics, flat = [], []
    for m in panels or metrics:   # report --panels: only those in the figures, in that order
        values = [v for v in (val(p, m) for p in points) if math.isfinite(v)]
        if not values:
            flat.append(f"`{m}` (no value at any point)")
        elif max(values) - min(values) <= 1e-12 * max(1.0, abs(max(values))):
            flat.append(f"`{m}` ({_fmt(values[0])} at every point)")
        else:
            heat_metrics.append(m)
    pairs = list(combinations(varying, 2))
    # what every figure was measured on, in its title (a review: a sweep PNG in a paper could not be traced back)
    title = (f"{doc0['experiment']} sweep: each point the mean of {per_text} trial{'' if per == [1] else 's'}"
             + (" of each condition" if len(conds) > 1 else f" of condition {conds[0]}")
             + f" (profiles {', '.join(doc0['corpus']['profiles'])}; seeds {', '.join(map(str, seeds))})"
             + (f"; fixed: {', '.join(fixed)}" if fixed else "")
             + (f"; PARTIAL: {len(state[1])} of {state[0]} points unfinished" if state and state[1] else ""))
    if pairs:
        lines += ["## Heatmaps", "", "Each cell: the metric's mean over the sweep points with those two values "
                  "(averaged over the other swept parameters). In every heatmap the bright (yellow) end is the "
                  "better one: each colour bar has its better end at the top and says so, so the bar of a "
                  "lower-is-better metric (↓) runs from high values at the bottom to low ones at the top.", ""]
    if (pairs or len(varying) == 1) and flat:
        lines += ["No figure for " + ", ".join(flat) + ": the sweep did not change it.", ""]
    for a, b in (pairs if heat_metrics else []):
        name = f"heatmap_{a}_{b}.png".replace("/", "_")
        heatmaps(points, a, b, heat_metrics, shown, figs / name, doc0["metrics"], title, width)
        lines += [f"![{a} x {b}](figures/{name})", "", vector_link(name), ""]
    if len(varying) == 1 and heat_metrics:
        name = f"line_{varying[0]}.png"
        line_plots(points, varying[0], heat_metrics, shown, figs / name, doc0["metrics"], title, width)
        lines += [f"![{varying[0]}](figures/{name})", "", vector_link(name), ""]
    from laughlab.harness.report_trials import trials_text

    dirs = {str(p["dir"]): p for p in points}   # a point once (its conditions are its trials' own column)
    swept = [k for k in varying if k != "condition"]
    (out / "trials.csv").write_text(trials_text(
        [(Path(d).relative_to(root).as_posix(), {k: p["params"].get(k, "") for k in swept}, Path(d))
         for d, p in sorted(dirs.items(), key=lambda kv: [_order(kv[1]["params"].get(k, "")) for k in swept])],
        list(doc0["metrics"])), encoding="utf-8")
    lines[lines.index("## Every point") - 1:lines.index("## Every point") - 1] = [
        "- every trial of every point, a row each with its point's swept settings and every metric: "
        "[trials.csv](trials.csv)"]
    (out / "README.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out / "README.md"
