"""Sink ``bvh``: the skeleton's motion as ``motion.bvh``, streamed chunk by chunk."""
from __future__ import annotations

from laughlab import hookimpl
from laughlab.bases import Sink
from laughlab.bvh import BvhStreamWriter
from laughlab.outfiles import Staging


class BvhSink(Sink):
    """Writes ``motion.bvh``: one frame per animation frame, Frame Time 1/fps.

    Frames are appended as they come, so memory does not grow with the run's
    length; the ``Frames:`` count is filled in when the run ends.
    """

    name = "bvh"

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.writer = BvhStreamWriter(self.staging.path(run.out_dir / "motion.bvh"), run.skeleton, 1.0 / run.fps)

    def write(self, chunk) -> None:
        self.writer.write(chunk.poses)

    def close(self):
        self.writer.close()
        return self.staging.commit()

    def abort(self) -> None:
        self.writer.close()
        self.staging.abort()


@hookimpl
def register_sinks(register):
    register(BvhSink)
