"""The keypoint term: how far the model's joints project from a detector's labelled body keypoints.

Beyond the papers (``shared/design.md`` §7): where a sequence carries a person detector's 15 keypoints with
confidences (an imported recording), the image fitnesses can add ``w * K(x)`` with

    K(x) = - mean_c  min_{labels}  sum_j w_cj rho(|pi_c(J_j(x)) - k_cj|) / sum_j w_cj,
    rho(e) = e^2 / (e^2 + s^2)                                     (Geman & McClure 1987)

over the views ``c`` that have confident keypoints (``w_cj`` = confidence times the joint's weight ``a_j``,
0 below :data:`MIN_CONFIDENCE`; ``a_j = 1`` unless the ``keypoint_joints`` option says otherwise; the model's
elbows ``J_j`` taken where the ``keypoint_elbow`` option puts the detector's, :func:`detector_elbows`).
``rho`` is bounded, so a misdetected joint costs at most 1 and cannot drag the pose; ``min_labels`` takes,
per view, the best of the labels as detected and left and right exchanged (the whole body's; with the
``keypoint_swaps`` option also parts of it alone: :data:`SWAPS`), so a view whose detector swapped the sides
still helps. ``s`` is :data:`SCALE` of the image diagonal unless the ``keypoint_scale`` option says otherwise.
``K`` lies in ``[-1, 0]``.

:func:`keypoint_cost` is batched over poses; :func:`keypoint_cost_reference` is the plain loop it is
tested against.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from swarmpose.camera import Camera
from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINT_INDEX, JOINTS15, SWAP15

__all__ = ["keypoint_cost", "keypoint_cost_reference", "views_agreeing", "joint_weights", "joint_thresholds",
           "detector_elbows", "SCALE", "SWAP", "SWAPS"]

#: Robust scale of the residual, as a fraction of the image diagonal (about 22 px at 544 x 960).
SCALE = 0.02
#: The permutation of the 15 joints that exchanges left and right.
SWAP = np.array(SWAP15)


def _swap_of(parts: tuple[str, ...]) -> tuple[int, ...]:
    """The permutation that exchanges left and right of the joints named ``l_/r_`` + one of ``parts`` only."""
    return tuple(int(SWAP[j]) if name[2:] in parts else j for j, name in enumerate(JOINTS15))


#: The labellings the keypoint term tries per view (permutations of the 15 joints), by ``keypoint_swaps``:
#: ``body``: as detected and the whole body's left and right exchanged; ``limbs``: also the arms' alone
#: (shoulders, elbows, wrists) and the legs' alone (hips, knees, ankles); ``ends``: also the elbows and wrists
#: alone and the knees and ankles alone (the shoulders and hips, which say where the body faces, only with the
#: whole body). MediaPipe on the synthetic clips' faceless renders now and then labels one view's arms and legs
#: differently; docs/results.md measures what each set does to the tracking.
SWAPS = {"body": (tuple(range(len(JOINTS15))), tuple(int(j) for j in SWAP)),
         "limbs": (tuple(range(len(JOINTS15))), tuple(int(j) for j in SWAP),
                   _swap_of(("shoulder", "elbow", "wrist")), _swap_of(("hip", "knee", "ankle"))),
         "ends": (tuple(range(len(JOINTS15))), tuple(int(j) for j in SWAP),
                  _swap_of(("elbow", "wrist")), _swap_of(("knee", "ankle")))}
_PERMS = {name: np.array(perms, dtype=np.int64) for name, perms in SWAPS.items()}  # (L, 15), for the kernel


def _per_joint(spec: str, option: str, base: float, ok, form: str, example: str,
               bare: bool) -> tuple[float, ...]:
    """The 15 joints' values from ``"part:v+part:v"`` over ``base`` (later parts win); with ``bare`` a part may be
    a number alone, which sets every joint."""
    values = [base] * len(JOINTS15)
    for item in filter(None, (t.strip() for t in str(spec).split("+"))):
        part, sep, value = item.rpartition(":") if ":" in item else ("", "", item)
        try:
            v = float(value)
        except ValueError:
            v = float("nan")
        if (not sep and not bare) or not ok(v):
            raise ConfigError(f"{option}: {item!r} is not {form} (e.g. {example})")
        hit = list(range(len(JOINTS15))) if not sep else [j for j, name in enumerate(JOINTS15)
                                                          if part.strip() and part.strip() in name]
        if not hit:
            raise ConfigError(f"{option}: {part!r} names none of the joints {', '.join(JOINTS15)}")
        for j in hit:
            values[j] = v
    return tuple(values)


@lru_cache(maxsize=32)  # read once per text, not on every evaluation of the fitness
def joint_weights(spec: str) -> tuple[float, ...]:
    """The 15 joints' weights ``a_j`` from ``"elbow:0.25+hip:0.5"``: each ``part:w`` sets every joint whose name
    contains ``part`` (``elbow``: both elbows; ``l_wrist``: one); later parts win; "" gives all 1.

    Raises
    ------
    ConfigError
        A part that names no joint, or a weight that is not a number >= 0.
    """
    return _per_joint(spec, "keypoint_joints", 1.0, lambda w: bool(np.isfinite(w) and w >= 0),
                      "PART:WEIGHT with a weight >= 0", "elbow:0.25+hip:0.5", bare=False)


@lru_cache(maxsize=32)
def joint_thresholds(spec: str | float) -> tuple[float, ...]:
    """The 15 joints' confidence thresholds from ``0.2``, ``"wrist:0.1"`` or ``"0.2+wrist:0.1"``: a number alone
    sets every joint, ``part:t`` the joints whose name contains ``part``; later parts win; the rest stay at
    :data:`MIN_CONFIDENCE`.

    Raises
    ------
    ConfigError
        A part that names no joint, or a threshold outside [0, 1].
    """
    return _per_joint(str(spec), "keypoint_threshold", MIN_CONFIDENCE, lambda t: bool(0 <= t <= 1),
                      "a threshold or PART:THRESHOLD, each in [0, 1]", "0.2+wrist:0.1", bare=True)


def detector_elbows(joints: np.ndarray, fraction: float) -> np.ndarray:
    """``joints (..., 15, 3)`` with each elbow moved to ``fraction`` of the way from its shoulder (1: unchanged).

    A detector places the elbow nearer the shoulder than a skeleton's joint centre: MediaPipe Pose splits the
    shoulder-wrist length at 0.50-0.59 on the shared clips' renders (the median per clip and side), where their
    skeletons split it at 0.56-0.63, and its elbows lie 15-68 mm up the upper arm from theirs."""
    if fraction == 1.0:
        return joints
    out = np.array(joints, dtype=np.float64, copy=True)
    for side in ("l", "r"):
        s, e = JOINT_INDEX[f"{side}_shoulder"], JOINT_INDEX[f"{side}_elbow"]
        out[..., e, :] = out[..., s, :] + fraction * (out[..., e, :] - out[..., s, :])
    return out


def keypoint_cost(joints: np.ndarray, cameras: Sequence[Camera], keypoints: np.ndarray,
                  confidence: np.ndarray, scale: float = SCALE,
                  weights: Sequence[float] | None = None, elbow: float = 1.0, swaps: str = "body",
                  threshold: float | Sequence[float] = MIN_CONFIDENCE, power: float = 1.0, min_views: int = 1,
                  tables: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``-K``: the robust keypoint cost ``(N,)`` in ``[0, 1]`` of model joints ``(N, 15, 3)`` (mm).

    One compiled pass over the poses, views and labellings (:mod:`swarmpose.fitness._keypoint_kernel`); equal to
    :func:`keypoint_cost_reference` to rounding (the projection's products are added in another order than
    numpy's matrix product adds them).

    Parameters
    ----------
    joints : (N, 15, 3)
    cameras : C cameras
    keypoints : (C, 15, 2) px, NaN where absent; confidence : (C, 15)
    scale : float
        ``s`` as a fraction of the first camera's image diagonal (default :data:`SCALE`).
    weights : (15,) float, optional
        The joints' weights ``a_j`` (:func:`joint_weights`); default all 1.
    elbow : float
        Where the detector's elbow is taken to lie on the model's upper arm (:func:`detector_elbows`).
    swaps : {"body", "limbs", "ends"}
        The labellings tried per view (:data:`SWAPS`).
    threshold : float or (15,) float
        A detection counts from confidence ``threshold`` on (default :data:`MIN_CONFIDENCE`; one per joint, by the
        detection's label: :func:`joint_thresholds`).
    power : float
        A counted detection's weight is ``confidence ** power`` (default 1: its confidence; 0: every counted
        detection alike).
    min_views : int
        A detection counts only where at least this many views count a detection of its joint (default 1), as
        :func:`views_agreeing` leaves them.
    tables : (R, t, cam), optional
        The cameras packed as :func:`swarmpose.render.project.camera_tables` packs them (an image fitness has
        them per frame; the kernel reads ``cam``'s first 10 columns); default: packed here.
    """
    from swarmpose.fitness._keypoint_kernel import keypoint_kernel

    J = np.ascontiguousarray(detector_elbows(np.asarray(joints, dtype=np.float64), elbow))
    if tables is None:  # the kernel reads R, t and the intrinsics and distortion (cameras of any size)
        tables = (np.stack([c.R for c in cameras]), np.stack([c.t for c in cameras]),
                  np.array([[c.fx, c.fy, c.cx, c.cy, c.skew, *c.dist] for c in cameras], dtype=np.float64))
    R, t, cam = tables
    s = float(scale) * float(np.hypot(cameras[0].width, cameras[0].height))
    a = np.ones(len(JOINTS15)) if weights is None else np.asarray(weights, dtype=np.float64)
    out = np.empty(J.shape[0])
    confidence = np.asarray(confidence, dtype=np.float64)
    if np.ndim(threshold):  # per joint: the detections under their joint's threshold weigh 0, as absent ones do
        confidence = np.where(confidence >= np.asarray(threshold, dtype=np.float64), confidence, 0.0)
        threshold = 0.0
    if min_views > 1:
        confidence = views_agreeing(keypoints, confidence, threshold, min_views)
    keypoint_kernel(J, R, t, cam, np.asarray(keypoints, dtype=np.float64), confidence,
                    _PERMS[swaps], a, float(threshold), float(power), s * s, out)
    return out


