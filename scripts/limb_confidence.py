"""How well the per-limb confidence (swarmpose.track.confidence) tells a lost limb, on finished results folders.

For every run and frame of each folder (tracked with ground truth): each limb's silhouette disagreement, and
whether the truth finds the limb lost (its two distal joints further than LOST_MM on average). Then:
* the AUC of the disagreement (the chance that a lost limb-frame has a larger one than a kept one);
* the logistic model P(lost) = 1 / (1 + exp(-(a + b log10(d + eps)))) fitted on all folders but one and
  tested on that one, in turn (leave one clip out): its AUC, and the predicted against the observed rates;
* the coefficients fitted on all folders (what swarmpose.track.confidence.COEFFICIENTS holds) and those of the
  shipped model on each folder (its mean predicted rate beside the observed one).

With --keypoints (folders tracked on sequences that carry a detector's keypoints, e.g. those of
``scripts/detected_keypoints.py``): the keypoint disagreement (swarmpose.track.confidence.keypoint_disagreement)
beside it, and the model of COEFFICIENTS_KEYPOINTS fitted and left out per clip the same way.

Run:  .venv/bin/python scripts/limb_confidence.py results/cmu_*-refined-20fps [--keypoints] [--json]
(the folders: ``scripts/forward_backward.py`` writes them, or ``swarmpose track CLIP --algo refined --fps 20 --runs 3``)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.stats import rankdata

from swarmpose.report.confidence import run_confidence
from swarmpose.report.results import load_results
from swarmpose.track.confidence import COEFFICIENTS, COEFFICIENTS_KEYPOINTS, LOST_MM, limb_confidence


def auc(score: np.ndarray, y: np.ndarray) -> float:
    r = rankdata(score)
    n1 = int(y.sum())
    n0 = len(y) - n1
    return float((r[y].sum() - n1 * (n1 + 1) / 2) / (n1 * n0)) if n1 and n0 else float("nan")


def fit_logistic(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``[a, b, ...]`` of P(lost) = 1 / (1 + exp(-(a + X @ [b, ...]))) by maximum likelihood."""
    X = np.column_stack([np.ones(len(X)), X])

    def nll(w: np.ndarray) -> float:
        z = X @ w
        return float(np.sum(np.logaddexp(0.0, z) - y * z))

    return minimize(nll, np.zeros(X.shape[1])).x


def fit(d: np.ndarray, y: np.ndarray, eps: float) -> np.ndarray:
    return fit_logistic(np.log10(d + eps)[:, None], y)


def calibration(held: np.ndarray, y: np.ndarray) -> list[dict]:
    bins = [(0.0, 0.1), (0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 1.0001)]
    return [{"predicted": [lo, min(hi, 1.0)], "limb_frames": int(m.sum()), "observed": float(y[m].mean()) if m.any()
             else None} for lo, hi in bins for m in [(held >= lo) & (held < hi)]]


def print_calibration(calib: list[dict]) -> None:
    print("| predicted P(lost) | limb-frames | observed lost |\n|---|---:|---:|")
    for c in calib:
        obs = "–" if c["observed"] is None else f"{c['observed']:.2f}"
        print(f"| {c['predicted'][0]:.1f}–{c['predicted'][1]:.1f} | {c['limb_frames']} | {obs} |")


