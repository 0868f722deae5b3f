"""Write the shipped body-model specs (src/swarmpose/models/*.json).

The specs are data; this script is how they were written, so that the layout of both models is
reviewed in one place. Limits are anatomical ranges (deg) as collected in
shared/reference/humaneva-facts.md §7.4; sigma values are placeholders overwritten by
scripts/derive_priors.py (max inter-frame change at 60 fps over the walking clips, thesis l.861).
Run:  .venv/bin/python scripts/make_model_specs.py
"""

from __future__ import annotations

import json
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "src" / "swarmpose" / "models"


def P(name, group, lower, upper, sigma, description, kind="rotation", tags=()):
    d = {"name": name, "kind": kind, "group": group, "lower": lower, "upper": upper, "sigma": sigma,
         "description": description}
    if kind == "rotation":
        d["unit"] = "deg"
    if tags:
        d["tags"] = list(tags)
    return d


def side_params(side, extra=False):
    """Leg and arm parameters of one side; positive angles mean the same motion on both sides."""
    L = side == "l"
    word = "left" if L else "right"
    legs = [
        P(f"{side}_hip_abd", f"{word}_leg", -30, 45, 4.0, f"{word} hip ab(+)/adduction (about x)"),
        P(f"{side}_hip_flex", f"{word}_leg", -30, 125, 5.0, f"{word} hip flexion(+)/extension"),
        P(f"{side}_hip_rot", f"{word}_leg", -45, 45, 5.0, f"{word} hip internal(+)/external rotation"),
        P(f"{side}_knee_flex", f"{word}_leg", -5, 140, 5.3, f"{word} knee flexion"),
    ]
    if extra:
        legs += [
            P(f"{side}_ankle_flex", f"{word}_leg", -50, 30, 5.0, f"{word} ankle dorsiflexion(+)/plantarflexion"),
            P(f"{side}_ankle_inv", f"{word}_leg", -30, 30, 5.0, f"{word} ankle inversion(+)/eversion"),
        ]
    arms = [
        P(f"{side}_clav_elev", f"{word}_arm", -20, 45, 2.0, f"{word} clavicle elevation(+)/depression"),
        P(f"{side}_clav_prot", f"{word}_arm", -25, 25, 2.0, f"{word} clavicle protraction(+)/retraction"),
        P(f"{side}_shoulder_abd", f"{word}_arm", -45, 180, 5.0, f"{word} shoulder ab(+)/adduction"),
        P(f"{side}_shoulder_flex", f"{word}_arm", -60, 180, 5.0, f"{word} shoulder flexion(+)/extension"),
        P(f"{side}_shoulder_rot", f"{word}_arm", -90, 90, 5.0, f"{word} shoulder internal(+)/external rotation (twist about the upper arm, last)"),
        P(f"{side}_elbow_flex", f"{word}_arm", -5, 150, 5.0, f"{word} elbow flexion"),
    ]
    if extra:
        arms += [
            P(f"{side}_forearm_rot", f"{word}_arm", -90, 90, 5.0, f"{word} forearm pronation(+)/supination"),
            P(f"{side}_wrist_flex", f"{word}_arm", -80, 80, 5.0, f"{word} wrist flexion(+)/extension"),
            P(f"{side}_wrist_dev", f"{word}_arm", -30, 30, 5.0, f"{word} wrist radial(+)/ulnar deviation"),
        ]
    return legs, arms


def axis(a, L):
    """Axis for side L (left) or mirrored for the right side, so one sign means one motion."""
    if L:
        return a
    return a[1:] if a.startswith("-") else "-" + a


def leg_joints(side, extra=False):
    L = side == "l"
    j = [
        {"name": f"{side}_hip", "parent": "pelvis", "offset": f"{side}_pelvis_to_hip",
         "rotation": [[axis("x", L), f"{side}_hip_abd"], ["-y", f"{side}_hip_flex"], [axis("-z", L), f"{side}_hip_rot"]]},
        {"name": f"{side}_knee", "parent": f"{side}_hip", "offset": f"{side}_thigh",
         "rotation": [["y", f"{side}_knee_flex"]]},
    ]
    if extra:
        j.append({"name": f"{side}_ankle", "parent": f"{side}_knee", "offset": f"{side}_shank",
                  "rotation": [["-y", f"{side}_ankle_flex"], [axis("-x", L), f"{side}_ankle_inv"]]})
        j.append({"name": f"{side}_toe", "parent": f"{side}_ankle", "offset": f"{side}_foot"})
    else:
        j.append({"name": f"{side}_ankle", "parent": f"{side}_knee", "offset": f"{side}_shank"})
    return j


