"""A run's stages stepped one frame outside the fast loop: checked on the first frame, timed on every
:data:`SAMPLE`-th (:func:`laughlab.core.pipeline.execute` steps the other frames through bound methods alone).

The timed frames say which plugin takes a frame's time (``metrics.json``: ``stage_ms``, the mean per stage over the
sampled frames; a plugin author's review: a body sleeping 20 ms a frame showed only as "frame loop 0.82x", and a VMC
stream's latency grew to 420 ms with nothing naming the stage).  The steps and their order are the fast loop's, so
the frames are the same bytes either way.
"""
from __future__ import annotations

import time

from laughlab.core import blame

#: every this many frames the stages are timed one by one (frame 0 is the checked one; 64 at 60 fps: about 1 s)
SAMPLE = 64


class Stepper:
    """The stages (extractor, detector, scheduler, the mixer's advance, body, face) of one run."""

    def __init__(self, ext, det, sch, body, face, mixer):
        self.ext, self.det, self.sch, self.body, self.face, self.mixer = ext, det, sch, body, face, mixer
        self.ns: dict[str, list[int]] = {}   # each stage's [total ns, frames timed]: constant memory (a soak review:
        #                                       a list of every timed frame's ns grew 0.7 MB an hour for ever)

    def checked(self, block, frame, warn: bool = True) -> None:
        """Frame 0's steps, checked: a step of another kind's signature, an extractor without ``mcs`` (a review:
        the energy scheduler's KeyError was laughlab's), and, with ``warn``, a stage that writes a channel an earlier
        one wrote (a plugin author's review: a face writing energy replaced the scheduler's in every file) are said
        (``laughlab.testing.run_frames`` steps a plugin's first frame so, ``warn`` off)."""
        frame.channels = watched = blame.WatchedChannels()
        for stage, plugin in (("extractor", self.ext), ("detector", self.det)):
            watched.stage = (stage, plugin.name)
            blame.first_step(stage, plugin, block, frame)
            if plugin is self.ext:
                blame.check_extractor(frame.control, self.ext, watched.writers)
            else:
                blame.check_detector(frame.control, self.det, watched.writers)
        watched.stage = ("scheduler", self.sch.name)
        blame.first_step("scheduler", self.sch, frame)
        self.mixer.advance(frame)
        self.mixer.offsets_by = blame.who("body", self.body)   # a bad offset's line names it
        for stage, plugin in (("body", self.body), ("face", self.face)):
            watched.stage = (stage, plugin.name)
            blame.first_step(stage, plugin, frame)
        if warn:
            blame.warn_clashes(watched)

    def step(self, block, frame) -> None:
        """One frame's steps in their order, untimed (``laughlab.testing.run_frames``; a run's fast loop steps the
        same through bound methods)."""
        self.ext.step(block, frame)
        self.det.step(block, frame)
        self.sch.step(frame)
        self.mixer.advance(frame)
        self.body.step(frame)
        self.face.step(frame)

    def timed(self, block, frame) -> None:
        """One frame's steps as the fast loop takes them, each stage's time kept (ns)."""
        clock, ns = time.perf_counter_ns, self.ns
        t = [clock()]
        self.ext.step(block, frame)
        t.append(clock())
        self.det.step(block, frame)
        t.append(clock())
        self.sch.step(frame)
        t.append(clock())
        self.mixer.advance(frame)
        t.append(clock())
        self.body.step(frame)
        t.append(clock())
        self.face.step(frame)
        t.append(clock())
        for i, name in enumerate(self.names()):
            total = ns.get(name)
            if total is None:
                total = ns[name] = [0, 0]
            total[0] += t[i + 1] - t[i]
            total[1] += 1

    def names(self) -> list[str]:
        return [f"extractor {self.ext.name}", f"detector {self.det.name}", f"scheduler {self.sch.name}", "mixer",
                f"body {self.body.name}", f"face {self.face.name}"]

    def stage_ms(self) -> dict[str, float]:
        """Each stage's mean time a frame (ms) over the timed frames (none: an input under :data:`SAMPLE` frames)."""
        return {name: total / n / 1e6 for name, (total, n) in self.ns.items()}


def slowest(stage_ms: dict, fps: float) -> str:
    """``; body sway 20.1 ms a frame of 16.7``: the stage that takes most of a frame's time, said when the stages
    together take more than half a frame (a stream then falls behind; '' otherwise)."""
    if not stage_ms or sum(stage_ms.values()) <= 500.0 / fps:
        return ""
    name, ms = max(stage_ms.items(), key=lambda kv: kv[1])
    return f"; {name} {ms:.1f} ms a frame of {1000.0 / fps:.1f}"
