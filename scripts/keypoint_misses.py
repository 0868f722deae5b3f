"""Where a tracked joint is lost, what the detector said: per frame, each view's detection against the truth.

For a ``swarmpose track`` results folder of a sequence that carries a detector's keypoints and a ground truth
(``scripts/detected_keypoints.py`` makes such folders), it lists the frames where ``--joint`` is more than
``--limit`` mm off in most runs (more than half), then for each of those frames (or ``--frames A:B``) and each view: the
distance in pixels from the truth's joint, projected, to the detection as labelled and to the detection of the
other side (a swapped label), and the detection's confidence; and, for run ``--run``, the tracked joint's and
the truth's distances from the detections (each view read as labelled or swapped, whichever is nearer the truth).
A detection the keypoint term ignores (confidence under its threshold, 0.3) is marked ``-``.

Run:  .venv/bin/python scripts/detected_keypoints.py --clips cmu_16_16_walk
      .venv/bin/python scripts/keypoint_misses.py results/detected-keypoints/cmu_16_16_walk-refined-heading
          --joint r_wrist [--frames 44:70] [--run 0] [--limit 100] [--json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.io.files import read_json_object
from swarmpose.io.sequence import open_sequence
from swarmpose.joints import JOINTS15, SWAP15


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--joint", required=True, choices=JOINTS15)
    ap.add_argument("--frames", default="", help="A:B, positions in the tracked frames (default: the lost ones)")
    ap.add_argument("--run", type=int, default=0)
    ap.add_argument("--limit", type=float, default=100.0, help="mm: a joint farther off is lost")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    config = read_json_object(args.results / "config.json")
    seq = open_sequence(config["sequence"])
    if seq.marker_data is None:
        raise SystemExit(f"{config['sequence']}: the sequence carries no keypoints")
    dense, conf = seq.marker_data.to_dense()
    j, js = JOINTS15.index(args.joint), SWAP15[JOINTS15.index(args.joint)]
    runs = sorted(args.results.glob("run_*/joints.npz"))
    if not runs:
        raise SystemExit(f"{args.results}: no run_*/joints.npz")
    err = []
    for f in runs:
        with np.load(f) as z:
            err.append(np.linalg.norm(z["joints"][:, j] - z["gt_joints"][:, j], axis=-1))
    err = np.array(err)
    with np.load(runs[args.run]) as z:
        tracked, truth = z["joints"][:, j], z["gt_joints"][:, j]
    with np.load(runs[args.run].parent / "track.npz") as z:
        frames = np.asarray(z["frame_indices"])
    lost_all = np.flatnonzero((err > args.limit).sum(axis=0) > len(runs) / 2)
    if args.frames:
        a, b = (int(v) for v in args.frames.split(":"))
        positions = np.arange(a, min(b, err.shape[1]))
    else:
        positions = lost_all
    rows = []
    for t in positions:
        k = int(frames[t])
        views = []
        for c, cam in enumerate(seq.cameras):
            uv_truth = cam.project(truth[t][None])[0]
            uv_tracked = cam.project(tracked[t][None])[0]
            as_, sw = dense[k, c, j], dense[k, c, js]
            e_as, e_sw = float(np.linalg.norm(as_ - uv_truth)), float(np.linalg.norm(sw - uv_truth))
            det = as_ if e_as <= e_sw else sw
            views.append({"view": cam.name, "truth_to_detection_px": e_as, "truth_to_swapped_px": e_sw,
                          "confidence": float(conf[k, c, j]), "counted": bool(conf[k, c, j] >= MIN_CONFIDENCE),
                          "tracked_to_detection_px": float(np.linalg.norm(det - uv_tracked))})
        rows.append({"position": int(t), "frame": k, "error_mm": [float(e[t]) for e in err], "views": views})
    if args.json:
        print(json.dumps({"results": str(args.results), "joint": args.joint, "limit_mm": args.limit,
                          "lost_in_most_runs": lost_all.tolist(), "frames": rows}))
        return
    print(f"{args.joint} more than {args.limit:g} mm off in most of {len(runs)} runs at positions {lost_all.tolist()}")
    print("position: error per run (mm) | per view: truth to detection / to the other side's (px), confidence, "
          f"run {args.run}'s joint to the nearer detection (px)")
    for r in rows:
        cells = [f"{v['view']} {v['truth_to_detection_px']:4.0f}/{v['truth_to_swapped_px']:4.0f} "
                 f"c{v['confidence']:.2f}{'' if v['counted'] else '-'} t{v['tracked_to_detection_px']:4.0f}"
                 for v in r["views"]]
        print(f"{r['position']:4d}: {' '.join(f'{e:4.0f}' for e in r['error_mm'])} | " + " | ".join(cells))


if __name__ == "__main__":
    main()
