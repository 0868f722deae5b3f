"""End-to-end tracking on a short synthesised sequence: results folder, resume, determinism, metrics."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmpose.metrics import track_errors
from swarmpose.track.runner import track_runs
from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker


@pytest.mark.parametrize("algo", ["sppso", "apf", "refined+height=silhouettes"])
def test_resume_gives_the_same_result_as_an_uninterrupted_run(short_sequence, tmp_path, algo, monkeypatch):
    algo, _, variant = algo.partition("+")
    if variant:  # every rise moves the root, so that the one into the resumed frame counts
        monkeypatch.setattr("swarmpose.track.step.RISE_DEAD_ZONE_MM", 0.0)
    cfg = TrackConfig(algo=algo, fps=20.0, seed=7, optim_variant=variant)
    setup = prepare_track(short_sequence, cfg, tmp_path / "a")
    full = run_tracker(setup, 0, tmp_path / "a")
    # "kill" after 2 of 4 frames, then resume in a fresh setup (as a new process would)
    setup_b = prepare_track(short_sequence, cfg, tmp_path / "b")
    part = run_tracker(setup_b, 0, tmp_path / "b", stop_after=2)
    assert len(part.params) == 2 and not (tmp_path / "b" / "run_000" / "joints.npz").exists()
    with pytest.raises(ValueError, match="--resume"):
        run_tracker(setup_b, 0, tmp_path / "b")
    resumed = run_tracker(prepare_track(short_sequence, cfg, tmp_path / "b"), 0, tmp_path / "b", resume=True)
    assert np.array_equal(resumed.params, full.params)
    assert np.array_equal(resumed.scores, full.scores)
    assert resumed.errors["d_mean"] == full.errors["d_mean"]


def test_results_folder_contents(short_sequence, tmp_path):
    cfg = TrackConfig(algo="sppso", fps=20.0, seed=1)
    summary = track_runs(short_sequence, cfg, 2, tmp_path, workers=1, progress=False)
    for key in ("algo", "fps", "runs", "evals_per_frame", "d_mean_mm", "d_max_mm", "ik_floor_mm", "mmta",
                "frames_per_s", "worst"):
        assert key in summary
    assert summary["evals_per_frame"] == 1000 and summary["runs"] == 2
    maxima = [r["d_max_mm"] for r in summary["per_run"]]
    assert summary["d_max_mm"] == pytest.approx(np.mean(maxima)) and summary["d_max_over_runs_mm"] == max(maxima)
    d_means = [r["d_mean_mm"] for r in summary["per_run"]]
    assert summary["d_mean_std_over_runs_mm"] == pytest.approx(np.std(d_means, ddof=1))
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["seed"] == 1 and config["run_seeds"]["1"] == [1, 1] and "numpy" in config["versions"]
    with np.load(tmp_path / "run_000" / "joints.npz", allow_pickle=False) as z:
        assert z["joints"].shape == z["gt_joints"].shape == (4, 15, 3)
        assert z["frame_times"] == pytest.approx([0.0, 0.05, 0.1, 0.15])
        assert z["world_from_source"].shape == (4, 4)
        # the errors can be recomputed independently from joints.npz
        d = track_errors(z["joints"], z["gt_joints"]).d_mean
    run0 = json.loads((tmp_path / "run_000" / "summary.json").read_text())
    assert run0["d_mean"] == pytest.approx(d)
    with np.load(tmp_path / "run_000" / "track.npz", allow_pickle=False) as z:
        assert np.all(z["evaluations"] == 1000)
    # different runs draw different random streams; the same seed repeats exactly
    r1 = json.loads((tmp_path / "run_001" / "summary.json").read_text())
    assert r1["d_mean"] != run0["d_mean"]


def test_tracking_starts_at_the_truth_and_stays_near_it(short_sequence, tmp_path):
    """Four frames at 20 fps of a walk with 1000 evaluations: the tracker must not wander off."""
    cfg = TrackConfig(algo="sppso", fps=20.0, seed=3)
    setup = prepare_track(short_sequence, cfg, None)
    assert setup.ik_floor_mm < 5.0
    res = run_tracker(setup, 0, None)
    assert res.errors["d_mean"] < 60.0, res.errors  # measured 35.9 mm (seed 3); 45.8 the worst of seeds 0-9


def test_track_command_json(short_sequence, tmp_path):
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "apf", "--fps", "20", "--runs", "1",
                                   "--workers", "1", "--out", str(tmp_path / "r"), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout.strip().splitlines()[-1])
    assert data["algo"] == "apf" and data["fps"] == 20.0 and data["evals_per_frame"] == 1000
    assert data["d_mean_mm"] > 0 and data["ik_floor_mm"] < data["d_mean_mm"]


def test_cones_come_from_the_sequence_measurements(short_sequence):
    """A synthesised sequence carries its subject's measurements; the tracker sizes its cones with them."""
    from swarmpose.body.measurements import limb_table
    from swarmpose.io.sequence import open_sequence

    with open_sequence(short_sequence) as seq:
        m = seq.subject_measurements
    assert m is not None and "observation body" in m.source
    setup = prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0), None)
    subject = setup.model.subject
    P = limb_table(m)
    np.testing.assert_allclose(subject.cones["torso"], P[0, :4])
    np.testing.assert_allclose(subject.cones["r_lower_arm"], P[8, :4])
    assert "cones from measurements" in subject.source and "head = reference" in subject.source


