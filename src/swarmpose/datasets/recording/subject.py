"""The subject among a frame's detections: views that agree with the calibration, left/right resolved.

A detector run on each view alone may label the person's left and right the wrong way round (a person
seen from behind, a blurred face) or lock on somebody else (people in the background). Per frame,
:func:`consistent_views` takes every pair of views, each with its labels as detected and swapped,
triangulates the joints from the pair and counts the views whose keypoints (either labelling) reproject
within ``threshold`` pixels (median over joints): the pair with most such inliers, then the smallest median
residual, wins; the inliers are triangulated together and the count is refined once more. The person is
thus the one seen by most cameras consistently with the calibration (an exhaustive minimal-set search
in the manner of RANSAC, Fischler & Bolles 1981, over ``C (C - 1)`` pair labellings).

Shape letters: ``T`` frames, ``C`` views, ``J`` joints.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from swarmpose.camera import Camera
from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.triangulation import residuals, triangulate

__all__ = ["ViewSelection", "consistent_views", "view_residuals"]



@dataclass
class ViewSelection:
    """What :func:`consistent_views` decided for every frame.

    Attributes
    ----------
    swapped : numpy.ndarray, shape (T, C), bool
        The view's left and right labels were exchanged.
    inlier : numpy.ndarray, shape (T, C), bool
        The view's detection agrees with the others (it shows the subject).
    points : numpy.ndarray, shape (T, J, 3)
        Joints triangulated from the inlier views (NaN where fewer than two).
    residual : numpy.ndarray, shape (T, C)
        Median reprojection residual over the view's confident joints, px (NaN without any).
    """

    swapped: np.ndarray
    inlier: np.ndarray
    points: np.ndarray
    residual: np.ndarray

    def apply(self, keypoints: np.ndarray, confidence: np.ndarray, swap: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Keypoints (T, C, J, 2) and confidences (T, C, J) relabelled as decided (not masked)."""
        perm = np.asarray(swap)
        kp = np.where(self.swapped[..., None, None], keypoints[:, :, perm], keypoints)
        cf = np.where(self.swapped[..., None], confidence[:, :, perm], confidence)
        return kp, cf


def view_residuals(cameras: Sequence[Camera], points: np.ndarray, keypoints: np.ndarray,
                   confidence: np.ndarray) -> np.ndarray:
    """Median residual (px) per frame and view over confident joints: points (..., J, 3), kp (..., C, J, 2)."""
    r = residuals(cameras, points, keypoints)
    r = np.where(confidence >= MIN_CONFIDENCE, r, np.nan)
    with warnings.catch_warnings():  # a view without confident joints: NaN, silently
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(r, axis=-1)


def _weights(confidence: np.ndarray) -> np.ndarray:
    return np.where(confidence >= MIN_CONFIDENCE, confidence, 0.0)


def consistent_views(cameras: Sequence[Camera], keypoints: np.ndarray, confidence: np.ndarray,
                     swap: Sequence[int], threshold: float) -> ViewSelection:
    """Per frame, the views that show one person consistently, and the labelling that makes them agree.

    Parameters
    ----------
    cameras : sequence of C Camera
    keypoints : numpy.ndarray, shape (T, C, J, 2)
        Detected joints, px; NaN where absent.
    confidence : numpy.ndarray, shape (T, C, J)
    swap : sequence of J int
        The permutation that exchanges left and right joints.
    threshold : float
        Largest median residual (px) of a view that shows the subject.

    Returns
    -------
    ViewSelection
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    cf = np.asarray(confidence, dtype=np.float64)
    T, C, J, _ = kp.shape
    perm = np.asarray(swap)
    both = np.stack([kp, kp[:, :, perm]], axis=2)  # (T, C, 2, J, 2): as detected, swapped
    both_cf = np.stack([cf, cf[:, :, perm]], axis=2)
    best_n = np.full(T, -1)
    best_r = np.full(T, np.inf)
    best_pts = np.full((T, J, 3), np.nan)
    for i, j in combinations(range(C), 2):
        for sj in (0, 1):
            pair_kp = np.stack([both[:, i, 0], both[:, j, sj]], axis=1)  # (T, 2, J, 2)
            pair_cf = np.stack([both_cf[:, i, 0], both_cf[:, j, sj]], axis=1)
            pts = triangulate([cameras[i], cameras[j]], pair_kp, _weights(pair_cf))
            n, r = _score(cameras, pts, both, both_cf, threshold)
            better = (n > best_n) | ((n == best_n) & (r < best_r))
            best_n = np.where(better, n, best_n)
            best_r = np.where(better, r, best_r)
            best_pts[better] = pts[better]
    sel = None
    pts = best_pts
    for _ in range(2):  # the inliers' joint triangulation, and the inliers it agrees with
        sel = _label(cameras, pts, both, both_cf, threshold)
        use_kp = np.where(sel.swapped[..., None, None], both[:, :, 1], both[:, :, 0])
        use_cf = np.where(sel.swapped[..., None], both_cf[:, :, 1], both_cf[:, :, 0])
        w = _weights(use_cf) * sel.inlier[..., None]
        new = triangulate(cameras, use_kp, w)
        ok = sel.inlier.sum(axis=1) >= 2
        pts = np.where(ok[:, None, None], new, pts)
    # the majority's labelling: a person all of whose inlier views are swapped is the same person mirrored
    sel = _label(cameras, pts, both, both_cf, threshold)
    n_in = sel.inlier.sum(axis=1)
    flip = (sel.swapped & sel.inlier).sum(axis=1) * 2 > n_in
    if flip.any():
        sel.swapped[flip] = ~sel.swapped[flip]
        pts[flip] = pts[flip][:, perm]
    sel.points = np.where((n_in >= 2)[:, None, None], pts, np.nan)
    return sel


def _score(cameras, pts, both, both_cf, threshold):
    """Inlier count and median inlier residual per frame for points (T, J, 3)."""
    r = np.stack([view_residuals(cameras, pts, both[:, :, s], both_cf[:, :, s]) for s in (0, 1)], axis=-1)
    r = np.nanmin(np.where(np.isnan(r), np.inf, r), axis=-1)  # (T, C): the better labelling
    inl = r < threshold
    n = inl.sum(axis=1)
    # the (lower) median of the inliers' residuals: sorted, the outliers' +inf last
    rr = np.sort(np.where(inl, r, np.inf), axis=1)
    idx = np.maximum(n - 1, 0) // 2
    med = np.where(n > 0, np.take_along_axis(rr, idx[:, None], axis=1)[:, 0], np.inf)
    return n, med


def _label(cameras, pts, both, both_cf, threshold) -> ViewSelection:
    r = np.stack([view_residuals(cameras, pts, both[:, :, s], both_cf[:, :, s]) for s in (0, 1)], axis=-1)
    rf = np.where(np.isnan(r), np.inf, r)
    swapped = rf[..., 1] < rf[..., 0]
    best = np.minimum(rf[..., 0], rf[..., 1])
    inlier = best < threshold
    residual = np.where(np.isfinite(best), best, np.nan)
    return ViewSelection(swapped=swapped, inlier=inlier, points=pts, residual=residual)
