"""Annealed particle filter (Deutscher & Reid 2005): unit behaviour and the paper's toy claims."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.optim import AnnealedParticleFilter, ParticleSet, optimize
from swarmpose.optim.testfunctions import planar_arm, sphere, two_arms


def _run(apf, f, record=None):
    while not apf.done:
        x = apf.ask()
        if record is not None:
            record(apf, x)
        apf.tell(f(x))
    return apf


# -- unit behaviour ------------------------------------------------------------------------------------
def test_each_layer_meets_the_survival_rate_target():
    rng = np.random.default_rng(0)
    apf = AnnealedParticleFilter(np.zeros((100, 3)), np.ones(3), 4, rng, alpha=0.3)
    rates = []
    while not apf.done:
        x = apf.ask()
        s = sphere(x - 0.5)
        apf.tell(s)
        rates.append(1.0 / np.sum(apf.weights**2) / 100)  # D/N, eq. 11-12
    assert np.allclose(rates, 0.3, rtol=1e-6)
    assert len(apf.betas) == 4 and all(b > 0 for b in apf.betas)


def test_scores_are_log_weights_scale_invariant():
    """beta absorbs any positive scaling of the fitness: same seed, same particles."""

    def asks(scale):
        apf = AnnealedParticleFilter(np.zeros((50, 2)), np.ones(2), 4, np.random.default_rng(1))
        out = []
        _run(apf, lambda x: scale * sphere(x - 1.0) + 3.0, lambda a, x: out.append(x))
        return out

    for a, b in zip(asks(1.0), asks(250.0), strict=True):
        assert np.allclose(a, b)


def test_estimate_is_weighted_mean_and_carry_is_final_weighted_set():
    apf = _run(AnnealedParticleFilter(np.zeros((80, 2)), np.ones(2), 3, np.random.default_rng(2)), sphere)
    assert np.allclose(apf.best.x, apf.weights @ apf.particles)  # eq. 8
    c = apf.carry()
    assert isinstance(c, ParticleSet) and np.array_equal(c.particles, apf.particles)
    assert c.weights.sum() == pytest.approx(1.0)
    assert apf.best_particle.score >= apf.best.score  # the mean's score is the weighted mean score
    with pytest.raises(RuntimeError):
        AnnealedParticleFilter(np.zeros((5, 2)), np.ones(2), 2, np.random.default_rng(0)).carry()


def test_a_proposal_takes_its_share_of_the_carried_weight():
    """``with_proposal``: the lowest-weight quarter of the set becomes the proposal, which weighs a quarter; the
    others keep their proportions; the next frame's resampling draws it in about a quarter of its centres."""
    from swarmpose.optim.base import ConfigError, ShapeError

    rng = np.random.default_rng(4)
    n, d = 200, 3
    carried = ParticleSet(rng.normal(size=(n, d)), rng.random(n) + 0.01)
    x = np.array([5.0, -5.0, 5.0])
    prop = carried.with_proposal(x, 0.25)
    is_x = np.all(prop.particles == x, axis=1)
    low = np.argsort(carried.weights, kind="stable")[:50]
    assert is_x.sum() == 50 and set(np.flatnonzero(is_x)) == set(low.tolist())
    assert prop.weights[is_x].sum() == pytest.approx(0.25) and prop.weights.sum() == pytest.approx(1.0)
    kept = ~is_x
    np.testing.assert_array_equal(prop.particles[kept], carried.particles[kept])
    np.testing.assert_allclose(prop.weights[kept] / prop.weights[kept].sum(),
                               carried.weights[kept] / carried.weights[kept].sum())
    assert carried.with_proposal(x, 0.0) is carried
    assert np.all(carried.with_proposal(x, 0.001).particles == x, axis=1).sum() == 1  # at least one
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(ConfigError, match="share"):
            carried.with_proposal(x, bad)
    with pytest.raises(ShapeError):
        carried.with_proposal(np.zeros(2), 0.25)
    with pytest.raises(ShapeError, match="one particle"):
        ParticleSet(np.zeros((1, d)), np.ones(1)).with_proposal(x, 0.25)
    # resampled as the next frame's centres: about 50 of 200 at the proposal (binomial sd 6.1; 4 sd margin)
    apf = AnnealedParticleFilter.start(np.zeros(d), np.full(d, 1e-9), n, 2, np.random.default_rng(5), carry=prop)
    near = np.all(np.abs(apf.ask() - x) < 1e-6, axis=1).sum()
    assert 26 <= near <= 74


