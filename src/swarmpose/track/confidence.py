"""Per-limb confidence of a finished track: how likely each limb's joints are within 100 mm of the truth.

The evidence is the silhouette distance term of each limb's cones (:meth:`ImageFitness.part_agreement`, the
worst of the limb's cones, averaged over the tracked views: 0 when the cones lie inside every observed
silhouette); the loss detection of :mod:`swarmpose.track.recovery` reads the same number. A logistic model
turns it into the probability that the limb (its two distal joints, e.g. elbow and wrist) is lost by more
than :data:`LOST_MM`:

    P(lost) = 1 / (1 + exp(-(a + b log10(d + eps)))),   confidence = 1 - P(lost)

with ``a``, ``b``, ``eps`` of :data:`COEFFICIENTS`, fitted on the forward runs of ``refined`` on the eight shared
clips at 20 fps (3 runs, 11,664 limb-frames, 29 % of them lost by more than 100 mm). Fitted on seven clips and
tested on the eighth in turn, the evidence ranks a lost limb above a kept one with probability 0.93 (AUC),
and the predicted rates match the observed ones (docs/results.md "Per-limb confidence"). The edge-map
support along the limb's sides, tried beside it, added 0.01 to that AUC at 50 ms per frame, so it is not
used. It is calibrated on background-subtracted silhouettes of rendered bodies: on a recording whose
masks are coarser, read it as a ranking of frames and limbs rather than as a probability.

Where the sequence carries a detector's keypoints, a second piece of evidence joins it: how far the limb's
two distal joints lie from the views' detections (:func:`keypoint_disagreement`, mm at the joints' depth,
median over the views, each view read as detected or left/right swapped), in the model of
:data:`COEFFICIENTS_KEYPOINTS`. Fitted on the shared clips with MediaPipe's keypoints on their renders (``refined``
without the keypoint term and the default with it, 3 runs each, 23,328 limb-frames, 16 % lost), left out per
clip, the two together rank a lost limb above a kept one with probability 0.980, against 0.945 for the
silhouettes alone; the keypoints see what the silhouettes cannot, a limb lost inside them (the walk: 0.83
against 0.50).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from swarmpose.joints import JOINT_INDEX
from swarmpose.track.recovery import Recovery

__all__ = ["LOST_MM", "COEFFICIENTS", "COEFFICIENTS_KEYPOINTS", "LIMB_JOINTS", "limb_confidence", "limb_lost", "limb_disagreement",
           "track_disagreement", "keypoint_disagreement"]

#: A limb is lost when its two distal joints are further than this from the truth on average (mm).
LOST_MM = 100.0
#: ``(a, b, eps)`` of the logistic model above.
COEFFICIENTS = (8.993, 3.204, 1e-4)
#: ``(a, b, c, eps, eps_k)`` of the model where the sequence carries a detector's keypoints:
#: P(lost) = 1 / (1 + exp(-(a + b log10(d + eps) + c log10(k + eps_k)))), k the keypoint disagreement in mm.
COEFFICIENTS_KEYPOINTS = (-10.031, 2.190, 8.224, 1e-4, 1.0)
#: Limb -> the joints its loss is measured on (the elbow and wrist, the knee and ankle).
LIMB_JOINTS: dict[str, tuple[str, str]] = {
    "left_arm": ("l_elbow", "l_wrist"), "right_arm": ("r_elbow", "r_wrist"),
    "left_leg": ("l_knee", "l_ankle"), "right_leg": ("r_knee", "r_ankle"),
}


def limb_confidence(disagreement: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
    """Confidence in ``[0, 1]`` (same shape) of limbs whose silhouette disagreement is ``disagreement``; NaN stays
    NaN. 0.98 for a limb inside every silhouette, 0.6 at a disagreement of 0.001, 0.07 at 0.01.

    With ``keypoints`` (the same shape: :func:`keypoint_disagreement`, mm) the model of
    :data:`COEFFICIENTS_KEYPOINTS` reads both where the keypoint number is finite, the silhouettes' alone elsewhere."""
    a, b, eps = COEFFICIENTS
    d = np.maximum(np.asarray(disagreement, dtype=np.float64), 0.0)
    z = a + b * np.log10(d + eps)
    if keypoints is not None:
        k = np.asarray(keypoints, dtype=np.float64)
        a2, b2, c2, eps2, eps_k = COEFFICIENTS_KEYPOINTS
        with np.errstate(invalid="ignore"):
            z_both = a2 + b2 * np.log10(d + eps2) + c2 * np.log10(np.maximum(k, 0.0) + eps_k)
        z = np.where(np.isfinite(k), z_both, z)
    return 1.0 - 1.0 / (1.0 + np.exp(-z))


