"""HumanEva-like camera rigs placed around a clip's capture volume.

:func:`default_rig` puts four greyscale cameras ``BW1..BW4`` (644x484, like HumanEva-I's BW
cameras, humaneva-facts §1.1) at the "corners" of the trajectory -- azimuths 45, 135, 225 and 315
degrees from the walking direction -- 2.15-2.45 m high, 3-7 m from the volume's centre and looking
at it. Each camera's distance and focal length (380-1200 px) make the person as large as possible
while every joint of every frame, grown by a body margin, stays inside the image with a pixel
margin; mild barrel distortion (``k1`` between -0.07 and -0.10) only pulls points further in. Rigs
are stored with :func:`swarmpose.camera.save_rig` / :func:`~swarmpose.camera.load_rig` (JSON).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from swarmpose.camera import Camera, load_rig, save_rig
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.io.mocap import MocapClip

__all__ = ["RigSettings", "default_rig", "capture_volume", "rig_summary", "save_rig", "load_rig"]


@dataclass(frozen=True)
class RigSettings:
    """How :func:`default_rig` places its cameras.

    Parameters
    ----------
    width, height : int, default 644 x 484
        Image size in pixels (HumanEva BW cameras).
    heights_mm : tuple of float, default (2300, 2150, 2450, 2200)
        Height of each camera's optical centre; also fixes the number of cameras.
    body_margin_mm : float, default 250
        Padding added around the joints (the body's flesh, head and feet extend past them).
    pixel_margin : float, default 0.06
        Fraction of each image half-size kept free at the borders.
    k1 : tuple of float, default (-0.08, -0.10, -0.07, -0.09)
        Radial distortion per camera (Bouguet ``kc(1)``; ``k2 = k3 = 0``, no tangential terms).
    f_min, f_max : float, default 380 and 1200
        Focal-length range in pixels (horizontal field of view 30-80 degrees at 644 px).
    distance_mm : (float, float), default (3000, 7000)
        Range of horizontal distances of the cameras from the volume's centre (a large lab).
    principal_offset_px : tuple of (float, float), default small offsets
        Principal point offset from the image centre per camera.
    """

    width: int = 644
    height: int = 484
    heights_mm: tuple[float, ...] = (2300.0, 2150.0, 2450.0, 2200.0)
    body_margin_mm: float = 250.0
    pixel_margin: float = 0.06
    k1: tuple[float, ...] = (-0.08, -0.10, -0.07, -0.09)
    f_min: float = 380.0
    f_max: float = 1200.0
    distance_mm: tuple[float, float] = (3000.0, 7000.0)
    principal_offset_px: tuple[tuple[float, float], ...] = ((2.5, -1.5), (-1.0, 2.0), (1.5, 1.0), (-2.0, -2.5))

    def __post_init__(self) -> None:
        n = len(self.heights_mm)
        if n < 1:
            raise ConfigError("RigSettings.heights_mm must name at least one camera height")
        if len(self.k1) != n or len(self.principal_offset_px) != n:
            raise ConfigError(f"RigSettings: heights_mm, k1 and principal_offset_px need {n} entries each, got "
                              f"{len(self.k1)} and {len(self.principal_offset_px)}")
        if not (0 <= self.pixel_margin < 0.5):
            raise ConfigError(f"RigSettings.pixel_margin must be in [0, 0.5), got {self.pixel_margin!r}")
        if not (0 < self.f_min < self.f_max):
            raise ConfigError(f"RigSettings: need 0 < f_min < f_max, got {self.f_min!r}, {self.f_max!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (for provenance)."""
        return asdict(self)


def capture_volume(points: np.ndarray, margin_mm: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounding box of points, grown by ``margin_mm`` (the floor side clamped at z = 0).

    Parameters
    ----------
    points : numpy.ndarray, shape (..., 3)
        World mm; NaN rows are ignored.
    margin_mm : float

    Returns
    -------
    lo, hi : numpy.ndarray, shape (3,)
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.size == 0:
        raise ShapeError("capture_volume: no finite points")
    lo = p.min(axis=0) - margin_mm
    hi = p.max(axis=0) + margin_mm
    lo[2] = min(max(lo[2], 0.0), p[:, 2].min())
    return lo, hi


def _clip_points(clip: MocapClip | np.ndarray) -> np.ndarray:
    if isinstance(clip, MocapClip):
        pts = [clip.positions, clip.end_sites]
        return np.concatenate([p.reshape(-1, 3) for p in pts])
    return np.asarray(clip, dtype=np.float64).reshape(-1, 3)


def _principal_axis(xy: np.ndarray) -> np.ndarray:
    """Unit direction of the largest horizontal spread of ``xy (N, 2)`` (x axis when round)."""
    d = xy - xy.mean(axis=0)
    cov = d.T @ d / max(len(d), 1)
    w, v = np.linalg.eigh(cov)
    if w[1] <= 1.5 * max(w[0], 1e-9):  # no clear walking direction: keep the world axes
        return np.array([1.0, 0.0])
    axis = v[:, 1]
    return axis if axis[0] >= 0 else -axis


def _fit_focal(cam: Camera, pts: np.ndarray, margin_mm: float, room_u: float, room_v: float) -> float:
    """Largest focal length keeping every point (grown by ``margin_mm``) inside the image; 0 if behind."""
    xyz = cam.cam_from_world(pts)
    z = xyz[:, 2]
    if np.any(z <= margin_mm + 100.0):
        return 0.0
    a = ((np.abs(xyz[:, 0]) + margin_mm) / z).max()  # normalized half-extent needed, x
    b = ((np.abs(xyz[:, 1]) + margin_mm) / z).max()
    return float(min(room_u / a, room_v / b))


def default_rig(clip: MocapClip | np.ndarray, settings: RigSettings | None = None) -> list[Camera]:
    """HumanEva-like cameras around a clip's capture volume.

    The cameras stand at the "corners" of the trajectory: at azimuths 45, 135, 225 and 315 degrees
    from the walking direction (the principal horizontal axis of the points; the world x axis when
    the motion stays in place), at heights ``settings.heights_mm``, looking at the centre of the
    volume. Per camera the horizontal distance (in ``distance_mm``, 100 mm steps) is the nearest
    one that makes the person within 3 % as large as possible in the image (median over the points
    of ``f / distance``) while every point, grown by ``body_margin_mm``, stays inside the image with
    ``pixel_margin`` and the focal length stays in ``[f_min, f_max]``.

    Parameters
    ----------
    clip : MocapClip or numpy.ndarray of shape (..., 3)
        The clip (all joints and end sites of all frames are used) or the world points to keep in view.
    settings : RigSettings, optional

    Returns
    -------
    list of Camera
        Named ``BW1, BW2, ...`` counter-clockwise.

    Raises
    ------
    ConfigError
        No distance in range fits the volume into the image.
    """
    s = settings or RigSettings()
    pts = _clip_points(clip)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        raise ShapeError("default_rig: no finite points")
    check = pts[:: max(1, len(pts) // 20000)]
    lo, hi = capture_volume(pts)
    centre = 0.5 * (lo + hi)
    target = np.array([centre[0], centre[1], 0.5 * (max(lo[2], 0.0) + hi[2])])
    axis = _principal_axis(pts[:, :2])
    heading = math.atan2(axis[1], axis[0])
    # the person's typical position (root-ish): the mean of the points of each frame is close enough
    centres = pts.reshape(-1, 3)
    n = len(s.heights_mm)
    cams = []
    for i in range(n):
        phi = heading + math.radians(45.0 + 360.0 * i / n)
        direction = np.array([math.cos(phi), math.sin(phi)])
        ox, oy = s.principal_offset_px[i]
        room_u = (s.width / 2.0) * (1.0 - s.pixel_margin) - abs(ox)
        room_v = (s.height / 2.0) * (1.0 - s.pixel_margin) - abs(oy)
        found = []
        for dist in np.arange(s.distance_mm[0], s.distance_mm[1] + 1.0, 100.0):
            eye = np.array([target[0] + dist * direction[0], target[1] + dist * direction[1], s.heights_mm[i]])
            probe = Camera.look_at(f"BW{i + 1}", eye, target, f=1.0, width=s.width, height=s.height)
            f = min(_fit_focal(probe, check, s.body_margin_mm, room_u, room_v), s.f_max)
            if f < s.f_min:
                continue
            score = f * float(np.median(1.0 / np.linalg.norm(centres[::7] - eye, axis=1)))
            found.append((score, eye, f))
        if not found:
            raise ConfigError(f"default_rig: camera BW{i + 1} cannot see the whole capture volume "
                              f"with a focal length in [{s.f_min}, {s.f_max}] px")
        top = max(sc for sc, _, _ in found)
        # the nearest camera whose person size is within 3 % of the best (flat optimum: stay close)
        _, eye, f = next(c for c in found if c[0] >= 0.97 * top)
        cams.append(Camera.look_at(
            f"BW{i + 1}", eye, target, f=float(f), width=s.width, height=s.height,
            dist=(float(s.k1[i]), 0.0, 0.0, 0.0, 0.0),
            cx=(s.width - 1) / 2.0 + ox, cy=(s.height - 1) / 2.0 + oy))
    return cams


def rig_summary(cameras: Sequence[Camera]) -> list[dict[str, Any]]:
    """Per camera: name, optical centre (mm), focal length (px), horizontal field of view (deg), k1."""
    out = []
    for c in cameras:
        out.append({"name": c.name, "centre_mm": [round(float(x), 1) for x in c.center], "f_px": round(c.fx, 1),
                    "hfov_deg": round(math.degrees(2 * math.atan(c.width / 2.0 / c.fx)), 1), "k1": c.dist[0]})
    return out
