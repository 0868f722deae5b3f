"""The offline backward pass (``track --backward``, swarmpose.track.step.backward_pass)."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.body.model import load_model
from swarmpose.track.path import best_path
from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker


@pytest.fixture(scope="module")
def tracked(short_sequence, tmp_path_factory):
    """The short walk (4 frames at 20 fps) with `refined`, forwards only and with the backward pass."""
    out = tmp_path_factory.mktemp("backward")
    fwd = run_tracker(prepare_track(short_sequence, TrackConfig(algo="refined", seed=3), out / "f"), 0, out / "f")
    cfg = TrackConfig(algo="refined", seed=3, backward=True)
    both = run_tracker(prepare_track(short_sequence, cfg, out / "b"), 0, out / "b")
    return fwd, both, out


def test_the_forward_pass_is_the_plain_track_and_each_frame_keeps_the_pose_the_fitness_prefers(tracked,
                                                                                                 short_sequence):
    from swarmpose.fitness import make_fitness
    from swarmpose.io.sequence import open_sequence
    from swarmpose.track.observation import frame_observation

    fwd, both, out = tracked
    T = len(fwd.params)
    passes = both.passes
    assert np.array_equal(passes["forward_params"], fwd.params)  # the same forward pass, same stream
    assert np.array_equal(passes["forward_scores"], fwd.scores)
    kept, mixed, path_forward = passes["backward_kept"], passes["backward_mixed"], passes["backward_path_forward"]
    assert kept.shape == mixed.shape == path_forward.shape == (T,)
    assert not (kept & mixed).any() and not (path_forward & (kept | mixed)).any()
    # each frame's pose is the forward pass's or the backward pass's, as the path over both chose
    setup = prepare_track(short_sequence, TrackConfig(algo="refined", seed=3, backward=True), out / "b")
    back = passes["backward_params"]
    take = best_path(np.stack([passes["forward_scores"], passes["backward_scores"]], axis=1),
                     np.stack([setup.model.joints15(fwd.params), setup.model.joints15(back)], axis=1),
                     setup.config.backward_path) == 1
    assert np.array_equal(both.params, np.where(take[:, None], back, fwd.params))
    assert np.array_equal(take, kept | mixed)
    assert np.array_equal(both.params[~kept & ~mixed], fwd.params[~kept & ~mixed])
    # per frame, the backward pass's pose scores at least as well as the forward pass's under the refinement's
    # options (its limbs are the better of both passes')
    fit = make_fitness("silhouette_edge", setup.model)
    options = dict(setup.config.optimizer(setup.model).refine_options) or None
    with open_sequence(short_sequence) as seq:
        for i in range(T):  # the last frame too: the forward pass's pose or the fresh search's
            fit.bind(frame_observation(seq, int(setup.frame_indices[i]), "silhouette_edge", 1, seq.backgrounds()))
            s = fit.evaluate(np.stack([fwd.params[i], back[i]]), options)
            assert s[1] >= s[0]
            assert passes["backward_scores"][i] == pytest.approx(s[1])
            assert both.scores[i] == pytest.approx(s[1] if take[i] else s[0])
    # the cost of both passes, per frame (the last frame: the fresh search over every heading and its rounds)
    assert np.all(both.evaluations > fwd.evaluations)
    assert both.evaluations[-1] > fwd.evaluations[-1] + 7 * 1000
    assert both.errors["backward_kept"] == int(kept.sum()) and both.errors["backward_mixed"] == int(mixed.sum())
    assert both.errors["backward_path_forward"] == int(path_forward.sum())


def test_the_results_folder_keeps_both_passes(tracked):
    _, both, out = tracked
    with np.load(out / "b" / "run_000" / "track.npz") as z:
        assert np.array_equal(z["params"], both.params)
        assert np.array_equal(z["forward_params"], both.passes["forward_params"])
        assert np.array_equal(z["backward_kept"], both.passes["backward_kept"])
    with np.load(out / "f" / "run_000" / "track.npz") as z:
        assert "forward_params" not in z


def test_same_seed_same_result_and_resume_after_an_interrupted_forward_pass(tracked, short_sequence, tmp_path):
    _, both, _ = tracked
    cfg = TrackConfig(algo="refined", seed=3, backward=True)
    setup = prepare_track(short_sequence, cfg, tmp_path)
    assert setup.progress_frames == 2 * len(setup.frame_indices) - 1
    part = run_tracker(setup, 0, tmp_path, stop_after=2)
    assert part.passes is None  # no backward pass before the forward pass is whole
    seen = []
    resumed = run_tracker(prepare_track(short_sequence, cfg, tmp_path), 0, tmp_path, resume=True,
                          progress=lambda done, total: seen.append((done, total)))
    assert np.array_equal(resumed.params, both.params)
    assert np.array_equal(resumed.scores, both.scores)
    T = len(setup.frame_indices)
    assert seen[-1] == (2 * T - 1, 2 * T - 1)  # the progress bar runs over both passes


def test_the_backward_setting_names_its_folder():
    import swarmpose.cli.app  # noqa: F401  (the commands register on the app first)
    from swarmpose.cli.track_commands import default_results_name

    assert default_results_name("walk", TrackConfig(algo="refined", backward=True)) == "walk-refined-20fps-backward"
    assert (default_results_name("walk", TrackConfig(algo="refined", backward=True, backward_path=0.0))
            == "walk-refined-20fps-backward-path0")


def test_the_path_weight_is_checked_and_its_cli_default_is_the_library_s():
    import inspect

    import swarmpose.cli.app  # noqa: F401
    from swarmpose.cli.common import DEFAULT_BACKWARD_PATH
    from swarmpose.cli.track_commands import track
    from swarmpose.errors import ConfigError
    from swarmpose.track.path import DEFAULT_PATH_WEIGHT

    assert TrackConfig().backward_path == DEFAULT_PATH_WEIGHT == DEFAULT_BACKWARD_PATH
    assert inspect.signature(track).parameters["backward_path"].default.default == DEFAULT_PATH_WEIGHT
    for bad in (-1.0, float("inf"), True, "0.3"):
        with pytest.raises(ConfigError, match="backward_path must be a weight"):
            TrackConfig(backward=True, backward_path=bad)


def test_the_path_weight_without_the_backward_pass_is_refused(short_sequence, tmp_path):
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    res = CliRunner().invoke(app, ["track", str(short_sequence), "--backward-path", "1", "--out", str(tmp_path / "o")])
    assert res.exit_code != 0 and "give --backward as well" in res.output and not (tmp_path / "o").exists()


def test_a_forward_pass_that_ends_lost_does_not_start_the_backward_pass_lost(short_sequence):
    """The forward pass's last pose turned round and its arms thrown up: the fresh wide search of the last frame
    scores better, is kept there, and the backward pass goes on from it (the other frames keep good poses)."""
    from swarmpose.body.priors import HardPriors
    from swarmpose.io.sequence import open_sequence
    from swarmpose.track.motion import parse_motion
    from swarmpose.track.observation import frame_observation
    from swarmpose.track.recovery import Recovery
    from swarmpose.track.step import FrameSearch, backward_pass
    from swarmpose.track.timing import PartTimer
    from swarmpose.track.tracker import _make_fitness

    setup = prepare_track(short_sequence, TrackConfig(algo="refined", seed=3), None)
    model = setup.model
    algo = setup.config.optimizer(model)
    motion = parse_motion(setup.config.motion)
    fit = _make_fitness(setup)
    search = FrameSearch(model=model, algo=algo, fitness=fit, motion=motion, motion_mask=motion.mask(model),
                         constraint=HardPriors(model).valid, timer=PartTimer(), extra_options={},
                         recovery=Recovery.from_settings(algo.recovery))
    forward = np.array(setup.ik_params, dtype=np.float64)  # the truth's IK fit, its last pose spoilt
    forward[-1, model.param_index("pelvis_rz")] += np.pi
    for name in ("l_shoulder_abd", "r_shoulder_abd"):
        forward[-1, model.param_index(name)] = model.upper[model.param_index(name)]
    with open_sequence(short_sequence) as seq:
        bgs = seq.backgrounds()

        def observe(i: int) -> None:
            fit.bind(frame_observation(seq, int(setup.frame_indices[i]), "silhouette_edge", 1, bgs))

        out = backward_pass(search, forward, observe, np.random.default_rng(0))
    d = np.linalg.norm(model.joints15(out.params) - setup.gt_joints, axis=-1).mean(axis=1)
    d_spoilt = np.linalg.norm(model.joints15(forward[-1:])[0] - setup.gt_joints[-1], axis=-1).mean()
    assert out.backward[-1] and d[-1] < 60.0 < 200.0 < d_spoilt
    assert d.max() < 60.0 and out.evaluations[-1] > 7 * 1000


def test_mix_limbs_takes_each_limb_from_the_pass_that_has_it(short_sequence):
    """Two poses of one frame, each with a different arm thrown out of the silhouettes: the mix keeps the good arm
    of each, scores higher than both, and says which parameters came from the second pose."""
    from swarmpose.body.priors import HardPriors
    from swarmpose.io.sequence import open_sequence
    from swarmpose.track.observation import frame_observation
    from swarmpose.track.step import mix_limbs
    from swarmpose.track.tracker import _make_fitness

    setup = prepare_track(short_sequence, TrackConfig(algo="refined", seed=3), None)
    model = setup.model
    fit = _make_fitness(setup)
    with open_sequence(short_sequence) as seq:
        fit.bind(frame_observation(seq, int(setup.frame_indices[1]), "silhouette_edge", 1, seq.backgrounds()))
    truth = np.array(setup.ik_params[1], dtype=np.float64)
    a, b = truth.copy(), truth.copy()
    a[model.param_index("l_shoulder_abd")] = model.upper[model.param_index("l_shoulder_abd")]
    b[model.param_index("r_shoulder_flex")] += 1.4
    x, score, from_b = mix_limbs(fit, model, a, b, None, HardPriors(model).valid)
    left, right = model.group("left_arm"), model.group("right_arm")
    assert np.array_equal(x[left], b[left]) and np.array_equal(x[right], a[right])
    assert np.allclose(x, truth)
    assert from_b[left].all() and not from_b[right].any()
    pair = fit.evaluate(np.stack([a, b]))
    assert score == pytest.approx(float(fit.evaluate(x[None])[0])) and score > pair.max()
    same, s2, none = mix_limbs(fit, model, truth, truth, None)
    assert np.array_equal(same, truth) and not none.any()


def test_the_silhouettes_centre_rises_with_the_body_and_moves_the_predicted_height():
    """The cone model drawn at two heights 120 mm apart: the triangulated centre of its silhouettes rises by about
    as much, and a search with ``silhouette_height`` moves its prediction of the root height by that rise, only
    from a neighbouring position (either direction) and never on the first frame searched."""
    from swarmpose.fitness import make_fitness
    from swarmpose.fitness.scene import demo_cameras, demo_frame
    from swarmpose.track.motion import parse_motion
    from swarmpose.track.start import centre_of_silhouettes
    from swarmpose.track.step import RISE_DEAD_ZONE_MM, FrameSearch
    from swarmpose.track.timing import PartTimer, TimedFitness

    model = load_model("balan31")
    cams = demo_cameras(4)
    low = model.zero_pose()
    low[model.param_index("pelvis_tz")] = 950.0
    high = low.copy()
    high[model.param_index("pelvis_tz")] += 120.0
    frames = [demo_frame(model, x, cams, inflate=1.0, clutter=0, noise=0.0) for x in (low, high)]
    c0, c1 = (centre_of_silhouettes(f.silhouettes, list(f.cameras)) for f in frames)
    assert c1[2] - c0[2] == pytest.approx(120.0, abs=6.0)
    assert np.linalg.norm((c1 - c0)[:2]) < 6.0
    assert centre_of_silhouettes(np.zeros_like(frames[0].silhouettes), list(cams)) is None

    fit = make_fitness("silhouette_edge", model)
    motion = parse_motion("zero-velocity")
    search = FrameSearch(model=model, algo=None, fitness=TimedFitness(fit, PartTimer()), motion=motion, motion_mask=motion.mask(model),
                         constraint=None, timer=None, extra_options={}, silhouette_height=True)
    rises = []
    for i, f in [(5, 0), (6, 1), (7, 0), (9, 1), (8, 0)]:  # positions, frames: 9 is not next to 7
        fit.bind(frames[f])
        rises.append(search._rise(i))
    dz = c1[2] - c0[2] - RISE_DEAD_ZONE_MM  # the rise beyond the dead zone
    assert rises[0] == 0.0 and rises[3] == 0.0
    assert rises[1] == pytest.approx(dz) and rises[2] == pytest.approx(-dz)
    assert rises[4] == pytest.approx(-dz)  # a backward pass: 9 -> 8
    small_rise = low.copy()
    small_rise[model.param_index("pelvis_tz")] += 0.5 * RISE_DEAD_ZONE_MM
    rises = []
    for i, x in enumerate((low, small_rise)):
        fit.bind(demo_frame(model, x, cams, inflate=1.0, clutter=0, noise=0.0))
        rises.append(search._rise(20 + i))
    assert rises == [0.0, 0.0]  # a rise within the dead zone does not move the prediction


def test_with_keypoint_height_the_trunks_keypoints_give_the_rise():
    """With ``keypoint_height`` the rise is the mean rise of the hips' and shoulders' triangulated keypoints between
    the position searched before and this one (either direction, no dead zone: a 4 mm rise counts); a frame missing
    one of them falls back to the silhouettes' rise (none known here: 0); an arm raised alone moves nothing."""
    from swarmpose.joints import JOINT_INDEX as J
    from swarmpose.track.step import FrameSearch

    model = load_model("balan31")
    x = model.zero_pose()
    x[model.param_index("pelvis_tz")] = 950.0
    kp = np.repeat(model.joints15(x[None]), 6, axis=0)
    kp[1] += [0.0, 0.0, 40.0]  # the body up 40 mm
    kp[2] = kp[1] + [0.0, 0.0, 4.0]
    kp[3] = kp[2]
    kp[3, J["r_wrist"]] += [0.0, 0.0, 300.0]  # an arm raised: not the trunk
    kp[3, J["r_elbow"]] += [0.0, 0.0, 150.0]
    kp[4] = kp[3]
    kp[4, J["l_hip"]] = np.nan
    kp[5] = kp[3]
    fitness = SimpleNamespace(features=None)  # no silhouettes: their rise is unknown
    search = FrameSearch(model=model, algo=None, fitness=fitness, motion=None, motion_mask=None, constraint=None,
                         timer=None, extra_options={}, silhouette_height=True, keypoint_height=True, kp_joints=kp)
    rises = [search._rise(i) for i in (0, 1, 2, 3, 4, 5, 3, 2, 1, 0)]
    assert rises[0] == 0.0  # nothing searched before
    assert rises[1] == pytest.approx(40.0) and rises[2] == pytest.approx(4.0) and rises[3] == pytest.approx(0.0)
    assert rises[4] == 0.0 and rises[5] == 0.0  # a hip missing on position 4, before or now
    assert rises[6] == 0.0  # 3 is not next to 5
    assert rises[7] == pytest.approx(0.0) and rises[8] == pytest.approx(-4.0) and rises[9] == pytest.approx(-40.0)
    without = dataclasses.replace(search, keypoint_height=False)
    assert [without._rise(i) for i in (0, 1)] == [0.0, 0.0]  # the silhouettes' rise alone: unknown here


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), density=st.floats(0.0, 0.3), values=st.sampled_from([1, 255]))
def test_the_silhouettes_centroids_are_the_pixels_mean(seed, density, values):
    """The summed centroids equal the plain mean of the set pixels' coordinates, to the last digit (random masks
    of 0/1 or 0/255, and a view that is one row of pixels)."""
    from swarmpose.track.start import _pixel_sums

    rng = np.random.default_rng(seed)
    masks = ((rng.random((3, 37, 53)) < density) * values).astype(np.uint8)
    masks[2, :, :] = 0
    masks[2, 3, :40] = values
    n, x, y = _pixel_sums(masks)
    for i in range(3):
        ys, xs = np.nonzero(masks[i])
        assert n[i] == xs.size
        if xs.size:
            assert x[i] / n[i] == xs.mean() and y[i] / n[i] == ys.mean()


