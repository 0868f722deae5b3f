"""Tracking a sequence without ground truth: the start from keypoints, the subject from them, held-out scores."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.errors import ConfigError
from swarmpose.fitness.keypoints import (
    SWAP,
    SWAPS,
    detector_elbows,
    joint_thresholds,
    joint_weights,
    keypoint_cost,
    keypoint_cost_reference,
    views_agreeing,
)
from swarmpose.io.sequence import MarkerData, MultiViewSequence, open_sequence, write_sequence
from swarmpose.joints import JOINTS15
from swarmpose.triangulation import reproject


def without_truth(src: Path, out: Path, *, noise_px: float = 0.0, seed: int = 0) -> Path:
    """The sequence with its ground truth, source clip and subject removed, and keypoints (the truth projected,
    with noise) as an imported recording would carry them."""
    rng = np.random.default_rng(seed)
    with open_sequence(src) as seq:
        uv = reproject(seq.cameras, np.asarray(seq.gt_joints))  # (T, C, 15, 2)
        uv = uv + rng.normal(0, noise_px, uv.shape) if noise_px else uv
        conf = np.full(uv.shape[:-1], 0.9)
        markers = MarkerData.from_dense(JOINTS15, uv, conf)
        bare = MultiViewSequence(cameras=seq.cameras, frame_rate=seq.frame_rate, n_frames=seq.n_frames,
                                 reader=seq._reader, backgrounds=seq.backgrounds(), markers=markers,
                                 frame_times=seq.frame_times)
        write_sequence(out, bare)
    return out


def test_keypoint_cost_matches_its_reference_and_is_robust():
    from swarmpose.camera import Camera

    rng = np.random.default_rng(1)
    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500], [0, 0, 1000],
                           dist=(0.05, 0.01, 0, 0, 0)) for i, a in enumerate((0.2, 1.9, 3.5))]
    truth = rng.normal(0, 300, (15, 3)) + [0, 0, 1000]
    kp = reproject(cams, truth)
    conf = rng.uniform(0.2, 1.0, (3, 15))
    kp[1, 4] = np.nan
    kp[2] = kp[2][SWAP]  # one view with left and right exchanged
    poses = truth[None] + rng.normal(0, 40, (6, 15, 3))
    fast = keypoint_cost(poses, cams, kp, conf)
    assert np.allclose(fast, keypoint_cost_reference(poses, cams, kp, conf), atol=1e-12)
    assert keypoint_cost(truth[None], cams, kp, conf)[0] < 1e-12  # the swapped view costs nothing either
    far = truth[None] + [0, 5000, 0]
    assert 0.9 < keypoint_cost(far, cams, kp, conf)[0] <= 1.0  # bounded: one term costs at most 1
    a = joint_weights("elbow:0+l_wrist:3")  # one-sided weights: the swapped view must weigh the model's joints
    assert np.allclose(keypoint_cost(poses, cams, kp, conf, weights=a),
                       keypoint_cost_reference(poses, cams, kp, conf, weights=a), atol=1e-12)
    elbows = [JOINTS15.index("l_elbow"), JOINTS15.index("r_elbow")]
    moved = truth.copy()
    moved[elbows] += [0, 0, 400]  # the elbows far off: they cost something, unless their weight is 0
    assert keypoint_cost(moved[None], cams, kp, conf)[0] > 0.05
    assert keypoint_cost(moved[None], cams, kp, conf, weights=a)[0] < 1e-12
    # the detector's elbows taken nearer the shoulders: the plain loops agree, and keypoints at those elbows cost 0
    assert np.allclose(keypoint_cost(poses, cams, kp, conf, weights=a, elbow=0.9),
                       keypoint_cost_reference(poses, cams, kp, conf, weights=a, elbow=0.9), atol=1e-12)
    kp_near = reproject(cams, detector_elbows(truth, 0.9))
    assert keypoint_cost(truth[None], cams, kp_near, conf, elbow=0.9)[0] < 1e-12
    assert keypoint_cost(truth[None], cams, kp_near, conf)[0] > 1e-4
    # the confidence threshold and power: the plain loops agree; below the threshold a detection does not count,
    # power 0 weighs every counted detection alike
    for threshold, power in ((0.1, 1.0), (0.5, 0.5), (0.3, 0.0)):
        assert np.allclose(keypoint_cost(poses, cams, kp, conf, threshold=threshold, power=power),
                           keypoint_cost_reference(poses, cams, kp, conf, threshold=threshold, power=power),
                           atol=1e-12)
    low = conf.copy()
    low[:, elbows] = 0.15
    assert keypoint_cost(moved[None], cams, kp, low)[0] < 1e-12  # under the default threshold: not counted
    assert keypoint_cost(moved[None], cams, kp, low, threshold=0.1)[0] > 1e-3
    flat = keypoint_cost(moved[None], cams, kp, low, threshold=0.1, power=0.0)[0]
    assert flat > keypoint_cost(moved[None], cams, kp, low, threshold=0.1)[0]  # the elbows weigh as much as the rest


def test_a_joint_one_view_alone_counts_is_left_out_with_keypoint_views_2():
    """``keypoint_views=2``: a wrist only one view reports confidently (the others under the threshold) costs
    nothing wherever the model puts it; seen by two views it counts; the option reaches the term through a
    fitness's options, and a bad value is refused with its name."""
    from swarmpose.camera import Camera
    from swarmpose.fitness.base import ImageOptions, parse_image_options

    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500], [0, 0, 1000])
            for i, a in enumerate((0.2, 1.9, 3.5))]
    truth = np.random.default_rng(2).normal(0, 300, (15, 3)) + [0, 0, 1000]
    kp = reproject(cams, truth)
    conf = np.full((3, 15), 0.9)
    w = JOINTS15.index("l_wrist")
    conf[1:, w] = 0.1  # only the first view counts the left wrist
    moved = truth.copy()
    moved[w] += [0, 0, 300]
    assert keypoint_cost(moved[None], cams, kp, conf)[0] > 1e-3
    assert keypoint_cost(moved[None], cams, kp, conf, min_views=2)[0] < 1e-12
    np.testing.assert_array_equal(views_agreeing(kp, conf, 0.3, 2)[:, w], 0.0)
    np.testing.assert_array_equal(np.delete(views_agreeing(kp, conf, 0.3, 2), w, axis=1), np.delete(conf, w, axis=1))
    conf[1, w] = 0.5  # a second view counts it: it counts again
    assert keypoint_cost(moved[None], cams, kp, conf, min_views=2)[0] > 1e-3
    assert keypoint_cost(moved[None], cams, kp, conf, min_views=3)[0] < 1e-12
    assert parse_image_options({"keypoint_views": "2"}, ImageOptions()).keypoint_views == 2
    for bad in ("0", "two", "1.5", True):
        with pytest.raises(ConfigError, match="keypoint_views"):
            parse_image_options({"keypoint_views": bad}, ImageOptions())


