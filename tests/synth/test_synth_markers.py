"""2D marker detections: z-buffer occlusion, drop-out and false-detection rates (Sharifi et al. 4.1)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError
from swarmpose.joints import JOINT_INDEX
from swarmpose.synth.markers import (
    MarkerSettings,
    MarkerStats,
    detect_markers,
    marker_points,
    marker_visibility,
    own_part_table,
)
from swarmpose.synth.raster import project_vertices, rasterize


def _render(body, k, cams):
    v, _ = body.mesh(k)
    uv, z = project_vertices(v, cams)
    return rasterize(uv, z, np.zeros(len(v)), body.faces, body.face_part, cams[0].height, cams[0].width)


def _visibility(body, clip, k, cams, names, occlusion=True):
    ras = _render(body, k, cams)
    pts = marker_points(clip, names)[k]
    uv = np.stack([c.project(pts) for c in cams])
    z = np.stack([c.project_with_depth(pts)[1] for c in cams])
    return marker_visibility(uv, z, ras.depth, ras.part, own_part_table(names, body.part_names),
                             occlusion=occlusion), uv, ras


def test_wrist_behind_the_torso_is_not_detected(walk_clip, walk_body):
    """Constructed case: a camera on the line through the left wrist and the pelvis/torso centre."""
    k = 40
    names = MarkerSettings().names
    wrist = walk_clip.joints[k, JOINT_INDEX["l_wrist"]]
    pelvis = walk_body.parts[walk_body.part_index("pelvis")]
    torso = walk_body.carry(k, np.array([pelvis.joint]), (pelvis.centre - walk_body.rest_positions[pelvis.joint])[None])[0]
    d = torso - wrist
    d /= np.linalg.norm(d)  # the line of sight from 'behind' to the wrist passes the torso's centre
    behind = Camera.look_at("behind", eye=torso + 3000.0 * d, target=torso, f=900.0)  # torso between
    front = Camera.look_at("front", eye=wrist - 3000.0 * d, target=wrist, f=900.0)  # wrist side
    vis, uv, ras = _visibility(walk_body, walk_clip, k, [behind, front], names)
    w = names.index("l_wrist")
    # the wrist projects onto the body in the 'behind' view, and a torso part is in front of it
    row, col = np.rint(uv[0, w, ::-1]).astype(int)
    assert ras.part[0, row, col] in {walk_body.part_index(p) for p in ("pelvis", "abdomen", "chest")}
    assert not vis[0, w]
    assert vis[1, w]
    # ... and with occlusion off it would be "seen"
    vis_all, _, _ = _visibility(walk_body, walk_clip, k, [behind, front], names, occlusion=False)
    assert vis_all[0, w]
    # the detector never reports it there (no drop-out, no false detections, no noise)
    s = MarkerSettings(dropout=0.0, false_per_view=0.0, noise_px=0.0)
    pos, ids = detect_markers(uv, vis, np.full((2, 4), np.nan), (644, 484), s, np.random.default_rng(0))
    assert w not in ids[0] and w in ids[1]
    np.testing.assert_allclose(pos[1][list(ids[1]).index(w)], uv[1, w])


def test_joints_are_seen_in_some_view(walk_clip, walk_body, walk_rig):
    """Every joint marker sits inside its own parts, so some camera sees it."""
    names = MarkerSettings(markers="extended").names
    for k in (0, 100, 200):
        vis, _, _ = _visibility(walk_body, walk_clip, k, walk_rig, names)
        assert vis.any(axis=0).all(), [n for n, v in zip(names, vis.any(axis=0), strict=True) if not v]
        assert vis.mean() > 0.75


def test_rates_over_the_clip_match_the_settings(walk_clip, walk_body, walk_rig):
    """Realised drop-out and false-detection rates over the whole clip are within 10 % of the settings."""
    s = MarkerSettings(dropout=0.05, false_per_view=0.5, noise_px=1.0)
    names = s.names
    own = own_part_table(names, walk_body.part_names)
    pts = marker_points(walk_clip, names)
    rng = np.random.default_rng(11)
    stats = MarkerStats()
    for k in range(walk_clip.frames):
        ras = _render(walk_body, k, walk_rig)
        uv = np.empty((4, len(names), 2))
        z = np.empty((4, len(names)))
        for c, cam in enumerate(walk_rig):
            uv[c], z[c] = cam.project_with_depth(pts[k])
        vis = marker_visibility(uv, z, ras.depth, ras.part, own)
        pos, ids = detect_markers(uv, vis, np.full((4, 4), np.nan), (644, 484), s, rng, stats)
        for c in range(4):
            true = ids[c] >= 0
            err = np.linalg.norm(pos[c][true] - uv[c, ids[c][true]], axis=1)
            assert err.max(initial=0.0) < 6.0  # 1 px noise
    assert stats.view_frames == 4 * walk_clip.frames
    assert abs(stats.dropout_rate - 0.05) <= 0.1 * 0.05, stats.to_dict()
    assert abs(stats.false_per_view - 0.5) <= 0.1 * 0.5, stats.to_dict()
    assert 0.75 < stats.visible_fraction < 0.99  # some self-occlusion, not much


def test_false_detections_fall_near_the_body():
    s = MarkerSettings(dropout=0.0, false_per_view=30.0, false_margin_px=10.0)
    uv = np.zeros((1, 0, 2))
    pos, ids = detect_markers(uv, np.zeros((1, 0), bool), np.array([[100.0, 50.0, 200.0, 250.0]]), (644, 484), s,
                              np.random.default_rng(1))
    assert np.all(ids[0] == -1) and len(pos[0]) > 10
    assert np.all(pos[0] >= [90.0, 40.0]) and np.all(pos[0] <= [210.0, 260.0])


def test_bad_settings():
    with pytest.raises(ConfigError, match="dropout"):
        MarkerSettings(dropout=1.5)
    with pytest.raises(ConfigError, match="markers"):
        MarkerSettings(markers="all")
    with pytest.raises(ConfigError, match="false_region"):
        MarkerSettings(false_region="sky")


def _detect(uv, settings, seed=0, boxes=None):
    from swarmpose.synth.markers import detect_markers

    C = uv.shape[0]
    boxes = np.full((C, 4), np.nan) if boxes is None else boxes
    return detect_markers(uv, np.ones(uv.shape[:2], bool), boxes, (644, 484), settings, np.random.default_rng(seed))


def test_marker_noise_reaches_the_chosen_fraction():
    """(markers.py:275 `u < noise_fraction` -> `>`): with the default fraction 1 no detection got noise,
    and the clip test only bounds the error from above."""
    from swarmpose.synth.markers import MarkerSettings

    uv = np.random.default_rng(0).uniform([50, 50], [590, 430], (1, 2000, 2))
    for frac in (1.0, 0.3):
        pos, ids = _detect(uv, MarkerSettings(dropout=0.0, false_per_view=0.0, noise_px=2.0, noise_fraction=frac))
        err = pos[0] - uv[0, ids[0]]
        moved = np.any(err != 0.0, axis=1)
        assert moved.mean() == pytest.approx(frac, abs=0.04)
        assert err[moved].std() == pytest.approx(2.0, rel=0.08)


def test_false_detections_fill_the_grown_box():
    """(markers.py:282 `box_max + margin` -> `box_max - margin`): the existing test checks containment
    only, which a smaller box passes. The false detections cover the whole grown box."""
    from swarmpose.synth.markers import MarkerSettings

    s = MarkerSettings(dropout=0.0, false_per_view=3000.0, false_margin_px=10.0)
    pos, ids = _detect(np.zeros((1, 0, 2)), s, seed=1, boxes=np.array([[100.0, 50.0, 200.0, 250.0]]))
    p = pos[0]
    assert np.all(p >= [90.0, 40.0]) and np.all(p <= [210.0, 260.0])
    np.testing.assert_allclose(p.min(axis=0), [90.0, 40.0], atol=1.0)
    np.testing.assert_allclose(p.max(axis=0), [210.0, 260.0], atol=1.0)


def test_noisy_detections_stay_inside_the_image():
    """(markers.py:284 clipping to the image removed): markers on the image border plus noise."""
    from swarmpose.synth.markers import MarkerSettings

    uv = np.array([[[0.0, 0.0], [643.0, 483.0], [0.0, 483.0], [643.0, 0.0]] * 50])
    pos, _ = _detect(uv, MarkerSettings(dropout=0.0, false_per_view=0.0, noise_px=3.0))
    assert np.all(pos[0] >= 0.0) and np.all(pos[0] <= [643.0, 483.0])
