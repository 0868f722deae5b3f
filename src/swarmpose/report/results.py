"""Reading a results folder written by ``swarmpose track`` (:func:`swarmpose.track.runner.track_runs`).

The layout (the contract between the tracker and the report)::

    RESULTS_DIR/
      config.json     settings, seeds, sequence path, frames, evaluations per frame, IK floor, versions
      subject.json    the body model's subject (limb lengths, cone sizes)
      ik.npz          params (T, D) (the smooth IK fit, the start pose), joint_error_mm (T, 15) and
                      floor_params (T, D) (the best fit: the IK floor per frame), frame_indices (T,)
      summary.json    errors aggregated over the runs
      run_000/        one folder per run:
        track.npz     params, joints, scores, evaluations, seconds, frame_indices, d_per_frame, param_names
        joints.npz    joints, gt_joints (T, 15, 3) mm, frame_times (T,) s, world_from_source (4, 4)
        summary.json  the run's errors

Only ``config.json`` and at least one finished run (``track.npz`` and ``joints.npz``) are required;
the rest is recomputed or left out when missing (a run still in progress has only
``progress.npz`` and is skipped).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import DataError, FormatError
from swarmpose.io.files import load_npz, read_json_object
from swarmpose.joints import JOINTS15
from swarmpose.metrics import valid_frames

__all__ = ["RunData", "Results", "load_results", "as_results", "largest_run_maximum"]


@dataclass
class RunData:
    """One finished run of a results folder.

    Attributes
    ----------
    run : int
        Run index (``run_XXX``).
    path : pathlib.Path
        The run's folder.
    params : numpy.ndarray, shape (T, D)
        Tracked pose parameters per processed frame.
    joints, gt_joints : numpy.ndarray, shape (T, 15, 3)
        Tracked and ground-truth HumanEva joints, world mm.
    frame_indices : numpy.ndarray, shape (T,), int64
        Sequence frame index of each processed frame.
    frame_times : numpy.ndarray, shape (T,)
        Seconds from the sequence's first frame.
    d_per_frame : numpy.ndarray, shape (T,)
        3D error D per frame (mean joint distance, mm).
    seconds, evaluations, scores : numpy.ndarray, shape (T,)
        Time, fitness evaluations and best fitness per frame (zeros where not stored).
    summary : dict
        The run's ``summary.json`` (empty when missing).
    """

    run: int
    path: Path
    params: np.ndarray
    joints: np.ndarray
    gt_joints: np.ndarray
    frame_indices: np.ndarray
    frame_times: np.ndarray
    d_per_frame: np.ndarray
    seconds: np.ndarray
    evaluations: np.ndarray
    scores: np.ndarray
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def joint_distances(self) -> np.ndarray:
        """Distance of every joint in every frame, ``(T, 15)`` mm (NaN where the ground truth is invalid)."""
        return np.linalg.norm(self.joints - self.gt_joints, axis=-1)

    @property
    def valid(self) -> np.ndarray:
        """``(T,)`` frames with valid ground truth: the only ones scored."""
        return valid_frames(self.gt_joints)

    @property
    def per_joint_mm(self) -> np.ndarray:
        """Mean error of each joint over the scored frames, ``(15,)`` mm (NaN without ground truth)."""
        if not self.valid.any():
            return np.full(15, np.nan)
        return self.joint_distances[self.valid].mean(axis=0)

    @property
    def frames_per_s(self) -> float:
        """Processed frames per second of tracking time (NaN when no timings are stored)."""
        total = float(np.sum(self.seconds))
        return float(len(self.seconds) / total) if total > 0 else float("nan")


@dataclass
class Results:
    """A loaded results folder (see the module docstring); build it with :func:`load_results`.

    Attributes
    ----------
    path : pathlib.Path
        The results folder.
    config : dict
        ``config.json``.
    summary : dict
        ``summary.json``, or the same numbers recomputed from the runs when it is missing.
    runs : list of RunData
        The finished runs, by run index.
    ik_joint_error_mm : numpy.ndarray of shape (T, 15), or None
        The IK floor per frame and joint (``ik.npz``), None when missing.
    skipped : list of str
        Runs that were not loaded and why (e.g. still in progress).
    """

    path: Path
    config: dict[str, Any]
    summary: dict[str, Any]
    runs: list[RunData]
    ik_joint_error_mm: np.ndarray | None = None
    ik_params: np.ndarray | None = None
    skipped: list[str] = field(default_factory=list)

    # ------------------------------------------------------------------ convenience
    @property
    def name(self) -> str:
        """The folder's name."""
        return self.path.name

    @property
    def frame_times(self) -> np.ndarray:
        """Seconds of the processed frames, ``(T,)`` (from the first run)."""
        return self.runs[0].frame_times

    @property
    def frame_indices(self) -> np.ndarray:
        """Sequence frame index of each processed frame, ``(T,)`` (from the first run)."""
        return self.runs[0].frame_indices

    @property
    def gt_joints(self) -> np.ndarray:
        """Ground-truth joints of the processed frames, ``(T, 15, 3)`` mm."""
        return self.runs[0].gt_joints

    @property
    def ik_frame_error_mm(self) -> np.ndarray | None:
        """The IK floor per frame (mean over the joints), ``(T,)`` mm, or None."""
        return None if self.ik_joint_error_mm is None else self.ik_joint_error_mm.mean(axis=1)

    @property
    def fps(self) -> float:
        """Tracking frame rate (``config.json`` ``fps``)."""
        return float(self.config.get("fps") or self.summary.get("fps") or 0.0)

    def run(self, k: int) -> RunData:
        """The run with index ``k``; the error lists the runs there are."""
        for r in self.runs:
            if r.run == k:
                return r
        have = ", ".join(str(r.run) for r in self.runs)
        raise DataError(f"{self.path}: no finished run {k} (finished runs: {have})")

    def per_joint_by_run(self) -> np.ndarray:
        """Mean error of each joint in each run, ``(R, 15)`` mm."""
        return np.stack([r.per_joint_mm for r in self.runs])

    # ------------------------------------------------------------------ model and sequence
    @cached_property
    def model(self):
        """The tracked body model: ``config.json`` model and variant with ``subject.json``.

        Raises
        ------
        DataError
            ``subject.json`` is missing.
        """
        from swarmpose.body.model import BodyModel
        from swarmpose.body.spec import Subject, load_spec

        subject_file = self.path / "subject.json"
        if not subject_file.is_file():
            raise DataError(f"{subject_file} not found: the body model's subject (limb lengths) is needed "
                            "to rebuild the tracked model")
        spec = load_spec(self.config.get("model", "balan31"))
        return BodyModel(spec, Subject.load(subject_file), self.config.get("variant"))

    def sequence_path(self, override: str | os.PathLike[str] | None = None) -> Path:
        """The tracked sequence folder (``config.json`` ``sequence``, or ``override``).

        A relative path is tried from the current directory, then from the results folder and its
        parent.

        Raises
        ------
        DataError
            The folder cannot be found.
        """
        if override is not None:
            p = Path(override)
            if not (p / "sequence.json").is_file():
                raise DataError(f"--sequence {str(p)!r}: no sequence folder there (no sequence.json)")
            from swarmpose.track.provenance import sequence_identity

            tracked = self.config.get("sequence_identity")
            if tracked is not None and sequence_identity(p) != tracked:
                raise DataError(f"--sequence {str(p)!r} is not the tracked sequence ({self.config.get('sequence')}, "
                                f"{tracked}; this one has {sequence_identity(p)})")
            return p
        raw = self.config.get("sequence")
        if not raw:
            raise DataError(f"{self.path / 'config.json'}: no 'sequence' recorded; pass the sequence folder")
        p = Path(raw)
        candidates = [p] if p.is_absolute() else [p, self.path / p, self.path.parent / p]
        for c in candidates:
            if (c / "sequence.json").is_file():
                return c
        raise DataError(f"sequence folder {str(raw)!r} (from {self.path / 'config.json'}) not found; "
                        "pass the sequence folder explicitly (--sequence)")

    def open_sequence(self, override: str | os.PathLike[str] | None = None):
        """Open the tracked sequence (:class:`swarmpose.io.sequence.MultiViewSequence`); close it after use."""
        from swarmpose.io.sequence import open_sequence

        return open_sequence(self.sequence_path(override))


