"""``swarmpose compare SUITE``: the papers' comparisons at equal budgets, one command each."""

from __future__ import annotations

from pathlib import Path

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    DEFAULT_FEATURE_CACHE,
    FEATURE_CACHE_HELP,
    console,
    fail_on_user_error,
    feature_cache,
    interrupted_tracking,
    print_json,
)
from swarmpose.cli.demo import DEFAULT_CLIP
from swarmpose.cli.track_commands import run_setting_parts


def default_comparison_name(suite: str, *, seed: int, downsample: int, max_frames: int | None) -> str:
    """``<suite>`` and, as `track`'s default folder, each setting that changes the results and is not the
    default (``-<N>frames``, ``-s<seed>``, ``-ds<N>``): another seed or a quick try at a lower resolution
    gets its own folder instead of being refused as a resume with other settings."""
    return "-".join([suite, *run_setting_parts(max_frames=max_frames, seed=seed, downsample=downsample)])


@app.command()
@fail_on_user_error
def compare(
    suite: str = typer.Argument(None, help="thesis-apf, thesis-partitions, thesis-budget, thesis-swarm, "
                                           "thesis-fitness, markers (Sharifi et al.'s epipolar "
                                           "score), markers-reprojection (the same comparisons with "
                                           "the reprojection fitness) or ablation (the default tracker "
                                           "built up one component at a time). With --list it may be "
                                           "left out."),
    sources: list[str] = typer.Option(None, "--clip", help="Sequence folders or BVH clips (repeatable); "
                                                            "default: the shared walking clip."),
    runs: int = typer.Option(5, min=1, help="Runs per entry."),
    seed: int = typer.Option(0, min=0, help="Seed (>= 0); run k of every entry draws from SeedSequence(\\[seed, k])."),
    out: Path = typer.Option(None, help="Output folder (default results/compare/<suite>, followed by each "
                                        "non-default setting that changes results: -<N>frames, -s<seed>, "
                                        "-ds<N>)."),
    downsample: int = typer.Option(1, help="Image downsampling: 1 (full resolution), 2, 4 or 8."),
    workers: int = typer.Option(None, min=1, help="Parallel local processes (default: one per core)."),
    feature_cache_dir: str = typer.Option(DEFAULT_FEATURE_CACHE, "--feature-cache", help=FEATURE_CACHE_HELP),
    scheduler: str = typer.Option(None, help="Dask scheduler address, e.g. tcp://host:8786: run the jobs on that "
                                             "cluster instead (pip install 'swarmpose\\[dask]')."),
    resume: bool = typer.Option(False, help="Continue interrupted runs."),
    max_frames: int = typer.Option(None, min=1, help="A quick try of a suite: N frames at the suite's lowest "
                                                     "rate, and the same stretch of time at the others (about "
                                                     "3N frames at 60 fps when the lowest is 20); the default "
                                                     "--out then has -<N>frames after the suite's name."),
    list_only: bool = typer.Option(False, "--list", help="Only list the suite's entries (every suite's without "
                                                          "SUITE): algorithm, frame rate, variant, fitness, "
                                                          "evaluations per frame, paper; nothing is run."),
    no_progress: bool = typer.Option(False, "--no-progress", help="No progress bars (for batch logs; --json "
                                                                   "implies it)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object with the table's rows."),
) -> None:
    """Run an experiment suite (entries × clips × runs in parallel) and write a comparison report.

    OUT (default results/compare/SUITE, with -s<seed> etc. for non-default settings) gets comparison.json, comparison.md (the table, the mean error
    over time of every entry and every run's D_mean as figures), comparison.html (the same as one
    self-contained page) and one `swarmpose track` results folder per clip and entry
    (OUT/<clip>/<entry>/, each open to `swarmpose report`). `swarmpose report OUT` redraws the figures.
    """
    from swarmpose.errors import ConfigError
    from swarmpose.experiments.run import run_suite, suite_configs
    from swarmpose.experiments.suites import SUITES
    from swarmpose.track.runner import connect_scheduler, resolve_sequence

    if list_only:
        from swarmpose.track.runner import check_source

        for s in sources or []:
            check_source(s)  # a plan with a clip that is not there is refused before the long run, too
        _list_suites([suite] if suite else list(SUITES), seed=seed, downsample=downsample, runs=runs,
                     n_clips=len(sources or [None]), json_out=json_out, max_frames=max_frames)
        return
    if suite is None:
        raise ConfigError(f"name a suite: {', '.join(SUITES)} (`swarmpose compare --list` shows their entries)")
    suite_configs(suite, seed=seed, downsample=downsample, max_frames=max_frames)  # an unknown suite or a bad setting fails before any clip is synthesised
    out = (out or Path("results") / "compare" / default_comparison_name(suite, seed=seed, downsample=downsample,
                                                                       max_frames=max_frames)).absolute()
    progress = not (json_out or no_progress)
    try:  # Ctrl-C from here on says what was saved: nothing while a clip is synthesised, then the frames
        client = connect_scheduler(scheduler) if scheduler else None  # a wrong address fails before any synthesis
        seqs = [resolve_sequence(s, progress=progress) for s in (sources or [str(DEFAULT_CLIP)])]
        report = run_suite(suite, seqs, out, runs=runs, seed=seed, workers=workers, scheduler=client,
                           resume=resume, downsample=downsample, progress=progress, max_frames=max_frames,
                           feature_cache=feature_cache(feature_cache_dir))
    except KeyboardInterrupt:
        raise interrupted_tracking(out) from None
    if json_out:
        print_json(report)
        return
    from swarmpose.report.comparison import comparison_table

    console.print(comparison_table(report), markup=False, highlight=False)
    console.print(f"written: {out / 'comparison.md'} (with {out / 'comparison_over_time.png'} and "
                  f"{out / 'comparison_d_mean.png'}), {out / 'comparison.html'} (one self-contained page) and "
                  f"{out / 'comparison.json'}", markup=False, highlight=False)


