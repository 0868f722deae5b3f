"""The optional PyTorch backend gives the numba backend's measurements (and the reference's).

Runs where PyTorch is installed (``make test`` installs the CPU build where this machine kind has it),
on the GPU when torch sees one (``SWARMPOSE_TEST_TORCH_DEVICE`` names another device).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from swarmpose.errors import ConfigError
from swarmpose.fitness import BACKENDS, make_fitness, torch_available
from swarmpose.fitness.scene import demo_cameras, demo_frame

torch = pytest.importorskip("torch")
DEVICE = os.environ.get("SWARMPOSE_TEST_TORCH_DEVICE", "cuda" if torch.cuda.is_available() else "cpu")
FIELDS = ("overlap", "projected", "edge_sum", "edge_sq", "edge_count", "region_sq", "region_count")
OPTIONS = [None, {"edge_cones": "torso"}, {"edge_cones": "torso+upper", "edge_top": False},
           {"terms": "silhouette"}, {"terms": "edge"}]


def _torch_fit(model, frame, kind="silhouette_edge", **backend_options):
    return make_fitness(kind, model, backend="torch",
                        backend_options={"device": DEVICE, **backend_options}).bind(frame)


def _assert_same(a, b, *, atol=1e-9):
    for f in FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        if f in ("overlap", "projected", "edge_count", "region_count"):
            np.testing.assert_array_equal(x, y, err_msg=f)
        else:
            np.testing.assert_allclose(x, y, atol=atol, rtol=0, err_msg=f)


def _wild_poses(model, true_pose, rig, n=120, seed=1):
    """Poses far from the truth: large perturbations, any orientation, bodies anywhere in the room and
    within a metre of a camera (cones cut by the near plane, thousands of samples)."""
    rng = np.random.default_rng(seed)
    p = true_pose + rng.normal(0.0, 4.0, (n, model.n_params)) * model.sigma
    q = n // 4
    p[:q, 3:6] = rng.uniform([-4500, -4500, -500], [4500, 4500, 2500], (q, 3))  # pelvis position, mm
    p[q:2 * q, 0:3] = rng.uniform(-np.pi, np.pi, (q, 3))  # pelvis orientation
    cams = rng.integers(0, len(rig), q)
    p[2 * q:3 * q, 3:6] = np.array([rig[c].center for c in cams]) + rng.normal(0.0, 500.0, (q, 3))
    return p


def _top_view_frame(model, true_pose):
    """A rig with cameras straight above and below the body: cones seen along their axes (closed rims)."""
    from swarmpose.camera import Camera

    cams = [Camera.look_at("above", eye=(1.0, 0.0, 4500.0), target=(0.0, 0.0, 900.0), f=700.0, width=322,
                           height=242, dist=(-0.2, 0.05, 0.0, 0.0, 0.0)),
            Camera.look_at("below", eye=(0.0, 1.0, -2500.0), target=(0.0, 0.0, 900.0), f=700.0, width=322,
                           height=242),
            *demo_cameras(2, width=322, height=242)]
    return demo_frame(model, true_pose, cams, rng=np.random.default_rng(8))


def test_registered_and_available():
    assert "torch" in BACKENDS and torch_available()


@pytest.mark.parametrize("kind", ["silhouette_edge", "deutscher_reid"])
@pytest.mark.parametrize("options", OPTIONS)
def test_matches_numba_exactly(model, scene, candidates, kind, options):
    """Same pixel counts and sample counts as the numba kernel; sums to rounding."""
    fast = make_fitness(kind, model).bind(scene)
    tfit = _torch_fit(model, scene, kind)
    _assert_same(tfit.measure(candidates, options), fast.measure(candidates, options))
    np.testing.assert_allclose(tfit.evaluate(candidates, options), fast.evaluate(candidates, options),
                               atol=1e-12, rtol=0)


def test_wild_poses_match_numba(model, scene, rig, true_pose):
    """Cones cut by the near plane, bodies out of view or filling a view, across the whole batch."""
    poses = _wild_poses(model, true_pose, rig)
    from swarmpose.render import project_cones

    drawn = project_cones(model, poses, rig).n_vertices > 0  # cones the near plane drops are compared too
    assert (~drawn).sum() > 100 and drawn.sum() > 1000, ((~drawn).sum(), drawn.sum())
    for kind in ("silhouette_edge", "deutscher_reid"):
        _assert_same(_torch_fit(model, scene, kind).measure(poses), make_fitness(kind, model).bind(scene).measure(poses))


def test_views_along_the_axes_match_numba(model, true_pose):
    """Cameras above and below: outlines that are one whole cap rim, the torso's top edge a closed rim."""
    from swarmpose.render import project_cones

    frame = _top_view_frame(model, true_pose)
    rng = np.random.default_rng(9)
    poses = true_pose + rng.normal(0.0, 0.5, (40, model.n_params)) * model.sigma
    pc = project_cones(model, poses, frame.cameras)
    whole_rim = np.isnan(pc.sides[..., 0, 0, 0]) & (pc.n_vertices > 0)
    # outlines that are one whole cap rim are compared, the torso's top edge among them
    assert whole_rim.sum() >= 80 and pc.end_arc_closed.sum() >= 40, (whole_rim.sum(), pc.end_arc_closed.sum())
    for kind in ("silhouette_edge", "deutscher_reid"):
        for options in (None, {"edge_cones": "torso"}):
            _assert_same(_torch_fit(model, frame, kind).measure(poses, options),
                         make_fitness(kind, model).bind(frame).measure(poses, options))