def as_results(results: str | os.PathLike[str] | Results) -> Results:
    """``results`` itself if already loaded, else :func:`load_results` of the folder."""
    return results if isinstance(results, Results) else load_results(results)


def _load_run(run_dir: Path, run: int, fps: float = 0.0) -> RunData:
    track = load_npz(run_dir / "track.npz", ("params",))
    jnt = load_npz(run_dir / "joints.npz", ("joints", "gt_joints"))
    joints = np.asarray(jnt["joints"], dtype=np.float64)
    gt = np.asarray(jnt["gt_joints"], dtype=np.float64)
    T = joints.shape[0]
    if joints.shape != gt.shape or joints.shape[1:] != (15, 3):
        raise FormatError(f"joints {joints.shape} and gt_joints {gt.shape} must both be (T, 15, 3)",
                          path=run_dir / "joints.npz")
    params = np.asarray(track["params"], dtype=np.float64)
    if params.shape[0] != T:
        raise FormatError(f"params has {params.shape[0]} frames, joints.npz {T}", path=run_dir / "track.npz")

    def arr(src: dict[str, np.ndarray], key: str, default: np.ndarray) -> np.ndarray:
        a = src.get(key)
        return default if a is None or a.shape[:1] != (T,) else np.asarray(a)

    d_default = np.linalg.norm(joints - gt, axis=-1).mean(axis=1)
    summary_file = run_dir / "summary.json"
    return RunData(
        run=run, path=run_dir, params=params, joints=joints, gt_joints=gt,
        frame_indices=arr(track, "frame_indices", np.arange(T)).astype(np.int64),
        # a folder without stored times: evenly spaced at the tracking rate (1 s apart if that is unknown)
        frame_times=arr(jnt, "frame_times", np.arange(T, dtype=np.float64) / (fps if fps > 0 else 1.0)).astype(np.float64),
        d_per_frame=arr(track, "d_per_frame", d_default).astype(np.float64),
        seconds=arr(track, "seconds", np.zeros(T)).astype(np.float64),
        evaluations=arr(track, "evaluations", np.zeros(T, np.int64)),
        scores=arr(track, "scores", np.zeros(T)).astype(np.float64),
        summary=read_json_object(summary_file) if summary_file.is_file() else {},
    )


