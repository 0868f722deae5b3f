"""Tests of swarmpose.io.mocap: units, axes, CMU -> HumanEva joints, resampling (real CMU clips)."""

from __future__ import annotations

import dataclasses
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from swarmpose.errors import ConfigError, FormatError
from swarmpose.io.bvh import BvhClip, BvhJoint, parse_bvh, read_bvh
from swarmpose.io.mocap import (
    UNIT_SCALES,
    MocapClip,
    clip_from_bvh,
    cmu_skeleton_map,
    infer_unit_scale,
    load_clip,
    resample,
    world_from_source_matrix,
)
from swarmpose.joints import JOINT_INDEX, JOINTS15

MOCAP_DIR = (Path(__file__).resolve().parents[2] / "../shared/data/mocap").resolve()
CLIPS = (
    "cmu_131_01_walk", "cmu_131_03_hop", "cmu_135_04_kick", "cmu_16_02_jump",
    "cmu_16_16_walk", "cmu_16_18_turn", "cmu_16_35_jog", "cmu_49_17_dance",
)
JI = JOINT_INDEX
# Bones of the 15-joint figure that are one rigid BVH segment each (the pelvis-thorax and thorax-head
# links span several rotating spine/neck joints and may change length).
RIGID_BONES = [
    ("pelvis", "l_hip"), ("pelvis", "r_hip"),
    ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"),
    ("thorax", "l_shoulder"), ("thorax", "r_shoulder"),
    ("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"), ("r_shoulder", "r_elbow"), ("r_elbow", "r_wrist"),
]


def _dir() -> Path:
    if not MOCAP_DIR.is_dir():
        pytest.skip(f"shared mocap data not found at {MOCAP_DIR} (the 'shared' folder sits beside the repo root)")
    return MOCAP_DIR


@cache
def _clip(name: str) -> MocapClip:
    return load_clip(_dir() / f"{name}.bvh")


def _bone(joints: np.ndarray, a: str, b: str) -> np.ndarray:
    return np.linalg.norm(joints[..., JI[a], :] - joints[..., JI[b], :], axis=-1)


# ---------------------------------------------------------------------- the 8 real clips
@pytest.mark.parametrize("name", CLIPS)
def test_clip_maps_to_plausible_15_joints(name):
    clip = _clip(name)
    J = clip.joints
    T = clip.frames
    assert J.shape == (T, 15, 3) and np.isfinite(J).all()
    assert clip.positions.shape == (T, 31, 3) and clip.end_sites.shape == (T, 31, 3)
    assert clip.frame_rate == 120.0 and clip.unit_name == "cmu"
    assert clip.mm_per_unit == pytest.approx(56.444, abs=1e-3)
    np.testing.assert_allclose(clip.frame_times[:3], [0.0, 1 / 120, 2 / 120])
    # geometry at frame 0 (world mm, z up, floor at z = 0)
    for side in "lr":
        assert 380.0 <= _bone(J[0], f"{side}_hip", f"{side}_knee") <= 460.0
        assert 380.0 <= _bone(J[0], f"{side}_knee", f"{side}_ankle") <= 470.0
        assert 220.0 <= _bone(J[0], f"{side}_shoulder", f"{side}_elbow") <= 320.0
        assert 150.0 <= _bone(J[0], f"{side}_elbow", f"{side}_wrist") <= 250.0
    assert 800.0 <= J[0, JI["pelvis"], 2] <= 1050.0
    assert 700.0 <= J[0, JI["l_hip"], 2] <= 1000.0 and 700.0 <= J[0, JI["r_hip"], 2] <= 1000.0
    z = J[0, :, 2]
    assert z[JI["head_top"]] > z[JI["thorax"]] > z[JI["pelvis"]] > z[JI["l_knee"]] > z[JI["l_ankle"]]
    assert z[JI["pelvis"]] > z[JI["r_knee"]] > z[JI["r_ankle"]]
    if name != "cmu_49_17_dance":  # the dancer starts with an arm above the head
        assert np.argmax(z) == JI["head_top"]
    assert 0.0 < np.nanmin(clip.end_sites[0, :, 2]) < 100.0  # lowest point (a toe tip) near the floor


