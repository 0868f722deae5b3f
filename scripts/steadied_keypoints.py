"""A detector's keypoints relabelled across views and steadied in time, as a sequence copy to track, and how far they lie.

For a sequence with a detector's keypoints and a ground truth (the ``<clip>-keypoints`` copies
``scripts/detected_keypoints.py`` makes), it writes ``--out``: the same sequence (its other files linked or copied)
whose keypoints are

* ``--relabel``: each view's left and right detections of a joint exchanged where that makes the views agree
  (:func:`swarmpose.triangulation.relabel_pairs`, as the tracker does before it triangulates; detections from
  confidence ``--floor`` on take part; the confidences go with their detections), and/or
* ``--median K``: each view's joint moved to the median of its detections (confidence >= ``--floor``) over the
  ``2 K + 1`` frames around it, at the sequence's own rate (K = 3 at 60 fps: 50 ms either side),

and prints, for the frames tracked at ``--fps``, how far the counted detections (confidence >= 0.3) of the limbs'
joints and of the wrists lie from the truth, projected (each view read as detected or with its whole body's left
and right exchanged, whichever is nearer, as the keypoint term reads it): the median, and the shares beyond 25 and
50 px, before and after; and how long, over every frame, a view's wrist stays more than 25 px off as detected. Track the copy with ``swarmpose track OUT --fps 20 --runs 3``.

Run:  .venv/bin/python scripts/steadied_keypoints.py results/detected-keypoints/cmu_16_16_walk-keypoints
          --out results/detected-keypoints/cmu_16_16_walk-steadied [--relabel] [--median 3] [--floor 0.05] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import warnings
from pathlib import Path

import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.io.sequence import open_sequence
from swarmpose.joints import JOINT_INDEX, SWAP15
from swarmpose.track.start import LEFT_RIGHT_PAIRS
from swarmpose.triangulation import relabel_pairs, reproject

LIMBS = [JOINT_INDEX[f"{s}_{j}"] for s in "lr" for j in ("elbow", "wrist", "knee", "ankle")]
WRISTS = [JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"]]


def relabelled(cameras: list, kp: np.ndarray, conf: np.ndarray, floor: float,
               threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """``kp (T, C, 15, 2)`` and ``conf (T, C, 15)`` with each view's left/right pairs exchanged where the views agree."""
    w = np.where(np.isfinite(kp).all(-1) & (conf >= floor), conf, 0.0)
    swapped = np.zeros(conf.shape, dtype=bool)
    out, _ = relabel_pairs(cameras, kp, w, LEFT_RIGHT_PAIRS, threshold)
    for a, b in LEFT_RIGHT_PAIRS:  # which detections moved: the confidences follow them
        moved = ~np.isclose(out[..., a, :], kp[..., a, :]).all(-1) & np.isfinite(kp[..., a, :]).all(-1)
        swapped[..., a] = swapped[..., b] = moved
    perm = np.array(SWAP15)
    return out, np.where(swapped, conf[..., perm], conf)


def steadied(kp: np.ndarray, conf: np.ndarray, k: int, floor: float) -> np.ndarray:
    """Each view's joint at the median of its detections (confidence >= ``floor``) over frames ``t - k .. t + k``."""
    use = np.where((conf >= floor)[..., None], kp, np.nan)
    out = kp.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window without any detection: the frame's own stays
        for t in range(kp.shape[0]):
            med = np.nanmedian(use[max(0, t - k):t + k + 1], axis=0)
            out[t] = np.where(np.isfinite(med) & np.isfinite(kp[t]), med, kp[t])
    return out


def _pixel_errors(kp: np.ndarray, truth_px: np.ndarray) -> np.ndarray:
    """``(..., C, 15)`` px from the truth, each view read as detected or with its whole body's left and right
    exchanged, whichever is nearer (as the keypoint term reads it)."""
    e0 = np.linalg.norm(kp - truth_px, axis=-1)
    e1 = np.linalg.norm(kp[..., list(SWAP15), :] - truth_px, axis=-1)
    return np.where((np.nansum(e1, axis=-1) < np.nansum(e0, axis=-1))[..., None], e1, e0)


