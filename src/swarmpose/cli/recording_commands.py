"""``swarmpose import`` and ``swarmpose cameras``: your own videos and calibration files in."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import console, err_console, escape, fail_on_user_error, print_json


def _expand_sources(paths: list[Path]) -> list[Path]:
    """A folder of videos stands for its videos; anything else (a video, an image folder) for itself."""
    from swarmpose.io.video import VIDEO_SUFFIXES

    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            videos = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in VIDEO_SUFFIXES)
            if videos:
                out.extend(videos)
                continue
        out.append(p)
    return out


def _offsets(items: list[str]) -> dict[str, int]:
    from swarmpose.errors import ConfigError

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = int(value)
        except ValueError:
            raise ConfigError(f"--offset {item!r}: expected NAME=FRAMES, e.g. cam02=1") from None
    return out


@app.command("import")
@fail_on_user_error
def import_(
    sources: Annotated[list[Path], typer.Argument(
        help="One video file or image folder per camera, named after its camera (cam01.mp4), or a folder of "
             "videos.", show_default=False)],
    calibration: Annotated[Path, typer.Option("--calibration", "-c", help=(
        "The cameras' calibration: Pose2Sim/aniposelib/FreeMoCap TOML, OpenCV YAML/XML, EasyMocap intri.yml "
        "(extri.yml beside it), or Qualisys .qca.txt."), show_default=False)],
    out: Annotated[Path, typer.Option("--out", "-o", help="The sequence folder to write.", show_default=False)],
    extrinsics: Annotated[Path, typer.Option(help="EasyMocap extri.yml, when not beside intri.yml.")] = None,
    start: Annotated[int, typer.Option(help="First frame (of the reference camera, the first video).")] = 0,
    stop: Annotated[int, typer.Option(help="Stop before this frame (default: the end).")] = None,
    step: Annotated[int, typer.Option(help="Take every step-th frame (the sequence's rate is the videos' / step).")] = 1,
    scale: Annotated[float, typer.Option(help="Resize the stored images by this factor (0.5: half size); the "
                                               "calibration is scaled with them.")] = 1.0,
    offset: Annotated[list[str], typer.Option(help="NAME=FRAMES: camera NAME shows frame k in its own frame "
                                                    "k + FRAMES. Repeat per camera.")] = None,
    auto_offsets: Annotated[bool, typer.Option("--auto-offsets", help=(
        "Estimate each camera's offset from the keypoints (the offsets that minimise the triangulation "
        "residual).")) ] = False,
    max_offset: Annotated[int, typer.Option(help="Largest offset --auto-offsets tries, frames.")] = 5,
    common_range: Annotated[bool, typer.Option("--common-range", help=(
        "Accept videos of different lengths: import the frames every camera has.")) ] = False,
    silhouettes: Annotated[str, typer.Option(help=(
        "learned: the detector's person segmentation (no empty scene needed); median: background subtraction "
        "against the temporal median of the frames; background: against --background; none."))] = "learned",
    background: Annotated[list[Path], typer.Option(help="Empty-scene video, image or image folder, one per camera "
                                                        "in the videos' order (--silhouettes background).")] = None,
    detect: Annotated[bool, typer.Option("--detect/--no-detect", help=(
        "Detect the person's keypoints and mask (MediaPipe Pose: pip install 'swarmpose\\[detect]')."))] = True,
    threshold: Annotated[float, typer.Option(help="Largest median residual (px of the videos) of a view that "
                                                  "shows the subject (default 2.5 % of the image diagonal).")] = None,
    fps: Annotated[float, typer.Option(help="Frame rate of image folders (videos state their own).")] = None,
    units: Annotated[str, typer.Option(help="The calibration's length unit (m, cm, mm) when its format does not "
                                            "state it.")] = None,
    up: Annotated[str, typer.Option(help="The calibration's up axis (+z, -y, ...); detected by default.")] = None,
    cache_dir: Annotated[Path, typer.Option(help="Where detections are kept between imports.")] = Path("cache/detections"),
    page: Annotated[bool, typer.Option("--page/--no-page", help="Write the HTML page with overlays and residuals "
                                                                 "(import/summary.html).")] = True,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing sequence folder.")] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a summary.")] = False,
) -> None:
    """Import your own recording: one video per camera and a calibration file become a sequence folder.

    The person is detected in every view (keypoints and a segmentation mask: no empty-scene frame needed),
    the subject is kept across views and frames by agreement with the calibration, left and right are resolved
    across views, and the import reports each camera's reprojection residual. Track the folder with
    `swarmpose track OUT`.
    """
    from swarmpose.datasets.recording import ImportOptions, import_recording

    opts = ImportOptions(start=start, stop=stop, step=step, scale=scale, offsets=_offsets(offset or []),
                         auto_offsets=auto_offsets, max_offset=max_offset, common_range=common_range,
                         silhouettes=silhouettes, background=background or None, detect=detect, threshold=threshold,
                         fps=fps, units=units, up=up, extrinsics=extrinsics, cache_dir=cache_dir)
    result = import_recording(_expand_sources(sources), calibration, out, options=opts, force=force,
                              progress=not json_out)
    html = None
    if page:
        from swarmpose.report.recording import write_import_report

        html = write_import_report(out)
    if json_out:
        print_json({**result.to_dict(), "page": None if html is None else str(html)})
        return
    console.print(f"wrote [bold]{escape(str(out))}[/bold]: {result.n_frames} frames at {result.frame_rate:g} fps, "
                  f"{len(result.cameras)} views of {result.image_size[0]}x{result.image_size[1]}", highlight=False)
    for name, res in result.residual_px.items():
        found = result.found_rate.get(name)
        console.print(f"  {escape(name)}: offset {result.offsets[result.cameras.index(name)]:+d}, person found in "
                      f"{100 * (found or 0):.0f} % of frames, median residual "
                      f"{'–' if not math.isfinite(res) else f'{res:.1f} px'}", highlight=False)
    if result.frame_residual_max_px is not None:
        console.print(f"  largest per-frame median residual {result.frame_residual_max_px:.1f} px (frame "
                      f"{result.worst_frame}); left/right resolved in {result.swapped_view_frames} view-frames, "
                      f"{result.dropped_view_frames} view-frames dropped", highlight=False)
    if result.offset_search:
        s = result.offset_search
        console.print(f"  automatic offsets {s['offsets']}: mean capped residual {s['cost_before_px']:.2f} -> "
                      f"{s['cost_after_px']:.2f} px", highlight=False)
    for note in result.notes:
        err_console.print(f"  [yellow]note[/yellow] {escape(note)}", highlight=False)
    if html is not None:
        console.print(f"page: {escape(str(html))}", highlight=False)


@app.command()
@fail_on_user_error
def cameras(
    source: Annotated[Path, typer.Argument(help="A calibration file, or an imported sequence folder.",
                                           show_default=False)],
    extrinsics: Annotated[Path, typer.Option(help="EasyMocap extri.yml, when not beside intri.yml.")] = None,
    units: Annotated[str, typer.Option(help="The calibration's length unit (m, cm, mm) when not stated.")] = None,
    up: Annotated[str, typer.Option(help="The calibration's up axis (+z, -y, ...); detected by default.")] = None,
    picture: Annotated[Path, typer.Option(help="Draw the rig (frusta over the floor) into this PNG.")] = None,
    convert: Annotated[Path, typer.Option(help="Write the cameras to this file: .toml, .yml/.xml (OpenCV), or "
                                                "intri.yml (EasyMocap pair, extri.yml beside it).")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")] = False,
) -> None:
    """Show a calibration: each camera's intrinsics, position and residual, the unit and up axis it was read
    with; draw the rig; convert it to another format."""
    import json

    import numpy as np

    residual: dict[str, float] = {}
    notes: list[str] = []
    if source.is_dir():
        from swarmpose.io.sequence import open_sequence

        with open_sequence(source) as seq:
            cams = list(seq.cameras)
        info = source / "import" / "import.json"
        if info.is_file():
            residual = json.loads(info.read_text()).get("residual_px", {})
        fmt, unit, up_axis = "sequence", "mm", "+z"
    else:
        from swarmpose.io.calibration import read_calibration

        calib = read_calibration(source, extrinsics=extrinsics, units=units, up=up)
        cams, notes = list(calib.cameras), list(calib.notes)
        fmt, unit, up_axis = calib.format, f"{calib.units} ({calib.units_source})", f"{calib.up} ({calib.up_source})"
    rows = []
    for cam in cams:
        pos = cam.center
        look = cam.R[2]
        rows.append({"name": cam.name, "width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy,
                     "cx": cam.cx, "cy": cam.cy, "dist": list(cam.dist), "position_mm": pos.tolist(),
                     "looking_down_deg": float(np.degrees(np.arcsin(-look[2]))),
                     "residual_px": residual.get(cam.name)})
    written = []
    if convert is not None:
        from swarmpose.io.calibration import write_calibration

        suffix = convert.suffix.lower()
        fmt_out = "toml" if suffix == ".toml" else "easymocap" if convert.name.startswith("intri") else "opencv"
        written = [str(p) for p in write_calibration(convert, cams, fmt_out)]
    if picture is not None:
        from swarmpose.report.rig import plot_rig

        plot_rig(cams, picture, title=f"{source.name}: {len(cams)} cameras")
    if json_out:
        print_json({"source": str(source), "format": fmt, "units": unit, "up": up_axis, "cameras": rows,
                    "notes": notes, "picture": None if picture is None else str(picture), "written": written})
        return
    console.print(f"[bold]{escape(source.name)}[/bold]: {fmt}, units {unit}, up {up_axis}", highlight=False)
    head = f"{'camera':<14} {'size':>9} {'fx px':>7} {'cx, cy px':>13} {'k1':>6} {'position (m)':>20} {'down':>5} {'resid.':>7}"
    console.print(head, markup=False, highlight=False)
    for r in rows:
        p = np.asarray(r["position_mm"]) / 1000
        res = r["residual_px"]
        console.print(f"{r['name'][:14]:<14} {r['width']:>4}x{r['height']:<4} {r['fx']:>7.1f} "
                      f"{r['cx']:>6.1f},{r['cy']:>6.1f} {r['dist'][0]:>6.3f} "
                      f"{f'({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})':>20} {r['looking_down_deg']:>4.0f}° "
                      f"{'–' if res is None else f'{res:.1f} px':>7}", markup=False, highlight=False)
    for n in notes:
        console.print(f"  [yellow]note[/yellow] {escape(n)}", highlight=False)
    if picture is not None:
        console.print(f"rig picture: {escape(str(picture))}", highlight=False)
    for w in written:
        console.print(f"wrote {escape(w)}", highlight=False)