@pytest.mark.parametrize("name", CLIPS)
def test_left_is_left_and_bones_rigid(name):
    clip = _clip(name)
    J, m = clip.joints, clip.skeleton_map
    # facing direction from the feet (ankle -> toe tip), horizontal; left = up x forward
    fwd = (clip.end_sites[:, m.l_toe] - J[:, JI["l_ankle"]]) + (clip.end_sites[:, m.r_toe] - J[:, JI["r_ankle"]])
    fwd[:, 2] = 0.0
    left = np.cross([0.0, 0.0, 1.0], fwd)
    assert (np.einsum("fa,fa->f", J[:, JI["l_hip"]] - J[:, JI["r_hip"]], left) > 0).all()
    # rigid skeleton: each single-segment bone keeps its length over all frames
    for a, b in RIGID_BONES:
        length = _bone(J, a, b)
        assert np.ptp(length) < 1e-6, (a, b)


def test_walkers_face_where_they_go():
    for name in ("cmu_16_16_walk", "cmu_16_35_jog", "cmu_131_01_walk"):
        clip = _clip(name)
        J, m = clip.joints, clip.skeleton_map
        travel = J[-1, JI["pelvis"]] - J[0, JI["pelvis"]]
        travel[2] = 0.0
        fwd = (clip.end_sites[0, m.l_toe] - J[0, JI["l_ankle"]]) + (clip.end_sites[0, m.r_toe] - J[0, JI["r_ankle"]])
        fwd[2] = 0.0
        cos = fwd @ travel / np.linalg.norm(fwd) / np.linalg.norm(travel)
        assert cos > 0.9, name
        # they move 2.5-4.5 m over the clip
        assert 2000.0 < np.linalg.norm(travel) < 5000.0


def test_both_layouts_have_the_same_semantics():
    mb, mx = _clip("cmu_16_16_walk"), _clip("cmu_131_01_walk")

    def mapped(clip, joint):
        return clip.joint_names[clip.skeleton_map.joint(joint)]

    assert mapped(mb, "l_shoulder") == "LeftArm" and mapped(mx, "l_shoulder") == "LeftShoulder"
    assert mapped(mb, "r_shoulder") == "RightArm" and mapped(mx, "r_shoulder") == "RightShoulder"
    assert mapped(mb, "l_hip") == "LeftUpLeg" and mapped(mx, "l_hip") == "LeftHip"
    assert mapped(mb, "l_wrist") == "LeftHand" and mapped(mx, "l_wrist") == "LeftWrist"
    assert mapped(mb, "thorax") == "Neck" and mapped(mx, "thorax") == "lowerneck"
    assert mapped(mb, "head_top") == "Head" and mapped(mx, "head_top") == "Head"
    for clip, clavicle in ((mb, "LeftShoulder"), (mx, "LeftCollar")):
        sh = clip.skeleton_map.joint("l_shoulder")
        assert clip.joint_names[clip.parents[sh]] == clavicle  # the shoulder is the clavicle's child
        # the clavicle and the thorax joint hang on the same parent (CMU "thorax" bone)
        assert clip.parents[clip.parents[sh]] == clip.parents[clip.skeleton_map.joint("thorax")]
    # same joint indices in both layouts (same tree, same order)
    assert mb.skeleton_map.joint_index == mx.skeleton_map.joint_index
    assert mb.joint_names[mb.skeleton_map.l_toe] == "LeftToeBase" and mx.joint_names[mx.skeleton_map.l_toe] == "LeftToe"