def test_marker_tracking_defaults_to_the_symmetric_reprojection(short_sequence):
    """AAPSO on the 2D markers (auto fitness = reprojection) follows the walk closely."""
    cfg = TrackConfig(algo="aapso", fps=25.0, seed=0)
    assert cfg.fitness_kind == "reprojection"
    assert TrackConfig(algo="aapso", fitness="markers").fitness_kind == "markers"
    setup = prepare_track(short_sequence, cfg, None)
    res = run_tracker(setup, 0, None)
    assert res.evaluations.tolist() == [4300] * len(setup.frame_indices)
    # measured on these 5 frames: 10.9 / 12.2 / 13.8 mm (seeds 0-2; the epipolar score: 50.3 / 25.4 / 25.5);
    # over the whole clip 15.3 mm (5 runs)
    assert res.errors["d_mean"] < 25.0, res.errors


def test_feature_options_reach_the_features_and_the_record(short_sequence, tmp_path):
    from typer.testing import CliRunner

    from swarmpose.cli.app import app
    from swarmpose.errors import ConfigError

    with pytest.raises(ConfigError, match="edge_threshold"):
        TrackConfig(feature_options="edge_treshold=8")
    with pytest.raises(ConfigError, match="terms"):
        TrackConfig(fitness_options="terms")
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--fps", "20", "--workers", "1",
                                   "--features", "edge_threshold=15", "--fitness-options", "terms=silhouette",
                                   "--out", str(tmp_path / "r"), "--json"])
    assert res.exit_code == 0, res.output
    config = json.loads((tmp_path / "r" / "config.json").read_text())
    assert config["feature_options"] == "edge_threshold=15" and config["fitness_options"] == "terms=silhouette"


def test_resume_checks_the_configuration(short_sequence, tmp_path):
    from swarmpose.errors import ConfigError

    cfg = TrackConfig(algo="sppso", fps=20.0, seed=2)
    first = track_runs(short_sequence, cfg, 1, tmp_path, workers=1, progress=False)
    cfg_file = tmp_path / "config.json"
    record = json.loads(cfg_file.read_text())
    # a folder written before a setting existed resumes (the setting had its default)
    for key in ("feature_options", "fitness_options", "motion"):
        del record[key]
    cfg_file.write_text(json.dumps(record))
    again = track_runs(short_sequence, cfg, 1, tmp_path, resume=True, workers=1, progress=False)
    assert again["d_mean_mm"] == first["d_mean_mm"]
    with pytest.raises(ConfigError, match=r"other settings \(seed: 2 there, 3 now\)"):
        track_runs(short_sequence, TrackConfig(algo="sppso", fps=20.0, seed=3), 1, tmp_path, resume=True,
                   workers=1, progress=False)
    with pytest.raises(ConfigError, match=r"fps: 20.0 there, 12.0 now"):  # not an IndexError from a stale IK
        track_runs(short_sequence, TrackConfig(algo="sppso", fps=12.0, seed=2), 1, tmp_path, resume=True,
                   workers=1, progress=False)
    track_runs(short_sequence, cfg, 2, tmp_path, resume=True, workers=1, progress=False)  # runs may be added
    with pytest.raises(ConfigError, match="holds 2 runs; resuming with --runs 1"):
        track_runs(short_sequence, cfg, 1, tmp_path, resume=True, workers=1, progress=False)
    with pytest.raises(ConfigError, match="already holds finished tracking results .*pass --resume"):
        track_runs(short_sequence, cfg, 2, tmp_path, workers=1, progress=False)
    record = json.loads(cfg_file.read_text())
    record["sequence_identity"] = "sequence.json sha1 0000000000000000"  # as if another clip had been tracked
    cfg_file.write_text(json.dumps(record))
    with pytest.raises(ConfigError, match="sequence: "):
        track_runs(short_sequence, cfg, 2, tmp_path, resume=True, workers=1, progress=False)
    del record["sequence_identity"]
    record["fitness_kind"] = "deutscher_reid"  # "auto" resolved differently when the folder was written
    cfg_file.write_text(json.dumps(record))
    with pytest.raises(ConfigError, match="fitness_kind: 'deutscher_reid' there"):
        track_runs(short_sequence, cfg, 2, tmp_path, resume=True, workers=1, progress=False)


