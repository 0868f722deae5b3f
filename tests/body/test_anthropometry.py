"""A subject from stature alone (Winter 2009, Fig. 4.1 proportions)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.anthropometry import HEIGHT_FRACTIONS, standing_joints15, subject_from_height
from swarmpose.body.model import BodyModel
from swarmpose.body.spec import Subject, load_spec
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINT_INDEX as J


def test_standing_pose_has_the_published_proportions():
    h = 1800.0
    j = standing_joints15(h)
    f = HEIGHT_FRACTIONS
    assert j[J["head_top"], 2] == pytest.approx(h)
    for side in ("l", "r"):
        assert np.linalg.norm(j[J[f"{side}_shoulder"]] - j[J[f"{side}_elbow"]]) == pytest.approx((f["shoulder"] - f["elbow"]) * h)
        assert np.linalg.norm(j[J[f"{side}_knee"]] - j[J[f"{side}_ankle"]]) == pytest.approx((f["knee"] - f["ankle"]) * h)
    assert j[J["l_hip"], 1] > 0 > j[J["r_hip"], 1]  # left is +y
    np.testing.assert_allclose(j[J["pelvis"]], 0.5 * (j[J["l_hip"]] + j[J["r_hip"]]))


@pytest.mark.parametrize("model", ["balan31", "full45"])
def test_subject_scales_with_height_and_builds_a_model(model):
    spec = load_spec(model)
    short, tall = subject_from_height(spec, 1500), subject_from_height(spec, 1800)
    for key in ("l_thigh", "l_shank", "l_upper_arm", "l_forearm"):
        assert tall.offsets[key][2] / short.offsets[key][2] == pytest.approx(1.2)
    assert "Winter (2009)" in tall.source
    m = BodyModel(spec, tall)
    pose = m.zero_pose()
    pose[m.param_index("pelvis_tz")] = 1000.0
    joints = m.joints15(pose[None])[0]
    # at the zero pose the model stands: the knee-ankle distance is the stature's shank
    assert np.linalg.norm(joints[J["l_knee"]] - joints[J["l_ankle"]]) == pytest.approx(
        (HEIGHT_FRACTIONS["knee"] - HEIGHT_FRACTIONS["ankle"]) * 1800, rel=1e-6)
    assert Subject.from_dict(tall.to_dict()).offsets == tall.offsets


@pytest.mark.parametrize("bad", [1.75, 175.0, 3000.0])
def test_a_height_not_in_millimetres_is_refused(bad):
    with pytest.raises(ConfigError, match="millimetres"):
        standing_joints15(bad)


def test_split_arms_keeps_each_arms_length_and_nothing_else():
    from swarmpose.body.anthropometry import UPPER_ARM_FRACTION, split_arms

    spec = load_spec("balan31")
    base = subject_from_height(spec, 1750)
    offsets = dict(base.offsets)
    offsets["l_upper_arm"], offsets["l_forearm"] = (0.0, 0.0, -240.0), (0.0, 0.0, -280.0)  # elbow 50 mm high
    offsets["r_upper_arm"], offsets["r_forearm"] = (0.0, 0.0, -300.0), (0.0, 0.0, -200.0)
    split = split_arms(Subject(name="kp", offsets=offsets, cones=base.cones, source="keypoints"))
    assert UPPER_ARM_FRACTION == pytest.approx(0.188 / 0.333)
    for side, total in (("l", 520.0), ("r", 500.0)):
        upper, fore = split.offsets[f"{side}_upper_arm"], split.offsets[f"{side}_forearm"]
        assert upper == pytest.approx((0.0, 0.0, -UPPER_ARM_FRACTION * total))
        assert -(upper[2] + fore[2]) == pytest.approx(total)
    assert {k: v for k, v in split.offsets.items() if "arm" not in k} == {
        k: v for k, v in offsets.items() if "arm" not in k}
    assert split.cones == base.cones and "split at 0.565" in split.source
    with pytest.raises(ConfigError, match="upper arm's share"):
        split_arms(base, 1.2)
