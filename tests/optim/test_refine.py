"""Local refinement (pattern search), wide box search and chaining: toy problems with known optima."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.optim.apf import AnnealedParticleFilter
from swarmpose.optim.base import ConfigError, optimize
from swarmpose.optim.refine import BoxSearch, Chain, PatternSearch, polish_best


def quadratic(centre, scales):
    c, s = np.asarray(centre, float), np.asarray(scales, float)
    return lambda x: -(((x - c) / s) ** 2).sum(axis=1)


def test_pattern_search_reaches_a_nearby_optimum_within_its_budget():
    d = 31
    rng = np.random.default_rng(0)
    centre = rng.normal(0, 1, d)
    f = quadratic(centre, np.linspace(0.5, 2.0, d))
    x0 = centre + rng.normal(0, 0.3, d)
    opt = PatternSearch(x0, np.full(d, 0.2), 600)
    res = optimize(opt, f)
    assert res.evaluations <= 600
    assert np.abs(res.x - centre).max() < 0.02
    assert res.score > f(x0[None])[0]


def test_pattern_search_moves_many_coordinates_together():
    """A ridge along (1, 1, ..., 1): no single coordinate's move climbs it; the gradient line does."""
    d = 10
    u = np.ones(d) / np.sqrt(d)

    def ridge(x):
        along = x @ u
        across = x - np.outer(along, u)
        return -(along - 3.0) ** 2 - 50.0 * (across**2).sum(axis=1)

    x0 = np.zeros(d)
    h = np.full(d, 0.1)
    single = ridge(np.concatenate([x0 + np.diag(h), x0 - np.diag(h)]))
    assert single.max() < ridge(x0[None])[0]  # every coordinate move alone is worse
    res = optimize(PatternSearch(x0, h, 400), ridge)
    assert res.x @ u == pytest.approx(3.0, abs=0.05)


def test_pattern_search_respects_bounds_and_constraint():
    d = 4
    f = quadratic(np.full(d, 5.0), np.ones(d))  # optimum outside the box
    lower, upper = -np.ones(d), np.ones(d)

    def constraint(x):
        return x[:, 0] <= 0.5  # the first coordinate may not pass 0.5

    seen = []

    def recorded(x):
        seen.append(x.copy())
        return f(x)

    res = optimize(PatternSearch(np.zeros(d), np.full(d, 0.3), 300, lower=lower, upper=upper,
                                 constraint=constraint), recorded)
    allx = np.concatenate(seen)
    assert np.all(allx >= lower) and np.all(allx <= upper)
    assert np.all(constraint(allx))
    np.testing.assert_allclose(res.x[1:], 1.0)
    assert res.x[0] == pytest.approx(0.5, abs=0.02)


def test_pattern_search_holds_zero_step_coordinates_and_stops_when_converged():
    f = quadratic([1.0, 2.0, 3.0], [1, 1, 1])
    opt = PatternSearch([0.0, 0.0, 0.0], [0.5, 0.0, 0.5], 10_000, min_step=1e-4)
    res = optimize(opt, f)
    assert res.x[1] == 0.0
    assert res.x[0] == pytest.approx(1.0, abs=1e-3) and res.x[2] == pytest.approx(3.0, abs=1e-3)
    assert res.evaluations < 10_000  # stopped once the steps were below min_step


def test_pattern_search_is_deterministic_and_checks_its_settings():
    f = quadratic(np.arange(5.0), np.ones(5))
    a = optimize(PatternSearch(np.zeros(5), np.ones(5), 200), f)
    b = optimize(PatternSearch(np.zeros(5), np.ones(5), 200), f)
    np.testing.assert_array_equal(a.x, b.x)
    with pytest.raises(ConfigError):
        PatternSearch(np.zeros(5), -np.ones(5), 10)
    with pytest.raises(ConfigError):
        PatternSearch(np.zeros(5), np.ones(5), 0)


