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


@dataclass
class ArkitParams:
    """Parameters of the ``arkit`` sink.

    Attributes
    ----------
    precision : int
        Decimals written for the weights.
    """

    precision: int = 6

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
    moved into place when the run succeeds and removed when it fails.
    """

    name = "arkit"
    background = True  # only writes files: may run in the helper process
    files = ("face_arkit.csv",)
    Params = ArkitParams

    def open(self, run) -> None:
        super().open(run)
        self.staging = Staging()
        self._f = None
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
        return self.staging.commit()

    def abort(self) -> None:
        self.staging.abort(getattr(self, "_f", None))  # closes it (a buffer that cannot be written is dropped) first


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
