"""An experiment's checks before anything is written (the command line's preflight): its harness resolved in one
line, and each condition's run built as its trials will compose it."""
from __future__ import annotations

from laughlab.core.errors import LaughlabError


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

    base = [o for o in overrides if not o.split("=")[0].lstrip("+~").startswith(("hydra", "overwrite", "progress"))]
    for name, cond in conditions.items():
        try:
            cfg = compose_app([*base, *cond])
            pipeline.build(OmegaConf.masked_copy(cfg, [k for k in cfg if k not in NOT_IN_A_RUN])).source.close()
        except LaughlabError as exc:
            build_base()   # the command line's own error, unprefixed, if it is one
            raise LaughlabError(f"condition {name!r} ({' '.join(cond)}): {exc}") from None
