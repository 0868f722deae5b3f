"""The offline choice of pose per frame as one path over the frames (swarmpose.track.path)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.errors import ConfigError, ShapeError
from swarmpose.track.path import best_path, best_path_reference, path_cost


def _case(seed: int, T: int, K: int, J: int = 3):
    rng = np.random.default_rng(seed)
    scores = rng.uniform(0.0, 1.0, (T, K))
    joints = np.cumsum(rng.normal(0.0, 60.0, (T, 1, J, 3)), axis=0) + rng.normal(0.0, 80.0, (T, K, J, 3))
    return scores, joints


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), T=st.integers(1, 6), K=st.integers(1, 3),
       weight=st.sampled_from([0.0, 0.1, 0.3, 1.0, 10.0]))
def test_the_path_is_the_cheapest_of_all_paths(seed, T, K, weight):
    scores, joints = _case(seed, T, K)
    path = best_path(scores, joints, weight)
    ref = best_path_reference(scores, joints, weight)
    assert path.shape == (T,) and path.dtype == np.int64
    assert path_cost(scores, joints, weight, path) == pytest.approx(path_cost(scores, joints, weight, ref), abs=1e-9)
    assert np.array_equal(path, ref)  # continuous random data: no ties


def test_without_weight_each_frame_takes_its_best_score():
    scores, joints = _case(1, 40, 3)
    assert np.array_equal(best_path(scores, joints, 0.0), scores.argmax(axis=1))


def test_a_pose_far_off_for_one_frame_loses_to_a_slightly_lower_score():
    """The offline pass's case: a body standing still; at frame 5 the second candidate scores 0.05 higher with
    one of its 15 joints 400 mm off, where both neighbours agree. The mean joint step is 400 / 15 = 26.7 mm to
    and from it: 2 * 0.267^2 = 0.142 at weight 1 (more than the score buys), 0.043 at weight 0.3 (less)."""
    T = 10
    joints = np.zeros((T, 2, 15, 3))
    scores = np.ones((T, 2))
    joints[5, 1, 4] = [0.0, 400.0, 0.0]
    scores[5, 1] += 0.05
    assert best_path(scores, joints, 1.0)[5] == 0
    assert best_path(scores, joints, 0.3)[5] == 1
    assert best_path(scores, joints, 0.0)[5] == 1
    joints[5, 1, 4] = [0.0, 1200.0, 0.0]  # 80 mm on average: 2 * 0.8^2 * 0.3 = 0.38
    assert best_path(scores, joints, 0.3)[5] == 0
    assert np.array_equal(best_path(scores, joints, 0.3), np.zeros(T))
    # equal candidates: the first is taken
    assert np.array_equal(best_path(np.ones((T, 2)), np.zeros((T, 2, 15, 3)), 0.3), np.zeros(T))


def test_bad_input_is_refused():
    scores, joints = _case(0, 4, 2)
    with pytest.raises(ShapeError, match="scores must be"):
        best_path(scores[0], joints)
    with pytest.raises(ShapeError, match="joints must be"):
        best_path(scores, joints[:, :1])
    with pytest.raises(ValueError, match="finite"):
        best_path(np.where(np.eye(4, 2) > 0, np.nan, scores), joints)
    for w in (-0.1, float("nan"), True, "0.3"):
        with pytest.raises(ConfigError, match="weight"):
            best_path(scores, joints, w)