def test_the_limbs_swaps_read_a_view_whose_legs_alone_are_swapped():
    """``keypoint_swaps=limbs``: a view whose detector exchanged the legs only (not the arms) costs nothing at the
    truth, as a whole-body swap does with ``body``; ``ends`` reads a view whose knees and ankles alone are exchanged;
    the plain loops agree; the permutations are involutions."""
    from swarmpose.camera import Camera

    for perm in SWAPS["limbs"] + SWAPS["ends"]:
        assert sorted(perm) == list(range(15)) and [perm[j] for j in perm] == list(range(15))
    rng = np.random.default_rng(4)
    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500], [0, 0, 1000])
            for i, a in enumerate((0.2, 1.9, 3.5))]
    truth = rng.normal(0, 300, (15, 3)) + [0, 0, 1000]
    kp = reproject(cams, truth)
    legs = np.array(SWAPS["limbs"][3])
    kp[1] = kp[1][legs]  # view 1: the legs' labels exchanged, the arms' not
    conf = rng.uniform(0.5, 1.0, (3, 15))
    assert keypoint_cost(truth[None], cams, kp, conf, swaps="limbs")[0] < 1e-12
    assert keypoint_cost(truth[None], cams, kp, conf)[0] > 0.01  # body: the whole body or nothing
    assert keypoint_cost(truth[None], cams, kp, conf, swaps="ends")[0] > 0.01  # the hips too: not the ends alone
    ends = reproject(cams, truth)
    ends[2] = ends[2][np.array(SWAPS["ends"][3])]  # view 2: the knees' and ankles' labels exchanged
    assert keypoint_cost(truth[None], cams, ends, conf, swaps="ends")[0] < 1e-12
    poses = truth[None] + rng.normal(0, 40, (5, 15, 3))
    for swaps in SWAPS:
        assert np.allclose(keypoint_cost(poses, cams, kp, conf, swaps=swaps, elbow=0.9),
                           keypoint_cost_reference(poses, cams, kp, conf, swaps=swaps, elbow=0.9), atol=1e-12)
    from swarmpose.fitness.base import ImageOptions

    with pytest.raises(ConfigError, match="keypoint_swaps must be one of body, limbs, ends"):
        ImageOptions(keypoint_swaps="arms")


