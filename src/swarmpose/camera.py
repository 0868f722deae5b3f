"""Calibrated pinhole cameras with Bouguet lens distortion, epipolar geometry and rig files.

Conventions (``shared/design.md`` §2, ``humaneva-facts.md`` §3):

* World: millimetres, right-handed, z up.
* Camera: ``x_cam = R @ x_world + t`` (``t`` in mm); the camera looks along its +z axis, image
  u to the right (+x_cam), v down (+y_cam). The optical centre in the world is ``-R.T @ t``.
* Pixels: ``(0, 0)`` is the *centre* of the top-left pixel (Bouguet's convention), so pixel
  ``(u, v)`` is ``image[round(v), round(u)]`` with no half-pixel shift.
* Projection (Bouguet ``project_points2``), for ``(x, y, z) = R X + t``::

      a = x / z,  b = y / z,  r2 = a^2 + b^2
      radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
      x_d = a radial + 2 p1 a b + p2 (r2 + 2 a^2)
      y_d = b radial + p1 (r2 + 2 b^2) + 2 p2 a b
      u = fx (x_d + skew y_d) + cx,   v = fy y_d + cy

  with ``dist = (k1, k2, p1, p2, k3)`` (Bouguet's ``kc`` order) and ``skew`` Bouguet's ``alpha_c``.

Shape letters: ``...`` any leading batch shape, ``C`` cameras.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.files import read_json_object

__all__ = ["Camera", "fundamental_matrix", "save_rig", "load_rig", "unique_cameras", "RIG_FORMAT", "RIG_VERSION"]

RIG_FORMAT = "swarmpose-rig"
RIG_VERSION = 1

_ROTATION_TOL = 1e-6
_FIELDS = ("name", "width", "height", "fx", "fy", "cx", "cy", "skew", "dist", "R", "t")


def _config_error(camera: str, field: str, message: str) -> ConfigError:
    err = ConfigError(f"camera {camera!r}: field {field!r}: {message}")
    err.field = field  # used by load_rig to name the field in its FormatError
    return err


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


def _points(points: Any, name: str = "points_world") -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim < 1 or p.shape[-1] != 3:
        raise ShapeError(f"{name} must have shape (..., 3), got {p.shape}")
    return p


@dataclass(frozen=True, eq=False)
class Camera:
    """A calibrated camera: Bouguet intrinsics with distortion, and its pose in the world.

    Parameters
    ----------
    name : str
        Camera name (unique within a rig).
    width, height : int
        Image size in pixels, > 0.
    fx, fy : float
        Focal lengths in pixels, > 0.
    cx, cy : float
        Principal point in pixels ((0, 0) = centre of the top-left pixel).
    skew : float, default 0.0
        Bouguet's skew coefficient ``alpha_c`` (dimensionless); ``K[0, 1] = skew * fx``.
    dist : tuple of 5 float, default zeros
        Distortion ``(k1, k2, p1, p2, k3)`` in Bouguet's ``kc`` order.
    R : numpy.ndarray, shape (3, 3)
        ``cam_from_world`` rotation, orthonormal with det +1 (to 1e-6).
    t : numpy.ndarray, shape (3,)
        ``cam_from_world`` translation in mm: ``x_cam = R @ x_world + t``.

    Raises
    ------
    ConfigError
        A value is out of range (the message names the field).

    Notes
    -----
    ``R`` and ``t`` are stored as read-only float64 copies. Two cameras compare equal when every
    field is exactly equal.
    """

    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    R: np.ndarray = None  # type: ignore[assignment]
    t: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        name = self.name
        if not isinstance(name, str) or not name:
            raise _config_error(str(name), "name", f"must be a non-empty string, got {name!r}")
        set_ = object.__setattr__
        for fld in ("width", "height"):
            v = getattr(self, fld)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer, float, np.floating)):
                raise _config_error(name, fld, f"must be an integer, got {v!r}")
            if not (math.isfinite(v) and float(v) == int(v)) or int(v) <= 0:
                raise _config_error(name, fld, f"must be a positive integer, got {v!r}")
            set_(self, fld, int(v))
        for fld in ("fx", "fy", "cx", "cy", "skew"):
            v = getattr(self, fld)
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise _config_error(name, fld, f"must be a number, got {v!r}") from None
            if isinstance(v, bool) or not math.isfinite(fv):
                raise _config_error(name, fld, f"must be a finite number, got {v!r}")
            if fld in ("fx", "fy") and fv <= 0:
                raise _config_error(name, fld, f"focal length must be > 0, got {v!r}")
            set_(self, fld, fv)
        try:
            dist = np.asarray(self.dist, dtype=np.float64)
        except (TypeError, ValueError):
            raise _config_error(name, "dist", f"must be 5 numbers, got {self.dist!r}") from None
        if dist.shape != (5,):
            raise _config_error(name, "dist", f"must be 5 numbers (k1, k2, p1, p2, k3), got shape {dist.shape}")
        if not np.isfinite(dist).all():
            raise _config_error(name, "dist", f"must be finite, got {tuple(dist.tolist())}")
        set_(self, "dist", tuple(float(d) for d in dist))
        if self.R is None:
            raise _config_error(name, "R", "is required")
        if self.t is None:
            raise _config_error(name, "t", "is required")
        try:
            R = np.array(self.R, dtype=np.float64)
            t = np.array(self.t, dtype=np.float64)
        except (TypeError, ValueError):
            raise _config_error(name, "R", "R and t must be numeric arrays") from None
        if R.shape != (3, 3):
            raise _config_error(name, "R", f"must have shape (3, 3), got {R.shape}")
        if t.shape != (3,):
            raise _config_error(name, "t", f"must have shape (3,), got {t.shape}")
        if not np.isfinite(R).all():
            raise _config_error(name, "R", "must be finite")
        if not np.isfinite(t).all():
            raise _config_error(name, "t", "must be finite")
        ortho = np.abs(R @ R.T - np.eye(3)).max()
        if ortho > _ROTATION_TOL:
            raise _config_error(name, "R", f"is not orthonormal (max |R R^T - I| = {ortho:.3g} > 1e-6)")
        det = float(np.linalg.det(R))
        if abs(det - 1.0) > _ROTATION_TOL:
            raise _config_error(name, "R", f"must have det +1, got {det:.6g}")
        set_(self, "R", _readonly(R))
        set_(self, "t", _readonly(t))

    # ------------------------------------------------------------------ equality
    def _key(self) -> tuple:
        return (self.name, self.width, self.height, self.fx, self.fy, self.cx, self.cy, self.skew,
                self.dist, tuple(self.R.ravel().tolist()), tuple(self.t.tolist()))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Camera):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    # ------------------------------------------------------------------ derived quantities
    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return (self.width, self.height)

    @property
    def center(self) -> np.ndarray:
        """World position of the optical centre, ``-R.T @ t``, shape (3,), mm."""
        return -self.R.T @ self.t

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix, shape (3, 3): ``[[fx, skew*fx, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, self.skew * self.fx, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> np.ndarray:
        """Projection matrix ``K @ [R | t]``, shape (3, 4) (no distortion)."""
        return self.K @ np.hstack([self.R, self.t[:, None]])

    @property
    def cam_from_world_matrix(self) -> np.ndarray:
        """Homogeneous ``cam_from_world`` transform, shape (4, 4)."""
        m = np.eye(4)
        m[:3, :3] = self.R
        m[:3, 3] = self.t
        return m

    @property
    def has_distortion(self) -> bool:
        """True when any of ``dist`` is non-zero."""
        return any(d != 0.0 for d in self.dist)

    # ------------------------------------------------------------------ projection
    def cam_from_world(self, points_world: Any) -> np.ndarray:
        """Transform world points into camera coordinates.

        Parameters
        ----------
        points_world : array_like, shape (..., 3)
            Points in world mm.

        Returns
        -------
        numpy.ndarray, shape (..., 3)
            ``R @ x + t`` in camera mm.
        """
        p = _points(points_world)
        return p @ self.R.T + self.t

    def world_from_cam(self, points_cam: Any) -> np.ndarray:
        """Inverse of :meth:`cam_from_world`: ``R.T @ (x_cam - t)``, shape (..., 3) -> (..., 3)."""
        p = _points(points_cam, "points_cam")
        return (p - self.t) @ self.R

    def distort_normalized(self, ab: Any) -> np.ndarray:
        """Apply Bouguet distortion to normalized coordinates ``(a, b) = (x/z, y/z)``.

        Parameters
        ----------
        ab : array_like, shape (..., 2)

        Returns
        -------
        numpy.ndarray, shape (..., 2)
            ``(x_d, y_d)`` (see the module docstring).
        """
        ab = np.asarray(ab, dtype=np.float64)
        if ab.ndim < 1 or ab.shape[-1] != 2:
            raise ShapeError(f"ab must have shape (..., 2), got {ab.shape}")
        return self._distort(ab[..., 0], ab[..., 1])

    def _distort(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k1, k2, p1, p2, k3 = self.dist
        r2 = a * a + b * b
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))  # 1 + k1 r2 + k2 r2^2 + k3 r2^3
        xd = a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a)
        yd = b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b
        return np.stack([xd, yd], axis=-1)

    def project_with_depth(self, points_world: Any) -> tuple[np.ndarray, np.ndarray]:
        """Project world points to pixels and return their depth.

        Parameters
        ----------
        points_world : array_like, shape (..., 3)
            Points in world mm; any leading batch shape.

        Returns
        -------
        uv : numpy.ndarray, shape (..., 2)
            Pixel coordinates (with distortion and skew). Meaningless where ``z <= 0`` (the point is
            behind the camera; ``inf``/``nan`` at ``z == 0``): mask those with ``z``.
        z : numpy.ndarray, shape (...)
            Depth along the optical axis, mm.
        """
        xyz = self.cam_from_world(points_world)
        z = xyz[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            a = xyz[..., 0] / z  # a = x / z
            b = xyz[..., 1] / z  # b = y / z
        if self.has_distortion:
            d = self._distort(a, b)
            xd, yd = d[..., 0], d[..., 1]
        else:
            xd, yd = a, b
        u = self.fx * (xd + self.skew * yd) + self.cx  # u = fx (x_d + alpha y_d) + cx
        v = self.fy * yd + self.cy  # v = fy y_d + cy
        return np.stack([u, v], axis=-1), z

    def project(self, points_world: Any) -> np.ndarray:
        """Project world points to pixels, shape (..., 3) -> (..., 2); see :meth:`project_with_depth`."""
        return self.project_with_depth(points_world)[0]

    def undistort_points(
        self,
        uv: Any,
        output: Literal["pixel", "normalized"] = "pixel",
        max_iter: int = 50,
        tol: float = 1e-14,
    ) -> np.ndarray:
        """Remove lens distortion from pixel coordinates (iterative inverse of the Bouguet model).

        Parameters
        ----------
        uv : array_like, shape (..., 2)
            Distorted pixel coordinates.
        output : {"pixel", "normalized"}
            ``"normalized"`` returns ``(a, b) = (x/z, y/z)``; ``"pixel"`` returns the ideal pixel
            ``K @ (a, b, 1)`` (skew included), i.e. where a distortion-free camera with the same ``K``
            would see the point -- the coordinates :func:`fundamental_matrix` expects.
        max_iter : int
            Maximum fixed-point iterations (Bouguet's ``comp_distortion_oulu`` uses 20).
        tol : float
            Stop when the largest update in normalized units is below this.

        Returns
        -------
        numpy.ndarray, shape (..., 2)

        Notes
        -----
        Fixed-point iteration ``a = (x_d - dx(a, b)) / radial(a, b)``; it converges for the
        moderate distortion of real lenses (|k1 r^2| well below 1) inside the image.
        """
        uv = np.asarray(uv, dtype=np.float64)
        if uv.ndim < 1 or uv.shape[-1] != 2:
            raise ShapeError(f"uv must have shape (..., 2), got {uv.shape}")
        if output not in ("pixel", "normalized"):
            raise ConfigError(f"output must be 'pixel' or 'normalized', got {output!r}")
        yd = (uv[..., 1] - self.cy) / self.fy
        xd = (uv[..., 0] - self.cx) / self.fx - self.skew * yd
        a, b = xd.copy(), yd.copy()
        if self.has_distortion:
            k1, k2, p1, p2, k3 = self.dist
            for _ in range(max_iter):
                r2 = a * a + b * b
                radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                dx = 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a)
                dy = p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b
                a_new = (xd - dx) / radial
                b_new = (yd - dy) / radial
                step = max(float(np.max(np.abs(a_new - a), initial=0.0)),
                           float(np.max(np.abs(b_new - b), initial=0.0)))
                a, b = a_new, b_new
                if not step > tol:  # also stops on NaN
                    break
        if output == "normalized":
            return np.stack([a, b], axis=-1)
        return np.stack([self.fx * (a + self.skew * b) + self.cx, self.fy * b + self.cy], axis=-1)

    # ------------------------------------------------------------------ variants
    def scaled(self, factor: float) -> Camera:
        """The same camera for an image resized by ``factor`` (0.5: half resolution).

        With pixel centres at integer coordinates, pixel ``u`` of the original image covers
        ``[u - 0.5, u + 0.5]``; resizing maps ``u`` to ``u' = (u + 0.5) * factor - 0.5``. So

        * ``fx' = fx * factor``, ``fy' = fy * factor`` (skew and distortion are unchanged),
        * ``cx' = (cx + 0.5) * factor - 0.5``, ``cy'`` likewise,
        * ``width' = round(width * factor)``, ``height'`` likewise (halves round up, at least 1),

        and ``scaled(f).project(X) == (project(X) + 0.5) * f - 0.5`` for every point.

        Parameters
        ----------
        factor : float
            Resize factor, finite and > 0.

        Returns
        -------
        Camera
        """
        factor = float(factor)
        if not (math.isfinite(factor) and factor > 0):
            raise ConfigError(f"scale factor must be finite and > 0, got {factor!r}")
        return Camera(
            name=self.name,
            width=max(1, int(math.floor(self.width * factor + 0.5))),
            height=max(1, int(math.floor(self.height * factor + 0.5))),
            fx=self.fx * factor,
            fy=self.fy * factor,
            cx=(self.cx + 0.5) * factor - 0.5,
            cy=(self.cy + 0.5) * factor - 0.5,
            skew=self.skew,
            dist=self.dist,
            R=self.R,
            t=self.t,
        )

    @classmethod
    def look_at(
        cls,
        name: str,
        eye: Sequence[float],
        target: Sequence[float],
        up: Sequence[float] = (0.0, 0.0, 1.0),
        f: float = 1000.0,
        width: int = 644,
        height: int = 484,
        dist: Sequence[float] = (0.0, 0.0, 0.0, 0.0, 0.0),
        *,
        fy: float | None = None,
        cx: float | None = None,
        cy: float | None = None,
        skew: float = 0.0,
    ) -> Camera:
        """Build a camera at ``eye`` looking at ``target``, image "up" towards ``up``.

        Parameters
        ----------
        name : str
        eye, target : sequence of 3 float
            Optical centre and a point on the optical axis, world mm.
        up : sequence of 3 float, default (0, 0, 1)
            World direction that appears upwards in the image (need not be orthogonal to the
            viewing direction, must not be parallel to it).
        f : float, default 1000.0
            Focal length in pixels (``fx``; also ``fy`` unless given).
        width, height : int, default 644 x 484 (the HumanEva greyscale cameras)
        dist : sequence of 5 float
            ``(k1, k2, p1, p2, k3)``.
        fy, cx, cy : float, optional
            Defaults ``fy = f`` and the image centre ``((width - 1) / 2, (height - 1) / 2)``.
        skew : float, default 0.0

        Returns
        -------
        Camera
            With rows of ``R`` = camera x (image right), y (image down), z (viewing direction)
            in world coordinates and ``t = -R @ eye``.
        """
        eye_a = np.asarray(eye, dtype=np.float64)
        target_a = np.asarray(target, dtype=np.float64)
        up_a = np.asarray(up, dtype=np.float64)
        for nm, v in (("eye", eye_a), ("target", target_a), ("up", up_a)):
            if v.shape != (3,) or not np.isfinite(v).all():
                raise ConfigError(f"look_at: {nm} must be 3 finite numbers, got {v!r}")
        z = target_a - eye_a
        nz = np.linalg.norm(z)
        if nz == 0:
            raise ConfigError("look_at: eye and target coincide")
        z = z / nz
        x = np.cross(z, up_a)  # image right = forward x up
        nx = np.linalg.norm(x)
        if nx < 1e-9 * max(1.0, np.linalg.norm(up_a)):
            raise ConfigError("look_at: the viewing direction is parallel to 'up'")
        x = x / nx
        y = np.cross(z, x)  # image down
        R = np.stack([x, y, z])
        return cls(
            name=name,
            width=width,
            height=height,
            fx=f,
            fy=f if fy is None else fy,
            cx=(width - 1) / 2.0 if cx is None else cx,
            cy=(height - 1) / 2.0 if cy is None else cy,
            skew=skew,
            dist=tuple(dist),
            R=R,
            t=-R @ eye_a,
        )

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of all fields (Python floats, so ``json`` round-trips them exactly)."""
        return {
            "name": self.name,
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "skew": self.skew,
            "dist": list(self.dist),
            "R": self.R.tolist(),
            "t": self.t.tolist(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Camera:
        """Inverse of :meth:`to_dict`.

        ``skew`` and ``dist`` may be omitted (defaults); every other field is required and unknown
        fields are rejected.

        Raises
        ------
        FormatError
            A field is missing, unknown or has the wrong type/value (the message names it).
        """
        return _camera_from_dict(data, path=None, where="camera")


def _camera_from_dict(data: Any, path: object, where: str) -> Camera:
    if not isinstance(data, Mapping):
        raise FormatError(f"{where}: expected an object, got {type(data).__name__}", path=path)
    label = f"{where} ({data['name']!r})" if isinstance(data.get("name"), str) else where
    unknown = sorted(set(data) - set(_FIELDS))
    if unknown:
        raise FormatError(f"{label}: unknown field(s) {unknown}", path=path, field=unknown[0])
    for fld in _FIELDS:
        if fld not in data and fld not in ("skew", "dist"):
            raise FormatError(f"{label}: missing field {fld!r}", path=path, field=fld)
    kwargs = {}
    for fld in _FIELDS:
        if fld not in data:
            continue
        v = data[fld]
        if fld == "name":
            if not isinstance(v, str):
                raise FormatError(f"{label}: 'name' must be a string", path=path, field=fld)
        elif fld in ("width", "height"):
            if isinstance(v, bool) or not isinstance(v, int):
                raise FormatError(f"{label}: {fld!r} must be an integer, got {v!r}", path=path, field=fld)
        elif fld in ("dist", "R", "t"):
            if not _is_numeric_nested(v):
                raise FormatError(f"{label}: {fld!r} must be a (nested) list of numbers", path=path, field=fld)
        elif isinstance(v, bool) or not isinstance(v, (int, float)):
            raise FormatError(f"{label}: {fld!r} must be a number, got {v!r}", path=path, field=fld)
        kwargs[fld] = tuple(v) if fld == "dist" else v
    try:
        return Camera(**kwargs)
    except ConfigError as exc:
        raise FormatError(f"{where}: {exc}", path=path, field=getattr(exc, "field", None)) from exc


def _is_numeric_nested(v: Any) -> bool:
    if isinstance(v, bool):
        return False
    if isinstance(v, (int, float)):
        return True
    if isinstance(v, list):
        return all(_is_numeric_nested(x) for x in v)
    return False


# ---------------------------------------------------------------------- epipolar geometry
def _skew_matrix(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def fundamental_matrix(cam_a: Camera, cam_b: Camera) -> np.ndarray:
    """Fundamental matrix between two cameras.

    ``x_b.T @ F @ x_a = 0`` for homogeneous pixel coordinates ``x_a = (u_a, v_a, 1)`` and
    ``x_b = (u_b, v_b, 1)`` of the same world point, where the pixels are *undistorted*: lens
    distortion is ignored (exact for cameras with ``dist == 0``; otherwise apply
    :meth:`Camera.undistort_points` with ``output="pixel"`` first). Skew is included via ``K``.

    Parameters
    ----------
    cam_a, cam_b : Camera
        Cameras with distinct optical centres.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``F = K_b^-T [t]_x R K_a^-1`` with ``R = R_b R_a^T``, ``t = t_b - R t_a`` (the
        ``camb_from_cama`` motion), scaled to unit Frobenius norm with its largest-magnitude entry
        positive. Rank 2; ``F @ e_a = 0`` and ``F.T @ e_b = 0`` at the epipoles.

    Raises
    ------
    ConfigError
        The two optical centres coincide (no epipolar geometry).
    """
    R = cam_b.R @ cam_a.R.T  # camb_from_cama rotation
    t = cam_b.t - R @ cam_a.t  # camb_from_cama translation
    if np.linalg.norm(t) <= 1e-12 * max(1.0, np.linalg.norm(cam_a.t), np.linalg.norm(cam_b.t)):
        raise ConfigError(f"cameras {cam_a.name!r} and {cam_b.name!r} share the optical centre")
    E = _skew_matrix(t) @ R  # essential matrix: x_b_cam^T E x_a_cam = 0
    F = np.linalg.inv(cam_b.K).T @ E @ np.linalg.inv(cam_a.K)
    F = F / np.linalg.norm(F)
    if F.flat[np.argmax(np.abs(F))] < 0:
        F = -F
    return F


# ---------------------------------------------------------------------- rig files
def unique_cameras(cameras: Iterable[Any], who: str) -> list[Camera]:
    """``cameras`` as a list, checked to be :class:`Camera` objects with unique names (``who`` names the caller
    in the :class:`~swarmpose.errors.ConfigError`)."""
    cams = list(cameras)
    for c in cams:
        if not isinstance(c, Camera):
            raise ConfigError(f"{who} expects Camera objects, got {type(c).__name__}")
    names = [c.name for c in cams]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"{who}: camera names must be unique, repeated: {dup}")
    return cams


def save_rig(path: str | os.PathLike[str], cameras: Iterable[Camera]) -> None:
    """Write cameras to a JSON rig file.

    Parameters
    ----------
    path : str or path-like
    cameras : iterable of Camera
        Names must be unique.

    Notes
    -----
    Layout: ``{"format": "swarmpose-rig", "version": 1, "cameras": [Camera.to_dict(), ...]}``.
    Floats are written with ``repr`` precision, so :func:`load_rig` returns equal cameras.
    """
    cams = unique_cameras(cameras, "save_rig")
    doc = {"format": RIG_FORMAT, "version": RIG_VERSION, "cameras": [c.to_dict() for c in cams]}
    Path(path).write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")


def load_rig(path: str | os.PathLike[str]) -> list[Camera]:
    """Read a JSON rig file written by :func:`save_rig`.

    Returns
    -------
    list of Camera
        In file order.

    Raises
    ------
    DataError
        The file cannot be read.
    FormatError
        Not valid JSON, wrong ``format``/``version``, or a camera with a missing, unknown or invalid
        field (the message names the file, the camera and the field).
    """
    path = Path(path)
    try:
        doc = read_json_object(path)  # not UTF-8, not JSON or not an object: a FormatError naming the file
    except OSError as exc:
        raise DataError(f"cannot read rig file {path}: {exc}") from exc
    for fld in ("format", "version", "cameras"):
        if fld not in doc:
            raise FormatError(f"missing field {fld!r}", path=path, field=fld)
    if doc["format"] != RIG_FORMAT:
        raise FormatError(f"format must be {RIG_FORMAT!r}, got {doc['format']!r}", path=path, field="format")
    if doc["version"] != RIG_VERSION:
        raise FormatError(f"unsupported version {doc['version']!r} (this reader knows {RIG_VERSION})",
                          path=path, field="version")
    if not isinstance(doc["cameras"], list):
        raise FormatError("'cameras' must be a list", path=path, field="cameras")
    cams = [_camera_from_dict(d, path=path, where=f"camera {i}") for i, d in enumerate(doc["cameras"])]
    names = [c.name for c in cams]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(f"camera names must be unique, repeated: {dup}", path=path, field="name")
    return cams