def _list_suites(names: list[str], *, seed: int, downsample: int, runs: int, n_clips: int, json_out: bool,
                 max_frames: int | None = None) -> None:
    """Print the entries of the named suites (validated as a run would validate them) without running."""
    from rich.table import Table

    from swarmpose.body.model import load_model
    from swarmpose.experiments.run import suite_configs

    listing = []
    for name in names:
        entries = []
        for e, cfg in suite_configs(name, seed=seed, downsample=downsample, max_frames=max_frames):
            evals = int(cfg.optimizer(load_model(cfg.model, None, cfg.variant)).evals_per_frame)
            entries.append({"label": e.label, "algo": e.algo, "fps": e.fps, "variant": e.variant,
                            "fitness": cfg.fitness_kind, "fitness_options": e.fitness_options,
                            "evals_per_frame": evals, "max_frames": cfg.max_frames, "reference": e.reference,
                            "motion": cfg.motion})
        listing.append({"suite": name, "entries": entries, "jobs": len(entries) * runs * n_clips})
    if json_out:
        print_json({"suites": listing, "runs": runs, "clips": n_clips, "max_frames": max_frames})
        return
    for item in listing:
        table = Table(title=f"{item['suite']}: {len(item['entries'])} entries x {n_clips} "
                            f"clip{'' if n_clips == 1 else 's'} x {runs} run{'' if runs == 1 else 's'} = "
                            f"{item['jobs']} tracking jobs", title_justify="left")
        refs = list(dict.fromkeys(e["reference"] for e in item["entries"]))
        # one reference for the suite: said under the table; one paper section: said there, with each entry's
        # figures in a column; several papers: each entry's reference in the column, less the parts that
        # every entry shares (said under the table)
        bases = {r.split(" (", 1)[0] for r in refs}
        footer = refs[0] if len(refs) == 1 else (bases.pop() if len(bases) == 1 else None)
        shared = ("", "") if footer is not None else _shared_parts(refs)
        if footer is None and any(shared):
            footer = ", ".join(x for x in shared if x)
        rows = []
        for e in item["entries"]:
            row = {"entry": e["label"], "algorithm": e["algo"], "fps": f"{e['fps']:g}", "variant": e["variant"] or "-",
                   "fitness": e["fitness"] + (f" ({e['fitness_options']})" if e["fitness_options"] else ""),
                   "motion": e["motion"], "evals per frame": str(e["evals_per_frame"])}
            row.update({"frames": str(e["max_frames"])} if max_frames is not None else {})
            row.update({"in the paper": _in_paper(e["reference"], footer, shared)} if len(refs) > 1 else {})
            rows.append(row)
        # a setting every entry shares is said once under the table: the columns left have room at 80 columns
        same = {col: rows[0][col] for col in ("variant", "fitness", "motion", "evals per frame", "frames")
                if col in rows[0] and len(rows) > 1 and len({r[col] for r in rows}) == 1}
        cols = [col for col in (rows[0] if rows else {}) if col not in same]
        narrow = {col: 6 for col in ("evals per frame", "frames")}  # numbers; the header wraps above them
        # each column as wide as its longest cell, then, while the table is wider than the terminal, the widest
        # text column gives way, first down to its longest word (the cells wrap), then further (a word folds):
        # nothing is cut, and an algorithm's name and the numbers are never broken
        width = {col: narrow.get(col) or max(len(r[col]) for r in [{col: col}, *rows]) for col in cols}
        word = {col: max(len(w) for r in [{col: col}, *rows] for w in r[col].split() or [""]) for col in cols}
        give = [col for col in cols if col not in ("algorithm", "fps", *narrow)]
        while give and sum(width.values()) + 3 * len(width) + 1 > console.width:
            wide = [c for c in give if width[c] > word[c]] or [c for c in give if width[c] > 4]
            if not wide:
                break
            width[max(wide, key=width.get)] -= 1
        for col in cols:
            table.add_column(col, justify="right" if col in ("fps", *narrow) else "left", overflow="fold",
                             width=width[col])
        for r in rows:
            table.add_row(*(v for col, v in r.items() if col not in same))
        console.print(table)
        if same:
            said = {"variant": lambda v: "no variant" if v == "-" else f"variant {v}",
                    "fitness": lambda v: f"fitness {v}", "motion": lambda v: f"motion {v}",
                    "evals per frame": lambda v: f"{v} evaluations per frame",
                    "frames": lambda v: f"{v} frames"}
            console.print(f"  every entry: {', '.join(said[col](v) for col, v in same.items())}", markup=False,
                          highlight=False)
        if footer:
            console.print(f"  paper: {footer}", markup=False, highlight=False)
        if max_frames is not None:
            console.print(f"  --max-frames {max_frames}: the first {max_frames} frames at the lowest rate and the same "
                          "stretch of time at the others (a quick try, not the papers' comparison)",
                          markup=False, highlight=False)


