"""Streaming a run as the VMC protocol: ARKit blendshapes and Unity humanoid bones over OSC.

The VMC protocol (Virtual Motion Capture, https://protocol.vmc.info) is OSC 1.0
over UDP; VSeeFace, Warudo, VMagicMirror and Unity receivers (EVMC4U) read it.
One animation frame is sent as::

    /VMC/Ext/OK        1 3 0 1              (int: loaded, calibration state, calibration mode, tracking)
    /VMC/Ext/T         time                 (float, s since the stream started)
    /VMC/Ext/Root/Pos  "root" 0 0 0  0 0 0 1
    /VMC/Ext/Bone/Pos  NAME px py pz qx qy qz qw     one per humanoid bone (Hips first)
    /VMC/Ext/Blend/Val NAME value                    one per blendshape, value in [0, 1]
    /VMC/Ext/Blend/Apply

in OSC bundles (time tag "immediately") of at most ``max_packet_bytes`` each;
``/VMC/Ext/Blend/Apply`` is always the last message of a frame.  The messages
are encoded here (:func:`osc_message`, :func:`osc_bundle`; OSC 1.0: padded
strings, big-endian int32/float32) because a per-frame encoder over
precomputed byte prefixes costs about 20 us a frame where building the same
bundle with python-osc's builders costs about 0.5 ms; the tests parse the
stream with python-osc's own server.

Face: ARKit blendshapes
-----------------------
A face that writes ARKit channels (``arkit.<name>``, e.g. the ``facs`` face)
is passed through: every ``arkit.*`` channel is sent under its ARKit name,
clipped to [0, 1].  Otherwise the ``smile`` face's channels are mapped
(:data:`SMILE_TO_ARKIT`)::

    jawOpen                 = jaw
    mouthLowerDown{L,R}     = 0.3 jaw          (the lower lip follows the jaw)
    mouthSmile{L,R}         = smile            (AU12)
    cheekSquint{L,R}        = 0.7 smile        (AU6: the Duchenne cheek raise of laughter)
    eyeSquint{L,R}          = 0.3 smile        (the raised cheek narrows the eye from below)
    eyeBlink{L,R}           = eyes_closed      (clip eye keys and blinks; ``blink`` if no eyes_closed)

each clipped to [0, 1].  ``Left``/``Right`` are the character's own sides.

Skeleton: Unity humanoid bones
------------------------------
Our joints map one to one onto Unity's humanoid bones (:data:`UNITY_BONES`):
hips Hips, spine Spine, spine1 Chest, spine2 UpperChest, neck Neck, head Head,
{side}_clavicle {Side}Shoulder, _upper_arm UpperArm, _forearm LowerArm, _hand
Hand, _thigh UpperLeg, _shin LowerLeg, _foot Foot, _toe Toes.  With
``upper_chest=False`` (avatars without an UpperChest bone) spine2's rotation is
folded into Chest (``R_chest = R_spine1 R_spine2``, an approximation: the
shoulders then bend about the lower pivot).

Both rigs have their rest pose in a T-pose with every local rotation the
identity (VRM's normalised bones), so a joint's local rotation relative to
its parent is sent as the bone's local rotation.

Coordinate conversion
~~~~~~~~~~~~~~~~~~~~~
laughlab is right-handed, Y up, the character faces +Z and its left is +X, cm
(:mod:`laughlab.motion.skeleton`).  Unity is left-handed, Y up, a humanoid faces +Z
and its right is +X, metres.  Forward and up agree; the sides are mirrored,
so the change of frame is the reflection ``S = diag(-1, 1, 1)``::

    p_unity = S p / 100                 = (-x, y, z) / 100 m
    R_unity = S R S

``S R S`` is the rotation by the same angle about the axis ``det(S) S u =
(ux, -uy, -uz)`` (an axis is a pseudovector: a mirror flips it once more), so
a quaternion ``(qx, qy, qz, qw)`` becomes::

    q_unity = (qx, -qy, -qz, qw)

and our local rotation ``R = Rz(z) Rx(x) Ry(y)`` (BVH ZXY order, degrees) is
the quaternion ``q = qz * qx * qy`` (Hamilton product, :func:`euler_zxy_to_quat`).
Bone positions are the joints' rest offsets from their parent (the hips: their
position above the root), converted the same way.
"""
from __future__ import annotations