def test_detector_elbows_move_along_the_upper_arm_only():
    rng = np.random.default_rng(2)
    joints = rng.normal(0, 300, (4, 15, 3))
    assert detector_elbows(joints, 1.0) is joints
    moved = detector_elbows(joints, 0.8)
    for side in "lr":
        s, e = JOINTS15.index(f"{side}_shoulder"), JOINTS15.index(f"{side}_elbow")
        np.testing.assert_allclose(moved[:, e] - joints[:, s], 0.8 * (joints[:, e] - joints[:, s]))
    others = [j for j in range(15) if "elbow" not in JOINTS15[j]]
    np.testing.assert_array_equal(moved[:, others], joints[:, others])
    # and back with 1 / fraction
    np.testing.assert_allclose(detector_elbows(moved, 1 / 0.8), joints, atol=1e-9)


def test_keypoint_joint_weights_are_read_and_refused_with_the_joints_named():
    assert joint_weights("") == (1.0,) * 15
    a = joint_weights("elbow:0.25+hip:0.5+r_hip:2")
    assert a[JOINTS15.index("l_elbow")] == a[JOINTS15.index("r_elbow")] == 0.25
    assert a[JOINTS15.index("l_hip")] == 0.5 and a[JOINTS15.index("r_hip")] == 2.0  # later parts win
    assert a[JOINTS15.index("pelvis")] == 1.0
    for bad, says in [("elbow", "PART:WEIGHT"), ("knuckle:1", "names none of the joints"), ("hip:-1", ">= 0"),
                      ("hip:x", "PART:WEIGHT")]:
        with pytest.raises(ConfigError, match=says):
            joint_weights(bad)


def test_keypoint_thresholds_per_joint_count_only_the_joints_named_lower():
    """``keypoint_threshold=wrist:0.1``: a wrist detected at 0.15 counts, an elbow at 0.15 does not; the same
    threshold for every joint given per joint is the number itself, to the last bit; the plain loops agree; the text
    is read and refused through a fitness's options with the option named."""
    from swarmpose.camera import Camera
    from swarmpose.fitness.base import ImageOptions, parse_image_options

    rng = np.random.default_rng(5)
    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500], [0, 0, 1000],
                           dist=(0.05, 0.01, 0, 0, 0)) for i, a in enumerate((0.2, 1.9, 3.5))]
    truth = rng.normal(0, 300, (15, 3)) + [0, 0, 1000]
    kp = reproject(cams, truth)
    conf = rng.uniform(0.35, 1.0, (3, 15))
    wrist, elbow = JOINTS15.index("l_wrist"), JOINTS15.index("l_elbow")
    conf[:, [wrist, elbow]] = 0.15
    thresholds = joint_thresholds("wrist:0.1")
    assert thresholds[wrist] == thresholds[JOINTS15.index("r_wrist")] == 0.1 and thresholds[elbow] == 0.3
    assert joint_thresholds("0.2+wrist:0.1")[elbow] == 0.2 and joint_thresholds(0.25) == (0.25,) * 15
    off_wrist, off_elbow = truth.copy(), truth.copy()
    off_wrist[wrist] += [0, 0, 300]
    off_elbow[elbow] += [0, 0, 300]
    assert keypoint_cost(off_wrist[None], cams, kp, conf)[0] < 1e-12  # 0.15 < 0.3: the wrist does not count
    assert keypoint_cost(off_wrist[None], cams, kp, conf, threshold=thresholds)[0] > 1e-3
    assert keypoint_cost(off_elbow[None], cams, kp, conf, threshold=thresholds)[0] < 1e-12
    poses = truth[None] + rng.normal(0, 40, (6, 15, 3))
    for t, views in ((thresholds, 1), (joint_thresholds("0.5+r_knee:0.05"), 2)):
        assert np.allclose(keypoint_cost(poses, cams, kp, conf, threshold=t, min_views=views),
                           keypoint_cost_reference(poses, cams, kp, conf, threshold=t, min_views=views), atol=1e-12)
    np.testing.assert_array_equal(keypoint_cost(poses, cams, kp, conf, threshold=(0.3,) * 15),
                                  keypoint_cost(poses, cams, kp, conf, threshold=0.3))
    assert parse_image_options({"keypoint_threshold": "0.2+wrist:0.1"}, ImageOptions()).keypoint_threshold == \
        "0.2+wrist:0.1"
    assert parse_image_options({"keypoint_threshold": "0.2"}, ImageOptions()).keypoint_threshold == 0.2
    for bad, says in [("wrist:1.5", "PART:THRESHOLD"), ("knuckle:0.1", "names none of the joints"),
                      ("0.2+wrist", "PART:THRESHOLD"), ("often", "keypoint_threshold must be")]:
        with pytest.raises(ConfigError, match=says):
            parse_image_options({"keypoint_threshold": bad}, ImageOptions())