def _shared_parts(refs: list[str]) -> tuple[str, str]:
    """The leading and the trailing comma-separated parts that every reference shares (``"Sharifi et al. 2017"``,
    ``"reprojection fitness (not the paper's)"``), each ``""`` when there is none."""
    parts = [r.split(", ") for r in refs if r]
    if len(parts) < 2:
        return "", ""
    n = min(len(p) for p in parts) - 1  # each reference keeps a part of its own
    head = 0
    while head < n and len({tuple(p[:head + 1]) for p in parts}) == 1:
        head += 1
    tail = 0
    while tail < n - head and len({tuple(p[len(p) - tail - 1:]) for p in parts}) == 1:
        tail += 1
    first = parts[0]
    return ", ".join(first[:head]), ", ".join(first[len(first) - tail:]) if tail else ""


def _in_paper(ref: str, footer: str | None, shared: tuple[str, str] = ("", "")) -> str:
    """An entry's cell in the listing's paper column: the part of its reference after the suite's shared
    section (``Fig. 6.10``), the part between the parts every entry shares (``Table 1 set-up``), or the whole
    reference when the suite cites several papers."""
    if not ref:
        return "-"
    if any(shared):
        head, tail = shared
        parts = ref.split(", ")
        parts = parts[len(head.split(", ")) if head else 0:]
        parts = parts[:len(parts) - len(tail.split(", "))] if tail else parts
        return ", ".join(parts) or "-"
    if footer is None:
        return ref
    return ref.split(" (", 1)[1].rstrip(")") if " (" in ref else "-"
