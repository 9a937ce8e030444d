"""Building the plugins from a configuration and running them frame by frame.

An offline run is a streaming run fed from a file as fast as it can go: the
same ``step`` calls, so live and offline results agree.
"""
from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from laughlab.core import blame, interrupts, plugins
from laughlab.core.bases import Context, RunInfo
from laughlab.core.errors import LaughlabError, NoAudio, UnknownParameter
from laughlab.core.frame import Frame
from laughlab.core.mixer import Mixer, settling
from laughlab.core.stages import SAMPLE, Stepper
from laughlab.core.outfiles import unwrite
from laughlab.core.recorder import Recorder
from laughlab.core.framesample import FrameSample

#: config group -> plugin kind
GROUPS = {"input": "source", "extractor": "extractor", "detector": "detector", "scheduler": "scheduler",
          "body": "body", "face": "face"}
CHUNK_FRAMES = 256
#: the longest ``run_out`` goes on after the input (s): the longest clip of the library is about 10 s
RUN_OUT_MAX_S = 20.0


@dataclass
class RunParams:
    """Top-level run parameters.

    Attributes
    ----------
    seed : int
        Seed of the run's one random generator (same seed, same bytes).
    fps : float
        Animation frames per second (the thesis' game engine: 60).
    progress : str
        ``auto`` (a bar on long inputs when stderr is a terminal), ``on`` or ``off``.
    overwrite : bool
        Allow writing into a run directory that holds an earlier run (:mod:`laughlab.core.rundir`).
    run_out : bool
        When the input ends while a clip plays, go on in silence until no clip plays and the blend back to idle
        is done (the energy scheduler's energy winds down: it may start a calmer clip first), at most
        :data:`RUN_OUT_MAX_S` (:func:`execute`); off, the last frame is wherever the clip was.
    """

    seed: int = 0
    fps: float = 60.0
    progress: str = "auto"
    overwrite: bool = False
    run_out: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a whole number >= 0 (got {self.seed!r})")
        if isinstance(self.fps, bool) or not (isinstance(self.fps, (int, float)) and math.isfinite(self.fps)
                                              and self.fps > 0):
            raise ValueError(f"fps must be a positive number (got {self.fps})")
        if not 1 <= self.fps <= 1000:   # fps=0.5 ran without a word: frames of 2 s, no clip on a clear laugh
            raise ValueError(f"fps must be 1-1000 animation frames a second (got {self.fps})")
        for key in ("overwrite", "run_out"):
            if not isinstance(getattr(self, key), bool):
                raise ValueError(f"{key} must be true or false (got {getattr(self, key)!r})")
        if self.progress not in ("auto", "on", "off"):
            raise ValueError(f"progress must be auto, on or off (got {self.progress!r})")


@dataclass
class Pipeline:
    """The plugins of one run, built and validated."""

    ctx: Context
    source: Any
    extractor: Any
    detector: Any
    scheduler: Any
    body: Any
    face: Any
    mixer: Mixer
    sinks: list = field(default_factory=list)
    run: RunParams = field(default_factory=RunParams)


def _section(cfg: DictConfig, key: str) -> dict:
    node = cfg.get(key)
    if node is None:
        raise LaughlabError(f"the configuration has no '{key}' group")
    missing = sorted(OmegaConf.missing_keys(node))
    if missing:
        raise LaughlabError(f"{missing[0]} is required: set {missing[0]}=VALUE")
    return OmegaConf.to_container(node, resolve=True)


def _built(kind: str, name: str, values, ctx: Context, where: str):
    """:func:`laughlab.core.plugins.create`; a plugin class that raises anything but a :class:`ValueError` (a bad
    value) as it is built is a bug, said in one line naming it (:func:`laughlab.core.blame.not_built`)."""
    try:
        return plugins.create(kind, name, values, ctx, where=where)
    except (LaughlabError, ValueError):
        raise
    except Exception as exc:   # noqa: BLE001 - the plugin's code, whatever it raised
        raise blame.not_built(exc, plugins.get(kind, name).obj, plugins.group_of(kind), name) from exc


def _create(group: str, kind: str, name: str, values, ctx: Context):
    """The plugin of ``group``; a parameter it does not have but another plugin of the group has says which."""
    try:
        return _built(kind, name, values, ctx, f"{group}.{name}")
    except UnknownParameter as exc:
        from laughlab.core.config import misplaced_parameter

        raise LaughlabError(misplaced_parameter(group, name, exc.key) or str(exc)) from None


