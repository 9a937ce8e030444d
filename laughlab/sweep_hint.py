"""The Hydra callback that ends a sweep of experiments with one line saying how to report it.

Named in ``conf/config.yaml`` (``hydra.callbacks``).  A sweep's jobs print their own line without the
``report:`` hint (:func:`laughlab.cli.task`); one hint for the whole sweep folder replaces one per job.
"""
from __future__ import annotations

import shlex

from hydra.experimental.callback import Callback


class SweepReportHint(Callback):
    def on_multirun_end(self, config, **kwargs) -> None:
        if not config.get("harness"):
            return
        from laughlab.harness.experiment import experiment_module

        module = experiment_module(config.harness.get("module"))
        if module is None or not hasattr(module, "run"):  # trial experiments: the report reads their results
            print(f"report: python -m laughlab report {shlex.quote(str(config.hydra.sweep.dir))}")
