"""``laughlab detect`` on a batch with damaged files: by default one line naming the file, before any work and with
nothing written; with ``--skip-unreadable`` each damaged file is left out in one line on stderr and the rest is
written, and the closing line says how many were skipped and how many had no laughter."""
import csv
import json
import re
from pathlib import Path

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
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a_tone.TextGrid", "a_tone.txt",
                                                                          "recordings.csv", "segments.csv"]
    assert list(csv.DictReader((out / "segments.csv").open())) == []
    # the tone has no segment, and its row says so (a data user's review: no laughter looked like not read), with
    # the settings that made it; the skipped files have rows too, with the reason stderr gave (not in the table
    # before 2026-11-29)
    settings = {"threshold": "0.5", "min_length_s": "0.2", "hop_s": "0.5", "smooth_windows": "3", "channels": "mix"}
    rows = list(csv.DictReader((out / "recordings.csv").open()))
    assert rows[0] == {"file": "a_tone", "duration_s": "2.0000", "segments": "0", "laughter_s": "0.0000", **settings,
                       "skipped": ""}
    assert [r["file"] for r in rows[1:]] == ["b_notes", "c_cut"]
    for r, line in zip(rows[1:], lines):
        assert r == {"file": r["file"], "duration_s": "", "segments": "", "laughter_s": "", **settings,
                     "skipped": line.removeprefix("laughlab: skipped: ")}
    (rec / "a_tone.wav").unlink()
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "out2"), "--skip-unreadable")
    assert r.returncode == 2 and "no readable audio among the inputs" in r.stderr.strip().splitlines()[-1]
    assert not (tmp_path / "out2").exists()


def test_a_file_failing_part_way_takes_its_seconds_off_the_progress_bar(tmp_path):
    """A diff review (2026-11-29): read block by block, a long file that failed 24 s in left those seconds on the bar,
    whose total lost the whole file: '61.7/31.7 s of audio'.  Every state of the bar is at most its total, and
    recordings.csv lists the inputs in their order, the skipped one in its place."""
    rec = tmp_path / "rec"
    rec.mkdir()
    noise = np.random.default_rng(0).normal(0, 0.1, 16000 * 40)
    sf.write(rec / "a_cut.flac", noise, 16000)
    data = (rec / "a_cut.flac").read_bytes()
    (rec / "a_cut.flac").write_bytes(data[: len(data) * 6 // 10])
    sf.write(rec / "b_good.wav", noise[: 16000 * 30], 16000)
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "out"), "--skip-unreadable", "--progress", "on")
    assert r.returncode == 0 and "skipped: cannot decode" in r.stderr, r.stderr
    bar = [(float(a), float(b)) for a, b in re.findall(r"(\d+\.\d)/(\d+\.\d) s of audio", r.stderr)]
    assert bar and max(a for a, _ in bar) > 20 and all(a <= b for a, b in bar), bar
    rows = list(csv.DictReader((tmp_path / "out" / "recordings.csv").open()))
    assert [(r["file"], r["skipped"] != "") for r in rows] == [("a_cut", True), ("b_good", False)]


@pytest.fixture(scope="module")
def laughing():
    """A real laugh the head hears (trackballs' evil laugh, 22.05 kHz, 4.6 s) when the corpus is there, else 5 s of
    the synthetic intense laughter; a NaN in it (read as 0).  A diff review: on noise every window's probability was
    0 (the noise veto), so the comparison below compared zeros and a wrong window passed."""
    from laughlab.corpora.fetch import corpus_dir
    from laughlab.synth.laughter import SyntheticLaughter

    f = corpus_dir() / "files" / "trackballs" / "evillaugh.wav"
    if f.is_file():
        x, sr = sf.read(f, dtype="float32")
    else:
        synth = SyntheticLaughter(seed=0, duration_s=5.0, sample_rate=22050, profile="intense")
        x, sr = synth.render(0, synth.n_samples).astype(np.float32), 22050
    x = x.copy()
    x[30000] = np.nan
    return x, sr


@pytest.mark.parametrize("cuts, hint", [((), 0), ((1, 2, 22050), 10), ((0, 0, 5000, 5000, 60000), 10 ** 6),
                                        ((11025, 11026, 50000), 101293), ((101292,), 101292)])
