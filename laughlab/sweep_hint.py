"""The Hydra callback that ends a sweep of experiments with one line saying how to report it.

Named in ``conf/config.yaml`` (``hydra.callbacks``).  A sweep's jobs print their own line without the
``report:`` hint (:func:`laughlab.cli.task`); one hint for the whole sweep folder replaces one per job.
"""
from __future__ import annotations

import shlex
from pathlib import Path

from hydra.experimental.callback import Callback


class SweepReportHint(Callback):
    def on_multirun_end(self, config, **kwargs) -> None:
        if not config.get("harness"):
            return
        from laughlab.harness.experiment import experiment_module

        module = experiment_module(config.harness.get("module"))
        if module is None or not hasattr(module, "run"):  # trial experiments: the report reads their results
            sweep = Path(str(config.hydra.sweep.dir))
            points = _experiments(sweep)
            if len(set(points.values())) > 1:   # a sweep over experiments: report refuses the folder (a review)
                names = ", ".join(sorted(set(points.values())))
                print(f"report: the sweep holds {len(set(points.values()))} experiments ({names}): report each "
                      f"point's folder, e.g. python -m laughlab report {shlex.quote(str(min(points)))}")
            else:
                print(f"report: python -m laughlab report {shlex.quote(str(sweep))}")


def _experiments(sweep: Path) -> dict[Path, str]:
    """Each finished point's folder in ``sweep`` -> the experiment its ``results.json`` names (read as ``report``
    reads it; damaged ones left out: ``report`` says what is wrong with them)."""
    from laughlab.core.errors import LaughlabError
    from laughlab.harness.results import read_results

    out = {}
    for path in sweep.rglob("results.json"):
        try:
            out[path.parent] = read_results(path)["experiment"]
        except (LaughlabError, OSError):
            continue
    return out
