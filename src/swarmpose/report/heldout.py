"""A score without ground truth: how well the track explains a camera it was not tracked with.

With ``track --views`` some cameras are held out. For each held-out camera and tracked frame:

* **silhouette IoU**: the model's silhouette (:func:`swarmpose.render.render_silhouette`) against the
  camera's own silhouette (the stored one: the detector's segmentation of an imported recording; else
  background subtraction against the sequence's backgrounds, as the tracker computes it);
* **joint error**: the model's 15 joints projected into the camera against the camera's own detected
  keypoints (confidence >= 0.3), the median over joints, px of the sequence;
* **baseline**: the same error for the joints triangulated from the tracked cameras' keypoints alone (what a
  keypoint-only tool gives), so the two can be compared frame by frame.

Medians and means over frames summarise each camera; :func:`heldout_plot` draws both errors and the IoU over
time. Nothing here needs ground truth, so it scores any sequence the same way.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.track.start import has_keypoints, keypoint_joints

__all__ = ["HeldOutScore", "heldout_scores", "heldout_plot"]


@dataclass
class HeldOutScore:
    """Per held-out camera: arrays over the tracked frames and their summaries."""

    camera: str
    iou: np.ndarray | None  # (T,) model silhouette vs the camera's silhouette
    model_px: np.ndarray | None  # (T,) median joint error of the model's joints, px
    baseline_px: np.ndarray | None  # (T,) the same for the tracked cameras' triangulation
    summary: dict[str, Any] = field(default_factory=dict)


def _stats(x: np.ndarray | None) -> dict[str, float | None]:
    if x is None:
        return {"median": None, "mean": None, "frames": 0}
    v = x[np.isfinite(x)]
    return {"median": float(np.median(v)) if v.size else None, "mean": float(v.mean()) if v.size else None,
            "frames": int(v.size)}


def _median_error(uv: np.ndarray, kp: np.ndarray, conf: np.ndarray) -> np.ndarray:
    err = np.linalg.norm(uv - kp, axis=-1)  # (T, 15)
    err = np.where(conf >= MIN_CONFIDENCE, err, np.nan)
    with warnings.catch_warnings():  # a frame without confident keypoints: NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(err, axis=1)


def heldout_scores(seq: Any, model: Any, params: np.ndarray, joints: np.ndarray, frames: np.ndarray,
                   tracked: list[str], *, silhouettes: bool = True) -> list[HeldOutScore]:
    """Scores of every camera of ``seq`` not in ``tracked`` (see the module docstring).

    Parameters
    ----------
    seq : MultiViewSequence
    model : BodyModel
    params : (T, D) tracked poses; joints : (T, 15, 3) their joints, mm; frames : (T,) sequence frames.
    tracked : names of the cameras tracked with.
    silhouettes : bool
        Also render the model and take the IoU (about 5 ms per view and frame).
    """
    from swarmpose.render import render_silhouette

    names = list(seq.view_names)
    held = [i for i, n in enumerate(names) if n not in tracked]
    if not held:
        return []
    tracked_idx = [i for i, n in enumerate(names) if n in tracked]
    kp = conf = base_joints = None
    if has_keypoints(seq):
        dense, c = seq.marker_data.to_dense()
        kp, conf = dense[frames], c[frames]
        base_joints = keypoint_joints(seq, frames, views=tracked_idx, keep_disagreeing=True)
    out = []
    bgs = seq.backgrounds()
    for c in held:
        cam = seq.cameras[c]
        model_px = baseline_px = iou = None
        if kp is not None:
            model_px = _median_error(cam.project(joints), kp[:, c], conf[:, c])
            baseline_px = _median_error(cam.project(base_joints), kp[:, c], conf[:, c])
        if silhouettes and ("silhouette" in seq.streams or (bgs is not None and "image" in seq.streams)):
            from swarmpose.features import silhouette

            iou = np.full(len(frames), np.nan)
            for t, k in enumerate(frames):
                stored = seq.silhouettes(int(k))
                obs = (stored[c] if stored is not None else silhouette(seq.images(int(k))[c], bgs[c])) > 0
                mine = render_silhouette(model, params[t], cam) > 0
                union = np.count_nonzero(obs | mine)
                iou[t] = np.count_nonzero(obs & mine) / union if union else np.nan
        score = HeldOutScore(names[c], iou, model_px, baseline_px)
        score.summary = {"camera": names[c], "iou": _stats(iou), "model_px": _stats(model_px),
                         "baseline_px": _stats(baseline_px)}
        if model_px is not None:
            both = np.isfinite(model_px) & np.isfinite(baseline_px)
            score.summary["model_better_frames"] = float(np.mean(model_px[both] < baseline_px[both])) if both.any() \
                else None
        out.append(score)
    return out


def heldout_plot(scores: list[HeldOutScore], times: np.ndarray, out: str | Path) -> Path:
    """Joint error (model and baseline) and silhouette IoU of every held-out camera over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    fig, axes = plt.subplots(2, 1, figsize=(9, 5.6), dpi=110, sharex=True)
    colours = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9"]
    for i, s in enumerate(scores):
        col = colours[i % len(colours)]
        if s.model_px is not None:
            axes[0].plot(times, s.model_px, color=col, lw=1.6, label=f"{s.camera}: model")
            axes[0].plot(times, s.baseline_px, color=col, lw=1.0, ls="--", label=f"{s.camera}: triangulation")
        if s.iou is not None:
            axes[1].plot(times, s.iou, color=col, lw=1.6, label=s.camera)
    axes[0].set_ylabel("median joint error (px)")
    axes[0].set_ylim(bottom=0)
    axes[0].set_title("Held-out cameras: the track against each camera's own keypoints and silhouette", fontsize=10)
    axes[1].set_ylabel("silhouette IoU")
    axes[1].set_ylim(0, 1)
    axes[1].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    return out