def test_next_frame_starts_from_carried_set_plus_b0():
    """eq. 9: S_{t+1,M} = resampled S_{t,0} + B_0."""
    rng = np.random.default_rng(3)
    first = _run(AnnealedParticleFilter.start(np.full(2, 5.0), np.full(2, 0.5), 200, 4, rng), sphere)
    carried = first.carry()
    sigma0 = np.array([1e-9, 1e-9])
    nxt = AnnealedParticleFilter.start(np.zeros(2), sigma0, 200, 2, np.random.default_rng(4), carry=carried)
    x = nxt.ask()
    # every new particle sits (up to 1e-9 noise) on a carried particle with positive weight; x0 is ignored
    d = np.abs(x[:, None, :] - carried.particles[None]).max(axis=2)
    src = d.argmin(axis=1)
    assert np.all(d.min(axis=1) < 1e-7)
    assert np.all(carried.weights[src] > 0)
    with pytest.raises(ValueError):
        AnnealedParticleFilter.start(np.zeros(2), sigma0, 100, 2, np.random.default_rng(0), carry=carried)


def test_fixed_schedule_shrinks_noise_by_alpha_per_layer():
    """eq. 13: P after layer l is alpha^l P_0 (flat fitness: pure diffusion)."""
    sigma0 = np.array([1.0, 2.0])
    apf = AnnealedParticleFilter(np.zeros((4000, 2)), sigma0, 4, np.random.default_rng(5), diffusion="fixed")
    stds = []

    def record(a, x):
        stds.append((x - a.parents).std(axis=0))

    _run(apf, lambda x: np.zeros(len(x)), record)
    for layer, s in enumerate(stds):  # layer 0: B_0 ~ N(0, P_0)
        assert np.allclose(s, sigma0 * np.sqrt(0.5**layer), rtol=0.05)


def test_adaptive_noise_follows_set_covariance_and_spares_frozen_parameters():
    sigma0 = np.array([1.0, 0.0, 0.3])
    apf = AnnealedParticleFilter(np.zeros((300, 3)), sigma0, 3, np.random.default_rng(6), diffusion_scale=0.5)
    out = []

    def record(a, x):
        out.append((x.copy(), a.parents.copy()))

    _run(apf, lambda x: -np.abs(x[:, 0] - 0.5), record)
    for x, _ in out:
        assert np.all(x[:, 1] == 0.0)  # no spread -> no noise (eq. 18)
    x, parents = out[1]
    # shrink by sqrt(1 - c) towards the mean, add N(0, c Cov): the diffused set keeps the parents' mean
    # and variances (DR05 sec. 6.1: "not enough to increase the variance of any given parameter") ...
    for j in (0, 2):
        assert x[:, j].var() == pytest.approx(parents[:, j].var(), rel=0.25)
        assert abs(x[:, j].mean() - parents[:, j].mean()) < 0.15 * parents[:, j].std()
    # ... while every particle moves off its parent (the gaps between repeated draws get filled):
    # x - parents = (sqrt(1 - c) - 1)(p - mean) + noise, variance ((1 - sqrt(0.5))^2 + 0.5) Var(p)
    moved = x - parents
    assert moved[:, 0].var() == pytest.approx((0.5 + (1 - np.sqrt(0.5)) ** 2) * parents[:, 0].var(), rel=0.25)


def test_adaptive_diffusion_keeps_unlocalised_parameters_from_growing():
    """A 31-D set whose weights depend on one parameter: over 10 layers the other 30 keep their spread
    (plain N(0, c Cov) noise with c = 0.68 would multiply their variance by ~1.68 per layer)."""
    d = 31
    x0 = np.zeros(d)
    apf = AnnealedParticleFilter.start(x0, np.full(d, 0.1), 200, 10, np.random.default_rng(3))
    stds = []
    _run(apf, lambda x: -50.0 * np.abs(x[:, 0] - 0.05), lambda a, x: stds.append(x.std(axis=0)))
    first, last = stds[0], stds[-1]
    assert np.all(last[1:] < 1.5 * first[1:]), last[1:] / first[1:]
    assert last[0] < 0.5 * first[0]  # the parameter that matters is localised


