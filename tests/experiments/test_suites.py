"""Experiment suites: variants keep or state their budgets; every suite is well formed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swarmpose import optim
from swarmpose.body.model import load_model
from swarmpose.errors import ConfigError
from swarmpose.experiments.suites import SUITES, apply_variant, parse_fitness_options, suite


@pytest.fixture(scope="module")
def model():
    return load_model("balan31")


@pytest.mark.parametrize(("variant", "evals"), [("", 1000), ("budget=2000", 2000), ("budget=4000", 4000),
                                                ("stage2=2x400", 1000), ("stage2=400x2", 1000),
                                                ("stage2=40x20", 1000)])
def test_sppso_variant_budgets(model, variant, evals):
    cfg = apply_variant(optim.get("sppso", model=model, fps=20.0), variant)
    assert cfg.evals_per_frame == evals
    assert _evaluations_of_one_frame(cfg, model) == evals


def _evaluations_of_one_frame(cfg, model) -> int:
    opt = cfg.start(np.zeros(model.n_params), np.random.default_rng(0))
    n = 0
    while not opt.done:
        x = opt.ask()
        opt.tell(-np.sum(x**2, axis=1))
        n += len(x)
    return n


def test_aapso_global_and_hard_variants(model):
    base = optim.get("aapso", model=model, fps=25.0)
    glob = apply_variant(base, "global=400x10")
    assert glob.evals_per_frame == 4000 and len(glob.stages) == 1 and glob.stages[0].active.all() == \
        np.logical_or.reduce([s.active for s in base.stages]).all()
    hard = apply_variant(base, "hard")
    assert hard.evals_per_frame == base.evals_per_frame
    torso = base.stages[0].active
    assert not any((s.active & torso).any() for s in hard.stages[1:])
    assert all((s.active & torso).any() for s in base.stages[1:])  # soft: torso searched at sigma/10
    for stage in hard.stages:  # what a stage searches is its effective scale: nothing outside its partition
        assert np.all(stage.effective_scale[~stage.active] == 0.0) and np.all(stage.effective_scale[stage.active] > 0)
    # end to end: once stage 1 is done, hard partitions never move the torso again
    x0 = np.clip(np.zeros(model.n_params), hard.lower, hard.upper)  # inside the bounds: nothing is clipped
    opt = hard.start(x0, np.random.default_rng(0))
    asked = []
    while not opt.done:
        x = opt.ask()
        asked.append(x)
        opt.tell(-np.sum((x - 0.1) ** 2, axis=1))
    later = np.vstack(asked)[hard.stages[0].evaluations:]
    assert len(later) == hard.evals_per_frame - hard.stages[0].evaluations
    # (eq. 18's variance of a parameter all particles share is 0 up to rounding: moves of ~1e-16 rad remain)
    assert np.ptp(later[:, torso], axis=0).max() < 1e-9 and np.ptp(later[:, ~torso], axis=0).min() > 1e-3


def test_sppso_global_variant_scores_the_whole_body(model):
    """global=PxI on SPPSO: one stage over every searched parameter with the full-body fitness of its last
    stage, as the registered pso-global (not stage 1's torso-only edges)."""
    base = optim.get("sppso", model=model, fps=20.0)
    glob = apply_variant(base, "global=25x40")
    (stage,) = glob.stages
    assert dict(stage.fitness_options) == dict(base.stages[-1].fitness_options) != dict(base.stages[0].fitness_options)
    registered = optim.get("pso-global", model=model, fps=20.0).stages[0]
    assert dict(stage.fitness_options) == dict(registered.fitness_options)
    assert stage.active.tolist() == registered.active.tolist()
    assert (stage.n_particles, stage.n_iterations) == (registered.n_particles, registered.n_iterations)


def test_apf_particles_and_layers_variant(model):
    """Sharifi et al. sec. 4.10 ran Deutscher & Reid's APF with 700 particles x 5 layers."""
    cfg = apply_variant(optim.get("apf-dr05", model=model, fps=25.0), "apf=700x5")
    assert (cfg.n_particles, cfg.n_layers, cfg.evals_per_frame) == (700, 5, 3500)
    assert _evaluations_of_one_frame(cfg, model) == 3500
    with pytest.raises(ConfigError, match="annealed particle filter"):
        apply_variant(optim.get("sppso", model=model, fps=25.0), "apf=700x5")
    with pytest.raises(ConfigError, match="apf=PxL"):
        apply_variant(optim.get("apf", model=model, fps=25.0), "apf=700")


def test_every_suite_names_known_algorithms():
    for name in SUITES:
        entries = suite(name)
        assert entries and all(e.algo in optim.names() for e in entries)
    with pytest.raises(ConfigError, match="thesis-apf"):
        suite("nope")


def test_marker_suites_differ_only_in_the_fitness():
    paper = [e for e in suite("markers") if e.fitness == "markers"]
    repro = suite("markers-reprojection")
    assert len(paper) == len(repro) == 6 and all(e.fitness == "reprojection" for e in repro)
    assert ([dataclasses.replace(e, fitness="reprojection", reference="") for e in paper]
            == [dataclasses.replace(e, reference="") for e in repro])


def test_every_entry_cites_the_table_or_figure_of_its_own_set_up():
    """Sharifi et al.: Table 1 base configuration (25 fps), 3 (12 fps), 4 global, 5 hard, 7 non-adaptive,
    8 APF; a fitness other than the paper's epipolar score is said. Thesis 6.5: Fig. 6.9 at 20 fps, 6.8 at 60."""
    tables = {"aapso 25fps": 1, "aapso 12fps": 3, "aapso global 400x10 25fps": 4, "aapso hard partitions 25fps": 5,
              "aapso-fixed (non-adaptive) 25fps": 7, "apf-dr05 700x5 25fps": 8}
    for name in ("markers", "markers-reprojection"):
        for e in suite(name):
            table = tables[e.label.removesuffix(" reprojection")]
            assert f"Table {table} set-up" in e.reference and e.reference.count("Table") == 1
            assert ("not the paper's" in e.reference) == (e.fitness != "markers")
    for e in suite("thesis-apf"):
        assert ("Fig. 6.9" if e.fps == 20.0 else "Fig. 6.8") in e.reference and e.reference.count("Fig.") == 1


def test_fitness_option_parsing():
    assert parse_fitness_options("terms=silhouette, edge_top=false") == {"terms": "silhouette", "edge_top": False}
    with pytest.raises(ConfigError):
        parse_fitness_options("terms")
    assert parse_fitness_options("edge_top=NO,x=On") == {"edge_top": False, "x": True}
    assert parse_fitness_options("edge_top=0") == {"edge_top": "0"}  # left to the fitness to refuse


@pytest.mark.parametrize("text", ["edge_top=0", "edge_top=maybe", "edge_top=1"])
def test_a_boolean_fitness_option_that_is_not_a_boolean_is_refused(text):
    from swarmpose.fitness.base import ImageOptions, parse_image_options

    with pytest.raises(ConfigError, match="edge_top must be a bool"):
        parse_image_options(parse_fitness_options(text), ImageOptions())
    assert parse_image_options(parse_fitness_options("edge_top=off"), ImageOptions()).edge_top is False


@pytest.mark.parametrize(("variant", "message"), [
    ("budget=abc", "1000, 2000"), ("budget=0", "1000, 2000"), ("budget=1500", "1000, 2000"),
    ("stage2=20", "stage2=PxI"), ("stage2=20x40x2", "stage2=PxI"), ("stage2=0x40", "stage2=PxI"),
    ("global=axb", "global=PxI"), ("hard=false", "expected hard"), ("budget", "budget=B"),
    ("nonsense=1", "unknown variant")])
def test_malformed_variants_are_refused_with_the_expected_form(model, variant, message):
    with pytest.raises(ConfigError, match=message):
        apply_variant(optim.get("sppso", model=model, fps=20.0), variant)


def test_refined_recovery_variants(model):
    """recovery=off drops the loss detection; recovery=T moves its threshold and keeps the rest of it."""
    base = optim.get("refined", model=model, fps=20.0)
    assert dict(apply_variant(base, "recovery=off").recovery) == {}
    low = apply_variant(base, "recovery=0.01+refine=50")
    assert low.recovery["threshold"] == 0.01 and low.refine_budget == 50
    assert {k: v for k, v in low.recovery.items() if k != "threshold"} == {
        k: v for k, v in base.recovery.items() if k != "threshold"}
    for bad in ("recovery=1.5", "recovery=x", "recovery=0"):
        with pytest.raises(ConfigError, match="recovery=T"):
            apply_variant(base, bad)
    with pytest.raises(ConfigError, match="has no limb recovery"):
        apply_variant(apply_variant(base, "recovery=off"), "recovery=0.01")


def test_refined_height_variant(model):
    base = optim.get("refined", model=model, fps=20.0)
    assert not base.silhouette_height
    on = apply_variant(base, "height=silhouettes+recovery=0.01")
    assert on.silhouette_height and on.recovery["threshold"] == 0.01
    assert not apply_variant(on, "height=off").silhouette_height
    kp = apply_variant(on, "height=keypoints")
    assert kp.silhouette_height and kp.keypoint_height and not on.keypoint_height
    off = apply_variant(kp, "height=off")
    assert not off.silhouette_height and not off.keypoint_height
    assert not apply_variant(kp, "height=silhouettes").keypoint_height
    default = optim.get("refined-heading", model=model, fps=20.0)
    assert default.silhouette_height and default.keypoint_height
    for bad, cfg in (("height=yes", base), ("height=silhouettes", optim.get("sppso", model=model, fps=20.0))):
        with pytest.raises(ConfigError, match="height=silhouettes"):
            apply_variant(cfg, bad)


def test_refined_head_variant(model):
    from swarmpose.optim.registry import HEAD_SEARCH

    base = optim.get("refined-limbs", model=model, fps=20.0)
    assert base.head_search == 0
    on = apply_variant(base, "head=50")
    assert on.head_search == 50 and on.evals_per_frame == base.evals_per_frame  # only with keypoints: not counted
    assert optim.get("refined-heading", model=model, fps=20.0).head_search == HEAD_SEARCH > 0
    assert apply_variant(on, "head=off").head_search == 0 and apply_variant(on, "head=0").head_search == 0
    for bad, cfg in (("head=x", base), ("head=-5", base), ("head=2.5", base),
                     ("head=50", optim.get("sppso", model=model, fps=20.0))):
        with pytest.raises(ConfigError, match="head=B"):
            apply_variant(cfg, bad)
    with pytest.raises(ConfigError, match="head_search"):
        dataclasses.replace(base, head_search=-1)


def test_refined_recovery_of_every_limb_with_the_frames_fitness(model):
    base = optim.get("refined", model=model, fps=20.0)
    v = apply_variant(base, "recovery=all+recovery_terms=fitness")
    assert v.recovery["threshold"] == -1.0 and v.recovery["terms"] == "fitness"
    assert apply_variant(v, "recovery_terms=distance").recovery["terms"] == "distance"
    assert apply_variant(v, "recovery_margin=0.01").recovery["margin"] == 0.01
    with pytest.raises(ConfigError, match="recovery_margin"):
        apply_variant(v, "recovery_margin=-1")
    assert apply_variant(v, "recovery_jump=0.01").recovery["jump"] == 0.01
    assert apply_variant(v, "recovery_jump=off").recovery["jump"] == 0.0
    for bad in ("recovery_jump=-1", "recovery_jump=x"):
        with pytest.raises(ConfigError, match="recovery_jump"):
            apply_variant(v, bad)
    with pytest.raises(ConfigError, match="recovery_jump"):
        apply_variant(optim.get("apf-dr05", model=model, fps=20.0), "recovery_jump=0.01")
    assert apply_variant(v, "recovery_in_turn=1").recovery["in_turn"] == 1
    g = apply_variant(v, "recovery_guard=silhouette")
    assert g.recovery["guard"] == "silhouette" and apply_variant(g, "recovery_guard=off").recovery["guard"] == ""
    assert apply_variant(v, "recovery_terms=silhouette").recovery["terms"] == "silhouette"
    for bad in ("recovery_guard=edge", "recovery_terms=edges"):
        with pytest.raises(ConfigError, match=bad.partition("=")[0]):
            apply_variant(v, bad)
    for bad in ("recovery_in_turn=0", "recovery_in_turn=x"):
        with pytest.raises(ConfigError, match="recovery_in_turn"):
            apply_variant(v, bad)
    for bad, cfg in (("recovery_terms=edges", base), ("recovery_terms=fitness", apply_variant(base, "recovery=off"))):
        with pytest.raises(ConfigError, match="recovery_terms"):
            apply_variant(cfg, bad)


def test_the_limbs_search_size_variants(model):
    """``recovery_search=SxR`` and ``recovery_refine=B`` size each searched limb's box search and its polish; the
    evaluations per frame follow (4 limbs on every frame); a bad size or a configuration without recovery is
    refused by name."""
    from swarmpose.track.recovery import Recovery

    base = optim.get("refined-heading", model=model, fps=20.0)
    small = apply_variant(base, "recovery_search=50x3+recovery_refine=50")
    r = Recovery.from_settings(small.recovery)
    assert (r.n_samples, r.n_rounds, r.refine_budget) == (50, 3, 50)
    assert (r.threshold, r.terms, r.guard) == (-1.0, "fitness", "silhouette")  # the rest of the default's recovery
    assert base.evals_per_frame - small.evals_per_frame == 4 * ((100 * 5 + 100) - (50 * 3 + 50))
    for bad in ("recovery_search=50", "recovery_search=0x3", "recovery_search=ax3", "recovery_refine=-1",
                "recovery_refine=x"):
        with pytest.raises(ConfigError, match=bad.partition("=")[0]):
            apply_variant(base, bad)
    with pytest.raises(ConfigError, match="recovery_search"):
        apply_variant(apply_variant(base, "recovery=off"), "recovery_search=50x3")


def test_the_keypoint_joints_option_is_read_and_a_bad_one_refused():
    from swarmpose.fitness.base import ImageOptions, parse_image_options

    opts = parse_image_options(parse_fitness_options("keypoints=2,keypoint_joints=elbow:0+hip:0.5"), ImageOptions())
    assert opts.keypoints == 2.0 and opts.keypoint_joints == "elbow:0+hip:0.5"
    with pytest.raises(ConfigError, match="names none of the joints"):
        parse_image_options(parse_fitness_options("keypoint_joints=elbows:0"), ImageOptions())
    assert parse_image_options(parse_fitness_options("keypoint_elbow=0.9"), ImageOptions()).keypoint_elbow == 0.9
    for bad in ("0", "1.5", "near", "on"):
        with pytest.raises(ConfigError, match="keypoint_elbow must be a fraction"):
            parse_image_options(parse_fitness_options(f"keypoint_elbow={bad}"), ImageOptions())
    opts = parse_image_options(parse_fitness_options("keypoint_scale=0.01,keypoint_swaps=ends"), ImageOptions())
    assert opts.keypoint_scale == 0.01 and opts.keypoint_swaps == "ends"
    assert ImageOptions().keypoint_scale == 0.02  # the term's SCALE
    for bad in ("0", "1.5", "wide", "on"):
        with pytest.raises(ConfigError, match="keypoint_scale must be a fraction"):
            parse_image_options(parse_fitness_options(f"keypoint_scale={bad}"), ImageOptions())
    opts = parse_image_options(parse_fitness_options("keypoint_threshold=0.1,keypoint_power=0"), ImageOptions())
    assert opts.keypoint_threshold == 0.1 and opts.keypoint_power == 0.0
    assert ImageOptions().keypoint_threshold == 0.3 and ImageOptions().keypoint_power == 1.0
    for name, bad in (("keypoint_threshold", "1.5"), ("keypoint_threshold", "-0.1"), ("keypoint_power", "5"),
                      ("keypoint_power", "on"), ("keypoint_power", "strong")):
        with pytest.raises(ConfigError, match=f"{name} must be a number in"):
            parse_image_options(parse_fitness_options(f"{name}={bad}"), ImageOptions())
