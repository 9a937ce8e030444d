"""Hand-edited CSV answers for ``study analyze`` (laughlab.study.answers): every row is checked against the
design, and the first that does not fit is one line naming the file, its line and the column (a review: a 55
on a 1..7 scale turned a mean of 4 into 10.25, a typo in a condition or question made a new one, "5a" or a
misspelt kind was dropped in silence, and "1x" as a participant gave a pandas traceback)."""
import csv
import json

import pytest

import fuzz

CONDITIONS = ["smile_only", "laugh_energy"]
COLUMNS = ["participant", "order_row", "trial", "stimulus", "condition", "audio_id", "kind", "question", "value",
           "text", "expected"]


def small_design(conditions=tuple(CONDITIONS), same: str = "") -> dict:
    """2 conditions x 2 audio items, 3 participants rating all 4 videos, one question on 7 points, an attention
    item (answer 2) in trial 2, the audio check.  ``same``: a condition whose videos are those of the first."""
    conditions = list(conditions)
    stimuli = {f"{c}-{a}": {"file": f"stimuli/{c}-{a}.mp4", "condition": c, "audio_id": a, "duration_s": 1.0,
                            "sha256": f"{conditions[0] if c == same else c}{a}"} for c in conditions for a in ("x", "y")}
    participants = {str(p): {"order_row": (p - 1) % 2, "audio_check": 0, "trials": [
        {"trial": k + 1, "stimulus": s, "condition": stimuli[s]["condition"], "audio_id": stimuli[s]["audio_id"],
         "file": stimuli[s]["file"], "attention": k == 1} for k, s in enumerate(sorted(stimuli))]}
        for p in (1, 2, 3)}
    return {"id": "test", "conditions": conditions, "scale": "likert", "points": 7,
            "slider": {"min": 0, "max": 100, "step": 1},
            "questions": [{"id": "naturalness", "prompt": "How natural?", "labels": ["no", "yes"]}],
            "attention": {"count": 1, "value": 2}, "exclusions": {"audio_check": True, "attention_max_fail": 0,
                                                                 "straightline": True},
            "stimuli": stimuli, "participants": participants}


@pytest.fixture
def answers(tmp_path):
    return write_answers(tmp_path, small_design())


