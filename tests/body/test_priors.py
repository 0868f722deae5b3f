"""Hard priors: joint limits and inter-penetration (thesis sec. 5.3.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.body.priors import HardPriors
from swarmpose.errors import ConfigError


@pytest.fixture(scope="module")
def model():
    return load_model("balan31")


@pytest.fixture(scope="module")
def priors(model):
    return HardPriors(model)


def pose(model, **deg):
    x = model.zero_pose()
    x[model.param_index("pelvis_tz")] = 1000.0
    for name, v in deg.items():
        x[model.param_index(name)] = np.radians(v)
    return x


def test_standing_and_walking_poses_are_valid(model, priors):
    walk = pose(model, l_hip_flex=30, r_hip_flex=-20, l_knee_flex=40, r_knee_flex=10,
                l_shoulder_flex=-20, r_shoulder_flex=20, l_elbow_flex=20, r_elbow_flex=30)
    assert priors.valid(np.stack([pose(model), walk])).all()


def test_crossing_legs_are_rejected(model, priors):
    crossed = pose(model, l_hip_abd=-30, r_hip_abd=-30)
    assert not priors.valid(crossed)[0]
    assert any("thigh" in r for r in priors.describe(crossed))


def test_arm_through_the_torso_is_rejected(model, priors):
    # forearm swung into the trunk by adduction past the body's side
    through = pose(model, l_shoulder_abd=-40)
    assert not priors.valid(through)[0]
    assert priors.describe(through) == ["l_lower_arm penetrates torso"]
    # forearm folded across the belly with the elbow behind the trunk's front surface
    folded = pose(model, r_shoulder_rot=80, r_elbow_flex=90)
    assert "r_lower_arm penetrates torso" in priors.describe(folded)
    # the same arm raised forward is fine
    assert priors.valid(pose(model, l_shoulder_flex=90))[0]


def test_joint_limits(model, priors):
    knee_backwards = pose(model, l_knee_flex=-30)
    assert not priors.valid(knee_backwards)[0]
    assert priors.describe(knee_backwards)[0].startswith("l_knee_flex = -30.0 outside")
    # the heading is unbounded: any turn is fine
    assert priors.valid(pose(model, pelvis_rz=1000.0))[0]


def test_batched_result_matches_single(model, priors):
    rng = np.random.default_rng(0)
    poses = pose(model) + rng.normal(scale=0.4, size=(64, model.n_params)) * model.is_rotation
    batched = priors.valid(poses)
    single = np.array([priors.valid(p)[0] for p in poses])
    assert np.array_equal(batched, single)
    assert 0 < batched.sum() < len(poses)  # the sample holds both kinds


def test_checks_can_be_switched_off(model):
    crossed = pose(model, l_hip_abd=-30, r_hip_abd=-30)
    assert HardPriors(model, check_collisions=False).valid(crossed)[0]
    with pytest.raises(ConfigError):
        HardPriors(model, penetration_tolerance=1.0)


def test_numba_collisions_match_the_numpy_reference(model, priors):
    rng = np.random.default_rng(1)
    poses = pose(model) + rng.normal(scale=0.6, size=(400, model.n_params)) * model.is_rotation
    fast = priors.collisions(poses)
    ref = priors.collisions_reference(poses)
    assert np.array_equal(fast, ref)
    assert fast.any() and not fast.all()


@pytest.fixture(scope="module")
def tilted_model(walk_clip_path):
    """The walk's subject: its torso leans back from the pelvis to the shoulders (axis not along z)."""
    from swarmpose.io.mocap import load_clip, subject_from_clip

    base = load_model("balan31")
    model = base.with_subject(subject_from_clip(base.spec, load_clip(walk_clip_path, fps=30)))
    t = model.cone_arrays.names.index("torso")
    tilt = model.cone_arrays.end[t, :2] - model.cone_arrays.start[t, :2]
    assert np.hypot(*tilt) > 15.0  # mm off the frame's z axis at the top
    return model


def _inside_by_linear_solve(priors, poses):
    """Independent oracle: solve ``d = s * axis + u * e_x + v * e_y`` for every sphere of B."""
    model = priors.model
    cones = model.cones(poses)
    ca = model.cone_arrays
    keep = 1.0 - priors.penetration_tolerance
    f = priors._frac
    out = np.zeros((len(poses), len(model.spec.collision_pairs)), dtype=bool)
    for i, (na, nb) in enumerate(model.spec.collision_pairs):
        a, b = ca.names.index(na), ca.names.index(nb)
        for n in range(len(poses)):
            basis = np.column_stack([cones.end[n, a] - cones.start[n, a], cones.axis_x[n, a], cones.axis_y[n, a]])
            for fm in f:
                rb = 0.5 * (cones.semi_x[b] + cones.semi_y[b])
                rho = rb[0] + (rb[1] - rb[0]) * fm
                centre = cones.start[n, b] + fm * (cones.end[n, b] - cones.start[n, b])
                s, u, v = np.linalg.solve(basis, centre - cones.start[n, a])
                if not 0.0 <= s <= 1.0:
                    continue
                semi_x = cones.semi_x[a, 0] + (cones.semi_x[a, 1] - cones.semi_x[a, 0]) * s
                semi_y = cones.semi_y[a, 0] + (cones.semi_y[a, 1] - cones.semi_y[a, 0]) * s
                if (u / (keep * (semi_x + rho))) ** 2 + (v / (keep * (semi_y + rho))) ** 2 < 1.0:
                    out[n, i] = True
                    break
    return out


