"""Marker fitness (Sharifi et al. 2017, eq. 7-12) and the robust reprojection fitness."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmpose.camera import fundamental_matrix
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.fitness import MarkerFitness, MarkerFrame, ReprojectionFitness, make_fitness
from swarmpose.fitness.markers import symmetric_epipolar_distance


@pytest.fixture(scope="module")
def detections(model, true_pose, rig):
    """Exact projections of the 15 joints at the true pose, in every view."""
    X = model.joints15(true_pose[None])[0]
    return [cam.project(X) for cam in rig]


def test_symmetric_epipolar_distance(rig, model, true_pose):
    X = model.joints15(true_pose[None])[0]
    F = fundamental_matrix(rig[0], rig[1])
    xa = rig[0].undistort_points(rig[0].project(X))
    xb = rig[1].undistort_points(rig[1].project(X))
    assert symmetric_epipolar_distance(F, xa, xb).max() < 1e-6
    d = symmetric_epipolar_distance(F, xa, xb + [0.0, 3.0])
    assert (d > 0.1).all()


def test_true_pose_scores_weight_one(model, true_pose, rig, detections):
    for backend in ("numba", "reference"):
        fit = make_fitness("markers", model, backend=backend).bind(MarkerFrame(detections, rig))
        w = fit(true_pose[None])
        assert w[0] == pytest.approx(0.0, abs=1e-5)  # log w: w = 1


def test_seen_point_beats_displaced_point(model, true_pose, rig, detections):
    fit = MarkerFitness(model).bind(MarkerFrame(detections, rig))
    moved = true_pose.copy()
    moved[3] += 80.0  # 8 cm: every projection is > 5 px from its detection
    s = fit.point_scores(np.stack([true_pose, moved]))
    assert s[0].max() < 1e-3
    np.testing.assert_allclose(s[1], math.sqrt(6) * 200.0)  # all 6 view pairs penalised
    w = fit(np.stack([true_pose, moved]))
    assert 0.0 >= w[0] > w[1] == pytest.approx(-math.sqrt(6) * 200.0)


def test_missing_detection_gets_the_penalty(model, true_pose, rig, detections):
    m = 7
    dets = [d.copy() for d in detections]
    dets[2] = np.delete(dets[2], m, axis=0)  # point m not detected in view 3
    dets[1] = np.vstack([dets[1], [[5.0, 5.0], [600.0, 400.0]]])  # false detections elsewhere
    fit = MarkerFitness(model).bind(MarkerFrame(dets, rig))
    s = fit.point_scores(true_pose[None])[0]
    assert s[m] == pytest.approx(math.sqrt(3) * 200.0)  # pairs (1,3), (2,3), (3,4) get 200 each
    assert np.delete(s, m).max() < 1e-3
    assert fit(true_pose[None])[0] == pytest.approx(-s.mean())  # log w of eq. 12
    ref = MarkerFitness(model, backend="reference").bind(MarkerFrame(dets, rig))
    assert ref(true_pose[None])[0] == pytest.approx(fit(true_pose[None])[0], rel=1e-9)


def test_backends_agree_on_noisy_detections(model, true_pose, rig, detections):
    rng = np.random.default_rng(0)
    dets = [d + rng.normal(0.0, 1.5, d.shape) for d in detections]
    dets[0] = dets[0][3:]
    poses = true_pose + rng.normal(0.0, 0.3, (12, model.n_params)) * model.sigma
    frame = MarkerFrame(dets, rig)
    for kind in ("markers", "reprojection"):
        a = make_fitness(kind, model).bind(frame)(poses)
        b = make_fitness(kind, model, backend="reference").bind(frame)(poses)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-300)
        assert np.isfinite(a).all() and (a <= 0).all()  # log-weights: w in (0, 1]
    a = ReprojectionFitness(model, symmetric=False).bind(frame)(poses)
    b = ReprojectionFitness(model, symmetric=False, backend="reference").bind(frame)(poses)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-300)


def test_reprojection_explains_every_detection(model, true_pose, rig, detections):
    """The symmetric term charges a detection no model point explains; the one-sided score cannot see it."""
    X = model.joints15(true_pose[None])[0]
    extra = X[4] + np.array([0.0, 0.0, -300.0])  # a marker 30 cm below the left wrist (e.g. on the hip)
    dets = [np.vstack([d, cam.project(extra[None])]) for d, cam in zip(detections, rig, strict=True)]
    frame = MarkerFrame(dets, rig)
    one_sided = ReprojectionFitness(model, symmetric=False).bind(frame)
    symmetric = ReprojectionFitness(model).bind(frame)
    assert one_sided(true_pose[None])[0] == pytest.approx(0.0, abs=1e-9)
    w = symmetric(true_pose[None])[0]
    e = np.array([np.linalg.norm(cam.project(X) - cam.project(extra[None]), axis=1).min() for cam in rig])
    n_terms = 15 * len(rig) + 16 * len(rig)  # model points + detections (15 true + 1 extra) per view
    expected = -np.log1p((np.minimum(e, 50.0) / 5.0) ** 2).sum() / n_terms
    assert w == pytest.approx(expected, rel=1e-9)
    assert w < 0.0


def test_reprojection_is_smooth_and_bounded(model, true_pose, rig, detections):
    fit = ReprojectionFitness(model).bind(MarkerFrame(detections, rig))
    shifts = np.array([0.0, 2.0, 5.0, 10.0, 20.0, 40.0])
    poses = np.repeat(true_pose[None], len(shifts), axis=0)
    poses[:, 4] += shifts  # mm sideways
    w = fit(poses)
    assert w[0] == pytest.approx(0.0, abs=1e-9)
    assert (np.diff(w) < 0).all()
    empty = ReprojectionFitness(model).bind(MarkerFrame([np.zeros((0, 2))] * len(rig), rig))
    assert empty(true_pose[None])[0] == pytest.approx(-math.log1p((50.0 / 5.0) ** 2))


def test_exception(model, rig, detections, true_pose):
    with pytest.raises(ShapeError):
        MarkerFrame(detections[:2], rig)
    with pytest.raises(ShapeError):
        MarkerFrame([np.zeros((3, 3))] * len(rig), rig)
    with pytest.raises(ConfigError, match="known"):
        make_fitness("markers", model, backend="cuda")
    with pytest.raises(ConfigError):
        MarkerFitness(model, rho=0.0)
    with pytest.raises(ConfigError):
        MarkerFitness(model, points="hands")
    fit = MarkerFitness(model)
    with pytest.raises(RuntimeError):
        fit(true_pose[None])
    with pytest.raises(ShapeError):
        fit.bind(detections)
    fit.bind(MarkerFrame(detections, rig))
    assert fit.evaluate(true_pose[None], {"edge_cones": "torso"}).shape == (1,)  # image options ignored
    assert fit.prepare_ms >= 0.0
