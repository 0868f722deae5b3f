"""Numba building blocks of the fast path: camera projection, cone outlines, row spans, sampling.

All functions are ``@njit(cache=True, nogil=True)`` per-element helpers; the batched, parallel
kernels that call them live in :mod:`swarmpose.render.project` and :mod:`swarmpose.fitness._numba`.
The geometry is described once, in :mod:`swarmpose.render` (module docstring); the plain numpy
reference of the same definitions is :mod:`swarmpose.render.reference`.

Array layouts (per view, per cone ``k`` of ``K``):

* ``cam (11,)``: ``fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, r2_max``.
* ``poly (K, P, 3)``: outline vertices ``(u, v, depth)`` in drawing order, ``nv[k]`` of them.
* ``sides (K, 2, 2, 3)``: the two silhouette lines, ``[side, end (0 = start cap, 1 = end cap), (u, v, depth)]``.
* ``axis (K, 2, 3)``: projected cap centres ``(u, v, depth)``.
* ``info (K, 4)`` int64: ``has_sides``, first and one-past-last vertex index of the end cap's outline
  arc, ``1`` if that arc is a closed rim.
* ``bbox (K, 4)``: ``u_min, u_max, v_min, v_max`` of the outline; ``orient (K,)``: sign of its area.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

TWO_PI = 2.0 * math.pi
_ANGLE_EPS = 1e-9


@nb.njit(cache=True, nogil=True, inline="always")
def project_cam_point(x, y, z, cam):
    """Bouguet projection of a camera-frame point (see :mod:`swarmpose.camera`); returns ``(u, v)``.

    ``r^2`` is capped at ``cam[10]`` inside the radial polynomial, so points far outside the field of
    view cannot fold back into the image (the polynomial is only valid near the image).
    """
    iz = 1.0 / z
    a = x * iz
    b = y * iz
    r2 = a * a + b * b
    rr = min(r2, cam[10])
    radial = 1.0 + rr * (cam[5] + rr * (cam[6] + rr * cam[9]))
    xd = a * radial + 2.0 * cam[7] * a * b + cam[8] * (r2 + 2.0 * a * a)
    yd = b * radial + cam[7] * (r2 + 2.0 * b * b) + 2.0 * cam[8] * a * b
    return cam[0] * (xd + cam[4] * yd) + cam[2], cam[1] * yd + cam[3]


@nb.njit(cache=True, nogil=True, inline="always")
def _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, c, s, cam):
    """Project the rim point ``S + c (a r X) + s (b r Y)`` (``c, s = cos th, sin th``) into ``poly[k, i]``."""
    px = Sx + c * ax + s * bx
    py = Sy + c * ay + s * by
    pz = Sz + c * az + s * bz
    u, v = project_cam_point(px, py, pz, cam)
    poly[k, i, 0] = u
    poly[k, i, 1] = v
    poly[k, i, 2] = pz


@nb.njit(cache=True, nogil=True)
def _emit_arc(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, th0, c0, s0, th1, c1, s1, forward,
              ctab, stab, cam):
    """Emit the arc ``[th0, th1]`` (``th0 < th1``; cosines/sines of the ends given): its end points and
    the grid angles ``2 pi j / n_rim`` strictly inside, increasing when ``forward`` else decreasing.
    Returns the next free index."""
    n_rim = ctab.shape[0]
    step = TWO_PI / n_rim
    if forward:
        _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, c0, s0, cam)
        i += 1
        j = int(math.floor(th0 / step)) + 1
        while j * step < th1 - _ANGLE_EPS:
            if j * step > th0 + _ANGLE_EPS:
                jj = j
                while jj >= n_rim:  # (cheaper than %; j < 3 n_rim here)
                    jj -= n_rim
                _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, ctab[jj], stab[jj], cam)
                i += 1
            j += 1
        _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, c1, s1, cam)
        i += 1
    else:
        _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, c1, s1, cam)
        i += 1
        j = int(math.ceil(th1 / step)) - 1
        while j * step > th0 + _ANGLE_EPS:
            if j * step < th1 - _ANGLE_EPS:
                jj = j
                while jj >= n_rim:
                    jj -= n_rim
                _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, ctab[jj], stab[jj], cam)
                i += 1
            j -= 1
        _emit(poly, k, i, Sx, Sy, Sz, ax, ay, az, bx, by, bz, c0, s0, cam)
        i += 1
    return i


@nb.njit(cache=True, nogil=True, inline="always")
def cone_outline(T, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                 k, poly, sides, axis, info, bbox, orient):
    """Outline polygon of cone ``k`` of one pose in one view (definition: :mod:`swarmpose.render`).

    Parameters
    ----------
    T : (J, 3, 4) world_from_joint transforms of the pose.
    joint, start, end, semi_a, semi_b, scale : the cone tables (:class:`~swarmpose.render.project.ConeTables`).
    Rc, tc, cam : the view's ``cam_from_world`` rotation (3, 3), translation (3,) and intrinsics (11,).
    ctab, stab : (n_rim,) cosines and sines of the rim grid angles ``2 pi j / n_rim``.
    near : near-plane margin in mm.
    k : cone index; the outputs are written at ``[k]``.

    Returns
    -------
    int
        Number of vertices (0: the cone is not drawn, it reaches to within ``near`` of the camera plane).
    """
    n_rim = ctab.shape[0]
    j = joint[k]
    # cap centres in the world, then in the camera frame: c = Rc S + tc; cap axes X, Y = Rc (joint x, y)
    s0x = T[j, 0, 0] * start[k, 0] + T[j, 0, 1] * start[k, 1] + T[j, 0, 2] * start[k, 2] + T[j, 0, 3]
    s0y = T[j, 1, 0] * start[k, 0] + T[j, 1, 1] * start[k, 1] + T[j, 1, 2] * start[k, 2] + T[j, 1, 3]
    s0z = T[j, 2, 0] * start[k, 0] + T[j, 2, 1] * start[k, 1] + T[j, 2, 2] * start[k, 2] + T[j, 2, 3]
    s1x = T[j, 0, 0] * end[k, 0] + T[j, 0, 1] * end[k, 1] + T[j, 0, 2] * end[k, 2] + T[j, 0, 3]
    s1y = T[j, 1, 0] * end[k, 0] + T[j, 1, 1] * end[k, 1] + T[j, 1, 2] * end[k, 2] + T[j, 1, 3]
    s1z = T[j, 2, 0] * end[k, 0] + T[j, 2, 1] * end[k, 1] + T[j, 2, 2] * end[k, 2] + T[j, 2, 3]
    c0x = Rc[0, 0] * s0x + Rc[0, 1] * s0y + Rc[0, 2] * s0z + tc[0]
    c0y = Rc[1, 0] * s0x + Rc[1, 1] * s0y + Rc[1, 2] * s0z + tc[1]
    c0z = Rc[2, 0] * s0x + Rc[2, 1] * s0y + Rc[2, 2] * s0z + tc[2]
    c1x = Rc[0, 0] * s1x + Rc[0, 1] * s1y + Rc[0, 2] * s1z + tc[0]
    c1y = Rc[1, 0] * s1x + Rc[1, 1] * s1y + Rc[1, 2] * s1z + tc[1]
    c1z = Rc[2, 0] * s1x + Rc[2, 1] * s1y + Rc[2, 2] * s1z + tc[2]
    Xx = Rc[0, 0] * T[j, 0, 0] + Rc[0, 1] * T[j, 1, 0] + Rc[0, 2] * T[j, 2, 0]
    Xy = Rc[1, 0] * T[j, 0, 0] + Rc[1, 1] * T[j, 1, 0] + Rc[1, 2] * T[j, 2, 0]
    Xz = Rc[2, 0] * T[j, 0, 0] + Rc[2, 1] * T[j, 1, 0] + Rc[2, 2] * T[j, 2, 0]
    Yx = Rc[0, 0] * T[j, 0, 1] + Rc[0, 1] * T[j, 1, 1] + Rc[0, 2] * T[j, 2, 1]
    Yy = Rc[1, 0] * T[j, 0, 1] + Rc[1, 1] * T[j, 1, 1] + Rc[1, 2] * T[j, 2, 1]
    Yz = Rc[2, 0] * T[j, 0, 1] + Rc[2, 1] * T[j, 1, 1] + Rc[2, 2] * T[j, 2, 1]
    A0 = semi_a[k]
    B0 = semi_b[k]
    s = scale[k]
    rmax = max(A0, B0)
    info[k, 0] = 0
    info[k, 1] = 0
    info[k, 2] = 0
    info[k, 3] = 0
    if c0z < near + rmax or c1z < near + rmax * s:
        return 0
    u, v = project_cam_point(c0x, c0y, c0z, cam)
    axis[k, 0, 0] = u
    axis[k, 0, 1] = v
    axis[k, 0, 2] = c0z
    u, v = project_cam_point(c1x, c1y, c1z, cam)
    axis[k, 1, 0] = u
    axis[k, 1, 1] = v
    axis[k, 1, 2] = c1z
    # Z = X x Y (cap normal), A = S1 - S0, d = S0 - camera centre = c0, w = d x A
    Zx = Xy * Yz - Xz * Yy
    Zy = Xz * Yx - Xx * Yz
    Zz = Xx * Yy - Xy * Yx
    Ax = c1x - c0x
    Ay = c1y - c0y
    Az = c1z - c0z
    wx = c0y * Az - c0z * Ay
    wy = c0z * Ax - c0x * Az
    wz = c0x * Ay - c0y * Ax
    wX = wx * Xx + wy * Xy + wz * Xz
    wY = wx * Yx + wy * Yy + wz * Yz
    dZ = c0x * Zx + c0y * Zy + c0z * Zz
    AZ = Ax * Zx + Ay * Zy + Az * Zz
    sg = 1.0 if AZ > 0.0 else -1.0
    # the lateral surface faces the camera at rim angle th iff alpha cos th + beta sin th + gamma > 0
    alpha = sg * B0 * wY
    beta = -sg * A0 * wX
    gamma = sg * A0 * B0 * ((s - 1.0) * dZ - AZ)
    cap0_front = sg * dZ > 0.0
    cap1_front = sg * (dZ + AZ) < 0.0
    # rim point offsets: start cap (a X, b Y), end cap s (a X, b Y)
    a0x = A0 * Xx
    a0y = A0 * Xy
    a0z = A0 * Xz
    b0x = B0 * Yx
    b0y = B0 * Yy
    b0z = B0 * Yz
    R = math.sqrt(alpha * alpha + beta * beta)
    nv = 0
    if R <= abs(gamma):
        # no silhouette generators: the outline is one whole rim
        lat_front = gamma > 0.0
        use0 = lat_front != cap0_front
        use1 = lat_front != cap1_front
        if use0 == use1:  # degenerate (numerically): take the larger cap
            use1 = s > 1.0
        if use1:
            for i in range(n_rim):
                _emit(poly, k, i, c1x, c1y, c1z, s * a0x, s * a0y, s * a0z, s * b0x, s * b0y, s * b0z,
                      ctab[i], stab[i], cam)
            info[k, 1] = 0
            info[k, 2] = n_rim
            info[k, 3] = 1
        else:
            for i in range(n_rim):
                _emit(poly, k, i, c0x, c0y, c0z, a0x, a0y, a0z, b0x, b0y, b0z, ctab[i], stab[i], cam)
        nv = n_rim
    else:
        phi = math.atan2(beta, alpha)
        cd = -gamma / R
        delta = math.acos(cd)
        # tangent angles phi -/+ delta without more trigonometry
        cp = alpha / R
        sp = beta / R
        sd = math.sqrt(max(0.0, 1.0 - cd * cd))
        cm = cp * cd + sp * sd  # cos(phi - delta)
        sm = sp * cd - cp * sd  # sin(phi - delta)
        cq = cp * cd - sp * sd  # cos(phi + delta)
        sq = sp * cd + cp * sd  # sin(phi + delta)
        # front arc (f0, f1) = (phi - delta, phi + delta), back arc (f1, f0 + 2 pi)
        f0 = (phi - delta) % TWO_PI
        f1 = f0 + 2.0 * delta
        # a cap's rim is on the outline where exactly one of (cap, lateral surface) faces the camera
        if cap0_front:
            nv = _emit_arc(poly, k, 0, c0x, c0y, c0z, a0x, a0y, a0z, b0x, b0y, b0z,
                           f1, cq, sq, f0 + TWO_PI, cm, sm, True, ctab, stab, cam)
        else:
            nv = _emit_arc(poly, k, 0, c0x, c0y, c0z, a0x, a0y, a0z, b0x, b0y, b0z,
                           f0, cm, sm, f1, cq, sq, True, ctab, stab, cam)
        info[k, 1] = nv
        forward = cap0_front != cap1_front  # arc 1 starts where arc 0 ended
        if cap1_front:
            nv = _emit_arc(poly, k, nv, c1x, c1y, c1z, s * a0x, s * a0y, s * a0z, s * b0x, s * b0y, s * b0z,
                           f1, cq, sq, f0 + TWO_PI, cm, sm, forward, ctab, stab, cam)
        else:
            nv = _emit_arc(poly, k, nv, c1x, c1y, c1z, s * a0x, s * a0y, s * a0z, s * b0x, s * b0y, s * b0z,
                           f0, cm, sm, f1, cq, sq, forward, ctab, stab, cam)
        info[k, 2] = nv
        info[k, 0] = 1
        # side 0: generator at the end of arc 0; side 1: at its start
        i0 = info[k, 1] - 1
        for q in range(3):
            sides[k, 0, 0, q] = poly[k, i0, q]
            sides[k, 0, 1, q] = poly[k, i0 + 1, q]
            sides[k, 1, 0, q] = poly[k, 0, q]
            sides[k, 1, 1, q] = poly[k, nv - 1, q]
    umin = np.inf
    umax = -np.inf
    vmin = np.inf
    vmax = -np.inf
    area = 0.0
    for i in range(nv):
        u = poly[k, i, 0]
        v = poly[k, i, 1]
        umin = min(umin, u)
        umax = max(umax, u)
        vmin = min(vmin, v)
        vmax = max(vmax, v)
        i2 = i + 1 if i + 1 < nv else 0
        area += u * poly[k, i2, 1] - poly[k, i2, 0] * v
    bbox[k, 0] = umin
    bbox[k, 1] = umax
    bbox[k, 2] = vmin
    bbox[k, 3] = vmax
    orient[k] = 1.0 if area >= 0.0 else -1.0
    return nv


def rim_tables(n_rim: int) -> tuple[np.ndarray, np.ndarray]:
    """``cos`` and ``sin`` of the rim grid angles ``2 pi j / n_rim``, ``j = 0 .. n_rim - 1``."""
    th = TWO_PI * np.arange(n_rim) / n_rim
    return np.cos(th), np.sin(th)


@nb.njit(cache=True, nogil=True, inline="always")
def _bucket_insert(cnt, bl, br, y, l_, r_):
    """Insert span ``[l_, r_]`` into row ``y``'s bucket, kept sorted by left end."""
    m = cnt[y]
    i = m - 1
    while i >= 0 and bl[y, i] > l_:
        bl[y, i + 1] = bl[y, i]
        br[y, i + 1] = br[y, i]
        i -= 1
    bl[y, i + 1] = l_
    br[y, i + 1] = r_
    cnt[y] = m + 1


