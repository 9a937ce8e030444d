"""A recording for Fig. 3.1: a loud calibration burst, then the given laughter 12 dB quieter.

``python -m laughlab.render.calibration_demo IN.wav OUT.wav`` (``make docs``).  The
burst is 0.3 s of decaying noise peaking near full scale, laid over the input's own
noise floor (its first 0.2 s, looped), as a clap close to the microphone would be
(van Duijn 2014, 3.1.1: "a loud sound very close to the microphone during the
calibration, but start laughing farther away").
"""
from __future__ import annotations

import sys

import numpy as np
import soundfile as sf


def with_burst(audio: np.ndarray, sr: int, gain_db: float = -12.0, seed: int = 0) -> np.ndarray:
    """``audio`` scaled by ``gain_db``, after 1 s of its own floor holding a loud 0.3 s burst at 0.3 s."""
    x = np.asarray(audio, dtype=np.float64) * 10 ** (gain_db / 20)
    floor = x[: int(0.2 * sr)]
    lead = np.resize(floor, sr) if len(floor) else np.zeros(sr)
    n = int(0.3 * sr)
    burst = np.random.default_rng(seed).normal(0.0, 0.3, n) * np.exp(-np.arange(n) / (0.08 * sr))
    lead[int(0.3 * sr):int(0.3 * sr) + n] += burst
    return np.clip(np.concatenate([lead, x]), -1.0, 1.0).astype(np.float32)


def main(argv: list[str]) -> None:
    if len(argv) != 2:
        sys.exit("usage: python -m laughlab.render.calibration_demo IN.wav OUT.wav")
    audio, sr = sf.read(argv[0], dtype="float64", always_2d=True)
    sf.write(argv[1], with_burst(audio.mean(axis=1), sr), sr)


if __name__ == "__main__":
    main(sys.argv[1:])
