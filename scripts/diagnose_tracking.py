"""Separate what limits a tracking error: the observations/fitness, the per-frame search, or drift.

Two measurements (issue 6 investigation; numbers quoted in its note):

``floor SEQ``  -- per sampled frame, with that frame's fitness bound:
    * ``f_truth``/``D_truth``: the fitness and 3D error D of the IK pose (the best model fit to the truth);
    * ``D_search60``/``D_search20``: one SPPSO search (1000 evaluations, sigma for 60 / 20 fps) started AT
      the IK pose -- the error a single frame's search adds even with a perfect prediction;
    * ``D_fitness_max``: the best pose found near the truth by a long local search (``--rounds`` SPPSO
      searches with the 240-fps sigma, each from the best so far, 1000 evaluations each; the IK pose kept
      when nothing beats it). Its distance from the truth is the error the fitness itself prefers -- an
      "observation floor" that no search can go below on these images (the IK floor ignores the images).

``oracle SEQ`` -- track with ideal observations in place of the image-derived ones, to split the error
    between the search and the mismatch of model and images. ``--silhouettes model`` replaces each view's
    observed silhouette by the tracker's own cone model rendered at the IK pose (the best model fit to the
    truth); ``--edges model`` replaces the edge map by the model's own edges at the IK pose (every visible
    cone side line and the torso's top, as the edge fitness samples them, blurred like ``edge_map``);
    ``--edges outline`` by the outline of the model's silhouette only (no inner edges); ``--edges
    observed-outline`` by the outline of the *observed* silhouette (the observation body's shape, no inner
    edges, no shading or texture edges); ``real`` keeps the image-derived observation. With both ``model``
    the images show exactly what the model expects, so the remaining error is the search's own (1000 evaluations, sigma, ambiguities of silhouettes and edges).

``drift RESULTS_DIR`` -- for a finished ``swarmpose track`` results folder: mean |error| of every
    parameter against the IK fit (degrees / mm), largest first, and the correlation of the root heading
    error with the spine-twist error (a pelvis that turns while the spine twists back keeps the shoulders
    in place and is barely visible in the fitness).

Run:  .venv/bin/python scripts/diagnose_tracking.py floor cache/sequences/<walk> [--rounds 20] [--json]
          [--terms silhouette|edge] [--features edge_sigma_px=4]
      .venv/bin/python scripts/diagnose_tracking.py oracle cache/sequences/<walk> --fps 60 --runs 5
          [--silhouettes model|real] [--edges model|outline|observed-outline|real] [--terms silhouette]
          [--fitness-options edge_top=false] [--algo sppso]
      .venv/bin/python scripts/diagnose_tracking.py drift results/<run folder>
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def _d(model, x: np.ndarray, gt: np.ndarray) -> float:
    return float(np.linalg.norm(model.joints15(x[None])[0] - gt, axis=1).mean())


def floor(seq_path: str, frames: list[int], rounds: int, options: dict, seed: int,
          features: str = "") -> list[dict]:
    from swarmpose import optim
    from swarmpose.body.priors import HardPriors
    from swarmpose.features import parse_feature_options
    from swarmpose.io.sequence import open_sequence
    from swarmpose.track.observation import frame_observation
    from swarmpose.track.tracker import TrackConfig, _make_fitness, prepare_track

    setup = prepare_track(seq_path, TrackConfig(algo="sppso", fps=60.0), None)
    model, fit = setup.model, _make_fitness(setup)
    constraint = HardPriors(model).valid
    seq = open_sequence(seq_path)
    backgrounds = seq.backgrounds()
    feature_options = parse_feature_options(features)

    def search(fps: float, x0: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        opt = optim.get("sppso", model=model, fps=fps).start(x0, rng, constraint=constraint)
        while not opt.done:
            poses = opt.ask()
            opt.tell(fit.evaluate(poses, {**opt.fitness_options, **options}))
        return np.array(opt.best.x), float(opt.best.score)

    rows = []
    try:
        for i in frames:
            fit.bind(frame_observation(seq, int(setup.frame_indices[i]), "silhouette_edge", 1, backgrounds,
                                        feature_options))
            xt, gt = setup.ik_params[i], setup.gt_joints[i]
            ft = float(fit.evaluate(xt[None], options)[0])
            rng = np.random.default_rng([seed, i])
            x60, f60 = search(60.0, xt, rng)
            x20, f20 = search(20.0, xt, rng)
            xb, fb = (x60, f60) if f60 > ft else (xt, ft)
            for _ in range(rounds):
                x, f = search(240.0, xb, rng)
                if f > fb:
                    xb, fb = x, f
            rows.append({"frame": int(setup.frame_indices[i]), "f_truth": ft, "D_truth": _d(model, xt, gt),
                         "f_search60": f60, "D_search60": _d(model, x60, gt), "f_search20": f20,
                         "D_search20": _d(model, x20, gt), "f_fitness_max": fb,
                         "D_fitness_max": _d(model, xb, gt)})
    finally:
        seq.close()
    return rows


def _model_edge_map(model, pose: np.ndarray, camera, shape: tuple[int, int], mode: str) -> np.ndarray:
    """The edge map the model itself would produce at ``pose`` (``mode`` "model" or "outline")."""
    from swarmpose.features import blur_edges
    from swarmpose.render import render_silhouette
    from swarmpose.render.reference import edge_samples_reference, reference_geometry

    if mode == "outline":
        return _outline_edge_map(render_silhouette(model, pose, camera))
    geom = reference_geometry(model, pose[None], [camera])
    n_cones = geom.cones.n_vertices.shape[2]
    xy, _, _, visible = edge_samples_reference(geom, 0, 0, np.ones(n_cones, bool), 0, 0.5)
    q = np.round(xy[visible]).astype(int)
    inside = (q[:, 0] >= 0) & (q[:, 0] < shape[1]) & (q[:, 1] >= 0) & (q[:, 1] < shape[0])
    binary = np.zeros(shape, np.uint8)
    binary[q[inside, 1], q[inside, 0]] = 1
    return blur_edges(binary)  # as features.edge_map does with the images' edges


def _outline_edge_map(mask: np.ndarray) -> np.ndarray:
    """The blurred outline of a binary silhouette, as ``features.edge_map`` blurs the images' edges."""
    import cv2

    from swarmpose.features import blur_edges

    return blur_edges(cv2.morphologyEx(np.asarray(mask, np.uint8), cv2.MORPH_GRADIENT, np.ones((2, 2), np.uint8)))


