"""docs/pipeline.md's table of channels.csv columns names every column the built-in plugins write (a new-user
review found the facs, cgm and several body columns missing from it), and its section on the VMC stream says what
the encoder sends."""
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


def test_the_vmc_stream_section_says_what_the_encoder_sends():
    """docs/pipeline.md's section for game developers (a game-developer review: the docs named no address, type,
    bone or unit of the stream) lists the encoder's addresses with their OSC types in order, every bone and the
    face=smile mapping as laughlab.io.vmc has them."""
    import numpy as np
    from pythonosc.osc_message import OscMessage

    from laughlab.io.vmc import SMILE_TO_ARKIT, UNITY_BONES, VmcEncoder

    text = (ROOT / "docs" / "pipeline.md").read_text()
    section = text[text.index("### In your own game or receiver"):]
    section = section[:section.index("\n### ") if "\n### " in section else len(section)]
    rows = [r.split("|") for r in section.splitlines() if r.startswith("| `/VMC")]
    table = [(r[1].strip(" `"), r[2].strip(" `").replace("(none)", "")) for r in rows]
    enc = VmcEncoder(list(UNITY_BONES.values()))
    sent = [OscMessage(m) for m in enc.messages(0.0, np.zeros((22, 3)), np.zeros((22, 4)), [("jawOpen", 0.5)])]
    seen = []
    for m in sent:
        entry = (m.address, "".join("i" if isinstance(a, int) else "f" if isinstance(a, float) else "s"
                                    for a in m.params))
        if not seen or seen[-1] != entry:
            seen.append(entry)
    assert table == seen
    for bone in UNITY_BONES.values():
        side = bone.startswith(("Left", "Right"))
        assert f"`{bone[4 if bone.startswith('Left') else 5:]}`" in section if side else f"`{bone}`" in section
    for name, terms in SMILE_TO_ARKIT.items():
        (channel, weight), = terms.items()
        base = re.sub(r"(Left|Right)$", "", name)
        said = f"`{name}` = " if base == name else f"`{base}{{Left,Right}}` = "
        assert said + ("" if weight == 1.0 else f"{weight:g} ") + channel in " ".join(section.split()), name
