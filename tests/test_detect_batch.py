"""``laughlab detect`` on a batch with damaged files: by default one line naming the file, before any work and with
nothing written; with ``--skip-unreadable`` each damaged file is left out in one line on stderr and the rest is
written, and the closing line says how many were skipped and how many had no laughter."""
import csv

import numpy as np
import pytest
import soundfile as sf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)


def batch(tmp_path):
    """A folder of three recordings: a tone (no laughter), a text file named .wav, and a FLAC cut in the middle of
    its audio (its header reads; decoding fails 1 s in)."""
    rec = tmp_path / "rec"
    rec.mkdir()
    t = np.arange(32000) / 16000
    sf.write(rec / "a_tone.wav", 0.1 * np.sin(2 * np.pi * 220 * t), 16000)
    (rec / "b_notes.wav").write_text("not audio\n")
    noise = np.random.default_rng(0).normal(0, 0.1, 16000 * 4)
    sf.write(rec / "c_cut.flac", noise, 16000)
    data = (rec / "c_cut.flac").read_bytes()
    (rec / "c_cut.flac").write_bytes(data[: len(data) // 2])
    return rec


def test_a_damaged_file_stops_the_batch_in_one_line_before_any_work(tmp_path):
    rec, out = batch(tmp_path), tmp_path / "out"
    r = laughlab("detect", str(rec), "--out", str(out))
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [r.stderr.strip()]
    assert "b_notes.wav" in r.stderr and "--skip-unreadable" in r.stderr
    assert not out.exists()
    (rec / "b_notes.wav").unlink()   # the cut FLAC is found only when read: still nothing written
    r = laughlab("detect", str(rec), "--out", str(out))
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [r.stderr.strip()]
    assert "c_cut.flac" in r.stderr and "cut short" in r.stderr and not out.exists()


def test_skip_unreadable_leaves_out_each_damaged_file_and_says_so(tmp_path):
    rec, out = batch(tmp_path), tmp_path / "out"
    r = laughlab("detect", str(rec), "--out", str(out), "--skip-unreadable")
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("laughlab: skipped: ") for line in lines)
    assert "b_notes.wav" in lines[0] and "c_cut.flac" in lines[1]
    assert r.stdout.startswith("laughlab: 1 file(s), 1 without laughter, 2 skipped, 2.0 s of audio, 0 laughter segment(s)")
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a_tone.TextGrid", "a_tone.txt", "segments.csv"]
    assert list(csv.DictReader((out / "segments.csv").open())) == []
    (rec / "a_tone.wav").unlink()
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "out2"), "--skip-unreadable")
    assert r.returncode == 2 and "no readable audio among the inputs" in r.stderr.strip().splitlines()[-1]
    assert not (tmp_path / "out2").exists()


def test_read_mono_fills_in_place_whatever_the_header_says(tmp_path, monkeypatch):
    """detect reads a file into one array sized by its header (half the memory of a list of blocks and its
    copy); a file with more or fewer samples than its header says (a compressed format's estimate, a WAV cut
    short by less than 0.1 s) is read whole all the same, sample for sample."""
    from laughlab.detector.detect import read_mono
    from laughlab.io import audio

    x = np.random.default_rng(1).normal(0, 0.1, 44100 * 3 + 7).astype(np.float32)
    sf.write(tmp_path / "x.flac", x, 44100, subtype="PCM_24")
    want = sf.read(tmp_path / "x.flac", dtype="float32")[0]
    got, sr = read_mono(tmp_path / "x.flac")
    assert sr == 44100 and got.dtype == np.float32 and np.array_equal(got, want)
    real = audio.read_blocks
    for more, keep in ((want[:5000], None), (want[:1], None), (want[:0], -100)):   # more than the header says, or fewer
        def blocks(path, block_s, more=more, keep=keep):
            for b in real(path, block_s):
                yield b[:keep]
            yield more

        monkeypatch.setattr(audio, "read_blocks", blocks)
        got, _ = read_mono(tmp_path / "x.flac")
        assert np.array_equal(got, np.concatenate([want[:keep], more]))