import errno
import math
import socket
import struct
import sys
import time
from typing import Iterable, Iterator, Mapping

import numpy as np

from laughlab.core.errors import LaughlabError

__all__ = [
    "SMILE_TO_ARKIT", "UNITY_BONES", "VRM_PRESETS", "arkit_weights", "euler_zxy_to_quat", "quat_to_matrix",
    "to_unity_quat", "to_unity_position", "BoneMap", "osc_string", "osc_message", "osc_bundle", "VmcEncoder",
    "VmcSender", "paced_chunks", "DEFAULT_PORT",
]

DEFAULT_PORT = 39539
"""The VMC protocol's usual receiver port (VSeeFace, Warudo, EVMC4U)."""

SMILE_TO_ARKIT: dict[str, dict[str, float]] = {
    "jawOpen": {"jaw": 1.0},
    "mouthLowerDownLeft": {"jaw": 0.3},
    "mouthLowerDownRight": {"jaw": 0.3},
    "mouthSmileLeft": {"smile": 1.0},
    "mouthSmileRight": {"smile": 1.0},
    "cheekSquintLeft": {"smile": 0.7},
    "cheekSquintRight": {"smile": 0.7},
    "eyeSquintLeft": {"smile": 0.3},
    "eyeSquintRight": {"smile": 0.3},
    "eyeBlinkLeft": {"eyes_closed": 1.0},
    "eyeBlinkRight": {"eyes_closed": 1.0},
}
"""ARKit blendshape = clip(sum of weight x channel, 0, 1) for faces without ``arkit.*`` channels."""

VRM_PRESETS: dict[str, tuple[str, ...]] = {
    "A": ("jawOpen",),
    "Joy": ("mouthSmileLeft", "mouthSmileRight"),
    "Blink_L": ("eyeBlinkLeft",),
    "Blink_R": ("eyeBlinkRight",),
}
"""VRM 0.x preset clips (mean of these ARKit values), for avatars without perfect-sync clips."""

UNITY_BONES: dict[str, str] = {
    "hips": "Hips", "spine": "Spine", "spine1": "Chest", "spine2": "UpperChest", "neck": "Neck", "head": "Head",
    **{f"{s}_{j}": f"{S}{b}" for s, S in (("left", "Left"), ("right", "Right"))
       for j, b in (("clavicle", "Shoulder"), ("upper_arm", "UpperArm"), ("forearm", "LowerArm"), ("hand", "Hand"),
                    ("thigh", "UpperLeg"), ("shin", "LowerLeg"), ("foot", "Foot"), ("toe", "Toes"))},
}
"""Our joint name -> Unity ``HumanBodyBones`` name."""

ARKIT_PREFIX = "arkit."


def arkit_weights(channels: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """ARKit blendshape weights (each clipped to [0, 1], NaN as 0) from a chunk's channels.

    Uses the ``arkit.*`` channels when there are any, else maps the ``smile``
    face's channels by :data:`SMILE_TO_ARKIT` (entries whose channels are all
    missing are left out).  Arrays keep the channels' shape.
    """
    names = [k for k in channels if k.startswith(ARKIT_PREFIX)]
    if names:
        try:   # one clip of them all: per name, it cost a live frame 0.8 ms in numpy's call overhead
            block = _unit(np.stack([np.asarray(channels[k], dtype=np.float64) for k in names]))
        except ValueError:   # channels of different shapes
            return {k[len(ARKIT_PREFIX):]: _unit(channels[k]) for k in names}
        return {k[len(ARKIT_PREFIX):]: block[i] for i, k in enumerate(names)}
    src = dict(channels)
    if "eyes_closed" not in src and "blink" in src:
        src["eyes_closed"] = src["blink"]
    out = {}
    for name, terms in SMILE_TO_ARKIT.items():
        have = [(src[c], w) for c, w in terms.items() if c in src]
        if have:
            out[name] = _unit(sum(w * np.asarray(v, dtype=np.float64) for v, w in have))
    return out


def _unit(x) -> np.ndarray:
    return np.clip(np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0), 0.0, 1.0)


