"""``input=file``'s ``channel`` and ``highpass_hz``, and what the run's line says of a DC offset and of channels
that cancel when mixed (a first-contact review: a DC offset of 0.05 full scale left a real laugh between speech
without a clip, and a stereo file whose channels cancel was called silent)."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import soundfile as sf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)
from laughlab.core.errors import LaughlabError

ARGS = ("input=file", "detector=none", "~output.plots")


@pytest.fixture(scope="module")
def laugh(tmp_path_factory):
    """6 s of the synthetic laughter (seed 0) at 44.1 kHz, as a file, and its samples."""
    root = tmp_path_factory.mktemp("file_input")
    r = laughlab("input.duration_s=6", "input.sample_rate=44100", "detector=none", "~output.plots",
                 f"hydra.run.dir={root / 'synth'}")
    assert r.returncode == 0, r.stderr
    x, sr = sf.read(root / "synth" / "input.wav", dtype="float64")
    return root, x, sr


def _run(root, name, path, *args):
    r = laughlab(*ARGS, f"input.path={path}", *args, f"hydra.run.dir={root / name}")
    assert r.returncode == 0, r.stderr
    mcs = np.genfromtxt(root / name / "channels.csv", delimiter=",", names=True)["mcs"]
    return r.stdout, mcs, json.loads((root / name / "metrics.json").read_text())


def test_a_dc_offset_is_said_and_highpass_hz_removes_it(laugh):
    root, x, sr = laugh
    sf.write(root / "clean.wav", x, sr, subtype="FLOAT")
    sf.write(root / "dc.wav", x + 0.05, sr, subtype="FLOAT")
    _, clean, m = _run(root, "clean", root / "clean.wav")
    assert abs(m["input_dc"]) < 1e-3
    out, shifted, m = _run(root, "dc", root / "dc.wav")
    assert m["input_dc"] == pytest.approx(np.mean(x) + 0.05, abs=1e-6)
    assert "(a DC offset of +0.050 full scale, which the level the motion follows includes: input.highpass_hz=20 " \
           "removes it)" in out
    out, fixed, _ = _run(root, "hp", root / "dc.wav", "input.highpass_hz=20")
    assert "DC offset" not in out
    # the offset compresses the motion control signal (measured: r 0.69 with the clean file's, its mean 0.17 for
    # 0.30); the high-pass gives back the clean file's, within 1e-3 (the filter starts at the first sample's level:
    # from rest, the offset's step was the loudest frame and shrank the MCS, a review found), and its clips
    _, clean_hp, _ = _run(root, "hpclean", root / "clean.wav", "input.highpass_hz=20")
    assert np.abs(fixed - clean_hp).max() < 1e-3 and np.abs(fixed - clean).max() < 0.01
    assert (root / "hp" / "events.csv").read_text() == (root / "hpclean" / "events.csv").read_text()
    assert np.corrcoef(shifted, clean)[0, 1] < 0.9 and shifted.mean() < 0.7 * clean.mean()


def test_the_high_pass_is_the_same_however_the_file_is_cut(laugh):
    """Run block by block with its state, the filter gives the samples of one pass over the whole file."""
    from omegaconf import OmegaConf
    from scipy.signal import butter, sosfilt, sosfilt_zi

    from laughlab.core.config import compose_config
    from laughlab.core.pipeline import build

    root, x, sr = laugh
    y = x + 0.05 * np.sin(2 * np.pi * 3 * np.arange(len(x)) / sr)   # rumble at 3 Hz
    sf.write(root / "rumble.wav", y, sr, subtype="FLOAT")
    cfg = compose_config(["input=file", f"input.path={root / 'rumble.wav'}", "input.highpass_hz=20"])
    src = build(OmegaConf.create(OmegaConf.to_container(cfg))).source
    got = np.concatenate(list(src._read()))
    sos = butter(2, 20, "highpass", fs=sr, output="sos")   # from the first sample's level: no step at the start
    want = sosfilt(sos, y.astype(np.float32), zi=sosfilt_zi(sos) * np.float32(y[0]))[0]
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert len(list(src.blocks())) == src.n_frames


def test_channels_that_cancel_are_said_and_channel_reads_one_alone(laugh):
    root, x, sr = laugh
    sf.write(root / "mono.wav", x, sr, subtype="PCM_16")
    sf.write(root / "phase.wav", np.stack([x, -x], axis=1), sr, subtype="PCM_16")
    out, _, m = _run(root, "phase", root / "phase.wav")
    assert len(m["input_channel_peaks"]) == 2 and min(m["input_channel_peaks"]) > 0.1
    assert "(silent when its 2 channels are mixed: they cancel out, each alone up to " in out
    assert "input.channel=0 reads the first alone)" in out and "(silent: its loudest" not in out
    _run(root, "left", root / "phase.wav", "input.channel=0")
    _run(root, "mono", root / "mono.wav")
    for name in ("channels.csv", "motion.bvh", "events.csv"):
        assert (root / "left" / name).read_bytes() == (root / "mono" / name).read_bytes(), name


@pytest.mark.parametrize("args, line", [
    (["input.channel=2"], "input.channel=2: {path} has 2 channel(s), numbered from 0"),
    (["input.highpass_hz=30000"], "bad parameter in input=file: highpass_hz must be <= 1000 (got 30000.0)"),
    (["input.highpass_hz=-1"], "bad parameter in input=file: highpass_hz must be >= 0"),
])
def test_a_channel_or_cutoff_the_file_cannot_take_is_one_line(laugh, args, line):
    root, x, sr = laugh
    path = root / "st.wav"
    sf.write(path, np.stack([x, x], axis=1), sr, subtype="PCM_16")
    r = laughlab(*ARGS, f"input.path={path}", *args, f"hydra.run.dir={root / 'bad'}")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert line.format(path=path) in r.stderr, r.stderr
    assert not (root / "bad").exists()


def test_a_file_it_may_not_read_says_permission_denied(tmp_path, monkeypatch):
    """libsndfile said "System error." for a file without read permission (a first-contact review). The tests run
    as root, who reads any file, so the refusal is the operating system's error as open() raises it."""
    from laughlab.core.errors import LaughlabError
    from laughlab.io import audio

    path = tmp_path / "noperm.wav"
    sf.write(path, np.zeros(800), 8000)

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(audio, "open", refused, raising=False)
    with pytest.raises(LaughlabError, match=rf"^cannot read audio from {path}: Permission denied$"):
        audio.probe_file(path)


