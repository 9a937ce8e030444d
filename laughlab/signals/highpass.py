"""The input's causal high-pass (``input.highpass_hz``): a DC offset or rumble removed before the extractors.

One filter for a file (``input=file``) and a program's own samples (:class:`laughlab.session.Session`), so a session
fed a recording in any pieces gives the file run's bytes.  A 2nd-order Butterworth high-pass (``scipy.signal.butter``,
second-order sections), run causally chunk by chunk (``sosfilt`` with its state carried), its state set at the
first sample's level: an offset is no step at the start (a review: from rest, the step's transient was the
loudest frame and shrank the rms extractor's MCS).  Samples that are not finite are filtered as silence and left as
they were (the run counts them).
"""
from __future__ import annotations

import numpy as np


class CausalHighpass:
    """``step(chunk)``: the chunk high-passed at ``hz`` (Hz) for audio at ``sample_rate`` (Hz), float32."""

    def __init__(self, hz: float, sample_rate: int):
        from scipy.signal import butter, sosfilt_zi

        self.sos = butter(2, hz, "highpass", fs=sample_rate, output="sos")
        self.zi = sosfilt_zi(self.sos)
        self.state = None

    def step(self, chunk: np.ndarray) -> np.ndarray:
        from scipy.signal import sosfilt

        bad = ~np.isfinite(chunk)
        clean = np.where(bad, 0.0, chunk)
        if self.state is None:
            if not len(chunk):
                return chunk
            self.state = self.zi * float(clean[0])
        x, self.state = sosfilt(self.sos, clean, zi=self.state)
        return np.where(bad, chunk, x).astype(np.float32)
