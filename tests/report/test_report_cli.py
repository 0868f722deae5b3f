"""``swarmpose report`` and ``swarmpose export``: paths printed, one JSON object with --json."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.export import bvh_axes
from swarmpose.io.bvh import read_bvh
from swarmpose.report import load_results


def _copy(src: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "res"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("report"))
    return dst


def test_report_json(fake_results, tmp_path: Path):
    res = _copy(fake_results[0], tmp_path)
    out = CliRunner().invoke(app, ["report", str(res), "--frames", "1", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert set(data) == {"summary", "html", "figures", "overlays", "video", "notes"}
    assert data["video"] is None and len(data["overlays"]) == 1 and len(data["figures"]) == 2
    assert all(Path(p).is_file() for p in [data["summary"], data["html"], *data["figures"], *data["overlays"]])


def test_report_text_and_errors(fake_results, tmp_path: Path):
    res = _copy(fake_results[0], tmp_path)
    out = CliRunner().invoke(app, ["report", str(res), "--frames", "0", "--video", "--out", str(tmp_path / "r")])
    assert out.exit_code == 0, out.output
    assert str(tmp_path / "r" / "summary.md") in out.output and "overlay_run000.gif" in out.output
    bad = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert bad.exit_code == 2
    for args, message in ((["--format", "mp4"], "add --video"), (["--video", "--format", "avi"], "gif or mp4")):
        wrong = CliRunner().invoke(app, ["report", str(res), *args, "--out", str(tmp_path / "w"), "--json"])
        assert wrong.exit_code == 2 and message in json.loads(wrong.stdout)["error"]
        assert not (tmp_path / "w").exists()  # refused before any figure is written
    assert "config.json not found: is this a swarmpose results folder?" in " ".join(bad.output.split())


def test_export_json_round_trip(fake_results, tmp_path: Path):
    bvh = tmp_path / "motion.bvh"
    out = CliRunner().invoke(app, ["export", str(fake_results[0]), "--run", "1", "--out", str(bvh), "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["bvh"] == str(bvh) and data["frames"] == 6 and data["frame_rate"] == 20.0
    res = load_results(fake_results[0])
    clip = read_bvh(bvh)
    assert clip.frames == 6 and clip.frame_rate == 20.0
    world = clip.global_positions() @ bvh_axes(True)
    names = res.model.spec.joint_names
    idx = [clip.joint_names.index(n) for n in names]
    np.testing.assert_allclose(world[:, idx], res.model.joint_positions(res.run(1).params), atol=1e-3)
    assert data["rest_facing"] == "+z"
    missing = CliRunner().invoke(app, ["export", str(fake_results[0]), "--run", "7", "--out", str(bvh)])
    assert missing.exit_code == 2 and "no finished run 7" in " ".join(missing.output.split())
    bad = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(bvh), "--rest-facing", "up"])
    assert bad.exit_code == 2 and "--rest-facing must be one of +z, +x" in " ".join(bad.output.split())
    assert data["resampled"] is False and data["tracked_frames"] == 6  # evenly spaced frames are kept
    again = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(bvh), "--z-up", "--json"])
    assert again.exit_code == 2 and "exists; add --force" in json.loads(again.stdout)["error"]
    assert read_bvh(bvh).frames == 6  # untouched
    zup = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(bvh), "--z-up", "--force", "--json"])
    assert zup.exit_code == 0 and json.loads(zup.stdout)["rest_facing"] == "+x"
    clash = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(bvh), "--z-up", "--rest-facing",
                                     "+z", "--force", "--json"])
    assert clash.exit_code == 2 and "Y-up" in json.loads(clash.stdout)["error"]


def test_output_paths_a_user_gets_wrong_are_handled(fake_results, tmp_path: Path):
    """export --out FOLDER writes into it; report --out FILE and show --out x.xyz are clear errors;
    a wrong --sequence is an error (exit 2), not a silent skip of the overlays."""
    res = _copy(fake_results[0], tmp_path)
    folder = tmp_path / "bvh"
    folder.mkdir()
    out = CliRunner().invoke(app, ["export", str(res), "--out", str(folder), "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.stdout)["bvh"] == str(folder / "res_run000.bvh") and (folder / "res_run000.bvh").is_file()
    new = CliRunner().invoke(app, ["export", str(res), "--out", str(tmp_path / "new") + "/", "--json"])
    assert new.exit_code == 0 and json.loads(new.stdout)["bvh"] == str(tmp_path / "new" / "res_run000.bvh")
    assert (tmp_path / "new" / "res_run000.bvh").is_file()  # a folder named with a trailing slash is made
    a_file = folder / "res_run000.bvh"
    bad = CliRunner().invoke(app, ["report", str(res), "--out", str(a_file)])
    assert bad.exit_code == 2 and "is a file" in " ".join(bad.output.split())
    bad = CliRunner().invoke(app, ["report", str(res), "--sequence", str(tmp_path / "nonexist"), "--video"])
    assert bad.exit_code == 2 and "no sequence folder there" in " ".join(bad.output.split())
    bad = CliRunner().invoke(app, ["show", str(fake_results[1]), "--out", str(tmp_path / "x.xyz")])
    assert bad.exit_code == 2 and ".png" in " ".join(bad.output.split())


def test_an_unknown_suite_fails_before_any_clip_is_synthesised(tmp_path: Path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    bad = CliRunner().invoke(app, ["compare", "nosuch", "--clip", str(tmp_path / "never.bvh")])
    assert bad.exit_code == 2 and "unknown suite 'nosuch'" in " ".join(bad.output.split())
    assert not (tmp_path / "cache").exists()
    # a bad setting too, and no --out folder is left behind
    bad = CliRunner().invoke(app, ["compare", "thesis-apf", "--downsample", "3", "--out", str(tmp_path / "cmp")])
    assert bad.exit_code == 2 and "downsample must be 1, 2, 4 or 8" in " ".join(bad.output.split())
    assert not (tmp_path / "cache").exists() and not (tmp_path / "cmp").exists()
    # a folder that is not a sequence fails when the suite loads it, and leaves no --out folder either
    (tmp_path / "notseq").mkdir()
    bad = CliRunner().invoke(app, ["compare", "thesis-apf", "--clip", str(tmp_path / "notseq"),
                                   "--out", str(tmp_path / "cmp")])
    assert bad.exit_code == 2 and "sequence.json: missing" in " ".join(bad.output.split())
    assert not (tmp_path / "cmp").exists()


def test_report_with_frames_without_ground_truth(results_builder, tmp_path: Path):
    """HumanEva marks invalid ground truth with NaN rows: such frames are not scored, and the report (plots,
    overlays of every frame, summary tables) and a summary recomputed from the joints agree with the
    numbers track wrote, over the valid frames only."""
    from swarmpose.metrics import track_errors

    (tmp_path / "gaps").mkdir()
    res_dir, _ = results_builder(tmp_path / "gaps", invalid=(2,))
    out = CliRunner().invoke(app, ["report", str(res_dir), "--frames", "6", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert len(data["overlays"]) == 6 and len(data["figures"]) == 2
    md = Path(data["summary"]).read_text()
    assert " nan" not in md.lower() and "| nan" not in md.lower()
    frames_row = next(line for line in md.splitlines() if line.startswith("| frames"))
    n = len(load_results(res_dir).frame_indices)
    assert f"; {n - 1} scored (the others lack valid ground truth)" in frames_row
    ik_row = next(line for line in md.splitlines() if line.startswith("| IK floor"))
    assert "100.0" in ik_row and ik_row.count("–") == 2  # MMTA over the scored frames; MMTP, frames/s: none
    per_joint = [line for line in md.splitlines() if line.startswith("| pelvis")]
    assert per_joint and "–" not in per_joint[0]
    stored = load_results(res_dir)
    for f in [*res_dir.glob("run_*/summary.json"), res_dir / "summary.json"]:
        f.unlink()
    again = load_results(res_dir)
    assert again.summary["recomputed"]
    for key in ("d_mean_mm", "d_max_mm", "mmta", "mmtp_mm", "ik_floor_mm"):
        assert np.isclose(again.summary[key], stored.summary[key]), key
    assert again.summary["worst"]["run"] == stored.summary["worst"]["run"]
    r = again.runs[0]
    e = track_errors(r.joints, r.gt_joints)
    assert np.isnan(e.d_per_frame[2]) and np.isfinite(np.delete(e.d_per_frame, 2)).all()
    assert np.isclose(e.d_mean, np.delete(e.d_per_frame, 2).mean())


def test_a_folder_without_frame_times_is_taken_as_evenly_spaced(fake_results, tmp_path: Path):
    """joints.npz written without frame_times (by hand, or by another tool): the runs are taken as evenly spaced
    at the tracking rate, so export keeps every frame (it used to resample 1-s frames onto 50 ms: 101 frames)."""
    res = _copy(fake_results[0], tmp_path)
    for run_dir in res.glob("run_*"):
        with np.load(run_dir / "joints.npz") as z:
            arrays = {k: z[k] for k in z.files if k != "frame_times"}
        np.savez(run_dir / "joints.npz", **arrays)
    np.testing.assert_allclose(load_results(res).frame_times, np.arange(6) / 20.0)
    out = CliRunner().invoke(app, ["export", str(res), "--out", str(tmp_path / "m.bvh"), "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["frames"] == 6 and data["resampled"] is False


def test_export_unit_and_rotation_order_flags(fake_results, tmp_path: Path):
    """--unit cm writes every length in cm and --order XYZ every joint's channels in that order; the joints
    still land where the model puts them."""
    bvh = tmp_path / "cm.bvh"
    out = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(bvh), "--unit", "cm", "--order", "XYZ",
                                   "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["unit"] == "cm" and data["rotation_order"] == "XYZ"
    clip = read_bvh(bvh)
    assert all(j.channels[-3:] == ("Xrotation", "Yrotation", "Zrotation") for j in clip.joints)
    res = load_results(fake_results[0])
    idx = [clip.joint_names.index(n) for n in res.model.spec.joint_names]
    world_cm = clip.global_positions() @ bvh_axes(True)
    np.testing.assert_allclose(world_cm[:, idx] * 10.0, res.model.joint_positions(res.run(0).params), atol=1e-2)
    bad = CliRunner().invoke(app, ["export", str(fake_results[0]), "--out", str(tmp_path / "x.bvh"), "--unit", "inch"])
    assert bad.exit_code == 2 and "--unit must be one of mm, cm, m" in " ".join(bad.output.split())


def test_report_full_views_draws_whole_views(fake_results, tmp_path: Path):
    """By default each view is cut to the person; --full-views keeps the whole 240-px views (3 views + 2 gaps)."""
    from PIL import Image

    widths = {}
    for flag in ([], ["--full-views"]):
        res = _copy(fake_results[0], tmp_path / ("full" if flag else "cut"))
        out = CliRunner().invoke(app, ["report", str(res), "--frames", "1", *flag, "--json"])
        assert out.exit_code == 0, out.output
        with Image.open(json.loads(out.stdout)["overlays"][0]) as im:
            widths[bool(flag)] = im.size[0]
    assert widths[True] == 3 * 240 + 2 * 4 and widths[False] < widths[True]


def test_report_on_a_file_says_it_is_a_file(fake_results, tmp_path: Path):
    summary = fake_results[0] / "summary.json"
    res = CliRunner().invoke(app, ["report", str(summary), "--json"])
    assert res.exit_code == 2
    message = json.loads(res.stdout)["error"]
    assert message == f"{summary} is a file, not a results folder (its folder {fake_results[0]} is one)"
    assert "no such results folder" not in res.stderr and "is a file, not a results folder" in res.stderr


def test_report_mp4_without_h264_notes_it_in_the_output_and_json(fake_results, tmp_path: Path, monkeypatch):
    import pytest

    import swarmpose.report as report
    from swarmpose.report.overlay import video_backends

    if not video_backends()["mp4-opencv"]:
        pytest.skip("no OpenCV FFmpeg here")
    monkeypatch.setattr(report, "mp4_is_h264", lambda: False)
    res = _copy(fake_results[0], tmp_path)
    out = CliRunner().invoke(app, ["report", str(res), "--frames", "0", "--video", "--format", "mp4", "--json"])
    assert out.exit_code == 0, out.output
    (note,) = json.loads(out.stdout)["notes"]
    assert "MPEG-4 Part 2" in note and "pip install 'swarmpose[video]'" in note
    plain = CliRunner().invoke(app, ["report", str(res), "--frames", "0", "--video", "--format", "mp4"],
                               env={"COLUMNS": "300"})
    assert plain.exit_code == 0 and f"note: {note}" in plain.stderr and "overlay_run000.mp4" in plain.stdout
