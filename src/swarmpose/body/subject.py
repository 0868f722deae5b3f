"""Subject measurements from a skeleton's rest pose or from joint positions (limb lengths and offsets
of ``balan31``/``full45``).

As HumanEva's limb lengths come from mocap ([HE] ``ComputeLimbLengths``), ours come from the clip's
skeleton: the rest pose (all channels zero) gives the joint-to-joint vectors
(:func:`subject_from_rest_points`; :func:`swarmpose.io.mocap.subject_from_clip` picks the points of a
clip). CMU-style rest poses face +Z with +Y up and +X on the subject's left, so a rest vector
``(x, y, z)`` becomes the model-frame vector ``(z, x, y)`` (x forward, y left, z up), times the
skeleton's mm-per-unit.

* Limbs (thigh, shank, upper arm, forearm) keep the model's canonical direction (straight down in
  the zero pose) with the measured length.
* Offsets between branching joints (pelvis→hip, pelvis→thorax, thorax→shoulder, thorax→head top)
  are the full measured 3-vectors, so the model's zero pose matches the subject's proportions.
* Cone radii are not in a skeleton. With the subject's measurements (:class:`SubjectMeasurements`:
  the HumanEva ``.mp`` widths and offsets and the static trial's marker distances) they follow
  HumanEva's ``ComputeLimbParameters`` (:func:`swarmpose.body.measurements.measured_cones`), as
  the thesis fitted its model to its subject (sec. 5.1.2). Without measurements they are the
  spec's reference sizes (a 1.75 m adult) scaled by the subject's leg length over the reference
  leg length (a documented approximation).
* The torso cone runs from the pelvis along the pelvis→thorax line up to the *top of the
  shoulders*: the height of the shoulder joints plus the upper arm's radius (the humeral head).
  HumanEva's torso length is pelvis → thorax origin at the top of the sternum; the CMU files'
  thorax joint sits about 11 cm lower (amc2bvh drops the thorax bone), so the thorax point alone
  would leave the cone's upper edge mid-chest, where an image has no edge to match (thesis sec.
  5.1.2 lengthened the torso for the same reason).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from swarmpose.body.measurements import SubjectMeasurements, measured_cones
from swarmpose.body.spec import BodySpec, Subject
from swarmpose.joints import JOINTS15

__all__ = ["REST_POINTS", "subject_from_rest_points", "subject_from_joints"]

#: The rest-pose points :func:`subject_from_rest_points` measures: the 15 joints of
#: :data:`swarmpose.joints.JOINTS15`, the head joint (below ``head_top``), the toes (ball of the foot)
#: and the hand tips (NaN where a skeleton has none).
REST_POINTS: tuple[str, ...] = (*JOINTS15, "head", "l_toe", "r_toe", "l_hand_tip", "r_hand_tip")


def _model_vec(v: np.ndarray, mm_per_unit: float) -> tuple[float, float, float]:
    """CMU rest frame (x left, y up, z forward) → model frame (x forward, y left, z up), in mm."""
    return (float(v[2] * mm_per_unit), float(v[0] * mm_per_unit), float(v[1] * mm_per_unit))


def _torso_top(offsets: dict, cones: dict) -> tuple[float, float, float]:
    """Pelvis → top of the shoulders along the pelvis→thorax line (see the module docstring)."""
    thorax = np.asarray(offsets["spine_to_thorax"], dtype=float)
    shoulder_z = 0.5 * (offsets["l_thorax_to_shoulder"][2] + offsets["r_thorax_to_shoulder"][2])
    arm_r = cones["l_upper_arm"][0] if "l_upper_arm" in cones else 0.0
    top_z = thorax[2] + max(shoulder_z + arm_r, 0.0)
    return tuple(float(v) for v in thorax * (top_z / thorax[2]))  # type: ignore[return-value]


def _cones(spec: BodySpec, ratio: float, measurements: SubjectMeasurements | None
           ) -> tuple[dict[str, tuple[float, float, float, float]], str]:
    """Cone sizes from measurements (reference x ``ratio`` for the cones they do not cover) and a note."""
    scaled = {n: (r0 * ratio, r1 * ratio, sx, sy) for n, (r0, r1, sx, sy) in spec.default_subject.cones.items()}
    if measurements is None:
        return scaled, f"cone radii = reference x {ratio:.3f}"
    cones, kept = measured_cones(measurements, scaled)
    note = f"cones from measurements ({measurements.source})"
    if kept:
        note += f"; {', '.join(kept)} = reference x {ratio:.3f}"
    return cones, note


def subject_from_rest_points(spec: BodySpec, points: Mapping[str, Any], mm_per_unit: float, *, name: str,
                             source: str, measurements: SubjectMeasurements | None = None) -> Subject:
    """Measure a subject for ``spec`` (``balan31`` or ``full45`` layout) from a skeleton's rest pose.

    Parameters
    ----------
    spec : BodySpec
    points : mapping of str to array_like, shape (3,)
        Every name of :data:`REST_POINTS`: rest-pose positions in source units, CMU rest frame
        (module docstring).
    mm_per_unit : float
        Millimetres per source unit.
    name : str
        The subject's name.
    source : str
        Where the points come from (the subject's ``source`` begins with it).
    measurements : SubjectMeasurements, optional
        Size the cones (module docstring).
    """
    s = mm_per_unit

    def p(point: str) -> np.ndarray:
        return np.asarray(points[point], dtype=np.float64)

    def length(a: str, b: str) -> float:
        return float(np.linalg.norm(p(b) - p(a)) * s)

    offsets: dict[str, tuple[float, float, float]] = {}
    for side in ("l", "r"):
        offsets[f"{side}_pelvis_to_hip"] = _model_vec(p(f"{side}_hip") - p("pelvis"), s)
        offsets[f"{side}_thigh"] = (0.0, 0.0, -length(f"{side}_hip", f"{side}_knee"))
        offsets[f"{side}_shank"] = (0.0, 0.0, -length(f"{side}_knee", f"{side}_ankle"))
        offsets[f"{side}_thorax_to_shoulder"] = _model_vec(p(f"{side}_shoulder") - p("thorax"), s)
        offsets[f"{side}_upper_arm"] = (0.0, 0.0, -length(f"{side}_shoulder", f"{side}_elbow"))
        offsets[f"{side}_forearm"] = (0.0, 0.0, -length(f"{side}_elbow", f"{side}_wrist"))
        offsets[f"{side}_foot"] = _model_vec(p(f"{side}_toe") - p(f"{side}_ankle"), s)
        hand_len = float(np.linalg.norm(np.nan_to_num(p(f"{side}_hand_tip") - p(f"{side}_wrist"))) * s)
        offsets[f"{side}_hand"] = (0.0, 0.0, -max(hand_len, 1.0))
    offsets["spine_to_thorax"] = _model_vec(p("thorax") - p("pelvis"), s)
    offsets["neck_to_head_top"] = _model_vec(p("head_top") - p("thorax"), s)
    head = p("head")
    offsets["neck_to_head"] = _model_vec(head - p("thorax"), s)
    offsets["head_to_top"] = _model_vec(p("head_top") - head, s)
    ref = spec.default_subject.offsets
    ref_leg = -(ref["l_thigh"][2] + ref["l_shank"][2])
    leg = -(offsets["l_thigh"][2] + offsets["l_shank"][2])
    ratio = leg / ref_leg
    cones, note = _cones(spec, ratio, measurements)
    offsets["pelvis_to_torso_top"] = _torso_top(offsets, cones)
    offsets = {k: v for k, v in offsets.items() if k in spec.default_subject.offsets}
    return Subject(name=name, offsets=offsets, cones=cones, source=f"{source}; {note}")


def _frames(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Per-frame right-handed frames ``(T, 3, 3)`` (columns x, y, z) with y along ``a - b`` and z along ``c``."""
    y = a - b
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    z = c - np.sum(c * y, axis=-1, keepdims=True) * y
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def subject_from_joints(spec: BodySpec, joints15: np.ndarray, name: str = "subject",
                        measurements: SubjectMeasurements | None = None, *, robust: bool = False,
                        source: str = "15-joint ground truth") -> Subject:
    """Measure a ``balan31``-layout subject from 15-joint ground truth alone (no skeleton file).

    For sources without a skeleton (HumanEva mocap): limb lengths are the mean joint distances; the
    branching offsets are averaged in per-frame body frames (pelvis: y from the right to the left
    hip, z towards the thorax; thorax: y from the right to the left shoulder, z up the spine).
    Frames with non-finite joints are ignored; ``measurements`` (optional) size the cones.
    ``robust``: medians over frames instead of means, for joints triangulated from a detector's
    keypoints, whose misdetections are outliers; ``source`` names the joints in the subject's record.
    """
    from swarmpose.joints import JOINT_INDEX as J

    g = np.asarray(joints15, dtype=np.float64)
    g = g[np.isfinite(g).all(axis=(1, 2))]
    if len(g) == 0:
        raise ValueError("no frame with finite ground-truth joints to measure a subject from")
    pel, tho = g[:, J["pelvis"]], g[:, J["thorax"]]
    Rp = _frames(g[:, J["l_hip"]], g[:, J["r_hip"]], tho - pel)
    Rt = _frames(g[:, J["l_shoulder"]], g[:, J["r_shoulder"]], tho - pel)

    stat = np.median if robust else np.mean

    def local(R: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
        return tuple(float(c) for c in stat(np.einsum("tji,tj->ti", R, v), axis=0))  # type: ignore[return-value]

    def length(a: str, b: str) -> float:
        return float(stat(np.linalg.norm(g[:, J[b]] - g[:, J[a]], axis=-1)))

    offsets: dict[str, tuple[float, float, float]] = {
        "spine_to_thorax": local(Rp, tho - pel),
        "neck_to_head_top": local(Rt, g[:, J["head_top"]] - tho),
    }
    for side in ("l", "r"):
        offsets[f"{side}_pelvis_to_hip"] = local(Rp, g[:, J[f"{side}_hip"]] - pel)
        offsets[f"{side}_thorax_to_shoulder"] = local(Rt, g[:, J[f"{side}_shoulder"]] - tho)
        offsets[f"{side}_thigh"] = (0.0, 0.0, -length(f"{side}_hip", f"{side}_knee"))
        offsets[f"{side}_shank"] = (0.0, 0.0, -length(f"{side}_knee", f"{side}_ankle"))
        offsets[f"{side}_upper_arm"] = (0.0, 0.0, -length(f"{side}_shoulder", f"{side}_elbow"))
        offsets[f"{side}_forearm"] = (0.0, 0.0, -length(f"{side}_elbow", f"{side}_wrist"))
    ref = spec.default_subject.offsets
    ratio = -(offsets["l_thigh"][2] + offsets["l_shank"][2]) / -(ref["l_thigh"][2] + ref["l_shank"][2])
    cones, note = _cones(spec, ratio, measurements)
    offsets["pelvis_to_torso_top"] = _torso_top(offsets, cones)
    offsets = {k: v for k, v in offsets.items() if k in spec.default_subject.offsets}
    return Subject(name=name, offsets=offsets, cones=cones, source=f"{source} ({len(g)} frames); {note}")
