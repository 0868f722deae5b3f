"""The fused numba kernel of the default CPU backend: outlines + scanline silhouette + edge samples.

One parallel pass over the poses (``prange``, all cores), views inside: build the ``K`` cone outlines
(:func:`swarmpose.render._kernels.cone_outline`), then

* silhouette counts ``Y = |O & P|`` and ``P = |P|`` by the scanline rule (row spans of every outline,
  merged per row, ``Y`` read from the row prefix sums of ``O``; no mask is ever built),
* edge sums over the visible sample points (thesis eq. 5.1; Deutscher & Reid eq. 14),
* foreground SSD over the interior grid points (Deutscher & Reid eq. 15),

all with the exact definitions of :mod:`swarmpose.render` (tested against
:mod:`swarmpose.render.reference`). Kinematics (:func:`swarmpose.body.kinematics.fk_pose_into`) runs
inside the same kernel, once per pose.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from swarmpose.body.kinematics import fk_pose_into
from swarmpose.body.priors import segment_distance2
from swarmpose.fitness.threads import fetch_add, store_release
from swarmpose.render._kernels import (
    axis_depth_at,
    axis_param,
    clip_segment,
    cone_outline,
    hidden,
    n_samples,
    pixel_value,
    silhouette_counts,
)

#: Hash of the kernel sources this module's cached kernels inline (body/kinematics.py, render/_kernels.py,
#: fitness/threads.py).
#: numba's cache sees edits to this file only, so an edit there must change this line (or cached kernels keep
#: running the old code); tests/test_numba_cache.py says when and gives the new value.
INLINED_SOURCES_SHA1 = "33cdf34a4b5bdb0c"

__all__ = ["copy_joints", "eval_claim", "eval_claim_go", "eval_kernel", "eval_share", "row_prefix_sums"]


@nb.njit(cache=True, nogil=True)
def row_prefix_sums(sil, out):
    """``out[c, y, x] = sum(sil[c, y, :x])`` for ``sil (C, H, W)`` into ``out (C, H, W + 1)``."""
    C, H, W = sil.shape
    for c in range(C):
        for y in range(H):
            acc = 0
            out[c, y, 0] = 0
            for x in range(W):
                acc += sil[c, y, x]
                out[c, y, x + 1] = acc


@nb.njit(cache=True, nogil=True, inline="always")
def _edge_point(x, y, z, k, c, edges, valid, K, poly, nvs, bbox, axis, orient, acc):
    """Add one edge sample: acc[0] += p, acc[1] += (1 - p)^2, acc[2] += 1 unless hidden."""
    if hidden(x, y, z, k, valid, K, poly, nvs, bbox, axis, orient):
        return
    p = pixel_value(edges, c, x, y)
    acc[0] += p
    acc[1] += (1.0 - p) * (1.0 - p)
    acc[2] += 1.0


@nb.njit(cache=True, nogil=True, inline="always")
def cone_reach(k, poly, nvs, axis):
    """The largest distance of outline ``k``'s vertices from its projected axis segment: the outline lies in the
    capsule of that radius around the axis (used to pass over lines that cannot meet it)."""
    r2 = 0.0
    for i in range(nvs[k]):
        x = poly[k, i, 0]
        y = poly[k, i, 1]
        s = axis_param(k, x, y, axis)
        ex = x - (axis[k, 0, 0] + s * (axis[k, 1, 0] - axis[k, 0, 0]))
        ey = y - (axis[k, 0, 1] + s * (axis[k, 1, 1] - axis[k, 0, 1]))
        r2 = max(r2, ex * ex + ey * ey)
    return math.sqrt(r2)


@nb.njit(cache=True, nogil=True, inline="always")
def line_occluders(px, py, pz, qx, qy, qz, k, valid, K, poly, nvs, bbox, axis, orient, reach, occ, t_in, t_out):
    """The cones that can hide part of cone ``k``'s silhouette line ``p -> q``: drawn (``valid``), their
    axis nearer somewhere than the line, their outline covering the parameter interval ``[t_in, t_out]`` of
    the line (Cyrus-Beck, :func:`swarmpose.render._kernels.clip_segment`). Written to ``occ[:m]``,
    ``t_in[:m]``, ``t_out[:m]``; returns ``m``."""
    m = 0
    zmax = max(pz, qz)
    for j in range(K):
        # cone j can hide a sample only if it is drawn and its axis is nearer somewhere than the line
        if j == k or not valid[j] or min(axis[j, 0, 2], axis[j, 1, 2]) >= zmax:
            continue
        # outline j lies in its bounding box (clip_segment's own first test, here before the costlier one below)
        if (max(px, qx) < bbox[j, 0] or min(px, qx) > bbox[j, 1]
                or max(py, qy) < bbox[j, 2] or min(py, qy) > bbox[j, 3]):
            continue
        # outline j lies within reach[j] of its projected axis: a line farther away cannot meet it (the margin
        # is far above rounding, so the test never rejects a line that clip_segment finds inside)
        r = reach[j] + 1e-3
        if segment_distance2(px, py, 0.0, qx, qy, 0.0, axis[j, 0, 0], axis[j, 0, 1], 0.0, axis[j, 1, 0],
                             axis[j, 1, 1], 0.0) > r * r:
            continue
        a, b = clip_segment(px, py, qx, qy, j, poly, nvs, bbox, orient)
        if a <= b:
            occ[m] = j
            t_in[m] = a
            t_out[m] = b
            m += 1
    return m


@nb.njit(cache=True, nogil=True, inline="always")
def line_sample(i, n, px, py, pz, qx, qy, qz, m, occ, t_in, t_out, axis):
    """Sample ``i`` of ``n`` on the line ``p -> q`` (at ``t = (i + 1/2) / n``): ``(x, y, hidden)``, hidden when
    one of the occluders ``occ[:m]`` covers it and its axis is nearer there (:func:`line_occluders`)."""
    t = (i + 0.5) / n
    x = px + t * (qx - px)
    y = py + t * (qy - py)
    for q in range(m):
        if t_in[q] <= t <= t_out[q] and axis_depth_at(occ[q], x, y, axis) < pz + t * (qz - pz):
            return x, y, True
    return x, y, False


@nb.njit(cache=True, nogil=True, inline="always")
def _edge_line(px, py, pz, qx, qy, qz, spacing, k, c, edges, valid, K, poly, nvs, bbox, axis, orient, reach,
               occ, t_in, t_out):
    """Samples at ``t = (i + 1/2) / n`` on the silhouette line ``p -> q`` of cone ``k``.

    Occlusion as in :func:`swarmpose.render._kernels.hidden`, but the footprint test is done once per
    (line, other cone) by clipping the line to the other outline (:func:`line_occluders`); per sample only
    the depth comparison with the few cones that cover part of the line remains (``occ``, ``t_in``,
    ``t_out``: ``(K,)`` scratch). Returns ``(sum p, sum (1 - p)^2, count)`` over the visible samples.
    """
    L = math.sqrt((qx - px) * (qx - px) + (qy - py) * (qy - py))
    n = n_samples(L, spacing)
    m = line_occluders(px, py, pz, qx, qy, qz, k, valid, K, poly, nvs, bbox, axis, orient, reach, occ, t_in,
                       t_out)
    s1 = 0.0
    s2 = 0.0
    cnt = 0.0
    for i in range(n):
        x, y, hid = line_sample(i, n, px, py, pz, qx, qy, qz, m, occ, t_in, t_out, axis)
        if hid:
            continue
        p = pixel_value(edges, c, x, y)
        s1 += p
        s2 += (1.0 - p) * (1.0 - p)
        cnt += 1.0
    return s1, s2, cnt


@nb.njit(cache=True, nogil=True, inline="always")
def _arc_segment(k, i0, i1, q, poly):
    """Segment ``q`` of the outline arc ``poly[k, i0:i1]`` (the last one back to ``i0``): its vertices and
    length."""
    a = i0 + q
    b = i0 + q + 1 if i0 + q + 1 < i1 else i0
    return a, b, math.sqrt((poly[k, b, 0] - poly[k, a, 0]) ** 2 + (poly[k, b, 1] - poly[k, a, 1]) ** 2)


@nb.njit(cache=True, nogil=True, inline="always")
def arc_length(k, i0, i1, closed, poly):
    """``(m, L)``: the number of vertices and the length of the outline arc ``poly[k, i0:i1]`` (closed: back to
    ``i0``)."""
    m = i1 - i0 + (1 if closed else 0)
    L = 0.0
    for q in range(m - 1):
        L += _arc_segment(k, i0, i1, q, poly)[2]
    return m, L


@nb.njit(cache=True, nogil=True, inline="always")
def arc_point(s, m, k, i0, i1, poly, seg, seg_start, seg_len, a, b):
    """The point at arc length ``s`` of the arc (:func:`arc_length`), walking on from segment ``seg`` (which
    starts at ``seg_start``, vertices ``a -> b``, length ``seg_len``): ``(x, y, z)`` and the walk's new state
    ``(seg, seg_start, seg_len, a, b)``."""
    while s > seg_start + seg_len and seg < m - 2:
        seg += 1
        seg_start += seg_len
        a, b, seg_len = _arc_segment(k, i0, i1, seg, poly)
    t = (s - seg_start) / seg_len if seg_len > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    x = poly[k, a, 0] + t * (poly[k, b, 0] - poly[k, a, 0])
    y = poly[k, a, 1] + t * (poly[k, b, 1] - poly[k, a, 1])
    z = poly[k, a, 2] + t * (poly[k, b, 2] - poly[k, a, 2])
    return x, y, z, seg, seg_start, seg_len, a, b


@nb.njit(cache=True, nogil=True)
def _edge_arc(k, i0, i1, closed, spacing, c, edges, valid, K, poly, nvs, bbox, axis, orient, acc):
    """Samples at arc lengths ``(i + 1/2) L / n`` on the outline arc ``poly[k, i0:i1]`` (closed: back to
    ``i0``)."""
    m, L = arc_length(k, i0, i1, closed, poly)
    if m < 2:
        return
    n = n_samples(L, spacing)
    seg = 0
    seg_start = 0.0
    a, b, seg_len = _arc_segment(k, i0, i1, 0, poly)
    for i in range(n):
        x, y, z, seg, seg_start, seg_len, a, b = arc_point((i + 0.5) * L / n, m, k, i0, i1, poly, seg, seg_start,
                                                           seg_len, a, b)
        _edge_point(x, y, z, k, c, edges, valid, K, poly, nvs, bbox, axis, orient, acc)


@nb.njit(cache=True, nogil=True)
def _region(k, nv, spacing, c, sil, poly, sides, axis, info, acc):
    """Deutscher & Reid interior grid of cone ``k``: acc[0] += (1 - O)^2, acc[1] += 1 per point."""
    if info[k, 0] == 1:
        p0x, p0y = sides[k, 0, 0, 0], sides[k, 0, 0, 1]
        q0x, q0y = sides[k, 0, 1, 0], sides[k, 0, 1, 1]
        p1x, p1y = sides[k, 1, 0, 0], sides[k, 1, 0, 1]
        q1x, q1y = sides[k, 1, 1, 0], sides[k, 1, 1, 1]
        la = math.sqrt((axis[k, 1, 0] - axis[k, 0, 0]) ** 2 + (axis[k, 1, 1] - axis[k, 0, 1]) ** 2)
        nt = n_samples(la, spacing)
        width = max(math.sqrt((p1x - p0x) ** 2 + (p1y - p0y) ** 2), math.sqrt((q1x - q0x) ** 2 + (q1y - q0y) ** 2))
        ns = n_samples(width, spacing)
        for i in range(nt):
            t = (i + 0.5) / nt
            lx = p0x + t * (q0x - p0x)
            ly = p0y + t * (q0y - p0y)
            rx = p1x + t * (q1x - p1x)
            ry = p1y + t * (q1y - p1y)
            for j in range(ns):
                u = (j + 0.5) / ns
                o = pixel_value(sil, c, lx + u * (rx - lx), ly + u * (ry - ly))
                acc[0] += (1.0 - o) * (1.0 - o)
                acc[1] += 1.0
    else:
        gx = 0.0
        gy = 0.0
        for i in range(nv):
            gx += poly[k, i, 0]
            gy += poly[k, i, 1]
        gx /= nv
        gy /= nv
        o = pixel_value(sil, c, gx, gy)
        acc[0] += (1.0 - o) * (1.0 - o)
        acc[1] += 1.0
        for i in range(nv):
            o = pixel_value(sil, c, gx + 0.5 * (poly[k, i, 0] - gx), gy + 0.5 * (poly[k, i, 1] - gy))
            acc[0] += (1.0 - o) * (1.0 - o)
            acc[1] += 1.0


@nb.njit(cache=True, nogil=True)
def _measure_view(n, c, T, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                  prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge, do_region,
                  counts, sums, poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ, t_in,
                  t_out, acc, racc):
    """Pose ``n`` (its joint transforms ``T``) in view ``c``: ``counts[n, c]`` and ``sums[n, c]``; the rest
    is scratch."""
    K = joint.shape[0]
    H = edges.shape[1]
    W = edges.shape[2]
    for k in range(K):
        nvs[k] = cone_outline(T, joint, start, end, semi_a, semi_b, scale, Rc[c], tc[c], cam[c],
                              ctab, stab, near, k, poly, sides, axis, info, bbox, orient)
        valid[k] = nvs[k] > 0
        if do_edge and valid[k]:
            reach[k] = cone_reach(k, poly, nvs, axis)
    y_ = 0
    p_ = 0
    if do_sil:
        y_, p_ = silhouette_counts(poly, nvs, valid, K, H, W, prefix, c, cnt, bl, br)
    counts[n, c, 0] = y_
    counts[n, c, 1] = p_
    acc[:] = 0.0
    if do_edge:
        for k in range(K):
            if not valid[k]:
                continue
            if edge_mask[k] and info[k, 0] == 1:
                for sd in range(2):
                    e1, e2, e3 = _edge_line(sides[k, sd, 0, 0], sides[k, sd, 0, 1], sides[k, sd, 0, 2],
                                            sides[k, sd, 1, 0], sides[k, sd, 1, 1], sides[k, sd, 1, 2],
                                            spacing, k, c, edges, valid, K, poly, nvs, bbox, axis,
                                            orient, reach, occ, t_in, t_out)
                    acc[0] += e1
                    acc[1] += e2
                    acc[2] += e3
            if k == top_cone:
                _edge_arc(k, info[k, 1], info[k, 2], info[k, 3] == 1, spacing, c, edges, valid, K,
                          poly, nvs, bbox, axis, orient, acc)
    sums[n, c, 0] = acc[0]
    sums[n, c, 1] = acc[1]
    sums[n, c, 2] = acc[2]
    racc[:] = 0.0
    if do_region:
        for k in range(K):
            if valid[k]:
                _region(k, nvs[k], region_spacing, c, sil, poly, sides, axis, info, racc)
    sums[n, c, 3] = racc[0]
    sums[n, c, 4] = racc[1]


@nb.njit(cache=True, nogil=True, inline="always")
def copy_joints(T, j15, out):
    """``out[q] = T[j15[q], :, 3]``: the origins of the joint frames ``j15`` (a pose's 15 joints, as
    :meth:`swarmpose.body.model.BodyModel.joints15` takes them from the same transforms)."""
    for q in range(j15.shape[0]):
        j = j15[q]
        out[q, 0] = T[j, 0, 3]
        out[q, 1] = T[j, 1, 3]
        out[q, 2] = T[j, 2, 3]


@nb.njit(cache=True, nogil=True)
def _scratch(K, H, P):
    """The per-thread scratch arrays of :func:`_measure_view`."""
    return (np.empty((K, P, 3)), np.empty((K, 2, 2, 3)), np.empty((K, 2, 3)), np.empty((K, 4), np.int64),
            np.empty((K, 4)), np.empty(K), np.zeros(K), np.empty(K, np.int64), np.empty(K, np.bool_), np.empty(H, np.int32),
            np.empty((H, K), np.int32), np.empty((H, K), np.int32), np.empty(K, np.int64), np.empty(K),
            np.empty(K), np.empty(3), np.empty(2))


@nb.njit(cache=True, nogil=True)
def eval_share(idx, poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
               joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
               prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
               do_sil, do_edge, do_region, j15, joints, counts, sums):
    """The poses ``poses[idx]`` of the batch (one thread's share; ``idx (M,)`` int64): see
    :func:`eval_kernel` for the arguments; results go to ``counts[idx]``, ``sums[idx]``.

    Releases the GIL (``nogil``), so Python threads can run shares in parallel.
    """
    C = Rc.shape[0]
    K = joint.shape[0]
    J = parents.shape[0]
    H = edges.shape[1]
    P = 2 * ctab.shape[0] + 4
    mine = idx.shape[0]
    Ts = np.empty((mine, J, 3, 4))
    for i in range(mine):
        fk_pose_into(poses[idx[i]], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, Ts[i])
        copy_joints(Ts[i], j15, joints[idx[i]])
    poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ, t_in, t_out, acc, racc = _scratch(
        K, H, P)
    for c in range(C):  # views outside: one view's prefix sums and edge map stay in cache
        for i in range(mine):
            _measure_view(idx[i], c, Ts[i], joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab,
                          near, prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge,
                          do_region, counts, sums, poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br,
                          occ, t_in, t_out, acc, racc)


@nb.njit(cache=True, nogil=True)
def eval_claim(claim, done, poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
               joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
               prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
               do_sil, do_edge, do_region, j15, joints, counts, sums):
    """The batch's (view, pose) items claimed one at a time, shared with other threads running the same
    function: item ``u`` is pose ``u % N`` in view ``u // N`` (views outside, as :func:`eval_share`); it is
    claimed by ``fetch_add(claim, 0, 1)`` and counted in ``done[0]`` once its results are written. The results
    are :func:`eval_share`'s, whichever thread measures which item. Releases the GIL."""
    N = poses.shape[0]
    C = Rc.shape[0]
    K = joint.shape[0]
    J = parents.shape[0]
    H = edges.shape[1]
    P = 2 * ctab.shape[0] + 4
    Ts = np.empty((N, J, 3, 4))
    have = np.zeros(N, np.bool_)  # the joint transforms this thread has computed
    poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ, t_in, t_out, acc, racc = _scratch(
        K, H, P)
    while True:
        u = fetch_add(claim, 0, 1)
        if u >= N * C:
            return
        c = u // N
        n = u - c * N
        if not have[n]:
            fk_pose_into(poses[n], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, Ts[n])
            have[n] = True
        if c == 0:  # each pose's first item: written once, by one thread
            copy_joints(Ts[n], j15, joints[n])
        _measure_view(n, c, Ts[n], joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                      prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge, do_region,
                      counts, sums, poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ, t_in,
                      t_out, acc, racc)
        fetch_add(done, 0, 1)


@nb.njit(cache=True, nogil=True)
def eval_claim_go(go, seq, claim, done, poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                  joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                  prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
                  do_sil, do_edge, do_region, j15, joints, counts, sums):
    """:func:`eval_claim` after ``go[0] = seq``, set once the GIL is released: a worker of
    :class:`swarmpose.fitness.threads.BatchThreads` that sees it starts claiming without waiting for the GIL."""
    store_release(go, 0, seq)
    eval_claim(claim, done, poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
               joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
               prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
               do_sil, do_edge, do_region, j15, joints, counts, sums)


@nb.njit(cache=True, parallel=True, nogil=True)
def eval_kernel(poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
                do_sil, do_edge, do_region, n_threads, j15, joints, counts, sums):
    """Per (pose, view) silhouette counts and edge/region sums, kinematics included.

    Parameters
    ----------
    poses : (N, D) float64.
    parents ... trans_param : kinematic tables (:class:`swarmpose.body.kinematics.KinematicArrays`).
    joint ... scale : cone tables (:class:`swarmpose.render.project.ConeTables`).
    Rc (C, 3, 3), tc (C, 3), cam (C, 11) : camera tables (:func:`swarmpose.render.project.camera_tables`).
    ctab, stab : (n_rim,) rim grid cosines and sines; near : float.
    prefix : (C, H, W + 1) int16/int32 row prefix sums of the observed silhouettes.
    sil : (C, H, W) uint8 observed silhouettes; edges : (C, H, W) float32 edge maps.
    edge_mask : (K,) bool cones edge-sampled; top_cone : int (-1: none); spacing, region_spacing : px.
    do_sil, do_edge, do_region : bool, which parts to compute.
    n_threads : int, ``numba.get_num_threads()`` (passed in: calling it here would defeat caching).
    j15 : (M,) int64 joint frames whose origins are written to ``joints`` (``M = 0``: none).

    Outputs
    -------
    counts : (N, C, 2) int64 -- ``Y``, ``P``.
    sums : (N, C, 5) float64 -- edge ``sum p``, ``sum (1 - p)^2``, visible sample count, region
        ``sum (1 - O)^2``, region point count.
    joints : (N, M, 3) float64 -- the origins of the joint frames ``j15`` (from the kinematics the kernel runs
        anyway: the keypoint term's joints without a second pass).

    Notes
    -----
    Poses are dealt round-robin to the threads (``prange`` over the thread count); each share
    (:func:`eval_share`) allocates its scratch once, computes its poses' kinematics once, then runs
    view by view (so that view's prefix sums and edge map stay in the core's cache).
    """
    nth = max(1, min(n_threads, poses.shape[0]))
    for th in nb.prange(nth):
        eval_share(np.arange(th, poses.shape[0], nth), poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                   joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                   prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing,
                   do_sil, do_edge, do_region, j15, joints, counts, sums)