def write_answers(tmp_path, d: dict, item_shift: dict | None = None):
    """A study folder holding only design.json, and a folder of 3 participants' answer files: laugh_energy
    rated 5, the other conditions 3, plus the participant's number modulo 2 (so no one straight-lines)."""
    study = tmp_path / "study"
    study.mkdir(parents=True)
    (study / "design.json").write_text(json.dumps(d))
    folder = tmp_path / "answers"
    folder.mkdir()
    for p, entry in d["participants"].items():
        rows = [[p, entry["order_row"], 0, "", "", "", "audio_check", "audio_check", 1, "hat", ""]]
        for t in entry["trials"]:
            v = (5 if t["condition"] == "laugh_energy" else 3) + int(p) % 2 + (item_shift or {}).get(t["audio_id"], 0)
            rows.append([p, entry["order_row"], t["trial"], t["stimulus"], t["condition"], t["audio_id"], "rating",
                         "naturalness", v, "", ""])
            if t["attention"]:
                rows.append([p, entry["order_row"], t["trial"], t["stimulus"], t["condition"], t["audio_id"],
                             "attention", "attention", 2, "", 2])
        with open(folder / f"participant_{int(p):03d}_answers.csv", "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(COLUMNS)
            w.writerows(rows)
    return study, folder


def edit(folder, line: int, column: str, value: str):
    """Set one cell of participant 1's file (``line`` as an editor counts: the header is line 1)."""
    f = folder / "participant_001_answers.csv"
    rows = list(csv.reader(f.open(newline="")))
    rows[line - 1][COLUMNS.index(column)] = value
    with open(f, "w", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
    return f


@pytest.mark.parametrize("line, column, value, why", [
    (3, "value", "55", "'55' is not on the scale (a whole point 1..7)"),
    (3, "value", "2.5", "'2.5' is not on the scale (a whole point 1..7)"),
    (3, "value", "0", "'0' is not on the scale (a whole point 1..7)"),
    (3, "value", "5a", "'5a' is not a number"),
    (3, "value", "", "'' is not a number"),
    (3, "condition", "smile_onyl", "'smile_onyl' is not a condition of the design (smile_only, laugh_energy)"),
    (3, "condition", "smile_only", "'smile_only': the stimulus laugh_energy-x is of the condition laugh_energy"),
    (3, "question", "naturalnes", "'naturalnes' is not a question of the design (naturalness)"),
    (3, "kind", "ratng", "'ratng' is not one of rating, attention, audio_check"),
    (3, "participant", "1x", "'1x' is not a whole number"),
    (3, "participant", "9", "participant 9 is not in the design (1..3)"),
    (3, "stimulus", "laugh_energy-y", "'laugh_energy-y': trial 1 of participant 1 shows laugh_energy-x"),
    (3, "trial", "7", "participant 1 has no trial 7 (1..4)"),
    (2, "value", "0.5", "'0.5': the audio check is 0 (failed) or 1 (passed)"),
    (5, "expected", "two", "'two' is not a number"),   # the attention row of trial 2
])
def test_a_row_that_does_not_fit_the_design_is_one_line_naming_file_line_and_column(answers, tmp_path, line, column,
                                                                                     value, why):
    study, folder = answers
    f = edit(folder, line, column, value)
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")])
    assert out.code == 2, out
    assert out.stderr == f"laughlab: error: {f}, line {line}, column {column}: {why}\n", out.stderr
    assert not (tmp_path / "rep").exists()


def test_good_answers_are_all_read_and_a_repeated_file_once(answers, tmp_path):
    """Means by hand: laugh_energy 5 + p % 2 over participants 1..3 is (6 + 5 + 6) / 3; each of 3 participants
    gave 2 ratings per condition.  A participant's file downloaded twice counts once; two different values for
    one answer are refused, naming both places."""
    study, folder = answers
    (folder / "participant_001_again.csv").write_bytes((folder / "participant_001_answers.csv").read_bytes())
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")])
    assert out.code == 0, out.stderr
    with open(tmp_path / "rep" / "means.csv") as f:
        means = {r["condition"]: r for r in csv.DictReader(f)}
    assert float(means["laugh_energy"]["mean"]) == pytest.approx(17 / 3, abs=1e-4)
    assert float(means["smile_only"]["mean"]) == pytest.approx(11 / 3, abs=1e-4)
    assert {r["n_ratings"] for r in means.values()} == {"6"} and set(means) == set(CONDITIONS)
    edit(folder, 3, "value", "7")
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep2")])
    assert out.code == 2 and out.stderr.count("\n") == 1, out.stderr
    assert (f"participant_001_answers.csv, line 3: participant 1 trial 1 naturalness is answered 7 here and 6 at "
            f"{folder / 'participant_001_again.csv'}, line 3; keep one") in out.stderr


def test_without_a_design_the_kinds_and_numbers_are_still_checked(answers, tmp_path):
    study, folder = answers
    f = edit(folder, 3, "kind", "")
    out = fuzz.run_cli(["study", "analyze", str(folder), "--out", str(tmp_path / "rep")])
    assert out.code == 2 and out.stderr == (f"laughlab: error: {f}, line 3, column kind: '' is not one of rating, "
                                            "attention, audio_check\n"), out.stderr


def test_conditions_showing_the_same_videos_are_not_tested(tmp_path):
    """A review: the riddle preset's SS and LS (SL and LL) are the same video byte for byte and the page does not
    show the role, yet the report tested SS - LS as a condition effect.  Here smile_copy shows smile_only's
    videos: of the 3 pairs only the 2 with laugh_energy are tested (Holm over those 2), the README says which
    pair is not, and study power refuses it."""
    from laughlab.study.design import identical_conditions

    d = small_design(("smile_only", "laugh_energy", "smile_copy"), same="smile_copy")
    assert identical_conditions(d) == [("smile_only", "smile_copy")]
    assert identical_conditions(small_design()) == []
    study, folder = write_answers(tmp_path, d)
    out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")])
    assert out.code == 0, out.stderr
    with open(tmp_path / "rep" / "contrasts.csv") as f:
        pairs = [(r["a"], r["b"]) for r in csv.DictReader(f)]
    assert sorted(pairs) == [("laugh_energy", "smile_copy"), ("smile_only", "laugh_energy")]
    assert "Not tested: smile_only - smile_copy. Each pair's conditions show the same videos" in \
        (tmp_path / "rep" / "README.md").read_text()
    out = fuzz.run_cli(["study", "power", str(study), "--contrast", "smile_copy:smile_only", "--effect", "1"])
    assert out.code == 2 and "smile_copy and smile_only show the same videos" in out.stderr, out.stderr


def test_the_report_warns_when_few_stimuli_vary():
    """A review: with 4 stimuli per condition and a stimulus variance of 0.5 (of 2.58) the Wald tests' familywise
    error was 0.095 at a nominal 0.05, and the report said nothing.  By hand: 0.5 / (0.64 + 0.5 + 1.44) = 19 %.
    A statistician's review: with the default 4 stimuli and an estimate under 5 % of the total the note was left out
    (19 of 20 false positives came without it); now every question under 10 stimuli per condition has it."""
    from laughlab.study.analyze import TYPE1, few_stimuli_note

    var = {"participant": 0.64, "stimulus": 0.5, "residual": 1.44}
    note = few_stimuli_note(var, 4)
    assert note.startswith("Only 4 stimuli per condition, and they vary (stimulus variance 0.5, 19% of the total): "
                           "the Wald tests below take that variance as known, so their p values are too small")
    assert TYPE1 in note and "benchmarks/bench_study_type1.py" in note
    assert few_stimuli_note(var, 10) == ""
    for small in (0.09, 1e-9, 0.0):   # 4 % of the total, or estimated at 0: too few stimuli to take it as not varying
        assert few_stimuli_note({**var, "stimulus": small}, 4).startswith(
            f"Only 4 stimuli per condition, too few to tell how much stimuli vary (the estimate, {small:.3g}, rests on "
            "them): the Wald tests")
    assert few_stimuli_note({**var, "stimulus": 1e-9}, 2).startswith("Only 2 stimuli per condition, too few to tell")


def test_the_report_cautions_with_few_participants():
    """A user-study review: 4 simulated participants' report called its Wald tests valid."""
    from laughlab.study.analyze import FEW_PARTICIPANTS, few_participants_note

    assert few_participants_note(FEW_PARTICIPANTS) == ""
    assert few_participants_note(4) == ("Only 4 participants: the Wald z tests below take the estimated variances as "
                                        "known, which with so few makes their p values too small; read them as a "
                                        "pilot's.")


def test_the_warning_reaches_the_readme(tmp_path):
    """Item x rated 3 points above item y (x +1, y -2) in every condition: a large stimulus variance with 2 stimuli per
    condition, so the README warns; without the shift it does not."""
    for shift, warned in (({"x": 1, "y": -2}, True), ({}, False)):
        study, folder = write_answers(tmp_path / str(warned), small_design(), shift)
        out = fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study)])
        assert out.code == 0, out.stderr
        text = (folder.with_name("answers-report") / "README.md").read_text()
        assert ("Only 2 stimuli per condition, and they vary" in text) == warned, text


