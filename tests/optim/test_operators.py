"""Pure operators: each checked against its equation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from swarmpose.optim import operators as op


def test_constriction_eq_5_9():
    assert op.constriction(2.05, 2.05) == pytest.approx(0.729843788, abs=1e-9)
    phi = 4.3
    assert op.constriction(2.15, 2.15) == pytest.approx(2 / abs(2 - phi - np.sqrt(phi**2 - 4 * phi)))
    assert op.constriction(2.15, 2.15) < op.constriction(2.05, 2.05)  # larger phi, faster convergence
    with pytest.raises(ValueError):
        op.constriction(2.0, 2.0)


def test_linear_coefficients_rise_from_start_to_end():
    c = op.linear_coefficients(2.05, 2.15, 39)
    assert c.shape == (39,) and c[0] == 2.05 and c[-1] == pytest.approx(2.15)
    assert np.all(np.diff(c) > 0)
    assert op.linear_coefficients(2.05, 2.15, 0).shape == (0,)
    assert op.linear_coefficients(2.05, 2.15, 1).tolist() == [2.05]


def test_constricted_velocity_matches_eq_5_8():
    rng = np.random.default_rng(3)
    v, x, p = rng.normal(size=(3, 4, 2))
    g = rng.normal(size=2)
    got = op.constricted_velocity(v, x, p, g, 2.1, 2.1, 0.7, np.random.default_rng(9))
    r = np.random.default_rng(9)
    e1, e2 = r.random((4, 2)), r.random((4, 2))
    assert np.allclose(got, 0.7 * (v + 2.1 * e1 * (p - x) + 2.1 * e2 * (g - x)))


@pytest.mark.parametrize("seed", range(4))
def test_constricted_move_equals_the_plain_operators_bit_for_bit(seed):
    """The compiled move is clamp_velocity(constricted_velocity(...)) and x + v to the last bit, drawing the same
    random numbers (the optimisers' results must not change), on any subset of rows, NaN and saturation included."""
    rng = np.random.default_rng(seed)
    n, d = 9, 31
    v, x, p = rng.normal(0.0, 3.0, size=(3, n, d))
    x[2, 4] = np.nan
    g = rng.normal(size=d)
    vmax = rng.uniform(0.1, 2.0, d)
    rows = np.sort(rng.choice(n, size=int(rng.integers(1, n + 1)), replace=False))
    c, chi = 2.05 + 0.03 * seed, 0.73
    a, b = np.random.default_rng(100 + seed), np.random.default_rng(100 + seed)
    x_new, v_new = op.constricted_move(v, x, p, g, rows, c, c, chi, vmax, a)
    v_ref = op.clamp_velocity(op.constricted_velocity(v[rows], x[rows], p[rows], g, c, c, chi, b), vmax)
    assert np.array_equal(v_new, v_ref, equal_nan=True)
    assert np.array_equal(x_new, x[rows] + v_ref, equal_nan=True)
    assert np.any(np.abs(v_ref) == vmax)  # some components saturate
    assert a.random() == b.random()  # the same numbers drawn


def test_clamp_velocity():
    v = np.array([[3.0, -3.0], [0.1, -0.1]])
    assert np.array_equal(op.clamp_velocity(v, np.array([1.0, 2.0])), [[1.0, -2.0], [0.1, -0.1]])


def test_personal_and_global_best():
    px, ps = np.zeros((3, 2)), np.array([1.0, 2.0, -np.inf])
    x = np.ones((3, 2))
    nx, ns = op.update_personal_best(px, ps, x, np.array([0.5, 3.0, -np.inf]))
    assert ns.tolist() == [1.0, 3.0, -np.inf]
    assert nx[:, 0].tolist() == [0.0, 1.0, 0.0]  # -inf never replaces, even -inf
    assert op.global_best(ns) == 1


def test_survival_rate_eq_11_12():
    s = np.log(np.array([1.0, 1.0, 2.0, 4.0]))  # scores are log-weights
    pi = np.array([1, 1, 2, 4]) / 8
    assert op.survival_rate(s, 1.0) == pytest.approx(1 / np.sum(pi**2) / 4)
    assert op.survival_rate(s, 0.0) == pytest.approx(1.0)


@pytest.mark.parametrize("alpha", [0.1, 0.5, 0.8])
def test_find_beta_meets_target_alpha(alpha):
    rng = np.random.default_rng(int(alpha * 10))
    s = rng.normal(size=200) * 3.0
    beta = op.find_beta(s, alpha)
    assert op.survival_rate(s, beta) == pytest.approx(alpha, rel=1e-6)
    # the annealing weights are invariant to affine rescaling of the scores
    beta2 = op.find_beta(5.0 * s - 7.0, alpha)
    assert beta2 == pytest.approx(beta / 5.0, rel=1e-6)
    assert np.allclose(op.annealing_weights(5.0 * s - 7.0, beta2), op.annealing_weights(s, beta), atol=1e-9)


def test_find_beta_edge_cases():
    assert op.find_beta(np.zeros(10), 0.5) == 0.0  # all equal: uniform at any beta
    s = np.array([0.0, 1.0, -np.inf, -np.inf, -np.inf, -np.inf])
    assert op.find_beta(s, 0.5) == 0.0  # only 2 of 6 valid: D/N <= 1/3 already at beta = 0
    s = np.array([3.0, 3.0, 3.0, 0.0])
    assert op.find_beta(s, 0.5) == np.inf  # 3 tied best: D/N -> 3/4 > alpha
    w = op.annealing_weights(s, np.inf)
    assert w.tolist() == [1 / 3, 1 / 3, 1 / 3, 0.0]
    w = op.annealing_weights(np.array([1.0, -np.inf]), 2.0)
    assert w.tolist() == [1.0, 0.0]


@pytest.mark.parametrize("resample", [op.resample_multinomial, op.resample_systematic])
def test_resampling_frequencies_follow_weights(resample):
    w = np.array([0.5, 0.25, 0.125, 0.125, 0.0])
    idx = resample(w, 40000, np.random.default_rng(0))
    counts = np.bincount(idx, minlength=5)
    assert counts[4] == 0
    chi = stats.chisquare(counts[:4], 40000 * w[:4])
    assert chi.pvalue > 1e-3


def test_crossover_eq_19_takes_one_contiguous_block_from_b():
    rng = np.random.default_rng(0)
    a, b = np.zeros((500, 6)), np.ones((500, 6))
    c = op.crossover(a, b, rng)
    for row in c:
        j = np.flatnonzero(row)
        assert j.size >= 1 and np.all(np.diff(j) == 1)  # non-empty contiguous block
    # every parameter (x1 included) can come from b, and whole arms are swapped sometimes
    assert np.all(c.mean(axis=0) > 0.1)
    assert np.any(np.all(c == [0, 0, 0, 1, 1, 1], axis=1))


def test_adaptive_diffusion_covariance_eq_18():
    rng = np.random.default_rng(1)
    s = rng.multivariate_normal([0, 0, 0], [[1.0, 0.8, 0.0], [0.8, 1.0, 0.0], [0.0, 0.0, 0.01]], size=50)
    cov = np.cov(s.T, bias=True)
    noise = np.concatenate([op.adaptive_diffusion(s, 0.3, rng) for _ in range(400)])
    assert noise.shape == (20000, 3)
    assert np.allclose(np.cov(noise.T, bias=True), 0.3 * cov, atol=0.03)
    frozen = s.copy()
    frozen[:, 2] = 4.0  # a parameter without spread gets no noise
    assert np.all(op.adaptive_diffusion(frozen, 0.5, rng)[:, 2] == 0.0)


def test_kernel_bandwidth():
    assert op.kernel_bandwidth(4, 100) == pytest.approx((4 / 600) ** (2 / 8))
    assert op.kernel_bandwidth(30, 100) > op.kernel_bandwidth(4, 100)  # wider in more dimensions
    assert op.kernel_bandwidth(4, 25) > op.kernel_bandwidth(4, 100)  # wider for fewer particles


def test_weighted_mean_eq_8():
    s = np.array([[0.0, 0.0], [2.0, 4.0]])
    assert op.weighted_mean(s, np.array([0.75, 0.25])).tolist() == [0.5, 1.0]


def test_aapso_alpha_eq_17():
    assert op.aapso_alpha(0, 10) == 1.0
    assert op.aapso_alpha(10, 10) == pytest.approx(0.2)


def test_aapso_velocity_eq_15():
    rng = np.random.default_rng(2)
    x, p = rng.normal(size=(2, 5, 3))
    g = rng.normal(size=3)
    var = np.array([0.5, 0.0, 2.0])
    got = op.aapso_velocity(x, p, g, var, np.random.default_rng(4))
    r = np.random.default_rng(4)
    b = np.sqrt(var) * r.standard_normal((5, 3))
    f1, f2 = r.random((5, 3)), r.random((5, 3))
    assert np.allclose(got, b + f1 * (p - x) + f2 * (g - x))


def test_redraw_invalid_redraws_only_violating_rows_at_most_max():
    calls = []

    def propose(rows):
        calls.append(rows.copy())
        return (np.full((rows.size, 1), float(len(calls))),)

    # valid when the value is >= the row's threshold; row 2 never becomes valid
    thresholds = np.array([1.0, 3.0, 99.0, 2.0])

    def is_valid(x):
        rows = calls[-1]
        return x[:, 0] >= thresholds[rows]

    (x,), valid = op.redraw_invalid(propose, is_valid, 4, max_redraws=10)
    assert calls[0].tolist() == [0, 1, 2, 3]
    assert calls[1].tolist() == [1, 2, 3]
    assert calls[2].tolist() == [1, 2]
    assert all(c.tolist() == [2] for c in calls[3:])
    assert len(calls) == 11  # first draw + 10 re-draws
    assert valid.tolist() == [True, True, False, True]
    assert x[:, 0].tolist() == [1.0, 3.0, 11.0, 2.0]


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 12), st.integers(1, 5), st.integers(0, 2 ** 32 - 1))
def test_compiled_tell_is_the_plain_update_and_global_best(n, d, seed):
    """``tell_personal_best`` = ``update_personal_best`` of the valid rows' scores, then ``global_best``:
    the same bests bit for bit, ties (first index) and ``-inf`` rows included."""
    rng = np.random.default_rng(seed)
    pool = np.array([-np.inf, -1.0, 0.0, 0.5, 2.0])  # few values: many ties
    px, ps = rng.normal(size=(n, d)), rng.choice(pool, n)
    x, s, valid = rng.normal(size=(n, d)), rng.choice(pool, n), rng.random(n) < 0.7
    want_x, want_s = op.update_personal_best(px, ps, x, np.where(valid, s, -np.inf))
    got_x, got_s = px.copy(), ps.copy()
    g = op.tell_personal_best(valid, s, x, got_x, got_s)
    np.testing.assert_array_equal(got_x, want_x)
    np.testing.assert_array_equal(got_s, want_s)
    assert g == op.global_best(want_s)
