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

__all__ = ["triangulate", "reproject", "residuals", "normalised_points", "relabel_pairs", "MAX_EXHAUSTIVE_VIEWS"]


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


#: Up to this many views :func:`relabel_pairs` tries every labelling of a pair (2^C); with more, one view at a time.
MAX_EXHAUSTIVE_VIEWS = 8


def _pair_cost(cameras: Sequence[Camera], uv: np.ndarray, w: np.ndarray, threshold: float) -> np.ndarray:
    """``sum_c,j w min(r, threshold)^2`` of the pair ``uv (..., C, 2, 2)`` triangulated with weights ``w``."""
    pts = triangulate(cameras, uv, w)
    r = residuals(cameras, pts, uv)
    r = np.where(np.isfinite(r), np.minimum(r, threshold), threshold)
    cost = (w * r * r).sum(axis=(-2, -1))
    return np.where(np.isfinite(pts).all(axis=(-2, -1)), cost, np.inf)


def _labelled(exchanged: np.ndarray, uv: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A pair's pixels ``(..., C, 2, 2)`` and weights ``(..., C, 2)`` with the views ``exchanged (..., C)`` swapped."""
    return (np.where(exchanged[..., None, None], uv[..., ::-1, :], uv),
            np.where(exchanged[..., None], w[..., ::-1], w))


def relabel_pairs(cameras: Sequence[Camera], uv: np.ndarray, weights: np.ndarray,
                  pairs: Sequence[tuple[int, int]], threshold: float,
                  min_views: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Each view's two detections of each pair ``(a, b)`` (a left and a right joint) exchanged where that makes
    the views agree: per pair and frame, the labelling of the views whose triangulation has the smallest weighted,
    truncated (at ``threshold`` px) squared reprojection residual; of a labelling and its opposite (which give
    the same two points, exchanged) the one that keeps the larger confidence as detected. A detector that
    swaps one view's ankles then no longer pulls both triangulated ankles off.

    Only where at least ``min_views`` views see both joints of the pair (weight > 0): two views agree about as
    well either way when the two joints lie near the same epipolar line (two wrists at one height), and on the
    shared clips with MediaPipe's keypoints relabelling from two views made some frames worse.

    ``uv (..., C, J, 2)`` px, ``weights (..., C, J)``; returns both relabelled. Up to
    :data:`MAX_EXHAUSTIVE_VIEWS` views every labelling is tried, beyond that one view at a time, as long as
    exchanging one lowers the residual."""
    uv = _check(cameras, uv).copy()
    w = np.asarray(weights, dtype=np.float64).copy()
    C = len(cameras)
    for a, b in pairs:
        pu = uv[..., [a, b], :]  # (..., C, 2, 2)
        pw = w[..., [a, b]]
        shape = pu.shape[:-3]
        if C <= MAX_EXHAUSTIVE_VIEWS:
            grid = np.array(np.meshgrid(*[[False, True]] * C, indexing="ij")).reshape(C, -1).T  # (2^C, C)
            grid = grid[~grid[:, 0]]  # a labelling and its opposite fit alike: view 0 as detected, then choose
            trials = np.broadcast_to(grid.reshape((len(grid),) + (1,) * len(shape) + (C,)), (len(grid),) + shape + (C,))
            cost = _pair_cost(cameras, *_labelled(trials, pu, pw), threshold)  # (S, ...)
            best = np.take_along_axis(trials, np.argmin(cost, axis=0)[None, ..., None], axis=0)[0]
        else:
            best = np.zeros(shape + (C,), dtype=bool)
            cost = _pair_cost(cameras, *_labelled(best, pu, pw), threshold)
            for _ in range(C):
                changed = False
                for c in range(C):
                    trial = best.copy()
                    trial[..., c] = ~trial[..., c]
                    tc = _pair_cost(cameras, *_labelled(trial, pu, pw), threshold)
                    better = tc < cost
                    if better.any():
                        best = np.where(better[..., None], trial, best)
                        cost = np.where(better, tc, cost)
                        changed = True
                if not changed:
                    break
        # of the labelling and its opposite, the one that keeps the larger confidence as detected
        conf = pw.sum(axis=-1)  # (..., C)
        best = best ^ ((conf * best).sum(axis=-1) > (conf * ~best).sum(axis=-1))[..., None]
        best &= (((pw > 0).all(axis=-1)).sum(axis=-1) >= min_views)[..., None]
        uv[..., [a, b], :], w[..., [a, b]] = _labelled(best, pu, pw)
    return uv, w
