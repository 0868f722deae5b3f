"""Named configurations: budgets as the papers state them, schedules, frame-rate scaling, determinism."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from swarmpose.errors import ConfigError
from swarmpose.optim import describe, get, names, optimize, register
from swarmpose.optim.apf import ParticleSet
from swarmpose.optim.cli import algorithms_command

from .conftest import make_balan31, make_marker45

# evaluations per frame as the papers state them
PAPER_BUDGETS = {
    "sppso": 10 * 20 + 20 * 40,  # Fleischmann 2012, Table 6.1
    "sppso3": 10 * 20 + 10 * 40 + 10 * 40,  # Fleischmann 2012, Table 6.3
    "pso-global": 25 * 40,  # Fleischmann 2012, sec. 6.6
    "hard2": 10 * 20 + 20 * 40,  # Fleischmann 2012, sec. 6.6 (SPPSO with x1-x6 fixed in stage 2)
    "hpso12": 12 * 10 * 60,  # Fleischmann 2012, sec. 6.6: 7200 evaluations
    "apf": 200 * 5,  # HumanEva APF, Fleischmann 2012 Table 4.3
    "apf-adaptive": 200 * 5,  # the HumanEva APF's budget with Deutscher & Reid's eq. 18-19 (thesis 4.4.4)
    "apf-dr05": 200 * 10,  # Deutscher & Reid 2005, sec. 3.1 and Fig. 9-10
    "aapso": 5 * 80 * 10 + 30 * 10,  # Sharifi et al. 2017, sec. 4.2
    "aapso-fixed": 5 * 80 * 10 + 30 * 10,
}
#: Configurations beyond the papers and their budgets (base search + refinement; a lost limb's search not counted).
OWN_BUDGETS = {"refined": 200 * 6 + 200, "refined-keypoints": 200 * 6 + 200,
               "refined-limbs": 200 * 6 + 200 + 4 * (1 + 100 * 5 + 100 + 2),  # + every limb searched, guarded
               "refined-heading": 200 * 6 + 200 + 4 * (1 + 100 * 5 + 100 + 2) + (1 + 15 + 2 * 150 + 2),  # + 15 turns
               "aapso-refined": 5 * 80 * 10 + 30 * 10 + 200}  # AAPSO, then the pattern search
BUDGETS = {**PAPER_BUDGETS, **OWN_BUDGETS}


def _fitness(model):
    sigma = np.where(np.asarray(model.sigma) > 0, model.sigma, 1.0)

    def f(x):
        return -np.sum(((x - 0.05) / sigma) ** 2, axis=1)

    return f


def test_names_and_describe():
    assert set(names()) == set(BUDGETS)
    rows = describe()
    assert [r["name"] for r in rows] == list(names())
    for r in rows:
        assert set(r) == {"name", "summary", "fitness", "evals_per_frame", "reference"}
        assert r["evals_per_frame"] == BUDGETS[r["name"]]
        assert r["reference"] and len(r["summary"]) > 20  # every entry says what it is
        assert r["fitness"] == ("reprojection" if r["name"].startswith("aapso") else "silhouette_edge")


def test_refined_keypoints_is_refined_with_the_keypoint_term(balan31):
    from swarmpose.optim.registry import KEYPOINT_WEIGHT

    plain, kp = get("refined", model=balan31, fps=20), get("refined-keypoints", model=balan31, fps=20)
    assert kp.base.fitness_options == {**plain.base.fitness_options, "keypoints": KEYPOINT_WEIGHT}
    assert kp.refine_options == {**plain.refine_options, "keypoints": KEYPOINT_WEIGHT}
    assert (kp.refine_budget, kp.base.n_particles, kp.base.n_layers) == (200, 200, 6)


def test_the_default_tracks_under_the_coupled_limits_and_a_variant_turns_them_off():
    from swarmpose.body.model import load_model
    from swarmpose.optim.variants import apply_variant
    from swarmpose.track.tracker import tracker_priors

    balan31 = load_model("balan31")
    default = get("refined-heading", model=balan31, fps=20)
    assert default.coupled_limits and tracker_priors(balan31, default).coupled_limits
    off = apply_variant(default, "coupled_limits=off")
    assert not off.coupled_limits and not tracker_priors(balan31, off).coupled_limits
    assert off.evals_per_frame == default.evals_per_frame
    for name in ("refined", "refined-limbs", "sppso", "apf-dr05"):  # the benchmarks keep the parameters' own limits
        assert not tracker_priors(balan31, get(name, model=balan31, fps=20)).coupled_limits
    assert apply_variant(get("refined", model=balan31, fps=20), "coupled_limits=on").coupled_limits
    with pytest.raises(ConfigError, match="coupled_limits=on or coupled_limits=off"):
        apply_variant(get("sppso", model=balan31, fps=20), "coupled_limits=on")


def test_cli_json_and_table(capsys):
    algorithms_command(json=True)
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and json.loads(out) == {"algorithms": describe()}
    algorithms_command(json=False)
    out = capsys.readouterr().out
    assert all(n in out for n in names()) and "7200" in out


def test_unknown_name_lists_known_names_and_model_is_required(balan31):
    with pytest.raises(ConfigError, match="sppso.*apf"):
        get("nope", model=balan31)
    with pytest.raises(ConfigError, match="model"):
        get("sppso", model=None)
    with pytest.raises(ConfigError, match="fps"):
        get("sppso", model=balan31, fps=0)
    with pytest.raises(ConfigError, match="already registered"):
        register("sppso", lambda m, f: None, reference="x", evals_per_frame=1)


@pytest.mark.parametrize("name", sorted(BUDGETS))
@pytest.mark.parametrize("make_model", [make_balan31, make_marker45], ids=["balan31", "marker45"])
def test_budget_is_exactly_the_papers(name, make_model):
    """Run every named configuration to done and count the evaluations it asked for (a refinement that
    has converged may stop before its budget)."""
    model = make_model()
    cfg = get(name, model=model, fps=60)
    assert cfg.name == name and cfg.evals_per_frame == BUDGETS[name]
    x0 = np.zeros(len(model.param_names))
    opt = cfg.start(x0, np.random.default_rng(0))
    f = _fitness(model)
    counted = 0

    def counting(x):
        nonlocal counted
        counted += x.shape[0]
        assert np.all(x >= model.lower) and np.all(x <= model.upper)
        assert all(isinstance(k, str) for k in opt.fitness_options)  # options a fitness can read by name
        return f(x)

    res = optimize(opt, counting)
    assert counted == res.evaluations == opt.evaluations
    if name in PAPER_BUDGETS:
        assert counted == PAPER_BUDGETS[name]
    else:
        assert counted <= BUDGETS[name]
    # every optimiser ends better than where it started (the APFs' estimate is the particles' weighted mean,
    # whose score is the weighted mean of the particles' scores, not its own fitness)
    assert f(res.x[None])[0] > f(x0[None])[0]
    if not name.startswith("apf"):
        assert res.score == f(res.x[None])[0]


@pytest.mark.parametrize("name", sorted(BUDGETS))
def test_same_seed_same_asks(name, balan31):
    def asks(seed):
        cfg = get(name, model=balan31, fps=20)
        opt = cfg.start(np.zeros(31), np.random.default_rng(seed))
        f = _fitness(balan31)
        out = []
        while not opt.done:
            x = opt.ask()
            out.append(x)
            opt.tell(f(x))
        return out

    a, b, c = asks(11), asks(11), asks(12)
    assert len(a) == len(b)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], c[0])


def test_thesis_frame_rate_scaling(balan31):
    twist = balan31.group("head_twist")
    for name in ("sppso", "pso-global", "hpso12", "apf", "apf-adaptive"):
        s60 = get(name, model=balan31, fps=60).sigma
        fixed = twist if name.startswith("apf") else []  # the thesis's APFs hold x31 fixed by sigma 0 (thesis 6.1)
        assert np.allclose(s60, np.where(np.isin(np.arange(31), fixed), 0.0, balan31.sigma))
        assert np.allclose(get(name, model=balan31, fps=20).sigma, 3 * s60)  # thesis 5.3.2
    assert np.allclose(get("apf-dr05", model=balan31, fps=60).sigma, 0.5 * balan31.sigma)  # DR05 3.1
    fixed, adaptive = get("apf", model=balan31, fps=20), get("apf-adaptive", model=balan31, fps=20)
    assert (fixed.diffusion, fixed.crossover, adaptive.diffusion, adaptive.crossover) == ("fixed", 0.0, "adaptive", 0.5)
    for f in dataclasses.fields(fixed):  # otherwise the same configuration: particles, layers, Sigma, bounds
        if f.name not in ("name", "reference", "diffusion", "crossover"):
            a, b = getattr(fixed, f.name), getattr(adaptive, f.name)
            assert (np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b), f.name
    assert list(twist) == [30]


def test_aapso_generic_sigma_and_frame_rate(balan31):
    cfg = get("aapso", model=balan31, fps=25)
    angles = np.setdiff1d(np.arange(31), balan31.group("root_position"))
    assert np.allclose(cfg.sigma[angles], 0.1)  # Sharifi et al. 3.2
    assert np.allclose(cfg.sigma[3:6], balan31.sigma[3:6] * 60 / 25)
    half = get("aapso", model=balan31, fps=12.5)
    assert np.allclose(half.sigma**2, 2 * cfg.sigma**2)  # P_0 doubled at half the rate (sec. 4.4)
    as_sigma = get("aapso", model=balan31, fps=12.5, fps_scaling="sigma")
    assert np.allclose(as_sigma.sigma, 2 * cfg.sigma)
    assert get("aapso-fixed", model=balan31).adaptive is False and cfg.adaptive is True


def test_overrides_and_validation(balan31):
    cfg = get("apf", model=balan31, n_particles=100)
    assert cfg.evals_per_frame == 500
    assert get("apf-dr05", model=balan31, n_particles=400).evals_per_frame == 4000  # DR05 Fig. 8 setting
    with pytest.raises(ConfigError, match="unknown override"):
        get("sppso", model=balan31, n_particles=3)
    with pytest.raises(ConfigError, match="alpha"):
        get("apf", model=balan31, alpha=1.5)
    with pytest.raises(ConfigError):
        get("sppso", model=balan31, c_start=1.9)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.n_particles = 3  # type: ignore[misc]
    with pytest.raises(ConfigError):
        get("sppso", model=balan31).start(np.zeros(31), np.random.default_rng(0), carry=object())
    with pytest.raises(ValueError):
        get("sppso", model=balan31).start(np.zeros(30), np.random.default_rng(0))


def test_apf_carries_its_particle_set_between_frames(balan31):
    cfg = get("apf", model=balan31, fps=60, n_particles=50)
    f = _fitness(balan31)
    first = cfg.start(np.zeros(31), np.random.default_rng(0))
    optimize(first, f)
    carry = first.carry()
    assert isinstance(carry, ParticleSet) and carry.particles.shape == (50, 31)
    second = cfg.start(np.full(31, 100.0), np.random.default_rng(1), carry=carry)  # x0 unused with a carry
    x = second.ask()
    assert np.abs(x - carry.particles.mean(axis=0)).max() < 10 * balan31.sigma.max()


# -- schedules -------------------------------------------------------------------------------------
def _scale(stage):
    return stage.effective_scale


def test_sppso_and_hard2_schedules(balan31):
    s1, s2 = get("sppso", model=balan31).stages
    assert (s1.n_particles, s1.n_iterations, s2.n_particles, s2.n_iterations) == (10, 20, 20, 40)
    assert np.flatnonzero(s1.active).tolist() == list(range(6))
    expect = np.ones(31)
    expect[3:6] = 0.1  # sigma_4..sigma_6 / 10 in stage 2
    expect[30] = 0.0  # head twist x31 held fixed
    assert np.allclose(_scale(s2), expect)
    assert s1.fitness_options["edge_cones"] == "torso" and s2.fitness_options["edge_cones"] == "all"
    assert s1.fitness_options["edge_top"] and s2.fitness_options["edge_top"]
    h1, h2 = get("hard2", model=balan31).stages
    assert np.allclose(_scale(h1), _scale(s1))
    expect[:6] = 0.0
    assert np.allclose(_scale(h2), expect)
    (g,) = get("pso-global", model=balan31).stages
    assert (g.n_particles, g.n_iterations) == (25, 40) and np.count_nonzero(g.active) == 30


def test_sppso3_schedule_table_6_3(balan31):
    s1, s2, s3 = get("sppso3", model=balan31).stages
    assert [(s.n_particles, s.n_iterations) for s in (s1, s2, s3)] == [(10, 20), (10, 40), (10, 40)]
    lower_limbs = [8, 9, 12, 13, 18, 19, 24, 25]  # x9, x10, x13, x14, x19, x20, x25, x26
    assert sorted(set(range(31)) - set(np.flatnonzero(s2.active))) == sorted(lower_limbs + [30])
    assert np.allclose(_scale(s2)[3:6], 0.1) and np.allclose(_scale(s2)[:3], 1.0)
    sc = _scale(s3)
    assert np.allclose(sc[:6], 0.1)
    assert np.allclose(sc[lower_limbs], np.sqrt(2))
    others = sorted(set(range(6, 30)) - set(lower_limbs))
    assert np.allclose(sc[others], 0.5) and sc[30] == 0
    assert s2.fitness_options["edge_cones"] == "torso+upper_limbs"


def test_hpso12_twelve_hard_partitions(balan31):
    stages = get("hpso12", model=balan31).stages
    assert len(stages) == 12 and all((s.n_particles, s.n_iterations) == (10, 60) for s in stages)
    parts = [set(np.flatnonzero(s.active)) for s in stages]
    assert sum(len(p) for p in parts) == 30 and set().union(*parts) == set(range(30))
    assert all(np.allclose(s.sigma_scale[s.active], 1.0) for s in stages)
    assert parts[0] == {3, 4, 5} and parts[1] == {0, 1, 2} and parts[-1] == {28, 29}


def test_aapso_refined_is_aapso_then_a_pattern_search(balan31):
    """The same AAPSO (its stages, spread and random draws), then 200 pattern-search evaluations from its estimate
    with a first step of half its spread."""
    from swarmpose.optim.refine import Chain, PatternSearch

    plain, refined = get("aapso", model=balan31, fps=25), get("aapso-refined", model=balan31, fps=25)
    assert refined.base.name == "aapso" and np.array_equal(refined.sigma, plain.sigma)
    f = _fitness(balan31)
    a = optimize(plain.start(np.zeros(31), np.random.default_rng(3)), f)
    chain = refined.start(np.zeros(31), np.random.default_rng(3))
    b = optimize(chain, f)
    assert isinstance(chain, Chain) and isinstance(chain.members[1], PatternSearch)
    assert np.array_equal(chain.members[0].best.x, a.x)  # AAPSO's part is AAPSO's, draw for draw
    assert np.array_equal(chain.members[1].step0, 0.5 * plain.sigma)
    assert b.score >= a.score and b.evaluations <= a.evaluations + 200


def test_aapso_six_soft_stages(balan31):
    stages = get("aapso", model=balan31).stages
    assert [(s.n_particles, s.n_iterations) for s in stages] == [(80, 10)] * 5 + [(30, 10)]
    torso = [0, 1, 2, 3, 4, 5, 26, 27]
    assert np.flatnonzero(stages[0].active).tolist() == torso
    for s, group in zip(stages[1:], ["left_arm", "right_arm", "left_leg", "right_leg", "head"], strict=True):
        sc = _scale(s)
        assert np.allclose(sc[torso], 0.1)
        assert np.allclose(sc[balan31.group(group)], 1.0)
        assert np.count_nonzero(sc) == len(torso) + len(balan31.group(group))


def test_sppso3_and_hpso12_stage_options_and_scales():
    """(sppso3 stage 3 fitness EDGE_ALL -> torso+upper), M28 (sppso3 stage 1 root scale 1 -> 0.5), M29
    (hpso12 fitness EDGE_ALL -> torso): test_sppso3_schedule_table_6_3 checks only stage 2's options and no
    stage-1 scale; test_hpso12 no options."""
    from swarmpose.body.model import load_model
    from swarmpose.optim import get

    m = load_model("balan31")
    s1, s2, s3 = get("sppso3", model=m).stages
    assert np.array_equal(s1.effective_scale, np.r_[np.ones(6), np.zeros(25)])
    assert [dict(s.fitness_options) for s in (s1, s2, s3)] == [
        {"edge_cones": "torso", "edge_top": True}, {"edge_cones": "torso+upper_limbs", "edge_top": True},
        {"edge_cones": "all", "edge_top": True}]
    assert all(dict(s.fitness_options) == {"edge_cones": "all", "edge_top": True}
               for s in get("hpso12", model=m).stages)
