"""The report's per-limb confidence (:mod:`swarmpose.track.confidence`): a table, a plot over time and
``limb_confidence.npz`` of one run, with the frames the ground truth finds lost beside it when there is one."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.report._style import SIDE_RGB, rgb01
from swarmpose.report.results import Results
from swarmpose.track.confidence import (
    LIMB_JOINTS,
    LOST_MM,
    keypoint_disagreement,
    limb_confidence,
    limb_lost,
    track_disagreement,
)
from swarmpose.track.observation import IMAGE_FITNESS
from swarmpose.track.start import has_keypoints

__all__ = ["run_confidence", "confidence_section"]


def run_confidence(res: Results, run: int = 0, sequence: Any = None) -> dict[str, np.ndarray] | None:
    """Disagreement and confidence ``(T, 4)`` of run ``run``'s limbs (None for a track that did not fit
    silhouettes, or a sequence with no silhouettes). Every frame is read again and its silhouettes compared
    with the run's pose."""
    from swarmpose.features import parse_feature_options
    from swarmpose.fitness import make_fitness
    from swarmpose.track.observation import frame_observation
    from swarmpose.track.start import tracked_views

    cfg = res.config
    kind = cfg.get("fitness_kind") or cfg.get("fitness")
    if kind not in IMAGE_FITNESS:
        return None
    r = res.run(run)
    model = res.model
    fitness = make_fitness(kind, model, backend=cfg.get("backend") or "numba")
    features = parse_feature_options(cfg.get("feature_options") or "")
    with res.open_sequence(sequence) as seq:
        views = tracked_views(seq, cfg.get("views") or "")
        bgs = seq.backgrounds()
        if bgs is None and "silhouette" not in seq.streams:
            return None  # neither stored silhouettes nor backgrounds to compute them from

        def observation(t: int) -> Any:
            return frame_observation(seq, int(r.frame_indices[t]), kind, int(cfg.get("downsample") or 1), bgs,
                                     features, views)

        disagreement = track_disagreement(fitness, model, r.params, observation)
        kp = None
        if has_keypoints(seq):  # the detector's keypoints: a second, independent piece of evidence
            dense = seq.marker_data.to_dense()[0]
            kp = keypoint_disagreement([seq.cameras[c] for c in views], dense[np.asarray(r.frame_indices)][:, views],
                                       r.joints)
    out = {"limbs": np.array(list(LIMB_JOINTS)), "frame_indices": r.frame_indices, "frame_times": r.frame_times,
           "disagreement": disagreement, "confidence": limb_confidence(disagreement, kp)}
    if kp is not None:
        out["keypoint_disagreement_mm"] = kp
    gt = getattr(r, "gt_joints", None)
    if gt is not None and np.isfinite(gt).any():
        out["lost"] = limb_lost(r.joints, gt)
    return out


def _plot(data: dict[str, np.ndarray], out: Path, title: str) -> Path:
    from swarmpose.report.plots import _figure, _save

    fig = _figure((8.0, 3.2), 120)
    ax = fig.add_subplot(1, 1, 1)
    left, right = SIDE_RGB["left"], SIDE_RGB["right"]
    styles = {"left_arm": (left, "-"), "right_arm": (right, "-"), "left_leg": (left, "--"), "right_leg": (right, "--")}
    t = data["frame_times"]
    for j, limb in enumerate(data["limbs"]):
        colour, ls = styles.get(str(limb), ((128, 128, 128), "-"))
        ax.plot(t, data["confidence"][:, j], ls, color=rgb01(colour), lw=1.2, label=str(limb).replace("_", " "))
        if "lost" in data:
            lost = data["lost"][:, j]
            ax.plot(t[lost], np.full(lost.sum(), -0.04 - 0.03 * j), "|", color=rgb01(colour), ms=6)
    ax.set_ylim(-0.17, 1.22)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("confidence")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper center", fontsize=7, ncol=4, frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, out, 120)


def confidence_section(res: Results, out_dir: Path, run: int = 0, sequence: Any = None) -> list[str]:
    """Markdown lines of the per-limb confidence of run ``run`` (empty for a track without silhouettes), and
    ``limb_confidence.npz`` and ``limb_confidence.png`` in ``out_dir``."""
    data = run_confidence(res, run, sequence)
    if data is None:
        return []
    np.savez(out_dir / "limb_confidence.npz", **data)
    truth = "lost" in data
    title = f"run {run}: per-limb confidence" + (f" (ticks: frames lost by > {LOST_MM:.0f} mm)" if truth else "")
    _plot(data, out_dir / "limb_confidence.png", title)
    conf = data["confidence"]
    lines = ["## Per-limb confidence", "",
             f"Run {run}: the probability that each limb's elbow and wrist (knee and ankle) are within "
             f"{LOST_MM:.0f} mm, from how far its cones reach outside the silhouettes"
             + (" and how far its joints lie from the detector's keypoints" if "keypoint_disagreement_mm" in data
                else "")
             + " (calibrated on the shared synthetic clips; on coarser masks read it as a ranking). Per frame in "
             "`limb_confidence.npz`.", "",
             "| limb | mean confidence | frames below 0.5 |" + (" frames lost (truth) |" if truth else ""),
             "|---|---:|---:|" + ("---:|" if truth else "")]
    for j, limb in enumerate(data["limbs"]):
        row = (f"| {str(limb).replace('_', ' ')} | {np.nanmean(conf[:, j]):.2f} | "
               f"{100 * np.mean(conf[:, j] < 0.5):.0f} % |")
        if truth:
            row += f" {100 * np.mean(data['lost'][:, j]):.0f} % |"
        lines.append(row)
    lines += ["", "![per-limb confidence](limb_confidence.png)", ""]
    return lines
