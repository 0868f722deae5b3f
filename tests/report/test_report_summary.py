"""summary.md and make_report: the numbers of summary.json, the tables, figures by relative path."""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from swarmpose.errors import DataError
from swarmpose.joints import JOINTS15
from swarmpose.metrics import track_errors
from swarmpose.report import load_results, make_report, write_summary
from swarmpose.report.overlay import video_backends


@pytest.fixture()
def results_copy(fake_results, tmp_path: Path) -> Path:
    dst = tmp_path / "res"
    shutil.copytree(fake_results[0], dst, ignore=shutil.ignore_patterns("report"))
    return dst


def test_make_report_writes_everything(results_copy: Path):
    paths = make_report(results_copy, overlay_frames=2, video=True)
    rep = results_copy / "report"
    assert paths.summary == rep / "summary.md"
    assert paths.figures == [rep / "error_over_time.png", rep / "per_joint_errors.png"]
    assert len(paths.overlays) == 2 and all(p.parent == rep / "overlays" for p in paths.overlays)
    assert paths.video == rep / "overlay_run000.gif"
    for p in [paths.summary, *paths.figures, *paths.overlays, paths.video]:
        assert p.is_file() and p.stat().st_size > 1000, p
    assert paths.notes == []
    d = paths.to_dict()
    assert set(d) == {"summary", "html", "figures", "overlays", "video", "notes"} and d["notes"] == []
    md = paths.summary.read_text()
    for p in [*paths.figures, *paths.overlays]:
        assert f"]({p.relative_to(rep).as_posix()})" in md
    # each overlay says which run and frame it draws, its D and whether it is the run's worst frame
    r0 = load_results(results_copy).run(0)
    worst = int(np.nanargmax(r0.d_per_frame))
    k = int(r0.frame_indices[worst])
    assert any(p.name == f"overlay_run000_frame{k:06d}.png" for p in paths.overlays)
    assert (f"*Run 0, sequence frame {k} (t = {r0.frame_times[worst]:.2f} s): D = {r0.d_per_frame[worst]:.1f} mm, "
            "the run's worst frame.*") in md
    assert md.count("the run's worst frame") == 1
    assert "](overlay_run000.gif)" in md
    # the page: every figure, overlay and the video embedded: the one file to send
    assert paths.html == rep / "summary.html"
    page = paths.html.read_text()
    assert page.count('<img src="data:image/') == len(paths.figures) + len(paths.overlays) + 2  # + the confidence
    gif = base64.b64encode(paths.video.read_bytes()).decode("ascii")
    assert f'<img src="data:image/gif;base64,{gif}"' in page
    assert 'href="overlay_run000.gif"' not in page and "<h2>Error per joint</h2>" in page


def test_the_report_gives_each_limbs_confidence(results_copy: Path):
    """Run 1's right arm is lost in frame 3 (its shoulder turned by 1.5 rad; every parameter of the fake runs has
    0.05 rad of noise besides): the report's per-limb confidence is lowest there, and the truth's lost frames
    stand beside it."""
    paths = make_report(results_copy, overlay_frames=1, run=1)
    rep = results_copy / "report"
    with np.load(rep / "limb_confidence.npz") as z:
        limbs, conf, lost, d = list(z["limbs"]), z["confidence"], z["lost"], z["disagreement"]
        assert d.shape == conf.shape == (len(z["frame_indices"]), 4)
    arm = limbs.index("right_arm")
    assert lost[3, arm] and conf[3, arm] < 0.01 and conf[3, arm] == conf.min()
    assert d[3, arm] > 10 * np.delete(d.ravel(), 3 * 4 + arm).max()  # the arm is far outside every silhouette
    md = paths.summary.read_text()
    assert "## Per-limb confidence" in md and "![per-limb confidence](limb_confidence.png)" in md
    assert "| right arm | " in md and "frames lost (truth)" in md
    assert (rep / "limb_confidence.png").stat().st_size > 1000


