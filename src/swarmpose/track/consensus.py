"""The runs' consensus: one track from several runs of the same sequence.

Beyond the papers. Independent runs (other seeds) of a stochastic tracker lose a limb on different frames more
often than on the same ones, so the joint-wise median of the runs' joints is right where most of them are. Per frame,
the hypotheses are every fused run's pose (and, for a run tracked with ``--backward``, its forward pass's pose as
well); the consensus is

    M_j = median_r J_j(x_r)                         (each of the 15 joints, coordinate by coordinate)
    x* = argmin_x sum_j |J_j(x) - M_j|^2            (the model fitted to them, from the hypothesis nearest M)

(:func:`swarmpose.track.start.keypoint_ik`, the keypoint fit of the tracker), or that nearest hypothesis itself
where the fit breaks the hard priors. A consensus track is thus a pose track like a run's: the report, the
exports and the error measures read it as one.

:func:`consensus_params` fuses the hypotheses of one frame range; :func:`write_consensus` writes a results
folder's runs, fused ``K`` at a time, as a results folder of their own.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError, DataError
from swarmpose.io.files import load_npz, read_json_object, save_npz

__all__ = ["Consensus", "consensus_params", "run_hypotheses", "write_consensus", "check_groups", "CONSENSUS_FOLDER"]

#: The results folder's sub-folder the consensus tracks are written to.
CONSENSUS_FOLDER = "consensus"


@dataclass
class Consensus:
    """One fused track: ``params (T, D)``, ``joints (T, 15, 3)`` mm, per frame the hypothesis nearest the median
    (``nearest (T,)``, an index into the hypotheses) and whether the fit was kept (``fitted (T,)``)."""

    params: np.ndarray
    joints: np.ndarray
    nearest: np.ndarray
    fitted: np.ndarray


def consensus_params(model: Any, hypotheses: np.ndarray, constraint: Any = None) -> Consensus:
    """Fuse ``hypotheses (R, T, D)`` (R poses per frame) into one track (module docstring).

    ``constraint(poses (N, D)) -> (N,) bool``: a fit it refuses is replaced by the hypothesis nearest the median.
    """
    from swarmpose.track.start import keypoint_ik

    P = np.asarray(hypotheses, dtype=np.float64)
    if P.ndim != 3 or P.shape[0] < 1 or P.shape[2] != model.n_params:
        raise ConfigError(f"consensus: expected hypotheses of shape (R, T, {model.n_params}), got {P.shape}")
    R, T, D = P.shape
    J = model.joints15(P.reshape(R * T, D)).reshape(R, T, 15, 3)
    median = np.median(J, axis=0)
    nearest = np.linalg.norm(J - median[None], axis=-1).sum(axis=-1).argmin(axis=0)
    params = P[nearest, np.arange(T)].copy()
    fitted = np.zeros(T, dtype=bool)
    if R > 2:  # with one or two hypotheses the median is their mean or one of them: nothing to fit
        for t in range(T):
            x = keypoint_ik(model, median[t], params[t], constraint)
            if x is not None:
                params[t] = x
                fitted[t] = True
    return Consensus(params=params, joints=model.joints15(params), nearest=nearest, fitted=fitted)


def run_hypotheses(track: dict[str, np.ndarray]) -> np.ndarray:
    """A run's poses ``(H, T, D)`` from its ``track.npz`` arrays: its track, or where it was tracked with
    ``--backward`` its two passes' (the backward pass's, whose limbs are the better of both passes per frame, and the
    forward pass's; a folder from before the path choice has the former as its track)."""
    out = [np.asarray(track["backward_params"] if "backward_params" in track else track["params"], dtype=np.float64)]
    if "forward_params" in track:
        out.append(np.asarray(track["forward_params"], dtype=np.float64))
    return np.stack(out)


def check_groups(runs: int, per_track: int) -> None:
    """Refuse ``--consensus per_track`` for ``runs`` runs unless they split into tracks of ``per_track`` runs."""
    _groups(list(range(runs)), per_track)


def _groups(runs: Sequence[int], per_track: int) -> list[list[int]]:
    if isinstance(per_track, bool) or int(per_track) != per_track or per_track < 2:
        raise ConfigError(f"--consensus K: K runs fused into each track, K >= 2 (got {per_track})")
    if not runs or len(runs) % per_track:
        raise ConfigError(f"--consensus {per_track}: the runs ({len(runs)}) must be a multiple of {per_track} "
                          f"(each consensus track fuses {per_track} runs: --runs {per_track}, {2 * per_track}, ...)")
    return [list(runs[i:i + per_track]) for i in range(0, len(runs), per_track)]


