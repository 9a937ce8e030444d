"""The yamnet detector: the bundled model against YAMNet's model card, the 16 kHz conversion, the gate's
rule frame by frame, bad model files, and ``laughlab detect`` end to end."""
import re
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
from hypothesis import given, settings, strategies as st

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.bases import Context
from laughlab.core.frame import Frame
from laughlab.core.summary import factor_text
from laughlab.detector import segments as S
from laughlab.detector import yamnet as Y
from laughlab.detector.stream16k import _sos_kernel
from laughlab.detector.yamnet_model import CUTS

FPS = 60.0


@pytest.fixture(scope="module")
def model():
    return Y.Yamnet()


def corpus_file(iid):
    from laughlab.corpora import fetch

    return fetch.require()[iid]


def mean_scores(model, path):
    from laughlab.corpora.mixed import load

    x = load(str(path), 16000)
    ends = np.arange(Y.WINDOW, max(len(x), Y.WINDOW) + 1, Y.WINDOW // 2)
    return Y.window_scores(x, 16000, ends, model).mean(axis=0)


def test_the_class_map_is_yamnets():
    names = Y.class_names()
    assert len(names) == 521 and names[0] == "Speech" and names[13] == "Laughter" and names[494] == "Silence"
    assert Y.laugh_indices(names) == [13, 14, 15, 16, 17, 18]


def test_the_model_takes_one_16k_window_and_gives_521_scores(model):
    s = model.scores(np.zeros(Y.WINDOW, np.float32))
    assert s.shape == (521,) and np.all((s >= 0) & (s <= 1))
    assert int(np.argmax(s)) == Y.class_names().index("Silence")


@pytest.mark.parametrize("iid,cls", [("hedgewars/British-Amazing", "Speech"),        # speech, test split
                                     ("hedgewars/Classic-Laugh", "Laughter"),
                                     ("lmms/bassloops-briff01", "Music"),
                                     ("hedgewars/HillBilly-PoisonCough", "Cough")])
def test_real_recordings_score_their_class_highest(model, iid, cls):
    m = mean_scores(model, corpus_file(iid))
    assert Y.class_names()[int(np.argmax(m))] == cls


@settings(max_examples=25, deadline=None)
@given(st.sampled_from([8000, 11025, 16000, 22050, 44100, 48000]),
       st.lists(st.integers(1, 3000), min_size=1, max_size=12))
def test_the_16k_conversion_does_not_depend_on_how_blocks_are_cut(sr, sizes):
    x = np.random.default_rng(sr).uniform(-0.5, 0.5, sr // 2)
    whole = Y.to_16k(x, sr)
    r, parts, i, j = Y.Resampler16k(sr), [], 0, 0
    while i < len(x):
        k = sizes[j % len(sizes)]
        parts.append(r.push(x[i:i + k]))
        i, j = i + k, j + 1
    assert np.array_equal(np.concatenate(parts), whole)
    # one output sample per 1/16000 s whose next input sample has arrived
    assert len(whole) == ((len(x) - 1) * 16000 - 1) // sr + 1 if sr != 16000 else len(x)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from([22050, 44100, 48000, 96000]), st.lists(st.integers(1, 5000), min_size=1, max_size=8),
       st.integers(0, 2 ** 32 - 1))
def test_the_filters_kernel_call_is_scipys_sosfilt_bit_for_bit(sr, sizes, seed):
    """``sosfilt_carry`` (scipy's compiled kernel called directly, 0.15 ms a call cheaper) gives
    ``scipy.signal.sosfilt``'s output and state, block after block."""
    from scipy.signal import butter, sosfilt

    sos = butter(8, 7200.0, fs=sr, output="sos")
    rng = np.random.default_rng(seed)
    za = zb = np.zeros((len(sos), 2))
    for n in sizes:
        x = rng.standard_normal(n) * 10 ** rng.uniform(-4, 0)
        a, za = sosfilt(sos, x, zi=za)
        b, zb = Y.sosfilt_carry(sos, x, zb)
        assert np.array_equal(a, b) and np.array_equal(za, zb)
    assert _sos_kernel() is not None      # the locked scipy has the kernel: the live path takes it


@pytest.mark.parametrize("sr", [8000, 11025, 22050, 44100, 48000])
def test_a_1khz_tone_keeps_its_level_through_the_conversion(sr):
    t = np.arange(sr) / sr
    y = Y.to_16k(0.5 * np.sin(2 * np.pi * 1000.0 * t), sr)[4000:]
    rms = np.sqrt(np.mean(y * y))
    assert rms == pytest.approx(0.5 / np.sqrt(2), rel=0.05)   # linear interpolation: -0.33 dB at 8 kHz
    spec = np.abs(np.fft.rfft(y * np.hanning(len(y))))
    assert np.argmax(spec) * 16000 / len(y) == pytest.approx(1000.0, abs=2.0)


def test_a_stream_shorter_than_the_window_is_padded_with_silence_before_it():
    w = Y.Window16k(16000)
    w.push(np.full(1000, 0.25))
    got = w.window()
    assert got.shape == (Y.WINDOW,) and np.all(got[:-1000] == 0) and np.all(got[-1000:] == np.float32(0.25))


def test_non_finite_samples_read_as_zero():
    w = Y.Window16k(44100)
    w.push(np.array([np.nan, np.inf, -np.inf, 3.0] * 100))
    assert np.all(np.isfinite(w.window()))


def test_a_missing_model_names_the_file_and_the_fix(tmp_path):
    with pytest.raises(Y.ModelFileError, match=r"nothing\.tflite.*git checkout laughlab/data/yamnet"):
        Y.Yamnet(tmp_path / "nothing.tflite")


def test_a_corrupt_model_names_the_file_and_the_fix(tmp_path, monkeypatch):
    bad = tmp_path / "yamnet"
    bad.mkdir()
    (bad / "yamnet.tflite").write_bytes(b"\0" * 1000)
    monkeypatch.setattr(Y._model, "data_dir", lambda: bad)
    with pytest.raises(Y.ModelFileError, match=r"yamnet\.tflite is damaged.*reinstall"):
        Y.Yamnet()


def test_a_corrupt_model_file_at_run_time_is_one_line(tmp_path):
    """The CLI with a damaged bundled model: one line naming the file, exit 2, no run directory left."""
    code = ("import sys, laughlab.detector.yamnet as Y, pathlib; d = pathlib.Path(sys.argv[1]); "
            "d.mkdir(); (d / 'yamnet.tflite').write_bytes(b'x'); Y._model.data_dir = lambda: d; "
            "from laughlab.cli import main; main(sys.argv[2:])")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "m"), f"hydra.run.dir={tmp_path / 'run'}",
                        "input.duration_s=2", "detector=yamnet"], capture_output=True, text=True)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laughlab: error:") and "yamnet.tflite" in lines[0], r.stderr
    assert not (tmp_path / "run" / "channels.csv").exists()


# --- the model split in its own layers: the same bytes, less work ---------------------------------------

def random_window(rng, n=Y.WINDOW):
    x = np.clip(rng.standard_normal(n) * 10 ** rng.uniform(-4, 0), -1, 1).astype(np.float32)
    if rng.random() < 0.3:
        x[:rng.integers(0, n)] = 0.0    # silence before the start, as in a stream's first second
    return x


