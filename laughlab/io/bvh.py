"""BVH (Biovision Hierarchy) motion files.

:func:`write_bvh` writes the project's pose convention (see
:mod:`laughlab.motion.skeleton`): a ROOT with ``Xposition Yposition Zposition
Zrotation Xrotation Yrotation`` channels, JOINTs with ``Zrotation Xrotation
Yrotation`` and an End Site under every leaf joint; numbers with 4 decimals,
written atomically (:func:`hierarchy_lines` and :func:`format_frames` serve
streaming writers).  :func:`read_bvh` reads any single-root BVH and converts
other rotation orders to ZXY.
"""
from __future__ import annotations

import os
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np

from laughlab.motion.skeleton import Skeleton, euler_to_matrix, matrix_to_euler

__all__ = ["write_bvh", "read_bvh", "hierarchy_lines", "format_frames", "frame_time_line"]

_ROOT_CHANNELS = "Xposition Yposition Zposition Zrotation Xrotation Yrotation"
_JOINT_CHANNELS = "Zrotation Xrotation Yrotation"


def _fmt(values) -> str:
    return " ".join(f"{v + 0.0:.4f}" for v in np.round(np.asarray(values, float), 4))


def _dfs_order(skeleton: Skeleton) -> list[int]:
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(skeleton.children(j)))
    return order


def hierarchy_lines(skeleton: Skeleton) -> list[str]:
    """Lines of the ``HIERARCHY`` section (from ``HIERARCHY`` to the root's closing brace).

    Raises
    ------
    ValueError
        If a joint name contains whitespace.
    """
    if any(re.search(r"\s", n) for n in skeleton.names):
        raise ValueError("joint names must not contain whitespace")
    lines = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        tab = "\t" * depth
        kind, chans = ("ROOT", f"6 {_ROOT_CHANNELS}") if j == 0 else ("JOINT", f"3 {_JOINT_CHANNELS}")
        lines.extend([f"{tab}{kind} {skeleton.names[j]}", f"{tab}{{",
                      f"{tab}\tOFFSET {_fmt(skeleton.offsets[j])}", f"{tab}\tCHANNELS {chans}"])
        kids = skeleton.children(j)
        for c in kids:
            emit(c, depth + 1)
        if not kids:
            lines.extend([f"{tab}\tEnd Site", f"{tab}\t{{",
                          f"{tab}\t\tOFFSET {_fmt(skeleton.end_sites[j])}", f"{tab}\t}}"])
        lines.append(f"{tab}}}")

    emit(0, 0)
    return lines


def frame_time_line(frame_time_s: float) -> str:
    """The ``Frame Time:`` line (no newline), with 10 decimals.

    Readers take the frame rate as ``1 / Frame Time``: Blender's BVH importer (``Update Scene FPS``) sets
    the scene's rate to ``round(1 / t)`` and its ``fps_base`` to the ratio, a 32-bit float.  Seven decimals
    (``0.0166667``) gave 59.99988 fps there (``fps_base`` 1.000002); ten give the run's rate exactly at
    every rate up to 1000 fps.
    """
    return f"Frame Time: {frame_time_s:.10f}"


def format_frames(skeleton: Skeleton, motion: np.ndarray) -> str:
    """MOTION-section text of pose vectors: one line per frame, 4 decimals, ``\\n``-terminated.

    Parameters
    ----------
    skeleton : Skeleton
    motion : ndarray, shape (F, 3 + 3J) or (3 + 3J,)

    Returns
    -------
    str
        Columns in the hierarchy's depth-first joint order (as BVH requires).
    """
    motion = np.atleast_2d(np.asarray(motion, dtype=np.float64))
    if motion.shape[1] != skeleton.n_channels:
        raise ValueError(f"motion has {motion.shape[1]} channels, skeleton needs {skeleton.n_channels}")
    if not np.all(np.isfinite(motion)):
        raise ValueError("motion contains non-finite values")
    order = _dfs_order(skeleton)
    if order != list(range(skeleton.n_joints)):  # BVH channels follow the hierarchy's DFS order
        motion = motion[:, [0, 1, 2] + [3 + 3 * j + k for j in order for k in range(3)]]
    return _fixed4_lines(motion)


