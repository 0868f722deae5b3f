"""The page of an imported recording: cameras, residuals over time, the rig and overlays of masks and keypoints.

:func:`write_import_report` reads a sequence folder written by :func:`swarmpose.datasets.recording.import_recording`
(``import/import.json`` and ``import/keypoints3d.npz``) and writes into its ``import/`` folder:

* ``residuals.png``: per camera, the median reprojection residual of its keypoints (px of the videos) over
  the frames, with the inlier threshold;
* ``rig.png``: the cameras' frusta over the floor (:func:`swarmpose.report.rig.plot_rig`);
* ``overlay_<frame>.png``: every view of a frame with the stored silhouette tinted, the detected keypoints
  (the body's left blue, right orange) and the triangulated joints projected back (white rings);
* ``summary.md`` and ``summary.html``: the tables and pictures as one page.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import cv2
import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.errors import DataError
from swarmpose.io.sequence import open_sequence
from swarmpose.joints import BONES15, JOINTS15
from swarmpose.report._style import SIDE_RGB, bgr, joint_side
from swarmpose.triangulation import reproject

__all__ = ["write_import_report", "overlay_frame"]

_IMPORT = "import"


def _load(folder: Path) -> tuple[dict, dict | None]:
    info_path = folder / _IMPORT / "import.json"
    if not info_path.is_file():
        raise DataError(f"{folder}: not an imported recording (no {_IMPORT}/import.json; `swarmpose import` writes it)")
    info = json.loads(info_path.read_text())
    kp_path = folder / _IMPORT / "keypoints3d.npz"
    arrays = None
    if kp_path.is_file():
        with np.load(kp_path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    return info, arrays


def overlay_frame(images: np.ndarray, silhouettes: np.ndarray | None, keypoints: np.ndarray | None,
                  projected: np.ndarray | None, *, max_height: int = 480) -> np.ndarray:
    """One BGR picture of all views side by side: silhouette tinted, keypoints, projected joints.

    ``images``/``silhouettes`` (C, H, W) uint8; ``keypoints``/``projected`` (C, 15, 2) px of the images.
    """
    C, H, W = images.shape
    f = min(1.0, max_height / H)
    tiles = []
    for c in range(C):
        tile = cv2.cvtColor(images[c], cv2.COLOR_GRAY2BGR)
        if silhouettes is not None:
            m = silhouettes[c] > 0
            tile[m] = (0.55 * tile[m] + 0.45 * np.array(bgr(SIDE_RGB["center"]))).astype(np.uint8)
        tile = cv2.resize(tile, (max(1, round(W * f)), max(1, round(H * f))), interpolation=cv2.INTER_AREA)
        scale = lambda p: (int(round((p[0] + 0.5) * f - 0.5)), int(round((p[1] + 0.5) * f - 0.5)))  # noqa: E731
        lw = max(1, round(2 * f * H / 480))
        if keypoints is not None:
            kp = keypoints[c]
            for a, b in BONES15:
                if np.isfinite(kp[[a, b]]).all():
                    side = joint_side(JOINTS15[b])
                    cv2.line(tile, scale(kp[a]), scale(kp[b]), bgr(SIDE_RGB[side]), lw, cv2.LINE_AA)
            for j in range(15):
                if np.isfinite(kp[j]).all():
                    cv2.circle(tile, scale(kp[j]), lw + 1, bgr(SIDE_RGB[joint_side(JOINTS15[j])]), -1, cv2.LINE_AA)
        if projected is not None:
            for j in range(15):
                p = projected[c, j]
                if np.isfinite(p).all():
                    cv2.circle(tile, scale(p), lw + 3, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
    return np.hstack(tiles)


def _residual_plot(path: Path, names: list[str], residual: np.ndarray, confidence: np.ndarray, threshold: float,
                   fps: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = np.where(confidence >= MIN_CONFIDENCE, residual, np.nan)
    T = r.shape[0]
    t = np.arange(T)
    fig, ax = plt.subplots(figsize=(9, 3.6), dpi=110)
    colours = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000"]
    with warnings.catch_warnings():  # a view without confident joints in a frame: a gap in its line
        warnings.simplefilter("ignore", RuntimeWarning)
        for c, name in enumerate(names):
            ax.plot(t, np.nanmedian(r[:, c], axis=1), lw=1.4, color=colours[c % len(colours)], label=name)
        ax.plot(t, np.nanmedian(r.reshape(T, -1), axis=1), lw=2.2, color="k", alpha=0.6, label="frame (all views)")
    ax.axhline(threshold, color="grey", ls="--", lw=1)
    ax.text(0, threshold, " inlier threshold", va="bottom", fontsize=8, color="grey")
    ax.set_xlabel(f"frame (at {fps:g} fps)")
    ax.set_ylabel("median residual (px of the videos)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.set_title("Keypoints triangulated from all views, reprojected into each", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_import_report(folder: str | Path, *, frames: int = 4) -> Path:
    """Write the import's page (see the module docstring) and return ``import/summary.html``."""
    from swarmpose.report.html import write_html
    from swarmpose.report.rig import plot_rig

    folder = Path(folder)
    info, arrays = _load(folder)
    out = folder / _IMPORT
    seq = open_sequence(folder)
    try:
        names = seq.view_names
        T = seq.n_frames
        plot_rig(seq.cameras, out / "rig.png", title=f"{folder.name}: {len(names)} cameras")
        lines = [f"# Imported recording `{folder.name}`", "",
                 f"{T} frames at {seq.frame_rate:g} fps, {len(names)} views of {seq.image_size[0]}x{seq.image_size[1]} "
                 f"px, imported in {info['seconds'].get('total', float('nan')):.0f} s.", ""]
        lines += ["| camera | video | fx px | position (m) | offset (frames) | person found | median residual px |",
                  "|---|---|---:|---|---:|---:|---:|"]
        for c, cam in enumerate(seq.cameras):
            pos = cam.center / 1000
            res = info["residual_px"].get(cam.name)
            found = info["found_rate"].get(cam.name)
            lines.append(f"| {cam.name} | {Path(info['videos'][c]).name} | {cam.fx:.1f} | "
                         f"({pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}) | {info['offsets'][c]} | "
                         f"{'–' if found is None else f'{100 * found:.0f} %'} | "
                         f"{'–' if res is None or not math.isfinite(res) else f'{res:.1f}'} |")
        lines.append("")
        if info.get("frame_residual_max_px") is not None:
            lines.append(f"Largest per-frame median residual: **{info['frame_residual_max_px']:.1f} px** (frame "
                         f"{info['worst_frame']}). Left and right exchanged in {info['swapped_view_frames']} view-frames; "
                         f"{info['redetected_view_frames']} view-frames detected again inside the subject's region, "
                         f"{info['dropped_view_frames']} dropped (somebody else, or nobody).")
            lines.append("")
        search = info.get("offset_search")
        if search:
            lines.append(f"Automatic offsets over {search['frames']} frames: mean capped residual "
                         f"{search['cost_before_px']:.2f} px with offsets 0, {search['cost_after_px']:.2f} px with "
                         f"{search['offsets']}.")
            lines.append("")
        if info.get("notes"):
            lines += ["## Notes", ""] + [f"- {n}" for n in info["notes"]] + [""]
        if arrays is not None:
            _residual_plot(out / "residuals.png", names, arrays["residual"], arrays["confidence"],
                           float(arrays["threshold"]), seq.frame_rate)
            lines += ["## Residuals over time", "", "![residuals](residuals.png)", ""]
        lines += ["## The rig", "", "![rig](rig.png)", ""]
        picks = sorted({0, T // 2, T - 1} | ({info["worst_frame"]} if info.get("worst_frame") is not None else set()))
        picks = picks[:max(1, frames)]
        lines += ["## Overlays", "",
                  "Stored silhouette tinted green; detected keypoints (the person's left blue, right orange); "
                  "the joints triangulated from all views projected back as white rings.", ""]
        dense = None if seq.marker_data is None else seq.marker_data.to_dense()[0]
        for k in picks:
            images = seq.images(k)
            sil = seq.silhouettes(k)
            kp = None if dense is None else dense[k]
            # the sequence's cameras take the world joints straight to its own (scaled) pixels
            proj = None if arrays is None else reproject(seq.cameras, arrays["points"][k])
            pic = overlay_frame(images, sil, kp, proj)
            name = f"overlay_{k:05d}.png"
            cv2.imwrite(str(out / name), pic)
            lines += [f"Frame {k}" + (" (largest residual)" if k == info.get("worst_frame") else ""), "",
                      f"![frame {k}]({name})", ""]
    finally:
        seq.close()
    md = out / "summary.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return write_html(md, title=f"swarmpose import: {folder.name}")
