"""A subject from stature alone: joint heights and widths as fractions of the height ``H``.

Segment proportions of Drillis & Contini (1966) as tabulated by Winter (2009), *Biomechanics and Motor
Control of Human Movement*, 4th ed., Fig. 4.1 (heights above the floor, standing):

==========================  ========  =====================================================
landmark                    fraction  used for
==========================  ========  =====================================================
top of the head             1.000     ``head_top``
shoulder (acromion)         0.818     shoulders; the thorax (base of the neck) between them
elbow                       0.630     elbows (upper arm 0.188 H; Winter's segment: 0.186 H)
wrist                       0.485     wrists (forearm 0.145 H; Winter: 0.146 H)
hip (greater trochanter)    0.530     hip joints; the pelvis between them
knee                        0.285     knees (thigh 0.245 H; Winter: 0.245 H)
ankle                       0.039     ankles (leg 0.246 H; Winter: 0.246 H)
shoulder width              0.259     the shoulder joints, ``0.259 H - 2 x 0.022 H`` apart
                                      (the joint centres lie inside the acromions)
hip width                   0.191     the hip joints, ``0.191 H / 2`` apart (their centres lie
                                      halfway in from the trochanters)
==========================  ========  =====================================================

The thorax of the 15-joint skeleton is the base of the neck (:func:`swarmpose.io.mocap.cmu_skeleton_map`):
here at shoulder height, midway between the shoulders. These are population means; a real person's
proportions differ from them by several per cent (docs/accuracy.md measures it on the shared subjects).
The subject is built by :func:`swarmpose.body.subject.subject_from_joints` from the standing pose, so the
cones are sized as for any subject without measurements.
"""

from __future__ import annotations

import numpy as np

from swarmpose.body.measurements import SubjectMeasurements
from swarmpose.body.spec import BodySpec, Subject
from swarmpose.body.subject import subject_from_joints
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINT_INDEX

__all__ = ["HEIGHT_FRACTIONS", "WIDTH_FRACTIONS", "UPPER_ARM_FRACTION", "standing_joints15", "subject_from_height",
           "split_arms", "limb_lengths"]

#: Heights above the floor as fractions of stature (Winter 2009, Fig. 4.1).
HEIGHT_FRACTIONS = {"head_top": 1.000, "shoulder": 0.818, "elbow": 0.630, "wrist": 0.485, "hip": 0.530,
                    "knee": 0.285, "ankle": 0.039}
#: Widths as fractions of stature (Winter 2009, Fig. 4.1) and the joint-centre insets used here.
WIDTH_FRACTIONS = {"shoulder": 0.259, "hip": 0.191, "shoulder_inset": 0.022}

#: The upper arm's share of the arm from shoulder to wrist (Winter 2009, Fig. 4.1: 0.188 H of 0.333 H).
UPPER_ARM_FRACTION = ((HEIGHT_FRACTIONS["shoulder"] - HEIGHT_FRACTIONS["elbow"])
                      / (HEIGHT_FRACTIONS["shoulder"] - HEIGHT_FRACTIONS["wrist"]))

#: Statures accepted, mm (a check against a value in metres or centimetres).
HEIGHT_RANGE_MM = (800.0, 2500.0)


def standing_joints15(height_mm: float) -> np.ndarray:
    """The 15 joints ``(15, 3)`` of a person of this stature standing upright, arms hanging, facing +x
    (the body model's frame: x forward, y left, z up), feet on the floor ``z = 0``.

    Raises
    ------
    ConfigError
        A height outside 800-2500 mm.
    """
    h = float(height_mm)
    lo, hi = HEIGHT_RANGE_MM
    if not lo <= h <= hi:
        raise ConfigError(f"height must be a stature in millimetres ({lo:.0f}-{hi:.0f}), got {height_mm!r}")
    f, w = HEIGHT_FRACTIONS, WIDTH_FRACTIONS
    shoulder_y = 0.5 * (w["shoulder"] - 2 * w["shoulder_inset"]) * h
    hip_y = 0.25 * w["hip"] * h
    j = np.zeros((15, 3))

    def put(name: str, y: float, z: float) -> None:
        j[JOINT_INDEX[name]] = (0.0, y, z * h)

    put("head_top", 0.0, f["head_top"])
    put("thorax", 0.0, f["shoulder"])
    put("pelvis", 0.0, f["hip"])
    for side, s in (("l", 1.0), ("r", -1.0)):
        for joint in ("shoulder", "elbow", "wrist"):
            put(f"{side}_{joint}", s * shoulder_y, f[joint])
        for joint in ("hip", "knee", "ankle"):
            put(f"{side}_{joint}", s * hip_y, f[joint])
    return j


def subject_from_height(spec: BodySpec, height_mm: float, *, name: str | None = None,
                        measurements: SubjectMeasurements | None = None) -> Subject:
    """A subject of the body model ``spec`` for a person of stature ``height_mm`` (mm), by Winter's ratios."""
    subject = subject_from_joints(spec, standing_joints15(height_mm)[None],
                                  name=name or f"stature-{float(height_mm):.0f}mm", measurements=measurements)
    note = subject.source.split("; ", 1)[-1]
    return Subject(name=subject.name, offsets=subject.offsets, cones=subject.cones,
                   source=f"stature {float(height_mm):.0f} mm, Winter (2009) Fig. 4.1 proportions; {note}")


def split_arms(subject: Subject, fraction: float = UPPER_ARM_FRACTION) -> Subject:
    """``subject`` with each arm's length from shoulder to wrist kept and split at ``fraction`` (the upper arm's
    share; by default Winter's proportion, 0.565).

    For a subject measured from a detector's keypoints: the elbow is the arm's least certain point (a learned
    detector places it 30 mm towards the shoulder on the shared synthetic clips, splitting the arm at 0.51-0.53
    of its length against the skeletons' 0.58; it splits the shared real recording's arms at 0.52 too), while
    the shoulder-to-wrist length agrees with the skeletons' to 2-3 %. A population proportion varies by a few
    per cent between people, less than that bias.
    """
    if not 0.0 < fraction < 1.0:
        raise ConfigError(f"the upper arm's share of the arm must lie in (0, 1), not {fraction}")
    offsets = dict(subject.offsets)
    for side in ("l", "r"):
        upper, fore = np.asarray(offsets[f"{side}_upper_arm"], float), np.asarray(offsets[f"{side}_forearm"], float)
        total = float(np.linalg.norm(upper) + np.linalg.norm(fore))
        offsets[f"{side}_upper_arm"] = tuple(float(v) for v in upper / np.linalg.norm(upper) * fraction * total)
        offsets[f"{side}_forearm"] = tuple(float(v) for v in fore / np.linalg.norm(fore) * (1.0 - fraction) * total)
    return Subject(name=subject.name, offsets=offsets, cones=subject.cones,
                   source=f"{subject.source}; each arm split at {fraction:.3f} of its length (Winter 2009)")


def limb_lengths(subject: Subject) -> dict[str, float]:
    """A ``balan31``-layout subject's left thigh, shank, upper arm and forearm lengths and its hip and shoulder
    widths, mm (what the proportion tables compare)."""
    o = subject.offsets
    out = {name: abs(o[key][2]) for name, key in (("thigh", "l_thigh"), ("shank", "l_shank"),
                                                   ("upper arm", "l_upper_arm"), ("forearm", "l_forearm"))}
    out["hip width"] = abs(o["l_pelvis_to_hip"][1] - o["r_pelvis_to_hip"][1])
    out["shoulder width"] = abs(o["l_thorax_to_shoulder"][1] - o["r_thorax_to_shoulder"][1])
    return out
