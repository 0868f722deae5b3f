"""``swarmpose bench detect``: the person detector's (MediaPipe Pose's) time per frame on a video or a sequence."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from swarmpose.cli.bench import bench_app
from swarmpose.cli.common import console, err_console, escape, fail_on_user_error, print_json


def _video_frames(path: Path, n: int) -> list:
    from swarmpose.detection.cache import iter_video_frames

    return list(iter_video_frames(path, n))


def _sequence_frames(source: str, n: int, view: int, progress: bool) -> tuple[list, str]:
    from swarmpose.errors import ConfigError
    from swarmpose.io.sequence import open_sequence
    from swarmpose.track.runner import resolve_sequence

    path = resolve_sequence(source, progress=progress)
    with open_sequence(path) as seq:
        if view >= seq.n_views:
            raise ConfigError(f"--view {view}: the sequence has {seq.n_views} views (0 to {seq.n_views - 1})")
        frames = [seq.images(k)[view] for k in range(min(n, seq.n_frames))]
        return frames, seq.view_names[view]


@bench_app.command("detect")
@fail_on_user_error
def detect(
    source: str = typer.Argument(None, help="A video file, a sequence folder or a BVH clip (synthesised as "
                                            "`track` does; default: the shared walk, cmu_16_16_walk)."),
    frames: int = typer.Option(50, min=1, help="Frames to time, the first N in order."),
    view: int = typer.Option(0, min=0, help="The view of a sequence to read (a video has one)."),
    segmentation: bool = typer.Option(True, "--segmentation/--no-segmentation",
                                      help="Compute the person mask too (as the detection cache does)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a table."),
) -> None:
    """Time MediaPipe Pose (model_complexity 1, video mode) per frame on one view: the frames are read
    first, one detection of the first frame builds MediaPipe's graph (reported apart, not counted), then
    every frame is detected in order. Needs the detect extra: pip install 'swarmpose\\[detect]'."""
    import os

    import numpy as np

    from swarmpose.cli.demo import DEFAULT_CLIP
    from swarmpose.detection.mediapipe_pose import MediaPipePose, import_mediapipe_pose
    from swarmpose.errors import DataError

    _, mp_version = import_mediapipe_pose()  # the install hint before anything is read or synthesised
    text = source or str(DEFAULT_CLIP)
    path = Path(text)
    if path.is_file() and path.suffix.lower() != ".bvh":
        kind, view_name = "video", None
        images = _video_frames(path, frames)
    else:
        kind = "sequence"
        images, view_name = _sequence_frames(text, frames, view, progress=not json_out)
    if not images:
        raise DataError(f"{text}: no frame to detect")
    h, w = images[0].shape[:2]
    with MediaPipePose(model_complexity=1, segmentation=segmentation) as det:
        t0 = time.perf_counter()
        det.detect(images[0])  # builds the graph
        startup_ms = 1e3 * (time.perf_counter() - t0)
        det.reset()
        ms, found = [], 0
        for image in images:
            t0 = time.perf_counter()
            d = det.detect(image)
            ms.append(1e3 * (time.perf_counter() - t0))
            found += bool(d.found)
    times = np.array(ms)
    res = {"source": text, "kind": kind, "view": view_name, "frames": len(images), "width": int(w),
           "height": int(h), "ms_per_frame_median": float(np.median(times)),
           "ms_per_frame_mean": float(times.mean()), "frames_per_s": float(1e3 / times.mean()),
           "startup_ms": startup_ms, "found_rate": found / len(images), "detector": "mediapipe-pose",
           "mediapipe": mp_version, "model_complexity": 1, "segmentation": segmentation,
           "cpu_count": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()}
    if json_out:
        print_json(res)
        return
    where = f"{text}" + (f" (view {view_name})" if view_name else "")
    err_console.print(f"[dim]{escape(where)}[/dim]", highlight=False)
    from rich.table import Table

    table = Table(title=f"MediaPipe Pose {mp_version} on {res['frames']} frames of {w}x{h}")
    for col in ("ms per frame (median)", "ms per frame (mean)", "frames/s", "found", "first call ms"):
        table.add_column(col, justify="right", overflow="fold")
    table.add_row(f"{res['ms_per_frame_median']:.1f}", f"{res['ms_per_frame_mean']:.1f}",
                  f"{res['frames_per_s']:.1f}", f"{100 * res['found_rate']:.0f} %", f"{startup_ms:.0f}")
    console.print(table)
