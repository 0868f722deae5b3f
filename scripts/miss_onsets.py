"""How a tracked limb joint comes to miss by more than a limit: drifting off, or in one jump?

For a ``swarmpose track`` results folder with a ground truth, every run's misses of the joints one limb's parameters
move (elbows, wrists, knees, ankles: farther than ``--limit`` mm from the truth) are grouped into episodes, runs of
consecutive missed frames of one joint. At an episode's first frame the joint's move since the frame before,
relative to its limb's root (the shoulder or the hip, so that the trunk's own move does not count), is set against
the truth's: an onset is *sudden* when the tracked joint moved more than ``2 x`` the truth's move ``+ 60 mm``. The
tracker's record of the limbs its recovery searched again and replaced (``track.npz``'s ``recovered``) says whether
the limb was replaced on that frame, beside how often it was replaced on any frame (the base rate).

Per clip: the episodes and their joint-frames, the sudden ones, and how many of the sudden onsets fell on a frame
where the recovery replaced the limb.

Run:  .venv/bin/python scripts/miss_onsets.py results/detected-keypoints/cmu_131_01_walk-refined-heading
          [more folders] [--runs 5] [--limit 100] [--json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.joints import JOINT_INDEX
from swarmpose.track.runner import recorded_config
from swarmpose.track.tracker import prepare_track

#: Limb joint -> (the limb's root joint, the limb as the tracker's recovery names it).
ROOT_OF = {"l_elbow": ("l_shoulder", "left_arm"), "l_wrist": ("l_shoulder", "left_arm"),
           "r_elbow": ("r_shoulder", "right_arm"), "r_wrist": ("r_shoulder", "right_arm"),
           "l_knee": ("l_hip", "left_leg"), "l_ankle": ("l_hip", "left_leg"),
           "r_knee": ("r_hip", "right_leg"), "r_ankle": ("r_hip", "right_leg")}


def onsets(est: np.ndarray, truth: np.ndarray, limit: float) -> list[dict]:
    """The miss episodes of ``est (T, 15, 3)`` against ``truth (T, 15, 3)``: per limb joint, each run of consecutive
    frames farther than ``limit`` mm, with its first frame, length, and the joint's move since the frame before
    relative to its limb's root, tracked and true (mm; an episode on the first frame has none)."""
    out = []
    for name, (root, limb) in ROOT_OF.items():
        k, r = JOINT_INDEX[name], JOINT_INDEX[root]
        missed = np.linalg.norm(est[:, k] - truth[:, k], axis=-1) > limit
        rel_e, rel_t = est[:, k] - est[:, r], truth[:, k] - truth[:, r]
        t = 0
        while t < len(missed):
            if not missed[t]:
                t += 1
                continue
            n = 1
            while t + n < len(missed) and missed[t + n]:
                n += 1
            moved = tuple(float(np.linalg.norm(rel[t] - rel[t - 1])) if t > 0 else None for rel in (rel_e, rel_t))
            out.append({"joint": name, "limb": limb, "frame": t, "frames": n, "moved_mm": moved[0],
                        "truth_moved_mm": moved[1]})
            t += n
    return out


def sudden(episode: dict) -> bool:
    """An onset where the tracked joint moved more than twice the truth's move and 60 mm."""
    m, mt = episode["moved_mm"], episode["truth_moved_mm"]
    return m is not None and m > 2 * mt + 60


def clip_onsets(results: Path, runs: int, limit: float) -> dict:
    config, cfg = recorded_config(results)
    setup = prepare_track(config["sequence"], cfg, results)
    if not setup.has_ground_truth:
        raise SystemExit(f"{results}: the sequence has no ground truth")
    run_files = sorted(results.glob("run_*/track.npz"))[:runs]
    if not run_files:
        raise SystemExit(f"{results}: no run_*/track.npz")
    episodes, base = [], []
    for f in run_files:
        with np.load(f) as z:
            joints = np.asarray(z["joints"])
            recovered = np.asarray(z["recovered"]) if "recovered" in z.files else None
            limbs = [str(s) for s in z["limbs"]] if "limbs" in z.files else []
        for e in onsets(joints, setup.gt_joints, limit):
            e["run"] = f.parent.name
            e["replaced"] = (bool(recovered[e["frame"], limbs.index(e["limb"])])
                             if recovered is not None and e["limb"] in limbs else None)
            episodes.append(e)
        if recovered is not None and recovered.size:
            base.append(float(recovered.mean()))
    hard = [e for e in episodes if sudden(e)]
    return {"results": str(results), "runs": len(run_files), "episodes": len(episodes),
            "joint_frames": sum(e["frames"] for e in episodes), "sudden": len(hard),
            "sudden_joint_frames": sum(e["frames"] for e in hard),
            "sudden_replaced": sum(bool(e["replaced"]) for e in hard),
            "replaced_base_rate": float(np.mean(base)) if base else None, "episodes_list": episodes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path, nargs="+")
    ap.add_argument("--runs", type=int, default=5, help="the first N runs of each folder")
    ap.add_argument("--limit", type=float, default=100.0, help="mm: a joint farther off is a miss")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    clips = [clip_onsets(r, args.runs, args.limit) for r in args.results]
    total = {k: sum(c[k] for c in clips) for k in ("episodes", "joint_frames", "sudden", "sudden_joint_frames",
                                                   "sudden_replaced")}
    if args.json:
        print(json.dumps({"clips": clips, "total": total}))
        return
    print(f"{'results':40s} {'runs':>4s} {'episodes':>8s} {'frames':>6s} {'sudden':>6s} {'frames':>6s} "
          f"{'replaced':>8s} {'base rate':>9s}")
    for c in clips:
        rate = f"{100 * c['replaced_base_rate']:8.0f}%" if c["replaced_base_rate"] is not None else f"{'-':>9s}"
        print(f"{Path(c['results']).name:40s} {c['runs']:4d} {c['episodes']:8d} {c['joint_frames']:6d} "
              f"{c['sudden']:6d} {c['sudden_joint_frames']:6d} {c['sudden_replaced']:8d} {rate}")
    print(f"{'total':40s} {'':4s} {total['episodes']:8d} {total['joint_frames']:6d} {total['sudden']:6d} "
          f"{total['sudden_joint_frames']:6d} {total['sudden_replaced']:8d}")


if __name__ == "__main__":
    main()
