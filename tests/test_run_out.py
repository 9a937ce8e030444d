"""``run_out=true``: an input that ends while a clip plays goes on in silence until the clip has ended and the
blend back to idle is done (a game developer's review: a baked 5.8 s laugh ended with the body half-way down a
``rofl``, hips at 50 cm and pitched 47 degrees, and nothing said how to let it finish)."""
from __future__ import annotations

import csv
import inspect
import json

import numpy as np
import pytest
import soundfile as sf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core import pipeline
from laughlab.core.mixer import Mixer

#: 3 s of the synthetic laughter (seed 0) ends inside hands_on_belly; the papers' pipeline, so no model
ARGS = ("input.duration_s=3", "detector=none", "~output.plots")
FPS = 60


def _rows(d, name="channels.csv"):
    return (d / name).read_text().splitlines()


def _events(d):
    with open(d / "events.csv", newline="") as f:
        return list(csv.DictReader(f))


def _last_pose(d):
    return [float(v) for v in (d / "motion.bvh").read_text().rstrip().splitlines()[-1].split()]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("run_out")
    off = laughlab(*ARGS, f"hydra.run.dir={root / 'off'}")
    on = laughlab(*ARGS, "run_out=true", f"hydra.run.dir={root / 'on'}")
    assert off.returncode == 0 and on.returncode == 0, off.stderr + on.stderr
    return root, off, on


def test_the_input_ending_mid_clip_is_said_with_the_setting(runs):
    root, off, _ = runs
    assert "3.0 s of synthetic input (ends mid-hands_on_belly: run_out=true plays it out), rms > none" in off.stdout
    ev = _events(root / "off")
    assert ev[-1]["event"] == "start" and ev[-1]["clip"] == "hands_on_belly"   # no stop: cut by the input's end
    assert json.loads((root / "off" / "metrics.json").read_text())["clip_at_end"] == "hands_on_belly"