@nb.njit(cache=True, nogil=True, inline="always")
def bucket_outline(poly, k, n, H, W, cnt, bl, br):
    """Insert the row spans of outline ``k`` (``n >= 3`` vertices) into the rows' buckets ``cnt, bl, br``
    (see :func:`silhouette_counts`): the outline split at its top and bottom vertices into two chains walked
    down the rows with incremental ``x``; on row ``y`` pixels ``ceil(x_min) .. floor(x_max)``, clipped to
    the image."""
    itop = 0
    ibot = 0
    for i in range(1, n):
        if poly[k, i, 1] < poly[k, itop, 1]:
            itop = i
        if poly[k, i, 1] > poly[k, ibot, 1]:
            ibot = i
    y0 = max(int(math.ceil(poly[k, itop, 1])), 0)
    y1 = min(int(math.floor(poly[k, ibot, 1])), H - 1)
    if y0 > y1:
        return
    # chain a: top -> bottom forward, chain b: top -> bottom backward; edge (x0, y0) -> (x1, y1)
    a0 = itop
    a1 = itop + 1 if itop + 1 < n else 0
    b0 = itop
    b1 = itop - 1 if itop > 0 else n - 1
    xa = 0.0
    sa = 0.0
    xb = 0.0
    sb = 0.0
    first = True
    for y in range(y0, y1 + 1):
        fy = float(y)
        if first or (poly[k, a1, 1] <= fy and a1 != ibot):
            while poly[k, a1, 1] <= fy and a1 != ibot:  # next edge (skips horizontal ones)
                a0 = a1
                a1 = a1 + 1 if a1 + 1 < n else 0
            d = poly[k, a1, 1] - poly[k, a0, 1]
            sa = (poly[k, a1, 0] - poly[k, a0, 0]) / d if d > 0.0 else 0.0
            xa = poly[k, a0, 0] + (fy - poly[k, a0, 1]) * sa
        if first or (poly[k, b1, 1] <= fy and b1 != ibot):
            while poly[k, b1, 1] <= fy and b1 != ibot:
                b0 = b1
                b1 = b1 - 1 if b1 > 0 else n - 1
            d = poly[k, b1, 1] - poly[k, b0, 1]
            sb = (poly[k, b1, 0] - poly[k, b0, 0]) / d if d > 0.0 else 0.0
            xb = poly[k, b0, 0] + (fy - poly[k, b0, 1]) * sb
        first = False
        lo_ = min(xa, xb)
        hi_ = max(xa, xb)
        xa += sa
        xb += sb
        lf = max(math.ceil(lo_), 0.0)
        rf = min(math.floor(hi_), W - 1.0)
        if lf <= rf:
            _bucket_insert(cnt, bl, br, y, int(lf), int(rf))