def test_a_pose_at_a_camera_gets_a_chunk_of_its_own(model, scene, rig, true_pose):
    """One particle next to a camera has thousands of samples; it must not size the tensors of the
    ordinary poses (the chunk plan) and must still be measured right."""
    from swarmpose.fitness.torch_backend import _plan_chunks

    rng = np.random.default_rng(10)
    poses = true_pose + rng.normal(0.0, 1.0, (200, model.n_params)) * model.sigma
    poses[57, 3:6] = rig[0].center + (0.0, 0.0, -600.0)
    tfit = _torch_fit(model, scene, "deutscher_reid")
    be, prep = tfit.backend, tfit.prepared
    req = tfit._request(tfit.default_options)
    pt = be._tensor(poses)
    cost = be._pose_costs(be._outlines(be._forward(pt), be._frame_tensors(prep)), prep, req)
    assert cost[57] > 20 * np.median(cost)
    chunks = _plan_chunks(cost, be.max_elements)
    for idx in chunks:
        assert len(idx) == 1 or len(idx) * cost[idx].max() <= be.max_elements
    assert [57] in [list(c) for c in chunks] or cost[57] * 2 <= be.max_elements
    np.testing.assert_array_equal(np.sort(np.concatenate(chunks)), np.arange(200))
    _assert_same(tfit.measure(poses), make_fitness("deutscher_reid", model).bind(scene).measure(poses))


@pytest.mark.parametrize("costs,budget", [([5, 1, 1, 9, 2], 10), ([100], 10), ([3] * 7, 9), ([1, 2], 1000)])
def test_chunk_plan(costs, budget):
    from swarmpose.fitness.torch_backend import _plan_chunks

    cost = np.array(costs)
    chunks = _plan_chunks(cost, budget)
    np.testing.assert_array_equal(np.sort(np.concatenate(chunks)), np.arange(len(costs)))
    for idx in chunks:
        assert len(idx) == 1 or len(idx) * cost[idx].max() <= budget


def test_matches_the_plain_reference(model, scene, candidates):
    ref = make_fitness("deutscher_reid", model, backend="reference").bind(scene)
    tfit = _torch_fit(model, scene, "deutscher_reid")
    _assert_same(tfit.measure(candidates[:6]), ref.measure(candidates[:6]))
    ref = make_fitness("silhouette_edge", model, backend="reference").bind(scene)
    tfit = _torch_fit(model, scene)
    _assert_same(tfit.measure(candidates[:6]), ref.measure(candidates[:6]))


@pytest.mark.parametrize("scale", [4, 1])
def test_walk_frames_match_numba(walk, scale):
    """Synthesised images of the walking clip (the observation body is not the cone model)."""
    rng = np.random.default_rng(scale)
    for f, x in enumerate(walk.ik):
        frame = walk.frames[f].downsample(scale)
        poses = x + rng.normal(0.0, 1.0, (30, walk.model.n_params)) * walk.model.sigma
        _assert_same(_torch_fit(walk.model, frame).measure(poses), make_fitness("silhouette_edge", walk.model)
                     .bind(frame).measure(poses))


def test_own_rendering_scores_one(model, true_pose, exact_scene):
    fs, _ = _torch_fit(model, exact_scene).terms(true_pose[None], {"terms": "silhouette"})
    np.testing.assert_array_equal(fs, 1.0)


def test_chunks_and_float32(model, scene, rig, true_pose):
    """Cutting the batch into chunks changes nothing; single precision moves a boundary pixel at most
    now and then."""
    poses = _wild_poses(model, true_pose, rig, n=40, seed=2)
    whole = _torch_fit(model, scene)
    tiny = _torch_fit(model, scene, max_elements=1)  # one pose per chunk
    _assert_same(tiny.measure(poses), whole.measure(poses))
    single = _torch_fit(model, scene, dtype="float32")
    fs_a, fe_a = single.terms(poses)
    fs_b, fe_b = whole.terms(poses)
    assert np.abs(fs_a - fs_b).max() <= 1e-3 and np.abs(fe_a - fe_b).max() <= 1e-3


def test_batch_edges(model, scene, candidates):
    fit = _torch_fit(model, scene)
    assert fit(candidates[:0]).shape == (0,)
    m = fit.backend.measure(fit.prepared, candidates[:0], fit._request(fit.default_options))
    assert m.overlap.shape == (0, 4)
    bad = candidates[:3].copy()
    bad[1, 4] = np.nan
    s = fit(bad)
    assert np.isnan(s[1]) and np.isfinite(s[[0, 2]]).all()
    np.testing.assert_array_equal(fit(candidates[:1]), make_fitness("silhouette_edge", model).bind(scene)(candidates[:1]))


