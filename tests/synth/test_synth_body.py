"""The observation body: closed outward meshes, follows the skeleton, is not the tracker's cone model."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.errors import ConfigError
from swarmpose.io.mocap import subject_from_clip
from swarmpose.synth.body import BodySettings, ObservationBody, capsule_template, sphere_template


@pytest.mark.parametrize("template", ["sphere", "capsule"])
def test_templates_closed_and_outward(template):
    if template == "sphere":
        v, f = sphere_template(9, 18)
        shape = v
    else:
        d, e, f = capsule_template(5, 18)
        shape = d + np.where(e[:, None] == 1, 1.0, -1.0) * np.array([0.0, 0.0, 1.0])
    # every undirected edge is shared by exactly two triangles, in opposite directions
    directed = Counter((int(a), int(b)) for tri in f for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])))
    assert all(c == 1 for c in directed.values())
    assert all((b, a) in directed for a, b in directed)
    # outward: positive enclosed volume (divergence theorem)
    v0, v1, v2 = shape[f[:, 0]], shape[f[:, 1]], shape[f[:, 2]]
    volume = np.einsum("fi,fi->f", v0, np.cross(v1, v2)).sum() / 6.0
    expected = 4 / 3 * np.pi if template == "sphere" else 4 / 3 * np.pi + 2 * np.pi
    assert volume == pytest.approx(expected, rel=0.1)


def test_shapes(walk_body: ObservationBody, walk_clip):
    b = walk_body
    v, n = b.mesh(10)
    assert v.shape == (b.n_vertices, 3) and n.shape == v.shape
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert b.faces.max() < b.n_vertices and b.faces.dtype == np.int32
    assert b.face_part.shape == (len(b.faces),) and b.vertex_part.shape == (b.n_vertices,)
    assert b.n_frames == walk_clip.frames
    with pytest.raises(IndexError):
        b.mesh(b.n_frames)


def test_follows_the_skeleton(walk_body: ObservationBody, walk_clip):
    """Points carried by joint rotations land on the clip's child joints (the rotation convention)."""
    parents = np.asarray(walk_clip.parents)
    child = np.arange(1, len(parents))
    for k in (0, 77, walk_clip.frames - 1):
        got = walk_body.carry(k, parents[child], walk_body.rest_positions[child] - walk_body.rest_positions[parents[child]])
        np.testing.assert_allclose(got, walk_clip.positions[k, child], atol=1e-6)


def test_has_the_parts_balan31_lacks(walk_body: ObservationBody):
    for name in ("pelvis", "abdomen", "chest", "neck", "head", "l_hand", "r_hand", "l_foot", "r_foot"):
        walk_body.part_index(name)
    with pytest.raises(KeyError, match="no part"):
        walk_body.part_index("tail")


def test_sizes_differ_from_the_tracker_cones(walk_clip, walk_body: ObservationBody):
    """Limb radii differ from balan31's (thesis variant, scaled to the same subject) by >= 5 %."""
    base = load_model("balan31")
    model = base.with_subject(subject_from_clip(base.spec, walk_clip))
    ca = model.cone_arrays
    pairs = {"l_thigh": "l_thigh", "l_calf": "l_calf", "l_upper_arm": "l_upper_arm", "l_lower_arm": "l_forearm"}
    for cone, part in pairs.items():
        r_cone = ca.radii[ca.index(cone)]
        r_body = walk_body.parts[walk_body.part_index(part)].radii
        rel = np.abs(r_body - r_cone) / r_cone
        assert rel.max() >= 0.05, (cone, r_cone, r_body)


def test_clothing_bulk(walk_clip):
    thin = ObservationBody.from_clip(walk_clip, BodySettings(clothing_mm=0.0))
    thick = ObservationBody.from_clip(walk_clip, BodySettings(clothing_mm=20.0))
    i = thin.part_index("l_thigh")
    np.testing.assert_allclose(thick.parts[i].radii - thin.parts[i].radii, 20.0)
    j = thin.part_index("head")  # skin: no clothing
    np.testing.assert_allclose(thick.parts[j].semi, thin.parts[j].semi)


