"""Interfaces of the plugin kinds.

Every plugin is a small stateful class with a ``name``, a ``Params`` dataclass
(its configurable parameters, validated before any work starts) and a
constructor ``__init__(params, ctx)``.  Per-frame plugins implement
``reset()`` and ``step(frame)``; the same objects serve live input and files:
an offline run is a streaming run fed from a file as fast as it can go.
Rates are per second, so results do not depend on the frame rate.
"""
from __future__ import annotations

import sys
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Iterator

import numpy as np

from laughlab.core.frame import Frame

if TYPE_CHECKING:  # pragma: no cover
    from laughlab.motion.clips import ClipLibrary
    from laughlab.motion.skeleton import Skeleton


@dataclass
class NoParams:
    """A plugin without parameters."""


@dataclass
class Context:
    """What every plugin may use: frame rate, audio rate, the run's seeded generator.

    Attributes
    ----------
    fps : float
        Animation frames per second.
    sample_rate : int
        Audio sample rate of the source (Hz).
    rng : numpy.random.Generator
        The seeded generator all randomness comes from.  A plugin built by the pipeline sees its own
        (:meth:`for_plugin`): one stream per group, so changing the face leaves the scheduler's and the
        body's random draws as they were, and the conditions of an experiment are paired.
    seed : int
        The run's seed.
    calibration_s : float
        Length of the calibration phase at the start of the input (van Duijn
        2014, 3.1.1), in seconds: what the source asks for (``Source.calibration_s``),
        or the extractor's ``calibration_s`` when it sets one.
    live : bool
        The source is live (``Source.live``: the microphone), set by ``pipeline.build`` when the source
        opens: a plugin may then move slow work off the frame loop (``body=hill``'s fit in its thread).
    """

    fps: float = 60.0
    sample_rate: int = 16000
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    seed: int = 0
    calibration_s: float = 0.0
    live: bool = False
    _clips: Any = None

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    def for_plugin(self, key: str) -> "PluginContext":
        """This context as the plugin of ``key`` (its group: ``face``, ``scheduler``...; a sink's
        ``output.NAME``) sees it: everything shared, but its own generator, seeded from the run's seed and the
        key (``numpy.random.default_rng([seed, crc32(key)])``).

        Until 2026-11-27 every plugin drew from one generator, so a face's blinks moved the energy scheduler's
        random clip choices and speeds: two faces compared on one seed had different bodies."""
        import zlib

        return PluginContext(self, np.random.default_rng([self.seed, zlib.crc32(key.encode())]))

    @property
    def clips(self) -> "ClipLibrary":
        """The clip library (loaded on first use)."""
        if self._clips is None:
            from laughlab.motion.clips import ClipLibrary

            self._clips = ClipLibrary.load()
        return self._clips

    @property
    def skeleton(self) -> "Skeleton":
        return self.clips.skeleton


class PluginContext:
    """A plugin's view of the run's :class:`Context`: every attribute is the shared context's (read and
    written through), except ``rng``, the plugin's own generator (:meth:`Context.for_plugin`)."""

    __slots__ = ("_shared", "rng")

    def __init__(self, shared: Context, rng: np.random.Generator):
        object.__setattr__(self, "_shared", shared)
        object.__setattr__(self, "rng", rng)

    def __getattr__(self, name: str):
        return getattr(object.__getattribute__(self, "_shared"), name)

    def __reduce__(self):   # sinks cross to their helper process pickled (laughlab.core.background)
        return PluginContext, (object.__getattribute__(self, "_shared"), self.rng)

    def __setattr__(self, name: str, value) -> None:
        if name == "rng":
            object.__setattr__(self, name, value)
        else:
            setattr(object.__getattribute__(self, "_shared"), name, value)


class Plugin(ABC):
    """Common base: a name, a parameter dataclass, and the context."""

    kind: ClassVar[str] = ""
    name: ClassVar[str] = ""
    Params: ClassVar[type] = NoParams

    def __init__(self, params: Any = None, ctx: Context | None = None):
        self.params = params if params is not None else self.Params()
        self.ctx = ctx if ctx is not None else Context()

    def reset(self) -> None:
        """Return to the state before the first frame."""


