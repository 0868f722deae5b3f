"""The observation body: closed outward meshes, follows the skeleton, is not the tracker's cone model."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.subject import subject_from_clip
from swarmpose.errors import ConfigError
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
