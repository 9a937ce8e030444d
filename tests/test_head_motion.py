"""Head and eyebrow motion by segment concatenation (Ding et al. 2014, 4.2): the database from the clip
library, the brow rule, the costs, the greedy real-time choice, the joins, and the ``facs`` face's head."""

import numpy as np
import pytest

from laughlab.concat import costs as C
from laughlab.core.bases import Context
from laughlab.core.errors import LaughlabError
from laughlab.core.frame import Frame
from laughlab.concat.head_motion import HEAD_CHANNELS, HeadMotion, HeadMotionParams, build_head_db, head_curves
from laughlab.concat.segments import PSEUDO_PHONEMES, segment_db
from laughlab.motion.skeleton import euler_to_matrix, matrix_to_euler
from laughlab_plugins.face_facs import FacsFace, FacsParams

FPS = 60.0
DT = 1.0 / FPS


@pytest.fixture(scope="module")
def heads(lib):
    return build_head_db(lib)


def test_head_curves_are_neck_times_head_and_the_brow_rule(lib):
    curves = head_curves(lib, brow_full_deg=15.0)
    sk = lib.skeleton
    clip = lib["stop_it"]  # turns and tilts the head
    c = curves["stop_it"]
    assert c.shape == (clip.length_frames, 4)
    k = int(np.argmax(np.abs(c[:, 1])))
    r = euler_to_matrix(clip.poses[k, sk.angle_slice("neck")]) @ euler_to_matrix(clip.poses[k, sk.angle_slice("head")])
    z, x, y = matrix_to_euler(r)
    np.testing.assert_allclose(c[k, :3], [x, y, z], atol=1e-9)  # pitch, yaw, roll
    assert abs(c[k, 1]) > 20  # a real turn
    # brow rule: clip(max(0, -pitch) / 15, 0, 1)
    for pitch, brow in zip(c[:, 0], c[:, 3]):
        assert brow == pytest.approx(min(1.0, max(0.0, -pitch) / 15.0))
    assert curves["rofl"][:, 3].max() == 1.0 and curves["idle"][:, 3].max() < 0.2


def test_database_follows_the_clip_segments(lib, heads):
    db = segment_db(lib)
    assert len(heads.db) == len(db)
    scale = np.array([1.0, 1.0, 1.0, 15.0]) * (100.0 / 10.0)
    for i, (h, s) in enumerate(zip(heads.db, db)):
        assert (h.clip, h.start_s, h.end_s, h.label) == (s.clip, s.start_s, s.end_s, s.label)
        assert heads.times[i][0] == 0.0 and heads.times[i][-1] == pytest.approx(s.duration_s)
        np.testing.assert_allclose(h.first, heads.curves[i][0] * scale)
        np.testing.assert_allclose(h.last, heads.curves[i][-1] * scale)
    # the first sample is the clip at the segment's start
    i = next(i for i, s in enumerate(db) if s.clip == "rofl" and s.start_s > 0)
    curve = head_curves(lib)["rofl"]
    f = db[i].start_s * lib["rofl"].fps
    lo = int(f)
    np.testing.assert_allclose(heads.curves[i][0], curve[lo] + (f - lo) * (curve[lo + 1] - curve[lo]), atol=1e-9)


def test_continuity_cost_is_in_units_of_cont_unit_deg(heads):
    # a 10-degree pitch jump costs 1, 20 degrees cost 4; brows in degrees of brow_full_deg
    a = np.array([0.0, 0.0, 0.0, 0.0]) * 10.0
    b = np.array([10.0, 0.0, 0.0, 0.0]) * 10.0
    assert C.c_cont(a, b) == pytest.approx(1.0)
    assert C.c_cont(a, 2 * b) == pytest.approx(4.0)
    i, j = 3, 17
    want = sum(((heads.curves[i][-1] - heads.curves[j][0]) * [1, 1, 1, 15] / 10.0) ** 2)
    assert C.cont_matrix(heads.db, [i], [j])[0, 0] == pytest.approx(want)


