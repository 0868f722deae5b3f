"""Silhouette distance: a smooth measure of silhouette agreement by distance transforms.

The overlap terms (thesis eq. 5.2-5.5, Deutscher & Reid eq. 15) count pixels: a limb that lies beside its
silhouette scores the same wherever it lies, so a search has nothing to follow back to it. This term
measures *how far* the model and the observation are apart, in both directions, and keeps rising all the
way to the person from tens of pixels away.

Each cone is drawn as a 2D *tapered capsule* in each view: the projected axis from ``a`` to ``b`` with
half-widths ``r_a``, ``r_b`` (the cross-section's extent perpendicular to the axis and the viewing ray,
times ``f / depth``). Per view ``c``, with the truncation ``tau`` pixels:

* **model -> observation** ``A_c``: the mean over sample points of every cone (``n_axis`` positions along
  the axis x ``ACROSS`` offsets across it) of ``min(d_out, tau)^2 / tau^2``, where ``d_out`` is the
  distance to the nearest observed silhouette pixel (the distance transform of the silhouette's
  complement, read bilinearly; ``tau`` outside the image). Every cone weighs the same, so a forearm
  outside the silhouette costs as much as a torso.
* **observation -> model** ``B_c``: the mean over observed points (silhouette pixels on a grid of
  ``stride`` pixels, from the connected components of at least ``min_component`` of the largest one) of
  ``min(d_model, tau)^2 / tau^2``, where ``d_model`` is the distance to the nearest capsule
  (``0`` inside one). A silhouette arm that no cone covers pulls the model's arm towards it.

The score is ``-mean_c (A_c + B_c)`` in ``[-2, 0]``, higher is better. :func:`part_distances` gives the
per-cone mean of ``A`` (the second entry point of design.md sec. 7, used for loss detection).

Two implementations of the same definitions: the numba kernel (:func:`distance_terms`) and a plain
numpy reference (:func:`distance_terms_reference`), compared by the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.render._kernels import project_cam_point

#: Hash of the kernel sources this module's cached kernels inline (render/_kernels.py); see
#: tests/test_numba_cache.py (numba's cache does not see edits to other files).
INLINED_SOURCES_SHA1 = "7ffc5a04828d3360"

__all__ = ["DistanceMaps", "FULL_WIDTH_PX", "DEFAULT_TAU_PX", "DEFAULT_STRIDE_PX", "prepare_distance_maps", "distance_terms",
           "distance_terms_reference", "part_distances"]

#: Image width the pixel defaults below refer to (HumanEva's 644 x 484); they scale with the bound frame's.
FULL_WIDTH_PX = 644.0
#: Truncation of the distances, pixels at full resolution (644 x 484): beyond it a sample costs the same.
DEFAULT_TAU_PX = 40.0
#: Grid step of the observed silhouette points, pixels at full resolution.
DEFAULT_STRIDE_PX = 12
#: Samples along each cone's projected axis.
N_AXIS = 6
#: Offsets across the axis, as fractions of the local half-width.
ACROSS = np.array([-0.7, 0.0, 0.7])
#: Observed components smaller than this fraction of the largest are not sampled (noise blobs).
MIN_COMPONENT = 0.02


@dataclass(eq=False)
class DistanceMaps:
    """One frame's state of the distance term, computed once (:func:`prepare_distance_maps`).

    Attributes
    ----------
    outside : (C, H', W') float32
        Distance (pixels of the frame) of each pixel to the nearest observed silhouette pixel (0 on the
        silhouette), on a grid ``scale`` times coarser than the frame.
    scale : int
        Frame pixels per ``outside`` pixel.
    points : (C, M, 2) float64
        Observed silhouette points ``(u, v)`` per view, padded; ``n_points[c]`` of them are used.
    n_points : (C,) int64
    tau, tau_b : float
        Truncation of the model-to-observation and observation-to-model distances, pixels at this
        resolution.
    """

    outside: np.ndarray
    points: np.ndarray
    n_points: np.ndarray
    tau: float
    tau_b: float
    scale: int = 1


def _silhouette_points(sil: np.ndarray, stride: int, min_component: float) -> np.ndarray:
    n, labels, stats, _ = cv2.connectedComponentsWithStats(sil.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros((0, 2))
    areas = stats[1:, cv2.CC_STAT_AREA]
    keep = np.zeros(n, bool)
    keep[1:] = areas >= min_component * areas.max()
    off = stride // 2
    grid = labels[off::stride, off::stride]
    vs, us = np.nonzero(keep[grid])
    return np.stack([us * stride + off, vs * stride + off], axis=1).astype(np.float64)


def prepare_distance_maps(silhouettes: np.ndarray, *, tau: float = DEFAULT_TAU_PX,
                          stride: int = DEFAULT_STRIDE_PX, min_component: float = MIN_COMPONENT,
                          tau_b: float | None = None, scale: int = 1) -> DistanceMaps:
    """Distance transforms (OpenCV, Euclidean with the 5x5 mask) and observed points of ``silhouettes (C, H, W)``.

    ``scale > 1`` computes them on the silhouettes reduced ``scale`` times (a pixel of the reduced image is
    on the silhouette when half of its block is), a quarter of the work at ``scale = 2``; the distances
    stay in frame pixels.

    Raises
    ------
    ConfigError
        ``tau`` not positive or ``stride`` not a whole number >= 1.
    """
    if not tau > 0:
        raise ConfigError(f"distance tau must be > 0 pixels, got {tau!r}")
    if isinstance(stride, bool) or int(stride) != stride or stride < 1:
        raise ConfigError(f"distance stride must be a whole number of pixels >= 1, got {stride!r}")
    if isinstance(scale, bool) or int(scale) != scale or scale < 1:
        raise ConfigError(f"distance scale must be a whole number >= 1, got {scale!r}")
    stride, scale = int(stride), int(scale)
    sil = np.asarray(silhouettes)
    C, H, W = sil.shape
    h, w = -(-H // scale), -(-W // scale)
    outside = np.empty((C, h, w), np.float32)
    pts = []
    for c in range(C):
        s = sil[c]
        if scale > 1:
            padded = np.zeros((h * scale, w * scale), np.float32)
            padded[:H, :W] = s != 0
            s = (padded.reshape(h, scale, w, scale).mean(axis=(1, 3)) >= 0.5).astype(np.uint8)
        comp = (s == 0).astype(np.uint8)
        if comp.all():  # nothing observed: every model point is as far as it can be
            outside[c] = np.float32(tau)
        else:
            outside[c] = cv2.distanceTransform(comp, cv2.DIST_L2, cv2.DIST_MASK_5) * np.float32(scale)
        p = _silhouette_points(s, max(1, round(stride / scale)), min_component)
        pts.append(p * scale + 0.5 * (scale - 1))
    M = max(1, max(len(p) for p in pts))
    points = np.zeros((C, M, 2))
    n_points = np.zeros(C, np.int64)
    for c, p in enumerate(pts):
        points[c, :len(p)] = p
        n_points[c] = len(p)
    return DistanceMaps(outside=outside, points=points, n_points=n_points, tau=float(tau),
                        tau_b=float(tau if tau_b is None else tau_b), scale=scale)


# ------------------------------------------------------------------------------------------------ numba
@nb.njit(cache=True, nogil=True, inline="always")
def _bilinear(img, u, v, fill):
    H, W = img.shape
    if not (u >= 0.0 and v >= 0.0 and u <= W - 1 and v <= H - 1):
        return fill
    x0 = min(int(u), W - 2) if W > 1 else 0
    y0 = min(int(v), H - 2) if H > 1 else 0
    fx = u - x0
    fy = v - y0
    x1 = min(x0 + 1, W - 1)
    y1 = min(y0 + 1, H - 1)
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    return top * (1.0 - fy) + bot * fy


@nb.njit(cache=True, nogil=True)
def _capsules(starts, ends, ax_x, ax_y, semi_x, semi_y, R, t, cam, near, caps):
    """Project the ``K`` cones of one pose into one view: ``caps[k] = (ua, va, ub, vb, ra, rb, ok)``."""
    K = starts.shape[0]
    for k in range(K):
        Sx, Sy, Sz = _rot(R, starts[k], t)
        Ex, Ey, Ez = _rot(R, ends[k], t)
        if Sz < near or Ez < near:
            caps[k, 6] = 0.0
            continue
        ua, va = project_cam_point(Sx, Sy, Sz, cam)
        ub, vb = project_cam_point(Ex, Ey, Ez, cam)
        # the direction across the cone in the image: perpendicular to its axis and to the viewing ray
        ax, ay, az = Ex - Sx, Ey - Sy, Ez - Sz
        mx, my, mz = 0.5 * (Sx + Ex), 0.5 * (Sy + Ey), 0.5 * (Sz + Ez)
        ux = ay * mz - az * my
        uy = az * mx - ax * mz
        uz = ax * my - ay * mx
        nrm = math.sqrt(ux * ux + uy * uy + uz * uz)
        if nrm < 1e-12:  # seen end on: any direction across the axis
            ux, uy, uz = 1.0, 0.0, 0.0
        else:
            ux, uy, uz = ux / nrm, uy / nrm, uz / nrm
        X = ax_x[k]
        Y = ax_y[k]
        px = (R[0, 0] * X[0] + R[0, 1] * X[1] + R[0, 2] * X[2]) * ux + (
            R[1, 0] * X[0] + R[1, 1] * X[1] + R[1, 2] * X[2]) * uy + (
            R[2, 0] * X[0] + R[2, 1] * X[1] + R[2, 2] * X[2]) * uz
        py = (R[0, 0] * Y[0] + R[0, 1] * Y[1] + R[0, 2] * Y[2]) * ux + (
            R[1, 0] * Y[0] + R[1, 1] * Y[1] + R[1, 2] * Y[2]) * uy + (
            R[2, 0] * Y[0] + R[2, 1] * Y[1] + R[2, 2] * Y[2]) * uz
        half0 = math.sqrt((semi_x[k, 0] * px) ** 2 + (semi_y[k, 0] * py) ** 2)
        half1 = math.sqrt((semi_x[k, 1] * px) ** 2 + (semi_y[k, 1] * py) ** 2)
        caps[k, 0] = ua
        caps[k, 1] = va
        caps[k, 2] = ub
        caps[k, 3] = vb
        ra = half0 * cam[0] / Sz
        rb = half1 * cam[0] / Ez
        caps[k, 4] = ra
        caps[k, 5] = rb
        caps[k, 6] = 1.0
        r = max(ra, rb)
        caps[k, 7] = min(ua, ub) - r  # bounding box of the capsule
        caps[k, 8] = max(ua, ub) + r
        caps[k, 9] = min(va, vb) - r
        caps[k, 10] = max(va, vb) + r


@nb.njit(cache=True, nogil=True, inline="always")
def _rot(R, x, t):
    return (R[0, 0] * x[0] + R[0, 1] * x[1] + R[0, 2] * x[2] + t[0],
            R[1, 0] * x[0] + R[1, 1] * x[1] + R[1, 2] * x[2] + t[1],
            R[2, 0] * x[0] + R[2, 1] * x[1] + R[2, 2] * x[2] + t[2])


@nb.njit(cache=True, nogil=True, inline="always")
def _capsule_distance(u, v, caps, k):
    ax = caps[k, 2] - caps[k, 0]
    ay = caps[k, 3] - caps[k, 1]
    L2 = ax * ax + ay * ay
    s = 0.0
    if L2 > 1e-12:
        s = ((u - caps[k, 0]) * ax + (v - caps[k, 1]) * ay) / L2
        s = min(1.0, max(0.0, s))
    dx = u - (caps[k, 0] + s * ax)
    dy = v - (caps[k, 1] + s * ay)
    return math.sqrt(dx * dx + dy * dy) - (caps[k, 4] + s * (caps[k, 5] - caps[k, 4]))


@nb.njit(cache=True, nogil=True)
def _distance_batch(starts, ends, ax_x, ax_y, semi_x, semi_y, R, t, cam, near, outside, scale, points, n_points,
                    tau, tau_b, n_axis, across, order, out_a, out_b, out_parts):
    N, K = starts.shape[0], starts.shape[1]
    C = R.shape[0]
    caps = np.zeros((K, 11))
    inv_tau2 = 1.0 / (tau * tau)
    inv_s = 1.0 / scale
    off = 0.5 * (scale - 1) * inv_s
    inv_tau2b = 1.0 / (tau_b * tau_b)
    n_across = across.shape[0]
    for n in range(N):
        for c in range(C):
            _capsules(starts[n], ends[n], ax_x[n], ax_y[n], semi_x, semi_y, R[c], t[c], cam[c], near, caps)
            img = outside[c]
            total = 0.0
            for k in range(K):
                acc = 0.0
                if caps[k, 6] == 0.0:
                    acc = n_axis * n_across * 1.0
                else:
                    ax = caps[k, 2] - caps[k, 0]
                    ay = caps[k, 3] - caps[k, 1]
                    L = math.sqrt(ax * ax + ay * ay)
                    if L > 1e-12:
                        nx, ny = -ay / L, ax / L
                    else:
                        nx, ny = 1.0, 0.0
                    for i in range(n_axis):
                        f = (i + 0.5) / n_axis
                        cu = caps[k, 0] + f * ax
                        cv = caps[k, 1] + f * ay
                        r = caps[k, 4] + f * (caps[k, 5] - caps[k, 4])
                        for j in range(n_across):
                            d = _bilinear(img, (cu + across[j] * r * nx) * inv_s - off,
                                          (cv + across[j] * r * ny) * inv_s - off, tau)
                            d = min(d, tau)
                            acc += d * d * inv_tau2
                part = acc / (n_axis * n_across)
                out_parts[n, c, k] = part
                total += part
            out_a[n, c] = total / K
            m = n_points[c]
            accb = 0.0
            for p in range(m):
                u = points[c, p, 0]
                v = points[c, p, 1]
                dmin = tau_b
                for q in range(K):
                    k = order[q]
                    if (caps[k, 6] == 0.0 or u < caps[k, 7] - dmin or u > caps[k, 8] + dmin
                            or v < caps[k, 9] - dmin or v > caps[k, 10] + dmin):
                        continue
                    d = _capsule_distance(u, v, caps, k)
                    if d <= 0.0:
                        dmin = 0.0
                        break
                    if d < dmin:
                        dmin = d
                accb += dmin * dmin * inv_tau2b
            out_b[n, c] = accb / m if m > 0 else 0.0


def _placed(model, poses: np.ndarray):
    pc = model.cones(poses)
    return (np.ascontiguousarray(pc.start), np.ascontiguousarray(pc.end), np.ascontiguousarray(pc.axis_x),
            np.ascontiguousarray(pc.axis_y), np.ascontiguousarray(pc.semi_x), np.ascontiguousarray(pc.semi_y))


def _cone_order(model) -> np.ndarray:
    """Largest cones first, so that the observed points inside the torso stop at the first test."""
    ca = model.cone_arrays
    size = np.linalg.norm(ca.end - ca.start, axis=1) * ca.radii.mean(axis=1) * ca.scale.mean(axis=1)
    return np.argsort(-size, kind="stable").astype(np.int64)


def distance_terms(model, poses: np.ndarray, R: np.ndarray, t: np.ndarray, cam: np.ndarray, maps: DistanceMaps,
                   near: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A (N, C)``, ``B (N, C)`` and the per-cone ``A`` terms ``(N, C, K)`` of ``poses (N, D)`` (numba).

    ``R, t, cam``: the camera tables of :func:`swarmpose.render.project.camera_tables`; ``near``: cones with
    a cap centre closer than this (mm) to the camera plane are not drawn (their samples cost ``1``).
    """
    p = np.ascontiguousarray(poses, dtype=np.float64)
    N, C, K = p.shape[0], R.shape[0], len(model.cone_arrays.names)
    out_a = np.zeros((N, C))
    out_b = np.zeros((N, C))
    parts = np.zeros((N, C, K))
    if N:
        _distance_batch(*_placed(model, p), R, t, cam, float(near), maps.outside, float(maps.scale), maps.points, maps.n_points,
                        float(maps.tau), float(maps.tau_b), N_AXIS, ACROSS, _cone_order(model), out_a, out_b, parts)
    return out_a, out_b, parts