# -- rotations ---------------------------------------------------------------------------------------------------

def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of ``(..., 4)`` quaternions stored as (x, y, z, w)."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def euler_zxy_to_quat(angles_deg: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of ``Rz(z) @ Rx(x) @ Ry(y)`` from ``(..., 3)`` angles (z, x, y) in degrees.

    Matches :func:`laughlab.motion.skeleton.euler_to_matrix`.
    """
    h = np.radians(np.asarray(angles_deg, dtype=np.float64)) * 0.5
    zero = np.zeros(h.shape[:-1])
    qz = np.stack([zero, zero, np.sin(h[..., 0]), np.cos(h[..., 0])], axis=-1)
    qx = np.stack([np.sin(h[..., 1]), zero, zero, np.cos(h[..., 1])], axis=-1)
    qy = np.stack([zero, np.sin(h[..., 2]), zero, np.cos(h[..., 2])], axis=-1)
    return _qmul(_qmul(qz, qx), qy)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions ``(..., 4)`` (x, y, z, w)."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def to_unity_quat(q: np.ndarray) -> np.ndarray:
    """Our (right-handed, left = +X) quaternion (x, y, z, w) in Unity's left-handed frame: (x, -y, -z, w)."""
    q = np.array(q, dtype=np.float64, copy=True)
    q[..., 1:3] *= -1.0
    return q + 0.0  # no negative zeros


def to_unity_position(p_cm: np.ndarray) -> np.ndarray:
    """Our position (cm) in Unity's frame (m): (-x, y, z) / 100."""
    p = np.asarray(p_cm, dtype=np.float64) / 100.0
    return p * np.array([-1.0, 1.0, 1.0]) + 0.0  # no negative zeros