def test_collision_volume_follows_a_tilted_torso_axis(tilted_model):
    """Cross-sections are centred on the leaning axis, as the renderer draws the cone: the test agrees
    with a linear-solve oracle, also for forearms near the torso's top (where the lean is largest)."""
    priors = HardPriors(tilted_model)
    rng = np.random.default_rng(4)
    x0 = tilted_model.zero_pose()
    x0[tilted_model.param_index("pelvis_tz")] = 1000.0
    arms = [tilted_model.param_index(n) for n in tilted_model.param_names if "shoulder" in n or "elbow" in n]
    poses = np.repeat(x0[None], 300, axis=0)
    poses[:, arms] += rng.normal(scale=1.0, size=(300, len(arms)))
    expected = _inside_by_linear_solve(priors, poses)
    assert np.array_equal(priors.collisions_reference(poses), expected)
    assert np.array_equal(priors.collisions(poses), expected)
    forearm_hits = expected[:, :2]
    assert forearm_hits.any() and not forearm_hits.all()


def test_a_collision_cone_lying_in_its_frames_xy_plane_is_refused(tmp_path):
    """Its cross-sections lie in that plane too, so they would not span a volume to test against."""
    import json
    from importlib import resources

    from swarmpose.body.model import BodyModel
    from swarmpose.body.spec import load_spec

    spec = json.loads((resources.files("swarmpose.models") / "balan31.json").read_text())
    spec["default_subject"]["offsets"]["pelvis_to_torso_top"] = [0.0, 300.0, 0.0]  # sideways, flat
    path = tmp_path / "flat.json"
    path.write_text(json.dumps(spec))
    flat = BodyModel(load_spec(path), None, "thesis")
    with pytest.raises(ConfigError, match="collision cone 'torso' lies in its joint frame's x-y plane"):
        HardPriors(flat)


def test_joint_limits_are_inclusive():
    """(model.py:178 `p <= upper` -> `p < upper`). Optimisers clip particles onto the bounds; a pose
    exactly on a limit must stay valid."""
    m = load_model("balan31")
    for bound in (m.lower, m.upper):
        x = np.where(np.isfinite(bound), bound, 0.0)
        assert m.within_limits(x).all()
        assert HardPriors(m, check_collisions=False).valid(x).all()
    outside = np.where(np.isfinite(m.upper), m.upper + 1e-9, 0.0)
    assert not m.within_limits(outside).any()


@pytest.mark.parametrize("tol", [0.0, 0.25, 0.8])
def test_numba_collisions_match_the_reference_at_any_tolerance(tol):
    """(priors.py:88 keep = `1 - tol` -> `tol`): the existing comparison runs only at the default 0.5,
    where both are 0.5."""
    m = load_model("balan31")
    priors = HardPriors(m, penetration_tolerance=tol)
    rng = np.random.default_rng(1)
    x0 = m.zero_pose()
    x0[m.param_index("pelvis_tz")] = 1000.0
    poses = x0 + rng.normal(scale=0.6, size=(400, m.n_params)) * m.is_rotation
    fast = priors.collisions(poses)
    assert np.array_equal(fast, priors.collisions_reference(poses))
    assert fast.any() and not fast.all()


@pytest.mark.parametrize("spec", ["balan31", "full45"])
@pytest.mark.parametrize("limits, collisions, coupled", [(True, True, False), (False, True, False),
                                                         (True, False, False), (True, True, True)])
