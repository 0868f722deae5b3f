"""Image fitness: thesis f = f_s + f_e (eq. 5.1-5.5), Deutscher-Reid (eq. 14-17), backends, options."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.errors import ConfigError, ShapeError
from swarmpose.features import FrameFeatures
from swarmpose.fitness import (
    BACKENDS,
    KINDS,
    Fitness,
    PreparedFrame,
    deutscher_reid_log_weight,
    edge_score,
    make_fitness,
    prepare_frame,
    silhouette_score,
)
from swarmpose.fitness.base import thesis_fitness
from swarmpose.fitness.scene import demo_cameras, demo_frame
from swarmpose.fitness.torch_backend import torch_available

#: The backends this machine can run (the torch backend needs PyTorch installed).
USABLE_BACKENDS = [b for b in BACKENDS if b != "torch" or torch_available()]

OPTION_VARIANTS = [
    None,
    {"edge_cones": "torso"},
    {"edge_cones": "torso+upper", "edge_top": False},
    {"edge_cones": "torso+upper_limbs"},
    {"terms": "silhouette"},
    {"terms": "edge"},
]


def _fits(model, frame, kind="silhouette_edge", **kw):
    return (make_fitness(kind, model, **kw).bind(frame),
            make_fitness(kind, model, backend="reference", **kw).bind(frame))


def test_smoke(model, scene, candidates):
    fit = make_fitness("silhouette_edge", model)
    assert isinstance(fit, Fitness)
    assert fit.bind(scene) is fit
    s = fit(candidates)
    assert s.shape == (len(candidates),) and s.dtype == np.float64
    assert np.isfinite(s).all() and (s >= 0).all() and (s <= 2).all()
    np.testing.assert_array_equal(s, fit.evaluate(candidates, None))
    assert fit(candidates[:0]).shape == (0,)
    bad = candidates[:3].copy()
    bad[1, 4] = np.nan
    s_bad = fit(bad)
    assert np.isnan(s_bad[1]) and np.isfinite(s_bad[[0, 2]]).all()
    assert fit(candidates[0]).shape == (1,)  # a (D,) pose is a batch of one


def test_own_rendering_scores_one(model, true_pose, exact_scene):
    for backend in USABLE_BACKENDS:
        fit = make_fitness("silhouette_edge", model, backend=backend).bind(exact_scene)
        fs, _ = fit.terms(true_pose[None], {"terms": "silhouette"})
        np.testing.assert_array_equal(fs, 1.0)
    # and at half resolution, on a frame rendered there
    cams = demo_cameras(4, width=322, height=242)
    half = demo_frame(model, true_pose, cams, inflate=1.0, clutter=0, noise=0.0)
    fit = make_fitness("silhouette_edge", model).bind(half)
    assert fit.evaluate(true_pose[None], {"terms": "silhouette"})[0] == 1.0


@pytest.mark.parametrize("options", OPTION_VARIANTS)
def test_matches_reference(model, scene, candidates, options):
    fast, ref = _fits(model, scene)
    poses = candidates[:8]
    a = fast.measure(poses, options)
    b = ref.measure(poses, options)
    np.testing.assert_array_equal(a.overlap, b.overlap)
    np.testing.assert_array_equal(a.projected, b.projected)
    np.testing.assert_array_equal(a.edge_count, b.edge_count)
    np.testing.assert_allclose(a.edge_sum, b.edge_sum, atol=1e-9)
    fs_a, fe_a = fast.terms(poses, options)
    fs_b, fe_b = ref.terms(poses, options)
    assert np.abs(fs_a - fs_b).max() <= 1e-3 and np.abs(fe_a - fe_b).max() <= 1e-3
    np.testing.assert_allclose(fast.evaluate(poses, options), ref.evaluate(poses, options), atol=1e-9)


@pytest.mark.parametrize("options", [None, {"edge_cones": "torso"}, {"terms": "silhouette"}, {"terms": "edge"}])
def test_deutscher_reid_matches_reference(model, scene, candidates, options):
    fast, ref = _fits(model, scene, kind="deutscher_reid")
    poses = candidates[:6]
    a, b = fast.measure(poses, options), ref.measure(poses, options)
    np.testing.assert_array_equal(a.region_count, b.region_count)
    np.testing.assert_allclose(a.region_sq, b.region_sq, atol=1e-9)
    np.testing.assert_allclose(a.edge_sq, b.edge_sq, atol=1e-9)
    wa, wb = fast.evaluate(poses, options), ref.evaluate(poses, options)
    np.testing.assert_allclose(wa, wb, rtol=1e-9)
    assert ((wa <= 0) & (wa >= -2 * len(scene.cameras))).all()  # log w, each view's SSDs at most 1 + 1


def test_truth_beats_perturbations(model, true_pose, scene):
    rng = np.random.default_rng(3)
    pert = true_pose + rng.normal(0.0, 2.0, (60, model.n_params)) * model.sigma
    for kind in ("silhouette_edge", "deutscher_reid"):
        fit = make_fitness(kind, model).bind(scene)
        s_true = fit(true_pose[None])[0]
        assert (fit(pert) < s_true).mean() > 0.9, kind
    fs_true, _ = make_fitness("silhouette_edge", model).bind(scene).terms(true_pose[None])
    assert fs_true.min() > 0.85  # 8 % thicker observed cones and clutter: high, below 1


def test_options_select_samples(model, scene, true_pose):
    fit = make_fitness("silhouette_edge", model).bind(scene)
    n = {name: fit.measure(true_pose[None], opts).edge_count.sum() for name, opts in [
        ("all", None), ("torso", {"edge_cones": "torso"}), ("upper", {"edge_cones": "torso+upper"}),
        ("torso_no_top", {"edge_cones": "torso", "edge_top": False})]}
    assert n["torso_no_top"] < n["torso"] < n["upper"] < n["all"]
    f_s = fit.evaluate(true_pose[None], {"terms": "silhouette"})
    f_e = fit.evaluate(true_pose[None], {"terms": "edge"})
    np.testing.assert_allclose(fit(true_pose[None]), f_s + f_e)
    torso_fit = make_fitness("silhouette_edge", model, edge_cones="torso").bind(scene)
    np.testing.assert_allclose(torso_fit(true_pose[None]), fit.evaluate(true_pose[None], {"edge_cones": "torso"}))


def test_stage_options_are_parsed_once_and_still_checked(model, scene, true_pose):
    """A stage's option mapping is parsed once per fitness (the same options object comes back), gives the same
    scores as a fresh fitness, and a bad option is refused every time it is passed, never kept."""
    fit = make_fitness("silhouette_edge", model).bind(scene)
    stage = {"edge_cones": "torso", "edge_top": True}
    first = fit._options(stage)
    assert fit._options(dict(stage)) is first
    fresh = make_fitness("silhouette_edge", model).bind(scene)
    assert np.array_equal(fit.evaluate(true_pose[None], stage), fresh.evaluate(true_pose[None], stage))
    for _ in range(2):
        with pytest.raises(ConfigError, match="unknown fitness option"):
            fit.evaluate(true_pose[None], {"edge_cone": "torso"})
    for i in range(300):  # a caller building new options every time: the cache stays bounded
        fit._options({"distance": float(i)})
    assert len(fit._parsed) <= 256
    assert fit._options({"edge_cones": ["torso"]}).edge_cones == ("torso",)  # an unhashable value: parsed as it comes


def test_degenerate_frames(model, rig, true_pose):
    """Empty observations and a model out of view: finite scores, the documented values."""
    C, H, W = 4, rig[0].height, rig[0].width
    empty = FrameFeatures(np.zeros((C, H, W), np.uint8), np.zeros((C, H, W), np.float32), rig)
    away = true_pose.copy()
    away[3] += 50_000.0  # out of every view
    behind = true_pose.copy()
    behind[3:6] = rig[0].center + 50.0  # at a camera: cones dropped by the near plane there
    poses = np.stack([true_pose, away, behind])
    for backend in USABLE_BACKENDS:
        fs, fe = make_fitness("silhouette_edge", model, backend=backend).bind(empty).terms(poses)
        assert np.isfinite(fs).all() and np.isfinite(fe).all()
        np.testing.assert_array_equal(fs[0], 0.0)  # model drawn, nothing observed
        np.testing.assert_array_equal(fs[1], 1.0)  # both empty: identical silhouettes
        np.testing.assert_array_equal(fe[:2], 0.0)
        w = make_fitness("deutscher_reid", model, backend=backend).bind(empty)(poses)
        assert np.isfinite(w).all() and (w <= 0).all()  # log-weights
    full = demo_frame(model, true_pose, rig, inflate=1.0, clutter=0, noise=0.0)
    fs, fe = make_fitness("silhouette_edge", model).bind(full).terms(poses)
    np.testing.assert_array_equal(fs[1], 0.0)  # nothing drawn, something observed
    assert np.isfinite(fs).all() and np.isfinite(fe).all()


def test_exception(model, scene, candidates):
    with pytest.raises(ConfigError, match="known"):
        make_fitness("chamfer", model)
    with pytest.raises(ConfigError, match="numba"):
        make_fitness("silhouette_edge", model, backend="cuda")
    with pytest.raises(ConfigError):
        make_fitness("silhouette_edge", model, no_such_option=1)
    with pytest.raises(ConfigError):
        make_fitness("silhouette_edge", model, edge_cones="arms")
    with pytest.raises(ConfigError):
        make_fitness("silhouette_edge", model, a=2.0)
    fit = make_fitness("silhouette_edge", model)
    with pytest.raises(RuntimeError, match="bind"):
        fit(candidates)
    with pytest.raises(ShapeError):
        fit.bind(np.zeros((4, 10, 10)))
    fit.bind(scene)
    with pytest.raises(ShapeError):
        fit(candidates[:, :7])
    with pytest.raises(ConfigError, match="known"):
        fit.evaluate(candidates, {"edge_cone": "torso"})
    with pytest.raises(ConfigError):
        fit.evaluate(candidates, {"terms": "both"})
    assert set(KINDS) == {"silhouette_edge", "deutscher_reid", "markers", "reprojection"}


def test_prepare(model, scene):
    prep = prepare_frame(scene)
    assert isinstance(prep, PreparedFrame) and prep.prepare_ms > 0
    np.testing.assert_array_equal(prep.prefix[:, :, -1], scene.silhouettes.sum(axis=2))
    np.testing.assert_array_equal(prep.prefix[:, 5, 100] - prep.prefix[:, 5, 40],
                                  scene.silhouettes[:, 5, 40:100].sum(axis=1))
    np.testing.assert_array_equal(prep.observed_area, scene.silhouettes.sum(axis=(1, 2)))
    fit = make_fitness("silhouette_edge", model).bind(prep)
    assert fit.prepared is prep and fit.prepare_ms == prep.prepare_ms


def test_silhouette_score_is_eq_5_5():
    rng = np.random.default_rng(0)
    O = rng.random((3, 30, 40)) < 0.3
    Pm = rng.random((5, 3, 30, 40)) < 0.4
    R = (O & ~Pm).sum(axis=(2, 3))  # eq. 5.2
    B = (Pm & ~O).sum(axis=(2, 3))  # eq. 5.3
    Y = (O & Pm).sum(axis=(2, 3))  # eq. 5.4
    expected = 0.5 * Y / (B + Y) + 0.5 * Y / (R + Y)  # eq. 5.5
    got = silhouette_score(Y, Pm.sum(axis=(2, 3)), O.sum(axis=(1, 2)))
    np.testing.assert_allclose(got, expected)
    np.testing.assert_array_equal(silhouette_score([[0, 0]], [[0, 5]], [0, 0]), [[1.0, 0.0]])
    np.testing.assert_array_equal(silhouette_score([[0]], [[0]], [7]), [[0.0]])
    np.testing.assert_allclose(edge_score([[3.0, 0.0]], [[4.0, 0.0]]), [[0.75, 0.0]])
    w = deutscher_reid_log_weight(np.array([[1.0, 0.0]]), np.array([[4.0, 0.0]]), np.array([[2.0, 0.0]]),
                              np.array([[8.0, 2.0]]))
    np.testing.assert_allclose(w, -(0.25 + 1.0 + 0.25 + 0.0))
    # a view where no interior point is drawn (the body outside it) has no region evidence: it costs the
    # largest SSD, 1, like a view without edge samples; it must not score as a perfect match
    none = np.zeros((1, 1))
    np.testing.assert_allclose(deutscher_reid_log_weight(none, np.ones((1, 1)), none, none), [-1.0])
    # the observed-coverage weight a of eq. 5.5 (0.5 in the thesis) weighs Y / O, and 1 - a weighs Y / P
    np.testing.assert_allclose(silhouette_score([[2]], [[4]], [8], a=0.2), [[0.8 * 2 / 4 + 0.2 * 2 / 8]])


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 12), c=st.sampled_from([1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 33, 130]),
       seed=st.integers(0, 2**32 - 1), a=st.sampled_from([0.0, 0.2, 0.5, 1.0]))
def test_thesis_fitness_is_the_plain_means_to_the_last_bit(n, c, seed, a):
    """The compiled f = mean_c f_s + mean_c f_e against the numpy formulas it replaces, bit for bit: empty
    silhouettes (both empty, one empty), views without edge samples, up to and past the compiled 128 views."""
    rng = np.random.default_rng(seed)
    O = rng.integers(0, 500, c) * (rng.random(c) < 0.8)
    P = rng.integers(0, 600, (n, c)) * (rng.random((n, c)) < 0.8)
    Y = np.minimum(rng.integers(0, 600, (n, c)), np.minimum(P, O[None]))
    count = rng.integers(0, 60, (n, c)).astype(np.float64)
    esum = count * rng.random((n, c))
    for sil, edge in ((True, True), (True, False), (False, True)):
        want = np.zeros(n)
        if sil:
            want += silhouette_score(Y, P, O, a).mean(axis=1)
        if edge:
            want += edge_score(esum, count).mean(axis=1)
        got = thesis_fitness(Y, P, O, esum, count, a, silhouette=sil, edge=edge)
        assert np.array_equal(got, want)
    counts = np.stack([Y, P], axis=-1)  # the kernel's layout: strided views, as Measurements.from_arrays gives
    assert np.array_equal(thesis_fitness(counts[..., 0], counts[..., 1], O, esum, count, a),
                          silhouette_score(Y, P, O, a).mean(axis=1) + edge_score(esum, count).mean(axis=1))
    with pytest.raises(ValueError, match="cannot exceed"):
        thesis_fitness(P + O.max() + 1, P, O, esum, count, a)


# --------------------------------------------------------------------------- on a synthesised walk
def test_walk_ik_pose_beats_2_sigma(walk):
    """f_s at the IK pose of the ground truth is higher than at poses perturbed by 2 sigma, on every
    frame (real synthesised images of cmu_16_16_walk; the observation body is not the cone model)."""
    rng = np.random.default_rng(5)
    fit = make_fitness("silhouette_edge", walk.model)
    diffs = []
    for frame, x in zip(walk.frames, walk.ik, strict=True):
        fit.bind(frame)
        pert = x + rng.normal(0.0, 2.0, (40, walk.model.n_params)) * walk.model.sigma
        fs_ik = fit.evaluate(x[None], {"terms": "silhouette"})[0]
        fs_p = fit.evaluate(pert, {"terms": "silhouette"})
        assert 0.85 < fs_ik < 0.95  # measured 0.897-0.904: the observation body is not the cones
        assert (fs_p < fs_ik).mean() > 0.95  # measured: all 40 on every frame
        diffs.append(fs_ik - np.median(fs_p))
    assert min(diffs) > 0.1  # measured 0.146-0.186


@pytest.mark.parametrize("scale,n_poses", [(4, 150), (1, 25)])
def test_walk_backends_agree(walk, scale, n_poses):
    """On real synthesised images and random poses around the IK poses, numba and the reference count the same
    pixels and edge samples exactly, and sum the same edge values (to float rounding).
    (The full 1000-pose run at 644x484 is in the report; here a subset keeps the suite fast.)"""
    rng = np.random.default_rng(scale)
    k = rng.integers(0, len(walk.ik), n_poses)
    poses = walk.ik[k] + rng.normal(0.0, 1.0, (n_poses, walk.model.n_params)) * walk.model.sigma
    for f in np.unique(k):
        frame = walk.frames[f].downsample(scale)
        fast, ref = _fits(walk.model, frame)
        sel = poses[k == f]
        a, b = fast.measure(sel), ref.measure(sel)
        np.testing.assert_array_equal(a.overlap, b.overlap)
        np.testing.assert_array_equal(a.projected, b.projected)
        np.testing.assert_array_equal(a.edge_count, b.edge_count)
        np.testing.assert_allclose(a.edge_sum, b.edge_sum, atol=1e-9)
        np.testing.assert_allclose(fast.evaluate(sel), ref.evaluate(sel), atol=1e-12)


def _child_eval(fit, poses, queue):
    queue.put(fit(poses).tolist())


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork()")
def test_thread_pool_survives_fork(model, scene, candidates):
    """The numba backend's thread pool is re-created in a forked worker (experiment grids fork)."""
    import multiprocessing as mp

    fit = make_fitness("silhouette_edge", model).bind(scene)
    expected = fit(candidates[:4])  # creates the pool in this process
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    proc = ctx.Process(target=_child_eval, args=(fit, candidates[:4], q))
    proc.start()
    got = q.get(timeout=120)
    proc.join(timeout=30)
    np.testing.assert_array_equal(got, expected)


def test_thread_modes_agree(model, scene, candidates):
    base = make_fitness("silhouette_edge", model).bind(scene)(candidates)
    for mode in ("prange", "serial"):
        fit = make_fitness("silhouette_edge", model, backend_options={"threads": mode}).bind(scene)
        np.testing.assert_array_equal(fit(candidates), base)
    with pytest.raises(ConfigError):
        make_fitness("silhouette_edge", model, backend_options={"threads": "gpu"})
