"""End to end through ``python -m laughlab``: the run-directory contract, reproducibility, errors."""
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import soundfile as sf

ROOT = Path(__file__).resolve().parents[1]


def laughlab(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "laughlab", *args], capture_output=True, text=True,
                          cwd=cwd or ROOT, timeout=300)


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "default"
    r = laughlab(f"hydra.run.dir={out}", "input.duration_s=12")
    assert r.returncode == 0, r.stderr
    return out


def test_run_directory_contract(default_run):
    d = default_run
    for name in ("channels.csv", "events.csv", "motion.bvh", "metrics.json", ".hydra/config.yaml",
                 "plots/fig3_2_mcs.png", "plots/fig4_2_energy.png", "truth.csv", "input.wav"):
        assert (d / name).is_file(), name
    assert not list(d.rglob("*.part"))
    ch = pd.read_csv(d / "channels.csv")
    assert ch.columns[0] == "time"
    for col in ("mcs", "chest", "belly", "smile", "jaw", "eyes_closed", "energy", "clip_energy"):
        assert col in ch.columns
    assert len(ch) == 12 * 60
    assert np.allclose(np.diff(ch.time), 1 / 60, atol=1e-6)
    assert np.isfinite(ch.drop(columns="time").to_numpy()).all()
    ev = pd.read_csv(d / "events.csv")
    assert list(ev.columns) == ["time", "event", "clip", "energy", "speed", "reason", "offset", "end"]
    assert (ev.event == "start").sum() >= 1
    m = json.loads((d / "metrics.json").read_text())
    for key in ("frame_ms_p50", "frame_ms_p99", "realtime_factor", "n_frames"):
        assert key in m
    assert m["n_frames"] == 12 * 60


def test_bvh_parses_in_an_independent_reader(default_run):
    from bvh import Bvh

    mocap = Bvh((default_run / "motion.bvh").read_text())
    assert mocap.nframes == 12 * 60                    # frames = duration x fps
    assert mocap.frame_time == pytest.approx(1 / 60, abs=1e-6)
    assert len(mocap.get_joints_names()) == 22
    assert len(mocap.frames[0]) == 69


def test_same_seed_same_bytes_other_seed_differs(default_run, tmp_path):
    again = tmp_path / "again"
    assert laughlab(f"hydra.run.dir={again}", "input.duration_s=12").returncode == 0
    for name in ("channels.csv", "events.csv", "motion.bvh", "truth.csv", "input.wav"):
        assert sha(default_run / name) == sha(again / name), name
    other = tmp_path / "other"
    assert laughlab(f"hydra.run.dir={other}", "input.duration_s=12", "seed=1").returncode == 0
    assert sha(default_run / "channels.csv") != sha(other / "channels.csv")


def test_file_input_matches_the_synthetic_run(default_run, tmp_path):
    """The synthetic run's audio, read back from input.wav, gives the same channels and motion."""
    r = laughlab(f"hydra.run.dir={tmp_path / 'f'}", "input=file", f"input.path={default_run / 'input.wav'}")
    assert r.returncode == 0, r.stderr
    for name in ("channels.csv", "events.csv", "motion.bvh"):
        assert sha(default_run / name) == sha(tmp_path / "f" / name), name


def one_line_error(r):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laughlab: error: "), r.stderr
    assert "Traceback" not in r.stderr
    return lines[0]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    (d / "text.wav").write_text("this is not audio\n")
    (d / "empty.wav").write_bytes(b"")
    sf.write(d / "zero.wav", np.zeros(0, dtype=np.float32), 16000)
    return d


@pytest.mark.parametrize("args, message", [
    (["input=file", "input.path=missing.wav"], "input file not found"),
    (["input=file", "input.path=empty.wav"], "input file is empty"),
    (["input=file", "input.path=text.wav"], "cannot read audio"),
    (["input=file", "input.path=zero.wav"], "no audio samples"),
    (["input=file"], "input.path is required"),
    (["extractor=nope"], "unknown extractor 'nope'; choose one of: phoneme, pressure, rms"),
    (["extractor.bogus=1"], "unknown parameter extractor.bogus; valid: scale"),
    (["extractor.rise_per_s=-1"], "rise_per_s must be > 0"),
    (["fps=0"], "fps must be a positive number"),
    (["fps=-30"], "fps must be a positive number"),
    (["experiment=nope"], "unknown experiment 'nope'"),
])
def test_bad_input_one_line_no_output(bad_files, args, message):
    out = bad_files / "run"
    r = laughlab(*args, f"hydra.run.dir={out}", cwd=bad_files)
    assert message in one_line_error(r)
    assert not out.exists()