def test_detect_reads_block_by_block_to_the_whole_signals_values(cuts, hint, laughing):
    """Since 2026-11-29 detect holds a file's 16 kHz samples alone, read block by block (the whole file was held:
    0.9 GB an hour at 48 kHz).  The times and probabilities are the whole signal's bit for bit whatever the blocks
    (empty ones, one sample, half a second and one more, a window's edge) and whatever the header promised
    (``frames_hint``: fewer samples than there are, as a compressed format's estimate, or more), at a hop that does
    not divide the signal; the laugh's windows reach the threshold, so a window sent with a wrong end would show."""
    from laughlab.detector import segments as S
    from laughlab.detector.yamnet import LaughterScore, Yamnet

    model, score = Yamnet(), LaughterScore()
    x, sr = laughing
    t, p = S.laughter_prob(x, sr, 0.37, model, score)
    assert len(t) >= 12 and np.isfinite(p).all() and p.max() > 0.5
    edges = [0, *cuts, len(x)]
    got_t, got_p, n = S.laughter_prob_blocks((x[a:b] for a, b in zip(edges, edges[1:])), sr, 0.37, model, score,
                                             frames_hint=hint)
    assert n == len(x) and np.array_equal(got_t, t) and np.array_equal(got_p, p)


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
                                                                          "d_tone.TextGrid", "d_tone.txt",
                                                                          "recordings.csv", "segments.csv"]
    (rec / "d_tone.wav").unlink()   # gone for good: the next --overwrite removes its labels as stale
    assert laughlab("detect", str(rec), "--out", str(out), "--overwrite").returncode == 0
    assert sorted(p.name for p in out.iterdir() if p.name[0] != ".") == ["a_tone.TextGrid", "a_tone.txt",
                                                                          "recordings.csv", "segments.csv"]


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
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "out"), "--formats", "csv,audacity,textgrid,elan")
    assert r.returncode == 0, r.stderr
    segs = [(float(row["start"]), float(row["end"])) for row in csv.DictReader((tmp_path / "out" / "segments.csv").open())]
    assert segs, "the laugh was found"
    assert (tmp_path / "out" / "laugh.txt").read_text().split("\n")[0].endswith("\tlaugh")
    for ext in ("txt", "TextGrid", "eaf"):   # ELAN's too (a review: input.truth= an .eaf was read as a CSV)
        ann = annotations.read(tmp_path / "out" / f"laugh.{ext}", len(x) / sr)
        got = np.array([(b.start, b.end) for b in ann.labels])   # ELAN's whole ms: within 1 ms of the 0.1 ms times
        np.testing.assert_allclose(got, np.array(segs), atol=1e-3 if ext == "eaf" else 5e-4)
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
    (tmp_path / "a.mp3").write_bytes(b"x")   # a first-contact review: three files were "two inputs"
    with pytest.raises(LaughlabError, match=r"^three inputs share the name 'a' \("):
        inputs([str(tmp_path)])
    (tmp_path / "a.mp3").unlink()
    # names that differ in case only: one file on macOS' and Windows' file systems (a review at scale)
    (tmp_path / "a.flac").unlink()
    (tmp_path / "A.flac").write_bytes(b"x")
    with pytest.raises(LaughlabError, match=r"^two inputs share the name 'A' and 'a', which differ in case or Unicode "
                                            r"form only \(one file on macOS and Windows\) \("):
        inputs([str(tmp_path)])
    (tmp_path / "A.flac").unlink()
    (tmp_path / "a.wav").unlink()
    for name in ("Straße.wav", "Strasse.wav"):   # two files everywhere ('ß' is not 'ss' to a file system)
        (tmp_path / name).write_bytes(b"x")
    assert sorted(n for _, n in inputs([str(tmp_path)])) == ["Strasse", "Straße"]
    for name in ("Straße.wav", "Strasse.wav"):
        (tmp_path / name).unlink()
    (tmp_path / "a.wav").write_bytes(b"x")
    # the same take name in two folders, given file by file (a shell glob, rec/*/*.wav; the detect review): their
    # folder names each by its path from it, and the line says so
    for day in ("day1", "day2"):
        (tmp_path / "rec" / day).mkdir(parents=True)
        (tmp_path / "rec" / day / "take1.wav").write_bytes(b"x")
    with pytest.raises(LaughlabError, match=r"give their folder instead \(" + re.escape(str((tmp_path / "rec").resolve()))
                       + r": each file found in it is named by its path from it\)"):
        inputs([str(tmp_path / "rec" / "day1" / "take1.wav"), str(tmp_path / "rec" / "day2" / "take1.wav")])


def test_a_stopped_detect_closes_its_progress_before_the_error_line(tmp_path, monkeypatch):
    """A review: after Ctrl-C the error line was printed at the end of the progress bar's line."""
    from laughlab.detector import segments

    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)

    def stopped(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(segments, "laughter_prob_blocks", stopped)
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(tmp_path / "out"), "--progress", "on")
    assert r.returncode == 130 and not (tmp_path / "out").exists()
    lines = r.stderr.splitlines()
    assert lines[-2].startswith("detect: 0.0/1.0 s of audio, ")
    # what was written is said (a review: "interrupted" left the user to guess): nothing, until every input is done
    assert lines[-1] == (f"laughlab: error: interrupted after 0 of 1 input(s); nothing was written to "
                         f"{tmp_path / 'out'} (detect writes when every input is done); the same command goes on "
                         "from there")


