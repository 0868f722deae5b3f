"""Running many tracking runs: local processes by default, a Dask cluster on request.

A *job* is one run of one configuration on one sequence. Jobs are independent and deterministic
(run ``k`` of seed ``S`` always draws from ``SeedSequence([S, k])``), so the results are identical
whether they run in this process, in local worker processes or on a Dask cluster.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError, DataError, FormatError
from swarmpose.io.files import load_npz, read_json_object
from swarmpose.io.lock import folder_lock, remove_unused_folder
from swarmpose.metrics import TrackErrors, aggregate_runs
from swarmpose.track.tracker import (
    TrackConfig,
    ground_truth_identity,
    model_identity,
    observation_identity,
    prepare_track,
    run_tracker,
    sequence_identity,
    sequence_location,
    tracker_priors,
    write_config,
)

__all__ = ["Job", "check_results_folder", "check_sequence_data", "close_client", "connect_scheduler",
           "errors_from_summary", "finished_run", "recorded_config", "resolve_sequence", "run_job", "run_jobs",
           "track_runs"]


@dataclass(frozen=True)
class Job:
    sequence: str
    config: dict[str, Any]
    run: int
    out_dir: str
    resume: bool = False
    frames: int = 0  # frames the run tracks (for the progress bar; 0 = unknown)
    feature_cache: str | None = None  # the feature stores' folder (track.feature_store); None: none


def resolve_sequence(source: str | Path, *, cache_dir: Path | None = None, progress: bool = True) -> Path | str:
    """A sequence folder as is; a ``.bvh`` clip is synthesised once with default settings into a cache;
    ``humaneva:``/``leewalk:`` dataset specs are passed on to :func:`swarmpose.io.sequence.open_sequence`."""
    p = Path(source)
    if p.suffix.lower() == ".bvh":
        from swarmpose.synth.synthesize import cached_sequence

        kwargs: dict[str, Any] = {"progress": progress}
        if cache_dir is not None:
            kwargs["cache_dir"] = cache_dir
        return Path(cached_sequence(p, **kwargs))
    if str(source).startswith(("humaneva:", "leewalk:")):
        return str(source)  # type: ignore[return-value]  # opened lazily by open_sequence
    _check_sequence_folder(source, p)
    return p


def check_source(source: str | Path) -> None:
    """Refuse a tracking source that is not there, without synthesising or opening it (``compare --list``):
    a ``.bvh`` clip must be a file, a sequence folder must hold ``sequence.json``; dataset specs pass."""
    p = Path(source)
    if str(source).startswith(("humaneva:", "leewalk:")):
        return
    if p.suffix.lower() == ".bvh":
        if not p.is_file():
            raise DataError(f"{p}: no such BVH clip")
        return
    _check_sequence_folder(source, p)
    if not (p / "sequence.json").is_file():
        raise DataError(f"{p}: {'no such sequence folder' if not p.exists() else 'not a sequence folder (no sequence.json)'}")


def _check_sequence_folder(source: str | Path, p: Path) -> None:
    """Say what a source that is not a sequence folder is (a results folder, some other file)."""
    if not str(source).strip():
        raise DataError("the source is empty: give a sequence folder, a .bvh clip or humaneva:PATH")
    if p.is_file():
        raise DataError(f"{p} is a file, not a sequence folder or a .bvh clip")
    if p.is_dir() and not (p / "sequence.json").is_file() and (p / "config.json").is_file():
        try:
            tracked = read_json_object(p / "config.json").get("sequence")
        except (FormatError, OSError):
            tracked = None
        where = f"; it was tracked from {tracked}" if tracked else ""
        raise DataError(f"{p} is a results folder (from swarmpose track or compare), not a sequence{where}")


#: In a worker process: where its runs report finished frames (set by :func:`_worker_init`).
_progress_queue: Any = None


def _worker_init(threads: int, progress_queue: Any = None, parent_pid: int | None = None) -> None:
    import numba

    from swarmpose.track.heap import fix_mmap_threshold

    global _progress_queue
    fix_mmap_threshold()  # a long run's heap grows less (swarmpose.track.heap)
    # Ctrl-C reaches the whole process group: the parent alone handles it (it stops the workers), so
    # that no worker dies half-way through a pool message and leaves the pool waiting forever
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    numba.set_num_threads(max(1, threads))
    _progress_queue = progress_queue
    if parent_pid is not None:
        threading.Thread(target=_exit_with_parent, args=(parent_pid,), daemon=True).start()


def _exit_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """End this worker when the parent is gone (``kill``, a batch system's SIGTERM, a crash): nothing
    else would, and an orphan would track on for no one. Its frames so far are saved; --resume goes on."""
    while True:
        time.sleep(poll_s)
        if os.getppid() != parent_pid:
            os._exit(1)


def _run_job_in_worker(index: int, job: Job) -> dict[str, Any]:
    """:func:`run_job` in a pool worker, reporting ``(index, frames done)`` to the parent's progress bar."""
    q = _progress_queue

    def report(done: int, _total: int) -> None:
        try:
            q.put_nowait((index, done))
        except Exception:  # noqa: BLE001 - the bar is cosmetic: never let it fail a run
            pass

    return run_job(job, progress=None if q is None else report)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued jobs and terminate the running ones (on Ctrl-C). The tracker saves its progress
    atomically after every frame, so ``--resume`` continues from the last finished frame."""
    procs = list((getattr(pool, "_processes", None) or {}).values())  # no public terminate() exists
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        proc.terminate()
    for proc in procs:
        proc.join(timeout=3)
        if proc.is_alive():  # still starting up, or stuck in a call that ignores SIGTERM
            proc.kill()
            proc.join(timeout=3)


def run_job(job: Job, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Execute one job (top-level so that worker processes and Dask can pickle it).

    ``progress(frames_done, frames)`` is called after every tracked frame.
    """
    out = Path(job.out_dir)
    done = finished_run(out, job.run) if job.resume else None
    if done is not None:  # tracked to the end by an earlier session: kept as it is, not tracked again
        return {**done, "run": job.run, "out_dir": job.out_dir}
    cfg = TrackConfig(**job.config)
    setup = prepare_track(job.sequence, cfg, out)
    res = run_tracker(setup, job.run, out, resume=job.resume, progress=progress, feature_cache=job.feature_cache)
    return {"run": job.run, "out_dir": job.out_dir, **res.errors}


def connect_scheduler(address: str, timeout_s: float = 20.0) -> Any:
    """A ``dask.distributed.Client`` for the scheduler at ``address``; a clear error when it cannot be reached.

    Called before any slow preparation (the IK fit), so a wrong ``--scheduler`` fails in seconds.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed: pip install 'swarmpose[dask]'") from None
    try:
        return Client(address, timeout=f"{timeout_s:g}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"cannot reach the Dask scheduler at {address!r}: {exc}") from None


def close_client(scheduler: Any) -> None:
    """Close a client from :func:`connect_scheduler` (nothing for an address string or None)."""
    if scheduler is not None and not isinstance(scheduler, str):
        scheduler.close()


def finished_run(out_dir: Path, run: int) -> dict[str, Any] | None:
    """The errors of run ``run`` in ``out_dir`` when an earlier session tracked it to the end (its ``summary.json``,
    ``track.npz`` and ``joints.npz`` written, the summary readable and naming that run); None otherwise. A resume
    keeps such a run as it is: tracking it again would redo an offline run's backward pass (its forward frames are
    saved, the backward pass is not) and rewrite its summary with an empty session's timing."""
    run_dir = Path(out_dir) / f"run_{run:03d}"
    if not all((run_dir / name).is_file() for name in ("summary.json", "track.npz", "joints.npz")):
        return None
    try:
        summary = read_json_object(run_dir / "summary.json")
    except (FormatError, OSError):
        return None  # damaged: tracked again from its saved frames
    return summary if summary.get("run") == run else None


