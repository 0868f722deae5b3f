"""``swarmpose demo``: the main job on the shared walking clip (what ``make demo`` runs)."""

from __future__ import annotations

from pathlib import Path

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    DEFAULT_ALGO,
    DEFAULT_FEATURE_CACHE,
    console,
    err_console,
    escape,
    fail_on_user_error,
    print_json,
)

DEFAULT_CLIP = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "mocap" / "cmu_16_16_walk.bvh"


@app.command()
@fail_on_user_error
def demo(
    clip: Path = typer.Option(DEFAULT_CLIP, help="BVH clip to run on (default: the shared walking clip)."),
    out: Path = typer.Option(Path("results/demo"), help="Results folder."),
    algo: str = typer.Option(DEFAULT_ALGO, help="Algorithm (see `swarmpose algorithms`)."),
    fps: float = typer.Option(20.0, help="Tracking frame rate."),
    runs: int = typer.Option(3, min=1, help="Independent runs."),
    seed: int = typer.Option(0, min=0, help="Seed (>= 0); run k draws from SeedSequence(\\[seed, k])."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object with the summary and paths."),
) -> None:
    """Synthesise the walking clip (cached), track it with the default tracker (refined-heading) at 20 fps, write
    results and a report.

    Steps: render the clip's real motion capture into 4 HumanEva-like cameras (once; cached under
    cache/sequences), fit the IK floor, track every run in parallel, then write the error graphs,
    per-joint plot, overlay images, summary.md and summary.html (the page with every image embedded)
    into OUT/report/.
    """
    from swarmpose.cli.track_commands import check_tracking_rate, is_clip
    from swarmpose.report import make_report
    from swarmpose.report.results import largest_run_maximum
    from swarmpose.track.runner import check_results_folder, resolve_sequence, track_runs
    from swarmpose.track.tracker import TrackConfig

    if not Path(clip).is_file():
        where = (": the shared data folder (../shared/data/mocap) must sit beside the repository (an install "
                 "outside the repository: pass --clip PATH/cmu_16_16_walk.bvh)" if Path(clip) == DEFAULT_CLIP else "")
        raise FileNotFoundError(f"demo clip {clip} not found{where}")
    check_tracking_rate(fps, clip if is_clip(clip) else None)  # before the clip is synthesised
    seq = resolve_sequence(clip, progress=not json_out)
    config = TrackConfig(algo=algo, fps=fps, seed=seed)
    summary = _finished(out)
    if summary is not None and summary.get("runs", 0) >= runs:
        check_results_folder(out, seq, config, runs, resume=True)  # other settings, fewer runs: refused, named
        err_console.print(f"[yellow]{escape(str(out))}/summary.json exists: reusing the tracked runs (delete the folder to "
                          f"redo){escape(_made_by_other_code(out))}[/yellow]")
    else:  # a fresh demo, an interrupted one (resumed) or more runs than a finished one (added)
        summary = track_runs(seq, config, runs, out, resume=(out / "config.json").is_file(), progress=not json_out,
                             feature_cache=DEFAULT_FEATURE_CACHE)
    paths = make_report(out, overlay_frames=4)
    data = {**summary, "report": str(paths.summary), "html": str(paths.html), "figures": [str(p) for p in paths.figures],
            "overlays": [str(p) for p in paths.overlays]}
    if json_out:
        print_json(data)
        return
    console.print(f"[bold]{algo}[/bold] on {escape(Path(clip).name)} at {fps:g} fps, {runs} runs, "
                  f"{summary['evals_per_frame']} evaluations per frame")
    d_max = f"D_max {summary['d_max_mm']:.1f} mm"
    largest = largest_run_maximum(summary)  # also for a reused folder written before the key existed
    if summary.get("runs", runs) > 1 and largest is not None:
        d_max += f" (mean of the runs' maxima; largest {largest:.1f})"
    console.print(f"  D_mean {summary['d_mean_mm']:.1f} mm, {d_max}, "
                  f"IK floor {summary['ik_floor_mm']:.1f} mm, MMTA {100 * summary['mmta']:.1f} %, "
                  f"{summary['frames_per_s']:.2f} frames/s per run")
    console.print(f"  report: {paths.summary}", markup=False, highlight=False)
    console.print(f"  page:   {paths.html}  (self-contained: open in a browser)", markup=False, highlight=False)
    for p in [*paths.figures, *paths.overlays]:
        console.print(f"    {p}", markup=False, highlight=False)


def _made_by_other_code(out: Path) -> str:
    """``"; they were tracked by source X, this is Y"`` when the folder's config names other code, else ``""``."""
    import json

    from swarmpose.track.provenance import source_revision

    try:
        made = json.loads((out / "config.json").read_text()).get("versions", {}).get("swarmpose_git")
    except (OSError, ValueError, AttributeError):
        made = None
    now = source_revision()
    if now is None or made == now:
        return ""
    return f"; they were tracked by source {made[:12] if made else 'of unknown revision'}, this is {now[:12]}"


def _finished(out: Path) -> dict | None:
    """The summary of a finished demo in ``out``, if there is a readable one."""
    import json

    try:
        return json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return None
