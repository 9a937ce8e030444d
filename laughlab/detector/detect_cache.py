"""What ``laughlab detect`` found in each input, kept until its batch is written: a batch interrupted or stopped by
a file it could not read starts again where it was, not from its first file.

A review at scale (2026-11-29): a Ctrl-C 14 s into a 5.2-hour corpus said ``interrupted after 4 of 322 input(s);
nothing was written``, and a file damaged 30 s in, found after the whole corpus was read, lost all of it; a batch
writes all of its outputs or none, so the work itself was lost.  Each input's segments are kept in
``$LAUGHLAB_DATA/detect`` (``~/.cache/laughlab/detect``) under a key of everything they depend on: the file (its
identity, :func:`file_key`), the channel, the settings (``--hop``, ``--smooth``, ``--threshold``, ``--min-length``),
and laughlab's detector itself (the model files, the detector's and the audio reading's modules, the packages'
versions: :func:`_detector_digest`), so a changed file, setting or detector is computed again.  A batch written
whole removes its inputs' entries; entries older than :data:`MAX_AGE_S` go when a batch starts.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from laughlab.core.outfiles import unwrite
from laughlab.detector.segments import Segment

#: the detector's own files and the reading of audio: a change to any of them computes every input again
_CODE = ("segments.py", "yamnet.py", "yamnet_model.py", "stream16k.py", "detect.py", "detect_cache.py",
         "../io/audio.py")
#: the packages whose versions decide the figures too
_PACKAGES = ("numpy", "scipy", "soundfile", "ai-edge-litert")
#: entries older than this are removed when a batch starts (a run never finished, a file since edited; s)
MAX_AGE_S = 30 * 86400


def cache_dir() -> Path:
    from laughlab.corpora.fetch import data_dir

    return data_dir() / "detect"


def _detector_digest() -> str | None:
    """The detector's files, the model's and the packages' versions, hashed; None where one cannot be read (the
    cache is then off)."""
    from importlib.metadata import PackageNotFoundError, version

    from laughlab.detector.yamnet_model import MODEL_SHA256

    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    try:
        for name in _CODE:
            h.update((here / name).read_bytes())
        for f in sorted((here.parent / "data" / "yamnet").glob("*")):
            if f.name == "yamnet.tflite":   # loading it checked its sha256 already (Yamnet(), before the batch)
                h.update(f.name.encode() + MODEL_SHA256.encode())
            elif f.is_file():
                h.update(f.name.encode() + f.read_bytes())
    except OSError:
        return None
    for pkg in _PACKAGES:
        try:
            h.update(f"{pkg} {version(pkg)}".encode())
        except PackageNotFoundError:
            h.update(pkg.encode())
    return h.hexdigest()


def file_key(f: Path) -> tuple | None:
    """What says a file is the same file: its resolved path, device and inode, size, and modification and change
    times (a copy made with its old modification time, ``cp -p`` or ``rsync -a``, has a new change time; a diff
    review's replaced file of the same size and time took the old one's segments); None if it cannot be read."""
    try:
        st = Path(f).stat()
        return (str(Path(f).resolve()), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    except OSError:
        return None


class DetectCache:
    """The kept segments of one batch's settings: :meth:`get` an input's ``(duration, segments)`` or None,
    :meth:`put` them, :meth:`forget` the batch's entries once its outputs are written."""

    def __init__(self, settings: dict):
        self.settings = json.dumps(settings, sort_keys=True)
        self.code = _detector_digest()
        self.folder = cache_dir()
        self.used: set[Path] = set()
        self.ok = self.code is not None   # every input done is kept (the interrupt's line says so only then)
        self._prune()

    def _prune(self) -> None:
        import time

        try:
            unwrite([p for p in self.folder.iterdir() if time.time() - p.stat().st_mtime > MAX_AGE_S])
        except OSError:
            pass

    def path(self, key: tuple | None, channel: int | None) -> Path | None:
        """The entry of the file ``key`` (:func:`file_key`) and ``channel`` under these settings."""
        if key is None or self.code is None:
            return None
        text = json.dumps([*key, channel, self.settings, self.code])
        p = self.folder / (hashlib.sha256(text.encode()).hexdigest()[:32] + ".json")
        self.used.add(p)
        return p

    def get(self, key: tuple | None, channel: int | None) -> tuple[float, list[Segment]] | None:
        p = self.path(key, channel)
        try:
            doc = json.loads(p.read_text(encoding="utf-8")) if p is not None else None
            return (float(doc["duration"]), [Segment(*s) for s in doc["segments"]]) if doc else None
        except (OSError, ValueError, KeyError, TypeError):
            return None

    def put(self, key: tuple | None, channel: int | None, duration: float, segments: list[Segment]) -> None:
        """Keep what the file ``key`` gave; ``key`` taken before it was read (a file changed while it was computed
        is not kept: :func:`file_key` of it after the read differs)."""
        p = self.path(key, channel)
        if p is None:
            self.ok = False
            return
        doc = {"duration": duration, "segments": [[s.start, s.end, s.prob] for s in segments]}
        try:   # a cache that cannot be written costs a rerun's time, nothing else
            p.parent.mkdir(parents=True, exist_ok=True)
            tmp = p.with_name(f"{p.stem}.{os.getpid()}.part")
            tmp.write_text(json.dumps(doc), encoding="utf-8")
            tmp.replace(p)
        except OSError:
            self.ok = False

    def forget(self) -> None:
        unwrite(self.used)
