"""How far the joints triangulated from a detector's keypoints lie from the truth, with and without relabelling.

For each sequence folder given (a sequence with a detector's keypoints and a ground truth: the copies
``scripts/detected_keypoints.py`` makes under its ``--work`` folder, ``<clip>-hybrid``), the frames the tracker
uses at ``--fps`` are triangulated as the tracker triangulates them (``swarmpose.track.start.keypoint_joints``:
each view's left and right detections exchanged where that makes three or more views agree, then a weighted
DLT and again without the outlying observations, a joint that fewer than two views still see left out) and as
detected (``relabel=False``). Per sequence: the joints' median and mean 3D error (mm, joints two views or more
agree on) and the share more than 100 mm off.

Run:  .venv/bin/python scripts/detected_keypoints.py --clips cmu_135_04_kick     (makes the copies)
      .venv/bin/python scripts/triangulated_keypoints.py results/detected-keypoints/*-hybrid [--fps 20] [--json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.io.sequence import open_sequence
from swarmpose.track.start import has_keypoints, keypoint_joints


def _errors(joints: np.ndarray, truth: np.ndarray) -> dict:
    e = np.linalg.norm(joints - truth, axis=-1)
    e = e[np.isfinite(e)]
    return {"median_mm": float(np.median(e)), "mean_mm": float(e.mean()), "over_100mm": float((e > 100).mean()),
            "joints": int(e.size)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+", type=Path)
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = ap.parse_args()
    rows = []
    for path in args.sequences:
        with open_sequence(path) as seq:
            if not has_keypoints(seq) or seq.gt_joints is None:
                raise SystemExit(f"{path}: needs a detector's keypoints and a ground truth")
            frames = np.asarray(seq.subsample(args.fps), dtype=np.int64)
            truth = np.asarray(seq.gt_joints)[frames]
            rows.append({"sequence": str(path), "frames": int(len(frames)),
                         "as_detected": _errors(keypoint_joints(seq, frames, relabel=False), truth),
                         "relabelled": _errors(keypoint_joints(seq, frames), truth)})
    mean = {k: {m: float(np.mean([r[k][m] for r in rows])) for m in ("median_mm", "mean_mm", "over_100mm")}
            for k in ("as_detected", "relabelled")}
    if args.json:
        print(json.dumps({"fps": args.fps, "sequences": rows, "mean": mean}))
        return
    print("| sequence | frames | as detected: median / mean mm, > 100 mm | relabelled: median / mean mm, > 100 mm |")
    print("|---|---:|---:|---:|")
    for r in rows + [{"sequence": "mean", "frames": "", **mean}]:
        cells = [f"{r[k]['median_mm']:.1f} / {r[k]['mean_mm']:.1f}, {100 * r[k]['over_100mm']:.1f} %"
                 for k in ("as_detected", "relabelled")]
        print(f"| {Path(r['sequence']).name} | {r['frames']} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