def keypoint_model(d: np.ndarray, k: np.ndarray, y: np.ndarray, where: np.ndarray) -> dict:
    """The model of COEFFICIENTS_KEYPOINTS (silhouette and keypoint disagreement), fitted on all groups but one and
    tested on that one in turn, and fitted on all."""
    _, _, _, eps, eps_k = COEFFICIENTS_KEYPOINTS
    X = np.column_stack([np.log10(d + eps), np.log10(k + eps_k)])
    held = np.zeros(len(d))
    for name in np.unique(where):
        test = where == name
        w = fit_logistic(X[~test], y[~test])
        held[test] = 1.0 / (1.0 + np.exp(-(w[0] + X[test] @ w[1:])))
    w = fit_logistic(X, y)
    shipped = 1.0 - limb_confidence(d, k)
    return {"auc_keypoints": auc(k, y), "auc_both_leave_one_clip_out": auc(held, y),
            "brier_both_leave_one_clip_out": float(np.mean((held - y) ** 2)),
            "fitted": {"a": float(w[0]), "b": float(w[1]), "c": float(w[2]), "eps": eps, "eps_k": eps_k},
            "shipped": dict(zip("abc", COEFFICIENTS_KEYPOINTS[:3], strict=True)), "calibration_leave_one_clip_out": calibration(held, y),
            "per_clip": {name: {"auc_silhouettes": auc(d[where == name], y[where == name]),
                                "auc_keypoints": auc(k[where == name], y[where == name]),
                                "predicted_lost": float(shipped[where == name].mean())} for name in np.unique(where)}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--keypoints", action="store_true",
                    help="folders tracked on sequences with a detector's keypoints: also the keypoint evidence and "
                         "the model with both, left out per clip (the sequence's source clip)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    d_all, k_all, y_all, folder_of = [], [], [], []
    for folder in args.folders:
        res = load_results(folder)
        group = folder.name
        if args.keypoints:
            with res.open_sequence() as seq:
                group = Path(seq.source_clip).stem if seq.source_clip else folder.name
        for run in [r.run for r in res.runs]:
            data = run_confidence(res, run)
            if data is None or "lost" not in data:
                raise SystemExit(f"{folder}: no silhouettes or no ground truth to score the confidence against")
            if args.keypoints and "keypoint_disagreement_mm" not in data:
                raise SystemExit(f"{folder}: its sequence carries no detector's keypoints")
            d_all.append(data["disagreement"].ravel())
            k_all.append(data["keypoint_disagreement_mm"].ravel() if args.keypoints else np.zeros(data["lost"].size))
            y_all.append(data["lost"].ravel())
            folder_of += [group] * data["lost"].size
    d, k, y, where = np.concatenate(d_all), np.concatenate(k_all), np.concatenate(y_all), np.array(folder_of)
    ok = np.isfinite(d) & np.isfinite(k)
    d, k, y, where = d[ok], k[ok], y[ok], where[ok]
    eps = COEFFICIENTS[2]
    held = np.zeros(len(d))
    for name in np.unique(where):
        test = where == name
        a, b = fit(d[~test], y[~test], eps)
        held[test] = 1.0 / (1.0 + np.exp(-(a + b * np.log10(d[test] + eps))))
    a, b = fit(d, y, eps)
    calib = calibration(held, y)
    shipped = 1.0 - limb_confidence(d)
    per_folder = {name: {"limb_frames": int((where == name).sum()), "observed_lost": float(y[where == name].mean()),
                         "predicted_lost": float(shipped[where == name].mean()),
                         "auc": auc(d[where == name], y[where == name])} for name in np.unique(where)}
    out = {"lost_mm": LOST_MM, "limb_frames": int(len(d)), "lost_share": float(y.mean()),
           "auc_disagreement": auc(d, y), "auc_leave_one_clip_out": auc(held, y),
           "brier_leave_one_clip_out": float(np.mean((held - y) ** 2)), "brier_constant": float(y.var()),
           "fitted": {"a": float(a), "b": float(b), "eps": eps}, "shipped": {"a": COEFFICIENTS[0], "b": COEFFICIENTS[1]},
           "calibration_leave_one_clip_out": calib, "per_folder": per_folder}
    if args.keypoints:
        out["keypoints"] = keypoint_model(d, k, y, where)
    if args.json:
        print(json.dumps(out))
        return
    print(f"{out['limb_frames']} limb-frames, {100 * out['lost_share']:.0f} % lost by > {LOST_MM:.0f} mm")
    print(f"AUC: disagreement {out['auc_disagreement']:.3f}, logistic left out per clip "
          f"{out['auc_leave_one_clip_out']:.3f}; Brier {out['brier_leave_one_clip_out']:.3f} "
          f"(a constant rate: {out['brier_constant']:.3f})")
    print(f"fitted on all: a = {a:.3f}, b = {b:.3f} (shipped: a = {COEFFICIENTS[0]}, b = {COEFFICIENTS[1]})")
    print_calibration(calib)
    print("| folder | limb-frames | observed lost | predicted (shipped) | AUC |\n|---|---:|---:|---:|---:|")
    for name, r in per_folder.items():
        print(f"| {name} | {r['limb_frames']} | {r['observed_lost']:.2f} | {r['predicted_lost']:.2f} | {r['auc']:.3f} |")
    if args.keypoints:
        kp = out["keypoints"]
        f = kp["fitted"]
        print(f"With the keypoints: AUC of the keypoint disagreement {kp['auc_keypoints']:.3f}; both, left out per "
              f"clip {kp['auc_both_leave_one_clip_out']:.3f}, Brier {kp['brier_both_leave_one_clip_out']:.3f}; "
              f"fitted on all: a = {f['a']:.3f}, b = {f['b']:.3f}, c = {f['c']:.3f}")
        print_calibration(kp["calibration_leave_one_clip_out"])
        print("| clip | AUC silhouettes | AUC keypoints | predicted (shipped) |\n|---|---:|---:|---:|")
        for name, r in kp["per_clip"].items():
            print(f"| {name} | {r['auc_silhouettes']:.3f} | {r['auc_keypoints']:.3f} | {r['predicted_lost']:.2f} |")


if __name__ == "__main__":
    main()
