"""Plain numpy/OpenCV implementation of the render definitions: simple, slow, obviously right.

It is the ground truth the numba fast path is tested against, and the engine of the
``"reference"`` fitness backend. It shares no code with the numba kernels: kinematics is
:func:`~swarmpose.body.kinematics.forward_kinematics_reference`, cones are placed by
:meth:`BodyModel.cones`, points are projected by :meth:`Camera.project`, footprints are the
convex hull (monotone chain, float64) of all rim points rasterised by a per-pixel half-plane test, and occlusion is a
per-sample point-in-hull test. Python loops over poses, views and cones are fine here.

Definitions: see :mod:`swarmpose.render`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarmpose.camera import Camera
from swarmpose.render.project import (
    DEFAULT_N_RIM,
    DEFAULT_NEAR_MM,
    ProjectedCones,
    camera_tables,
    cone_tables,
    max_vertices,
)

__all__ = ["project_cones_reference", "reference_geometry", "ReferenceGeometry", "rasterize_convex",
           "union_mask", "convex_hull", "line_samples", "polyline_samples", "point_in_convex", "edge_samples_reference",
           "region_samples_reference", "nearest_pixel_values"]

_EPS = 1e-9


@dataclass(frozen=True)
class ReferenceGeometry:
    """:class:`ProjectedCones` plus, per cone and view, the points whose convex hull is the footprint.

    Attributes
    ----------
    cones : ProjectedCones
    hulls : list (N) of list (C) of list (K) of (H_k, 2) float64 arrays or None
        Convex hull (counter-clockwise in ``(u, v)``) of all ``2 * n_rim`` rim grid points of both caps
        plus the four silhouette-line end points; ``None`` where the cone is not drawn.
    width, height : int
    """

    cones: ProjectedCones
    hulls: list
    width: int
    height: int


def _arc_angles(th0: float, th1: float, forward: bool, n_rim: int) -> list[float]:
    """End points and the grid angles ``2 pi j / n_rim`` strictly inside ``[th0, th1]``."""
    step = 2 * math.pi / n_rim
    inner = [j * step for j in range(math.floor(th0 / step) - 1, math.ceil(th1 / step) + 2)
             if th0 + _EPS < j * step < th1 - _EPS]
    seq = [th0, *inner, th1]
    return seq if forward else seq[::-1]


def reference_geometry(model, poses: np.ndarray, cameras: Sequence[Camera], *, n_rim: int = DEFAULT_N_RIM,
                       near: float = DEFAULT_NEAR_MM) -> ReferenceGeometry:
    """Outlines and footprint hulls of ``N`` poses in ``C`` views (numpy; loops over poses/views/cones).

    The silhouette lines of a truncated cone with similar elliptical caps (semi-axes ``a, b`` at the
    start, ``s a, s b`` at the end, in the plane spanned by the joint frame's x, y axes ``X, Y`` with
    normal ``Z``; axis ``A = S1 - S0``; camera centre ``c``; ``d = S0 - c``) touch the start rim at
    the angles ``th`` where the lateral surface's normal is orthogonal to the viewing ray::

        alpha cos th + beta sin th + gamma = 0,
        alpha = sg b (d x A).Y,  beta = -sg a (d x A).X,  gamma = sg a b ((s - 1) d.Z - A.Z),

    with ``sg = sign(A.Z)``; the surface faces the camera where the left side is positive. A cap's
    rim lies on the outline where exactly one of (cap, lateral surface) faces the camera.
    """
    p = model.check_poses(poses)
    cams = list(cameras)
    _, _, _, W, H = camera_tables(cams)
    ct = cone_tables(model)
    T = model.forward(p, reference=True)
    pc = model.cones(p, transforms=T)
    N, K, C = p.shape[0], len(ct.names), len(cams)
    P = max_vertices(n_rim)
    verts = np.full((N, C, K, P, 2), np.nan)
    depth = np.full((N, C, K, P), np.nan)
    nvs = np.zeros((N, C, K), np.int64)
    sides = np.full((N, C, K, 2, 2, 2), np.nan)
    side_depth = np.full((N, C, K, 2, 2), np.nan)
    axis = np.full((N, C, K, 2, 2), np.nan)
    axis_depth = np.full((N, C, K, 2), np.nan)
    end_arc = np.zeros((N, C, K, 2), np.int64)
    closed = np.zeros((N, C, K), bool)
    hulls = [[[None] * K for _ in range(C)] for _ in range(N)]
    a0, b0, s = ct.semi_a, ct.semi_b, ct.scale
    grid = 2 * math.pi * np.arange(n_rim) / n_rim
    for c, cam in enumerate(cams):
        S0 = cam.cam_from_world(pc.start)  # (N, K, 3)
        S1 = cam.cam_from_world(pc.end)
        X = pc.axis_x @ cam.R.T
        Y = pc.axis_y @ cam.R.T
        Z = np.cross(X, Y)
        A = S1 - S0
        w = np.cross(S0, A)  # d x A with d = S0 - (camera centre = 0)
        sg = np.where(np.einsum("nki,nki->nk", A, Z) > 0, 1.0, -1.0)
        dZ = np.einsum("nki,nki->nk", S0, Z)
        AZ = np.einsum("nki,nki->nk", A, Z)
        alpha = sg * b0 * np.einsum("nki,nki->nk", w, Y)
        beta = -sg * a0 * np.einsum("nki,nki->nk", w, X)
        gamma = sg * a0 * b0 * ((s - 1.0) * dZ - AZ)
        cap0_front = sg * dZ > 0
        cap1_front = sg * (dZ + AZ) < 0
        # 1) the outline's (cap, angle) sequence per pose and cone (Python; the closed-form rule)
        cap_of = np.zeros((N, K, P), np.int64)
        ang = np.zeros((N, K, P))
        count = np.zeros((N, K), np.int64)
        arc0_len = np.zeros((N, K), np.int64)
        tangents = np.zeros((N, K), bool)
        for n in range(N):
            for k in range(K):
                rmax = max(a0[k], b0[k])
                if S0[n, k, 2] < near + rmax or S1[n, k, 2] < near + rmax * s[k]:
                    continue  # not drawn
                R = math.hypot(alpha[n, k], beta[n, k])
                if R <= abs(gamma[n, k]):
                    # no silhouette generators: one whole rim
                    lat_front = gamma[n, k] > 0
                    use0 = lat_front != cap0_front[n, k]
                    use1 = lat_front != cap1_front[n, k]
                    if use0 == use1:
                        use1 = s[k] > 1.0
                    seq = [(1 if use1 else 0, th) for th in grid]
                    n0 = 0 if use1 else len(seq)
                    closed[n, c, k] = bool(use1)
                else:
                    phi = math.atan2(beta[n, k], alpha[n, k])
                    delta = math.acos(-gamma[n, k] / R)
                    f0 = (phi - delta) % (2 * math.pi)
                    front = (f0, f0 + 2 * delta)
                    back = (f0 + 2 * delta, f0 + 2 * math.pi)
                    seq = [(0, th) for th in _arc_angles(*(back if cap0_front[n, k] else front), True, n_rim)]
                    n0 = len(seq)
                    fwd = bool(cap0_front[n, k] != cap1_front[n, k])  # arc 1 starts where arc 0 ended
                    seq += [(1, th) for th in _arc_angles(*(back if cap1_front[n, k] else front), fwd, n_rim)]
                    tangents[n, k] = True
                m = len(seq)
                count[n, k] = m
                arc0_len[n, k] = n0
                cap_of[n, k, :m] = [q for q, _ in seq]
                ang[n, k, :m] = [th for _, th in seq]
        # 2) rim points in the camera frame, projected by the camera model: outline vertices and the
        #    rim grid of both caps (for the footprint hull)
        radius = np.where(cap_of == 1, s[None, :, None], 1.0)[..., None]  # (N, K, P, 1)
        centre = np.where((cap_of == 1)[..., None], S1[:, :, None, :], S0[:, :, None, :])
        P3 = centre + radius * (a0[None, :, None, None] * np.cos(ang)[..., None] * X[:, :, None, :]
                                + b0[None, :, None, None] * np.sin(ang)[..., None] * Y[:, :, None, :])
        with np.errstate(all="ignore"):  # cones behind the camera (not drawn) give inf/nan
            uv = cam.project(cam.world_from_cam(P3))
        cg, sgr = np.cos(grid)[:, None], np.sin(grid)[:, None]
        off = (a0[None, :, None, None] * cg * X[:, :, None, :]
               + b0[None, :, None, None] * sgr * Y[:, :, None, :])  # (N, K, n_rim, 3): a cos X + b sin Y
        rims = np.concatenate([S0[:, :, None, :] + off, S1[:, :, None, :] + s[None, :, None, None] * off], axis=2)
        with np.errstate(all="ignore"):
            rim_uv = cam.project(cam.world_from_cam(rims))  # (N, K, 2 n_rim, 2)
            centres_uv = cam.project(cam.world_from_cam(np.stack([S0, S1], axis=2)))  # (N, K, 2, 2)
        # 3) fill the outputs; footprint = convex hull of outline vertices and rim grid points
        for n in range(N):
            for k in range(K):
                m = int(count[n, k])
                if not m:
                    continue
                n0 = int(arc0_len[n, k])
                verts[n, c, k, :m] = uv[n, k, :m]
                depth[n, c, k, :m] = P3[n, k, :m, 2]
                nvs[n, c, k] = m
                if tangents[n, k]:
                    end_arc[n, c, k] = (n0, m)
                    # side 0: generator at the end of arc 0 (vertices n0-1, n0); side 1: at its start (0, m-1)
                    sides[n, c, k, 0] = uv[n, k, [n0 - 1, n0]]
                    side_depth[n, c, k, 0] = P3[n, k, [n0 - 1, n0], 2]
                    sides[n, c, k, 1] = uv[n, k, [0, m - 1]]
                    side_depth[n, c, k, 1] = P3[n, k, [0, m - 1], 2]
                elif closed[n, c, k]:
                    end_arc[n, c, k] = (0, m)
                axis[n, c, k] = centres_uv[n, k]
                axis_depth[n, c, k] = (S0[n, k, 2], S1[n, k, 2])
                hulls[n][c][k] = convex_hull(np.concatenate([uv[n, k, :m], rim_uv[n, k]]))
    cones = ProjectedCones(vertices=verts, depth=depth, n_vertices=nvs, sides=sides, side_depth=side_depth,
                           axis=axis, axis_depth=axis_depth, end_arc=end_arc, end_arc_closed=closed)
    return ReferenceGeometry(cones=cones, hulls=hulls, width=W, height=H)


def project_cones_reference(model, poses: np.ndarray, cameras: Sequence[Camera], *, n_rim: int = DEFAULT_N_RIM,
                            near: float = DEFAULT_NEAR_MM) -> ProjectedCones:
    """:func:`swarmpose.render.project_cones` in plain numpy (see :func:`reference_geometry`)."""
    return reference_geometry(model, poses, cameras, n_rim=n_rim, near=near).cones


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull in float64 (Andrew's monotone chain), counter-clockwise in ``(u, v)`` (positive
    signed area), collinear points dropped. ``(M, 2)`` -> ``(H, 2)``.

    (``cv2.convexHull`` works in float32; near-coincident rim points then yield a hull that is not
    convex in float64, and one extended edge can cut pixels off.)
    """
    pts = sorted(set(map(tuple, np.asarray(points, np.float64))))
    if len(pts) <= 2:
        return np.array(pts, np.float64).reshape(-1, 2)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], np.float64)


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def point_in_convex(poly: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Closed point-in-polygon test for a convex polygon with positive signed area.

    Parameters
    ----------
    poly : (M, 2) vertices, counter-clockwise in ``(u, v)`` (positive :func:`_signed_area`).
    x, y : arrays of one shape
        Query points.

    Returns
    -------
    bool array of the shape of ``x``: ``(b - a) x (p - a) >= 0`` for every edge ``a -> b``.
    """
    a = np.asarray(poly, np.float64)
    b = np.roll(a, -1, axis=0)
    x = np.asarray(x, np.float64)[..., None]
    y = np.asarray(y, np.float64)[..., None]
    cross = (b[:, 0] - a[:, 0]) * (y - a[:, 1]) - (b[:, 1] - a[:, 1]) * (x - a[:, 0])  # (..., M)
    return np.all(cross >= 0.0, axis=-1)


def rasterize_convex(poly: np.ndarray, width: int, height: int, out: np.ndarray | None = None) -> np.ndarray:
    """Pixels whose centre lies inside or on a convex polygon (the pixel rule of :mod:`swarmpose.render`).

    A pixel centre ``(x, y)`` is inside when ``(b - a) x (p - a) >= 0`` for every counter-clockwise
    edge ``a -> b``. For the pixel row ``y`` each inequality is linear in ``x``:
    ``e_y x <= e_x (y - a_y) + e_y a_x`` with ``e = b - a``; solved for ``x`` (upper bound where
    ``e_y > 0``, lower bound where ``e_y < 0``, a pass/fail test on ``y`` where ``e_y = 0``) the row's
    inside pixels are the integers between the largest lower and the smallest upper bound.

    Parameters
    ----------
    poly : (M, 2) float
        Convex polygon, counter-clockwise in ``(u, v)`` (positive signed area).
    width, height : int
    out : (height, width) bool, optional
        OR-ed into in place (union of several polygons).

    Returns
    -------
    (height, width) bool
    """
    mask = np.zeros((height, width), bool) if out is None else out
    a = np.asarray(poly, np.float64)
    y0 = max(math.ceil(a[:, 1].min()), 0)
    y1 = min(math.floor(a[:, 1].max()), height - 1)
    if y0 > y1 or len(a) < 3:
        return mask
    b = np.roll(a, -1, axis=0)
    ex, ey = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    y = np.arange(y0, y1 + 1, dtype=np.float64)[:, None]  # (rows, 1)
    rhs = ex * (y - a[:, 1]) + ey * a[:, 0]  # (rows, M): inside iff ey * x <= rhs
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = rhs / ey
    lo = np.max(np.where(ey < 0, bound, -np.inf), axis=1)
    hi = np.min(np.where(ey > 0, bound, np.inf), axis=1)
    ok = np.all((ey != 0) | (rhs >= 0), axis=1)  # horizontal edges: 0 <= ex (y - a_y)
    lo = np.maximum(np.ceil(lo), 0)
    hi = np.minimum(np.floor(hi), width - 1)
    for r in np.flatnonzero(ok & (lo <= hi)):
        mask[y0 + r, int(lo[r]):int(hi[r]) + 1] = True
    return mask


def union_mask(geom: ReferenceGeometry, n: int, c: int) -> np.ndarray:
    """``(H, W)`` bool union of the footprints of pose ``n`` in view ``c``."""
    mask = np.zeros((geom.height, geom.width), bool)
    for hull in geom.hulls[n][c]:
        if hull is not None:
            rasterize_convex(hull, geom.width, geom.height, out=mask)
    return mask


def line_samples(p: np.ndarray, q: np.ndarray, zp: float, zq: float, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """``n = max(1, floor(|q - p| / spacing + 1/2))`` points at ``t = (i + 1/2) / n`` on ``p -> q``,
    with linearly interpolated depth. Returns ``(n, 2)`` points and ``(n,)`` depths."""
    L = float(np.hypot(*(q - p)))
    n = max(1, math.floor(L / spacing + 0.5))
    t = (np.arange(n) + 0.5) / n
    return p + t[:, None] * (q - p), zp + t * (zq - zp)


def polyline_samples(pts: np.ndarray, z: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples at arc lengths ``(i + 1/2) L / n`` on a polyline of length ``L`` (``n`` as in
    :func:`line_samples`), depths interpolated along each segment."""
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    L = float(cum[-1])
    n = max(1, math.floor(L / spacing + 0.5))
    sarc = (np.arange(n) + 0.5) * L / n
    x = np.interp(sarc, cum, pts[:, 0])
    y = np.interp(sarc, cum, pts[:, 1])
    return np.stack([x, y], axis=1), np.interp(sarc, cum, z)


def _hidden(geom: ReferenceGeometry, n: int, c: int, k: int, xy: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Samples of cone ``k`` inside the footprint of another drawn cone whose axis is nearer there."""
    pc = geom.cones
    hid = np.zeros(len(z), bool)
    if not len(z):
        return hid
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    for j, hull in enumerate(geom.hulls[n][c]):
        if j == k or hull is None:
            continue
        if (hull.max(axis=0) < lo).any() or (hull.min(axis=0) > hi).any():
            continue  # bounding boxes apart
        a0, a1 = pc.axis[n, c, j]
        d = a1 - a0
        L2 = float(d @ d)
        t = np.clip(((xy - a0) @ d) / L2, 0.0, 1.0) if L2 > 1e-12 else np.full(len(z), 0.5)
        zj = pc.axis_depth[n, c, j, 0] + t * (pc.axis_depth[n, c, j, 1] - pc.axis_depth[n, c, j, 0])
        cand = (zj < z) & ~hid
        if cand.any():
            idx = np.flatnonzero(cand)
            hid[idx] = point_in_convex(hull, xy[idx, 0], xy[idx, 1])
    return hid


def edge_samples_reference(geom: ReferenceGeometry, n: int, c: int, cone_mask: np.ndarray, top_cone: int,
                           spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Edge sample points of pose ``n`` in view ``c`` (thesis sec. 5.2.1, Fig. 5.3).

    Parameters
    ----------
    cone_mask : (K,) bool
        Cones whose two silhouette lines are sampled.
    top_cone : int
        Cone whose end-cap outline arc is also sampled (the torso's upper edge), ``-1`` for none.
    spacing : float
        Sample spacing in pixels.

    Returns
    -------
    points (S, 2), depth (S,), cone (S,) int, visible (S,) bool
    """
    pc = geom.cones
    pts, zs, ks = [], [], []
    for k in range(len(cone_mask)):
        if not pc.n_vertices[n, c, k]:
            continue
        if cone_mask[k] and not np.isnan(pc.sides[n, c, k, 0, 0, 0]):
            for side in range(2):
                xy, z = line_samples(pc.sides[n, c, k, side, 0], pc.sides[n, c, k, side, 1],
                                     pc.side_depth[n, c, k, side, 0], pc.side_depth[n, c, k, side, 1], spacing)
                pts.append(xy)
                zs.append(z)
                ks.append(np.full(len(z), k))
        if k == top_cone:
            i0, i1 = pc.end_arc[n, c, k]
            if i1 - i0 >= 2 or (pc.end_arc_closed[n, c, k] and i1 > i0):
                idx = list(range(i0, i1)) + ([i0] if pc.end_arc_closed[n, c, k] else [])
                xy, z = polyline_samples(pc.vertices[n, c, k, idx], pc.depth[n, c, k, idx], spacing)
                pts.append(xy)
                zs.append(z)
                ks.append(np.full(len(z), k))
    if not pts:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, bool)
    xy = np.concatenate(pts)
    z = np.concatenate(zs)
    kk = np.concatenate(ks)
    vis = np.ones(len(z), bool)
    for k in np.unique(kk):
        sel = kk == k
        vis[sel] = ~_hidden(geom, n, c, int(k), xy[sel], z[sel])
    return xy, z, kk, vis


def region_samples_reference(geom: ReferenceGeometry, n: int, c: int, spacing: float) -> np.ndarray:
    """Interior grid points of every drawn cone of pose ``n`` in view ``c`` (Deutscher & Reid Fig. 6(b)).

    With silhouette lines, the grid is bilinear in the quadrilateral of the four line end points:
    ``n_t`` steps along the axis (``n_t`` from the projected axis length, ``n_s`` from the larger cap
    width, both as in :func:`line_samples`), points at ``((i + 1/2) / n_t, (j + 1/2) / n_s)``. Without
    (a view along the axis) the points are the outline's vertex centroid ``g`` and
    ``g + (v_i - g) / 2`` for every vertex ``v_i``.

    Returns
    -------
    (S, 2) float64
    """
    pc = geom.cones
    out = []
    for k in range(pc.n_vertices.shape[2]):
        m = int(pc.n_vertices[n, c, k])
        if not m:
            continue
        if not np.isnan(pc.sides[n, c, k, 0, 0, 0]):
            p0, q0 = pc.sides[n, c, k, 0]
            p1, q1 = pc.sides[n, c, k, 1]
            a0, a1 = pc.axis[n, c, k]
            nt = max(1, math.floor(float(np.hypot(*(a1 - a0))) / spacing + 0.5))
            width = max(float(np.hypot(*(p1 - p0))), float(np.hypot(*(q1 - q0))))
            ns = max(1, math.floor(width / spacing + 0.5))
            t = ((np.arange(nt) + 0.5) / nt)[:, None, None]
            u = ((np.arange(ns) + 0.5) / ns)[None, :, None]
            left = p0 + t * (q0 - p0)
            right = p1 + t * (q1 - p1)
            out.append((left + u * (right - left)).reshape(-1, 2))
        else:
            v = pc.vertices[n, c, k, :m]
            g = v.mean(axis=0)
            out.append(np.concatenate([g[None], g + 0.5 * (v - g)]))
    return np.concatenate(out) if out else np.zeros((0, 2))


def nearest_pixel_values(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``img[floor(y + 1/2), floor(x + 1/2)]`` for ``xy (S, 2)``; 0 outside the image. ``img (H, W)``."""
    xi = np.floor(xy[:, 0] + 0.5)
    yi = np.floor(xy[:, 1] + 0.5)
    H, W = img.shape
    ok = (xi >= 0) & (yi >= 0) & (xi < W) & (yi < H)
    out = np.zeros(len(xy), np.float64)
    out[ok] = img[yi[ok].astype(np.int64), xi[ok].astype(np.int64)]
    return out