def test_with_keypoints_the_confidence_reads_them_too(results_builder, tmp_path: Path):
    """A sequence with a detector's keypoints: the report measures how far each limb lies from them, and the lost
    arm is the least trusted limb-frame by both pieces of evidence."""
    res, _ = results_builder(tmp_path, keypoints=True)
    paths = make_report(res, overlay_frames=1, run=1)
    with np.load(res / "report" / "limb_confidence.npz") as z:
        limbs, conf, k = list(z["limbs"]), z["confidence"], z["keypoint_disagreement_mm"]
    arm = limbs.index("right_arm")
    assert k.shape == conf.shape and np.isfinite(k).all()
    assert k[3, arm] == k.max() and k[3, arm] > 200 and conf[3, arm] == conf.min() and conf[3, arm] < 0.01
    assert "how far its joints lie from the detector's keypoints" in paths.summary.read_text()


def test_a_second_report_keeps_what_it_does_not_replace(results_copy: Path):
    """A report into a folder with an earlier one overwrites only the files it writes again: the first report's
    overlays of other frames or another run, and its video, stay; summary.md names this report's."""
    rep = results_copy / "report"
    first = make_report(results_copy, overlay_frames=4, video=True)
    other = rep / "overlays" / "notes.txt"
    other.write_text("mine")
    kept = {p: p.read_bytes() for p in [*first.overlays, first.video]}
    second = make_report(results_copy, overlay_frames=1, run=1, video=True)
    assert len(first.overlays) == 4 and len(second.overlays) == 1 and second.video == rep / "overlay_run001.gif"
    assert all(p.read_bytes() == data for p, data in kept.items())  # still there, untouched
    assert sorted((rep / "overlays").glob("*.png")) == sorted([*first.overlays, *second.overlays])
    assert sorted(rep.glob("overlay_run*")) == [first.video, second.video] and other.read_text() == "mine"
    md = second.summary.read_text()
    assert all(p.name in md for p in [*second.overlays, second.video])
    assert not any(p.name in md for p in [*first.overlays, first.video])
    again = make_report(results_copy, overlay_frames=1, run=1)  # the same files again: replaced, nothing added
    assert again.overlays == second.overlays and sorted(rep.glob("overlay_run*")) == [first.video, second.video]


@pytest.mark.skipif(not video_backends()["mp4-opencv"], reason="no OpenCV FFmpeg here")
def test_an_mp4_without_h264_says_so(results_copy: Path, monkeypatch):
    """Without imageio-ffmpeg an MP4 is MPEG-4 Part 2, which most browsers do not play: a note says so and how to
    get H.264; with it, no note. The page embeds the MP4 in a video player."""
    import swarmpose.report as report

    monkeypatch.setattr(report, "mp4_is_h264", lambda: False)
    paths = make_report(results_copy, overlay_frames=0, video=True, video_format="mp4")
    assert paths.video == results_copy / "report" / "overlay_run000.mp4"
    (note,) = paths.notes
    assert "MPEG-4 Part 2" in note and "browsers" in note and "pip install 'swarmpose[video]'" in note
    assert paths.to_dict()["notes"] == [note] and f"> Note: {note}" in paths.summary.read_text()
    page = paths.html.read_text()
    mp4 = base64.b64encode(paths.video.read_bytes()).decode("ascii")
    assert f'src="data:video/mp4;base64,{mp4}"' in page and "<video controls" in page
    monkeypatch.setattr(report, "mp4_is_h264", lambda: True)
    assert make_report(results_copy, overlay_frames=0, video=True, video_format="mp4").notes == []


def test_a_video_too_large_to_embed_is_linked_with_a_note(results_copy: Path, monkeypatch):
    import swarmpose.report.html as page_html

    monkeypatch.setattr(page_html, "MAX_VIDEO_EMBED_BYTES", 1000)
    paths = make_report(results_copy, overlay_frames=0, video=True)
    assert paths.video.stat().st_size > 1000
    (note,) = paths.notes
    assert note.startswith("overlay_run000.gif is ") and "summary.html embeds: the page links it" in note
    page = paths.html.read_text()
    assert 'href="overlay_run000.gif"' in page and "data:image/gif" not in page


