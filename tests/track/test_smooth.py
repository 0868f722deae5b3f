"""Offline smoothing of a track (track --smooth, swarmpose.track.smooth) and the jitter measure."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.errors import ConfigError
from swarmpose.metrics import joint_acceleration
from swarmpose.track.smooth import smooth_params
from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

ROT = np.array([True, True, False])
LOW = np.array([-np.inf, -1.0, -np.inf])
HIGH = np.array([np.inf, 3.1, np.inf])


def test_off_constant_and_limits():
    t = np.arange(30) / 20.0
    p = np.tile([0.3, 0.5, 1000.0], (30, 1))
    assert np.array_equal(smooth_params(p, t, 0.0, ROT, LOW, HIGH), p)
    assert np.allclose(smooth_params(p, t, 0.05, ROT, LOW, HIGH), p)
    q = p.copy()
    q[10:, 1] = 3.1  # at the upper limit: the average of values inside the limits stays inside
    assert np.all(smooth_params(q, t, 0.1, ROT, LOW, HIGH)[:, 1] <= 3.1)
    with pytest.raises(ConfigError, match="seconds"):
        smooth_params(p, t, -1.0, ROT, LOW, HIGH)


def test_noise_is_removed_and_the_motion_kept():
    rng = np.random.default_rng(0)
    t = np.arange(200) / 20.0
    truth = np.stack([0.5 * np.sin(t), 0.4 * np.cos(0.7 * t), 100 * t], axis=1)
    noisy = truth + rng.normal(0, [0.05, 0.05, 5.0], truth.shape)
    s = smooth_params(noisy, t, 0.05, ROT, LOW, HIGH)
    assert np.abs(s - truth).mean(axis=0)[0] < 0.6 * np.abs(noisy - truth).mean(axis=0)[0]
    assert np.abs(s - truth)[5:-5].mean() < np.abs(noisy - truth)[5:-5].mean()


def test_the_heading_is_unwrapped_and_a_bounded_jump_is_not():
    t = np.arange(20) / 20.0
    p = np.zeros((20, 3))
    p[:, 0] = np.where(np.arange(20) < 10, np.pi - 0.01, -np.pi + 0.01)  # a heading crossing +-pi
    p[:, 1] = np.where(np.arange(20) < 10, 3.0, -0.5)  # a bounded rotation jumping by more than pi
    s = smooth_params(p, t, 0.05, ROT, LOW, HIGH)
    assert np.all(np.abs(np.cos(s[:, 0]) + 1.0) < 1e-3)  # stays at the back, never averaged through 0
    assert np.allclose(s[:3, 1], 3.0, atol=1e-3) and np.allclose(s[-3:, 1], -0.5, atol=1e-3)


def test_joint_acceleration_of_a_known_motion_with_uneven_steps():
    t = np.cumsum(np.r_[0.0, np.tile([0.033, 0.017], 20)])  # 25 fps taken from 60: uneven steps
    a = np.array([300.0, -400.0, 1200.0])  # mm/s^2
    joints = (0.5 * a * t[:, None] ** 2)[:, None, :] * np.ones((1, 15, 1))
    assert joint_acceleration(joints, t) == pytest.approx(np.linalg.norm(a), rel=1e-9)
    joints[5, 3] = np.nan  # frames with a missing joint are left out
    assert joint_acceleration(joints, t) == pytest.approx(np.linalg.norm(a), rel=1e-9)
    assert np.isnan(joint_acceleration(joints[:2], t[:2]))


def test_track_smooth_keeps_the_raw_poses_and_measures_the_jitter(short_sequence, tmp_path):
    with pytest.raises(ConfigError, match="smooth"):
        TrackConfig(smooth=-0.1)
    raw = run_tracker(prepare_track(short_sequence, TrackConfig(seed=2), tmp_path / "r"), 0, tmp_path / "r")
    setup = prepare_track(short_sequence, TrackConfig(seed=2, smooth=0.05), tmp_path / "s")
    res = run_tracker(setup, 0, tmp_path / "s")
    m = setup.model
    assert np.array_equal(res.passes["raw_params"], raw.params)
    want = smooth_params(raw.params, setup.frame_times, 0.05, m.is_rotation, m.lower, m.upper)
    assert np.array_equal(res.params, want)
    with np.load(tmp_path / "s" / "run_000" / "track.npz") as z:
        assert np.array_equal(z["raw_params"], raw.params) and np.array_equal(z["params"], want)
    assert res.errors["acceleration_mm_s2"] == pytest.approx(joint_acceleration(m.joints15(want), setup.frame_times))
    assert res.errors["gt_acceleration_mm_s2"] > 0
    assert "backward_kept" not in res.errors


def test_the_smoothing_names_its_folder():
    import swarmpose.cli.app  # noqa: F401  (the commands register on the app first)
    from swarmpose.cli.track_commands import default_results_name

    assert default_results_name("walk", TrackConfig(smooth=0.05)) == "walk-sppso-20fps-smooth0.05s"
