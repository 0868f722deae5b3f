"""Tests of swarmpose.io.bvh: parsing, errors with line numbers, forward kinematics, real CMU clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarmpose.errors import DataError, FormatError, ShapeError
from swarmpose.io.bvh import BvhClip, elementary_rotations, nominal_frame_rate, read_bvh

MOCAP_DIR = (Path(__file__).resolve().parents[2] / "../shared/data/mocap").resolve()

# file -> (frames, duration in s) from shared/data/mocap/README.md
README_TABLE = {
    "cmu_131_01_walk.bvh": (994, 8.283),
    "cmu_131_03_hop.bvh": (1102, 9.183),
    "cmu_16_16_walk.bvh": (510, 4.250),
    "cmu_16_18_turn.bvh": (520, 4.333),
    "cmu_16_35_jog.bvh": (162, 1.350),
    "cmu_16_02_jump.bvh": (466, 3.883),
    "cmu_49_17_dance.bvh": (750, 6.250),
    "cmu_135_04_kick.bvh": (1316, 10.967),
}

# Line numbers (1-based) are part of the tests below.
TWO_JOINTS = """\
HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Arm
  {
    OFFSET 0 5 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 0 2
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.04
10 20 30 90 0 0 90 0 0
1 2 3 0 0 0 0 0 0
0 0 0 90 90 0 0 0 0
"""


def write(tmp_path: Path, text: str, name: str = "clip.bvh") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def replace_line(text: str, lineno: int, new: str | None) -> str:
    lines = text.splitlines()
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- hierarchy and FK
def test_two_joint_structure(tmp_path):
    clip = read_bvh(write(tmp_path, TWO_JOINTS))
    assert clip.joint_names == ["Hips", "Arm"]
    assert clip.parents.tolist() == [-1, 0]
    assert clip.children(0) == [1] and clip.children(1) == []
    assert clip.joints[0].channels == ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    assert clip.joints[1].channel_start == 6
    assert clip.joints[0].end_site is None
    np.testing.assert_array_equal(clip.joints[1].end_site, [0, 0, 2])
    assert clip.frames == 3 and clip.motion.shape == (3, 9)
    assert clip.frame_time == 0.04 and clip.frame_rate == 25.0
    assert clip.duration_s == pytest.approx(0.12)


def test_two_joint_forward_kinematics_by_hand(tmp_path):
    clip = read_bvh(write(tmp_path, TWO_JOINTS))
    # Frame 0: root at (10, 20, 30), R_root = Rz(90) (maps (x, y, z) -> (-y, x, z)).
    #   Arm = root + Rz(90) (0, 5, 0) = (10 - 5, 20, 30) = (5, 20, 30)
    #   R_arm_global = Rz(90) Rx(90); Rx(90) (0, 0, 2) = (0, -2, 0); Rz(90) (0, -2, 0) = (2, 0, 0)
    #   End site = (5, 20, 30) + (2, 0, 0) = (7, 20, 30)
    # Frame 1: no rotation: Arm = (1, 2, 3) + (0, 5, 0) = (1, 7, 3); end = (1, 7, 5)
    # Frame 2: R_root = Rz(90) Rx(90) (channels list Z then X): Rx(90) (0, 5, 0) = (0, 0, 5), Rz(90) keeps it
    #   Arm = (0, 0, 5); end = Rz(90) Rx(90) (0, 0, 2) = (2, 0, 0) -> (2, 0, 5)
    #   (the other order, Rx(90) Rz(90) (0, 5, 0), would give (-5, 0, 0))
    pos = clip.global_positions()
    ends = clip.end_site_positions()
    expected_pos = [[[10, 20, 30], [5, 20, 30]], [[1, 2, 3], [1, 7, 3]], [[0, 0, 0], [0, 0, 5]]]
    np.testing.assert_allclose(pos, expected_pos, atol=1e-12)
    assert np.isnan(ends[:, 0]).all()
    np.testing.assert_allclose(ends[:, 1], [[7, 20, 30], [1, 7, 5], [2, 0, 5]], atol=1e-12)
    np.testing.assert_allclose(clip.root_translation(), [[10, 20, 30], [1, 2, 3], [0, 0, 0]])
    # frame selection
    np.testing.assert_allclose(clip.global_positions(frames=slice(1, 3)), pos[1:3])
    np.testing.assert_allclose(clip.global_positions(frames=2), pos[2:3])
    np.testing.assert_allclose(clip.end_site_positions(frames=[2, 0])[:, 1], [[2, 0, 5], [7, 20, 30]], atol=1e-12)
    rot = clip.local_rotations(frames=slice(0, 1))
    assert rot.shape == (1, 2, 3, 3)
    np.testing.assert_allclose(rot[0, 1], elementary_rotations("X", 90.0), atol=1e-15)


def test_channel_order_zyx_vs_zxy(tmp_path):
    angles = {"Z": 30.0, "Y": -50.0, "X": 70.0}
    results = {}
    for order in ("ZYX", "ZXY", "XYZ", "YZX"):
        chans = " ".join(f"{a}rotation" for a in order)
        text = (
            "HIERARCHY\nROOT R\n{\n OFFSET 0 0 0\n CHANNELS 3 " + chans + "\n End Site\n {\n  OFFSET 1 2 3\n }\n}\n"
            "MOTION\nFrames: 1\nFrame Time: 0.1\n" + " ".join(str(angles[a]) for a in order) + "\n"
        )
        clip = read_bvh(write(tmp_path, text, f"{order}.bvh"))
        rot = clip.local_rotations()[0, 0]
        # product of elementary rotations in the listed order (column vectors) = scipy's intrinsic Euler
        ref = Rotation.from_euler(order, [angles[a] for a in order], degrees=True).as_matrix()
        np.testing.assert_allclose(rot, ref, atol=1e-12)
        manual = elementary_rotations(order[0], angles[order[0]]) @ elementary_rotations(
            order[1], angles[order[1]]) @ elementary_rotations(order[2], angles[order[2]])
        np.testing.assert_allclose(rot, manual, atol=1e-12)
        np.testing.assert_allclose(clip.end_site_positions()[0, 0], rot @ [1, 2, 3], atol=1e-12)
        results[order] = rot
    assert not np.allclose(results["ZYX"], results["ZXY"])


def test_position_channels_replace_offset_components(tmp_path):
    text = (
        "HIERARCHY\nROOT R\n{\n OFFSET 1 2 3\n CHANNELS 2 Zposition Xposition\n"
        " JOINT C\n {\n  OFFSET 0 1 0\n  CHANNELS 1 Yposition\n }\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.5\n7 8 9\n"
    )
    clip = read_bvh(write(tmp_path, text))
    np.testing.assert_allclose(clip.root_translation(), [[8, 2, 7]])
    np.testing.assert_allclose(clip.global_positions()[0], [[8, 2, 7], [8, 11, 7]])
    assert clip.frame_rate == 2.0


def test_whitespace_tabs_crlf_and_braces_on_same_line(tmp_path):
    messy = TWO_JOINTS.replace("  ", "\t \t").replace("\n", "  \r\n").replace("Frame Time: 0.04", "Frame Time:\t0.04")
    messy = messy.replace("ROOT Hips  \r\n{", "ROOT Hips {").replace("MOTION", "\r\nMOTION")
    messy = messy.replace("1 2 3 0", "  1\t2   3 0") + "\r\n\r\n"
    a = read_bvh(write(tmp_path, TWO_JOINTS, "a.bvh"))
    b = read_bvh(write(tmp_path, "\ufeff" + messy, "b.bvh"))
    assert a.joint_names == b.joint_names
    np.testing.assert_array_equal(a.motion, b.motion)
    np.testing.assert_array_equal(a.global_positions(), b.global_positions())


def test_end_site_brace_on_same_line_and_named_end_site(tmp_path):
    text = TWO_JOINTS.replace("End Site\n    {", "End Site {")
    assert "End Site {" in text
    a = read_bvh(write(tmp_path, text, "a.bvh"))
    b = read_bvh(write(tmp_path, TWO_JOINTS.replace("End Site", "End Site Arm_End"), "b.bvh"))
    for clip in (a, b):
        np.testing.assert_array_equal(clip.joints[1].end_site, [0, 0, 2])


def test_multiple_roots_and_zero_channel_joint(tmp_path):
    text = (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
        " JOINT Fixed\n {\n  OFFSET 1 0 0\n  CHANNELS 0\n  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\n"
        "ROOT B\n{\n OFFSET 5 5 5\n CHANNELS 1 Yrotation\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.1\n1 1 1 90\n"
    )
    clip = read_bvh(write(tmp_path, text))
    assert clip.parents.tolist() == [-1, 0, -1]
    np.testing.assert_allclose(clip.global_positions()[0], [[1, 1, 1], [2, 1, 1], [5, 5, 5]])
    np.testing.assert_allclose(clip.end_site_positions()[0, 1], [2, 2, 1])


def test_rest_positions(tmp_path):
    clip = read_bvh(write(tmp_path, TWO_JOINTS))
    pos, ends = clip.rest_positions()
    np.testing.assert_allclose(pos, [[0, 0, 0], [0, 5, 0]])
    np.testing.assert_allclose(ends[1], [0, 5, 2])


def test_nominal_frame_rate():
    assert nominal_frame_rate(0.0083333) == 120.0
    assert nominal_frame_rate(0.033333) == 30.0
    assert nominal_frame_rate(1 / 29.97) == pytest.approx(29.97)


def test_clip_validates_motion_shape(tmp_path):
    clip = read_bvh(write(tmp_path, TWO_JOINTS))
    with pytest.raises(ShapeError, match="9"):
        BvhClip(path=None, joints=clip.joints, frame_time=0.04, motion=np.zeros((2, 8)))


# ---------------------------------------------------------------------- errors
class _Err:
    """The FormatError's message without the file name (tmp paths contain the test's name)."""

    def __init__(self, exc: FormatError):
        self.line = exc.line
        self.text = str(exc).replace(str(exc.path), "<path>")

    def __str__(self) -> str:
        return self.text


def _error(tmp_path, text) -> _Err:
    path = write(tmp_path, text, "c.bvh")
    with pytest.raises(FormatError) as info:
        read_bvh(path)
    assert str(info.value).startswith(f"{path}, line ") or str(info.value).startswith(f"{path}: ")
    assert isinstance(info.value, ValueError)
    return _Err(info.value)


def test_error_truncated_motion(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 17, "Frames: 4"))
    assert "truncated" in str(err) and "4" in str(err) and "3 data lines" in str(err)
    assert err.line == 21


def test_error_extra_data_lines(tmp_path):
    err = _error(tmp_path, TWO_JOINTS + "0 0 0 0 0 0 0 0 0\n")
    assert "more data lines" in str(err) and err.line == 22


def test_error_wrong_value_count(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 20, "1 2 3 0 0 0 0 0"))
    assert "expected 9" in str(err) and "got 8" in str(err) and err.line == 20


def test_error_non_numeric(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 19, "10 20 abc 90 0 0 90 0 0"))
    assert "'abc'" in str(err) and "value 3" in str(err) and err.line == 19
    err = _error(tmp_path, replace_line(TWO_JOINTS, 8, "OFFSET 0 five 0"))
    assert "'five'" in str(err) and err.line == 8


@pytest.mark.parametrize("token", ["nan", "inf", "-Infinity"])
def test_error_non_finite(tmp_path, token):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 20, f"1 2 3 0 0 {token} 0 0 0"))
    assert "not finite" in str(err) and repr(token) in str(err) and err.line == 20


def test_error_missing_sections(tmp_path):
    no_motion = "\n".join(TWO_JOINTS.splitlines()[:15]) + "\n"
    err = _error(tmp_path, no_motion)
    assert "MOTION" in str(err)
    err = _error(tmp_path, replace_line(TWO_JOINTS, 17, None))
    assert "Frames" in str(err) and err.line == 17
    err = _error(tmp_path, replace_line(TWO_JOINTS, 18, None))
    assert "Frame Time" in str(err) and err.line == 18
    err = _error(tmp_path, replace_line(TWO_JOINTS, 18, "Frame Time: -0.1"))
    assert "Frame Time" in str(err)
    err = _error(tmp_path, "MOTION\n")
    assert "HIERARCHY" in str(err) and err.line == 1


def test_error_unbalanced_braces(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 14, None))  # '}' of Arm missing
    assert "unbalanced" in str(err) and "Hips" in str(err) and err.line == 15
    err = _error(tmp_path, replace_line(TWO_JOINTS, 15, "}\n}"))  # one '}' too many
    assert "unbalanced" in str(err) and err.line == 16
    err = _error(tmp_path, replace_line(TWO_JOINTS, 7, None))  # '{' of Arm missing
    assert "expected '{' after 'Arm' (line 6)" in str(err) and err.line == 7


def test_error_unknown_channel(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 9, "CHANNELS 3 Xrotation Wrotation Zrotation"))
    assert "'Wrotation'" in str(err) and err.line == 9


def test_error_channel_count_mismatch(tmp_path):
    err = _error(tmp_path, replace_line(TWO_JOINTS, 9, "CHANNELS 3 Xrotation Yrotation"))
    assert "declares 3" in str(err) and "lists 2" in str(err) and err.line == 9


def test_error_missing_file(tmp_path):
    with pytest.raises(DataError):
        read_bvh(tmp_path / "missing.bvh")


# ---------------------------------------------------------------------- the real clips
def _mocap_dir() -> Path:
    if not MOCAP_DIR.is_dir():
        pytest.skip(f"shared mocap data not found at {MOCAP_DIR} (the 'shared' folder sits beside the repo root)")
    return MOCAP_DIR


@pytest.mark.parametrize("name", sorted(README_TABLE))
def test_real_clips_load(name):
    path = _mocap_dir() / name
    clip = read_bvh(path)
    frames, duration = README_TABLE[name]
    header = path.read_text().split("MOTION", 1)[1].split()
    assert header[0] == "Frames:" and int(header[1]) == frames == clip.frames
    assert clip.frame_time == 0.0083333 and clip.frame_rate == 120.0
    assert round(clip.duration_s, 3) == pytest.approx(duration)
    assert len(clip.joints) == 31 and clip.n_channels == 96
    assert clip.joints[0].channels[:3] == ("Xposition", "Yposition", "Zposition")
    np.testing.assert_array_equal(clip.root_translation(), clip.motion[:, :3])
    pos = clip.global_positions(frames=slice(0, 50))
    assert pos.shape == (50, 31, 3) and np.isfinite(pos).all()
    # every CMU bone keeps its length (rigid skeleton)
    parents = clip.parents
    bone = np.linalg.norm(pos[:, 1:] - pos[:, parents[1:]], axis=-1)
    np.testing.assert_allclose(bone, np.broadcast_to(np.linalg.norm(clip.offsets[1:], axis=1), bone.shape),
                               atol=1e-9)
    ends = clip.end_site_positions(frames=0)
    assert np.isfinite(ends[0][[j.end_site is not None for j in clip.joints]]).all()
