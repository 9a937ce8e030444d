"""A run with a scheduler that starts no full-body clip says why, in its line and ``metrics.json`` (a researcher's
and an avatar developer's reviews: real laughs under the default detector, or under ``body=hill``, played no clip
and nothing said why)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import soundfile as sf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)


def _run(tmp_path, name, *args):
    r = laughlab(*args, "~output.plots", f"hydra.run.dir={tmp_path / name}")
    assert r.returncode == 0, r.stderr
    return r.stdout, json.loads((tmp_path / name / "metrics.json").read_text())


def test_energy_under_the_mildest_clip_is_said_with_both_numbers(tmp_path):
    # 2 s of the synthetic laughter at a third of the thesis' gain (60 /s): L rises to about 0.8
    out, m = _run(tmp_path, "short", "input.duration_s=2", "scheduler.gain_per_s=20", "detector=none")
    energy = np.loadtxt(tmp_path / "short" / "channels.csv", delimiter=",", skiprows=1,
                        usecols=_column(tmp_path / "short", "energy"))
    assert m["no_clip"] == "energy" and m["mildest_clip_energy"] == 5.0   # lean_front1 and others: e(a) = 5
    assert m["energy_peak"] == pytest.approx(energy.max(), abs=1e-6) and 0 < m["energy_peak"] < 5
    assert (f"(no full-body clip: the laughing energy peaked at {m['energy_peak']:.1f}, under the mildest "
            "clip's 5)") in out


def test_a_detector_that_never_opened_its_gate_is_said(tmp_path):
    """Two seconds of a steady 200 Hz hum: loud enough to feed the energy, and not laughter to YAMNet."""
    t = np.arange(2 * 16000) / 16000
    sf.write(tmp_path / "hum.wav", 0.5 * np.sin(2 * np.pi * 200 * t), 16000)
    out, m = _run(tmp_path, "hum", "input=file", f"input.path={tmp_path / 'hum.wav'}", "detector=yamnet")
    gate = np.loadtxt(tmp_path / "hum" / "channels.csv", delimiter=",", skiprows=1,
                      usecols=_column(tmp_path / "hum", "clip_gate"))
    assert m["no_clip"] == "gate" and gate.max() < 0.5
    assert "(no full-body clip: the laughter detector never heard laughter; detector=none starts clips" in out
    out, m = _run(tmp_path, "none", "input=file", f"input.path={tmp_path / 'hum.wav'}", "detector=none")
    assert "no_clip" not in m and "no full-body clip" not in out   # the papers' pipeline: clips on the hum


def test_a_run_with_clips_or_without_a_scheduler_or_a_blip_says_nothing(tmp_path):
    for name, args in (("clips", ("input.duration_s=3", "detector=none")),
                       ("blip", ("input.duration_s=0.5", "detector=none")),   # under 1 s: no clip expected
                       ("none", ("input.duration_s=3", "detector=none", "scheduler=none"))):
        out, m = _run(tmp_path, name, *args)
        assert ("no_clip" in m) == (name == "blip") and "no full-body clip" not in out, name   # metrics.json has it


def _column(run, name) -> int:
    return (run / "channels.csv").read_text().splitlines()[0].split(",").index(name)


def test_energy_and_gate_that_never_met_are_said_apart():
    """An animator's review: a real laugh (ovos' Evil_Laugh_Male_6, 48 kHz) under the default pipeline started no
    clip and the run said nothing: the gate had opened (after the laugh) and the energy had peaked at 12 (while the
    gate was shut), so neither reason held. The third one: they never met on a frame."""
    from types import SimpleNamespace

    from laughlab.core.recorder import Recorder
    from laughlab.core.summary import no_clip_text

    sch = SimpleNamespace(name="energy", actions=[SimpleNamespace(energy=5.0), SimpleNamespace(energy=10.0)])
    rec = Recorder(0, 0)
    rec._tally({"clip_gate": np.array([0.0, 0.0, 0.2, 1.0, 1.0]), "energy": np.array([3.0, 12.4, 8.0, 0.2, 0.1])})
    m = rec.no_clip(sch)
    assert m == {"no_clip": "apart", "energy_peak": 12.4, "energy_allowed_peak": 0.2, "mildest_clip_energy": 5.0}
    assert no_clip_text(m) == (" (no full-body clip: the laughing energy peaked at 12.4 while the laughter detector "
                               "held clips back, and reached 0.2 while it allowed them, under the mildest clip's 5)")
    rec._tally({"clip_gate": np.array([0.6]), "energy": np.array([5.0])})   # they meet once: no reason to give
    assert rec.no_clip(sch) == {}


def test_a_plugins_laugh_gate_that_never_opened_is_the_reason():
    """A plugin author's review: a detector of their own (no clip_gate) whose laugh_gate stayed shut gated mcs to 0,
    and the run blamed "the laughing energy peaked at 0.0"."""
    from types import SimpleNamespace

    from laughlab.core.recorder import Recorder

    sch = SimpleNamespace(name="energy", actions=[SimpleNamespace(energy=5.0)])
    rec = Recorder(0, 0)
    rec._tally({"laugh_gate": np.array([0.0, 0.2, 0.4]), "energy": np.zeros(3)})
    assert rec.no_clip(sch) == {"no_clip": "gate"}
    rec._tally({"laugh_gate": np.array([0.9]), "energy": np.zeros(1)})   # it opened once: the energy's reason
    assert rec.no_clip(sch)["no_clip"] == "energy"


def test_the_reviews_real_laugh_says_why(tmp_path):
    from laughlab.corpora.fetch import corpus_dir

    laugh = corpus_dir() / "files" / "ovos" / "male-Evil_Laugh_Male_6-Himan-1359990674.wav"
    if not laugh.exists():
        pytest.skip("the corpus is not fetched (make corpus)")
    out, m = _run(tmp_path, "evil", "input=file", f"input.path={laugh}")
    assert m["no_clip"] == "apart" and m["energy_peak"] > 5 > m["energy_allowed_peak"], m
    assert "while the laughter detector held clips back" in out
