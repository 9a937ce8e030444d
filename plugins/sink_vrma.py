"""Sink ``vrma``: ``animation.vrma``, the run as a VRM Animation (``VRMC_vrm_animation`` 1.0).

Humanoid bone rotations, the hips' translation, VRM preset expression weights from the face's
ARKit weights, and the input's duration; any VRM plays it (three-vrm-animation, the VRM add-on
for Blender).  The layout is :mod:`laughlab.avatar.vrma`.  The whole animation is kept until the
end, as by the ``gltf`` sink, whose recording this sink shares.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab_plugins.sink_gltf import GltfSink


@dataclass
class VrmaParams:
    """Parameters of the ``vrma`` sink (none: a VRM Animation fits any VRM)."""


class VrmaSink(GltfSink):
    """Writes ``animation.vrma`` at the end of the run."""

    name = "vrma"
    Params = VrmaParams
    filename = "animation.vrma"
    files = (filename,)

    def _drives_avatar(self) -> bool:
        return True

    def data(self, n: int) -> bytes:
        from laughlab.avatar.channels import joined
        from laughlab.avatar.vrma import vrma_bytes

        return vrma_bytes(self.run.skeleton, np.concatenate(self.times), np.concatenate(self.poses),
                          joined(self.arkit), joined(self.breath), audio_duration_s=self.audio_duration_s(n),
                          fps=self.run.fps)


@hookimpl
def register_sinks(register):
    register(VrmaSink)
