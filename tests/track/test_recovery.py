"""Loss detection and recovery on a constructed frame: one arm 90 degrees off."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError
from swarmpose.fitness import make_fitness
from swarmpose.fitness.scene import demo_cameras, demo_frame
from swarmpose.track.recovery import Recovery


@pytest.fixture(scope="module")
def setup():
    model = load_model("balan31")
    pose = model.zero_pose()
    pose[5] = 1000.0
    pose[model.param_index("l_shoulder_abd")] = 0.4
    pose[model.param_index("r_shoulder_abd")] = 0.6
    pose[model.param_index("r_elbow_flex")] = 0.5
    frame = demo_frame(model, pose, demo_cameras(4, width=322, height=242), rng=np.random.default_rng(3))
    fitness = make_fitness("silhouette_edge", model).bind(frame)
    return model, pose, fitness


def arm_error(model, x, truth, side="r"):
    j = [model.spec.joints15.index(f"{side}_{n}") for n in ("elbow", "wrist")]
    return np.linalg.norm(model.joints15(x[None])[0, j] - model.joints15(truth[None])[0, j], axis=1).max()


def test_a_lost_arm_is_found_and_brought_back(setup):
    model, truth, fitness = setup
    lost = truth.copy()
    lost[model.param_index("r_shoulder_abd")] += np.radians(90)  # the right arm swung 90 degrees off
    assert arm_error(model, lost, truth) > 300
    rec = Recovery()
    assert rec.lost(fitness, model, truth) == []
    assert rec.lost(fitness, model, lost) == ["right_arm"]
    sigma = model.sigma * 3.0
    out = rec.run(fitness, model, lost, np.random.default_rng(0), HardPriors(model).valid, sigma)
    assert out.lost == ["right_arm"] and out.recovered == ["right_arm"]
    assert out.evaluations == 1 + rec.n_samples * rec.n_rounds + rec.refine_budget
    assert arm_error(model, out.x, truth) < 100
    others = np.setdiff1d(np.arange(model.n_params), model.group("right_arm"))
    np.testing.assert_array_equal(out.x[others], lost[others])  # only the lost limb was searched


def test_nothing_is_searched_when_nothing_is_lost(setup):
    model, truth, fitness = setup
    out = Recovery().run(fitness, model, truth, np.random.default_rng(0), None, model.sigma)
    assert out.evaluations == 0 and out.lost == [] and out.recovered == []
    np.testing.assert_array_equal(out.x, truth)


def test_settings_are_checked():
    assert Recovery.from_settings({}) is None
    assert Recovery.from_settings({"threshold": 0.1}).threshold == 0.1
    with pytest.raises(ConfigError, match="unknown recovery"):
        Recovery.from_settings({"thresold": 0.1})


def test_every_limb_searched_again_with_the_frames_fitness(setup):
    """``recovery=all`` with ``recovery_terms=fitness``: every limb is searched again on every frame, scored by
    the frame's own fitness, so that a limb off inside the silhouette (which the distance term cannot see) is
    brought back too."""
    from swarmpose.track.recovery import LIMBS

    model, truth, fitness = setup
    off = truth.copy()
    off[model.param_index("r_elbow_flex")] += 0.8  # the forearm bent further
    rec = Recovery(threshold=-1.0, terms="fitness")
    out = rec.run(fitness, model, off, np.random.default_rng(1), HardPriors(model).valid, model.sigma * 3.0)
    assert out.lost == list(LIMBS) and "right_arm" in out.recovered
    assert fitness.evaluate(out.x[None])[0] > fitness.evaluate(off[None])[0]
    assert arm_error(model, out.x, truth) < 0.75 * arm_error(model, off, truth)  # 195 -> 127 mm (seed 1)


def test_a_margin_keeps_the_limb_unless_the_search_scores_clearly_higher(setup):
    model, truth, fitness = setup
    lost = truth.copy()
    lost[model.param_index("r_shoulder_abd")] += np.radians(90)
    kw = dict(rng=np.random.default_rng(0), constraint=HardPriors(model).valid, sigma=model.sigma * 3.0)
    kept = Recovery(margin=10.0).run(fitness, model, lost, **kw)  # more than any score can gain
    assert kept.lost == ["right_arm"] and kept.recovered == []
    np.testing.assert_array_equal(kept.x, lost)
    found = Recovery(margin=0.01).run(fitness, model, lost, **kw)  # a lost arm gains far more than 0.01
    assert found.recovered == ["right_arm"] and arm_error(model, found.x, truth) < 100


def test_limbs_looked_at_in_turn(setup):
    """``in_turn=K``: K limbs per frame in turn, every limb once every 4/K frames; a lost limb outside the
    frame's turn is left alone, inside it searched as before."""
    from swarmpose.track.recovery import LIMBS

    model, truth, fitness = setup
    names = list(LIMBS)
    one, two = Recovery(threshold=-1.0, in_turn=1), Recovery(threshold=-1.0, in_turn=2)
    assert [one.looked_at(model, i) for i in range(5)] == [[n] for n in names + names[:1]]
    assert [two.looked_at(model, i) for i in range(2)] == [names[:2], names[2:]]
    assert Recovery(in_turn=4).looked_at(model, 3) == names == Recovery().looked_at(model, 3)
    lost = truth.copy()
    lost[model.param_index("r_shoulder_abd")] += np.radians(90)
    kw = dict(rng=np.random.default_rng(0), constraint=HardPriors(model).valid, sigma=model.sigma * 3.0)
    k = names.index("right_arm")
    other = Recovery(in_turn=1).run(fitness, model, lost, position=k + 1, **kw)
    assert other.lost == [] and other.evaluations == 0
    np.testing.assert_array_equal(other.x, lost)
    mine = Recovery(in_turn=1).run(fitness, model, lost, position=k, **kw)
    assert mine.recovered == ["right_arm"] and arm_error(model, mine.x, truth) < 100
    assert Recovery.from_settings({"in_turn": 2}).in_turn == 2


