"""Video files through ffmpeg: encoding a run's frames and audio into MP4, probing and decoding.

:class:`VideoEncoder` pipes raw RGB frames into ffmpeg (the binary shipped by
imageio-ffmpeg): H.264 (libx264), yuv420p, constant frame rate, AAC audio
from a WAV file, MP4 with ``+faststart``.  The RGB frames become YUV with the BT.709 matrix in limited
(tv) range, and the stream says so (colour matrix, primaries and transfer ``bt709``, range ``tv``): a
player does not have to guess, and guesses differ (BT.601 for SD in ffmpeg, BT.709 for HD in most
players; untagged, ffmpeg's default BT.601 conversion played as BT.709 shifted skin and shirt colours
by up to 10 of 255 levels).  The flags ``-fflags +bitexact
-flags:v +bitexact -flags:a +bitexact -map_metadata -1`` and a fixed x264
thread count make repeated renders byte-identical (given the same ffmpeg build).
"""
from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from laughlab.core.errors import LaughlabError


def ffmpeg_exe() -> str:
    """The ffmpeg binary shipped with imageio-ffmpeg (or ``IMAGEIO_FFMPEG_EXE``)."""
    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise LaughlabError(f"video output needs imageio-ffmpeg (pip install imageio-ffmpeg): {exc}") from None
    return imageio_ffmpeg.get_ffmpeg_exe()


#: RGB to YUV with the BT.709 matrix in limited range, and the stream tagged so (see the module docstring)
COLOR = ["-vf", "scale=out_color_matrix=bt709:out_range=tv,"
               "setparams=colorspace=bt709:color_primaries=bt709:color_trc=bt709:range=tv"]

BITEXACT = ["-fflags", "+bitexact", "-flags:v", "+bitexact", "-flags:a", "+bitexact", "-map_metadata", "-1"]


class VideoEncoder:
    """Pipes RGB frames into ffmpeg: H.264 yuv420p at a constant frame rate, AAC audio, MP4.

    Parameters
    ----------
    path : Path
        Output file (written as MP4 whatever its suffix).
    width, height : int
        Frame size (even numbers: yuv420p halves the chroma).
    fps : float
        Video frame rate (constant).
    audio : Path or None
        A WAV (or any ffmpeg-readable) file muxed as AAC from time 0; None: video only.
    crf, preset, threads : x264 quality, speed preset and thread count (fixed for identical bytes).
    audio_bitrate_k, audio_rate : AAC bit rate (kbit/s) and sample rate (Hz).
    """

    def __init__(self, path: Path, width: int, height: int, fps: float, audio: Path | None = None, crf: int = 20,
                 preset: str = "veryfast", threads: int = 2, audio_bitrate_k: int = 128, audio_rate: int = 48000):
        self.path = Path(path)
        self.shape = (int(height), int(width), 3)
        rate = _rate(fps)
        cmd = [ffmpeg_exe(), "-nostdin", "-y", "-hide_banner", "-loglevel", "error",
               "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", rate, "-i", "pipe:0"]
        if audio is not None:
            cmd += ["-i", ffmpeg_input(audio)]
        cmd += ["-map", "0:v:0"] + (["-map", "1:a:0"] if audio is not None else [])
        cmd += COLOR + ["-c:v", "libx264", "-preset", preset, "-crf", str(crf), "-pix_fmt", "yuv420p",
                        "-threads", str(threads), "-fps_mode", "cfr", "-r", rate, "-movflags", "+faststart"]
        if audio is not None:
            cmd += ["-c:a", "aac", "-b:a", f"{audio_bitrate_k}k", "-ar", str(audio_rate)]
        cmd += BITEXACT + ["-f", "mp4", str(self.path)]
        self.cmd = cmd
        self._err = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._err)
        except OSError as exc:
            self._err.close()
            raise LaughlabError(f"cannot start ffmpeg: {exc}") from None
        self.frames = 0

    def write(self, frame: np.ndarray) -> None:
        if frame.shape != self.shape or frame.dtype != np.uint8:
            raise ValueError(f"frame must be uint8 {self.shape}, got {frame.dtype} {frame.shape}")
        try:
            self.proc.stdin.write(np.ascontiguousarray(frame).tobytes())
        except BrokenPipeError:
            raise LaughlabError(f"ffmpeg stopped: {self._error_text()}") from None
        self.frames += 1

    def _error_text(self) -> str:
        self.proc.wait()
        self._err.seek(0)
        lines = [ln for ln in self._err.read().decode(errors="replace").splitlines() if ln.strip()]
        return lines[-1] if lines else f"exit status {self.proc.returncode}"

    def close(self) -> None:
        """Finish the file; raise LaughlabError if ffmpeg failed."""
        try:
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        code = self.proc.wait()
        try:
            if code != 0:
                raise LaughlabError(f"ffmpeg failed: {self._error_text()}")
        finally:
            self._err.close()

    def abort(self) -> None:
        """Stop ffmpeg without finishing the file (the caller removes it)."""
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.stdin.close()
        except (BrokenPipeError, OSError, ValueError):
            pass
        self.proc.wait()
        if not self._err.closed:
            self._err.close()


def ffmpeg_input(path: str | Path) -> str:
    """A file for ``ffmpeg -i``: absolute, after ``file:``, so that a name like ``take1:laugh.wav`` or ``file,x.wav``
    is not read as a protocol or options (a video producer's review: 'Protocol not found' for output=video only)."""
    return f"file:{Path(path).resolve()}"


