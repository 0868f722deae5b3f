"""Error measures on hand-built motions whose errors are known (thesis eq. 4.4-4.6; Sharifi et al. eq. 19-20)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.errors import ShapeError
from swarmpose.joints import JOINTS15
from swarmpose.metrics import MMTA_DELTA_MM, aggregate_runs, track_errors, valid_frames


def _displaced(gt: np.ndarray, distances: np.ndarray, rng) -> np.ndarray:
    """``gt`` with every joint moved by the given distance ``(T, 15)`` in a random direction."""
    v = rng.normal(size=gt.shape)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return gt + v * distances[..., None]


def test_known_distances_give_the_papers_measures():
    rng = np.random.default_rng(0)
    gt = rng.normal(0, 300, (3, 15, 3))
    dist = np.array([
        np.full(15, 10.0),  # every joint matched at 10 mm
        np.r_[np.full(5, 50.0), np.full(10, 150.0)],  # 5 of 15 within delta
        np.full(15, 200.0),  # none within delta: MMTP takes the penalty delta (Sharifi l.218)
    ])
    e = track_errors(_displaced(gt, dist, rng), gt)
    np.testing.assert_allclose(e.d_per_frame, [10.0, (5 * 50 + 10 * 150) / 15, 200.0])
    assert e.d_mean == pytest.approx(np.mean([10.0, 350.0 / 3, 200.0]))
    assert e.d_max == pytest.approx(200.0)
    assert e.mmta == pytest.approx(np.mean([1.0, 5 / 15, 0.0]))
    assert e.mmtp == pytest.approx(np.mean([10.0, 50.0, MMTA_DELTA_MM]))
    assert e.mu == pytest.approx(e.d_mean)
    assert e.sigma == pytest.approx(np.mean([0.0, np.std(dist[1]), 0.0]))
    assert e.per_joint[JOINTS15[0]] == pytest.approx(np.mean([10.0, 50.0, 200.0]))
    assert e.per_joint[JOINTS15[-1]] == pytest.approx(np.mean([10.0, 150.0, 200.0]))
    assert e.d_std == pytest.approx(np.std([10.0, 350.0 / 3, 200.0]))  # population SD over the frames
    assert track_errors(_displaced(gt[:1], dist[:1], rng), gt[:1]).d_std == 0.0  # one frame: no spread, not NaN


def test_frames_without_ground_truth_are_not_scored():
    rng = np.random.default_rng(1)
    gt = rng.normal(0, 300, (4, 15, 3))
    est = _displaced(gt, np.full((4, 15), 20.0), rng)
    est[2] += 500.0  # a bad estimate where the truth is unknown must not count
    gt[2] = np.nan
    e = track_errors(est, gt)
    assert np.isnan(e.d_per_frame[2]) and np.allclose(np.delete(e.d_per_frame, 2), 20.0)
    assert (e.d_mean, e.d_max, e.mmta, e.mmtp) == pytest.approx((20.0, 20.0, 1.0, 20.0))
    np.testing.assert_array_equal(valid_frames(gt), [True, True, False, True])
    gt[1, 4, 0] = np.nan  # one missing joint invalidates the frame
    assert track_errors(est, gt).d_per_frame[1] != track_errors(est, gt).d_per_frame[1]


def test_bad_input_is_refused_with_a_reason():
    gt = np.zeros((2, 15, 3))
    with pytest.raises(ShapeError, match=r"\(T, 15, 3\)"):
        track_errors(np.zeros((2, 14, 3)), gt)
    for delta in (0.0, -5.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="delta_mm"):
            track_errors(gt, gt, delta_mm=delta)
    with pytest.raises(ValueError, match="no frame to score"):
        track_errors(gt, np.full((2, 15, 3), np.nan))
    with pytest.raises(ValueError, match="no frame to score"):
        track_errors(np.zeros((0, 15, 3)), np.zeros((0, 15, 3)))
    est = gt.copy()
    est[1, 0, 0] = np.inf
    with pytest.raises(ValueError, match="not finite at 1 scored frame"):
        track_errors(est, gt)


def test_aggregate_over_runs():
    rng = np.random.default_rng(2)
    gt = rng.normal(0, 300, (5, 15, 3))
    runs = [track_errors(_displaced(gt, np.full((5, 15), d), rng), gt) for d in (30.0, 120.0, 60.0)]
    agg = aggregate_runs(runs)
    assert agg["d_mean"] == pytest.approx(70.0) and agg["runs"] == 3
    assert agg["worst"]["run"] == 1 and agg["worst"]["d_mean"] == pytest.approx(120.0)
    assert agg["d_mean_std_over_runs"] == pytest.approx(45.825756949558, rel=1e-12)  # sample SD, n - 1 = 2
    assert agg["mmta"] == pytest.approx(2 / 3)
    assert agg["d_max"] == pytest.approx(np.mean([r.d_max for r in runs]))  # mean of the runs' maxima
    assert agg["d_max_over_runs"] == runs[1].d_max == pytest.approx(120.0)  # the largest D of any run
    assert aggregate_runs(runs[:1])["d_mean_std_over_runs"] == 0.0
    with pytest.raises(ValueError, match="no runs"):
        aggregate_runs([])


def test_the_worst_run_is_the_highest_d_mean_and_joints_are_averaged_over_runs():
    """Run A is worse on average, run B has the single largest error: the worst run is A (the papers rank
    by D_mean); per-joint errors are the mean of the runs' own per-joint errors."""
    rng = np.random.default_rng(3)
    gt = rng.normal(0, 300, (6, 15, 3))
    a = np.full((6, 15), 80.0)  # D_mean 80, D_max 80
    b = np.full((6, 15), 20.0)
    b[3] = 300.0  # D_mean 63.3, D_max 300
    c = np.tile(np.linspace(5.0, 145.0, 15), (6, 1))  # per joint 5..145 mm, D_mean 75
    runs = [track_errors(_displaced(gt, d, rng), gt) for d in (b, a, c)]
    agg = aggregate_runs(runs)
    assert agg["worst"]["run"] == 1 and agg["worst"]["d_mean"] == pytest.approx(80.0)
    assert agg["d_max_over_runs"] == pytest.approx(300.0)
    for j, name in enumerate(JOINTS15):
        expected = np.mean([(20.0 * 5 + 300.0) / 6, 80.0, c[0, j]])
        assert agg["per_joint"][name] == pytest.approx(expected)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), shift=st.floats(-1e4, 1e4), scale=st.floats(0.0, 400.0))
