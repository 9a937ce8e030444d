"""``laughlab detect --score``: the segments scored against each input's own annotation (a new-user review: a
researcher with annotated recordings had no documented way to measure detect against them).  The numbers are
checked here by an independent count of 10 ms frames, not by the function that makes them."""
import csv
import shutil

import numpy as np
import pytest
import soundfile as sf

from inprocess import laughlab  # the command line in this process (tests/inprocess.py)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Three recordings of the synthetic laughter (8 s, seeds 0 and 1, and 2), the first annotated by its
    truth.csv, the second by Audacity labels of its bouts, the third not at all."""
    root = tmp_path_factory.mktemp("score")
    rec = root / "rec"
    rec.mkdir()
    for seed, name in ((0, "a"), (1, "b"), (2, "c")):
        run = root / f"synth{seed}"
        r = laughlab("input.duration_s=8", f"input.seed={seed}", "input.sample_rate=44100", "detector=none",
                     "~output.plots", f"hydra.run.dir={run}")
        assert r.returncode == 0, r.stderr
        shutil.copy(run / "input.wav", rec / f"{name}.wav")
        if name == "a":
            shutil.copy(run / "truth.csv", rec / "a.truth.csv")
        if name == "b":
            with open(run / "truth.csv", newline="") as fh:
                bouts = [r for r in csv.DictReader(fh) if r["kind"] == "bout"]
            (rec / "b.txt").write_text("".join(f"{b['onset_s']}\t{b['offset_s']}\tlaugh\n" for b in bouts))
    return root, rec


def _bouts(rec, name):
    if name == "a":
        with open(rec / "a.truth.csv", newline="") as fh:
            return [(float(r["onset_s"]), float(r["offset_s"])) for r in csv.DictReader(fh) if r["kind"] == "bout"]
    return [tuple(map(float, line.split("\t")[:2])) for line in (rec / "b.txt").read_text().splitlines()]


def test_the_scores_are_the_frames_bouts_and_segments_counted_by_hand(folder):
    root, rec = folder
    out = root / "out"
    r = laughlab("detect", str(rec), "--out", str(out), "--score", "--threshold", "0.2", "--hop", "0.25")
    assert r.returncode == 0, r.stderr
    with open(out / "segments.csv", newline="") as fh:
        segs = [(row["file"], float(row["start"]), float(row["end"])) for row in csv.DictReader(fh)]
    with open(out / "scores.csv", newline="") as fh:
        rows = {row["file"]: row for row in csv.DictReader(fh)}
    assert list(rows) == ["a", "b", "all"]                       # c has no annotation: not scored
    pooled = np.zeros(3)
    total_bouts = total_found = total_out = 0
    for name in ("a", "b"):
        dur = sf.info(str(rec / f"{name}.wav")).duration
        t = (np.arange(int(np.ceil(dur / 0.01))) + 0.5) * 0.01
        bouts, mine = _bouts(rec, name), [(a, b) for f, a, b in segs if f == name]
        truth = np.any([(t >= a) & (t < b) for a, b in bouts], axis=0)
        det = np.any([(t >= a) & (t < b) for a, b in mine], axis=0) if mine else np.zeros_like(truth)
        tp, fp, fn = int((det & truth).sum()), int((det & ~truth).sum()), int((~det & truth).sum())
        found = sum(any(s < b and e > a for s, e in mine) for a, b in bouts)
        outside = sum(not any(s < b and e > a for a, b in bouts) for s, e in mine)
        row = rows[name]
        assert (int(row["bouts"]), int(row["found"]), int(row["segments_outside"])) == (len(bouts), found, outside)
        if tp + fp:
            assert float(row["precision"]) == pytest.approx(tp / (tp + fp), abs=1e-4)
        assert float(row["recall"]) == pytest.approx(tp / (tp + fn), abs=1e-4)
        pooled += (tp, fp, fn)
        total_bouts, total_found, total_out = total_bouts + len(bouts), total_found + found, total_out + outside
    tp, fp, fn = pooled
    assert float(rows["all"]["f1"]) == pytest.approx(2 * tp / (2 * tp + fp + fn), abs=1e-4)
    assert (int(rows["all"]["bouts"]), int(rows["all"]["found"])) == (total_bouts, total_found)
    assert rows["b"]["annotation"].endswith("b.txt") and rows["a"]["annotation"].endswith("a.truth.csv")
    assert (f"; scored against 2 annotations: {total_found} of {total_bouts} bouts found, frame F1 "
            f"{2 * tp / (2 * tp + fp + fn):.2f} (precision ") in r.stdout
    assert f"{total_out} segment" in r.stdout and ", 1 input without an annotation -> scores.csv" in r.stdout


def test_a_bad_annotation_or_none_at_all_is_one_line_before_any_work(folder, tmp_path):
    _, rec = folder
    bad = tmp_path / "bad"
    shutil.copytree(rec, bad)
    (bad / "b.txt").write_text("1.0\t2.0\tlaugh\n1.5\t3.0\tlaugh\n")             # overlapping bouts
    r = laughlab("detect", str(bad), "--out", str(tmp_path / "o1"), "--score")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "b.txt" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o1").exists()
    for f in bad.glob("*.t*"):
        f.unlink()
    r = laughlab("detect", str(bad), "--out", str(tmp_path / "o2"), "--score")
    assert r.returncode == 2 and r.stderr == ("laughlab: error: --score: no input has an annotation beside it "
                                              "(NAME.truth.csv, NAME.txt, NAME.TextGrid or NAME.eaf next to NAME.wav; "
                                              "docs/detector.md)\n")
    assert not (tmp_path / "o2").exists()


def test_detects_own_labels_in_the_input_folder_are_not_an_annotation(tmp_path):
    """--out the input folder: the NAME.txt an earlier detect wrote beside NAME.wav is its output, not a truth."""
    rec = tmp_path / "rec"
    rec.mkdir()
    sf.write(rec / "x.wav", 0.1 * np.sin(np.arange(32000) / 5), 16000)
    assert laughlab("detect", str(rec), "--out", str(rec), "--formats", "csv,audacity", "--overwrite").returncode == 0
    assert (rec / "x.txt").exists()
    r = laughlab("detect", str(rec), "--out", str(rec), "--formats", "csv,audacity", "--overwrite", "--score")
    assert r.returncode == 2 and "no input has an annotation" in r.stderr


def test_labels_a_detect_wrote_beside_the_recordings_are_not_annotations_of_another_run(tmp_path):
    """A review: detect into the recordings' folder, then detect --score into another --out scored the first run's
    NAME.txt as the recording's annotation (F1 1 against itself)."""
    rec = tmp_path / "rec"
    rec.mkdir()
    sf.write(rec / "x.wav", 0.1 * np.sin(np.arange(32000) / 5), 16000)
    assert laughlab("detect", str(rec), "--out", str(rec), "--formats", "csv,audacity", "--overwrite").returncode == 0
    r = laughlab("detect", str(rec), "--out", str(tmp_path / "o"), "--score")
    assert r.returncode == 2 and "no input has an annotation" in r.stderr