def test_bad_settings():
    with pytest.raises(ConfigError, match="clothing_mm"):
        BodySettings(clothing_mm=-1.0)
    with pytest.raises(ConfigError, match="albedo"):
        BodySettings(albedo={"shirt": 0.5})


def test_measurements_match_the_geometry(walk_body: ObservationBody, walk_clip):
    """The lab measurements agree with the skeleton and with the rest-pose mesh they describe."""
    m = walk_body.measurements()
    # shoulder markers straight above the shoulder joints: their distance is the joints' distance
    from swarmpose.joints import JOINT_INDEX as J

    gt = walk_clip.joints
    sho = np.linalg.norm(gt[:, J["l_shoulder"]] - gt[:, J["r_shoulder"]], axis=1)
    assert m.shoulder_markers == pytest.approx(sho.mean(), abs=1.0)
    # rest-pose mesh: every joint at rest, no rotation
    rest = ObservationBody(list(walk_body.parts), walk_body.rest_positions[None],
                           np.broadcast_to(np.eye(3), (1, len(walk_body.rest_positions), 3, 3)),
                           walk_body.rest_positions, walk_body.settings, walk_body.scale)
    v, _ = rest.mesh(0)
    rp = walk_body.rest_positions
    sm = walk_clip.skeleton_map
    for side in ("l", "r"):
        knee, ankle, hip = (rp[sm.joint(f"{side}_{j}")] for j in ("knee", "ankle", "hip"))
        leg = [walk_body.part_index(f"{side}_thigh"), walk_body.part_index(f"{side}_calf")]
        pts = v[np.isin(rest.vertex_part, leg)]
        axis = (ankle - hip) / np.linalg.norm(ankle - hip)
        along = (pts - knee) @ axis
        near = pts[np.abs(along) < 30.0] - knee
        radial = np.linalg.norm(near - np.outer(near @ axis, axis), axis=1)
        assert getattr(m, f"{side}_knee_width") == pytest.approx(2 * radial.max(), rel=0.02)
    chest = v[rest.vertex_part == walk_body.part_index("chest")]
    fwd = np.array([0.0, -1.0, 0.0])  # CMU rest pose faces -y in world axes
    depth = (chest @ fwd).max() - (chest @ fwd).min()
    assert m.sternum_t10 == pytest.approx(depth + 14.0, rel=0.01)


def _winding_normals(body: ObservationBody, k: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """The vertex normals the renderer shades with, and the area-weighted normals of the triangles around
    each vertex taken along their winding (the side back-face culling treats as the front)."""
    v, n = body.mesh(k)
    f = body.faces.astype(np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    acc = np.zeros_like(v)
    for i in range(3):
        np.add.at(acc, f[:, i], fn)
    return n, acc / np.linalg.norm(acc, axis=1, keepdims=True)


def test_every_part_is_wound_outwards_with_surface_normals(walk_body: ObservationBody):
    """Every part's triangles wind counter-clockwise seen from outside, as the rasteriser's back-face culling
    assumes, and the shading normals are the surface's. The head's axes frame was mirrored (det -1) until
    stop 27: its triangles faced inwards and the images showed the inside of the back of the head (the neck
    through the face), 0.15 % of the walk's pixels; a normal scaled by the semi-axes instead of divided by
    them left every test passing."""
    n, winding = _winding_normals(walk_body)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    cos = np.einsum("vi,vi->v", winding, n)
    for i, part in enumerate(walk_body.parts):
        c = cos[walk_body.vertex_part == i]
        assert c.mean() > 0.995 and c.min() > 0.99, (part.name, float(c.mean()), float(c.min()))
    assert all(np.linalg.det(p.axes) > 0 for p in walk_body.parts if p.kind == "ellipsoid")