def _recompute_summary(config: dict[str, Any], runs: list[RunData], ik_floor: float | None) -> dict[str, Any]:
    """The aggregate of :func:`swarmpose.track.runner.track_runs`, from the runs' joints."""
    from swarmpose.metrics import aggregate_runs, track_errors

    try:
        errs = [track_errors(r.joints, r.gt_joints) for r in runs]
    except ValueError as exc:  # no valid ground truth, or a non-finite estimate
        raise FormatError(f"cannot score the runs: {exc}", path=runs[0].path.parent) from None
    agg = aggregate_runs(errs)
    worst = runs[int(agg["worst"]["run"])]
    return {
        "algo": config.get("algo"),
        "fps": config.get("fps"),
        "runs": len(runs),
        "evals_per_frame": config.get("evals_per_frame"),
        "d_mean_mm": agg["d_mean"],
        "d_max_mm": agg["d_max"],
        "d_max_over_runs_mm": agg["d_max_over_runs"],
        "ik_floor_mm": ik_floor,
        "mmta": agg["mmta"],
        "mmtp_mm": agg["mmtp"],
        "mu_mm": agg["mu"],
        "sigma_mm": agg["sigma"],
        "frames_per_s": float(np.nanmean([r.frames_per_s for r in runs])),
        "frames": int(runs[0].joints.shape[0]),
        "worst": {"run": worst.run, "d_mean_mm": agg["worst"]["d_mean"], "d_max_mm": agg["worst"]["d_max"],
                  "mmta": agg["worst"]["mmta"]},
        "per_joint_mm": agg["per_joint"],
        "per_run": [{"run": r.run, "d_mean_mm": e.d_mean, "d_max_mm": e.d_max, "mmta": e.mmta,
                     "mmtp_mm": e.mmtp, "sigma_mm": e.sigma, "frames_per_s": r.frames_per_s}
                    for r, e in zip(runs, errs, strict=True)],
        "recomputed": True,
    }


def largest_run_maximum(summary: dict[str, Any]) -> float | None:
    """The largest D of any run: ``d_max_over_runs_mm``, or for a summary written before that key existed
    the largest of its ``per_run`` D_max (``d_max_mm``, or ``d_max`` in a `compare` entry's summary); None
    when it has neither."""
    if summary.get("d_max_over_runs_mm") is not None:
        return float(summary["d_max_over_runs_mm"])
    maxima = [r.get("d_max_mm", r.get("d_max")) for r in summary.get("per_run", []) if isinstance(r, dict)]
    maxima = [m for m in maxima if isinstance(m, (int, float))]
    return float(max(maxima)) if maxima else None


def _summarised_runs(summary: dict[str, Any], path: Path) -> list[int]:
    """The run numbers a folder's ``summary.json`` aggregates (its ``per_run`` entries)."""
    per_run = summary.get("per_run")
    try:
        if isinstance(per_run, list) and per_run and all(isinstance(r, dict) and "run" in r for r in per_run):
            return sorted(int(r["run"]) for r in per_run)
        return list(range(len(per_run) if isinstance(per_run, list) else int(summary.get("runs", 0))))
    except (TypeError, ValueError):
        raise FormatError("per_run[].run and runs must be run numbers", path=path) from None


def _run_list(runs: list[int] | None) -> str:
    return ", ".join(str(k) for k in runs) if runs else "none"


