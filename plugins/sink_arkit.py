"""Sink ``arkit``: ``face_arkit.csv``, the ARKit blendshape weights of the face, streamed chunk by chunk."""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.face.facs import ARKIT_BLENDSHAPES
from laughlab.io.vmc import arkit_weights
from laughlab.core.outfiles import Staging

#: prefix of the channels holding ARKit weights (``arkit.jawOpen``)
PREFIX = "arkit."

#: the 61 value columns of a Live Link Face take's CSV, in its order (after ``Timecode,BlendShapeCount``): Apple's 52
#: blendshapes with a capital first letter (its jaw and mouth left/right pairs right first), then 9 head and eye
#: rotations, which laughlab writes as 0 (the head's turn is in channels.csv and motion.bvh, in degrees)
LIVELINK_COLUMNS: tuple[str, ...] = (
    "EyeBlinkLeft", "EyeLookDownLeft", "EyeLookInLeft", "EyeLookOutLeft", "EyeLookUpLeft", "EyeSquintLeft",
    "EyeWideLeft", "EyeBlinkRight", "EyeLookDownRight", "EyeLookInRight", "EyeLookOutRight", "EyeLookUpRight",
    "EyeSquintRight", "EyeWideRight", "JawForward", "JawRight", "JawLeft", "JawOpen", "MouthClose", "MouthFunnel",
    "MouthPucker", "MouthRight", "MouthLeft", "MouthSmileLeft", "MouthSmileRight", "MouthFrownLeft",
    "MouthFrownRight", "MouthDimpleLeft", "MouthDimpleRight", "MouthStretchLeft", "MouthStretchRight",
    "MouthRollLower", "MouthRollUpper", "MouthShrugLower", "MouthShrugUpper", "MouthPressLeft", "MouthPressRight",
    "MouthLowerDownLeft", "MouthLowerDownRight", "MouthUpperUpLeft", "MouthUpperUpRight", "BrowDownLeft",
    "BrowDownRight", "BrowInnerUp", "BrowOuterUpLeft", "BrowOuterUpRight", "CheekPuff", "CheekSquintLeft",
    "CheekSquintRight", "NoseSneerLeft", "NoseSneerRight", "TongueOut", "HeadYaw", "HeadPitch", "HeadRoll",
    "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll", "RightEyeYaw", "RightEyePitch", "RightEyeRoll")


def livelink_timecode(frame: int, fps: float) -> str:
    """A frame's ``HH:MM:SS:FF.mmm`` (Live Link Face's timecode: hours, minutes, seconds, the frame in its second,
    and the sub-frame, 0 here) at ``fps`` rounded to whole frames a second, from 00:00:00:00.000."""
    rate = max(1, int(round(fps)))
    sec, ff = divmod(int(frame), rate)
    return f"{sec // 3600:02d}:{sec // 60 % 60:02d}:{sec % 60:02d}:{ff:02d}.000"


@dataclass
class ArkitParams:
    """Parameters of the ``arkit`` sink.

    Attributes
    ----------
    precision : int
        Decimals written for the weights.
    livelink : bool
        Also write ``face_livelink.csv``, the layout of Epic's Live Link Face app's takes (:data:`LIVELINK_COLUMNS`).
    """

    precision: int = 6
    livelink: bool = False

    def __post_init__(self) -> None:
        if not 1 <= self.precision <= 17:
            raise ValueError(f"precision must be in 1..17 (got {self.precision})")


