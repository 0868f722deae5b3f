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
