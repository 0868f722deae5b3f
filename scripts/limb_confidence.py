"""How well the per-limb confidence (swarmpose.track.confidence) tells a lost limb, on finished results folders.

For every run and frame of each folder (tracked with ground truth): each limb's silhouette disagreement, and
whether the truth finds the limb lost (its two distal joints further than LOST_MM on average). Then:
* the AUC of the disagreement (the chance that a lost limb-frame has a larger one than a kept one);
* the logistic model P(lost) = 1 / (1 + exp(-(a + b log10(d + eps)))) fitted on all folders but one and
  tested on that one, in turn (leave one clip out): its AUC, and the predicted against the observed rates;
* the coefficients fitted on all folders (what swarmpose.track.confidence.COEFFICIENTS holds) and those of the
  shipped model on each folder (its mean predicted rate beside the observed one).

Run:  .venv/bin/python scripts/limb_confidence.py results/cmu_*-refined-20fps [--json]
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
from swarmpose.track.confidence import COEFFICIENTS, LOST_MM, limb_confidence


def auc(score: np.ndarray, y: np.ndarray) -> float:
    r = rankdata(score)
    n1 = int(y.sum())
    n0 = len(y) - n1
    return float((r[y].sum() - n1 * (n1 + 1) / 2) / (n1 * n0)) if n1 and n0 else float("nan")


def fit(d: np.ndarray, y: np.ndarray, eps: float) -> np.ndarray:
    X = np.column_stack([np.ones_like(d), np.log10(d + eps)])

    def nll(w: np.ndarray) -> float:
        z = X @ w
        return float(np.sum(np.logaddexp(0.0, z) - y * z))

    return minimize(nll, np.zeros(2)).x


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    d_all, y_all, folder_of = [], [], []
    for folder in args.folders:
        res = load_results(folder)
        for run in [r.run for r in res.runs]:
            data = run_confidence(res, run)
            if data is None or "lost" not in data:
                raise SystemExit(f"{folder}: no silhouettes or no ground truth to score the confidence against")
            d_all.append(data["disagreement"].ravel())
            y_all.append(data["lost"].ravel())
            folder_of += [folder.name] * data["lost"].size
    d, y, where = np.concatenate(d_all), np.concatenate(y_all), np.array(folder_of)
    ok = np.isfinite(d)
    d, y, where = d[ok], y[ok], where[ok]
    eps = COEFFICIENTS[2]
    held = np.zeros(len(d))
    for name in np.unique(where):
        test = where == name
        a, b = fit(d[~test], y[~test], eps)
        held[test] = 1.0 / (1.0 + np.exp(-(a + b * np.log10(d[test] + eps))))
    a, b = fit(d, y, eps)
    bins = [(0.0, 0.1), (0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 1.0001)]
    calib = [{"predicted": [lo, min(hi, 1.0)], "limb_frames": int(m.sum()), "observed": float(y[m].mean()) if m.any()
              else None} for lo, hi in bins for m in [(held >= lo) & (held < hi)]]
    shipped = 1.0 - limb_confidence(d)
    per_folder = {name: {"limb_frames": int((where == name).sum()), "observed_lost": float(y[where == name].mean()),
                         "predicted_lost": float(shipped[where == name].mean()),
                         "auc": auc(d[where == name], y[where == name])} for name in np.unique(where)}
    out = {"lost_mm": LOST_MM, "limb_frames": int(len(d)), "lost_share": float(y.mean()),
           "auc_disagreement": auc(d, y), "auc_leave_one_clip_out": auc(held, y),
           "brier_leave_one_clip_out": float(np.mean((held - y) ** 2)), "brier_constant": float(y.var()),
           "fitted": {"a": float(a), "b": float(b), "eps": eps}, "shipped": {"a": COEFFICIENTS[0], "b": COEFFICIENTS[1]},
           "calibration_leave_one_clip_out": calib, "per_folder": per_folder}
    if args.json:
        print(json.dumps(out))
        return
    print(f"{out['limb_frames']} limb-frames, {100 * out['lost_share']:.0f} % lost by > {LOST_MM:.0f} mm")
    print(f"AUC: disagreement {out['auc_disagreement']:.3f}, logistic left out per clip "
          f"{out['auc_leave_one_clip_out']:.3f}; Brier {out['brier_leave_one_clip_out']:.3f} "
          f"(a constant rate: {out['brier_constant']:.3f})")
    print(f"fitted on all: a = {a:.3f}, b = {b:.3f} (shipped: a = {COEFFICIENTS[0]}, b = {COEFFICIENTS[1]})")
    print("| predicted P(lost) | limb-frames | observed lost |\n|---|---:|---:|")
    for c in calib:
        obs = "–" if c["observed"] is None else f"{c['observed']:.2f}"
        print(f"| {c['predicted'][0]:.1f}–{c['predicted'][1]:.1f} | {c['limb_frames']} | {obs} |")
    print("| folder | limb-frames | observed lost | predicted (shipped) | AUC |\n|---|---:|---:|---:|---:|")
    for name, r in per_folder.items():
        print(f"| {name} | {r['limb_frames']} | {r['observed_lost']:.2f} | {r['predicted_lost']:.2f} | {r['auc']:.3f} |")


if __name__ == "__main__":
    main()