def part_distances(parts: np.ndarray) -> np.ndarray:
    """Per-cone ``A`` averaged over the views: ``(N, C, K) -> (N, K)`` in ``[0, 1]`` (0: inside everywhere)."""
    return parts.mean(axis=1)


# ------------------------------------------------------------------------------------------------ reference
def _bilinear_reference(img: np.ndarray, u: float, v: float, fill: float) -> float:
    H, W = img.shape
    if not (0.0 <= u <= W - 1 and 0.0 <= v <= H - 1):
        return fill
    x0, y0 = min(int(np.floor(u)), W - 2), min(int(np.floor(v)), H - 2)
    fx, fy = u - x0, v - y0
    q = img[y0:y0 + 2, x0:x0 + 2].astype(np.float64)
    return float((q[0, 0] * (1 - fx) + q[0, 1] * fx) * (1 - fy) + (q[1, 0] * (1 - fx) + q[1, 1] * fx) * fy)


def distance_terms_reference(model, poses: np.ndarray, cameras, maps: DistanceMaps,
                             near: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Plain reference of :func:`distance_terms` (loops in Python, camera objects' own projection)."""
    poses = np.asarray(poses, dtype=np.float64)
    pc = model.cones(poses)
    N, K = pc.start.shape[:2]
    C = len(cameras)
    tau = maps.tau
    A = np.zeros((N, C))
    B = np.zeros((N, C))
    parts = np.zeros((N, C, K))
    for n in range(N):
        for c, camera in enumerate(cameras):
            caps = []
            for k in range(K):
                S = camera.R @ pc.start[n, k] + camera.t
                E = camera.R @ pc.end[n, k] + camera.t
                if S[2] < near or E[2] < near:
                    caps.append(None)
                    continue
                a = camera.project(pc.start[n, k][None])[0]
                b = camera.project(pc.end[n, k][None])[0]
                u = np.cross(E - S, 0.5 * (S + E))
                u = u / np.linalg.norm(u) if np.linalg.norm(u) >= 1e-12 else np.array([1.0, 0.0, 0.0])
                px, py = (camera.R @ pc.axis_x[n, k]) @ u, (camera.R @ pc.axis_y[n, k]) @ u
                half = np.hypot(pc.semi_x[k] * px, pc.semi_y[k] * py)
                caps.append((a, b, half[0] * camera.fx / S[2], half[1] * camera.fx / E[2]))
            for k, cap in enumerate(caps):
                if cap is None:
                    parts[n, c, k] = 1.0
                    continue
                a, b, ra, rb = cap
                d_ab = b - a
                L = np.linalg.norm(d_ab)
                nrm = np.array([-d_ab[1], d_ab[0]]) / L if L > 1e-12 else np.array([1.0, 0.0])
                vals = []
                for i in range(N_AXIS):
                    f = (i + 0.5) / N_AXIS
                    centre, r = a + f * d_ab, ra + f * (rb - ra)
                    for s in ACROSS:
                        q = centre + s * r * nrm
                        off = 0.5 * (maps.scale - 1) / maps.scale
                        d = _bilinear_reference(maps.outside[c], q[0] / maps.scale - off, q[1] / maps.scale - off, tau)
                        vals.append(min(d, tau) ** 2 / tau**2)
                parts[n, c, k] = np.mean(vals)
            A[n, c] = parts[n, c].mean()
            m = int(maps.n_points[c])
            acc = 0.0
            for pnt in maps.points[c, :m]:
                dmin = maps.tau_b
                for cap in caps:
                    if cap is None:
                        continue
                    a, b, ra, rb = cap
                    d_ab = b - a
                    L2 = d_ab @ d_ab
                    s = float(np.clip((pnt - a) @ d_ab / L2, 0.0, 1.0)) if L2 > 1e-12 else 0.0
                    d = np.linalg.norm(pnt - (a + s * d_ab)) - (ra + s * (rb - ra))
                    dmin = min(dmin, max(d, 0.0))
                acc += dmin**2 / maps.tau_b**2
            B[n, c] = acc / m if m else 0.0
    return A, B, parts