def test_an_interrupted_batch_goes_on_where_it_stopped(tmp_path, monkeypatch):
    """A review at scale: a Ctrl-C 14 s into a 5.2-hour corpus, or a damaged file found late, lost every input done
    (a batch writes all or none). The inputs done are kept, keyed on the file and the settings: the same command goes
    on from there, with the same bytes as a run never stopped, and a batch written whole leaves nothing kept."""
    from laughlab.detector import segments

    monkeypatch.setenv("LAUGHLAB_DATA", str(tmp_path / "data"))
    rng = np.random.default_rng(1)
    (tmp_path / "in").mkdir()
    for k in range(3):
        sf.write(tmp_path / "in" / f"t{k}.wav", rng.normal(0, 0.1, 16000 * 2), 16000)
    args = ("--threshold", "0", "--smooth", "1")   # every file one segment holding its mean probability: rows to
    whole = laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "whole"), *args)   # compare
    assert whole.returncode == 0, whole.stderr
    assert len((tmp_path / "whole" / "segments.csv").read_text().splitlines()) == 1 + 3
    assert not list((tmp_path / "data" / "detect").glob("*.json"))   # written whole: nothing kept
    real, calls = segments.laughter_prob_blocks, []

    def stops_at_the_third(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(segments, "laughter_prob_blocks", stops_at_the_third)
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "out"), *args)
    assert r.returncode == 130 and "interrupted after 2 of 3 input(s)" in r.stderr
    assert r.stderr.rstrip().endswith("the same command goes on from there")
    assert len(list((tmp_path / "data" / "detect").glob("*.json"))) == 2
    monkeypatch.setattr(segments, "laughter_prob_blocks", real)
    calls.clear()
    monkeypatch.setattr(segments, "laughter_prob_blocks", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "out"), *args)
    assert r.returncode == 0 and len(calls) == 1, r.stderr   # the third alone computed
    assert "laughlab: 2 of 3 input(s) as an earlier, unfinished run of these settings found them" in r.stderr
    for name in ("segments.csv", "recordings.csv", "t0.TextGrid", "t2.TextGrid"):
        assert (tmp_path / "out" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    assert not list((tmp_path / "data" / "detect").glob("*.json"))
    # another setting is computed afresh, not taken from a kept one
    monkeypatch.setattr(segments, "laughter_prob_blocks", stops_at_the_third)
    calls.clear()
    laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "o2"), *args)
    calls.clear()
    monkeypatch.setattr(segments, "laughter_prob_blocks", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "o2"), "--threshold", "0.6")
    assert r.returncode == 0 and len(calls) == 3, r.stderr
    # a file replaced by another of the same size and modification time (cp -p, rsync -a) is computed afresh
    import os

    src = tmp_path / "in" / "t1.wav"
    st = src.stat()
    sf.write(tmp_path / "other.wav", rng.normal(0, 0.3, 16000 * 2), 16000)
    assert len(list((tmp_path / "data" / "detect").glob("*.json"))) == 2   # t0, t1 kept by o2's stopped run
    os.replace(tmp_path / "other.wav", src)
    os.utime(src, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert src.stat().st_size == st.st_size and src.stat().st_mtime_ns == st.st_mtime_ns
    calls.clear()
    monkeypatch.setattr(segments, "laughter_prob_blocks", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    r = laughlab("detect", str(tmp_path / "in"), "--out", str(tmp_path / "o3"), *args)
    assert r.returncode == 0 and len(calls) == 2 and "1 of 3 input(s) as an earlier" in r.stderr, r.stderr


def test_ends_never_pass_the_recording_and_names_are_quoted_in_the_csv(tmp_path):
    """A review: a 5.8375964 s file's segment ended at 5.8376 (segments.csv, labels, TextGrid xmax) and 5838 ms
    (ELAN), past its last sample; a file name with a comma or a quote split its segments.csv row (pandas shifted
    the columns without a word).  Hand values: times to 0.1 ms rounded down at the end, ms in ELAN."""
    import pandas as pd

    from laughlab.detector import segments as S

    dur = 257434 / 44100   # 5.83759637... s
    t = np.arange(0.25, dur, 0.5)
    segs = S.segments(t, np.ones_like(t), 0.5, 0.5, 0.2, dur)
    assert segs == [S.Segment(0.0, 5.8375, 1.0)]
    assert "xmax = 5.8375" in S.textgrid_text(segs, dur) and "xmax = 5.8376" not in S.textgrid_text(segs, dur)
    assert 'TIME_VALUE="5837"' in S.eaf_text(segs, duration_s=dur)
    assert S.segments(t, np.ones_like(t), 0.5, 0.5, 0.2, 6.0)[-1].end == 6.0   # a whole duration stays whole
    names = ["Smith, J - take 1", 'say "ha"', "plain"]
    S.write_outputs(tmp_path, [(n, 2.0, [S.Segment(0.5, 1.25, 0.75)]) for n in names], ("csv",))
    rows = list(csv.DictReader((tmp_path / "segments.csv").open(newline="")))
    assert [(r["file"], r["start"], r["end"], r["probability"]) for r in rows] == \
        [(n, "0.5000", "1.2500", "0.7500") for n in names]
    assert list(pd.read_csv(tmp_path / "segments.csv")["file"]) == names
    assert (tmp_path / "segments.csv").read_text().splitlines()[-1] == "plain,0.5000,1.2500,0.7500"   # as before


def test_the_same_file_twice_is_read_once_and_unread_formats_are_named(tmp_path, capsys):
    """A review: a folder and a file in it (or overlapping globs) were refused as "two inputs share the name 'a'
    (in/a.wav, in/a.wav)"; a folder's .m4a and .wma recordings were left out without a word, and a folder of only
    .m4a was "no audio files"."""
    from laughlab.core.errors import LaughlabError
    from laughlab.detector.detect import inputs

    rec = tmp_path / "in"
    rec.mkdir()
    sf.write(rec / "a.wav", np.zeros(1600), 16000)
    sf.write(rec / "b.wav", np.zeros(1600), 16000)
    assert inputs([str(rec), str(rec / "a.wav"), str(rec / "b.wav")]) == [(rec / "a.wav", "a"), (rec / "b.wav", "b")]
    assert capsys.readouterr().err == ""
    (rec / "phone.m4a").write_bytes(b"x")
    (rec / "sub").mkdir()
    (rec / "sub" / "c.wma").write_bytes(b"x")
    (rec / "notes.txt").write_text("mine")
    assert [n for _, n in inputs([str(rec), str(rec)])] == ["a", "b"]   # the folder twice: its files counted once
    assert capsys.readouterr().err == ("laughlab: not read: 2 file(s) (.m4a, .wma: formats laughlab does not read; "
                                       "convert them to WAV, e.g. ffmpeg -i IN.m4a OUT.wav)\n")
    r = laughlab("detect", str(rec / "phone.m4a"), "--out", str(tmp_path / "o"))   # given by itself: the same advice
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and \
        "(.m4a: a format laughlab does not read; convert it to WAV, e.g. ffmpeg -i IN.m4a OUT.wav)" in r.stderr
    (rec / "a.wav").unlink()
    (rec / "b.wav").unlink()
    with pytest.raises(LaughlabError, match=r"^no audio files in folder .*in that laughlab reads: 2 file\(s\) "
                                            r"\(\.m4a, \.wma: formats"):
        inputs([str(rec)])


def test_labels_corrected_in_place_are_not_replaced_by_overwrite(tmp_path):
    """A diff review: detect, correct, evaluate is the documented loop, yet a TextGrid corrected in place in the
    --out folder was replaced by the next ``detect --overwrite`` without a word.  detect's record holds each file's
    sha256: an edited one is the user's now, refused in one line and kept; unedited files are replaced as before."""
    rec = tmp_path / "rec"
    rec.mkdir()
    t = np.arange(32000) / 16000
    sf.write(rec / "a.wav", 0.1 * np.sin(2 * np.pi * 220 * t), 16000)
    out = tmp_path / "out"
    assert laughlab("detect", str(rec), "--out", str(out)).returncode == 0
    assert laughlab("detect", str(rec), "--out", str(out), "--overwrite").returncode == 0   # unedited: replaced
    grid = out / "a.TextGrid"
    mine = grid.read_text().replace('text = ""', 'text = "laugh"', 1)
    grid.write_text(mine)
    r = laughlab("detect", str(rec), "--out", str(out), "--overwrite")
    assert r.returncode == 2 and r.stderr == (
        f"laughlab: error: {out} holds a.TextGrid, edited since detect wrote it, and this run would replace it; move "
        "it or choose another --out (--overwrite replaces only detect's own files, unedited)\n"), r.stderr
    assert grid.read_text() == mine


def test_a_folders_hidden_files_and_folders_are_not_inputs(tmp_path):
    """A review: recordings copied from a Mac to a USB drive have a ``._take1.wav`` beside each (AppleDouble, not
    audio; hidden by ls and Finder), and the batch stopped on it; a hidden folder's copies (``.Trashes``) were
    taken as takes. A folder's hidden files and folders are left out; a hidden file given by itself is read."""
    rec = tmp_path / "rec"
    (rec / "day1").mkdir(parents=True)
    (rec / ".Trashes").mkdir()
    t = np.arange(16000) / 16000
    sf.write(rec / "day1" / "take1.wav", 0.1 * np.sin(2 * np.pi * 220 * t), 16000)
    sf.write(rec / ".Trashes" / "old.wav", 0.1 * np.sin(2 * np.pi * 220 * t), 16000)
    (rec / "day1" / "._take1.wav").write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X        ")
    out = tmp_path / "out"
    r = laughlab("detect", str(rec), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.name[0] != ".") == \
        ["day1", "day1/take1.TextGrid", "day1/take1.txt", "recordings.csv", "segments.csv"]
    r = laughlab("detect", str(rec / "day1" / "._take1.wav"), "--out", str(tmp_path / "o2"))
    assert r.returncode == 2 and "._take1.wav" in r.stderr


def test_a_linked_session_folder_is_searched_once_and_a_link_loop_ends(tmp_path):
    """The detect review: a folder of recordings whose sessions are links to folders elsewhere (another drive) gave
    only the real folders' files, the linked ones left out without a word (rglob does not follow links). Linked
    folders are searched, each real folder once (a link back to a parent is no loop)."""
    from laughlab.detector.detect import inputs

    rec, elsewhere = tmp_path / "rec", tmp_path / "drive" / "s2"
    (rec / "s1").mkdir(parents=True)
    elsewhere.mkdir(parents=True)
    for f in (rec / "s1" / "take.wav", elsewhere / "take.wav"):
        f.write_bytes(b"x")
    (rec / "s2").symlink_to(elsewhere, target_is_directory=True)
    (rec / "s1" / "up").symlink_to(rec, target_is_directory=True)   # a loop
    assert [n for _, n in inputs([str(rec)])] == ["s1/take", "s2/take"]


def test_a_subfolder_that_cannot_be_listed_is_one_line_not_left_out(tmp_path, monkeypatch):
    """os.walk skips a folder it cannot list (permissions), so its recordings were left out without a word (noted
    by the detect review, which ran as root): now one line naming it."""
    import os

    from laughlab.core.errors import LaughlabError
    from laughlab.detector.detect import inputs

    (tmp_path / "rec" / "locked").mkdir(parents=True)
    (tmp_path / "rec" / "a.wav").write_bytes(b"x")
    real = os.scandir

    def scandir(path="."):
        if str(path).endswith("locked"):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path)

    monkeypatch.setattr(os, "scandir", scandir)
    with pytest.raises(LaughlabError, match=r"^cannot read the folder .*locked: Permission denied$"):
        inputs([str(tmp_path / "rec")])


def test_each_laugh_as_audio_the_recordings_own_samples(tmp_path):
    """``--formats ...,audio``: each segment of ``segments.csv`` as ``NAME_laugh_K.wav`` (as ``segment_laughter.py``
    writes its ``laugh_K.wav``; the detect review found no way but a script), the recording's own samples, rate,
    channels and sample format; a file of yours by a clip's name is refused even with --overwrite, before anything
    is written."""
    from laughlab.corpora import fetch

    x, sr = sf.read(fetch.require(kinds=["laugh"])["btanks/laugh01"])
    quiet = np.zeros(sr)
    two = np.concatenate([quiet, x, quiet, quiet, x, quiet])
    stereo = np.stack([two, -0.5 * two], axis=1)
    rec = tmp_path / "rec" / "day 1"
    rec.mkdir(parents=True)
    sf.write(rec / "take.wav", stereo, sr, subtype="PCM_24")
    out = tmp_path / "out"
    r = laughlab("detect", str(tmp_path / "rec"), "--out", str(out), "--formats", "csv,audio")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader((out / "segments.csv").open()))
    assert len(rows) >= 2 and {row["file"] for row in rows} == {"day 1/take"}
    src, _ = sf.read(rec / "take.wav", dtype="int32")
    for k, row in enumerate(rows):
        clip = out / "day 1" / f"take_laugh_{k}.wav"
        info = sf.info(clip)
        assert (info.samplerate, info.channels, info.subtype) == (sr, 2, "PCM_24")
        got, _ = sf.read(clip, dtype="int32")
        a, b = round(float(row["start"]) * sr), round(float(row["end"]) * sr)
        np.testing.assert_array_equal(got, src[a:b])
    assert sorted(p.name for p in (out / "day 1").iterdir()) == [f"take_laugh_{k}.wav" for k in range(len(rows))]
    # a clip name that is yours: refused, nothing of this run written
    again = tmp_path / "again"
    again.mkdir()
    (again / "day 1").mkdir()
    (again / "day 1" / "take_laugh_0.wav").write_bytes(b"mine")
    r = laughlab("detect", str(tmp_path / "rec"), "--out", str(again), "--formats", "csv,audio", "--overwrite")
    assert r.returncode == 2 and "take_laugh_0.wav" in r.stderr and "which no earlier detect wrote there" in r.stderr
    assert (again / "day 1" / "take_laugh_0.wav").read_bytes() == b"mine"
    assert sorted(p.name for p in again.rglob("*")) == ["day 1", "take_laugh_0.wav"]
    # an earlier detect's clips that this run does not write again are removed (--overwrite): one laugh now
    sf.write(rec / "take.wav", stereo[: 3 * sr + len(x)], sr, subtype="PCM_24")
    r = laughlab("detect", str(tmp_path / "rec"), "--out", str(out), "--formats", "csv,audio", "--overwrite")
    assert r.returncode == 0, r.stderr
    n = len(list(csv.DictReader((out / "segments.csv").open())))
    assert 1 <= n < len(rows)
    assert sorted(p.name for p in (out / "day 1").iterdir()) == [f"take_laugh_{k}.wav" for k in range(n)]


