"""Export tracked motion as a Biovision hierarchy (BVH) file for animation tools.

The hierarchy is the body model's own kinematic tree: one ``JOINT`` per model joint (depth-first,
children in model order), ``OFFSET`` = the joint's offset from its parent (the subject's
measurement, mm unless ``scale`` says otherwise), three rotation channels on every joint, position
channels on the root (and on any other joint the model translates), and an ``End Site`` on every
leaf, so importers give the leaf bone a length: by default a continuation of the bone by a quarter of
its length (30-100 mm: hands, toes). Two leaves get a shape instead, so that the figure neither grows
nor sticks through the floor: the head top's end site points forward (the face's direction, a
quarter of the neck-to-head-top length), and an ankle that ends the leg (a model without feet)
gets a foot, 0.4 x the shank long, pointing forward and 30 degrees down. These end sites are
drawing aids; the tracked joints are the ``JOINT`` s.

Axes
----
The swarmpose world is right-handed, millimetres, **Z up** (x forward and y to the subject's left
in the zero pose). BVH tools expect **Y up**, so by default every vector is written as::

    bvh = (x, z, -y)        (a rotation of -90 degrees about x; its inverse is world = (x, -z, y))

which is exactly the inverse of what :func:`swarmpose.io.mocap.load_clip` applies to a BVH file,
so an exported clip loaded back with ``unit="mm"`` lands in the same world. ``y_up=False`` keeps
the world's axes (Z up).

Rest pose
---------
Animation tools expect the rest pose (all channels zero) to stand facing **+Z** with Y up (the
subject's left along +X), as the CMU files do. The body model's zero pose faces the world's +x,
which the axes above would put on BVH +X (the character would appear turned by 90 degrees). So by
default (``rest_facing="+z"``, Y up only) the rest skeleton is laid out turned by ``Q = Ry(-90°)``
(offsets ``Q A o``), every joint's rotation is conjugated by ``Q`` and the root's carries the
constant ``Q^T``: the joints still land at ``A p`` in every frame, so the round trip above holds.
``rest_facing="+x"`` keeps the model's own rest orientation.

Rotations
---------
In the zero pose every model joint frame is aligned with the world, as BVH joint frames are in
the rest pose (all channels zero). A joint's BVH rotation is its local rotation
``L = G_parent^T G_joint`` (``G`` from :meth:`BodyModel.forward`), expressed in the rest pose's BVH
axes (``B L B^T`` with ``B = Q A``, see *Rest pose*; the root's is ``A G_root B^T``), and written
as Euler angles in degrees for the channel order (default ``Zrotation Xrotation Yrotation``:
``L = Rz(z) Rx(x) Ry(y)``, the BVH convention of :mod:`swarmpose.io.bvh`). Of the two Euler
solutions of each frame the one closest to the previous frame is taken and each angle is
unwrapped, so the curves are continuous (no 360 degree jumps) for animation tools that
interpolate them. ``rotation_order="model"`` writes each joint's own elementary axes in the
model's order instead (the channels then are the model's joint angles, with the sign of the axis,
and the extra axes are zero; the root's also carry the rest turn of *Rest pose*).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.joints import JOINTS15

__all__ = ["export_bvh", "bvh_axes", "rest_rotation", "euler_from_matrices", "uniform_clock", "ROTATION_ORDERS",
           "REST_FACINGS"]

#: Channel orders accepted by :func:`export_bvh` (besides ``"model"``).
ROTATION_ORDERS = ("ZXY", "ZYX", "XYZ", "XZY", "YXZ", "YZX")
#: Rest-pose orientations accepted by :func:`export_bvh`: facing BVH +Z (tools' convention) or the model's +x.
REST_FACINGS = ("+z", "+x")
_AX = "XYZ"


def bvh_axes(y_up: bool = True) -> np.ndarray:
    """The 3x3 matrix ``A`` with ``bvh = A @ world`` (``(x, z, -y)`` for Y up, identity otherwise)."""
    if y_up:
        return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    return np.eye(3)


def rest_rotation(y_up: bool = True, rest_facing: str = "+z") -> np.ndarray:
    """The 3x3 rotation ``Q`` (in BVH axes) that turns the model's rest pose to face ``rest_facing``.

    ``Ry(-90°)`` (BVH +X to +Z) for Y up and ``"+z"``; the identity for ``"+x"`` or Z up (a Z-up file
    keeps the world's axes entirely).
    """
    facing = str(rest_facing).lower()
    if facing not in REST_FACINGS:
        raise ConfigError(f"unknown rest facing {rest_facing!r} (known: {', '.join(REST_FACINGS)})")
    if y_up and facing == "+z":
        return np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    return np.eye(3)


def euler_from_matrices(mats: np.ndarray, order: str, *, continuous: bool = True) -> np.ndarray:
    """Euler angles (degrees) of rotation matrices for a BVH channel order, continuous over frames.

    Parameters
    ----------
    mats : numpy.ndarray, shape (T, 3, 3)
        Rotation matrices, one per frame.
    order : str
        Three distinct letters of ``XYZ`` in channel order: ``"ZXY"`` means
        ``R = Rz(a) @ Rx(b) @ Ry(c)`` and returns ``(a, b, c)``.
    continuous : bool, default True
        Pick, frame by frame, the Euler solution nearest to the previous frame's angles and unwrap
        each angle to within 180 degrees of it (frame 0 takes the solution with the middle angle in
        [-90, 90]).

    Returns
    -------
    numpy.ndarray, shape (T, 3)
        Angles in degrees, in ``order``.
    """
    from scipy.spatial.transform import Rotation

    order = order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ConfigError(f"rotation order must be 3 distinct axes of XYZ, got {order!r}")
    mats = np.asarray(mats, dtype=np.float64).reshape(-1, 3, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: the rotation is still exact
        a = Rotation.from_matrix(mats).as_euler(order, degrees=True)  # upper case: intrinsic = R1 R2 R3
    if not continuous or len(a) < 2:
        return a
    b = np.stack([a[:, 0] + 180.0, 180.0 - a[:, 1], a[:, 2] + 180.0], axis=1)  # the other solution
    out = np.empty_like(a)
    out[0] = a[0]
    for t in range(1, len(a)):
        ref = out[t - 1]
        ca = ref + (a[t] - ref + 180.0) % 360.0 - 180.0
        cb = ref + (b[t] - ref + 180.0) % 360.0 - 180.0
        out[t] = cb if np.abs(cb - ref).sum() < np.abs(ca - ref).sum() else ca
    return out


def _end_site(bone_offset, role: str | None) -> np.ndarray:
    """The End Site offset of a leaf joint in the model's zero-pose axes (mm; forward +x, up +z).

    ``role`` ``"head"``: forward, a quarter of the bone (30-100 mm); ``"foot"`` (an ankle that ends the
    leg): 0.4 x the shank, forward and 30 degrees down; otherwise the bone continued by a quarter of its
    length (30-100 mm), or 50 mm up for a bone of zero length.
    """
    bone = np.asarray(bone_offset, dtype=np.float64)
    n = float(np.linalg.norm(bone))
    if n <= 1e-9:
        return np.array([0.0, 0.0, 50.0])
    if role == "head":
        return np.array([float(np.clip(0.25 * n, 30.0, 100.0)), 0.0, 0.0])
    if role == "foot":
        a = np.radians(30.0)
        return 0.4 * n * np.array([np.cos(a), 0.0, -np.sin(a)])
    return bone / n * float(np.clip(0.25 * n, 30.0, 100.0))


def _children(parents: np.ndarray) -> list[list[int]]:
    kids: list[list[int]] = [[] for _ in range(len(parents))]
    for j, p in enumerate(parents):
        if p >= 0:
            kids[int(p)].append(j)
    return kids


def _model_order(model, j: int, A: np.ndarray) -> str:
    """Channel order of joint ``j``'s own elementary rotations in the BVH axes, completed to 3 axes."""
    kin = model.kin
    axes = []
    for k in range(3):
        ax = int(kin.rot_axis[j, k])
        if ax >= 0:
            mapped = int(np.argmax(np.abs(A[:, ax])))  # A e_ax = +-e_mapped
            if mapped not in axes:
                axes.append(mapped)
    axes += [a for a in range(3) if a not in axes]
    return "".join(_AX[a] for a in axes)


def uniform_clock(params: np.ndarray, frame_times: np.ndarray, frame_rate: float,
                  tolerance: float = 0.01) -> tuple[np.ndarray, np.ndarray, bool]:
    """Poses on the uniform clock a BVH file needs: ``(params (T', D), times (T',), resampled)``.

    A tracking rate that does not divide the sequence's (25 fps from 60) tracks the nearest frames, 33 and
    50 ms apart; written one per ``1 / frame_rate`` they would warp time by up to 25 % (velocities off by
    as much, alternating). When an interval differs from ``1 / frame_rate`` by more than ``tolerance``
    (relative), every parameter is interpolated linearly in time onto ``t_0 + k / frame_rate``; otherwise
    the poses are returned as they are. The clock has as many steps as fit the tracked span, rounded to the
    nearest: T frames tracked at the nearest frames of a ``frame_rate`` clock give T frames, the last of
    which may lie up to half a step past the last tracked time and holds its pose (25 fps from 60: frame 3
    at 120 ms, tracked at 117). Angles are interpolated as the tracker keeps them (continuous, unwrapped),
    between neighbours at most one tracked interval apart.
    """
    p = np.asarray(params, dtype=np.float64)
    t = np.asarray(frame_times, dtype=np.float64)
    if t.shape != (p.shape[0],):
        raise ConfigError(f"frame_times must hold {p.shape[0]} times (one per pose), got shape {t.shape}")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise ConfigError("frame_times must be finite and increasing (seconds)")
    if not frame_rate > 0:
        raise ConfigError(f"frame_rate must be > 0, got {frame_rate!r}")
    step = 1.0 / frame_rate
    if len(t) < 2 or np.all(np.abs(np.diff(t) - step) <= tolerance * step):
        return p, t, False
    grid = t[0] + np.arange(int(np.round((t[-1] - t[0]) / step)) + 1) * step
    out = np.stack([np.interp(grid, t, p[:, d]) for d in range(p.shape[1])], axis=1)  # held past t[-1]
    return out, grid, True


def export_bvh(
    model,
    params: np.ndarray,
    frame_rate: float,
    path: str | os.PathLike[str],
    *,
    y_up: bool = True,
    rotation_order: str = "ZXY",
    scale: float = 1.0,
    decimals: int = 6,
    rest_facing: str = "+z",
) -> Path:
    """Write poses of a body model as a BVH file (see the module docstring for axes and angles).

    Parameters
    ----------
    model : BodyModel
        The tracked body model (its joints become the BVH hierarchy).
    params : numpy.ndarray, shape (T, D)
        One pose per frame (a ``(D,)`` pose is one frame).
    frame_rate : float
        Frames per second (``Frame Time: 1 / frame_rate``).
    path : path-like
        The ``.bvh`` file to write (parent folders are created).
    y_up : bool, default True
        Write Y-up axes ``(x, z, -y)``; False keeps the world's Z-up axes.
    rotation_order : str, default "ZXY"
        Channel order of every joint's rotation (one of :data:`ROTATION_ORDERS`), or ``"model"``
        for each joint's own axes.
    scale : float, default 1.0
        File units per millimetre (1 = mm, 0.1 = cm, 0.001 = m).
    decimals : int, default 6
        Decimals of the written numbers.
    rest_facing : {"+z", "+x"}, default "+z"
        Where the rest pose (all channels zero) faces in a Y-up file: +Z as animation tools expect,
        or +X, the model's own zero pose. The joint positions of every frame are the same either way.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ShapeError
        ``params`` is not ``(T, D)`` for the model.
    ConfigError
        Non-positive ``frame_rate`` or ``scale``, no frames, an unknown rotation order or rest facing.

    Examples
    --------
    >>> from swarmpose.body.model import load_model
    >>> model = load_model("balan31")
    >>> poses = np.tile(model.zero_pose(), (3, 1)); poses[:, 5] = 1000.0
    >>> p = export_bvh(model, poses, 60.0, "/tmp/zero.bvh")   # doctest: +SKIP
    """
    P = model.check_poses(params, "params")
    T = P.shape[0]
    if T < 1:
        raise ConfigError("params has no frames to export")
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ConfigError(f"frame_rate must be > 0, got {frame_rate!r}")
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigError(f"scale must be > 0, got {scale!r}")
    order_all = str(rotation_order)
    if order_all != "model" and order_all.upper() not in ROTATION_ORDERS:
        raise ConfigError(f"unknown rotation order {rotation_order!r} (known: {', '.join(ROTATION_ORDERS)}, model)")
    A = bvh_axes(y_up)
    B = rest_rotation(y_up, rest_facing) @ A  # rest-pose joint axes in BVH coordinates
    kin = model.kin
    names = model.spec.joint_names
    parents = np.asarray(kin.parents)
    J = len(names)
    kids = _children(parents)

    G = model.forward(P)  # (T, J, 3, 4) world_from_joint
    Rb = np.einsum("ab,tjbc,dc->tjad", A, G[..., :3], B)  # joint axes in BVH coordinates, from the rest pose
    pb = np.einsum("ab,tjb->tja", A, G[..., 3]) * scale
    translated = [j for j in range(J) if parents[j] < 0 or np.any(kin.trans_param[j] >= 0)]

    # depth-first joint order (children in model order)
    dfs: list[int] = []
    stack = [j for j in range(J) if parents[j] < 0][::-1]
    while stack:
        j = stack.pop()
        dfs.append(j)
        stack.extend(kids[j][::-1])

    orders = {j: (_model_order(model, j, B) if order_all == "model" else order_all.upper()) for j in range(J)}
    columns: list[np.ndarray] = []
    channel_names: dict[int, list[str]] = {}
    for j in dfs:
        p = int(parents[j])
        chans: list[str] = []
        if j in translated:
            if p < 0:
                local_t = pb[:, j]
            else:
                local_t = np.einsum("tba,tb->ta", Rb[:, p], pb[:, j] - pb[:, p])
            chans += ["Xposition", "Yposition", "Zposition"]
            columns += [local_t[:, 0], local_t[:, 1], local_t[:, 2]]
        local_R = Rb[:, j] if p < 0 else np.einsum("tba,tbc->tac", Rb[:, p], Rb[:, j])
        ang = euler_from_matrices(local_R, orders[j])
        chans += [f"{c}rotation" for c in orders[j]]
        columns += [ang[:, 0], ang[:, 1], ang[:, 2]]
        channel_names[j] = chans

    num = f"{{:.{int(decimals)}f}}"

    def vec(v: np.ndarray) -> str:
        return " ".join(num.format(float(x) + 0.0) for x in v)

    role_of = {"head_top": "head", "l_ankle": "foot", "r_ankle": "foot"}
    leaf_roles = {int(j): role_of[name] for name, j in zip(JOINTS15, model.joints15_index, strict=True)
                  if name in role_of and not kids[int(j)]}
    lines = ["HIERARCHY"]

    def write_joint(j: int, depth: int) -> None:
        ind = "\t" * depth
        p = int(parents[j])
        lines.append(f"{ind}{'ROOT' if p < 0 else 'JOINT'} {names[j]}")
        lines.append(f"{ind}{{")
        off = np.zeros(3) if p < 0 else B @ np.asarray(kin.offsets[j]) * scale
        lines.append(f"{ind}\tOFFSET {vec(off)}")
        lines.append(f"{ind}\tCHANNELS {len(channel_names[j])} {' '.join(channel_names[j])}")
        for c in kids[j]:
            write_joint(c, depth + 1)
        if not kids[j]:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {vec(B @ _end_site(kin.offsets[j], leaf_roles.get(j)) * scale)}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    for root in (j for j in range(J) if parents[j] < 0):
        write_joint(root, 0)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / float(frame_rate):.8f}"]
    motion = np.stack(columns, axis=1)
    motion[np.abs(motion) < 0.5 * 10.0 ** -int(decimals)] = 0.0  # no "-0.000000"
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", encoding="ascii", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
        np.savetxt(fh, motion, fmt=f"%.{int(decimals)}f", delimiter=" ")
    return out
