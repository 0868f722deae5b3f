"""The trunk's lean searched again, on a constructed frame: a trunk that leans by its spine, tracked leaning by its
pelvis."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINTS15
from swarmpose.optim import registry
from swarmpose.optim.variants import apply_variant
from swarmpose.track.lean import LeanSearch, lean_candidates


@pytest.fixture(scope="module")
def setup(bent_body_frame):
    """A body bent forward at the spine (0.5 rad), arms and legs bent a little, seen by 4 cameras."""
    return bent_body_frame({"spine_flex": 0.5, "l_shoulder_abd": 0.4, "r_shoulder_flex": 0.6, "r_elbow_flex": 0.5,
                            "l_hip_flex": 0.3, "r_hip_flex": 0.2, "l_knee_flex": 0.6})


def search(**kw) -> LeanSearch:
    return LeanSearch.from_settings({**registry.LEAN_SEARCH, **kw})


def joint_error(model, x, truth) -> float:
    return float(np.linalg.norm(model.joints15(x[None])[0] - model.joints15(truth[None])[0], axis=1).mean())


def test_a_lean_pitches_the_pelvis_and_keeps_the_upper_body(setup):
    """Each candidate pitches the pelvis by its degrees, the spine and the hips by as much the other way round and
    the same way: the shoulders, arms and head stay where they were; the legs move with the hips."""
    model, pose, _ = setup
    cands = lean_candidates(model, pose, (-20.0, 15.0))
    ip = model.param_index("pelvis_ry")
    np.testing.assert_allclose(cands[:, ip] - pose[ip], np.radians([-20.0, 15.0]))
    np.testing.assert_allclose(cands[:, model.param_index("spine_flex")] - pose[model.param_index("spine_flex")],
                               np.radians([20.0, -15.0]))
    j0, j = model.joints15(pose[None])[0], model.joints15(cands)
    upper = [JOINTS15.index(n) for n in ("thorax", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow",
                                         "r_wrist", "head_top")]
    np.testing.assert_allclose(j[:, upper], np.broadcast_to(j0[upper], j[:, upper].shape), atol=1e-6)
    knees = [JOINTS15.index("l_knee"), JOINTS15.index("r_knee")]
    assert (np.linalg.norm(j[:, knees] - j0[knees], axis=-1) > 5).all()
    # clipped to the joint limits: the pelvis cannot pitch past its own
    far = lean_candidates(model, pose, (80.0,))[0]
    assert far[ip] == model.upper[ip]


def test_a_trunk_leaned_by_the_pelvis_is_leaned_back_by_the_spine(setup):
    model, truth, fitness = setup
    leaned = lean_candidates(model, truth, (20.0,))[0]
    assert joint_error(model, leaned, truth) > 10  # the upper body in place: the legs moved with the hips
    out = search().run(fitness, model, leaned, HardPriors(model).valid, model.sigma * 3.0)
    assert out.leaned == -20.0
    assert out.score > fitness.evaluate(leaned[None])[0]
    assert joint_error(model, out.x, truth) < 5


def test_the_pose_is_kept_when_no_lean_scores_higher(setup):
    model, truth, fitness = setup
    s = search()
    out = s.run(fitness, model, truth, HardPriors(model).valid, model.sigma)
    assert out.leaned == 0.0 and out.score == pytest.approx(fitness.evaluate(truth[None])[0])
    np.testing.assert_array_equal(out.x, truth)
    assert len(s.degrees) + 1 < out.evaluations <= s.evaluations == 1 + 6 + 2 * 100


def test_settings_a_model_without_the_parameters_and_the_variant():
    assert LeanSearch.from_settings({}) is None
    for bad in ({**registry.LEAN_SEARCH, "margin": 0.1}, {**registry.LEAN_SEARCH, "degrees": (10.0, 0.0)},
                {**registry.LEAN_SEARCH, "n_best": 7}, {**registry.LEAN_SEARCH, "budget": 0}):
        with pytest.raises(ConfigError, match="lean search"):
            LeanSearch.from_settings(bad)
    stub = SimpleNamespace(name="stub", param_names=("pelvis_ry", "l_hip_flex", "r_hip_flex"))
    with pytest.raises(ConfigError, match="spine_flex"):
        lean_candidates(stub, np.zeros(3), (10.0,))
    model = load_model("balan31")
    cfg = registry.get("refined-heading", model=model, fps=20)
    on = apply_variant(cfg, "lean=on")
    assert not cfg.lean_search and dict(on.lean_search) == dict(registry.LEAN_SEARCH)
    assert on.evals_per_frame == cfg.evals_per_frame + 207
    assert apply_variant(on, "lean=off").evals_per_frame == cfg.evals_per_frame
    with pytest.raises(ConfigError, match="lean=on or lean=off"):
        apply_variant(cfg, "lean=yes")


def test_a_run_with_the_lean_search_counts_its_evaluations(short_sequence: Path, tmp_path: Path):
    """The tracker searches the lean on every frame: each frame's evaluations are the small search's and the
    lean's (its polishes can stop early), and the track differs from the one without it."""
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    cfg = TrackConfig(algo="refined", fps=20.0, seed=5, downsample=2, max_frames=3,
                      optim_variant="apf=20x2+refine=10+recovery=off+lean=on")
    leaned = run_tracker(prepare_track(short_sequence, cfg, tmp_path / "a"), 0)
    assert np.all(leaned.evaluations > 40 + 10 + 7) and np.all(leaned.evaluations <= 40 + 10 + 207)
    plain = run_tracker(prepare_track(short_sequence, dataclasses.replace(
        cfg, optim_variant="apf=20x2+refine=10+recovery=off"), tmp_path / "b"), 0)
    assert np.all(plain.evaluations == 40 + 10)
    assert not np.array_equal(plain.params, leaned.params)