def test_failure_during_the_run_leaves_nothing(tmp_path):
    plugdir = tmp_path / "plug"
    plugdir.mkdir()
    (plugdir / "fragile.py").write_text(
        "import laughlab\n"
        "from laughlab.core.errors import LaughlabError\n"
        "from laughlab_plugins.extractor_rms import RmsExtractor\n"
        "class Fragile(RmsExtractor):\n"
        "    name = 'fragile'\n"
        "    def step(self, block, frame):\n"
        "        if frame.index == 700:\n"
        "            raise LaughlabError('audio went away at frame 700')\n"
        "        super().step(block, frame)\n"
        "@laughlab.hookimpl\n"
        "def register_extractors(register):\n"
        "    register(Fragile)\n")
    out = tmp_path / "run"
    r = laughlab(f"plugins_dir={plugdir}", "extractor=fragile", f"hydra.run.dir={out}")
    assert "audio went away at frame 700" in one_line_error(r)
    assert not out.exists()


def test_existing_run_is_not_overwritten_without_asking(default_run, tmp_path):
    before = sha(default_run / "channels.csv")
    r = laughlab(f"hydra.run.dir={default_run}", "seed=5")
    assert "already holds a run" in one_line_error(r)
    assert sha(default_run / "channels.csv") == before
    target = tmp_path / "o"
    assert laughlab(f"hydra.run.dir={target}", "input.duration_s=2").returncode == 0
    r = laughlab(f"hydra.run.dir={target}", "input.duration_s=3", "overwrite=true")
    assert r.returncode == 0, r.stderr
    assert len(pd.read_csv(target / "channels.csv")) == 180


def test_plugins_command_lists_kind_name_origin():
    r = laughlab("plugins")
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    assert lines[0].split()[:3] == ["kind", "name", "origin"]
    rows = {tuple(ln.split()[:2]) for ln in lines[1:]}
    for row in [("source", "synthetic"), ("extractor", "rms"), ("face", "smile"), ("body", "shapes"),
                ("scheduler", "energy"), ("sink", "bvh")]:
        assert row in rows


def test_a_successful_run_says_what_ran_how_long_and_where(tmp_path):
    out = tmp_path / "run"
    r = laughlab(f"hydra.run.dir={out}", "input.duration_s=2")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 1
    line = lines[0]
    assert line.startswith("laughlab: 2.0 s of synthetic input, rms > yamnet > smile > shapes > energy, in ")
    assert "x real time" in line and f"-> {out}/: " in line
    for name in ("channels.csv", "events.csv", "motion.bvh", "plots/"):
        assert name in line and (out / name.rstrip("/")).exists()


def test_progress_in_a_log_is_a_line_every_few_seconds_not_a_bar():
    import io

    from laughlab.harness.runner import LogProgress

    buf = io.StringIO()
    p = LogProgress(5, "smoke", every_s=3600.0, stream=buf)
    for _ in range(5):
        p.update()
    assert buf.getvalue() == ""                              # nothing until every_s has passed
    p.close()
    assert buf.getvalue().startswith("smoke: 5/5 trials, ") and "\r" not in buf.getvalue()
    p = LogProgress(5, "smoke", every_s=0.0, stream=(buf := io.StringIO()))
    p.update()
    p.update()
    assert buf.getvalue().splitlines()[:2] == ["smoke: 1/5 trials, 0 s", "smoke: 2/5 trials, 0 s"]


def test_help_lists_every_group_with_examples_and_docs():
    r = laughlab("--help")
    assert r.returncode == 0 and "Hydra" not in r.stdout.splitlines()[0]
    assert r.stdout.startswith("usage: python -m laughlab")
    for line in ("  face:        smile, cgm, facs", "  body:        shapes, follow, fourier, hill",
                 "  detector:    yamnet, laugh, none"):
        assert line in r.stdout
    assert "examples:" in r.stdout and "README.md" in r.stdout and "--hydra-help" in r.stdout