def test_joints_come_from_positions_and_end_sites():
    clip = _clip("cmu_16_35_jog")
    m = clip.skeleton_map
    for i in range(len(JOINTS15)):
        src = clip.end_sites if m.from_end_site[i] else clip.positions
        np.testing.assert_array_equal(clip.joints[:, i], src[:, m.joint_index[i]])
    assert m.from_end_site == tuple(n == "head_top" for n in JOINTS15)
    # thorax = base of the neck = where the clavicles start (amc2bvh OFFSET 0 quirk)
    clav = clip.parents[m.joint("l_shoulder")]
    np.testing.assert_allclose(clip.positions[:, clav], clip.joints[:, JI["thorax"]], atol=1e-9)


def test_world_transform():
    clip = _clip("cmu_16_16_walk")
    m = clip.world_from_source
    s = clip.mm_per_unit
    np.testing.assert_allclose(m, world_from_source_matrix(s))
    np.testing.assert_allclose(np.linalg.det(m[:3, :3] / s), 1.0)
    np.testing.assert_allclose(m[:3, 3], 0.0)
    src = clip.bvh.global_positions(frames=slice(0, 5))
    np.testing.assert_allclose(clip.positions[:5], src @ m[:3, :3].T, atol=1e-9)
    # world = s * (x, -z, y): BVH up (Y) becomes world z
    np.testing.assert_allclose(clip.positions[:5, 0, 2], s * src[:, 0, 1])
    np.testing.assert_allclose(clip.positions[:5, 0, 1], -s * src[:, 0, 2])


# ---------------------------------------------------------------------- units
def _scaled_bvh(bvh: BvhClip, factor: float) -> BvhClip:
    joints = []
    for j in bvh.joints:
        end = None if j.end_site is None else j.end_site * factor
        joints.append(dataclasses.replace(j, offset=j.offset * factor, end_site=end))
    motion = bvh.motion.copy()
    motion[:, :3] *= factor
    return BvhClip(path=bvh.path, joints=joints, frame_time=bvh.frame_time, motion=motion)


def test_infer_unit_scale():
    bvh = read_bvh(_dir() / "cmu_16_16_walk.bvh")
    assert infer_unit_scale(bvh) == (UNIT_SCALES["cmu"], "cmu")
    mm = UNIT_SCALES["cmu"]
    for unit in ("mm", "cm", "m", "inch"):
        assert infer_unit_scale(_scaled_bvh(bvh, mm / UNIT_SCALES[unit]))[1] == unit
    # overrides
    clip = clip_from_bvh(bvh, unit_scale="inch")
    assert clip.unit_name == "inch" and clip.mm_per_unit == 25.4
    clip = clip_from_bvh(bvh, unit_scale=10.0)
    assert clip.unit_name == "cm"
    clip = clip_from_bvh(bvh, unit_scale=3.0)
    assert clip.unit_name == "custom" and clip.mm_per_unit == 3.0
    with pytest.raises(ConfigError):
        clip_from_bvh(bvh, unit_scale="furlong")
    with pytest.raises(ConfigError):
        clip_from_bvh(bvh, unit_scale=-1.0)


# ---------------------------------------------------------------------- resampling
@pytest.mark.parametrize(("fps", "step"), [(60, 2), (30, 4), (20, 6), (12, 10)])
def test_resample_integer_ratio_is_subsampling(fps, step):
    clip = _clip("cmu_131_01_walk")
    r = resample(clip, fps)
    assert isinstance(r, MocapClip) and r.frame_rate == fps
    assert r.frames == len(range(0, clip.frames, step))
    np.testing.assert_allclose(r.joints, clip.joints[::step], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.positions, clip.positions[::step], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.bvh.motion, clip.bvh.motion[::step], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.frame_times, np.arange(r.frames) / fps)
    assert r.bvh.frame_time == 1.0 / fps


def test_load_clip_with_fps():
    path = _dir() / "cmu_16_35_jog.bvh"
    a = load_clip(path, fps=30)
    np.testing.assert_allclose(a.joints, _clip("cmu_16_35_jog").joints[::4], rtol=0, atol=1e-9)
    b = resample(read_bvh(path), 30)
    assert isinstance(b, BvhClip)
    np.testing.assert_allclose(b.motion, read_bvh(path).motion[::4], rtol=0, atol=1e-9)


