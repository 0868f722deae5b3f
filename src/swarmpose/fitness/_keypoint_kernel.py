"""The keypoint term's compiled kernel (:func:`swarmpose.fitness.keypoints.keypoint_cost`): every pose, view and
labelling in one pass, the cameras' projection (:meth:`swarmpose.camera.Camera.project_with_depth`: Bouguet
distortion, no cap) written out, the sums over the joints in numpy's order (:mod:`swarmpose.fitness._rowsum`)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from swarmpose.fitness._rowsum import row_sum

#: Hash of the kernel sources this module's cached kernels inline (fitness/_rowsum.py); tests/test_numba_cache.py
#: says when it must change.
INLINED_SOURCES_SHA1 = "7c39a6f7705c545b"

__all__ = ["keypoint_kernel"]


@nb.njit(cache=True, nogil=True)
def keypoint_kernel(J, R, t, cam, kp, conf, perms, a, threshold, power, s2, out):
    """``out (N,)`` = the keypoint cost of joints ``J (N, 15, 3)`` in views ``R (C, 3, 3)``, ``t (C, 3)``,
    ``cam (C, >= 10)`` (``fx, fy, cx, cy, skew, k1, k2, p1, p2, k3``); detections ``kp (C, 15, 2)`` (NaN: absent)
    with confidences ``conf (C, 15)``, counted from ``threshold`` on with weight ``conf ** power``; labellings
    ``perms (L, 15)``; joint weights ``a (15,)``; ``s2`` the robust scale squared."""
    N = J.shape[0]
    C = R.shape[0]
    L = perms.shape[0]
    M = J.shape[1]
    w = np.zeros(M)
    ww = np.empty((L, M))
    wsum = np.empty(L)
    u = np.empty(M)
    v = np.empty(M)
    term = np.empty(M)
    for n in range(N):
        out[n] = 0.0
    views = 0
    for c in range(C):
        for j in range(M):
            x, y, f = kp[c, j, 0], kp[c, j, 1], conf[c, j]
            finite = math.isfinite(x) and math.isfinite(y)
            w[j] = f ** power if finite and f >= threshold and f > 0 else 0.0  # an absent detection weighs 0
        counted = False
        for q in range(L):
            for j in range(M):
                ww[q, j] = w[perms[q, j]] * a[j]
            wsum[q] = row_sum(ww[q])
            counted = counted or wsum[q] > 0
        if not counted:
            continue
        views += 1
        fx, fy, cx, cy, skew = cam[c, 0], cam[c, 1], cam[c, 2], cam[c, 3], cam[c, 4]
        k1, k2, p1, p2, k3 = cam[c, 5], cam[c, 6], cam[c, 7], cam[c, 8], cam[c, 9]
        for n in range(N):
            behind = False
            for j in range(M):
                px, py, pz = J[n, j, 0], J[n, j, 1], J[n, j, 2]
                xc = R[c, 0, 0] * px + R[c, 0, 1] * py + R[c, 0, 2] * pz + t[c, 0]
                yc = R[c, 1, 0] * px + R[c, 1, 1] * py + R[c, 1, 2] * pz + t[c, 1]
                z = R[c, 2, 0] * px + R[c, 2, 1] * py + R[c, 2, 2] * pz + t[c, 2]
                if not z > 0:
                    behind = True
                    break
                aa = xc / z
                bb = yc / z
                r2 = aa * aa + bb * bb
                radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                xd = aa * radial + 2.0 * p1 * aa * bb + p2 * (r2 + 2.0 * aa * aa)
                yd = bb * radial + p1 * (r2 + 2.0 * bb * bb) + 2.0 * p2 * aa * bb
                u[j] = fx * (xd + skew * yd) + cx
                v[j] = fy * yd + cy
            if behind:
                out[n] += 1.0
                continue
            best = np.inf
            nan = False
            for q in range(L):
                if wsum[q] <= 0:
                    continue
                for j in range(M):
                    dx = u[j] - kp[c, perms[q, j], 0]
                    dy = v[j] - kp[c, perms[q, j], 1]
                    e2 = dx * dx + dy * dy
                    rho = e2 / (e2 + s2) * ww[q, j]
                    term[j] = 0.0 if math.isnan(rho) else rho  # nansum; an absent detection's term is NaN x 0
                cost = row_sum(term) / wsum[q]
                if math.isnan(cost):
                    nan = True
                elif cost < best:
                    best = cost
            out[n] += 1.0 if nan or not math.isfinite(best) else best
    if views:
        for n in range(N):
            out[n] /= views
