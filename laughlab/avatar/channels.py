"""What drives an avatar's face and breathing, collected from a run's chunks: ARKit weights, ``chest``, ``belly``."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from laughlab.io.vmc import arkit_weights

BREATH_CHANNELS = ("chest", "belly")


def face_and_breath(channels: Mapping[str, np.ndarray]) -> tuple[dict, dict]:
    """A chunk's ARKit weights (:func:`laughlab.io.vmc.arkit_weights`) and its breathing channels."""
    breath = {k: np.asarray(channels[k], dtype=np.float64) for k in BREATH_CHANNELS if k in channels}
    return arkit_weights(channels), breath


def joined(chunks: list[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Per-chunk channel dicts joined into one array per channel (the channels every chunk has)."""
    if not chunks:
        return {}
    keys = set.intersection(*(set(c) for c in chunks))
    return {k: np.concatenate([np.asarray(c[k], dtype=np.float64) for c in chunks]) for k in sorted(keys)}
