"""The silhouette distance term: numba kernel against the plain reference, and the shape of its landscape."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.errors import ConfigError
from swarmpose.fitness import make_fitness
from swarmpose.fitness.distance import distance_terms, distance_terms_reference, prepare_distance_maps
from swarmpose.render.project import camera_tables


@pytest.mark.parametrize("scale", [1, 2])
def test_kernel_matches_reference(model, scene, candidates, scale):
    maps = prepare_distance_maps(scene.silhouettes, tau=40.0, stride=12, scale=scale)
    R, t, cam, _, _ = camera_tables(scene.cameras)
    got = distance_terms(model, candidates[:12], R, t, cam, maps, 100.0)
    ref = distance_terms_reference(model, candidates[:12], scene.cameras, maps, 100.0)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def test_fitness_entry_points_use_the_same_definitions(model, scene, candidates):
    fast = make_fitness("silhouette_edge", model).bind(scene)
    slow = make_fitness("silhouette_edge", model, backend="reference").bind(scene)
    p = candidates[:4]
    np.testing.assert_allclose(fast.evaluate(p, {"terms": "distance"}), slow.evaluate(p, {"terms": "distance"}),
                               rtol=1e-9)
    np.testing.assert_allclose(fast.part_agreement(p), slow.part_agreement(p), rtol=1e-9, atol=1e-12)
    # the weighted term is added to the papers' fitness, which stays as it was without it
    base = fast.evaluate(p)
    np.testing.assert_allclose(fast.evaluate(p, {"distance": 0.5}), base + 0.5 * fast.distance_score(p))
    np.testing.assert_array_equal(fast.evaluate(p, {"distance": 0}), base)


def test_score_keeps_rising_towards_the_person(model, scene, true_pose):
    """Shift the whole body sideways by 0..200 mm: the distance score falls at every step (the overlap terms
    are flat once the silhouettes no longer overlap; this one is not, up to its truncation)."""
    fit = make_fitness("silhouette_edge", model).bind(scene)
    shifts = np.array([0.0, 25.0, 50.0, 100.0, 150.0, 200.0])
    poses = np.repeat(true_pose[None], len(shifts), axis=0)
    poses[:, 3] += shifts
    s = fit.evaluate(poses, {"terms": "distance"})
    assert np.all(np.diff(s) < 0), s
    assert -0.05 < s[0] <= 0.0


def test_lost_arm_shows_in_its_cones(model, scene, true_pose):
    fit = make_fitness("silhouette_edge", model).bind(scene)
    off = true_pose.copy()
    off[model.param_index("r_shoulder_abd")] -= np.radians(90)  # the right arm raised 90 degrees off
    parts = fit.part_agreement(np.stack([true_pose, off]))
    names = model.cone_arrays.names
    arm = [names.index("r_upper_arm"), names.index("r_lower_arm")]
    assert parts[0].max() < 0.01
    assert parts[1, arm].max() > 0.1
    others = np.setdiff1d(np.arange(len(names)), arm)
    np.testing.assert_allclose(parts[1, others], parts[0, others])


def test_empty_view_and_bad_settings():
    sil = np.zeros((2, 20, 30), np.uint8)
    sil[1, 5:15, 10:20] = 1
    maps = prepare_distance_maps(sil, tau=5.0, stride=2)
    assert maps.n_points[0] == 0 and maps.n_points[1] == 25
    assert np.all(maps.outside[0] == 5.0)
    assert maps.outside[1, 10, 15] == 0.0 and maps.outside[1, 10, 25] == pytest.approx(6.0)
    with pytest.raises(ConfigError, match="tau"):
        prepare_distance_maps(sil, tau=0.0)
    with pytest.raises(ConfigError, match="stride"):
        prepare_distance_maps(sil, stride=1.5)


def test_noise_blobs_are_not_sampled():
    sil = np.zeros((1, 100, 100), np.uint8)
    sil[0, 10:90, 40:60] = 1  # the person
    sil[0, 2:4, 2:4] = 1  # a 4-pixel blob: < 2 % of the person
    maps = prepare_distance_maps(sil, stride=2)
    assert maps.points[0, :maps.n_points[0], 0].min() >= 40


def test_reduced_maps_keep_frame_pixel_distances():
    sil = np.zeros((1, 60, 80), np.uint8)
    sil[0, 20:40, 30:50] = 1
    full = prepare_distance_maps(sil, stride=2)
    half = prepare_distance_maps(sil, stride=2, scale=2)
    assert half.outside.shape == (1, 30, 40)
    # a pixel 10 frame pixels right of the square: within a reduced pixel of the exact distance
    assert full.outside[0, 30, 59] == pytest.approx(10.0, abs=0.1)
    assert half.outside[0, 15, 29] == pytest.approx(10.0, abs=2.0)
    assert abs(half.n_points[0] - full.n_points[0]) <= 0.1 * full.n_points[0]
