"""Where a track without ground truth starts: the 15 joints triangulated from the sequence's keypoints.

A recording imported with a person detector (``swarmpose import``) stores each view's 15 body keypoints,
labelled, with confidences and left and right already resolved across views, as its marker stream.
:func:`keypoint_joints` triangulates them per tracked frame (weighted DLT, then again without the
observations that reproject more than the threshold away: a wrong wrist in one view). The tracker's start
pose is then the IK fit of the body model to frame 0's joints, and the subject's limbs can be measured from
the joints over all frames (:func:`swarmpose.body.subject.subject_from_joints` with medians).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.errors import ConfigError, DataError
from swarmpose.joints import BONES15, JOINT_INDEX, JOINTS15, SWAP15
from swarmpose.triangulation import relabel_pairs, residuals, triangulate

__all__ = ["keypoint_joints", "keypoint_ik", "keypoint_start", "tracked_views", "has_keypoints", "fill_gaps",
           "bone_lengths", "elbow_fraction", "ELBOW_FRACTION_RANGE", "TRUNK_JOINTS",
           "silhouette_centre", "silhouette_start", "heading_candidates", "START_HEADINGS", "START_SEARCHES",
           "START_ROUNDS"]



def has_keypoints(seq: Any) -> bool:
    """Whether ``seq`` stores labelled 15-joint keypoints with confidences (an imported recording)."""
    md = getattr(seq, "marker_data", None)
    return md is not None and md.confidence is not None and tuple(md.names) == JOINTS15


#: The 15 joints' left/right pairs (shoulders, elbows, wrists, hips, knees, ankles), as index pairs.
LEFT_RIGHT_PAIRS = tuple((j, int(SWAP15[j])) for j in range(len(JOINTS15)) if j < SWAP15[j])


def keypoint_joints(seq: Any, frames: np.ndarray, *, views: list[int] | None = None,
                    threshold: float | None = None, relabel: bool = True,
                    keep_disagreeing: bool = False) -> np.ndarray:
    """World joints ``(T, 15, 3)`` mm triangulated from the keypoints of ``frames`` (NaN where < 2 views agree).

    Each view's left and right detections of a joint are first exchanged where that makes the views agree
    (:func:`swarmpose.triangulation.relabel_pairs`, where at least three views see both); then a weighted DLT,
    and again without the observations whose residual exceeds ``threshold``. A joint that fewer than two views
    still see after that is NaN: its views disagree, and the first pass's point between them is wrong (on the 8
    shared clips' renders 115 of 117 such points lie over 100 mm from the truth, 93 of 97 on the clips mirrored).

    Parameters
    ----------
    seq : MultiViewSequence
        With keypoints (:func:`has_keypoints`).
    frames : array of int
        Sequence frames.
    views : list of int, optional
        The views to use (default all): a held-out camera stays out.
    threshold : float, optional
        Largest residual (px of the sequence) of an observation kept in the second pass; default 2.5 % of
        the image diagonal.
    relabel : bool
        Exchange left and right detections where that makes the views agree (default); False: as detected.
    keep_disagreeing : bool
        Where the views disagree, keep the first pass's point, as a plain triangulation gives it (the baseline a
        held-out camera scores the model against); default False: NaN.
    """
    dense, conf = seq.marker_data.to_dense()
    idx = np.asarray(frames, dtype=np.int64)
    v = list(range(seq.n_views)) if views is None else list(views)
    cams = [seq.cameras[c] for c in v]
    kp = dense[idx][:, v]
    w = np.where(conf[idx][:, v] >= MIN_CONFIDENCE, conf[idx][:, v], 0.0)
    thr = 0.025 * float(np.hypot(*seq.image_size)) if threshold is None else float(threshold)
    if relabel:
        kp, w = relabel_pairs(cams, kp, w, LEFT_RIGHT_PAIRS, thr)
    pts = triangulate(cams, kp, w)
    r = residuals(cams, pts, kp)
    w2 = np.where(np.isfinite(r) & (r < thr), w, 0.0)
    again = triangulate(cams, kp, w2)
    return np.where(np.isfinite(again), again, pts) if keep_disagreeing else again


#: The range :func:`elbow_fraction` keeps its answer in.
ELBOW_FRACTION_RANGE = (0.7, 1.0)


def _arm_split(joints: np.ndarray) -> np.ndarray:
    """``|shoulder elbow| / (|shoulder elbow| + |elbow wrist|)`` per frame and side ``(T, 2)`` of ``(T, 15, 3)``."""
    out = []
    for side in ("l", "r"):
        s, e, w = (joints[:, JOINT_INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
        upper, fore = np.linalg.norm(e - s, axis=-1), np.linalg.norm(w - e, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(upper / (upper + fore))
    return np.stack(out, axis=1)


def elbow_fraction(model: Any, joints: np.ndarray) -> float:
    """Where the detector's elbow lies on the model's upper arm, as a fraction of it from the shoulder.

    The detector's split of the arm (the median over frames and sides of ``|SE| / (|SE| + |EW|)`` of the
    triangulated keypoints ``joints (T, 15, 3)``) over the model's own (its bone lengths), kept in
    :data:`ELBOW_FRACTION_RANGE`; 1.0 when no frame shows a whole arm. The keypoint term then compares the
    detector's elbows with that point of the model's upper arms (``keypoint_elbow``)."""
    detected = _arm_split(np.asarray(joints, dtype=np.float64)).ravel()
    detected = detected[np.isfinite(detected)]
    if not detected.size:
        return 1.0
    own = float(np.mean(_arm_split(model.joints15(model.zero_pose()[None]))))
    lo, hi = ELBOW_FRACTION_RANGE
    return float(np.clip(np.median(detected) / own, lo, hi))


def bone_lengths(joints: np.ndarray) -> np.ndarray:
    """Median length (mm) of each of :data:`~swarmpose.joints.BONES15` over the frames of ``joints (T, 15, 3)``
    where both its ends are finite; NaN where no frame has both."""
    j = np.asarray(joints, dtype=np.float64)
    out = np.full(len(BONES15), np.nan)
    for b, (p, c) in enumerate(BONES15):
        d = np.linalg.norm(j[:, c] - j[:, p], axis=-1)
        d = d[np.isfinite(d)]
        if d.size:
            out[b] = float(np.median(d))
    return out


def fill_gaps(joints: np.ndarray, k: int = 0, reach: int = 10, tolerance: float = 0.3) -> np.ndarray:
    """Frame ``k``'s joints ``(15, 3)`` with each missing joint taken from the nearest frame (within ``reach``)
    that has it; NaN where none does.

    Joints are filled from the pelvis outwards along :data:`~swarmpose.joints.BONES15`. Where the joint's parent
    is known in both frames, the neighbour's bone (joint minus parent) is added to this frame's parent, and
    only when its length is within ``tolerance`` of the bone's median over all frames: a neighbour whose
    detector mixed the left and right arm (an elbow 500 mm from its shoulder) gives nothing, and the joint
    stays missing. Without a parent the neighbour's joint is taken as it is.
    """
    j = np.asarray(joints, dtype=np.float64)
    out = np.array(j[k], dtype=np.float64)
    lengths = bone_lengths(j)
    parent = {c: (p, b) for b, (p, c) in enumerate(BONES15)}
    order = [JOINTS15.index("pelvis")] + [c for _, c in BONES15]
    for c in order:
        if np.isfinite(out[c]).all():
            continue
        p, b = parent.get(c, (None, None))
        for d in range(1, reach + 1):
            for kk in (k - d, k + d):
                if not (0 <= kk < len(j)) or not np.isfinite(j[kk, c]).all():
                    continue
                if p is not None and np.isfinite(out[p]).all() and np.isfinite(j[kk, p]).all():
                    bone = j[kk, c] - j[kk, p]
                    if np.isfinite(lengths[b]) and abs(np.linalg.norm(bone) / lengths[b] - 1.0) <= tolerance:
                        out[c] = out[p] + bone
                elif p is None or not np.isfinite(out[p]).all():
                    out[c] = j[kk, c]
                if np.isfinite(out[c]).all():
                    break
            if np.isfinite(out[c]).all():
                break
    return out


def keypoint_ik(model: Any, joints: np.ndarray, x0: np.ndarray, constraint: Any = None) -> np.ndarray | None:
    """The pose nearest ``x0`` that fits one frame's triangulated joints ``(15, 3)`` (an IK fit from ``x0``,
    polished on the joint residuals), or None when a joint is missing or the fit breaks ``constraint``."""
    from swarmpose.body.ik import fit_ik

    j = np.asarray(joints, dtype=np.float64)
    if not np.isfinite(j).all():
        return None
    x = fit_ik(model, j[None], init=np.asarray(x0, dtype=np.float64)).floor_params[0]
    if constraint is not None and not bool(np.asarray(constraint(x[None])).ravel()[0]):
        return None
    return x


def tracked_views(seq: Any, views: str) -> list[int]:
    """Indices of the cameras ``views`` names (``"cam01,cam03"``; ``""``: all), in the sequence's order."""
    names = list(seq.view_names)
    if not views:
        return list(range(len(names)))
    wanted = [v.strip() for v in str(views).split(",") if v.strip()]
    unknown = [v for v in wanted if v not in names]
    if unknown:
        raise ConfigError(f"--views: no camera {', '.join(map(repr, unknown))} in the sequence (its cameras: "
                          f"{', '.join(names)})")
    if len(set(wanted)) < 1:
        raise ConfigError("--views names no camera")
    return [i for i, n in enumerate(names) if n in wanted]


