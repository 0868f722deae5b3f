"""The 15-joint ground truth from Plug-in-Gait virtual markers (the support code's cur_frame rule)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from he_fixtures import (
    LOST,
    MP,
    TORSO_RADIUS,
    expected_joints15,
    labels,
    mocap_array,
    rot_z,
    static_markers,
)

from swarmpose.datasets.humaneva import (
    BODY_POSE20,
    HEAD_LENGTH_MM,
    MocapMarkers,
    humaneva_ground_truth,
    joints15_from_points20,
    limb_lengths,
    limb_parameters,
)
from swarmpose.errors import ConfigError, FormatError


@pytest.fixture(scope="module")
def mocap() -> MocapMarkers:
    return MocapMarkers(tuple(labels()), mocap_array())


def _gt(mocap: MocapMarkers, positions):
    return humaneva_ground_truth(mocap, np.asarray(positions, float), torso_radius=TORSO_RADIUS,
                                 l_shoulder_offset=MP["LShoulderOffset"], r_shoulder_offset=MP["RShoulderOffset"])


def test_joints_match_the_support_code_rules(mocap):
    pos = np.array([1.0, 2.0, 7.0, 30.5, 44.25, 60.0])
    gt = _gt(mocap, pos)
    assert gt.valid.all()
    expected = np.stack([expected_joints15(p) for p in pos])  # translation is linear: exact at fractional p
    np.testing.assert_allclose(gt.joints15, expected, atol=1e-9)
    head_top = gt.points20[:, BODY_POSE20.index("headDistal")]
    head_base = gt.points20[:, BODY_POSE20.index("headProximal")]
    np.testing.assert_allclose(np.linalg.norm(head_top - head_base, axis=1), HEAD_LENGTH_MM)


def test_lost_marker_invalidates_bracketing_frames(mocap):
    name, frame = LOST
    gt = _gt(mocap, [frame - 1.0, frame - 0.5, float(frame), frame + 0.5, frame + 1.0])
    assert gt.valid.tolist() == [True, False, False, False, True]
    assert np.isnan(gt.joints15[1:4]).all() and np.isfinite(gt.joints15[[0, 4]]).all()


def test_lost_virtual_marker_invalidates_instead_of_identity(mocap):
    m = mocap.markers.copy()
    m[9, labels().index("LTIA")] = 0.0  # x-axis point of the left shank frame, mocap frame 10
    gt = _gt(MocapMarkers(mocap.labels, m), [9.0, 9.5, 10.0, 11.0])
    assert gt.valid.tolist() == [True, False, False, True]


def test_non_orthogonal_axes_invalidate(mocap):
    m = mocap.markers.copy()
    i = labels().index("PELO")
    m[4, i + 2] = m[4, i] + 100.0 * (rot_z(0.3) @ np.array([1.0, 0, 0.2]))  # tilted x axis
    gt = _gt(MocapMarkers(mocap.labels, m), [5.0, 6.0])
    assert gt.valid.tolist() == [False, True]


def test_slerp_between_mocap_frames():
    """Halfway between two frames whose body yaw differs by 40 degrees, the pelvis frame has turned by 20."""
    base = mocap_array(2)
    labs = labels()
    turned = base.copy()
    centre = base[1, labs.index("PELO")]
    turned[1] = (rot_z(math.radians(40)) @ (base[1] - centre).T).T + centre
    gt = _gt(MocapMarkers(tuple(labs), turned), [1.0, 1.5, 2.0])
    axis = gt.points20[:, BODY_POSE20.index("headDistal")] - gt.points20[:, BODY_POSE20.index("headProximal")]
    assert np.allclose(axis[:, 2], HEAD_LENGTH_MM)  # the head axis stays vertical under yaw
    assert gt.valid.all()
    # the pelvis-shift direction (local -x) turns by 20 degrees at the half position
    d = []
    for k, p in enumerate((1.0, 1.5, 2.0)):
        f = int(math.floor(p)) - 1
        a = p - math.floor(p)
        o = (1 - a) * turned[f, labs.index("PELO")] + a * turned[min(f + 1, 1), labs.index("PELO")]
        v = gt.points20[k, BODY_POSE20.index("torsoDistal")] - o
        d.append(math.degrees(math.atan2(v[1], v[0])))
    assert (d[1] - d[0]) == pytest.approx(20.0, abs=1e-6) and (d[2] - d[0]) == pytest.approx(40.0, abs=1e-6)


def test_missing_labels_and_range(mocap):
    short = MocapMarkers(tuple(lab if lab != "LFIN" else "XXXX" for lab in mocap.labels), mocap.markers)
    with pytest.raises(FormatError, match="LFIN"):
        _gt(short, [2.0])
    alt = MocapMarkers(tuple(lab if lab != "RFRM" else "RFRA" for lab in mocap.labels), mocap.markers)
    assert _gt(alt, [2.0]).valid.all()  # RFRM or RFRA
    with pytest.raises(ConfigError, match="positions"):
        _gt(mocap, [0.5])
    with pytest.raises(ConfigError):
        _gt(mocap, [61.0])


def test_midpoints_of_double_joints():
    rng = np.random.default_rng(0)
    p20 = rng.normal(size=(4, 20, 3))
    j = joints15_from_points20(p20)
    i = {n: k for k, n in enumerate(BODY_POSE20)}
    np.testing.assert_allclose(j[:, 0], (p20[:, i["torsoProximal"]] + p20[:, i["headProximal"]]) / 2)
    np.testing.assert_allclose(j[:, 3], (p20[:, i["upperLArmDistal"]] + p20[:, i["lowerLArmProximal"]]) / 2)
    np.testing.assert_allclose(j[:, 14], p20[:, i["headDistal"]])


def test_limb_lengths_and_parameters(mocap):
    L = limb_lengths(mocap)
    np.testing.assert_allclose(L[[0, 2, 3, 10, 11, 17]], [500, 450, 420, 300, 250, HEAD_LENGTH_MM])
    assert L[4] == 0 and L[8] == 0
    static = MocapMarkers(mocap.labels, static_markers())
    P = limb_parameters(static, MP)
    assert P[0, 0] == pytest.approx(TORSO_RADIUS)
    assert P[5, 0] == MP["LShoulderOffset"] and P[7, 0] == MP["RShoulderOffset"]
    assert P[1, 1] == MP["LKneeWidth"] / 2 and P[9, 4] == pytest.approx(math.radians(MP["HeadOffset"]))