def _frames_saved(job: Job) -> int:
    """Frames of ``job`` tracked by an earlier session (``--resume``): all for a finished run, else the
    count in its ``progress.npz`` (0 when there is none or it cannot be read; the run reports itself)."""
    if not job.resume:
        return 0
    if finished_run(Path(job.out_dir), job.run) is not None:
        return job.frames
    run_dir = Path(job.out_dir) / f"run_{job.run:03d}"
    try:
        done = int(load_npz(run_dir / "progress.npz", ("done",))["done"])
    except (FormatError, OSError, ValueError, TypeError):  # missing or damaged: the run itself reports it
        return 0
    return max(0, min(done, job.frames))


class _JobsBar:
    """One progress bar over many runs: by frames when every job knows its frame count, else by runs."""

    def __init__(self, jobs: Sequence[Job], enabled: bool, by_frames: bool = True) -> None:
        from tqdm import tqdm

        self.jobs = jobs
        self.by_frames = by_frames and bool(jobs) and all(j.frames > 0 for j in jobs)
        total = sum(j.frames for j in jobs) if self.by_frames else len(jobs)
        # frames a resumed run saved before: counted from the start, so the rate and ETA are this session's
        self.done_frames = [_frames_saved(j) if self.by_frames else 0 for j in jobs]
        self.finished = 0
        self.bar = tqdm(total=total, initial=sum(self.done_frames), desc="tracking" if self.by_frames else "runs",
                        unit="frame" if self.by_frames else "run", file=sys.stderr, disable=not enabled)
        if self.by_frames:
            self._postfix()

    def _postfix(self) -> None:
        self.bar.set_postfix_str(f"{self.finished}/{len(self.jobs)} runs done", refresh=False)

    def frame(self, index: int, done: int) -> None:
        self.done_frames[index] = max(self.done_frames[index], done)

    def job_done(self, index: int) -> None:
        self.finished += 1
        self.done_frames[index] = self.jobs[index].frames
        if self.by_frames:
            self._postfix()

    def refresh(self) -> None:
        n = sum(self.done_frames) if self.by_frames else self.finished
        if n != self.bar.n:
            self.bar.update(n - self.bar.n)

    def close(self) -> None:
        self.bar.close()