def test_the_split_model_gives_the_whole_files_scores_bit_for_bit(model):
    """Front end + network, the network in 1-4 parts in turn, and many patches at once: the unsplit file's bytes."""
    rng = np.random.default_rng(11)
    wins = [random_window(rng) for _ in range(6)] + [np.zeros(Y.WINDOW, np.float32), np.ones(Y.WINDOW, np.float32)]
    whole = np.stack([model.whole_file_scores(w) for w in wins])
    patches = np.stack([model.logmel(Y.frames(w)) for w in wins])
    assert np.array_equal(model.network(patches), whole)                      # 8 windows in one call
    assert np.array_equal(np.stack([model.scores(w) for w in wins]), whole)
    for n in CUTS:                                                            # the network in n parts
        for w, ref in zip(wins[:3], whole):
            h = model.logmel(Y.frames(w))
            for i in range(n):
                h = model.part(i, h, n)
            assert np.array_equal(h[0].astype(np.float64), ref), n
    # a row depends on its own frame only: any subset of frames gives the same rows
    f = Y.frames(wins[0])
    assert np.array_equal(model.logmel(f[[3, 50, 95]]), patches[0][[3, 50, 95]])


def test_offline_window_scores_are_the_whole_files_one_window_at_a_time(model):
    """window_scores (detect, fits, benchmarks): 64 windows at a time on two threads, rows shared between
    overlapping windows; each window's scores are the unsplit file's on that window, bit for bit."""
    rng = np.random.default_rng(5)
    x = rng.uniform(-0.3, 0.3, 44100 * 8)
    ends = np.arange(0, len(x) + 1, 2205)                        # 161 windows, every 50 ms, from the start
    got = Y.window_scores(x, 44100, ends, model)
    x16 = np.clip(Y.to_16k(x, 44100), -1.0, 1.0).astype(np.float32)
    pad = np.concatenate([np.zeros(Y.WINDOW, np.float32), x16, np.zeros(Y.WINDOW, np.float32)])
    for i in rng.choice(len(ends), 12, replace=False):
        e16 = int(round(int(ends[i]) * 16000 / 44100)) + Y.WINDOW
        assert np.array_equal(got[i], model.whole_file_scores(pad[e16 - Y.WINDOW:e16]))
    with pytest.raises(ValueError, match="outside the audio"):
        Y.window_scores(x, 44100, [len(x) + 44100 * 2], model)


@pytest.mark.parametrize("sr", [44100, 16000])
def test_a_non_finite_sample_reads_as_silence_offline_and_spoils_nothing_after_it(model, sr):
    """A review: one NaN in a 44.1 kHz file entered the low-pass filter's state and ``detect`` lost every laugh
    after it.  Offline scores of a file with NaN and inf samples are those of the file with 0 there."""
    rng = np.random.default_rng(8)
    x = rng.uniform(-0.3, 0.3, sr * 3)
    bad = x.copy()
    bad[[100, sr, sr + 7]] = [np.nan, np.inf, -np.inf]
    zero = x.copy()
    zero[[100, sr, sr + 7]] = 0.0
    ends = np.arange(sr // 2, len(x) + 1, sr // 4)
    got = Y.window_scores(bad, sr, ends, model)
    assert np.isfinite(got).all() and np.array_equal(got, Y.window_scores(zero, sr, ends, model))


def test_offline_scores_report_their_progress_piece_by_piece(model):
    """``detect``'s bar moves through a long file (a review: 0% until a 2-hour file ended): the seconds of input
    converted, piece by piece, adding up to the file's length; the scores are the same with or without it."""
    from laughlab.detector.stream16k import CONVERT_CHUNK

    sr = 44100
    x = np.random.default_rng(3).uniform(-0.2, 0.2, 2 * CONVERT_CHUNK + 1000)
    ends = np.arange(sr, len(x) + 1, sr)
    seen = []
    got = Y.window_scores(x, sr, ends, model, progress=seen.append)
    assert seen == [CONVERT_CHUNK / sr, CONVERT_CHUNK / sr, 1000 / sr]
    assert np.array_equal(got, Y.window_scores(x, sr, ends, model))


def test_frames_are_the_models_own():
    """96 frames of 400 samples every 160, as the file's reshape and gather cut them (ops 0-4)."""
    x = np.arange(Y.WINDOW, dtype=np.float32)
    f = Y.frames(x)
    assert f.shape == (96, 400) and f[0, 0] == 0 and f[1, 0] == 160 and f[95, -1] == Y.WINDOW - 1
    assert np.array_equal(Y.frame_starts(20000), 20000 - Y.WINDOW + 160 * np.arange(96))


@settings(max_examples=12, deadline=None)
@given(st.sampled_from([16000, 22050, 44100, 48000]), st.lists(st.integers(1, 4000), min_size=1, max_size=8).map(
           lambda sizes: [max(s, 200) if i % 2 else s for i, s in enumerate(sizes)]),   # short blocks, not only
       st.lists(st.booleans(), min_size=1, max_size=7), st.integers(0, 2**31))
def test_kept_log_mel_rows_are_the_windows_own(sr, sizes, prepares, seed):
    """Window16k.patch (rows kept from earlier windows, rows made ahead by prepare) equals the front end
    on the window's 96 frames, whatever the blocks, the window times and the prepare calls."""
    model = Y.Yamnet()
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.5, 0.5, int(sr * 1.6))
    w, i, j, hop = Y.Window16k(sr), 0, 0, sr // 4
    next_window = hop
    while i < len(x):
        k = sizes[j % len(sizes)]
        w.push(x[i:i + k])
        i, j = i + k, j + 1
        if prepares[j % len(prepares)]:
            w.prepare(model)
        if i >= next_window:
            next_window += hop
            win = w.window()
            assert np.array_equal(w.patch(model), model.logmel(Y.frames(win)))


def test_a_tflite_file_that_is_not_yamnet_is_refused(tmp_path, model):
    other = tmp_path / "other.tflite"
    other.write_bytes(model.m.split.front)          # a valid TensorFlow Lite file, but not YAMNet's layers
    with pytest.raises(Y.ModelFileError, match=r"other\.tflite is not the YAMNet model"):
        Y.Yamnet(other)


def test_prefetching_a_file_gives_the_same_bytes_and_a_mismatch_falls_back(tmp_path):
    """input=file: the helper thread's windows (prefetch, the default) give the frame thread's bytes; a
    helper that reads other audio is caught window by window and the frame thread takes over."""
    from laughlab.core import pipeline
    from laughlab.harness.runner import _compose

    wav = tmp_path / "in.wav"
    sf.write(wav, corpus_audio(), 44100, subtype="PCM_16")

    def run(name, extra=(), sabotage=None):
        cfg = _compose(["input=file", f"input.path={wav}", "output=trial", "progress=off", *extra])
        pipe = pipeline.build(cfg)
        helpers = []
        real_prefetch = pipe.detector.prefetch

        def prefetch(blocks):
            if sabotage is not None:   # from block ``sabotage`` on, the helper hears each block backwards
                real_prefetch(lambda: (b[::-1].copy() if i >= sabotage else b for i, b in enumerate(blocks())))
            else:
                real_prefetch(blocks)
            helpers.append(pipe.detector.ahead)
        pipe.detector.prefetch = prefetch
        pipeline.execute(pipe, tmp_path / name, {})
        return helpers, (tmp_path / name / "channels.csv").read_bytes()

    none, a = run("off", ["detector.prefetch=false"])
    (on,), b = run("on")
    n = len(a.splitlines()) - 1                                   # frames; a window every 15, 3 frames to take effect
    assert none == [None] and on.served == len(range(14, n - 3, 15)) > 15 and not on.done and b == a
    (bad,), c = run("bad", sabotage=0)
    assert bad.served == 0 and bad.done and c == a
    # the helper agrees for 7 windows (blocks 0-104), then not: the frame thread takes the stream up there
    (late,), d = run("late", sabotage=110)
    assert late.served == 7 and late.done and d == a
    # a float file with NaN samples (read as 0 by the conversion): the helper's samples still agree
    x = corpus_audio().astype(np.float32)
    x[[1000, 50_000, 200_000]] = np.nan
    sf.write(wav, x, 44100, subtype="FLOAT")
    none, e = run("nan-off", ["detector.prefetch=false"])
    (nan,), f = run("nan-on")
    assert nan.served > 15 and not nan.done and f == e


