"""``hydra.job.chdir=true``: Hydra runs the job in its run folder, and laughlab's paths are the user's.

The run folder and the files a run reads are named from where the command runs; once Hydra has changed into
the run folder, a relative ``hydra.run.dir`` named a folder inside itself and a relative ``input.path`` was
looked up there (until 2026-11-28 every run with ``hydra.job.chdir=true`` ended in two lines, Hydra's and
``cannot write outputs/...``, after it had written its files).  :func:`anchor_run_dir` makes the run folder
absolute before it is claimed, :func:`anchor_paths` the read paths in the job, from Hydra's ``runtime.cwd``.
"""
from __future__ import annotations

import os

from laughlab.core.errors import LaughlabError

#: the settings that name a file a run reads (a sink's ``character`` too: ``output.*.character``)
PATH_KEYS = ("input.path", "input.truth", "character", "extractor.textgrid", "plugins_dir")


def _chdir(cfg) -> bool:
    from omegaconf import OmegaConf

    return bool(OmegaConf.select(cfg, "hydra.job.chdir", default=False))


def anchor_run_dir(cfg) -> None:
    """A single run's ``hydra.run.dir``, absolute when the job will run in it; an experiment is refused (its
    trials are composed again from the command's own overrides, in the run folder)."""
    from omegaconf import open_dict

    if not _chdir(cfg):
        return
    if cfg.get("harness"):
        raise LaughlabError("hydra.job.chdir=true does not apply to an experiment: its trials read their inputs "
                            "from where the command runs; drop it")
    with open_dict(cfg):
        cfg.hydra.run.dir = os.path.abspath(cfg.hydra.run.dir)


def anchor_paths(cfg, cwd: str) -> None:
    """The read paths of ``cfg`` that are relative, made absolute from ``cwd`` (where the command ran)."""
    from omegaconf import OmegaConf, open_dict

    keys = list(PATH_KEYS) + [f"output.{name}.character" for name in (cfg.get("output") or {})]
    with open_dict(cfg):
        for key in keys:
            value = OmegaConf.select(cfg, key, default=None)
            if isinstance(value, str) and value and not os.path.isabs(os.path.expanduser(value)):
                OmegaConf.update(cfg, key, os.path.join(cwd, value))