def test_a_report_for_a_missing_run_leaves_the_previous_report_alone(results_copy: Path):
    from swarmpose.errors import DataError

    first = make_report(results_copy, overlay_frames=2)
    before = {p: p.stat().st_mtime_ns for p in (results_copy / "report").rglob("*") if p.is_file()}
    with pytest.raises(DataError, match="no finished run 5"):
        make_report(results_copy, overlay_frames=2, run=5)
    with pytest.raises(DataError, match="no finished run 5"):  # also when the overlays would be skipped
        make_report(results_copy, overlay_frames=0, video=False, run=5)
    after = {p: p.stat().st_mtime_ns for p in (results_copy / "report").rglob("*") if p.is_file()}
    assert after == before and all(p.is_file() for p in first.overlays)


def test_summary_has_the_numbers(results_copy: Path):
    s = json.loads((results_copy / "summary.json").read_text())
    md = write_summary(results_copy).read_text()
    mean_row = (f"| **mean** | {s['d_mean_mm']:.1f} | {s['d_max_mm']:.1f} | {100 * s['mmta']:.1f} | "
                f"{s['mmtp_mm']:.1f} | {s['frames_per_s']:.2f} |")
    assert mean_row in md
    mmtp = {run.run: track_errors(run.joints, run.gt_joints).mmtp for run in load_results(results_copy).runs}
    for r in s["per_run"]:
        assert (f"| {r['run']} | {r['d_mean_mm']:.1f} | {r['d_max_mm']:.1f} | {100 * r['mmta']:.1f} | "
                f"{mmtp[r['run']]:.1f} | {r['frames_per_s']:.2f} |") in md
    w = s["worst"]
    wr = next(r for r in s["per_run"] if r["run"] == w["run"])
    assert w["run"] != 0 and f"{mmtp[w['run']]:.1f}" != f"{mmtp[0]:.1f}"  # the worst row is not run 0's
    assert (f"| **worst** (run {w['run']}) | {w['d_mean_mm']:.1f} | {w['d_max_mm']:.1f} | {100 * w['mmta']:.1f} | "
            f"{mmtp[w['run']]:.1f} | {wr['frames_per_s']:.2f} |") in md
    assert f"| IK floor | {s['ik_floor_mm']:.1f} |" in md
    for name in JOINTS15:
        assert f"| {name} | {s['per_joint_mm'][name]:.1f} |" in md
    # each joint's smallest and largest run mean, which need not be the best and worst run's
    assert "| joint | mean (mm) | min over runs (mm) | max over runs (mm) | IK floor (mm) |" in md
    cfg = json.loads((results_copy / "config.json").read_text())
    assert f"| numpy | `{cfg['versions']['numpy']}` |" in md
    assert "| algorithm | sppso |" in md and "| tracking frame rate | 20 fps |" in md
    assert "swarmpose track " in md and "--seed 3" in md