def test_a_frame_prepared_elsewhere_is_uploaded_once(model, scene, candidates):
    from swarmpose.fitness import prepare_frame

    prep = prepare_frame(scene)
    fit = _torch_fit(model, prep)
    fit(candidates[:2])
    assert len(prep.extra) == 1
    fit(candidates[:2])
    assert len(prep.extra) == 1


def test_bad_settings_are_named(model, monkeypatch):
    with pytest.raises(ConfigError, match="dtype"):
        make_fitness("silhouette_edge", model, backend="torch", backend_options={"dtype": "float16"})
    with pytest.raises(ConfigError, match="device"):
        make_fitness("silhouette_edge", model, backend="torch", backend_options={"device": "no-such-device"})
    if not torch.cuda.is_available():
        with pytest.raises(ConfigError, match="device"):
            make_fitness("silhouette_edge", model, backend="torch", backend_options={"device": "cuda"})
    with pytest.raises(ConfigError, match="max_elements"):
        make_fitness("silhouette_edge", model, backend="torch", backend_options={"max_elements": 0})
    with pytest.raises(ConfigError, match="markers"):
        make_fitness("markers", model, backend="torch")
    monkeypatch.setitem(__import__("sys").modules, "torch", None)  # as if not installed
    with pytest.raises(ConfigError, match=r"pip install .swarmpose\[torch\]."):
        make_fitness("silhouette_edge", model, backend="torch")


def test_degenerate_frames(model, rig, true_pose):
    from swarmpose.features import FrameFeatures

    C, H, W = 4, rig[0].height, rig[0].width
    empty = FrameFeatures(np.zeros((C, H, W), np.uint8), np.zeros((C, H, W), np.float32), rig)
    away = true_pose.copy()
    away[3] += 50_000.0
    poses = np.stack([true_pose, away])
    fs, fe = _torch_fit(model, empty).terms(poses)
    np.testing.assert_array_equal(fs, [[0.0] * C, [1.0] * C])
    np.testing.assert_array_equal(fe, 0.0)


def test_tracking_with_the_torch_backend(tmp_path, mocap_dir):
    """Two frames tracked with --backend torch give the numba backend's result."""
    from swarmpose.synth.synthesize import synthesize
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    seq = tmp_path / "seq"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", seq, fps=60, seed=0, max_frames=4, measure=False, progress=False)
    runs = {}
    for backend in ("numba", "torch"):
        cfg = TrackConfig(algo="sppso", fps=20.0, seed=5, backend=backend, downsample=4)
        runs[backend] = run_tracker(prepare_track(seq, cfg, None), 0, None)
    np.testing.assert_allclose(runs["torch"].scores, runs["numba"].scores, atol=1e-9)
    assert abs(runs["torch"].errors["d_mean"] - runs["numba"].errors["d_mean"]) < 1e-6


def test_demo_scene_at_half_resolution(model, true_pose):
    cams = demo_cameras(4, width=322, height=242)
    half = demo_frame(model, true_pose, cams, rng=np.random.default_rng(4))
    poses = _wild_poses(model, true_pose, cams, n=30, seed=3)
    _assert_same(_torch_fit(model, half).measure(poses), make_fitness("silhouette_edge", model).bind(half).measure(poses))


def test_torch_backend_matches_numba_on_the_image_border():
    """(torch_backend.py:693 `xi < W` -> `xi <= W`): the demo scenes have zero edges and silhouette at
    the border, so a sample read from outside the last column goes unnoticed. With all-ones feature images
    every sample at x or y in [W - 1/2, W + 1/2) matters."""
    pytest.importorskip("torch")
    from swarmpose.body.model import load_model
    from swarmpose.features import FrameFeatures
    from swarmpose.fitness import make_fitness
    from swarmpose.fitness.scene import demo_cameras

    m = load_model("balan31")
    cams = demo_cameras(4, width=322, height=242)
    ones = FrameFeatures(np.ones((4, 242, 322), np.uint8), np.ones((4, 242, 322), np.float32), cams)
    rng = np.random.default_rng(3)
    p = np.tile(m.zero_pose(), (200, 1))
    p += rng.normal(0.0, 2.0, p.shape) * m.sigma
    p[:, 3:6] = rng.uniform([-2500, -2500, 500], [2500, 2500, 1300], (200, 3))  # bodies across the views
    for kind in ("silhouette_edge", "deutscher_reid"):
        fast = make_fitness(kind, m).bind(ones).measure(p, None)
        tor = make_fitness(kind, m, backend="torch", backend_options={"device": "cpu"}).bind(ones).measure(p, None)
        for f in ("edge_sum", "edge_count", "region_sq", "region_count", "overlap", "projected"):
            np.testing.assert_allclose(getattr(tor, f), getattr(fast, f), atol=1e-9, rtol=0, err_msg=f)
