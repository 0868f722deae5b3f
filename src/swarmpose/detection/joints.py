"""From MediaPipe's 33 BlazePose landmarks to the body model's 15 joints (:data:`swarmpose.joints.JOINTS15`).

The mapping is data: :data:`JOINT_SOURCES` gives, for each of the 15 joints, the landmarks it is made
of and their weights (which sum to 1), and :data:`CONFIDENCE_SCALE` the factor on its confidence.

* Shoulders, elbows, wrists, hips, knees and ankles are the landmarks themselves. MediaPipe's
  ``left_*`` is the *person's* left (not the left of the image), as is swarmpose's ``l_*``.
* ``thorax`` and ``pelvis`` are the body model's (HumanEva's) joints: the base of the neck and the pelvis
  (the skeleton's root), which are not MediaPipe's shoulder and hip midpoints. On the synthetic clips,
  whose ground truth has both (``scripts/track_without_truth.py --clips cmu_16_16_walk cmu_16_18_turn
  cmu_49_17_dance cmu_135_04_kick --import-only`` imports them with the detector and fits these), the
  joints triangulated from the keypoints put the truth's pelvis at ``hip_mid + p * (shoulder_mid -
  hip_mid)`` with ``p`` = 0.31, 0.31, 0.29, 0.24 (walk and turn of subject 16, dance of 49, kick of 135;
  least squares over the frames) and its thorax at ``shoulder_mid - t * (shoulder_mid - hip_mid)`` with
  ``t`` = 0.15, 0.15, 0.20, 0.21. :data:`PELVIS_FRACTION` and :data:`THORAX_FRACTION` are their means:
  the triangulated pelvis moves from 117-139 mm off the truth to 21-57 mm, the thorax from 68-89 mm to
  17-24 mm. A linear combination of landmarks stays consistent across views (it triangulates to the same
  combination of the 3D landmarks).
* ``head_top`` is no landmark. It is extrapolated along the neck, above the ears:
  ``head_top = ear_mid + HEAD_TOP_FRACTION * (ear_mid - shoulder_mid)``, i.e. the weights
  ``(1 + f) / 2`` on each ear and ``-f / 2`` on each shoulder. The ear canal lies about 0.12 m below
  the vertex and about 0.18 m above the shoulders (acromions) of an adult, so ``f`` is about 2/3.
  Checked on the four Pose2Sim demo views (MediaPipe's shoulders and ears, 100 frames each): the
  outline of the segmentation mask along the shoulder-to-ear direction lies at ``f`` = 0.74 to 1.10
  (median per view), ``f = 0.6`` falls inside the head, ``f = 0.8`` on its outline; the projected
  vertex belongs slightly inside the outline (the outline is the head's occluding contour), hence
  ``f = 0.7``. A linear combination of projected points is exact for an affine camera and close for
  a person far from the camera. Being a guess, its confidence is scaled by
  ``CONFIDENCE_SCALE["head_top"] = 0.5``.

A joint's confidence is the minimum of its landmarks' confidences (times its scale); it is NaN-free
(0 where a landmark is absent), and its coordinates are NaN when any of its landmarks is NaN.

Public API
----------
``BLAZEPOSE33``: the 33 landmark names in MediaPipe's order. ``JOINT_SOURCES``, ``CONFIDENCE_SCALE``,
``HEAD_TOP_FRACTION``: the table above. ``to_joints15(keypoints (..., 33, 2), confidence (..., 33))
-> (..., 15, 2), (..., 15)``. ``SWAP15``: the permutation of the 15 joints that swaps left and right
(``joints[..., SWAP15, :]`` is the left/right-swapped skeleton; ``SWAP15[SWAP15]`` is the identity).
"""

from __future__ import annotations

import numpy as np

from swarmpose.errors import ShapeError
from swarmpose.joints import JOINTS15
from swarmpose.joints import SWAP15 as SWAP15_TUPLE

__all__ = ["BLAZEPOSE33", "BLAZEPOSE_INDEX", "HEAD_TOP_FRACTION", "PELVIS_FRACTION", "THORAX_FRACTION",
           "JOINT_SOURCES", "CONFIDENCE_SCALE", "MIN_CONFIDENCE", "SWAP15", "SWAP33", "to_joints15"]

BLAZEPOSE33: tuple[str, ...] = (
    "nose",
    "left_eye_inner", "left_eye", "left_eye_outer",
    "right_eye_inner", "right_eye", "right_eye_outer",
    "left_ear", "right_ear",
    "mouth_left", "mouth_right",
    "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow",
    "left_wrist", "right_wrist",
    "left_pinky", "right_pinky",
    "left_index", "right_index",
    "left_thumb", "right_thumb",
    "left_hip", "right_hip",
    "left_knee", "right_knee",
    "left_ankle", "right_ankle",
    "left_heel", "right_heel",
    "left_foot_index", "right_foot_index",
)
BLAZEPOSE_INDEX: dict[str, int] = {name: i for i, name in enumerate(BLAZEPOSE33)}

HEAD_TOP_FRACTION = 0.7
_F = HEAD_TOP_FRACTION
#: The pelvis from the hip midpoint towards the shoulder midpoint, as a fraction of the trunk (see above).
PELVIS_FRACTION = 0.29
#: The thorax from the shoulder midpoint towards the hip midpoint, as a fraction of the trunk (see above).
THORAX_FRACTION = 0.18
_P, _T = PELVIS_FRACTION, THORAX_FRACTION

