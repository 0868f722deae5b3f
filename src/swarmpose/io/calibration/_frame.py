"""Units and up axis of a calibration's world: detection, and the change to swarmpose's (mm, z up)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError

__all__ = ["AXES", "world_from_up", "detect_up", "detect_units", "to_world"]

#: Signed world axes, as ``up=`` names them.
AXES: dict[str, np.ndarray] = {
    "+x": np.array([1.0, 0.0, 0.0]), "-x": np.array([-1.0, 0.0, 0.0]),
    "+y": np.array([0.0, 1.0, 0.0]), "-y": np.array([0.0, -1.0, 0.0]),
    "+z": np.array([0.0, 0.0, 1.0]), "-z": np.array([0.0, 0.0, -1.0]),
}

# x_new = A x_old with A @ up = +z: a quarter or half turn about a horizontal axis (det +1).
_WORLD_FROM_UP: dict[str, np.ndarray] = {
    "+z": np.eye(3),
    "-z": np.diag([1.0, -1.0, -1.0]),  # half turn about x
    "+y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # (x, y, z) -> (x, -z, y)
    "-y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),  # (x, y, z) -> (x, z, -y)
    "+x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),  # (x, y, z) -> (-z, y, x)
    "-x": np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),  # (x, y, z) -> (z, y, -x)
}

#: Largest angle (degrees) between the cameras' mean image-up direction and the axis it snaps to.
UP_MAX_ANGLE = 40.0
#: A plain OpenCV file whose cameras are a median of less than this from the rig's centre is in metres.
METRES_BELOW = 50.0


def check_up(up: str) -> str:
    """``up`` normalised (``"y"`` -> ``"+y"``), or a ConfigError listing the choices."""
    u = str(up).strip().lower()
    u = "+" + u if u in ("x", "y", "z") else u
    if u not in AXES:
        raise ConfigError(f"up must be one of {', '.join(AXES)}, got {up!r}")
    return u


def world_from_up(up: str) -> np.ndarray:
    """The rotation ``A`` (3x3, det +1) with ``A @ up = (0, 0, 1)``: ``x_new = A @ x_old``.

    ``+y`` (y up) maps ``(x, y, z)`` to ``(x, -z, y)``, the usual y-up to z-up change; the x axis is kept
    for the y and z cases, the y axis for the x cases.
    """
    return _WORLD_FROM_UP[check_up(up)].copy()


def detect_up(cameras: Sequence[Camera]) -> tuple[str, str]:
    """The world's up axis from the cameras' image "up" directions, and a note saying how clear it was.

    Each camera's image up, ``-R[1, :]`` (minus its y axis in world coordinates), is averaged over the
    cameras; the mean snaps to the nearest signed world axis.

    Raises
    ------
    ConfigError
        The mean is more than 40 degrees from every axis (or zero): pass ``up=``.
    """
    ups = np.stack([-np.asarray(c.R)[1, :] for c in cameras])
    mean = ups.mean(axis=0)
    norm = float(np.linalg.norm(mean))
    if norm < 1e-9:
        raise ConfigError("cannot detect the up axis: the cameras' image-up directions cancel out; pass up=")
    mean /= norm
    k = int(np.argmax(np.abs(mean)))
    axis = ("+" if mean[k] > 0 else "-") + "xyz"[k]
    angle = math.degrees(math.acos(min(1.0, abs(float(mean[k])))))
    each = np.degrees(np.arccos(np.clip(ups @ AXES[axis], -1.0, 1.0)))
    if angle > UP_MAX_ANGLE:
        raise ConfigError(f"cannot detect the up axis: the cameras' mean image-up direction "
                          f"{np.round(mean, 3).tolist()} is {angle:.0f} degrees from the nearest axis {axis}; "
                          "pass up=")
    note = (f"up axis {axis} detected from the {len(cameras)} cameras' image-up directions: their mean is "
            f"{angle:.1f} degrees from {axis} (each camera {each.min():.0f} to {each.max():.0f} degrees)")
    return axis, note


def detect_units(cameras: Sequence[Camera]) -> tuple[str, str]:
    """``"m"`` or ``"mm"`` from the rig's spread, and a note saying why.

    The median distance of the camera centres from their centroid (from the origin for one camera)
    below 50 file units means metres, else millimetres. A centimetre file needs ``units="cm"``.
    """
    centres = np.stack([c.center for c in cameras])
    if len(cameras) > 1:
        d = float(np.median(np.linalg.norm(centres - centres.mean(axis=0), axis=1)))
        what = "from the rig's centre"
    else:
        d = float(np.linalg.norm(centres[0]))
        what = "from the world origin (one camera)"
    if d == 0.0:
        raise ConfigError("cannot detect the length unit: the camera is at the world origin; pass units=")
    units = "m" if d < METRES_BELOW else "mm"
    note = (f"length unit detected as {'metres' if units == 'm' else 'millimetres'}: the cameras are a median "
            f"{d:.4g} file units {what} (below {METRES_BELOW:g} means metres; pass units= to override, e.g. "
            "units='cm')")
    return units, note


def to_world(cam: Camera, A: np.ndarray, mm_per_unit: float) -> Camera:
    """The camera in the new world ``x_new = A x_old`` (old in file units): ``R' = R A^T``, ``t' = t * scale``."""
    return Camera(name=cam.name, width=cam.width, height=cam.height, fx=cam.fx, fy=cam.fy, cx=cam.cx, cy=cam.cy,
                  skew=cam.skew, dist=cam.dist, R=np.asarray(cam.R) @ A.T, t=np.asarray(cam.t) * mm_per_unit)