def _fixed4_lines(motion: np.ndarray) -> str:
    """Rows of numbers with 4 decimals, space-separated, one row per line (vectorised).

    Each number is right-aligned in a fixed-width field (e.g. ``    -12.3456``) of at least four
    integer digits, so the layout does not depend on how the frames are chunked: a live run's
    file equals an offline run's.  Every BVH reader accepts it (fields are whitespace-separated); this
    is several times faster than Python's per-number formatting.  Rounding is
    numpy's (half to even on the 4th decimal); ``-0.0000`` is written ``0.0000``.
    """
    n, c = motion.shape
    if n == 0:
        return ""
    v = np.round(motion * 1e4).astype(np.int64)
    neg = v < 0
    ip, fr = np.divmod(np.abs(v), 10000)
    width = max(4, len(str(int(ip.max()))))  # 4 integer digits at least: the same layout whatever the chunk
    nd = np.ones_like(ip)
    for k in range(1, width):
        nd += ip >= 10 ** k
    field = 1 + 1 + width + 5  # separator, sign slot, integer digits, '.', 4 decimals
    buf = np.full((n, c, field), ord(" "), dtype=np.uint8)
    for k in range(width):  # integer digits, most significant first, at 2 + k
        digit = (ip // 10 ** (width - 1 - k)) % 10
        buf[:, :, 2 + k] = np.where(k >= width - nd, ord("0") + digit, ord(" "))
    rows, cols = np.nonzero(neg)
    buf[rows, cols, (1 + width - nd)[rows, cols]] = ord("-")  # just before the first digit
    buf[:, :, 2 + width] = ord(".")
    for k in range(4):
        buf[:, :, 3 + width + k] = ord("0") + (fr // 10 ** (3 - k)) % 10
    lines = np.empty((n, c * field + 1), dtype=np.uint8)
    lines[:, :-1] = buf.reshape(n, c * field)
    lines[:, -1] = ord("\n")
    return lines.tobytes().decode("ascii")


def write_bvh(path: str | os.PathLike, skeleton: Skeleton, motion: np.ndarray, frame_time_s: float) -> Path:
    """Write a motion to a BVH file (atomically: temp file + ``os.replace``).

    Parameters
    ----------
    path : str or PathLike
        Destination ``.bvh`` file.
    skeleton : Skeleton
        Joint names must not contain whitespace.
    motion : ndarray, shape (F, 3 + 3J)
        Pose vectors (root position cm, ZXY Euler angles degrees).
    frame_time_s : float
        Seconds per frame, e.g. ``1 / 24``.

    Returns
    -------
    Path
        The written path.
    """
    motion = np.atleast_2d(np.asarray(motion, dtype=np.float64))
    text = "\n".join(hierarchy_lines(skeleton) + ["MOTION", f"Frames: {len(motion)}",
                                                  frame_time_line(frame_time_s), ""])
    body = format_frames(skeleton, motion)
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="ascii", newline="\n") as fh:
            fh.write(text)
            fh.write(body)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600 files
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def read_bvh(path: str | os.PathLike) -> tuple[Skeleton, np.ndarray, float]:
    """Read a single-root BVH file.

    Rotation channels in any order are converted to the ZXY convention;
    position channels on non-root joints are ignored (with a warning).

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    skeleton : Skeleton
    motion : ndarray, shape (F, 3 + 3J)
        Root position (cm) then ``(z, x, y)`` degrees per joint.
    frame_time_s : float

    Raises
    ------
    ValueError
        One-line message with the line number on malformed input.
    """
    lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    head_end = next((i for i, ln in enumerate(lines) if ln.lstrip().startswith("Frame Time")), len(lines) - 1)
    toks = [(t, i + 1) for i, ln in enumerate(lines[:head_end + 1]) for t in ln.split()]
    pos = 0

    def fail(msg: str, line: int | None = None) -> ValueError:
        if line is None:
            line = toks[pos][1] if pos < len(toks) else len(lines)
        return ValueError(f"{path}: line {line}: {msg}")

    def take(expected: str | None = None) -> str:
        nonlocal pos
        if pos >= len(toks):
            raise fail(f"unexpected end of file (expected {expected or 'more data'})")
        tok = toks[pos][0]
        if expected is not None and tok != expected:
            raise fail(f"expected {expected!r}, found {tok!r}")
        pos += 1
        return tok

    def number() -> float:
        tok = take()
        try:
            return float(tok)
        except ValueError:
            raise fail(f"expected a number, found {tok!r}", toks[pos - 1][1]) from None

    names, parents, offsets, ends, channels = [], [], [], [], []

    def joint(parent: int) -> None:
        j = len(names)
        names.append(take())
        parents.append(parent)
        ends.append((0.0, 0.0, 0.0))
        take("{")
        take("OFFSET")
        offsets.append((number(), number(), number()))
        chans: list[str] = []
        if pos < len(toks) and toks[pos][0] == "CHANNELS":
            take()
            n = take()
            if not n.isdigit():
                raise fail(f"bad channel count {n!r}", toks[pos - 1][1])
            chans = [take() for _ in range(int(n))]
            bad = [c for c in chans if c not in {f"{a}{k}" for a in "XYZ" for k in ("position", "rotation")}]
            if bad:
                raise fail(f"unknown channel {bad[0]!r}")
        channels.append(chans)
        while True:
            tok = take()
            if tok == "}":
                return
            if tok == "JOINT":
                joint(j)
            elif tok == "End":
                take("Site")
                take("{")
                take("OFFSET")
                ends[j] = (number(), number(), number())
                take("}")
            else:
                raise fail(f"unexpected token {tok!r}", toks[pos - 1][1])

    take("HIERARCHY")
    take("ROOT")
    joint(-1)
    take("MOTION")
    take("Frames:")
    n_frames = number()
    if n_frames != int(n_frames) or n_frames < 0:
        raise fail(f"bad frame count {n_frames}", toks[pos - 1][1])
    n_frames = int(n_frames)
    take("Frame")
    take("Time:")
    frame_time = number()
    data_line = toks[pos - 1][1]  # frames start on the next line
    width = sum(len(c) for c in channels)
    rows = lines[data_line:]
    try:
        values = np.array(" ".join(rows).split(), dtype=np.float64)
    except ValueError:
        values = None
    if values is None or values.size != n_frames * width:
        count = 0
        for k, ln in enumerate(rows, start=data_line + 1):
            parts = ln.split()
            if not parts:
                continue
            count += 1
            if len(parts) != width:
                raise ValueError(f"{path}: line {k}: expected {width} values, found {len(parts)}")
            try:
                [float(p) for p in parts]
            except ValueError:
                raise ValueError(f"{path}: line {k}: non-numeric motion value") from None
        raise ValueError(f"{path}: line {len(lines)}: header says {n_frames} frames, found {count}")
    raw = values.reshape(n_frames, width)

    jn = len(names)
    motion = np.zeros((n_frames, 3 + 3 * jn))
    col = 0
    for j, chans in enumerate(channels):
        cols = {c: col + k for k, c in enumerate(chans)}
        col += len(chans)
        if j == 0:
            for a, axis in enumerate("XYZ"):
                if f"{axis}position" in cols:
                    motion[:, a] = raw[:, cols[f"{axis}position"]]
        elif any(c.endswith("position") for c in chans):
            warnings.warn(f"{path}: position channels of joint {names[j]!r} ignored", stacklevel=2)
        rot = [c for c in chans if c.endswith("rotation")]
        order = "".join(c[0] for c in rot)
        if order == "ZXY":
            motion[:, 3 + 3 * j:6 + 3 * j] = raw[:, [cols[c] for c in rot]]
        elif rot:
            mats = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
            for c in rot:
                a = np.zeros((n_frames, 3))
                a[:, "ZXY".index(c[0])] = raw[:, cols[c]]
                mats = mats @ euler_to_matrix(a)
            eul = matrix_to_euler(mats)
            motion[:, 3 + 3 * j:6 + 3 * j] = np.degrees(np.unwrap(np.radians(eul), axis=0))
    skeleton = Skeleton(tuple(names), tuple(parents), np.array(offsets), np.array(ends))
    return skeleton, motion, float(frame_time)