def test_the_fused_check_agrees_with_the_plain_one(spec, limits, collisions, coupled):
    """valid (one numba pass: limits, kinematics, collisions) against valid_reference (numpy limits, then the
    collision kernel on batched kinematics), on poses spread a little past the limits, so that both answers occur."""
    m = load_model(spec)
    pr = HardPriors(m, check_limits=limits, check_collisions=collisions, coupled_limits=coupled)
    rng = np.random.default_rng(5)
    x = np.tile(m.zero_pose(), (3000, 1))
    x[:, m.param_index("pelvis_tz")] = 1000.0
    bounded = np.isfinite(m.lower) & np.isfinite(m.upper)
    span = np.where(bounded, np.where(bounded, m.upper, 0.0) - np.where(bounded, m.lower, 0.0), 2 * np.pi)
    mid = np.where(bounded, 0.5 * (np.where(bounded, m.upper, 0.0) + np.where(bounded, m.lower, 0.0)), 0.0)
    rot = np.asarray(m.is_rotation)
    wide = np.where(np.arange(3000) % 3 == 0, 1.2, 0.8)[:, None]  # a third may leave the limits
    x[:, rot] = mid[rot] + (rng.random((3000, rot.sum())) - 0.5) * wide * span[rot]
    x[::97, 7] = np.nan  # a NaN parameter breaks the limits
    got, want = pr.valid(x), pr.valid_reference(x)
    assert np.array_equal(got, want)
    assert 0.05 < got.mean() < 0.95  # both answers are exercised


def test_segment_distance_is_the_closest_approach():
    """The early rejection of a collision pair reads the distance between the two cones' axes: against the
    minimum over a fine grid of both segments' points, including parallel, crossing and point-like segments."""
    from swarmpose.body.priors import segment_distance2

    rng = np.random.default_rng(3)
    cases = [rng.normal(0, 100, 12) for _ in range(200)]
    p = rng.normal(0, 100, 3)
    d = rng.normal(0, 100, 3)
    cases += [np.r_[p, p + d, p + [0, 0, 30], p + d + [0, 0, 30]],  # parallel
              np.r_[p, p + d, p + d, p + 2 * d],  # touching end to end, collinear
              np.r_[p, p, p + d, p + d],  # both point-like
              np.r_[p, p, p - d, p + d]]  # a point on the other segment
    g = np.linspace(0.0, 1.0, 401)
    for c in cases:
        a, b, r, t = c[:3], c[3:6], c[6:9], c[9:]
        pa = a + g[:, None] * (b - a)
        pb = r + g[:, None] * (t - r)
        grid = np.sqrt(((pa[:, None] - pb[None]) ** 2).sum(-1).min())
        exact = np.sqrt(segment_distance2(*a, *b, *r, *t))
        assert exact <= grid + 1e-9
        assert grid - exact <= 0.01 * (np.linalg.norm(b - a) + np.linalg.norm(t - r)) + 1e-9


def test_the_shoulders_second_branch_is_out_with_the_coupled_limits(model):
    """Abduction and flexion both past 90 deg (each inside its own limits) is out only with ``coupled_limits``; either
    alone past 90 is in. Such a pose is the same upper arm as one of the first branch twisted 180 deg about it (the
    angles' other solution), a twist the rotation's +-90 deg limits leave out there."""
    on = HardPriors(model, coupled_limits=True)
    off = HardPriors(model)
    for side in ("l", "r"):
        abd, flex, rot = f"{side}_shoulder_abd", f"{side}_shoulder_flex", f"{side}_shoulder_rot"
        both = pose(model, **{abd: 178, flex: 166, rot: 10})
        ok = np.stack([pose(model, **{abd: 170}), pose(model, **{flex: 170}), pose(model, **{abd: 90, flex: 170}),
                       pose(model, **{abd: 95, flex: 60})])
        assert not on.valid(both[None])[0] and off.valid(both[None])[0]
        assert on.valid(ok).all() and off.valid(ok).all()
        assert not on.valid_reference(both[None])[0]
        # the other branch's twin: the same upper arm, its twist 160 deg from the pose's, outside the rotation limits
        twin = pose(model, **{abd: 178 - 180, flex: 180 - 166, rot: 10 - 180})
        j = model.joints15(np.stack([both, twin]))
        assert np.allclose(j[0], j[1], atol=1e-6)
        assert not model.within_limits(twin[None])[0]


def test_the_spec_refuses_a_bad_coupled_limit(tmp_path):
    import json

    from swarmpose.body.spec import load_spec
    from swarmpose.errors import FormatError

    src = json.loads((Path(__file__).resolve().parents[2] / "src/swarmpose/models/balan31.json").read_text())
    for entry, field in (({"parameters": ["l_shoulder_abd", "nose"], "above": [90, 90]}, "coupled_limits[0]"),
                         ({"parameters": ["l_shoulder_abd", "l_shoulder_flex"], "above": [90, 200]}, "coupled_limits[0]"),
                         ({"parameters": ["l_shoulder_abd"], "above": [90]}, "coupled_limits[0]"),
                         ({"parameters": ["l_shoulder_abd", "l_shoulder_flex"]}, "coupled_limits[0].above")):
        bad = dict(src, coupled_limits=[entry])
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(FormatError) as err:
            load_spec(path)
        assert field in str(err.value) and "bad.json" in str(err.value)
