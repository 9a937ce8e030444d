"""Stand-ins for testing pipelines and plugins without hardware, and the plugin contract's checks.

:func:`check_plugin` is what a plugin's own tests call (docs/architecture.md, "Testing a plugin"): it builds the
class as a run does, runs it in its stage between built-in plugins on seeded synthetic laughter and checks what
the rest of laughlab relies on, raising :class:`ContractError` (an ``AssertionError``: a failed pytest assert)
with one line per broken rule.  :func:`run_frames` gives the frames themselves for a test's own asserts.
"""
from __future__ import annotations

import math
import pickle
import tempfile
from pathlib import Path
from types import SimpleNamespace
from typing import Sequence

import numpy as np

from laughlab.core.stages import Stepper
from laughlab.io.audio import cut_frames, frame_edges
from laughlab.core.bases import REQUIRED, Context, Source
from laughlab.core.errors import LaughlabError

__all__ = ["ChunkedSource", "ContractError", "check_plugin", "run_frames"]


class ChunkedSource(Source):
    """A microphone stand-in: given audio delivered in irregular device blocks.

    The blocks cycle through ``sizes`` (samples); the pipeline re-cuts them into
    frames exactly as it does a live device's, so a run on this source must equal
    the offline run of the same audio.
    """

    name = "chunked"
    live = True

    def __init__(self, audio: np.ndarray, sample_rate: int, ctx: Context, sizes: Sequence[int]):
        super().__init__(None, ctx)
        self.audio, self.sample_rate, self.sizes = audio, sample_rate, list(sizes)
        self.n_frames = None

    def blocks(self):
        def chunks():
            i, k = 0, 0
            while i < len(self.audio):
                s = self.sizes[k % len(self.sizes)]
                yield self.audio[i:i + s]
                i, k = i + s, k + 1
        return cut_frames(chunks(), self.sample_rate, self.ctx.fps)


class ContractError(AssertionError):
    """A plugin breaks the contract of its kind: the message has one line per rule broken."""


#: the stages a run steps each frame, in order, and the built-in each is filled with around the plugin checked
#: (``detector=none``: the papers' pipelines, no model to load)
STAGES = (("extractor", "rms"), ("detector", "none"), ("scheduler", "energy"), ("body", "shapes"), ("face", "smile"))


def _build(cls: type, params, ctx: Context):
    """``cls`` as a run builds it: its class checked as at registration, ``params`` (a mapping, its defaults when
    None) checked as the command line's, its own random stream."""
    from laughlab.core import plugins

    kind = getattr(cls, "kind", "")
    if kind not in plugins.KINDS or kind == "metric":
        raise ContractError(f"{getattr(cls, '__name__', cls)!r} is no plugin class: subclass one of laughlab's "
                            "Source, Extractor, Detector, Scheduler, Body, Face or Sink")
    name = getattr(cls, "name", "") or ""
    if not name:
        raise ContractError(f"{cls.__name__} has no name: give its class name = '...'")
    group = plugins.group_of(kind)
    try:
        plugins._check_class(kind, name, cls, "check_plugin")
        values = plugins.make_params(cls, params or {}, f"output.{name}" if kind == "sink" else f"{group}.{name}")
    except Exception as exc:  # noqa: BLE001 - the line a run would print
        raise ContractError(str(exc)) from None
    return cls(values, ctx.for_plugin(f"output.{name}" if kind == "sink" else group))


def _audio(seconds: float, sample_rate: int, seed: int) -> np.ndarray:
    from laughlab.synth.laughter import SyntheticLaughter

    return SyntheticLaughter(seed=seed, duration_s=seconds, sample_rate=sample_rate).audio()