@pytest.mark.parametrize("limit", [None, 100])
def test_a_long_sessions_float_wav_becomes_rf64_past_riffs_4_gib(tmp_path, monkeypatch, limit):
    """A soak review: a microphone session saved with its audio (``input.save_audio``) reached RIFF's 4 GiB after
    6.8 h at 44.1 kHz, and the header's struct.pack error removed the whole session.  The spool reserves a JUNK
    chunk that becomes RF64's ds64 past the limit (EBU Tech 3306); both forms read back as written (the limit set
    to 100 bytes here, to write an RF64 file of a few kilobytes)."""
    import struct

    import soundfile as sf

    from laughlab.io.audio import FloatWavWriter

    if limit is not None:
        monkeypatch.setattr(FloatWavWriter, "RIFF_LIMIT", limit)
    x = np.sin(np.arange(3 * 44100) / 7.0).astype(np.float32) * 0.5
    with FloatWavWriter(tmp_path / "s.wav", 44100, long=True) as w:
        w.write(x[:1000])
        w.write(x[1000:])
    head = (tmp_path / "s.wav").read_bytes()[:16]
    assert head[:4] == (b"RIFF" if limit is None else b"RF64") and head[12:16] == (b"JUNK" if limit is None else b"ds64")
    if limit is not None:
        riff, data, n = struct.unpack("<QQQ", (tmp_path / "s.wav").read_bytes()[20:44])
        assert data == 4 * len(x) and n == len(x) and riff == (tmp_path / "s.wav").stat().st_size - 8
    y, sr = sf.read(tmp_path / "s.wav", dtype="float32")
    assert sr == 44100 and np.array_equal(y, x)
    # a copy cut short is said, RF64 as RIFF (the RF64 one ran on what was left without a word: a diff review)
    from laughlab.io.audio import probe_file

    (tmp_path / "cut.wav").write_bytes((tmp_path / "s.wav").read_bytes()[:-4 * 66150])
    with pytest.raises(LaughlabError, match=r"cut\.wav is cut short: its header promises 3\.00 s of audio, the file "
                                            r"holds 1\.50 s"):
        probe_file(tmp_path / "cut.wav")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="sparse files: elsewhere 4 GiB would be written")
def test_the_float_wav_at_its_real_limit(tmp_path):
    """At the real RIFF limit (a sparse file, no 4 GiB written): the last size RIFF holds stays RIFF, one sample more
    is RF64, libsndfile counts both exactly; a writer without the JUNK room says so in one line (it was struct.error)."""
    import soundfile as sf

    from laughlab.io.audio import FloatWavWriter

    last = FloatWavWriter.RIFF_LIMIT // 4
    for n, magic in ((last, b"RIFF"), (last + 1, b"RF64")):
        path = tmp_path / f"{n}.wav"
        w = FloatWavWriter(path, 48000, long=True)
        w.f.seek(4 * n - 4, 1)   # the audio's place, left sparse, and its last sample
        w.write(np.array([0.25], np.float32))
        w.n = n
        w.close()
        assert path.read_bytes()[:4] == magic and sf.info(str(path)).frames == n
    w = FloatWavWriter(tmp_path / "short.wav", 48000)
    w.n = last + 1
    with pytest.raises(LaughlabError, match=r"short\.wav: 6\.2 h of audio at 48000 Hz is past what a WAV file holds"):
        w.close()
    assert w.f.closed


def test_the_dc_offset_is_one_reads_whoever_else_reads_the_file(tmp_path):
    """A reproducibility review: the detector's look-ahead and the main loop read the file at once, both adding to
    one sum from two threads: updates were lost and their order varied, so metrics.json's input_dc differed in 1 of
    25 runs of one file (in 1-4 of an experiment's 64 trials). The source keeps each reader's own sums and reports
    the furthest reader's: with readers in threads, the same numbers as one read alone, to the bit."""
    import threading

    from laughlab.core.bases import Context
    from laughlab_plugins.source_file import FileSource, FileParams

    x = np.random.default_rng(0).normal(0.01, 0.2, 300_000).astype(np.float32)
    sf.write(tmp_path / "n.wav", x, 44100, subtype="FLOAT")

    def source():
        src = FileSource(FileParams(path=str(tmp_path / "n.wav")), Context(fps=60))
        src.open()
        return src

    alone = source()
    for _ in alone._read():
        pass
    for _ in range(5):
        both = source()
        readers = [threading.Thread(target=lambda: [None for _ in both._read()]) for _ in range(2)]
        for r in readers:
            r.start()
        for r in readers:
            r.join()
        assert both.metrics() == alone.metrics() and both.count == len(x)
