"""The ``video`` sink: MP4 (H.264 yuv420p, CFR, AAC) of the character, decoded back with ffmpeg."""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from laughlab.core import pipeline
from laughlab.core import plugins
from laughlab.core.bases import Chunk, Context, RunInfo
from laughlab.core.config import compose_config
from laughlab.core.errors import LaughlabError
from laughlab.io.video import decode_audio, decode_frames, probe
from laughlab.render.scene import Camera, Renderer
from laughlab.motion.skeleton import HUMANOID, rest_pose
from laughlab_plugins import sink_video
from laughlab_plugins.sink_video import VideoParams, VideoSink

W, H = 160, 120


@pytest.fixture(scope="module", autouse=True)
def registered():
    """Register the sink unless its entry point already did."""
    mine = not plugins.pm.is_registered(sink_video) and "video" not in plugins.registry()["sink"]
    if mine:
        plugins.pm.register(sink_video, name="test-sink-video")
    yield
    if mine:
        plugins.pm.unregister(sink_video)


def run_pipeline(out: Path, *overrides: str, video: dict | None = None, fail_after: int | None = None) -> dict:
    cfg = compose_config(["input.duration_s=2.0", *overrides])
    cfg = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    OmegaConf.set_struct(cfg, False)
    cfg.output = OmegaConf.create({"video": {"width": W, "height": H, "supersample": 1, **(video or {})}})
    out.mkdir(parents=True, exist_ok=True)
    pipe = pipeline.build(cfg)
    if fail_after is not None:
        step, n = pipe.face.step, [0]

        def failing(frame):
            n[0] += 1
            if n[0] > fail_after:
                raise RuntimeError("boom")
            step(frame)

        pipe.face.step = failing
    return pipeline.execute(pipe, out, {})


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_mp4_streams_duration_and_frames(tmp_path):
    run_pipeline(tmp_path, "fps=60")
    mp4 = tmp_path / "video.mp4"
    info = probe(mp4)
    assert info["video"] == {"codec": "h264", "pix_fmt": "yuv420p", "width": W, "height": H, "fps": 30.0}
    assert info["audio"]["codec"] == "aac"
    assert info["duration_s"] == pytest.approx(2.0, abs=0.05)
    frames = decode_frames(mp4, W, H)
    assert len(frames) == 60  # 2 s at 30 fps: every second of the 120 animation frames
    audio = decode_audio(mp4)
    assert len(audio) / 48000 == pytest.approx(2.0, abs=0.03)
    assert np.abs(audio).max() > 0.01  # the laughter is there
    assert not list(tmp_path.glob(".*.part"))


def test_audio_is_in_sync_with_the_input(tmp_path):
    """The muxed audio starts at time 0: its envelope matches the input's without a lag."""
    import soundfile as sf

    run_pipeline(tmp_path, "input.save_audio=true")
    x, sr = sf.read(tmp_path / "input.wav")
    y = decode_audio(tmp_path / "video.mp4", sr)
    hop = sr // 100  # 10 ms envelopes
    n = min(len(x), len(y)) // hop
    ex = np.abs(x[:n * hop]).reshape(n, hop).mean(1)
    ey = np.abs(y[:n * hop]).reshape(n, hop).mean(1)
    lags = range(-5, 6)
    corr = [np.corrcoef(ex[max(0, -k):n - max(0, k)], ey[max(0, k):n - max(0, -k)])[0, 1] for k in lags]
    assert list(lags)[int(np.argmax(corr))] == 0
    assert max(corr) > 0.9


def test_same_seed_same_bytes(tmp_path):
    run_pipeline(tmp_path / "a", "seed=3")
    run_pipeline(tmp_path / "b", "seed=3")
    assert sha(tmp_path / "a" / "video.mp4") == sha(tmp_path / "b" / "video.mp4")


