"""Sink ``vmc``: the face as ARKit blendshapes and the skeleton as Unity humanoid bones, live over OSC.

``python -m laughlab input=mic output=vmc`` animates a VSeeFace, Warudo or Unity
(EVMC4U) avatar from the microphone; ``output=vmc`` on a file or synthetic
input plays it at real time.  Protocol, blendshape mapping and coordinate
conversion: :mod:`laughlab.io.vmc`.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from laughlab import hookimpl
from laughlab.core.bases import Sink
from laughlab.core.clock import FramePacer
from laughlab.core.errors import LaughlabError
from laughlab.core.plugins import check_range
from laughlab.core.quiet import to_devnull
from laughlab.core.framesample import FrameSample
from laughlab.core.interrupts import deferred
from laughlab.io.vmc import (DEFAULT_PORT, VRM_PRESETS, BoneMap, VmcEncoder, VmcSender, arkit_weights,
                          latency_summary)
from laughlab.motion.skeleton import rest_pose


#: frames in a row, each less than half a frame after the one before, that make a burst (:meth:`VmcSink.write`)
BURST = 8


@dataclass
class VmcParams:
    """Parameters of the ``vmc`` sink.

    Attributes
    ----------
    host : str
        Receiver's host name or address.
    port : int
        Receiver's UDP port (39539: the VMC protocol's usual port).
    realtime : str
        ``auto``: a live source (``input=mic``) is sent as it comes (the frames after its end,
        ``run_out``, at the frame clock); any other
        input is paced at the frame clock (frame k sent (k + 1)/fps after the
        start, when its audio would have been captured live).  ``on`` / ``off``
        force pacing on or off (off: as fast as the pipeline runs).
    max_packet_bytes : int
        Largest UDP datagram; a frame's messages are split into several OSC
        bundles below it (1400 fits an Ethernet frame).  0: one bundle per frame.
    upper_chest : bool
        Send the UpperChest bone; False folds its rotation into Chest (avatars without one; a ``character``
        without one needs no setting).
    blend_case : str
        ``arkit``: ARKit's spelling (``jawOpen``); ``capitalized``: first letter
        upper case (``JawOpen``), as some VRM perfect-sync avatars name their clips.
    vrm_presets : bool
        Also send the VRM 0.x preset clips ``A`` (jawOpen), ``Joy`` (smile),
        ``Blink_L``, ``Blink_R`` for avatars without perfect-sync clips (the blinks times 1 - Joy).
    report : bool
        Print the frame count and the measured latency when the run ends.
    character : str or None
        Your avatar (the top-level ``character=PATH`` sets it): the Hips' height and the bones' offsets sent are
        its own, and the body's movement is scaled to its legs; None: laughlab's mannequin's (Hips 0.95 m up).
    rest_on_stop : bool
        When the stream ends (the input's end, Ctrl-C, a failure) send one more frame at rest: every
        blendshape sent at 0 and the neutral standing pose (arms down), then ``Blend/Apply``.  Receivers (VSeeFace,
        Warudo, EVMC4U) keep the last values they got, so without it the avatar stays frozen mid-laugh.
    rest_blend_s : float
        Before that frame, go back to it over this long (s) from the last frame sent, pose and blendshapes linearly,
        a frame every 1/fps (0: the rest frame at once, which a game showed as a pop: a game developer's review).
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    realtime: str = "auto"
    max_packet_bytes: int = 1400
    upper_chest: bool = True
    blend_case: str = "arkit"
    vrm_presets: bool = False
    report: bool = True
    rest_on_stop: bool = True
    rest_blend_s: float = 0.25
    character: Optional[str] = None

    def __post_init__(self) -> None:
        if not self.host:
            raise ValueError("host must not be empty")
        _check_host(self.host)
        check_range("port", self.port, 1, 65535)
        check_range("rest_blend_s", self.rest_blend_s, 0, 5)
        if self.realtime not in ("auto", "on", "off"):
            raise ValueError(f"realtime must be auto, on or off (got {self.realtime!r})")
        if self.max_packet_bytes != 0:
            check_range("max_packet_bytes", self.max_packet_bytes, 512, 65000)
        if self.blend_case not in ("arkit", "capitalized"):
            raise ValueError(f"blend_case must be arkit or capitalized (got {self.blend_case!r})")


def _check_host(host: str) -> None:
    """A host written as VSeeFace and Warudo show their receiver, ``IP:port``, or as a URL, is said with how to write
    it (it was 'Name or service not known' at the first frame, review-live-2 5); an IPv6 address has colons of its
    own and passes."""
    url = "://" in host
    bare = host.split("://", 1)[1].split("/", 1)[0] if url else host
    name, _, port = bare.rpartition(":") if bare.count(":") == 1 else ("", "", "")
    how = f"output.vmc.host={name} output.vmc.port={port}" if name and port.isdigit() else \
        f"output.vmc.host={bare}" if url else None
    if how is not None:
        raise ValueError(f"host is an address or a name alone (got {host!r}): write {how}"
                         + (" (VMC is OSC over UDP, no URL)" if url else ""))


class VmcSink(Sink):
    """Sends every frame as VMC messages as soon as the pipeline hands it over.

    ``streaming = True`` asks the pipeline for one-frame chunks (proposed
    pipeline change), so a live frame goes out as soon as it is computed.

    Latency: for each frame, the time from its audio block's capture to the
    frame's last datagram leaving the socket.  The capture time is
    ``Chunk.capture_ns`` (when the frame loop got the block), and for a paced
    non-live input the moment its audio would have been captured live.
    ``metrics()`` gives ``vmc_frames``, ``vmc_dropped_datagrams`` (the socket
    never blocks the frame loop: :class:`laughlab.io.vmc.VmcSender`) and
    ``vmc_latency_ms_p50``/``p90``/``p99``/``max`` for ``metrics.json``.
    """

    name = "vmc"
    Params = VmcParams
    streaming = True

    def __init__(self, params=None, ctx=None):
        super().__init__(params, ctx)
        from laughlab.avatar import sink_character

        self.avatar = sink_character(self.params)

    def check_host(self) -> None:
        """The host resolves, or the line :meth:`open` would say: a ``Session`` says it when it is made (an API
        user's review: it came at the first feed), before any frame."""
        import socket

        try:
            socket.getaddrinfo(self.params.host, int(self.params.port), type=socket.SOCK_DGRAM)
        except OSError as exc:
            raise self._unreachable(exc) from None

    def _unreachable(self, exc: OSError) -> LaughlabError:
        return LaughlabError(f"output.vmc: cannot reach host {self.params.host!r}: {exc}")

    def open(self, run) -> None:
        super().open(run)
        p = self.params
        try:
            self.sender = VmcSender(p.host, p.port)
        except OSError as exc:
            raise self._unreachable(exc) from None
        # an avatar without an UpperChest: Neck's offset is from its Chest (a VTuber's review: with UpperChest sent, a
        # receiver that has none put Neck 8 cm low under Chest and lost the upper-chest bend)
        upper = p.upper_chest and (self.avatar is None or "upperChest" in self.avatar.bones)
        self.bones = BoneMap(run.skeleton, upper_chest=upper)
        if self.avatar is not None:   # the avatar's own bones and height
            from laughlab.avatar.retarget import vmc_rest

            self.bones.place(*vmc_rest(self.avatar, run.skeleton, self.bones.joints, self.bones.offsets))
        self.encoder = VmcEncoder(self.bones.bones, p.max_packet_bytes)
        live = self.live = bool(getattr(run.source, "live", False))
        self.paced = p.realtime == "on" or (p.realtime == "auto" and not live)
        self.pacer = FramePacer(run.fps)  # paced: frame k is due (k + 1) / fps after the start
        self.n = 0
        self.lat_ms = FrameSample("d")   # bounded: a session until Ctrl-C
        self._names: dict[str, str] = {}
        self._sent: dict[str, None] = {}   # the blendshape names sent, in order (the rest frame zeroes them)
        self._t = 0.0                       # the time of the last frame sent (s)
        self._last: tuple | None = None     # the last frame's pose (BVH channels) and blendshapes, for the rest blend
        self._sent_ns = None                # when the last frame left, and the frames that left in bursts
        self.early = self._in_row = 0
        self._tail_k = None                 # the first frame after a live input's end (run_out)
        self._stopped = self._rested = False
        self._summary: dict | None = None

    def _blend_name(self, name: str) -> str:
        out = self._names.get(name)
        if out is None:
            out = self._names[name] = name[:1].upper() + name[1:] if self.params.blend_case == "capitalized" \
                else name
        return out

    def write(self, chunk) -> None:
        n = len(chunk.times)
        if not n:
            return
        pos, rot = self.bones.local(np.nan_to_num(np.asarray(chunk.poses, dtype=np.float64)))
        weights = arkit_weights(chunk.channels)
        if self.params.vrm_presets:
            for preset, names in VRM_PRESETS.items():
                have = [weights[k] for k in names if k in weights]
                if have:
                    weights[preset] = np.mean(have, axis=0)
            # VRoid's Joy closes the eyes itself: the blinks blend out as Joy rises (VRM 1.0's overrideBlink
            # "blend"; UniVRM 0.x receivers apply no such rule), or the eyelids went through the face (a VTuber's
            # review: Joy 1.0 with Blink_L and Blink_R 0.59 in 170 of 367 frames)
            if "Joy" in weights:
                for blink in ("Blink_L", "Blink_R"):
                    if blink in weights:
                        weights[blink] = weights[blink] * (1.0 - weights["Joy"])
        names = [self._blend_name(k) if k not in VRM_PRESETS else k for k in weights]
        self._sent.update(dict.fromkeys(names))
        values = np.array([weights[k] for k in weights]).reshape(len(weights), n).T.tolist() if weights else [[]] * n
        capture = getattr(chunk, "capture_ns", None)
        clock = time.perf_counter_ns
        end = chunk.input_end_s if self.live and self.params.realtime == "auto" else None
        for i in range(n):
            k = self.n
            if self.paced:
                captured = self.pacer.wait(k)
            elif end is not None and chunk.times[i] >= end:   # run_out after a live input: the rest of the clip
                self._tail_k = k if self._tail_k is None else self._tail_k   # at the frame clock from its first
                captured = self.pacer.wait(k - self._tail_k)   # frame (it went out 9x too fast: a VTuber's review)
            else:
                captured = int(capture[i]) if capture is not None else None
            msgs = self.encoder.messages(float(chunk.times[i]), pos[i], rot[i], zip(names, values[i]))
            self.sender.send(self.encoder.packets(msgs))
            now = clock()
            # a burst: 8 or more frames in a row, each less than half a frame after the one before; UDP receivers
            # drop what comes faster than they read (a Session fed a whole file lost 130 of 336 frames with no
            # datagram dropped here: a game developer's review); a microphone's block of two frames is no burst
            early = self._sent_ns is not None and now - self._sent_ns < 5e8 / self.run.fps
            self._in_row = self._in_row + 1 if early else 0
            self.early += BURST if self._in_row == BURST else self._in_row > BURST
            self._sent_ns = now
            self._t = float(chunk.times[i])
            if captured is not None:
                self.lat_ms.values.append((now - captured) / 1e6)
            self.n += 1
        self.lat_ms.settle()
        self._last = (np.nan_to_num(np.asarray(chunk.poses[-1], dtype=np.float64)), names, values[-1])

    def _finish(self) -> None:
        if self._stopped:   # abort() after close()
            return
        self._stopped = True
        try:
            if self.params.rest_on_stop and self.n and self.sender.failed is None:
                self._send_rest()
                self._rested = True
        finally:
            self.sender.close()

    def _send_rest(self) -> None:
        """One frame at rest after the last: every blendshape sent at 0, the neutral standing pose every clip starts
        and ends at (the idle clip's first frame: arms down, hips 95 cm up), Blend/Apply.  It was the skeleton's
        T-pose (``rest_pose``), so every receiver's avatar ended a session with its arms straight out (a game
        developer's review); a pose of zeros had put the hips on the floor (diff-review 12)."""
        fps, neutral = self.run.fps, self._neutral()
        steps = int(round(self.params.rest_blend_s * fps)) if self._last is not None else 0
        last, names, values = self._last if steps else (None, (), ())
        pos, rot = self.bones.local(neutral[None])   # the frame at rest, made before the way back to it
        rest = self.encoder.packets(self.encoder.messages(self._t + (steps + 1) / fps, pos[0], rot[0],
                                                          ((k, 0.0) for k in self._sent)))
        # from the last frame sent, at the frame clock (slept 1/fps a frame, they came right after a microphone's
        # last frame, 2 ms after it, and late by the sends' own time: a game developer's review)
        now = time.perf_counter_ns()   # a close long after the last frame (a Session that paused): from now, not
        after = now if self._sent_ns is None else max(self._sent_ns, now - int(1e9 / fps))   # a burst (the diff review)

        def wait(j: int) -> None:
            due = after + j * 1e9 / fps - time.perf_counter_ns()
            if due > 0:
                time.sleep(due / 1e9)
        try:
            for j in range(1, steps + 1):   # from the last frame towards rest, paced at the frame clock
                w = j / (steps + 1)
                pos, rot = self.bones.local((last + w * (neutral - last))[None])
                msgs = self.encoder.messages(self._t + j / fps, pos[0], rot[0],
                                             ((k, (1.0 - w) * v) for k, v in zip(names, values)))
                wait(j)
                self.sender.send(self.encoder.packets(msgs), strict=False)
            if steps:
                wait(steps + 1)
        finally:   # a second Ctrl-C or SIGTERM while easing back: the frame at rest at once, a third one held off
            with deferred():   # until it is sent (the avatar stayed mid-laugh, a VTuber's review)
                self.sender.send(rest, strict=False)   # its error warned of: the frames went out
        self.rest_frames = steps + 1

    def _neutral(self) -> np.ndarray:
        """The pose the character stands in at rest: the idle clip at its start (the run's clip library, which
        the mixer plays), or the T-pose of a skeleton that is not the library's."""
        library, skeleton = self.ctx.clips, self.bones.skeleton
        if library.skeleton != skeleton:
            return rest_pose(skeleton)
        return np.asarray(library.idle.sample_rows(np.zeros(1)), dtype=np.float64)[0]

    def _latency(self) -> dict:
        s = latency_summary(self.lat_ms.array(np.float64))
        return {**s, "max": self.lat_ms.max()} if s["n"] else s   # the max of every frame, not of those kept

    def metrics(self) -> dict:
        """Frames sent and the capture-to-send latency (ms) for ``metrics.json``."""
        s = self._summary or self._latency()
        out = {"vmc_frames": int(self.n), "vmc_dropped_datagrams": int(self.sender.dropped),
               "vmc_refused_sends": int(self.sender.refused), "vmc_early_frames": int(self.early)}
        for key in ("p50", "p90", "p99", "max"):  # None (JSON null) when nothing was measured
            out[f"vmc_latency_ms_{key}"] = s[key] if s["n"] else None
        return out

    def close(self):
        self._finish()
        self._summary = self._latency()
        if self.params.report:
            s = self._summary
            how = "paced at the frame clock" if self.paced else \
                ("live" if self.live else "not paced: as fast as computed")
            dropped = f", {self.sender.dropped} datagrams dropped" if self.sender.dropped else ""
            if self.sender.refused:   # the kernel said nothing listens there (a connected socket; Linux, macOS)
                dropped += f", {self.sender.refused} sends refused: nothing listened there"
            if self.early > self.run.fps:   # more than a second's frames in bursts
                dropped += (f"; {self.early} frames left in bursts, faster than the frame clock: a receiver may drop "
                            "frames that come faster than it reads (realtime=on paces a file; feed a Session a block a "
                            "frame)")
            try:
                # the rest frame counted apart: a receiver counts one message more than the frames (a review)
                rest = ("" if not self._rested else " and a rest frame" if self.rest_frames == 1 else
                        f" and {self.rest_frames} frames back to rest")
                print(f"vmc: {self.n} frame{'' if self.n == 1 else 's'}{rest} to {self.params.host}:{self.params.port} ({how}{dropped}); latency "
                      f"audio block -> OSC send: median {s['p50']:.2f} ms, p90 {s['p90']:.2f} ms, max "
                      f"{s['max']:.2f} ms", file=sys.stdout, flush=True)
            except BrokenPipeError:   # stdout closed (| head): no fault of the session, which is kept (review-live-2 7)
                to_devnull(sys.stdout.fileno())   # what is still buffered goes nowhere
        return []

    def abort(self) -> None:
        if getattr(self, "sender", None) is not None:
            self._finish()


@hookimpl
def register_sinks(register):
    register(VmcSink)