def test_resample_non_integer_ratio_slerp():
    clip = _clip("cmu_16_16_walk")
    r = resample(clip, 25)  # source frame positions k * 4.8
    last = (clip.frames - 1) / 120.0
    assert r.frames == int(np.floor(last * 25 + 1e-9)) + 1
    assert r.frame_times[-1] <= last
    # t = 1/25 s is source frame 4.8: root translation linear, local rotations slerped
    src = clip.bvh
    root = 0.2 * src.root_translation(4) + 0.8 * src.root_translation(5)
    np.testing.assert_allclose(r.bvh.root_translation(1), root, atol=1e-12)
    rot = src.local_rotations(frames=slice(4, 6))
    got = r.bvh.local_rotations(frames=1)
    for j in (1, 3, 8, 20):
        ref = Slerp([0.0, 1.0], Rotation.from_matrix(rot[:, j]))([0.8]).as_matrix()[0]
        np.testing.assert_allclose(got[0, j], ref, atol=1e-9)
    # frames at multiples of 1/5 s coincide with source frames (k * 4.8 = 24 at k = 5)
    np.testing.assert_allclose(r.joints[5], clip.joints[24], atol=1e-9)
    np.testing.assert_array_equal(r.bvh.motion[5], clip.bvh.motion[24])
    # the skeleton stays rigid and the re-derived Euler angles reproduce the interpolated pose
    for a, b in RIGID_BONES:
        assert np.ptp(_bone(r.joints, a, b)) < 1e-6
    m = r.world_from_source[:3, :3]
    np.testing.assert_allclose(r.bvh.global_positions() @ m.T, r.positions, atol=1e-6)
    # interpolated poses lie between their neighbours
    mid = r.joints[1]
    lo, hi = clip.joints[4], clip.joints[5]
    assert np.all(np.linalg.norm(mid - lo, axis=-1) <= np.linalg.norm(hi - lo, axis=-1) + 1e-6)


def test_resample_bad_fps():
    clip = _clip("cmu_16_35_jog")
    with pytest.raises(ConfigError):
        resample(clip, 0)
    with pytest.raises(ConfigError):
        resample(clip, float("nan"))
    with pytest.raises(ConfigError):
        resample("clip", 30)  # type: ignore[arg-type]


# ---------------------------------------------------------------------- structure mismatch
def test_non_cmu_skeleton_raises():
    text = (
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n"
        " JOINT Spine\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Yrotation Xrotation\n"
        "  End Site\n  {\n   OFFSET 0 5 0\n  }\n }\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.0333333\n0 0 0 0 0 0 0 0 0\n"
    )
    bvh = parse_bvh(text, path="tiny.bvh")
    with pytest.raises(FormatError, match="skeleton is not CMU-style") as info:
        cmu_skeleton_map(bvh)
    assert "tiny.bvh" in str(info.value) and "3 children" in str(info.value)
    with pytest.raises(FormatError, match="not CMU-style"):
        clip_from_bvh(bvh)


def test_truncated_arm_raises():
    bvh = read_bvh(_dir() / "cmu_16_35_jog.bvh")
    # cut the left arm after the elbow: drop LeftHand and everything below it
    wrist = bvh.joint_index("LeftHand")
    drop = {wrist} | {j for j in range(len(bvh.joints)) if _is_below(bvh, j, wrist)}
    keep = [j for j in range(len(bvh.joints)) if j not in drop]
    remap = {old: new for new, old in enumerate(keep)}
    joints, cols, start = [], [], 0
    for old in keep:
        j = bvh.joints[old]
        parent = remap[j.parent] if j.parent >= 0 else -1
        end = j.end_site
        if old == bvh.parents[wrist]:
            end = np.array([1.0, 0.0, 0.0])
        joints.append(BvhJoint(j.name, parent, j.offset, j.channels, start, end))
        cols.extend(range(j.channel_start, j.channel_start + len(j.channels)))
        start += len(j.channels)
    cut = BvhClip(path=bvh.path, joints=joints, frame_time=bvh.frame_time, motion=bvh.motion[:, cols])
    with pytest.raises(FormatError, match="left arm"):
        cmu_skeleton_map(cut)