def test_overwrite_keeps_the_earlier_labels_of_a_file_skipped_now(tmp_path):
    """A re-read: with --overwrite --skip-unreadable, the labels an earlier detect wrote for a file that cannot be
    read now were removed as stale; they stay (and stay in the manifest), the others' are replaced."""
    rec, out = batch(tmp_path), tmp_path / "out"
    (rec / "b_notes.wav").unlink()
    (rec / "c_cut.flac").unlink()
    t = np.arange(16000) / 16000
    sf.write(rec / "d_tone.wav", 0.1 * np.sin(2 * np.pi * 330 * t), 16000)
    assert laughlab("detect", str(rec), "--out", str(out)).returncode == 0
    (rec / "d_tone.wav").write_text("damaged since\n")
    r = laughlab("detect", str(rec), "--out", str(out), "--overwrite", "--skip-unreadable")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a_tone.TextGrid", "a_tone.txt",
                                                                          "d_tone.TextGrid", "d_tone.txt", "segments.csv"]
    (rec / "d_tone.wav").unlink()   # gone for good: the next --overwrite removes its labels as stale
    assert laughlab("detect", str(rec), "--out", str(out), "--overwrite").returncode == 0
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a_tone.TextGrid", "a_tone.txt", "segments.csv"]


def test_detect_writes_annotations_a_corpus_folder_reads(tmp_path):
    """A review: detect's Audacity labels said 'laughter' (the corpus' label is 'laugh') and its TextGrid's tier is
    'laughter' (the corpus reads 'bouts'), so its output, corrected by hand, could not give a recording its truth.
    Now a detect -> correct -> evaluate loop: the files it writes are read as the recording's annotation."""
    from laughlab.corpora import annotations, fetch
    from laughlab.harness.corpus import build_corpus

    src = fetch.require(kinds=["laugh"])["btanks/laugh01"]
    rec = tmp_path / "rec"
    rec.mkdir()
    x, sr = sf.read(src)
    sf.write(rec / "laugh.wav", x, sr)
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    segs = [(float(row["start"]), float(row["end"])) for row in csv.DictReader((tmp_path / "out" / "segments.csv").open())]
    assert segs, "the laugh was found"
    assert (tmp_path / "out" / "laugh.txt").read_text().split("\n")[0].endswith("\tlaugh")
    for ext in ("txt", "TextGrid"):
        ann = annotations.read(tmp_path / "out" / f"laugh.{ext}", len(x) / sr)
        assert [(round(b.start, 3), round(b.end, 3)) for b in ann.labels] == [(round(a, 3), round(b, 3)) for a, b in segs]
        assert {b.text for b in ann.labels} == {"laugh"}
    # beside its recording in a corpus folder, the TextGrid is its truth (bouts, no calls)
    (rec / "laugh.TextGrid").write_bytes((tmp_path / "out" / "laugh.TextGrid").read_bytes())
    (item,) = build_corpus({"folder": str(rec), "profiles": []})
    assert item.id == "rec-laugh" and item.truth == str(rec / "laugh.TextGrid")


def test_two_inputs_of_one_name_are_both_named(tmp_path):
    """A review: "two inputs share the name 'a'" did not say which files; both paths are in the line."""
    from laughlab.core.errors import LaughlabError
    from laughlab.detector.detect import inputs

    for ext in ("wav", "flac"):
        (tmp_path / f"a.{ext}").write_bytes(b"x")
    with pytest.raises(LaughlabError) as e:
        inputs([str(tmp_path)])
    assert str(e.value) == (f"two inputs share the name 'a' ({tmp_path / 'a.flac'}, {tmp_path / 'a.wav'}): their "
                            "label files would collide; run them separately (--out)")


def test_a_stopped_detect_closes_its_progress_before_the_error_line(tmp_path, monkeypatch):
    """A review: after Ctrl-C the error line was printed at the end of the progress bar's line."""
    from laughlab.detector import segments

    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)

    def stopped(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(segments, "laughter_prob", stopped)
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(tmp_path / "out"), "--progress", "on")
    assert r.returncode == 130 and not (tmp_path / "out").exists()
    lines = r.stderr.splitlines()
    assert lines[-2].startswith("detect: 0.0/1.0 s of audio, ") and lines[-1] == "laughlab: error: interrupted"