def _count_rows(fps, hop_s, seconds, seed):
    """Step the default detector at 44.1 kHz over noise, counting the log-mel rows: per window, the blocks
    still to convert and the rows its ``patch`` computed; and all the rows the run computed."""
    from laughlab_plugins.detector_yamnet import YamnetDetector, YamnetParams

    det = YamnetDetector(YamnetParams(hop_s=hop_s), Context(fps=fps, sample_rate=44100))
    per_window, rows, patch, logmel = [], [], det.window.patch, det.model.logmel

    def counting_rows(frames):
        rows.append(len(frames))
        return logmel(frames)

    def counting(model, window=None):
        pending, before = len(det.window.pending), len(rows)
        out = patch(model, window)
        per_window.append((pending, sum(rows[before:])))
        return out

    det.window.patch, det.model.logmel = counting, counting_rows
    rng = np.random.default_rng(seed)
    n = int(round(44100 / fps))
    for k in range(int(seconds * fps)):
        det.step(rng.uniform(-0.3, 0.3, n), Frame(k, k / fps, 1 / fps, {"mcs": 0.5}, None, {}, {}, [], 0.0))
    return per_window, sum(rows)


@pytest.mark.parametrize("fps,hop_s", [(60, 0.25), (30, 0.3), (60, 0.1), (25, 0.5)])  # windows on the 10 ms grid
def test_a_windows_frame_converts_at_most_one_block_and_computes_few_rows(fps, hop_s):
    """The frame that takes a window also runs the network's first part: the frames between windows have
    converted the audio and computed the complete rows (``prepare``), up to the frame before it."""
    seen, _ = _count_rows(fps, hop_s, 4, 3)
    assert len(seen) >= 7 and seen[0][1] == 96                   # the first window computes all its rows
    for pending, computed in seen[1:]:
        assert pending <= 1 and computed <= int(np.ceil(100.0 / fps)) + 1


@pytest.mark.parametrize("fps,hop_s", [(30, 0.25), (60, 0.25), (30, 0.3)])
def test_windows_off_one_anothers_grid_compute_no_row_twice(fps, hop_s):
    """At 30 fps a window every 8 frames (4,266.7 samples at 16 kHz) never falls on the last one's 160-sample
    grid: the rows the frames between windows made on that grid were thrown away (119 rows a window for 96).
    ``prepare`` now makes rows only while the windows keep one grid; the scores are the same either way."""
    seen, rows = _count_rows(fps, hop_s, 6, 5)
    windows = len(seen)
    new_rows = 96 + (windows - 1) * round(hop_s * 100)             # the first window's, then each hop's frames
    off_grid = round(hop_s * fps) * 16000 % (fps * 160) != 0
    assert windows >= 20
    if off_grid:   # each window's own rows; in vain only between the first two (the stride is not known yet)
        assert 96 * windows <= rows <= 96 * windows + round(hop_s * 100)
    else:
        assert rows <= new_rows + 2 * windows                       # kept rows reused; at most a frame's straddle


def corpus_audio():
    """Real speech, a real laugh, the speech again at 44.1 kHz (test split)."""
    from laughlab.corpora.mixed import load

    speech = load(str(corpus_file("hedgewars/British-Amazing")), 44100)
    return np.concatenate([speech, load(str(corpus_file("hedgewars/Classic-Laugh")), 44100), speech])


# --- the gate's rule ------------------------------------------------------------------------------------

class FixedScore:
    """Stands in for the head, the laughter classes and the other human sounds (``os``, the veto): their scores,
    one per model window, in order."""

    def __init__(self, ps, qs=None, os=None, ns=None):
        self.ps = list(ps)
        self.qs = list(qs) if qs is not None else [0.0] * len(self.ps)
        self.os = list(os) if os is not None else [0.0] * len(self.ps)
        self.ns = list(ns) if ns is not None else [0.0] * len(self.ps)

    def both(self, scores):
        return self.ps.pop(0), self.qs.pop(0)

    def other_human(self, scores):
        return self.os.pop(0)

    def noise(self, scores):
        return self.ns.pop(0)


def gate_run(ps, mcs, qs=None, os=None, ns=None, **params):
    from laughlab_plugins.detector_yamnet import YamnetDetector, YamnetParams

    # the rule these hand-computed sequences were written for: the head alone, windows every 0.5 s, no quiet close
    params = {"rule": "head", "hop_s": 0.5, "open_windows": 2, "close_quiet_s": 0.0, "model_frames": 1, **params}
    det = YamnetDetector(YamnetParams(**params), Context(fps=FPS, sample_rate=16000))
    det.score = FixedScore(ps, qs, os, ns)
    rows = []
    for k, m in enumerate(mcs):
        f = Frame(k, k / FPS, 1 / FPS, {"mcs": m}, None, {}, {}, [], 0.0)
        det.step(np.zeros(int(16000 / FPS)), f)
        rows.append((f.control["laughter"], f.control["laugh_gate"], f.control["face_gate"], f.control["mcs"],
                     f.control["clip_gate"]))
    return np.array(rows)


def test_the_face_answers_a_new_sound_at_once_and_clips_wait_for_the_model():
    # a sound from frame 10 on; windows every 30 frames (0.5 s): at frames 29, 59, 89 (0-based)
    mcs = [0.0] * 10 + [0.6] * 110
    r = gate_run([0.1, 0.9, 0.1, 0.1], mcs, attack_s=0.0, release_s=0.0, open_windows=1)
    # frames 10..58: the face follows the sound (provisional: the window at frame 29 has heard
    # 20 frames = 0.33 s >= decide_s, so it decides: p = 0.1 -> closed)
    assert np.all(r[10:29, 2] == 1.0) and np.all(r[10:29, 3] == 0.6)
    assert np.all(r[29:59, 2] == 0.0) and np.all(r[29:59, 3] == 0.0)
    # the clips' gain is the model's only: open from the window that said 0.9 (frame 59) to the next (89)
    assert np.all(r[:59, 1] == 0.0) and np.all(r[59:89, 1] == 1.0) and np.all(r[89:, 1] == 0.0)
    assert np.all(r[59:89, 2] == 1.0) and np.all(r[59:89, 4] == 1.0)
    assert np.all(r[:10, 2] == 0.0)   # silence: nothing provisional


