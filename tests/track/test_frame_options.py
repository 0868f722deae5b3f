"""The default tracker's own fitness options for every search of a frame: the detector's keypoints where the
sequence carries them, nothing where it does not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmpose.io.sequence import MarkerData, MultiViewSequence, open_sequence, write_sequence
from swarmpose.joints import JOINTS15
from swarmpose.triangulation import reproject


def _with_keypoints(short_sequence: Path, out: Path, keypoints_of) -> Path:
    """The short walk with its ground truth kept and ``keypoints_of(cameras, truth)`` (T, C, 15, 2) as its
    keypoints, confidence 0.9."""
    with open_sequence(short_sequence) as seq:
        uv = keypoints_of(seq.cameras, np.asarray(seq.gt_joints))
        markers = MarkerData.from_dense(JOINTS15, uv, np.full(uv.shape[:-1], 0.9))
        write_sequence(out, MultiViewSequence(
            cameras=seq.cameras, frame_rate=seq.frame_rate, n_frames=seq.n_frames, reader=seq._reader,
            backgrounds=seq.backgrounds(), markers=markers, frame_times=seq.frame_times,
            gt_joints=np.asarray(seq.gt_joints), world_from_source=seq.world_from_source,
            source_clip=seq.source_clip, subject_measurements=seq.subject_measurements))
    return out


@pytest.fixture(scope="module")
def keypoint_sequence(short_sequence: Path, tmp_path_factory) -> Path:
    """The short walk with its ground truth kept and keypoints added: the truth projected, 4 px of noise."""
    rng = np.random.default_rng(3)

    def noisy(cameras, truth: np.ndarray) -> np.ndarray:
        uv = reproject(cameras, truth)
        return uv + rng.normal(0, 4.0, uv.shape)

    return _with_keypoints(short_sequence, tmp_path_factory.mktemp("kp") / "walk", noisy)


def _track(path: Path, algo: str, variant: str = "", options: str = "", *, ik_ran: bool | None = None) -> np.ndarray:
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    cfg = TrackConfig(algo=algo, optim_variant=variant, fitness_options=options, max_frames=2, downsample=2)
    result = run_tracker(prepare_track(path, cfg), 0)
    if ik_ran is not None:  # the per-frame keypoint IK ran, or did not
        assert (result.part_seconds.get("keypoint_ik", 0.0) > 0) == ik_ran
    return result.params


def test_the_default_weighs_keypoints_where_the_sequence_has_them(short_sequence: Path, keypoint_sequence: Path):
    from swarmpose.body.model import load_model
    from swarmpose.optim import registry
    from swarmpose.optim.registry import (
        FRAME_KEYPOINT_WEIGHT,
        HEAD_SEARCH,
        KEYPOINT_ELBOW,
        KEYPOINT_JOINTS,
        RECOVERY_JUMP,
    )
    from swarmpose.track.start import has_keypoints

    with open_sequence(short_sequence) as plain, open_sequence(keypoint_sequence) as kp:
        assert not has_keypoints(plain) and has_keypoints(kp) and kp.gt_joints is not None
    assert registry.get("refined-heading", model=load_model("balan31"), fps=20).frame_options == {
        "keypoints": FRAME_KEYPOINT_WEIGHT, "keypoint_elbow": KEYPOINT_ELBOW, "keypoint_joints": KEYPOINT_JOINTS}
    # without keypoints: refined-limbs with the turn search and the recovery's jump margin, pose for pose
    jump = f"recovery_jump={RECOVERY_JUMP:g}"
    np.testing.assert_array_equal(_track(short_sequence, "refined-heading", ik_ran=False),
                                  _track(short_sequence, "refined-limbs", f"turn=on+{jump}"))
    # with them: the term in every search, as the run's own --fitness-options would put it there, the IK, the
    # root's height moved by the trunk's keypoints, and the head searched on its own
    heading = _track(keypoint_sequence, "refined-heading", ik_ran=True)
    assert not np.array_equal(heading, _track(keypoint_sequence, "refined-heading", "height=silhouettes"))
    assert not np.array_equal(heading, _track(keypoint_sequence, "refined-heading", "head=off"))
    np.testing.assert_array_equal(heading, _track(keypoint_sequence, "refined-limbs",
                                                  f"turn=on+keypoint_ik=on+height=keypoints+head={HEAD_SEARCH}+{jump}",
                                                  f"keypoints={FRAME_KEYPOINT_WEIGHT:g},keypoint_elbow={KEYPOINT_ELBOW},"
                                                  f"keypoint_joints={KEYPOINT_JOINTS}"))
    assert not np.array_equal(heading, _track(keypoint_sequence, "refined-limbs", "turn=on+keypoint_ik=on"))
    # the run's own options go over the configuration's: keypoints=0 turns the term off
    np.testing.assert_array_equal(_track(keypoint_sequence, "refined-heading", options="keypoints=0"),
                                  _track(keypoint_sequence, "refined-limbs",
                                         f"turn=on+keypoint_ik=on+height=keypoints+head={HEAD_SEARCH}+{jump}",
                                         "keypoints=0"))


def test_the_keypoint_terms_scale_and_swaps_reach_the_searches(keypoint_sequence: Path):
    """``keypoint_scale`` at the term's own SCALE, ``keypoint_swaps=body``, ``keypoint_threshold=0.3``,
    ``keypoint_power=1`` and ``keypoint_views=1`` track pose for pose as without them (and ``keypoint_views=4`` where
    every view sees every joint); another scale, threshold or power changes the track."""
    default = _track(keypoint_sequence, "refined-heading")
    np.testing.assert_array_equal(default, _track(keypoint_sequence, "refined-heading",
                                                  options="keypoint_scale=0.02,keypoint_swaps=body,"
                                                          "keypoint_threshold=0.3,keypoint_power=1,keypoint_views=1"))
    np.testing.assert_array_equal(default, _track(keypoint_sequence, "refined-heading", options="keypoint_views=4"))
    assert not np.array_equal(default, _track(keypoint_sequence, "refined-heading", options="keypoint_scale=0.005"))
    assert not np.array_equal(default, _track(keypoint_sequence, "refined-heading",
                                              options="keypoint_threshold=0.05,keypoint_power=0"))


def test_the_keypoint_ik_variant():
    from swarmpose.body.model import load_model
    from swarmpose.errors import ConfigError
    from swarmpose.optim import registry
    from swarmpose.optim.variants import apply_variant

    model = load_model("balan31")
    cfg = registry.get("refined-heading", model=model, fps=20)
    assert cfg.keypoint_ik and not registry.get("refined-limbs", model=model, fps=20).keypoint_ik
    off = apply_variant(cfg, "keypoint_ik=off")
    assert not off.keypoint_ik and apply_variant(off, "keypoint_ik=on").keypoint_ik
    assert off.frame_options == cfg.frame_options and off.turn_search == cfg.turn_search
    with pytest.raises(ConfigError, match="keypoint_ik=on or keypoint_ik=off"):
        apply_variant(cfg, "keypoint_ik=yes")
    with pytest.raises(ConfigError, match="keypoint_ik=on or keypoint_ik=off"):
        apply_variant(registry.get("sppso", model=model, fps=20), "keypoint_ik=on")


def _check_variant(head: str, value: str, expected: float, bad: tuple[str, ...], match: str, refused_by: str,
                   refused_match: str) -> None:
    """On the default, ``head=value`` sets its field ``head`` (0 by default) to ``expected`` and ``head=off`` back to
    0; each of ``bad`` is refused with ``match``, and the variant on ``refused_by`` with ``refused_match``."""
    from swarmpose.body.model import load_model
    from swarmpose.errors import ConfigError
    from swarmpose.optim import registry
    from swarmpose.optim.variants import apply_variant

    model = load_model("balan31")
    cfg = registry.get("refined-heading", model=model, fps=20)
    on = apply_variant(cfg, f"{head}={value}")
    assert getattr(cfg, head) == 0 and getattr(on, head) == expected
    assert getattr(apply_variant(on, f"{head}=off"), head) == 0
    for b in bad:
        with pytest.raises(ConfigError, match=match):
            apply_variant(cfg, f"{head}={b}")
    with pytest.raises(ConfigError, match=refused_match):
        apply_variant(registry.get(refused_by, model=model, fps=20), f"{head}={value}")


def test_the_keypoint_proposals_variant(short_sequence: Path, keypoint_sequence: Path):
    """``keypoint_proposals=F``: parsed and checked; on a sequence with keypoints the fit from the prediction runs
    (without the fit after the searches) and changes the track; without keypoints, pose for pose as without it."""
    _check_variant("keypoint_proposals", "0.25", 0.25, ("1", "-0.1", "many"), "keypoint_proposals=F", "sppso",
                   "keypoint_proposals=F")
    plain = _track(keypoint_sequence, "refined-heading", "keypoint_ik=off", ik_ran=False)
    proposed = _track(keypoint_sequence, "refined-heading", "keypoint_ik=off+keypoint_proposals=0.25", ik_ran=True)
    assert not np.array_equal(plain, proposed)
    np.testing.assert_array_equal(_track(short_sequence, "refined-heading", "keypoint_proposals=0.25", ik_ran=False),
                                  _track(short_sequence, "refined-heading"))


def test_the_keypoint_fit_polished(keypoint_sequence: Path):
    """``keypoint_ik_polish=B``: parsed and checked (it needs the keypoint fit); where the fit scores lower than the
    frame's pose, at most B more evaluations search from it, and a polished fit that scores no higher is not kept."""
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    _check_variant("keypoint_ik_polish", "150", 150, ("-1", "1.5", "on"), "keypoint_ik_polish=B", "refined-limbs",
                   "add keypoint_ik=on first")

    def run(variant: str):
        c = TrackConfig(algo="refined-heading", optim_variant=variant, max_frames=3, downsample=2)
        return run_tracker(prepare_track(keypoint_sequence, c), 0)

    plain, polished = run(""), run("keypoint_ik_polish=150")
    extra = np.asarray(polished.evaluations) - np.asarray(plain.evaluations)
    assert extra.sum() > 0 and extra.max() <= 150  # it ran, within its budget per frame
    # on these frames no polished fit beats the searched pose, so the poses are the searches' own
    np.testing.assert_array_equal(plain.params, polished.params)