def run_frames(cls: type, params=None, *, seconds: float = 4.0, seed: int = 0, fps: float = 60.0,
               sample_rate: int = 16000, reset: bool = True, plugin=None) -> list:
    """The frames of ``seconds`` of seeded synthetic laughter with a plugin of ``cls`` (an extractor, detector,
    scheduler, body or face) in its stage and the built-ins of :data:`STAGES` in the others, stepped as
    :func:`laughlab.core.pipeline.execute` steps them (the clip mixer between scheduler and body).  ``plugin``: an
    instance of ``cls`` to step instead of a new one (``reset()`` first unless ``reset=False``)."""
    from laughlab.core import plugins
    from laughlab.core.frame import Frame
    from laughlab.core.mixer import Mixer

    ctx = Context(fps=float(fps), sample_rate=sample_rate, rng=np.random.default_rng(seed), seed=seed)
    mine = plugin if plugin is not None else _build(cls, params, ctx)
    if mine.kind not in dict(STAGES):
        raise ContractError(f"run_frames steps extractors, detectors, schedulers, bodies and faces, not a {mine.kind}")
    stages = [mine if group == mine.kind else plugins.create(group, name, {}, ctx) for group, name in STAGES]
    mixer = Mixer(ctx.clips)
    for stage in stages:
        if stage is not mine or reset:
            stage.reset()
    ext, det, sch, body, face = stages
    frames = []
    audio = _audio(seconds, sample_rate, seed)
    stepper = Stepper(ext, det, sch, body, face, mixer)
    try:
        for k, block in enumerate(cut_frames([audio], sample_rate, fps)):
            frame = Frame(k, k / fps, 1.0 / fps, {}, None, {}, {}, [], 0.0)
            if k == 0:   # as a run's first frame: a step of the wrong signature, an extractor without mcs, one line
                stepper.checked(block, frame, warn=False)
            else:
                stepper.step(block, frame)   # the mixer's advance: a clip the library lacks, the run's line
            mixer.note(frame)
            frames.append(frame)
        mixer.take()               # a joint the skeleton lacks: the run's line
    except LaughlabError as exc:
        raise ContractError(f"{mine.kind} {mine.name!r}: {exc}") from None
    return frames


#: how far outside [0, 1] a weight may round (``body=hill``'s belly: -1.5e-19 on a silent first frame)
TOL = 1e-9


def _values(frames, attr: str) -> list[tuple]:
    return [tuple((k, float(v)) for k, v in getattr(f, attr).items()) for f in frames]


def _check_frames(kind: str, frames: list, clips, skeleton) -> list[str]:
    """What a run relies on in a stage's frames: one string per broken rule."""
    from laughlab.face.facs import ARKIT_BLENDSHAPES

    bad: list[str] = []
    first = frames[0]
    where = "control" if kind in ("extractor", "detector") else "channels"   # a detector's outputs are controls
    written = set(getattr(first, where))
    needed = {"extractor": ("mcs",), "detector": ("laughter", "laugh_gate")}.get(kind) or REQUIRED.get(kind, ())
    missing = [c for c in needed if c not in written]
    if missing:
        bad.append(f"writes no {', '.join(missing)} (a {kind} writes {', '.join(needed)})")
    for attr in ("control", "channels"):
        keys = list(getattr(first, attr))
        for f in frames:
            if list(getattr(f, attr)) != keys:
                odd = ", ".join(sorted(set(getattr(f, attr)) ^ set(keys)))
                bad.append(f"frame {f.index} writes other {attr} than frame 0 ({odd}): every frame writes the same "
                           "ones")
                break
            for k, v in getattr(f, attr).items():
                if not isinstance(v, (int, float, np.integer, np.floating, np.bool_)) or not math.isfinite(v):
                    bad.append(f"{attr} {k!r} is {v!r} ({type(v).__name__}) at frame {f.index}: a finite number")
                    break
            else:
                continue
            break
    shapes = ("chest", "belly") if kind == "body" else ()   # shape weights: outside [0, 1] they extrapolate
    unit = [c for c in (*needed, *(k for k in written if k.startswith("arkit.")),
                        *(("clip_gate",) if kind == "detector" and "clip_gate" in written else ())) if c not in shapes]
    for c in unit:
        vals = [getattr(f, where).get(c, 0.0) for f in frames]
        out = [i for i, v in enumerate(vals) if isinstance(v, (int, float)) and not -TOL <= v <= 1.0 + TOL]
        if out:
            j = out[0]
            bad.append(f"{c} is {vals[j]} at frame {j}: a weight in [0, 1]")
    if kind == "detector":   # laugh_gate alone gates nothing: the character laughed on (a plugin author's review)
        from laughlab.core.blame import one_number as num

        shut = [f for f in frames if num(f.control.get("laugh_gate", 1.0)) and f.control["laugh_gate"] < 0.5
                and "mcs_ungated" not in f.control and num(f.control.get("mcs", 0.0)) and f.control["mcs"] > 0.0]
        if shut:
            bad.append(f"laugh_gate is {shut[0].control['laugh_gate']:g} at frame {shut[0].index} but mcs "
                       f"{shut[0].control['mcs']:g} is not gated: a detector gates the driving signals with "
                       "laughlab.detector.model.apply_gate(frame, gain)")
    unknown = sorted(k[6:] for k in written if k.startswith("arkit.") and k[6:] not in ARKIT_BLENDSHAPES)
    if unknown:
        bad.append(f"arkit.{', arkit.'.join(unknown)}: not ARKit blendshape names "
                   "(laughlab.face.facs.ARKIT_BLENDSHAPES)")
    for f in frames:
        for joint, rot in f.offsets.items():
            if joint not in skeleton.names:
                bad.append(f"frame {f.index} offsets joint {joint!r}, which the skeleton lacks "
                           f"({', '.join(skeleton.names)})")
            elif len(tuple(rot)) != 3 or not all(math.isfinite(float(a)) for a in rot):
                bad.append(f"frame {f.index} offsets {joint!r} by {rot!r}: three finite angles (z, x, y), degrees")
            else:
                continue
            return bad
        for ev in f.events:
            if getattr(ev, "kind", None) not in ("start", "stop") or getattr(ev, "clip", None) not in clips.names:
                bad.append(f"frame {f.index} has event {ev!r}: a laughlab.ClipEvent, start or stop, of a clip of "
                           f"the library ({', '.join(clips.names)})")
                return bad
    return bad