def test_hysteresis_keeps_the_clip_gain_open_between_close_below_and_open_at():
    r = gate_run([0.6, 0.4, 0.35, 0.2], [0.0] * 120, attack_s=0.0, release_s=0.0, open_windows=1)
    assert np.all(r[29:119, 1] == 1.0) and r[119, 1] == 0.0


def test_the_clip_gain_opens_after_open_windows_windows_in_a_row():
    # two windows in a row at or above 0.5; a lone window is not enough
    r = gate_run([0.9, 0.2, 0.6, 0.7, 0.4], [0.0] * 150, attack_s=0.0, release_s=0.0)
    # windows at frames 29 (0.9), 59 (0.2), 89 (0.6), 119 (0.7), 149 (0.4)
    assert np.all(r[:119, 1] == 0.0)                   # 0.9 alone is not enough, nor 0.6 alone
    assert np.all(r[119:, 1] == 1.0)                   # 0.6 then 0.7: open at 119; 0.4 >= close_below keeps it


def test_rule_classes_opens_on_the_laughter_classes_score_with_hysteresis():
    # windows every 15 frames (0.25 s): at frames 14, 29, 44, 59, 74 (0-based); the head says 0.9 throughout,
    # which rule=classes ignores
    qs = [0.02, 0.12, 0.07, 0.04, 0.2]
    r = gate_run([0.9] * 5, [0.6] * 75, qs, rule="classes", hop_s=0.25, class_open=0.1, class_close=0.05,
                 attack_s=0.0, release_s=0.0)
    assert np.all(r[:29, 1] == 0.0)        # 0.02 < 0.1
    assert np.all(r[29:59, 1] == 1.0)      # 0.12 opens; 0.07 >= 0.05 keeps it open
    assert np.all(r[59:74, 1] == 0.0)      # 0.04 < 0.05 closes it at once (hold_s = 0)
    assert r[74, 1] == 1.0                 # 0.2 opens it again
    assert r[29, 0] == 0.9                 # `laughter` still holds the head's probability


def test_rule_either_opens_on_the_head_or_the_classes_and_closes_when_both_fall():
    # windows at frames 14, 29, 44, 59, 74, 89; head 2 windows in a row >= 0.5 (keeps >= 0.3), classes 1 >= 0.1
    ps = [0.6, 0.7, 0.2, 0.1, 0.1, 0.1]
    qs = [0.0, 0.0, 0.06, 0.02, 0.3, 0.0]
    r = gate_run(ps, [0.6] * 90, qs, rule="either", hop_s=0.25, class_open=0.1, class_close=0.05,
                 attack_s=0.0, release_s=0.0)
    assert np.all(r[:29, 1] == 0.0)        # one head window is not enough
    assert np.all(r[29:44, 1] == 1.0)      # the head opens (0.6, 0.7)
    assert np.all(r[44:59, 1] == 1.0)      # head 0.2 < 0.3 but classes 0.06 >= 0.05 keep it
    assert np.all(r[59:74, 1] == 0.0)      # both below: closed
    assert np.all(r[74:89, 1] == 1.0) and r[89, 1] == 0.0   # the classes alone open it (0.3), then 0.0 closes
    # rule=head on the same scores: open only from frame 29 to 43
    h = gate_run(ps, [0.6] * 90, qs, rule="head", hop_s=0.25, attack_s=0.0, release_s=0.0)
    assert np.all(h[29:44, 1] == 1.0) and np.all(h[44:, 1] == 0.0) and np.all(h[:29, 1] == 0.0)


def test_a_window_where_another_human_sound_outscores_laughter_neither_opens_nor_keeps_the_gain():
    # windows at frames 14, 29, 44, 59, 74, 89; the classes' score 0.3 in every window (opens under rule=classes);
    # YAMNet's other human sounds (a cough...) outscore it in the 1st, 2nd and 5th windows
    qs, os_ = [0.3] * 6, [0.5, 0.4, 0.1, 0.2, 0.9, 0.0]
    kw = dict(rule="classes", hop_s=0.25, class_open=0.1, class_close=0.05, attack_s=0.0, release_s=0.0)
    r = gate_run([0.0] * 6, [0.6] * 90, qs, os_, **kw)
    assert np.all(r[:44, 1] == 0.0)                       # vetoed: no opening on a cough that sounds like laughter
    assert np.all(r[44:74, 1] == 1.0)                     # 0.3 > 0.1 and > 0.2: laughter
    assert np.all(r[74:89, 1] == 0.0) and r[89, 1] == 1.0  # the veto closes it at once; the next window reopens
    assert np.all(r[:29, 2] == 1.0)                       # the face follows the new sound provisionally ...
    assert np.all(r[29:44, 2] == 0.0)                     # ... until a vetoed window decides: not laughter
    assert r[14, 0] == 0.0 and r[14, 1] == 0.0            # `laughter` (the published score) is unchanged
    off = gate_run([0.0] * 6, [0.6] * 90, qs, os_, veto="none", **kw)
    assert np.all(off[14:, 1] == 1.0)                     # detector.veto=none: the classes alone decide
    # veto=both: the head under rule=either too: 0.9 x3 with a louder cough in the 3rd window starts over
    cough = [0.0, 0.0, 0.5, 0.0, 0.0, 0.0]
    e = gate_run([0.9] * 6, [0.6] * 90, [0.0] * 6, cough, rule="either", hop_s=0.25, open_windows=3, veto="both",
                 attack_s=0.0, release_s=0.0)
    assert np.all(e[:89, 1] == 0.0) and e[89, 1] == 1.0   # windows 4, 5, 6 in a row: open at frame 89
    c = gate_run([0.9] * 6, [0.6] * 90, [0.0] * 6, cough, rule="either", hop_s=0.25, open_windows=3, veto="classes",
                 attack_s=0.0, release_s=0.0)
    assert np.all(c[:44, 1] == 0.0) and np.all(c[44:, 1] == 1.0)   # veto=classes leaves the head alone


@pytest.mark.parametrize("rule", ["head", "classes", "either"])
@pytest.mark.parametrize("veto", ["none", "classes", "both"])
@pytest.mark.parametrize("noise_veto", [1.0, 0.1])
def test_the_train_split_sweep_gates_like_the_detector(rule, veto, noise_veto):
    """``yamnet_fit --rules`` chose the thresholds with ``gate_windows``: the detector's rule, window by window."""
    from laughlab.detector.yamnet_fit import gate_windows

    rng = np.random.default_rng(5)   # a draw where each veto changes some window (asserted below)
    ps, qs = rng.uniform(0, 1, 40).round(2), (rng.uniform(0, 0.2, 40) ** 2 * 5).round(3)
    os_ = np.where(rng.random(40) < 0.25, 0.5, 0.0)   # a quarter of the windows: a cough louder than laughter
    ns = np.where(rng.random(40) < 0.25, 0.4, 0.05)   # a quarter: steady noise louder than laughter and 0.1
    kw = dict(open_windows=3, class_open=0.1, class_windows=1, class_close=0.05)
    r = gate_run(list(ps), [0.6] * 600, list(qs), list(os_), list(ns), rule=rule, hop_s=0.25, attack_s=0.0,
                 release_s=0.0, veto=veto, noise_veto=noise_veto, **kw)
    want = gate_windows(ps, qs, rule, other=os_, veto=veto, noise=ns, noise_veto=noise_veto, **kw)
    assert np.array_equal(r[14::15, 1] == 1.0, want) and want.any() and not want.all()
    if veto != "none" and not (rule == "head" and veto == "classes") and noise_veto == 1.0:   # the veto changed
        assert not np.array_equal(want, gate_windows(ps, qs, rule, **kw))                      # something here
    if noise_veto < 1.0 and rule != "classes" and veto != "both":   # the noise veto changed something (the head's rules)
        assert not np.array_equal(want, gate_windows(ps, qs, rule, other=os_, veto=veto, **kw))


