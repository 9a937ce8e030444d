"""The video's framing (laughlab/render/framing.py): the whole character stays inside the frame.

The media review of 2026-11-27 found a raised arm cut by the frame's top in the stimuli's laugh_energy videos
(benchmarks/bench_framing.py counts them: 16 of 960 frames at the top, 17 at the left, before).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from laughlab.motion.skeleton import HUMANOID, rest_pose
from laughlab.render.character_view import CharacterRenderer, background
from laughlab.render.framing import Framing
from laughlab.render.scene import Camera

ASSETS = Path(__file__).parent / "assets" / "avatars"


def raise_arm(n: int = 40) -> np.ndarray:
    """``n`` poses: the left arm rises from the T-pose to straight up over 10 frames, held, then back down."""
    poses = np.repeat(rest_pose()[None], n, axis=0)
    up = np.clip(np.minimum(np.arange(n) - 8, n - 6 - np.arange(n)) / 10.0, 0.0, 1.0)
    poses[:, 3 + 3 * HUMANOID.index("left_upper_arm")] = 90.0 * up   # channel 0 at 90 degrees: the hand overhead
    return poses


def edges_are_background(img: np.ndarray, bg: np.ndarray, k: int = 2) -> bool:
    """The top ``k`` rows and the ``k`` columns at either side show only the backdrop (the bottom cuts the body)."""
    diff = np.abs(img.astype(int) - bg.astype(int)).sum(axis=2) > 24
    return not (diff[:k].any() or diff[:, :k].any() or diff[:, -k:].any())


def test_a_raised_arm_stays_inside_the_frame_with_a_margin():
    """Before, the camera kept its distance and the raised hand left the frame by the top edge."""
    poses = raise_arm()
    r = CharacterRenderer(HUMANOID, 160, 120, supersample=1)
    w = np.zeros((len(poses), r.morphs.shape[0]))
    frames = r.render_many(poses[:25], w[:25]) + r.render_many(poses[25:], w[25:])
    frames += r.flush() if hasattr(r, "flush") else []
    bg = np.clip(background(120, 160) + 0.5, 0, 255).astype(np.uint8)
    assert len(frames) == len(poses)
    cut = [i for i, f in enumerate(frames) if not edges_are_background(f, bg)]
    assert not cut, f"the character reaches an edge in frames {cut}"


def test_the_distance_is_never_short_of_a_frames_need_moves_smoothly_and_is_exact_elsewhere():
    needs = np.full(300, 170.0)
    needs[[60, 64, 200]] = (230.0, 250.0, 200.0)                # a raise (two frames close together), another
    f = Framing(Camera(distance_cm=170.0, fov_deg=30.0), 640, 480)
    out = [job for i, need in enumerate(needs) for job in f.push(i, need)]
    assert len(out) == 300 - f.hold - 2 * f.smooth              # the look-ahead holds the last frames
    out += f.flush()
    order, dist = zip(*out)
    dist = np.array(dist)
    assert list(order) == list(range(300)) and np.all(dist >= needs)
    assert np.abs(np.diff(dist)).max() <= 80.0 / 8              # a ramp over more than 8 frames, no jump
    assert np.all(dist[60:65] == dist[60])                      # two raises 4 frames apart: one zoom, held
    far = np.ones(300, bool)
    for k in (60, 64, 200):
        far[max(0, k - 40): k + 41] = False
    assert far.sum() > 100 and np.all(dist[far] == 170.0)      # far from any need: exactly the configured distance


@pytest.mark.parametrize("name", ["Godette_vrm_v4.vrm"])
def test_the_avatars_raised_arm_stays_inside_the_frame(name):
    from laughlab.avatar.load import load_avatar
    from laughlab.render.avatar_view import AvatarRenderer

    poses = raise_arm()
    r = AvatarRenderer(load_avatar(ASSETS / name), HUMANOID, 160, 120, supersample=1)
    frames = r.render_many(r.worlds(poses), [{}] * len(poses))
    frames += r.flush() if hasattr(r, "flush") else []
    bg = np.clip(background(120, 160) + 0.5, 0, 255).astype(np.uint8)
    assert len(frames) == len(poses)
    cut = [i for i, f in enumerate(frames) if not edges_are_background(f, bg)]
    assert not cut, f"the avatar reaches an edge in frames {cut}"


def test_a_stimulus_framed_otherwise_is_rendered_again(tmp_path, monkeypatch):
    """experiment=stimuli keeps a video whose render key is unchanged: the key names the framing, so stimuli
    rendered before the look-ahead framing (a hand cut by the top) are not kept beside the new ones."""
    import laughlab_experiments.stimuli as stimuli
    from laughlab.render import framing

    wav = tmp_path / "a.wav"
    wav.write_bytes(b"RIFF")
    spec = {"audio_path": str(wav), "fps": 30.0}
    key = stimuli.render_key(["scheduler=energy"], spec, False)
    assert stimuli.render_key(["scheduler=energy"], spec, False) == key
    monkeypatch.setattr(framing, "VERSION", "another")
    assert stimuli.render_key(["scheduler=energy"], spec, False) != key


def _rows_drawn(frame: np.ndarray, bg: np.ndarray) -> np.ndarray:
    return np.flatnonzero((np.abs(frame.astype(int) - bg.astype(int)).sum(axis=2) > 24).any(axis=1))


@pytest.mark.parametrize("who", ["mannequin", "Godette_vrm_v4.vrm"])
def test_the_body_framing_keeps_the_feet_in_the_frame_as_well(who):
    """output.video.framing=body (an avatar developer's review: a full-body laugh lost its shins): every edge shows
    only the backdrop, the bottom too, and the character fills most of the height (it is not a speck far away);
    the upper framing cuts the body at the bottom edge, as documented."""
    from laughlab.avatar.load import load_avatar
    from laughlab.render.avatar_view import AvatarRenderer

    poses = raise_arm()
    bg = np.clip(background(120, 160) + 0.5, 0, 255).astype(np.uint8)
    shown = {}
    for framing in ("upper", "body"):
        if who == "mannequin":
            r = CharacterRenderer(HUMANOID, 160, 120, supersample=1, framing=framing)
            frames = r.render_many(poses, np.zeros((len(poses), r.morphs.shape[0]))) + r.flush()
        else:
            r = AvatarRenderer(load_avatar(ASSETS / who), HUMANOID, 160, 120, supersample=1, framing=framing)
            frames = r.render_many(r.worlds(poses), [{}] * len(poses)) + r.flush()
        assert len(frames) == len(poses)
        shown[framing] = frames
    cut = [i for i, f in enumerate(shown["body"]) if not edges_are_background(f, bg)
           or _rows_drawn(f, bg).max() >= 120 - 2]
    assert not cut, f"the whole {who} leaves the frame in frames {cut}"
    still = r.render(rest_pose(), np.zeros(r.morphs.shape[0])) if who == "mannequin" else r.render(rest_pose(), {})
    rows = _rows_drawn(still, bg)                                # the rest pose alone (no raise ahead to make room)
    assert rows.max() - rows.min() > 0.75 * 120 and rows.max() < 120 - 2
    assert all(_rows_drawn(f, bg).max() == 119 for f in shown["upper"])   # the upper framing: the legs cut
