"""Where a tracked joint misses by more than a limit: does the evidence prefer the truth's limb, or the tracked one?

For a ``swarmpose track`` results folder with a ground truth, every run's joint-frames beyond ``--limit`` mm
(wrists, elbows, knees and ankles: the joints one limb's parameters move) are scored with the frame's fitness
as the tracker scores its last choice of the frame (the refinement's options with the run's own over them, the
detector's elbows where the run measured them): the tracked pose against the same pose with that limb's
parameters taken from the IK pose (the model's best fit to the truth). Beside the whole fitness, each of its
terms alone: the silhouette, the edges, the two together (the image) and, on a sequence with a detector's
keypoints, the keypoint term (the whole less the image). Where the fitness scores the tracked limb higher, no
search can find the truth's: the evidence itself points elsewhere; where it scores the truth's limb higher, the
search missed it.

Per clip: the misses counted, the share where each term scores the truth's limb higher, the median score
difference (truth's limb less tracked), how far the truth's limb puts the joint (it moves the limb only, on
the tracked trunk), and the share where the whole IK pose scores higher than the tracked one.

``--polish N``: on each frame with a miss, a pattern search of N evaluations over the whole pose (the
refinement's step and options, the run's hard priors) from the tracked pose and from the IK pose: where the
fitness is the refinement's, do the two basins' tops differ, and where does each leave the missed joint? Where the
truth's basin ends higher and near the truth a search could find it; where the two end within a few thousandths of
each other, or the truth's drifts off, the evidence cannot tell them apart.

``--limb-polish N``: on each frame with a miss, a pattern search of N evaluations over the missed limb's parameters
alone (the rest of the tracked pose held, as the tracker's limb searches hold it) from the tracked limb and from the
truth's limb: do the two tops differ, and would the tracker's silhouette guard let the truth's replace the tracked
one (its silhouette overlap term not lower)? Where the limb's own tops lie within a few thousandths, a limb search
cannot tell the truth's place from the tracked one.

Run:  .venv/bin/python scripts/miss_evidence.py results/detected-keypoints/cmu_131_01_walk-refined-heading
          [more folders] [--runs 3] [--limit 100] [--polish 1500] [--limb-polish 200] [--json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.features import parse_feature_options
from swarmpose.fitness.base import parse_fitness_options
from swarmpose.io.files import read_json_object
from swarmpose.io.sequence import open_sequence
from swarmpose.joints import JOINTS15
from swarmpose.optim.base import optimize
from swarmpose.optim.refine import PatternSearch
from swarmpose.track.observation import frame_observation
from swarmpose.track.runner import recorded_config
from swarmpose.track.start import has_keypoints, tracked_views
from swarmpose.track.tracker import _make_fitness, prepare_track, tracker_priors

#: The joints one limb's parameters move, and that limb's parameter group.
LIMB_OF = {"l_elbow": "left_arm", "l_wrist": "left_arm", "r_elbow": "right_arm", "r_wrist": "right_arm",
           "l_knee": "left_leg", "l_ankle": "left_leg", "r_knee": "right_leg", "r_ankle": "right_leg"}
TERMS = ("fitness", "silhouette", "edge", "image", "keypoints")


def polished(fitness, model, algo, constraint, x: np.ndarray, options: dict, budget: int,
             params: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """The top of ``x``'s basin: a pattern search of ``budget`` evaluations over the whole pose (or ``params``
    alone) with the refinement's step (``refine_step`` of the search's spread) under the run's hard priors."""
    step = algo.refine_step * np.asarray(algo.sigma, dtype=np.float64)
    if params is not None:
        step = np.where(np.isin(np.arange(model.n_params), params), step, 0.0)
    ps = PatternSearch(np.asarray(x, dtype=np.float64), step, budget, lower=model.lower, upper=model.upper,
                       constraint=constraint)
    found = optimize(ps, lambda poses: fitness.evaluate(poses, options))
    return np.asarray(found.x), float(found.score)


