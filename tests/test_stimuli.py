"""``experiment=stimuli``: videos per audio item x condition, loudness, manifest and counterbalanced orders."""
from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.config import compose_config
from laughlab.core.errors import LaughlabError
from laughlab.io.video import decode_audio, probe
from laughlab_experiments.stimuli import MANIFEST_COLUMNS, normalise_loudness, run, williams

pyloudnorm = pytest.importorskip("pyloudnorm")

SMALL = ["harness.corpus.profiles=[intense]", "harness.corpus.seeds=1", "harness.corpus.duration_s=1.5",
         "harness.video.width=96", "harness.video.height=72", "harness.video.fps=15", "harness.video.supersample=1",
         "harness.participants=5", "progress=off", "fps=30"]


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The default preset rendered twice into different folders."""
    outs = []
    for name in ("a", "b"):
        out = tmp_path_factory.mktemp(name)
        run(compose_config(["experiment=stimuli", *SMALL]), out)
        outs.append(out)
    return outs


def test_manifest_lists_every_video_with_its_hash(rendered):
    out = rendered[0]
    rows = read_csv(out / "manifest.csv")
    assert list(rows[0]) == list(MANIFEST_COLUMNS)
    assert [r["condition"] for r in rows] == ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    for r in rows:
        f = out / r["file"]
        assert r["stimulus_id"] == f"{r['condition']}-intense-s00" and f.name == f"{r['stimulus_id']}.mp4"
        assert hashlib.sha256(f.read_bytes()).hexdigest() == r["sha256"]
        assert float(r["duration_s"]) == pytest.approx(1.5, abs=1 / 15) and r["fps"] == "15" and r["seed"] == "0"
        info = probe(f)
        assert info["video"]["codec"] == "h264" and info["audio"]["codec"] == "aac"
    assert sorted(p.name for p in (out / "stimuli").iterdir()) == sorted(f"{r['stimulus_id']}.mp4" for r in rows)
    assert not [p for p in out.iterdir() if p.name.startswith(".") or p.name.startswith("laughlab-")]


def test_same_seed_same_manifest_bytes(rendered):
    a, b = rendered
    assert (a / "manifest.csv").read_bytes() == (b / "manifest.csv").read_bytes()
    assert (a / "orders" / "psychopy_all.csv").read_bytes() == (b / "orders" / "psychopy_all.csv").read_bytes()


def test_conditions_differ(rendered):
    rows = read_csv(rendered[0] / "manifest.csv")
    assert len({r["sha256"] for r in rows}) == len(rows)


def test_audio_is_normalised_to_the_target_loudness(rendered):
    out = rendered[0]
    meta = read_csv(out / "audio.csv")[0]
    assert float(meta["loudness_out_lufs"]) == pytest.approx(-23.0, abs=0.01)
    y = decode_audio(out / "stimuli" / "laugh_energy-intense-s00.mp4", 48000).astype(np.float64)
    assert pyloudnorm.Meter(48000).integrated_loudness(y) == pytest.approx(-23.0, abs=0.7)  # after AAC


def test_orders_for_psychopy_and_jspsych(rendered):
    out = rendered[0]
    conds = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    rows = williams(4)
    files = {r["stimulus_id"]: r["file"] for r in read_csv(out / "manifest.csv")}
    every = read_csv(out / "orders" / "psychopy_all.csv")
    assert len(every) == 5 * 4
    js_all = json.loads((out / "orders" / "jspsych_all.json").read_text())
    for p in range(1, 6):
        psy = read_csv(out / "orders" / "psychopy" / f"participant_{p:03d}.csv")
        assert [r["condition"] for r in psy] == [conds[i] for i in rows[(p - 1) % 4]]
        assert all(files[r["stimulus_id"]] == r["file"] and (out / r["file"]).is_file() for r in psy)
        assert psy == [r for r in every if r["participant"] == str(p)]
        js = json.loads((out / "orders" / "jspsych" / f"participant_{p:03d}.json").read_text())
        assert js == js_all[str(p)]
        assert [v["stimulus"] for v in js] == [[r["file"]] for r in psy]  # the video plugins take a list
        assert [v["trial"] for v in js] == [1, 2, 3, 4]


def test_riddle_preset_through_the_command_line(tmp_path):
    """SS/SL/LS/LL: smiles are silent, laughs are heard; one trial per condition with role and response."""
    out = tmp_path / "riddle"
    r = laughlab("experiment=stimuli", "harness.preset=riddle", *SMALL, "harness.corpus.profiles=[intense,mild]",
                 f"hydra.run.dir={out}", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    rows = read_csv(out / "manifest.csv")
    assert [r["condition"] for r in rows] == ["SS", "SS", "SL", "SL", "LS", "LS", "LL", "LL"]
    for row in rows:
        audio = decode_audio(out / row["file"])
        if row["condition"] in ("SS", "LS"):
            assert np.abs(audio).max() < 1e-4
        else:
            assert np.abs(audio).max() > 0.01
    psy = read_csv(out / "orders" / "psychopy" / "participant_001.csv")
    assert len(psy) == 4 and sorted(r["condition"] for r in psy) == ["LL", "LS", "SL", "SS"]
    assert {(r["condition"], r["role"], r["response"]) for r in psy} == {
        ("SS", "speaking", "smile"), ("SL", "speaking", "laugh"), ("LS", "listening", "smile"),
        ("LL", "listening", "laugh")}
    assert [r["audio_id"] for r in psy] == ["intense-s00", "mild-s00", "intense-s00", "mild-s00"]
    assert "stimuli: 8 videos" in r.stdout and f"; the study page: python -m laughlab study build {out}\n" in r.stdout


def test_the_riddles_silent_smiles_keep_the_mouth_shut_and_its_laughs_open_it(tmp_path):
    """A video producer's review: SS and LS (a silent smile) drove the jaw from the muted laugh, so the smile
    stimuli showed a laughing mouth without a sound (dark mouth pixels as many as the laugh's).  Their jaw stays
    shut; the smile is there; SL's jaw opens on the same input."""
    import pandas as pd
    from omegaconf import OmegaConf

    from laughlab.core import pipeline
    from laughlab.core.config import compose_app

    from laughlab_experiments.stimuli import _shut_mouth

    h = OmegaConf.to_container(compose_config(["experiment=stimuli", "harness.preset=riddle"]).harness, resolve=True)
    conds, muted = h["conditions"], set(h["presets"]["riddle"]["muted"])
    got = {}
    for cond in ("SS", "LS", "SL"):
        shut = _shut_mouth(conds[cond], cond) if cond in muted else ()
        cfg = compose_app([*conds[cond], *shut, "input.profile=intense", "input.duration_s=4", "seed=0",
                           "~output.plots"])
        pipeline.execute(pipeline.build(cfg), tmp_path / cond, {})
        got[cond] = pd.read_csv(tmp_path / cond / "channels.csv")
    for cond in ("SS", "LS"):
        assert got[cond]["jaw"].max() == 0.0 and got[cond]["smile"].max() > 0.5, cond
    assert got["SL"]["jaw"].max() > 0.5
    # another face renders as before, said in a note (face=facs has no setting that keeps its mouth shut)
    assert _shut_mouth([*conds["SS"], "face=facs"], "SS") == ()


def test_a_silent_recording_among_the_stimuli_is_named(tmp_path):
    """A video producer's review: a silent WAV in the corpus folder stopped the run with 'cannot normalise the
    loudness of silent audio', naming no file."""
    import soundfile as sf

    (tmp_path / "rec").mkdir()
    sf.write(tmp_path / "rec" / "quiet.wav", np.zeros(32000), 16000)
    r = laughlab("experiment=stimuli", f"harness.corpus.folder={tmp_path / 'rec'}", "harness.corpus.profiles=[]",
                 f"hydra.run.dir={tmp_path / 'out'}", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == ("laughlab: error: stimulus audio quiet.wav: cannot normalise the "
                                              "loudness of silent audio; take it out of the corpus folder\n"), r.stderr
    assert not (tmp_path / "out").exists()


def test_normalise_loudness():
    rng = np.random.default_rng(0)
    x = (0.05 * rng.standard_normal(16000 * 2)).astype(np.float32)
    y, info = normalise_loudness(x, 16000, -23.0)
    assert info["loudness_out_lufs"] == pytest.approx(-23.0, abs=1e-6)
    assert y.dtype == np.float32 and not info["limited"]
    y, info = normalise_loudness(x, 16000, -3.0, max_peak_dbfs=-1.0)  # too loud for the peak limit
    assert info["limited"] and info["peak_out_dbfs"] == pytest.approx(-1.0, abs=1e-4)
    assert info["loudness_out_lufs"] < -3.0
    with pytest.raises(LaughlabError, match="silent"):
        normalise_loudness(np.zeros(16000), 16000)
    with pytest.raises(LaughlabError, match="0.4 s"):
        normalise_loudness(x[:1000], 16000)


def test_a_failed_run_leaves_no_files(tmp_path, monkeypatch):
    import laughlab_experiments.stimuli as stimuli

    real, calls = stimuli._render, []

    def render(*args, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise LaughlabError("boom")
        return real(*args, **kw)

    monkeypatch.setattr(stimuli, "_render", render)
    with pytest.raises(LaughlabError, match="boom"):
        run(compose_config(["experiment=stimuli", *SMALL]), tmp_path)
    assert not list(tmp_path.iterdir())


def test_an_interrupted_run_resumes_and_renders_only_what_is_missing(tmp_path, monkeypatch, rendered):
    """Ctrl-C during the third video: the two rendered videos and their journal stay; the same command then
    renders only the missing ones, and the folder ends as a whole run's (same manifest bytes, no journal).
    A changed setting renders again what it changes (every video here: the video width)."""
    import laughlab_experiments.stimuli as stimuli

    real, calls, stop = stimuli._render, [], [True]

    def render(*args, **kw):
        calls.append(args[2].name)
        if len(calls) == 3 and stop[0]:
            stop[0] = False
            raise KeyboardInterrupt
        return real(*args, **kw)

    monkeypatch.setattr(stimuli, "_render", render)
    with pytest.raises(KeyboardInterrupt):
        run(compose_config(["experiment=stimuli", *SMALL]), tmp_path)
    first = calls[:2]
    assert sorted(p.stem for p in (tmp_path / "stimuli").glob("*.mp4")) == sorted(first)
    assert (tmp_path / "stimuli" / stimuli.JOURNAL).is_file() and not (tmp_path / "manifest.csv").exists()
    calls.clear()
    (tmp_path / f"{stimuli.SCRATCH}killed").mkdir()   # what a SIGKILL leaves: the scratch folder goes on resume
    run(compose_config(["experiment=stimuli", *SMALL]), tmp_path)
    assert not list(tmp_path.glob(f"{stimuli.SCRATCH}*"))
    n = len(read_csv(rendered[0] / "manifest.csv"))
    assert len(calls) == n - 2 and not set(calls) & set(first)   # only the missing ones
    assert (tmp_path / "manifest.csv").read_bytes() == (rendered[0] / "manifest.csv").read_bytes()
    assert not (tmp_path / "stimuli" / stimuli.JOURNAL).exists()
    # a damaged video is rendered again; a changed setting renders again what it changes (the width: every video)
    other = [*SMALL, "harness.video.width=64"]
    calls.clear()
    stop[0] = True
    with pytest.raises(KeyboardInterrupt):
        run(compose_config(["experiment=stimuli", *other]), tmp_path / "w")
    kept = calls[:2]
    (tmp_path / "w" / "stimuli" / f"{kept[0]}.mp4").write_bytes(b"damaged")
    calls.clear()
    stop[0] = True
    with pytest.raises(KeyboardInterrupt):
        run(compose_config(["experiment=stimuli", *other]), tmp_path / "w")
    assert calls[0] == kept[0] and kept[1] not in calls
    calls.clear()
    run(compose_config(["experiment=stimuli", *SMALL, "harness.video.width=48"]), tmp_path / "w")
    assert len(calls) == n
    assert {r["sha256"] for r in read_csv(tmp_path / "w" / "manifest.csv")} == \
        {hashlib.sha256(p.read_bytes()).hexdigest() for p in (tmp_path / "w" / "stimuli").glob("*.mp4")}


def test_an_unbalanced_design_is_said_before_rendering():
    """A review: 25 participants on a square of 4 rows, and one_per_condition with one audio item for four
    conditions, were accepted without a word."""
    from laughlab_experiments.stimuli import design_notes

    assert design_notes(4, 2, 24, "all") == [] and design_notes(3, 6, 12, "one_per_condition") == []   # 3: 6 rows
    (note,) = design_notes(4, 2, 25, "all")
    assert note.startswith("25 participants on a Williams square of 4 rows: row 1 serves one participant more")
    assert note.endswith("24 or 28 participants balance them")
    (note,) = design_notes(3, 6, 8, "all")
    assert "rows 1-2 serve one participant more" in note and note.endswith("6 or 12 participants balance them")
    (note,) = design_notes(4, 1, 4, "one_per_condition")
    assert note.startswith("one_per_condition with 1 audio item(s) for 4 conditions: each participant hears an item")


def test_a_bad_design_is_refused_before_anything_is_made(tmp_path):
    """A sweeps review: harness.design=al was refused in one line, but after the harness had made runs/ (left empty)."""
    r = laughlab("experiment=stimuli", "harness.design=al", "hydra.run.dir=runs/st2", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == ("laughlab: error: harness.design must be all or one_per_condition "
                                              "(got 'al')\n"), r.stderr
    assert list(tmp_path.iterdir()) == []