def keypoint_disagreement(cameras: Sequence[Any], keypoints: np.ndarray, joints: np.ndarray,
                          limbs: Sequence[str] = tuple(LIMB_JOINTS)) -> np.ndarray:
    """``(T, L)`` how far each limb's two distal joints lie from a detector's keypoints, in mm at the joints' depth.

    ``keypoints (T, C, 15, 2)`` are the views' detections (NaN where absent), ``joints (T, 15, 3)`` the track's.
    In each view the model's joints are projected and each joint's pixel distance to its detection is taken to mm
    at that joint's depth (pixels x depth / focal length); a view counts as detected or with left and right
    swapped, whichever fits the whole pose better (the import can leave a view swapped). A limb's number is the
    median over the views of its two joints' mean; NaN where no view has both."""
    from swarmpose.joints import SWAP15

    kp = np.asarray(keypoints, dtype=np.float64)
    J = np.asarray(joints, dtype=np.float64)
    mm = []
    mm_swapped = []
    for c, cam in enumerate(cameras):
        uv, z = cam.project_with_depth(J)  # (T, 15, 2), (T, 15)
        scale = np.where(z > 0, z, np.nan) / (0.5 * (cam.K[0, 0] + cam.K[1, 1]))
        mm.append(np.linalg.norm(uv - kp[:, c], axis=-1) * scale)
        mm_swapped.append(np.linalg.norm(uv - kp[:, c][:, list(SWAP15)], axis=-1) * scale)
    d, ds = np.stack(mm, axis=1), np.stack(mm_swapped, axis=1)  # (T, C, 15)
    with np.errstate(invalid="ignore"):
        swapped = np.nansum(ds, axis=-1) < np.nansum(d, axis=-1)
    best = np.where(swapped[..., None], ds, d)
    out = np.full((len(J), len(limbs)), np.nan)
    for j, limb in enumerate(limbs):
        per_view = best[:, :, [JOINT_INDEX[n] for n in LIMB_JOINTS[limb]]].mean(axis=-1)  # NaN if either is
        seen = np.isfinite(per_view).any(axis=1)
        out[seen, j] = np.nanmedian(per_view[seen], axis=1)
    return out


def limb_lost(joints: np.ndarray, truth: np.ndarray, limbs: Sequence[str] = tuple(LIMB_JOINTS)) -> np.ndarray:
    """``(T, L)`` bool: each limb's two distal joints further than :data:`LOST_MM` from the truth on average
    (frames without finite truth: False)."""
    out = np.zeros((len(joints), len(limbs)), dtype=bool)
    for j, limb in enumerate(limbs):
        idx = [JOINT_INDEX[n] for n in LIMB_JOINTS[limb]]
        err = np.linalg.norm(np.asarray(joints)[:, idx] - np.asarray(truth)[:, idx], axis=-1).mean(axis=1)
        out[:, j] = np.nan_to_num(err, nan=0.0) > LOST_MM
    return out


def limb_disagreement(fitness: Any, model: Any, x: np.ndarray) -> dict[str, float]:
    """Limb -> the silhouette disagreement of pose ``x (D,)`` with the bound frame (worst cone of the limb)."""
    parts = fitness.part_agreement(np.asarray(x, dtype=np.float64)[None])[0]
    return {limb: float(parts[cones].max()) for limb, (cones, _) in Recovery().limbs(model).items()}


def track_disagreement(fitness: Any, model: Any, params: np.ndarray, observations: Any,
                       limbs: Sequence[str] = tuple(LIMB_JOINTS)) -> np.ndarray:
    """``(T, L)`` disagreement of every frame's pose ``params[t]``; ``observations(t)`` gives frame t's
    observation to bind (an image fitness: silhouettes)."""
    out = np.full((len(params), len(limbs)), np.nan)
    for t, x in enumerate(np.asarray(params, dtype=np.float64)):
        fitness.bind(observations(t))
        d = limb_disagreement(fitness, model, x)
        out[t] = [d.get(limb, np.nan) for limb in limbs]
    return out
