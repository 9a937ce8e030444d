"""Frames collected into chunks of arrays for the sinks (:func:`laughlab.core.pipeline.execute`)."""
from __future__ import annotations

import numpy as np

from laughlab.core import blame
from laughlab.core.bases import Chunk, check_contract
from laughlab.core.errors import LaughlabError
from laughlab.core.frame import Frame


class Recorder:
    """Collects frames into chunks of arrays for the sinks.

    A frame's dictionaries are kept as they are and turned into one array per channel once
    per chunk (a list comprehension per channel costs a fraction of per-frame assignments);
    the floats are the same.
    """

    def __init__(self, n: int, n_channels: int, names: dict | None = None):
        self.n, self.n_channels, self.names = n, n_channels, names   # names: stage -> plugin, for the contract
        self.keys: tuple | None = None
        self.writers: dict = {}   # channel -> the stages that wrote it on the first frame (stages.Stepper.checked)
        self.done = 0  # frames handed out in earlier chunks
        # over the run: clip starts, the largest clip_gate and energy, the energy while clips were allowed (no_clip)
        self.starts, self.gate_max, self.energy_max, self.energy_allowed_max = 0, None, 0.0, 0.0
        self.laugh_gate_max = None   # a detector's laugh_gate (one without a clip_gate: a plugin's)
        self._reset()

    def _reset(self) -> None:
        self.times: list = []
        self.controls: list = []
        self.outputs: list = []
        self.capture: list = []
        self.labels: list = []
        self.events: list = []
        self.i = 0

    def add(self, frame: Frame, capture_ns: int = 0) -> None:
        if self.keys is None:
            if self.names is not None:
                check_contract(frame.channels, self.names)
            self.writers = dict(getattr(frame.channels, "writers", {}))   # named by a value no writer takes
            self.keys = (tuple(frame.control), tuple(frame.channels))
        self.capture.append(capture_ns)
        self.controls.append(frame.control)
        self.outputs.append(frame.channels)
        self.times.append(frame.time_s)
        self.labels.append(frame.label)
        if frame.events:
            self.events.extend(frame.events)
        self.i += 1

    def _owner(self, key: str) -> str | None:
        """``face 'giggle'``: the stage that last wrote ``key`` on the first frame, or None."""
        who = self.writers.get(key)
        return f"{who[-1][0]} {who[-1][1]!r}" if who else None

    def take(self, poses: np.ndarray) -> Chunk:
        """The recorded frames with their ``poses`` (the mixer renders them per chunk)."""
        i = self.i
        if len(poses) != i:
            raise LaughlabError(f"{len(poses)} poses for {i} frames")
        vals = {}
        for keys, dicts in zip(self.keys or ((), ()), (self.controls, self.outputs)):
            if sum(map(len, dicts)) != len(keys) * i:  # (a frame missing a channel raises KeyError below)
                raise LaughlabError(f"the frames do not all write the same channels (first frame: {', '.join(keys)})")
            for k in keys:
                try:
                    vals[k] = np.fromiter([d[k] for d in dicts], dtype=np.float64, count=i)
                except KeyError:
                    raise LaughlabError(f"channel {k!r} is not written every frame") from None
                except (TypeError, ValueError):   # a value that is not a number: say which and where
                    raise blame.PluginBug(blame.not_a_number(k, [d[k] for d in dicts], self.done,
                                                             self._owner)) from None
        blame.check_finite(vals, poses, self.done, raw=lambda k, j: next(  # the value as given (None), on failure
            ds[j][k] for keys, ds in zip(self.keys, (self.controls, self.outputs)) if k in keys), owner=self._owner)
        chunk = Chunk(np.array(self.times, dtype=np.float64), vals, poses, self.events, self.labels,
                      np.array(self.capture, dtype=np.int64))
        self.done += i
        self._tally(vals)
        self._reset()
        return chunk

    def _tally(self, vals: dict) -> None:
        self.starts += sum(ev.kind == "start" for ev in self.events)
        if len(vals.get("clip_gate", ())):
            self.gate_max = max(self.gate_max or 0.0, float(vals["clip_gate"].max()))
        if len(vals.get("laugh_gate", ())):
            self.laugh_gate_max = max(self.laugh_gate_max or 0.0, float(vals["laugh_gate"].max()))
        if len(vals.get("energy", ())):
            self.energy_max = max(self.energy_max, float(vals["energy"].max()))
            allowed = vals["energy"][vals["clip_gate"] >= 0.5] if len(vals.get("clip_gate", ())) else vals["energy"]
            if len(allowed):
                self.energy_allowed_max = max(self.energy_allowed_max, float(allowed.max()))

    def no_clip(self, scheduler) -> dict:
        """Why a run with a scheduler started no full-body clip, for ``metrics.json`` and the run's line (a
        review: a real laugh under the default detector, or under ``body=hill``, played none, and nothing said
        why): ``no_clip`` ``"gate"`` (a detector's ``clip_gate`` never reached 0.5,
        :func:`laughlab.detector.model.clip_allowed`) or ``"energy"`` (the laughing energy peaked under the
        mildest clip's e(a): ``energy_peak``, ``mildest_clip_energy``) or ``"apart"`` (both reached theirs, but the
        energy stayed under e(a) on every frame the gate allowed clips: ``energy_allowed_peak`` too; an animator's
        review: a real laugh's energy peaked at 12 while the gate was shut, and the run said nothing); empty
        otherwise."""
        if self.starts or getattr(scheduler, "name", "none") == "none":
            return {}
        gate = self.gate_max if self.gate_max is not None else self.laugh_gate_max   # a gate that never opened
        if gate is not None and gate < 0.5:
            return {"no_clip": "gate"}
        mildest = min((float(a.energy) for a in getattr(scheduler, "actions", ())), default=None)
        if mildest is not None and self.energy_max < mildest:
            return {"no_clip": "energy", "energy_peak": self.energy_max, "mildest_clip_energy": mildest}
        if mildest is not None and self.gate_max is not None and self.energy_allowed_max < mildest:
            return {"no_clip": "apart", "energy_peak": self.energy_max, "energy_allowed_peak": self.energy_allowed_max,
                    "mildest_clip_energy": mildest}
        return {}