def test_a_reused_folder_never_misreads_the_cached_ik_fit(short_sequence, tmp_path):
    """ik.npz and subject.json are reused only for the same sequence, model and frame rate; a bad option
    is refused before anything is written."""
    from swarmpose.errors import ConfigError
    from swarmpose.track.tracker import prepare_track

    with pytest.raises(ConfigError, match="unknown"):
        prepare_track(short_sequence, TrackConfig(algo="nosuch", fps=20.0), tmp_path / "a")
    with pytest.raises(ConfigError, match="stage2=PxI"):
        prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0, optim_variant="stage2=20"), tmp_path / "a")
    assert not (tmp_path / "a").exists()
    s20 = prepare_track(short_sequence, TrackConfig(fps=20.0), tmp_path / "b")
    s12 = prepare_track(short_sequence, TrackConfig(fps=12.0), tmp_path / "b")  # ik.npz of 20 fps is there
    fresh = prepare_track(short_sequence, TrackConfig(fps=12.0), None)
    assert len(s12.frame_indices) < len(s20.frame_indices)
    np.testing.assert_array_equal(s12.ik_params, fresh.ik_params)
    again = prepare_track(short_sequence, TrackConfig(fps=12.0), tmp_path / "b")  # now from the cache
    np.testing.assert_array_equal(again.ik_params, fresh.ik_params)
    with np.load(tmp_path / "b" / "ik.npz", allow_pickle=False) as z:
        assert '"fps": 12.0' in str(z["key"])


def test_observe_hook_sees_every_frame_and_its_observation_is_tracked(short_sequence):
    """``run_tracker(observe=...)`` (used by the oracle diagnostics) gets each processed frame and what it
    returns is what the fitness is bound to."""
    import dataclasses

    setup = prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0, seed=2), None)
    seen = []

    def passthrough(k, frame):
        seen.append(k)
        return frame

    plain = run_tracker(setup, 0, None)
    same = run_tracker(setup, 0, None, observe=passthrough)
    assert seen == [int(k) for k in setup.frame_indices] == [0, 3, 6, 9]
    assert np.array_equal(same.params, plain.params)

    def no_silhouette(k, frame):
        return dataclasses.replace(frame, silhouettes=np.zeros_like(frame.silhouettes))

    blind = run_tracker(setup, 0, None, observe=no_silhouette)
    assert not np.array_equal(blind.params, plain.params)
    assert np.all(blind.scores < plain.scores)  # nothing of the model overlaps an empty silhouette


