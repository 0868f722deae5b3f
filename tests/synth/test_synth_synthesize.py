"""End to end: a short stretch of the walking clip, synthesised, measured and read back."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.errors import DataError, FormatError
from swarmpose.io.sequence import open_sequence
from swarmpose.synth.synthesize import SynthReport, cached_sequence, synthesize

SHORT_FRAMES = 24  # the short_walk fixture (conftest.py): 24 frames, f_s every 4th frame
FS_STRIDE = 4


def test_report(short_walk: SynthReport):
    r = short_walk
    assert r.frames == SHORT_FRAMES and r.views == 4
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    for key in ("frames", "views", "seconds", "silhouette_iou", "model_fs_at_gt"):
        assert key in d
    assert {"min", "mean"} <= set(d["silhouette_iou"]) and "mean" in d["model_fs_at_gt"]
    assert d["model_fs_at_gt"]["n_frames"] == SHORT_FRAMES // FS_STRIDE
    assert d["model_fs_at_gt"]["ik_floor_mm"] < 5.0


def test_image_silhouettes_match_exact_masks(short_walk: SynthReport):
    """Acceptance: IoU >= 0.9 on every frame and view (here: a short stretch of the walking clip)."""
    assert short_walk.iou.shape == (SHORT_FRAMES, 4)
    assert np.all(short_walk.iou >= 0.9), short_walk.to_dict()["silhouette_iou"]


def test_observation_body_is_not_the_tracker_model(short_walk: SynthReport):
    """Guard: balan31 at its IK pose explains the observed silhouettes well but not perfectly."""
    fs = short_walk.fs
    assert fs.shape == (SHORT_FRAMES // FS_STRIDE, 4) and np.all(np.isfinite(fs))
    assert 0.70 <= fs.mean() <= 0.93, fs.mean()


def test_sequence_loads_back(short_walk: SynthReport, walk_clip):
    with open_sequence(short_walk.path) as seq:
        assert seq.n_frames == SHORT_FRAMES and seq.view_names == ["BW1", "BW2", "BW3", "BW4"]
        assert seq.image_size == (644, 484) and seq.frame_rate == 60.0
        np.testing.assert_array_equal(seq.gt_joints, walk_clip.joints[:SHORT_FRAMES])
        np.testing.assert_allclose(seq.frame_times, np.arange(SHORT_FRAMES) / 60.0)
        np.testing.assert_array_equal(seq.world_from_source, walk_clip.world_from_source)
        assert seq.provenance["seed"] == 3 and seq.provenance["clip"]["name"] == "cmu_16_16_walk"
        assert seq.provenance["clip"]["source_frame_rate"] == 120.0  # the capture rate, not the 60 fps rendered
        assert seq.provenance["settings"]["markers"]["dropout"] == 0.05
        assert short_walk.measurements is not None and seq.subject_measurements == short_walk.measurements
        img, mask = seq.images(5), seq.masks(5)
        assert img.shape == (4, 484, 644) and set(np.unique(mask)) == {0, 1}
        bg = seq.backgrounds()
        # the person is where the mask is: clearly different from the background there, not elsewhere
        diff = np.abs(img.astype(int) - bg.astype(int))
        assert diff[mask == 1].mean() > 30.0 and diff[mask == 0].mean() < 4.0
        assert 8.0 < seq.markers(5)[0].shape[0] < 20.0
        assert seq.marker_data.visible.shape == (SHORT_FRAMES, 4, 15)


def test_same_seed_same_images(short_walk: SynthReport, walk_clip_path, tmp_path):
    again = synthesize(walk_clip_path, tmp_path / "again", seed=3, max_frames=2, measure=False, progress=False)
    other = synthesize(walk_clip_path, tmp_path / "other", seed=4, max_frames=2, measure=False, progress=False)
    with open_sequence(short_walk.path) as a, open_sequence(again.path) as b, open_sequence(other.path) as c:
        np.testing.assert_array_equal(a.images(1), b.images(1))
        np.testing.assert_array_equal(a.markers(1)[2], b.markers(1)[2])
        assert not np.array_equal(a.images(1), c.images(1))
        np.testing.assert_array_equal(a.masks(1), c.masks(1))  # geometry does not depend on the seed


def test_cached_sequence(walk_clip_path, tmp_path, monkeypatch):
    import importlib

    mod = importlib.import_module("swarmpose.synth.synthesize")  # the module, not the function

    calls = []
    real = mod.synthesize

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **{**kwargs, "max_frames": 2})

    monkeypatch.setattr(mod, "synthesize", counting)
    p1 = cached_sequence(walk_clip_path, tmp_path / "cache", fps=30, seed=1, progress=False)
    p2 = cached_sequence(walk_clip_path, tmp_path / "cache", fps=30, seed=1, progress=False)
    assert p1 == p2 and len(calls) == 1 and p1.name.startswith("cmu_16_16_walk-30fps-s1-")
    p3 = cached_sequence(walk_clip_path, tmp_path / "cache", fps=30, seed=2, progress=False)
    assert p3 != p1 and len(calls) == 2
    assert [p.name for p in (tmp_path / "cache").iterdir() if p.name.startswith(".")] == []
    with pytest.raises(DataError, match="no such clip"):
        cached_sequence(tmp_path / "missing.bvh", tmp_path / "cache")
    # a clip that cannot be read leaves no (empty) cache folders behind, and a cache that is there stays
    bad = tmp_path / "cut.bvh"
    bad.write_text(walk_clip_path.read_text()[:400])
    for cache in (tmp_path / "new" / "sequences", tmp_path / "cache"):
        with pytest.raises(FormatError, match="cut.bvh, line 17"):
            cached_sequence(bad, cache, progress=False)
    assert not (tmp_path / "new").exists() and {p1, p3} <= set((tmp_path / "cache").iterdir())


def test_cli_synth_json_and_show(walk_clip_path, short_walk: SynthReport, tmp_path):
    runner = CliRunner()
    out = tmp_path / "cli"
    res = runner.invoke(app, ["synth", str(walk_clip_path), "--out", str(out), "--max-frames", "3",
                              "--fs-stride", "2", "--seed", "5", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)  # exactly one JSON object on stdout
    assert data["frames"] == 3 and data["views"] == 4 and data["seconds"] > 0
    assert data["silhouette_iou"]["min"] >= 0.9 and data["model_fs_at_gt"]["mean"] is not None
    assert data["warnings"] == []
    assert 250.0 < data["subject_measurements"]["LSHO-RSHO"] < 450.0  # what the tracker sizes its cones with
    assert "synth" in res.stderr  # the progress bar goes to stderr
    # a second run into the same folder needs --force
    res = runner.invoke(app, ["synth", str(walk_clip_path), "--out", str(out), "--max-frames", "1", "--json"])
    assert res.exit_code == 2 and "not empty" in res.stderr and "not empty" in json.loads(res.stdout)["error"]
    png = tmp_path / "sheet.png"
    res = runner.invoke(app, ["show", str(short_walk.path), "--frame", "7", "--out", str(png)])
    assert res.exit_code == 0, res.output
    import cv2

    sheet = cv2.imread(str(png))
    assert sheet.shape[1] == 3 * 644 and sheet.shape[0] > 4 * 484
    res = runner.invoke(app, ["show", str(short_walk.path), "--frame", "99"])
    assert res.exit_code == 2 and "outside" in res.stderr
    res = runner.invoke(app, ["show", str(short_walk.path), "--frame", "2", "--out", str(png), "--json"])
    assert res.exit_code == 2 and "exists; add --force" in json.loads(res.stdout)["error"]  # not clobbered
    assert cv2.imread(str(png)).shape[:2] == sheet.shape[:2]
    res = runner.invoke(app, ["show", str(short_walk.path), "--frame", "2", "--out", str(png), "--scale", "0.5",
                              "--force", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["path"] == str(png) and data["frame"] == 2
    assert (data["height"], data["width"]) == cv2.imread(str(png)).shape[:2] and data["width"] == 3 * 644 // 2


def test_cli_synth_albedo(walk_clip_path, tmp_path):
    """``--albedo`` dresses the observation body (recorded in the provenance); bad input names the materials."""
    from swarmpose.io.sequence import open_sequence

    runner = CliRunner()
    args = ["synth", str(walk_clip_path), "--max-frames", "1", "--no-measure", "--no-progress", "--json"]
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "light"), "--albedo", "shirt=0.9, trousers=0.05"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "plain")])
    assert res.exit_code == 0, res.output
    with open_sequence(tmp_path / "light") as light, open_sequence(tmp_path / "plain") as plain:
        albedo = light.provenance["settings"]["body"]["albedo"]
        assert albedo["shirt"] == 0.9 and albedo["trousers"] == 0.05 and albedo["skin"] == 0.28
        import cv2

        mask = np.asarray(plain.masks(0)[0]) != 0
        near = cv2.dilate(mask.astype(np.uint8), np.ones((9, 9), np.uint8)) != 0  # the optics blur the rim
        a, b = (np.asarray(s.images(0)[0], dtype=float) for s in (light, plain))
        # same seed and pose: only the person's shading changes (lighter shirt, darker trousers)
        assert np.abs(a - b)[~near].max() <= 1.0
        assert (a - b)[mask].max() > 60 and (a - b)[mask].min() < -20
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "bad"), "--albedo", "shrt=0.5"])
    assert res.exit_code == 2 and "shrt=0.5" in res.stderr and "shoes" in res.stderr


def test_cli_synth_warns_when_the_clothes_blend_into_the_room(walk_clip_path, tmp_path):
    """A shirt as light as the room loses the torso from the silhouettes: synth says so and names the shirt."""
    args = ["synth", str(walk_clip_path), "--max-frames", "1", "--fs-stride", "0", "--no-progress",
            "--out", str(tmp_path / "light"), "--albedo", "shirt=0.6"]
    res = CliRunner().invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["silhouette_iou"]["p50"] < 0.85
    assert len(data["warnings"]) == 1 and "shirt (0.6" in data["warnings"][0]
    assert "trousers" not in data["warnings"][0] and "warning:" in res.stderr  # also beside the progress
    res = CliRunner().invoke(app, [*args[:-4], "--out", str(tmp_path / "again"), "--albedo", "shirt=0.6"])
    assert res.exit_code == 0 and "warning:" in res.stderr and "darker --albedo" in res.stderr


def test_cli_synth_names_the_options(walk_clip_path, tmp_path):
    """Bad settings are reported with the flag the user typed, before anything is written; an --fps above the
    clip's capture rate is noted on stderr (the frames between captured ones are interpolated)."""
    runner = CliRunner()
    base = ["synth", str(walk_clip_path), "--max-frames", "1", "--no-measure", "--no-progress", "--json"]
    for flag, value in (("--dropout", "2"), ("--false-per-view", "-1"), ("--marker-noise-px", "nan"),
                        ("--clothing-mm", "500"), ("--noise-sigma", "-3"), ("--markers", "all")):
        out = tmp_path / flag.strip("-")
        res = runner.invoke(app, [*base, "--out", str(out), flag, value])
        assert res.exit_code == 2, (flag, res.output)
        message = json.loads(res.stdout)["error"]
        assert message.startswith(flag) and "Settings" not in message, message
        assert not out.exists()
    res = runner.invoke(app, [*base, "--out", str(tmp_path / "a"), "--albedo", "shirt=3"])
    assert res.exit_code == 2 and json.loads(res.stdout)["error"].startswith("--albedo shirt must be in [0, 1]")
    res = runner.invoke(app, [*base, "--out", str(tmp_path / "f"), "--fps", "0"])
    assert res.exit_code == 2 and "--fps" in res.stderr
    res = runner.invoke(app, [*base, "--out", str(tmp_path / "up"), "--fps", "240"])
    assert res.exit_code == 0, res.output
    assert "captured at 120 Hz" in res.stderr and "interpolated" in res.stderr
    res = runner.invoke(app, [*base, "--out", str(tmp_path / "down"), "--fps", "60"])
    assert res.exit_code == 0 and "interpolated" not in res.stderr


