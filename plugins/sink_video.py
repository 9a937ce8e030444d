"""Sink ``video``: the run as an MP4 (H.264 + AAC) showing the character and its face.

``python -m laughlab output=video`` writes ``video.mp4`` beside the usual files.
Drawing: :mod:`laughlab.render.scene`; encoding: :mod:`laughlab.io.video`.
"""
from __future__ import annotations

import math
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.errors import LaughlabError
from laughlab.core.outfiles import Staging
from laughlab.core.plugins import check_range
from laughlab.io.video import VideoEncoder, scratch_dir, source_audio
from laughlab.render.scene import Camera, Renderer
from laughlab.motion.skeleton import global_transforms
from laughlab.io.vmc import arkit_weights

PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow")


@dataclass
class CameraParams:
    """The perspective camera (:class:`laughlab.render.scene.Camera`).

    Attributes
    ----------
    azimuth_deg : float
        0 = in front of the character, positive = towards its left.
    elevation_deg : float
        Height angle above the target.
    distance_cm : float
        Distance from the target (cm).
    target_height_cm : float
        Height of the point looked at (cm; the hips are at 95).
    fov_deg : float
        Vertical field of view.
    """

    azimuth_deg: float = 20.0
    elevation_deg: float = 6.0
    distance_cm: float = 360.0
    target_height_cm: float = 96.0
    fov_deg: float = 36.0

    def __post_init__(self) -> None:
        check_range("camera.elevation_deg", self.elevation_deg, -80, 80)
        check_range("camera.distance_cm", self.distance_cm, 50, 5000)
        check_range("camera.fov_deg", self.fov_deg, 5, 120)


@dataclass
class VideoParams:
    """Parameters of the ``video`` sink.

    Attributes
    ----------
    file : str
        Output file name in the run directory.
    width, height : int
        Frame size in pixels (even: yuv420p).
    fps : float or None
        Video frame rate; None = the animation's.  Lower rates take the
        animation frame nearest each video frame's time (every k-th frame when
        the animation rate is k times the video rate: 60 -> 30 fps takes every
        second frame).  At most the animation rate.
    crf : int
        x264 quality (0 lossless .. 51 worst; 18-23 look clean).
    preset : str
        x264 speed preset.
    threads : int
        x264 threads; fixed (not "auto") so the same run gives the same bytes on any machine.
    supersample : int
        Anti-aliasing: draw at this multiple of the size and downsample (1 = off, faster).
    style : str
        ``character``: the skinned character (:mod:`laughlab.character.body`), rendered in
        software (no GPU), framed on the upper body and face by ``character_camera``;
        ``schematic``: the stick figure with a drawn face, framed by ``camera``, for quick looks.
    inset : bool
        Show the zoomed face (top right; van Duijn 2014, 6.1; ``schematic`` only).
    inset_size : float
        Inset side as a fraction of the height.
    audio : bool
        Mux the input's audio (AAC).  The audio is ``audio_path`` if given, else
        the source's file (``input=file``), else the synthetic source's audio
        (the same samples as its ``input.wav``).  A live microphone has no
        file: its video has no audio.
    audio_path : str or None
        A WAV to mux instead of the source's audio (e.g. a loudness-normalised copy).
    audio_bitrate_k : int
        AAC bit rate (kbit/s).
    audio_rate : int
        AAC sample rate (Hz).
    camera : CameraParams
        The ``schematic`` style's camera.
    character_camera : CameraParams
        The ``character`` style's camera (upper body and face).
    framing : str
        The ``character`` style's framing: ``upper`` (the upper body and face, the default) or ``body`` (the
        whole body, feet included: looking between the head and the feet, from at least the distance at which
        the character standing at rest fits; an avatar developer's review: a full-body laugh lost its shins).
    character : str or None
        A user's avatar (VRM, humanoid glTF) to render instead of the mannequin (``character`` style;
        the top-level ``character=PATH`` sets it): :mod:`laughlab.render.avatar_view`.
    """

    file: str = "video.mp4"
    style: str = "character"
    width: int = 640
    height: int = 480
    fps: float | None = 30.0
    crf: int = 20
    preset: str = "veryfast"
    threads: int = 2
    supersample: int = 2
    inset: bool = True
    inset_size: float = 0.36
    audio: bool = True
    audio_path: str | None = None
    audio_bitrate_k: int = 128
    audio_rate: int = 48000
    camera: CameraParams = field(default_factory=CameraParams)
    character_camera: CameraParams = field(default_factory=lambda: CameraParams(
        azimuth_deg=15.0, elevation_deg=3.0, distance_cm=170.0, target_height_cm=138.0, fov_deg=30.0))
    character: Optional[str] = None
    framing: str = "upper"

    def __post_init__(self) -> None:
        if self.framing not in ("upper", "body"):
            raise ValueError(f"framing must be upper or body (got {self.framing!r})")
        if not self.file or "/" in self.file or "\\" in self.file:
            raise ValueError(f"file must be a plain file name (got {self.file!r})")
        if not self.file.lower().endswith(".mp4") or self.file.startswith("."):
            # another output's name (input.wav, motion.bvh, plots) replaced the video or was half replaced by it
            raise ValueError(f"file must be a file name ending in .mp4 (got {self.file!r})")
        for name in ("width", "height"):
            v = getattr(self, name)
            check_range(name, v, 16, 4096)
            if v % 2:
                raise ValueError(f"{name} must be even for yuv420p (got {v})")
        if self.style not in ("character", "schematic"):
            raise ValueError(f"style must be character or schematic (got {self.style!r})")
        if self.fps is not None:
            check_range("fps", self.fps, 1, 240)
        check_range("crf", self.crf, 0, 51)
        if self.crf == 0:   # x264's lossless mode switches to the High 4:4:4 Predictive profile (a video review)
            raise ValueError("crf 0 is lossless H.264 (the High 4:4:4 Predictive profile), which Safari, QuickTime "
                             "and PowerPoint do not play; use 1 or more (18 looks lossless)")
        if self.preset not in PRESETS:
            raise ValueError(f"preset must be one of {', '.join(PRESETS)} (got {self.preset!r})")
        check_range("threads", self.threads, 1, 64)
        check_range("supersample", self.supersample, 1, 4)
        check_range("inset_size", self.inset_size, 0.1, 0.9)
        check_range("audio_bitrate_k", self.audio_bitrate_k, 16, 512)
        check_range("audio_rate", self.audio_rate, 8000, 96000)
        if self.audio_rate not in AAC_RATES:   # ffmpeg's AAC encoder wrote nothing, in a line naming no setting
            raise ValueError(f"audio_rate must be a rate AAC takes: {', '.join(map(str, AAC_RATES))} (got "
                             f"{self.audio_rate})")
        if self.character and self.style != "character":
            raise ValueError(f"a character (avatar) is drawn in style=character only (got style={self.style})")