def test_the_ik_floor_row_has_its_maximum_and_mmta(results_copy: Path):
    """The IK floor row: its largest frame error and the share of its joints within 100 mm (MMTA), from
    ik.npz's per-joint errors; errors on both sides of 100 and 200 mm tell the threshold apart."""
    with np.load(results_copy / "ik.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    T = arrays["joint_error_mm"].shape[0]
    err = np.full((T, 15), 20.0)
    err[:, :3] = 150.0  # 3 of 15 joints beyond 100 mm (within 200)
    err[1, 3:6] = 250.0  # frame 1: 3 more, beyond 200 mm too
    arrays["joint_error_mm"] = err
    np.savez(results_copy / "ik.npz", **arrays)
    md = write_summary(results_copy).read_text()
    row = next(line for line in md.splitlines() if line.startswith("| IK floor |"))
    mmta = 100 * np.mean(err < 100.0)
    assert row.split(" | ")[2:4] == [f"{err.mean(axis=1).max():.1f}", f"{mmta:.1f}"], row


def test_report_without_sequence_skips_overlays(results_copy: Path, tmp_path: Path):
    cfg = json.loads((results_copy / "config.json").read_text())
    cfg["sequence"] = str(tmp_path / "moved")
    (results_copy / "config.json").write_text(json.dumps(cfg))
    paths = make_report(results_copy)
    assert paths.overlays == [] and paths.video is None
    assert len(paths.notes) == 1 and "overlays skipped" in paths.notes[0]
    assert "> Note: overlays skipped" in paths.summary.read_text()
    assert all(p.is_file() for p in paths.figures)
    assert paths.to_dict()["notes"] == paths.notes  # --json says so too, not only stderr
    # a video is asked for: no report that exits 0 without it
    (paths.summary.parent / "summary.md").unlink()
    with pytest.raises(DataError, match="no video without the tracked sequence's images.*moved"):
        make_report(results_copy, video=True)
    assert not (paths.summary.parent / "summary.md").exists()


def test_single_run_report(results_copy: Path):
    shutil.rmtree(results_copy / "run_001")
    (results_copy / "summary.json").unlink()
    res = load_results(results_copy)
    paths = make_report(res, overlay_frames=0)
    md = paths.summary.read_text()
    assert "**worst**" not in md and "| 0 |" in md
    assert paths.overlays == []


def test_reproduce_command_carries_every_non_default_setting(results_copy: Path):
    cfg = json.loads((results_copy / "config.json").read_text())
    cfg.update(optim_variant="stage2=40x20", fitness_options="terms=silhouette", feature_options="edge_threshold=8",
               motion="constant-velocity@root_position", views="BW1,BW2", backward=True, smooth=0.05)
    (results_copy / "config.json").write_text(json.dumps(cfg))
    md = write_summary(results_copy).read_text()
    cmd = md.split("Reproduce with:")[1].split("```")[1]
    for part in ("--variant stage2=40x20", "--fitness-options terms=silhouette", "--features edge_threshold=8",
                 "--motion constant-velocity@root_position", "--seed 3", "--views BW1,BW2", "--backward",
                 "--smooth 0.05"):
        assert part in cmd
    assert "| optimiser variant | `stage2=40x20` |" in md and "| motion model | constant-velocity@root_position |" in md


@pytest.mark.parametrize(("path", "expected"), [(None, " --backward-path 0"), (0.3, ""), (1.0, " --backward-path 1")])
def test_reproduce_command_carries_the_backward_path_weight(results_copy: Path, path, expected):
    """A folder without the weight predates the path: its passes' poses were chosen frame by frame (0)."""
    cfg = json.loads((results_copy / "config.json").read_text())
    cfg.update(backward=True)
    cfg.pop("backward_path", None)
    if path is not None:
        cfg["backward_path"] = path
    (results_copy / "config.json").write_text(json.dumps(cfg))
    cmd = write_summary(results_copy).read_text().split("Reproduce with:")[1].split("```")[1]
    assert ("--backward" + expected) in cmd and cmd.count("--backward-path") == (1 if expected else 0)


def test_run_folders_beyond_the_configured_runs_are_left_out(results_copy: Path):
    cfg = json.loads((results_copy / "config.json").read_text())
    n = cfg["runs"]
    shutil.copytree(results_copy / "run_000", results_copy / f"run_{n:03d}")
    res = load_results(results_copy)
    assert [r.run for r in res.runs] == list(range(n))
    assert res.skipped == [f"run_{n:03d} (beyond the {n} run(s) of config.json)"]


def test_a_wrong_sequence_given_explicitly_is_an_error_not_a_note(results_copy: Path, fake_results, tmp_path: Path):
    from swarmpose.errors import DataError
    from swarmpose.track.provenance import sequence_identity

    with pytest.raises(DataError, match="no sequence folder there"):
        make_report(results_copy, sequence=tmp_path / "nonexist")
    seq_dir = fake_results[1]
    cfg = json.loads((results_copy / "config.json").read_text())
    cfg["sequence_identity"] = "sequence.json sha1 0123456789abcdef"  # tracked on another clip
    (results_copy / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(DataError, match="is not the tracked sequence"):
        make_report(results_copy, sequence=seq_dir, overlay_frames=1)
    cfg["sequence_identity"] = sequence_identity(seq_dir)
    (results_copy / "config.json").write_text(json.dumps(cfg))
    assert len(make_report(results_copy, sequence=seq_dir, overlay_frames=1).overlays) == 1
