"""The heading's search on a constructed frame: the body turned away, or its pelvis alone."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINTS15
from swarmpose.optim import registry
from swarmpose.optim.variants import apply_variant
from swarmpose.track.turn import TurnSearch, keypoint_turn, turn_candidates


@pytest.fixture(scope="module")
def setup(bent_body_frame):
    return bent_body_frame({"l_shoulder_abd": 0.4, "r_shoulder_flex": 0.6, "r_elbow_flex": 0.5, "l_hip_flex": 0.5,
                            "l_knee_flex": 0.9, "r_knee_flex": 0.3})


def search(**kw) -> TurnSearch:
    return TurnSearch.from_settings({**registry.TURN_SEARCH, **kw})


def joint_error(model, x, truth) -> float:
    return float(np.linalg.norm(model.joints15(x[None])[0] - model.joints15(truth[None])[0], axis=1).mean())


def test_a_whole_turn_rotates_every_joint_about_the_vertical_through_the_pelvis(setup):
    model, pose, _ = setup
    turned = turn_candidates(model, pose, (90.0,), ())[0]
    j0, j1 = model.joint_positions(np.stack([pose, turned]))
    pelvis = j0[0]
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z
    np.testing.assert_allclose(j1, (j0 - pelvis) @ rot.T + pelvis, atol=1e-6)


def test_the_pelvis_alone_turns_with_the_legs_and_trunk_kept(setup):
    model, pose, _ = setup
    pose = pose.copy()
    pose[model.param_index("l_hip_flex")] = 0.0  # exact with the thighs hanging (knees bent: the twist shows)
    ix = model.joint_index
    for degrees in (30.0, -35.0):  # within the spine's twist limits (40)
        turned = turn_candidates(model, pose, (), (degrees,))[0]
        j0, j1 = model.joint_positions(np.stack([pose, turned]))
        # the hips' and the spine's own twists made up for the pelvis's turn: every segment below and above
        # points where it did (the hips moved with the pelvis, so positions differ but directions do not)
        for a, b in (("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"),
                     ("spine", "thorax"), ("thorax", "l_shoulder"), ("l_elbow", "l_wrist"), ("r_elbow", "r_wrist")):
            np.testing.assert_allclose(j1[ix[b]] - j1[ix[a]], j0[ix[b]] - j0[ix[a]], atol=1e-6)
        hips0, hips1 = j0[ix["l_hip"]] - j0[ix["r_hip"]], j1[ix["l_hip"]] - j1[ix["r_hip"]]
        angle = np.degrees(np.arctan2(hips1[1], hips1[0]) - np.arctan2(hips0[1], hips0[0]))
        assert angle == pytest.approx(degrees, abs=1e-6)  # while the pelvis turned


def test_a_body_turned_away_is_turned_back(setup):
    model, truth, fitness = setup
    away = turn_candidates(model, truth, (-90.0,), ())[0]
    assert joint_error(model, away, truth) > 150
    out = search().run(fitness, model, away, HardPriors(model).valid, model.sigma * 3.0)
    assert out.turned == 90.0
    assert out.score > fitness.evaluate(away[None])[0]
    assert joint_error(model, out.x, truth) < 20


def test_a_turn_is_kept_only_above_the_margin(setup):
    model, truth, fitness = setup
    away = turn_candidates(model, truth, (-90.0,), ())[0]
    scores = fitness.evaluate(np.stack([away, truth]))
    gain = scores[1] - scores[0]
    assert gain > 0.01
    for margin, turned in ((0.5 * gain, 90.0), (2.0 * gain, 0.0)):
        out = search(margin=margin).run(fitness, model, away, HardPriors(model).valid, model.sigma * 3.0)
        assert out.turned == turned, margin


def test_a_pelvis_left_behind_is_turned_with_the_legs_kept(setup):
    model, truth, fitness = setup
    behind = turn_candidates(model, truth, (), (-30.0,))[0]
    out = search().run(fitness, model, behind, HardPriors(model).valid, model.sigma * 3.0)
    assert out.turned == 30.0
    assert joint_error(model, out.x, truth) < 0.5 * joint_error(model, behind, truth)


def test_the_pose_is_kept_when_no_turn_scores_higher(setup):
    model, truth, fitness = setup
    s = search(guard="")
    out = s.run(fitness, model, truth, HardPriors(model).valid, model.sigma)
    assert out.turned == 0.0 and out.score is None
    np.testing.assert_array_equal(out.x, truth)
    turns = len(s.whole) + len(s.pelvis)
    assert turns + 1 < out.evaluations <= 1 + turns + s.n_best * s.budget


def test_settings_and_the_variant():
    assert TurnSearch.from_settings({}) is None
    with pytest.raises(ConfigError, match="unknown turn search"):
        TurnSearch.from_settings({**registry.TURN_SEARCH, "turns": 3})
    with pytest.raises(ConfigError, match="n_best"):
        search(n_best=0)
    with pytest.raises(ConfigError, match="margin"):
        search(margin=-0.1)
    model = load_model("balan31")
    cfg = registry.get("refined-limbs", model=model, fps=20)
    on = apply_variant(cfg, "turn=on")
    t = registry.TURN_SEARCH
    assert dict(on.turn_search) == dict(t)
    extra = 1 + len(t["whole"]) + len(t["pelvis"]) + t["n_best"] * t["budget"] + 2
    assert on.evals_per_frame == cfg.evals_per_frame + extra
    assert not apply_variant(on, "turn=off").turn_search
    assert apply_variant(on, "turn_margin=0.005").turn_search["margin"] == 0.005
    assert apply_variant(on, "turn_margin=0.005").evals_per_frame == on.evals_per_frame
    for bad in ("turn_margin=-1", "turn_margin=x"):
        with pytest.raises(ConfigError, match="turn_margin=M"):
            apply_variant(on, bad)
    with pytest.raises(ConfigError, match="turn=on first"):
        apply_variant(cfg, "turn_margin=0.01")
    with pytest.raises(ConfigError, match="turn=on or turn=off"):
        apply_variant(cfg, "turn=yes")
    with pytest.raises(ConfigError, match="turn=on or turn=off"):
        apply_variant(registry.get("sppso", model=model, fps=20), "turn=on")


def test_refined_heading_is_refined_limbs_with_the_turn_search():
    model = load_model("balan31")
    limbs = registry.get("refined-limbs", model=model, fps=20)
    heading = registry.get("refined-heading", model=model, fps=20)
    on = apply_variant(limbs, f"turn=on+recovery_jump={registry.RECOVERY_JUMP:g}")  # the recovery's jump margin too
    for f in ("base", "refine_budget", "refine_step", "recovery", "silhouette_height", "turn_search"):
        assert repr(getattr(heading, f)) == repr(getattr(on, f)), f  # (configurations compare by identity)
    assert heading.evals_per_frame == on.evals_per_frame
    assert registry.default_motion("refined-heading") == registry.default_motion("refined-limbs")


def test_the_heading_is_carried_on_beyond_its_dead_zone():
    from swarmpose.track.step import FrameSearch

    model = load_model("balan31")
    rz = model.param_index("pelvis_rz")

    def search(constraint=lambda poses: np.ones(len(poses), bool)):
        return FrameSearch(model=model, algo=None, fitness=None, motion=None, motion_mask=None,
                           constraint=constraint, timer=None, extra_options={}, heading_speed=10.0)

    history = np.zeros((2, model.n_params))
    pred = history[-1].copy()
    for step_deg, carried_deg in ((30.0, 20.0), (-30.0, -20.0), (5.0, 0.0), (10.0, 0.0)):
        history[1, rz] = np.radians(step_deg)
        pred[rz] = history[1, rz]
        out = search()._carry_heading(history, pred)
        assert np.degrees(out[rz] - pred[rz]) == pytest.approx(carried_deg, abs=1e-9)
        np.testing.assert_array_equal(np.delete(out, rz), np.delete(pred, rz))
    history[1, rz] = np.radians(40.0)
    refused = search(lambda poses: np.zeros(len(poses), bool))._carry_heading(history, pred)
    assert refused is pred  # a carried heading the hard priors refuse is not used


def test_the_heading_speed_variant():
    model = load_model("balan31")
    cfg = registry.get("refined-heading", model=model, fps=20)
    assert cfg.heading_speed is None
    assert apply_variant(cfg, "heading_speed=10").heading_speed == 10.0
    assert apply_variant(apply_variant(cfg, "heading_speed=10"), "heading_speed=off").heading_speed is None
    assert apply_variant(cfg, "heading_speed=10").evals_per_frame == cfg.evals_per_frame
    for bad in ("heading_speed=-1", "heading_speed=fast"):
        with pytest.raises(ConfigError, match="heading_speed=D"):
            apply_variant(cfg, bad)
    with pytest.raises(ConfigError, match="heading_speed=D"):
        apply_variant(registry.get("sppso", model=model, fps=20), "heading_speed=10")


def test_the_keypoints_hips_give_the_turn_that_brings_a_lagging_pelvis_back(setup):
    """A pelvis 22 degrees behind (between the fixed turns tried): :func:`keypoint_turn` reads the turn back from
    the truth's hips, the search tries it and keeps it; a missing hip or a turn under ``least`` gives None."""
    model, truth, fitness = setup
    behind = turn_candidates(model, truth, (), (-22.0,))[0]
    joints = model.joints15(truth[None])[0]
    by = keypoint_turn(model, behind, joints)
    assert by == pytest.approx(22.0, abs=0.5)
    assert keypoint_turn(model, truth, joints) is None  # within `least` degrees
    gone = joints.copy()
    gone[JOINTS15.index("l_hip")] = np.nan
    assert keypoint_turn(model, behind, gone) is None
    s = search(keypoints=True)
    out = s.run(fitness, model, behind, HardPriors(model).valid, model.sigma * 3.0, extra=(by,))
    assert out.turned == by
    assert joint_error(model, out.x, truth) < 0.5 * joint_error(model, behind, truth)
    model20 = load_model("balan31")
    on = apply_variant(apply_variant(registry.get("refined-limbs", model=model20, fps=20), "turn=on"),
                       "turn_keypoints=on")
    assert on.turn_search["keypoints"] is True
    assert on.evals_per_frame == apply_variant(on, "turn_keypoints=off").evals_per_frame + 2
    with pytest.raises(ConfigError, match="turn_keypoints=on or turn_keypoints=off"):
        apply_variant(on, "turn_keypoints=maybe")
