"""Scheduler ``none``: no full-body clips; the mixer plays the idle motion throughout."""
from __future__ import annotations

from laughlab import hookimpl
from laughlab.core.bases import Scheduler


class NoScheduler(Scheduler):
    """Starts no clip.  Writes ``energy`` and ``clip_energy`` as 0 so outputs keep their columns."""

    name = "none"

    def step(self, frame) -> None:
        frame.channels["energy"] = 0.0
        frame.channels["clip_energy"] = 0.0


@hookimpl
def register_schedulers(register):
    register(NoScheduler)