def _is_below(bvh: BvhClip, j: int, ancestor: int) -> bool:
    p = bvh.parents[j]
    while p >= 0:
        if p == ancestor:
            return True
        p = bvh.parents[p]
    return False


def test_mirrored_skeleton_raises():
    bvh = read_bvh(_dir() / "cmu_16_35_jog.bvh")
    flip = np.array([-1.0, 1.0, 1.0])
    joints = [dataclasses.replace(j, offset=j.offset * flip, end_site=None if j.end_site is None else j.end_site * flip)
              for j in bvh.joints]
    mirrored = BvhClip(path=bvh.path, joints=joints, frame_time=bvh.frame_time, motion=bvh.motion)
    with pytest.raises(FormatError, match="mirrored"):
        cmu_skeleton_map(mirrored)


def _with_offsets(bvh: BvhClip, change) -> BvhClip:
    joints = [dataclasses.replace(j, offset=change(k, j.offset),
                                  end_site=None if j.end_site is None else change(k, j.end_site))
              for k, j in enumerate(bvh.joints)]
    return BvhClip(path=bvh.path, joints=joints, frame_time=bvh.frame_time, motion=bvh.motion)


def test_swapped_arms_raise():
    """Arms in the other order under the thorax (the right arm first) would map the left arm's joints to
    the right ones: refused, judged from where the first arm stands."""
    bvh = read_bvh(_dir() / "cmu_16_35_jog.bvh")
    shoulders = {bvh.joint_index("LeftShoulder"), bvh.joint_index("RightShoulder")}
    arm = {j for j in range(len(bvh.joints)) if j in shoulders or any(_is_below(bvh, j, s) for s in shoulders)}
    flip = np.array([-1.0, 1.0, 1.0])
    swapped = _with_offsets(bvh, lambda k, v: v * flip if k in arm else v)
    with pytest.raises(FormatError, match="first arm is on the other side from the root's first leg.*neck, left arm"):
        cmu_skeleton_map(swapped)


def test_rest_pose_not_facing_plus_z_raises():
    """The subject's limb offsets are read in CMU's rest frame (facing +Z): another facing is refused."""
    bvh = read_bvh(_dir() / "cmu_16_35_jog.bvh")
    turn = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    turned = _with_offsets(bvh, lambda k, v: turn @ v)
    with pytest.raises(FormatError, match=r"rest pose faces \+90 degrees from \+Z"):
        cmu_skeleton_map(turned)
    slight = Rotation.from_euler("y", 5, degrees=True).as_matrix()
    cmu_skeleton_map(_with_offsets(bvh, lambda k, v: slight @ v))  # a rest pose a little turned is fine


def test_resampled_rotation_channels_stay_continuous(mocap_dir):
    """(mocap.py:637 the Euler solution nearer the interpolated channels -> the farther one): the
    rotations are the same either way, but the resampled clip's channels jump by ~180 deg."""
    from swarmpose.io.bvh import read_bvh
    from swarmpose.io.mocap import resample

    src = read_bvh(mocap_dir / "cmu_16_16_walk.bvh")
    out = resample(src, 47.0)  # non-integer ratio: slerped frames
    t = np.arange(out.frames) / 47.0 * src.frame_rate
    k = np.minimum(np.floor(t).astype(int), src.frames - 2)
    lin = src.motion[k] + (t - k)[:, None] * (src.motion[k + 1] - src.motion[k])
    # where the source itself does not jump between the two frames (the CMU files switch Euler branch
    # now and then), the resampled channels follow the linear interpolation to within a few degrees
    smooth = np.abs(src.motion[k + 1] - src.motion[k]) < 20.0
    assert smooth.mean() > 0.95
    assert np.abs(out.motion - lin)[smooth].max() < 5.0
