"""Sink ``bvh``: the skeleton's motion as ``motion.bvh``, streamed chunk by chunk."""
from __future__ import annotations

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.io.bvh import format_frames, frame_time_line, hierarchy_lines
from laughlab.core.outfiles import Staging

_COUNT_WIDTH = 12  # room for the frame count, patched in when the run ends


class BvhSink(Sink):
    """Writes ``motion.bvh``: one BVH frame per animation frame, Frame Time 1/fps.

    Frames are appended as they come, so memory does not grow with the run's
    length; the ``Frames:`` count is written when the run ends.
    """

    name = "bvh"
    background = True  # only writes files: may run in the helper process
    files = ("motion.bvh",)

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self.skeleton = run.skeleton
        self._f = open(self.staging.path(run.out_dir / "motion.bvh"), "w", encoding="ascii", newline="\n")
        self._f.write("\n".join(hierarchy_lines(run.skeleton)) + "\nMOTION\n")
        self._count_at = self._f.tell() + len("Frames: ")
        self._f.write(f"Frames: {'0':<{_COUNT_WIDTH}}\n{frame_time_line(1.0 / run.fps)}\n")
        self.n = 0

    def write(self, chunk) -> None:
        if len(chunk.poses):
            self._f.write(format_frames(self.skeleton, np.asarray(chunk.poses)))
            self.n += len(chunk.poses)

    def close(self):
        self._f.seek(self._count_at)
        self._f.write(f"{self.n:<{_COUNT_WIDTH}}")
        self._f.close()
        return self.staging.commit()

    def abort(self) -> None:
        self.staging.abort(getattr(self, "_f", None))  # closes it (a buffer that cannot be written is dropped) first


@hookimpl
def register_sinks(register):
    register(BvhSink)