def arm_joints(side, extra=False):
    L = side == "l"
    j = [
        {"name": f"{side}_clavicle", "parent": "thorax", "offset": None,
         "rotation": [[axis("x", L), f"{side}_clav_elev"], [axis("-z", L), f"{side}_clav_prot"]]},
        {"name": f"{side}_shoulder", "parent": f"{side}_clavicle", "offset": f"{side}_thorax_to_shoulder",
         "rotation": [[axis("x", L), f"{side}_shoulder_abd"], ["-y", f"{side}_shoulder_flex"],
                      [axis("-z", L), f"{side}_shoulder_rot"]]},
        {"name": f"{side}_elbow", "parent": f"{side}_shoulder", "offset": f"{side}_upper_arm",
         "rotation": [["-y", f"{side}_elbow_flex"]] + ([[axis("-z", L), f"{side}_forearm_rot"]] if extra else [])},
    ]
    if extra:
        j.append({"name": f"{side}_wrist", "parent": f"{side}_elbow", "offset": f"{side}_forearm",
                  "rotation": [["-y", f"{side}_wrist_flex"], [axis("x", L), f"{side}_wrist_dev"]]})
        j.append({"name": f"{side}_hand_tip", "parent": f"{side}_wrist", "offset": f"{side}_hand"})
    else:
        j.append({"name": f"{side}_wrist", "parent": f"{side}_elbow", "offset": f"{side}_forearm"})
    return j


ROOT_PARAMS = [
    P("pelvis_rx", "root_orientation", -45, 45, 2.0, "pelvis roll about the forward axis (x1)"),
    P("pelvis_ry", "root_orientation", -45, 45, 2.0, "pelvis pitch about the left axis (x2)"),
    P("pelvis_rz", "root_orientation", None, None, 3.0, "heading about the vertical axis (x3), unbounded"),
    P("pelvis_tx", "root_position", None, None, 13.7, "pelvis position x, mm (x4)", kind="translation"),
    P("pelvis_ty", "root_position", None, None, 13.7, "pelvis position y, mm (x5)", kind="translation"),
    P("pelvis_tz", "root_position", 300, 1700, 8.0, "pelvis height, mm (x6)", kind="translation"),
]
ROOT_JOINT = {"name": "pelvis", "parent": None, "offset": None,
              "rotation": [["z", "pelvis_rz"], ["x", "pelvis_rx"], ["y", "pelvis_ry"]],
              "translation": ["pelvis_tx", "pelvis_ty", "pelvis_tz"]}

JOINTS15 = ["thorax", "pelvis", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist",
            "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle", "head_top"]

# A reference adult of about 1.75 m (mm). Real subjects come from swarmpose.body.subject.
OFFSETS = {
    "l_pelvis_to_hip": [40, 90, -100], "r_pelvis_to_hip": [40, -90, -100],
    "l_thigh": [0, 0, -410], "r_thigh": [0, 0, -410],
    "l_shank": [0, 0, -420], "r_shank": [0, 0, -420],
    "spine_to_thorax": [-20, 0, 430],
    # torso cone axis: pelvis to the top of the shoulders (HumanEva's torso runs to the thorax origin at
    # the top of the sternum; see swarmpose.body.subject for how a subject's value is measured)
    "pelvis_to_torso_top": [-20, 0, 480],
    "l_thorax_to_shoulder": [-30, 180, 30], "r_thorax_to_shoulder": [-30, -180, 30],
    "l_upper_arm": [0, 0, -290], "r_upper_arm": [0, 0, -290],
    "l_forearm": [0, 0, -250], "r_forearm": [0, 0, -250],
    "neck_to_head_top": [0, 0, 280],
}
CONES = {  # r_start, r_end, scale_x (depth), scale_y (width)
    "torso": [150, 165, 0.6, 1.0],
    "l_thigh": [85, 55, 1, 1], "r_thigh": [85, 55, 1, 1],
    "l_calf": [55, 40, 1, 1], "r_calf": [55, 40, 1, 1],
    "l_upper_arm": [45, 38, 1, 1], "r_upper_arm": [45, 38, 1, 1],
    "l_lower_arm": [38, 28, 1, 1], "r_lower_arm": [38, 28, 1, 1],
    "head": [95, 95, 1.0, 0.8],
}
CONE_LIST = [  # thesis Table 5.2 order
    {"name": "torso", "joint": "pelvis", "axis": "pelvis_to_torso_top", "side": "center"},
    {"name": "l_thigh", "joint": "l_hip", "axis": "l_thigh", "side": "left"},
    {"name": "l_calf", "joint": "l_knee", "axis": "l_shank", "side": "left"},
    {"name": "r_thigh", "joint": "r_hip", "axis": "r_thigh", "side": "right"},
    {"name": "r_calf", "joint": "r_knee", "axis": "r_shank", "side": "right"},
    {"name": "l_upper_arm", "joint": "l_shoulder", "axis": "l_upper_arm", "side": "left"},
    {"name": "l_lower_arm", "joint": "l_elbow", "axis": "l_forearm", "side": "left"},
    {"name": "r_upper_arm", "joint": "r_shoulder", "axis": "r_upper_arm", "side": "right"},
    {"name": "r_lower_arm", "joint": "r_elbow", "axis": "r_forearm", "side": "right"},
    {"name": "head", "joint": "neck", "axis": "neck_to_head_top", "side": "center"},
]
THESIS_VARIANT = {  # thesis sec. 5.1.2, the four modifications of Balan's cones
    "l_calf": {"length": 1.2}, "r_calf": {"length": 1.2},
    "l_lower_arm": {"length": 1.2}, "r_lower_arm": {"length": 1.2},
    "head": {"length": 0.6, "start_shift": 0.3},
    # not the thesis's torso x1.05: the torso axis already reaches the top of the shoulders (commit 107e751;
    # docs/body-models.md)
    "l_thigh": {"thickness": 1.2}, "r_thigh": {"thickness": 1.2},
}
COLLISIONS = [["torso", "l_lower_arm"], ["torso", "r_lower_arm"], ["l_thigh", "r_thigh"], ["l_calf", "r_calf"],
              ["l_thigh", "r_calf"], ["r_thigh", "l_calf"]]  # (volume A, sphere chain B)

