"""Run an experiment suite: entries × clips × runs as independent jobs, then one comparison table."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.experiments.suites import Entry, suite
from swarmpose.io.lock import folder_lock, remove_unused_folder
from swarmpose.metrics import aggregate_runs
from swarmpose.report.comparison import write_comparison
from swarmpose.track.runner import (
    Job,
    check_results_folder,
    check_sequence_data,
    close_client,
    connect_scheduler,
    errors_from_summary,
    run_jobs,
    sum_recoveries,
)
from swarmpose.track.tracker import TrackConfig, prepare_track, write_config

__all__ = ["folder_slug", "run_suite", "suite_configs"]


def folder_slug(text: str) -> str:
    """``text`` as a folder-name part: letters, digits, ``-`` and ``.`` kept, anything else ``_``."""
    return "".join(c if c.isalnum() or c in "-." else "_" for c in text).strip("_")


def _sequence_name(seq: Any) -> str:
    """The folder name of a sequence, or a dataset spec's short name (``S1_Walking_1``)."""
    from swarmpose.datasets import dataset_sequence_name, is_dataset_spec

    return dataset_sequence_name(seq) if is_dataset_spec(seq) else Path(str(seq)).name


def suite_configs(name: str, *, seed: int = 0, downsample: int = 1,
                  max_frames: int | None = None) -> list[tuple[Entry, TrackConfig]]:
    """Every entry of suite ``name`` with its validated :class:`TrackConfig` (bad settings fail here, before
    any clip is synthesised or folder written).

    ``max_frames`` (a quick try, not the papers' comparison): the first N frames at the suite's lowest
    rate, and the same stretch of time at the others (3N - 2 frames at 60 fps beside 20 fps), so
    that every entry tracks the same motion.
    """
    entries = suite(name)
    slowest = min(e.fps for e in entries)

    def frames(e: Entry) -> int | None:
        if max_frames is None:
            return None
        return int(np.floor((max_frames - 1) * e.fps / slowest + 1e-9)) + 1

    return [(e, TrackConfig(algo=e.algo, fps=e.fps, fitness=e.fitness, seed=seed, downsample=downsample,
                            optim_variant=e.variant, fitness_options=e.fitness_options, max_frames=frames(e),
                            motion=e.motion))
            for e in entries]


def run_suite(name: str, sequences: list[Path], out_dir: Path, *, runs: int = 5, seed: int = 0,
              workers: int | None = None, scheduler: Any = None, resume: bool = False,
              downsample: int = 1, progress: bool = True, max_frames: int | None = None,
              feature_cache: str | Path | None = None) -> dict[str, Any]:
    """Run suite ``name`` on the sequences and write ``out_dir/comparison.json`` and its report
    (:func:`swarmpose.report.comparison.write_comparison`: ``comparison.md``, two figures, ``comparison.html``)."""
    configs = suite_configs(name, seed=seed, downsample=downsample, max_frames=max_frames)
    out_dir = Path(out_dir)
    planned: dict[Path, tuple[Any, Entry, TrackConfig]] = {}
    for seq in sequences:  # every cell checked before any is written
        for e, cfg in configs:
            cell = out_dir / folder_slug(_sequence_name(seq)) / folder_slug(e.label)
            if cell in planned:
                raise ConfigError(f"two sequences would share the results folder {cell}: {planned[cell][0]} and "
                                  f"{seq} (give clips with different names)")
            check_results_folder(cell, seq, cfg, runs, resume)  # other settings in the cell: refused, named
            planned[cell] = (seq, e, cfg)
    fresh = not out_dir.exists()
    with folder_lock(out_dir):  # one writer: a second compare (or --resume) on this folder is refused
        return _run_cells(name, configs, planned, out_dir, runs=runs, seed=seed, workers=workers,
                          scheduler=scheduler, resume=resume, progress=progress, max_frames=max_frames,
                          fresh=fresh, feature_cache=feature_cache)


def _run_cells(name: str, configs: list[tuple[Entry, TrackConfig]], planned: dict[Path, tuple[Any, Entry, TrackConfig]],
               out_dir: Path, *, runs: int, seed: int, workers: int | None, scheduler: Any, resume: bool,
               progress: bool, max_frames: int | None, fresh: bool = False,
               feature_cache: str | Path | None = None) -> dict[str, Any]:
    jobs: list[Job] = []
    cells: list[tuple[Entry, Path, Path, Any]] = []
    try:
        if isinstance(scheduler, str):
            scheduler = connect_scheduler(scheduler)  # before the IK fits: a wrong address fails at once
        for cell, (seq, e, cfg) in planned.items():
            setup = prepare_track(seq, cfg, cell)  # IK floor once per cell, before the workers start
            check_sequence_data(cell, setup, resume)
            cell.mkdir(parents=True, exist_ok=True)
            write_config(cell, setup, runs, resume)
            cells.append((e, Path(seq), cell, setup))
            jobs += [Job(str(seq), asdict(cfg), k, str(cell), resume, setup.progress_frames,
                         None if feature_cache is None else str(feature_cache)) for k in range(runs)]
    except BaseException:
        close_client(scheduler)
        if fresh:  # a sequence or setting that fails before any tracking leaves no empty folders behind
            remove_unused_folder(out_dir)
        raise
    results = run_jobs(jobs, workers=workers, scheduler=scheduler, progress=progress)
    rows = []
    for e, seq, cell, setup in cells:
        mine = sorted((r for r in results if Path(r["out_dir"]) == cell), key=lambda r: r["run"])
        agg = aggregate_runs([errors_from_summary(r) for r in mine])
        row = {"label": e.label, "algo": e.algo, "fps": e.fps, "variant": e.variant, "fitness": setup.config.fitness_kind,
               "fitness_options": e.fitness_options, "sequence": seq.name, "runs": len(mine),
               "frames": int(len(setup.frame_indices)),
               "evals_per_frame": setup.evals_per_frame, "d_mean_mm": agg["d_mean"], "d_max_mm": agg["d_max"],
               "d_max_over_runs_mm": agg["d_max_over_runs"], "d_mean_std_over_runs_mm": agg["d_mean_std_over_runs"],
               "worst_d_mean_mm": agg["worst"]["d_mean"],
               "ik_floor_mm": setup.ik_floor_mm, "mmta": agg["mmta"], "mmtp_mm": agg["mmtp"],
               "frames_per_s": float(np.mean([r["frames_per_s"] for r in mine])), "reference": e.reference,
               "recoveries": sum_recoveries(mine), "out_dir": str(cell)}
        (cell / "summary.json").write_text(json.dumps({**row, "per_run": mine}, indent=1, default=float) + "\n")
        rows.append(row)
    report = {"suite": name, "runs": runs, "seed": seed, "max_frames": max_frames,
              "lowest_fps": min(e.fps for e, _ in configs), "rows": rows}
    (out_dir / "comparison.json").write_text(json.dumps(report, indent=1) + "\n")
    write_comparison(out_dir, report)  # comparison.md with its figures, and comparison.html
    return report