def test_figures_are_also_pdf_the_same_bytes_again_and_an_interval_past_the_scale_is_marked(answers, tmp_path):
    """A review: 110-dpi PNGs only, and an interval past the axis's end cut off without a mark.  By hand: on the
    Likert axis 0.6..7.4 an interval [3.9, 7.8] passes the top at 7.8, [0.2, 2] the bottom at 0.2."""
    from PIL import Image

    from laughlab.study.plots import off_axis

    assert off_axis([3.9, 0.2, 2.0, float("nan")], [7.8, 2.0, 7.4, float("nan")], (0.6, 7.4)) == [(0, 7.8, 1),
                                                                                                   (1, 0.2, -1)]
    study, folder = answers
    for out in ("a", "b"):
        assert fuzz.run_cli(["study", "analyze", str(folder), "--design", str(study), "--out",
                             str(tmp_path / out)]).code == 0
    for name in ("fig_means", "fig_participants"):
        pdf = (tmp_path / "a" / f"{name}.pdf").read_bytes()
        assert pdf.startswith(b"%PDF") and pdf == (tmp_path / "b" / f"{name}.pdf").read_bytes()
        assert (tmp_path / "a" / f"{name}.png").read_bytes() == (tmp_path / "b" / f"{name}.png").read_bytes()
        assert round(Image.open(tmp_path / "a" / f"{name}.png").info["dpi"][0]) == 300


def test_a_second_analyze_keeps_what_the_researcher_changed_unless_told(answers, tmp_path):
    """A review: notes added to the report's README were deleted without a word by the next study analyze."""
    study, folder = answers
    args = ["study", "analyze", str(folder), "--design", str(study), "--out", str(tmp_path / "rep")]
    assert fuzz.run_cli(args).code == 0
    assert fuzz.run_cli(args).code == 0   # nothing changed: the earlier report is replaced
    readme = tmp_path / "rep" / "README.md"
    readme.write_text(readme.read_text() + "MY NOTES: participant 3 said the audio was choppy\n")
    (tmp_path / "rep" / "notes.txt").write_text("mine")
    out = fuzz.run_cli(args)
    assert out.code == 2 and out.stderr.count("\n") == 1, out.stderr
    assert ("holds files changed since it was written: README.md; not a study report's: notes.txt; choose another "
            "--out, or add --overwrite") in out.stderr
    assert "MY NOTES" in readme.read_text()
    out = fuzz.run_cli(args + ["--overwrite"])
    assert out.code == 0, out.stderr
    assert "MY NOTES" not in readme.read_text() and (tmp_path / "rep" / "notes.txt").read_text() == "mine"
    assert "notes.txt" not in out.stdout   # the command names the report's files, not the researcher's