class Source(Plugin):
    """Audio, cut into one block per animation frame.

    Frame ``k`` holds the samples ``[round(k*sr/fps), round((k+1)*sr/fps))``, so
    any sample rate works with any frame rate.

    Attributes set by ``open``: ``sample_rate`` (Hz), ``n_frames`` (None if live),
    ``truth`` (ground truth object or None), ``calibration_s`` (the calibration
    phase this input asks for, thesis 3.1.1; 0 = none).  ``reread``: ``blocks()`` may be called again,
    from another thread, while a run reads it, and gives the same blocks (a file: a detector may read
    ahead, ``Detector.prefetch``).
    """

    kind = "source"
    calibration_s: float = 0.0
    sample_rate: int = 16000
    n_frames: int | None = None
    truth: Any = None
    live: bool = False
    reread: bool = False

    def open(self) -> None:
        """Check the input and read its format; raise LaughlabError on bad input."""

    @abstractmethod
    def blocks(self) -> Iterator[np.ndarray]:
        """Yield one mono block of samples per frame (read-only float64 views of the float32 samples)."""
        ...

    def audio_path(self) -> Path | None:
        """A file holding the input audio, if there is one (for muxing, reports)."""
        return None

    def close(self) -> None:
        """Release devices and files."""


class Extractor(Plugin):
    """Turns the audio of one frame into named control signals in ``frame.control``."""

    kind = "extractor"

    @abstractmethod
    def step(self, block: np.ndarray, frame: Frame) -> None:
        """Read ``block``, the frame's mono float samples in [-1, 1] at ``ctx.sample_rate`` (frame k holds
        ``round((k+1)*sr/fps) - round(k*sr/fps)`` of them), and write this frame's control signals into
        ``frame.control``: ``mcs``, the motion control signal in [0, 1] that the detector, scheduler, body and face
        read, and any others; the same names every frame, finite floats (``laughlab.testing.check_plugin``)."""


class Detector(Plugin):
    """Tells laughter from other sound and gates what drives the body and face.

    Runs right after the extractor on the same block: writes
    ``control['laughter']`` (probability in [0, 1]) and ``control['laugh_gate']``
    (the gain in [0, 1]), and applies the gain to the extractor's driving
    signals (see ``laughlab.detector.model.apply_gate``).  Look-ahead: none beyond the frame's
    own audio block.
    """

    kind = "detector"

    @abstractmethod
    def step(self, block: np.ndarray, frame: Frame) -> None:
        """Read the frame's ``block`` (as :meth:`Extractor.step`) and ``frame.control`` after the extractor; write
        ``laughter`` and ``laugh_gate`` (both in [0, 1]) and gate the driving signals, as the class says."""

    def prefetch(self, blocks) -> None:
        """Called after ``reset`` when the input can be read again (``Source.reread``): ``blocks()`` gives
        the run's blocks from the start.  A detector may compute ahead from them (``detector=yamnet`` runs
        its model in a helper thread); what ``step`` writes must stay the same bytes as without it."""


class Scheduler(Plugin):
    """Starts and stops full-body clips: appends :class:`ClipEvent` to ``frame.events``."""

    kind = "scheduler"

    @abstractmethod
    def step(self, frame: Frame) -> None:
        """Read ``frame.control`` (``mcs``, ``clip_gate``...); append the frame's clip starts and stops to
        ``frame.events`` (clips of ``ctx.clips``), write ``energy`` (and ``clip_energy``) into the channels."""


class Body(Plugin):
    """Body driver: writes body channels and joint offsets into the frame."""

    kind = "body"

    @abstractmethod
    def step(self, frame: Frame) -> None:
        """Read ``frame.control``; write the body's channels (``chest``, ``belly``: shape weights, 0 the base, 1 the
        expanded shape, which may extrapolate) and ``frame.offsets``: joint rotations added to the clip pose (joint ->
        (Z, X, Y) degrees, BVH order)."""


class Face(Plugin):
    """Face model: writes face channels into the frame."""

    kind = "face"

    @abstractmethod
    def step(self, frame: Frame) -> None:
        """Read ``frame.control``; write the face's channels in [0, 1] (``smile``, ``jaw``, ``eyes_closed``, or
        ARKit's own names as ``arkit.NAME``)."""


@dataclass
class RunInfo:
    """What a sink learns when a run opens.

    Attributes
    ----------
    out_dir : Path
        The run directory.
    fps : float
        Frames per second.
    skeleton : Skeleton
        The skeleton of the poses.
    n_frames : int or None
        Number of frames, if known in advance.
    source : Source
        The audio source (for its audio and ground truth).
    config : dict
        The composed configuration.
    """

    out_dir: Path
    fps: float
    skeleton: Any
    n_frames: int | None
    source: Any = None
    config: dict = field(default_factory=dict)