def limb_tops(fitness, model, algo, constraint, x: np.ndarray, x_truth: np.ndarray, group: np.ndarray,
              options: dict, budget: int) -> dict:
    """The tops of the tracked limb's basin and of the truth's, each a pattern search of ``budget`` evaluations over
    the limb's parameters ``group`` alone from ``x`` and ``x_truth``: their scores and silhouette overlap terms."""
    tops = [polished(fitness, model, algo, constraint, start, options, budget, group) for start in (x, x_truth)]
    pair = np.stack([tops[0][0], tops[1][0]])
    sil = fitness.evaluate(pair, {**options, "keypoints": 0.0, "terms": "silhouette"})
    return {"poses": pair, "tracked_score": tops[0][1], "truth_score": tops[1][1],
            "silhouette_difference": float(sil[1] - sil[0])}


def tops_summary(d: np.ndarray, tops: list[dict], evaluations: int) -> dict:
    """The truth's top less the tracked one's, ``d``, summed up, beside the missed joints' errors at both tops."""
    return {"evaluations": evaluations, "truth_higher": float(np.mean(d > 0)), "median_difference": float(np.median(d)),
            "median_abs_difference": float(np.median(np.abs(d))),
            "truth_error_mm_median": float(np.median([t["truth_error_mm"] for t in tops])),
            "tracked_error_mm_median": float(np.median([t["tracked_error_mm"] for t in tops]))}