# The shoulders' second branch of angles: abduction and flexion both past 90 deg turn the upper arm down again with a
# twist that the rotation's limits (+-90 deg) leave out elsewhere; no IK-fitted pose of the eight shared clips goes
# there, the tracker's arms did (the turn's right arm on 424 of 783 frames over 9 runs: docs/results.md).
COUPLED = [{"parameters": [f"{s}_shoulder_abd", f"{s}_shoulder_flex"], "above": [90, 90],
            "description": "abduction and flexion both past 90 deg turn the upper arm down again, twisted beyond the "
                           "shoulder rotation's limits (the angles' second branch); no IK-fitted pose of the eight "
                           "shared clips goes there"} for s in ("l", "r")]


def balan31():
    legs_l, arms_l = side_params("l")
    legs_r, arms_r = side_params("r")
    params = (ROOT_PARAMS + legs_l + legs_r + arms_l + arms_r + [
        P("spine_flex", "spine", -30, 75, 2.0, "trunk flexion(+)/extension about the pelvis (x27)"),
        P("spine_twist", "spine", -40, 40, 2.0, "trunk axial twist (x28)"),
        P("neck_lat", "head", -45, 45, 3.0, "head lateral bend, + to the right (x29)"),
        P("neck_flex", "head", -45, 45, 3.0, "head flexion(+)/extension (x30)"),
        P("neck_twist", "head", -70, 70, 3.0, "head twist about its axis (x31; fixed in SPPSO)", tags=["head_twist"]),
    ])
    joints = ([ROOT_JOINT] + leg_joints("l") + leg_joints("r") + [
        {"name": "spine", "parent": "pelvis", "offset": None,
         "rotation": [["y", "spine_flex"], ["z", "spine_twist"]]},
        {"name": "thorax", "parent": "spine", "offset": "spine_to_thorax"},
    ] + arm_joints("l") + arm_joints("r") + [
        {"name": "neck", "parent": "thorax", "offset": None,
         "rotation": [["x", "neck_lat"], ["y", "neck_flex"], ["z", "neck_twist"]]},
        {"name": "head_top", "parent": "neck", "offset": "neck_to_head_top"},
    ])
    return {
        "format": "swarmpose-body", "version": 1, "name": "balan31",
        "description": ("Balan et al. (2005) 31-parameter kinematic tree with 10 truncated cones as used by "
                        "Fleischmann (2012), thesis Tables 5.1/5.2 and sec. 5.1; parameter layout x1..x31 "
                        "as thesis Table 5.1 (cross-checked with PARSEC bodytrack)."),
        "references": ["Fleischmann 2012, sec. 5.1, Tables 5.1, 5.2", "Balan, Sigal, Black 2005 (VS-PETS)",
                       "shared/reference/humaneva-facts.md §7"],
        "parameters": params, "joints": joints, "cones": CONE_LIST, "joints15": JOINTS15,
        "default_subject": {"name": "reference-1.75m", "source": "generic adult proportions",
                            "offsets": OFFSETS, "cones": CONES},
        "variants": {"thesis": THESIS_VARIANT},
        "collision_pairs": COLLISIONS,
        "coupled_limits": COUPLED,
    }