def test_the_detectors_elbows_are_measured_on_the_sequence(short_sequence: Path, tmp_path: Path):
    """``keypoint_elbow=auto``: keypoints whose elbows lie at 0.85 of the upper arm give about 0.85 (recorded with
    the run's errors); a sequence without keypoints tracks as without the option."""
    from swarmpose.fitness.keypoints import detector_elbows
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    out = _with_keypoints(short_sequence, tmp_path / "walk",
                          lambda cameras, truth: reproject(cameras, detector_elbows(truth, 0.85)))

    def run(path: Path, options: str):
        cfg = TrackConfig(algo="refined-heading", fitness_options=options, max_frames=3, downsample=2)
        return run_tracker(prepare_track(path, cfg), 0)

    measured = run(out, "keypoint_elbow=auto")
    assert abs(measured.errors["keypoint_elbow"] - 0.85) < 0.02
    plain = run(short_sequence, "keypoint_elbow=auto")
    assert "keypoint_elbow" not in plain.errors
    np.testing.assert_array_equal(plain.params, run(short_sequence, "").params)


def test_the_elbow_fraction_of_straight_arms_and_its_limits():
    from swarmpose.body.model import load_model
    from swarmpose.fitness.keypoints import detector_elbows
    from swarmpose.track.start import ELBOW_FRACTION_RANGE, elbow_fraction

    model = load_model("balan31")
    straight = np.repeat(model.joints15(model.zero_pose()[None]), 4, axis=0)  # arms straight at the sides
    assert elbow_fraction(model, straight) == pytest.approx(1.0)
    assert elbow_fraction(model, detector_elbows(straight, 0.9)) == pytest.approx(0.9)
    assert elbow_fraction(model, detector_elbows(straight, 0.4)) == ELBOW_FRACTION_RANGE[0]
    assert elbow_fraction(model, np.full((3, 15, 3), np.nan)) == 1.0


