"""``swarmpose compare SUITE``: the papers' comparisons at equal budgets, one command each."""

from __future__ import annotations

from pathlib import Path

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import console, fail_on_user_error, print_json
from swarmpose.cli.demo import DEFAULT_CLIP


@app.command()
@fail_on_user_error
def compare(
    suite: str = typer.Argument(..., help="thesis-apf, thesis-partitions, thesis-budget, thesis-swarm, "
                                          "thesis-fitness, markers (Sharifi et al.'s epipolar "
                                          "score) or markers-reprojection (the same comparisons with "
                                          "the reprojection fitness)."),
    sources: list[str] = typer.Option(None, "--clip", help="Sequence folders or BVH clips (repeatable); "
                                                            "default: the shared walking clip."),
    runs: int = typer.Option(5, min=1, help="Runs per entry."),
    seed: int = typer.Option(0, min=0, help="Seed (>= 0); run k of every entry draws from SeedSequence(\\[seed, k])."),
    out: Path = typer.Option(None, help="Output folder (default results/compare/<suite>)."),
    downsample: int = typer.Option(1, help="Image downsampling: 1 (full resolution), 2, 4 or 8."),
    workers: int = typer.Option(None, min=1, help="Parallel local processes (default: one per core)."),
    scheduler: str = typer.Option(None, help="Dask scheduler address: run the jobs on that cluster instead."),
    resume: bool = typer.Option(False, help="Continue interrupted runs."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object with the table's rows."),
) -> None:
    """Run an experiment suite (entries × clips × runs in parallel) and write a comparison table."""
    from swarmpose.experiments.run import run_suite, suite_configs
    from swarmpose.track.runner import connect_scheduler, resolve_sequence

    suite_configs(suite, seed=seed, downsample=downsample)  # an unknown suite or a bad setting fails before any clip is synthesised
    client = connect_scheduler(scheduler) if scheduler else None  # a wrong address fails before any synthesis
    seqs = [resolve_sequence(s, progress=not json_out) for s in (sources or [str(DEFAULT_CLIP)])]
    out = out or Path("results") / "compare" / suite
    report = run_suite(suite, seqs, out, runs=runs, seed=seed, workers=workers, scheduler=client,
                       resume=resume, downsample=downsample, progress=not json_out)
    if json_out:
        print_json(report)
        return
    console.print((out / "comparison.md").read_text(), markup=False, highlight=False)
    console.print(f"written: {out / 'comparison.md'} and {out / 'comparison.json'}", markup=False, highlight=False)
