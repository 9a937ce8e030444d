"""Cutting audio into one block per animation frame, reading files in blocks."""
from __future__ import annotations

from bisect import bisect_right
from pathlib import Path
from typing import Iterable, Iterator

import numpy as np

from laughlab.core.errors import LaughlabError, first_line

#: sample rates the ``file`` source accepts (Hz)
MIN_RATE, MAX_RATE = 8000, 192000


def frame_edges(n_frames: int, sample_rate: int, fps: float) -> np.ndarray:
    """Sample index where each frame starts, plus the end: ``round(k * sr / fps)``, k = 0..n."""
    return np.round(np.arange(n_frames + 1) * (sample_rate / fps)).astype(np.int64)


def n_frames_for(n_samples: int, sample_rate: int, fps: float) -> int:
    """Number of frames :func:`cut_frames` cuts ``n_samples`` samples into: the frames k whose first sample,
    ``round(k * sr / fps)``, is a sample of the input (the last may be partial).  ``ceil(n * fps / sr)`` counted one
    more when the last edge rounds to the input's end (16 kHz at 72 fps, 253778 samples: 1143 for 1142 frames)."""
    if n_samples <= 0:
        return 0
    n = int(np.ceil(n_samples * fps / sample_rate - 1e-9))
    while n > 1 and np.round((n - 1) * (sample_rate / fps)) >= n_samples:   # frame n - 1 starts past the end
        n -= 1
    return n


def cut_frames(chunks: Iterable[np.ndarray], sample_rate: int, fps: float) -> Iterator[np.ndarray]:
    """Re-cut a stream of sample chunks into per-frame blocks.

    Frame k holds samples ``[round(k*sr/fps), round((k+1)*sr/fps))``; the last
    frame may be shorter.  Blocks are read-only float64 views (the sources' float32
    samples, exactly), valid until the next one; a chunk is converted once, not each
    frame by its extractor.  The frame edges of each chunk are computed at once
    (numpy), the same integers as ``int(round(k * sr / fps))`` frame by frame.
    """
    step = sample_rate / fps
    buf = np.zeros(0, dtype=np.float64)
    k, consumed = 0, 0  # frame index, samples dropped from the front of buf
    for chunk in chunks:
        x = np.asarray(chunk, dtype=np.float32).astype(np.float64)  # float32 first: the sources' precision
        buf = np.concatenate([buf, x]) if len(buf) else x
        buf.flags.writeable = False  # a plugin must not change the samples the next stage reads
        # frames that end inside buf: round((k+1)*step) - consumed <= len(buf)
        n = max(0, int((consumed + len(buf)) / step) + 2 - k)
        edges = (np.round(np.arange(k, k + n + 1) * step).astype(np.int64) - consumed).tolist()
        m = bisect_right(edges, len(buf), 1) - 1  # frames that end inside buf
        for a, b in zip(edges[:m], edges[1:m + 1]):
            yield buf[a:b]
        k += m
        pos = edges[m] if m else 0
        buf = buf[pos:]
        consumed += pos
    if len(buf):
        yield buf


def to_mono(data: np.ndarray) -> np.ndarray:
    """Mix channels to mono by their mean (float32)."""
    if data.ndim == 2:
        return data.mean(axis=1, dtype=np.float32) if data.shape[1] > 1 else data[:, 0]
    return data.astype(np.float32, copy=False)


def probe_file(path: str | Path):
    """Open an audio file with soundfile and check it; return its ``soundfile.info``.

    Raises LaughlabError with one line for a missing, empty, unreadable or
    zero-length file or an unsupported sample rate.
    """
    import soundfile as sf

    p = Path(path).expanduser()
    if not p.exists():
        raise LaughlabError(f"input file not found: {path}")
    if p.is_dir():
        raise LaughlabError(f"input path is a folder, not an audio file: {path}")
    if p.stat().st_size == 0:
        raise LaughlabError(f"input file is empty: {path}")
    try:   # libsndfile says "System error." for a file it may not open (a first-contact review)
        with open(p, "rb"):
            pass
    except OSError as exc:
        raise LaughlabError(f"cannot read audio from {path}: {exc.strerror or exc}") from None
    try:
        info = sf.info(str(p))
    except Exception as exc:
        reason = first_line(exc)
        raise LaughlabError(f"cannot read audio from {path}: {reason}{convert_hint([p])}") from None
    if info.frames <= 0:
        raise LaughlabError(f"input file has no audio samples: {path}")
    if info.format in WAV_FORMATS:   # WAVEX too: sox writes 24-bit and multichannel WAV so (a review: missed)
        check_wav_length(p, info, path)
    if not MIN_RATE <= info.samplerate <= MAX_RATE:
        raise LaughlabError(f"sample rate {info.samplerate} Hz of {path} is outside {MIN_RATE}-{MAX_RATE} Hz")
    if info.subtype in ("FLOAT", "DOUBLE") and not _any_finite(p):
        raise LaughlabError(f"{path} holds no finite samples (every one is NaN or infinite): a damaged or "
                            "mis-converted file")
    return info


