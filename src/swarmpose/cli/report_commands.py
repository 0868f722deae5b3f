"""``swarmpose report`` and ``swarmpose export``: plots, overlays and a summary of a results folder;
the tracked motion as BVH, TRC or C3D."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    console,
    count,
    err_console,
    escape,
    fail_on_user_error,
    names_a_folder,
    print_json,
)


@app.command()
@fail_on_user_error
def report(
    results_dir: Annotated[Path, typer.Argument(help="A results folder written by `swarmpose track`, or a "
                                                     "`swarmpose compare` folder (its figures and page are "
                                                     "redrawn).")],
    video: Annotated[bool, typer.Option("--video", help="Also write the overlays of every frame as a video "
                                                        "(summary.html embeds it).")] = False,
    frames: Annotated[int, typer.Option("--frames", min=0,
                                        help="Number of overlay images (with the worst frame); 0: none.")] = 4,
    run: Annotated[int, typer.Option("--run", min=0, help="The run drawn in the overlays and the video.")] = 0,
    video_format: Annotated[str | None, typer.Option("--format", help="Video format with --video: gif (default), or "
                                                                      "mp4: H.264 with the 'video' extra (pip "
                                                                      "install 'swarmpose\\[video]'), else OpenCV's "
                                                                      "MPEG-4 Part 2, which most browsers do not "
                                                                      "play.")] = None,
    sequence: Annotated[Path | None, typer.Option("--sequence", help="The tracked sequence folder, if it has "
                                                                     "moved since tracking.")] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Report folder (default RESULTS_DIR/report).")] = None,
    full_views: Annotated[bool, typer.Option("--full-views", help="Draw the whole camera views in the overlays "
                                                                  "(default: each view cut to the person).")] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object with the paths written.")] = False,
) -> None:
    """Write a report: error-over-time and per-joint plots, overlay images (and a video), summary.md and
    summary.html (the same page with every image embedded, to open in a browser or send).

    The error plot shows D per frame of each run, their mean and the IK floor (thesis Fig. 6.5);
    the overlays draw the tracked cones (left limbs blue, right limbs orange, torso/head green)
    and the ground-truth skeleton (yellow) on every camera view, cut to the person; runs tracked on
    2D markers also show the detections (sky-blue rings).

    On a `swarmpose compare` folder (one with comparison.json) it redraws that comparison's figures,
    comparison.md and comparison.html; each entry's own folder (<clip>/<entry>/) takes this command too.
    """
    from swarmpose.errors import ConfigError
    from swarmpose.report import make_report

    if (results_dir / "comparison.json").is_file() and not (results_dir / "config.json").is_file():
        _report_comparison(results_dir, json_out=json_out, given={
            "--video": video, "--run": run != 0, "--format": video_format is not None, "--sequence": sequence is not None,
            "--out": out is not None, "--full-views": full_views, "--frames": frames != 4})
        return

    if out is not None and out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} is a file; the report needs a folder")
    if video_format is not None and not video:
        raise ConfigError(f"--format {video_format} chooses the video's format: add --video to write one")
    video_format = (video_format or "gif").lower()
    if video_format not in ("gif", "mp4"):  # before any figure is written
        raise ConfigError(f"--format must be gif or mp4, got {video_format!r}")
    paths = make_report(results_dir, video=video, overlay_frames=frames, run=run, out_dir=out,
                        sequence=sequence, video_format=video_format, crop=not full_views)
    for note in paths.notes:
        err_console.print(f"[yellow]note:[/yellow] {escape(note)}", highlight=False)
    if json_out:
        print_json(paths.to_dict())
        return
    console.print(f"[bold]report of {escape(str(results_dir))}[/bold]")
    console.print(f"  summary  {paths.summary}", markup=False, highlight=False)
    if paths.html is not None:
        console.print(f"  page     {paths.html}  (self-contained: open in a browser)", markup=False, highlight=False)
    for p in paths.figures:
        console.print(f"  figure   {p}", markup=False, highlight=False)
    for p in paths.overlays:
        console.print(f"  overlay  {p}", markup=False, highlight=False)
    if paths.video is not None:
        console.print(f"  video    {paths.video}", markup=False, highlight=False)


def _report_comparison(folder: Path, *, json_out: bool, given: dict[str, bool]) -> None:
    """`swarmpose report COMPARE_DIR`: the comparison's figures, comparison.md and comparison.html redrawn."""
    from swarmpose.errors import ConfigError
    from swarmpose.report.comparison import entry_folder, load_comparison, write_comparison

    report = load_comparison(folder)
    used = [opt for opt, on in given.items() if on]
    if used:
        example = entry_folder(folder, report["rows"][0]) if report["rows"] else folder / "<clip>" / "<entry>"
        raise ConfigError(f"{', '.join(used)} {'applies' if len(used) == 1 else 'apply'} to one results folder; {folder} is a comparison: report one of "
                          f"its entries with them (e.g. swarmpose report {example})")
    paths = write_comparison(folder, report)
    for note in paths["notes"]:
        err_console.print(f"[yellow]note:[/yellow] {escape(note)}", highlight=False)
    if json_out:
        print_json(paths)
        return
    console.print(f"[bold]comparison {escape(str(report['suite']))} in {escape(str(folder))}[/bold]")
    console.print(f"  table    {paths['comparison']}", markup=False, highlight=False)
    console.print(f"  page     {paths['html']}  (self-contained: open in a browser)", markup=False, highlight=False)
    for p in paths["figures"]:
        console.print(f"  figure   {p}", markup=False, highlight=False)


