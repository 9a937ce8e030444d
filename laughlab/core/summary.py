"""The one line a run prints when it succeeds: what ran on what, how long the command took, how fast, where."""
from __future__ import annotations

import math
import shlex
from pathlib import Path


#: a live session this far behind the microphone at its worst (s, beyond the device's own latency) says so: the
#: lag lip sync starts to show (a warm-up stall of a few frames at the start is not worth a word)
BEHIND_S = 0.1

#: a file whose loudest sample is below this (dB full scale) is called silent in the run's line: nothing moves
SILENT_DBFS = -60.0

#: a file whose samples' mean is this far from 0 (full scale, -40 dBFS) has its DC offset said in the run's line
DC_OFFSET = 0.01

#: the plugin groups a run's summary line and a report name, in the order the summary line gives them
CHAIN = ("extractor", "detector", "face", "body", "scheduler")


#: the files of a run the viewer plays (``python -m laughlab view``, ``laughlab.viewer.server``)
VIEWER_NEEDS = ("motion.bvh", "channels.csv", "events.csv")


def summary_line(cfg, metrics: dict, out_dir: Path, seconds: float, skip=frozenset()) -> str:
    """One line on success: what ran on what, how long the command took, its speed, where its files are
    (not those named in ``skip``: the user's own files in the run's folder).

    ``seconds``: the wall time from the process' start (:mod:`laughlab.core.clock`), the time the user
    waited.  The speed is the one that means something for the run's output (:func:`speed`).
    e.g. ``laughlab: 30.0 s of synthetic input, rms > none > smile > shapes > energy, in 3.4 s
    (8.8x real time; frame loop 219x) -> runs/demo/: channels.csv, events.csv, motion.bvh, plots/``
    """
    src = cfg.input.name
    what = f"{Path(str(cfg.input.path)).name}" if src == "file" else f"{src} input"
    peak = metrics.get("input_peak")
    silent = peak is not None and peak < 10 ** (SILENT_DBFS / 20)
    loudest = max(metrics.get("input_channel_peaks") or [0.0])   # a silent mix of channels that are not silent
    if silent and loudest >= 10 ** (SILENT_DBFS / 20):
        what += (f" (silent when its {len(metrics['input_channel_peaks'])} channels are mixed: they cancel out, "
                 f"each alone up to {20 * math.log10(loudest):.0f} dBFS; input.channel=0 reads the first alone)")
    elif silent:   # a review: a silent file ran without a word
        what += f" (silent: {silent_text(peak)}" + \
            ("; is the microphone muted? input.device=NAME_OR_INDEX chooses another" if src == "mic" else "") + ")"
    # samples a float file holds that no sound is: said, not only counted in metrics.json (a new-user review)
    odd = [f"{counted(bad, 'NaN or infinite sample')} read as silence"
           for bad in [int(metrics.get("nonfinite_samples") or 0)] if bad]
    if peak is not None and peak > 1.0 + 1e-6:   # a float file's samples past full scale: kept as they are
        odd.append(f"its loudest sample {20 * math.log10(peak):+.1f} dBFS, over full scale")
    dc = float(metrics.get("input_dc") or 0.0)   # a new-user review: an offset of 0.05 left a laugh without a clip
    if abs(dc) >= DC_OFFSET and not (cfg.input.get("highpass_hz") or 0):
        odd.append(f"a DC offset of {dc:+.3f} full scale, which the level the motion follows includes: "
                   "input.highpass_hz=20 removes it")
    what += f" ({'; '.join(odd)})" if odd else ""
    # the last frame mid-clip, or the silence run_out added (a game developer's review: a baked laugh ended with
    # the body half-way down a rofl, and nothing said how to let it finish)
    if metrics.get("run_out_s"):
        what += f", then {float(metrics['run_out_s']):.1f} s of silence to bring it to rest (run_out)"
    elif metrics.get("clip_at_end"):
        what += f" (ends mid-{metrics['clip_at_end']}: run_out=true plays it out)"
    why = "" if silent else no_clip_text(metrics)   # silence is said already
    # one bracket, not two back to back (a review: "(a DC offset ...) (no full-body clip ...)")
    what = what[:-1] + "; " + why[2:] if why and what.endswith(")") else what + why
    chain = " > ".join(str(cfg[g].name) + (" (fused)" if g == "detector" and cfg[g].get("fuse") else "")
                       for g in CHAIN
                       if g in cfg and cfg[g] is not None and "name" in cfg[g])   # fused: detector=yamnet_fused
    dur = float(metrics.get("duration_s") or 0.0)
    files = sorted(p.name + ("/" if p.is_dir() else "") for p in Path(out_dir).iterdir()
                   if not p.name.startswith(".") and p.name not in skip)
    took = f"in {duration_text(seconds)} ({speed(cfg, metrics, seconds)})"
    length = f"{dur:.1f}" if dur >= 1.0 or dur == 0.0 else f"{dur:.2g}"   # a 0.05 s file is not "0.1 s"
    # the next step, as an experiment's and a study's lines give theirs (a review): a run with motion is watched
    # (only when the viewer has what it plays: motion.bvh without the channels is refused by view: a review)
    watch = (f"; watch it: python -m laughlab view {shlex.quote(str(out_dir))}"
             if all(n in files for n in VIEWER_NEEDS) else "")
    return f"laughlab: {length} s of {what}, {chain}, {took} -> {out_dir}/: {', '.join(files)}{watch}"