def test_the_run_goes_on_in_silence_until_the_blend_back_to_idle_is_done(runs):
    root, _, on = runs
    off_rows, on_rows = _rows(root / "off"), _rows(root / "on")
    assert on_rows[:len(off_rows)] == off_rows        # the input's frames are the same bytes
    assert len(on_rows) > len(off_rows) == 1 + 3 * FPS
    ev = _events(root / "on")
    starts, stops = [e for e in ev if e["event"] == "start"], [e for e in ev if e["event"] == "stop"]
    # every clip stops; in the silence the energy scheduler's laughing energy winds down (it may start a calmer
    # clip, as here: lean_front2 at energy 10 after hands_on_belly at 15), then none
    assert len(starts) == len(stops) and stops[-1]["clip"] == starts[-1]["clip"]
    assert [e["clip"] for e in starts if float(e["time"]) < 3.0] == [e["clip"] for e in _events(root / "off")
                                                                     if e["event"] == "start"]
    # the last frame is the first at which the mixer's blend to idle (10/24 s from the clip's stop) is done and the
    # face is at rest: the default face's smile, clipped at 1 while its state falls, held 1 there until this
    # session (a facial animator's review: run_out ended on a full smile)
    t_stop = float(stops[-1]["time"])
    blend_done = t_stop + inspect.signature(Mixer).parameters["idle_blend_s"].default   # 10/24 s
    frames = len(on_rows) - 1
    assert (frames - 1) / FPS >= blend_done - 1.01 / FPS
    with open(root / "on" / "channels.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    smile = [float(r["smile"]) for r in rows]
    assert max(smile[len(off_rows) - 2:]) == 1.0 and smile[-1] == smile[-2] == 0.0 < smile[-3]
    assert float(rows[-1]["jaw"]) == 0.0
    m = json.loads((root / "on" / "metrics.json").read_text())
    assert m["duration_s"] == pytest.approx(3.0) and m["n_frames"] == frames
    assert m["run_out_s"] == pytest.approx((frames - 3 * FPS) / FPS) and "clip_at_end" not in m
    assert f"3.0 s of synthetic input, then {m['run_out_s']:.1f} s of silence to bring it to rest (run_out)" \
        in on.stdout
    # standing: the hips at the idle pose's height, where the cut run's last frame is elsewhere
    assert abs(_last_pose(root / "on")[1] - 95.0) < 2.0
    assert _last_pose(root / "off") != _last_pose(root / "on")


def test_an_input_that_ends_before_any_clip_runs_out_until_the_face_is_at_rest(tmp_path):
    """0.5 s of the synthetic laughter ends before any clip, the smile still fading (0.032, falling 0.0033 a frame):
    run_out plays silence until it has (an animator's review: a baked laugh ended on a 0.29 smile), and no longer."""
    a = laughlab("input.duration_s=0.5", "detector=none", "~output.plots", f"hydra.run.dir={tmp_path / 'a'}")
    b = laughlab("input.duration_s=0.5", "detector=none", "~output.plots", "run_out=true",
                 f"hydra.run.dir={tmp_path / 'b'}")
    assert a.returncode == b.returncode == 0
    cut, out = _rows(tmp_path / "a"), _rows(tmp_path / "b")
    assert out[:len(cut)] == cut and _events(tmp_path / "a") == _events(tmp_path / "b") == []
    with open(tmp_path / "b" / "channels.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    smile = [float(r["smile"]) for r in rows]
    last_input = len(cut) - 2   # the input's last frame
    # the first frame that did not move ends it: the smile reached 0 one frame before
    assert smile[last_input] > 0.03 and smile[-1] == smile[-2] == 0.0 and smile[-3] > 0.0
    assert all(float(r["mcs"]) == 0.0 and float(r["jaw"]) == 0.0 for r in rows[last_input + 1:])
    # a run whose face is already at rest gains nothing: the settled run again, from its own wav
    c = laughlab("input=file", f"input.path={tmp_path / 'b' / 'input.wav'}", "detector=none", "~output.plots",
                 "run_out=true", f"hydra.run.dir={tmp_path / 'c'}")
    assert c.returncode == 0, c.stderr
    assert len(_rows(tmp_path / "c")) == len(out)


def test_the_silence_is_bounded(tmp_path, monkeypatch):
    monkeypatch.setattr(pipeline, "RUN_OUT_MAX_S", 0.25)
    r = laughlab(*ARGS, "run_out=true", f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 0, r.stderr
    assert len(_rows(tmp_path / "r")) == 1 + 3 * FPS + 15   # 0.25 s at 60 fps


def test_a_session_runs_out_as_the_file_does(runs, tmp_path):
    """Streaming and offline agree: the session's close() returns the silent frames the file run wrote."""
    from laughlab.session import Session

    root = runs[0]
    x, sr = sf.read(root / "on" / "input.wav", dtype="float32")
    frames = []
    with Session(["run_out=true", "detector=none"], sample_rate=sr) as s:
        for i in range(0, len(x), 1234):
            frames += s.feed(x[i:i + 1234])
        frames += s.close()
    with open(root / "on" / "channels.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(frames) == len(rows)
    for col in ("mcs", "energy", "smile", "jaw"):
        np.testing.assert_allclose([fr.channels[col] for fr in frames], [float(r[col]) for r in rows], atol=1e-6,
                                   err_msg=col)


def test_run_out_takes_true_or_false(tmp_path):
    r = laughlab("input.duration_s=1", "run_out=maybe", f"hydra.run.dir={tmp_path / 'r'}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "run_out" in r.stderr, r.stderr
    assert not (tmp_path / "r").exists()


def test_the_figures_hatch_the_silence_after_the_input(tmp_path, monkeypatch):
    """The figures drew run_out's silence as if it were the laugh's own (left from the game developer's review):
    every time-axis figure hatches from the input's end (3 s) to the last frame, and says so in its legend; a run
    without run_out hatches nothing."""
    from matplotlib.figure import Figure

    NAMES = ("fig3_1_calibration", "fig3_2_mcs", "fig4_1_energy", "fig4_2_energy")
    hatched: dict = {}
    original = Figure.savefig

    def watched(self, fname, *args, **kwargs):
        spans = [p.get_x() for ax in self.axes for p in ax.patches if p.get_hatch() == "///"]
        legends = [t.get_text() for leg in self.legends for t in leg.get_texts()]
        hatched.setdefault(next((n for n in NAMES if n in str(fname)), str(fname)), (spans, legends))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", watched)
    on = laughlab("input.duration_s=3", "detector=none", "run_out=true", f"hydra.run.dir={tmp_path / 'on'}")
    assert on.returncode == 0, on.stderr
    assert set(NAMES) <= set(hatched)
    for name in NAMES:
        spans, legends = hatched.pop(name)
        assert spans and all(x == pytest.approx(3.0) for x in spans), name
        assert "after the input: silence (run_out)" in legends, name
    off = laughlab("input.duration_s=3", "detector=none", f"hydra.run.dir={tmp_path / 'off'}")
    assert off.returncode == 0, off.stderr
    assert all(not spans for spans, _ in hatched.values()), hatched


def test_concats_idle_segments_do_not_keep_run_out_going(tmp_path):
    """A review: under scheduler=concat run_out always reached its 20 s cap, the scheduler starting one idle segment
    (a looping clip) after another, and the run without it said "ends mid-idle". Idle is no clip to play out."""
    args = ("input.duration_s=3", "detector=none", "extractor=phoneme", "scheduler=concat", "face=cgm",
            "~output.plots")   # Ding's face, at rest at once (the thesis' smile takes 14 s to fall from 1)
    on = laughlab(*args, "run_out=true", f"hydra.run.dir={tmp_path / 'on'}")
    off = laughlab(*args, f"hydra.run.dir={tmp_path / 'off'}")
    assert on.returncode == off.returncode == 0, on.stderr + off.stderr
    m = json.loads((tmp_path / "on" / "metrics.json").read_text())
    assert m.get("run_out_s", 0.0) < 2.0                         # the clip it ends in played out, not 20 s
    assert "ends mid-idle" not in off.stdout
    assert json.loads((tmp_path / "off" / "metrics.json").read_text()).get("clip_at_end") != "idle"
    ev = _events(tmp_path / "on")
    assert ev[-1]["clip"] == "idle" or ev[-1]["event"] == "stop"   # nothing but idle left playing