def test_measures_are_translation_invariant_and_bounded(seed, shift, scale):
    rng = np.random.default_rng(seed)
    gt = rng.normal(0, 300, (6, 15, 3))
    est = gt + rng.normal(0, 1, gt.shape) * scale
    a, b = track_errors(est, gt), track_errors(est + shift, gt + shift)
    assert a.d_mean == pytest.approx(b.d_mean, abs=1e-6) and a.mmta == b.mmta
    assert 0.0 <= a.mmta <= 1.0 and 0.0 <= a.mmtp <= MMTA_DELTA_MM and a.d_mean <= a.d_max + 1e-9


def test_distances_errors_and_acceleration_in_steps_equal_one_step(monkeypatch):
    """A long track is measured FRAMES_CHUNK frames at a time: the same numbers as all frames at once, with
    missing joints, frames without ground truth and uneven time steps across the steps' borders."""
    from swarmpose import metrics

    rng = np.random.default_rng(3)
    T = 103
    est, gt = rng.normal(0, 300, (T, 15, 3)), rng.normal(0, 300, (T, 15, 3))
    est[[7, 40], 4] = np.nan
    t = np.cumsum(rng.uniform(0.01, 0.05, T))
    h0, h1 = (t[1:-1] - t[:-2])[:, None, None], (t[2:] - t[1:-1])[:, None, None]
    acc = np.linalg.norm(2.0 * (h0 * est[2:] - (h0 + h1) * est[1:-1] + h1 * est[:-2]) / (h0 * h1 * (h0 + h1)), axis=-1)
    want_acc = acc[np.isfinite(acc).all(axis=1)].mean()
    want_d = np.linalg.norm(est - gt, axis=-1)
    scored, truth = est.copy(), gt.copy()
    scored[[7, 40], 4] = 0.0
    truth[[3, 50, 51]] = np.nan  # frames not scored
    monkeypatch.setattr(metrics, "FRAMES_CHUNK", 4096)
    want_err = metrics.track_errors(scored, truth)
    for chunk in (5, 16, 101, 4096):
        monkeypatch.setattr(metrics, "FRAMES_CHUNK", chunk)
        assert metrics.joint_acceleration(est, t) == pytest.approx(want_acc, rel=1e-12)
        np.testing.assert_array_equal(metrics.joint_distances(est, gt), want_d)
        err = metrics.track_errors(scored, truth)
        np.testing.assert_allclose(err.d_per_frame, want_err.d_per_frame, rtol=1e-12)
        for k, v in want_err.summary().items():
            assert err.summary()[k] == pytest.approx(v, rel=1e-12), k