def build(cfg: DictConfig) -> Pipeline:
    """Validate every parameter, build the plugins and open the source.

    Raises LaughlabError (one line) on any bad parameter, unknown plugin or bad input.
    """
    if cfg.get("plugins_dir"):
        plugins.load_plugin_dir(cfg.plugins_dir)
    run_values = {k: cfg.get(k) for k in ("seed", "fps", "progress", "overwrite", "run_out") if k in cfg}
    try:
        run = RunParams(**run_values)
    except (ValueError, TypeError) as exc:
        raise LaughlabError(f"bad parameter: {exc}") from None
    ctx = Context(fps=float(run.fps), rng=np.random.default_rng(run.seed), seed=int(run.seed))
    built = {}
    for group, kind in GROUPS.items():
        values = _section(cfg, group)
        name = values.get("name")
        if not name:
            raise LaughlabError(f"'{group}' has no plugin name; set {group}=NAME")
        if group != "input":
            built[group] = None
            continue
        try:  # a check a source makes only when it opens (a file's header, a generator's arguments)
            built[group] = _create(group, kind, name, values, ctx)
            built[group].open()
        except ValueError as exc:
            raise LaughlabError(f"bad parameter in {plugins.typed(f'{group}.{name}')}: {exc}") from None
        ctx.sample_rate = built[group].sample_rate
        ctx.calibration_s = float(built[group].calibration_s)
        ctx.live = bool(getattr(built[group], "live", False))
    for group, kind in GROUPS.items():
        if group == "input":
            continue
        values = _section(cfg, group)
        try:
            built[group] = _create(group, kind, values["name"], values, ctx)
        except ValueError as exc:
            where = plugins.typed(f"{group}.{values['name']}")
            raise LaughlabError(f"bad parameter in {where}: {exc}") from None
        if group == "scheduler" and ctx.live and getattr(built[group], "offline_plan", False):
            raise LaughlabError(_offline_only(built[group]))   # before any sink opens
        if group == "extractor" and not getattr(built[group], "calibrates", False):
            ctx.calibration_s = 0.0  # no min/max to calibrate: input=mic skips its calibration phase
    outputs = _section(cfg, "output") or {}
    for name, params in outputs.items():
        if params is not None and not isinstance(params, dict):
            raise LaughlabError(f"output.{name} must hold the sink's parameters, e.g. output.{name}.KEY=VALUE "
                                f"(got {str(params)[:40]!r})")
    character = cfg.get("character")
    if character is not None:
        for name in outputs:
            if "character" in _param_names("sink", name) and not (outputs[name] or {}).get("character"):
                outputs[name] = {**(outputs[name] or {}), "character": str(character)}
    sinks = [_built("sink", name, params or {}, ctx, f"output.{name}")
             for name, params in outputs.items()]
    return Pipeline(ctx, built["input"], built["extractor"], built["detector"], built["scheduler"], built["body"],
                    built["face"],
                    Mixer(ctx.clips), sinks, run)


def _param_names(kind: str, name: str) -> set[str]:
    """The parameter names of a plugin (empty if it has none or is unknown)."""
    try:
        params = getattr(plugins.get(kind, name).obj, "Params", None)
    except LaughlabError:
        return set()
    return {f.name for f in dataclasses.fields(params)} if dataclasses.is_dataclass(params) else set()


def check_character_used(cfg: DictConfig) -> None:
    """A plain run with ``character=PATH`` must have an output that uses it (the sink that does checks the
    file as it is built); experiments set their own outputs per trial."""
    path = cfg.get("character")
    outputs = dict(cfg.get("output") or {})
    if path is not None and not any("character" in _param_names("sink", name) for name in outputs):
        # what to do, in the options the user types (a review: the line named the sinks csv, bvh, plots, arkit, not
        # output=files, and no fix); a VRM Animation fits any VRM as it is
        vrma = "; animation.vrma (output=vrma) fits any VRM without it" if "vrma" in outputs else ""
        raise LaughlabError(f"character={path} is shown by output=gltf, output=video and output=viewer, and sized for "
                            f"by output=vmc (and `laughlab view RUN --character PATH`); this run's outputs "
                            f"({', '.join(outputs) or 'none'}) do not use it: add one, e.g. 'output=[files,gltf]', "
                            f"or leave out character={vrma}")