def test_box_search_finds_a_far_optimum_of_its_coordinates_only():
    d = 6
    mask = np.array([False, False, True, True, False, False])
    lower, upper = -np.full(d, 3.0), np.full(d, 3.0)
    target = np.array([0.0, 0.0, 2.5, -2.0, 0.0, 0.0])
    x0 = np.array([0.1, -0.1, -2.5, 2.0, 0.2, 0.0])  # the masked pair starts on the far side of the box
    f = quadratic(target, np.ones(d))
    opt = BoxSearch(x0, mask, lower, upper, np.random.default_rng(1), n_samples=50, n_rounds=4)
    res = optimize(opt, f)
    assert res.evaluations == opt.budget == 1 + 50 * 4
    np.testing.assert_array_equal(res.x[~mask], x0[~mask])
    assert np.abs(res.x[mask] - target[mask]).max() < 0.3
    with pytest.raises(ConfigError, match="finite bounds"):
        BoxSearch(x0, mask, np.full(d, -np.inf), upper, np.random.default_rng(1))


def test_chain_runs_members_in_turn_and_carries_the_first_ones_state():
    d = 3
    f = quadratic([0.5, -0.5, 0.2], np.ones(d))
    first = AnnealedParticleFilter.start(np.zeros(d), np.full(d, 0.3), 40, 3, np.random.default_rng(0))
    chain = Chain(first, [lambda x, s: PatternSearch(x, np.full(d, 0.05), 100)])
    res = optimize(chain, f)
    assert res.evaluations == 40 * 3 + 100
    assert np.abs(res.x - [0.5, -0.5, 0.2]).max() < 0.01
    assert chain.carry() is not None
    assert isinstance(chain.members[1], PatternSearch)


def test_line_moves_equal_the_plain_version_to_the_last_bit():
    """The compiled Newton and gradient moves equal :func:`line_moves_reference`, bit for bit: polls with both
    sides, one side (the other invalid or clipped away at a bound), none, steps of 0, ties and scores that are all
    equal."""
    from swarmpose.optim.refine import line_moves_reference

    rng = np.random.default_rng(5)
    for case in range(400):
        d = int(rng.integers(1, 12))
        x = rng.normal(0.0, 1.0, d)
        h = np.abs(rng.normal(0.0, 0.3, d)) * (rng.random(d) > 0.2)  # some coordinates held
        active = np.flatnonzero(h > 0)
        eye = np.eye(d)[active] * h[active, None]
        asked = np.concatenate([x + eye, x - eye])
        keep = rng.random(len(asked)) > 0.25  # moves dropped (invalid, or equal to x after clipping)
        asked = asked[keep]
        scores = rng.normal(0.0, 1.0, len(asked))
        if case % 5 == 0:
            scores[rng.random(len(asked)) < 0.3] = rng.choice([np.nan, -np.inf])
        if case % 7 == 0:
            scores[:] = 0.5  # flat: no gradient, Newton steps of sign 0
        fx = float(rng.normal())
        opt = PatternSearch(x, np.where(h > 0, h, 0.0), 100, newton=(0.5, 1.0), gradient=(0.25, 1.0, 4.0))
        opt.h = h.copy()
        got = opt._line_moves(asked, scores, fx, x)
        want = line_moves_reference(asked, scores, fx, x, h, opt.newton, opt.gradient)
        assert got.shape == want.shape
        assert np.array_equal(got, want), case


def test_polish_best_climbs_from_the_best_few_and_keeps_what_beats_the_bar():
    """The two best-scored starts are polished (the third, better placed but scored lower, is not), the best
    polished one is returned with its start's index while it beats ``above``; a non-finite score ends the list."""
    target = np.array([1.0, -2.0, 0.5])

    def score(poses: np.ndarray) -> np.ndarray:
        return -np.sum((np.asarray(poses) - target) ** 2, axis=1)

    cands = np.array([[3.0, -2.0, 0.5], [1.0, 1.0, 0.5], [1.2, -2.0, 0.5], [9.0, 9.0, 9.0]])
    scores = np.array([-0.5, -0.1, -9.0, np.nan])  # the third is nearest but scored lowest: not tried
    lo, hi = np.full(3, -10.0), np.full(3, 10.0)
    x, s, k, n = polish_best(score, cands, scores, 2, np.full(3, 0.5), 60, lo, hi)
    assert k in (0, 1) and n == 120 and s > -1e-3
    np.testing.assert_allclose(x, target, atol=0.05)
    none = polish_best(score, cands, scores, 2, np.full(3, 0.5), 60, lo, hi, above=1.0)
    assert none[0] is None and none[1] == 1.0 and none[2] == -1 and none[3] == 120
    stop = polish_best(score, cands, np.array([np.nan, -np.inf, -np.inf, -np.inf]), 3, np.full(3, 0.5), 60, lo, hi)
    assert stop == (None, -np.inf, -1, 0)
