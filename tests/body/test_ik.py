"""Inverse kinematics and subject fitting on real motion capture."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.ik import fit_ik
from swarmpose.body.model import BodyModel, load_model
from swarmpose.body.priors import HardPriors
from swarmpose.body.spec import load_spec
from swarmpose.io.mocap import load_clip, subject_from_clip


def test_ik_recovers_the_models_own_poses():
    """A smooth motion of the model itself is fitted exactly (warm start follows it)."""
    m = load_model("balan31")
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 15)[:, None]
    amp = rng.normal(scale=0.3, size=(1, m.n_params)) * m.is_rotation
    phase = rng.uniform(0, 2 * np.pi, size=(1, m.n_params))
    x = amp * np.sin(2 * np.pi * t + phase)
    x[:, m.param_index("pelvis_tz")] = 950.0
    x[:, m.param_index("pelvis_tx")] = 800.0 * t[:, 0]
    x[:, m.param_index("pelvis_rz")] = 2.5 * t[:, 0]
    x = np.clip(x, m.lower, m.upper)
    # without the rest prior (which trades up to ~1 mm of fit for a stable decomposition, see fit_ik)
    res = fit_ik(m, m.joints15(x), rest_weight=0.0, polish=False)  # the smooth fit itself
    assert res.floor_max_mm < 0.05  # the damping term biases by ~0.01 mm


def test_ik_rejects_bad_input():
    m = load_model("balan31")
    with pytest.raises(ValueError, match=r"\(T, 15, 3\)"):
        fit_ik(m, np.zeros((4, 14, 3)))
    bad = np.zeros((2, 15, 3))
    bad[1, 3, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        fit_ik(m, bad)


@pytest.fixture(scope="module")
def walk(walk_clip_path):
    clip = load_clip(walk_clip_path, fps=30)
    spec = load_spec("balan31")
    model = BodyModel(spec, subject_from_clip(spec, clip), "thesis")
    return clip, model, fit_ik(model, clip.joints)


def test_subject_measurements_come_from_the_skeleton(walk):
    clip, model, _ = walk
    # model limb lengths equal the clip's bone lengths
    thigh = np.linalg.norm(clip.joints[:, 9] - clip.joints[:, 8], axis=-1)
    assert -model.subject.offsets["l_thigh"][2] == pytest.approx(thigh.mean(), abs=1e-6)
    assert 380 < -model.subject.offsets["l_thigh"][2] < 460


def test_walking_ik_floor_is_small_and_poses_are_valid(walk):
    clip, model, res = walk
    assert res.params.shape == (clip.frames, 31)
    assert res.floor_mean_mm < 2.0  # measured 0.92 mm (the acceptance asked for < 30)
    assert res.floor_max_mm < 5.0  # measured 2.41 mm
    # the ground truth must be a feasible pose for the tracker: hard priors hold on it
    assert HardPriors(model).valid(res.params).mean() > 0.99


def test_subject_from_joints_alone_fits_almost_as_well(walk):
    """Without a skeleton file (HumanEva), the subject measured from the 15 joints still fits them."""
    from swarmpose.body.subject import subject_from_joints

    clip, model, res = walk
    spec = model.spec
    subj = subject_from_joints(spec, clip.joints, name="gt-only")
    m2 = BodyModel(spec, subj, "thesis")
    assert -subj.offsets["l_thigh"][2] == pytest.approx(-model.subject.offsets["l_thigh"][2], abs=1e-6)
    res2 = fit_ik(m2, clip.joints[::3])
    assert res2.floor_mean_mm < 3.0  # measured 1.74 mm


@pytest.mark.parametrize("spec_name", ["balan31", "full45"])
def test_thesis_variant_keeps_the_torso_top_at_the_shoulders(walk_clip_path, spec_name):
    """The subject's torso already ends at the top of the shoulders (the alignment thesis sec. 5.1.2's
    x1.05 was for); the variant must not lengthen it again (an 18 mm too high top edge sank the body)."""
    clip = load_clip(walk_clip_path, fps=30)
    spec = load_spec(spec_name)
    model = BodyModel(spec, subject_from_clip(spec, clip), "thesis")
    k = model.cone_arrays.names.index("torso")
    top = np.asarray(model.subject.offsets["pelvis_to_torso_top"])
    np.testing.assert_allclose(model.cone_arrays.end[k], top, atol=1e-9)
    # ... and that top is the shoulder joints' height plus the upper arm's radius
    o = model.subject.offsets
    shoulder_z = 0.5 * (o["l_thorax_to_shoulder"][2] + o["r_thorax_to_shoulder"][2]) + o["spine_to_thorax"][2]
    assert top[2] == pytest.approx(shoulder_z + model.subject.cones["l_upper_arm"][0], abs=1e-6)


def test_the_ik_floor_is_the_best_fit_not_the_smooth_one(walk):
    """The smooth fit (damping, rest prior: the tracker's start pose) is polished per frame on the joints
    alone; the floor is the polished fit's error, lower, and its poses stay valid and near the smooth ones."""
    clip, model, res = walk
    smooth_err = np.linalg.norm(model.joints15(res.params) - clip.joints, axis=-1)
    np.testing.assert_allclose(res.joint_error_mm, np.linalg.norm(model.joints15(res.floor_params) - clip.joints,
                                                                  axis=-1))
    assert (res.frame_error_mm <= smooth_err.mean(axis=1) + 1e-9).all()
    assert res.floor_mean_mm < 0.6 * smooth_err.mean()  # walk at 30 fps: about 0.9 against 2.1 mm
    assert HardPriors(model).valid(res.floor_params).all()
    assert np.abs(res.floor_params - res.params)[:, model.is_rotation].max() < 0.5  # radians
    quick = fit_ik(model, clip.joints[:5], polish=False)
    np.testing.assert_array_equal(quick.floor_params, quick.params)


def test_initial_root_pose_recovers_a_tilted_root():
    """(ik.py:73 `arctan2(-R[2, 0], ...)` sign): with zero joint angles, the rigid fit of pelvis, hips
    and thorax gives back the root exactly."""
    from swarmpose.body.ik import initial_root_pose

    m = load_model("balan31")
    x = m.zero_pose()
    for name, v in (("pelvis_rx", 0.3), ("pelvis_ry", -0.4), ("pelvis_rz", 2.0), ("pelvis_tx", 120.0),
                    ("pelvis_ty", -300.0), ("pelvis_tz", 950.0)):
        x[m.param_index(name)] = v
    np.testing.assert_allclose(initial_root_pose(m, m.joints15(x)[0]), x, atol=1e-9)


def test_ik_fit_does_not_depend_on_where_the_subject_faces(mocap_dir):
    """(ik.py:133 the rest prior also on the root): the smooth fit (the tracker's start pose) must be
    equivariant under a rotation of the world about the vertical -- only the heading and the root's
    horizontal position change. Measured: the mutant's heading differs by ~1e-2 rad."""
    from swarmpose.body.ik import fit_ik
    from swarmpose.body.model import BodyModel
    from swarmpose.body.spec import load_spec
    from swarmpose.io.mocap import load_clip, subject_from_clip

    clip = load_clip(mocap_dir / "cmu_16_16_walk.bvh", fps=30)
    spec = load_spec("balan31")
    model = BodyModel(spec, subject_from_clip(spec, clip), "thesis")
    gt = clip.joints[:8]
    th = 2.5
    c, s = np.cos(th), np.sin(th)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    a = fit_ik(model, gt, polish=False).params
    b = fit_ik(model, gt @ Rz.T, polish=False).params
    rz, tx, ty = (model.param_index(n) for n in ("pelvis_rz", "pelvis_tx", "pelvis_ty"))
    np.testing.assert_allclose(np.angle(np.exp(1j * (b[:, rz] - a[:, rz] - th))), 0.0, atol=1e-4)
    np.testing.assert_allclose(b[:, [tx, ty]], a[:, [tx, ty]] @ Rz[:2, :2].T, atol=0.05)
    others = [i for i in range(model.n_params) if i not in (rz, tx, ty)]
    np.testing.assert_allclose(b[:, others], a[:, others], atol=1e-4)


def test_ik_with_missing_joints_fits_the_rest_and_leaves_the_unseen_limb_at_rest():
    """missing=True: a wrist and elbow no view saw get no residual; the other joints are fitted as before and the
    unseen arm keeps the start's (zero) angles; by default a missing joint is an error."""
    m = load_model("balan31")
    x = m.zero_pose()
    x[m.param_index("pelvis_tz")] = 950.0
    x[m.param_index("l_knee_flex")] = 0.6
    x[m.param_index("l_elbow_flex")] = 1.0
    joints = m.joints15(x[None])
    seen = joints.copy()
    seen[0, [3, 4]] = np.nan  # l_elbow, l_wrist
    with pytest.raises(ValueError, match="non-finite"):
        fit_ik(m, seen)
    res = fit_ik(m, seen, missing=True)
    assert np.isnan(res.joint_error_mm[0, [3, 4]]).all()
    assert np.nanmax(res.joint_error_mm) < 2.0
    fitted = res.params[0]
    assert fitted[m.param_index("l_knee_flex")] == pytest.approx(0.6, abs=0.02)
    assert abs(fitted[m.param_index("l_elbow_flex")]) < 0.01  # nothing pulled the elbow from the start
    with pytest.raises(ValueError, match="no finite joint"):
        fit_ik(m, np.full((1, 15, 3), np.nan), missing=True)