def clip_evidence(results: Path, runs: int, limit: float, polish: int = 0, limb_polish: int = 0) -> dict:
    config, cfg = recorded_config(results)
    setup = prepare_track(config["sequence"], cfg, results)
    if not setup.has_ground_truth:
        raise SystemExit(f"{results}: the sequence has no ground truth")
    model, fitness = setup.model, _make_fitness(setup)
    algo = cfg.optimizer(model)
    constraint = tracker_priors(model, algo).valid
    truth_tops: dict[tuple, tuple[np.ndarray, float]] = {}  # (position, options) -> the truth's basin's top
    options = {**getattr(algo, "refine_options", {}), **(getattr(algo, "frame_options", None) or {}),
               **parse_fitness_options(cfg.fitness_options)}
    run_dirs = sorted(results.glob("run_*/track.npz"))[:runs]
    if not run_dirs:
        raise SystemExit(f"{results}: no run_*/track.npz")
    seq = open_sequence(config["sequence"])
    try:
        views = tracked_views(seq, cfg.views)
        keypoints = seq.marker_data.to_dense() if has_keypoints(seq) else None
        if keypoints is None:
            options.pop("keypoint_elbow", None)
            options["keypoints"] = 0.0
        backgrounds = seq.backgrounds()
        feature_options = parse_feature_options(cfg.feature_options)
        rows = []
        for f in run_dirs:
            run_options = dict(options)
            if run_options.get("keypoint_elbow") == "auto":
                run_options["keypoint_elbow"] = read_json_object(f.parent / "summary.json")["keypoint_elbow"]
            with np.load(f) as z:
                params = np.asarray(z["params"])
            err = np.linalg.norm(model.joints15(params) - setup.gt_joints, axis=-1)
            for t in range(len(params)):
                missed = [JOINTS15[j] for j in np.flatnonzero(err[t] > limit) if JOINTS15[j] in LIMB_OF]
                if not missed:
                    continue
                fitness.bind(frame_observation(seq, int(setup.frame_indices[t]), cfg.fitness_kind, cfg.downsample,
                                               backgrounds, feature_options, views, keypoints))
                tops = None
                if polish > 0:  # the tops of the tracked pose's basin and of the truth's (the same for every run)
                    key = (t, tuple(sorted(run_options.items())))
                    if key not in truth_tops:
                        truth_tops[key] = polished(fitness, model, algo, constraint, setup.ik_params[t], run_options,
                                                   polish)
                    tops = [polished(fitness, model, algo, constraint, params[t], run_options, polish),
                            truth_tops[key]]
                    top_err = np.linalg.norm(model.joints15(np.stack([tops[0][0], tops[1][0]]))
                                             - setup.gt_joints[t][None], axis=-1)
                limb_cache: dict[str, dict] = {}
                for joint in missed:
                    x = params[t].copy()
                    x_truth = x.copy()
                    group = model.group(LIMB_OF[joint])
                    x_truth[group] = setup.ik_params[t][group]
                    pair = np.stack([x, x_truth])
                    tracked, limb, whole = fitness.evaluate(np.stack([x, x_truth, setup.ik_params[t]]), run_options)
                    score = {"fitness": np.array([tracked, limb])}
                    image = {**run_options, "keypoints": 0.0}
                    score["image"] = fitness.evaluate(pair, image)
                    score["silhouette"] = fitness.evaluate(pair, {**image, "terms": "silhouette"})
                    score["edge"] = fitness.evaluate(pair, {**image, "terms": "edge"})
                    if keypoints is not None:
                        score["keypoints"] = score["fitness"] - score["image"]
                    j = JOINTS15.index(joint)
                    moved = float(np.linalg.norm(model.joints15(x_truth[None])[0, j] - setup.gt_joints[t, j]))
                    rows.append({"run": f.parent.name, "position": t, "joint": joint, "error_mm": float(err[t, j]),
                                 "truth_limb_error_mm": moved,
                                 "truth_limb_minus_tracked": {k: float(v[1] - v[0]) for k, v in score.items()},
                                 "truth_pose_minus_tracked": float(whole - tracked)})
                    if limb_polish > 0:
                        if LIMB_OF[joint] not in limb_cache:
                            limb_cache[LIMB_OF[joint]] = limb_tops(fitness, model, algo, constraint, x, x_truth, group,
                                                                   run_options, limb_polish)
                        lt = limb_cache[LIMB_OF[joint]]
                        e = np.linalg.norm(model.joints15(lt["poses"])[:, j] - setup.gt_joints[t, j][None], axis=-1)
                        rows[-1]["limb_polished"] = {"limb": LIMB_OF[joint], "tracked_score": lt["tracked_score"],
                                                     "truth_score": lt["truth_score"],
                                                     "silhouette_difference": lt["silhouette_difference"],
                                                     "tracked_error_mm": float(e[0]), "truth_error_mm": float(e[1])}
                    if tops is not None:
                        rows[-1]["polished"] = {"tracked_score": tops[0][1], "truth_score": tops[1][1],
                                                "tracked_error_mm": float(top_err[0, j]),
                                                "truth_error_mm": float(top_err[1, j])}
    finally:
        seq.close()
    out = {"results": str(results), "runs": len(run_dirs), "limit_mm": limit, "misses": len(rows)}
    if rows:
        out["truth_limb_error_mm_median"] = float(np.median([r["truth_limb_error_mm"] for r in rows]))
        out["truth_pose_higher"] = float(np.mean([r["truth_pose_minus_tracked"] > 0 for r in rows]))
        for term in TERMS:
            d = np.array([r["truth_limb_minus_tracked"][term] for r in rows if term in r["truth_limb_minus_tracked"]])
            if len(d):
                out[term] = {"truth_higher": float(np.mean(d > 0)), "median_difference": float(np.median(d))}
        if polish > 0:
            d = np.array([r["polished"]["truth_score"] - r["polished"]["tracked_score"] for r in rows])
            # per frame, the best top any run's basin reached against the truth's: a run that stopped below its
            # basin's top makes the truth look better than the evidence says
            best: dict[int, list[float]] = {}
            for r in rows:
                b = best.setdefault(r["position"], [-np.inf, r["polished"]["truth_score"]])
                b[0] = max(b[0], r["polished"]["tracked_score"])
            frames = {t: {"best_tracked_top": b[0], "truth_top": b[1], "difference": b[1] - b[0]}
                      for t, b in sorted(best.items())}
            out["polished_frames"] = frames
            out["polished"] = tops_summary(d, [r["polished"] for r in rows], polish)
        if limb_polish > 0:  # one entry per (run, frame, limb): a limb with two missed joints counts once
            limbs = {(r["run"], r["position"], r["limb_polished"]["limb"]): r["limb_polished"] for r in rows}
            d = np.array([v["truth_score"] - v["tracked_score"] for v in limbs.values()])
            guard = np.array([v["silhouette_difference"] >= 0 for v in limbs.values()])
            out["limb_polished"] = {**tops_summary(d, [r["limb_polished"] for r in rows], limb_polish),
                                    "limb_frames": len(limbs), "truth_higher_and_guard": float(np.mean((d > 0) & guard))}
    out["rows"] = rows
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, nargs="+")
    ap.add_argument("--runs", type=int, default=3, help="the first N runs of each folder")
    ap.add_argument("--limit", type=float, default=100.0, help="mm: a joint farther off is a miss")
    ap.add_argument("--polish", type=int, default=0, metavar="N",
                    help="pattern-search evaluations from the tracked and the IK pose on each frame with a miss")
    ap.add_argument("--limb-polish", type=int, default=0, metavar="N",
                    help="pattern-search evaluations over the missed limb alone from the tracked and the truth's limb")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    clips = [clip_evidence(r, args.runs, args.limit, args.polish, args.limb_polish) for r in args.results]
    if args.json:
        print(json.dumps({"clips": clips}))
        return
    print(f"{'results':40s} {'misses':>6s} {'truth limb':>11s} {'truth pose':>10s}  "
          + "  ".join(f"{t:>16s}" for t in TERMS))
    print(f"{'':40s} {'':>6s} {'mm (median)':>11s} {'higher':>10s}  " + "  ".join(f"{'higher · median':>16s}" for _ in TERMS))
    for c in clips:
        if not c["misses"]:
            print(f"{Path(c['results']).name:40s} {0:6d}")
            continue
        cells = [f"{100 * c[t]['truth_higher']:5.0f} % {c[t]['median_difference']:+8.4f}" if t in c else f"{'-':>16s}"
                 for t in TERMS]
        print(f"{Path(c['results']).name:40s} {c['misses']:6d} {c['truth_limb_error_mm_median']:11.0f} "
              f"{100 * c['truth_pose_higher']:8.0f} %  " + "  ".join(cells))
        if "polished" in c:
            p = c["polished"]
            print(f"{'':40s} polished ({p['evaluations']} evaluations from each): the truth's basin higher "
                  f"{100 * p['truth_higher']:.0f} %, by {p['median_difference']:+.4f} (median; |.| "
                  f"{p['median_abs_difference']:.4f}); the missed joint then {p['truth_error_mm_median']:.0f} mm off "
                  f"from the truth, {p['tracked_error_mm_median']:.0f} mm from the tracked pose")
            diffs = " ".join(f"{t}: {v['difference']:+.4f}" for t, v in c["polished_frames"].items())
            print(f"{'':40s} per frame, the truth's top less the best run's: {diffs}")
        if "limb_polished" in c:
            p = c["limb_polished"]
            print(f"{'':40s} the limb alone ({p['evaluations']} evaluations from each), {p['limb_frames']} missed limbs: "
                  f"the truth's limb's top higher {100 * p['truth_higher']:.0f} % (with the silhouette term not lower "
                  f"{100 * p['truth_higher_and_guard']:.0f} %), by {p['median_difference']:+.4f} (median; |.| "
                  f"{p['median_abs_difference']:.4f}); the missed joint then {p['truth_error_mm_median']:.0f} mm off "
                  f"from the truth, {p['tracked_error_mm_median']:.0f} mm from the tracked limb")


if __name__ == "__main__":
    main()
