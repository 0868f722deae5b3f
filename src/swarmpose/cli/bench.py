"""``swarmpose bench fitness`` (evaluations per second of the fitness backends, and frame preparation) and
``swarmpose bench track`` (one tracking run timed by part)."""

from __future__ import annotations

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    DEFAULT_ALGO,
    DEFAULT_FEATURE_CACHE,
    FEATURE_CACHE_HELP,
    console,
    err_console,
    escape,
    fail_on_user_error,
    feature_cache,
    print_json,
)

bench_app = typer.Typer(help="Benchmarks: fitness throughput, where a tracking run spends its time, person detection speed.",
                        no_args_is_help=True)
app.add_typer(bench_app, name="bench")


def _ints(text: str, name: str) -> list[int]:
    from swarmpose.errors import ConfigError

    try:
        vals = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ConfigError(f"--{name} must be comma-separated integers, got {text!r}") from None
    if not vals or min(vals) < 1:
        raise ConfigError(f"--{name} must be positive integers, got {text!r}")
    return vals


@bench_app.command("fitness")
@fail_on_user_error
def fitness(
    backends: str = typer.Option("auto", help="Comma-separated backends (numba, torch, reference); 'reference' "
                                 "gives the ratios. auto: numba, torch where PyTorch is installed, reference (the "
                                 "slow one: a full run of the defaults takes a few minutes)."),
    scales: str = typer.Option("1,2,4", help="Downsampling factors of 644x484 (1 full, 2 half, 4 quarter, 8)."),
    batches: str = typer.Option("20,200", help="Batch sizes (poses per call)."),
    views: int = typer.Option(4, help="Number of camera views."),
    repeats: int = typer.Option(5, help="Timing runs per measurement (the median is reported)."),
    min_time: float = typer.Option(0.3, help="Seconds per timing run."),
    reference_max_batch: int = typer.Option(200, help="Time the reference backend on at most this many poses."),
    seed: int = typer.Option(0, min=0, help="Seed (>= 0) of the demo scene and the candidate poses."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a table."),
) -> None:
    """Evaluations/s of each fitness backend (kinematics + projection + silhouette + edge, all views)."""
    from swarmpose.errors import ConfigError
    from swarmpose.fitness import BACKENDS
    from swarmpose.fitness.bench import run_fitness_benchmark
    from swarmpose.fitness.torch_backend import import_torch, torch_available

    if backends.strip() == "auto":
        names = ["numba", *(["torch"] if torch_available() else []), "reference"]
    else:
        names = [b.strip() for b in backends.split(",") if b.strip()]
    unknown = [b for b in names if b not in BACKENDS]
    if unknown or not names:
        raise ConfigError(f"unknown backend(s) {unknown or backends!r} (known: {', '.join(BACKENDS)})")
    if "torch" in names:
        import_torch()  # the install hint when PyTorch is missing
    if views < 1 or repeats < 1 or min_time < 0 or reference_max_batch < 1:
        raise ConfigError("--views, --repeats and --reference-max-batch must be >= 1, --min-time >= 0")

    def say(msg: str) -> None:
        if not json_out:
            err_console.print(f"[dim]{msg}…[/dim]", highlight=False)

    scale_list = _ints(scales, "scales")
    if any(f not in (1, 2, 4, 8) for f in scale_list):
        raise ConfigError(f"--scales: each factor must be 1, 2, 4 or 8 (what `track --downsample` takes), got {scales!r}")
    batch_list = _ints(batches, "batches")
    res = run_fitness_benchmark(backends=names, scales=scale_list, batches=batch_list,
                                n_views=views, repeats=repeats, min_time=min_time,
                                reference_max_batch=reference_max_batch, seed=seed, progress=say)
    res["settings"] = {"backends": names, "scales": scale_list, "batches": batch_list, "views": views,
                       "repeats": repeats, "min_time_s": min_time, "reference_max_batch": reference_max_batch,
                       "seed": seed}
    if json_out:
        print_json(res)
        return
    from rich.table import Table

    m = res["machine"]
    console.print(f"[bold]machine[/bold]: {m['cpu']}, {m['cpu_count']} CPUs, numba {m['numba']} "
                  f"({m['numba_threads']} threads; numba backend threads: {m['numba_backend_threads']}), "
                  f"numpy {m['numpy']}, "
                  f"OpenCV {m['opencv']}, Python {m['python']}; load average {m['loadavg_start']} -> "
                  f"{m['loadavg_end']}", highlight=False)
    if "torch" in m:
        console.print(f"[bold]torch[/bold] {m['torch']} on {m['torch_device']}", highlight=False)
    table = Table(title=f"fitness evaluations/s ({views} views, silhouette + edge, incl. kinematics)")
    for col in ("backend", "resolution", "batch", "evals/s", "x reference", "frames/s at 1000 evals"):
        table.add_column(col, justify="right" if col != "backend" else "left", overflow="fold")
    for r in res["rows"]:
        ratio = r["ratio_to_reference"]
        table.add_row(r["backend"], f"{r['width']}x{r['height']}", str(r["batch"]), f"{r['evals_per_s']:,.0f}",
                      "-" if ratio is None else f"{ratio:,.1f}", f"{r['evals_per_s'] / 1000:.1f}")
    console.print(table)
    la = m.get("loadavg_start")  # before the benchmark's own load
    if la and la[0] > 0.5 * (m.get("cpu_count") or 1):
        console.print(f"[yellow]warning:[/yellow] other processes were using the CPUs (1-minute load average "
                      f"{la[0]:.1f} on {m['cpu_count']} CPUs at the start): these rates are lower bounds.",
                      highlight=False)
    p = res["prepare"]
    levels = ", ".join(f"{k}: {v:.1f} ms" for k, v in p["levels"].items())
    console.print(f"frame preparation ({views} raw 644x484 images -> features + prefix sums): "
                  f"{res['prepare_ms']:.1f} ms (features {p['features_ms']:.1f} ms, prefix sums "
                  f"{p['prefix_ms']:.2f} ms); per level: {levels}", highlight=False)


@bench_app.command("track")
@fail_on_user_error
def track(
    source: str = typer.Argument(None, help="Sequence folder or BVH clip (default: the shared walk, "
                                            "cmu_16_16_walk)."),
    algo: str = typer.Option(None, help="Algorithm (default: track's default; see `swarmpose algorithms`)."),
    variant: str = typer.Option("", help="A variant of the algorithm, as `track --variant` takes it."),
    fps: float = typer.Option(20.0, help="Tracking rate, frames/s."),
    max_frames: int = typer.Option(None, "--max-frames", min=1, help="Only the first N frames."),
    seed: int = typer.Option(0, min=0, help="Seed of the run."),
    views: str = typer.Option("", help="Track with these cameras only, e.g. cam01,cam02,cam03 (as `track --views`: "
                                       "a recording's held-out camera stays out)."),
    downsample: int = typer.Option(1, help="Image downsampling, as `track --downsample` takes it: 1 (full "
                                           "resolution), 2, 4 or 8 (coarser)."),
    repeat: int = typer.Option(1, min=1, help="Play the tracked frames this many times, every other pass "
                                              "backwards: a long recording, to see whether the cost per frame "
                                              "grows with it."),
    backward: bool = typer.Option(False, "--backward", help="Time the offline pass as well, as `track --backward` "
                                                            "runs it: each frame's time is its forward and its "
                                                            "backward search together."),
    feature_cache_dir: str = typer.Option(DEFAULT_FEATURE_CACHE, "--feature-cache",
                                          help=FEATURE_CACHE_HELP + " Off: the time of a sequence's first run."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a table."),
) -> None:
    """Track one run in this process and show where its time goes, part by part of the frame loop
    (features, motion model, optimiser, fitness, hard priors, recovery, the keypoint fits, a run's members'
    consensus, results writing), and its memory: the peak, and how fast it grows after the first quarter of the
    run (`--json`: samples along the run)."""
    from swarmpose.cli.demo import DEFAULT_CLIP
    from swarmpose.track.bench import bench_track
    from swarmpose.track.runner import resolve_sequence
    from swarmpose.track.tracker import TrackConfig

    cfg = TrackConfig(algo=algo or DEFAULT_ALGO, fps=fps, seed=seed, max_frames=max_frames, optim_variant=variant,
                      views=views, downsample=downsample, backward=backward)
    seq = resolve_sequence(source or str(DEFAULT_CLIP), progress=not json_out)
    res = bench_track(seq, cfg, repeat=repeat, feature_cache=feature_cache(feature_cache_dir))
    if json_out:
        print_json(res)
        return
    from rich.table import Table

    table = Table(title=f"{res['algo']}{' --variant ' + res['variant'] if res['variant'] else ''}"
                        f"{' --backward' if res['backward'] else ''} at "
                        f"{res['fps']:g} fps"
                        f"{', downsampled ' + str(res['downsample']) + 'x' if res['downsample'] > 1 else ''}: "
                        f"{res['frames']} frames, "
                        f"{res['frames_per_s']:.2f} frames/s ({res['ms_per_frame']:.1f} ms per frame), "
                        f"{res['evals_per_frame']} evaluations per frame")
    for col in ("part", "ms per frame", "share", "what"):
        table.add_column(col, justify="left" if col in ("part", "what") else "right", overflow="fold")
    for p in res["parts"]:
        table.add_row(p["part"], f"{p['ms_per_frame']:.1f}", f"{100 * p['share']:.0f} %", p["what"])
    console.print(table)
    console.print(f"ms per frame in the first and the last quarter of the run: "
                  f"{res['ms_per_frame_first_quarter']:.1f} and {res['ms_per_frame_last_quarter']:.1f}",
                  highlight=False)
    store = res["feature_store"]
    console.print("features: every frame computed (--feature-cache off)" if store is None else
                  f"features: {store['read']} frames read from the feature store, {store['computed']} computed "
                  f"({escape(store['folder'])})", highlight=False)
    growth = res["rss_growth_kb_per_frame"]
    memory = f"peak memory {res['peak_rss_mb']:.0f} MB" + ("" if growth is None else
                                                           f", growing {growth:.2f} KB per frame after the first quarter")
    console.print(f"{memory}; D_mean {res['d_mean_mm']:.1f} mm" if res["d_mean_mm"] is not None else memory,
                  highlight=False)


from swarmpose.cli import bench_detect  # noqa: E402,F401 - registers `bench detect` on bench_app
