"""The keypoint term: how far the model's joints project from a detector's labelled body keypoints.

Beyond the papers (``shared/design.md`` §7): where a sequence carries a person detector's 15 keypoints with
confidences (an imported recording), the image fitnesses can add ``w * K(x)`` with

    K(x) = - mean_c  min_{labels}  sum_j w_cj rho(|pi_c(J_j(x)) - k_cj|) / sum_j w_cj,
    rho(e) = e^2 / (e^2 + s^2)                                     (Geman & McClure 1987)

over the views ``c`` that have confident keypoints (``w_cj`` = confidence, 0 below
:data:`MIN_CONFIDENCE`). ``rho`` is bounded, so a misdetected joint costs at most 1 and cannot drag the
pose; ``min_labels`` takes, per view, the better of the labels as detected and left and right exchanged,
so a view whose detector swapped the sides still helps. ``s`` is :data:`SCALE` of the image diagonal.
``K`` lies in ``[-1, 0]``.

:func:`keypoint_cost` is batched over poses; :func:`keypoint_cost_reference` is the plain loop it is
tested against.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from swarmpose.camera import Camera
from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.joints import JOINTS15, SWAP15

__all__ = ["keypoint_cost", "keypoint_cost_reference", "SCALE", "SWAP"]

#: Robust scale of the residual, as a fraction of the image diagonal (about 22 px at 544 x 960).
SCALE = 0.02
#: The permutation of the 15 joints that exchanges left and right.
SWAP = np.array(SWAP15)


def _weights(confidence: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    ok = np.isfinite(keypoints).all(axis=-1) & (confidence >= MIN_CONFIDENCE)
    return np.where(ok, confidence, 0.0)


def keypoint_cost(joints: np.ndarray, cameras: Sequence[Camera], keypoints: np.ndarray,
                  confidence: np.ndarray, scale_px: float | None = None) -> np.ndarray:
    """``-K``: the robust keypoint cost ``(N,)`` in ``[0, 1]`` of model joints ``(N, 15, 3)`` (mm).

    Parameters
    ----------
    joints : (N, 15, 3)
    cameras : C cameras
    keypoints : (C, 15, 2) px, NaN where absent; confidence : (C, 15)
    scale_px : float, optional
        ``s``; default :data:`SCALE` of the first camera's image diagonal.
    """
    J = np.asarray(joints, dtype=np.float64)
    s = SCALE * float(np.hypot(cameras[0].width, cameras[0].height)) if scale_px is None else float(scale_px)
    total = np.zeros(J.shape[0])
    views = 0
    for c, cam in enumerate(cameras):
        kp = np.asarray(keypoints[c], dtype=np.float64)
        w = _weights(np.asarray(confidence[c], dtype=np.float64), kp)
        if w.sum() <= 0:
            continue
        uv, z = cam.project_with_depth(J)  # (N, 15, 2)
        behind = ~(z > 0).all(axis=1)
        k = np.nan_to_num(kp)
        costs = []
        for perm in (slice(None), SWAP):
            e2 = ((uv - k[perm]) ** 2).sum(axis=-1)  # (N, 15)
            rho = e2 / (e2 + s * s)
            ww = w[perm]
            costs.append(np.nansum(rho * ww, axis=1) / ww.sum())
        view = np.minimum(costs[0], costs[1])
        total += np.where(behind | ~np.isfinite(view), 1.0, view)
        views += 1
    return total / views if views else total


def keypoint_cost_reference(joints: np.ndarray, cameras: Sequence[Camera], keypoints: np.ndarray,
                            confidence: np.ndarray, scale_px: float | None = None) -> np.ndarray:
    """:func:`keypoint_cost` written as plain loops over poses, views, labellings and joints."""
    J = np.asarray(joints, dtype=np.float64)
    s = SCALE * float(np.hypot(cameras[0].width, cameras[0].height)) if scale_px is None else float(scale_px)
    out = np.zeros(len(J))
    for n in range(len(J)):
        acc, views = 0.0, 0
        for c, cam in enumerate(cameras):
            weights = [float(confidence[c][j]) if np.isfinite(keypoints[c][j]).all()
                       and confidence[c][j] >= MIN_CONFIDENCE else 0.0 for j in range(len(JOINTS15))]
            if sum(weights) <= 0:
                continue
            views += 1
            uv, z = cam.project_with_depth(J[n])
            if not (z > 0).all():
                acc += 1.0
                continue
            best = np.inf
            for perm in (list(range(len(JOINTS15))), list(SWAP)):
                num = den = 0.0
                for j in range(len(JOINTS15)):
                    wj = weights[perm[j]]
                    if wj == 0:
                        continue
                    e2 = float(((uv[j] - keypoints[c][perm[j]]) ** 2).sum())
                    num += wj * e2 / (e2 + s * s)
                    den += wj
                best = min(best, num / den)
            acc += best
        out[n] = acc / views if views else 0.0
    return out