def test_channels_each_finds_who_laughed_in_a_dyad(tmp_path):
    """A dyad, one speaker a channel: the laugh on the right channel alone is found in take.ch2 only, and its clip
    is that channel's samples; mixed (the default) it is found in take; a mono file keeps its name."""
    from laughlab.corpora import fetch

    x, sr = sf.read(fetch.require(kinds=["laugh"])["btanks/laugh01"])
    quiet = np.zeros(sr)
    right = np.concatenate([quiet, x, quiet])
    left = 0.001 * np.random.default_rng(0).standard_normal(len(right))   # a quiet room on the left
    rec = tmp_path / "rec"
    rec.mkdir()
    sf.write(rec / "take.wav", np.stack([left, right], axis=1), sr, subtype="PCM_16")
    sf.write(rec / "solo.wav", right, sr, subtype="PCM_16")
    out = tmp_path / "each"
    r = laughlab("detect", str(rec), "--out", str(out), "--channels", "each", "--formats", "csv,textgrid,audio")
    assert r.returncode == 0, r.stderr
    # two files, three inputs: the line counts files as files (it said 3 file(s))
    assert r.stdout.startswith("laughlab: 2 file(s) as 3 inputs (a channel each), 1 without laughter, "), r.stdout
    rows = list(csv.DictReader((out / "segments.csv").open()))
    assert {row["file"] for row in rows} == {"take.ch2", "solo"}
    assert {p.name for p in out.glob("*.TextGrid")} == {"take.ch1.TextGrid", "take.ch2.TextGrid", "solo.TextGrid",
                                                         "take.TextGrid"}
    # the recording's own TextGrid, a tier a channel (the Left of the seventeenth session's note, from a conversation
    # analyst's review: Praat opens the stereo file with one TextGrid, not one a channel): each tier the channel's own
    from praatio import textgrid

    both = textgrid.openTextgrid(str(out / "take.TextGrid"), includeEmptyIntervals=False)
    assert both.tierNames == ("laughter-ch1", "laughter-ch2")
    for k in (1, 2):
        own = textgrid.openTextgrid(str(out / f"take.ch{k}.TextGrid"), includeEmptyIntervals=False)
        assert list(both.getTier(f"laughter-ch{k}").entries) == list(own.getTier("laughter").entries)
        assert both.maxTimestamp == own.maxTimestamp
    assert not both.getTier("laughter-ch1").entries and both.getTier("laughter-ch2").entries
    # read back as an annotation of the stereo recording (its channels mixed), the laughter of either channel
    from laughlab.corpora import annotations

    assert annotations.read(out / "take.TextGrid", len(right) / sr).bouts == [
        (e.start, e.end) for e in both.getTier("laughter-ch2").entries]
    src, _ = sf.read(rec / "take.wav", dtype="int32")
    first = next(row for row in rows if row["file"] == "take.ch2")
    clip, _ = sf.read(out / "take.ch2_laugh_0.wav", dtype="int32")
    a, b = round(float(first["start"]) * sr), round(float(first["end"]) * sr)
    assert clip.ndim == 1 and np.array_equal(clip, src[a:b, 1])
    mixed = tmp_path / "mixed"
    r = laughlab("detect", str(rec), "--out", str(mixed))
    assert r.returncode == 0, r.stderr
    assert {row["file"] for row in csv.DictReader((mixed / "segments.csv").open())} == {"take", "solo"}


