"""Sink ``gltf``: ``character.glb``, the run on the skinned character (glTF 2.0 binary).

The character is :mod:`laughlab.character.body` (procedural, MIT); the file's layout is
:mod:`laughlab.io.gltf`.  With ``character=PATH`` (a VRM 0.x/1.0 or humanoid glTF, see
``docs/avatars.md``) the file is that avatar with the run baked in (:mod:`laughlab.avatar.bake`).  Its morph weights per frame: the face's ARKit weights (``arkit.*``
channels, or the ``smile`` face's smile/jaw/eyes mapped to ARKit names, as for VMC) and the
body's ``chest`` and ``belly`` channels, each clipped to [0, 1].  The whole animation is kept
until the end (about 0.4 kB a frame, 24 MB for 30 minutes at 60 fps).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.outfiles import Staging


@dataclass
class GltfParams:
    """Parameters of the ``gltf`` sink.

    Attributes
    ----------
    character : str or None
        A user's avatar to bake the run into (the top-level ``character=PATH`` sets it); None: the
        built-in mannequin.
    """

    character: Optional[str] = None


class GltfSink(Sink):
    """Writes ``character.glb`` at the end of the run."""

    name = "gltf"
    background = True  # only writes files: may run in the helper process
    Params = GltfParams

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        from laughlab.avatar import sink_character

        # kept: the end of the run bakes this avatar, the one checked, not the file as it is then (replaced or
        # re-exported during a long run, a review found: a traceback, or another avatar baked)
        self.avatar = sink_character(self.params)
        if self.avatar is not None:
            from laughlab.avatar.expressions import say_face_route

            say_face_route(self.avatar)

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.times: list = []
        self.poses: list = []
        self.weights: list = []
        self.arkit: list = []
        self.breath: list = []
        self.audio_s = None   # seconds of audio read by the last chunk: the input's own length at the end

    filename = "character.glb"
    files = (filename,)

    def _drives_avatar(self) -> bool:
        return bool(self.params.character)

    def write(self, chunk) -> None:
        from laughlab.avatar.channels import face_and_breath
        from laughlab.character.body import morph_weights

        self.times.append(np.asarray(chunk.times, dtype=np.float64))
        self.poses.append(np.asarray(chunk.poses, dtype=np.float64))
        self.audio_s = chunk.audio_s
        if self._drives_avatar():
            arkit, breath = face_and_breath(chunk.channels)
            self.arkit.append(arkit)
            self.breath.append(breath)
        else:
            self.weights.append(morph_weights(chunk.channels, len(chunk.times)))

    def close(self):
        if not self.times:
            return []
        path = self.staging.path(self.run.out_dir / self.filename)
        path.write_bytes(self.data(sum(len(t) for t in self.times)))
        return self.staging.commit()

    def audio_duration_s(self, n: int) -> float:
        """The input's length (s): what the last chunk read, or the ``n`` frames' span when unknown."""
        return float(self.audio_s) if self.audio_s is not None else n / self.run.fps

    def data(self, n: int) -> bytes:
        """The file's bytes for the ``n`` frames recorded."""
        if self.avatar is not None:
            from laughlab.avatar.bake import baked_glb
            from laughlab.avatar.channels import joined

            return baked_glb(self.avatar, self.run.skeleton, np.concatenate(self.times),
                             np.concatenate(self.poses), joined(self.arkit), joined(self.breath),
                             audio_duration_s=self.audio_duration_s(n), fps=self.run.fps)
        from laughlab.character.body import build
        from laughlab.io.gltf import character_glb

        return character_glb(build(self.run.skeleton), np.concatenate(self.times), np.concatenate(self.poses),
                             np.concatenate(self.weights), audio_duration_s=self.audio_duration_s(n), fps=self.run.fps,
                             generator="laughlab")

    def abort(self) -> None:
        self.staging.abort()


@hookimpl
def register_sinks(register):
    register(GltfSink)
