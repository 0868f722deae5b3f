"""The tracker's constraint: the hard priors as a callable, and PSO's constrained moves compiled with the same
numbers as the plain path."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.optim.pso import ConstrictedPSO, StagedPSO
from swarmpose.optim.staged import Stage
from swarmpose.track.constraint import PriorsConstraint
from swarmpose.track.timing import PartTimer


@pytest.fixture(scope="module")
def model():
    return load_model("balan31")


def _start(model, rng):
    """A pose with both elbows and knees near their limits, the arms near the torso: moves leave the limits
    and collide often."""
    x = model.zero_pose() + 0.01 * rng.standard_normal(model.n_params) * np.isfinite(model.lower)
    x[model.param_index("pelvis_tz")] = 1000.0
    x[model.param_index("l_shoulder_abd")] = 0.35
    x[model.param_index("r_shoulder_abd")] = 0.35
    for name in ("l_elbow_flex", "r_elbow_flex", "l_knee_flex", "r_knee_flex"):
        i = model.param_index(name)
        x[i] = model.upper[i] - 0.02
    return x


class _Counting:
    """The plain constraint (no ``constricted_moves``), counting its calls."""

    def __init__(self, fn):
        self.fn = fn
        self.calls = 0

    def __call__(self, poses):
        self.calls += 1
        return self.fn(poses)


def _run(opt, target, iterations):
    asks, valids = [], []
    for _ in range(iterations):
        x = opt.ask()
        asks.append(x.copy())
        valids.append(getattr(opt, "valid", None))
        opt.tell(-np.abs(x - target).sum(axis=1))
    return asks, valids


@pytest.mark.parametrize(("collisions", "tolerance", "max_redraws", "seed", "coupled"),
                         [(True, 0.5, 10, 0, False), (True, 0.5, 10, 1, False), (False, 0.5, 10, 2, False),
                          (True, 0.0, 0, 3, False), (True, 0.0, 2, 4, False), (True, 0.5, 10, 5, True)])
def test_compiled_moves_are_the_plain_moves(model, collisions, tolerance, max_redraws, seed, coupled):
    priors = HardPriors(model, penetration_tolerance=tolerance, check_collisions=collisions, coupled_limits=coupled)
    x0 = _start(model, np.random.default_rng(seed))
    if coupled:  # the right arm raised near both 90-degree bounds of the coupled limit: moves cross it often
        x0[model.param_index("r_shoulder_abd")] = x0[model.param_index("r_shoulder_flex")] = np.radians(88.0)
    sigma = 3.0 * model.sigma  # wide moves: many leave the limits or collide, some stay invalid after the re-draws
    target = x0 + 5.0 * model.sigma
    plain = _Counting(priors.valid)
    runs = {}
    for name, constraint in (("plain", plain), ("compiled", PriorsConstraint(priors))):
        rng = np.random.default_rng(seed)
        opt = ConstrictedPSO(x0, sigma, 12, 15, rng, lower=model.lower, upper=model.upper, constraint=constraint,
                             max_redraws=max_redraws)
        runs[name] = (*_run(opt, target, 15), rng.random(4), opt.best)
    (a_p, v_p, r_p, b_p), (a_c, v_c, r_c, b_c) = runs["plain"], runs["compiled"]
    for k, (xp, xc) in enumerate(zip(a_p, a_c, strict=True)):
        assert np.array_equal(xp, xc), f"ask {k} differs"
    for vp, vc in zip(v_p, v_c, strict=True):
        assert np.array_equal(vp, vc)
    assert np.array_equal(r_p, r_c)  # the generator was left in the same state
    assert np.array_equal(b_p.x, b_c.x) and b_p.score == b_c.score
    # the case is not trivial: moves were re-drawn, some rows clipped onto a bound, some stayed invalid
    assert plain.calls > 15  # one call per ask without re-draws
    moved = np.concatenate(a_p[1:])
    assert np.any((moved == model.lower) | (moved == model.upper))
    if tolerance == 0.0:  # any contact collides: some moves stay invalid after their re-draws
        assert not np.all(np.concatenate(v_p[1:]))
    if coupled:  # without the coupled limit the same swarm goes into the region; with it no valid move lies there
        def inside(x):
            return (x[:, model.param_index("r_shoulder_abd")] > np.pi / 2) & (
                x[:, model.param_index("r_shoulder_flex")] > np.pi / 2)

        free = ConstrictedPSO(x0, sigma, 12, 15, np.random.default_rng(seed), lower=model.lower, upper=model.upper,
                              constraint=PriorsConstraint(HardPriors(model, penetration_tolerance=tolerance)),
                              max_redraws=max_redraws)
        free_asks, free_valid = _run(free, target, 15)
        assert any((inside(x) & v).any() for x, v in zip(free_asks[1:], free_valid[1:], strict=True))
        assert not any((inside(x) & v).any() for x, v in zip(a_p[1:], v_p[1:], strict=True))


def test_staged_pso_with_the_compiled_moves(model):
    priors = HardPriors(model)
    x0 = _start(model, np.random.default_rng(7))
    every, ones = np.ones(model.n_params, bool), np.ones(model.n_params)
    stages = [Stage("one", every, ones, 10, 6), Stage("two", every, 0.5 * ones, 20, 6)]
    target = x0 + 2.0 * model.sigma
    out = []
    for constraint in (priors.valid, PriorsConstraint(priors)):
        opt = StagedPSO(x0, 2.0 * model.sigma, stages, np.random.default_rng(7), lower=model.lower,
                        upper=model.upper, constraint=constraint)
        out.append(_run(opt, target, 12)[0])
    for xp, xc in zip(*out, strict=True):
        assert np.array_equal(xp, xc)


def test_calls_are_the_priors_and_timed(model):
    priors = HardPriors(model)
    timer = PartTimer()
    c = PriorsConstraint(priors, timer)
    rng = np.random.default_rng(0)
    poses = model.zero_pose() + rng.normal(0.0, 1.0, (50, model.n_params)) * model.sigma * 10
    assert np.array_equal(c(poses), priors.valid_reference(poses))
    assert timer.seconds["priors"] > 0.0