JOINT_SOURCES: dict[str, tuple[tuple[str, float], ...]] = {
    "thorax": (("left_shoulder", (1 - _T) / 2), ("right_shoulder", (1 - _T) / 2),
               ("left_hip", _T / 2), ("right_hip", _T / 2)),
    "pelvis": (("left_hip", (1 - _P) / 2), ("right_hip", (1 - _P) / 2),
               ("left_shoulder", _P / 2), ("right_shoulder", _P / 2)),
    "l_shoulder": (("left_shoulder", 1.0),),
    "l_elbow": (("left_elbow", 1.0),),
    "l_wrist": (("left_wrist", 1.0),),
    "r_shoulder": (("right_shoulder", 1.0),),
    "r_elbow": (("right_elbow", 1.0),),
    "r_wrist": (("right_wrist", 1.0),),
    "l_hip": (("left_hip", 1.0),),
    "l_knee": (("left_knee", 1.0),),
    "l_ankle": (("left_ankle", 1.0),),
    "r_hip": (("right_hip", 1.0),),
    "r_knee": (("right_knee", 1.0),),
    "r_ankle": (("right_ankle", 1.0),),
    "head_top": (("left_ear", (1 + _F) / 2), ("right_ear", (1 + _F) / 2),
                 ("left_shoulder", -_F / 2), ("right_shoulder", -_F / 2)),
}
CONFIDENCE_SCALE: dict[str, float] = {"head_top": 0.5}  # 1 for the others
#: Keypoints below this confidence are not used: MediaPipe's visibility of a hidden joint is low. The import's
#: subject selection, the tracker's start, the keypoint term and the held-out scores all use it.
MIN_CONFIDENCE = 0.3


def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(index (15, P) int, weight (15, P), scale (15,))``; short rows are padded with their first
    landmark at weight 0 (so padding neither adds a NaN nor changes the minimum confidence)."""
    assert set(JOINT_SOURCES) == set(JOINTS15), "JOINT_SOURCES must name each of the 15 joints"
    width = max(len(parts) for parts in JOINT_SOURCES.values())
    index = np.zeros((len(JOINTS15), width), np.intp)
    weight = np.zeros((len(JOINTS15), width))
    for j, name in enumerate(JOINTS15):
        parts = JOINT_SOURCES[name]
        assert abs(sum(w for _, w in parts) - 1.0) < 1e-12, f"the weights of {name} must sum to 1"
        index[j, :] = BLAZEPOSE_INDEX[parts[0][0]]
        for p, (landmark, w) in enumerate(parts):
            index[j, p] = BLAZEPOSE_INDEX[landmark]
            weight[j, p] = w
    scale = np.array([CONFIDENCE_SCALE.get(name, 1.0) for name in JOINTS15])
    return index, weight, scale


_INDEX, _WEIGHT, _SCALE = _tables()


def _swap(names: tuple[str, ...], left: str, right: str) -> np.ndarray:
    """The permutation of ``names`` exchanging each ``left...`` name with its ``right...`` twin."""
    lookup = {n: i for i, n in enumerate(names)}
    perm = np.arange(len(names))
    for i, n in enumerate(names):
        if n.startswith(left):
            perm[i] = lookup[right + n[len(left):]]
        elif n.startswith(right):
            perm[i] = lookup[left + n[len(right):]]
    perm.setflags(write=False)
    return perm


SWAP15 = np.array(SWAP15_TUPLE)
SWAP15.setflags(write=False)
SWAP33 = _swap(BLAZEPOSE33, "left_", "right_")


def to_joints15(keypoints: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 15 joints from BlazePose landmarks, vectorised over leading axes.

    Parameters
    ----------
    keypoints : (..., 33, 2)
        Landmark pixels (NaN where absent).
    confidence : (..., 33)
        Landmark confidences in ``[0, 1]``.

    Returns
    -------
    joints : (..., 15, 2) float64
        Weighted sums of landmarks (:data:`JOINT_SOURCES`); NaN where a landmark used is NaN.
    joint_confidence : (..., 15) float64
        Minimum confidence of the landmarks used, times :data:`CONFIDENCE_SCALE`; 0 where NaN.

    Raises
    ------
    ShapeError
        Shapes other than those above.
    """
    keypoints = np.asarray(keypoints, dtype=np.float64)
    confidence = np.asarray(confidence, dtype=np.float64)
    n = len(BLAZEPOSE33)
    if keypoints.shape[-2:] != (n, 2) or confidence.shape != keypoints.shape[:-1]:
        raise ShapeError(f"expected keypoints (..., {n}, 2) and confidence (..., {n}), got {keypoints.shape} "
                         f"and {confidence.shape}")
    parts = keypoints[..., _INDEX, :]  # (..., 15, P, 2)
    joints = np.einsum("...jpd,jp->...jd", parts, _WEIGHT)
    joint_conf = np.nan_to_num(confidence[..., _INDEX].min(axis=-1), nan=0.0) * _SCALE
    joint_conf = np.where(np.isnan(joints).any(axis=-1), 0.0, joint_conf)
    return joints, joint_conf
