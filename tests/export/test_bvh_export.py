"""BVH export: read back with swarmpose's own reader, the joints land where the model puts them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError, FormatError, ShapeError
from swarmpose.export import ROTATION_ORDERS, bvh_axes, euler_from_matrices, export_bvh, rest_rotation
from swarmpose.io.bvh import elementary_rotations, read_bvh


def random_valid_poses(model, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.lower), model.lower, -np.pi)
    hi = np.where(np.isfinite(model.upper), model.upper, np.pi)
    P = rng.uniform(lo, hi, size=(20 * n, model.n_params))
    for name, (a, b) in {"pelvis_tx": (-2000, 2000), "pelvis_ty": (-2000, 2000), "pelvis_tz": (800, 1100)}.items():
        P[:, model.param_index(name)] = rng.uniform(a, b, len(P))
    P = P[HardPriors(model).valid(P)]
    assert len(P) >= n
    return P[:n]


def _back_to_world(path: Path, y_up: bool, scale: float = 1.0):
    clip = read_bvh(path)
    return clip, clip.global_positions() @ bvh_axes(y_up) / scale  # world = A^T p


@pytest.mark.parametrize("model_name", ["balan31", "full45"])
@pytest.mark.parametrize("y_up", [True, False])
@pytest.mark.parametrize("order", ["ZXY", "XYZ", "model"])
@pytest.mark.parametrize("rest_facing", ["+z", "+x"])
def test_round_trip_positions(tmp_path: Path, model_name: str, y_up: bool, order: str, rest_facing: str):
    model = load_model(model_name)
    P = random_valid_poses(model, 12, seed=len(order) + y_up)
    path = export_bvh(model, P, 60.0, tmp_path / "m.bvh", y_up=y_up, rotation_order=order,
                      rest_facing=rest_facing)
    clip, world = _back_to_world(path, y_up)
    assert clip.frames == 12
    names = model.spec.joint_names
    assert sorted(clip.joint_names) == sorted(names)
    idx = [clip.joint_names.index(n) for n in names]
    err = np.abs(world[:, idx] - model.joint_positions(P)).max()
    assert err < 1e-3, err
    # every joint rotates; the root also translates; leaves end in an End Site
    for j in clip.joints:
        assert sum(c.endswith("rotation") for c in j.channels) == 3
    assert clip.joints[0].channels[:3] == ("Xposition", "Yposition", "Zposition")
    leaves = [i for i in range(len(clip.joints)) if not clip.children(i)]
    assert leaves and all(clip.joints[i].end_site is not None for i in leaves)


def test_header_and_units(tmp_path: Path):
    model = load_model("balan31")
    P = random_valid_poses(model, 4)
    path = export_bvh(model, P, 20.0, tmp_path / "cm" / "m.bvh", scale=0.1)
    text = path.read_text()
    assert "MOTION\nFrames: 4\nFrame Time: 0.05000000\n" in text
    clip, world = _back_to_world(path, True, scale=0.1)
    assert clip.frame_rate == 20.0 and clip.frame_time == pytest.approx(0.05)
    idx = [clip.joint_names.index(n) for n in model.spec.joint_names]
    np.testing.assert_allclose(world[:, idx], model.joint_positions(P), atol=1e-3)
    p60 = export_bvh(model, P, 60.0, tmp_path / "60.bvh")
    assert read_bvh(p60).frame_rate == 60.0
    # offsets are the subject's measurements in the rest pose's axes: B = Q A (Y up, turned to face +Z);
    # the hip's offset is not vertical, so a wrong turn would show there
    B = rest_rotation() @ bvh_axes(True)
    clip60 = read_bvh(p60)
    for joint, offset in (("l_knee", "l_thigh"), ("l_hip", "l_pelvis_to_hip"), ("r_shoulder", "r_thorax_to_shoulder")):
        np.testing.assert_allclose(clip60.joints[clip60.joint_index(joint)].offset,
                                   B @ np.asarray(model.subject.offsets[offset]), atol=1e-6, err_msg=joint)


def _rest_positions(clip) -> np.ndarray:
    """Joint positions with every channel zero: the offsets summed down the tree."""
    rest = np.zeros((len(clip.joints), 3))
    for j, joint in enumerate(clip.joints):
        p = int(clip.parents[j])
        rest[j] = (rest[p] if p >= 0 else 0.0) + np.asarray(joint.offset)
    return rest


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("model_name", ["balan31", "full45"])
def test_rest_pose_faces_plus_z(tmp_path: Path, model_name: str):
    """All channels zero: Y up and the subject's left on +X, so (right-handed) facing +Z, as tools expect."""
    model = load_model(model_name)
    P = random_valid_poses(model, 2)
    clip = read_bvh(export_bvh(model, P, 60.0, tmp_path / "m.bvh"))
    rest = _rest_positions(clip)

    def at(name: str) -> np.ndarray:
        return rest[clip.joint_index(name)]

    assert _unit(at("l_hip") - at("r_hip"))[0] > 0.99  # left on +X
    assert _unit(at("head_top") - at("pelvis"))[1] > 0.95  # up on +Y
    if "l_toe" in clip.joint_names:
        assert _unit(at("l_toe") - at("l_ankle"))[2] > 0.6  # the feet point to +Z
    # --rest-facing +x keeps the model's own zero pose, which faces +X (left on -Z)
    old = read_bvh(export_bvh(model, P, 60.0, tmp_path / "x.bvh", rest_facing="+x"))
    rest_x = _rest_positions(old)
    assert -_unit(rest_x[old.joint_index("l_hip")] - rest_x[old.joint_index("r_hip")])[2] > 0.99
    with pytest.raises(ConfigError, match="rest facing"):
        export_bvh(model, P, 60.0, tmp_path / "bad.bvh", rest_facing="-y")


