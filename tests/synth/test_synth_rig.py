"""The HumanEva-like default rig keeps every clip's motion in view."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.camera import load_rig, save_rig
from swarmpose.errors import ConfigError
from swarmpose.io.mocap import load_clip
from swarmpose.synth.rig import RigSettings, default_rig


def _check_rig(cams, clip):
    assert [c.name for c in cams] == ["BW1", "BW2", "BW3", "BW4"]
    for c in cams:
        assert (c.width, c.height) == (644, 484)
        assert 2000.0 <= c.center[2] <= 2500.0
        assert -0.1 <= c.dist[0] <= -0.07 and c.dist[1:] == (0.0, 0.0, 0.0, 0.0)
        assert 380.0 <= c.fx <= 1200.0
        pts = np.concatenate([clip.positions.reshape(-1, 3), clip.end_sites[~np.isnan(clip.end_sites[..., 0])]])
        uv, z = c.project_with_depth(pts)
        assert np.all(z > 1000.0)
        margin = 0.06 * np.array([c.width, c.height]) / 2 - 3.0
        assert np.all(uv >= margin - 0.5) and np.all(uv <= np.array([c.width, c.height]) - 0.5 - margin), c.name


def test_walk_rig_keeps_the_person_in_view(walk_clip, walk_rig):
    _check_rig(walk_rig, walk_clip)
    # the person is reasonably large: median ankle-to-head height >= 120 px in every view
    for c in walk_rig:
        v = c.project(walk_clip.joints)[..., 1]
        assert np.median(v.max(axis=1) - v.min(axis=1)) >= 120.0


@pytest.mark.parametrize("name", ["cmu_49_17_dance", "cmu_16_35_jog"])
def test_other_clips(mocap_dir, name):
    clip = load_clip(mocap_dir / f"{name}.bvh", fps=30)
    _check_rig(default_rig(clip), clip)


def test_rig_json_round_trip(walk_rig, tmp_path):
    save_rig(tmp_path / "rig.json", walk_rig)
    assert load_rig(tmp_path / "rig.json") == walk_rig


def test_points_input_and_settings():
    pts = np.random.default_rng(0).uniform([-1000, -500, 0], [1000, 500, 1800], (200, 3))
    cams = default_rig(pts, RigSettings(heights_mm=(2200.0, 2300.0), k1=(-0.05, -0.05),
                                        principal_offset_px=((0.0, 0.0), (0.0, 0.0))))
    assert len(cams) == 2
    with pytest.raises(ConfigError, match="need 2 entries"):
        RigSettings(heights_mm=(2200.0, 2300.0))