def test_steady_noise_louder_than_laughter_keeps_the_head_from_opening_the_gate():
    """``detector.noise_veto`` by hand, rule=either, 3 windows of the head at 0.9 open the gate: steady noise at 0.4
    in the 3rd window (above 0.1 and the laughter classes' 0) starts the count over, so windows 4-6 open it; noise
    at 0.05 (under 0.1), or at 0.4 under a laughter-class score of 0.5, or noise_veto=1 leave it alone."""
    kw = dict(rule="either", hop_s=0.25, open_windows=3, attack_s=0.0, release_s=0.0, class_open=0.6,
              class_close=0.55)
    noisy = [0.0, 0.0, 0.4, 0.0, 0.0, 0.0]
    e = gate_run([0.9] * 6, [0.6] * 90, [0.0] * 6, None, noisy, **kw)
    assert np.all(e[:89, 1] == 0.0) and e[89, 1] == 1.0          # windows 4, 5, 6 in a row: open at frame 89
    for ps, qs, ns, extra in (([0.9] * 6, [0.0] * 6, [0.0, 0.0, 0.05, 0.0, 0.0, 0.0], {}),
                              ([0.9] * 6, [0.5] * 6, noisy, {}),
                              ([0.9] * 6, [0.0] * 6, noisy, {"noise_veto": 1.0})):
        g = gate_run(ps, [0.6] * 90, qs, None, ns, **kw, **extra)
        assert np.all(g[:44, 1] == 0.0) and np.all(g[44:, 1] == 1.0)   # the 3rd window (frame 44) opens it
    assert np.array_equal(e[:, 0], gate_run([0.9] * 6, [0.6] * 90, [0.0] * 6, **kw)[:, 0])   # published unchanged


def test_the_train_sweep_counts_bouts_false_openings_and_first_openings_by_hand():
    """``yamnet_fit --rules``' figures on a hand-made scene: two bouts (1-2 s, 5-6 s), windows every 0.5 s."""
    from laughlab.detector.yamnet_fit import _first_open, _found_false

    t = np.arange(1, 21) * 0.5                                  # window ends 0.5 ... 10 s
    opened = np.zeros(20, bool)
    opened[[2, 3]] = True                                       # 1.5-2.0 s: inside bout 1, 0.5 s after its start
    opened[[6, 7]] = True                                       # 3.5-4.0 s: outside both (bout 1's tail ends at 3 s)
    opened[[12]] = True                                         # 6.5 s: bout 2's 1 s tail, 1.5 s after its start
    sc = {"t": t, "dur": 10.0, "bouts": [(1.0, 2.0), (5.0, 6.0)]}
    found, false = _found_false([sc], lambda s: opened)
    # non-laughter: 10 s - (2 s + 2 s of bouts and tails) = 6 s = 0.1 min; one opening outside -> 100 per 10 min
    assert found == 1.0 and false == pytest.approx(100.0)
    assert _first_open([sc], lambda s: opened) == pytest.approx(1.0)   # median of 0.5 s and 1.5 s
    assert np.isnan(_first_open([sc], lambda s: np.zeros(20, bool)))


def test_the_train_sweep_refuses_a_hop_out_of_range(capsys):
    from laughlab.detector.yamnet_fit import main

    with pytest.raises(SystemExit) as e:
        main(["--rules", "--hop", "0"])
    assert e.value.code == 2 and "--hop must be from 0.01 to 1 s (got 0)" in capsys.readouterr().err


def test_the_clip_gain_closes_after_close_quiet_s_of_quiet_and_cannot_open_in_quiet():
    # sound (mcs 0.6) for frames 0..39, then quiet; the classes say laughter in every window (0.5)
    mcs = [0.6] * 40 + [0.0] * 50
    r = gate_run([0.0] * 6, mcs, [0.5] * 6, rule="classes", hop_s=0.25, class_open=0.1, class_close=0.05,
                 close_quiet_s=0.3, attack_s=0.0, release_s=0.0)
    # open from the first window (frame 14); quiet from frame 40: 18 frames (0.3 s) below onset_mcs at frame 57
    assert np.all(r[:14, 1] == 0.0) and np.all(r[14:57, 1] == 1.0)
    assert np.all(r[57:, 1] == 0.0)        # closed, and the windows at 59, 74, 89 (0.5) do not reopen it
    # without the quiet close the window's score keeps it open
    k = gate_run([0.0] * 6, mcs, [0.5] * 6, rule="classes", hop_s=0.25, close_quiet_s=0.0, attack_s=0.0,
                 release_s=0.0)
    assert np.all(k[14:, 1] == 1.0)


def test_bad_rule_parameters_are_refused():
    from laughlab_plugins.detector_yamnet import YamnetParams

    with pytest.raises(ValueError, match="rule must be one of head, classes, either"):
        YamnetParams(rule="both")
    with pytest.raises(ValueError, match="class_close <= class_open"):
        YamnetParams(class_open=0.1, class_close=0.2)
    with pytest.raises(ValueError, match="class_windows"):
        YamnetParams(class_windows=0)
    with pytest.raises(ValueError, match="model_frames must be a whole number from 1 to 4"):
        YamnetParams(model_frames=5)
    with pytest.raises(ValueError, match="prefetch must be true or false"):
        YamnetParams(prefetch="yes")
    with pytest.raises(ValueError, match="veto must be one of none, classes, both"):
        YamnetParams(veto=True)


def test_the_default_rule_is_either_every_quarter_second_with_the_quiet_close():
    from laughlab_plugins.detector_yamnet import YamnetParams

    p = YamnetParams()
    assert (p.rule, p.hop_s, p.open_windows, p.class_open, p.class_windows, p.class_close, p.close_quiet_s) == \
        ("either", 0.25, 3, 0.1, 1, 0.05, 0.3)


def test_the_scheduler_reads_the_ungated_mcs_times_the_clip_gain():
    from laughlab.detector.model import clip_drive

    assert clip_drive({"mcs": 0.3, "mcs_ungated": 0.6, "clip_gate": 0.5}) == 0.3
    assert clip_drive({"mcs": 0.0, "mcs_ungated": 0.6, "clip_gate": 0.0}) == 0.0
    assert clip_drive({"mcs": 0.7}) == 0.7   # detector=none, laugh: unchanged


# --- offline segments -------------------------------------------------------------------------------------

def test_segments_by_hand():
    t = np.arange(10) * 0.5 + 0.25
    p = np.array([0, 0.6, 0.7, 0, 0, 0.9, 0, 0, 0.8, 0.8])
    got = S.segments(t, p, 0.5, threshold=0.5, min_length_s=0.6, duration_s=4.8)
    assert got == [S.Segment(0.5, 1.5, 0.65), S.Segment(4.0, 4.8, 0.8)]   # the lone 0.5 s run is dropped