@app.command()
@fail_on_user_error
def export(
    results_dir: Annotated[Path, typer.Argument(help="A results folder written by `swarmpose track`.")],
    out: Annotated[str, typer.Option("--out", help="The file to write; its suffix picks the format: .bvh "
                                                   "(animation tools), .trc (OpenSim markers) or .c3d (lab "
                                                   "format). A folder (existing or ending in /): "
                                                   "<results folder>_runXXX.bvh in it.")],
    run: Annotated[int, typer.Option("--run", min=0, help="Which run to export.")] = 0,
    z_up: Annotated[bool, typer.Option("--z-up", help="BVH: keep the world's Z-up axes (default: Y up, "
                                                      "(x, z, -y)); `swarmpose info` and `ik` do not read "
                                                      "such files back.")] = False,
    unit: Annotated[str, typer.Option("--unit", "--units", help="Length unit of the file: mm, cm or m for BVH; "
                                                                "mm or m for TRC; C3D is in mm.")] = "mm",
    order: Annotated[str, typer.Option("--order", help="BVH: rotation channel order of every joint (ZXY, XYZ, "
                                                       "...), or 'model' for each joint's own axes.")] = "ZXY",
    rest_facing: Annotated[str | None, typer.Option("--rest-facing", help="BVH: where the rest pose (all channels "
                                                    "zero) faces in a Y-up file: +z (what animation tools expect; the "
                                                    "default) or +x (the body model's own zero pose). A --z-up "
                                                    "file always keeps the model's zero pose. Only default files "
                                                    "(Y up, +z) can be read back by `swarmpose info` and `ik`.")] = None,
    resample: Annotated[bool, typer.Option("--resample/--no-resample", help="When the tracked frames are not evenly "
                                           "spaced (25 fps from a 60 fps sequence: 33 and 50 ms), interpolate "
                                           "the poses onto an even 1/fps clock (BVH and C3D have one frame time); "
                                           "--no-resample writes the tracked frames as they are (a TRC file "
                                           "keeps their times in its Time column).")] = True,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the --out file when it exists.")] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a line: the file "
                                                          "written, its format, frames, units and axes.")] = False,
) -> None:
    """Export a run's tracked motion: BVH for animation tools (Blender, MotionBuilder), TRC for
    OpenSim, C3D for biomechanics tools (Mokka, Vicon, Visual3D). The --out suffix picks the format.

    BVH: the hierarchy is the body model's joint tree with the subject's limb lengths; the frame rate
    is the tracking rate. Y up by default: a BVH vector is (x, z, -y) of the swarmpose world (Z up, mm),
    so the joints land where `track` put them, and the rest pose stands facing +Z (--rest-facing +x: the
    model's own zero pose, facing +X; --z-up keeps the world's axes and the model's zero pose).

    TRC: the 15 tracked joints as markers, in OpenSim's layout, Y up: (x, z, -y) of the world (the
    model's zero pose faces +X, its right on +Z), in mm or m (--unit); a missing joint has empty fields.

    C3D: the 15 tracked joints as labelled points in the world's own axes (Z up, mm), POINT:RATE the
    frame rate; a missing joint has residual -1. Needs ezc3d: pip install 'swarmpose\\[export]'.
    """
    import numpy as np

    from swarmpose.errors import ConfigError
    from swarmpose.export import REST_FACINGS, export_bvh, uniform_clock
    from swarmpose.report.results import load_results

    fmt = "bvh" if names_a_folder(out) else Path(out).suffix.lower().lstrip(".")
    if fmt not in EXPORT_FORMATS:
        raise ConfigError(f"--out {out}: the suffix picks the format: .bvh, .trc or .c3d")
    units = EXPORT_UNITS[fmt]
    if unit not in units:
        raise ConfigError(f"--unit must be one of {', '.join(units)}" + (f" for {fmt.upper()}" if fmt != "bvh" else "")
                          + f", got {unit!r}")
    if fmt != "bvh":
        given = [opt for opt, on in (("--z-up", z_up), ("--order", order != "ZXY"),
                                     ("--rest-facing", rest_facing is not None)) if on]
        if given:
            raise ConfigError(f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to BVH files; "
                              f"a {fmt.upper()} file holds {EXPORT_AXES[fmt][1]} of the world")
        if fmt == "c3d":
            from swarmpose.export.c3d_export import require_ezc3d

            require_ezc3d()  # before anything is read: the error says how to install it
    if rest_facing is not None and rest_facing.lower() not in REST_FACINGS:
        raise ConfigError(f"--rest-facing must be one of {', '.join(REST_FACINGS)}, got {rest_facing!r}")
    if z_up and rest_facing is not None and rest_facing.lower() != "+x":
        raise ConfigError("--rest-facing +z applies to Y-up files; a --z-up file keeps the model's zero pose (+x)")
    rest_facing = (rest_facing or ("+x" if z_up else "+z")).lower()
    res = load_results(results_dir)
    r = res.run(run)
    if names_a_folder(out):  # the file goes into it
        out = Path(out) / f"{Path(results_dir).resolve().name}_run{run:03d}.bvh"
    out = Path(out)
    if out.exists() and not force:  # a mistyped --out must not clobber a source clip
        raise ConfigError(f"--out {out} exists; add --force to overwrite it")
    fps = res.fps
    if not fps > 0:
        raise ConfigError(f"{results_dir / 'config.json'}: no tracking frame rate ('fps') recorded")
    T = r.joints.shape[0]
    tracked = r.params if fmt == "bvh" else r.joints.reshape(T, -1)
    even, grid, uneven = uniform_clock(tracked, r.frame_times, fps)
    values, times = (even, grid) if resample else (tracked, r.frame_times)
    resampled = resample and uneven
    d = np.diff(r.frame_times)
    if resampled:
        err_console.print(f"note: the tracked frames are {1000 * d.min():.0f}-{1000 * d.max():.0f} ms apart; "
                          f"the {'poses' if fmt == 'bvh' else 'joints'} are interpolated onto an even "
                          f"{1000 / fps:.1f} ms clock ({len(values)} frames from {T})", highlight=False)
    elif uneven and fmt == "trc":
        err_console.print(f"note: the tracked frames are {1000 * d.min():.0f}-{1000 * d.max():.0f} ms apart; the "
                          f"Time column keeps them and DataRate says {fps:g} fps", highlight=False)
    elif uneven:
        err_console.print(f"[yellow]warning:[/yellow] the tracked frames are {1000 * d.min():.0f}-{1000 * d.max():.0f} ms "
                          f"apart but the file says {1000 / fps:.1f} ms each: its timing is warped "
                          "(--resample interpolates onto an even clock)", highlight=False)
    interval = {"min": round(float(d.min()), 6), "max": round(float(d.max()), 6)} if d.size else None
    if fmt == "bvh":
        scales = {"mm": 1.0, "cm": 0.1, "m": 0.001}
        path = export_bvh(res.model, values, fps, out, y_up=not z_up, rotation_order=order,
                          scale=scales[unit], rest_facing=rest_facing)
        data = {"bvh": str(path), "file": str(path), "format": "bvh", "run": run, "frames": int(values.shape[0]),
                "frame_rate": float(fps), "joints": len(res.model.spec.joints), "axes": "z_up" if z_up else "y_up",
                "unit": unit, "units": unit, "rotation_order": order, "rest_facing": rest_facing,
                "resampled": resampled, "tracked_frames": T,
                # to the microsecond: frame times are differences of seconds (0.05 printed as 0.04999999999999982)
                "tracked_interval_s": interval}
        if json_out:
            print_json(data)
            return
        console.print(f"wrote {path}: {data['frames']} frames at {fps:g} fps, {data['joints']} joints "
                      f"({'Z' if z_up else 'Y'} up, {unit})", markup=False, highlight=False)
        return

    from swarmpose.export.c3d_export import write_c3d
    from swarmpose.export.trc import write_trc
    from swarmpose.joints import JOINTS15

    joints = values.reshape(len(values), len(JOINTS15), 3)
    if fmt == "trc":
        path = write_trc(out, joints, times, names=JOINTS15, units=unit, frame_rate=fps)
    else:
        path = write_c3d(out, joints, times, names=JOINTS15, frame_rate=fps)
    axes, mapping = EXPORT_AXES[fmt]
    missing = int((~np.isfinite(joints).all(axis=2)).sum())
    data = {"file": str(path), "format": fmt, "run": run, "frames": int(len(joints)), "frame_rate": float(fps),
            "markers": len(JOINTS15), "units": unit, "axes": axes, "from_world": mapping, "missing_points": missing,
            "start_s": round(float(times[0]), 6), "resampled": resampled, "tracked_frames": T,
            "tracked_interval_s": interval}
    if json_out:
        print_json(data)
        return
    gaps = f", {count(missing, 'missing point')}" if missing else ""
    console.print(f"wrote {path}: {data['frames']} frames at {fps:g} fps, {len(JOINTS15)} "
                  f"{'markers' if fmt == 'trc' else 'points'}{gaps} ({axes[0].upper()} up: {mapping} of the "
                  f"world, {unit})", markup=False, highlight=False)


#: ``swarmpose export`` formats (the --out suffix) and the units each takes.
EXPORT_UNITS = {"bvh": ("mm", "cm", "m"), "trc": ("mm", "m"), "c3d": ("mm",)}
EXPORT_FORMATS = tuple(EXPORT_UNITS)
#: The axes of the TRC and C3D files (``--json`` ``axes``) and the world vector each holds.
EXPORT_AXES = {"trc": ("y_up", "(x, z, -y)"), "c3d": ("z_up", "(x, y, z)")}
