"""Per-camera frame offsets from the keypoints: the integer offsets that minimise the triangulation residual.

Cameras that were started by hand are a frame or two apart. With the subject's keypoints detected in every
view, the offsets of cameras ``1..C-1`` against camera 0 are found by coordinate descent: each camera in
turn takes the offset in ``[-max_offset, max_offset]`` that minimises the mean reprojection residual (each
residual capped at the inlier threshold, so a misdetection weighs no more than a bad sync) of the joints
triangulated from all views over a window of frames; two sweeps. A person who moves gives the signal: on
still frames every offset fits equally well, which the caller sees as a flat table.

Shape letters: ``N_c`` frames of camera ``c``'s video, ``J`` joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarmpose.camera import Camera
from swarmpose.datasets.recording.subject import consistent_views
from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.triangulation import residuals

__all__ = ["OffsetSearch", "estimate_offsets", "sync_cost"]


@dataclass
class OffsetSearch:
    """The result of :func:`estimate_offsets`.

    Attributes
    ----------
    offsets : list of int
        Camera ``c`` shows reference frame ``k`` in its frame ``k + offsets[c]``; ``offsets[0] == 0``.
    cost_before, cost_after : float
        Mean capped residual (px) with the starting offsets and with the result.
    table : dict
        ``{camera index: [(offset, cost), ...]}`` of the last sweep, for the page and the docs.
    frames : int
        Frames in the window.
    """

    offsets: list[int]
    cost_before: float
    cost_after: float
    table: dict[int, list[tuple[int, float]]]
    frames: int


def _gather(kp: Sequence[np.ndarray], cf: Sequence[np.ndarray], ref: np.ndarray, offsets: Sequence[int]):
    idx = [ref + o for o in offsets]
    k = np.stack([kp[c][i] for c, i in enumerate(idx)], axis=1)
    w = np.stack([cf[c][i] for c, i in enumerate(idx)], axis=1)
    return k, w


def sync_cost(cameras: Sequence[Camera], keypoints: np.ndarray, confidence: np.ndarray, swap: Sequence[int],
              threshold: float) -> float:
    """Mean capped residual (px) of keypoints (T, C, J, 2) after :func:`consistent_views`."""
    sel = consistent_views(cameras, keypoints, confidence, swap, threshold)
    kp, cf = sel.apply(keypoints, confidence, swap)
    r = residuals(cameras, sel.points, kp)
    r = np.minimum(r, threshold)[(cf >= MIN_CONFIDENCE) & np.isfinite(r)]
    return float(r.mean()) if r.size else float("inf")


def estimate_offsets(cameras: Sequence[Camera], keypoints: Sequence[np.ndarray], confidence: Sequence[np.ndarray],
                     swap: Sequence[int], threshold: float, *, start: Sequence[int] | None = None,
                     max_offset: int = 5, window: int = 300, sweeps: int = 2) -> OffsetSearch:
    """Integer frame offsets of every camera against camera 0 (see the module docstring).

    Parameters
    ----------
    cameras : sequence of C Camera
    keypoints : sequence of C arrays (N_c, J, 2)
        Each camera's detections over its whole video (NaN where absent).
    confidence : sequence of C arrays (N_c, J)
    swap : sequence of J int
        The left/right permutation.
    threshold : float
        Inlier residual, px.
    start : sequence of C int, optional
        Offsets to start from (zeros).
    max_offset : int
        Largest offset tried, frames.
    window : int
        At most this many reference frames are used (the middle of the common range).
    """
    C = len(cameras)
    n = np.array([len(k) for k in keypoints])
    off = [0] * C if start is None else [int(o) for o in start]

    off = [max(-max_offset, min(max_offset, o)) for o in off]
    lo, hi = max_offset, int(n.min()) - max_offset  # every offset tried stays inside every video
    if hi - lo > window:
        lo = (lo + hi) // 2 - window // 2
        hi = lo + window
    ref = np.arange(lo, max(hi, lo))
    if ref.size < 2:
        return OffsetSearch(off, float("nan"), float("nan"), {}, int(ref.size))

    def cost(offs):
        k, w = _gather(keypoints, confidence, ref, offs)
        return sync_cost(cameras, k, w, swap, threshold)

    before = cost(off)
    table: dict[int, list[tuple[int, float]]] = {}
    best_cost = before
    for _ in range(max(1, sweeps)):
        changed = False
        for c in range(1, C):
            row = []
            for d in range(off[c] - max_offset, off[c] + max_offset + 1):
                if abs(d) > max_offset:
                    continue
                trial = list(off)
                trial[c] = d
                row.append((d, cost(trial)))
            table[c] = row
            d_best, c_best = min(row, key=lambda dc: (dc[1], abs(dc[0])))
            if c_best < best_cost - 1e-9 and d_best != off[c]:
                off[c], best_cost, changed = d_best, c_best, True
        if not changed:
            break
    return OffsetSearch(off, before, cost(off), table, int(ref.size))
