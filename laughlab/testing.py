"""Stand-ins for testing pipelines and plugins without hardware."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from laughlab.io.audio import cut_frames
from laughlab.core.bases import Context, Source


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