@nb.njit(cache=True, nogil=True, inline="always")
def row_range(poly, nvs, valid, K, H):
    """``(Ymin, Ymax)``: the image rows the drawn outlines (``valid``, three vertices or more) can cover;
    ``Ymin > Ymax`` when none."""
    Ymin = H
    Ymax = -1
    for k in range(K):
        if not valid[k] or nvs[k] < 3:
            continue
        for i in range(nvs[k]):
            yy = poly[k, i, 1]
            if yy < Ymin:
                Ymin = max(int(math.ceil(yy)), 0)
            if yy > Ymax:
                Ymax = min(int(math.floor(yy)), H - 1)
    return Ymin, Ymax


@nb.njit(cache=True, nogil=True, inline="always")
def bucket_outlines(poly, nvs, valid, K, H, W, cnt, bl, br):
    """The row spans of every drawn outline (``valid``, three vertices or more) in the rows' buckets ``cnt, bl,
    br`` (emptied first over the rows they can cover): returns those rows ``(Ymin, Ymax)`` (:func:`row_range`)."""
    Ymin, Ymax = row_range(poly, nvs, valid, K, H)
    for y in range(Ymin, Ymax + 1):
        cnt[y] = 0
    for k in range(K):
        if valid[k] and nvs[k] >= 3:
            bucket_outline(poly, k, nvs[k], H, W, cnt, bl, br)
    return Ymin, Ymax


