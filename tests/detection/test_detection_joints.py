"""The BlazePose-33 to JOINTS15 mapping (swarmpose.detection.joints) on synthetic landmarks."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.detection.joints import (
    BLAZEPOSE33,
    BLAZEPOSE_INDEX,
    CONFIDENCE_SCALE,
    HEAD_TOP_FRACTION,
    JOINT_SOURCES,
    PELVIS_FRACTION,
    SWAP15,
    SWAP33,
    THORAX_FRACTION,
    to_joints15,
)
from swarmpose.errors import ShapeError
from swarmpose.joints import JOINT_INDEX, JOINTS15

J = JOINT_INDEX
B = BLAZEPOSE_INDEX


@pytest.fixture
def landmarks():
    rng = np.random.default_rng(3)
    return rng.uniform(0, 1000, (33, 2)), rng.uniform(0.2, 1.0, 33)


def test_direct_joints_are_their_landmarks(landmarks):
    kp, conf = landmarks
    joints, jc = to_joints15(kp, conf)
    assert joints.shape == (15, 2) and jc.shape == (15,)
    for side, mp_side in (("l", "left"), ("r", "right")):
        for part in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            np.testing.assert_array_equal(joints[J[f"{side}_{part}"]], kp[B[f"{mp_side}_{part}"]])
            assert jc[J[f"{side}_{part}"]] == conf[B[f"{mp_side}_{part}"]]


def test_trunk_joints_along_the_trunk_and_min_confidence(landmarks):
    kp, conf = landmarks
    joints, jc = to_joints15(kp, conf)
    shoulders = (kp[B["left_shoulder"]] + kp[B["right_shoulder"]]) / 2
    hips = (kp[B["left_hip"]] + kp[B["right_hip"]]) / 2
    np.testing.assert_allclose(joints[J["thorax"]], shoulders - THORAX_FRACTION * (shoulders - hips))
    np.testing.assert_allclose(joints[J["pelvis"]], hips + PELVIS_FRACTION * (shoulders - hips))
    assert 0 < THORAX_FRACTION < PELVIS_FRACTION < 0.5  # each stays on its own half of the trunk
    trunk = min(conf[B[f"{s}_{p}"]] for s in ("left", "right") for p in ("shoulder", "hip"))
    assert jc[J["thorax"]] == trunk and jc[J["pelvis"]] == trunk


def test_head_top_above_the_ears_with_lower_confidence():
    kp = np.zeros((33, 2))
    conf = np.ones(33)
    kp[B["left_shoulder"]], kp[B["right_shoulder"]] = (80, 500), (120, 500)   # shoulder midpoint (100, 500)
    kp[B["left_ear"]], kp[B["right_ear"]] = (90, 400), (110, 400)              # ear midpoint (100, 400)
    joints, jc = to_joints15(kp, conf)
    np.testing.assert_allclose(joints[J["head_top"]], (100, 400 - HEAD_TOP_FRACTION * 100))
    assert 0 < HEAD_TOP_FRACTION < 1
    assert jc[J["head_top"]] == pytest.approx(CONFIDENCE_SCALE["head_top"]) and CONFIDENCE_SCALE["head_top"] < 1
    conf[B["right_ear"]] = 0.3
    assert to_joints15(kp, conf)[1][J["head_top"]] == pytest.approx(0.3 * CONFIDENCE_SCALE["head_top"])


def test_table_is_complete_and_weights_sum_to_one():
    assert set(JOINT_SOURCES) == set(JOINTS15)
    for name, parts in JOINT_SOURCES.items():
        assert sum(w for _, w in parts) == pytest.approx(1.0), name
        assert all(landmark in BLAZEPOSE33 for landmark, _ in parts)
        if name.startswith("l_"):
            assert all(landmark.startswith("left_") for landmark, _ in parts)  # the person's left is left
        if name.startswith("r_"):
            assert all(landmark.startswith("right_") for landmark, _ in parts)


def test_absent_landmarks_make_their_joints_absent(landmarks):
    kp, conf = landmarks
    kp, conf = kp.copy(), conf.copy()
    kp[B["left_hip"]] = np.nan
    conf[B["left_hip"]] = 0.0
    joints, jc = to_joints15(kp, conf)
    bad = {J["l_hip"], J["pelvis"], J["thorax"]}  # both trunk joints use the hips
    for j in range(15):
        assert np.isnan(joints[j]).all() == (j in bad), JOINTS15[j]
        assert (jc[j] == 0) == (j in bad), JOINTS15[j]
    assert np.isfinite(jc).all()


def test_vectorised_over_leading_axes():
    rng = np.random.default_rng(0)
    kp = rng.uniform(0, 500, (4, 3, 33, 2))
    conf = rng.uniform(0, 1, (4, 3, 33))
    joints, jc = to_joints15(kp, conf)
    assert joints.shape == (4, 3, 15, 2) and jc.shape == (4, 3, 15)
    one, one_c = to_joints15(kp[2, 1], conf[2, 1])
    np.testing.assert_allclose(joints[2, 1], one)
    np.testing.assert_allclose(jc[2, 1], one_c)


def test_shapes_are_checked():
    with pytest.raises(ShapeError):
        to_joints15(np.zeros((15, 2)), np.zeros(15))
    with pytest.raises(ShapeError):
        to_joints15(np.zeros((33, 2)), np.zeros(32))


@pytest.mark.parametrize(("perm", "names", "left", "right"), [(SWAP15, JOINTS15, "l_", "r_"),
                                                              (SWAP33, BLAZEPOSE33, "left_", "right_")])
def test_swap_is_an_involution_exchanging_left_and_right(perm, names, left, right):
    np.testing.assert_array_equal(perm[perm], np.arange(len(names)))
    assert sorted(perm.tolist()) == list(range(len(names)))
    for i, name in enumerate(names):
        swapped = names[perm[i]]
        if name.startswith(left):
            assert swapped == right + name[len(left):]
        elif name.startswith(right):
            assert swapped == left + name[len(right):]
        else:
            assert swapped == name


def test_swapping_landmarks_then_mapping_equals_mapping_then_swapping(landmarks):
    kp, conf = landmarks
    a, ac = to_joints15(kp[SWAP33], conf[SWAP33])
    b, bc = to_joints15(kp, conf)
    np.testing.assert_allclose(a, b[SWAP15])
    np.testing.assert_allclose(ac, bc[SWAP15])
