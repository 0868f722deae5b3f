"""``scripts/mirrored_clips.py``: a clip mirrored left for right is the reflection of the motion, and mirrored twice
it is the clip again."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from swarmpose.io.bvh import read_bvh
from swarmpose.io.mocap import infer_unit_scale


def test_a_mirrored_clip_is_the_reflection_of_its_other_side_and_twice_the_clip(mocap_dir: Path, tmp_path: Path,
                                                                                  load_script):
    m = load_script("mirrored_clips")
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
    names, off = m.reflection_offsets(src, once)
    hips = names.index("Hips")
    assert off[:, hips].max() < 0.01  # the root: its position reflected (to the print resolution)
    # the rest: each side keeps its own bones, a few mm from the other side's (the jog's subject: 7.5 mm median)
    assert np.median(off) < 15 and off.max() < 60
    # and far from the unreflected motion: the mirror changed something
    before, after = clip.global_positions(), read_bvh(once).global_positions()
    assert np.median(np.linalg.norm(after - before, axis=-1)) * infer_unit_scale(clip)[0] > 100