def test_triangulated_keypoints_put_back_one_views_swapped_ankles(short_sequence: Path, tmp_path: Path):
    """A detector that exchanged the ankles in one view (and the wrists in another, on one frame): the
    triangulated joints are the truth's all the same."""
    from swarmpose.joints import JOINT_INDEX
    from swarmpose.track.start import keypoint_joints

    def swapped(cameras, truth: np.ndarray) -> np.ndarray:
        uv = reproject(cameras, truth)
        la, ra = JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]
        uv[:, 1, [la, ra]] = uv[:, 1, [ra, la]]
        lw, rw = JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"]
        uv[0, 3, [lw, rw]] = uv[0, 3, [rw, lw]]
        return uv

    with open_sequence(_with_keypoints(short_sequence, tmp_path / "walk", swapped)) as seq:
        frames = np.arange(seq.n_frames)
        np.testing.assert_allclose(keypoint_joints(seq, frames), np.asarray(seq.gt_joints)[frames], atol=0.5)


def test_a_joint_whose_views_disagree_is_not_triangulated(short_sequence: Path, tmp_path: Path):
    """The right wrist seen confidently by two views only, one of them 80 px off across the epipolar line (along
    it two views cannot disagree): the two rays pass far apart, the residual check leaves one view, and the joint is
    NaN (missing) rather than a point between them; every other joint, and the wrist on the other frames, as the
    truth's."""
    from swarmpose.joints import JOINT_INDEX
    from swarmpose.track.start import keypoint_joints

    rw = JOINT_INDEX["r_wrist"]

    def two_disagreeing(cameras, truth: np.ndarray) -> np.ndarray:
        uv = reproject(cameras, truth)
        x = truth[1, rw]
        centre = -cameras[1].R.T @ cameras[1].t  # the epipolar line of view 1's ray, in view 0
        a, b = (cameras[0].project(p[None])[0] for p in (x, x + 0.3 * (x - centre)))
        across = np.array([b[1] - a[1], a[0] - b[0]]) / np.hypot(*(b - a))
        uv[1, 0, rw] += 80.0 * across
        uv[1, 2:, rw] = np.nan  # frame 1: the wrist seen by views 0 and 1 only
        return uv

    with open_sequence(_with_keypoints(short_sequence, tmp_path / "walk", two_disagreeing)) as seq:
        frames = np.arange(seq.n_frames)
        got, truth = keypoint_joints(seq, frames), np.asarray(seq.gt_joints)[frames]
        assert np.isnan(got[1, rw]).all()
        plain = keypoint_joints(seq, frames, keep_disagreeing=True)  # the point between the two views
        assert np.isfinite(plain[1, rw]).all() and np.linalg.norm(plain[1, rw] - truth[1, rw]) > 50.0
        ok = np.ones(got.shape[:2], bool)
        ok[1, rw] = False
        np.testing.assert_allclose(got[ok], truth[ok], atol=0.5)