def test_score_by_hand():
    truth = [{"kind": "bout", "onset_s": 1.0, "offset_s": 2.0}, {"kind": "speech", "onset_s": 3.0, "offset_s": 5.0},
             {"kind": "bout", "onset_s": 6.0, "offset_s": 7.0}]
    got = S.score([S.Segment(1.5, 2.5), S.Segment(3.5, 4.0)], truth, 8.0)
    assert (got["tp"], got["fp"], got["fn"]) == (50, 100, 150)
    assert got["found"] == 1 and got["bouts"] == 2 and got["false_segments"] == {"speech": 1}
    assert S.f1(50, 100, 150) == pytest.approx(100 / 350)


def test_smooth_is_a_centred_average():
    assert np.allclose(S.smooth(np.array([0, 3, 0, 0.0]), 3), [1.5, 1, 1, 0])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=12), st.integers(1, 9))
def test_smoothing_keeps_the_length_and_averages_the_neighbours_that_exist(p, n):
    """Fewer windows than the smoothing (a file under a few seconds) used to get ``n`` values back, shifted."""
    got = S.smooth(np.array(p), n)
    h = (n - 1) // 2
    want = [np.mean(p[max(0, i + h - n + 1):i + h + 1]) for i in range(len(p))]   # n values, centred (odd n)
    assert len(got) == len(p) and np.allclose(got, want)


def test_detect_writes_three_formats_that_read_back(tmp_path):
    laugh = corpus_file("hedgewars/Classic-Laugh")
    x, sr = sf.read(laugh)
    (tmp_path / "in").mkdir()
    sf.write(tmp_path / "in" / "a.wav", x, sr)
    sf.write(tmp_path / "in" / "short8k.wav", np.zeros(2000), 8000)     # 0.25 s at 8 kHz: padded, still answers
    out = tmp_path / "out"
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(out))
    assert r.returncode == 0, r.stderr
    # one line: files, audio, segments, the time waited and the speed, written as a run's summary writes them
    # (two significant digits below 10x: a short input is not "0x real time")
    # (a file with no segment is counted: it has no row in segments.csv)
    m = re.fullmatch(r"laughlab: 2 file\(s\), 1 without laughter, (\d+\.\d) s of audio, (\d+) laughter segment\(s\) "
                     r"in (.+) \((\S+)x real time\) -> (.+)/", r.stdout.strip())
    assert m and m[5] == str(out) and m[4] == factor_text(float(m[4])) and re.fullmatch(r"\d+(\.\d+)? s|\d+ min \d\d s", m[3])
    assert float(m[1]) == round(len(x) / sr + 0.25, 1)
    assert {p.name for p in out.iterdir() if p.name[0] != "."} == {"segments.csv", "recordings.csv", "a.txt",
                                                                   "a.TextGrid", "short8k.txt", "short8k.TextGrid"}
    segs = S.read_folder(out)
    assert segs["a"] and segs.get("short8k", []) == []
    assert segs["a"][0].start < 2.0 and all(s.end <= len(x) / sr for s in segs["a"])
    from praatio import textgrid

    tg = textgrid.openTextgrid(str(out / "a.TextGrid"), includeEmptyIntervals=False)
    laughs = [(e.start, e.end) for e in tg.getTier("laughter").entries if e.label == "laugh"]
    assert laughs == [(s.start, s.end) for s in segs["a"]]
    # the CSV says the same
    csv_only = tmp_path / "csv"
    csv_only.mkdir()
    (csv_only / "segments.csv").write_text((out / "segments.csv").read_text())
    assert S.read_folder(csv_only)["a"] == [S.Segment(s.start, s.end) for s in segs["a"]]


def test_elan_file_holds_the_segments_in_milliseconds(tmp_path):
    """ELAN's EAF: the time slots of each ``laugh`` annotation are the segment's ends in whole ms."""
    import xml.etree.ElementTree as ET

    segs = [S.Segment(0.25, 1.2004), S.Segment(2.0, 2.5)]
    root = ET.fromstring(S.eaf_text(segs))
    assert root.tag == "ANNOTATION_DOCUMENT" and root.find("HEADER").get("TIME_UNITS") == "milliseconds"
    slots = {t.get("TIME_SLOT_ID"): int(t.get("TIME_VALUE")) for t in root.iter("TIME_SLOT")}
    got = [(slots[a.get("TIME_SLOT_REF1")], slots[a.get("TIME_SLOT_REF2")], a.findtext("ANNOTATION_VALUE"))
           for a in root.find("TIER").iter("ALIGNABLE_ANNOTATION")]
    assert got == [(250, 1200, "laugh"), (2000, 2500, "laugh")]
    assert root.find("TIER").get("LINGUISTIC_TYPE_REF") == root.find("LINGUISTIC_TYPE").get("LINGUISTIC_TYPE_ID")
    empty = ET.fromstring(S.eaf_text([]))
    assert empty.find("TIER") is not None and not list(empty.iter("ANNOTATION"))
    out = tmp_path / "o"
    S.write_outputs(out, [("rec", 3.0, segs)], ("elan",))
    assert [p.name for p in out.iterdir()] == ["rec.eaf"] and (out / "rec.eaf").read_text() == S.eaf_text(segs)
    # with the recording (a second review: ELAN opened the files with no audio): linked by its absolute file URL
    # and by its path from the EAF's folder, both of which lead to it the way ELAN follows them (its checkMedia
    # opens what follows "file:" as it stands, and joins the relative path to the EAF's folder: no
    # percent-decoding, so a space or an accent in a name is written as itself; a review found "day%201")
    from pathlib import Path

    rec = tmp_path / "takes" / "day 1" / "rec é.wav"
    rec.parent.mkdir(parents=True)
    rec.write_bytes(b"")
    S.write_outputs(out, [("rec", 3.0, segs, rec)], ("elan",))
    media = ET.fromstring((out / "rec.eaf").read_text()).find("HEADER").find("MEDIA_DESCRIPTOR")
    assert media.get("MIME_TYPE") == "audio/x-wav"
    assert media.get("MEDIA_URL") == "file://" + rec.resolve().as_posix()
    assert Path(media.get("MEDIA_URL").split(":", 1)[1]).is_file()
    assert (out / media.get("RELATIVE_MEDIA_URL")).resolve() == rec.resolve()
    assert S.elan_url(Path("//server/share/a.wav")) == "file://server/share/a.wav"   # ELAN's form of a share
    # on Windows a recording on another drive than --out has no relative path (ntpath.relpath raises ValueError):
    # the absolute link alone, as ELAN writes it then, not a traceback (the detect review)
    import ntpath
    import os

    def other_drive(path, start):
        return ntpath.relpath("D:\\rec\\a.wav", "C:\\out")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os.path, "relpath", other_drive)
        media = ET.fromstring(S.eaf_text(segs, rec, out)).find("HEADER").find("MEDIA_DESCRIPTOR")
    assert media.get("RELATIVE_MEDIA_URL") is None and media.get("MEDIA_URL") == S.elan_url(rec.resolve())
    for ext in ("mp3", "flac"):   # ELAN's generic audio type (an mp3's "audio/mpeg" was none of ELAN's: a video to it)
        rec2 = rec.with_suffix("." + ext)
        rec2.write_bytes(b"")
        S.write_outputs(out, [("rec", 3.0, segs, rec2)], ("elan",))
        media = ET.fromstring((out / "rec.eaf").read_text()).find("HEADER").find("MEDIA_DESCRIPTOR")
        assert media.get("MIME_TYPE") == "audio/*"