def test_angles_are_continuous(tmp_path: Path):
    """A root turning three times about the vertical: no 360 degree jumps between frames."""
    model = load_model("balan31")
    T = 240
    P = np.zeros((T, model.n_params))
    P[:, model.param_index("pelvis_rz")] = np.linspace(0.0, 6.0 * np.pi, T)
    P[:, model.param_index("pelvis_tz")] = 950.0
    P[:, model.param_index("l_shoulder_abd")] = np.linspace(0.0, np.pi, T)  # through 90 degrees
    P[:, model.param_index("l_shoulder_flex")] = 0.3
    path = export_bvh(model, P, 60.0, tmp_path / "turn.bvh")
    clip = read_bvh(path)
    jumps = np.abs(np.diff(clip.motion[:, 3:], axis=0))
    assert jumps.max() < 10.0, jumps.max()
    idx = [clip.joint_names.index(n) for n in model.spec.joint_names]
    world = clip.global_positions() @ bvh_axes(True)
    assert np.abs(world[:, idx] - model.joint_positions(P)).max() < 1e-3


@pytest.mark.parametrize("order", ROTATION_ORDERS)
def test_euler_convention_matches_bvh_reader(order: str):
    rng = np.random.default_rng(1)
    from scipy.spatial.transform import Rotation

    R = Rotation.random(50, random_state=rng).as_matrix()
    ang = euler_from_matrices(R, order, continuous=False)
    back = np.einsum("nab,nbc,ncd->nad", elementary_rotations(order[0], ang[:, 0]),
                     elementary_rotations(order[1], ang[:, 1]), elementary_rotations(order[2], ang[:, 2]))
    np.testing.assert_allclose(back, R, atol=1e-10)


def test_errors(tmp_path: Path):
    model = load_model("balan31")
    P = np.zeros((2, model.n_params))
    with pytest.raises(ShapeError):
        export_bvh(model, np.zeros((2, 5)), 60.0, tmp_path / "a.bvh")
    with pytest.raises(ConfigError, match="frame_rate"):
        export_bvh(model, P, 0.0, tmp_path / "a.bvh")
    with pytest.raises(ConfigError, match="rotation order"):
        export_bvh(model, P, 60.0, tmp_path / "a.bvh", rotation_order="XXY")


@pytest.mark.parametrize("model_name", ["balan31", "full45"])
def test_exported_clip_loads_back_as_ground_truth(tmp_path: Path, model_name: str):
    """An exported file is a clip swarmpose reads (style "auto" -> "swarmpose", by joint name): its 15
    joints are the model's, in the same world, and the subject measured from it is the model's."""
    from swarmpose.io.mocap import load_clip, subject_from_clip

    model = load_model(model_name)
    P = random_valid_poses(model, 5)
    path = export_bvh(model, P, 30.0, tmp_path / "m.bvh")
    clip = load_clip(path, style="auto")
    assert clip.skeleton_map.style == "swarmpose" and clip.unit_name == "mm"
    np.testing.assert_allclose(clip.joints, model.joints15(P), atol=1e-3)
    measured = subject_from_clip(model.spec, clip)
    for name in ("l_thigh", "r_shank", "l_upper_arm", "r_forearm", "l_pelvis_to_hip", "r_thorax_to_shoulder",
                 "spine_to_thorax", "l_foot", "r_hand", "neck_to_head", "head_to_top"):
        if name in model.subject.offsets:  # full45 has feet, hands and a head joint; balan31 not
            np.testing.assert_allclose(measured.offsets[name], model.subject.offsets[name], atol=1e-3, err_msg=name)
    if model_name == "balan31":  # a full45 subject cannot be measured from a file without toes and hands
        with pytest.raises(ConfigError, match="needs the joints l_toe, l_hand_tip, head"):
            subject_from_clip(load_model("full45").spec, clip)
    # the model's own +X rest facing is refused with the way out named; CMU files still map as CMU
    turned = export_bvh(model, P, 30.0, tmp_path / "x.bvh", rest_facing="+x")
    with pytest.raises(FormatError, match="--rest-facing \\+z"):
        load_clip(turned, style="auto")
    with pytest.raises(FormatError, match="not CMU-style"):
        load_clip(path)  # the default style stays "cmu"
    with pytest.raises(FormatError, match="without --z-up"):
        load_clip(export_bvh(model, P, 30.0, tmp_path / "z.bvh", y_up=False), style="auto")