def test_crossover_fraction_mixes_parents():
    """eq. 19: a fraction of the new particles take a parameter block from a second weighted draw.

    Half the particles are 0, half 1, weights uniform. A crossover child mixes 0s and 1s when its two
    parents come from different halves (1/2) and the block is not all 4 parameters (9 of the 10 cut pairs):
    0.45 of the children, so 0.225 of the set at a crossover fraction of 0.5 (SD 0.006 with 4000 particles).
    """
    n = 4000
    init = np.concatenate([np.zeros((n // 2, 4)), np.ones((n // 2, 4))])

    def mixed(frac):
        apf = AnnealedParticleFilter(
            init, np.zeros(4), 2, np.random.default_rng(7), crossover=frac, diffuse_first=False
        )
        apf.ask()
        apf.tell(np.zeros(n))  # flat: uniform weights
        apf.ask()
        p = apf.parents
        return float(np.mean(p.min(axis=1) != p.max(axis=1)))

    assert mixed(0.0) == 0.0
    assert abs(mixed(0.5) - 0.225) < 0.025
    assert abs(mixed(1.0) - 0.45) < 0.03


@pytest.mark.parametrize("resampling", ["multinomial", "systematic"])
def test_crossed_particles_are_a_random_share_of_the_set(monkeypatch, resampling):
    """The crossover fraction is taken from anywhere in the resampled set. Systematic resampling returns its
    pointers sorted; crossing its first rows would cross only the lowest-numbered particles."""
    import swarmpose.optim.apf as apf_module

    n = 2000
    init = np.repeat(np.arange(n, dtype=float)[:, None], 3, axis=1)  # particle i is (i, i, i)
    seen = []
    real = apf_module.crossover
    monkeypatch.setattr(apf_module, "crossover", lambda a, b, rng: seen.append(a[:, 0].copy()) or real(a, b, rng))
    apf = AnnealedParticleFilter(init, np.zeros(3), 2, np.random.default_rng(3), crossover=0.25,
                                 diffuse_first=False, resampling=resampling)
    apf.ask()
    apf.tell(np.zeros(n))  # uniform weights
    apf.ask()
    (a,) = seen
    assert len(a) == 500
    # uniform over 0..1999: mean 999.5, SD of the mean of 500 about 26; sorted first rows would give ~250
    assert abs(a.mean() - 999.5) < 120 and a.min() < 200 and a.max() > 1800


def test_constraint_violations_get_zero_weight():
    def constraint(p):
        return p[:, 0] > 0

    apf = AnnealedParticleFilter(
        np.zeros((100, 2)), np.ones(2), 3, np.random.default_rng(8), constraint=constraint, max_redraws=0
    )
    x = apf.ask()
    apf.tell(-np.sum((x + 1) ** 2, axis=1))  # the optimum (-1, -1) is invalid
    assert np.all(apf.weights[~constraint(x)] == 0.0)
    _run(apf, lambda p: -np.sum((p + 1) ** 2, axis=1))
    assert apf.best.x[0] > 0


def test_budget_and_determinism():
    def asks(seed):
        out = []
        apf = AnnealedParticleFilter.start(
            np.ones(3), np.ones(3), 40, 5, np.random.default_rng(seed), crossover=0.3
        )
        _run(apf, sphere, lambda a, x: out.append(x))
        return out, apf.evaluations

    a, n = asks(1)
    b, _ = asks(1)
    assert n == 200 and len(a) == 5
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    res = optimize(
        AnnealedParticleFilter.start(np.ones(3), np.ones(3), 40, 5, np.random.default_rng(2)), sphere
    )
    assert res.evaluations == 200 and res.score > -1.0  # from -3 at the start


# -- DR05 toy claims ---------------------------------------------------------------------------------
def _normalised_variances(diffusion, trials=20, n=200, layers=6, half_width=0.6):
    """DR05 sec. 6.1: uniform initial set around a 4-link arm; per-layer variance / initial variance."""
    rng0 = np.random.default_rng(2005)
    var = np.zeros((trials, layers, 4))
    for k in range(trials):
        truth = rng0.uniform(-1.0, 1.0, 4)
        prob = planar_arm(truth)
        rng = np.random.default_rng([2005, k])
        init = truth + rng.uniform(-half_width, half_width, (n, 4))
        apf = AnnealedParticleFilter(
            init, np.full(4, half_width / np.sqrt(3)), layers, rng, diffusion=diffusion, diffuse_first=False
        )

        def record(a, x, k=k):
            var[k, a.layer] = x.var(axis=0) / (half_width**2 / 3)

        _run(apf, prob, record)
    return np.median(var, axis=0)


@pytest.mark.slow
def test_dr05_fig12_13_adaptive_diffusion_localises_hierarchically():
    adaptive = _normalised_variances("adaptive")
    fixed = _normalised_variances("fixed")
    # Fig. 13: the variances end ordered by topological dominance, x1 (root) best localised
    last = adaptive[-1]
    assert last[0] < last[1] < last[2] < last[3], last
    assert last[0] < 0.25
    # ... x1 is localised first: from layer 3 on, its variance is below every other parameter's
    assert np.all(adaptive[2:, 0] < adaptive[2:, 1:].min(axis=1))
    # Fig. 12(c) vs (f): after the first diffusion the fixed schedule has wiped out x1's localisation,
    # noise proportional to the set's variance keeps it
    assert adaptive[1, 0] < 0.8 * fixed[1, 0], (adaptive[1, 0], fixed[1, 0])
    assert fixed[1, 0] > 0.95


def _track(make, d, n, layers, diffusion, crossover, seed, frames=20, step=0.1):
    """Track a smoothly moving planar linkage (max step ``step`` rad/frame) with carried particle sets."""
    r = np.random.default_rng(seed)
    centre, period, phase = r.uniform(-1, 1, d), r.uniform(20, 40, d), r.uniform(0, 2 * np.pi, d)
    amp = step * period / (2 * np.pi)
    traj = np.array([centre + amp * np.sin(2 * np.pi * t / period + phase) for t in range(frames + 1)])
    prob = make(traj[0])
    sigma0 = np.full(d, 0.5 * step)  # DR05 sec. 3.1: half the maximum expected movement
    rng = np.random.default_rng([seed, 99])
    x, carry, err, ssd = traj[0], None, [], []
    for t in range(1, frames + 1):
        p = prob.with_target(traj[t])
        apf = AnnealedParticleFilter.start(
            x, sigma0, n, layers, rng, carry=carry, diffusion=diffusion, crossover=crossover
        )
        _run(apf, p)
        x, carry = apf.best.x, apf.carry()
        err.append(p.joint_error(x[None])[0])
        ssd.append(p.ssd(x[None])[0])
    return float(np.mean(err)), float(np.mean(ssd))


@pytest.mark.slow
def test_dr05_adaptive_diffusion_tracks_the_planar_arm_like_the_fixed_schedule():
    """DR05 sec. 6.1 reports "successful tracking with fewer than half the number of particles".

    That held here (median error 0.62x fixed-100 with adaptive-50) only with plain eq. 18 noise, which
    grows every unlocalised parameter's variance by (1 + c) per layer and blew up on the 31-parameter
    body (316 mm on the walk). With the variance-keeping shrinkage the 4-link arm tracks about as well as
    with the fixed schedule at equal particles (measured medians: 0.0325 vs 0.0297 at 50 particles,
    0.0244 vs 0.0220 at 100), so the 2x claim does not reproduce; what the test keeps is that adaptive
    diffusion tracks (errors of a few hundredths of a radian) and improves with particles."""
    seeds = range(12)
    adaptive50 = np.array([_track(planar_arm, 4, 50, 6, "adaptive", 0.0, s, frames=15)[0] for s in seeds])
    adaptive100 = np.array([_track(planar_arm, 4, 100, 6, "adaptive", 0.0, s, frames=15)[0] for s in seeds])
    fixed50 = np.array([_track(planar_arm, 4, 50, 6, "fixed", 0.0, s, frames=15)[0] for s in seeds])
    assert np.median(adaptive50) < 1.25 * np.median(fixed50), (np.median(adaptive50), np.median(fixed50))
    assert np.median(adaptive100) < 0.9 * np.median(adaptive50)
    assert np.median(adaptive50) < 0.05


@pytest.mark.slow
def test_dr05_fig16_crossover_lowers_error_on_branched_arms():
    """DR05 Fig. 15-16: two 3-link arms sharing a root are tracked better with crossover."""
    seeds = range(12)
    without = np.array([_track(two_arms, 6, 25, 6, "adaptive", 0.0, s, frames=30)[1] for s in seeds])
    with_x = np.array([_track(two_arms, 6, 25, 6, "adaptive", 0.5, s, frames=30)[1] for s in seeds])
    # final SSD (Fig. 16's measure), averaged over the frames
    assert np.median(with_x) < 0.85 * np.median(without), (np.median(with_x), np.median(without))
    assert np.mean(with_x < without) >= 0.75
