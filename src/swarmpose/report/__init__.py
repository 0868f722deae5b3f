"""Reports of a results folder (design.md §1 "report", §6): plots, overlays, video and a summary.

Public API
----------
``make_report(results_dir, *, video=False, overlay_frames=4, ...) -> ReportPaths``
    Everything below into ``RESULTS_DIR/report/`` (what ``swarmpose report`` runs).
``error_over_time(results_dir) -> Path``
    D per frame of each run (thin), their mean (thick) and the IK floor (dashed) over time, like
    thesis Fig. 6.5.
``per_joint_errors(results_dir) -> Path``
    Error per joint: mean over runs with whiskers from the smallest to the largest run's, the IK floor beside.
``overlays(results_dir, frames=4, run=0) -> list[Path]``
    PNGs of chosen frames: every view with the estimated cones (left/right/centre in three colours)
    and the ground-truth skeleton.
``overlay_video(results_dir, path, run=0, fps=None, fmt="gif" | "mp4") -> Path``
    The overlays of every frame as an animated GIF or an MP4.
``write_summary(results_dir) -> Path``
    ``summary.md``: configuration, error and per-joint tables, figures, versions.
``write_html(markdown_file) -> Path``
    The same page as one self-contained HTML file (``summary.html``, images embedded).
``write_comparison(compare_dir) -> dict``
    A ``swarmpose compare`` folder's table, figures (error over time per entry, every run's D_mean)
    and HTML page.
``load_results(results_dir) -> Results``
    The folder read into memory (see :mod:`swarmpose.report.results` for the layout).

matplotlib is only imported by the plotting functions (Agg canvas, no window).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from swarmpose.errors import DataError
from swarmpose.report import html as _page
from swarmpose.report.comparison import write_comparison
from swarmpose.report.html import write_html
from swarmpose.report.overlay import mp4_is_h264, overlay_video, overlays, render_overlay
from swarmpose.report.plots import error_over_time, per_joint_errors
from swarmpose.report.results import Results, RunData, load_results
from swarmpose.report.summary import write_summary

__all__ = [
    "ReportPaths",
    "Results",
    "RunData",
    "error_over_time",
    "load_results",
    "make_report",
    "overlay_video",
    "overlays",
    "per_joint_errors",
    "render_overlay",
    "write_comparison",
    "write_html",
    "write_summary",
]


@dataclass
class ReportPaths:
    """What :func:`make_report` wrote.

    Attributes
    ----------
    summary : pathlib.Path
        ``summary.md``.
    html : pathlib.Path or None
        ``summary.html``: the summary as one self-contained page (figures and overlays embedded).
    figures : list of pathlib.Path
        The error plots.
    overlays : list of pathlib.Path
        Overlay PNGs (empty when the sequence could not be found; see ``notes``).
    video : pathlib.Path or None
        The overlay video, if asked for.
    notes : list of str
        Parts that were skipped and why, and what to know about the video (an MP4 most browsers do not play,
        one too large for summary.html to embed).
    """

    summary: Path
    html: Path | None = None
    figures: list[Path] = field(default_factory=list)
    overlays: list[Path] = field(default_factory=list)
    video: Path | None = None
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """``{"summary", "html", "figures", "overlays", "video", "notes"}`` with paths as strings (the CLI's
        ``--json``; ``notes`` says what was skipped and why, as ``compare``'s report does)."""
        return {"summary": str(self.summary), "html": None if self.html is None else str(self.html), "figures": [str(p) for p in self.figures],
                "overlays": [str(p) for p in self.overlays],
                "video": None if self.video is None else str(self.video), "notes": list(self.notes)}


def make_report(
    results_dir: str | os.PathLike[str] | Results,
    *,
    video: bool = False,
    overlay_frames: int = 4,
    run: int = 0,
    out_dir: str | os.PathLike[str] | None = None,
    sequence: str | os.PathLike[str] | None = None,
    video_format: str = "gif",
    video_scale: float = 0.5,
    crop: bool = True,
) -> ReportPaths:
    """Write the whole report of a results folder.

    Parameters
    ----------
    results_dir : path-like or Results
        A folder written by ``swarmpose track``.
    video : bool, default False
        Also write the overlays of every frame as a video; summary.html embeds it (up to
        :data:`swarmpose.report.html.MAX_VIDEO_EMBED_BYTES`, else links it, with a note). An MP4 without
        imageio-ffmpeg is MPEG-4 Part 2, which most browsers do not play: a note says so.
    overlay_frames : int, default 4
        Number of overlay PNGs (spread over the sequence, with the worst frame); 0 for none. Files of an
        earlier report in ``out_dir`` are replaced only by files of the same name (another run's overlays or
        video stay; summary.md names this report's).
    run : int, default 0
        The run drawn in the overlays and the video.
    out_dir : path-like, optional
        Default ``RESULTS_DIR/report``.
    sequence : path-like, optional
        The tracked sequence folder, when ``config.json``'s path no longer points to it.
    video_format : {"gif", "mp4"}, default "gif"
    video_scale : float, default 0.5
        Resize factor of the video pictures.
    crop : bool, default True
        Cut the overlays' views to the person (False: the whole camera views).

    Returns
    -------
    ReportPaths

    Notes
    -----
    Overlays and video need the sequence's images. When the sequence cannot be found the overlays are
    skipped with a note (in ``ReportPaths.notes`` and in ``summary.md``) and the rest is written; a video,
    which is asked for, raises :class:`DataError` before anything is written, as does a ``sequence`` given
    explicitly that is not the tracked sequence.
    """
    res = results_dir if isinstance(results_dir, Results) else load_results(results_dir)
    res.run(run)  # no such finished run: an error before any file of an earlier report is touched
    images_missing: DataError | None = None  # why overlays cannot be drawn, found before anything is written
    if overlay_frames > 0 or video:
        if sequence is not None:
            res.sequence_path(sequence)  # a wrong folder the user named is an error, before anything is drawn
        try:
            res.sequence_path(sequence)
            _ = res.model
        except DataError as exc:
            if video:  # a report that exits 0 without the video asked for would pass for done
                raise DataError(f"no video without the tracked sequence's images: {exc}") from exc
            images_missing = exc
    out = Path(out_dir) if out_dir is not None else res.path / "report"
    out.mkdir(parents=True, exist_ok=True)
    truth = res.summary.get("ground_truth", True) is not False
    if truth:
        figures = [error_over_time(res, out=out / "error_over_time.png"),
                   per_joint_errors(res, out=out / "per_joint_errors.png")]
    else:
        from swarmpose.report.without_truth import fitness_over_time

        figures = [fitness_over_time(res, out / "fitness_over_time.png")]
    notes: list[str] = []
    over: list[Path] = []
    vid: Path | None = None
    # a report writes its files over those of an earlier one of the same name and leaves the others (another
    # run's overlays, a GIF beside a new MP4) as they are: summary.md and summary.html show this report's
    if images_missing is not None:
        notes.append(f"overlays skipped: {images_missing}")
    elif overlay_frames > 0 or video:
        if overlay_frames > 0:
            over = overlays(res, overlay_frames, run=run, out_dir=out / "overlays", sequence=sequence, crop=crop)
        if video:
            vid = overlay_video(res, out / f"overlay_run{run:03d}.{video_format}", run=run,
                                fmt=video_format, scale=video_scale, sequence=sequence, crop=crop)
            if vid.suffix.lower() == ".mp4" and not mp4_is_h264():
                notes.append(f"{vid.name} is MPEG-4 Part 2 (OpenCV's FFmpeg; imageio-ffmpeg is not installed), "
                             "which most browsers do not play: for H.264 install the video extra, pip install "
                             "'swarmpose[video]', and make the report again, or make a GIF")
            size, limit = vid.stat().st_size, _page.MAX_VIDEO_EMBED_BYTES
            if size > limit:
                notes.append(f"{vid.name} is {size / 1e6:.1f} MB, more than the {limit / 1e6:.1f} MB that "
                             "summary.html embeds: the page links it, so send the video with the page")
    confidence: list[str] = []
    if images_missing is None and (overlay_frames > 0 or video):
        from swarmpose.report.confidence import confidence_section

        confidence = confidence_section(res, out, run=run, sequence=sequence)
    if truth:
        summary = write_summary(res, out=out / "summary.md", figures=figures, overlays=over, video=vid, notes=notes,
                                sections=confidence)
    else:
        from swarmpose.report.without_truth import heldout_section, write_summary_without_truth

        heldout: list[str] = []
        if images_missing is None:
            _, heldout = heldout_section(res, out, run=run)
        summary = write_summary_without_truth(res, out / "summary.md", figures=figures, overlays=over,
                                              heldout=heldout + confidence, notes=notes)
    page = write_html(summary)
    return ReportPaths(summary=summary, html=page, figures=figures, overlays=over, video=vid, notes=notes)