def load_results(results_dir: str | os.PathLike[str]) -> Results:
    """Load a results folder written by ``swarmpose track``.

    Parameters
    ----------
    results_dir : path-like

    Returns
    -------
    Results

    Raises
    ------
    DataError
        The folder or its ``config.json`` is missing, or it holds no finished run.
    FormatError
        A file is malformed (the message names it).
    """
    root = Path(results_dir)
    if root.is_file():  # summary.json, a run's joints.npz, a video: the folder that holds it is meant
        parent = root.parent
        hint = (f" (its folder {parent} is one)" if (parent / "config.json").is_file()
                or (parent / "comparison.json").is_file() else " (give the folder that `swarmpose track` wrote)")
        raise DataError(f"{root} is a file, not a results folder{hint}")
    if not root.is_dir():
        raise DataError(f"{root}: no such results folder")
    cfg_file = root / "config.json"
    if not cfg_file.is_file():
        entries = sorted(c.parent for c in root.glob("*/*/config.json"))
        if entries:  # a `swarmpose compare` folder: <sequence>/<entry>/ are the results folders
            listed = ", ".join(str(e) for e in entries[:3]) + (f" and {len(entries) - 3} more" if len(entries) > 3 else "")
            if (root / "comparison.json").is_file():
                raise DataError(f"{root} holds a comparison (comparison.json), not one run's results; its entries "
                                f"are: {listed}")
            raise DataError(f"{root} holds the entries of a comparison that has not finished (no comparison.json): "
                            "continue it with the same `swarmpose compare` command and --resume, which also writes "
                            f"its table and figures; or report one of its entries: {listed}")
        raise DataError(f"{cfg_file} not found: is this a swarmpose results folder?")
    config = read_json_object(cfg_file)
    runs: list[RunData] = []
    skipped: list[str] = []
    n_runs = config.get("runs")  # the runs summary.json aggregates; run folders beyond are left out
    for d in sorted(root.glob("run_*")):
        if not d.is_dir():
            continue
        try:
            k = int(d.name[4:])
        except ValueError:
            continue
        if isinstance(n_runs, int) and k >= n_runs:
            skipped.append(f"{d.name} (beyond the {n_runs} run(s) of config.json)")
            continue
        if not ((d / "track.npz").is_file() and (d / "joints.npz").is_file()):
            why = "in progress" if (d / "progress.npz").is_file() else "no track.npz/joints.npz"
            skipped.append(f"{d.name} ({why})")
            continue
        fps = config.get("fps")
        runs.append(_load_run(d, k, float(fps) if isinstance(fps, int | float) else 0.0))
    if not runs:
        extra = f" ({', '.join(skipped)})" if skipped else ""
        hint = ("is tracking still running? If it was interrupted, continue it with the same `swarmpose track` "
                "(or `compare`) command and --resume" if any("in progress" in k for k in skipped)
                else "is tracking still running?")
        raise DataError(f"{root}: no finished run (run_XXX/track.npz and joints.npz){extra}; {hint}")
    T = runs[0].joints.shape[0]
    if any(r.joints.shape[0] != T for r in runs):
        raise FormatError(f"runs have different frame counts {[r.joints.shape[0] for r in runs]}", path=root)
    ik_err = ik_params = None
    ik_file = root / "ik.npz"
    if ik_file.is_file():
        ik = load_npz(ik_file, ("joint_error_mm",))
        ik_err = np.asarray(ik["joint_error_mm"], dtype=np.float64)
        ik_params = ik.get("params")
        if ik_err.shape != (T, 15):
            raise FormatError(f"joint_error_mm has shape {ik_err.shape}, expected ({T}, 15) like the runs",
                              path=ik_file)
    # as track: valid frames only; none without ground truth
    ik_floor = None if ik_err is None or not np.isfinite(ik_err).any() else float(np.nanmean(ik_err.mean(axis=1)))
    summary_file = root / "summary.json"
    stored = read_json_object(summary_file) if summary_file.is_file() else None
    loaded = sorted(r.run for r in runs)
    stored_runs = None if stored is None else _summarised_runs(stored, summary_file)
    if stored is not None and stored_runs == loaded:
        summary = stored
    else:
        summary = _recompute_summary(config, runs, ik_floor if ik_floor is not None else config.get("ik_floor_mm"))
        if stored is not None:
            # a resume that adds runs rewrites summary.json only at its end: until then it is an older aggregate
            summary["recomputed_because"] = (
                f"summary.json aggregates run(s) {_run_list(stored_runs)}; the folder has finished run(s) "
                f"{_run_list(loaded)} (an interrupted --resume? finishing it rewrites summary.json): the numbers "
                "here are recomputed from the runs' joints")
            for key in ("frames_scored", "frame_interval_s", "sequence", "fitness", "motion", "seed", "out_dir"):
                if key in stored:
                    summary.setdefault(key, stored[key])
    summary.setdefault("per_joint_mm", {n: float(v) for n, v in
                                        zip(JOINTS15, np.mean([r.per_joint_mm for r in runs], axis=0),
                                            strict=True)})
    return Results(path=root, config=config, summary=summary, runs=runs, ik_joint_error_mm=ik_err,
                   ik_params=ik_params, skipped=skipped)