def test_power_tests_the_family_analyze_tests():
    """A diff review: analyze left the same-video pairs out of Holm's family but power adjusted over every pair, so
    its power was too low (a Holm p of 0.89 where analyze's was 0.45).  On one simulated data set: Holm's p of the
    tested pair is by hand min(1, 2 p) among 2 pairs (3 p among 3), and power's ``detected`` counts it at an alpha
    between the two exactly when it is given the pairs analyze leaves out."""
    import numpy as np

    from laughlab.study.analyze import contrasts, fit_model
    from laughlab.study.power import detected, simulate

    conds = ["smile_only", "laugh_energy", "smile_copy"]
    same = [("smile_only", "smile_copy")]
    trials = [[(c, a) for c in conds for a in ("x", "y", "z")] for _ in range(16)]
    df = simulate(trials, {"laugh_energy": 0.45}, {"participant": 0.3, "residual": 1.0}, 4.0,
                  np.random.default_rng(5))
    fit, ref, _ = fit_model(df, conds)

    def holm(pairs):
        c = contrasts(fit, ref, conds, pairs)
        pair = {"smile_only", "laugh_energy"}
        row = next(r for _, r in c.iterrows() if {r["a"], r["b"]} == pair)
        return float(row["p"]), float(row["p_holm"]), len(c)

    p2, holm2, n2 = holm(same)
    p3, holm3, n3 = holm(())
    assert (n2, n3) == (2, 3) and p2 == p3
    ps2 = sorted(contrasts(fit, ref, conds, same)["p"])
    assert holm2 == pytest.approx(min(1.0, 2 * p2) if p2 == ps2[0] else max(min(1.0, 2 * ps2[0]), p2))
    assert holm3 > holm2
    alpha = (holm2 + holm3) / 2
    assert detected(df, conds, "laugh_energy", "smile_only", alpha, 0.45, same)
    assert not detected(df, conds, "laugh_energy", "smile_only", alpha, 0.45)


def test_the_included_per_order_row_are_counted():
    """A statistician's review: excluding two of a Latin-square row's three participants moved the contrasts by 0.1
    (no order term in the model) and nothing showed it.  By hand: rows 0 (participants 1, 5, 9), 1 (2, 6) and 2 (3);
    5 and 9 excluded."""
    import pandas as pd

    from laughlab.study.participation import order_rows

    df = pd.DataFrame({"participant": [1, 1, 5, 9, 2, 6, 3], "order_row": [0, 0, 0, 0, 1, 1, 2]})
    assert order_rows(df, {5: ["x"], 9: ["y"]}) == {0: [1, 3], 1: [2, 2], 2: [1, 1]}


def test_a_stimulus_variance_at_zero_is_not_called_harmless():
    """The fit note said a stimulus variance at zero 'leaves the tests as they are': then they count the stimuli as
    not varying, liberal with few of them (a statistician's review)."""
    from types import SimpleNamespace

    import numpy as np

    from laughlab.study.analyze import fit_note

    fit = SimpleNamespace(converged=True, bse_fe=np.array([0.2, 0.3]), vcomp=np.array([0.6, 1e-12]), scale=1.4,
                          model=SimpleNamespace(exog_vc=SimpleNamespace(names=["participant", "stimulus"])))
    assert fit_note(fit, ["The MLE may be on the boundary of the parameter space."]) == (
        "The fit converged; the stimulus variance is at or near zero (stimuli differ no more than the rating noise, so "
        "the model is in effect one without that random intercept), so the tests below count the stimuli as not "
        "varying: with few stimuli per condition they are then liberal (below).")


def test_power_says_when_the_effect_nears_the_scales_end():
    """A statistician's review: study power accepted base + effect at the scale's very end and reported power 'for
    effect 1' while the ratings, cut at 7, carried about 0.63 of it."""
    from laughlab.study.power import near_end_note

    assert near_end_note(1.0, 4.0, (1, 7)) == ""                        # 5: two points from the end
    assert near_end_note(1.0, 6.0, (1, 7)).startswith(
        "power: note: the base rating 6 and the effect +1 reach 7, within a point of the scale's end (7)")
    assert "(1)" in near_end_note(-2.5, 4.0, (1, 7))                   # 1.5: near the bottom
    assert near_end_note(1.0, 6.0, None) == ""


def test_means_near_the_scales_end_are_said():
    """A statistician's review: near an end the scale compresses differences; the report said nothing of it."""
    from laughlab.study.analyze import near_end

    means = [{"question": "naturalness", "condition": "a", "mean": 4.0},
             {"question": "naturalness", "condition": "b", "mean": 6.25}]
    assert near_end(means, [1.0, 7.0]) == ("Within a point of the scale's end (1..7): naturalness b 6.25. Ratings "
                                           "cannot pass the end, so differences involving these means show smaller "
                                           "than they are.")
    assert near_end(means[:1], [1.0, 7.0]) == "" and near_end(means, None) == ""