def check_plugin(cls: type, params=None, *, seconds: float = 4.0, seed: int = 0, fps: float = 60.0,
                 sample_rate: int = 16000) -> None:
    """Check a plugin class against its kind's contract as a run would meet it; raise :class:`ContractError` with
    one line per rule broken.

    Every kind: the class registers (a ``name``, its kind's methods, ``Params`` a dataclass) and its defaults (or
    ``params``, a mapping as ``face.KEY=VALUE`` sets them) pass the checks of the command line.  An extractor,
    detector, scheduler, body or face (:func:`run_frames`, ``seconds`` of seeded synthetic laughter): it writes its
    kind's channels (an extractor ``mcs``, a detector ``laughter``/``laugh_gate`` (and ``clip_gate`` if it writes
    one), a body ``chest``/``belly``, a face ``smile``/``jaw``/``blink``/``eyes_closed``) in [0, 1], and a
    detector whose ``laugh_gate`` is shut gates ``mcs`` (``laughlab.detector.model.apply_gate``) (a body's ``chest``/``belly`` are shape weights, 0 the base and 1 the expanded shape,
    which may extrapolate beyond them, as ``body=hill`` squeezes below rest and ``body=fourier`` above its intense
    clip), the same names every frame, finite numbers only; ``arkit.*`` names are ARKit's;
    offsets name the skeleton's joints; events are clips of the library; a second plugin on the same seed gives
    the same values, and an extractor or a detector gives them again after a run and ``reset()``.  A sink:
    ``open``/``write``/``close`` in a temporary folder return the files it wrote, each named in ``files``
    (``planned``); ``abort`` after a chunk leaves the folder as it was; a ``background`` sink pickles; a
    ``streaming`` sink gets a frame a chunk, as a run gives it.  A source (:func:`_check_source`): it opens, its
    ``sample_rate`` is a whole number of Hz from 8000, ``n_frames`` None exactly when it is ``live``, and its blocks
    are frames as :func:`laughlab.io.audio.cut_frames` cuts them (frame ``k`` of ``round((k+1)*sr/fps) -
    round(k*sr/fps)`` samples, the last one maybe shorter; ``n_frames`` of them), mono floats at full scale, in [-1,
    1]; a second source on the same seed gives the same blocks, and so does ``blocks()`` again when it says
    ``reread``.  A live source is read for ``seconds``.  Weights may round up to :data:`TOL` outside [0, 1].
    """
    ctx = Context(fps=float(fps), sample_rate=sample_rate, seed=seed)
    plugin = _build(cls, params, ctx)
    where = f"{plugin.kind} {cls.name!r} ({cls.__module__}.{cls.__name__})"
    if plugin.kind == "sink":
        bad = _check_sink(cls, params, seconds=seconds, seed=seed, fps=fps, sample_rate=sample_rate)
    elif plugin.kind == "source":
        bad = _check_source(cls, params, seconds=seconds, seed=seed, fps=fps)
    else:
        kw = dict(seconds=seconds, seed=seed, fps=fps, sample_rate=sample_rate)
        frames = run_frames(cls, params, **kw)
        bad = _check_frames(plugin.kind, frames, ctx.clips, ctx.skeleton)
        if not bad:
            once = [_values(frames, a) for a in ("control", "channels")]
            if [_values(run_frames(cls, params, **kw), a) for a in ("control", "channels")] != once:
                bad.append("two plugins on the same seed give different values: keep state on self (not in the module "
                           "or the class: a second run, or an experiment's next trial, starts from it) and draw "
                           "randomness from self.ctx.rng only")
            elif plugin.kind in ("extractor", "detector"):   # a scheduler that plans ahead (scheduler=concat)
                run_frames(cls, params, **kw, plugin=plugin)     # runs them over the input, then reset()s them
                again = run_frames(cls, params, **kw, plugin=plugin)
                if [_values(again, a) for a in ("control", "channels")] != once:
                    bad.append("after a run and reset() its values differ from a new one's: reset() returns every "
                               "state to the first frame's (scheduler=concat runs an extractor and a detector over "
                               "the input to plan, then resets them)")
    if bad:
        raise ContractError(f"{where}: " + "; ".join(bad))