def run_jobs(jobs: Sequence[Job], *, workers: int | None = None, scheduler: Any = None,
             progress: bool = True) -> list[dict[str, Any]]:
    """Run jobs in parallel local processes (default), in-process (``workers=1``) or on Dask.

    ``scheduler``: a Dask scheduler address, or a client from :func:`connect_scheduler` (closed here).
    The progress bar counts tracked frames over all runs (runs on Dask: finished runs).
    """
    results: list[dict[str, Any] | None] = [None] * len(jobs)
    if scheduler:
        from dask.distributed import as_completed as dask_completed

        client = connect_scheduler(scheduler) if isinstance(scheduler, str) else scheduler
        bar = _JobsBar(jobs, progress, by_frames=False)  # remote workers cannot reach a local queue
        with client:
            futures = {client.submit(run_job, j, pure=False): i for i, j in enumerate(jobs)}
            for fut in dask_completed(futures):
                results[futures[fut]] = fut.result()
                bar.job_done(futures[fut])
                bar.refresh()
        bar.close()
        return [r for r in results if r is not None]
    bar = _JobsBar(jobs, progress)
    cpus = os.cpu_count() or 1
    workers = min(len(jobs), cpus) if workers is None else max(1, workers)
    try:
        if workers == 1:
            for i, j in enumerate(jobs):
                results[i] = run_job(j, progress=lambda done, _t, i=i: (bar.frame(i, done), bar.refresh()))
                bar.job_done(i)
                bar.refresh()
        else:
            _run_in_pool(jobs, workers, cpus, results, bar)
    finally:
        bar.close()
    return [r for r in results if r is not None]


