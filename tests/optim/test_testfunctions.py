"""Test functions: sign convention (scores = -f) and known optima."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.optim.testfunctions import (
    hierarchical_body,
    hierarchical_objective,
    planar_arm,
    rastrigin,
    rosenbrock,
    sphere,
    two_arms,
)


@pytest.mark.parametrize(
    ("f", "opt"),
    [(sphere, 0.0), (rosenbrock, 1.0), (rastrigin, 0.0)],
    ids=["sphere", "rosenbrock", "rastrigin"],
)
def test_benchmarks_are_scores_with_optimum_zero(f, opt):
    rng = np.random.default_rng(0)
    x = rng.uniform(-2, 2, (50, 10))
    s = f(x)
    assert s.shape == (50,) and np.all(s <= 0)
    assert f(np.full((1, 10), opt))[0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(s < 0)


def test_rastrigin_value():
    assert rastrigin(np.array([[1.0, 0.0]]))[0] == pytest.approx(-1.0)


@pytest.mark.parametrize("make", [planar_arm, two_arms])
def test_linkage_silhouette_ssd_zero_at_target_and_positive_elsewhere(make):
    rng = np.random.default_rng(1)
    d = 4 if make is planar_arm else 6
    t = rng.uniform(-1, 1, d)
    prob = make(t)
    assert prob(t[None])[0] == pytest.approx(0.0, abs=1e-12)
    others = t + rng.normal(0, 0.3, (20, d))
    assert np.all(prob(others) < 0)
    assert prob.joint_error(t[None])[0] == pytest.approx(0.0, abs=1e-12)


def test_planar_arm_root_dominates():
    # moving x1 moves every link; the same offset on x4 (the last link) costs less
    t = np.array([0.3, 0.4, -0.5, 0.6])
    prob = planar_arm(t)
    d = np.zeros(4)
    costs = []
    for i in range(4):
        e = d.copy()
        e[i] = 0.05
        costs.append(prob.ssd((t + e)[None])[0])
    assert costs == sorted(costs, reverse=True)


def test_hierarchical_body_and_objective_optimum():
    t = np.linspace(-0.5, 0.5, 11)
    prob, model = hierarchical_body(t)
    assert prob(t[None])[0] == pytest.approx(0.0, abs=1e-12)
    assert len(model.param_names) == 11 and model.group("left_arm").tolist() == [3, 4]
    with pytest.raises(KeyError):
        model.group("spine")
    obj, x0, model = hierarchical_objective(rng=np.random.default_rng(0))
    assert obj.dimension == 30 and x0.shape == (30,)
    assert obj(obj.target[None])[0] == pytest.approx(0.0, abs=1e-12)
    assert obj(x0[None])[0] < 0