def test_auto_maps_by_name_whatever_the_tree_order(tmp_path: Path):
    """A model file whose thorax lists the neck first has the CMU tree shape; "auto" still maps it by name
    (read as CMU, head_top would be the exporter's made-up End Site, 45 mm off)."""
    import json

    import swarmpose
    from swarmpose.io.mocap import load_clip

    spec = json.loads((Path(swarmpose.__file__).parent / "models" / "full45.json").read_text())
    head = [j for j in spec["joints"] if j["name"] in ("neck", "head", "head_top")]
    rest = [j for j in spec["joints"] if j["name"] not in ("neck", "head", "head_top")]
    i = [j["name"] for j in rest].index("thorax")
    spec["joints"] = rest[: i + 1] + head + rest[i + 1:]
    (tmp_path / "neck_first.json").write_text(json.dumps(spec))
    model = load_model(str(tmp_path / "neck_first.json"))
    P = random_valid_poses(model, 4)
    clip = load_clip(export_bvh(model, P, 30.0, tmp_path / "nf.bvh"), style="auto")
    assert clip.skeleton_map.style == "swarmpose"
    np.testing.assert_allclose(clip.joints, model.joints15(P), atol=1e-3)


def test_uneven_tracked_frames_are_put_on_an_even_clock():
    """25 fps tracked from 60 fps picks frames 33 and 50 ms apart; the BVH needs one frame time, so the poses
    are interpolated onto t0 + k / 25: a motion uniform in time stays uniform per frame (no 25 % warp)."""
    from swarmpose.export import uniform_clock

    t = np.round(np.arange(0, 61) / 25 * 60) / 60  # the nearest 60-fps frames of a 25-fps clock
    assert set(np.round(np.diff(t) * 1000).astype(int)) == {33, 50}
    params = np.stack([1000.0 * t, np.sin(t)], axis=1)  # 1 m/s and a smooth angle
    out, grid, resampled = uniform_clock(params, t, 25.0)
    assert resampled and np.allclose(np.diff(grid), 0.04) and grid[0] == t[0] and len(grid) == len(t)
    np.testing.assert_allclose(np.diff(out[:, 0]), 40.0, atol=1e-9)  # 40 mm per 40 ms frame
    np.testing.assert_allclose(out[:, 1], np.sin(grid), atol=2e-3)
    for n in range(2, 13):  # every tracked frame gives a BVH frame; the last may be held up to 1/120 s
        out, grid, _ = uniform_clock(params[:n], t[:n], 25.0)
        assert len(grid) == n and grid[-1] - t[n - 1] <= 0.5 / 60 + 1e-12
        if grid[-1] >= t[n - 1]:
            np.testing.assert_array_equal(out[-1], params[n - 1])  # held, not extrapolated
    even = np.arange(10) / 20
    same, _, again = uniform_clock(params[:10], even, 20.0)
    assert not again and same is not None and np.array_equal(same, params[:10])
    with pytest.raises(ConfigError, match="increasing"):
        uniform_clock(params[:3], np.array([0.0, 0.1, 0.1]), 20.0)


@pytest.mark.parametrize("model_name", ["balan31", "full45"])
def test_end_sites_neither_grow_the_figure_nor_go_through_the_floor(model_name: str, tmp_path: Path):
    """Rest pose (Y up, facing +Z): the head top's End Site points forward, level with it (it used to add
    70 mm above the head); balan31's ankles end the leg, and their End Sites are feet, forward and 30 degrees
    down, 0.4 x the shank (they used to continue the shank 100 mm straight down)."""
    model = load_model(model_name)
    clip = read_bvh(export_bvh(model, random_valid_poses(model, 2), 30.0, tmp_path / "m.bvh"))
    pos, ends = clip.rest_positions()
    head = clip.joint_names.index("head_top")
    assert ends[head, 1] == pytest.approx(pos[head, 1], abs=1e-6) and ends[head, 2] - pos[head, 2] >= 30.0
    assert np.nanmax(ends[:, 1]) <= pos[:, 1].max() + 1e-6  # nothing above the head top
    for side in ("l", "r"):
        ankle = clip.joint_names.index(f"{side}_ankle")
        if model_name == "balan31":
            shank = float(np.linalg.norm(clip.offsets[ankle]))
            foot = ends[ankle] - pos[ankle]
            np.testing.assert_allclose(foot, 0.4 * shank * np.array([0.0, -0.5, np.sqrt(3) / 2]), atol=1e-5)
        else:  # full45 has feet: the toe's End Site continues the foot
            assert np.isnan(ends[ankle]).all()