@nb.njit(cache=True, nogil=True)
def silhouette_counts(poly, nvs, valid, K, H, W, prefix, v, cnt, bl, br):
    """``(Y, P)`` of the union of the drawn outlines in view ``v`` by the scanline rule.

    Each outline is split at its top and bottom vertices into two chains that are walked down the
    image rows with incremental ``x`` (the classic polygon scan conversion); on row ``y`` the outline
    covers ``[x_min(y), x_max(y)]`` between the two chains' crossings, i.e. pixels
    ``ceil(x_min) .. floor(x_max)`` (clipped to the image; a crossing exactly on a pixel centre
    counts). That span is inserted, sorted by left end, into the row's bucket; then each row's spans
    are merged and counted: ``P`` covered pixels, ``Y`` of them in the observed silhouette, read from
    the row prefix sums ``prefix[v]`` (thesis eq. 5.2-5.4 need only these: ``R = |O| - Y``,
    ``B = P - Y``). No mask is built. For a convex outline the chains' crossings are the row's
    extreme crossings, so the pixel set is the pixel-centre rule of :mod:`swarmpose.render`.

    Scratch: ``cnt (H,)``, ``bl, br (H, K)`` integer.
    """
    Ymin, Ymax = bucket_outlines(poly, nvs, valid, K, H, W, cnt, bl, br)
    if Ymin > Ymax:
        return 0, 0
    Ycount = 0
    Pcount = 0
    for y in range(Ymin, Ymax + 1):
        M = -1  # right end of the merged cover so far
        for i in range(cnt[y]):
            st = max(bl[y, i], M + 1)
            r_ = br[y, i]
            if r_ >= st:
                Pcount += r_ - st + 1
                Ycount += prefix[v, y, r_ + 1] - prefix[v, y, st]
                M = r_
    return Ycount, Pcount


