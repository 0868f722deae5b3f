"""Triangulation of 2D keypoints seen by calibrated cameras, and their reprojection residuals.

The linear (DLT) triangulation of Hartley & Zisserman (2nd ed., sec. 12.2), on undistorted,
normalised image coordinates, with one weight per view and point: each view contributes the two rows
``w (a P_3 - P_1)`` and ``w (b P_3 - P_2)`` of ``A X = 0`` with ``P = [R | t]``, and ``X`` is the right
singular vector of ``A`` with the smallest singular value. A point seen (weight > 0) by fewer than two
views is NaN. Everything is batched over any leading shape.

Shape letters: ``C`` cameras, ``J`` points (joints), ``...`` any leading batch shape.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ShapeError

__all__ = ["triangulate", "reproject", "residuals", "normalised_points"]


def _check(cameras: Sequence[Camera], uv: np.ndarray) -> np.ndarray:
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim < 3 or uv.shape[-1] != 2 or uv.shape[-3] != len(cameras):
        raise ShapeError(f"keypoints must have shape (..., C={len(cameras)}, J, 2), got {uv.shape}")
    return uv


def normalised_points(cameras: Sequence[Camera], uv: np.ndarray) -> np.ndarray:
    """Undistorted normalised coordinates ``(x/z, y/z)`` of pixels ``uv`` (..., C, J, 2); NaN stays NaN."""
    uv = _check(cameras, uv)
    out = np.full(uv.shape, np.nan)
    for c, cam in enumerate(cameras):
        pts = uv[..., c, :, :]
        ok = np.isfinite(pts).all(axis=-1)
        if ok.any():
            out[..., c, :, :][ok] = cam.undistort_points(pts[ok], output="normalized")
    return out


def triangulate(cameras: Sequence[Camera], uv: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """World points (mm) from their pixels in several views (weighted DLT on undistorted coordinates).

    Parameters
    ----------
    cameras : sequence of C Camera
    uv : numpy.ndarray, shape (..., C, J, 2)
        Pixels (with the cameras' distortion); NaN where a view does not see the point.
    weights : numpy.ndarray, shape (..., C, J), optional
        Non-negative weight of each view's observation (a detector's confidence); default 1.
        Views with weight 0 or NaN pixels are left out.

    Returns
    -------
    numpy.ndarray, shape (..., J, 3)
        NaN where fewer than two views see a point.
    """
    uv = _check(cameras, uv)
    ab = normalised_points(cameras, uv)
    w = np.ones(uv.shape[:-1]) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != uv.shape[:-1]:
        raise ShapeError(f"weights must have shape {uv.shape[:-1]}, got {w.shape}")
    valid = np.isfinite(ab).all(axis=-1) & (w > 0) & np.isfinite(w)
    w = np.where(valid, w, 0.0)
    ab = np.where(valid[..., None], ab, 0.0)
    P = np.stack([np.hstack([cam.R, cam.t[:, None]]) for cam in cameras])  # (C, 3, 4)
    # rows (..., C, J, 2, 4): a P3 - P1 and b P3 - P2
    a, b = ab[..., 0:1], ab[..., 1:2]
    P1, P2, P3 = P[:, None, 0, :], P[:, None, 1, :], P[:, None, 2, :]  # (C, 1, 4)
    rows = np.stack([a * P3 - P1, b * P3 - P2], axis=-2) * w[..., None, None]
    # condition: the rows are in mm-scaled units; scale the homogeneous coordinate instead of the rows
    A = np.moveaxis(rows, -4, -3)  # (..., J, C, 2, 4)
    A = A.reshape(*A.shape[:-3], -1, 4)
    scale = np.array([1e-3, 1e-3, 1e-3, 1.0])  # X in metres inside the solve: a better-conditioned A
    _, _, vt = np.linalg.svd(A / scale, full_matrices=False)
    X = vt[..., -1, :] / scale
    with np.errstate(divide="ignore", invalid="ignore"):
        pts = X[..., :3] / X[..., 3:4]
    enough = valid.sum(axis=-2) >= 2  # (..., J)
    return np.where(enough[..., None], pts, np.nan)


def reproject(cameras: Sequence[Camera], points: np.ndarray) -> np.ndarray:
    """Pixels ``(..., C, J, 2)`` of world points ``(..., J, 3)`` in every camera (NaN behind a camera)."""
    pts = np.asarray(points, dtype=np.float64)
    out = []
    for cam in cameras:
        uv, z = cam.project_with_depth(pts)
        out.append(np.where((z > 0)[..., None], uv, np.nan))
    return np.stack(out, axis=-3)


def residuals(cameras: Sequence[Camera], points: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Pixel distance ``(..., C, J)`` between the reprojected ``points`` (..., J, 3) and ``uv`` (..., C, J, 2).

    NaN where either is missing.
    """
    uv = _check(cameras, uv)
    return np.linalg.norm(reproject(cameras, points) - uv, axis=-1)
