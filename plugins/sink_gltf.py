"""Sink ``gltf``: ``character.glb``, the run on the skinned character (glTF 2.0 binary).

The character is :mod:`laughlab.character.body` (procedural, MIT); the file's layout is
:mod:`laughlab.io.gltf`.  Its morph weights per frame: the face's ARKit weights (``arkit.*``
channels, or the ``smile`` face's smile/jaw/eyes mapped to ARKit names, as for VMC) and the
body's ``chest`` and ``belly`` channels, each clipped to [0, 1].  The whole animation is kept
until the end (about 0.4 kB a frame, 24 MB for 30 minutes at 60 fps).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.outfiles import Staging


@dataclass
class GltfParams:
    """Parameters of the ``gltf`` sink (none yet: the character and its framing are fixed)."""


class GltfSink(Sink):
    """Writes ``character.glb`` at the end of the run."""

    name = "gltf"
    background = True  # only writes files: may run in the helper process
    Params = GltfParams

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.times: list = []
        self.poses: list = []
        self.weights: list = []

    def write(self, chunk) -> None:
        from laughlab.character.body import morph_weights

        self.times.append(np.asarray(chunk.times, dtype=np.float64))
        self.poses.append(np.asarray(chunk.poses, dtype=np.float64))
        self.weights.append(morph_weights(chunk.channels, len(chunk.times)))

    def close(self):
        if not self.times:
            return []
        from laughlab.character.body import build
        from laughlab.io.gltf import character_glb

        n = sum(len(t) for t in self.times)
        data = character_glb(build(self.run.skeleton), np.concatenate(self.times), np.concatenate(self.poses),
                             np.concatenate(self.weights), audio_duration_s=n / self.run.fps, fps=self.run.fps,
                             generator="laughlab")
        path = self.staging.path(self.run.out_dir / "character.glb")
        path.write_bytes(data)
        return self.staging.commit()

    def abort(self) -> None:
        self.staging.abort()


@hookimpl
def register_sinks(register):
    register(GltfSink)