@nb.njit(cache=True, nogil=True, inline="always")
def hidden(x, y, z, k, valid, K, poly, nvs, bbox, axis, orient):
    """True when image point ``(x, y)`` at depth ``z`` on cone ``k`` is covered by the outline of
    another drawn cone whose axis is nearer there (depth of that cone's axis at the point's
    orthogonal projection onto its projected axis, clamped to the segment)."""
    for j in range(K):
        if j == k or not valid[j]:
            continue
        if x < bbox[j, 0] or x > bbox[j, 1] or y < bbox[j, 2] or y > bbox[j, 3]:
            continue
        zj = axis_depth_at(j, x, y, axis)
        if zj >= z:
            continue
        n = nvs[j]
        inside = True
        o = orient[j]
        for i in range(n):
            i2 = i + 1 if i + 1 < n else 0
            cr = ((poly[j, i2, 0] - poly[j, i, 0]) * (y - poly[j, i, 1])
                  - (poly[j, i2, 1] - poly[j, i, 1]) * (x - poly[j, i, 0]))
            if cr * o < 0.0:
                inside = False
                break
        if inside:
            return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def clip_segment(px, py, qx, qy, j, poly, nvs, bbox, orient):
    """Parameter interval ``[t_in, t_out]`` within ``[0, 1]`` of the segment ``p + t (q - p)`` inside the
    closed convex outline ``j`` (Cyrus-Beck: the half-plane conditions of :func:`hidden` are linear in
    ``t``); ``t_in > t_out`` when the segment misses it."""
    if (max(px, qx) < bbox[j, 0] or min(px, qx) > bbox[j, 1]
            or max(py, qy) < bbox[j, 2] or min(py, qy) > bbox[j, 3]):
        return 1.0, 0.0
    dx = qx - px
    dy = qy - py
    # t_in = max(0, max over edges with f1 > 0 of -f0 / f1), t_out = min(1, min over f1 < 0 of f0 / -f1),
    # kept as fractions (num, den > 0), compared by cross-multiplication, with an early exit when the
    # interval becomes empty; one division at the end
    in_n = 0.0
    in_d = 1.0
    out_n = 1.0
    out_d = 1.0
    n = nvs[j]
    o = orient[j]
    for i in range(n):
        i2 = i + 1 if i + 1 < n else 0
        ex = poly[j, i2, 0] - poly[j, i, 0]
        ey = poly[j, i2, 1] - poly[j, i, 1]
        # f(t) = o (e x (p + t d - a)) = f0 + t f1 must be >= 0
        f0 = o * (ex * (py - poly[j, i, 1]) - ey * (px - poly[j, i, 0]))
        f1 = o * (ex * dy - ey * dx)
        if f1 > 0.0:
            if -f0 * in_d > in_n * f1:
                in_n = -f0
                in_d = f1
        elif f1 < 0.0:
            if f0 * out_d < out_n * -f1:
                out_n = f0
                out_d = -f1
        elif f0 < 0.0:
            return 1.0, 0.0
        if in_n * out_d > out_n * in_d:
            return 1.0, 0.0
    return in_n / in_d, out_n / out_d