def test_cli_synth_no_occlusion_detects_the_hidden_markers(walk_clip_path, tmp_path):
    """Without drop-outs, false detections or noise, ``--no-occlusion`` detects every marker inside the image;
    the default loses the ones the body hides (the far arm and leg in a side view), never adds any."""
    from swarmpose.io.sequence import open_sequence

    runner = CliRunner()
    base = ["synth", str(walk_clip_path), "--max-frames", "3", "--no-measure", "--no-progress", "--json",
            "--dropout", "0", "--false-per-view", "0", "--marker-noise-px", "0"]
    for name, extra in (("hidden", []), ("all", ["--no-occlusion"])):
        res = runner.invoke(app, [*base, "--out", str(tmp_path / name), *extra])
        assert res.exit_code == 0, res.output
    with open_sequence(tmp_path / "hidden") as hidden, open_sequence(tmp_path / "all") as everything:
        assert everything.provenance["settings"]["markers"]["occlusion"] is False
        assert hidden.provenance["settings"]["markers"]["occlusion"] is True
        n_hidden = n_all = 0
        for k in range(3):
            for v, (ids_h, ids_a, pts_a) in enumerate(zip(hidden.marker_ids(k), everything.marker_ids(k),
                                                          everything.markers(k), strict=True)):
                w, h = everything.cameras[v].width, everything.cameras[v].height
                inside = (pts_a[:, 0] >= 0) & (pts_a[:, 0] < w) & (pts_a[:, 1] >= 0) & (pts_a[:, 1] < h)
                assert inside.all() and len(set(ids_a.tolist())) == len(ids_a)
                assert set(ids_h.tolist()) <= set(ids_a.tolist())
                n_hidden += len(ids_h)
                n_all += len(ids_a)
        assert n_all == 3 * 4 * 15  # the walk stays inside every view: all 15 joints everywhere
        assert 0.7 * n_all < n_hidden < n_all, (n_hidden, n_all)  # 164 of 180 here