def chunk_frames(pipe: Pipeline) -> int:
    """Frames per chunk handed to the sinks: 1 for a live source or a streaming sink, else ``CHUNK_FRAMES``.

    A live source (``source.live``) or a sink that declares ``streaming = True``
    (e.g. ``vmc``) gets every frame as soon as it is computed; otherwise sinks
    get chunks of ``CHUNK_FRAMES`` frames (fewer calls, vectorised writing).
    """
    if getattr(pipe.source, "live", False) or any(getattr(s, "streaming", False) for s in pipe.sinks):
        return 1
    return CHUNK_FRAMES


def planned_files(cfg) -> frozenset[str]:
    """The names a run's sinks may write at the top of its folder: every registered sink's ``files``
    (a user's ``motion.bvh`` is kept whatever the outputs) and the chosen sinks' own, parameters included
    (``output.video.file``).  :func:`laughlab.core.rundir.claim` refuses a folder that holds one of the
    user's by these names."""
    names = {n for info in plugins.registry()["sink"].values() for n in getattr(info.obj, "files", ())}
    output = cfg.get("output") if hasattr(cfg, "get") else None
    for name, params in (output or {}).items():
        info = plugins.registry()["sink"].get(name)
        if info is not None and hasattr(info.obj, "planned"):
            try:
                values = OmegaConf.to_container(params, resolve=True) if isinstance(params, DictConfig) else params
            except Exception:  # a bad value: build() says so in one line; the class' own names still count
                values = {}
            names.update(info.obj.planned(values if isinstance(values, dict) else {}))
    return frozenset(names)


def _progress_bar(pipe: Pipeline):
    """A bar on the terminal when the run will take a while: ``progress=auto`` shows it for an input over
    60 s, or of any length when a sink declares ``slow = True`` (``video`` draws and encodes each frame,
    about 30 frames/s: a 9 s input was quiet for 20-40 s).  Not for a live source: it goes at the speed of the
    sound, and its calibration meter and stop lines use the line (a review: they were printed onto the bar's)."""
    n = pipe.source.n_frames
    slow = any(getattr(s, "slow", False) for s in pipe.sinks)
    live = bool(getattr(pipe.source, "live", False))
    show = pipe.run.progress == "on" or (pipe.run.progress == "auto" and sys.stderr.isatty() and not live
                                         and (n is None or n > 60 * pipe.ctx.fps or slow))
    if not show:
        return None
    from laughlab.core.progress import bar   # progress=on into a log: plain lines, not carriage returns

    return bar(n, "laughlab", "frames", unit="frame", leave=False)


def plugin_config(pipe: Pipeline) -> dict:
    """The configuration of a pipeline built in code: ``{group: {"name": ..., **params}}`` per plugin group."""
    from dataclasses import asdict, is_dataclass

    out = {}
    for group in GROUPS:
        plugin = getattr(pipe, {"input": "source"}.get(group, group))
        params = asdict(plugin.params) if is_dataclass(plugin.params) else {}
        out[group] = {"name": plugin.name, **params}
    return out