def _run_in_pool(jobs: Sequence[Job], workers: int, cpus: int, results: list[dict[str, Any] | None],
                 bar: _JobsBar) -> None:
    # "spawn": numba's OpenMP threading layer is not fork-safe once the parent has used it
    ctx = multiprocessing.get_context("spawn")
    frames_done = ctx.Queue()
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                               initargs=(max(1, cpus // workers), frames_done, os.getpid()))
    try:
        # the workers start here; a Ctrl-C while they import would print their tracebacks, so they
        # start with SIGINT ignored (inherited) and keep ignoring it (_worker_init)
        with _sigint_ignored():
            futures = {pool.submit(_run_job_in_worker, i, j): i for i, j in enumerate(jobs)}
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            _drain(frames_done, bar)
            for fut in finished:
                results[futures[fut]] = fut.result()
                bar.job_done(futures[fut])
            bar.refresh()
        pool.shutdown(wait=True)
    except BaseException:  # Ctrl-C or a failed job: do not wait for the queued runs
        _stop_pool(pool)
        raise
    finally:
        frames_done.close()


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore Ctrl-C for a moment (only the main thread may change signal handlers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _drain(q: Any, bar: _JobsBar) -> None:
    while True:
        try:
            index, done = q.get_nowait()
        except queue.Empty:
            return
        bar.frame(index, done)


def errors_from_summary(summary: dict[str, Any]) -> TrackErrors:
    """Rebuild :class:`TrackErrors` (without the per-frame array) from a run's summary dict."""
    keys = ("d_mean", "d_max", "d_std", "mmta", "mmtp", "mu", "sigma")
    return TrackErrors(d_per_frame=np.zeros(0), per_joint=summary["per_joint"], **{k: summary[k] for k in keys})


def recorded_config(results: Path) -> tuple[dict[str, Any], TrackConfig]:
    """A results folder's ``config.json`` and the tracking settings it records (its other entries, such as the
    versions and the resolved fitness, left out; a setting written before it existed takes its default)."""
    record = read_json_object(Path(results) / "config.json")
    names = {f.name for f in fields(TrackConfig)}
    return record, TrackConfig(**{k: v for k, v in record.items() if k in names})


def check_results_folder(out_dir: Path, sequence: str | Path, config: TrackConfig, runs: int, resume: bool) -> None:
    """Refuse to mix runs of different settings in one results folder (before anything is written).

    Without ``resume`` the folder must not hold tracking results yet. With ``resume`` its
    ``config.json`` must name the same sequence and settings, and at least as many runs (more may be
    added: runs are independent).
    """
    from swarmpose.datasets import is_dataset_spec

    cfg_file = out_dir / "config.json"
    started = sorted({p.parent.name for p in out_dir.glob("run_*/*.npz")})
    if not resume:
        if started or (out_dir / "summary.json").is_file():
            state = "finished" if (out_dir / "summary.json").is_file() else "unfinished"
            which = f" ({', '.join(started)})" if started else ""
            raise ConfigError(f"{out_dir} already holds {state} tracking results{which}: pass --resume to continue "
                              "them with the same settings, or choose another --out")
        return
    if not cfg_file.is_file():
        return  # nothing to resume yet: a fresh start
    old = read_json_object(cfg_file)
    new = asdict(config)
    defaults = asdict(TrackConfig())  # a folder written before a setting existed used its default
    def shown(key: str, value: Any) -> str:
        return "all frames" if key == "max_frames" and value is None else repr(value)

    differ = [f"{k}: {shown(k, old.get(k, defaults[k]))} there, {shown(k, v)} now" for k, v in new.items()
              if old.get(k, defaults[k]) != v]
    # "auto" may resolve differently in another version (AAPSO: markers -> reprojection)
    if old.get("fitness_kind", config.fitness_kind) != config.fitness_kind:
        differ.append(f"fitness_kind: {old['fitness_kind']!r} there, {config.fitness_kind!r} now")
    here = sequence_location(sequence)
    if "sequence_identity" in old:
        same_sequence = old["sequence_identity"] == sequence_identity(sequence)
    else:  # written before the fingerprint: the same folder, or the same folder name (cache names carry a hash)
        then = str(old.get("sequence", ""))
        if Path(then).is_dir() and Path(str(sequence)).is_dir():
            same_sequence = Path(then).resolve() == Path(str(sequence)).resolve()
        elif is_dataset_spec(then) or is_dataset_spec(here):
            same_sequence = then == here
        else:
            same_sequence = Path(then).name == Path(here).name
    if not same_sequence:
        differ.append(f"sequence: {old.get('sequence')} there, {here} now (not the same data)")
    if "model_spec_sha1" in old and old["model_spec_sha1"] != model_identity(config.model):
        differ.append(f"body model: the spec {config.model!r} has changed since")
    if differ:
        raise ConfigError(f"{cfg_file}: the runs being resumed used other settings ({'; '.join(differ)}); "
                          "use another --out for the new settings")
    if isinstance(old.get("runs"), int) and runs < old["runs"]:
        raise ConfigError(f"{cfg_file}: the folder holds {old['runs']} runs; resuming with --runs {runs} would "
                          f"leave runs {runs}..{old['runs'] - 1} out of the summary (pass --runs {old['runs']} "
                          "or more)")


def check_sequence_data(out_dir: Path, setup: Any, resume: bool) -> None:
    """On a resume, refuse a sequence whose data were edited since the folder's runs were tracked: the
    ground truth at the tracked frames (``config.json``'s ``ground_truth_sha1``) and the observation files
    (``observations_sha1``, one hash per file). A key missing from an older folder is not checked."""
    cfg_file = out_dir / "config.json"
    if not resume or not cfg_file.is_file():
        return
    old = read_json_object(cfg_file)
    where = sequence_location(setup.sequence_path)
    then = old.get("ground_truth_sha1")
    if then is not None and then != ground_truth_identity(setup.gt_joints):
        raise ConfigError(f"{cfg_file}: the ground truth of {where} at the tracked frames is not the one the "
                          "finished runs were scored against (edited since?); track into another --out")
    then = old.get("observations_sha1")
    now = observation_identity(setup.sequence_path)
    if isinstance(then, dict) and now is not None and then != now:
        changed = sorted(k for k in then.keys() | now.keys() if then.get(k) != now.get(k))
        raise ConfigError(f"{cfg_file}: {', '.join(changed)} of {where} changed since the finished runs were "
                          "tracked (images, cameras or markers edited in place?); track into another --out")


def _intervals(frame_times: np.ndarray) -> dict[str, float | None]:
    """Mean, shortest and longest time between tracked frames: a rate that does not divide the
    sequence's (25 fps from 60) picks the nearest frames, so the spacing alternates (33 / 50 ms)."""
    d = np.diff(np.asarray(frame_times, dtype=np.float64))
    if d.size == 0:  # one frame: no interval (null in the JSON)
        return {"mean": None, "min": None, "max": None}
    return {"mean": float(d.mean()), "min": float(d.min()), "max": float(d.max())}


def track_runs(sequence: str | Path, config: TrackConfig, runs: int, out_dir: Path, *, resume: bool = False,
               workers: int | None = None, scheduler: Any = None, progress: bool = True,
               feature_cache: str | Path | None = None, consensus: int = 0) -> dict[str, Any]:
    """Track ``runs`` runs of one configuration and write ``out_dir`` (config, runs, summary); ``feature_cache``:
    the feature stores' folder (:mod:`swarmpose.track.feature_store`), None for none. ``consensus=K``: then fuse
    the runs K at a time into ``out_dir/consensus`` (:func:`swarmpose.track.consensus.write_consensus`; its
    summary under ``"consensus"``)."""
    from swarmpose.track.consensus import check_groups

    out_dir = Path(out_dir)
    if consensus:
        check_groups(runs, consensus)
    check_results_folder(out_dir, sequence, config, runs, resume)  # before anything is written
    fresh = not out_dir.exists()
    with folder_lock(out_dir):  # a second process on this folder (a --resume started twice) is refused
        try:
            if isinstance(scheduler, str):
                scheduler = connect_scheduler(scheduler)  # before the IK fit: a wrong address fails at once
            setup = prepare_track(sequence, config, out_dir)  # fits and caches the IK floor once
            check_sequence_data(out_dir, setup, resume)
            write_config(out_dir, setup, runs, resume)
        except BaseException:
            close_client(scheduler)
            if fresh:  # a source or setting that fails leaves no results folder behind
                remove_unused_folder(out_dir)
            raise
        summary = _track_jobs(sequence, config, runs, out_dir, setup, resume=resume, workers=workers,
                              scheduler=scheduler, progress=progress, feature_cache=feature_cache)
        if consensus:
            from swarmpose.track.consensus import write_consensus

            priors = tracker_priors(setup.model, config.optimizer(setup.model))  # the runs' own hard priors
            summary["consensus"] = write_consensus(out_dir, consensus, setup.model, priors.valid,
                                                   setup.has_ground_truth)
            (out_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
        return summary


def sum_recoveries(per_run: Sequence[dict[str, Any]]) -> dict[str, int]:
    total: dict[str, int] = {}
    for r in per_run:
        for limb, n in (r.get("recoveries") or {}).items():
            total[limb] = total.get(limb, 0) + int(n)
    return total


def _track_jobs(sequence: str | Path, config: TrackConfig, runs: int, out_dir: Path, setup: Any, *, resume: bool,
                workers: int | None, scheduler: Any, progress: bool,
                feature_cache: str | Path | None = None) -> dict[str, Any]:
    cache = None if feature_cache is None else str(feature_cache)
    jobs = [Job(str(sequence), asdict(config), k, str(out_dir), resume, setup.progress_frames, cache)
            for k in range(runs)]
    per_run = run_jobs(jobs, workers=workers, scheduler=scheduler, progress=progress)
    if setup.has_ground_truth:
        agg = aggregate_runs([errors_from_summary(r) for r in per_run])
    else:  # no ground truth: every error measure is absent (null in the JSON), never a number
        agg = {k: None for k in ("d_mean", "d_max", "d_max_over_runs", "mmta", "mmtp", "mu", "sigma",
                                 "d_mean_std_over_runs", "per_joint")}
        agg["worst"] = {"run": None, "d_mean": None, "d_max": None, "mmta": None}
    summary = {
        "algo": config.algo,
        "fps": config.fps,
        "runs": runs,
        "evals_per_frame": setup.evals_per_frame,
        "d_mean_mm": agg["d_mean"],
        "d_max_mm": agg["d_max"],  # mean of the runs' maxima
        "d_max_over_runs_mm": agg["d_max_over_runs"],  # the largest D of any run
        "ik_floor_mm": setup.ik_floor_mm,
        "mmta": agg["mmta"],
        "mmtp_mm": agg["mmtp"],
        "mu_mm": agg["mu"],  # Sharifi et al. eq. 19 (equals d_mean_mm)
        "sigma_mm": agg["sigma"],  # eq. 19: per-frame spread over the 15 joints, averaged over frames
        "frames_per_s": float(np.mean([r["frames_per_s"] for r in per_run])),
        "frames": int(len(setup.frame_indices)),
        "frames_scored": int(setup.valid.sum()),  # with valid ground truth: the errors are over these
        "ground_truth": setup.has_ground_truth,
        "views": config.views or None,
        "frame_interval_s": _intervals(setup.frame_times),
        "worst": {"run": agg["worst"]["run"], "d_mean_mm": agg["worst"]["d_mean"],
                  "d_max_mm": agg["worst"]["d_max"], "mmta": agg["worst"]["mmta"]},
        "d_mean_std_over_runs_mm": agg["d_mean_std_over_runs"],  # sample SD of the runs' D_mean
        "per_joint_mm": agg["per_joint"],
        # frames on which a limb was found lost and searched again with success, over all runs
        "recoveries": sum_recoveries(per_run),
        "per_run": [{"run": r["run"], "d_mean_mm": r["d_mean"], "d_max_mm": r["d_max"], "mmta": r["mmta"],
                     "mmtp_mm": r["mmtp"], "sigma_mm": r["sigma"], "frames_per_s": r["frames_per_s"],
                     "recoveries": r.get("recoveries", {})}
                    for r in sorted(per_run, key=lambda r: r["run"])],
        "sequence": sequence_location(sequence),
        "fitness": config.fitness_kind,
        "motion": config.motion,
        "seed": config.seed,
        "out_dir": str(out_dir),
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