#: the sample rates AAC (MPEG-4 audio's sampling frequency index) takes, within audio_rate's range
AAC_RATES = (8000, 11025, 12000, 16000, 22050, 24000, 32000, 44100, 48000, 64000, 88200, 96000)


class VideoSink(Sink):
    """Renders frames as they come and pipes them into ffmpeg; the MP4 appears when the run succeeds.

    Video frame ``m`` shows animation frame ``round(m * fps / video_fps)`` at
    time ``m / video_fps``; the audio starts at time 0, so sound and picture
    are in sync (frame ``k``'s animation reflects the audio up to the end of
    its own audio block).  The file is encoded under a temporary name and
    moved into place in ``close``; a failed run leaves no MP4.
    """

    name = "video"
    Params = VideoParams
    slow = True  # draws and encodes every frame: the progress bar shows on any length (progress=auto)
    files = ("video.mp4",)

    @classmethod
    def planned(cls, params: dict) -> tuple[str, ...]:
        """``output.video.file`` (``video.mp4``), or the first folder of a relative path."""
        name = Path(str((params or {}).get("file") or cls.files[0]))
        return () if name.is_absolute() or not name.parts else (name.parts[0],)

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        from laughlab.avatar import sink_character

        self.avatar = sink_character(self.params)
        if self.avatar is not None:
            from laughlab.avatar.expressions import say_face_route

            say_face_route(self.avatar)

    def open(self, run) -> None:
        super().open(run)
        p = self.params
        self.vfps = float(run.fps if p.fps is None else p.fps)
        if self.vfps > run.fps + 1e-9:
            raise LaughlabError(f"output.video.fps ({self.vfps:g}) must not exceed the animation fps ({run.fps:g})")
        self.ratio = run.fps / self.vfps
        self.staging = Staging()
        self.tmp_dir = scratch_dir()
        self.encoder = None
        try:
            audio = None
            if p.audio:
                if p.audio_path:
                    audio = Path(p.audio_path).expanduser()
                    if not audio.is_file():
                        raise LaughlabError(f"output.video.audio_path not found: {p.audio_path}")
                else:
                    audio = source_audio(run.source, self.tmp_dir)
            self.audio = audio
            if self.avatar is not None:
                from laughlab.avatar.errors import AvatarError
                from laughlab.render.avatar_view import AvatarRenderer

                try:
                    self.renderer = AvatarRenderer(self.avatar, run.skeleton, p.width, p.height,
                                                   Camera(**vars(p.character_camera)), p.supersample, p.framing)
                except AvatarError as exc:   # a texture whose pixels do not decode: the avatar's line, not ours
                    raise LaughlabError(str(exc)) from None
            elif p.style == "character":
                from laughlab.render.character_view import CharacterRenderer

                self.renderer = CharacterRenderer(run.skeleton, p.width, p.height,
                                                  Camera(**vars(p.character_camera)), p.supersample, p.framing)
            else:
                self.renderer = Renderer(run.skeleton, p.width, p.height, Camera(**vars(p.camera)), p.inset,
                                         p.inset_size, p.supersample)
            self.encoder = VideoEncoder(self.staging.path(run.out_dir / p.file), p.width, p.height, self.vfps, audio,
                                        p.crf, p.preset, p.threads, p.audio_bitrate_k, p.audio_rate)
        except BaseException:
            self.abort()
            raise
        self.channels_seen: set = set()   # the ARKit weights the face gave (metrics: the morphs they drove)
        self.n = 0          # animation frames seen
        self.m = 0          # video frames written
        self.render_s = 0.0

    def _next_index(self) -> int:
        return int(math.floor(self.m * self.ratio + 0.5))

    def write(self, chunk) -> None:
        n = len(chunk.times)
        want = []
        while self._next_index() < self.n + n:
            want.append(self._next_index() - self.n)
            self.m += 1
        self.n += n
        if not want:
            return
        t0 = time.perf_counter()
        sk = self.run.skeleton
        idx = np.array(want)
        poses = np.nan_to_num(np.asarray(chunk.poses, dtype=np.float64)[idx])
        if self.avatar is not None:
            self._avatar_frames(chunk, idx, poses)
            self.render_s += time.perf_counter() - t0
            return
        if self.params.style == "character":
            from laughlab.character.body import morph_weights

            mw = morph_weights(chunk.channels, n)[idx]
            for frame in self.renderer.render_many(poses, mw):
                self.encoder.write(frame)
            self.render_s += time.perf_counter() - t0
            return
        pos, rot = global_transforms(sk, poses)
        leaves = sk.leaves()
        ends = pos[:, leaves] + np.einsum("fjab,jb->fja", rot[:, leaves], sk.end_sites[leaves])
        weights = {k: v[idx].tolist() for k, v in arkit_weights(chunk.channels).items()}
        body = {k: (np.asarray(chunk.channels[k])[idx].tolist() if k in chunk.channels else [0.0] * len(idx))
                for k in ("chest", "belly")}
        for i in range(len(idx)):
            w = {k: v[i] for k, v in weights.items()}
            frame = self.renderer.render(pos[i], rot[i], ends[i], w, body["chest"][i], body["belly"][i])
            self.encoder.write(frame)
        self.render_s += time.perf_counter() - t0

    def _avatar_frames(self, chunk, idx: np.ndarray, poses: np.ndarray) -> None:
        from laughlab.avatar.channels import face_and_breath
        from laughlab.avatar.expressions import breath_on_bones, breathing_pose, morph_weights

        arkit, breath = face_and_breath(chunk.channels)
        self.channels_seen |= set(arkit)
        arkit = {k: np.asarray(v)[idx] for k, v in arkit.items()}
        breath = {k: np.asarray(v)[idx] for k, v in breath.items()}
        poses = breathing_pose(poses, breath_on_bones(self.avatar, breath), self.run.skeleton)
        morphs = morph_weights(self.avatar, arkit, breath, len(idx))
        frames = self.renderer.render_many(self.renderer.worlds(poses),
                                           [{k: v[i] for k, v in morphs.items()} for i in range(len(idx))])
        for frame in frames:
            self.encoder.write(frame)

    def close(self):
        try:
            if hasattr(self.renderer, "flush"):   # the frames the character's camera held to look ahead
                t0 = time.perf_counter()
                for frame in self.renderer.flush():
                    self.encoder.write(frame)
                self.render_s += time.perf_counter() - t0
            self.encoder.close()
        finally:
            shutil.rmtree(self.tmp_dir, ignore_errors=True)
        if self.m == 0:
            raise LaughlabError("output.video: no frames to encode")
        if self.params.audio and self.params.audio_path:   # a video producer's review: 10 s on a frozen frame, unsaid
            from laughlab.io.video import probe

            audio_s, picture_s = probe(self.audio)["duration_s"], self.m / self.vfps
            if audio_s is not None and audio_s > picture_s + 1.0 / self.vfps:
                print(f"laughlab: warning: output.video.audio_path {self.params.audio_path} lasts {audio_s:.2f} s, "
                      f"the picture {picture_s:.2f} s: its last frame stays on screen for the rest", file=sys.stderr)
        return self.staging.commit()

    def metrics(self) -> dict:
        """Video frames written and the drawing-plus-piping speed (frames per second of wall time)."""
        out = {"video_frames": int(self.m), "video_fps": self.vfps,
               "video_render_fps": self.m / self.render_s if self.render_s > 0 else float("nan")}
        if self.avatar is not None:   # how the face drove the avatar (its one line was said at start-up)
            from laughlab.avatar.expressions import face_route

            route = face_route(self.avatar, self.channels_seen)
            out.update(avatar_morphs=route["morphs"], avatar_morphs_driven=route["morphs_driven"])
        return out

    def abort(self) -> None:
        try:
            if getattr(self, "encoder", None) is not None:
                self.encoder.abort()
        finally:
            self.staging.abort()
            shutil.rmtree(self.tmp_dir, ignore_errors=True)


@hookimpl
def register_sinks(register):
    register(VideoSink)
