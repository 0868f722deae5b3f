"""Error measures of tracked 15-joint motion (design.md §5).

* HumanEva 3D error (Sigal et al. 2010, eq. 3–5; thesis eq. 4.4–4.6): per frame D = mean over the
  15 joints of the Euclidean distance (mm); D_mean and D_max over the evaluated frames; per joint.
* MMTA / MMTP (Sharifi et al. 2017, eq. 19–20, after Canton-Ferrer et al.): the share of joints within
  δ = 100 mm of the ground truth, and the mean distance of those matched joints, averaged over
  frames; a frame with no joint within δ contributes the penalty distance δ to MMTP (Sharifi l.218).
  μ and σ per frame are the mean and standard deviation of the joint distances (eq. 19).

All functions take ``(T, 15, 3)`` arrays in mm (HumanEva joint order).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from swarmpose.errors import ShapeError
from swarmpose.joints import JOINTS15

__all__ = ["TrackErrors", "joint_distances", "valid_frames", "track_errors", "aggregate_runs", "spread_over_runs",
           "MMTA_DELTA_MM", "joint_acceleration", "FRAMES_CHUNK"]

MMTA_DELTA_MM = 100.0
#: Frames per step of :func:`joint_distances` and :func:`joint_acceleration`: a long recording's whole track
#: (20,000 frames) is measured without (T, 15, 3) temporaries.
FRAMES_CHUNK = 1024


def joint_distances(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Euclidean distance per frame and joint, ``(T, 15)`` mm."""
    est = np.asarray(estimate, dtype=np.float64)
    gt = np.asarray(truth, dtype=np.float64)
    if est.shape != gt.shape or est.ndim != 3 or est.shape[1:] != (15, 3):
        raise ShapeError(f"estimate and truth must both be (T, 15, 3); got {est.shape} and {gt.shape}")
    out = np.empty(est.shape[:2])
    for a in range(0, len(est), FRAMES_CHUNK):
        out[a:a + FRAMES_CHUNK] = np.linalg.norm(est[a:a + FRAMES_CHUNK] - gt[a:a + FRAMES_CHUNK], axis=-1)
    return out


@dataclass(frozen=True)
class TrackErrors:
    """Errors of one tracked run (mm unless noted)."""

    d_per_frame: np.ndarray  # (T,); NaN at frames without valid ground truth
    d_mean: float
    d_max: float
    d_std: float
    per_joint: dict[str, float]
    mmta: float  # fraction in [0, 1]
    mmtp: float
    mu: float  # Sharifi eq. 19, averaged over frames
    sigma: float

    def summary(self) -> dict[str, object]:
        d = asdict(self)
        d.pop("d_per_frame")
        return d


