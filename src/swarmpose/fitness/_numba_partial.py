"""The fused kernel for a batch that moves few cones: the cones that stay are measured once, then reused.

A limb's search (:mod:`swarmpose.track.recovery`) scores hundreds of poses that differ only in that limb's
parameters, so every other cone projects the same in every pose. Here the batch's first pose is measured once
per view for the cones that stay (:func:`stay_base`: their outlines; their row spans merged, with each row's
counts; their edge samples, each with its pixel value and whether another staying cone hides it), and each
(view, pose) item then computes only the cones that move (:func:`eval_claim_moving`):

* silhouette counts: the staying cones' totals plus, on each row a moving cone covers, the union of the row's
  spans minus the staying spans' own counts (integers: exact);
* edge sums: a staying cone's line is summed again sample by sample, in the same order, only where a moving
  outline can hide part of it (:func:`swarmpose.fitness._numba.line_occluders`); otherwise its stored sum is the
  same sum. A staying top cone's end arc adds its stored samples one by one, those a moving cone hides left
  out. A moving cone's lines and end arc are measured as :func:`swarmpose.fitness._numba._measure_view`
  measures them.

Every float sum adds the same values in the same order as :func:`swarmpose.fitness._numba.eval_share`, so the
results are equal to the last bit (tested). A pose whose staying cones' transforms differ from the first
pose's after all is measured in full. The Deutscher-Reid region sums are not handled here (the caller measures
such a batch in full).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from swarmpose.body.kinematics import fk_pose_into
from swarmpose.fitness._numba import (
    _arc_segment,
    _edge_arc,
    _edge_line,
    _measure_view,
    _scratch,
    arc_length,
    arc_point,
    cone_reach,
    copy_joints,
    line_occluders,
    line_sample,
)
from swarmpose.fitness.threads import fetch_add, store_release
from swarmpose.render._kernels import bucket_outlines, cone_outline, hidden, n_samples, pixel_value

#: Hash of the kernel sources this module's cached kernels inline (see :mod:`swarmpose.fitness._numba`).
INLINED_SOURCES_SHA1 = "67f14f0576431013"

__all__ = ["stay_base", "eval_claim_moving", "eval_claim_moving_go"]


@nb.njit(cache=True, nogil=True)
def stay_base(T0, moving, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
              prefix, edges, edge_mask, top_cone, spacing):
    """The staying cones (``~moving``) of the pose with joint transforms ``T0 (J, 3, 4)``, in every view.

    Returns
    -------
    b_poly (C, K, P, 3), b_sides (C, K, 2, 2, 3), b_axis (C, K, 2, 3), b_info (C, K, 4), b_bbox (C, K, 4),
    b_orient (C, K), b_reach (C, K), b_nvs (C, K), b_valid (C, K)
        Every cone's outline in every view (:func:`swarmpose.render._kernels.cone_outline`) and its reach
        (:func:`swarmpose.fitness._numba.cone_reach`).
    s_cnt (C, H), s_l (C, H, K), s_r (C, H, K)
        Per row the staying outlines' spans merged: ``s_cnt`` disjoint spans ``[s_l, s_r]``, sorted.
    s_rows (C, H, 2), s_tot (C, 2)
        Per row and in all: ``Y`` and ``P`` of those spans.
    l_n (C, K, 2), l_off (C, K, 2), l_sum (C, K, 2, 3)
        Each staying, edge-sampled cone's two lines: sample count, offset into the sample arrays, and
        ``(sum p, sum (1 - p)^2, count)`` over the samples no other staying cone hides.
    smp_p (S,), smp_hid (S,)
        Per sample its pixel value and whether a staying cone hides it.
    a_n (C,), a_off (C,), arc_xyz (A, 3), arc_p (A,), arc_hid (A,)
        The top cone's end arc where it stays (``a_n = 0`` elsewhere): its samples (as
        :func:`swarmpose.fitness._numba._edge_arc` places them), their pixel values and whether a staying cone
        hides them.
    """
    C = Rc.shape[0]
    K = joint.shape[0]
    H = edges.shape[1]
    W = edges.shape[2]
    P = 2 * ctab.shape[0] + 4
    b_poly = np.zeros((C, K, P, 3))
    b_sides = np.zeros((C, K, 2, 2, 3))
    b_axis = np.zeros((C, K, 2, 3))
    b_info = np.zeros((C, K, 4), np.int64)
    b_bbox = np.zeros((C, K, 4))
    b_orient = np.zeros((C, K))
    b_reach = np.zeros((C, K))
    b_nvs = np.zeros((C, K), np.int64)
    b_valid = np.zeros((C, K), np.bool_)
    s_cnt = np.zeros((C, H), np.int32)
    s_l = np.zeros((C, H, K), np.int32)
    s_r = np.zeros((C, H, K), np.int32)
    s_rows = np.zeros((C, H, 2), np.int64)
    s_tot = np.zeros((C, 2), np.int64)
    l_n = np.zeros((C, K, 2), np.int64)
    l_off = np.zeros((C, K, 2), np.int64)
    l_sum = np.zeros((C, K, 2, 3))
    a_n = np.zeros(C, np.int64)
    a_off = np.zeros(C, np.int64)
    stay = ~moving
    total = 0
    arcs = 0
    for c in range(C):
        for k in range(K):
            b_nvs[c, k] = cone_outline(T0, joint, start, end, semi_a, semi_b, scale, Rc[c], tc[c], cam[c], ctab,
                                       stab, near, k, b_poly[c], b_sides[c], b_axis[c], b_info[c], b_bbox[c],
                                       b_orient[c])
            b_valid[c, k] = b_nvs[c, k] > 0
            if b_valid[c, k]:
                b_reach[c, k] = cone_reach(k, b_poly[c], b_nvs[c], b_axis[c])
            if stay[k] and b_valid[c, k] and edge_mask[k] and b_info[c, k, 0] == 1:
                for sd in range(2):
                    dx = b_sides[c, k, sd, 1, 0] - b_sides[c, k, sd, 0, 0]
                    dy = b_sides[c, k, sd, 1, 1] - b_sides[c, k, sd, 0, 1]
                    l_n[c, k, sd] = n_samples(math.sqrt(dx * dx + dy * dy), spacing)
                    l_off[c, k, sd] = total
                    total += l_n[c, k, sd]
        k = top_cone
        if k >= 0 and stay[k] and b_valid[c, k]:
            m, L = arc_length(k, b_info[c, k, 1], b_info[c, k, 2], b_info[c, k, 3] == 1, b_poly[c])
            if m >= 2:
                a_n[c] = n_samples(L, spacing)
                a_off[c] = arcs
                arcs += a_n[c]
    smp_p = np.zeros(max(total, 1))
    smp_hid = np.zeros(max(total, 1), np.bool_)
    arc_xyz = np.zeros((max(arcs, 1), 3))
    arc_p = np.zeros(max(arcs, 1))
    arc_hid = np.zeros(max(arcs, 1), np.bool_)
    cnt = np.zeros(H, np.int32)
    bl = np.zeros((H, K), np.int32)
    br = np.zeros((H, K), np.int32)
    occ = np.zeros(K, np.int64)
    t_in = np.zeros(K)
    t_out = np.zeros(K)
    for c in range(C):
        poly = b_poly[c]
        nvs = b_nvs[c]
        valid_s = b_valid[c] & stay
        # the staying outlines' row spans, merged
        Ymin, Ymax = bucket_outlines(poly, nvs, valid_s, K, H, W, cnt, bl, br)
        for y in range(Ymin, Ymax + 1):
            M = -1
            m = 0
            for i in range(cnt[y]):
                st = max(bl[y, i], M + 1)
                r_ = br[y, i]
                if r_ >= st:
                    s_rows[c, y, 0] += prefix[c, y, r_ + 1] - prefix[c, y, st]
                    s_rows[c, y, 1] += r_ - st + 1
                    if m > 0 and st == s_r[c, y, m - 1] + 1:
                        s_r[c, y, m - 1] = r_  # touching: one span
                    else:
                        s_l[c, y, m] = st
                        s_r[c, y, m] = r_
                        m += 1
                    M = r_
            s_cnt[c, y] = m
            s_tot[c, 0] += s_rows[c, y, 0]
            s_tot[c, 1] += s_rows[c, y, 1]
        # the staying lines' samples, hidden or not by the other staying cones
        for k in range(K):
            if not (valid_s[k] and edge_mask[k] and b_info[c, k, 0] == 1):
                continue
            for sd in range(2):
                px, py, pz = b_sides[c, k, sd, 0, 0], b_sides[c, k, sd, 0, 1], b_sides[c, k, sd, 0, 2]
                qx, qy, qz = b_sides[c, k, sd, 1, 0], b_sides[c, k, sd, 1, 1], b_sides[c, k, sd, 1, 2]
                n = l_n[c, k, sd]
                o = l_off[c, k, sd]
                m = line_occluders(px, py, pz, qx, qy, qz, k, valid_s, K, poly, nvs, b_bbox[c], b_axis[c],
                                   b_orient[c], b_reach[c], occ, t_in, t_out)
                s1 = 0.0
                s2 = 0.0
                cn = 0.0
                for i in range(n):
                    x, y, hid = line_sample(i, n, px, py, pz, qx, qy, qz, m, occ, t_in, t_out, b_axis[c])
                    p = pixel_value(edges, c, x, y)
                    smp_p[o + i] = p
                    smp_hid[o + i] = hid
                    if not hid:
                        s1 += p
                        s2 += (1.0 - p) * (1.0 - p)
                        cn += 1.0
                l_sum[c, k, sd, 0] = s1
                l_sum[c, k, sd, 1] = s2
                l_sum[c, k, sd, 2] = cn
        # the top cone's end arc
        if a_n[c] > 0:
            k = top_cone
            i0 = b_info[c, k, 1]
            i1 = b_info[c, k, 2]
            m, L = arc_length(k, i0, i1, b_info[c, k, 3] == 1, poly)
            n = a_n[c]
            o = a_off[c]
            seg = 0
            seg_start = 0.0
            a, b, seg_len = _arc_segment(k, i0, i1, 0, poly)
            for i in range(n):
                x, y, z, seg, seg_start, seg_len, a, b = arc_point((i + 0.5) * L / n, m, k, i0, i1, poly, seg,
                                                                   seg_start, seg_len, a, b)
                arc_xyz[o + i, 0] = x
                arc_xyz[o + i, 1] = y
                arc_xyz[o + i, 2] = z
                arc_hid[o + i] = hidden(x, y, z, k, valid_s, K, poly, nvs, b_bbox[c], b_axis[c], b_orient[c])
                arc_p[o + i] = pixel_value(edges, c, x, y)
    return (b_poly, b_sides, b_axis, b_info, b_bbox, b_orient, b_reach, b_nvs, b_valid, s_cnt, s_l, s_r, s_rows, s_tot,
            l_n, l_off, l_sum, smp_p, smp_hid, a_n, a_off, arc_xyz, arc_p, arc_hid)


@nb.njit(cache=True, nogil=True, inline="always")
def _moving_counts(c, valid_m, poly, nvs, K, H, W, prefix, cnt, bl, br, s_cnt, s_l, s_r, s_rows, s_tot):
    """``(Y, P)`` in view ``c``: the staying cones' totals, and on each row a moving outline (``valid_m``)
    covers, the union of its spans with the row's staying spans in place of the staying spans' own counts."""
    y_ = s_tot[c, 0]
    p_ = s_tot[c, 1]
    Ymin, Ymax = bucket_outlines(poly, nvs, valid_m, K, H, W, cnt, bl, br)
    for y in range(Ymin, Ymax + 1):
        nm = cnt[y]
        if nm == 0:
            continue
        ns = s_cnt[c, y]
        i = 0
        j = 0
        M = -1  # right end of the merged cover so far
        yy = 0
        pp = 0
        while i < ns or j < nm:  # the row's staying and moving spans by left end
            if j >= nm or (i < ns and s_l[c, y, i] <= bl[y, j]):
                l_ = s_l[c, y, i]
                r_ = s_r[c, y, i]
                i += 1
            else:
                l_ = bl[y, j]
                r_ = br[y, j]
                j += 1
            st = max(l_, M + 1)
            if r_ >= st:
                pp += r_ - st + 1
                yy += prefix[c, y, r_ + 1] - prefix[c, y, st]
                M = r_
        y_ += yy - s_rows[c, y, 0]
        p_ += pp - s_rows[c, y, 1]
    return y_, p_


@nb.njit(cache=True, nogil=True, inline="always")
def _staying_line(c, k, sd, px, py, pz, qx, qy, qz, valid_m, reach, K, poly, nvs, bbox, axis, orient, occ, t_in,
                  t_out, l_n, l_off, l_sum, smp_p, smp_hid):
    """``(sum p, sum (1 - p)^2, count)`` of staying cone ``k``'s line ``sd`` in view ``c``: its stored sums where
    no moving cone (``valid_m``) can hide part of it, else its stored samples summed again in order, those a
    moving cone hides left out as well."""
    m = line_occluders(px, py, pz, qx, qy, qz, k, valid_m, K, poly, nvs, bbox, axis, orient, reach, occ, t_in,
                       t_out)
    if m == 0:
        return l_sum[c, k, sd, 0], l_sum[c, k, sd, 1], l_sum[c, k, sd, 2]
    n = l_n[c, k, sd]
    o = l_off[c, k, sd]
    s1 = 0.0
    s2 = 0.0
    cn = 0.0
    for i in range(n):
        if smp_hid[o + i]:
            continue
        _, _, hid = line_sample(i, n, px, py, pz, qx, qy, qz, m, occ, t_in, t_out, axis)
        if hid:
            continue
        p = smp_p[o + i]
        s1 += p
        s2 += (1.0 - p) * (1.0 - p)
        cn += 1.0
    return s1, s2, cn


@nb.njit(cache=True, nogil=True, inline="always")
def _staying_arc(c, k, valid_m, K, poly, nvs, bbox, axis, orient, a_n, a_off, arc_xyz, arc_p, arc_hid, acc):
    """The staying top cone ``k``'s end arc in view ``c`` added to ``acc`` sample by sample (as
    :func:`swarmpose.fitness._numba._edge_arc` adds them), the samples a staying or moving cone hides left out."""
    o = a_off[c]
    for i in range(o, o + a_n[c]):
        if arc_hid[i] or hidden(arc_xyz[i, 0], arc_xyz[i, 1], arc_xyz[i, 2], k, valid_m, K, poly, nvs, bbox, axis,
                                orient):
            continue
        p = arc_p[i]
        acc[0] += p
        acc[1] += (1.0 - p) * (1.0 - p)
        acc[2] += 1.0


@nb.njit(cache=True, nogil=True)
def eval_claim_moving(claim, done, full, poses, moving, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                      joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                      prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge,
                      T0, b_poly, b_sides, b_axis, b_info, b_bbox, b_orient, b_reach, b_nvs, b_valid, s_cnt, s_l, s_r,
                      s_rows, s_tot, l_n, l_off, l_sum, smp_p, smp_hid, a_n, a_off, arc_xyz, arc_p, arc_hid, j15, joints, counts,
                      sums):
    """:func:`swarmpose.fitness._numba.eval_claim` for a batch whose poses move only the cones ``moving (K,)``
    against the first pose (its transforms ``T0``; the base ``b_poly`` ... ``smp_hid`` from :func:`stay_base`):
    the (view, pose) items claimed one at a time; an item copies the view's staying outlines from the base
    (once per run of items of that view), computes its moving cones' outlines, then ``counts[n, c]`` and
    ``sums[n, c, :3]`` as the module docstring says, or measures the pose in full when the
    pose moves a staying cone after all (counted in ``full[0]``). Releases the GIL."""
    N = poses.shape[0]
    C = Rc.shape[0]
    K = joint.shape[0]
    J = parents.shape[0]
    H = edges.shape[1]
    W = edges.shape[2]
    P = 2 * ctab.shape[0] + 4
    Ts = np.empty((N, J, 3, 4))
    have = np.zeros(N, np.bool_)
    stays = np.ones(N, np.bool_)
    poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ, t_in, t_out, acc, racc = _scratch(
        K, H, P)
    valid_m = np.zeros(K, np.bool_)
    view = -1  # the view whose staying outlines the scratch holds
    while True:
        u = fetch_add(claim, 0, 1)
        if u >= N * C:
            return
        c = u // N
        n = u - c * N
        if not have[n]:
            fk_pose_into(poses[n], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, Ts[n])
            have[n] = True
            for k in range(K):  # do the staying cones stay?
                if not moving[k]:
                    j = joint[k]
                    for a in range(3):
                        for b in range(4):
                            if Ts[n, j, a, b] != T0[j, a, b]:
                                stays[n] = False
        if c == 0:  # each pose's first item: written once, by one thread
            copy_joints(Ts[n], j15, joints[n])
        if not stays[n]:
            _measure_view(n, c, Ts[n], joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                          prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge, False,
                          counts, sums, poly, sides, axis, info, bbox, orient, reach, nvs, valid, cnt, bl, br, occ,
                          t_in, t_out, acc, racc)
            fetch_add(full, 0, 1)
            view = -1
        else:
            if view != c:
                poly[:] = b_poly[c]
                sides[:] = b_sides[c]
                axis[:] = b_axis[c]
                info[:] = b_info[c]
                bbox[:] = b_bbox[c]
                orient[:] = b_orient[c]
                reach[:] = b_reach[c]
                nvs[:] = b_nvs[c]
                valid[:] = b_valid[c]
                view = c
            for k in range(K):
                if moving[k]:
                    nvs[k] = cone_outline(Ts[n], joint, start, end, semi_a, semi_b, scale, Rc[c], tc[c], cam[c],
                                          ctab, stab, near, k, poly, sides, axis, info, bbox, orient)
                    valid[k] = nvs[k] > 0
                    if valid[k]:
                        reach[k] = cone_reach(k, poly, nvs, axis)
                valid_m[k] = moving[k] and valid[k]
            y_ = 0
            p_ = 0
            if do_sil:
                y_, p_ = _moving_counts(c, valid_m, poly, nvs, K, H, W, prefix, cnt, bl, br, s_cnt, s_l, s_r,
                                        s_rows, s_tot)
            counts[n, c, 0] = y_
            counts[n, c, 1] = p_
            acc[:] = 0.0
            if do_edge:
                for k in range(K):
                    if not valid[k]:
                        continue
                    if edge_mask[k] and info[k, 0] == 1:
                        for sd in range(2):
                            px, py, pz = sides[k, sd, 0, 0], sides[k, sd, 0, 1], sides[k, sd, 0, 2]
                            qx, qy, qz = sides[k, sd, 1, 0], sides[k, sd, 1, 1], sides[k, sd, 1, 2]
                            if moving[k]:
                                e1, e2, e3 = _edge_line(px, py, pz, qx, qy, qz, spacing, k, c, edges, valid, K, poly, nvs,
                                                        bbox, axis, orient, reach, occ, t_in, t_out)
                            else:
                                e1, e2, e3 = _staying_line(c, k, sd, px, py, pz, qx, qy, qz, valid_m, reach, K,
                                                           poly, nvs, bbox, axis, orient, occ, t_in, t_out, l_n,
                                                           l_off, l_sum, smp_p, smp_hid)
                            acc[0] += e1
                            acc[1] += e2
                            acc[2] += e3
                    if k == top_cone:
                        if moving[k]:
                            _edge_arc(k, info[k, 1], info[k, 2], info[k, 3] == 1, spacing, c, edges, valid, K,
                                      poly, nvs, bbox, axis, orient, acc)
                        else:
                            _staying_arc(c, k, valid_m, K, poly, nvs, bbox, axis, orient, a_n, a_off, arc_xyz, arc_p,
                                         arc_hid, acc)
            sums[n, c, 0] = acc[0]
            sums[n, c, 1] = acc[1]
            sums[n, c, 2] = acc[2]
            sums[n, c, 3] = 0.0
            sums[n, c, 4] = 0.0
        fetch_add(done, 0, 1)


@nb.njit(cache=True, nogil=True)
def eval_claim_moving_go(go, seq, claim, done, full, poses, moving, parents, offsets, rot_axis, rot_sign, rot_param,
                         trans_param, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                         prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge,
                         T0, b_poly, b_sides, b_axis, b_info, b_bbox, b_orient, b_reach, b_nvs, b_valid, s_cnt, s_l, s_r,
                         s_rows, s_tot, l_n, l_off, l_sum, smp_p, smp_hid, a_n, a_off, arc_xyz, arc_p, arc_hid, j15, joints,
                         counts, sums):
    """:func:`eval_claim_moving` after ``go[0] = seq`` (see :func:`swarmpose.fitness._numba.eval_claim_go`)."""
    store_release(go, 0, seq)
    eval_claim_moving(claim, done, full, poses, moving, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                      joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                      prefix, sil, edges, edge_mask, top_cone, spacing, region_spacing, do_sil, do_edge,
                      T0, b_poly, b_sides, b_axis, b_info, b_bbox, b_orient, b_reach, b_nvs, b_valid, s_cnt, s_l, s_r,
                      s_rows, s_tot, l_n, l_off, l_sum, smp_p, smp_hid, a_n, a_off, arc_xyz, arc_p, arc_hid, j15, joints,
                      counts, sums)
