"""laughlab.face.provisional: a face's slow states taken back when detector=yamnet rejects the face's provisional
answer to a sound (a review: the smile stayed above 0.5 through 99% of a minute of speech)."""
import numpy as np
import pandas as pd
import pytest
import soundfile as sf
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core.config import compose_config
from laughlab.face.provisional import Retraction


class State:
    def __init__(self, v=0.0):
        self.v = v


def frames(ctrl, states, back, push):
    """Run ``back`` over control dicts; ``push(k)`` is the face's own step (it may move the states)."""
    out = []
    for k, c in enumerate(ctrl):
        back.begin(c)
        push(k)
        back.clamp()
        out.append([s.v for s in states])
    return np.array(out)


def test_by_hand_a_rejected_answer_comes_down_linearly_to_where_it_began():
    s = State(0.1)
    back = Retraction([(s, "v")], retract_s=0.05, dt=0.01)        # 5 frames
    ctrl = [{}] + [{"face_provisional": 1.0}] * 3 + [{"face_retract": 1.0}] + [{}] * 6
    rises = {1: 0.5, 2: 0.7, 3: 0.9}                                  # what the face builds while it answers

    def push(k):
        s.v = rises.get(k, s.v)
    got = frames(ctrl, [s], back, push)[:, 0]
    # snapshot 0.1 on the answer's first frame (before its step); taken back from 0.9: 0.9 - 0.8 * j / 5
    assert got == pytest.approx([0.1, 0.5, 0.7, 0.9, 0.74, 0.58, 0.42, 0.26, 0.1, 0.1, 0.1])


def test_a_confirmed_answer_is_kept_and_a_state_already_lower_is_left():
    s, t = State(0.2), State(0.6)
    back = Retraction([(s, "v"), (t, "v")], retract_s=0.02, dt=0.01)
    ctrl = [{"face_provisional": 1.0}, {"face_provisional": 1.0}, {}, {}]   # confirmed: no face_retract

    def push(k):
        s.v, t.v = s.v + 0.2, t.v - 0.1
    got = frames(ctrl, [s, t], back, push)
    assert got[:, 0] == pytest.approx([0.4, 0.6, 0.8, 1.0]) and got[:, 1] == pytest.approx([0.5, 0.4, 0.3, 0.2])
    s.v, t.v = 0.2, 0.6                                              # rejected now: t fell below its snapshot
    back.reset()
    ctrl = [{"face_provisional": 1.0}, {"face_retract": 1.0}, {}, {}]
    got = frames(ctrl, [s, t], back, push)
    assert got[:, 1] == pytest.approx([0.5, 0.4, 0.3, 0.2])          # never raised to its snapshot
    assert got[:, 0] == pytest.approx([0.4, 0.3, 0.2, 0.4])          # ceiling 0.4 -> 0.3 -> 0.2 (2 frames), then free


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.booleans(), st.floats(-0.3, 0.3)), min_size=1, max_size=80),
       st.floats(0.0, 0.5))
def test_taking_back_never_raises_a_state_nor_holds_it_below_its_snapshot(events, retract_s):
    """Over any sequence of answers, rejections and face steps: the clamp only lowers a state, never below the
    snapshot of the answer it takes back."""
    s = State(0.3)
    back = Retraction([(s, "v")], retract_s, 1 / 60)
    base = None
    for provisional, retract, delta in events:
        c = {"face_provisional": float(provisional), "face_retract": float(retract)}
        if provisional and not back.was:
            base = s.v
        back.begin(c)
        s.v = max(0.0, s.v + delta)
        before = s.v
        back.clamp()
        assert s.v <= before
        if s.v < before:
            assert base is not None and s.v >= base - 1e-12


def run(tmp_path, *overrides):
    cfg = compose_config(["~output.plots", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k not in ("hydra", "harness")])
    pipeline.execute(pipeline.build(cfg), tmp_path)
    return pd.read_csv(tmp_path / "channels.csv")


@pytest.mark.parametrize("face", ["smile", "facs"])
def test_without_a_detector_nothing_changes(tmp_path, face):
    """detector=none (the papers): no provisional answers, the same bytes whatever retract_s."""
    a = run(tmp_path / "a", f"face={face}", "detector=none", "input.duration_s=6")
    b = run(tmp_path / "b", f"face={face}", "detector=none", "input.duration_s=6", "face.retract_s=null")
    pd.testing.assert_frame_equal(a, b)


@pytest.mark.parametrize("face", ["smile", "facs"])
def test_on_real_speech_the_smile_lets_go(tmp_path, face):
    """Held-out speech of the corpus at 44.1 kHz (20 s of short game-voice utterances, British and Russian voices):
    the smile above 0.5 far less of the time than when every provisional answer is kept."""
    from laughlab.corpora import fetch

    lock = fetch.require(kinds=["speech"])
    ids = [i for i in sorted(lock) if i.startswith(("hedgewars/British-", "hedgewars/Russian-"))
           and sf.info(lock[i]).samplerate == 44100][:16]
    parts, gaps_end, n = [], [], 0
    for i in ids:
        x, sr = sf.read(lock[i], always_2d=True)
        parts += [x.mean(axis=1), np.zeros(int(0.4 * sr))]
        n += len(x) + int(0.4 * sr)
        gaps_end.append(n / sr)          # the end of the silence after each utterance
    sf.write(tmp_path / "talk.wav", np.concatenate(parts), sr)
    kept = run(tmp_path / "kept", "input=file", f"input.path={tmp_path / 'talk.wav'}", f"face={face}",
               "face.retract_s=null")
    back = run(tmp_path / "back", "input=file", f"input.path={tmp_path / 'talk.wav'}", f"face={face}")
    assert back["face_retract"].sum() >= 3                          # the model took answers back
    over_kept, over_back = (kept["smile"] > 0.5).mean(), (back["smile"] > 0.5).mean()
    assert over_kept > 0.6 and over_back < 0.7 * over_kept, (over_kept, over_back)
    # what each utterance built is gone before the next one starts (kept, it carries over)
    def at_gap_ends(ch):
        return np.interp(np.array(gaps_end[:-1]) - 0.02, ch["time"], ch["smile"])
    # (7 of 15 on 2026-11-27; the others follow utterances the model heard as laughter: Drat, Fire, Flawless...)
    assert (at_gap_ends(kept) < 0.1).sum() == 0 and (at_gap_ends(back) < 0.1).sum() >= 5, (
        at_gap_ends(kept), at_gap_ends(back))
    # frames before the first answer taken back are the same
    first = int(np.argmax(back["face_retract"].to_numpy() > 0))
    pd.testing.assert_frame_equal(kept.iloc[:first], back.iloc[:first])