def test_blas_runs_on_one_thread_while_tracking(short_sequence):
    """BLAS's own threads took the cores from the fitness's threads (the results are the same): a run limits
    them to one and gives back the limit it found."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}

    setup = prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0, seed=2), None)
    inside = []

    def look(k, frame):
        inside.append(blas_threads())
        return frame

    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        run_tracker(setup, 0, None, observe=look)
        assert blas_threads() == before
    assert inside and all(set(t.values()) == {1} for t in inside)


def test_track_variant_option(short_sequence, tmp_path):
    """``swarmpose track --variant`` reaches the optimiser (its budget is recorded) and bad ones fail early."""
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    runner = CliRunner()
    res = runner.invoke(app, ["track", str(short_sequence), "--algo", "apf-dr05", "--variant", "apf=100x3",
                              "--fps", "20", "--workers", "1", "--out", str(tmp_path / "r"), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout.strip().splitlines()[-1])
    assert data["evals_per_frame"] == 300
    assert json.loads((tmp_path / "r" / "config.json").read_text())["optim_variant"] == "apf=100x3"
    res = runner.invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--variant", "apf=100x3",
                              "--fps", "20", "--workers", "1", "--out", str(tmp_path / "bad"), "--json"])
    assert res.exit_code == 2 and "annealed particle filter" in res.stderr
    assert json.loads(res.stdout) == {"error": "variant 'apf=100x3' needs an annealed particle filter, "
                                               "'sppso' is not one", "exit_code": 2}  # one object, as --json says


@pytest.mark.parametrize("algo", ["sppso", "apf"])
def test_constant_velocity_centres_the_search_one_step_on(short_sequence, tmp_path, monkeypatch, algo):
    """Frames 0 and 1 have no velocity yet (same draws, same estimates as zero velocity); frame 2's search
    is centred at 2 x1 - x0 (SPPSO) and the carried APF particles move by x1 - x0. A killed
    constant-velocity run resumes exactly; the config records the canonical name."""
    from swarmpose.errors import ConfigError

    with pytest.raises(ConfigError, match="motion model"):
        TrackConfig(motion="constant-velocity:3")
    assert TrackConfig(motion="constant-velocity:1").motion == "constant-velocity"
    recorded = {"zero-velocity": [], "constant-velocity": []}  # per frame: (x0, carried particles)
    original = TrackConfig.optimizer

    class Recording:
        def __init__(self, inner, record):
            self.inner, self.record = inner, record

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def start(self, x0, rng, **kw):
            carry = kw.get("carry")
            self.record.append((np.array(x0), None if carry is None else carry.particles.copy()))
            return self.inner.start(x0, rng, **kw)

    monkeypatch.setattr(TrackConfig, "optimizer", lambda self, model: Recording(original(self, model),
                                                                               recorded[self.motion]))
    zero = run_tracker(prepare_track(short_sequence, TrackConfig(algo=algo, fps=20.0, seed=4), None), 0, None)
    cfg = TrackConfig(algo=algo, fps=20.0, seed=4, motion="constant-velocity")
    setup = prepare_track(short_sequence, cfg, None)
    full = run_tracker(setup, 0, None)
    starts_zero, starts = list(recorded["zero-velocity"]), list(recorded["constant-velocity"])
    assert np.array_equal(full.params[:2], zero.params[:2])
    p0, p1 = full.params[0], full.params[1]
    if algo == "sppso":
        np.testing.assert_allclose(starts[2][0], 2 * p1 - p0)
        np.testing.assert_array_equal(starts[1][0], p0)
        assert not np.allclose(full.params[2:], zero.params[2:])
    else:
        # the APF starts from its carried set: the same set as zero velocity's at frame 2, moved by x1 - x0
        from swarmpose.body.priors import HardPriors

        moved = starts[2][1] - starts_zero[2][1]
        stays_valid = HardPriors(setup.model).valid(starts_zero[2][1] + (p1 - p0))
        assert stays_valid.any() and not stays_valid.all()  # both kinds occur (37 % move with seed 4)
        assert np.all(np.isclose(moved[stays_valid], p1 - p0))  # moved by the step where they stay valid,
        assert np.all(moved[~stays_valid] == 0)  # left where they were where it would break a limit
    run_tracker(prepare_track(short_sequence, cfg, tmp_path), 0, tmp_path, stop_after=3)
    resumed = run_tracker(prepare_track(short_sequence, cfg, tmp_path), 0, tmp_path, resume=True)
    assert np.array_equal(resumed.params, full.params)
    assert json.loads((tmp_path / "run_000" / "summary.json").read_text())["d_mean"] == full.errors["d_mean"]


def test_sequence_identity_ignores_time_version_and_paths_but_not_the_data(short_sequence, tmp_path):
    import shutil

    from swarmpose.track.provenance import sequence_identity

    copy = tmp_path / "moved"
    shutil.copytree(short_sequence, copy)
    meta = json.loads((copy / "sequence.json").read_text())
    meta["provenance"]["created_utc"] = "2030-01-01T00:00:00+00:00"  # synthesised again, elsewhere
    meta["provenance"]["swarmpose_version"] = "9.9"
    meta["provenance"]["clip"]["path"] = "/elsewhere/clip.bvh"
    meta["source_clip"] = "/elsewhere/clip.bvh"
    (copy / "sequence.json").write_text(json.dumps(meta, indent=3))
    assert sequence_identity(copy) == sequence_identity(short_sequence)
    meta["provenance"]["seed"] = meta["provenance"].get("seed", 0) + 1  # other data
    (copy / "sequence.json").write_text(json.dumps(meta))
    assert sequence_identity(copy) != sequence_identity(short_sequence)
    assert sequence_identity("humaneva:/d/S1/Walking_1") == "humaneva:/d/S1/Walking_1"


def test_ik_cache_key_and_legacy_files(short_sequence, tmp_path):
    """A key that differs only in the sequence forces a refit; an ik.npz written before the key
    existed is still read when its frames and parameter count agree."""
    cfg = TrackConfig(fps=20.0)
    first = prepare_track(short_sequence, cfg, tmp_path)
    with np.load(tmp_path / "ik.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    marked = arrays["params"].copy()
    marked[0, 0] += 0.5  # recognisable if read back
    np.savez(tmp_path / "ik.npz", **{**arrays, "params": marked, "key": np.array("another sequence")})
    np.testing.assert_array_equal(prepare_track(short_sequence, cfg, tmp_path).ik_params, first.ik_params)
    legacy = {k: v for k, v in arrays.items() if k != "key"}
    np.savez(tmp_path / "ik.npz", **{**legacy, "params": marked})
    np.testing.assert_array_equal(prepare_track(short_sequence, cfg, tmp_path).ik_params, marked)


def test_unknown_edge_cones_fail_before_anything_is_written(short_sequence, tmp_path):
    from swarmpose.errors import ConfigError

    with pytest.raises(ConfigError, match="edge cone set"):
        track_runs(short_sequence, TrackConfig(fitness_options="edge_cones=nosuch"), 1, tmp_path / "r",
                   workers=1, progress=False)
    assert not (tmp_path / "r" / "config.json").exists() and not list((tmp_path / "r").glob("run_*"))


def test_a_suite_refuses_two_sequences_that_would_share_a_folder(short_sequence, tmp_path):
    import shutil

    from swarmpose.errors import ConfigError
    from swarmpose.experiments.run import run_suite

    a, b = tmp_path / "a" / "walk", tmp_path / "b" / "walk"
    shutil.copytree(short_sequence, a)
    shutil.copytree(short_sequence, b)
    with pytest.raises(ConfigError, match="would share the results folder"):
        run_suite("thesis-apf", [a, b], tmp_path / "out", runs=1, workers=1, progress=False)
    assert not list((tmp_path / "out").rglob("config.json"))


def test_marker_fitness_on_a_sequence_without_markers_fails_before_the_ik_fit(tmp_path, mocap_dir):
    """`compare markers` on images-only data: a clear error naming the way out, and no results written."""
    from swarmpose.errors import DataError
    from swarmpose.experiments.run import run_suite
    from swarmpose.synth.markers import MarkerSettings
    from swarmpose.synth.synthesize import synthesize

    seq = tmp_path / "no_markers"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", seq, fps=60, seed=0, max_frames=3, measure=False, progress=False,
               markers=MarkerSettings(markers="none"))
    with pytest.raises(DataError, match="no 2D marker detections.*--markers joints15"):
        run_suite("markers", [seq], tmp_path / "cmp", runs=1, workers=1, progress=False)
    assert not list((tmp_path / "cmp").rglob("ik.npz")) and not list((tmp_path / "cmp").rglob("run_*"))


def test_damaged_result_files_are_named_not_tracebacks(short_sequence, tmp_path):
    """A truncated or foreign progress.npz, a broken config.json or a damaged ik.npz cache: a FormatError that
    names the file (and says how to go on), or a refit for the cache; never a traceback or a pickle load."""
    from swarmpose.errors import FormatError
    from swarmpose.track.runner import check_results_folder

    cfg = TrackConfig(fps=20.0, seed=7)
    setup = prepare_track(short_sequence, cfg, tmp_path)
    run_tracker(setup, 0, tmp_path, stop_after=1)
    progress = tmp_path / "run_000" / "progress.npz"
    good = progress.read_bytes()
    for damaged in (b"not an archive\n", good[: len(good) // 3]):
        progress.write_bytes(damaged)
        with pytest.raises(FormatError, match=r"progress\.npz.*delete it to track run 0 afresh"):
            run_tracker(setup, 0, tmp_path, resume=True)
    progress.write_bytes(good)
    assert len(run_tracker(setup, 0, tmp_path, resume=True).params) == len(setup.frame_indices)
    (tmp_path / "config.json").write_text("{bad")
    with pytest.raises(FormatError, match=r"config\.json, line 1: not valid JSON"):
        check_results_folder(tmp_path, short_sequence, cfg, 1, resume=True)
    (tmp_path / "ik.npz").write_bytes(b"PK\x03\x04 truncated")
    again = prepare_track(short_sequence, cfg, tmp_path)  # refitted, not trusted
    np.testing.assert_allclose(again.ik_params, setup.ik_params)


def test_a_resumed_folder_keeps_its_history(short_sequence, tmp_path):
    """config.json keeps the first session's creation time and lists the earlier sessions' versions and
    sequence paths; the versions name the source revision when it is a git checkout."""
    import shutil

    from swarmpose.track.provenance import source_revision

    track_runs(short_sequence, TrackConfig(fps=20.0), 1, tmp_path / "r", workers=1, progress=False)
    first = json.loads((tmp_path / "r" / "config.json").read_text())
    assert "sessions" not in first
    if source_revision():
        assert first["versions"]["swarmpose_git"] == source_revision()
    moved = tmp_path / "moved_seq"
    shutil.copytree(short_sequence, moved)  # the same data from another path: resumable
    track_runs(moved, TrackConfig(fps=20.0), 2, tmp_path / "r", resume=True, workers=1, progress=False)
    second = json.loads((tmp_path / "r" / "config.json").read_text())
    assert second["created"] == first["created"] and "resumed" in second
    assert second["sessions"] == [{k: first[k] for k in ("created", "versions", "sequence", "runs")}]
    assert second["sequence"] == str(moved.resolve()) and second["runs"] == 2


def test_sources_that_are_not_sequences_are_named_and_leave_nothing_behind(short_sequence, tmp_path):
    """A file, a results folder or an empty source: the message says what it is; a failing track removes the
    empty results folder it made; report points from a comparison folder to its entries and from an
    interrupted folder to --resume."""
    from typer.testing import CliRunner

    from swarmpose.cli.app import app
    from swarmpose.errors import DataError
    from swarmpose.report import load_results
    from swarmpose.track.runner import resolve_sequence

    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(DataError, match="is a file, not a sequence folder or a .bvh clip"):
        resolve_sequence(tmp_path / "notes.txt")
    with pytest.raises(DataError, match="source is empty"):
        resolve_sequence("")
    track_runs(short_sequence, TrackConfig(fps=20.0), 1, tmp_path / "res", workers=1, progress=False)
    with pytest.raises(DataError, match=f"results folder .* tracked from {short_sequence.resolve()}"):
        resolve_sequence(tmp_path / "res")
    out = CliRunner().invoke(app, ["track", str(tmp_path / "missing"), "--out", str(tmp_path / "o"), "--json"])
    assert out.exit_code == 2 and not (tmp_path / "o").exists()
    cmp = tmp_path / "cmp"
    (cmp / "seq").mkdir(parents=True)
    import shutil

    shutil.copytree(tmp_path / "res", cmp / "seq" / "sppso_20fps")
    with pytest.raises(DataError, match="entries of a comparison that has not finished.*--resume.*sppso_20fps"):
        load_results(cmp)
    (cmp / "comparison.json").write_text("{}")
    with pytest.raises(DataError, match="holds a comparison.*sppso_20fps"):
        load_results(cmp)
    setup = prepare_track(short_sequence, TrackConfig(fps=20.0), tmp_path / "cut")
    (tmp_path / "cut" / "config.json").write_text("{}")
    run_tracker(setup, 0, tmp_path / "cut", stop_after=1)
    with pytest.raises(DataError, match="--resume"):
        load_results(tmp_path / "cut")


def test_max_frames_tracks_the_first_frames_only_and_is_part_of_the_settings(short_sequence, tmp_path,
                                                                            monkeypatch):
    from typer.testing import CliRunner

    from swarmpose.cli.app import app
    from swarmpose.errors import ConfigError
    from swarmpose.report.summary import _reproduce

    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--fps", "60", "--max-frames", "3",
                                   "--workers", "1", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["frames"] == 3 and data["frames_scored"] == 3
    out = tmp_path / "results" / f"{short_sequence.name}-sppso-60fps-3frames"  # not the full run's folder
    with np.load(out / "run_000" / "joints.npz", allow_pickle=False) as z:
        assert z["joints"].shape == (3, 15, 3) and z["frame_times"] == pytest.approx([0, 1 / 60, 2 / 60])
    config = json.loads((out / "config.json").read_text())
    assert config["max_frames"] == 3 and "--max-frames 3" in _reproduce(config)
    # resuming with another length is refused, by name
    with pytest.raises(ConfigError, match="max_frames: 3 there, 5 now"):
        track_runs(short_sequence, TrackConfig(fps=60.0, max_frames=5), 1, out, resume=True, progress=False)
    with pytest.raises(ConfigError, match="max_frames: 3 there, all frames now"):
        track_runs(short_sequence, TrackConfig(fps=60.0), 1, out, resume=True, progress=False)
    for bad in (0, -2, 2.5, "3", float("nan"), float("inf")):
        with pytest.raises(ConfigError, match="max_frames"):
            TrackConfig(max_frames=bad)
    assert TrackConfig(max_frames=3.0).max_frames == 3 and isinstance(TrackConfig(max_frames=np.int64(3)).max_frames, int)
    # more than the sequence has: all frames, said so; a single frame has no interval (null, not NaN)
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--fps", "20", "--max-frames", "50",
                                   "--workers", "1", "--out", str(tmp_path / "long")])
    assert res.exit_code == 0 and "has 4 frames at 20 fps" in res.stderr
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--fps", "20", "--max-frames", "1",
                                   "--workers", "1", "--out", str(tmp_path / "one"), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["frame_interval_s"] == {"mean": None, "min": None, "max": None}
    assert "NaN" not in (tmp_path / "one" / "summary.json").read_text()
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--max-frames", "0", "--json"])
    assert res.exit_code == 2


def test_a_suite_end_to_end_writes_its_comparison(short_sequence, tmp_path, monkeypatch):
    """`compare SUITE --max-frames N`: every entry tracked, a table with one row per entry, marked as a
    quick try; resuming the finished suite gives the same table."""
    from typer.testing import CliRunner

    from swarmpose.cli.app import app
    from swarmpose.experiments.run import suite_configs

    monkeypatch.chdir(tmp_path)
    args = ["compare", "thesis-apf", "--clip", str(short_sequence), "--max-frames", "2", "--runs", "1",
            "--workers", "1", "--json"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    out = tmp_path / "results" / "compare" / "thesis-apf-2frames"
    entries = [e.label for e, _ in suite_configs("thesis-apf")]
    assert [r["label"] for r in report["rows"]] == entries and report["max_frames"] == 2
    for row in report["rows"]:
        cell = json.loads((tmp_path / row["out_dir"] / "summary.json").read_text())
        assert cell["d_mean_mm"] == row["d_mean_mm"] > row["ik_floor_mm"] and row["runs"] == 1
        with np.load(tmp_path / row["out_dir"] / "run_000" / "joints.npz", allow_pickle=False) as z:
            # 2 frames at the lowest rate (20 fps), the same 0.05 s at 60 fps: every entry sees the same motion
            assert row["frames"] == len(z["joints"]) == {20.0: 2, 60.0: 4}[row["fps"]]
            assert z["frame_times"][-1] == pytest.approx(0.05)
    assert json.loads((out / "comparison.json").read_text()) == report
    table = (out / "comparison.md").read_text()
    assert "first 2 frames at 20 fps (0.05 s" in table
    # one row per entry, each numbered with its paper reference (the suite's entries cite different ones)
    refs = list(dict.fromkeys(e.reference for e, _ in suite_configs("thesis-apf")))
    for e, _ in suite_configs("thesis-apf"):
        assert f"| {e.label} [{refs.index(e.reference) + 1}] |" in table
    assert all(f"{i}. {ref}" in table for i, ref in enumerate(refs, 1))
    assert "](comparison_over_time.png)" in table and "](comparison_d_mean.png)" in table
    assert (out / "comparison.html").read_text().count("data:image/png;base64,") == 2
    again = CliRunner().invoke(app, [*args, "--resume"])
    assert again.exit_code == 0, again.output
    assert [r["d_mean_mm"] for r in json.loads(again.stdout)["rows"]] == [r["d_mean_mm"] for r in report["rows"]]


def test_the_default_results_folder_names_every_setting_that_changes_the_results():
    """Another seed, resolution or setting gets its own folder, not one it would be told to --resume."""
    from swarmpose.cli.track_commands import default_results_name

    assert default_results_name("walk", TrackConfig(algo="sppso", fps=20.0)) == "walk-sppso-20fps"
    name = default_results_name("walk", TrackConfig(algo="sppso", fps=25.0, seed=3, downsample=2, max_frames=30,
                                                    fitness="deutscher_reid", optim_variant="budget=2000",
                                                    fitness_options="terms=silhouette", motion="constant-velocity:0.5"))
    assert name == "walk-sppso-25fps-30frames-s3-ds2-deutscher_reid-budget_2000-terms_silhouette-constant-velocity_0.5"
    assert default_results_name("walk", TrackConfig(model="full45")) != default_results_name("walk", TrackConfig())


def test_the_default_comparison_folder_names_the_seed_resolution_and_frames():
    """`compare`'s default folder, like `track`'s: a seed sweep or a quick try at a lower resolution does not
    land in the folder of the full run (where it was refused as a resume with other settings)."""
    from swarmpose.cli.compare_commands import default_comparison_name

    assert default_comparison_name("thesis-apf", seed=0, downsample=1, max_frames=None) == "thesis-apf"
    assert default_comparison_name("thesis-budget", seed=2, downsample=8, max_frames=1) == "thesis-budget-1frames-s2-ds8"


def test_track_flags_reach_the_tracker(short_sequence, tmp_path):
    """The --backend, --model, --fitness and --motion flags of `swarmpose track`, end to end on the short walk:
    each lands in config.json and changes what is tracked as it should."""
    from typer.testing import CliRunner

    from swarmpose.cli.app import app

    def track(name, *args):
        res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--workers", "1", "--no-progress", *args,
                                       "--out", str(tmp_path / name), "--json"])
        assert res.exit_code == 0, res.output
        with np.load(tmp_path / name / "run_000" / "joints.npz", allow_pickle=False) as z:
            joints = z["joints"]
        return json.loads(res.stdout), json.loads((tmp_path / name / "config.json").read_text()), joints

    # the plain-numpy reference backend counts the same pixels as numba, so the search is the same to the bit
    # (one frame: the reference backend scores ~45 poses/s at 161x121)
    common = ["--algo", "sppso", "--fps", "20", "--downsample", "4", "--max-frames", "1"]
    ref, ref_cfg, ref_joints = track("ref", *common, "--backend", "reference")
    fast, _, fast_joints = track("numba", *common, "--backend", "numba")
    assert ref_cfg["backend"] == "reference"
    np.testing.assert_array_equal(ref_joints, fast_joints)
    assert ref["d_mean_mm"] == fast["d_mean_mm"] < 60.0
    # the 45-parameter marker model (feet, hands, head) with AAPSO on the 2D markers
    f45, f45_cfg, _ = track("full45", "--algo", "aapso", "--fps", "25", "--model", "full45", "--max-frames", "2")
    assert f45_cfg["model"] == "full45" and f45_cfg["fitness_kind"] == "reprojection"
    assert f45["d_mean_mm"] < 25.0  # measured 11.5 mm
    # Deutscher & Reid's own fitness (eq. 17) under their APF
    dr, dr_cfg, _ = track("dr", "--algo", "apf-dr05", "--fitness", "deutscher_reid", "--variant", "apf=50x3",
                          "--fps", "20", "--downsample", "4", "--max-frames", "2")
    assert dr_cfg["fitness_kind"] == "deutscher_reid" and dr["evals_per_frame"] == 150
    assert dr["d_mean_mm"] < 60.0  # measured 16.7 mm
    # the motion model: from the third frame on the search is centred elsewhere, so the estimate differs
    common = ["--algo", "sppso", "--fps", "20", "--downsample", "4", "--max-frames", "3"]
    _, zero_cfg, zero = track("zero", *common)
    _, cv_cfg, cv = track("cv", *common, "--motion", "constant-velocity:0.5")
    assert zero_cfg["motion"] == "zero-velocity" and cv_cfg["motion"] == "constant-velocity:0.5"
    np.testing.assert_array_equal(cv[:2], zero[:2])
    assert not np.array_equal(cv[2], zero[2])


def test_run_k_of_seed_s_draws_from_seed_sequence_s_k(short_sequence, tmp_path):
    """Run k of seed S is its own stream, SeedSequence([S, k]): run 0 of seed 1 is not run 1 of seed 0
    (as it would be with a seed of S + k), and it is what config.json records."""
    from swarmpose.track.tracker import run_seed

    assert np.array_equal(run_seed(3, 2).generate_state(4), np.random.SeedSequence([3, 2]).generate_state(4))
    assert not np.array_equal(run_seed(1, 0).generate_state(4), run_seed(0, 1).generate_state(4))
    s0 = prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0, seed=0), tmp_path / "s0")
    s1 = prepare_track(short_sequence, TrackConfig(algo="sppso", fps=20.0, seed=1), tmp_path / "s1")
    a = run_tracker(s0, 1, tmp_path / "s0")
    b = run_tracker(s1, 0, tmp_path / "s1")
    assert not np.array_equal(a.params, b.params)


def test_the_tracker_searches_with_sigma_scaled_to_its_own_rate():
    """Thesis sec. 6.2: sigma x 60 / fps. The optimiser a TrackConfig builds is the registry's at the
    config's rate (at 20 fps three times the 60-fps sigma), not one at a fixed rate."""
    from swarmpose import optim
    from swarmpose.body.model import load_model

    model = load_model("balan31")
    at20, at60 = (TrackConfig(algo="sppso", fps=f).optimizer(model) for f in (20.0, 60.0))
    np.testing.assert_allclose(at20.sigma, 3.0 * at60.sigma)
    np.testing.assert_allclose(at20.sigma, optim.get("sppso", model=model, fps=20.0).sigma)
    assert at20.fps == 20.0


