"""What flows between plugins during one animation frame.

Time is discrete: one :class:`Frame` per animation tick (default 60 fps).  The
pipeline hands the same :class:`Frame` object to the extractor, scheduler, body
and face in that order; each reads what earlier stages wrote and adds its own
named values.  All values are plain floats so a frame costs microseconds.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence


@dataclass(slots=True)
class ClipEvent:
    """A clip starting or stopping.

    Attributes
    ----------
    time_s : float
        Time of the event (s).
    kind : str
        ``"start"`` or ``"stop"``.
    clip : str
        Clip name in the library.
    energy : float
        The clip's laughing energy e(a) (thesis Eq. 4.1 units).
    speed : float
        Playback speed factor (1 = the clip's authored speed).
    blend_s : float
        Blend-in time of a start (s).
    offset_s : float
        Where in the clip playback starts (s of clip time); 0 = its first frame.
    end_s : float or None
        Where in the clip playback ends (s of clip time); None = the clip's end.
        With ``offset_s`` this plays a segment of a clip (segment concatenation).
    reason : str
        For stops: ``"finished"``, ``"overruled"`` (``energy``) or ``"next"`` (``concat``: a new
        pseudo-phoneme); ``"end"`` is what the harness' clip plays (``TrialData.plays``) give a
        clip still playing when the input ends (no event is written for it).
    """

    time_s: float
    kind: str
    clip: str
    energy: float
    speed: float = 1.0
    blend_s: float = 0.0
    reason: str = ""
    offset_s: float = 0.0
    end_s: float | None = None


@dataclass(slots=True)
class Frame:
    """The state of one animation frame.

    Attributes
    ----------
    index : int
        Frame number, from 0.
    time_s : float
        Time of the frame's start, ``index / fps`` (s); the frame's audio is
        ``[time_s, time_s + dt)``, so its values are known at ``time_s + dt``.
    dt : float
        Frame period 1/fps (s).
    control : dict[str, float]
        Named control signals from the extractor (``mcs``, ``rms``, ...).
    label : str or None
        Optional pseudo-phoneme label of the frame.
    channels : dict[str, float]
        Named output channels (face and body shape weights, laughing energy, ...).
        Written to ``channels.csv``.
    offsets : dict[str, tuple[float, float, float]]
        Joint rotation offsets (degrees, BVH order Z, X, Y) added to the clip pose.
    events : list[ClipEvent]
        Clip starts and stops decided this frame.
    clip_eyes : float
        Eye closure keyed by the playing clip, in [0, 1] (thesis 3.3.3).
    """

    index: int = 0
    time_s: float = 0.0
    dt: float = 1.0 / 60.0
    control: dict = field(default_factory=dict)
    label: str | None = None
    channels: dict = field(default_factory=dict)
    offsets: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    clip_eyes: float = 0.0


def clip_blocks(events: Sequence[ClipEvent], end_time: float) -> list[tuple[str, float, float, float]]:
    """Pair clip start and stop events into ``(clip, start_s, stop_s, energy)`` blocks."""
    blocks, open_ = [], {}
    for ev in events:
        if ev.kind == "start":
            open_[ev.clip] = ev
        elif ev.kind == "stop" and ev.clip in open_:
            s = open_.pop(ev.clip)
            blocks.append((ev.clip, s.time_s, ev.time_s, s.energy))
    for name, s in open_.items():
        blocks.append((name, s.time_s, end_time, s.energy))
    return sorted(blocks, key=lambda b: b[1])