def _check_source(cls: type, params, *, seconds: float, seed: int, fps: float) -> list[str]:
    """What a run relies on in a source (:func:`check_plugin`): one string per broken rule."""
    def opened():
        src = _build(cls, params, Context(fps=float(fps), rng=np.random.default_rng(seed), seed=seed))
        try:
            src.open()
        except (LaughlabError, ValueError, OSError) as exc:
            raise ContractError(f"source {cls.name!r} does not open with {dict(params or {}) or 'its defaults'}: "
                                f"{exc}") from None
        return src

    def read(src) -> list:
        out = []
        for block in src.blocks():
            out.append(np.array(block, copy=True) if isinstance(block, np.ndarray) else block)
            if src.live and len(out) >= limit:
                break
        return out

    bad: list[str] = []
    limit = max(1, int(round(seconds * fps)))
    src = opened()
    try:
        sr, n, live = src.sample_rate, src.n_frames, bool(src.live)
        if isinstance(sr, bool) or not isinstance(sr, (int, np.integer)) or sr < 8000:
            return [f"sample_rate is {sr!r} after open(): a whole number of Hz, 8000 or more"]
        if live != (n is None):
            bad.append(f"n_frames is {n!r} and live is {live}: a live source has no n_frames (None), a file or a "
                       "generator has its count of frames")
        cal = getattr(src, "calibration_s", 0.0)
        if not isinstance(cal, (int, float)) or not math.isfinite(cal) or cal < 0:
            bad.append(f"calibration_s is {cal!r}: seconds, 0 or more")
        audio = src.audio_path()
        if audio is not None and not Path(audio).is_file():
            bad.append(f"audio_path() is {audio}, which is not a file")
        blocks = read(src)
        if src.reread and not live and _differ(read(src), blocks):
            bad.append("reread = True but blocks() again gives other blocks: a detector reading ahead would see "
                       "other audio than the run")
    finally:
        src.close()
    wanted = np.diff(frame_edges(len(blocks), sr, fps))
    for k, (b, want) in enumerate(zip(blocks, wanted)):
        last = not live and k == len(blocks) - 1
        if not isinstance(b, np.ndarray) or b.ndim != 1 or b.dtype.kind != "f":
            what = f"{type(b).__name__} {getattr(b, 'shape', '')} {getattr(b, 'dtype', '')}".strip()
            bad.append(f"block {k} is a {what}: a 1-D numpy array of float samples (mono)")
            break
        if len(b) != want and not (last and 0 < len(b) < want):
            bad.append(f"block {k} has {len(b)} samples: frame k holds round((k+1)*sr/fps) - round(k*sr/fps) "
                       f"samples ({want} here; laughlab.io.audio.cut_frames cuts them)")
            break
        if not np.all(np.isfinite(b)) or (len(b) and np.max(np.abs(b)) > 1.0):
            bad.append(f"block {k} holds samples up to {np.max(np.abs(b)):g}: full-scale floats in [-1, 1], finite "
                       "(16-bit integers divided by 32768)")
            break
    if not live and isinstance(n, (int, np.integer)) and len(blocks) != n:
        bad.append(f"blocks() gave {len(blocks)} blocks for n_frames = {n}")
    if not bad:
        again = opened()
        try:
            if _differ(read(again), blocks):
                bad.append("two sources on the same seed give different blocks: draw from self.ctx.rng (or "
                           "self.ctx.seed) only")
        finally:
            again.close()
    return bad


