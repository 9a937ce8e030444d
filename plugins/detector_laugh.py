"""Detector ``laugh``: a per-frame laughter probability, and a gate on what drives the character.

Thesis future work (van Duijn 2014, ch. 6: "a laughter detection component"
before the motion control signal).  Per frame: causal acoustic features of the
frame and the second before it (``laughlab.detector.model.FeatureStream``), a small
MLP fitted on the corpus' train split (``laughlab/data/detector.json``,
``python -m laughlab.detector.fit``), a hysteresis gate
(``laughlab.detector.model.Gate``), and the gate applied to ``mcs``, ``pressure``,
``call_onset`` and the pseudo-phoneme label (``laughlab.detector.model.apply_gate``).
Writes ``control['laughter']`` (probability) and ``control['laugh_gate']`` (gain).
Look-ahead: the frame's own audio block, nothing more.
"""
from __future__ import annotations

from dataclasses import dataclass

from laughlab import hookimpl
from laughlab.core.bases import Detector
from laughlab.detector.model import FeatureStream, Gate, GateParams, Model, apply_gate


@dataclass
class LaughParams(GateParams):
    """The gate's rule (``GateParams``) and the model.

    Attributes
    ----------
    model : str or None
        A model JSON written by ``python -m laughlab.detector.fit --out FILE``;
        None: the bundled model.
    """

    model: str | None = None


#: the lowest frame rate the features can be measured at: 8 Hz modulation needs at least 16 frames a second
MIN_FPS = 20.0


class LaughDetector(Detector):
    name = "laugh"
    Params = LaughParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        try:
            self.model = Model.load(self.params.model)
        except FileNotFoundError:
            raise ValueError(f"model file not found: {self.params.model}") from None
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"model {self.params.model or '(bundled)'} is not a detector model: {exc}") from None
        if not self.ctx.fps >= MIN_FPS:
            raise ValueError(f"detector=laugh needs fps >= {MIN_FPS:g}: its cues include the level's 3-8 Hz "
                             f"modulation, measured once per frame (got fps={self.ctx.fps:g})")
        self.features = FeatureStream(self.ctx.sample_rate, self.ctx.fps)
        self.gate = Gate(self.params, self.ctx.dt)

    def reset(self) -> None:
        self.features.reset()
        self.gate.reset()

    def step(self, block, frame) -> None:
        x = self.features.step(block)
        p = float(self.model.prob_at(x, self.features.level_dbfs))
        gain = self.gate.step(p)
        frame.control["laughter"] = p
        frame.control["laugh_gate"] = gain
        apply_gate(frame, gain)


@hookimpl
def register_detectors(register):
    register(LaughDetector)