@nb.njit(cache=True, nogil=True, inline="always")
def axis_param(j, x, y, axis):
    """The parameter ``t`` in ``[0, 1]`` of the orthogonal projection of ``(x, y)`` onto cone ``j``'s projected
    axis (``t = 1/2`` for a point-like axis)."""
    ax = axis[j, 0, 0]
    ay = axis[j, 0, 1]
    dx = axis[j, 1, 0] - ax
    dy = axis[j, 1, 1] - ay
    L2 = dx * dx + dy * dy
    t = 0.5
    if L2 > 1e-12:
        t = ((x - ax) * dx + (y - ay) * dy) / L2
        t = min(max(t, 0.0), 1.0)
    return t


@nb.njit(cache=True, nogil=True, inline="always")
def axis_depth_at(j, x, y, axis):
    """Depth of cone ``j``'s axis at the orthogonal projection of ``(x, y)`` onto its projected axis
    (clamped to the segment; ``t = 1/2`` for a point-like axis)."""
    t = axis_param(j, x, y, axis)
    return axis[j, 0, 2] + t * (axis[j, 1, 2] - axis[j, 0, 2])


@nb.njit(cache=True, nogil=True, inline="always")
def n_samples(length, spacing):
    """Number of samples on a line of ``length`` px: ``max(1, floor(length / spacing + 0.5))``."""
    return max(1, int(math.floor(length / spacing + 0.5)))


@nb.njit(cache=True, nogil=True, inline="always")
def pixel_value(img, v, x, y):
    """``img[v, floor(y + 0.5), floor(x + 0.5)]`` (nearest pixel centre), 0 outside the image."""
    H = img.shape[1]
    W = img.shape[2]
    xi = math.floor(x + 0.5)
    yi = math.floor(y + 0.5)
    if xi < 0 or yi < 0 or xi >= W or yi >= H:
        return 0.0
    return float(img[v, int(yi), int(xi)])