def _rate(fps: float) -> str:
    """ffmpeg's rate string: an integer, or a fraction for rates like 29.97."""
    from fractions import Fraction

    ntsc = round(float(fps) * 1.001)   # 23.976, 29.97, 59.94 are N*1000/1001 (limit_denominator gave 2997/100)
    if ntsc > 0 and abs(float(fps) - ntsc * 1000 / 1001) < 0.005 and abs(float(fps) - round(float(fps))) > 1e-9:
        return f"{ntsc * 1000}/1001"
    fr = Fraction(float(fps)).limit_denominator(1001)
    return str(fr.numerator) if fr.denominator == 1 else f"{fr.numerator}/{fr.denominator}"


def probe(path: str | Path) -> dict:
    """Stream facts of a media file from ``ffmpeg -i`` (imageio-ffmpeg ships no ffprobe).

    Returns ``duration_s``, ``video`` (``codec``, ``pix_fmt``, ``width``,
    ``height``, ``fps``) and ``audio`` (``codec``, ``sample_rate``) or None, and ``color``: the
    video's colour tags as ffmpeg prints them after the pixel format (``"tv, bt709"``), "" if none.
    """
    r = subprocess.run([ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", ffmpeg_input(path)], capture_output=True,
                       text=True)
    err = r.stderr
    out: dict = {"duration_s": None, "video": None, "audio": None, "color": ""}
    m = re.search(r"Duration: (\d+):(\d+):(\d+(?:\.\d+)?)", err)
    if m:
        out["duration_s"] = int(m.group(1)) * 3600 + int(m.group(2)) * 60 + float(m.group(3))
    m = re.search(r"Stream #\d+:\d+.*?: Video: (\w+)[^,]*, (\w+)[^,]*?(?:\([^)]*\))?, (\d+)x(\d+).*?, ([\d.]+) fps",
                  err)
    if m:
        out["video"] = {"codec": m.group(1), "pix_fmt": m.group(2), "width": int(m.group(3)),
                        "height": int(m.group(4)), "fps": float(m.group(5))}
        tags = re.search(r"Video: .*?, " + m.group(2) + r"\(([^)]*)\)", err)
        out["color"] = ", ".join(t for t in (tags.group(1).split(", ") if tags else []) if t != "progressive")
    m = re.search(r"Stream #\d+:\d+.*?: Audio: (\w+)[^,]*, (\d+) Hz", err)
    if m:
        out["audio"] = {"codec": m.group(1), "sample_rate": int(m.group(2))}
    return out


def decode_frames(path: str | Path, width: int, height: int) -> np.ndarray:
    """Every video frame of a file as ``(N, height, width, 3)`` uint8 (decoded by ffmpeg)."""
    r = subprocess.run([ffmpeg_exe(), "-nostdin", "-loglevel", "error", "-i", ffmpeg_input(path), "-map", "0:v:0",
                        "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True)
    if r.returncode != 0:
        raise LaughlabError(f"cannot decode {path}: {r.stderr.decode(errors='replace').strip()}")
    return np.frombuffer(r.stdout, np.uint8).reshape(-1, height, width, 3)


def decode_audio(path: str | Path, sample_rate: int = 48000) -> np.ndarray:
    """The first audio stream of a file as mono float32 samples at ``sample_rate`` (decoded by ffmpeg)."""
    r = subprocess.run([ffmpeg_exe(), "-nostdin", "-loglevel", "error", "-i", ffmpeg_input(path), "-map", "0:a:0",
                        "-ac", "1", "-ar", str(sample_rate), "-f", "f32le", "-"], capture_output=True)
    if r.returncode != 0:
        raise LaughlabError(f"cannot decode audio of {path}: {r.stderr.decode(errors='replace').strip()}")
    return np.frombuffer(r.stdout, "<f4").copy()


def source_audio(source, tmp_dir: Path) -> Path | None:
    """A file holding the source's audio, or None (live input: video only).

    ``source.audio_path()`` when the source reads a file; else, for a source
    that writes its audio as an artifact (the ``synthetic`` source's
    ``input.wav``), the same audio rendered into ``tmp_dir`` (the source
    writes ``input.wav`` only after the sinks close, and it is deterministic,
    so the copy is identical).
    """
    if source is None:
        return None
    path = source.audio_path() if hasattr(source, "audio_path") else None
    if path is not None and Path(path).exists():
        return Path(path)
    truth = getattr(source, "truth", None)
    if truth is not None and hasattr(truth, "render") and hasattr(truth, "n_samples"):
        from laughlab.io.audio import FloatWavWriter

        tmp_dir = Path(tmp_dir)
        tmp_dir.mkdir(parents=True, exist_ok=True)
        wav = tmp_dir / "input.wav"
        with FloatWavWriter(wav, source.sample_rate) as f:
            block = 16384
            for start in range(0, truth.n_samples, block):
                f.write(truth.render(start, min(block, truth.n_samples - start)))
        return wav
    return None


#: the video sink's scratch folders in the system's temporary folder: ``laughlab-video-PID-XXXXXXXX``
SCRATCH_PREFIX = "laughlab-video-"


def scratch_dir() -> Path:
    """A new scratch folder for a video run's audio, named by this process' id; first, those of processes that are
    gone are removed (a run killed by SIGKILL or a power cut cannot clean up after itself: the media review found
    107 of them, 252 MB, one more per full test run)."""
    import os
    import shutil

    for d in Path(tempfile.gettempdir()).glob(SCRATCH_PREFIX + "*-*"):
        pid = d.name[len(SCRATCH_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:   # gone: nothing will use its folder again
            shutil.rmtree(d, ignore_errors=True)
        except OSError:   # alive, another user's (PermissionError): theirs
            pass
    return Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-"))