#: The joints a start from keypoints cannot do without: they place and turn the trunk.
TRUNK_JOINTS = ("thorax", "pelvis", "l_shoulder", "r_shoulder", "l_hip", "r_hip")


def keypoint_start(model: Any, joints: np.ndarray, sequence_path: Any, first: int):
    """Start pose from the joints triangulated from the keypoints: the IK fit of frame 0's joints (a joint
    missing there is taken from the nearest frame that has it, :func:`fill_gaps`; a limb joint that no
    nearby frame gives plausibly is left to the search, its limb starting at rest); no IK floor without
    ground truth."""
    from swarmpose.body.ik import fit_ik

    start = fill_gaps(joints, 0)
    missing = [JOINTS15[j] for j in np.flatnonzero(~np.isfinite(start).all(axis=1))]
    if any(name in TRUNK_JOINTS for name in missing):
        raise DataError(f"{sequence_path}: too few views see {', '.join(missing)} around frame {first} to "
                        "triangulate the start pose; import from a later frame (`swarmpose import --start`) or track with more cameras")
    ik = fit_ik(model, start[None], missing=True)
    T = len(joints)
    params = np.full((T, model.n_params), np.nan)
    params[0] = ik.params[0]
    return params, np.full((T, 15), np.nan), params.copy()


