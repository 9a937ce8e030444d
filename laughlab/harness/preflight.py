"""An experiment's checks before anything is written (the command line's preflight): its harness resolved in one
line, and each condition's run built as its trials will compose it."""
from __future__ import annotations

from laughlab.core.errors import LaughlabError
from laughlab.core.overrides import override_key, without_command_keys


def resolved_harness(cfg) -> dict:
    """``cfg.harness`` resolved; an interpolation that names a missing key is one line (a review:
    ``harness.preset=nope`` was omegaconf's InterpolationKeyError traceback)."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    try:
        return OmegaConf.to_container(cfg.harness, resolve=True)
    except OmegaConfBaseException as exc:
        raw = OmegaConf.to_container(cfg.harness, resolve=False)
        presets = raw.get("presets")
        if isinstance(presets, dict) and raw.get("preset") not in presets:
            raise LaughlabError(f"unknown harness.preset {raw.get('preset')!r}; choose one of: "
                                f"{', '.join(presets)}") from None
        raise LaughlabError(f"harness: {str(exc).splitlines()[0]}") from None


def check_single_run_keys(overrides: list[str]) -> None:
    """A single run's ``seed=`` and ``output=``/``output.*`` given to an experiment, refused in one line (``seed=``
    was recorded and changed nothing; ``output=viewer`` was dropped without a word, ``output.plots.max_seconds=10`` failed
    after the first trials).  ``output.plots.*`` is the showcase runs' figures' (width, pdf...), and kept."""
    keys = {override_key(o) for o in overrides}
    keys = {k for k in keys if not k.startswith("output.plots.")}
    if "seed" in keys:
        raise LaughlabError("seed= does not apply to an experiment: its runs' seeds are harness.corpus.seeds "
                            "(synthetic inputs: how many, or a list such as [10,11]) and harness.run_seeds "
                            "(each recording's runs, e.g. [0,1,2])")
    if any(k.split(".")[0] == "output" for k in keys):
        raise LaughlabError("output settings do not apply to an experiment (but output.plots.*, its showcase "
                            "figures'): its trials write what its metrics read and its showcase runs files with "
                            "plots; to stream, view or export a condition, run it alone with its overrides and "
                            "output=...")


def check_condition_runs(overrides: list[str], conditions: dict, build_base) -> None:
    """Each condition's run built as its trials compose it (the command line's overrides, then the condition's),
    before any trial: a key the condition's plugin lacks (``scheduler.overrule_c`` under a ``scheduler=none``
    condition) stopped the experiment after its first trials, and under a parallel sweep silently (a review).
    When one fails, ``build_base()`` builds the run without the condition: an error of the command line's own
    values is said as a single run says it, others name the condition.  (The base run, which no trial runs, is
    not built otherwise: under energy_ablation it loaded YAMNet for each value a sweep's check tried.)"""
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.core.config import NOT_IN_A_RUN, compose_app

    base = without_command_keys(overrides)
    for name, cond in conditions.items():
        try:
            cfg = compose_app([*base, *cond])
            pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k not in NOT_IN_A_RUN])).source.close()
        except LaughlabError as exc:
            build_base()   # the command line's own error, unprefixed, if it is one
            raise LaughlabError(f"condition {name!r} ({' '.join(cond)}): {exc}") from None