def no_clip_text(metrics: dict) -> str:
    """Why no full-body clip started (``metrics['no_clip']``, :meth:`laughlab.core.recorder.Recorder.no_clip`), or ""."""
    why = metrics.get("no_clip")
    if why == "gate":
        return (" (no full-body clip: the laughter detector never heard laughter; detector=none starts clips on any "
                "loud sound, as the papers do)")
    if why == "energy" and float(metrics.get("duration_s") or 0) >= 1.0:   # a blip is not expected to start one
        return (f" (no full-body clip: the laughing energy peaked at {metrics['energy_peak']:.1f}, under the mildest "
                f"clip's {metrics['mildest_clip_energy']:g})")
    if why == "apart":
        return (f" (no full-body clip: the laughing energy peaked at {metrics['energy_peak']:.1f} while the laughter "
                f"detector held clips back, and reached {metrics['energy_allowed_peak']:.1f} while it allowed them, "
                f"under the mildest clip's {metrics['mildest_clip_energy']:g})")
    return ""


def silent_text(peak: float) -> str:
    """``its loudest sample -72 dBFS`` (``peak``: the largest absolute sample, 1 full scale), or ``... is 0``."""
    return "its loudest sample " + (f"{20 * math.log10(peak):.0f} dBFS" if peak > 0 else "is 0")


def speed(cfg, metrics: dict, seconds: float) -> str:
    """How fast the run went, in the terms of its output.

    - a live input (the microphone): it runs at the speed of the sound, so the compute per frame against the
      frame's time, and how far the session fell behind the microphone when it did (``input_lag_s_max`` over
      :data:`BEHIND_S`, or the device's overflows: the sinks count there, not in the compute);
    - a stream paced at the frame clock (``output=vmc`` on a file): real time by design;
    - otherwise the whole command's real-time factor (audio seconds per second waited), then the frame loop's
      (``metrics.json``: ``realtime_factor``, the plugins and the writers), and for a video its rendered
      frames per second, the part that takes the time;
    - and in the last two, the slowest stage when the stages take over half a frame's time
      (:func:`laughlab.core.stages.slowest`, from ``stage_ms``).
    """
    fps = float(metrics.get("fps") or cfg.get("fps") or 60.0)
    if str(cfg.input.name) == "mic":
        p99 = metrics.get("frame_ms_p99")
        said = f"live; compute per frame p99 {float(p99):.2f} ms of {1000 / fps:.1f} ms" if p99 is not None else "live"
        lag, lost = float(metrics.get("input_lag_s_max") or 0.0), int(metrics.get("input_overflows") or 0)
        if lag > BEHIND_S or lost:   # the compute kept up, the session did not: a sink or a stall held it up
            said += f"; fell behind the microphone by {lag:.2f} s" + (f", audio lost {lost} times" if lost else "")
        return said
    from laughlab.core.stages import slowest

    slow = slowest(metrics.get("stage_ms") or {}, fps)   # a stage that takes over half a frame, named
    for sink, what in (("vmc", "the vmc stream"), ("viewer", "the live viewer")):
        node = (cfg.get("output") or {}).get(sink)
        if node is not None and str(node.get("realtime", "auto")) in ("auto", "on"):
            return f"paced at the frame clock for {what}{slow}"
    dur = float(metrics.get("duration_s") or 0.0)
    parts = [f"{factor_text(dur / seconds)}x real time" if seconds > 0 else "instant"]
    if metrics.get("video_frames"):
        rate = metrics.get("video_render_fps")
        parts.append(f"video: {counted(int(metrics['video_frames']), 'frame')} rendered at {float(rate):.1f} frames/s"
                     if rate is not None and rate == rate else f"video: {counted(int(metrics['video_frames']), 'frame')}")
    elif metrics.get("realtime_factor"):
        parts.append(f"frame loop {factor_text(float(metrics['realtime_factor']))}x")
    return "; ".join(parts) + slow


def counted(n: int, word: str) -> str:
    """``1 trial``, ``2 trials``: a count and its noun (a new-user review read "1 trials")."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def factor_text(x: float) -> str:
    """A speed factor with two significant digits below 10 (0.091, 0.15, 8.8), whole above (219)."""
    return f"{x:.0f}" if x >= 10 else f"{x:.1f}" if x >= 1 else f"{x:.2g}"


def duration_text(s: float) -> str:
    """A duration as a person reads it: 3.4 s, 2 min 05 s, 1 h 02 min."""
    if s < 60:
        return f"{s:.1f} s"
    m = int(round(s)) // 60
    return f"{m} min {int(round(s)) % 60:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"