def test_detect_replaces_nothing_without_asking_and_leaves_no_stale_segments(tmp_path):
    """An --out holding files is refused before any work (the user's edited labels kept); ``--overwrite``
    writes this run's segment files and removes those an earlier detect wrote that this run does not write,
    other files kept (a ``.txt`` of the user's among them)."""
    (tmp_path / "in").mkdir()
    for name in ("a", "b"):
        sf.write(tmp_path / "in" / f"{name}.wav", np.zeros(1600), 16000)
    out = tmp_path / "out"
    assert laughlab("detect", str(tmp_path / "in"), "--out", str(out)).returncode == 0
    (out / "notes.md").write_text("mine\n")   # (a label file of detect's edited in place: test_detect_batch)
    (out / "notes.txt").write_text("mine too\n")                # named like a label file, but not detect's
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    r = laughlab("detect", str(tmp_path / "in" / "a.wav"), "--out", str(out))
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [r.stderr.strip()]
    assert "already holds files" in r.stderr and "--overwrite" in r.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    r = laughlab("detect", str(tmp_path / "in" / "a.wav"), "--out", str(out), "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a.TextGrid", "a.txt", "notes.md",
                                                                          "notes.txt", "recordings.csv",
                                                                          "segments.csv"]
    assert (out / "a.txt").read_text() == "" and (out / "notes.md").read_text() == "mine\n"
    assert (out / "notes.txt").read_text() == "mine too\n"
    assert (out / "segments.csv").read_text() == "file,start,end,probability\n"
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(out / "notes.md"))
    assert r.returncode == 2 and "is a file, not a folder" in r.stderr


def test_detect_overwrite_refuses_files_no_detect_wrote(tmp_path):
    """``--overwrite`` replaces only files an earlier detect wrote: a hand-made ``NAME.TextGrid`` beside
    ``NAME.wav`` (the harness' annotation layout) or a ``segments.csv`` of the user's is refused, before any
    work, and kept byte for byte."""
    sf.write(tmp_path / "rec.wav", np.zeros(1600), 16000)
    mine = {"rec.TextGrid": 'File type = "ooTextFile"\nmine\n', "segments.csv": "file,start,end\nmine,0,1\n"}
    for name, text in mine.items():
        (tmp_path / name).write_text(text)
    for name in mine:
        r = laughlab("detect", str(tmp_path / "rec.wav"), "--out", str(tmp_path), "--overwrite",
                     "--formats", "textgrid" if name.endswith("TextGrid") else "csv")
        assert r.returncode == 2 and r.stderr.strip().splitlines() == [r.stderr.strip()]
        assert name in r.stderr and "no earlier detect wrote" in r.stderr
    assert {n: (tmp_path / n).read_text() for n in mine} == mine
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.TextGrid", "rec.wav", "segments.csv"]
    r = laughlab("detect", str(tmp_path / "rec.wav"), "--out", str(tmp_path), "--overwrite", "--formats", "audacity")
    assert r.returncode == 0, r.stderr   # a name of detect's that is not there: written, the user's files kept
    assert {n: (tmp_path / n).read_text() for n in mine} == mine and (tmp_path / "rec.txt").read_text() == ""


@pytest.mark.parametrize("args,message", [
    (["nothing.wav"], "input not found: nothing.wav"),
    (["--threshold", "2", "x"], "--threshold must be in [0, 1]"),
    (["--formats", "eaf", "x"], "unknown format eaf"),
    (["--smooth", "4", "x"], "--smooth must be a positive odd number of windows (a centred average: 1, 3, 5, ...; "
                             "got 4)"),
    (["--smooth=-1", "x"], "--smooth must be a positive odd number of windows (a centred average: 1, 3, 5, ...; "
                           "got -1)"),
])
def test_detect_bad_input_is_one_line(tmp_path, args, message):
    if "x" in args:
        sf.write(tmp_path / "x.wav", np.zeros(1600), 16000)
    r = laughlab("detect", *args, "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [r.stderr.strip()] and message in r.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_the_head_is_refitted_byte_for_byte():
    """``python -m laughlab.detector.yamnet_fit --check`` refits on the train split and compares the bytes (~2-5 min)."""
    from laughlab.detector.yamnet_fit import main

    # byte for byte on the CPU family the bundled heads were fitted on; elsewhere within yamnet_fit.CPU_TOLERANCE
    # (exit 3): the refit is fitted on YAMNet's scores, which XNNPACK rounds by CPU family
    from golden import HEADS_FITTED_ON, cpu_family

    # (another family may round alike: this AMD EPYC with AVX-VNNI besides refits the bytes of the one without)
    assert main(["--check"]) in ((0,) if cpu_family() == HEADS_FITTED_ON else (0, 3))


def test_detect_progress_in_a_log_is_plain_lines(tmp_path):
    """Not a terminal (a log, CI): a line, not tqdm's carriage-return bar (it left 'detect:   0%|' in the log)."""
    laugh = corpus_file("hedgewars/Classic-Laugh")
    r = laughlab("detect", str(laugh), "--out", str(tmp_path / "out"), "--progress", "on")
    assert r.returncode == 0, r.stderr
    assert "\r" not in r.stderr and "%|" not in r.stderr
    m = re.match(r"detect: (\d+\.\d)/(\d+\.\d) s of audio, \d+ s$", r.stderr.strip())
    assert m and m[1] == m[2]                                    # it ends at the total (it said 108/107.8 s)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=60), st.floats(0.05, 1.0), st.floats(0.0, 0.5),
       st.floats(0.0, 1.0))
def test_detect_textgrids_read_back_in_praatio_and_laughlab(tmp_path_factory, p, hop, min_length, tail):
    """Whatever the segments and the duration (here up to a hop past the last window, as a file's end falls),
    the TextGrid is one Praat reads: praatio and laughlab's own check take it, its laugh intervals are the
    segments; a segment that ends with the recording leaves no zero-length interval after it (a 10.88743 s file
    whose last segment ended at 10.8874 was refused by both before)."""
    from praatio import textgrid

    from laughlab.io.textgrid import _scan_textgrid

    p = np.array(p)
    times = (np.arange(len(p)) + 0.5) * hop
    duration = float(times[-1] + tail * hop) + 1.2345e-5
    segs = S.segments(times, p, hop, 0.5, min_length, duration)
    path = tmp_path_factory.mktemp("tg") / "x.TextGrid"
    path.write_text(S.textgrid_text(segs, duration))
    tg = textgrid.openTextgrid(str(path), includeEmptyIntervals=True)
    laughs = [(e.start, e.end) for e in tg.getTier("laughter").entries if e.label == "laugh"]
    assert laughs == [(s.start, s.end) for s in segs]
    _scan_textgrid(path.read_text(), str(path))   # laughlab's own check, as Praat reads a TextGrid
    assert tg.maxTimestamp <= duration and all(s.end <= duration for s in segs)   # nothing past the last sample


@pytest.mark.parametrize("duration", [1 / 44100, 0.0, 4e-5])
def test_a_recording_shorter_than_the_textgrids_resolution_still_gives_one_praat_reads(tmp_path, duration):
    """A review: a 1-sample file's TextGrid ran from 0 to 0, which praatio refuses."""
    from praatio import textgrid

    from laughlab.io.textgrid import _scan_textgrid

    path = tmp_path / "x.TextGrid"
    path.write_text(S.textgrid_text([], duration))
    tier = textgrid.openTextgrid(str(path), includeEmptyIntervals=True).getTier("laughter")
    assert [(e.start, e.end, e.label) for e in tier.entries] == [(0.0, 0.0001, "")]
    _scan_textgrid(path.read_text(), str(path))