def joint_acceleration(joints: np.ndarray, times: np.ndarray) -> float:
    """Jitter: the mean magnitude of the joints' acceleration, mm/s^2, by central second differences over
    ``joints (T, J, 3)`` at ``times (T,)`` s (uneven steps allowed); frames with a non-finite joint are left out;
    NaN with fewer than 3 frames. Taken :data:`FRAMES_CHUNK` frames at a time."""
    x = np.asarray(joints, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    if len(x) < 3:
        return float("nan")
    total, count = 0.0, 0
    for s in range(1, len(x) - 1, FRAMES_CHUNK):  # the centres s .. e - 1 of the second differences
        e = min(s + FRAMES_CHUNK, len(x) - 1)
        h0 = (t[s:e] - t[s - 1:e - 1])[:, None, None]
        h1 = (t[s + 1:e + 1] - t[s:e])[:, None, None]
        a = 2.0 * (h0 * x[s + 1:e + 1] - (h0 + h1) * x[s:e] + h1 * x[s - 1:e - 1]) / (h0 * h1 * (h0 + h1))
        n = np.linalg.norm(a, axis=-1)
        n = n[np.isfinite(n).all(axis=1)]
        total, count = total + float(n.sum()), count + n.size
    return total / count if count else float("nan")


def valid_frames(truth: np.ndarray) -> np.ndarray:
    """``(T,)`` bool: frames whose ground truth is finite for every joint (HumanEva marks invalid frames
    with NaN rows; they are not scored)."""
    return np.isfinite(np.asarray(truth, dtype=np.float64)).all(axis=(1, 2))


def track_errors(estimate: np.ndarray, truth: np.ndarray, delta_mm: float = MMTA_DELTA_MM) -> TrackErrors:
    """All error measures of one run; see the module docstring.

    Frames whose ground truth is not finite are not scored: ``d_per_frame`` is NaN there and every other
    measure is taken over the valid frames only.

    Raises
    ------
    ShapeError
        ``estimate`` and ``truth`` are not both ``(T, 15, 3)``.
    ValueError
        ``delta_mm`` is not a positive distance, no frame has valid ground truth, or the estimate is not
        finite at a frame that is scored.
    """
    if not (np.isfinite(delta_mm) and delta_mm > 0):
        raise ValueError(f"delta_mm must be a positive distance in mm, got {delta_mm!r}")
    est, gt = np.asarray(estimate), np.asarray(truth)
    if est.shape != gt.shape or est.ndim != 3 or est.shape[1:] != (15, 3):
        raise ShapeError(f"estimate and truth must both be (T, 15, 3); got {est.shape} and {gt.shape}")
    ok = valid_frames(gt)
    if not ok.any():
        raise ValueError(f"no frame to score: the ground truth of all {len(ok)} frames is missing or not finite")
    # per frame, FRAMES_CHUNK frames at a time: a long track is scored without (T, 15) temporaries
    T = len(ok)
    d_per_frame, share, mmtp_frame, sigma = np.full(T, np.nan), np.zeros(T), np.zeros(T), np.zeros(T)
    joint_sum = np.zeros(15)
    for a in range(0, T, FRAMES_CHUNK):
        b = min(a + FRAMES_CHUNK, T)
        rows = a + np.flatnonzero(ok[a:b])
        dist = joint_distances(est[rows], gt[rows])
        if not np.isfinite(dist).all():
            bad = rows[~np.isfinite(dist).all(axis=1)]
            raise ValueError(f"the estimate is not finite at {len(bad)} scored frame(s), first at index {int(bad[0])}")
        d_per_frame[rows] = dist.mean(axis=1)
        matched = dist < delta_mm
        n_match = matched.sum(axis=1)
        share[rows] = n_match / dist.shape[1]
        mmtp_frame[rows] = np.where(n_match > 0, np.where(matched, dist, 0.0).sum(axis=1) / np.maximum(n_match, 1),
                                    delta_mm)
        sigma[rows] = dist.std(axis=1)
        joint_sum += dist.sum(axis=0)
    d = d_per_frame[ok]
    return TrackErrors(
        d_per_frame=d_per_frame,
        d_mean=float(d.mean()),
        d_max=float(d.max()),
        d_std=float(d.std()),
        per_joint={n: float(v) for n, v in zip(JOINTS15, joint_sum / int(ok.sum()), strict=True)},
        mmta=float(share[ok].mean()),
        mmtp=float(mmtp_frame[ok].mean()),
        mu=float(d.mean()),
        sigma=float(sigma[ok].mean()),
    )


def spread_over_runs(d_means: Sequence[float]) -> float:
    """Sample standard deviation (n - 1) of the runs' D_mean, mm: the runs are a sample of the tracker's
    outcomes; 0 for a single run."""
    return float(np.std(d_means, ddof=1)) if len(d_means) > 1 else 0.0


def aggregate_runs(runs: Sequence[TrackErrors]) -> dict[str, object]:
    """Mean over runs of each measure, their spread, and the worst run (highest D_mean).

    The spread ``d_mean_std_over_runs`` is :func:`spread_over_runs` of the runs' D_mean; ``d_max`` is the
    mean of the runs' maxima and ``d_max_over_runs`` the largest D of any run and frame.
    """
    if not runs:
        raise ValueError("no runs to aggregate")
    keys = ("d_mean", "d_max", "d_std", "mmta", "mmtp", "mu", "sigma")
    out: dict[str, object] = {k: float(np.mean([getattr(r, k) for r in runs])) for k in keys}
    out["d_mean_std_over_runs"] = spread_over_runs([r.d_mean for r in runs])
    out["d_max_over_runs"] = float(max(r.d_max for r in runs))
    worst = max(range(len(runs)), key=lambda i: runs[i].d_mean)
    out["worst"] = {"run": worst, **{k: getattr(runs[worst], k) for k in keys}}
    out["per_joint"] = {n: float(np.mean([r.per_joint[n] for r in runs])) for n in JOINTS15}
    out["runs"] = len(runs)
    return out
