"""Per-limb confidence: the calibrated curve, the loss measure, and the evidence on known geometry."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.joints import JOINT_INDEX as J
from swarmpose.track.confidence import LIMB_JOINTS, LOST_MM, limb_confidence, limb_disagreement, limb_lost


def test_confidence_falls_with_the_disagreement_and_keeps_nan():
    d = np.array([0.0, 1e-4, 1e-3, 1e-2, 0.1, 1.0, np.nan])
    c = limb_confidence(d)
    assert np.all(np.diff(c[:-1]) < 0) and np.isnan(c[-1])
    assert c[0] > 0.97 and 0.5 < c[2] < 0.7 and c[3] < 0.1 and c[5] < 0.01  # the fitted curve's points
    assert limb_confidence(d.reshape(7, 1)).shape == (7, 1)


def test_a_limb_is_lost_when_its_distal_joints_are_far():
    truth = np.zeros((3, 15, 3))
    est = truth.copy()
    est[1, J["l_wrist"]] = [0, 0, 2 * LOST_MM + 10]  # mean of elbow and wrist: just over the limit
    est[2, J["r_knee"]] = [0, 0, 2 * LOST_MM - 10]  # just under
    truth[0, J["l_ankle"]] = np.nan  # no truth: not lost
    lost = limb_lost(est, truth)
    assert lost.shape == (3, len(LIMB_JOINTS))
    assert lost.tolist() == [[False] * 4, [True, False, False, False], [False] * 4]


def test_the_evidence_sees_an_arm_outside_the_silhouettes():
    from swarmpose.body.model import load_model
    from swarmpose.fitness import make_fitness
    from swarmpose.fitness.scene import demo_cameras, demo_frame

    model = load_model("balan31")
    pose = model.zero_pose()
    pose[model.param_index("pelvis_tz")] = 1000.0
    frame = demo_frame(model, pose, demo_cameras(width=322, height=242), clutter=0, inflate=1.0, noise=0)
    fit = make_fitness("silhouette_edge", model).bind(frame)
    at_truth = limb_disagreement(fit, model, pose)
    assert set(at_truth) == set(LIMB_JOINTS) and max(at_truth.values()) < 1e-3
    assert min(limb_confidence(np.array(list(at_truth.values())))) > 0.6
    moved = pose.copy()
    moved[model.param_index("r_shoulder_abd")] += 1.5  # the right arm raised sideways, out of every silhouette
    off = limb_disagreement(fit, model, moved)
    assert off["right_arm"] > 0.01 and limb_confidence(np.array(off["right_arm"])) < 0.1
    assert off["left_arm"] == pytest.approx(at_truth["left_arm"], abs=1e-9)
    assert off["left_leg"] == pytest.approx(at_truth["left_leg"], abs=1e-9)


def test_the_keypoint_evidence_on_known_geometry():
    """Exact detections give 0; a view left with left and right swapped changes nothing; a wrist moved across
    the cameras' view shows in its arm alone, at about half the move (the mean of elbow and wrist); a limb no
    view detected is NaN."""
    from swarmpose.body.model import load_model
    from swarmpose.fitness.scene import demo_cameras
    from swarmpose.joints import SWAP15
    from swarmpose.track.confidence import keypoint_disagreement
    from swarmpose.triangulation import reproject

    model = load_model("balan31")
    pose = model.zero_pose()
    pose[model.param_index("pelvis_tz")] = 1000.0
    cams = demo_cameras(width=644, height=484)
    joints = model.joints15(np.stack([pose, pose]))  # (2, 15, 3)
    kp = reproject(cams, joints)  # (2, C, 15, 2)
    np.testing.assert_allclose(keypoint_disagreement(cams, kp, joints), 0.0, atol=1e-9)
    swapped = kp.copy()
    swapped[:, 1] = kp[:, 1][:, list(SWAP15)]
    np.testing.assert_allclose(keypoint_disagreement(cams, swapped, joints), 0.0, atol=1e-9)
    moved = joints.copy()
    moved[1, J["r_wrist"], 2] += 200.0  # straight up: across every camera's view
    k = keypoint_disagreement(cams, kp, moved)
    arm = list(LIMB_JOINTS).index("right_arm")
    assert np.allclose(np.delete(k[1], arm), 0.0, atol=1e-9) and 80.0 < k[1, arm] < 110.0, k[1]
    blind = kp.copy()
    blind[0, :, J["l_knee"]] = np.nan
    k = keypoint_disagreement(cams, blind, joints)
    leg = list(LIMB_JOINTS).index("left_leg")
    assert np.isnan(k[0, leg]) and np.isfinite(np.delete(k[0], leg)).all() and np.isfinite(k[1]).all()


def test_the_keypoints_lower_the_confidence_of_a_limb_far_from_them():
    d = np.full(5, 1e-4)
    k = np.array([0.0, 20.0, 60.0, 200.0, np.nan])
    c = limb_confidence(d, k)
    assert np.all(np.diff(c[:-1]) < 0) and c[0] > 0.99 and c[2] > 0.9 and c[3] < 0.5
    assert c[-1] == limb_confidence(d[-1:])[0]  # no keypoint there: the silhouettes' model alone
