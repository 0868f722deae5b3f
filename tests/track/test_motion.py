"""Motion models (swarmpose.track.motion): zero velocity (thesis sec. 5.3.2) and constant velocity."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from swarmpose.errors import ConfigError
from swarmpose.track.motion import MotionModel, parse_motion

finite = st.floats(-1e3, 1e3, allow_nan=False)


@given(arrays(np.float64, (3, 5), elements=finite))
def test_zero_velocity_predicts_the_last_estimate(history):
    assert np.array_equal(parse_motion("zero-velocity").predict(history), history[-1])


@given(arrays(np.float64, 5, elements=finite), arrays(np.float64, 5, elements=finite),
       st.floats(0.0, 1.0))
def test_constant_velocity_carries_the_last_step_on(start, step, d):
    """On a straight line x_k = start + k step the prediction is x_2 + d step (d = 1: the next point)."""
    history = np.stack([start, start + step, start + 2 * step])
    predicted = parse_motion(f"constant-velocity:{d}").predict(history)
    np.testing.assert_allclose(predicted, start + (2 + d) * step, atol=1e-9)
    np.testing.assert_allclose(parse_motion("constant-velocity").predict(history), start + 3 * step, atol=1e-9)


def test_constant_velocity_needs_two_estimates_and_respects_the_priors():
    cv = parse_motion("constant-velocity")
    one = np.array([[1.0, 2.0]])
    assert np.array_equal(cv.predict(one), one[0])
    history = np.array([[0.0, 0.0], [1.0, 1.0]])
    assert np.array_equal(cv.predict(history), [2.0, 2.0])
    # a prediction outside the hard priors is not used: zero velocity for that frame
    below_two = lambda poses: np.all(poses < 1.5, axis=1)  # noqa: E731
    assert np.array_equal(cv.predict(history, below_two), [1.0, 1.0])


def test_carried_particles_move_by_the_step_where_they_stay_valid():
    cv = MotionModel("constant-velocity", 1.0)
    particles = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    valid = lambda poses: poses[:, 0] < 2.5  # noqa: E731
    moved = cv.move_particles(particles, np.array([1.0, 0.0]), valid)
    assert moved.tolist() == [[1.0, 0.0], [2.0, 0.0], [2.0, 0.0]]  # the last would leave the valid region
    assert cv.move_particles(particles, np.zeros(2)) is particles


@pytest.mark.parametrize("text, match", [
    ("constant-velocity:2", r"\[0, 1\]"), ("constant-velocity:x", "number"), ("constant-velocity:", "number"),
    ("linear", "known: zero-velocity"), ("zero-velocity:1", "no ':D'"), ("zero-velocity@root", "no ':D' and no '@"),
    ("constant-velocity@pelvis_rz*2", r"pelvis_rz\*F .* \[0, 1\]"), ("constant-velocity@pelvis_rz*", "got ''"),
    ("zero-velocity@pelvis_rz*0.5", "no ':D' and no '@"),
])
def test_bad_motion_models_are_named(text, match):
    with pytest.raises(ConfigError, match=match):
        parse_motion(text)
    with pytest.raises(ConfigError, match="unknown motion model 'linear'"):
        MotionModel("linear", 1.0)


def test_names_round_trip_to_a_canonical_text():
    for text in ("zero-velocity", "constant-velocity", "constant-velocity:0.5", "constant-velocity:0.123456789",
                 "constant-velocity@root_position+spine", "constant-velocity@pelvis_tx+pelvis_rz*0.5",
                 "constant-velocity:0.8@pelvis_tx*1.0+pelvis_rz*0.25"):
        assert str(parse_motion(text)) == text
        assert parse_motion(str(parse_motion(text))) == parse_motion(text)
    assert str(parse_motion(" constant-velocity:1 ")) == "constant-velocity"


def test_groups_limit_the_step_and_are_checked_against_the_model():
    from swarmpose.body.model import BodyModel
    from swarmpose.body.spec import load_spec

    model = BodyModel(load_spec("balan31"))
    cv = parse_motion("constant-velocity:0.5@root_position+left_leg")
    assert cv.groups == ("root_position", "left_leg") and str(cv) == "constant-velocity:0.5@root_position+left_leg"
    mask = cv.mask(model)
    assert np.count_nonzero(mask) == len(model.group("root_position")) + len(model.group("left_leg"))
    assert set(mask[mask != 0]) == {0.5}  # each named parameter carries d of its last step
    history = np.stack([np.zeros(model.n_params), np.ones(model.n_params)])
    predicted = cv.predict(history, mask=mask)
    np.testing.assert_array_equal(predicted, np.where(mask, 1.5, 1.0))
    assert parse_motion("constant-velocity").mask(model) is None
    with pytest.raises(ConfigError, match="no parameter group 'arms'"):
        parse_motion("constant-velocity@arms").mask(model)
    with pytest.raises(ConfigError, match="after '@'"):
        parse_motion("constant-velocity@")


def test_single_parameters_move_on_by_name():
    """``@pelvis_tx+pelvis_ty`` (refined's default): the horizontal root position, not its height."""
    from swarmpose.body.model import load_model

    model = load_model("balan31")
    cv = parse_motion("constant-velocity@pelvis_tx+pelvis_ty")
    mask = cv.mask(model)
    assert np.flatnonzero(mask).tolist() == [model.param_index("pelvis_tx"), model.param_index("pelvis_ty")]
    history = np.zeros((2, model.n_params))
    history[1, 3:6] = (10.0, 20.0, 30.0)
    pred = cv.predict(history, None, mask)
    np.testing.assert_allclose(pred[3:6], (20.0, 40.0, 30.0))
    with pytest.raises(ConfigError, match="parameter's name"):
        parse_motion("constant-velocity@pelvis_tq").mask(model)


def test_a_group_carries_its_own_fraction_of_the_last_step():
    from swarmpose.body.model import load_model

    model = load_model("balan31")
    tx, rz, knee = (model.param_index(n) for n in ("pelvis_tx", "pelvis_rz", "l_knee_flex"))
    history = np.zeros((2, model.n_params))
    history[1, [tx, rz, knee]] = [100.0, 0.4, 0.2]
    for text, expect in (("constant-velocity@pelvis_tx+pelvis_rz", (200.0, 0.8)),
                         ("constant-velocity@pelvis_tx+pelvis_rz*0.5", (200.0, 0.6)),
                         ("constant-velocity:0.5@pelvis_tx+pelvis_rz*0.25", (150.0, 0.5))):
        cv = parse_motion(text)
        predicted = cv.predict(history, mask=cv.mask(model))
        np.testing.assert_allclose(predicted[[tx, rz]], expect, atol=1e-12)
        assert predicted[knee] == 0.2  # not named: it stays
    # the groups' own fractions equal to d give the model without them, to the last digit
    plain, own = parse_motion("constant-velocity:0.7@root_position"), parse_motion("constant-velocity:0.7@root_position*0.7")
    rng = np.random.default_rng(0)
    h = rng.normal(size=(2, model.n_params))
    assert np.array_equal(plain.predict(h, mask=plain.mask(model)), own.predict(h, mask=own.mask(model)))