class BoneMap:
    """Which of a skeleton's joints go out as which Unity bone, and their rest positions.

    Parameters
    ----------
    skeleton : Skeleton
    upper_chest : bool
        Send ``spine2`` as UpperChest; if False fold its rotation into Chest.
    names : dict, optional
        Joint name -> Unity bone name (default :data:`UNITY_BONES`); joints not
        in it are not sent.
    """

    def __init__(self, skeleton, upper_chest: bool = True, names: Mapping[str, str] | None = None):
        names = dict(UNITY_BONES if names is None else names)
        self.skeleton = skeleton
        self.fold: dict[int, int] = {}  # joint folded away -> the joint that takes its rotation
        if not upper_chest and "spine2" in skeleton.names and "spine1" in skeleton.names:
            names.pop("spine2", None)
            self.fold[skeleton.index("spine2")] = skeleton.index("spine1")
        self.joints = [j for j, n in enumerate(skeleton.names) if n in names]
        self.bones = [names[skeleton.names[j]] for j in self.joints]
        offsets = np.array(skeleton.offsets, dtype=np.float64)
        for folded in self.fold:  # children of a folded joint hang from its parent: add its offset
            for c in skeleton.children(folded):
                offsets[c] = offsets[c] + offsets[folded]
        self.offsets = offsets
        self.rest = to_unity_position(offsets[self.joints])
        self.hips_move = None   # with an avatar: (its hips at rest, laughlab's rest root (cm), scale of the motion,
        #                         the hips' world position into its parent's frame: (A, b))

    def place(self, offsets_cm: np.ndarray, hips_cm: np.ndarray, rest_root_cm: np.ndarray, scale: float,
              to_parent: tuple | None = None) -> "BoneMap":
        """Send another character's bones: their offsets (``(len(joints), 3)``, laughlab's frame, cm), its hips at
        rest, the root's motion from laughlab's rest root scaled by ``scale``, and ``to_parent = (A, b)``, which
        takes the hips' world position into its parent's frame, ``A @ p + b`` (the Hips' local position; None:
        the world's), as :func:`laughlab.avatar.retarget.vmc_rest` gives them; the rotations are the same."""
        self.rest = to_unity_position(np.asarray(offsets_cm, dtype=np.float64))
        A, b = to_parent if to_parent is not None else (np.eye(3), np.zeros(3))
        self.hips_move = (np.asarray(hips_cm, dtype=np.float64), np.asarray(rest_root_cm, dtype=np.float64), scale,
                          np.asarray(A, dtype=np.float64), np.asarray(b, dtype=np.float64))
        return self

    def local(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unity local positions ``(F, B, 3)`` (m) and rotations ``(F, B, 4)`` (x, y, z, w) of the bones."""
        poses = np.atleast_2d(np.asarray(poses, dtype=np.float64))
        f, jn = poses.shape[0], self.skeleton.n_joints
        q = euler_zxy_to_quat(poses[:, 3:3 + 3 * jn].reshape(f, jn, 3))
        for folded, into in self.fold.items():
            q[:, into] = _qmul(q[:, into], q[:, folded])
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        rot = to_unity_quat(q[:, self.joints])
        pos = np.broadcast_to(self.rest, (f, len(self.joints), 3)).copy()
        if self.joints and self.joints[0] == 0:  # the root carries the pose's translation
            root = self.skeleton.offsets[0] + poses[:, :3]
            if self.hips_move is not None:
                hips, rest_root, scale, A, b = self.hips_move
                root = (hips + (root - rest_root) * scale) @ A.T + b
            pos[:, 0] = to_unity_position(root)
        return pos, rot


# -- OSC 1.0 encoding --------------------------------------------------------------------------------------------

def osc_string(s: str) -> bytes:
    """An OSC string: UTF-8, null-terminated, padded with nulls to a multiple of 4 bytes."""
    b = s.encode("utf-8")
    return b + b"\0" * (4 - len(b) % 4)


def osc_message(address: str, *args) -> bytes:
    """One OSC message; ``int`` args are int32 (i), ``float`` float32 (f), ``str`` strings (s)."""
    tags, data = ",", []
    for a in args:
        if isinstance(a, bool) or isinstance(a, (int, np.integer)):
            tags += "i"
            data.append(struct.pack(">i", int(a)))
        elif isinstance(a, (float, np.floating)):
            tags += "f"
            data.append(struct.pack(">f", float(a)))
        elif isinstance(a, str):
            tags += "s"
            data.append(osc_string(a))
        else:
            raise TypeError(f"unsupported OSC argument {a!r}")
    return osc_string(address) + osc_string(tags) + b"".join(data)


_BUNDLE_HEAD = b"#bundle\0" + struct.pack(">Q", 1)  # time tag 1 = "immediately"


def osc_bundle(messages: Iterable[bytes]) -> bytes:
    """An OSC bundle (time tag immediately) of encoded messages."""
    return _BUNDLE_HEAD + b"".join(struct.pack(">i", len(m)) + m for m in messages)


class VmcEncoder:
    """Encodes frames as VMC messages over precomputed byte prefixes.

    Parameters
    ----------
    bones : list of str
        Unity bone names, in the order their values are given.
    max_packet_bytes : int
        Largest bundle (bytes); a frame's messages are split into several
        bundles below it (0: one bundle per frame, however large).
    """

    OK = osc_message("/VMC/Ext/OK", 1, 3, 0, 1)
    APPLY = osc_message("/VMC/Ext/Blend/Apply")
    ROOT = osc_message("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    _T = osc_string("/VMC/Ext/T") + osc_string(",f")
    _BONE = osc_string("/VMC/Ext/Bone/Pos") + osc_string(",sfffffff")
    _BLEND = osc_string("/VMC/Ext/Blend/Val") + osc_string(",sf")

    def __init__(self, bones: list[str], max_packet_bytes: int = 1400):
        self.bone_prefix = [self._BONE + osc_string(b) for b in bones]
        self.max_packet_bytes = int(max_packet_bytes)
        self._blend_prefix: dict[str, bytes] = {}

    def _blend(self, name: str) -> bytes:
        p = self._blend_prefix.get(name)
        if p is None:
            p = self._blend_prefix[name] = self._BLEND + osc_string(name)
        return p

    def messages(self, t: float, positions: np.ndarray, rotations: np.ndarray,
                 blends: Iterable[tuple[str, float]]) -> list[bytes]:
        """The messages of one frame, in protocol order (OK first, Blend/Apply last)."""
        msgs = [self.OK, self._T + struct.pack(">f", t), self.ROOT]
        vals = np.concatenate([positions, rotations], axis=1).tolist()
        pack7 = struct.Struct(">7f").pack
        msgs += [p + pack7(*v) for p, v in zip(self.bone_prefix, vals)]
        msgs += [self._blend(n) + struct.pack(">f", v) for n, v in blends]
        msgs.append(self.APPLY)
        return msgs

    def packets(self, messages: list[bytes]) -> list[bytes]:
        """Bundle messages into datagrams no larger than ``max_packet_bytes`` (order kept)."""
        limit = self.max_packet_bytes
        if limit <= 0:
            return [osc_bundle(messages)]
        out, cur, size = [], [], len(_BUNDLE_HEAD)
        for m in messages:
            n = 4 + len(m)
            if cur and size + n > limit:
                out.append(osc_bundle(cur))
                cur, size = [], len(_BUNDLE_HEAD)
            cur.append(m)
            size += n
        if cur:
            out.append(osc_bundle(cur))
        return out


#: send errors that pass (the network, the receiver, the socket's buffer, a firewall's full connection table):
#: the datagram is dropped and counted.  Any other (EINVAL, EAFNOSUPPORT, EMSGSIZE, EBADF, EACCES...) comes
#: back on every send, and ends the run (:class:`VmcSendError`).  Windows' socket codes too.
TRANSIENT_ERRNOS = frozenset(getattr(errno, prefix + name) for name in (
    "EAGAIN", "EWOULDBLOCK", "EINTR", "ENOBUFS", "ENOMEM", "EHOSTUNREACH", "ENETUNREACH", "EHOSTDOWN", "ENETDOWN",
    "ENETRESET", "ECONNREFUSED", "ECONNRESET", "EPERM") for prefix in ("", "WSA") if hasattr(errno, prefix + name))


class VmcSendError(LaughlabError):
    """A send error that comes back on every send: the stream cannot go out at all."""


class VmcSender:
    """A UDP socket to one VMC receiver that never makes the frame loop wait.

    The socket is non-blocking: a datagram it cannot take at once is dropped and counted (``dropped``).  A
    LAN address nobody answers (the avatar PC switched off) fills the send buffer while the kernel waits 3 s
    for ARP, and a blocking ``sendto`` froze the frame loop for those 3 s (review-live 2).  Other send errors
    that pass (:data:`TRANSIENT_ERRNOS`: no route, no buffer space) drop the datagram too; the first of each
    kind is said once on stderr with the address and the cause, never as a fault of the run's folder.
    ``ConnectionRefusedError`` (nobody listening on that port; the socket is connected so that the kernel says it)
    goes on, counted (``refused``) and said once as a note.  An error that
    would come back on every send (an IPv6 link-local address without its scope, a datagram too large for
    the path) raises :class:`VmcSendError`, one line with the address and the cause: the run stops rather
    than run to its end sending nothing (diff-review 7).  ``SO_BROADCAST`` is set on IPv4, so a broadcast
    address (255.255.255.255, or the LAN's) reaches every receiver on it.  A host name that resolves to both
    families is sent to over IPv4 (VSeeFace, Warudo and EVMC4U listen on IPv4); an IPv6 address stays IPv6.

    Raises ``OSError`` (from ``socket.getaddrinfo``) if the host does not resolve.
    """

    def __init__(self, host: str, port: int):
        infos = socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)
        # a name with an IPv4 address goes to it: VMC receivers listen on IPv4 only, and 'localhost' resolved to
        # ::1 first (Debian's /etc/hosts, Windows) sent the stream where nobody listens, silently (review-live-2 1)
        info = next((i for i in infos if i[0] == socket.AF_INET), infos[0])
        self.address = info[4]
        self.where = f"{host}:{port}"
        self.sock = socket.socket(info[0], socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        if info[0] == socket.AF_INET:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        self.connected = False
        try:   # connected, the kernel says when nothing listens there (Linux, macOS: ICMP port unreachable)
            self.sock.connect(self.address)
            self.connected = True   # then send(), not sendto(): BSD and macOS refuse an address (EISCONN)
        except OSError:   # not now (no route yet): sent to as before, the errors said at send
            pass
        self.packets = 0   # datagrams handed to the socket
        self.dropped = 0   # datagrams dropped: the socket could not take them, or refused them
        self.refused = 0   # sends the receiver's machine answered "nothing listens on that port"
        self.failed: VmcSendError | None = None   # the error that ended the stream
        self._said: set = set()

    def send(self, packets: list[bytes], strict: bool = True) -> None:
        """Send ``packets``; an error that would come back on every send raises :class:`VmcSendError`, or with
        ``strict=False`` (the frame at rest, the stream's last) is dropped and said like a passing one."""
        for p in packets:
            try:
                if self.connected:
                    self.sock.send(p)
                else:
                    self.sock.sendto(p, self.address)
            except ConnectionRefusedError:  # nobody listening (ICMP port unreachable): UDP goes on, said once (a
                self.refused += 1           # VTuber's review: a wrong port streamed to nobody without a word)
                if self.refused == 1:
                    print(f"laughlab: note: output.vmc: nothing listens at {self.where} (yet): is the receiver "
                          "running, on this port? The stream goes on", file=sys.stderr, flush=True)
            except BlockingIOError:
                self._drop("BlockingIOError", "the network does not take the datagrams as fast as they come: is "
                                              "the receiver switched off or asleep?")
                continue
            except OSError as exc:
                cause = exc.strerror or type(exc).__name__
                if exc.errno not in TRANSIENT_ERRNOS and strict:
                    hint = (f" (a datagram of {len(p)} bytes: set output.vmc.max_packet_bytes lower, 1400 fits "
                            "Ethernet)" if exc.errno == errno.EMSGSIZE else "")
                    self.failed = VmcSendError(f"output.vmc: cannot send to {self.where}: {cause}{hint}; the run stops "
                                               "and what it wrote is removed")
                    raise self.failed from None
                self._drop(exc.errno, cause)
                continue
            self.packets += 1

    def _drop(self, kind, cause: str) -> None:
        self.dropped += 1
        if kind not in self._said:
            self._said.add(kind)
            print(f"laughlab: warning: output.vmc: cannot send to {self.where} ({cause}); its datagrams are dropped "
                  "and counted (the vmc line, metrics.json: vmc_dropped_datagrams)", file=sys.stderr, flush=True)

    def close(self) -> None:
        self.sock.close()


def paced_chunks(audio: np.ndarray, sample_rate: int, block: int, clock=time.perf_counter,
                 sleep=time.sleep, on_start=None) -> Iterator[np.ndarray]:
    """Yield ``audio`` in blocks of ``block`` samples at real time, like a capture device.

    Block ``i`` (samples ``[i*block, (i+1)*block)``) is released when its last
    sample would have been captured: ``t0 + (i + 1) * block / sample_rate``
    after the first request.  ``on_start(t0)`` receives the start time (the
    wall-clock time of sample 0).  A stand-in for a microphone in tests and
    benchmarks.
    """
    t0 = clock()
    if on_start is not None:
        on_start(t0)
    audio = np.asarray(audio, dtype=np.float32)
    for i, start in enumerate(range(0, len(audio), block)):
        end = min(len(audio), start + block)
        due = t0 + end / sample_rate
        wait = due - clock()
        if wait > 0:
            sleep(wait)
        yield audio[start:end]


def latency_summary(ms: np.ndarray) -> dict:
    """Median, p90, p99 and max of latencies (ms); NaN when there are none."""
    ms = np.asarray(ms, dtype=np.float64)
    ms = ms[np.isfinite(ms)]
    if not len(ms):
        return {"p50": math.nan, "p90": math.nan, "p99": math.nan, "max": math.nan, "n": 0}
    return {"p50": float(np.percentile(ms, 50)), "p90": float(np.percentile(ms, 90)),
            "p99": float(np.percentile(ms, 99)), "max": float(ms.max()), "n": int(len(ms))}
