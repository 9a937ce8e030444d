"""YAMNet's scores fused with the feature MLP's causal cues: ``detector.fuse=true`` (docs/detector.md).

YAMNet hears a window of 0.975 s as a whole and calls many short acted laughs Speech; the feature MLP
(``laughlab/data/detector.json``, issue 10) hears the level's 3-8 Hz modulation, voicing and the repeated
vowel of the last second but also calls a lot of talk laughter.  A logistic regression on both, per model
window (``laughlab/data/yamnet/fuse.json``, fitted on the train split by ``python -m
laughlab.detector.yamnet_fit --fuse``), ranks held-out laughter frames better than either
(``docs/detector.md``, *Fusion*).

Its inputs, per window, at the frame that takes the window (no look-ahead):

- ``log_classes``: the natural log of the laughter classes' score (the largest of YAMNet's six laughter
  classes) plus 1e-4;
- ``head_logit``: the logit of the bundled head's probability (``head.json``, on YAMNet's 521 log scores);
- ``mlp_logit``: the logit of the feature MLP's probability at that frame (0 in digital silence);
- the 23 features of ``laughlab.detector.model.FEATURES`` at that frame (``FeatureStream``, the last second
  of audio at the input rate; its long statistics cover the window's last second).

Each input is standardised by the train split's mean and spread; probabilities enter as logits clipped to
[1e-4, 1 - 1e-4].
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laughlab.detector.model import FEATURES, FeatureStream, Model

#: the fused head's inputs, in order
INPUTS = ("log_classes", "head_logit", "mlp_logit") + FEATURES
#: added to the laughter classes' score before its log; probabilities are clipped to [P_MIN, 1 - P_MIN]
EPS = 1e-4
P_MIN = 1e-4


def logit(p) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=np.float64), P_MIN, 1.0 - P_MIN)
    return np.log(p / (1.0 - p))


def inputs(q, p_head, p_mlp, feats) -> np.ndarray:
    """The fused head's input rows (``INPUTS`` order) from the classes' score ``q``, the head's probability,
    the MLP's probability (scalars or (N,)) and the features ((23,) or (N, 23))."""
    q, p_head, p_mlp = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (q, p_head, p_mlp))
    f = np.atleast_2d(np.asarray(feats, dtype=np.float64))
    return np.column_stack([np.log(q + EPS), logit(p_head), logit(p_mlp), f])


@dataclass
class Fusion:
    """``p = sigmoid(w . (x - mean) / scale + b)`` over :data:`INPUTS`."""

    mean: np.ndarray
    scale: np.ndarray
    weights: np.ndarray
    bias: float
    meta: dict

    @classmethod
    def load(cls, path: str | Path | None = None) -> "Fusion":
        """The bundled fused head, or the file ``path``; a file that cannot be read or was fitted on other inputs
        raises ``ModelFileError`` (a ``ValueError``), its message one line naming the file and the fix."""
        from laughlab.detector.yamnet_model import RESTORE, ModelFileError, data_dir

        p = Path(path) if path is not None else data_dir() / "fuse.json"
        refit = "python -m laughlab.detector.yamnet_fit --fuse"
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
            other = tuple(d["inputs"]) != INPUTS
            if not other:
                f = cls(np.array(d["mean"], dtype=np.float64), np.array(d["scale"], dtype=np.float64),
                        np.array(d["weights"], dtype=np.float64), float(d["bias"]), d)
                if not (f.mean.shape == f.scale.shape == f.weights.shape == (len(INPUTS),)):
                    raise ValueError("wrong length")
                return f
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ModelFileError(f"cannot read the fused head {p} ({exc}): {RESTORE}; or refit it: {refit}") from None
        raise ModelFileError(f"the fused head {p} was fitted on other inputs; refit: {refit}")

    def prob(self, x: np.ndarray) -> np.ndarray:
        """Probabilities of the input rows ``x`` ((N, len(INPUTS)))."""
        z = ((np.asarray(x) - self.mean) / self.scale) @ self.weights + self.bias
        return 1.0 / (1.0 + np.exp(-np.clip(z, -30.0, 30.0)))


class FrameCues:
    """The feature MLP's cues kept up to date frame by frame; read on the frames that take a window.

    ``push(block)`` every frame (the per-frame measures: level, spectrum, pitch); ``now()`` gives the 23
    features and the MLP's probability after the last push (the history's statistics are computed only
    then, once per window)."""

    def __init__(self, sample_rate: int, fps: float):
        self.stream = FeatureStream(sample_rate, fps)
        self.mlp = Model.load()

    def reset(self) -> None:
        self.stream.reset()

    def push(self, block: np.ndarray) -> None:
        self.stream.push(block)

    def now(self) -> tuple[np.ndarray, float]:
        f = self.stream.features()
        return f, float(self.mlp.prob_at(f[None, :], [self.stream.level_dbfs])[0])
