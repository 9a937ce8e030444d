"""What ``laughlab detect`` found in each input, kept until its batch is written: a batch interrupted or stopped by
a file it could not read starts again where it was, not from its first file.

A review at scale (2026-11-29): a Ctrl-C 14 s into a 5.2-hour corpus said ``interrupted after 4 of 322 input(s);
nothing was written``, and a file damaged 30 s in, found after the whole corpus was read, lost all of it; a batch
writes all of its outputs or none, so the work itself was lost.  Each input's segments are kept in
``$LAUGHLAB_DATA/detect`` (``~/.cache/laughlab/detect``) under a key of everything they depend on: the file (its
resolved path, size and modification time), the channel, the settings (``--hop``, ``--smooth``, ``--threshold``,
``--min-length``), and laughlab's detector itself (the model files' and the detector modules' bytes), so a changed
file, setting or detector is computed again.  A batch written whole removes its inputs' entries.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from laughlab.detector.segments import Segment

#: the detector's own files: a change to any of them computes every input again
_CODE = ("segments.py", "yamnet.py", "yamnet_model.py", "stream16k.py", "detect_cache.py")


def cache_dir() -> Path:
    from laughlab.corpora.fetch import data_dir

    return data_dir() / "detect"


def _detector_digest() -> str:
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for name in _CODE:
        h.update((here / name).read_bytes())
    data = here.parent / "data" / "yamnet"
    for f in sorted(data.glob("*")):
        if f.is_file():
            h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()


class DetectCache:
    """The kept segments of one batch's settings: :meth:`get` an input's ``(duration, segments)`` or None,
    :meth:`put` them, :meth:`forget` the batch's entries once its outputs are written."""

    def __init__(self, settings: dict):
        self.settings = json.dumps(settings, sort_keys=True)
        self.code = _detector_digest()
        self.folder = cache_dir()
        self.used: list[Path] = []

    def _path(self, f: Path, channel: int | None) -> Path | None:
        try:
            st = Path(f).stat()
            key = json.dumps([str(Path(f).resolve()), st.st_size, st.st_mtime_ns, channel, self.settings, self.code])
        except OSError:
            return None
        p = self.folder / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".json")
        self.used.append(p)
        return p

    def get(self, f: Path, channel: int | None) -> tuple[float, list[Segment]] | None:
        p = self._path(f, channel)
        try:
            doc = json.loads(p.read_text(encoding="utf-8")) if p is not None else None
            return (float(doc["duration"]), [Segment(*s) for s in doc["segments"]]) if doc else None
        except (OSError, ValueError, KeyError, TypeError):
            return None

    def put(self, f: Path, channel: int | None, duration: float, segments: list[Segment]) -> None:
        p = self._path(f, channel)
        if p is None:
            return
        doc = {"duration": duration, "segments": [[s.start, s.end, s.prob] for s in segments]}
        try:   # a cache that cannot be written costs a rerun's time, nothing else
            p.parent.mkdir(parents=True, exist_ok=True)
            tmp = p.with_suffix(".part")
            tmp.write_text(json.dumps(doc), encoding="utf-8")
            tmp.replace(p)
        except OSError:
            pass

    def forget(self) -> None:
        for p in self.used:
            try:
                p.unlink()
            except OSError:
                pass
