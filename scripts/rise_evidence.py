"""How well each cue predicts the body's rise from one tracked frame to the next, against the ground truth.

The default tracker moves its predicted root height by the body's rise since the frame before. Two cues are
compared here with the truth's pelvis height step, on sequences with a ground truth and a detector's keypoints:

* ``silhouettes``: the rise of the silhouettes' triangulated centre, less the dead zone
  (:data:`swarmpose.track.step.RISE_DEAD_ZONE_MM`) towards 0: ``--variant height=silhouettes``;
* ``keypoints``: the mean rise of the hips' and shoulders' triangulated keypoints
  (:data:`swarmpose.track.step.RISE_JOINTS`; all views, the tracker's triangulation); where a frame misses one of
  them, the silhouettes' rise: ``--variant height=keypoints``, the default where a sequence has keypoints.

Per sequence: the mean absolute step of the truth's pelvis height (what predicting no rise misses), and each cue's
mean absolute error, in mm per tracked frame.

Run:  .venv/bin/python scripts/rise_evidence.py work/cmu_16_35_jog-keypoints [more sequences] [--fps 20] [--json]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from swarmpose.io.sequence import open_sequence
from swarmpose.joints import JOINT_INDEX
from swarmpose.track.start import has_keypoints, keypoint_joints, silhouette_centre
from swarmpose.track.step import RISE_DEAD_ZONE_MM, RISE_JOINTS


def rise_errors(path: str, fps: float) -> dict:
    """The truth's mean pelvis step and each cue's mean error (mm per frame) on one sequence."""
    seq = open_sequence(path)
    try:
        if seq.gt_joints is None or not has_keypoints(seq):
            raise SystemExit(f"{path}: needs a ground truth and a detector's keypoints")
        frames = seq.subsample(fps)
        truth = np.asarray(seq.gt_joints, dtype=np.float64)[frames][:, JOINT_INDEX["pelvis"], 2]
        views = list(range(seq.n_views))
        centres = [silhouette_centre(seq, int(k), views) for k in frames]
        centres = [np.full(3, np.nan) if c is None else c for c in centres]
        kp = keypoint_joints(seq, frames, views=views)
    finally:
        seq.close()
    step = np.diff(truth)
    centre_rise = np.nan_to_num(np.diff(np.asarray(centres)[:, 2]))
    sil = np.sign(centre_rise) * np.maximum(0.0, np.abs(centre_rise) - RISE_DEAD_ZONE_MM)
    trunk = kp[:, list(RISE_JOINTS), 2]
    kp_rise = np.diff(trunk, axis=0).mean(axis=1)
    kp_cue = np.where(np.isfinite(kp_rise), kp_rise, sil)
    return {"sequence": path, "frames": len(frames), "truth_step_mm": float(np.mean(np.abs(step))),
            "silhouettes_error_mm": float(np.mean(np.abs(step - sil))),
            "keypoints_error_mm": float(np.mean(np.abs(step - kp_cue))),
            "keypoint_steps_share": float(np.mean(np.isfinite(kp_rise)))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+")
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--json", action="store_true", help="one JSON object")
    args = ap.parse_args()
    rows = [rise_errors(p, args.fps) for p in args.sequences]
    if args.json:
        print(json.dumps({"fps": args.fps, "sequences": rows}))
        return
    print(f"{'sequence':48s} frames  truth step  silhouettes  keypoints  (mm per frame; keypoint steps)")
    for r in rows:
        print(f"{r['sequence'][-48:]:48s} {r['frames']:6d} {r['truth_step_mm']:10.1f} {r['silhouettes_error_mm']:12.1f}"
              f" {r['keypoints_error_mm']:10.1f}  ({100 * r['keypoint_steps_share']:.0f} %)")


if __name__ == "__main__":
    main()
