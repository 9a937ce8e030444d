"""docs/pipeline.md's table of channels.csv columns names every column the built-in plugins write (a new-user
review found the facs, cgm and several body columns missing from it)."""
import re
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config

ROOT = Path(__file__).resolve().parents[1]

#: one run per group of plugins: together they write every built-in channel
RUNS = [[], ["face=facs"], ["face=cgm"], ["body=hill", "extractor=pressure"], ["body=fourier"], ["body=follow"],
        ["extractor=phoneme", "scheduler=concat"], ["detector=laugh"], ["detector=none", "scheduler=none"]]


def documented() -> set[str]:
    text = (ROOT / "docs" / "pipeline.md").read_text()
    section = text[text.index("### The columns of `channels.csv`"):]
    section = section[:section.index("\n\n", section.index("| column |"))]
    names = set()
    for row in section.splitlines():
        if row.startswith("| `"):
            names |= set(re.findall(r"`([a-z_0-9.A-Z]+)`", row.split("|")[1]))
    return names


@pytest.mark.parametrize("overrides", RUNS, ids=[" ".join(r) or "default" for r in RUNS])
def test_every_column_a_built_in_plugin_writes_is_documented(tmp_path, overrides):
    cfg = compose_config(["input.duration_s=1", "input.save_audio=false", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    pipe = pipeline.build(cfg)
    pipe.sinks = [s for s in pipe.sinks if s.name == "csv"]
    pipeline.execute(pipe, tmp_path)
    header = (tmp_path / "channels.csv").read_text().splitlines()[0].split(",")
    names = documented()
    missing = [c for c in header if c not in names and not (c.startswith("arkit.") and "arkit.NAME" in names)]
    assert not missing, f"docs/pipeline.md's channels.csv table lacks {missing}"