def test_failed_run_leaves_no_partial_mp4(tmp_path):
    with pytest.raises(RuntimeError, match="boom"):
        run_pipeline(tmp_path, "input.duration_s=6", video={"fps": None}, fail_after=300)  # after a chunk was encoded
    assert not list(tmp_path.glob("*.mp4")) and not list(tmp_path.glob(".*"))


def _decode_as(path: Path, matrix: str) -> np.ndarray:
    """The video's frames as RGB, read with the YUV matrix ``matrix`` (bt709, bt601) in limited range: what a
    player that assumes that matrix shows."""
    import subprocess

    from laughlab.io.video import ffmpeg_exe

    r = subprocess.run([ffmpeg_exe(), "-v", "error", "-i", str(path), "-vf",
                        f"scale=in_color_matrix={matrix}:in_range=tv,format=rgb24", "-f", "rawvideo", "-"],
                       capture_output=True, check=True)
    return np.frombuffer(r.stdout, np.uint8).reshape(-1, 48, 64, 3)


def test_colours_are_bt709_and_the_stream_says_so(tmp_path):
    """The RGB frames become YUV by BT.709 and the stream is tagged bt709 / tv range, so every player
    shows the rendered colours (untagged BT.601 read as BT.709, as players do for HD video, was off by
    up to 17 of 255 levels on saturated red and green)."""
    from laughlab.io.video import VideoEncoder

    colours = np.array([(200, 40, 40), (40, 160, 60), (60, 83, 120), (230, 180, 150), (20, 20, 200)], np.uint8)
    mp4 = tmp_path / "c.mp4"
    enc = VideoEncoder(mp4, 64, 48, 30.0)
    for c in colours:
        enc.write(np.tile(c, (48, 64, 1)))
    enc.close()
    assert probe(mp4)["color"] == "tv, bt709"   # matrix, primaries and transfer bt709, limited range
    for frames in (decode_frames(mp4, 64, 48), _decode_as(mp4, "bt709")):   # as tagged; as an HD player assumes
        assert np.abs(frames[:, 24, 32].astype(int) - colours).max() <= 3
    data = mp4.read_bytes()
    assert b"colrnclx\x00\x01\x00\x01\x00\x01" in data   # the MP4's own colour box (QuickTime reads it)
    assert data.find(b"moov") < data.find(b"mdat")            # +faststart: plays while it downloads


def _sink(tmp_path, anim_fps=30.0, **params) -> VideoSink:
    """A video sink drawing the schematic figure (its face inset is where these tests look)."""
    p = VideoParams(**{"width": 320, "height": 240, "fps": None, "supersample": 1, "audio": False,
                       "style": "schematic", **params})
    sink = VideoSink(p, Context(fps=anim_fps))
    sink.open(RunInfo(tmp_path, anim_fps, HUMANOID, None, None))
    return sink


def _chunk(channels: dict, n: int, fps: float = 30.0) -> Chunk:
    poses = np.tile(rest_pose(), (n, 1))
    for side, s in (("left", 1), ("right", -1)):  # arms down
        poses[:, HUMANOID.angle_slice(f"{side}_upper_arm")] = (-78 * s, 0, 0)
    return Chunk(np.arange(n) / fps, {k: np.asarray(v, float) for k, v in channels.items()}, poses, [], [None] * n)


def _inset_mouth_box(width, height, inset_size=0.36):
    s = int(inset_size * height)
    m = int(0.025 * height)
    x0, y0 = width - s - m, m
    cx, cy, scale = x0 + 0.5 * s, y0 + 0.48 * s, s / 30.0
    my = cy + 4.9 * scale  # the mouth sits 4.9 cm below the head centre
    return (slice(int(my - 1 * scale), int(my + 5 * scale)), slice(int(cx - 4 * scale), int(cx + 4 * scale)))


