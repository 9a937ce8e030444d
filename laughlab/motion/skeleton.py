"""Humanoid skeleton, pose vectors and forward kinematics.

Conventions
-----------
Units are centimetres and degrees. The world is Y up, the floor is ``y = 0``
and the character faces +Z in its rest pose, so its left side is +X.

Pose vector
    One frame is a float64 vector of length ``3 + 3 * J``::

        [root_x, root_y, root_z,            # root (hips) position, cm
         z_0, x_0, y_0,                     # joint 0 Euler angles, degrees
         z_1, x_1, y_1, ...]                # ... one triple per joint

    The angle triples follow the BVH channel order ``Zrotation Xrotation
    Yrotation``: the local rotation of a joint is ``R = Rz(z) @ Rx(x) @ Ry(y)``
    and it rotates the offsets of the joint's children (standard BVH).  The
    world position of the root is ``offsets[0] + (root_x, root_y, root_z)``
    (the root offset of ``HUMANOID`` is zero).  A motion is an ``(F, 3 + 3J)``
    array of such vectors.

Handy signs for ``HUMANOID`` (rest = T-pose, arms along +-X):

* spine/neck/head ``x > 0`` bends forward, ``x < 0`` leans back;
  ``y`` twists (turns) about the vertical axis, ``z`` bends sideways.
* left upper arm ``z < 0`` lowers the arm (``-78`` hangs it by the side),
  ``y < 0`` swings it forward; the right side mirrors as ``(-z, x, -y)``.
* thigh ``x < 0`` lifts the knee forward, shin ``x > 0`` bends the knee.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Skeleton",
    "HUMANOID",
    "rest_pose",
    "forward_kinematics",
    "global_transforms",
    "euler_to_matrix",
    "matrix_to_euler",
]


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joint hierarchy with rest offsets.

    Parameters
    ----------
    names : tuple of str
        Joint names, parents listed before children (depth-first order is
        what BVH files use).
    parents : tuple of int
        Parent index per joint, ``-1`` for the root (exactly one root).
    offsets : ndarray, shape (J, 3)
        Offset of each joint from its parent in the parent's frame, cm.
    end_sites : ndarray, shape (J, 3), optional
        BVH ``End Site`` offset for joints without children, cm (rows of
        joints with children are ignored).  Defaults to zeros.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    end_sites: np.ndarray = field(default=None)

    def __post_init__(self) -> None:
        names, parents = tuple(self.names), tuple(int(p) for p in self.parents)
        offsets = np.array(self.offsets, dtype=np.float64).reshape(-1, 3)
        ends = np.zeros_like(offsets) if self.end_sites is None else np.array(
            self.end_sites, dtype=np.float64).reshape(-1, 3)
        if not (len(names) == len(parents) == len(offsets) == len(ends)):
            raise ValueError("names, parents, offsets and end_sites differ in length")
        if len(set(names)) != len(names):
            raise ValueError("joint names are not unique")
        if not parents or parents[0] != -1 or any(not 0 <= p < i for i, p in enumerate(parents) if i):
            raise ValueError("joint 0 must be the only root and parents must precede children")
        offsets.flags.writeable = False
        ends.flags.writeable = False
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "end_sites", ends)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Skeleton):
            return NotImplemented
        return (self.names == other.names and self.parents == other.parents
                and np.allclose(self.offsets, other.offsets, atol=1e-4)
                and np.allclose(self.end_sites[self.leaves()], other.end_sites[other.leaves()], atol=1e-4))

    __hash__ = None  # type: ignore[assignment]

    @property
    def n_joints(self) -> int:
        """Number of joints ``J`` (End Sites excluded)."""
        return len(self.names)

    @property
    def n_channels(self) -> int:
        """Length of a pose vector, ``3 + 3 * J``."""
        return 3 + 3 * self.n_joints

    def index(self, name: str) -> int:
        """Index of joint ``name`` (``KeyError`` if unknown)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"unknown joint {name!r}") from None

    def children(self, j: int) -> list[int]:
        """Indices of the direct children of joint ``j``."""
        return [i for i, p in enumerate(self.parents) if p == j]

    def leaves(self) -> list[int]:
        """Indices of joints without children (they carry an End Site)."""
        has_child = set(self.parents)
        return [j for j in range(self.n_joints) if j not in has_child]

    def channel_names(self) -> list[str]:
        """Names of the pose-vector entries, e.g. ``hips_Xposition``, ``hips_Zrotation``."""
        root = self.names[0]
        out = [f"{root}_{a}position" for a in "XYZ"]
        for n in self.names:
            out += [f"{n}_{a}rotation" for a in "ZXY"]
        return out

    def angle_slice(self, name: str) -> slice:
        """Slice of the ``(z, x, y)`` angles of joint ``name`` in a pose vector."""
        k = 3 + 3 * self.index(name)
        return slice(k, k + 3)


def _humanoid() -> Skeleton:
    # (name, parent, offset cm, end site cm). Adult ~175 cm, hips at 95 cm.
    spec = [
        ("hips", None, (0, 0, 0), None),
        ("spine", "hips", (0, 10, 0), None),
        ("spine1", "spine", (0, 12, 0), None),
        ("spine2", "spine1", (0, 12, 0), None),
        ("neck", "spine2", (0, 17, 0), None),
        ("head", "neck", (0, 9, 1), (0, 20, 0)),                # head_end = End Site
    ]
    for side, s in (("left", 1), ("right", -1)):
        spec += [
            (f"{side}_clavicle", "spine2", (3 * s, 13, 2), None),
            (f"{side}_upper_arm", f"{side}_clavicle", (14 * s, 0, -2), None),
            (f"{side}_forearm", f"{side}_upper_arm", (28 * s, 0, 0), None),
            (f"{side}_hand", f"{side}_forearm", (25 * s, 0, 0), (17 * s, 0, 0)),
        ]
    for side, s in (("left", 1), ("right", -1)):
        spec += [
            (f"{side}_thigh", "hips", (9 * s, -4, 0), None),
            (f"{side}_shin", f"{side}_thigh", (0, -42, 0), None),
            (f"{side}_foot", f"{side}_shin", (0, -41, 0), None),
            (f"{side}_toe", f"{side}_foot", (0, -6, 12), (0, -1, 6)),
        ]
    names = tuple(n for n, *_ in spec)
    parents = tuple(-1 if p is None else names.index(p) for _, p, _, _ in spec)
    ends = [e if e is not None else (0, 0, 0) for *_, e in spec]
    return Skeleton(names, parents, np.array([o for _, _, o, _ in spec], float), np.array(ends, float))


