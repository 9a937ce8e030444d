"""Detector ``none``: every sound drives the character, as in the papers."""
from __future__ import annotations

from laughlab import hookimpl
from laughlab.core.bases import Detector


class NoDetector(Detector):
    """Passes the extractor's signals unchanged; writes ``laughter`` and ``laugh_gate`` as 1."""

    name = "none"

    def step(self, block, frame) -> None:
        frame.control["laughter"] = 1.0
        frame.control["laugh_gate"] = 1.0


@hookimpl
def register_detectors(register):
    register(NoDetector)