def test_a_recordings_tail_shorter_than_half_a_hop_is_judged_too(tmp_path):
    """A new-user review: 4.9 s at --hop 2 --threshold 0 (every window laughter) was labelled 0 to 4.0 s: the windows
    stopped at the last whole hop's centre (3 s), so the last 0.9 s was never judged.  By hand: centres 1, 3, 5 s,
    each speaking for +-1 s, the last one cut at the recording's end: one segment 0 to 4.9 s."""
    sf.write(tmp_path / "a.wav", np.zeros(int(4.9 * 16000)), 16000)
    out = tmp_path / "out"
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(out), "--hop", "2", "--threshold", "0",
                 "--smooth", "1")
    assert r.returncode == 0, r.stderr
    assert (out / "a.txt").read_text() == "0.0000\t4.9000\tlaugh\n"


class AlwaysLaughter:
    """A score that hears laughter in every window (head 1, classes 1, no noise)."""

    def both(self, scores):
        return 1.0, 1.0

    def noise(self, scores):
        return 0.0


@pytest.mark.parametrize("hop", [0.05, 0.1, 0.3, 0.5, 1.0, 2.0])
def test_the_windows_cover_the_whole_recording_and_no_more(hop, monkeypatch):
    """Property over lengths, each hop: the first window speaks from 0 s, the last for a hop that begins before the
    recording's end and reaches it; no window ends more than SPEAKS_FOR_S past the last sample (zeros after it)."""
    from hypothesis import given, settings, strategies as st

    from laughlab.detector import segments as S, yamnet

    seen = {}

    class Scores:   # the windows laughter_prob asks for, all zeros
        def __init__(self, sr, model, frames_hint=0):
            self.n, seen["ends"] = 0, []

        def push(self, b):
            self.n += len(b)

        def want(self, ends):
            seen["ends"] += list(ends)

        def finish(self):
            seen["ends"] = np.asarray(seen["ends"])
            return np.zeros((len(seen["ends"]), yamnet.N_CLASSES))

    monkeypatch.setattr(yamnet, "WindowScores", Scores)

    @settings(max_examples=60, deadline=None)
    @given(n=st.integers(1, 16000 * 9), sr=st.sampled_from([8000, 16000, 44100]))
    def check(n, sr):
        dur = n / sr
        t, p = S.laughter_prob(np.zeros(n, np.float32), sr, hop, model=object(), score=AlwaysLaughter())
        assert len(t) == len(p) == len(seen["ends"]) and t[0] == pytest.approx(hop / 2)
        assert np.allclose(np.diff(t), hop)
        assert t[-1] - hop / 2 < dur <= t[-1] + hop / 2 + 1e-9
        assert seen["ends"].max() <= round((dur + S.SPEAKS_FOR_S) * sr)
        segs = S.segments(t, p, hop, 0.0, 0.0, dur)
        assert [(s.start, s.end) for s in segs] == [(0.0, S.floor_to(dur, 4))]

    check()