def test_miss_evidence_finds_a_moved_arm_and_the_evidence_for_the_truths(keypoint_sequence: Path, tmp_path: Path,
                                                                         load_script):
    """``scripts/miss_evidence.py`` on a results folder whose run holds the IK poses with the left arm swung far
    off: it finds the left wrist as a miss (nothing off the left arm), the truth's arm puts the wrist back within the IK
    floor, and with keypoints at the truth every term scores the truth's arm higher."""
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker, write_config

    script = load_script("miss_evidence")
    out = tmp_path / "results"
    setup = prepare_track(keypoint_sequence, TrackConfig(algo="refined-heading", max_frames=2), out)
    write_config(out, setup, 1)
    run_tracker(setup, 0, out)
    model = setup.model
    params = setup.ik_params.copy()
    arm = model.group("left_arm")
    params[:, arm] = np.clip(params[:, arm] + 1.2, model.lower[arm], model.upper[arm])
    track = dict(np.load(out / "run_000" / "track.npz"))
    track["params"] = params
    np.savez(out / "run_000" / "track.npz", **track)
    err = np.linalg.norm(model.joints15(params) - setup.gt_joints, axis=-1)
    wrist = JOINTS15.index("l_wrist")
    left_arm = [JOINTS15.index(j) for j in ("l_shoulder", "l_elbow", "l_wrist")]
    assert (err[:, wrist] > 100).all() and (np.delete(err, left_arm, axis=1) < 100).all()
    found = script.clip_evidence(out, 1, 100.0)
    assert {r["joint"] for r in found["rows"]} <= {"l_wrist", "l_elbow"}
    assert sum(r["joint"] == "l_wrist" for r in found["rows"]) == 2
    assert all(r["truth_limb_error_mm"] < 10 for r in found["rows"])
    for term in ("fitness", "silhouette", "image", "keypoints"):
        assert found[term]["truth_higher"] == 1.0, term
    # polished: a short pattern search cannot carry the swung arm back, the truth's basin tops it on every frame
    # and keeps the wrist within the IK floor's reach
    polished = script.clip_evidence(out, 1, 100.0, polish=62)
    assert polished["misses"] == found["misses"] and polished["polished"]["truth_higher"] == 1.0
    assert polished["polished"]["truth_error_mm_median"] < 20 < polished["polished"]["tracked_error_mm_median"]
    assert set(polished["polished_frames"]) == {r["position"] for r in found["rows"]}
    assert all(v["difference"] > 0 for v in polished["polished_frames"].values())
    # the limb alone: from the swung arm a short search of the arm stays in its basin, the truth's arm tops it (the
    # silhouettes agreeing) and stays near the truth; one entry per frame's missed arm, not per missed joint
    limb = script.clip_evidence(out, 1, 100.0, limb_polish=40)["limb_polished"]
    assert limb["limb_frames"] == len({r["position"] for r in found["rows"]})
    assert limb["truth_higher"] == 1.0 and limb["truth_higher_and_guard"] == 1.0 and limb["median_difference"] > 0
    assert limb["truth_error_mm_median"] < 20 < 100 < limb["tracked_error_mm_median"]