def test_a_resume_keeps_finished_runs_and_tracks_only_the_new_one(short_sequence, tmp_path, monkeypatch):
    """``track --backward --resume`` on a folder whose runs are finished: nothing is tracked again (the backward
    pass is not redone, the summaries stay); a run added by a larger --runs is tracked, and only it."""
    import json

    from swarmpose.track import runner

    cfg = TrackConfig(algo="sppso", fps=30.0, seed=2, backward=True)
    out = tmp_path / "res"
    first = runner.track_runs(short_sequence, cfg, 1, out, workers=1, progress=False)
    before = (out / "run_000" / "summary.json").read_text()
    with np.load(out / "run_000" / "track.npz") as z:
        params = z["params"].copy()
    tracked = []
    real = runner.run_tracker

    def spy(setup, run, *args, **kwargs):
        tracked.append(run)
        return real(setup, run, *args, **kwargs)

    monkeypatch.setattr(runner, "run_tracker", spy)
    again = runner.track_runs(short_sequence, cfg, 1, out, resume=True, workers=1, progress=False)
    assert tracked == []
    assert (out / "run_000" / "summary.json").read_text() == before
    assert again["d_mean_mm"] == first["d_mean_mm"] and again["per_run"] == first["per_run"]
    more = runner.track_runs(short_sequence, cfg, 2, out, resume=True, workers=1, progress=False)
    assert tracked == [1]
    with np.load(out / "run_000" / "track.npz") as z:
        assert np.array_equal(z["params"], params)
    assert [r["run"] for r in more["per_run"]] == [0, 1]
    assert more["per_run"][0] == first["per_run"][0]
    assert json.loads((out / "run_001" / "summary.json").read_text())["backward_kept"] >= 0