def write_consensus(results: Path, per_track: int, model: Any, constraint: Any = None,
                    has_ground_truth: bool = True) -> dict[str, Any]:
    """Fuse a results folder's runs ``per_track`` at a time (runs 0..K-1 into track 0, K..2K-1 into track 1, ...)
    and write them to ``results/consensus`` as a results folder of their own (``config.json`` with a ``consensus``
    record, the subject, ``run_XXX/{track.npz, joints.npz, summary.json}``, ``summary.json``); returns that summary.

    Raises :class:`~swarmpose.errors.ConfigError` when the runs (``config.json``'s) are not a multiple of
    ``per_track``, :class:`~swarmpose.errors.DataError` when one of them is unfinished.
    """
    from swarmpose.metrics import aggregate_runs

    results = Path(results)
    config = read_json_object(results / "config.json")
    runs = list(range(int(config.get("runs") or 0)))
    groups = _groups(runs, per_track)
    unfinished = [f"run_{r:03d}" for r in runs if not (results / f"run_{r:03d}" / "track.npz").is_file()]
    if unfinished:
        raise DataError(f"{results}: {', '.join(unfinished)} not finished (resume them first: swarmpose track ... "
                        "--resume)")
    out = results / CONSENSUS_FOLDER
    tmp = results / f".{CONSENSUS_FOLDER}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        for name in ("subject.json", "ik.npz"):
            if (results / name).is_file():
                shutil.copy2(results / name, tmp / name)
        ref = load_npz(results / f"run_{runs[0]:03d}" / "joints.npz", ("joints", "gt_joints"))
        gt = np.asarray(ref["gt_joints"], dtype=np.float64)
        per_run, errors = [], []
        for k, group in enumerate(groups):
            t0 = time.perf_counter()
            hyps, seconds, frame_indices = [], 0.0, None
            for r in group:
                run_dir = results / f"run_{r:03d}"
                track = load_npz(run_dir / "track.npz", ("params",))
                h = run_hypotheses(track)
                if h.shape[1] != gt.shape[0]:
                    raise DataError(f"{run_dir}: {h.shape[1]} frames tracked of {gt.shape[0]}: the run is unfinished "
                                    "(resume it first: swarmpose track ... --resume)")
                hyps.append(h)
                if frame_indices is None:
                    frame_indices = track.get("frame_indices")
                seconds += float(np.sum(track["seconds"])) if "seconds" in track else 0.0
            fused = consensus_params(model, np.concatenate(hyps), constraint)
            seconds += time.perf_counter() - t0
            summary = {"run": k, "fused_runs": group, "hypotheses": int(sum(len(h) for h in hyps)),
                       "frames_fitted": int(fused.fitted.sum()),
                       "frames_per_s": len(fused.params) / seconds if seconds > 0 else None}
            e = _write_track(tmp / f"run_{k:03d}", fused, ref, frame_indices, group, model, summary, has_ground_truth)
            if e is not None:
                errors.append(e)
            per_run.append(summary)
        record = {**config, "runs": len(groups),
                  "consensus": {"runs_per_track": per_track, "source": str(results.resolve()),
                                "fused_runs": groups}}
        (tmp / "config.json").write_text(json.dumps(record, indent=1) + "\n")
        agg = aggregate_runs(errors) if errors else None
        total = {"algo": config.get("algo"), "fps": config.get("fps"), "runs": len(groups),
                 "runs_per_track": per_track, "ground_truth": has_ground_truth,
                 "d_mean_mm": None if agg is None else agg["d_mean"],
                 "d_max_mm": None if agg is None else agg["d_max"],
                 "d_max_over_runs_mm": None if agg is None else agg["d_max_over_runs"],
                 "mmta": None if agg is None else agg["mmta"],
                 "frames_per_s": float(np.mean([r["frames_per_s"] or 0.0 for r in per_run])),
                 "per_run": [{"run": r["run"], "fused_runs": r["fused_runs"], "d_mean_mm": r.get("d_mean"),
                              "d_max_mm": r.get("d_max"), "mmta": r.get("mmta"), "frames_per_s": r["frames_per_s"],
                              "frames_fitted": r["frames_fitted"]} for r in per_run],
                 "out_dir": str(out)}
        (tmp / "summary.json").write_text(json.dumps(total, indent=1) + "\n")
        shutil.rmtree(out, ignore_errors=True)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return total


def _write_track(run_dir: Path, fused: Consensus, ref: dict[str, np.ndarray], frame_indices: np.ndarray | None,
                 group: list[int], model: Any, summary: dict[str, Any], has_ground_truth: bool) -> Any:
    """Write one consensus track as a run folder (``track.npz``, ``joints.npz`` beside ``ref``'s truth, times and
    world frame, ``summary.json``: ``summary`` with its errors); returns its :class:`~swarmpose.metrics.TrackErrors`
    (None without ground truth)."""
    from swarmpose.metrics import joint_acceleration, track_errors

    gt = np.asarray(ref["gt_joints"], dtype=np.float64)
    T = len(fused.params)
    run_dir.mkdir()
    errors = track_errors(fused.joints, gt) if has_ground_truth else None  # frames without valid truth: NaN
    d = np.full(T, np.nan) if errors is None else errors.d_per_frame
    save_npz(run_dir / "track.npz", params=fused.params, joints=fused.joints, d_per_frame=d,
             frame_indices=np.arange(T) if frame_indices is None else frame_indices, fused_runs=np.array(group),
             nearest=fused.nearest, fitted=fused.fitted, param_names=np.array(model.param_names))
    save_npz(run_dir / "joints.npz", joints=fused.joints, gt_joints=gt,
             **{k: ref[k] for k in ("frame_times", "world_from_source") if k in ref})
    times = ref.get("frame_times")
    summary["acceleration_mm_s2"] = None if times is None else joint_acceleration(fused.joints, times)
    if errors is not None:
        summary.update(errors.summary())
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return errors
