"""A batch that moves few cones (a limb's search): the staying cones measured once, the measurements the same to
the last bit as every pose measured in full (swarmpose.fitness._numba_partial)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.fitness.backends import NumbaBackend, Request, parameter_cones

FIELDS = ("overlap", "projected", "edge_sum", "edge_sq", "edge_count", "region_sq", "region_count")


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in FIELDS)


def _group_batch(model, base: np.ndarray, group: str, n: int, spread: float, rng) -> np.ndarray:
    """``n`` poses that differ from ``base`` (the first) only in ``group``'s parameters, drawn over
    ``spread`` sigmas and clipped to the joint limits."""
    idx = np.asarray(model.group(group))
    poses = np.repeat(base[None], n, axis=0)
    poses[1:, idx] += rng.normal(0.0, spread, (n - 1, idx.size)) * model.sigma[idx]
    poses[:, idx] = np.clip(poses[:, idx], model.lower[idx], model.upper[idx])
    return poses


def _request(edge_mask=None, top=0, **kw) -> Request:
    return Request(edge_mask=np.ones(10, bool) if edge_mask is None else edge_mask, top_cone=top, **kw)


def test_parameter_cones_follow_the_tree(model):
    """A limb's parameters move its two cones, the head's the head; the root's every cone."""
    from swarmpose.render.project import cone_tables

    names = cone_tables(model).names
    moves = parameter_cones(model.kin, cone_tables(model).joint, model.n_params)
    moved = {g: {names[k] for d in model.group(g) for k in np.flatnonzero(moves[d])} for g in model.groups}
    assert moved["left_arm"] == {"l_upper_arm", "l_lower_arm"}
    assert moved["right_leg"] == {"r_thigh", "r_calf"}
    assert moved["head"] == {"head"}
    assert moved["spine"] == {"head", "l_upper_arm", "l_lower_arm", "r_upper_arm", "r_lower_arm"}
    assert moved["root"] == set(names)


@pytest.mark.parametrize("group", ["left_arm", "right_arm", "left_leg", "right_leg", "head", "spine"])
@pytest.mark.parametrize("spread", [1.0, 12.0])
def test_limb_batches_equal_the_full_measurement(model, scene, true_pose, group, spread):
    """Poses around the scene's pose (arms beside the torso: lines cross, cones hide each other's samples) and
    spread over the joint limits (limbs in front of and behind the body, partly outside the image): counts and
    edge sums equal the full kernel's to the last bit, every item through the moving-cones path."""
    rng = np.random.default_rng([len(group), int(spread), ord(group[0])])
    fast, full = NumbaBackend(model), NumbaBackend(model, moving=False)
    prepared = fast.prepare(scene)
    base = true_pose + rng.normal(0.0, 0.5, model.n_params) * model.sigma
    poses = _group_batch(model, base, group, 60, spread, rng)
    for request in (_request(), _request(top=-1, silhouette=False), _request(edge=False),
                    _request(edge_mask=np.arange(10) % 2 == 0, top=5, edge_spacing=3.0)):
        a = fast.measure(prepared, poses, request)
        assert fast.last_full_items == 0
        assert _same(a, full.measure(prepared, poses, request))


@pytest.mark.parametrize("threads", ["pool", "serial"])
def test_walk_frames_equal_the_full_measurement(walk, threads):
    """On synthesised walk frames, a limb search's batches around the IK pose (every limb, the top arc's cone
    staying and moving) equal the full kernel's measurements to the last bit."""
    rng = np.random.default_rng(3)
    model = walk.model
    fast, full = NumbaBackend(model, threads=threads), NumbaBackend(model, moving=False, threads=threads)
    for f in (0, 3):
        prepared = fast.prepare(walk.frames[f])
        for group, top in (("left_arm", 0), ("right_arm", 7), ("left_leg", 0), ("right_leg", 1)):
            poses = _group_batch(model, walk.ik[f], group, 40, 6.0, rng)
            request = _request(top=top)
            a = fast.measure(prepared, poses, request)
            assert fast.last_full_items == 0
            assert _same(a, full.measure(prepared, poses, request))


