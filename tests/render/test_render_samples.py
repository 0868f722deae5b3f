"""Edge sample points (thesis sec. 5.2.1, Fig. 5.3) and cone subsets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError
from swarmpose.render import EDGE_CONE_SETS, edge_cone_mask, edge_samples, project_cones
from swarmpose.render.reference import reference_geometry, region_samples_reference


def _line_distance(pts: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    d = q - p
    return np.abs(d[0] * (pts[:, 1] - p[1]) - d[1] * (pts[:, 0] - p[0])) / np.hypot(*d)


def test_cone_sets(model):
    names = model.cone_arrays.names
    assert set(EDGE_CONE_SETS) == {"all", "torso", "torso+upper"}
    all_ = edge_cone_mask(names, "all")
    assert all_.sum() == len(names) - 1 and not all_[names.index("head")]
    assert [names[i] for i in np.flatnonzero(edge_cone_mask(names, "torso"))] == ["torso"]
    upper = {names[i] for i in np.flatnonzero(edge_cone_mask(names, "torso+upper"))}
    assert upper == {"torso", "l_thigh", "r_thigh", "l_upper_arm", "r_upper_arm"}
    np.testing.assert_array_equal(edge_cone_mask(names, "torso+upper_limbs"), edge_cone_mask(names, "torso+upper"))
    assert edge_cone_mask(names, ["l_calf", "head"]).sum() == 1  # the head is never edge-sampled
    with pytest.raises(ConfigError, match="torso"):
        edge_cone_mask(names, "legs")
    with pytest.raises(ConfigError, match="model cones"):
        edge_cone_mask(names, ["tail"])


def test_samples_on_silhouette_lines(model, rig, base_pose):
    spacing = 6.0
    es = edge_samples(model, base_pose, rig, cones="all", top_edge=False, spacing=spacing)
    pc = project_cones(model, base_pose, rig)
    for c in range(len(rig)):
        sel = es.cone[0, c] >= 0
        for k in np.unique(es.cone[0, c, sel]):
            pts = es.points[0, c][es.cone[0, c] == k]
            expected = 0
            for side in range(2):
                p, q = pc.sides[0, c, k, side]
                L = float(np.hypot(*(q - p)))
                expected += max(1, math.floor(L / spacing + 0.5))
            d = np.min([_line_distance(pts, *pc.sides[0, c, k, s]) for s in range(2)], axis=0)
            assert d.max() < 1e-9
            assert len(pts) == expected
    assert not np.isin(es.cone[0], [model.cone_arrays.names.index("head")]).any()


def test_top_edge(model, rig, base_pose):
    names = model.cone_arrays.names
    t = names.index("torso")
    with_top = edge_samples(model, base_pose, rig, cones="torso", top_edge=True)
    without = edge_samples(model, base_pose, rig, cones="torso", top_edge=False)
    n_with = (with_top.cone[0] == t).sum(axis=1)
    n_without = (without.cone[0] == t).sum(axis=1)
    assert (n_with > n_without).all()
    # the upper edge lies above (smaller v than) the torso's lower end
    pc = project_cones(model, base_pose, rig)
    for c in range(len(rig)):
        extra = with_top.points[0, c, n_without[c]:n_with[c]]
        assert extra[:, 1].max() < pc.axis[0, c, t, 0, 1]
    # no torso selected: no top edge either
    legs = edge_samples(model, base_pose, rig, cones=["l_thigh"], top_edge=True)
    assert not (legs.cone == t).any()


def test_occlusion_side_view(model):
    """Seen from the subject's left, the right arm hangs behind the torso: its samples are hidden; the
    left arm in front stays visible."""
    pose = model.zero_pose()
    pose[5] = 1000.0
    cam = Camera.look_at("left", eye=(0.0, 4000.0, 1200.0), target=(0.0, 0.0, 1100.0))
    es = edge_samples(model, pose, [cam], cones="all")
    names = model.cone_arrays.names
    vis = {}
    for name in ("l_upper_arm", "r_upper_arm", "r_lower_arm"):
        sel = es.cone[0, 0] == names.index(name)
        assert sel.any()
        vis[name] = es.visible[0, 0, sel].mean()
    assert vis["l_upper_arm"] > 0.9
    assert vis["r_upper_arm"] < 0.2 and vis["r_lower_arm"] < 0.5
    # every hidden sample lies inside the footprint of another cone whose axis is nearer
    geom = reference_geometry(model, pose, [cam])
    from swarmpose.render.reference import point_in_convex

    for i in np.flatnonzero((es.cone[0, 0] >= 0) & ~es.visible[0, 0]):
        x, y = es.points[0, 0, i]
        k = es.cone[0, 0, i]
        assert any(point_in_convex(h, np.array([x]), np.array([y]))[0]
                   and geom.cones.axis_depth[0, 0, j].min() < es.depth[0, 0, i]
                   for j, h in enumerate(geom.hulls[0][0]) if j != k and h is not None)


def test_region_samples_inside_cones(model, rig, base_pose):
    geom = reference_geometry(model, base_pose, rig)
    from swarmpose.render.reference import point_in_convex

    pts = region_samples_reference(geom, 0, 0, spacing=8.0)
    assert len(pts) > 50
    inside_any = np.zeros(len(pts), bool)
    for hull in geom.hulls[0][0]:
        if hull is not None:
            inside_any |= point_in_convex(hull, pts[:, 0], pts[:, 1])
    assert inside_any.all()


def test_exception(model, rig, base_pose):
    with pytest.raises(ConfigError):
        edge_samples(model, base_pose, rig, spacing=0.0)