def errors(kp: np.ndarray, conf: np.ndarray, truth_px: np.ndarray) -> dict:
    """Median and shares beyond 25 / 50 px of the counted limb and wrist detections, each view's labelling as
    detected or mirrored, whichever is nearer the truth."""
    e = _pixel_errors(kp, truth_px)
    counted = (conf >= MIN_CONFIDENCE) & np.isfinite(e)
    out = {}
    for name, joints in (("limbs", LIMBS), ("wrists", WRISTS)):
        x = e[..., joints][counted[..., joints]]
        out[name] = {"n": int(x.size), "median_px": float(np.median(x)), "over_25px": float((x > 25).mean()),
                     "over_50px": float((x > 50).mean())}
    return out


def miss_runs(kp: np.ndarray, conf: np.ndarray, truth_px: np.ndarray) -> dict:
    """How long a view's counted wrist detection stays more than 25 px off (as :func:`errors` reads it), in frames
    of the sequence: the mean and the longest run."""
    e = _pixel_errors(kp, truth_px)
    off = (conf >= MIN_CONFIDENCE) & (e > 25)
    runs = []
    for c in range(kp.shape[1]):
        for j in WRISTS:
            n = 0
            for flag in [*off[:, c, j], False]:
                if flag:
                    n += 1
                elif n:
                    runs.append(n)
                    n = 0
    return {"runs": len(runs), "mean_frames": float(np.mean(runs)) if runs else 0.0,
            "longest_frames": int(max(runs, default=0))}


def write_copy(src: Path, dst: Path, kp: np.ndarray, conf: np.ndarray) -> None:
    """``src`` as ``dst`` with these keypoints (the views linked, the small files copied)."""
    if dst.exists():
        raise SystemExit(f"{dst} exists: choose another --out")
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for p in src.iterdir():
        if p.name == "markers.npz":
            continue
        if p.is_dir():
            os.symlink(p.resolve(), tmp / p.name)
        else:
            shutil.copy2(p, tmp / p.name)
    T, C, J, _ = kp.shape
    present = np.isfinite(kp).all(-1)
    ids = np.broadcast_to(np.arange(J, dtype=np.int16), (T, C, J))
    np.savez(tmp / "markers.npz", counts=present.sum(-1).astype(np.int64), uv=kp[present], ids=ids[present],
             confidence=conf[present])
    tmp.rename(dst)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequence", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--relabel", action="store_true", help="exchange left and right where the views agree")
    ap.add_argument("--median", type=int, default=0, help="K: the median over 2K + 1 frames (0: none)")
    ap.add_argument("--floor", type=float, default=0.05, help="detections from this confidence on take part")
    ap.add_argument("--fps", type=float, default=20.0, help="the tracked frames the errors are measured on")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with open_sequence(args.sequence) as seq:
        if seq.gt_joints is None or seq.marker_data is None or seq.marker_data.confidence is None:
            raise SystemExit(f"{args.sequence}: needs a detector's keypoints and a ground truth")
        dense, conf = seq.marker_data.to_dense()
        cameras = list(seq.cameras)
        threshold = 0.025 * float(np.hypot(*seq.image_size))
        frames = np.asarray(seq.subsample(args.fps), dtype=np.int64)
        truth_all = reproject(cameras, np.asarray(seq.gt_joints))
    truth_px = truth_all[frames]
    kp, cf = np.asarray(dense, dtype=np.float64), np.nan_to_num(np.asarray(conf, dtype=np.float64))
    before = errors(kp[frames], cf[frames], truth_px)
    runs = miss_runs(kp, cf, truth_all)
    if args.relabel:
        kp, cf = relabelled(cameras, kp, cf, args.floor, threshold)
    if args.median > 0:
        kp = steadied(kp, cf, args.median, args.floor)
    write_copy(args.sequence, args.out, kp, cf)
    result = {"sequence": str(args.sequence), "out": str(args.out), "relabel": args.relabel, "median": args.median,
              "floor": args.floor, "before": before, "after": errors(kp[frames], cf[frames], truth_px),
              "wrist_misses_before": runs}
    if args.json:
        print(json.dumps(result))
        return
    for when in ("before", "after"):
        print(when + ": " + "; ".join(f"{name} {r['n']} detections, median {r['median_px']:.1f} px, "
                                      f"{100 * r['over_25px']:.1f} % > 25 px, {100 * r['over_50px']:.1f} % > 50 px"
                                      for name, r in result[when].items()))
    print(f"a view's wrist more than 25 px off, before: {runs['runs']} times, for {runs['mean_frames']:.1f} frames "
          f"on average, {runs['longest_frames']} at most")


if __name__ == "__main__":
    main()
