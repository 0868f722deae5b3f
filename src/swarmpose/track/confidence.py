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
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from swarmpose.joints import JOINT_INDEX
from swarmpose.track.recovery import Recovery

__all__ = ["LOST_MM", "COEFFICIENTS", "LIMB_JOINTS", "limb_confidence", "limb_lost", "limb_disagreement",
           "track_disagreement"]

#: A limb is lost when its two distal joints are further than this from the truth on average (mm).
LOST_MM = 100.0
#: ``(a, b, eps)`` of the logistic model above.
COEFFICIENTS = (8.993, 3.204, 1e-4)
#: Limb -> the joints its loss is measured on (the elbow and wrist, the knee and ankle).
LIMB_JOINTS: dict[str, tuple[str, str]] = {
    "left_arm": ("l_elbow", "l_wrist"), "right_arm": ("r_elbow", "r_wrist"),
    "left_leg": ("l_knee", "l_ankle"), "right_leg": ("r_knee", "r_ankle"),
}


def limb_confidence(disagreement: np.ndarray) -> np.ndarray:
    """Confidence in ``[0, 1]`` (same shape) of limbs whose silhouette disagreement is ``disagreement``; NaN stays
    NaN. 0.98 for a limb inside every silhouette, 0.6 at a disagreement of 0.001, 0.07 at 0.01."""
    a, b, eps = COEFFICIENTS
    d = np.asarray(disagreement, dtype=np.float64)
    z = a + b * np.log10(np.maximum(d, 0.0) + eps)
    return 1.0 - 1.0 / (1.0 + np.exp(-z))


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