def _body_frame_bias(gt: np.ndarray, est: np.ndarray, joint: str) -> list[float]:
    """Mean signed error of one joint (mm) along the subject's forward, left and up directions.

    Left is the horizontal right-to-left hip direction of the truth, up is world +z, forward = left x up.
    A systematic offset (the same sign in every run) points at a model/image mismatch, not at the search.
    """
    from swarmpose.joints import JOINT_INDEX as J

    left = gt[:, J["l_hip"]] - gt[:, J["r_hip"]]
    left[:, 2] = 0.0
    left /= np.linalg.norm(left, axis=1, keepdims=True)
    forward = np.cross(left, [0.0, 0.0, 1.0])
    e = est[:, J[joint]] - gt[:, J[joint]]
    return [round(float(np.nanmean(np.sum(e * d, axis=1))), 1) for d in (forward, left)] + \
        [round(float(np.nanmean(e[:, 2])), 1)]


def oracle(seq_path: str, fps: float, runs: int, silhouettes: str, edges: str, algo: str, terms: str,
           seed: int, fitness_options: str = "") -> dict:
    import dataclasses

    from swarmpose.render import render_silhouette
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    options = ",".join(o for o in (f"terms={terms}" if terms else "", fitness_options) if o)
    config = TrackConfig(algo=algo, fps=fps, seed=seed, fitness="silhouette_edge", fitness_options=options)
    setup = prepare_track(seq_path, config, None)
    ik = {int(k): setup.ik_params[i] for i, k in enumerate(setup.frame_indices)}

    def observe(k: int, frame):
        pose, changes = ik[k], {}
        if silhouettes == "model":
            changes["silhouettes"] = np.stack([render_silhouette(setup.model, pose, cam)
                                               for cam in frame.cameras]).astype(frame.silhouettes.dtype)
        if edges == "observed-outline":
            # the image-derived silhouettes, before any replacement
            changes["edges"] = np.stack([_outline_edge_map(s) for s in frame.silhouettes]).astype(np.float32)
        elif edges != "real":
            changes["edges"] = np.stack([_model_edge_map(setup.model, pose, cam, frame.edges.shape[1:], edges)
                                         for cam in frame.cameras]).astype(np.float32)
        return dataclasses.replace(frame, **changes) if changes else frame

    results = [run_tracker(setup, r, None, observe=observe) for r in range(runs)]
    per_run = [r.errors for r in results]
    return {"sequence": seq_path, "algo": algo, "fps": fps, "runs": runs, "silhouettes": silhouettes,
            "edges": edges, "terms": terms or "silhouette+edge", "fitness_options": fitness_options, "seed": seed,
            "d_mean_mm": float(np.mean([e["d_mean"] for e in per_run])),
            "d_max_mm": float(np.mean([e["d_max"] for e in per_run])),
            "mmta": float(np.mean([e["mmta"] for e in per_run])),
            "ik_floor_mm": setup.ik_floor_mm,
            "d_mean_per_run_mm": [round(float(e["d_mean"]), 2) for e in per_run],
            "pelvis_bias_fwd_left_up_mm": [_body_frame_bias(setup.gt_joints, r.joints, "pelvis") for r in results],
            "thorax_bias_fwd_left_up_mm": [_body_frame_bias(setup.gt_joints, r.joints, "thorax") for r in results]}


