"""``scripts/mirrored_clips.py``: a clip mirrored left for right is the reflection of the motion, and mirrored twice
it is the clip again."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from swarmpose.io.bvh import read_bvh
from swarmpose.io.mocap import infer_unit_scale


def _script():
    path = Path(__file__).parents[2] / "scripts" / "mirrored_clips.py"
    spec = importlib.util.spec_from_file_location("mirrored_clips", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_mirrored_clip_is_the_reflection_of_its_other_side_and_twice_the_clip(mocap_dir: Path, tmp_path: Path):
    m = _script()
    names = {"LeftArm", "RightArm", "LHipJoint", "RHipJoint", "lhand", "rhand", "lowerback", "Neck"}
    assert [m.other_side(n, names) for n in ("LeftArm", "RHipJoint", "lhand", "lowerback", "Neck")] == \
        ["RightArm", "LHipJoint", "rhand", "lowerback", "Neck"]
    src = mocap_dir / "cmu_16_35_jog.bvh"
    once, twice = tmp_path / "once.bvh", tmp_path / "twice.bvh"
    m.write_mirrored(src, once)
    m.write_mirrored(once, twice)
    clip, back = read_bvh(src), read_bvh(twice)
    np.testing.assert_allclose(back.motion, clip.motion, atol=1e-4)  # the files' four decimals
    assert [j.offset.tolist() for j in back.joints] == [j.offset.tolist() for j in clip.joints]
    names, before = m.world_joints(src)
    _, after = m.world_joints(once)
    twin = [names.index(m.other_side(n, set(names))) for n in names]
    off = np.linalg.norm(after - before[:, twin] * [-1.0, 1.0, 1.0], axis=-1) * infer_unit_scale(clip)[0]
    hips = names.index("Hips")
    assert off[:, hips].max() < 0.01  # the root: its position reflected (to the print resolution)
    # the rest: each side keeps its own bones, a few mm from the other side's (the jog's subject: 7.5 mm median)
    assert np.median(off) < 15 and off.max() < 60
    # and far from the unreflected motion: the mirror changed something
    assert np.median(np.linalg.norm(after - before, axis=-1)) * infer_unit_scale(clip)[0] > 100