def execute(pipe: Pipeline, out_dir: Path, config: dict | None = None, extra: dict | None = None) -> dict:
    """Run the pipeline to the end of the input, write every output, return the metrics (``extra``'s keys
    added to ``metrics.json``: the command line's provenance of a single run).

    On any failure the sinks remove what they wrote (also the files of those that had closed) and the
    exception propagates.
    """
    out_dir = Path(out_dir)
    ctx, src = pipe.ctx, pipe.source
    config = config or plugin_config(pipe)
    info = RunInfo(out_dir, ctx.fps, ctx.skeleton, src.n_frames, src, config)
    opened = []
    n_chunk = chunk_frames(pipe)
    rec = Recorder(n_chunk, ctx.skeleton.n_channels, {"face": pipe.face.name, "body": pipe.body.name})
    times = FrameSample("q")  # per-frame compute time (ns), 8 bytes a frame, bounded (a session until Ctrl-C)
    bar = _progress_bar(pipe)
    artifacts: list[Path] = []
    written: list[Path] = []
    helper, behind = _helper_for(pipe, n_chunk)
    k = None   # the frame being stepped, for the line naming a plugin that raises (core.blame)
    try:
        if helper is not None:
            helper.open(behind, RunInfo(out_dir, ctx.fps, ctx.skeleton, src.n_frames, _source_view(src), config))
            opened.append(helper)
        for sink in pipe.sinks:
            if sink in behind:
                continue
            sink.open(info)
            opened.append(sink)
        for plugin in (pipe.extractor, pipe.detector, pipe.scheduler, pipe.body, pipe.face, pipe.mixer):
            plugin.reset()
        if getattr(src, "reread", False) and not src.live:
            pipe.detector.prefetch(src.blocks)   # an offline file: the detector may read ahead (same bytes)
        ext, det, sch, body, face, mixer = (pipe.extractor, pipe.detector, pipe.scheduler, pipe.body, pipe.face,
                                            pipe.mixer)
        dt = ctx.dt
        if getattr(sch, "offline_plan", False):
            _plan_offline(pipe)
        clock = time.perf_counter_ns
        wall0 = time.perf_counter()
        k = samples = 0
        rate = float(ctx.sample_rate)

        # streaming sinks (vmc) first: a live frame goes out before the file writers take their share of it
        order = sorted(opened, key=lambda s: not getattr(s, "streaming", False))

        def hand_over() -> None:   # the frames recorded since the last chunk, to every sink
            interrupts.check()     # a stop signal whose KeyboardInterrupt was lost (raised in a __del__)
            chunk = rec.take(mixer.take())
            chunk.audio_s, chunk.input_end_s = samples / rate, (tail[0] / rate if tail and pipe.run.run_out else None)
            for sink in order:
                sink.write(chunk)
            times.settle()

        # bound methods in locals: the loop runs once per frame
        ext_step, det_step, sch_step, body_step, face_step = ext.step, det.step, sch.step, body.step, face.step
        advance, note, add, record_ns = mixer.advance, mixer.note, rec.add, times.values.append

        stepper = Stepper(ext, det, sch, body, face, mixer)   # frame 0 checked, every SAMPLE-th timed
        tail = []   # [input samples, frames] once the input has ended (run_out)

        def run_out():
            """After the input: silent frames while a clip plays, its blend back to idle runs or the face returns to
            rest (``run_out``, :func:`laughlab.core.mixer.settling`), each a frame's samples as the input's are cut."""
            tail.extend((samples, k))
            if not pipe.run.run_out or k == 0:
                return
            per_frame = rate / ctx.fps   # samples a frame
            while settling(mixer, before, frame) and (k - tail[1]) * dt < RUN_OUT_MAX_S:
                yield np.zeros(int(round((k + 1) * per_frame)) - int(round(k * per_frame)), np.float32)

        frame = None
        for block in itertools.chain(src.blocks(), run_out()):
            t0 = clock()
            before, frame = frame, Frame(k, k * dt, dt, {}, None, {}, {}, [], 0.0)
            if k % SAMPLE:
                ext_step(block, frame)
                det_step(block, frame)
                sch_step(frame)
                advance(frame)
                body_step(frame)
                face_step(frame)
            elif k:
                stepper.timed(block, frame)
            else:
                stepper.checked(block, frame)
            note(frame)
            add(frame, t0)
            record_ns(clock() - t0)
            k += 1
            samples += len(block)
            if k % n_chunk == 0:
                hand_over()
                if bar is not None:
                    bar.update(n_chunk)
        if k == 0:
            raise NoAudio("the input holds no audio frames")
        if rec.i:
            hand_over()
            if bar is not None:
                bar.update(k % n_chunk)   # the last, partial chunk: the bar ends at every frame
        wall = time.perf_counter() - wall0
        interrupts.check()
        for sink in order:   # streaming first: vmc's rest frame went out after the files and plots, 1 s late
            written += sink.close() or []
        if hasattr(src, "save_artifacts"):
            artifacts = src.save_artifacts(out_dir)
        metrics = {**_metrics(pipe, times, k, tail[0] / rate, wall), "stage_ms": stepper.stage_ms()}
        if k > tail[1]:
            metrics["run_out_s"] = (k - tail[1]) * dt   # the silent frames after the input
        elif mixer.clip is not None and not mixer.clip.loop:   # said by the summary line: the last frame is mid-clip
            metrics["clip_at_end"] = mixer.clip.name
        metrics.update(rec.no_clip(sch))   # said by the summary line: why no clip started
        # their own (mic overflows, vmc latency, body=hill's calls)
        for more in (getattr(p, "metrics", None) for p in (src, pipe.body, *opened)):
            metrics.update((more() if callable(more) else None) or {})
        metrics.update(extra or {})
        tmp = out_dir / ".metrics.json.part"
        tmp.write_text(json.dumps(metrics, indent=2, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(tmp, out_dir / "metrics.json")
        return metrics
    except BaseException as exc:
        blame.mark(exc, [src, pipe.extractor, pipe.detector, pipe.scheduler, pipe.body, pipe.face, *pipe.sinks],
                   k, ctx.fps)
        for sink in opened:
            try:
                sink.abort()
            except Exception:  # cleanup must not hide the original error
                pass
        # and the files of the sinks that had closed before the failure, with their folders (plots/) if empty
        unwrite(list(artifacts) + written, out_dir)
        raise
    finally:
        if helper is not None:
            helper.stop()
        if bar is not None:
            bar.close()
        for stage in (pipe.detector, pipe.body, pipe.face):   # stages with a worker thread (detector=yamnet
            # detector.async_frames, body=hill control=fit live)
            stop = getattr(stage, "close", None)
            if callable(stop):
                stop()
        src.close()


def _helper_for(pipe: Pipeline, n_chunk: int):
    """The helper process and the sinks it runs (``background`` sinks of an offline, chunked run)."""
    from laughlab.core import background

    if n_chunk == 1 or background.helper() is None:
        return None, []
    behind = [s for s in pipe.sinks if getattr(s, "background", False)]
    return (background.take(), behind) if behind else (None, [])


def _source_view(src):
    from laughlab.core.background import SourceView

    return SourceView(getattr(src, "name", ""), bool(getattr(src, "live", False)), int(src.sample_rate),
                      src.n_frames, getattr(src, "truth", None))


def _plan_offline(pipe: Pipeline) -> None:
    """First pass for offline schedulers: the extractor's label of every frame, then ``plan``.

    The look-ahead is the whole input, so a live source is refused.
    """
    src, ext, det, sch = pipe.source, pipe.extractor, pipe.detector, pipe.scheduler
    if src.live:   # a pipeline built in code with a live source put in (build refuses the configuration)
        raise LaughlabError(_offline_only(sch))
    labels = []
    for k, block in enumerate(src.blocks()):
        frame = Frame(k, k * pipe.ctx.dt, pipe.ctx.dt, {}, None, {}, {}, [], 0.0)
        ext.step(block, frame)
        det.step(block, frame)
        labels.append(sch.label_of(frame))
    sch.plan(labels)
    ext.reset()
    det.reset()


def _offline_only(sch, source: str = "a live source (input=mic)") -> str:
    """The refusal of a scheduler that plans over the whole input on a live source, naming the setting to use:
    its ``mode`` parameter's default (``scheduler.mode=greedy``, the real-time mode)."""
    modes = [f.default for f in dataclasses.fields(sch.params) if f.name == "mode"] \
        if dataclasses.is_dataclass(sch.params) else []
    now = f" (scheduler.mode={sch.params.mode})" if modes else ""
    fix = f"scheduler.mode={modes[0]}, its real-time mode" if modes else "a real-time scheduler"
    return (f"scheduler={sch.name}{now} plans over the whole input and cannot run on {source}; "
            f"use {fix}")


def _metrics(pipe: Pipeline, times: FrameSample, n_frames: int, audio_s: float, wall_s: float) -> dict:
    """Compute metrics: per-frame compute time (ms) and real-time factor.

    ``duration_s``: the input's own length, ``audio_s`` (samples read / sample rate, s); the frames span
    ``n_frames / fps``, up to one frame more (the last frame covers the audio's end).

    ``frame_ms_p50``/``frame_ms_p99``: percentiles of the time spent in the
    plugins and the mixer per frame (ms), excluding reading audio and writing
    files; the mixer renders poses once per chunk of frames (``Mixer.take``),
    which, like the hand-over to the writers, counts in ``realtime_factor`` only.  ``realtime_factor``: audio duration / wall-clock time of the whole
    frame loop including reading and writing (higher is faster).
    """
    ms = times.array(np.int64) / 1e6
    return {
        "n_frames": int(n_frames),
        "fps": pipe.ctx.fps,
        "duration_s": audio_s,
        "seed": pipe.run.seed,
        "frame_ms_p50": float(np.percentile(ms, 50)),
        "frame_ms_p99": float(np.percentile(ms, 99)),
        "frame_ms_max": times.max() / 1e6,
        "wall_s": wall_s,
        "realtime_factor": audio_s / wall_s if wall_s > 0 else float("inf"),
        "nonfinite_samples": int(getattr(pipe.extractor, "nonfinite_samples", 0)),
    }
