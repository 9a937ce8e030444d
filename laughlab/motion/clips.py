"""Full-body laughter clips (keyframed BVH motions) and the clip library.

A clip is a dense ``(F, 3 + 3J)`` pose array at the clip frame rate (24 fps for
the bundled library) plus an energy value (thesis section 5.5), a loop flag and
eye keyframes (thesis section 3.3.3).  Playback time ``t`` maps to the frame
position ``t * fps``; a clip lasts ``length_frames / fps`` seconds.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from laughlab.core.scalar import interp
from laughlab.io.bvh import read_bvh
from laughlab.motion.skeleton import HUMANOID, Skeleton

__all__ = ["Clip", "ClipLibrary", "EYE_RAMP_FRAMES", "SKELETONS"]

EYE_RAMP_FRAMES = 3.0
"""Frames the eyes take to close or open after an eye keyframe."""

SKELETONS: dict[str, Skeleton] = {"humanoid": HUMANOID}


@dataclass
class Clip:
    """One full-body animation.

    Attributes
    ----------
    name : str
    energy : float
        Laughing energy consumed over the clip (thesis units).
    length_frames : int
        Number of frames ``F``.
    fps : float
        Frame rate of ``poses``, frames per second.
    poses : ndarray, shape (F, 3 + 3J)
        Dense pose vectors (root cm, ZXY Euler degrees).
    eyes : list of (frame, closed)
        Eye keyframes, ``closed`` 0 (open) or 1 (closed).  At a key the eyes
        start moving to the new state and reach it ``EYE_RAMP_FRAMES`` later.
    loop : bool
        If true, sampling wraps around (frame ``F`` equals frame 0).
    """

    name: str
    energy: float
    length_frames: int
    fps: float
    poses: np.ndarray
    eyes: list[tuple[float, float]] = field(default_factory=lambda: [(0.0, 0.0)])
    loop: bool = False

    def __post_init__(self) -> None:
        self.poses = np.asarray(self.poses, dtype=np.float64)
        if self.poses.ndim != 2 or len(self.poses) != self.length_frames:
            raise ValueError(f"clip {self.name!r}: poses shape {self.poses.shape} does not match "
                             f"length_frames={self.length_frames}")
        self.eyes = sorted((float(f), float(v)) for f, v in self.eyes) or [(0.0, 0.0)]
        x, y = [self.eyes[0][0]], [self.eyes[0][1]]
        for (f0, v0), (f1, v1), nxt in zip(self.eyes, self.eyes[1:], self.eyes[2:] + [(np.inf, 0)]):
            ramp = min(EYE_RAMP_FRAMES, 0.5 * (nxt[0] - f1))
            x += [f1, f1 + ramp]
            y += [v0, v1]
        self._eye_x, self._eye_y = np.array(x), np.array(y)
        self._eye_xl, self._eye_yl = [float(v) for v in x], [float(v) for v in y]  # for scalar interp

    @property
    def duration_s(self) -> float:
        """Clip duration ``length_frames / fps`` in seconds."""
        return self.length_frames / self.fps

    def _frame_pos(self, t_s: np.ndarray) -> np.ndarray:
        f = np.asarray(t_s, dtype=np.float64) * self.fps
        if self.loop:
            return np.mod(f, self.length_frames)
        return np.clip(f, 0.0, self.length_frames - 1)

    def sample_many(self, t_s: np.ndarray) -> np.ndarray:
        """Poses at times ``t_s`` (seconds, array-like), linear between frames.

        Returns
        -------
        ndarray, shape (N, 3 + 3J)
        """
        f = np.atleast_1d(self._frame_pos(t_s))
        i0 = np.floor(f).astype(int)
        w = (f - i0)[:, None]
        i1 = (i0 + 1) % self.length_frames if self.loop else np.minimum(i0 + 1, self.length_frames - 1)
        return (1.0 - w) * self.poses[i0] + w * self.poses[i1]

    def sample(self, t_s: float) -> np.ndarray:
        """Pose vector at time ``t_s`` seconds (clamped to the end, or wrapped if ``loop``).

        The same arithmetic as :meth:`sample_many`, without array set-up: this
        runs once per frame in the mixer.
        """
        n = self.length_frames
        f = t_s * self.fps
        if self.loop:
            f %= n
        elif f <= 0.0:
            return self.poses[0].copy()
        elif f >= n - 1:
            return self.poses[n - 1].copy()
        i0 = int(f)
        w = f - i0
        i1 = i0 + 1 if i0 + 1 < n else 0
        return (1.0 - w) * self.poses[i0] + w * self.poses[i1]

    def sample_rows(self, t_s: np.ndarray) -> np.ndarray:
        """:meth:`sample` at each of the times ``t_s`` (s): the same arithmetic element by element.

        Returns
        -------
        ndarray, shape (N, 3 + 3J)
            Row k is ``sample(t_s[k])`` (bit for bit, up to the sign of a zero).
        """
        n = self.length_frames
        f = np.asarray(t_s, dtype=np.float64) * self.fps
        lo = hi = None
        if self.loop:
            f = np.mod(f, n)  # Python's float % and np.mod share fmod's arithmetic
        else:
            lo, hi = f <= 0.0, f >= n - 1
            f = np.where(lo | hi, 0.0, f)
        i0 = f.astype(np.int64)
        w = (f - i0)[:, None]
        i1 = np.where(i0 + 1 < n, i0 + 1, 0)
        out = (1.0 - w) * self.poses[i0] + w * self.poses[i1]
        if lo is not None:
            out[lo] = self.poses[0]
            out[hi] = self.poses[n - 1]
        return out

    def eyes_closed_many(self, t_s: np.ndarray) -> np.ndarray:
        """Eye closure in ``[0, 1]`` at times ``t_s`` (seconds, array-like)."""
        f = np.asarray(t_s, dtype=np.float64) * self.fps
        f = np.mod(f, self.length_frames) if self.loop else f
        return np.interp(f, self._eye_x, self._eye_y)

    def eyes_closed(self, t_s: float) -> float:
        """Eye closure in ``[0, 1]`` at time ``t_s`` seconds (1 = closed)."""
        f = t_s * self.fps
        if self.loop:
            f %= self.length_frames
        return interp(f, self._eye_xl, self._eye_yl)  # = float(np.interp(...)), 5x faster per frame


def _default_folder() -> Path:
    from importlib.resources import files

    return Path(str(files("laughlab_plugins") / "clips"))


_READ: dict = {}


def _read_clip(path: Path):
    """``read_bvh(path)``, parsed once per process while the file is unchanged (by size and mtime).

    Every run builds its library; an experiment or a sweep in one process builds hundreds, and parsing
    the twelve bundled BVH files costs ~40 ms each time.  The motion array is shared, so it is read-only.
    """
    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _READ:
        sk, motion, frame_time = read_bvh(path)
        motion.flags.writeable = False
        _READ[key] = (sk, motion, frame_time)
    return _READ[key]


class ClipLibrary:
    """A set of clips sharing one skeleton and frame rate.

    Parameters
    ----------
    clips : iterable of Clip
    skeleton : Skeleton
    fps : float
    """

    def __init__(self, clips, skeleton: Skeleton = HUMANOID, fps: float = 24.0) -> None:
        self._clips = {c.name: c for c in clips}
        self.skeleton = skeleton
        self.fps = float(fps)

    @classmethod
    def load(cls, folder: str | Path | None = None) -> "ClipLibrary":
        """Load ``library.json`` and its BVH files from ``folder``.

        Parameters
        ----------
        folder : str or Path, optional
            Defaults to the bundled ``laughlab_plugins/clips`` folder.

        Raises
        ------
        ValueError
            If the index or a clip file is missing, or a clip does not match
            the library skeleton, frame count or frame rate.
        """
        folder = Path(folder) if folder is not None else _default_folder()
        index = folder / "library.json"
        if not index.is_file():
            raise ValueError(f"clip library index {index} not found")
        meta = json.loads(index.read_text(encoding="utf-8"))
        fps = float(meta["fps"])
        if meta.get("skeleton", "humanoid") not in SKELETONS:
            raise ValueError(f"{index}: unknown skeleton {meta.get('skeleton')!r}")
        skeleton = SKELETONS[meta.get("skeleton", "humanoid")]
        clips = []
        for c in meta["clips"]:
            path = folder / c["file"]
            if not path.is_file():
                raise ValueError(f"clip {c['name']!r}: file {path} not found")
            sk, motion, frame_time = _read_clip(path)
            if motion.shape[1] != skeleton.n_channels or sk.names != skeleton.names:
                raise ValueError(f"clip {c['name']!r}: {path.name} has {motion.shape[1]} channels / "
                                 f"{sk.n_joints} joints, skeleton {meta.get('skeleton')!r} needs "
                                 f"{skeleton.n_channels} channels")
            if len(motion) != int(c["length_frames"]):
                raise ValueError(f"clip {c['name']!r}: {path.name} has {len(motion)} frames, "
                                 f"library.json says {c['length_frames']}")
            if abs(frame_time * fps - 1.0) > 1e-4:
                raise ValueError(f"clip {c['name']!r}: frame time {frame_time} s does not match fps {fps}")
            clips.append(Clip(c["name"], float(c["energy"]), len(motion), fps, motion,
                              [tuple(e) for e in c.get("eyes", [[0, 0]])], bool(c.get("loop", False))))
        return cls(clips, skeleton, fps)

    @property
    def names(self) -> tuple[str, ...]:
        """Clip names in library order."""
        return tuple(self._clips)

    @property
    def idle(self) -> Clip:
        """The looping ``idle`` clip."""
        return self["idle"]

    def __getitem__(self, name: str) -> Clip:
        try:
            return self._clips[name]
        except KeyError:
            raise KeyError(f"no clip {name!r}; have {', '.join(self._clips)}") from None

    def __iter__(self) -> Iterator[Clip]:
        return iter(self._clips.values())

    def __len__(self) -> int:
        return len(self._clips)

    def __contains__(self, name: object) -> bool:
        return name in self._clips