def views_agreeing(keypoints: np.ndarray, confidence: np.ndarray, threshold: float | Sequence[float],
                   min_views: int) -> np.ndarray:
    """``confidence (C, 15)`` with 0 for the joints that fewer than ``min_views`` views count (a detection present,
    its confidence at least ``threshold`` and above 0): a joint one view alone reports confidently cannot be
    triangulated, and a wrong one leads the model's joint along that view's ray."""
    conf = np.asarray(confidence, dtype=np.float64)
    counted = np.isfinite(np.asarray(keypoints, dtype=np.float64)).all(axis=-1) & (conf >= threshold) & (conf > 0)
    return np.where(counted.sum(axis=0) >= min_views, conf, 0.0)


def keypoint_cost_reference(joints: np.ndarray, cameras: Sequence[Camera], keypoints: np.ndarray,
                            confidence: np.ndarray, scale: float = SCALE,
                            weights: Sequence[float] | None = None, elbow: float = 1.0,
                            swaps: str = "body", threshold: float | Sequence[float] = MIN_CONFIDENCE,
                            power: float = 1.0, min_views: int = 1) -> np.ndarray:
    """:func:`keypoint_cost` written as plain loops over poses, views, labellings and joints."""
    thr = [float(threshold)] * len(JOINTS15) if np.ndim(threshold) == 0 else [float(v) for v in threshold]
    seen_by = [sum(1 for c in range(len(cameras)) if np.isfinite(keypoints[c][j]).all()
                   and confidence[c][j] >= thr[j] and confidence[c][j] > 0) for j in range(len(JOINTS15))]
    J = np.array(joints, dtype=np.float64)
    for n in range(len(J)):
        for side in ("l", "r"):
            sh, el = J[n, JOINT_INDEX[f"{side}_shoulder"]].copy(), J[n, JOINT_INDEX[f"{side}_elbow"]].copy()
            J[n, JOINT_INDEX[f"{side}_elbow"]] = sh + elbow * (el - sh)
    a = [1.0] * len(JOINTS15) if weights is None else [float(v) for v in weights]
    s = float(scale) * float(np.hypot(cameras[0].width, cameras[0].height))
    out = np.zeros(len(J))
    for n in range(len(J)):
        acc, views = 0.0, 0
        for c, cam in enumerate(cameras):
            conf = [float(confidence[c][j]) ** power if np.isfinite(keypoints[c][j]).all()
                    and confidence[c][j] >= thr[j] and confidence[c][j] > 0 and seen_by[j] >= min_views else 0.0
                    for j in range(len(JOINTS15))]
            labellings = []
            for perm in SWAPS[swaps]:
                wl = [conf[perm[j]] * a[j] for j in range(len(JOINTS15))]  # model joint j, detection perm[j]
                if sum(wl) > 0:
                    labellings.append((perm, wl))
            if not labellings:
                continue
            views += 1
            uv, z = cam.project_with_depth(J[n])
            if not (z > 0).all():
                acc += 1.0
                continue
            best = np.inf
            for perm, wl in labellings:
                num = den = 0.0
                for j in range(len(JOINTS15)):
                    if wl[j] == 0:
                        continue
                    e2 = float(((uv[j] - keypoints[c][perm[j]]) ** 2).sum())
                    num += wl[j] * e2 / (e2 + s * s)
                    den += wl[j]
                best = min(best, num / den)
            acc += best
        out[n] = acc / views if views else 0.0
    return out