#: Headings tried at frame 0 of a track that starts from the silhouettes, and how many of the best are searched.
START_HEADINGS = 12
START_SEARCHES = 3
#: Further searches of frame 0, each from the best pose so far, after the headings' searches.
START_ROUNDS = 4


def silhouette_centre(seq: Any, k: int, views: list[int]) -> np.ndarray | None:
    """The person's centre (mm): the tracked views' silhouette centroids triangulated (a coarse visual hull's
    centre), or None when fewer than two views see anyone. Silhouettes are the stored ones, else background
    subtraction against the sequence's backgrounds."""
    stored = seq.silhouettes(int(k))
    if stored is None:
        from swarmpose.features import silhouette

        images, bgs = seq.images(int(k)), seq.backgrounds()
        if images is None or bgs is None:
            return None
        stored = np.stack([silhouette(images[c], bgs[c]) for c in range(seq.n_views)])
    return centre_of_silhouettes(stored[views], [seq.cameras[c] for c in views])


def _pixel_sums(silhouettes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per view of ``(C, H, W)`` masks: the number of set pixels and the sums of their x and y (int64)."""
    b = silhouettes != 0
    rows = np.count_nonzero(b, axis=2)  # (C, H)
    cols = np.count_nonzero(b, axis=1)  # (C, W)
    return (rows.sum(axis=1).astype(np.int64), cols @ np.arange(b.shape[2], dtype=np.int64),
            rows @ np.arange(b.shape[1], dtype=np.int64))


def centre_of_silhouettes(silhouettes: np.ndarray, cameras: list) -> np.ndarray | None:
    """The silhouettes' centroids ``(C, H, W)`` (one per camera; views with fewer than 50 pixels left out)
    triangulated: ``(3,)`` mm, or None when fewer than two views see anyone."""
    uv = np.full((1, len(cameras), 1, 2), np.nan)
    n, x, y = _pixel_sums(np.asarray(silhouettes))
    seen = n >= 50
    uv[0, seen, 0, 0] = x[seen] / n[seen]  # exact integer sums: the same means as the pixels' coordinates' mean
    uv[0, seen, 0, 1] = y[seen] / n[seen]
    centre = triangulate(list(cameras), uv)[0, 0]
    return centre if np.isfinite(centre).all() else None


def silhouette_start(model: Any, centre: np.ndarray) -> np.ndarray:
    """A standing pose ``(D,)`` (joint angles zero) whose pelvis is at ``centre``, heading 0."""
    from swarmpose.joints import JOINT_INDEX

    x = model.zero_pose().astype(np.float64)
    pelvis = model.joints15(x[None])[0][JOINT_INDEX["pelvis"]]
    for a, name in enumerate(("pelvis_tx", "pelvis_ty", "pelvis_tz")):
        x[model.param_index(name)] += centre[a] - pelvis[a]
    return np.clip(x, model.lower, model.upper)


def heading_candidates(model: Any, x: np.ndarray, n: int = START_HEADINGS) -> np.ndarray:
    """``(n, D)``: ``x`` turned to ``n`` headings about the vertical (the root's ``pelvis_rz``)."""
    out = np.repeat(np.asarray(x, dtype=np.float64)[None], n, axis=0)
    out[:, model.param_index("pelvis_rz")] = np.linspace(-np.pi, np.pi, n, endpoint=False)
    return np.clip(out, model.lower, model.upper)