def _differ(a: list, b: list) -> bool:
    return len(a) != len(b) or any(not np.array_equal(x, y) for x, y in zip(a, b))


def _chunks(seconds: float, seed: int, fps: float, sample_rate: int, n: int = 64):
    """A run's chunks of frames (the built-ins of :data:`STAGES`), as a sink receives them."""
    from laughlab.core import plugins
    from laughlab.core.mixer import Mixer
    from laughlab.core.recorder import Recorder

    cls = plugins.get("face", "smile").obj
    frames = run_frames(cls, None, seconds=seconds, seed=seed, fps=fps, sample_rate=sample_rate)
    ctx = Context(fps=float(fps))
    mixer, rec, out = Mixer(ctx.clips), Recorder(n, ctx.skeleton.n_channels), []
    for frame in frames:   # the poses again: run_frames' mixer is its own
        mixer.advance(frame)
        mixer.note(frame)
        rec.add(frame)
        if rec.i == n:
            out.append(rec.take(mixer.take()))
    if rec.i:
        out.append(rec.take(mixer.take()))
    return out, ctx.skeleton, len(frames)


def _check_sink(cls: type, params, *, seconds: float, seed: int, fps: float, sample_rate: int) -> list[str]:
    from laughlab.core.bases import RunInfo

    bad: list[str] = []
    chunks, skeleton, n = _chunks(seconds, seed, fps, sample_rate, 1 if getattr(cls, "streaming", False) else 64)
    source = SimpleNamespace(name="synthetic", live=False, sample_rate=sample_rate, n_frames=n, truth=None)
    ctx = Context(fps=float(fps), sample_rate=sample_rate, seed=seed)
    planned = set(cls.planned(dict(params or {})))
    with tempfile.TemporaryDirectory(prefix="laughlab-check-") as tmp:
        out = Path(tmp) / "run"
        out.mkdir()
        sink = _build(cls, params, ctx)
        if getattr(cls, "background", False):
            try:
                pickle.loads(pickle.dumps(sink))
            except Exception as exc:  # noqa: BLE001
                bad.append(f"background = True but it does not pickle ({type(exc).__name__}: {exc})")
        sink.open(RunInfo(out, float(fps), skeleton, n, source, {}))
        for chunk in chunks:
            sink.write(chunk)
        files = [Path(p) for p in (sink.close() or [])]
        for p in files:
            full = Path(p).resolve()
            rel = full.relative_to(out.resolve()) if full.is_relative_to(out.resolve()) else None
            if rel is None or not Path(p).exists():
                bad.append(f"close() returned {p}, which is not a file it wrote in the run folder")
            elif rel.parts[0] not in planned:
                bad.append(f"it wrote {rel.parts[0]}, which its files (or planned()) do not name: a run then cannot "
                           "keep a file of the user's by that name from being replaced")
        left = sorted(p.name for p in out.iterdir() if p.name not in {f.relative_to(out).parts[0] for f in files
                                                                    if f.resolve().is_relative_to(out.resolve())})
        if left:
            bad.append(f"close() left {', '.join(left)} in the run folder without returning it")
        aborted = Path(tmp) / "aborted"
        aborted.mkdir()
        sink = _build(cls, params, ctx)
        sink.open(RunInfo(aborted, float(fps), skeleton, n, source, {}))
        sink.write(chunks[0])
        sink.abort()
        left = sorted(p.name for p in aborted.iterdir())
        if left:
            bad.append(f"abort() after a chunk left {', '.join(left)}: a failed run leaves nothing half-written")
    return bad