def test_an_out_folder_inside_the_input_folder_is_not_read_back(tmp_path):
    """A new-user review: ``detect rec --out rec/labels --formats audio`` run again with --overwrite read its own
    laughs' clips back as recordings (``labels/a_laugh_0``'s labels, clips of clips).  The files an earlier detect
    wrote into --out (its manifest) are left out of a folder's search."""
    rec = tmp_path / "rec"
    rec.mkdir()
    sf.write(rec / "a.wav", np.zeros(3 * 16000), 16000)
    args = ("detect", str(rec), "--out", str(rec / "labels"), "--formats", "csv,audio", "--threshold", "0")
    assert laughlab(*args).returncode == 0
    assert (rec / "labels" / "a_laugh_0.wav").is_file()
    r = laughlab(*args, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("laughlab: 1 file(s), 3.0 s of audio, 1 laughter segment(s)")
    assert sorted(p.relative_to(rec).as_posix() for p in rec.rglob("*") if p.is_file() and p.name[0] != ".") == [
        "a.wav", "labels/a_laugh_0.wav", "labels/recordings.csv", "labels/segments.csv"]
    # a folder holding only an earlier detect's clips: the line says why none is read
    r = laughlab("detect", str(rec / "labels"), "--out", str(rec / "labels"), "--overwrite")
    assert r.returncode == 2 and r.stderr.strip() == (
        f"laughlab: error: no audio files in folder {rec / 'labels'} other than the 1 laugh clip(s) an earlier "
        "detect wrote (its --out)")
    # a second run into another --out inside the folder (a researcher's review: labB read labA's clips, 9 files
    # for 4): an earlier detect's --out anywhere below is left out, its clips and its segments.csv alike
    r = laughlab("detect", str(rec), "--out", str(rec / "labB"), "--formats", "csv,audio", "--threshold", "0")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("laughlab: 1 file(s), 3.0 s of audio, 1 laughter segment(s)")
    assert sorted(p.name for p in (rec / "labB").iterdir() if p.name[0] != ".") == [
        "a_laugh_0.wav", "recordings.csv", "segments.csv"]
    # a clip given by name is read: only a folder's search leaves them out
    r = laughlab("detect", str(rec / "labels" / "a_laugh_0.wav"), "--out", str(tmp_path / "clip"))
    assert r.returncode == 0 and r.stdout.startswith("laughlab: 1 file(s)"), r.stderr


def test_a_detect_stopped_while_writing_its_clips_leaves_nothing_of_its_own(tmp_path, monkeypatch):
    """A new-user review: a Ctrl-C while detect wrote 146 clips left 85 of them, labels, and no segments.csv.  Now
    its files are moved into place together: stopped before that, a new --out is not there at all, and an --out
    that an earlier detect filled keeps that run's files, byte for byte, with no temporary file beside them."""
    from laughlab.detector import segments as S

    rec = tmp_path / "rec"
    rec.mkdir()
    for name in ("a", "b"):
        sf.write(rec / f"{name}.wav", np.zeros(3 * 16000), 16000)
    out = tmp_path / "out"
    args = ("detect", str(rec), "--out", str(out), "--formats", "csv,audacity,audio", "--threshold", "0")
    real, calls = S.write_clip, []

    def stopped(*a, **k):
        calls.append(a[0])
        if len(calls) == 2:   # the first clip written, the user stops the second
            raise KeyboardInterrupt
        real(*a, **k)

    monkeypatch.setattr(S, "write_clip", stopped)
    r = laughlab(*args)
    assert r.returncode == 130 and r.stderr.strip() == "laughlab: error: interrupted" and not out.exists()
    monkeypatch.setattr(S, "write_clip", real)
    assert laughlab(*args).returncode == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert sorted(map(str, before)) == [".laughlab-detect.json", "a.txt", "a_laugh_0.wav", "b.txt", "b_laugh_0.wav",
                                        "recordings.csv", "segments.csv"]
    calls.clear()
    monkeypatch.setattr(S, "write_clip", stopped)
    for name in ("a", "b"):   # longer recordings: every file would change
        sf.write(rec / f"{name}.wav", np.zeros(4 * 16000), 16000)
    r = laughlab(*args, "--overwrite")
    assert r.returncode == 130
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    record = Path(".laughlab-detect.json")
    assert after.keys() == before.keys() and all(after[k] == before[k] for k in before if k != record)
    # the manifest names the files this run would have written too, and keeps the earlier ones' hashes (an edit
    # made after the earlier run is still found by the next --overwrite)
    assert json.loads(after[record])["sha256"] == json.loads(before[record])["sha256"]


def test_detect_finds_no_laughter_in_steady_white_noise(tmp_path):
    """A new-user review: 3 s of white noise gave a laughter segment (the head took it for laughter).  The noise
    veto of the live gate applies offline too: a window where YAMNet's steady-noise classes outscore laughter and
    0.1 has probability 0.  The same file's laugh, mixed over the noise at 20 dB below it, is still found."""
    from laughlab.corpora import fetch

    rate = 44100
    noise = (0.27 * np.random.default_rng(3).standard_normal(3 * rate)).clip(-1, 1)
    sf.write(tmp_path / "white.wav", noise, rate, subtype="PCM_16")
    r = laughlab("detect", str(tmp_path / "white.wav"), "--out", str(tmp_path / "o"))
    assert r.returncode == 0 and r.stdout.startswith("laughlab: 1 file(s), 1 without laughter, 3.0 s of audio, "
                                                     "0 laughter segment(s)"), r.stdout
    x, sr = sf.read(fetch.require(kinds=["laugh"])["btanks/laugh01"])
    x = x if x.ndim == 1 else x.mean(axis=1)
    quiet = 0.1 * np.sqrt(np.mean(x ** 2)) * np.random.default_rng(4).standard_normal(len(x))   # 20 dB under it
    sf.write(tmp_path / "laugh.wav", x + quiet, sr, subtype="PCM_16")
    r = laughlab("detect", str(tmp_path / "laugh.wav"), "--out", str(tmp_path / "o2"))
    assert r.returncode == 0 and "1 laughter segment(s)" in r.stdout, r.stdout


def _damaged_flac(path):
    """A FLAC whose header reads and whose first block does not (a file damaged past its header)."""
    x = np.random.default_rng(0).standard_normal(48000) * 0.1
    sf.write(path, x, 48000)
    data = path.read_bytes()
    path.write_bytes(data[:8300] + b"\0" * 20000)


def test_every_unreadable_input_is_named_at_once_before_any_work(tmp_path):
    """A review: the first unreadable file alone was named; a file damaged past its header stopped the batch only
    at its turn, after the others' work (450 s of audio, then nothing written)."""
    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)
    (tmp_path / "notes.wav").write_text("not audio", encoding="utf-8")
    _damaged_flac(tmp_path / "zz_last.flac")
    r = laughlab("detect", str(tmp_path), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("laughlab: error: 2 inputs cannot be read: ") and "notes.wav" in r.stderr
    assert "zz_last.flac after 0.0 s" in r.stderr and r.stderr.endswith("(--skip-unreadable leaves such files out)\n")
    assert not (tmp_path / "out").exists()
    r = laughlab("detect", str(tmp_path), "--out", str(tmp_path / "out"), "--skip-unreadable")
    assert r.returncode == 0 and r.stderr.count("laughlab: skipped: ") == 2, r.stderr
    assert "2 skipped" in r.stdout


def test_overwrite_says_what_it_removed_of_an_earlier_batch(tmp_path):
    """A review: a run of one recording with --overwrite into a batch's folder removed the others' files unsaid."""
    for name in ("a", "b"):
        sf.write(tmp_path / f"{name}.wav", np.zeros(16000), 16000)
    out = tmp_path / "out"
    assert laughlab("detect", str(tmp_path / "a.wav"), str(tmp_path / "b.wav"), "--out", str(out)).returncode == 0
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(out), "--overwrite")
    assert r.returncode == 0 and (out / "a.TextGrid").exists() and not (out / "b.TextGrid").exists()
    assert f"laughlab: --overwrite removed 2 files an earlier detect wrote into {out} for recordings this run did " \
           "not read (b.TextGrid, b.txt)" in r.stderr, r.stderr
    refused = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(out))
    assert "its other recordings' files too" in refused.stderr


