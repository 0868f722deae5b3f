"""Forward kinematics: hand-computed poses, batched == one-by-one, numba == numpy reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from swarmpose.body.kinematics import elementary_rotation
from swarmpose.body.model import load_model
from swarmpose.joints import JOINT_INDEX as J


@pytest.fixture(scope="module")
def model():
    return load_model("balan31")


def standing(model, **deg):
    x = model.zero_pose()
    x[model.param_index("pelvis_tz")] = 1000.0
    for name, v in deg.items():
        x[model.param_index(name)] = np.radians(v) if model.is_rotation[model.param_index(name)] else v
    return x


def test_zero_pose_is_the_sum_of_offsets(model):
    off = model.subject.offsets
    j = model.joints15(standing(model))[0]
    pelvis = np.array([0.0, 0.0, 1000.0])
    assert np.allclose(j[J["pelvis"]], pelvis)
    assert np.allclose(j[J["l_hip"]], pelvis + off["l_pelvis_to_hip"])
    assert np.allclose(j[J["l_knee"]], pelvis + off["l_pelvis_to_hip"] + np.array(off["l_thigh"]))
    assert np.allclose(j[J["thorax"]], pelvis + off["spine_to_thorax"])
    assert np.allclose(j[J["r_shoulder"]], pelvis + off["spine_to_thorax"] + np.array(off["r_thorax_to_shoulder"]))
    assert np.allclose(j[J["head_top"]], pelvis + off["spine_to_thorax"] + np.array(off["neck_to_head_top"]))
    # upright: ankles straight below hips, wrists straight below shoulders
    assert np.allclose(j[J["l_ankle"], :2], j[J["l_hip"], :2])
    assert np.allclose(j[J["r_wrist"], :2], j[J["r_shoulder"], :2])


def test_knee_flexion_moves_the_ankle_backwards(model):
    shank = -model.subject.offsets["l_shank"][2]
    j = model.joints15(standing(model, l_knee_flex=90.0))[0]
    # +90 deg flexion about +y: the shank (along -z) turns to point backwards (-x)
    assert np.allclose(j[J["l_ankle"]] - j[J["l_knee"]], [-shank, 0.0, 0.0], atol=1e-9)
    # the other leg did not move
    j0 = model.joints15(standing(model))[0]
    assert np.allclose(j[J["r_ankle"]], j0[J["r_ankle"]])


def test_positive_angles_mean_the_same_motion_on_both_sides(model):
    j = model.joints15(standing(model, l_hip_flex=30, r_hip_flex=30, l_shoulder_abd=40, r_shoulder_abd=40))[0]
    # hip flexion brings both knees forward (+x)
    assert j[J["l_knee"], 0] > j[J["l_hip"], 0] + 100 and j[J["r_knee"], 0] > j[J["r_hip"], 0] + 100
    # abduction lifts both elbows sideways, away from the body
    assert j[J["l_elbow"], 1] > j[J["l_shoulder"], 1] + 100
    assert j[J["r_elbow"], 1] < j[J["r_shoulder"], 1] - 100


def test_heading_rotates_the_whole_body_about_z(model):
    j0 = model.joints15(standing(model))[0]
    j1 = model.joints15(standing(model, pelvis_rz=90.0))[0]
    Rz = elementary_rotation(2, np.array([np.pi / 2]))[0]
    centre = np.array([0.0, 0.0, 1000.0])
    assert np.allclose(j1, (j0 - centre) @ Rz.T + centre, atol=1e-9)


def test_root_translation_moves_everything(model):
    j0 = model.joints15(standing(model))[0]
    j1 = model.joints15(standing(model, pelvis_tx=100.0, pelvis_ty=-50.0))[0]
    assert np.allclose(j1 - j0, [100.0, -50.0, 0.0])


def test_spine_does_not_move_the_torso_cone(model):
    """Thesis Table 5.2: the torso cylinder is fixed to the pelvis, not to the spine joint."""
    c0 = model.cones(standing(model))
    c1 = model.cones(standing(model, spine_flex=40.0))
    k = model.cone_arrays.index("torso")
    h = model.cone_arrays.index("head")
    assert np.allclose(c0.end[:, k], c1.end[:, k])
    assert not np.allclose(c0.end[:, h], c1.end[:, h])


def test_thesis_variant_lengthens_lower_limbs(model):
    plain = load_model("balan31", variant=None)
    k = plain.cone_arrays.index("l_calf")
    L0 = np.linalg.norm(plain.cone_arrays.end[k] - plain.cone_arrays.start[k])
    L1 = np.linalg.norm(model.cone_arrays.end[k] - model.cone_arrays.start[k])
    assert L1 == pytest.approx(1.2 * L0)


pose_batches = arrays(np.float64, st.tuples(st.integers(1, 6), st.just(31)),
                      elements=st.floats(-3.0, 3.0, allow_nan=False))


@settings(max_examples=40, deadline=None)
@given(poses=pose_batches)
def test_batched_equals_one_by_one_and_reference(poses):
    model = load_model("balan31")
    poses = poses.copy()
    poses[:, 3:6] *= 300.0  # translations in mm
    batched = model.forward(poses)
    single = np.stack([model.forward(p)[0] for p in poses])
    reference = model.forward(poses, reference=True)
    assert np.allclose(batched, single, atol=1e-9)
    assert np.allclose(batched, reference, atol=1e-9)
    # rotations stay orthonormal
    R = batched[..., :3]
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-9)


def test_parallel_kernel_equals_reference():
    """Batches of PARALLEL_MIN_BATCH poses or more go through the prange kernel: same transforms."""
    from swarmpose.body.kinematics import PARALLEL_MIN_BATCH

    model = load_model("balan31")
    rng = np.random.default_rng(3)
    poses = rng.uniform(-3.0, 3.0, (PARALLEL_MIN_BATCH + 44, model.n_params))
    poses[:, 3:6] *= 300.0
    np.testing.assert_allclose(model.forward(poses), model.forward(poses, reference=True), atol=1e-9)
    np.testing.assert_allclose(model.forward(poses[:7]), model.forward(poses)[:7], atol=1e-12)  # serial kernel


def test_a_long_track_s_joints_are_computed_in_steps_with_the_same_values():
    """More than JOINTS_CHUNK poses (a long recording's track) go through joints15 in steps: the same joints as
    the poses taken a few at a time."""
    from swarmpose.body.model import JOINTS_CHUNK

    model = load_model("balan31")
    rng = np.random.default_rng(5)
    poses = rng.uniform(-3.0, 3.0, (2 * JOINTS_CHUNK + 17, model.n_params))
    poses[:, 3:6] *= 300.0
    steps = np.concatenate([model.joints15(poses[a:a + 100]) for a in range(0, len(poses), 100)])
    np.testing.assert_array_equal(model.joints15(poses), steps)
    np.testing.assert_allclose(model.joints15(poses[:50], reference=True), steps[:50], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(poses=pose_batches)
def test_bone_lengths_are_preserved(poses):
    model = load_model("balan31")
    rest = model.joint_positions(model.zero_pose())[0]
    pos = model.joint_positions(poses)
    parents = model.kin.parents
    for j in range(1, len(parents)):
        expected = np.linalg.norm(rest[j] - rest[parents[j]])
        got = np.linalg.norm(pos[:, j] - pos[:, parents[j]], axis=-1)
        assert np.allclose(got, expected, atol=1e-6)


def test_full45_has_45_parameters_and_same_zero_pose_joints():
    full = load_model("full45")
    assert full.n_params == 45
    x = full.zero_pose()
    j = full.joints15(x)[0]
    assert j.shape == (15, 3)
    assert np.all(np.isfinite(j))
    # extra markers exist and the hand tip hangs below the wrist
    pos = full.joint_positions(x)[0]
    assert pos[full.joint_index["l_hand_tip"], 2] < j[J["l_wrist"], 2]


def test_bad_pose_shape_is_a_clear_error(model):
    with pytest.raises(ValueError, match=r"expected shape \(N, 31\)"):
        model.forward(np.zeros((3, 30)))


@pytest.mark.parametrize("name", ["balan31", "full45"])
def test_every_variant_change_reaches_the_cone_arrays(name):
    """(model.py:265 thickness ignored) and M06 (model.py:261 start_shift ignored): every change the
    spec's "thesis" variant lists (length, thickness, start_shift) shows in the compiled cones."""
    plain = load_model(name, variant=None)
    thesis = load_model(name, variant="thesis")
    p, t = plain.cone_arrays, thesis.cone_arrays
    for cname, mod in plain.spec.variants["thesis"].items():
        k = p.index(cname)
        axis_p = p.end[k] - p.start[k]
        frac = next(c for c in plain.spec.cones if c.name == cname)
        m = np.asarray(plain.subject.offsets[frac.axis])
        np.testing.assert_allclose(t.start[k], m * (frac.start_frac + mod.get("start_shift", 0.0)), atol=1e-9)
        np.testing.assert_allclose(t.end[k] - t.start[k], axis_p * mod.get("length", 1.0), atol=1e-9)
        np.testing.assert_allclose(t.radii[k], p.radii[k] * mod.get("thickness", 1.0), rtol=1e-12)
