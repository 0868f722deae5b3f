"""Bad input to `swarmpose import`: one clear error naming the file and what was expected, and nothing written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from recording_fixtures import motion, rig, write_image_folders
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.io.calibration import write_calibration


@pytest.fixture()
def rec(tmp_path: Path):
    cams = rig(3)
    folders = write_image_folders(tmp_path / "videos", cams, motion(6))
    write_calibration(tmp_path / "calib.toml", cams, "toml")
    return tmp_path, folders


def run_import(root: Path, sources, calib=None, *extra: str):
    out = root / "seq"
    args = ["import", *map(str, sources), "--calibration", str(calib or root / "calib.toml"), "--out", str(out),
            "--no-detect", "--silhouettes", "median", "--fps", "30", "--no-page", "--json", *extra]
    res = CliRunner().invoke(app, args)
    leftovers = [p.name for p in root.iterdir() if p.name.startswith((".seq", "seq"))]
    return res, leftovers


def error_of(res) -> str:
    assert res.exit_code == 2, res.output
    return json.loads(res.stdout.strip().splitlines()[-1])["error"]


def test_the_good_recording_imports(rec):
    root, folders = rec
    res, left = run_import(root, folders)
    assert res.exit_code == 0, res.output
    assert left == ["seq"] and json.loads(res.stdout)["n_frames"] == 6


def test_an_unreadable_video(rec):
    root, folders = rec
    bad = root / "cam02.mp4"
    bad.write_text("not a video")
    res, left = run_import(root, [folders[0], bad, folders[2]])
    assert "cam02.mp4: cannot be opened as a video" in error_of(res) and left == []


def test_a_camera_without_calibration_entry(rec):
    root, folders = rec
    extra = root / "videos" / "cam07"
    shutil.copytree(folders[0], extra)
    res, left = run_import(root, [*folders, extra])
    msg = error_of(res)
    assert "cam07: no camera named like 'cam07' in" in msg and "calib.toml (its cameras: cam01, cam02, cam03)" in msg
    assert left == []


def test_frame_counts_that_differ(rec):
    root, folders = rec
    for f in sorted(folders[1].iterdir())[-2:]:
        f.unlink()
    res, left = run_import(root, folders)
    msg = error_of(res)
    assert "cam02.mp4" not in msg and "cam02 has 4 (2 fewer than cam01)" in msg and "--common-range" in msg
    assert left == []
    res, left = run_import(root, folders, None, "--common-range")
    assert res.exit_code == 0 and json.loads(res.stdout)["n_frames"] == 4


def test_an_image_size_that_does_not_match(rec):
    root, folders = rec
    for f in folders[2].iterdir():
        cv2.imwrite(str(f), np.zeros((200, 300), np.uint8))
    res, left = run_import(root, folders)
    msg = error_of(res)
    assert "cam03: frames are 300x200 but camera 'cam03' in" in msg and "is 320x240" in msg and left == []


def test_a_scaled_video_is_rescaled_and_said_so(rec):
    root, folders = rec
    for f in folders[2].iterdir():
        img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(f), cv2.resize(img, (160, 120), interpolation=cv2.INTER_AREA))
    res, left = run_import(root, folders)
    assert res.exit_code == 0, res.output
    notes = json.loads(res.stdout)["notes"]
    assert any("cam03: 160x120, the calibration says 320x240: the same view at 0.5 times" in n for n in notes)
    assert any("padded on the right and bottom to 320x240" in n for n in notes)


def test_a_calibration_that_does_not_parse(rec):
    root, folders = rec
    bad = root / "broken.toml"
    bad.write_text("[cam01\nmatrix = [[1, 0")
    res, left = run_import(root, folders, bad)
    msg = error_of(res)
    assert "broken.toml" in msg and left == []


def test_a_calibration_that_lacks_a_field(rec):
    root, folders = rec
    text = (root / "calib.toml").read_text()
    start = text.index("[cam02]")
    head, tail = text[:start], text[start:]
    lines = [ln for ln in tail.splitlines() if not ln.startswith("matrix")]
    (root / "nomatrix.toml").write_text(head + "\n".join(lines) + "\n")
    res, left = run_import(root, folders, root / "nomatrix.toml")
    msg = error_of(res)
    assert "nomatrix.toml" in msg and "cam02" in msg and "matrix" in msg and left == []


def test_an_existing_folder_is_kept_unless_forced(rec):
    root, folders = rec
    (root / "seq").mkdir()
    (root / "seq" / "notes.txt").write_text("mine")
    res, _ = run_import(root, folders)
    assert "exists and is not empty" in error_of(res)
    res, _ = run_import(root, folders, None, "--force")
    assert "refusing to replace a folder that holds no sequence" in error_of(res)
    assert (root / "seq" / "notes.txt").read_text() == "mine"


def test_frame_sources_video_folder_and_single_image(rec, tmp_path: Path):
    from swarmpose.io.video import open_frames

    root, folders = rec
    folder = open_frames(folders[0])
    assert (folder.name, folder.n_frames, folder.size, folder.fps) == ("cam01", 6, (320, 240), None)
    one = open_frames(sorted(folders[0].iterdir())[2])
    assert (one.name, one.n_frames) == ("000002", 1)
    _, img = next(one.frames([0]))
    assert img.shape == (240, 320, 3) and img[0, 1, 0] == 2  # the frame number the fixture wrote
    with pytest.raises(Exception, match=r"frames 0\.\.6 requested, it has 6"):
        list(folder.frames(range(7)))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(Exception, match="holds no images"):
        open_frames(empty)