def test_a_silhouette_guard_keeps_only_limbs_the_silhouettes_accept(setup):
    """``guard="silhouette"``: a searched limb is kept only when the silhouette overlap term does not fall; the lost
    arm's search raises both terms and is kept, two more evaluations counted."""
    model, truth, fitness = setup
    lost = truth.copy()
    lost[model.param_index("r_shoulder_abd")] += np.radians(90)
    kw = dict(rng=np.random.default_rng(0), constraint=HardPriors(model).valid, sigma=model.sigma * 3.0)
    plain = Recovery().run(fitness, model, lost, **kw)
    kw["rng"] = np.random.default_rng(0)
    guarded = Recovery(guard="silhouette").run(fitness, model, lost, **kw)
    assert guarded.recovered == ["right_arm"] and guarded.evaluations == plain.evaluations + 2
    np.testing.assert_array_equal(guarded.x, plain.x)
    sil = fitness.evaluate(np.stack([lost, guarded.x]), {"terms": "silhouette"})
    assert sil[1] > sil[0]


def test_the_guard_refuses_a_limb_the_silhouettes_score_lower(setup):
    """A searched limb that wins on the frame's score but loses on the silhouettes is refused. A fitness built for
    the test: its full score prefers the right shoulder at +1 rad, its silhouette term the shoulder where it is."""
    model, truth, _ = setup
    k = model.param_index("r_shoulder_abd")

    class Split:
        def evaluate(self, poses, options=None):
            want = truth[k] if (options or {}).get("terms") == "silhouette" else truth[k] + 1.0
            return -((np.asarray(poses)[:, k] - want) ** 2)

    kw = dict(rng=np.random.default_rng(0), constraint=None, sigma=model.sigma * 3.0)
    free = Recovery(threshold=-1.0, terms="fitness", in_turn=1).run(Split(), model, truth, position=1, **kw)
    assert free.recovered == ["right_arm"] and abs(free.x[k] - truth[k] - 1.0) < 0.1
    kw["rng"] = np.random.default_rng(0)
    guarded = Recovery(threshold=-1.0, terms="fitness", in_turn=1, guard="silhouette").run(Split(), model, truth,
                                                                                           position=1, **kw)
    assert guarded.lost == ["right_arm"] and guarded.recovered == []
    assert guarded.evaluations == free.evaluations + 2
    np.testing.assert_array_equal(guarded.x, truth)


def test_the_registry_counts_the_limbs_the_recovery_searches():
    from swarmpose import optim
    from swarmpose.optim.registry import RECOVERY_LIMBS
    from swarmpose.track.recovery import LIMBS

    assert RECOVERY_LIMBS == len(LIMBS)
    model = load_model("balan31")
    cfg = optim.get("refined-limbs", model=model, fps=20.0)
    per_limb = 1 + Recovery().n_samples * Recovery().n_rounds + Recovery().refine_budget + 2
    assert cfg.evals_per_frame == optim.get("refined", model=model, fps=20.0).evals_per_frame + len(LIMBS) * per_limb
    assert Recovery.from_settings(cfg.recovery) == Recovery(threshold=-1.0, terms="fitness", guard="silhouette")
    assert cfg.silhouette_height


def test_a_jump_margin_grows_with_how_far_the_limb_moves(setup):
    """``jump``: ``jump`` per 100 mm of the largest joint move; the left arm hangs straight in the frontal plane and
    abduction turns it about the axis through the shoulder normal to that plane, so the wrist moves by the chord
    ``2 L sin(theta / 2)``."""
    model, truth, fitness = setup
    j15 = model.spec.joints15
    sh, wr = j15.index("l_shoulder"), j15.index("l_wrist")
    arm = np.linalg.norm(np.diff(model.joints15(truth[None])[0, [sh, wr]], axis=0))
    for theta in (0.1, 0.5, 1.2):
        moved = truth.copy()
        moved[model.param_index("l_shoulder_abd")] += theta
        chord = 2 * arm * np.sin(theta / 2)
        assert Recovery(jump=0.01).jump_margin(model, truth, moved) == pytest.approx(0.01 * chord / 100, rel=1e-6)
        assert Recovery().jump_margin(model, truth, moved) == 0.0
    assert Recovery(jump=0.01).jump_margin(model, truth, truth) == 0.0


def test_a_jump_margin_keeps_the_limb_unless_the_search_scores_clearly_higher_for_its_move(setup):
    model, truth, fitness = setup
    lost = truth.copy()
    lost[model.param_index("r_shoulder_abd")] += np.radians(90)
    kw = dict(rng=np.random.default_rng(0), constraint=HardPriors(model).valid, sigma=model.sigma * 3.0)
    kept = Recovery(jump=1.0).run(fitness, model, lost, **kw)  # 1 per 100 mm: more than a 300 mm move can gain
    assert kept.lost == ["right_arm"] and kept.recovered == []
    np.testing.assert_array_equal(kept.x, lost)
    found = Recovery(jump=0.005).run(fitness, model, lost, **kw)  # the lost arm's gain is far above 0.005 per 100 mm
    assert found.recovered == ["right_arm"] and arm_error(model, found.x, truth) < 100
    assert Recovery.from_settings({"jump": 0.01}).jump == 0.01