def test_greedy_choice_at_each_label_change(lib, heads):
    p = HeadMotionParams()
    hm = HeadMotion(p, lib)
    labels = ["silence"] * 30 + ["a"] * 25 + ["fricative"] * 20 + ["a"] * 40
    prev = None
    runs = C.label_runs(labels)
    means = {c: heads.db.mean_duration(c) for c in PSEUDO_PHONEMES}
    counts = dict.fromkeys(PSEUDO_PHONEMES, 1)
    for (label, start, n), nxt in zip(runs, runs[1:] + [None]):
        hm.step(start * DT, label)
        want = C.choose(heads.db, label, means[label], p.gamma, prev)
        assert hm.segment == want
        assert hm.speed == pytest.approx(C.stretch(heads.db.durations[want], means[label], p.speed_min, p.speed_max))
        prev = want
        for k in range(start + 1, start + n):
            hm.step(k * DT, label)
            if hm.segment != prev:  # a segment played to its end: chained, same class
                assert hm.segment in heads.db.candidates(label)
                prev = hm.segment
        counts[label] += 1
        means[label] += (n * DT - means[label]) / counts[label]


def test_joins_are_smoothed_linearly(lib):
    labels = (["silence"] * 20 + ["cackle"] * 15 + ["o"] * 15) * 4
    def run(blend):
        hm = HeadMotion(HeadMotionParams(blend_s=blend), lib)
        return np.array([hm.step(k * DT, lab) for k, lab in enumerate(labels)])
    raw, smooth = run(0.0), run(0.15)
    jumps_raw = np.abs(np.diff(raw[:, 0])).max()
    jumps = np.abs(np.diff(smooth[:, 0])).max()
    assert jumps < jumps_raw
    assert np.abs(smooth[0, :3]).max() == 0.0  # the head starts at rest, then fades into the first segment


def test_deterministic_and_label_from_mcs(lib):
    a = HeadMotion(HeadMotionParams(), lib)
    b = HeadMotion(HeadMotionParams(), lib)
    seq = ["silence", "vowel", "a", "silence"] * 30
    assert [a.step(k * DT, s) for k, s in enumerate(seq)] == [b.step(k * DT, s) for k, s in enumerate(seq)]
    assert a.label_of(Frame(control={"mcs": 0.05})) == "silence"
    assert a.label_of(Frame(control={"mcs": 0.5})) == "vowel"
    assert a.label_of(Frame(control={"mcs": 0.5}, label="grunt")) == "grunt"
    with pytest.raises(LaughlabError, match="unknown pseudo-phoneme"):
        a.step(99.0, "laugh")


def test_gain_scales_angles_and_brows(lib):
    seq = ["cackle"] * 60 + ["a"] * 60
    hm = HeadMotion(HeadMotionParams(), lib)
    one = np.array([hm.step(k * DT, s) for k, s in enumerate(seq)])
    hm = HeadMotion(HeadMotionParams(gain=0.5), lib)
    half = np.array([hm.step(k * DT, s) for k, s in enumerate(seq)])
    np.testing.assert_allclose(half[:, :3], 0.5 * one[:, :3], atol=1e-12)
    np.testing.assert_allclose(half[:, 3], 0.5 * one[:, 3], atol=1e-12)


def test_facs_face_writes_the_head_channels_and_offsets(lib):
    ctx = Context(fps=FPS, rng=np.random.default_rng(0))
    ctx._clips = lib
    f = FacsFace(FacsParams(asymmetry=0.0, desync_s=0.0), ctx)
    hm = HeadMotion(HeadMotionParams(), lib)
    pitches = []
    for k in range(240):
        label = "cackle" if (k // 20) % 2 else "silence"
        fr = Frame(k, k * DT, DT, {"mcs": 0.8}, label)
        f.step(fr)
        want = hm.step(k * DT, label)
        got = tuple(fr.channels[c] for c in HEAD_CHANNELS)
        assert got == want
        assert fr.offsets["head"] == (want[2], want[0], want[1])  # (z, x, y) = (roll, pitch, yaw)
        assert fr.channels["arkit.browInnerUp"] == pytest.approx(min(1.0, want[3]))
        pitches.append(want[0])
    assert np.ptp(pitches) > 2.0  # the head moves
    f = FacsFace(FacsParams(head=HeadMotionParams(enabled=False)), ctx)
    fr = Frame(0, 0.0, DT, {"mcs": 0.8}, "a")
    f.step(fr)
    assert "head" not in fr.offsets and all(fr.channels[c] == 0.0 for c in HEAD_CHANNELS)


def test_params_validated():
    with pytest.raises(ValueError, match="gamma"):
        HeadMotionParams(gamma=1.5)
    with pytest.raises(ValueError, match="speed_max"):
        HeadMotionParams(speed_min=2.0, speed_max=1.0)
    with pytest.raises(ValueError, match="brow_full_deg"):
        HeadMotionParams(brow_full_deg=0.0)