def test_a_resume_refuses_ground_truth_edited_since(short_sequence, tmp_path):
    """sequence.json's identity does not see data files edited in place: config.json also records a hash of
    the tracked frames' ground truth, and a resume against other ground truth is refused (it would re-score
    the finished runs against it, from an IK start fitted to the old one)."""
    import shutil

    from swarmpose.errors import ConfigError

    seq = tmp_path / "seq"
    shutil.copytree(short_sequence, seq)
    cfg = TrackConfig(algo="sppso", fps=20.0, max_frames=2)
    track_runs(seq, cfg, 1, tmp_path / "out", workers=1, progress=False)
    assert len(json.loads((tmp_path / "out" / "config.json").read_text())["ground_truth_sha1"]) == 16
    track_runs(seq, cfg, 2, tmp_path / "out", resume=True, workers=1, progress=False)  # unchanged: resumes
    with np.load(seq / "ground_truth.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["joints"] = arrays["joints"] + np.array([300.0, 0.0, 0.0])
    np.savez_compressed(seq / "ground_truth.npz", **arrays)
    before = (tmp_path / "out" / "config.json").read_text()
    with pytest.raises(ConfigError, match="ground truth .* not the one the finished runs were scored against"):
        track_runs(seq, cfg, 3, tmp_path / "out", resume=True, workers=1, progress=False)
    assert (tmp_path / "out" / "config.json").read_text() == before  # refused before anything is written


def _rewrite_archive(path, change=None):
    """Write the zip at ``path`` again, one minute later, with ``change(name, data)`` applied to its entries."""
    import zipfile

    with zipfile.ZipFile(path) as z:
        entries = [(info, z.read(info.filename)) for info in z.infolist()]
    with zipfile.ZipFile(path, "w") as z:
        for info, data in entries:
            stamped = zipfile.ZipInfo(info.filename, date_time=(*info.date_time[:4], (info.date_time[4] + 1) % 60, 0))
            stamped.compress_type = info.compress_type
            z.writestr(stamped, change(info.filename, data) if change else data)


def test_a_resume_refuses_images_edited_since_but_not_a_rewritten_archive(short_sequence, tmp_path):
    """config.json records a hash per observation file (view archives by their entries' CRCs): a resume after
    an image was edited in place is refused naming the archive, while the same images written again (a
    re-synthesis: new timestamps in the zip, so other bytes) resume."""
    import shutil

    import cv2

    from swarmpose.errors import ConfigError

    seq = tmp_path / "seq"
    shutil.copytree(short_sequence, seq)
    cfg = TrackConfig(algo="sppso", fps=20.0, max_frames=2)
    track_runs(seq, cfg, 1, tmp_path / "out", workers=1, progress=False)
    recorded = json.loads((tmp_path / "out" / "config.json").read_text())["observations_sha1"]
    views = sorted(p.relative_to(seq).as_posix() for p in (seq / "views").glob("*.zip"))
    assert set(views) <= set(recorded) and {"cameras.json", "markers.npz"} <= set(recorded)
    assert "ground_truth.npz" not in recorded  # ground_truth_sha1 covers it, by the tracked frames

    archive = seq / views[1]
    before_bytes = archive.read_bytes()
    _rewrite_archive(archive)
    assert archive.read_bytes() != before_bytes
    track_runs(seq, cfg, 2, tmp_path / "out", resume=True, workers=1, progress=False)  # same images: resumes

    def brighten_first_image(name, data):
        if name != "image/000000.png":
            return data
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        img[:10, :10] = 255 - img[:10, :10]
        return cv2.imencode(".png", img)[1].tobytes()

    _rewrite_archive(archive, brighten_first_image)
    before = (tmp_path / "out" / "config.json").read_text()
    with pytest.raises(ConfigError, match=rf"{views[1]} of .* changed since the finished runs were tracked"):
        track_runs(seq, cfg, 3, tmp_path / "out", resume=True, workers=1, progress=False)
    assert (tmp_path / "out" / "config.json").read_text() == before  # refused before anything is written