@dataclass
class Chunk:
    """A run of consecutive frames handed to the sinks.

    Attributes
    ----------
    times : ndarray (N,)
        Frame times (s).
    channels : dict[str, ndarray (N,)]
        Every named channel (controls and outputs).
    poses : ndarray (N, C)
        Skeleton poses (BVH channel vectors).
    events : list[ClipEvent]
        Clip events within these frames.
    labels : list[str | None]
        Per-frame pseudo-phoneme labels.
    capture_ns : ndarray (N,) of int64 or None
        ``time.perf_counter_ns()`` when each frame's audio block reached the
        pipeline (for latency measurements; None when unknown).
    audio_s : float or None
        Seconds of audio the run has read up to the end of these frames (samples / sample rate):
        on the last chunk, the input's own length, which the frames' span (frames / fps) exceeds
        by up to a frame. None when unknown.
    input_end_s : float or None
        Where the input ended (s), once it has and ``run_out`` goes on in silence; None before (and
        always without ``run_out``): ``audio_s`` then counts the silence too.
    """

    times: np.ndarray
    channels: dict
    poses: np.ndarray
    events: list
    labels: list
    capture_ns: np.ndarray | None = None
    audio_s: float | None = None
    input_end_s: float | None = None

    def events_by_frame(self, fps: float) -> list[list]:
        """The chunk's clip events, frame by frame: an event goes to the frame whose time it falls on (within half
        a frame), for a sink that hands frames on one at a time (the live viewer, a session)."""
        out: list[list] = [[] for _ in range(len(self.times))]
        for e in self.events:
            out[min(len(out) - 1, int(np.searchsorted(self.times, e.time_s - 0.5 / fps)))].append(e)
        return out


class Sink(Plugin):
    """Writes a run's frames somewhere.

    File sinks write to temporary names and move them into place in ``close``;
    ``abort`` removes whatever they wrote, so a failed run leaves nothing half-written.
    """

    kind = "sink"
    #: may run in the helper process of an offline run (:mod:`laughlab.core.background`): the sink
    #: only writes files, pickles, and uses nothing of ``run.source`` but ``name``, ``live``,
    #: ``sample_rate``, ``n_frames`` and ``truth``
    background: ClassVar[bool] = False
    #: the names the sink writes at the top of the run folder (files or folders).  A run refuses a folder
    #: that holds a file of the user's by one of them, even with ``overwrite=true`` (:mod:`laughlab.core.rundir`)
    files: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def planned(cls, params: dict) -> tuple[str, ...]:
        """The names a run with these parameters (the ``output.<name>`` node) will write: :attr:`files`, or,
        for a sink whose file name is a parameter, that name."""
        return cls.files

    def open(self, run: RunInfo) -> None:
        """The run starts: its folder, frame rate, skeleton, source and configuration (:class:`RunInfo`)."""
        self.run = run

    def write(self, chunk: Chunk) -> None:
        """Take the next chunk of frames."""

    def close(self) -> list[Path]:
        """Finish; return the files written."""
        return []

    def abort(self) -> None:
        """Remove partial output after a failure."""


#: the channels each stage writes at least (docs/architecture.md, "Writing a plugin"): what every sink and metric
#: reads (a plugin authors' review: a face without jaw, or a face registered as a body, ran without a word and the
#: experiment's jaw metrics went "n/a")
REQUIRED = {"face": ("smile", "jaw", "blink", "eyes_closed"), "body": ("chest", "belly")}


_WARNED: set = set()


def check_contract(channels, names: dict) -> None:
    """On a run's first frame: the face and the body (``names``: stage -> plugin name) wrote their channels; if
    not, one warning line on stderr (once per plugin in a process: an experiment's trials, each of its worker
    processes once), as a face that drives only the jaw is a fair experiment, but the character's other shapes
    then stay at rest and metrics that read them are n/a."""
    for stage, needed in REQUIRED.items():
        missing = [c for c in needed if c not in channels]
        if missing and (stage, names.get(stage)) not in _WARNED:
            _WARNED.add((stage, names.get(stage)))
            print(f"laughlab: warning: {stage} {names.get(stage)!r} writes no {', '.join(missing)} (a {stage} writes "
                  f"{', '.join(needed)}: docs/architecture.md); the character's {'/'.join(missing)} stay at rest "
                  "and the metrics that read them are n/a", file=sys.stderr)