@pytest.mark.parametrize("out", ["-", " "])
def test_out_dash_is_refused_in_one_line(tmp_path, out):
    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", out, cwd=tmp_path)
    assert r.returncode == 2 and "detect writes files into a folder" in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "-").exists()


def test_formats_as_praat_spells_them(tmp_path):
    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(tmp_path / "out"), "--formats", "TextGrid,CSV")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        ".laughlab-detect.json", "a.TextGrid", "recordings.csv", "segments.csv"]


def test_a_file_damaged_late_is_skipped_on_a_line_of_its_own_and_off_the_bars_total(tmp_path):
    """A review: the skip notice was printed into the progress bar's line, and the bar ended at 89% (its total held
    the damaged file's header duration)."""
    sf.write(tmp_path / "a.wav", np.zeros(16000 * 2), 16000)
    x = np.random.default_rng(1).standard_normal(48000 * 6) * 0.1
    sf.write(tmp_path / "late.flac", x, 48000)
    data = (tmp_path / "late.flac").read_bytes()
    (tmp_path / "late.flac").write_bytes(data[:len(data) // 2] + b"\0" * (len(data) // 2))
    r = laughlab("detect", str(tmp_path), "--out", str(tmp_path / "out"), "--skip-unreadable", "--progress", "on")
    assert r.returncode == 0, r.stderr
    lines = r.stderr.replace("\r", "\n").splitlines()
    skipped = [ln for ln in lines if "skipped: " in ln]
    assert len(skipped) == 1 and skipped[0].startswith("laughlab: skipped: cannot decode "), lines
    last = [ln for ln in lines if ln.startswith("detect: ")][-1]
    assert last.startswith("detect: 100%") or "2.0/2.0 s" in last, last


def test_overwrite_with_fewer_formats_says_nothing_of_other_recordings(tmp_path):
    """A diff review: the same recording's files of a format no longer asked for were said to be other
    recordings'."""
    sf.write(tmp_path / "a.wav", np.zeros(16000), 16000)
    out = tmp_path / "out"
    assert laughlab("detect", str(tmp_path / "a.wav"), "--out", str(out)).returncode == 0
    r = laughlab("detect", str(tmp_path / "a.wav"), "--out", str(out), "--overwrite", "--formats", "csv")
    assert r.returncode == 0 and "removed" not in r.stderr and not (out / "a.TextGrid").exists()


def test_a_folder_of_segments_passes_by_detects_own_tables_and_names_a_csv_without_the_columns(tmp_path):
    """A diff review: skipping every CSV without file,start,end (so that detect's recordings.csv could be read
    back) scored a peer's 'filename,start,end' table as no segment at all, silently."""
    from laughlab.core.errors import LaughlabError
    from laughlab.detector import segments as S

    (tmp_path / "segments.csv").write_text("file,start,end,probability\na,0.5,1.0,0.9\n")
    (tmp_path / "recordings.csv").write_text("file,duration_s,segments,laughter_s\na,2.0,1,0.5\n")
    assert S.read_folder(tmp_path) == {"a": [S.Segment(0.5, 1.0)]}
    (tmp_path / "peer.csv").write_text("filename,start,end\nb,0.1,0.2\n")
    with pytest.raises(LaughlabError, match="peer.csv: a table of segments needs the columns file, start, end "
                                            r"\(it has filename, start, end\)"):
        S.read_folder(tmp_path)


def test_clips_of_a_float_recording_are_the_same_bytes_every_run(tmp_path):
    """A review at scale: the clips cut from a 32-bit float recording differed on every run (libsndfile's PEAK chunk
    holds the time it was written); the same recording and settings now give the same bytes."""
    import time

    from laughlab.detector.segments import Segment, write_clip

    x = (np.random.default_rng(0).normal(0, 0.2, (44100, 2))).astype(np.float32)
    sf.write(tmp_path / "take.wav", x, 44100, subtype="FLOAT")
    seg = Segment(0.25, 0.75, 0.9)
    write_clip(tmp_path / "a.wav", tmp_path / "take.wav", seg)
    time.sleep(1.1)   # the stamp's resolution is a second
    write_clip(tmp_path / "b.wav", tmp_path / "take.wav", seg)
    assert (tmp_path / "a.wav").read_bytes() == (tmp_path / "b.wav").read_bytes()
    got, sr = sf.read(tmp_path / "a.wav", dtype="float32")
    assert sr == 44100 and sf.info(str(tmp_path / "a.wav")).subtype == "FLOAT"
    assert np.array_equal(got, x[round(0.25 * 44100):round(0.75 * 44100)])


def test_an_empty_clip_of_one_channel_is_an_empty_wav(tmp_path):
    """The diff review: a segment of no samples (2.0-2.0 s, --min-length 0) of one channel ended detect in a
    traceback once clips were written through SoundFile (reshape of an empty array)."""
    from laughlab.detector.segments import Segment, write_clip

    sf.write(tmp_path / "st.wav", np.zeros((48000, 2), np.float32), 48000, subtype="FLOAT")
    write_clip(tmp_path / "c.wav", tmp_path / "st.wav", Segment(0.5, 0.5, 1.0), channel=1)
    info = sf.info(str(tmp_path / "c.wav"))
    assert info.frames == 0 and info.channels == 1