def test_a_detect_stopped_while_writing_leaves_nothing_a_later_overwrite_refuses(tmp_path, monkeypatch):
    """A Ctrl-C while detect wrote its files left the written ones out of its manifest, and the next
    --overwrite refused them as the user's: the manifest now lists them before they are written.  (A new --out
    goes whole on a stop since 2026-11-29, so an earlier detect's --out here: c's.)"""
    for name in ("a", "b", "c"):
        sf.write(tmp_path / f"{name}.wav", np.zeros(1600), 16000)
    out = tmp_path / "out"
    assert laughlab("detect", str(tmp_path / "c.wav"), "--out", str(out)).returncode == 0
    real = S.write_outputs

    def stopped(out_dir, results, formats, extra=None, settings=None, skipped=None, order=None):
        # the first input's own files written, then a stop; the shared tables (segments.csv, recordings.csv) are only ever written with every input's
        # files (all or none since 2026-11-28), so a stop never leaves them rewritten with the earlier hashes
        real(out_dir, results[:1], tuple(f for f in formats if f != "csv"), extra, settings)
        raise KeyboardInterrupt

    monkeypatch.setattr(S, "write_outputs", stopped)
    r = laughlab("detect", str(tmp_path / "a.wav"), str(tmp_path / "b.wav"), "--out", str(out), "--overwrite")
    assert r.returncode != 0 and (out / "a.txt").exists() and not (out / "b.txt").exists()
    monkeypatch.setattr(S, "write_outputs", real)
    r = laughlab("detect", str(tmp_path / "a.wav"), str(tmp_path / "b.wav"), "--out", str(out), "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a.TextGrid", "a.txt", "b.TextGrid",
                                                                          "b.txt", "recordings.csv", "segments.csv"]


def test_detect_keeps_a_trees_layout_and_its_repeated_take_names(tmp_path):
    """A second review: detect flattened a tree of recordings into one folder and refused two folders' take1.wav.
    A file found in a given folder now names its outputs by its path from that folder (``day1/take1``): the tree's
    layout in --out and in segments.csv's file column; --overwrite replaces them and removes a stale nested one."""
    import csv
    import xml.etree.ElementTree as ET

    rec = tmp_path / "rec"
    for day in ("day1", "day2"):
        (rec / day).mkdir(parents=True)
        sf.write(rec / day / "take1.wav", np.zeros(1600), 16000)
    sf.write(rec / "solo.wav", np.zeros(1600), 16000)
    out = tmp_path / "out"
    r = laughlab("detect", str(rec), "--out", str(out), "--formats", "csv,textgrid,elan")
    assert r.returncode == 0, r.stderr
    got = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file() and p.name[0] != ".")
    assert got == ["day1/take1.TextGrid", "day1/take1.eaf", "day2/take1.TextGrid", "day2/take1.eaf", "recordings.csv",
                   "segments.csv", "solo.TextGrid", "solo.eaf"]
    eaf = out / "day2" / "take1.eaf"   # its link to the recording works from its own folder
    media = ET.fromstring(eaf.read_text()).find("HEADER").find("MEDIA_DESCRIPTOR")
    assert (eaf.parent / media.get("RELATIVE_MEDIA_URL")).resolve() == (rec / "day2" / "take1.wav").resolve()
    assert list(csv.DictReader((out / "segments.csv").open())) == []   # silence: no segment
    (rec / "day1" / "take1.wav").unlink()
    r = laughlab("detect", str(rec), "--out", str(out), "--formats", "csv,textgrid,elan", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert not (out / "day1").exists() and (out / "day2" / "take1.TextGrid").exists()


def test_quieting_stderr_from_two_threads_at_once_restores_it():
    """A review: the offline helper's two network threads each saved and restored fd 2 while building their
    interpreters; when one saved it while the other had it on /dev/null, /dev/null stayed for the rest of the
    process and a run's error line was lost.  The interleaving forced here: A enters, B enters, A leaves, B leaves."""
    import os
    import threading

    from laughlab.core.quiet import quiet_stderr as _quiet_stderr

    def ident():
        st_ = os.fstat(2)
        return st_.st_dev, st_.st_ino

    null = os.stat(os.devnull)
    before = ident()
    if before == (null.st_dev, null.st_ino):   # the test means something only if fd 2 is not /dev/null already
        pytest.skip("fd 2 is /dev/null")
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = {"waits": []}

    def a():
        with _quiet_stderr():
            a_in.set()
            seen["waits"].append(b_in.wait(10))
        a_out.set()

    def b():
        seen["waits"].append(a_in.wait(10))
        with _quiet_stderr():
            seen["inside"] = ident()
            b_in.set()
            seen["waits"].append(a_out.wait(10))
            seen["after_a"] = ident()

    ts = [threading.Thread(target=a), threading.Thread(target=b)]
    for t in ts:
        t.start()
    for t in ts:
        t.join(20)
    assert not any(t.is_alive() for t in ts) and seen["waits"] == [True] * 3   # the order was the one forced
    assert seen["inside"] == seen["after_a"] == (null.st_dev, null.st_ino)   # quiet while either is inside
    assert ident() == before                                                  # and restored once both left


def test_an_error_line_said_while_stderr_is_quiet_reaches_the_real_stderr(tmp_path):
    """A review: an error line printed while another thread built an interpreter (fd 2 on /dev/null) was lost;
    quiet.say writes it to the real stderr.  In a child process, whose fd 2 is a file."""
    err = tmp_path / "err.txt"
    code = ("import sys; sys.stderr = sys.__stderr__\n"
            "from laughlab.core import quiet\n"
            "with quiet.quiet_stderr():\n"
            "    print('C++ log', file=sys.stderr, flush=True)\n"
            "    quiet.say('laughlab: error: said inside')\n"
            "quiet.say('laughlab: error: said after')\n")
    with open(err, "w") as fh:
        r = subprocess.run([sys.executable, "-c", code], stderr=fh)
    assert r.returncode == 0
    assert err.read_text() == "laughlab: error: said inside\nlaughlab: error: said after\n"


def test_steady_white_noise_starts_no_clip(tmp_path):
    """A new-user review: 30 s of white noise started 12 clips with the default detector, as many as without one
    (the head took it for laughter).  End to end at 44.1 kHz, 10 s of seeded white noise at 0.27 RMS (as sox's
    ``synth whitenoise``): no clip with the default noise_veto, clips with it off."""
    x = (0.27 * np.random.default_rng(7).standard_normal(10 * 44100)).clip(-1, 1).astype(np.float32)
    sf.write(tmp_path / "white.wav", x, 44100, subtype="PCM_16")
    starts = {}
    for veto in ("0.1", "1"):
        out = tmp_path / f"run{veto}"
        r = laughlab("input=file", f"input.path={tmp_path / 'white.wav'}", f"hydra.run.dir={out}", "~output.plots",
                     f"detector.noise_veto={veto}", "progress=off")
        assert r.returncode == 0, r.stderr
        starts[veto] = (out / "events.csv").read_text().count(",start,")
    assert starts["0.1"] == 0 and starts["1"] > 0, starts