def _any_finite(p: Path, block: int = 65536) -> bool:
    """Does a float file hold a finite sample?  Read until the first one (at once for a sound file; to the end only
    for a file of NaN and infinities, which a run would take as a silence of its length: a review)."""
    import numpy as np
    import soundfile as sf

    for b in sf.blocks(str(p), blocksize=block, dtype="float32", always_2d=True):
        if np.isfinite(b).any():
            return True
    return False


#: libsndfile's names of RIFF WAVE files, whose header says how long their audio is (:func:`check_wav_length`);
#: RF64 too (a long microphone session's saved audio: a copy cut short ran on half of it without a word)
WAV_FORMATS = ("WAV", "WAVEX", "RF64")


def check_wav_length(p: Path, info, shown) -> None:
    """A WAV file whose ``data`` chunk is more than 0.1 s shorter than its header says (a copy or a recording cut
    short): one line instead of a run on what is left.  A size of 0 or 0xFFFFFFFF (a stream's) is not checked."""
    import struct

    size = p.stat().st_size
    with open(p, "rb") as f:
        head = f.read(12)
        if len(head) < 12 or head[:4] not in (b"RIFF", b"RF64") or head[8:12] != b"WAVE":
            return
        long = None   # RF64: the data's size is ds64's 64-bit one
        while True:
            chunk = f.read(8)
            if len(chunk) < 8:
                return
            cid, n = chunk[:4], struct.unpack("<I", chunk[4:])[0]
            if cid == b"ds64" and n >= 16:
                long = struct.unpack("<QQ", f.read(16))[1]
                f.seek(n - 16 + (n & 1), 1)
                continue
            if cid == b"data":
                start = f.tell()
                n = long if long is not None and n == 0xFFFFFFFF else n
                break
            f.seek(n + (n & 1), 1)
    held = size - start
    if n in (0, 0xFFFFFFFF) or n <= held or info.frames <= 0:
        return
    per_s = held / info.frames * info.samplerate   # bytes per second of audio
    if (n - held) / per_s < 0.1:   # a few bytes or frames short (a copy cut in its last frame): read what is whole
        return
    raise LaughlabError(f"{shown} is cut short: its header promises {n / per_s:.2f} s of audio, the file holds "
                        f"{held / per_s:.2f} s (copy it again, or rewrite its header: sox IN.wav OUT.wav)")


def read_blocks(path: str | Path, block_s: float = 1.0, channel: int | None = None) -> Iterator[np.ndarray]:
    """Yield the file's audio as mono float32 chunks of about ``block_s`` seconds (its channels mixed, or channel
    ``channel`` alone, from 0).

    Memory stays constant whatever the file's length.  16-bit PCM WAV files (the usual
    recording format) are read with the standard library's ``wave`` and scaled by 1/32768,
    which is exactly libsndfile's conversion at a third of its cost (a test compares the
    two); every other format goes through soundfile.
    """
    import soundfile as sf

    p = str(Path(path).expanduser())
    info = sf.info(p)
    if info.format == "WAV" and info.subtype == "PCM_16":
        yield from _read_pcm16_wav(p, max(1, int(info.samplerate * block_s)), channel)
        return
    pick = to_mono if channel is None else (lambda data: np.ascontiguousarray(data[:, channel]))
    with sf.SoundFile(p) as f:
        n = max(1, int(f.samplerate * block_s))
        done = 0
        while True:
            try:
                data = f.read(n, dtype="float32", always_2d=True)
            except (sf.LibsndfileError, RuntimeError) as exc:   # e.g. a FLAC cut short: 'decoder lost sync'
                reason = first_line(exc).removeprefix("Error : ")
                raise LaughlabError(f"cannot decode {path} after {done / f.samplerate:.1f} s: {reason} (the file is "
                                    "damaged or cut short)") from None
            if len(data) == 0:
                break
            done += len(data)
            yield pick(data)


