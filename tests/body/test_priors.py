"""Hard priors: joint limits and inter-penetration (thesis sec. 5.3.2)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError


@pytest.fixture(scope="module")
def model():
    return load_model("balan31")


@pytest.fixture(scope="module")
def priors(model):
    return HardPriors(model)


def pose(model, **deg):
    x = model.zero_pose()
    x[model.param_index("pelvis_tz")] = 1000.0
    for name, v in deg.items():
        x[model.param_index(name)] = np.radians(v)
    return x


def test_standing_and_walking_poses_are_valid(model, priors):
    walk = pose(model, l_hip_flex=30, r_hip_flex=-20, l_knee_flex=40, r_knee_flex=10,
                l_shoulder_flex=-20, r_shoulder_flex=20, l_elbow_flex=20, r_elbow_flex=30)
    assert priors.valid(np.stack([pose(model), walk])).all()


def test_crossing_legs_are_rejected(model, priors):
    crossed = pose(model, l_hip_abd=-30, r_hip_abd=-30)
    assert not priors.valid(crossed)[0]
    assert any("thigh" in r for r in priors.describe(crossed))


def test_arm_through_the_torso_is_rejected(model, priors):
    # forearm swung into the trunk by adduction past the body's side
    through = pose(model, l_shoulder_abd=-40)
    assert not priors.valid(through)[0]
    assert priors.describe(through) == ["l_lower_arm penetrates torso"]
    # forearm folded across the belly with the elbow behind the trunk's front surface
    folded = pose(model, r_shoulder_rot=80, r_elbow_flex=90)
    assert "r_lower_arm penetrates torso" in priors.describe(folded)
    # the same arm raised forward is fine
    assert priors.valid(pose(model, l_shoulder_flex=90))[0]


def test_joint_limits(model, priors):
    knee_backwards = pose(model, l_knee_flex=-30)
    assert not priors.valid(knee_backwards)[0]
    assert priors.describe(knee_backwards)[0].startswith("l_knee_flex = -30.0 outside")
    # the heading is unbounded: any turn is fine
    assert priors.valid(pose(model, pelvis_rz=1000.0))[0]


def test_batched_result_matches_single(model, priors):
    rng = np.random.default_rng(0)
    poses = pose(model) + rng.normal(scale=0.4, size=(64, model.n_params)) * model.is_rotation
    batched = priors.valid(poses)
    single = np.array([priors.valid(p)[0] for p in poses])
    assert np.array_equal(batched, single)
    assert 0 < batched.sum() < len(poses)  # the sample holds both kinds


def test_checks_can_be_switched_off(model):
    crossed = pose(model, l_hip_abd=-30, r_hip_abd=-30)
    assert HardPriors(model, check_collisions=False).valid(crossed)[0]
    with pytest.raises(ConfigError):
        HardPriors(model, penetration_tolerance=1.0)


def test_numba_collisions_match_the_numpy_reference(model, priors):
    rng = np.random.default_rng(1)
    poses = pose(model) + rng.normal(scale=0.6, size=(400, model.n_params)) * model.is_rotation
    fast = priors.collisions(poses)
    ref = priors.collisions_reference(poses)
    assert np.array_equal(fast, ref)
    assert fast.any() and not fast.all()
