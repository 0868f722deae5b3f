"""Batched forward kinematics of a kinematic tree: ``(N, D)`` poses to ``(N, J, 3, 4)`` transforms.

Two implementations with the same arrays in and out:

* :func:`forward_kinematics_reference` — plain numpy, a loop over joints (never over poses);
  obviously right, used by tests.
* :func:`forward_kinematics` — numba, parallel over poses; the default. Its per-pose kernel
  :func:`fk_pose_into` is an ``@njit`` function that other numba kernels (fitness) call inline.

A transform ``T[n, j]`` is ``world_from_joint`` as a 3×4 matrix ``[R | t]``: ``R`` the joint frame's
axes in world coordinates (columns), ``t`` its origin in mm. Each joint's local rotation is the
product of elementary rotations described by :class:`KinematicArrays` (thesis sec. 5.1.1: Euler
angles turned into rotation matrices and chained along the tree; Sharifi et al. eq. 4–5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

__all__ = [
    "KinematicArrays",
    "forward_kinematics",
    "forward_kinematics_reference",
    "fk_pose_into",
    "elementary_rotation",
]


@dataclass(frozen=True)
class KinematicArrays:
    """The tree compiled to flat arrays (what numba kernels take).

    Attributes
    ----------
    parents : (J,) int64, ``parents[j] < j``, ``-1`` for the root.
    offsets : (J, 3) float64, joint origin in the parent frame (mm).
    rot_axis : (J, 3) int64, axis 0/1/2 of the k-th elementary rotation, ``-1`` = none.
    rot_sign : (J, 3) float64, ±1.
    rot_param : (J, 3) int64, index of the driving parameter.
    trans_param : (J, 3) int64, parameter added to the origin's x/y/z, ``-1`` = none.
    """

    parents: np.ndarray
    offsets: np.ndarray
    rot_axis: np.ndarray
    rot_sign: np.ndarray
    rot_param: np.ndarray
    trans_param: np.ndarray

    @property
    def n_joints(self) -> int:
        return int(self.parents.shape[0])

    def as_tuple(self) -> tuple[np.ndarray, ...]:
        return (self.parents, self.offsets, self.rot_axis, self.rot_sign, self.rot_param, self.trans_param)


def elementary_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Right-handed rotation matrices about ``x`` (0), ``y`` (1) or ``z`` (2): angles ``(N,)`` → ``(N, 3, 3)``."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    if axis == 0:
        rows = ((one, zero, zero), (zero, c, -s), (zero, s, c))
    elif axis == 1:
        rows = ((c, zero, s), (zero, one, zero), (-s, zero, c))
    elif axis == 2:
        rows = ((c, -s, zero), (s, c, zero), (zero, zero, one))
    else:
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def forward_kinematics_reference(poses: np.ndarray, kin: KinematicArrays) -> np.ndarray:
    """Reference FK in numpy. ``poses (N, D)`` → ``world_from_joint (N, J, 3, 4)``."""
    poses = np.asarray(poses, dtype=np.float64)
    n = poses.shape[0]
    J = kin.n_joints
    R = np.empty((n, J, 3, 3))
    t = np.empty((n, J, 3))
    for j in range(J):
        local = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        for k in range(3):
            ax = int(kin.rot_axis[j, k])
            if ax >= 0:
                local = local @ elementary_rotation(ax, kin.rot_sign[j, k] * poses[:, kin.rot_param[j, k]])
        origin = np.broadcast_to(kin.offsets[j], (n, 3)).copy()
        for a in range(3):
            if kin.trans_param[j, a] >= 0:
                origin[:, a] += poses[:, kin.trans_param[j, a]]
        p = kin.parents[j]
        if p < 0:
            R[:, j] = local
            t[:, j] = origin
        else:
            R[:, j] = R[:, p] @ local
            t[:, j] = t[:, p] + np.einsum("nab,nb->na", R[:, p], origin)
    return np.concatenate([R, t[..., None]], axis=-1)


@nb.njit(cache=True, fastmath=False, nogil=True)
def fk_pose_into(pose, parents, offsets, rot_axis, rot_sign, rot_param, trans_param, out):
    """FK of one pose ``(D,)`` into ``out (J, 3, 4)`` (numba; see :func:`forward_kinematics`)."""
    J = parents.shape[0]
    loc = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for j in range(J):
        # local = product of the joint's elementary rotations, left to right
        for a in range(3):
            for b in range(3):
                loc[a, b] = 1.0 if a == b else 0.0
        for k in range(3):
            ax = rot_axis[j, k]
            if ax < 0:
                continue
            ang = rot_sign[j, k] * pose[rot_param[j, k]]
            c = np.cos(ang)
            s = np.sin(ang)
            # tmp = loc @ E(ax, ang): only the two columns orthogonal to ax change
            i1 = (ax + 1) % 3
            i2 = (ax + 2) % 3
            for a in range(3):
                tmp[a, ax] = loc[a, ax]
                tmp[a, i1] = loc[a, i1] * c + loc[a, i2] * s
                tmp[a, i2] = -loc[a, i1] * s + loc[a, i2] * c
            for a in range(3):
                for b in range(3):
                    loc[a, b] = tmp[a, b]
        ox = offsets[j, 0]
        oy = offsets[j, 1]
        oz = offsets[j, 2]
        if trans_param[j, 0] >= 0:
            ox += pose[trans_param[j, 0]]
        if trans_param[j, 1] >= 0:
            oy += pose[trans_param[j, 1]]
        if trans_param[j, 2] >= 0:
            oz += pose[trans_param[j, 2]]
        p = parents[j]
        if p < 0:
            for a in range(3):
                for b in range(3):
                    out[j, a, b] = loc[a, b]
            out[j, 0, 3] = ox
            out[j, 1, 3] = oy
            out[j, 2, 3] = oz
        else:
            for a in range(3):
                for b in range(3):
                    out[j, a, b] = out[p, a, 0] * loc[0, b] + out[p, a, 1] * loc[1, b] + out[p, a, 2] * loc[2, b]
                out[j, a, 3] = out[p, a, 3] + out[p, a, 0] * ox + out[p, a, 1] * oy + out[p, a, 2] * oz


@nb.njit(cache=True, parallel=True, nogil=True)
def _fk_batch(poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param, out):
    for n in nb.prange(poses.shape[0]):
        fk_pose_into(poses[n], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, out[n])


@nb.njit(cache=True, nogil=True)
def _fk_batch_serial(poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param, out):
    for n in range(poses.shape[0]):
        fk_pose_into(poses[n], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, out[n])


# Below this batch size one thread is faster than waking the pool (about 1 us per pose).
PARALLEL_MIN_BATCH = 256


def forward_kinematics(poses: np.ndarray, kin: KinematicArrays) -> np.ndarray:
    """Batched FK (numba; parallel over poses for large batches).

    ``poses (N, D)`` → ``world_from_joint (N, J, 3, 4)``.
    """
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    out = np.empty((poses.shape[0], kin.n_joints, 3, 4))
    kernel = _fk_batch if poses.shape[0] >= PARALLEL_MIN_BATCH else _fk_batch_serial
    kernel(poses, *kin.as_tuple(), out)
    return out
