"""The report of a track without ground truth: what was tracked, the fitness over time, the held-out cameras.

A recording imported with ``swarmpose import`` has no motion capture, so there is no 3D error. The report says
so, and shows instead what can be measured: each run's fitness per frame, and, for cameras held out with
``track --views``, how well the track explains them (:mod:`swarmpose.report.heldout`) beside a plain
triangulation of the tracked cameras' keypoints.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from swarmpose.report.heldout import HeldOutScore, heldout_plot, heldout_scores
from swarmpose.report.results import Results

__all__ = ["fitness_over_time", "heldout_section", "write_summary_without_truth"]


def fitness_over_time(res: Results, out: str | Path) -> Path:
    """Every run's best fitness per tracked frame."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    fig, ax = plt.subplots(figsize=(9, 3.4), dpi=110)
    for r in res.runs:
        ax.plot(r.frame_times, r.scores, lw=1.3, label=f"run {r.run}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fitness (higher is better)")
    ax.set_title(f"{res.name}: the best pose's fitness per frame (no ground truth)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    return out


def heldout_section(res: Results, out_dir: Path, run: int = 0) -> tuple[list[HeldOutScore], list[str]]:
    """Held-out scores of run ``run`` and their Markdown (empty when every camera was tracked)."""
    views = res.config.get("views") or ""
    if not views:
        return [], []
    r = res.run(run)
    tracked = [v.strip() for v in views.split(",") if v.strip()]
    with res.open_sequence() as seq:
        scores = heldout_scores(seq, res.model, r.params, r.joints, r.frame_indices, tracked)
    if not scores:
        return [], []
    heldout_plot(scores, r.frame_times, out_dir / "heldout.png")
    (out_dir / "heldout.json").write_text(json.dumps([s.summary for s in scores], indent=1) + "\n")

    def f(x, fmt=".1f"):
        return "–" if x is None else format(x, fmt)

    lines = ["## Held-out cameras", "",
             f"Tracked with {', '.join(tracked)}; each other camera scores run {run}: the model's joints projected "
             "into it against its own detected keypoints (median over joints, px), beside the joints triangulated "
             "from the tracked cameras' keypoints alone, and the model's silhouette against the camera's.", "",
             "| held-out camera | model px (median / mean) | triangulation px (median / mean) | model better on | "
             "silhouette IoU (median / mean) |", "|---|---:|---:|---:|---:|"]
    for s in scores:
        m, b, i = s.summary["model_px"], s.summary["baseline_px"], s.summary["iou"]
        better = s.summary.get("model_better_frames")
        lines.append(f"| {s.camera} | {f(m['median'])} / {f(m['mean'])} | {f(b['median'])} / {f(b['mean'])} | "
                     f"{'–' if better is None else f'{100 * better:.0f} % of frames'} | "
                     f"{f(i['median'], '.3f')} / {f(i['mean'], '.3f')} |")
    lines += ["", "![held-out cameras](heldout.png)", ""]
    return scores, lines


def write_summary_without_truth(res: Results, out: Path, *, figures: Sequence[Path], overlays: Sequence[Path],
                                heldout: Sequence[str], notes: Sequence[str] = ()) -> Path:
    """``summary.md`` of a track without ground truth."""
    cfg = res.config
    s = res.summary
    lines = [f"# {res.name}: {cfg.get('algo')} at {res.fps:g} fps", "",
             "> No ground truth was given for this sequence, so there is no 3D error; the held-out cameras (if any) "
             "and the fitness are what can be measured.", ""]
    lines += [f"- {n}" for n in notes]
    lines += ["", "| setting | value |", "|---|---|",
              f"| sequence | `{cfg.get('sequence')}` |",
              f"| runs | {len(res.runs)} (seed {cfg.get('seed')}) |",
              f"| frames | {s.get('frames')} |",
              f"| evaluations per frame | {cfg.get('evals_per_frame')} |",
              f"| cameras tracked | {cfg.get('views') or 'all'} |",
              f"| frames/s per run | {np.mean([r.frames_per_s for r in res.runs]):.2f} |", ""]
    lines += list(heldout)
    for fig in figures:
        lines += [f"![{fig.stem}]({fig.relative_to(out.parent)})", ""]
    if overlays:
        lines += ["## Overlays", ""]
        for p in overlays:
            lines += [f"![{p.stem}]({p.relative_to(out.parent)})", ""]
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out
