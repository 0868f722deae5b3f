"""A small fake results folder (the layout ``swarmpose track`` writes) over a synthetic sequence.

The "ground truth" is a walking-like motion of the ``balan31`` model itself, rendered as grey
silhouettes over a textured background into three 240x180 views; the "tracked" runs are the
ground-truth poses plus noise (run 1 temporarily loses an arm).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.camera import Camera
from swarmpose.io.sequence import SequenceWriter
from swarmpose.metrics import aggregate_runs, track_errors
from swarmpose.render import render_silhouette

SEQ_FPS, TRACK_FPS, N_SEQ, STEP = 60.0, 20.0, 18, 3
W, H = 240, 180


def rig() -> list[Camera]:
    eyes = [(4200.0, 300.0, 1500.0), (300.0, 4200.0, 1600.0), (-3500.0, -2500.0, 1700.0)]
    return [Camera.look_at(f"C{i + 1}", eye=e, target=(300.0, 0.0, 950.0), f=210.0, width=W, height=H,
                           dist=(-0.04, 0.0, 0.0, 0.0, 0.0)) for i, e in enumerate(eyes)]


def walk(model, n: int) -> np.ndarray:
    """A simple walking-like motion ``(n, D)``: forward along x, legs and arms swinging."""
    P = np.zeros((n, model.n_params))
    ph = np.linspace(0.0, 2.0 * np.pi, n)
    ix = model.param_index
    P[:, ix("pelvis_tx")] = np.linspace(0.0, 600.0, n)
    P[:, ix("pelvis_tz")] = 950.0
    P[:, ix("l_hip_flex")] = 0.4 * np.sin(ph)
    P[:, ix("r_hip_flex")] = -0.4 * np.sin(ph)
    P[:, ix("l_knee_flex")] = 0.3 + 0.3 * np.cos(ph)
    P[:, ix("r_knee_flex")] = 0.3 - 0.3 * np.cos(ph)
    P[:, ix("l_shoulder_abd")] = 0.6
    P[:, ix("r_shoulder_abd")] = 0.6
    P[:, ix("l_shoulder_flex")] = -0.3 * np.sin(ph)
    P[:, ix("r_shoulder_flex")] = 0.3 * np.sin(ph)
    P[:, ix("l_elbow_flex")] = 0.4
    P[:, ix("r_elbow_flex")] = 0.4
    return P


def _background() -> np.ndarray:
    yy, xx = np.mgrid[0:H, 0:W]
    return 150 + 40 * np.sin(xx / 9.0) * np.cos(yy / 13.0)


def _image(model, pose, cam, rng) -> np.ndarray:
    bg = _background()
    sil = render_silhouette(model, pose, cam).astype(bool)
    img = np.where(sil, 70.0, bg) + rng.normal(0, 4, (H, W))
    return np.clip(img, 0, 255).astype(np.uint8)


def build_results(root: Path, *, runs: int = 2, invalid: tuple[int, ...] = (),
                  keypoints: bool = False) -> tuple[Path, Path]:
    """Write a sequence and a results folder under ``root``; return ``(results_dir, sequence_dir)``.

    ``invalid``: processed frames whose ground truth is missing (NaN rows, as HumanEva marks them); the
    summaries are then those ``swarmpose track`` writes, over the valid frames only. ``keypoints``: the sequence
    carries a detector's keypoints (the truth projected, confidence 0.9), as an imported recording does."""
    rng = np.random.default_rng(5)
    model = load_model("balan31")
    cams = rig()
    gt_params = walk(model, N_SEQ)
    gt = model.joints15(gt_params)
    seq_dir = root / "seq"
    w = SequenceWriter(seq_dir, cams, SEQ_FPS, N_SEQ, streams=("image",))
    for k in range(N_SEQ):
        w.write_frame(k, image=np.stack([_image(model, gt_params[k], c, rng) for c in cams]))
    markers = None
    if keypoints:
        from swarmpose.io.sequence import MarkerData
        from swarmpose.joints import JOINTS15
        from swarmpose.triangulation import reproject

        uv = reproject(cams, gt)
        markers = MarkerData.from_dense(JOINTS15, uv, np.full(uv.shape[:-1], 0.9))
    w.finish(gt_joints=gt, frame_times=np.arange(N_SEQ) / SEQ_FPS, markers=markers,
             backgrounds=np.stack([np.clip(_background(), 0, 255).astype(np.uint8)] * len(cams)))

    res = root / "results"
    res.mkdir()
    frames = np.arange(0, N_SEQ, STEP)
    T = len(frames)
    times = frames / SEQ_FPS
    model.subject.save(res / "subject.json")
    ik_params = gt_params[frames] + rng.normal(0, 0.01, (T, model.n_params))
    gt_frames = gt[frames].copy()
    gt_frames[list(invalid)] = np.nan
    ik_err = np.linalg.norm(model.joints15(ik_params) - gt_frames, axis=-1)
    ik_floor = float(np.nanmean(ik_err.mean(axis=1)))
    np.savez(res / "ik.npz", params=ik_params, joint_error_mm=ik_err, frame_indices=frames)
    errs = []
    per_run = []
    for r in range(runs):
        p = gt_params[frames] + rng.normal(0, 0.05, (T, model.n_params))
        p[:, model.param_index("pelvis_tx")] += rng.normal(0, 20, T)
        if r == 1:
            p[3, model.param_index("r_shoulder_flex")] += 1.5  # a lost arm in frame 9
        joints = model.joints15(p)
        e = track_errors(joints, gt_frames)
        errs.append(e)
        seconds = np.full(T, 0.5 + 0.1 * r)
        run_dir = res / f"run_{r:03d}"
        run_dir.mkdir()
        np.savez(run_dir / "track.npz", params=p, joints=joints, scores=rng.uniform(size=T),
                 evaluations=np.full(T, 1000), seconds=seconds, frame_indices=frames, d_per_frame=e.d_per_frame,
                 param_names=np.array(model.param_names))
        np.savez(run_dir / "joints.npz", joints=joints, gt_joints=gt_frames, frame_times=times,
                 world_from_source=np.eye(4))
        fps_run = float(T / seconds.sum())
        (run_dir / "summary.json").write_text(json.dumps({"run": r, **e.summary(), "frames_per_s": fps_run,
                                                          "evals_per_frame": 1000,
                                                          "ik_floor_mm": ik_floor}))
        per_run.append({"run": r, "d_mean_mm": e.d_mean, "d_max_mm": e.d_max, "mmta": e.mmta,
                        "frames_per_s": fps_run})
    agg = aggregate_runs(errs)
    config = {"algo": "sppso", "fps": TRACK_FPS, "model": "balan31", "variant": "thesis", "fitness": "auto",
              "backend": "numba", "downsample": 1, "seed": 3, "start": "ik", "fitness_kind": "silhouette_edge",
              "runs": runs, "run_seeds": {str(k): [3, k] for k in range(runs)}, "sequence": str(seq_dir),
              "frames": T, "evals_per_frame": 1000, "ik_floor_mm": ik_floor,
              "versions": {"swarmpose": "0.1.0", "numpy": np.__version__}, "created": "2024-01-01T00:00:00"}
    (res / "config.json").write_text(json.dumps(config, indent=1))
    summary = {"algo": "sppso", "fps": TRACK_FPS, "runs": runs, "evals_per_frame": 1000,
               "d_mean_mm": agg["d_mean"], "d_max_mm": agg["d_max"], "ik_floor_mm": ik_floor,
               "mmta": agg["mmta"], "mmtp_mm": agg["mmtp"],
               "frames_per_s": float(np.mean([r["frames_per_s"] for r in per_run])), "frames": T,
               "worst": {"run": agg["worst"]["run"], "d_mean_mm": agg["worst"]["d_mean"],
                         "d_max_mm": agg["worst"]["d_max"], "mmta": agg["worst"]["mmta"]},
               "d_mean_std_over_runs_mm": agg["d_mean_std_over_runs"], "per_joint_mm": agg["per_joint"],
               "per_run": per_run, "sequence": str(seq_dir), "fitness": "silhouette_edge", "seed": 3,
               "out_dir": str(res)}
    (res / "summary.json").write_text(json.dumps(summary, indent=1))
    return res, seq_dir


@pytest.fixture(scope="session")
def fake_results(tmp_path_factory) -> tuple[Path, Path]:
    """``(results_dir, sequence_dir)`` shared by the report tests (read-only: write reports elsewhere)."""
    return build_results(tmp_path_factory.mktemp("fake"))


@pytest.fixture(scope="session")
def results_builder():
    """:func:`build_results` itself, for tests that need a folder of their own (e.g. invalid frames)."""
    return build_results
