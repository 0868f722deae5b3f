"""The Lee walk adapter: the documented layout, custom layouts, errors that say which files were expected."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from he_fixtures import expected_joints15

from swarmpose.datasets import open_dataset_sequence
from swarmpose.datasets.leewalk import LeeWalkLayout, leewalk_sequence, open_leewalk, read_number_table
from swarmpose.errors import ConfigError, DataError, FormatError


def test_leewalk_sequence(leewalk_root: Path):
    rel = open_leewalk(leewalk_root)
    assert rel.n_frames == 10 and rel.size == (96, 72)
    assert [c.name for c in rel.cameras] == ["cam1", "cam2", "cam3", "cam4"]
    assert rel.gt_params.shape == (10, 31) and rel.gt_joints.shape == (10, 15, 3)
    with leewalk_sequence(f"leewalk:{leewalk_root}?frames=3-7") as seq:
        assert seq.n_frames == 5 and seq.streams == ("image", "silhouette") and seq.frame_rate == 60.0
        np.testing.assert_allclose(seq.gt_joints[0], expected_joints15(1 + 2 * 2), atol=1e-6)
        img, sil = seq.images(1), seq.silhouettes(1)
        assert img.shape == (4, 72, 96) and set(np.unique(sil)) <= {0, 1}
        for c, cam in enumerate(seq.cameras):  # ground truth lands on the dots and inside the silhouettes
            uv = np.rint(cam.project(seq.gt_joints[1])).astype(int)
            assert all(img[c, v, u] == 255 and sil[c, v, u] == 1 for u, v in uv)
        assert len(seq.provenance["gt_params"]) == 5
    with open_dataset_sequence(f"leewalk:{leewalk_root}") as seq:
        assert seq.n_frames == 10


def test_missing_calibration_names_the_expected_files(leewalk_root: Path, tmp_path: Path):
    root = tmp_path / "lee"
    shutil.copytree(leewalk_root, root)
    (root / "calibration" / "cam3.cal").unlink()
    with pytest.raises(DataError) as e:
        open_leewalk(root)
    msg = str(e.value)
    assert "calibration file for camera 3" in msg and str(root / "calibration" / "cam3.cal") in msg
    assert "Spica3Calib.cal" in msg and "LeeWalkLayout" in msg


def test_a_source_that_fails_to_open_points_to_the_check(leewalk_root: Path, tmp_path: Path):
    """Opening stops at the first problem (here the missing camera 2, found before cam1.cal is parsed); the
    message names `swarmpose datasets check`, whose report lists both."""
    from swarmpose.datasets import check_dataset

    root = tmp_path / "lee"
    shutil.copytree(leewalk_root, root)
    (root / "calibration" / "cam1.cal").write_text("not a calibration\n")
    (root / "calibration" / "cam2.cal").unlink()
    with pytest.raises(DataError, match="calibration file for camera 2") as e:
        open_dataset_sequence(f"leewalk:{root}?frames=1-5")
    assert f"`swarmpose datasets check {root}` lists every problem" in str(e.value)
    report = " ".join(check_dataset(root).problems)
    assert "cam1.cal" in report and "camera 2" in report
    with pytest.raises(DataError, match="no such Lee walk folder") as e:  # nothing there to check
        open_dataset_sequence(f"leewalk:{tmp_path / 'nowhere'}")
    assert "datasets check" not in str(e.value)


def test_missing_images_and_silhouettes(leewalk_root: Path, tmp_path: Path):
    root = tmp_path / "lee"
    shutil.copytree(leewalk_root, root)
    shutil.rmtree(root / "images" / "cam2")
    with pytest.raises(DataError, match="no images for camera 2"):
        open_leewalk(root)
    shutil.rmtree(root / "silhouettes" / "cam2")
    with pytest.raises(DataError, match="no images and no background-subtracted images for camera 2"):
        open_leewalk(root)


def test_custom_layout(leewalk_root: Path, tmp_path: Path):
    root = tmp_path / "mine"
    for k in "1234":
        (root / f"view{k}").mkdir(parents=True)
        shutil.copy(leewalk_root / "calibration" / f"cam{k}.cal", root / f"view{k}" / "camera.cal")
        shutil.copytree(leewalk_root / "silhouettes" / f"cam{k}", root / f"view{k}" / "fg")
    layout = LeeWalkLayout(calibration=("view{cam}/camera.cal",), images=(), silhouettes=("view{cam}/fg",))
    with open_leewalk(root, layout).sequence() as seq:
        assert seq.streams == ("silhouette",) and seq.gt_joints is None and seq.n_frames == 10


def test_ground_truth_tables(tmp_path: Path):
    f = tmp_path / "params.txt"
    f.write_text("# header\n" + "0 " * 31 + "\n" + "1 " * 30 + "\n")
    with pytest.raises(FormatError, match="30 values, expected 31") as e:
        read_number_table(f, 31, "ground-truth parameter file")
    assert e.value.line == 3
    f.write_text("1 " * 30 + "x\n")
    with pytest.raises(FormatError) as e:
        read_number_table(f, 31, "ground-truth parameter file", [f"x{j + 1}" for j in range(31)])
    assert e.value.field == "x31" and e.value.line == 1
    f.write_text("\n\n")
    with pytest.raises(FormatError, match="no data lines"):
        read_number_table(f, 31, "ground-truth parameter file")


def test_short_ground_truth_and_bad_frames(leewalk_root: Path, tmp_path: Path):
    root = tmp_path / "lee"
    shutil.copytree(leewalk_root, root)
    lines = (root / "groundtruth" / "joints15.txt").read_text().splitlines()
    (root / "groundtruth" / "joints15.txt").write_text("\n".join(lines[:4]) + "\n")
    with pytest.raises(FormatError, match="4 frames of ground truth, the images have 10"):
        open_leewalk(root)
    with pytest.raises(ConfigError, match="frames"):
        open_leewalk(leewalk_root).sequence((5, 11))
    with pytest.raises(ConfigError, match="unknown leewalk option"):
        leewalk_sequence(f"leewalk:{leewalk_root}?cams=1")
    with pytest.raises(DataError, match="no such Lee walk folder"):
        open_leewalk(tmp_path / "absent")


def test_ground_truth_joints_lost_markers_and_units(leewalk_root: Path, tmp_path: Path):
    root = tmp_path / "lee"
    shutil.copytree(leewalk_root, root)
    gt_file = root / "groundtruth" / "joints15.txt"
    joints = np.loadtxt(gt_file).reshape(-1, 15, 3)
    joints[4, 7] = 0.0  # a lost right wrist in frame 5
    np.savetxt(gt_file, joints.reshape(len(joints), 45))
    rel = open_leewalk(root)
    assert np.isnan(rel.gt_joints[4, 7]).all() and np.isfinite(rel.gt_joints[4, :7]).all()
    assert np.isfinite(np.delete(rel.gt_joints, 4, axis=0)).all()
    np.savetxt(gt_file, joints.reshape(len(joints), 45) / 1000.0)  # metres
    with pytest.raises(FormatError, match=r"joints15.txt.*median thigh \(hip to knee\) is 0\.\d+, expected 250-700 mm"):
        open_leewalk(root)


def test_lee_walk_keeps_a_joint_with_one_zero_coordinate():
    """(leewalk.py:167 lost marker = all three coordinates 0 -> any one): a joint exactly on a world
    axis plane is not lost."""
    from swarmpose.datasets.leewalk import _checked_joints
    from swarmpose.joints import JOINT_INDEX

    gt = np.random.default_rng(0).uniform(100.0, 1000.0, (3, 15, 3))
    gt[:, JOINT_INDEX["l_knee"]] = gt[:, JOINT_INDEX["l_hip"]] - [0.0, 0.0, 420.0]
    gt[:, JOINT_INDEX["r_knee"]] = gt[:, JOINT_INDEX["r_hip"]] - [0.0, 0.0, 420.0]
    gt[1, 3] = (0.0, 512.5, 900.0)  # on the x = 0 plane
    gt[2, 5] = 0.0  # lost
    out = _checked_joints(gt, Path("joints15.txt"))
    np.testing.assert_array_equal(out[1, 3], gt[1, 3])
    assert np.isnan(out[2, 5]).all() and np.isfinite(np.delete(out.reshape(-1, 3), 2 * 15 + 5, axis=0)).all()