def test_a_staying_cone_that_moves_is_measured_in_full(model, scene, true_pose):
    """Told that only the left arm moves while some poses also move the right arm, the kernel measures those
    poses in full (and counts them): the measurements stay exact."""
    rng = np.random.default_rng(7)
    fast, full = NumbaBackend(model), NumbaBackend(model, moving=False)
    prepared = fast.prepare(scene)
    poses = _group_batch(model, true_pose, "left_arm", 30, 3.0, rng)
    right = np.asarray(model.group("right_arm"))
    poses[10:20, right] += 0.2
    request = _request()
    moving = np.zeros(10, bool)
    moving[fast._moves[np.asarray(model.group("left_arm"))].any(axis=0)] = True
    p = np.ascontiguousarray(poses)
    counts, sums = np.empty((30, 4, 2), np.int64), np.empty((30, 4, 5))
    args = (p, *model.kin.as_tuple(), *fast.cones.as_tuple(), prepared.R, prepared.t, prepared.cam, fast._ctab,
            fast._stab, fast.near, prepared.prefix, prepared.silhouettes, prepared.edges, request.edge_mask, 0,
            5.0, 8.0, True, True, False)
    joints = np.empty((30, 15, 3))
    fast._measure_moving(prepared, p, request, moving, args, 1, fast._j15, joints, counts, sums)
    assert fast.last_full_items == 10 * 4  # the ten poses, in every view
    assert np.array_equal(joints, model.joints15(poses))  # those measured in full and the others alike
    ref = full.measure(prepared, poses, request)
    assert np.array_equal(counts[..., 0], ref.overlap) and np.array_equal(counts[..., 1], ref.projected)
    assert np.array_equal(sums[..., :3], np.stack([ref.edge_sum, ref.edge_sq, ref.edge_count], axis=-1))


def test_the_base_is_kept_for_a_search_and_renewed_after(model, scene, exact_scene, true_pose):
    """Two batches of one limb's search on one frame share the staying cones' base; another staying pose or
    another frame measures it again; all equal the full measurement."""
    rng = np.random.default_rng(9)
    fast, full = NumbaBackend(model), NumbaBackend(model, moving=False)
    prepared = fast.prepare(scene)
    request = _request()
    first = _group_batch(model, true_pose, "right_arm", 20, 4.0, rng)
    second = _group_batch(model, true_pose, "right_arm", 20, 4.0, rng)
    second[0] = second[1]  # another first pose, the same staying cones
    fast.measure(prepared, first, request)
    kept = fast._base[3]
    assert _same(fast.measure(prepared, second, request), full.measure(prepared, second, request))
    assert fast._base[3] is kept
    other = _group_batch(model, true_pose + 0.01, "right_arm", 20, 4.0, rng)
    assert _same(fast.measure(prepared, other, request), full.measure(prepared, other, request))
    assert fast._base[3] is not kept
    again = fast.prepare(exact_scene)
    assert _same(fast.measure(again, other, request), full.measure(again, other, request))
    assert fast._base[0] is again


def test_batches_that_move_much_or_want_regions_are_measured_in_full(model, scene, true_pose):
    """The root, the torso's parameters, region sums or a single pose: the full kernel (no base)."""
    rng = np.random.default_rng(4)
    fast = NumbaBackend(model)
    prepared = fast.prepare(scene)
    for group in ("root", "torso"):
        fast.measure(prepared, _group_batch(model, true_pose, group, 10, 1.0, rng), _request())
        assert fast.last_full_items == -1
    arm = _group_batch(model, true_pose, "left_arm", 10, 1.0, rng)
    fast.measure(prepared, arm, _request(region=True))
    assert fast.last_full_items == -1
    fast.measure(prepared, arm[:1], _request())
    assert fast.last_full_items == -1
    assert NumbaBackend(model, moving=False)._moving_cones(arm, _request()) is None


@pytest.mark.parametrize("threads", ["pool", "prange", "serial"])
def test_the_kernels_return_the_poses_joints(model, scene, true_pose, threads):
    """``Request(joints=True)``: every path (the moving cones', the full kernel's, each thread mode) writes the
    poses' 15 joints from its own kinematics, equal to ``BodyModel.joints15`` to the last bit; without it none.
    The measurements are the same either way."""
    rng = np.random.default_rng(17)
    backend = NumbaBackend(model, threads=threads)
    prepared = backend.prepare(scene)
    limb = _group_batch(model, true_pose, "left_leg", 40, 3.0, rng)
    whole = true_pose + rng.normal(0.0, 1.0, (40, model.n_params)) * model.sigma
    for poses in (limb, whole, whole[:1]):
        with_joints = backend.measure(prepared, poses, _request(joints=True))
        assert np.array_equal(with_joints.joints, model.joints15(poses))
        without = backend.measure(prepared, poses, _request())
        assert without.joints is None
        assert _same(with_joints, without)