HUMANOID: Skeleton = _humanoid()
"""Default 22-joint humanoid (69 channels); rest pose is a T-pose, hips 95 cm high."""

HIPS_HEIGHT_CM = 95.0


def rest_pose(skeleton: Skeleton = HUMANOID) -> np.ndarray:
    """Rest pose vector: root at hips height (95 cm) above the origin, all angles 0.

    Returns
    -------
    ndarray, shape (3 + 3J,)
    """
    pose = np.zeros(skeleton.n_channels)
    pose[1] = HIPS_HEIGHT_CM
    return pose


def euler_to_matrix(angles_deg: np.ndarray) -> np.ndarray:
    """Rotation matrices ``Rz(z) @ Rx(x) @ Ry(y)`` from ``(..., 3)`` angles ``(z, x, y)`` in degrees.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    a = np.radians(np.asarray(angles_deg, dtype=np.float64))
    cz, cx, cy = np.cos(a[..., 0]), np.cos(a[..., 1]), np.cos(a[..., 2])
    sz, sx, sy = np.sin(a[..., 0]), np.sin(a[..., 1]), np.sin(a[..., 2])
    r = np.empty(a.shape[:-1] + (3, 3))
    r[..., 0, 0] = cz * cy - sz * sx * sy
    r[..., 0, 1] = -sz * cx
    r[..., 0, 2] = cz * sy + sz * sx * cy
    r[..., 1, 0] = sz * cy + cz * sx * sy
    r[..., 1, 1] = cz * cx
    r[..., 1, 2] = sz * sy - cz * sx * cy
    r[..., 2, 0] = -cx * sy
    r[..., 2, 1] = sx
    r[..., 2, 2] = cx * cy
    return r


def matrix_to_euler(r: np.ndarray) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix`: ``(..., 3, 3)`` -> ``(..., 3)`` angles ``(z, x, y)`` in degrees.

    ``x`` is in ``[-90, 90]``; at the gimbal singularity ``y`` is set to 0.
    """
    r = np.asarray(r, dtype=np.float64)
    x = np.arcsin(np.clip(r[..., 2, 1], -1.0, 1.0))
    lock = np.abs(r[..., 2, 1]) > 1 - 1e-9
    z = np.where(lock, np.arctan2(r[..., 1, 0], r[..., 0, 0]), np.arctan2(-r[..., 0, 1], r[..., 1, 1]))
    y = np.where(lock, 0.0, np.arctan2(-r[..., 2, 0], r[..., 2, 2]))
    return np.degrees(np.stack([z, x, y], axis=-1))


def global_transforms(skeleton: Skeleton, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions and world rotation matrices of every joint.

    Parameters
    ----------
    skeleton : Skeleton
    poses : ndarray, shape (F, 3 + 3J) or (3 + 3J,)

    Returns
    -------
    positions : ndarray, shape (F, J, 3) (or (J, 3)), cm
    rotations : ndarray, shape (F, J, 3, 3) (or (J, 3, 3))
    """
    poses = np.asarray(poses, dtype=np.float64)
    single = poses.ndim == 1
    poses = np.atleast_2d(poses)
    if poses.shape[1] != skeleton.n_channels:
        raise ValueError(f"poses have {poses.shape[1]} channels, skeleton needs {skeleton.n_channels}")
    f, jn = poses.shape[0], skeleton.n_joints
    local = euler_to_matrix(poses[:, 3:].reshape(f, jn, 3))
    pos = np.empty((f, jn, 3))
    rot = np.empty((f, jn, 3, 3))
    pos[:, 0] = skeleton.offsets[0] + poses[:, :3]
    rot[:, 0] = local[:, 0]
    for j in range(1, jn):
        p = skeleton.parents[j]
        pos[:, j] = pos[:, p] + rot[:, p] @ skeleton.offsets[j]
        rot[:, j] = rot[:, p] @ local[:, j]
    return (pos[0], rot[0]) if single else (pos, rot)


def forward_kinematics(skeleton: Skeleton, poses: np.ndarray, end_sites: bool = False) -> np.ndarray:
    """World joint positions for a batch of pose vectors.

    Parameters
    ----------
    skeleton : Skeleton
    poses : ndarray, shape (F, 3 + 3J) or (3 + 3J,)
        Pose vectors (see module docstring).
    end_sites : bool
        If true, append the End Site positions of the leaf joints (in
        ``skeleton.leaves()`` order) after the J joints.

    Returns
    -------
    ndarray, shape (F, J, 3) (or (F, J + n_leaves, 3)); a single pose gives (J, 3).
        World positions in cm.
    """
    pos, rot = global_transforms(skeleton, poses)
    if not end_sites:
        return pos
    leaves = skeleton.leaves()
    ends = pos[..., leaves, :] + np.einsum("...ij,...j->...i", rot[..., leaves, :, :], skeleton.end_sites[leaves])
    return np.concatenate([pos, ends], axis=-2)