def full45():
    legs_l, arms_l = side_params("l", extra=True)
    legs_r, arms_r = side_params("r", extra=True)
    params = (ROOT_PARAMS + legs_l + legs_r + arms_l + arms_r + [
        P("spine_lat", "spine", -35, 35, 2.0, "trunk lateral bend"),
        P("spine_flex", "spine", -30, 75, 2.0, "trunk flexion(+)/extension"),
        P("spine_twist", "spine", -40, 40, 2.0, "trunk axial twist"),
        P("neck_lat", "head", -45, 45, 3.0, "lower neck lateral bend"),
        P("neck_flex", "head", -45, 45, 3.0, "lower neck flexion"),
        P("neck_twist", "head", -50, 50, 3.0, "lower neck twist"),
        P("head_lat", "head", -30, 30, 3.0, "head lateral bend on the upper neck"),
        P("head_flex", "head", -40, 40, 3.0, "head flexion on the upper neck"),
        P("head_twist", "head", -50, 50, 3.0, "head twist on the upper neck", tags=["head_twist"]),
    ])
    joints = ([ROOT_JOINT] + leg_joints("l", True) + leg_joints("r", True) + [
        {"name": "spine", "parent": "pelvis", "offset": None,
         "rotation": [["x", "spine_lat"], ["y", "spine_flex"], ["z", "spine_twist"]]},
        {"name": "thorax", "parent": "spine", "offset": "spine_to_thorax"},
    ] + arm_joints("l", True) + arm_joints("r", True) + [
        {"name": "neck", "parent": "thorax", "offset": None,
         "rotation": [["x", "neck_lat"], ["y", "neck_flex"], ["z", "neck_twist"]]},
        {"name": "head", "parent": "neck", "offset": "neck_to_head",
         "rotation": [["x", "head_lat"], ["y", "head_flex"], ["z", "head_twist"]]},
        {"name": "head_top", "parent": "head", "offset": "head_to_top"},
    ])
    cones = [dict(c) for c in CONE_LIST]
    cones[-1] = {"name": "head", "joint": "head", "axis": "head_to_top", "start_frac": -0.3, "side": "center"}
    offsets = dict(OFFSETS)
    del offsets["neck_to_head_top"]
    offsets.update({"neck_to_head": [0, 0, 100], "head_to_top": [0, 0, 180]})
    offsets.update({"l_foot": [140, 0, -60], "r_foot": [140, 0, -60],
                    "l_hand": [0, 0, -90], "r_hand": [0, 0, -90]})
    return {
        "format": "swarmpose-body", "version": 1, "name": "full45",
        "description": ("A fuller 45-parameter model for marker tracking (Sharifi et al. 2017, sec. 3.1: "
                        "root 6 + joint angles, 45 in all): balan31 plus trunk lateral bend, ankles (2+2), "
                        "forearm rotation (1+1), wrists (2+2) and a 3-DoF head on a 3-DoF neck, with hand-tip and toe "
                        "markers."),
        "references": ["Sharifi, Harati, Vahedian 2017, sec. 3.1"],
        "parameters": params, "joints": joints, "cones": cones, "joints15": JOINTS15,
        "default_subject": {"name": "reference-1.75m", "source": "generic adult proportions",
                            "offsets": offsets, "cones": CONES},
        "variants": {"thesis": {k: v for k, v in THESIS_VARIANT.items() if k != "head"}},
        "collision_pairs": COLLISIONS,
        "coupled_limits": COUPLED,
        "extra_markers": [["l_hand_tip", "l_hand_tip", ""], ["r_hand_tip", "r_hand_tip", ""],
                          ["l_toe", "l_toe", ""], ["r_toe", "r_toe", ""]],
    }


def with_derived_sigmas(spec, path):
    """``spec`` with the sigmas that scripts/derive_priors.py wrote into the existing file at ``path``."""
    if path.exists():
        old = {p["name"]: p for p in json.loads(path.read_text())["parameters"]}
        for p in spec["parameters"]:
            if p["name"] in old and "sigma_source" in old[p["name"]]:
                p["sigma"] = old[p["name"]]["sigma"]
                p["sigma_source"] = old[p["name"]]["sigma_source"]
    return spec


def write(spec, keep_sigma=True):
    path = OUT / f"{spec['name']}.json"
    if keep_sigma:
        spec = with_derived_sigmas(spec, path)
    path.write_text(json.dumps(spec, indent=1) + "\n")
    print(f"wrote {path} ({len(spec['parameters'])} parameters)")


if __name__ == "__main__":
    write(balan31())
    write(full45())