def drift(results: Path) -> dict:
    ik = np.load(results / "ik.npz", allow_pickle=False)["params"]
    runs = sorted(results.glob("run_*/track.npz"))
    if not runs:
        raise SystemExit(f"{results}: no run_*/track.npz (is this a finished `swarmpose track` folder?)")
    err, corr = [], []
    for f in runs:
        with np.load(f, allow_pickle=False) as z:
            names = [str(n) for n in z["param_names"]]
            d = z["params"] - ik[: len(z["params"])]
        err.append(np.abs(d).mean(axis=0))
        corr.append(float(np.corrcoef(d[:, names.index("pelvis_rz")], d[:, names.index("spine_twist")])[0, 1]))
    mean = np.mean(err, axis=0)
    scale = np.array([1.0 if n.endswith(("_tx", "_ty", "_tz")) else 180.0 / np.pi for n in names])
    order = np.argsort(-(mean * scale))
    return {"runs": len(runs),
            "mean_abs_error": {names[j]: round(float(mean[j] * scale[j]), 2) for j in order},
            "heading_vs_spine_twist_corr": [round(c, 3) for c in corr],
            "heading_error_deg_per_run": [round(float(np.degrees(e[names.index("pelvis_rz")])), 2) for e in err]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("floor")
    a.add_argument("sequence")
    a.add_argument("--frames", default="0,40,80,120,160,200,240", help="frame numbers at 60 fps")
    a.add_argument("--rounds", type=int, default=20)
    a.add_argument("--terms", default="", help="fitness terms, e.g. 'silhouette' (default: f_s + f_e)")
    a.add_argument("--features", default="", help="image feature settings as `swarmpose track --features`")
    a.add_argument("--seed", type=int, default=0)
    a.add_argument("--json", action="store_true")
    b = sub.add_parser("drift")
    b.add_argument("results", type=Path)
    o = sub.add_parser("oracle")
    o.add_argument("sequence")
    o.add_argument("--fps", type=float, default=60.0)
    o.add_argument("--runs", type=int, default=5)
    o.add_argument("--silhouettes", choices=("model", "real"), default="model")
    o.add_argument("--edges", choices=("model", "outline", "observed-outline", "real"), default="model")
    o.add_argument("--algo", default="sppso")
    o.add_argument("--terms", default="", help="fitness terms, e.g. 'silhouette' (default: f_s + f_e)")
    o.add_argument("--fitness-options", default="", help="more fitness options, e.g. 'edge_top=false'")
    o.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.cmd == "drift":
        print(json.dumps(drift(args.results), indent=1))
        return
    if args.cmd == "oracle":
        print(json.dumps(oracle(args.sequence, args.fps, args.runs, args.silhouettes, args.edges, args.algo,
                                args.terms, args.seed, args.fitness_options), indent=1))
        return
    options = {"terms": args.terms} if args.terms else {}
    rows = floor(args.sequence, [int(s) for s in args.frames.split(",")], args.rounds, options, args.seed,
                 args.features)
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k != "frame"}
    if args.json:
        print(json.dumps({"frames": rows, "mean": mean}))
        return
    keys = list(rows[0])
    print(" ".join(f"{k:>14}" for k in keys))
    for r in rows + [{"frame": "mean", **mean}]:
        print(" ".join(f"{r[k]:>14.4g}" if not isinstance(r[k], str) else f"{r[k]:>14}" for k in keys))


if __name__ == "__main__":
    main()
