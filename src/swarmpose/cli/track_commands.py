"""``swarmpose track``: track a sequence (or a BVH clip, synthesised into a cache) with a named algorithm."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    DEFAULT_ALGO,
    DEFAULT_BACKWARD_PATH,
    DEFAULT_FEATURE_CACHE,
    FEATURE_CACHE_HELP,
    console,
    count,
    err_console,
    escape,
    fail_on_user_error,
    feature_cache,
    interrupted_tracking,
    print_json,
)

if TYPE_CHECKING:
    from swarmpose.track.tracker import TrackConfig

#: What `swarmpose track` runs without --algo (`swarmpose algorithms` marks it).


def run_setting_parts(*, max_frames: int | None, seed: int, downsample: int) -> list[str]:
    """The default folder names' parts for the frame count, seed and downsampling, each when it is not the
    default (``30frames``, ``s1``, ``ds2``); `track`'s and `compare`'s folders share them."""
    return ([f"{max_frames}frames"] if max_frames is not None else []) + ([f"s{seed}"] if seed else []) + \
        ([f"ds{downsample}"] if downsample != 1 else [])


def _default_motion(algo: str) -> str:
    from swarmpose.optim.registry import default_motion

    return default_motion(algo)


def default_results_name(name: str, cfg: TrackConfig) -> str:
    """``<sequence>-<algo>-<fps>fps`` and every setting that changes the results and is not the default
    (``-30frames-s1-ds2-markers-hard``...), so that another seed or setting is not taken for a run to resume."""
    from swarmpose.experiments.run import folder_slug

    parts = [name, cfg.algo, f"{cfg.fps:g}fps",
             *run_setting_parts(max_frames=cfg.max_frames, seed=cfg.seed, downsample=cfg.downsample)]
    if cfg.model != "balan31":
        parts.append(folder_slug(Path(cfg.model).stem))
    for value, default in ((cfg.fitness, "auto"), (cfg.optim_variant, ""), (cfg.fitness_options, ""),
                           (cfg.feature_options, ""), (cfg.motion, _default_motion(cfg.algo))):
        if value and value != default:
            parts.append(folder_slug(str(value)))
    if cfg.subject:
        parts.append("subject-" + folder_slug(Path(cfg.subject).stem))
    if cfg.height_mm is not None:
        parts.append(f"h{cfg.height_mm:g}mm")
    if cfg.views:
        parts.append("views-" + folder_slug(cfg.views))
    if cfg.backward:
        parts.append("backward")
        if cfg.backward_path != DEFAULT_BACKWARD_PATH:
            parts.append(f"path{cfg.backward_path:g}")
    if cfg.smooth:
        parts.append(f"smooth{cfg.smooth:g}s")
    return "-".join(parts)


def is_clip(source: str | Path) -> bool:
    """Whether a tracking source is a ``.bvh`` clip (synthesised into a sequence before it is tracked)."""
    return Path(source).suffix.lower() == ".bvh"


def synthesis_rate() -> float:
    """The frame rate a ``.bvh`` source is synthesised at before it is tracked (``resolve_sequence``)."""
    import inspect

    from swarmpose.synth.synthesize import cached_sequence

    return float(inspect.signature(cached_sequence).parameters["fps"].default)


def check_tracking_rate(fps: float, source: str | Path | None = None) -> None:
    """Refuse a ``--fps`` that is not a rate above 0, or that is above the sequence's frame rate (a sequence is
    subsampled to the tracking rate, never interpolated). ``source``: a ``.bvh`` clip (synthesised at
    :func:`synthesis_rate`: checked before it is), or a sequence folder or dataset spec as ``resolve_sequence``
    returns it (opened for its rate); None checks the sign only."""
    import math

    from swarmpose.errors import ConfigError

    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps: {fps:g} is not a tracking rate; give one above 0, at most the sequence's "
                          "frame rate")
    if source is None:
        return
    if is_clip(source):
        rate, made = synthesis_rate(), f"{Path(source).name} is synthesised at that rate; "
    else:
        from swarmpose.io.sequence import open_sequence

        with open_sequence(source) as seq:
            rate, made = float(seq.frame_rate), ""
    if fps > rate * (1 + 1e-9):
        rates = ", ".join(f"{rate / k:g}" for k in (1, 2, 3))
        raise ConfigError(f"--fps: {fps:g} is above the sequence's {rate:g} fps ({made}tracking takes the "
                          f"sequence's frames and makes no new ones: {rates}, ...)")


@app.command()
@fail_on_user_error
def track(
    source: str = typer.Argument(..., help="A sequence folder, a BVH clip (synthesised once into cache/), "
                                           "humaneva:PATH/S1/Walking_1[?cams=...] or leewalk:PATH "
                                           "(docs/datasets.md)."),
    algo: str = typer.Option(DEFAULT_ALGO, help="Algorithm name (see `swarmpose algorithms`)."),
    fps: float = typer.Option(20.0, help="Tracking frame rate, at most the sequence's: the sequence is subsampled "
                                         "to it (60, 30, 20, 12...); a rate that does not divide the sequence's "
                                         "(25 from 60) tracks the nearest frames."),
    runs: int = typer.Option(1, min=1, help="Independent runs (different random streams)."),
    seed: int = typer.Option(0, min=0, help="Seed (>= 0); run k draws from SeedSequence(\\[seed, k]) (recorded)."),
    out: Path = typer.Option(None, help="Results folder (default results/<sequence>-<algo>-<fps>fps, followed by "
                                        "every non-default setting that changes results, in this order: "
                                        "-<N>frames, -s<seed>, -ds<N>, model, fitness, variant, options, "
                                        "motion)."),
    resume: bool = typer.Option(False, help="Continue an interrupted run in --out without redoing frames (finished "
                                "runs are kept as they are)."),
    model: str = typer.Option("balan31", help="Body model name or spec file."),
    fitness: str = typer.Option(
        "auto", help="auto (silhouette_edge; reprojection for aapso*), silhouette_edge, deutscher_reid, "
                     "markers (Sharifi et al.'s epipolar score) or reprojection (robust, symmetric)."),
    variant: str = typer.Option(
        "", help="Optimiser variant, as the compare suites use them. budget=B: B evaluations per frame (1000, "
                 "2000, ...; the SPPSO family's iterations x B/1000); stage2=PxI: SPPSO's second stage with P "
                 "particles x I iterations; global=PxI: one PSO stage over all parameters; hard: each stage after the "
                 "first holds the first stage's parameters fixed; apf=PxL: an APF with P particles x L layers "
                 "(apf, apf-adaptive, apf-dr05). For refined: refine=B, recovery=off or recovery=T (a limb is lost "
                 "above a silhouette disagreement of T, default 0.05), height=silhouettes (the predicted root height "
                 "follows the rise of the silhouettes' centre). Join several with +."),
    downsample: int = typer.Option(1, help="Image downsampling: 1 (full resolution), 2, 4 or 8: coarser images, "
                                           "less accurate and only a little faster (docs/results.md, Coarser images)."),
    backend: str = typer.Option(
        "numba", help="Fitness backend: numba (default, all CPU cores), torch (PyTorch on the GPU when there is "
                      "one: numba's pixel and sample counts; pip install 'swarmpose\\[torch]') or reference "
                      "(plain numpy, slow: the definition the fast backends are tested against)."),
    fitness_options: str = typer.Option(
        "", help="Fitness options, key=value[,...], applied on top of the options each optimiser stage sets "
                 "(SPPSO's first stage scores torso edges only): terms=silhouette|edge (one term only), "
                 "edge_top=false (no torso top edge), edge_cones=all|torso|torso+upper."),
    features: str = typer.Option(
        "", help="Image feature settings, key=value[,...]: edge_threshold (Sobel magnitude / 4, default 40: "
                 "keeps grey-level steps above 53 after the pre-smoothing), edge_dilate_px (silhouette "
                 "dilation that masks the edges, default 7), edge_sigma_px (edge blur, default 2.0), "
                 "silhouette_threshold (grey levels from the background, default 25), silhouette_blur_px "
                 "(default 2), silhouette_open_px (default 3), silhouette_close_px (default 5)."),
    motion: str = typer.Option(
        "auto", help="Motion model that centres each frame's search: auto (the algorithm's own: "
                     "constant-velocity@pelvis_tx+pelvis_ty for refined, zero-velocity for the papers'), zero-velocity "
                     "(the thesis's, sec. 5.3.2) or constant-velocity\\[:D]\\[@GROUP+...] (moves on by D x the "
                     "last step, D = 1 by default, only the named parameter groups if given, e.g. "
                     "@root_position)."),
    subject: Path = typer.Option(None, help="Subject file (limb lengths, cone sizes; `swarmpose subject`) instead "
                                            "of the one measured from the sequence's motion capture."),
    height: float = typer.Option(None, "--height", help="Build the subject from this stature, mm (published "
                                                          "proportions, as `swarmpose subject`)."),
    views: str = typer.Option("", help="Track with these cameras only, e.g. cam01,cam02,cam03: the others are "
                                       "held out, and the report scores the model in them (no ground truth "
                                       "needed)."),
    max_frames: int = typer.Option(None, min=1, help="Track only the first N frames at --fps (a quick try; the "
                                                     "default --out then has -<N>frames after the rate)."),
    backward: bool = typer.Option(False, "--backward", help="Offline: track the frames again from the last one "
                                                            "backwards and keep, per frame, the pose the fitness "
                                                            "prefers (the backward pass goes on from it). Twice "
                                                            "the time; repairs limbs one direction loses."),
    backward_path: float = typer.Option(DEFAULT_BACKWARD_PATH, "--backward-path", min=0.0,
                                        help="With --backward: the two passes' poses are chosen as one path over "
                                             "the frames, the fitness against this weight on the joints' steps "
                                             "between frames (a pose with a limb far off that no neighbouring frame "
                                             "has loses); 0: each frame chooses alone."),
    smooth: float = typer.Option(0.0, "--smooth", min=0.0, max=10.0,
                                 help="Offline: smooth the poses over time with a Gaussian of this standard "
                                      "deviation in seconds, e.g. 0.05 (0: off). Less jitter; track.npz keeps the "
                                      "raw poses as raw_params."),
    consensus: int = typer.Option(0, "--consensus", min=0,
                                  help="Offline: also fuse the runs K at a time into one track each, per frame the "
                                       "model fitted to the median of their joints (with --backward both passes "
                                       "count), written to OUT/consensus as a results folder of its own (report "
                                       "and export read it). --runs must be a multiple of K; K times the time of "
                                       "one run. 0: off."),
    feature_cache_dir: str = typer.Option(DEFAULT_FEATURE_CACHE, "--feature-cache", help=FEATURE_CACHE_HELP),
    workers: int = typer.Option(None, min=1, help="Parallel worker processes (default: one per core, at most --runs); "
                                                  "each uses cores / workers numba threads."),
    scheduler: str = typer.Option(None, help="Run on a Dask cluster at this address, e.g. tcp://host:8786 "
                                             "(pip install 'swarmpose\\[dask]'; sequence and --out must be at the "
                                             "same path on every worker)."),
    no_progress: bool = typer.Option(False, "--no-progress", help="No progress bars (for batch logs; --json "
                                                                   "implies it)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object with the summary."),
) -> None:
    """Track 3D motion frame by frame and, where the sequence has ground truth, measure it.

    A sequence without ground truth (an imported recording) starts from its triangulated keypoints and
    measures the subject from them (or from --height); --views holds cameras out to score the track in.

    Writes a results folder: config.json (settings, seeds, versions), subject.json (the body's
    measurements), ik.npz (the IK floor), summary.json (means over the runs and the worst run), and per
    run run_XXX/ with joints.npz (joints, gt_joints, frame_times, world_from_source), track.npz
    (parameters, fitness, evaluations, timings per frame), summary.json and progress.npz (what
    --resume continues from); with --consensus K also consensus/, the runs fused K at a time, a results
    folder of its own. `swarmpose report FOLDER` draws it.
    """
    from swarmpose.track.runner import connect_scheduler, resolve_sequence, track_runs
    from swarmpose.track.tracker import TrackConfig

    check_tracking_rate(fps, source if is_clip(source) else None)  # a .bvh clip: before it is synthesised
    if backward_path != DEFAULT_BACKWARD_PATH and not backward:
        from swarmpose.errors import ConfigError

        raise ConfigError(f"--backward-path {backward_path:g} weighs the choice between the two passes of --backward; "
                          "give --backward as well")
    cfg = TrackConfig(algo=algo, fps=fps, model=model, fitness=fitness, backend=backend,
                      downsample=downsample, seed=seed, fitness_options=fitness_options,
                      feature_options=features, optim_variant=variant, motion=motion,
                      max_frames=max_frames, subject=str(subject or ""), height_mm=height, views=views,
                      backward=backward, backward_path=backward_path, smooth=smooth)
    if backend == "torch" and not scheduler:
        import torch

        if not torch.cuda.is_available():
            err_console.print("[yellow]note:[/yellow] PyTorch sees no GPU here: the torch backend runs on the CPU, "
                              "about 50x slower than the default numba backend (it is the GPU path)",
                              highlight=False)
    progress = not (json_out or no_progress)
    try:  # Ctrl-C from here on says what was saved: nothing while the clip is synthesised, then the frames
        client = connect_scheduler(scheduler) if scheduler else None  # a wrong address fails before any synthesis
        seq = resolve_sequence(source, progress=progress)
        if not is_clip(source):
            check_tracking_rate(fps, seq)  # a sequence folder or a dataset's: its own rate
        if out is None:
            if isinstance(seq, str):  # a dataset spec such as humaneva:/data/HumanEva/S1/Walking_1
                from swarmpose.datasets import dataset_sequence_name

                name = dataset_sequence_name(seq)
            else:
                name = seq.name
            out = Path("results") / default_results_name(name, cfg)
        summary = track_runs(seq, cfg, runs, out, resume=resume, workers=workers, scheduler=client,
                             progress=progress, feature_cache=feature_cache(feature_cache_dir), consensus=consensus)
    except KeyboardInterrupt:
        raise interrupted_tracking(out) from None
    if max_frames is not None and summary["frames"] < max_frames:
        err_console.print(f"[yellow]note:[/yellow] the sequence has {summary['frames']} frames at {fps:g} fps: all "
                          f"were tracked (--max-frames {max_frames} is more)", highlight=False)
    gap = summary["frame_interval_s"]
    if gap["max"] is not None and gap["max"] - gap["min"] > 1e-6:
        err_console.print(f"[yellow]note:[/yellow] {fps:g} fps does not divide the sequence's frame rate: the "
                          f"tracked frames are {1000 * gap['min']:.0f}-{1000 * gap['max']:.0f} ms apart "
                          f"(mean {1000 * gap['mean']:.1f} ms), the nearest frames to a {fps:g} fps clock",
                          highlight=False)
    if json_out:
        print_json(summary)
        return
    name = seq.name if isinstance(seq, Path) else str(seq)
    console.print(f"[bold]{algo}[/bold] on {escape(name)} at {fps:g} fps, {count(runs, 'run')}, "
                  f"{summary['evals_per_frame']} evaluations per frame ({summary['fitness']} fitness)")
    over = []
    if runs > 1:
        over.append(f"means over the {runs} runs")
    if summary["frames_scored"] < summary["frames"]:
        over.append(f"over the {summary['frames_scored']} of {summary['frames']} frames with valid ground truth")
    if not summary.get("ground_truth", True):
        console.print(f"  no ground truth: no 3D error; {summary['frames_per_s']:.2f} frames/s"
                      + (f"; tracked with {summary['views']}" if summary.get("views") else ""), highlight=False)
        if summary.get("consensus"):
            c = summary["consensus"]
            console.print(f"  consensus of {c['runs_per_track']} runs ({count(c['runs'], 'track')}) in "
                          f"{c['out_dir']}/", markup=False, highlight=False)
        console.print(f"  results in {out}/  (the report scores held-out cameras: swarmpose report {out})",
                      markup=False, highlight=False)
        return
    d_max = f"D_max {summary['d_max_mm']:.1f} mm"
    if runs > 1:
        d_max += f" (largest {summary['d_max_over_runs_mm']:.1f})"
    console.print(f"  D_mean {summary['d_mean_mm']:.1f} mm, {d_max} "
                  f"(IK floor {summary['ik_floor_mm']:.1f} mm); MMTA {100 * summary['mmta']:.1f} %; "
                  f"{summary['frames_per_s']:.2f} frames/s" + (f"  ({'; '.join(over)})" if over else ""),
                  highlight=False)
    if runs > 1:
        w = summary["worst"]
        console.print(f"  worst run {w['run']}: D_mean {w['d_mean_mm']:.1f} mm, D_max {w['d_max_mm']:.1f} mm")
    if summary.get("consensus"):
        c = summary["consensus"]
        console.print(f"  consensus of {c['runs_per_track']} runs ({count(c['runs'], 'track')}): D_mean "
                      f"{c['d_mean_mm']:.1f} mm, D_max {c['d_max_mm']:.1f} mm; MMTA {100 * c['mmta']:.1f} %; "
                      f"in {c['out_dir']}/", markup=False, highlight=False)
    console.print(f"  results in {out}/  (make a report: swarmpose report {out})", markup=False, highlight=False)


@app.command()
def algorithms(json_out: bool = typer.Option(False, "--json", help='Print one JSON object {"algorithms": [...]} '
                                                                   "instead of a table.")) -> None:
    """List every named algorithm: what it is and tracks, its fitness evaluations per frame, its measured error
    and speed on the shared walk, and its paper; the default of `track` is marked."""
    from swarmpose.experiments.measured import CLIP, MEASURED
    from swarmpose.optim.registry import describe

    rows = [{**r, "default": r["name"] == DEFAULT_ALGO,
             "walk": None if r["name"] not in MEASURED else {"clip": CLIP, **MEASURED[r["name"]]._asdict()}}
            for r in describe()]
    if json_out:
        print_json({"algorithms": rows, "default": DEFAULT_ALGO, "walk_clip": CLIP})
        return
    from rich.table import Table

    tracks = {"silhouette_edge": "silhouettes + edges (images)", "reprojection": "2D markers (reprojection)"}
    table = Table(title="swarmpose algorithms (swarmpose track --algo NAME)", show_lines=True)
    # the numbers' columns as narrow as their numbers, so that an 80-column terminal leaves the text room
    table.add_column("name", min_width=max(len(r["name"]) for r in rows), overflow="fold")
    table.add_column("what it is, what it tracks, paper", overflow="fold")
    table.add_column("evals per frame", justify="right", max_width=6, overflow="fold")
    table.add_column("walk D_mean", justify="right", max_width=9, overflow="fold")
    table.add_column("frames/s", justify="right", max_width=8, overflow="fold")
    for r in rows:
        walk = r["walk"]
        what = (f"{escape(r['summary'])}\n[dim]tracks {escape(tracks.get(r['fitness'], r['fitness']))}; "
                f"{escape(r['reference'])}[/dim]")
        table.add_row(f"[bold]{escape(r['name'])}[/bold]" + ("\n(default)" if r["default"] else ""), what,
                      str(r["evals_per_frame"]),
                      "–" if walk is None else f"{walk['d_mean_mm']:.1f} mm\nat {walk['fps']:g} fps",
                      "–" if walk is None or walk["frames_per_s"] is None else f"{walk['frames_per_s']:.1f}")
    console.print(table)
    runs = sorted({m.runs for m in MEASURED.values()})
    console.print(f"walk D_mean: the mean 3D joint error on the synthetic walk {CLIP} at the rate shown, over "
                  f"{' or '.join(map(str, runs))} runs of seed 0; frames/s: per run, two runs at a time on 2 cores; –: not "
                  "measured. --json gives each one's command; docs/results.md has the spread and the other "
                  f"clips. (default): what `swarmpose track` runs without --algo.", markup=False, highlight=False)