@pytest.mark.parametrize("face", ["smile", "arkit"])
def test_mouth_opens_with_the_jaw(tmp_path, face):
    n = 10
    jaw = np.r_[np.zeros(n), np.ones(n)]
    channels = {"smile": np.zeros(2 * n), "jaw": jaw, "eyes_closed": np.zeros(2 * n)} if face == "smile" else \
        {"au26": jaw, "arkit.jawOpen": jaw, "arkit.mouthSmileLeft": np.zeros(2 * n)}
    sink = _sink(tmp_path)
    sink.write(_chunk(channels, 2 * n))
    files = sink.close()
    assert files == [tmp_path / "video.mp4"]
    assert probe(files[0])["audio"] is None  # audio=False: video only
    frames = decode_frames(files[0], 320, 240).astype(float)
    assert len(frames) == 2 * n
    closed, opened = frames[n // 2], frames[n + n // 2]
    mouth = _inset_mouth_box(320, 240)
    diff = np.abs(opened - closed).mean(axis=-1)
    assert diff[mouth].mean() > 20  # the mouth region changes
    # ... and little else does: the jaw drop moves the mouth and the chin only
    eyes = (slice(mouth[0].start - int(0.2 * 240 * 0.36), mouth[0].start - int(0.1 * 240 * 0.36)), mouth[1])
    assert diff[eyes].mean() < 3
    dark = (opened[mouth].mean(axis=-1) < 110).mean() - (closed[mouth].mean(axis=-1) < 110).mean()
    assert dark > 0.1  # an open mouth shows its dark inside


def test_eyes_close_and_smile_shows(tmp_path):
    n = 6
    sink = _sink(tmp_path)
    sink.write(_chunk({"smile": np.r_[np.zeros(n), np.ones(n)], "jaw": np.zeros(2 * n),
                       "eyes_closed": np.r_[np.zeros(n), np.ones(n)]}, 2 * n))
    frames = decode_frames(sink.close()[0], 320, 240).astype(float)
    diff = np.abs(frames[-1] - frames[0]).mean(axis=-1)
    mouth = _inset_mouth_box(320, 240)
    assert diff[mouth].mean() > 5
    s, m = int(0.36 * 240), int(0.025 * 240)
    y_eye = int(m + 0.48 * s - 1.9 * s / 30)  # eyes 1.9 cm above the head centre
    assert diff[y_eye - 3:y_eye + 3, 320 - s - m:320 - m].mean() > 5


def test_video_fps_takes_every_kth_frame(tmp_path):
    sink = _sink(tmp_path, anim_fps=60.0, fps=20.0)
    for _ in range(3):  # 3 chunks of 50 frames at 60 fps = 2.5 s -> 50 frames at 20 fps
        sink.write(_chunk({"jaw": np.zeros(50)}, 50, 60.0))
    mp4 = sink.close()[0]
    assert len(decode_frames(mp4, 320, 240)) == 50
    assert probe(mp4)["video"]["fps"] == 20.0


def test_abort_removes_everything(tmp_path):
    sink = _sink(tmp_path)
    sink.write(_chunk({"jaw": np.zeros(30)}, 30))
    sink.abort()
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("bad", [{"width": 161}, {"height": 0}, {"preset": "warp"}, {"crf": 60},
                                 {"camera": {"fov_deg": 200}}, {"file": "a/b.mp4"}])
def test_bad_parameters(bad):
    with pytest.raises(LaughlabError):
        plugins.create("sink", "video", bad, Context())


@pytest.mark.parametrize("bad, says", [
    ({"crf": 0}, "crf 0 is lossless H.264 (the High 4:4:4 Predictive profile)"),   # plays in Chromium, not Safari
    ({"audio_rate": 12345}, "audio_rate must be a rate AAC takes"),                # ffmpeg wrote nothing, unnamed
    ({"audio_rate": 44000}, "audio_rate must be a rate AAC takes")])
def test_settings_a_player_or_ffmpeg_would_refuse_are_named(bad, says):
    """A video producer's review: crf=0 made a High 4:4:4 Predictive stream (the docs say H.264 High), and
    audio_rate=12345 ended in ffmpeg's 'Nothing was written into output file', naming no setting."""
    with pytest.raises(LaughlabError) as err:
        plugins.create("sink", "video", bad, Context())
    assert says in str(err.value)


def test_ntsc_rates_are_written_as_1001_fractions_and_a_name_like_a_protocol_is_a_file(tmp_path):
    """29.97 was written as 2997/100 (the docs say 30000/1001), and a relative 'take1:laugh.wav' was read by
    ffmpeg as a protocol (output=video only: 'Protocol not found')."""
    from laughlab.io.video import _rate, ffmpeg_input

    assert [_rate(f) for f in (29.97, 23.976, 59.94, 30, 25, 12.5)] == [
        "30000/1001", "24000/1001", "60000/1001", "30", "25", "25/2"]
    import soundfile as sf

    odd = tmp_path / "take1:laugh.wav"
    sf.write(odd, np.zeros(8000), 16000)
    import contextlib

    with contextlib.chdir(tmp_path):
        assert ffmpeg_input("take1:laugh.wav") == f"file:{odd}"
        assert probe("take1:laugh.wav")["audio"]["sample_rate"] == 16000


def test_video_fps_above_animation_fps_is_refused(tmp_path):
    sink = VideoSink(VideoParams(fps=60.0, audio=False), Context(fps=30))
    with pytest.raises(LaughlabError, match="must not exceed"):
        sink.open(RunInfo(tmp_path, 30.0, HUMANOID, None, None))


def test_true_perspective():
    cam = Camera(azimuth_deg=0, elevation_deg=0, distance_cm=300, target_height_cm=100, fov_deg=40)
    project = cam.projector(640, 480)
    xy, depth = project(np.array([[0, 100, 0], [20, 100, 0], [20, 100, -100], [20, 100, 100]], float))
    assert xy[0] == pytest.approx([320, 240])
    assert depth[0] == pytest.approx(300)
    # the same offset looks smaller further away, larger closer: x shrinks as 1/depth
    off = xy[1:, 0] - 320
    assert off[1] < off[0] < off[2]
    assert off[0] * depth[1] == pytest.approx(off[1] * depth[2])
    assert off[0] > 0  # the character's left (+X) is on the right of a camera in front of it


def test_renderer_draws_every_joint_of_an_unknown_skeleton():
    from laughlab.motion.skeleton import Skeleton

    sk = Skeleton(("root", "a", "b"), (-1, 0, 1), np.array([[0, 0, 0], [0, 50, 0], [30, 0, 0]], float))
    r = Renderer(sk, 64, 48, supersample=1, inset=False)
    pos = np.array([[0, 60, 0], [0, 110, 0], [30, 110, 0]], float)
    img = r.render(pos, np.tile(np.eye(3), (3, 1, 1)), None, {})
    assert img.shape == (48, 64, 3) and (img != r.render(pos * 0 - 1000, np.tile(np.eye(3), (3, 1, 1)), None,
                                                         {})).any()


def test_yaml_defaults_equal_the_dataclass_defaults():
    import yaml
    from dataclasses import asdict

    from laughlab.core.config import conf_dir as _conf_dir

    conf = yaml.safe_load(_conf_dir().joinpath("output", "video.yaml").read_text())
    assert set(conf) == {"csv", "bvh", "plots", "arkit", "video"}
    assert conf["video"] == asdict(VideoParams())


def test_the_character_style_shows_the_skinned_character_and_its_face(tmp_path):
    """style=character (the default): the software-rendered character; its mouth opens with the jaw,
    its eyes close, and nothing far from the face changes with them."""
    n = 4
    jaw = np.r_[np.zeros(n), np.ones(n), np.zeros(n)]
    eyes = np.r_[np.zeros(2 * n), np.ones(n)]
    sink = _sink(tmp_path, style="character", supersample=2)
    sink.write(_chunk({"arkit.jawOpen": jaw, "arkit.eyeBlinkLeft": eyes, "arkit.eyeBlinkRight": eyes}, 3 * n))
    frames = decode_frames(sink.close()[0], 320, 240).astype(float)
    first = frames[n // 2]
    r, g, b = first[..., 0], first[..., 1], first[..., 2]
    skin = (r > g + 15) & (g > b) & (r > 140)
    shirt = (b > r + 25) & (b > 90)
    assert skin.mean() > 0.01 and shirt.mean() > 0.05  # a face and a blue shirt fill the frame
    ys, xs = np.nonzero(skin[: 120])  # the face: the skin in the upper half
    face = (slice(max(0, ys.min() - 5), ys.max() + 5), slice(max(0, xs.min() - 5), xs.max() + 5))
    jaw_diff = np.abs(frames[n + n // 2] - first).mean(axis=-1)
    eye_diff = np.abs(frames[2 * n + n // 2] - first).mean(axis=-1)
    for diff in (jaw_diff, eye_diff):
        changed = diff > 12  # above the encoder's noise
        assert changed[face].sum() > 20 and changed[face].sum() > 0.9 * changed.sum()  # the face, not the rest
    # jaw and eyes move different parts of the face
    assert np.argmax(jaw_diff[face].sum(axis=1)) > np.argmax(eye_diff[face].sum(axis=1))


def test_scratch_folders_of_processes_that_are_gone_are_removed_others_kept(tmp_path, monkeypatch):
    """A video run killed by SIGKILL left its laughlab-video-* folder in /tmp with the run's audio (the media review
    found 107, 252 MB; every full test run added one): the next video run removes those of processes that are gone,
    and keeps a living process' and a name it does not know."""
    import os
    import subprocess
    import sys
    import tempfile

    from laughlab.io.video import SCRATCH_PREFIX, scratch_dir

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = tmp_path / f"{SCRATCH_PREFIX}{int(gone.stdout)}-abc"
    alive = tmp_path / f"{SCRATCH_PREFIX}{os.getppid()}-def"
    old = tmp_path / f"{SCRATCH_PREFIX}xyz123"
    for d in (dead, alive, old):
        d.mkdir()
        (d / "input.wav").write_bytes(b"x" * 100)
    mine = scratch_dir()
    assert mine.parent == tmp_path and mine.name.startswith(f"{SCRATCH_PREFIX}{os.getpid()}-") and mine.is_dir()
    assert not dead.exists() and alive.exists() and old.exists()


def test_an_audio_path_longer_than_the_picture_is_said(tmp_path):
    """A video producer's review: output.video.audio_path of 12 s on a 2 s run made an MP4 of 12 s, 10 of them on a
    frozen last frame, without a word.  One warning line; an audio_path as long as the picture says nothing."""
    import soundfile as sf

    from inprocess import laughlab

    for name, seconds in (("long.wav", 6.0), ("same.wav", 1.5)):
        sf.write(tmp_path / name, 0.1 * np.sin(np.arange(int(16000 * seconds)) / 10), 16000)
    r = laughlab("input.duration_s=1.5", "output=video", f"output.video.audio_path={tmp_path / 'long.wav'}",
                 "~output.plots", f"hydra.run.dir={tmp_path / 'a'}")
    assert r.returncode == 0 and r.stderr == (f"laughlab: warning: output.video.audio_path {tmp_path / 'long.wav'} "
                                              "lasts 6.00 s, the picture 1.50 s: its last frame stays on screen for "
                                              "the rest\n"), r.stderr
    r = laughlab("input.duration_s=1.5", "output=video", f"output.video.audio_path={tmp_path / 'same.wav'}",
                 "~output.plots", f"hydra.run.dir={tmp_path / 'b'}")
    assert r.returncode == 0 and r.stderr == "", r.stderr