def _read_pcm16_wav(path: str, n: int, channel: int | None = None) -> Iterator[np.ndarray]:
    """Chunks of ``n`` frames of a 16-bit PCM WAV file as float32 in [-1, 1), mixed to mono (or one channel)."""
    import wave

    scale = np.float32(1.0 / 32768.0)
    with wave.open(path, "rb") as w:
        ch = w.getnchannels()
        while True:
            raw = w.readframes(n)
            raw = raw[:len(raw) - len(raw) % (2 * ch)]  # a file cut mid-frame: its whole frames, as libsndfile
            if not raw:
                break
            x = np.frombuffer(raw, dtype="<i2").astype(np.float32) * scale
            yield to_mono(x.reshape(-1, ch)) if channel is None else np.ascontiguousarray(x.reshape(-1, ch)[:, channel])


class FloatWavWriter:
    """Streams mono 32-bit float WAV (IEEE float, format 3) with a deterministic header.

    libsndfile adds a PEAK chunk with a time stamp to float WAV files, so the
    same audio would give different bytes on every run; this writer does not.
    """

    #: the most audio a RIFF WAV's 32-bit sizes hold (bytes of data, with the header)
    RIFF_LIMIT = 0xFFFFFFFF - 4 - 36 - 26 - 12 - 8

    def __init__(self, path: str | Path, sample_rate: int, long: bool = False):
        self.f = open(path, "wb")
        self.sample_rate = int(sample_rate)
        self.n = 0
        self.long = long
        self._header()

    def _header(self) -> None:
        """RIFF, then (``long``) a 36-byte JUNK chunk that becomes RF64's ds64 past 4 GiB of audio (EBU Tech 3306:
        a microphone session saved at 44.1 kHz reached it after 6.8 h, and struct.pack's error removed the whole
        session, a soak review), fmt, fact, data."""
        import struct

        data_bytes = 4 * self.n
        riff_bytes = 4 + (36 if self.long else 0) + 26 + 12 + 8 + data_bytes
        rf64 = self.long and data_bytes > self.RIFF_LIMIT

        def size(n: int) -> int:   # RF64's 32-bit sizes say 'see ds64'
            return 0xFFFFFFFF if rf64 else n

        self.f.write((b"RF64" if rf64 else b"RIFF") + struct.pack("<I", size(riff_bytes)) + b"WAVE")
        if rf64:
            self.f.write(b"ds64" + struct.pack("<IQQQI", 28, riff_bytes, data_bytes, self.n, 0))
        elif self.long:   # the room ds64 takes past 4 GiB
            self.f.write(b"JUNK" + struct.pack("<I", 28) + bytes(28))
        # fmt chunk: IEEE float, mono, rate, byte rate, block align 4, 32 bits, cbSize 0
        self.f.write(b"fmt " + struct.pack("<IHHIIHHH", 18, 3, 1, self.sample_rate, 4 * self.sample_rate, 4, 32, 0))
        self.f.write(b"fact" + struct.pack("<II", 4, size(self.n)))
        self.f.write(b"data" + struct.pack("<I", size(data_bytes)))

    def write(self, samples: np.ndarray) -> None:
        x = np.asarray(samples, dtype="<f4")
        self.f.write(x.tobytes())
        self.n += len(x)

    def close(self) -> None:
        try:
            if not self.long and 4 * self.n > self.RIFF_LIMIT:   # a WAV's 32-bit sizes (struct.error: a traceback)
                raise LaughlabError(f"{self.f.name}: {self.n / self.sample_rate / 3600:.1f} h of audio at "
                                    f"{self.sample_rate} Hz is past what a WAV file holds (4 GiB): a shorter input")
            self.f.seek(0)
            self._header()
        finally:
            self.f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


#: the suffixes of recordings a folder is searched for (``detect``, a corpus folder): formats libsndfile reads
#: (``.wave``: WAV's other suffix, skipped without a word before 2026-11-29, a new-user review; ``.opus``: Ogg Opus)
AUDIO_SUFFIXES = (".wav", ".wave", ".flac", ".ogg", ".opus", ".mp3", ".aiff", ".aif")

#: recordings in formats libsndfile does not read (phones', video's): their lines say how to convert them
OTHER_MEDIA = {".m4a", ".aac", ".wma", ".mp4", ".m4b", ".3gp", ".amr", ".caf", ".webm", ".mka", ".mov", ".mkv", ".avi"}


def convert_hint(files) -> str:
    """`` (.m4a: a format laughlab does not read; convert it to WAV, e.g. ffmpeg -i IN.m4a OUT.wav)`` for files
    of :data:`OTHER_MEDIA`, else empty."""
    kinds = sorted({Path(f).suffix.lower() for f in files} & OTHER_MEDIA)
    if not kinds:
        return ""
    return (f" ({', '.join(kinds)}: {'a format' if len(kinds) == 1 else 'formats'} laughlab does not read; convert "
            f"{'it' if len(files) == 1 else 'them'} to WAV, e.g. ffmpeg -i IN{kinds[0]} OUT.wav)")