@pytest.fixture(scope="module")
def bare_sequence(short_sequence: Path, tmp_path_factory) -> Path:
    return without_truth(short_sequence, tmp_path_factory.mktemp("bare") / "walk", noise_px=1.0)


def test_a_sequence_without_truth_is_tracked_from_its_keypoints(bare_sequence: Path, short_sequence: Path,
                                                                  tmp_path: Path):
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    out = tmp_path / "res"
    res = CliRunner().invoke(app, ["track", str(bare_sequence), "--algo", "sppso", "--max-frames", "3", "--out",
                                   str(out), "--views", "BW1,BW2,BW3", "--fitness-options", "keypoints=1",
                                   "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["ground_truth"] is False and summary["d_mean_mm"] is None and summary["views"] == "BW1,BW2,BW3"
    subject = json.loads((out / "subject.json").read_text())
    assert "triangulated from the detector's keypoints" in subject["source"]
    with np.load(out / "run_000" / "joints.npz") as z:
        joints, gt = z["joints"], z["gt_joints"]
    assert np.isnan(gt).all()
    with open_sequence(short_sequence) as seq:  # scored afterwards against the withheld truth
        truth = np.asarray(seq.gt_joints)[seq.subsample(20)[:3]]
    err = np.linalg.norm(joints - truth, axis=-1).mean(axis=1)
    assert err[0] < 50.0, err
    rep = CliRunner().invoke(app, ["report", str(out), "--frames", "1"])
    assert rep.exit_code == 0, rep.output
    text = (out / "report" / "summary.md").read_text()
    assert "No ground truth was given" in text and "| BW4 |" in text
    held = json.loads((out / "report" / "heldout.json").read_text())[0]
    assert held["camera"] == "BW4" and held["model_px"]["median"] < 15 and held["iou"]["median"] > 0.5


def test_a_recording_without_truth_gets_its_consensus_scored_in_the_held_out_camera(bare_sequence: Path,
                                                                                      tmp_path: Path):
    """``--consensus`` on a sequence without ground truth: no 3D error (null, never a number), the consensus folder
    reported like any results folder, the held-out camera scoring its track."""
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    out = tmp_path / "res"
    res = CliRunner().invoke(app, ["track", str(bare_sequence), "--algo", "sppso", "--max-frames", "2", "--runs", "3",
                                   "--consensus", "3", "--out", str(out), "--views", "BW1,BW2,BW3", "--json"])
    assert res.exit_code == 0, res.output
    c = json.loads(res.stdout)["consensus"]
    assert c["ground_truth"] is False and c["d_mean_mm"] is None and c["mmta"] is None and c["runs"] == 1
    with np.load(out / "consensus" / "run_000" / "track.npz") as z:
        assert np.isnan(z["d_per_frame"]).all() and z["params"].shape[0] == 2
    rep = CliRunner().invoke(app, ["report", str(out / "consensus"), "--frames", "1"])
    assert rep.exit_code == 0, rep.output
    held = json.loads((out / "consensus" / "report" / "heldout.json").read_text())[0]
    assert held["camera"] == "BW4" and held["model_px"]["median"] < 15


def test_without_truth_or_keypoints_the_error_says_what_to_do(short_sequence: Path, tmp_path: Path):
    from swarmpose.errors import DataError
    from swarmpose.track.tracker import TrackConfig, prepare_track

    with open_sequence(short_sequence) as seq:
        bare = MultiViewSequence(cameras=seq.cameras, frame_rate=seq.frame_rate, n_frames=seq.n_frames,
                                 reader=seq._reader, backgrounds=seq.backgrounds())
        write_sequence(tmp_path / "bare", bare)
    with pytest.raises(DataError, match=r"no ground truth and no body keypoints: pass --height MM"):
        prepare_track(tmp_path / "bare", TrackConfig(algo="sppso"))
    with pytest.raises(Exception, match="no camera 'cam9'"):
        prepare_track(short_sequence, TrackConfig(algo="sppso", views="BW1,cam9"))


def test_refined_keypoints_fits_the_keypoints(bare_sequence: Path, short_sequence: Path, tmp_path: Path):
    """With keypoints close to the truth the keypoint term and the per-frame keypoint IK bring every frame near it."""
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    cfg = TrackConfig(algo="refined-keypoints", max_frames=3, height_mm=1700)
    setup = prepare_track(bare_sequence, cfg)
    result = run_tracker(setup, 0)
    assert result.part_seconds["keypoint_ik"] > 0
    with open_sequence(short_sequence) as seq:
        truth = np.asarray(seq.gt_joints)[seq.subsample(20)[:3]]
    err = np.linalg.norm(result.joints - truth, axis=-1).mean(axis=1)
    assert (err < 35.0).all(), err


def test_one_tracked_camera_cannot_triangulate_a_start(bare_sequence: Path):
    from swarmpose.errors import DataError
    from swarmpose.track.tracker import TrackConfig, prepare_track

    with pytest.raises(DataError, match=r"seen by two of the tracked cameras \(BW1\); track with more cameras"):
        prepare_track(bare_sequence, TrackConfig(algo="sppso", views="BW1"))


def test_without_keypoints_a_stature_starts_from_the_silhouettes(short_sequence: Path, tmp_path: Path):
    """No ground truth, no keypoints, --height: the silhouettes' centre places the root, frame 0 searches every
    heading, and the track lands near the withheld truth."""
    from swarmpose.track.start import START_HEADINGS, START_ROUNDS, START_SEARCHES
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    with open_sequence(short_sequence) as seq:
        bare = MultiViewSequence(cameras=seq.cameras, frame_rate=seq.frame_rate, n_frames=seq.n_frames,
                                 reader=seq._reader, backgrounds=seq.backgrounds())
        write_sequence(tmp_path / "bare", bare)
        truth = np.asarray(seq.gt_joints)[seq.subsample(20)[:2]]
    setup = prepare_track(tmp_path / "bare", TrackConfig(algo="sppso", max_frames=2, height_mm=1517))
    assert setup.search_start and not setup.has_ground_truth
    start_pelvis = setup.model.joints15(setup.ik_params[:1])[0, 1]
    assert np.linalg.norm(start_pelvis[:2] - truth[0, 1, :2]) < 150  # the centre, on the floor plane
    result = run_tracker(setup, 0)
    budget = setup.evals_per_frame
    assert result.evaluations[0] == START_HEADINGS + (START_SEARCHES + START_ROUNDS) * budget
    assert result.evaluations[1] == budget
    err = np.linalg.norm(result.joints - truth, axis=-1).mean(axis=1)
    assert (err < 150).all(), err


def test_fill_gaps_takes_plausible_bones_from_the_nearest_frames():
    """A missing joint comes from the nearest frame whose bone to the parent has a plausible length (against the
    bone's median over all frames), moved with this frame's parent; a neighbour whose elbow is 500 mm from its
    shoulder (a detector's mixed-up arm) is passed over; without a plausible neighbour within reach the joint
    stays missing, and the start still fits the rest with the unseen arm at rest."""
    from swarmpose.body.model import load_model
    from swarmpose.joints import JOINT_INDEX as J
    from swarmpose.track.start import fill_gaps, keypoint_start

    model = load_model("balan31")
    x = model.zero_pose()
    x[model.param_index("pelvis_tz")] = 950.0
    walk = np.repeat(model.joints15(x[None]), 12, axis=0)
    walk += np.arange(12)[:, None, None] * np.array([60.0, 0, 0])  # walking along x, 60 mm per frame
    kp = walk.copy()
    kp[0, J["l_elbow"]] = np.nan
    kp[1:4, J["l_elbow"]] = kp[1:4, J["l_shoulder"]] + [0, 500.0, 0]  # implausible in the nearest three frames
    filled = fill_gaps(kp, 0)
    assert np.allclose(filled[J["l_elbow"]], walk[0, J["l_elbow"]])  # frame 4's bone on frame 0's shoulder
    assert np.isnan(fill_gaps(kp, 0, reach=3)[J["l_elbow"]]).all()  # none plausible within reach
    assert np.allclose(fill_gaps(kp, 0, tolerance=10.0)[J["l_elbow"]], kp[1, J["l_elbow"]] - [60.0, 0, 0])
    kp[:4, J["l_elbow"]] = np.nan
    kp[:4, J["l_wrist"]] = np.nan
    params, _, _ = keypoint_start(model, kp[:4], "seq", 0)  # no frame of these four sees the left arm
    err = np.linalg.norm(model.joints15(params[:1])[0] - walk[0], axis=-1)
    assert err.max() < 5.0  # the truth's arm hangs, as the rest pose's does
    trunk = kp.copy()
    trunk[:, J["l_hip"]] = np.nan
    with pytest.raises(Exception, match="too few views see l_hip"):
        keypoint_start(model, trunk, "seq", 0)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.sampled_from(sorted(SWAPS)), st.sampled_from([(0.3, 1.0), (0.1, 0.5), (0.05, 0.0)]),
       st.integers(1, 9), st.integers(1, 5), st.integers(1, 3))
def test_the_compiled_keypoint_cost_is_the_plain_loops(seed, swaps, tp, n, n_views, min_views):
    """The compiled term against :func:`keypoint_cost_reference` (plain loops): random cameras with distortion,
    detections missing or at confidence 0, joints behind a camera, every labelling set, threshold, power and number
    of views a joint needs; and a fitness's packed camera tables give the same numbers as packing them here."""
    from swarmpose.camera import Camera
    from swarmpose.render.project import camera_tables

    rng = np.random.default_rng(seed)
    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500 + 300 * rng.normal()], [0, 0, 1000],
                           dist=tuple(rng.normal(0, [0.05, 0.01, 0.002, 0.002, 0.001])))
            for i, a in enumerate(rng.uniform(0, 2 * np.pi, n_views))]
    truth = rng.normal(0, 300, (15, 3)) + [0, 0, 1000]
    kp = reproject(cams, truth) + rng.normal(0, 5, (n_views, 15, 2))
    kp[rng.random((n_views, 15)) < 0.1] = np.nan
    conf = rng.uniform(0.0, 1.0, (n_views, 15))
    conf[rng.random((n_views, 15)) < 0.1] = 0.0
    poses = truth[None] + rng.normal(0, 80, (n, 15, 3))
    if n > 1:
        poses[-1, 3] = [3000 * np.cos(0.0), 0.0, 1500]  # a joint at or behind some camera
    threshold, power = tp
    a = joint_weights("elbow:0.5+l_wrist:2") if seed % 2 else None
    fast = keypoint_cost(poses, cams, kp, conf, weights=a, elbow=0.9, swaps=swaps, threshold=threshold, power=power,
                         min_views=min_views)
    plain = keypoint_cost_reference(poses, cams, kp, conf, weights=a, elbow=0.9, swaps=swaps, threshold=threshold,
                                    power=power, min_views=min_views)
    np.testing.assert_allclose(fast, plain, rtol=1e-9, atol=1e-12)
    packed = keypoint_cost(poses, cams, kp, conf, weights=a, elbow=0.9, swaps=swaps, threshold=threshold,
                           power=power, min_views=min_views, tables=camera_tables(cams)[:3])
    np.testing.assert_array_equal(packed, fast)