class ArkitSink(Sink):
    """Writes ``face_arkit.csv``: ``time`` (s), then one column per ARKit blendshape the run has.

    The columns are the channels named ``arkit.NAME`` (written by faces such as
    ``facs`` and ``cgm``), named ``NAME`` without the prefix, in Apple's order
    (:data:`laughlab.face.facs.ARKIT_BLENDSHAPES`); values are clipped to [0, 1].
    A run without them (``face=smile``, the default) has the 11 weights the VMC stream and ``character.glb``
    make of its ``smile``, ``jaw`` and ``eyes_closed`` channels (:data:`laughlab.io.vmc.SMILE_TO_ARKIT`; a game
    developer's review asked for ARKit names with the defaults and got no file).  A run with neither writes
    nothing, so the sink can stay in the default outputs.  Streamed: each chunk is appended to a staged file that is
    moved into place when the run succeeds and removed when it fails.  With ``livelink: true`` also
    ``face_livelink.csv``, the same weights in a Live Link Face take's layout (Unreal's and the DCC importers of
    its takes): ``Timecode`` ``HH:MM:SS:FF.mmm`` from 0 at the run's frame rate, ``BlendShapeCount`` 61, the 52
    shapes capitalised (0 for those the face does not write) and 9 rotations at 0 (:data:`LIVELINK_COLUMNS`).
    """

    name = "arkit"
    background = True  # only writes files: may run in the helper process
    files = ("face_arkit.csv", "face_livelink.csv")
    Params = ArkitParams

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self._f = self._ll = None
        self._columns: list[str] | None = None

    def write(self, chunk) -> None:
        if self._columns is None:
            present = {k[len(PREFIX):] for k in chunk.channels if k.startswith(PREFIX)}
            warn_unknown(present)
            self._mapped = not present   # no arkit.* channels: the smile face's mapping, as vmc and gltf send it
            if self._mapped:
                present = set(arkit_weights(chunk.channels))
            self._columns = [n for n in ARKIT_BLENDSHAPES if n in present]
            if not self._columns:
                return
            self._f = open(self.staging.path(self.run.out_dir / "face_arkit.csv"), "w", newline="", encoding="utf-8")
            self._f.write(",".join(["time", *self._columns]) + "\n")
            if self.params.livelink:
                self._ll = open(self.staging.path(self.run.out_dir / "face_livelink.csv"), "w", newline="",
                                encoding="utf-8")
                self._ll.write(",".join(["Timecode", "BlendShapeCount", *LIVELINK_COLUMNS]) + "\n")
                # each Live Link column's place in a row of ``data`` (after its time), None for one not written
                at = {n[0].upper() + n[1:]: i + 1 for i, n in enumerate(self._columns)}
                self._ll_at = [at.get(c) for c in LIVELINK_COLUMNS]
        if not self._columns:
            return
        if self._mapped:
            weights = arkit_weights(chunk.channels)
            data = np.column_stack([chunk.times] + [weights[c] for c in self._columns])
        else:
            self._warn_outside(chunk)
            data = np.column_stack([chunk.times] + [np.clip(chunk.channels[PREFIX + c], 0.0, 1.0)
                                                    for c in self._columns])
        n, c = data.shape
        row = ",".join([f"%.{self.params.precision}f"] * c) + "\n"
        self._f.write((row * n) % tuple((data + 0.0).ravel().tolist()))
        if self._ll is not None:
            self._write_livelink(data)

    def _write_livelink(self, data) -> None:
        """The chunk's rows of ``face_livelink.csv``: each frame's timecode, 61, and the 61 values (a shape the face
        does not write, and the rotations, 0)."""
        fmt = f"%.{self.params.precision}f"
        zero = fmt % 0.0
        for r in data:
            frame = int(round(float(r[0]) * self.run.fps))
            values = [zero if i is None else fmt % (r[i] + 0.0) for i in self._ll_at]
            self._ll.write(",".join([livelink_timecode(frame, self.run.fps), str(len(LIVELINK_COLUMNS)), *values])
                           + "\n")

    def _warn_outside(self, chunk) -> None:
        """A face's ARKit weight outside [0, 1], said once a run: this file, the stream and the character clip it,
        channels.csv keeps it (a plugin author's review: 1.7 in one file and 1.0 in the other, without a word)."""
        if getattr(self, "_said", False):
            return
        for c in self._columns:
            v = np.asarray(chunk.channels[PREFIX + c], dtype=np.float64)
            bad = np.flatnonzero((v < 0.0) | (v > 1.0))
            if bad.size:
                self._said = True
                frame = int(round(float(chunk.times[bad[0]]) * self.run.fps))
                print(f"laughlab: warning: the face's {PREFIX}{c} is {v[bad[0]]:g} at frame {frame}, outside the "
                      "weights' 0-1: face_arkit.csv, the stream and the character clip it, channels.csv keeps it",
                      file=sys.stderr)
                return

    def close(self):
        if self._f is None:
            return []
        self._f.close()
        if self._ll is not None:
            self._ll.close()
        return self.staging.commit()

    def abort(self) -> None:
        # closes them (a buffer that cannot be written is dropped) first
        self.staging.abort(getattr(self, "_f", None), getattr(self, "_ll", None))


_WARNED: set = set()


def warn_unknown(names) -> None:
    """One warning line (once per set of names in a process) for ``arkit.*`` channels that are not ARKit blendshape
    names, each with the nearest name: ``face_arkit.csv`` leaves them out (a plugin authors' review: a face's
    ``arkit.mouthSmile`` and ``arkit.JawOpen`` were in ``channels.csv`` but silently not in ``face_arkit.csv``)."""
    import difflib
    import sys

    unknown = tuple(sorted(set(names) - set(ARKIT_BLENDSHAPES)))
    if not unknown or unknown in _WARNED:
        return
    _WARNED.add(unknown)
    said = []
    for n in unknown:
        near = difflib.get_close_matches(n, ARKIT_BLENDSHAPES, n=1, cutoff=0.6) or \
            [a for a in ARKIT_BLENDSHAPES if a.lower() == n.lower()]
        said.append(f"{PREFIX}{n}" + (f" (did you mean {near[0]}?)" if near else ""))
    print(f"laughlab: warning: {', '.join(said)}: not ARKit blendshape names, so face_arkit.csv leaves "
          f"{'it' if len(unknown) == 1 else 'them'} out (the 52 names: laughlab.face.facs.ARKIT_BLENDSHAPES)",
          file=sys.stderr)


@hookimpl
def register_sinks(register):
    register(ArkitSink)
