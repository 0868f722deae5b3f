"""Error plots of a results folder: D over time (thesis Fig. 6.5) and the error of each joint.

Both functions draw with matplotlib's Agg canvas directly (no ``pyplot``, no global backend
switch), so they work headless and never open a window.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from swarmpose.joints import JOINTS15
from swarmpose.report._style import IK_RGB, SIDE_RGB, count, joint_side, rgb01
from swarmpose.report.results import Results, as_results

__all__ = ["error_over_time", "per_joint_errors", "default_report_dir"]

def default_report_dir(results: Results) -> Path:
    """Where the report of a results folder goes by default: ``RESULTS_DIR/report``."""
    return results.path / "report"


def _figure(figsize: tuple[float, float], dpi: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, out: Path, dpi: float) -> Path:
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi, format="png")
    return out


def _title_head(res: Results) -> str:
    cfg, s = res.config, res.summary
    algo = cfg.get("algo") or s.get("algo") or "?"
    parts = [str(algo).upper()]
    if res.fps:
        parts.append(f"at {res.fps:g} fps")
    evals = cfg.get("evals_per_frame") or s.get("evals_per_frame")
    if evals:
        parts.append(f"({evals} evaluations/frame)")
    return " ".join(parts)


def error_over_time(
    results: str | os.PathLike[str] | Results,
    *,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (9.0, 4.2),
    dpi: float = 110,
) -> Path:
    """Plot the 3D error D of every processed frame over time (thesis Fig. 6.5).

    Each run is a thin coloured line, the mean over runs a thick black line, and the IK floor (the
    error of the model's best fit to the ground truth, thesis sec. 6.4) a dashed grey line. The top
    axis shows the sequence frame index.

    Parameters
    ----------
    results : path-like or Results
        A results folder (or one loaded with :func:`swarmpose.report.results.load_results`).
    out : path-like, optional
        PNG to write; default ``RESULTS_DIR/report/error_over_time.png``.
    figsize : (float, float), default (9, 4.2)
        Inches.
    dpi : float, default 110
        Pixels per inch: the PNG is ``figsize * dpi`` pixels (990 x 462 by default).

    Returns
    -------
    pathlib.Path
        The PNG written.
    """
    res = as_results(results)
    out_path = Path(out) if out is not None else default_report_dir(res) / "error_over_time.png"
    t = res.frame_times
    D = np.stack([r.d_per_frame for r in res.runs])  # (R, T)
    mean = D.mean(axis=0)
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot(1, 1, 1)
    cmap_colors = [rgb01(c) for c in ((86, 180, 233), (230, 159, 0), (204, 121, 167), (0, 158, 115),
                                      (213, 94, 0), (0, 114, 178), (240, 228, 66))]
    many = len(res.runs) > 10
    for i, r in enumerate(res.runs):
        label = None if many and i else (f"{len(res.runs)} runs" if many else f"run {r.run}")
        ax.plot(t, r.d_per_frame, lw=0.9, alpha=0.85, color=cmap_colors[i % len(cmap_colors)], label=label,
                marker="." if len(t) < 30 else None, ms=3)
    if len(res.runs) > 1:
        ax.plot(t, mean, lw=2.4, color="black", label=f"mean of {len(res.runs)} runs")
    ik = res.ik_frame_error_mm
    if ik is not None:
        ax.plot(t, ik, lw=1.4, ls="--", color=rgb01(IK_RGB),
                label=f"IK floor (model limit), mean {float(np.nanmean(ik)):.1f} mm")
    s = res.summary
    d_mean = float(s.get("d_mean_mm", float(np.nanmean(D, axis=1).mean())))
    d_max = float(s.get("d_max_mm", float(np.nanmax(D, axis=1).mean())))
    max_label = "max (mean of the runs' maxima)" if len(res.runs) > 1 else "max"
    ax.set_title(f"{_title_head(res)}\nD mean = {d_mean:.1f} mm, {max_label} = {d_max:.1f} mm", fontsize=11)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("3D error D (mm)")
    top = float(np.nanmax(D)) if D.size else 1.0
    ax.set_ylim(0.0, max(top * 1.08, 1.0))
    if len(t) > 1:
        ax.set_xlim(float(t[0]), float(t[-1]))
        fi = res.frame_indices.astype(np.float64)
        slope, icpt = np.polyfit(t, fi, 1) if t[-1] > t[0] else (0.0, 0.0)
        if slope > 0 and np.max(np.abs(slope * t + icpt - fi)) < 0.5:  # frames evenly spaced in time
            sec = ax.secondary_xaxis("top", functions=(lambda x: slope * np.asarray(x) + icpt,
                                                       lambda f: (np.asarray(f) - icpt) / slope))
            sec.set_xlabel("sequence frame", fontsize=9)
            sec.tick_params(labelsize=8)
    ax.grid(True, color="0.88", lw=0.6)
    ax.set_axisbelow(True)
    # beside the axes, not on them: inside it covered the curves' early peaks
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8, frameon=False)
    fig.tight_layout()
    return _save(fig, out_path, dpi)


def per_joint_errors(
    results: str | os.PathLike[str] | Results,
    *,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (10.0, 4.4),
    dpi: float = 110,
) -> Path:
    """Bar chart of the mean error of each of the 15 joints.

    For each joint: the mean over runs (bar, coloured by body side as in the overlays) with the
    smallest and largest of the runs' means of that joint as whiskers, and the IK floor of that joint as a
    grey line across the bar, when ``ik.npz`` is there (a line stays visible at the ~1 mm floor of a
    synthetic sequence, where a bar of its own would be flat and take half of the joint's width).

    Parameters
    ----------
    results : path-like or Results
    out : path-like, optional
        PNG to write; default ``RESULTS_DIR/report/per_joint_errors.png``.
    figsize, dpi : see :func:`error_over_time`.

    Returns
    -------
    pathlib.Path
        The PNG written.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    res = as_results(results)
    out_path = Path(out) if out is not None else default_report_dir(res) / "per_joint_errors.png"
    per_run = res.per_joint_by_run()  # (R, 15)
    mean, lo, hi = per_run.mean(axis=0), per_run.min(axis=0), per_run.max(axis=0)
    ik = None if res.ik_joint_error_mm is None else np.nanmean(res.ik_joint_error_mm, axis=0)
    x = np.arange(len(JOINTS15), dtype=np.float64)
    w = 0.7
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot(1, 1, 1)
    colors = [rgb01(SIDE_RGB[joint_side(n)]) for n in JOINTS15]
    ax.bar(x, mean, width=w, color=colors, edgecolor="black", lw=0.5, zorder=2)
    if len(res.runs) > 1:
        ax.errorbar(x, mean, yerr=np.stack([mean - lo, hi - mean]), fmt="none", ecolor="black",
                    elinewidth=1.0, capsize=3, zorder=3)
    if ik is not None:
        ax.hlines(ik, x - w / 2, x + w / 2, colors=[rgb01(IK_RGB)], lw=2.6, zorder=4)
    ax.set_xticks(x)
    ax.set_xticklabels([n.replace("_", " ") for n in JOINTS15], rotation=40, ha="right", fontsize=9)
    ax.set_ylabel("mean 3D error (mm)")
    spread = "; whiskers: range over the runs" if len(res.runs) > 1 else ""
    ax.set_title(f"{_title_head(res)}: error per joint, mean over {count(len(res.runs), 'run')}{spread}", fontsize=11)
    ax.grid(True, axis="y", color="0.88", lw=0.6)
    ax.set_axisbelow(True)
    handles = [Patch(facecolor=rgb01(SIDE_RGB[s]), edgecolor="black", lw=0.5, label=lab)
               for s, lab in (("left", "left side"), ("right", "right side"), ("center", "torso / head"))]
    if ik is not None:
        handles.append(Line2D([], [], color=rgb01(IK_RGB), lw=2.6, label="IK floor (model limit)"))
    ax.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9, ncol=len(handles))
    ymax = float(max(np.max(hi), np.max(ik) if ik is not None else 0.0))
    ax.set_ylim(0.0, max(ymax * 1.18, 1.0))
    fig.tight_layout()
    return _save(fig, out_path, dpi)
